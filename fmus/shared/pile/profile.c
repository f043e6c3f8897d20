/* Material profile: cutting with exact sub-cell bookkeeping, and slumping. See profile.h. */
#include <math.h>

#include "profile.h"

static double cell_low(const Grid *g, int i) { return g->y_min + i * g->dy; }

/* Integral of the unit triangle max(0, 1 - |t|) from -infinity to x. */
static double triangle_integral(double x)
{
    if (x <= -1.0) return 0.0;
    if (x <= 0.0) return 0.5 * (x + 1.0) * (x + 1.0);
    if (x <= 1.0) return 1.0 - 0.5 * (1.0 - x) * (1.0 - x);
    return 1.0;
}

void profile_init(Profile *p, const Grid *g, double z0, double grade, double height,
                  double center, double half_width)
{
    for (int i = 0; i < N_h; ++i) {
        const double lo = (cell_low(g, i) - center) / half_width;
        const double hi = (cell_low(g, i + 1) - center) / half_width;
        const double mean = half_width * (triangle_integral(hi) - triangle_integral(lo)) / g->dy;
        const double ground = z0 + grade * (0.5 * (cell_low(g, i) + cell_low(g, i + 1)) - center);
        p->h[i] = height > 0.0 ? ground + height * mean : ground;
    }
    p->active = -1;
    p->n_seg = 0;
}

int profile_cell(const Grid *g, double y)
{
    const double x = (y - g->y_min) / g->dy;
    if (!(x >= 0.0) || !(x <= N_h)) return -1;
    const int i = (int)floor(x);
    return i < N_h ? i : N_h - 1;
}

void profile_release(Profile *p)
{
    p->active = -1;
    p->n_seg = 0;
}

static void activate(Profile *p, const Grid *g, int i)
{
    p->active = i;
    p->n_seg = 1;
    p->seg_y[0] = cell_low(g, i);
    p->seg_y[1] = cell_low(g, i + 1);
    p->seg_h[0] = p->h[i];
}

/* Area above `level` in the active cell over [a, b]. */
static double segments_area(const Profile *p, double a, double b, double level)
{
    double area = 0.0;
    for (int j = 0; j < p->n_seg; ++j) {
        const double c0 = fmax(p->seg_y[j], a), c1 = fmin(p->seg_y[j + 1], b);
        if (c1 > c0 && p->seg_h[j] > level) area += (p->seg_h[j] - level) * (c1 - c0);
    }
    return area;
}

/* Appends a segment ending at `end` with height `z`, merging it into an equal neighbour. */
static void push_segment(double *ys, double *hs, int *n, double end, double z)
{
    if (*n > 0 && hs[*n - 1] == z) {
        ys[*n] = end;
        return;
    }
    hs[*n] = z;
    ys[*n + 1] = end;
    ++*n;
}

/* Cuts the active cell down to `level` over [a, b]; returns the removed area. The loop mirrors
 * segments_area term by term, so a dry run and the cut agree to the last bit. */
static double segments_cut(Profile *p, double a, double b, double level)
{
    double ys[3 * PROFILE_MAX_SEGMENTS + 1], hs[3 * PROFILE_MAX_SEGMENTS];
    double area = 0.0;
    int n = 0;
    ys[0] = p->seg_y[0];
    for (int j = 0; j < p->n_seg; ++j) {
        const double s0 = p->seg_y[j], s1 = p->seg_y[j + 1], z = p->seg_h[j];
        const double c0 = fmax(s0, a), c1 = fmin(s1, b);
        if (!(c1 > c0)) {
            push_segment(ys, hs, &n, s1, z);
            continue;
        }
        if (c0 > s0) push_segment(ys, hs, &n, c0, z);
        if (z > level) area += (z - level) * (c1 - c0);
        push_segment(ys, hs, &n, c1, fmin(z, level));
        if (s1 > c1) push_segment(ys, hs, &n, s1, z);
    }
    /* Too many segments: merge the neighbouring pair closest in height (volume kept). */
    while (n > PROFILE_MAX_SEGMENTS) {
        int best = 0;
        for (int j = 1; j < n - 1; ++j)
            if (fabs(hs[j + 1] - hs[j]) < fabs(hs[best + 1] - hs[best])) best = j;
        const double l0 = ys[best + 1] - ys[best], l1 = ys[best + 2] - ys[best + 1];
        hs[best] = (hs[best] * l0 + hs[best + 1] * l1) / (l0 + l1);
        for (int j = best + 1; j < n - 1; ++j) {
            hs[j] = hs[j + 1];
            ys[j] = ys[j + 1];
        }
        ys[n - 1] = ys[n];
        --n;
    }
    double volume = 0.0;
    for (int j = 0; j < n; ++j) {
        p->seg_y[j] = ys[j];
        p->seg_h[j] = hs[j];
        volume += hs[j] * (ys[j + 1] - ys[j]);
    }
    p->seg_y[n] = ys[n];
    p->n_seg = n;
    p->h[p->active] = volume / (ys[n] - ys[0]);
    return area;
}

/* Shared walk over the cells a straight tip move overlaps, in the direction of travel (so the
 * cell the tip ends in is activated last). With apply == 0 it only sums the area. */
