/*
 * The material profile: surface height z = h(y) as N_h cells of equal length dy over
 * [y_min, y_min + N_h dy]; the material fills each cell from z_floor up to h (uniform density,
 * the paper's assumptions). Cross-section areas are in m^2 (times the slice width = volume).
 *
 * Partial cells. A cell keeps one mean height, but the bucket tip usually sweeps a cell in many
 * small pieces. Cutting a piece of a flat cell and averaging at once would lose the knowledge of
 * which part is already cut: the next piece would remove too little (sweeping a cell in n pieces
 * would take only 1 - (1 - 1/n)^n of it, 63 % for large n). So the cell the tip is in ("active"
 * cell) carries an exact sub-cell profile: up to PROFILE_MAX_SEGMENTS flat segments. A cut takes
 * min(segment height, cut level) over the swept y-interval's overlap with each segment; the
 * cell's mean height h is kept equal to the segments' mean. When the tip leaves the cell (or
 * slumping needs it) the cell falls back to its mean; volume is exact throughout.
 */
#ifndef PILE_PROFILE_H
#define PILE_PROFILE_H

#include "model.h"

#define PROFILE_MAX_SEGMENTS 16

typedef struct {
    double y_min;   /* m, left edge of cell 0 */
    double dy;      /* m, cell length */
    double z_floor; /* m, bottom of the material; no cut goes below it */
} Grid;

typedef struct {
    double h[N_h];                           /* m, mean surface height of each cell */
    double seg_y[PROFILE_MAX_SEGMENTS + 1];  /* m, segment edges of the active cell */
    double seg_h[PROFILE_MAX_SEGMENTS];      /* m, segment heights of the active cell */
    int active;                              /* index of the active cell, -1 if none */
    int n_seg;
} Profile;

/* Ground through z0 at y = center, inclined by `grade` (dz/dy), plus a triangular heap
 * (height >= 0, crest at center, base half width half_width > 0): each cell gets the exact mean
 * of that shape over the cell (a line's mean is its value at the cell centre). */
void profile_init(Profile *p, const Grid *g, double z0, double grade, double height,
                  double center, double half_width);

/* Index of the cell holding y, or -1 if y lies outside the grid. */
int profile_cell(const Grid *g, double y);

/* Area (m^2) above the cut path that a straight tip move from (ya, za) to (yb, zb) would
 * remove, with every cut level raised by `lift` (m, >= 0). Changes nothing. */
double profile_sweep_area(const Profile *p, const Grid *g, double ya, double za, double yb,
                          double zb, double lift);

/* Performs that cut and returns the removed area (m^2): the same number as
 * profile_sweep_area with the same arguments. */
double profile_sweep(Profile *p, const Grid *g, double ya, double za, double yb, double zb,
                     double lift);

/* Highest surface near cell k (k and its neighbours; the uncut part of an active cell). */
double profile_top_near(const Profile *p, int k);

/* Conservative slumping: transfers between neighbouring cells until no step between them
 * exceeds max_step (m) by more than PROFILE_RELAX_TOLERANCE, at most max_sweeps sweep pairs.
 * The two cell boundaries of cell `held` (-1: none) are closed: the buried bucket holds the
 * material there. Returns the sweeps used. */
/* 10 um per 5 cm cell: slopes within 0.01 deg of repose. The sweeps converge linearly, so
 * each decade of tolerance costs as much as the next: 1e-9 m took 2.8 times as long (the
 * masses of a paper campaign move by 0.003 kg). */
#define PROFILE_RELAX_TOLERANCE 1e-5 /* m */
int profile_relax(Profile *p, double max_step, int held, int max_sweeps);

/* Ends the sub-cell profile of the active cell (its mean height stays). */
void profile_release(Profile *p);

/* Surface height at y (m): linear between cell centres, constant beyond the end centres. */
double profile_surface_at(const Profile *p, const Grid *g, double y);

/* Cross-section area of material above z_floor (m^2). */
double profile_area(const Profile *p, const Grid *g);

#endif
