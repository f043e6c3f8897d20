/*
 * The soil force on the bucket tip, in the frame of the soil surface (tip_force.c).
 */
#ifndef PILE_TIP_FORCE_H
#define PILE_TIP_FORCE_H

#include "profile.h"

/* How far each resistance is mobilised (the elastic-plastic state of the soil at the tip). */
typedef struct {
    double side[2]; /* cutting on the +y and -y side, in [0, 1] */
    double normal;  /* along the surface normal: > 0 penetration, < 0 lift-out, in [-1, 1] */
} Mobilization;

typedef struct {
    double F_y, F_z; /* N, force of the soil on the bucket */
    double depth;    /* m, depth of the tip below the surface, normal to it (0: out of soil) */
} TipForce;

/* Moves the tip by (dy, dz) m to (y, z) with the tip-to-pin line at bucket_angle (rad,
 * counter-clockwise from +y), on the profile p as cut by that move: updates the mobilisation m
 * and returns the force there; `full`: the bucket is full (its cut heaps in front). v holds the parameters (value references as in model.h). All
 * inputs finite. */
TipForce tip_force(const double *v, const Profile *p, const Grid *g, double y, double z,
                   double dy, double dz, double bucket_angle, int full, Mobilization *m);

#endif