static double sweep(Profile *p, const Grid *g, double ya, double za, double yb, double zb,
                    double lift, int apply)
{
    const double y_end = cell_low(g, N_h);
    const double lo = fmax(fmin(ya, yb), g->y_min), hi = fmin(fmax(ya, yb), y_end);
    if (!(hi > lo)) return 0.0;
    const int first = profile_cell(g, lo), last = profile_cell(g, hi);
    const int step = yb > ya ? 1 : -1;
    double area = 0.0;
    for (int i = step > 0 ? first : last; step > 0 ? i <= last : i >= first; i += step) {
        const double c_lo = cell_low(g, i), c_hi = cell_low(g, i + 1);
        const double a = fmax(lo, c_lo), b = fmin(hi, c_hi);
        if (!(b > a)) continue;
        /* The path is straight: its mean height over [a, b] is its height at the middle. */
        const double z = za + (zb - za) * (0.5 * (a + b) - ya) / (yb - ya);
        const double level = fmax(z, g->z_floor) + lift;
        const int whole = a == c_lo && b == c_hi;
        if (i == p->active) {
            area += apply ? segments_cut(p, a, b, level) : segments_area(p, a, b, level);
        } else if (p->h[i] > level) {
            if (whole) {
                area += (p->h[i] - level) * g->dy;
                if (apply) p->h[i] = level;
            } else if (apply) {
                activate(p, g, i); /* the previous active cell falls back to its mean */
                area += segments_cut(p, a, b, level);
            } else {
                area += (p->h[i] - level) * (b - a);
            }
        }
    }
    return area;
}

double profile_sweep_area(const Profile *p, const Grid *g, double ya, double za, double yb,
                          double zb, double lift)
{
    /* The dry run never writes through the pointer. */
    return sweep((Profile *)p, g, ya, za, yb, zb, lift, 0);
}

double profile_sweep(Profile *p, const Grid *g, double ya, double za, double yb, double zb,
                     double lift)
{
    return sweep(p, g, ya, za, yb, zb, lift, 1);
}

double profile_top_near(const Profile *p, int k)
{
    double top = p->h[k];
    if (p->active == k)
        for (int j = 0; j < p->n_seg; ++j) top = fmax(top, p->seg_h[j]);
    if (k > 0) top = fmax(top, p->h[k - 1]);
    if (k < N_h - 1) top = fmax(top, p->h[k + 1]);
    return top;
}

/* One pair's half-excess move (see profile_relax), on heights a = h[i], b = h[i + 1] held in
 * registers by the caller; returns whether it moved. */
static inline __attribute__((always_inline)) int relax_pair(double *a, double *b,
                                                            double max_step)
{
    const double step = *a - *b;
    const double excess = fabs(step) - max_step;
    if (!(excess > PROFILE_RELAX_TOLERANCE)) return 0;
    /* Half the excess moves down the slope: the pair ends exactly at max_step. */
    const double moved = 0.5 * excess;
    if (step > 0.0) {
        *a -= moved;
        *b += moved;
    } else {
        *a += moved;
        *b -= moved;
    }
    return 1;
}

/*
 * Sweeps alternate forward and backward over the pairs (Gauss-Seidel). A pair changes only if
 * one of its cells changed since it was last visited, so each pass visits only the pairs next to
 * the cells the previous pass changed, extending as it goes (a pair that moves material makes
 * the next pair in the pass's direction due): the same changes in the same order as full
 * sweeps, so the same result bit for bit, without visiting the settled rest of the profile.
 * A pass carries the cell it shares with the next pair in a register (the same arithmetic,
 * without a store and reload per pair). The relaxation is most of the Pile's time.
 */
static int free_pair(int i, int held)
{
    return held < 0 || (i != held && i + 1 != held);
}

int profile_relax(Profile *p, double max_step, int held, int max_sweeps)
{
    if (p->active >= 0 && p->active != held) profile_release(p);
    double *h = p->h;
    int lo = 0, hi = N_h - 1; /* cells changed since their pairs were visited */
    for (int sweep_count = 1; sweep_count <= max_sweeps; ++sweep_count) {
        int changed_lo = N_h, changed_hi = -1;
        int last = hi < N_h - 2 ? hi : N_h - 2;
        int i = lo > 0 ? lo - 1 : 0;
        double left = h[i];
        for (; i <= last; ++i) {
            double right = h[i + 1];
            if (free_pair(i, held) && relax_pair(&left, &right, max_step)) {
                if (i < changed_lo) changed_lo = i;
                changed_hi = i + 1;
                if (i + 1 > last && i + 1 <= N_h - 2) last = i + 1;
            }
            h[i] = left;
            left = right;
        }
        h[i] = left;
        if (changed_hi < 0) return sweep_count;
        lo = N_h;
        hi = -1;
        int first = changed_lo > 0 ? changed_lo - 1 : 0;
        i = changed_hi < N_h - 2 ? changed_hi : N_h - 2;
        double right = h[i + 1];
        for (; i >= first; --i) {
            double left_cell = h[i];
            if (free_pair(i, held) && relax_pair(&left_cell, &right, max_step)) {
                if (i + 1 > hi) hi = i + 1;
                lo = i;
                if (i - 1 < first && i >= 1) first = i - 1;
            }
            h[i + 1] = right;
            right = left_cell;
        }
        h[i + 1] = right;
        /* A forward pass that moved something always leaves work to check: the sweeps end
         * when a forward pass moves nothing. */
        if (hi < 0) { /* the backward pass changed nothing: what it saw is settled */
            lo = changed_lo;
            hi = changed_hi;
        }
    }
    return max_sweeps;
}

double profile_surface_at(const Profile *p, const Grid *g, double y)
{
    const double x = (y - g->y_min) / g->dy - 0.5;
    if (x <= 0.0) return p->h[0];
    if (x >= N_h - 1) return p->h[N_h - 1];
    const int i = (int)floor(x);
    const double f = x - i;
    return (1.0 - f) * p->h[i] + f * p->h[i + 1];
}

double profile_area(const Profile *p, const Grid *g)
{
    double sum = 0.0;
    for (int i = 0; i < N_h; ++i) sum += p->h[i] - g->z_floor;
    return sum * g->dy;
}
