/* Per-cell density field and mass bookkeeping. See density_field.h. */
#include <math.h>

#include "density_field.h"

/* splitmix64 (Steele, Lea, Flood 2014): a well-mixed 64-bit hash of the knot index. */
static unsigned long long splitmix64(unsigned long long x)
{
    x += 0x9E3779B97F4A7C15ULL;
    x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ULL;
    x = (x ^ (x >> 27)) * 0x94D049BB133111EBULL;
    return x ^ (x >> 31);
}

/* Knot j's value in [-1, 1): the top 53 bits as a double, exact on every machine. */
static double knot(unsigned long long seed, long j)
{
    const unsigned long long bits = splitmix64(seed * 0x100000001B3ULL ^ (unsigned long long)j);
    return 2.0 * (double)(bits >> 11) * 0x1.0p-53 - 1.0;
}

double density_deviation(double y, double y_min, double length, unsigned long long seed)
{
    const double x = (y - y_min) / length;
    const double j = floor(x);
    const double f = x - j;
    return (1.0 - f) * knot(seed, (long)j) + f * knot(seed, (long)j + 1);
}

/* Column of cell i from z_floor to `height`, in m^2 of the cross-section. */
static double column(const Grid *g, double height) { return (height - g->z_floor) * g->dy; }

void mass_book_init(MassBook *b, const Profile *p, const Grid *g, double density,
                    double variation, double length, unsigned long long seed, double width)
{
    for (int i = 0; i < N_h; ++i) {
        const double y = g->y_min + (i + 0.5) * g->dy;
        const double rho = density * (1.0 + variation * density_deviation(y, g->y_min, length,
                                                                           seed));
        b->cell[i] = rho * width * column(g, p->h[i]);
    }
    b->bucket = b->dumped = b->spilled = 0.0;
}

double mass_book_cut(MassBook *b, const double *before, const Profile *p, const Grid *g)
{
    double moved = 0.0;
    for (int i = 0; i < N_h; ++i) {
        if (!(p->h[i] < before[i])) continue;
        const double taken = b->cell[i] * (before[i] - p->h[i]) / (before[i] - g->z_floor);
        b->cell[i] -= taken;
        moved += taken;
    }
    b->bucket += moved;
    return moved;
}

void mass_book_relax(MassBook *b, const double *before, const Profile *p, const Grid *g)
{
    /* In one dimension the flow over boundary i|i+1 is what cells 0..i lost (closed ends).
     * Every flow is priced at its giver's density before the slump, then applied: the books
     * change by the same amounts on both sides, so the total is conserved whatever the order. */
    double per_area[N_h];
    for (int i = 0; i < N_h; ++i) {
        const double area = column(g, before[i]);
        per_area[i] = area > 0.0 ? b->cell[i] / area : -1.0;
    }
    /* A column cut down to z_floor has no density of its own: what it passes on within the
     * slump came from a neighbour, so it is priced at the nearest non-empty one. */
    for (int i = 0; i < N_h; ++i) {
        for (int d = 1; per_area[i] < 0.0 && d < N_h; ++d) {
            if (i - d >= 0 && per_area[i - d] >= 0.0 && column(g, before[i - d]) > 0.0)
                per_area[i] = per_area[i - d];
            else if (i + d < N_h && per_area[i + d] >= 0.0 && column(g, before[i + d]) > 0.0)
                per_area[i] = per_area[i + d];
        }
        if (per_area[i] < 0.0) per_area[i] = 0.0;
    }
    double flow = 0.0;
    for (int i = 0; i < N_h - 1; ++i) {
        flow += (before[i] - p->h[i]) * g->dy;
        if (flow == 0.0) continue;
        const double mass = flow * per_area[flow > 0.0 ? i : i + 1];
        b->cell[i] -= mass;
        b->cell[i + 1] += mass;
    }
}

void mass_book_spill(MassBook *b, int k, double volume, double bucket_volume)
{
    const double mass = b->bucket * volume / bucket_volume;
    b->bucket -= mass;
    b->cell[k] += mass;
    b->spilled += mass;
}

double mass_book_pile(const MassBook *b)
{
    double sum = 0.0;
    for (int i = 0; i < N_h; ++i) sum += b->cell[i];
    return sum;
}
