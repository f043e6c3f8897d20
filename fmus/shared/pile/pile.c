/*
 * Pile mechanics shared by every pile model (fmus/Pile, fmus/PileZelenin, ...): the material a
 * bucket digs, as a surface profile z = h(y) (profile.h) with uniform density and width (the
 * paper's assumptions). The soil resistance law is the model's own (pile_resistance.h): this file
 * only finds the cut depth, the rake angle and the direction. Mass is conserved: pile_mass + bucket_mass + dumped_mass stays the initial
 * mass to round-off.
 *
 * One step. The tip moves on a straight line from its position at the end of the last step to
 * the new input, in substeps of at most a quarter cell (in y and in z). Each substep:
 *  1. Cut: every cell the tip sweeps is cut down to the tip path (never below z_floor); the cut
 *     material enters the bucket while its edge leads (the tip-to-pin line at a rake <= 90 deg
 *     to the move); beyond, only the share sin(rake) enters, down to none when the bucket's back
 *     leads (the rest stays: the bucket pushes it aside). A vertical move sweeps no area and
 *     cuts nothing: the capacity
 *     is filled by dragging, as a real bucket fills. When a cut would overflow `capacity`, all
 *     cut levels of the substep rise together until exactly the free volume is removed; with a
 *     full bucket nothing more is cut and the material stays where it is (the bucket pushes
 *     through it and still meets the resistance below).
 *  2. Slump: slopes steeper than repose_angle relax by conservative transfers between
 *     neighbouring cells, iterated to convergence. While the tip is buried (below the highest
 *     surface of its cell and the two neighbours), the two boundaries of its cell are closed:
 *     the bucket is a wall, so the face in front of it stands until it is cut and the material
 *     behind cannot run back under it. When the bucket leaves the material, the trench walls
 *     slump freely (and fill the next cut: the ground's memory).
 * After the substeps, a bucket out of the ground (tip a cell above the surface) spills what its tilt cannot
 * hold (held_share) onto the surface below its tip: the cell there takes it and slumping spreads
 * it (spilled_mass counts it; it is pile material again). Then dump > 0.5 moves the bucket
 * content to dumped_mass.
 *
 * Force: tip_force.c, in the surface frame, from the tip's path: an elastic-plastic state per
 * resistance, advanced by the step's move, so the force at the end of a step is a function of
 * where the tip has been (no velocity differenced from the last step, nothing divided by h).
 *
 * Scales: the pile tracks the material of a slice slice_width wide (every mass and volume); the
 * soil force acts on the whole cutting edge, bucket_width wide.
 *
 * Density: uniform by default (the paper's assumption); density_variation > 0 gives every cell
 * its own density from a seeded field (density_field.h), and the pile then keeps books of mass
 * beside the volumes. The soil force keeps the mean density.
 */
#include <math.h>

#include <string.h>

#include "density_field.h"
#include "model.h"
#include "profile.h"
#include "pile_resistance.h"
#include "tip_force.h"

#define PI 3.14159265358979323846
#define SUBSTEP_CELL_FRACTION 0.25 /* largest tip move per substep, in cells */
#define MAX_SUBSTEPS 4096          /* a jump longer than 1024 cells is cut in coarser pieces */
#define RELAX_MAX_SWEEPS 20000     /* bound per substep; a 1.9 m x 4 m trench settles in ~2500 */
#define CAPACITY_BISECTIONS 100
#define FULL_FRACTION (1.0 - 1e-12)

typedef struct {
    Profile profile;
    double bucket_volume;  /* m^3 */
    double dumped_volume;  /* m^3 */
    double removed_volume; /* m^3, everything cut since the start */
    double spilled_volume; /* m^3, everything spilled back onto the pile since the start */
    double tip_y, tip_z;   /* m, tip position at the end of the last step */
    int held;              /* cell held by the buried bucket at the last relaxation, or -1 */
    int settled;           /* the last relaxation converged: nothing to do until a change */
    Mobilization mobilized; /* how far the soil's resistances are mobilised (tip_force.h) */
    int varied;            /* density_variation > 0: the masses are in `mass` */
    MassBook mass;         /* kg, per cell and in the bucket (only when varied) */
} PileState;

