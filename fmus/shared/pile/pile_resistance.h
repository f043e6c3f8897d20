/*
 * The one part a pile model supplies itself: its soil resistance law. The shared pile mechanics
 * (pile.c: cutting, capacity, slumping, dumping, outputs) call these two functions; each pile
 * model's model.c defines them from its own parameters (v is indexed by value reference, as in
 * model.h). So a new resistance law is one small file, and the mechanics are never copied.
 */
#ifndef PILE_RESISTANCE_H
#define PILE_RESISTANCE_H

#include "model.h"

/* NULL when the law's parameters in v are valid, else a static message naming the bad one. */
const char *pile_check_resistance(const double *v);

/* Draft H (N) on the bucket slice of width v[VR_width], against the motion, for a cut of
 * `depth` (m, > 0) at rake angle `rake` (rad, in [0, pi]: the angle between the tip-to-pin
 * line and the direction opposite to the motion; pi/2 = the line is normal to the motion).
 * Must be >= 0 and finite. */
double pile_draft(const double *v, double rake, double depth);

#endif
