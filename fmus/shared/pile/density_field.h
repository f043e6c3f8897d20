/*
 * A seeded per-cell density field and the mass bookkeeping that goes with it.
 *
 * With density_variation a > 0, cell i of the profile holds material of density
 * density * (1 + a u(y_i)), u in [-1, 1]: u is piecewise linear between knots
 * density_correlation_length apart, each knot's value drawn from density_seed by splitmix64
 * (integer arithmetic: the same field on every machine). Material keeps its mass where it
 * goes: each cell's column (from z_floor up to its surface) is taken as well mixed, so a cut
 * takes the column's mean density, a slump carries the giving column's mean density into its
 * neighbour, and a spill carries the bucket's mean density. The books hold masses, not
 * densities, so every move conserves mass to round-off.
 *
 * With a = 0 the pile is uniform and nothing here runs: masses are density * volume as before.
 */
#ifndef PILE_DENSITY_FIELD_H
#define PILE_DENSITY_FIELD_H

#include "profile.h"

typedef struct {
    double cell[N_h]; /* kg, material of each profile cell (of the slice) */
    double bucket;    /* kg in the bucket */
    double dumped;    /* kg dumped since the start */
    double spilled;   /* kg spilled back onto the pile since the start */
} MassBook;

/* Relative density deviation u(y) in [-1, 1] of the field with knots `length` (m) apart from
 * y_min, drawn from `seed`. */
double density_deviation(double y, double y_min, double length, unsigned long long seed);

/* Fills the books for the profile p: cell i gets density (1 + variation u) times its column's
 * volume (slice `width` m wide); bucket, dumped and spilled are zero. */
void mass_book_init(MassBook *b, const Profile *p, const Grid *g, double density,
                    double variation, double length, unsigned long long seed, double width);

/* After a cut lowered cells from `before` (m, the heights before) to p->h: their material's
 * mass moves into the bucket. Returns the mass moved (kg). */
double mass_book_cut(MassBook *b, const double *before, const Profile *p, const Grid *g);

/* After a conservative slump from `before` to p->h: the mass each boundary carried, at the
 * giving column's mean density. */
void mass_book_relax(MassBook *b, const double *before, const Profile *p, const Grid *g);

/* A spill of `volume` (m^3) out of a bucket holding `bucket_volume` (m^3) onto cell k. */
void mass_book_spill(MassBook *b, int k, double volume, double bucket_volume);

/* Mass of the profile's material (kg). */
double mass_book_pile(const MassBook *b);

#endif