const size_t model_state_size = sizeof(PileState);

static Grid grid_of(const double *v)
{
    Grid g = {v[VR_y_min], (v[VR_y_max] - v[VR_y_min]) / N_h, v[VR_z_floor]};
    return g;
}

/* The initial ground's lowest height over the grid (the heap only adds to it). */
static double lowest_ground(const double *v)
{
    const double grade = tan(v[VR_ground_slope]);
    const double end = grade > 0.0 ? v[VR_y_min] : v[VR_y_max];
    return v[VR_z_surface0] + grade * (end - v[VR_heap_center_y]);
}

static const char *check_parameters(const double *v)
{
    if (!(v[VR_n_cells] == N_h)) return "n_cells must equal the number of profile cells h[]";
    /* Bulk densities of what an excavator digs run from about 300 kg/m3 (peat) to 5000 kg/m3
     * (iron ore); beyond the bound a bucket load outweighs the arm it hangs from. */
    if (!(v[VR_density] >= 100.0 && v[VR_density] <= 10000.0))
        return "density must lie in [100, 10000] kg/m3 (a bulk density of soil or rock)";
    if (!(v[VR_density_variation] >= 0.0 && v[VR_density_variation] <= 0.5))
        return "density_variation must lie in [0, 0.5] (a relative deviation of the density)";
    if (!(v[VR_density_correlation_length] >= 0.05 && v[VR_density_correlation_length] <= 1e3))
        return "density_correlation_length must lie in [0.05, 1000] m";
    if (!(v[VR_density_seed] >= 0.0 && v[VR_density_seed] == floor(v[VR_density_seed])))
        return "density_seed must be an integer >= 0";
    if (!(v[VR_slice_width] > 0.0 && isfinite(v[VR_slice_width])))
        return "slice_width must be > 0 m";
    if (!(v[VR_bucket_width] > 0.0 && isfinite(v[VR_bucket_width])))
        return "bucket_width must be > 0 m";
    if (!(isfinite(v[VR_y_min]) && isfinite(v[VR_y_max]) && v[VR_y_max] > v[VR_y_min]))
        return "y_max must be greater than y_min (both finite)";
    if (!(isfinite(v[VR_z_surface0]) && isfinite(v[VR_z_floor])
          && v[VR_z_floor] < v[VR_z_surface0]))
        return "z_floor must lie below z_surface0 (both finite)";
    if (!(v[VR_heap_height] >= 0.0 && isfinite(v[VR_heap_height])))
        return "heap_height must be >= 0 m (0 = flat ground)";
    if (!isfinite(v[VR_heap_center_y])) return "heap_center_y must be finite";
    if (!(v[VR_heap_half_width] > 0.0 && isfinite(v[VR_heap_half_width])))
        return "heap_half_width must be > 0 m";
    if (!(v[VR_capacity] > 0.0 && isfinite(v[VR_capacity]))) return "capacity must be > 0 m3";
    if (!(v[VR_repose_angle] > 0.0 && v[VR_repose_angle] < 0.5 * PI))
        return "repose_angle must lie in (0, pi/2) rad";
    if (!(fabs(v[VR_ground_slope]) <= v[VR_repose_angle]))
        return "ground_slope must lie within +-repose_angle rad (a steeper ground would slump)";
    if (!(lowest_ground(v) > v[VR_z_floor]))
        return "the inclined ground must stay above z_floor over the whole grid";
    if (!(v[VR_mobilization_length] > 0.0 && isfinite(v[VR_mobilization_length])))
        return "mobilization_length must be > 0 m";
    return pile_check_resistance(v);
}

static const char *check_inputs(const double *v)
{
    if (!isfinite(v[VR_tip_y])) return "tip_y is not finite";
    if (!isfinite(v[VR_tip_z])) return "tip_z is not finite";
    if (!isfinite(v[VR_bucket_angle])) return "bucket_angle is not finite";
    if (!isfinite(v[VR_dump])) return "dump is not finite";
    return NULL;
}

/* Cuts along one substep into the bucket, never past its capacity; returns the cut volume. */
/* Share of the swept material that enters the bucket for a move (dy, dz) with the tip-to-pin line
 * at `angle`: all of it while the edge leads (rake to the move <= 90 deg), sin(rake) beyond, down
 * to none with the bucket's back leading (rake 180 deg), where it pushes the soil aside. */
