/*
 * The part a pile model supplies itself: its soil resistance law. The shared pile mechanics
 * (pile.c: cutting, capacity, slumping, dumping; tip_force.c: the surface frame and the three
 * cases of motion) call these functions; each pile model's model.c defines them from its own
 * parameters (v is indexed by value reference, as in model.h). So a new resistance law is one
 * small file, and the mechanics are never copied.
 *
 * Every force is on the whole cutting edge of the bucket, v[VR_bucket_width] wide (the force
 * scale), not on the material slice v[VR_slice_width] whose mass the pile tracks (the mass
 * scale). Depths are measured normal to the soil surface.
 */
#ifndef PILE_RESISTANCE_H
#define PILE_RESISTANCE_H

#include "model.h"

/* NULL when the law's parameters in v are valid, else a static message naming the bad one. */
const char *pile_check_resistance(const double *v);

/* Cutting: the edge travels along the surface at `depth` (m, > 0) below it, its face at `rake`
 * (rad, in [SOIL_CUT_RAKE_MIN, pi/2]: the angle between the tip-to-pin line and the surface
 * behind the edge; pi/2 = a face normal to the surface). `full`: the bucket is full, so what it
 * cuts heaps in front of it instead of entering. Writes the draft (N, >= 0, against the travel)
 * and the normal force (N, along the surface normal, > 0 pushes the edge out of the soil). Both
 * finite. */
void pile_cutting_force(const double *v, double rake, double depth, int full, double *draft,
                        double *normal);

/* Penetration: the edge pushed into the soil along the surface normal, its tip `depth` (m, > 0)
 * below the surface. Returns the resistance (N, >= 0, finite). */
double pile_penetration_resistance(const double *v, double depth);

/* Lift-out: the edge pulled out along the surface normal from `depth` (m, > 0). Returns the
 * resistance (N, >= 0, finite): what the soil outside the bucket holds back (the material inside
 * rises with the bucket and is weighed as payload). */
double pile_lift_resistance(const double *v, double depth);

/* Rakes below this are taken as this: the wedge has no failure plane as the face lies flat. */
#define SOIL_CUT_RAKE_MIN 0.17453292519943295 /* 10 deg */

#endif