static double fill_share(double angle, double dy, double dz)
{
    const double length = hypot(dy, dz);
    if (!(length > 0.0)) return 1.0;
    const double cos_rake = -(cos(angle) * dy + sin(angle) * dz) / length;
    return cos_rake >= 0.0 ? 1.0 : sqrt(fmax(0.0, 1.0 - cos_rake * cos_rake));
}

static double cut_into_bucket(const double *v, PileState *s, const Grid *g, double ya, double za,
                            double yb, double zb)
{
    const double capacity = v[VR_capacity], width = v[VR_slice_width];
    if (s->bucket_volume >= FULL_FRACTION * capacity) return 0.0;
    const double swept = profile_sweep_area(&s->profile, g, ya, za, yb, zb, 0.0);
    const double share = fill_share(v[VR_bucket_angle], yb - ya, zb - za);
    const double free_area = fmin((capacity - s->bucket_volume) / width, share * swept);
    double lift = 0.0;
    if (swept > free_area) {
        /* Raise the cut until it fits: the area falls monotonically with the lift and is zero
         * once every level is above the highest surface. */
        double top = s->profile.h[0], low = 0.0;
        for (int i = 1; i < N_h; ++i) top = fmax(top, s->profile.h[i]);
        for (int j = 0; j < s->profile.n_seg; ++j) top = fmax(top, s->profile.seg_h[j]);
        double high = top - fmax(fmin(za, zb), g->z_floor) + 1.0;
        for (int k = 0; k < CAPACITY_BISECTIONS; ++k) {
            const double mid = 0.5 * (low + high);
            if (profile_sweep_area(&s->profile, g, ya, za, yb, zb, mid) > free_area)
                low = mid;
            else
                high = mid;
        }
        lift = high;
    }
    double before[N_h];
    if (s->varied) memcpy(before, s->profile.h, sizeof before);
    const double volume = width * profile_sweep(&s->profile, g, ya, za, yb, zb, lift);
    if (s->varied) mass_book_cut(&s->mass, before, &s->profile, g);
    s->bucket_volume += volume;
    s->removed_volume += volume;
    return volume;
}

/* Share of the heaped capacity a bucket out of the ground holds with its opening tilted by
 * `tilt` (rad) from facing straight up (0: carried level, pi: upside down), for material of
 * repose angle rho of which `heap` of the capacity lies above the strike plane. A cross-section
 * (the bucket's width carries it unchanged):
 *  - the heap, a mound on the strike plane (length L) with flanks at repose: tilted by t < rho,
 *    its flanks stand at rho + t uphill and rho - t downhill against the plane, area
 *    L^2 sin(rho + t) sin(rho - t) / (2 sin 2 rho), so it keeps 1 - sin^2 t / sin^2 rho of the
 *    level heap's L^2 tan(rho) / 4, none from t = rho;
 *  - the struck part, a half-disc below the plane (the bucket's curved shell): it keeps all
 *    while its free surface may stand at rho, then, tilted by p = t - rho more, the segment
 *    below the chord from the lower lip at p to the plane: (a - sin a) / pi, a = pi - 2 p,
 *    none from t = rho + 90 deg. */
static double held_share(double tilt, double rho, double heap)
{
    const double s_t = sin(fmin(tilt, rho)), s_rho = sin(rho);
    const double heaped = tilt < rho ? 1.0 - (s_t * s_t) / (s_rho * s_rho) : 0.0;
    const double a = PI - 2.0 * fmin(fmax(tilt - rho, 0.0), 0.5 * PI);
    return heap * heaped + (1.0 - heap) * (a - sin(a)) / PI;
}

/* Whether the tip is a cell length (the profile's resolution) above the surface near it: while
 * it grazes the surface (entering, or cutting along it) the face in front holds the content. */
static int out_of_ground(const PileState *s, const Grid *g, double y, double z)
{
    const int k = profile_cell(g, y);
    return k < 0 || z > profile_top_near(&s->profile, k) + g->dy;
}

/* Spills onto the surface below the tip (y) what the bucket, out of the ground, cannot hold at
 * its tilt; returns whether it spilled. The bucket's opening faces the tip-to-pin line turned
 * clockwise, (sin phi, -cos phi): its tilt from up is acos(-cos phi). */
static int spill(const double *v, PileState *s, const Grid *g, double y)
{
    const double tilt = acos(fmin(1.0, fmax(-1.0, -cos(v[VR_bucket_angle]))));
    const double holds = v[VR_capacity] * held_share(tilt, v[VR_repose_angle], v[VR_heap_share]);
    if (!(s->bucket_volume > holds)) return 0;
    const double volume = s->bucket_volume - holds;
    int k = profile_cell(g, y);
    if (k < 0) k = y < g->y_min ? 0 : N_h - 1; /* beyond the grid: its end cell takes it */
    profile_release(&s->profile);
    if (s->varied) mass_book_spill(&s->mass, k, volume, s->bucket_volume);
    s->profile.h[k] += volume / (v[VR_slice_width] * g->dy);
    s->bucket_volume = holds;
    s->spilled_volume += volume;
    return 1;
}

/* Slumps the profile if anything changed since it last settled. */
static void settle(PileState *s, const Grid *g, double max_step, int held, int changed)
{
    if (!changed && held == s->held && s->settled) return;
    double before[N_h];
    if (s->varied) memcpy(before, s->profile.h, sizeof before);
    s->settled = profile_relax(&s->profile, max_step, held, RELAX_MAX_SWEEPS) < RELAX_MAX_SWEEPS;
    if (s->varied) mass_book_relax(&s->mass, before, &s->profile, g);
    s->held = held;
}

/* The cell whose boundaries the buried bucket holds closed, or -1. */
static int held_cell(const PileState *s, const Grid *g, double y, double z)
{
    const int k = profile_cell(g, y);
    return k >= 0 && z < profile_top_near(&s->profile, k) ? k : -1;
}

static void write_outputs(double *v, PileState *s, const Grid *g, double dy, double dz)
{
    const double density = v[VR_density], width = v[VR_slice_width];
    const double tip_y = v[VR_tip_y], tip_z = v[VR_tip_z];
    if (s->varied) {
        v[VR_bucket_mass] = s->mass.bucket;
        v[VR_dumped_mass] = s->mass.dumped;
        v[VR_spilled_mass] = s->mass.spilled;
        v[VR_pile_mass] = mass_book_pile(&s->mass);
    } else {
        v[VR_bucket_mass] = density * s->bucket_volume;
        v[VR_dumped_mass] = density * s->dumped_volume;
        v[VR_spilled_mass] = density * s->spilled_volume;
        v[VR_pile_mass] = density * width * profile_area(&s->profile, g);
    }
    v[VR_removed_volume] = s->removed_volume;
    v[VR_surface_z_at_tip] = profile_surface_at(&s->profile, g, tip_y);
    for (int i = 0; i < N_h; ++i) v[VR_h_1 + i] = s->profile.h[i];
    const int full = s->bucket_volume >= FULL_FRACTION * v[VR_capacity];
    const TipForce f = tip_force(v, &s->profile, g, tip_y, tip_z, dy, dz, v[VR_bucket_angle],
                                 full, &s->mobilized);
    v[VR_cut_depth] = f.depth;
    v[VR_F_y] = f.F_y;
    v[VR_F_z] = f.F_z;
}

int model_initialize(double *v, void *state, const char **error)
{
    PileState *s = state;
    const char *message = check_parameters(v);
    if (message == NULL) message = check_inputs(v);
    if (message != NULL) {
        *error = message;
        return 1;
    }
    const Grid g = grid_of(v);
    profile_init(&s->profile, &g, v[VR_z_surface0], tan(v[VR_ground_slope]), v[VR_heap_height],
                 v[VR_heap_center_y], v[VR_heap_half_width]);
    /* A heap steeper than the repose angle settles before the first step. */
    s->settled = 0;
    s->held = -1;
    s->varied = 0; /* the initial heap settles before the field is laid on it */
    settle(s, &g, g.dy * tan(v[VR_repose_angle]), -1, 1);
    s->varied = v[VR_density_variation] > 0.0;
    if (s->varied)
        mass_book_init(&s->mass, &s->profile, &g, v[VR_density], v[VR_density_variation],
                       v[VR_density_correlation_length],
                       (unsigned long long)v[VR_density_seed], v[VR_slice_width]);
    s->bucket_volume = s->dumped_volume = s->removed_volume = s->spilled_volume = 0.0;
    s->tip_y = v[VR_tip_y];
    s->tip_z = v[VR_tip_z];
    s->mobilized.side[0] = s->mobilized.side[1] = s->mobilized.normal = 0.0;
    write_outputs(v, s, &g, 0.0, 0.0);
    return 0;
}

int model_do_step(double *v, void *state, double t, double h, const char **error)
{
    PileState *s = state;
    (void)t;
    const char *message = check_inputs(v);
    if (message == NULL && !(h >= 0.0 && isfinite(h)))
        message = "communication step size must be finite and >= 0 s";
    if (message != NULL) {
        *error = message;
        return 1;
    }
    const Grid g = grid_of(v);
    const double max_step = g.dy * tan(v[VR_repose_angle]);
    const double y0 = s->tip_y, z0 = s->tip_z, y1 = v[VR_tip_y], z1 = v[VR_tip_z];
    const double travel = fmax(fabs(y1 - y0), fabs(z1 - z0));
    const double pieces = ceil(travel / (SUBSTEP_CELL_FRACTION * g.dy));
    const int n = pieces < 1.0 ? 1 : pieces > MAX_SUBSTEPS ? MAX_SUBSTEPS : (int)pieces;
    double ya = y0, za = z0;
    for (int k = 1; k <= n; ++k) {
        const double f = (double)k / n;
        const double yb = k == n ? y1 : y0 + f * (y1 - y0), zb = k == n ? z1 : z0 + f * (z1 - z0);
        const double cut = cut_into_bucket(v, s, &g, ya, za, yb, zb);
        settle(s, &g, max_step, held_cell(s, &g, yb, zb), cut > 0.0);
        ya = yb;
        za = zb;
    }
    if (out_of_ground(s, &g, y1, z1) && spill(v, s, &g, y1)) settle(s, &g, max_step, -1, 1);
    if (v[VR_dump] > 0.5) {
        s->dumped_volume += s->bucket_volume;
        s->bucket_volume = 0.0;
        s->mass.dumped += s->mass.bucket;
        s->mass.bucket = 0.0;
    }
    s->tip_y = y1;
    s->tip_z = z1;
    write_outputs(v, s, &g, y1 - y0, z1 - z0);
    return 0;
}

/* A state restored from bytes must not index outside the profile or carry a non-finite value. */
int model_check_state(const double *v, const void *state, const char **error)
{
    const PileState *s = state;
    const Profile *p = &s->profile;
    (void)v;
    int ok = s->held >= -1 && s->held < N_h && p->active >= -1 && p->active < N_h
             && p->n_seg >= 0 && p->n_seg <= PROFILE_MAX_SEGMENTS;
    for (int i = 0; ok && i < N_h; ++i) ok = isfinite(p->h[i]);
    for (int j = 0; ok && j <= PROFILE_MAX_SEGMENTS; ++j) ok = isfinite(p->seg_y[j]);
    for (int j = 0; ok && j < PROFILE_MAX_SEGMENTS; ++j) ok = isfinite(p->seg_h[j]);
    ok = ok && isfinite(s->bucket_volume) && isfinite(s->dumped_volume)
         && isfinite(s->removed_volume) && isfinite(s->spilled_volume) && isfinite(s->tip_y)
         && isfinite(s->tip_z) && (s->varied == 0 || s->varied == 1);
    for (int i = 0; ok && s->varied && i < N_h; ++i) ok = isfinite(s->mass.cell[i]);
    ok = ok && isfinite(s->mass.bucket) && isfinite(s->mass.dumped) && isfinite(s->mass.spilled);
    for (int i = 0; ok && i < 2; ++i) ok = fabs(s->mobilized.side[i]) <= 1.0;
    ok = ok && fabs(s->mobilized.normal) <= 1.0;
    if (!ok) *error = "the pile state is out of range (profile indices or non-finite values)";
    return ok ? 0 : 1;
}
