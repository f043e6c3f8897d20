/*
 * The soil force on the bucket, evaluated in the frame of the soil surface (the frame in which
 * the earthmoving equation holds: travel along the surface, depth normal to it, rake to it).
 *
 * Surface frames. On each side of the tip (s = +1: towards +y, s = -1: towards -y) the surface
 * is a least-squares line through SLOPE_POINTS points one cell apart, starting LOOK_AHEAD_CELLS
 * from the tip (the cell under the tip is already cut to the tip). Its inclination theta_s is
 * clamped to +-repose_angle (a steeper stretch is a face the buried bucket holds). With
 *   t_s = s (cos theta_s, sin theta_s)   travel along that surface, into its soil
 *   n_s = (-sin theta_s, cos theta_s)    its normal, out of the soil
 *   d_s = (line_s(y) - z) cos theta_s    the tip's depth below the line, normal to it, >= 0.
 * n_0 is the normal of the ground around the tip, inclined at (theta_+1 + theta_-1) / 2: the
 * cells right at the tip are left out as for the lines (at a trench's front face their slope is
 * the face, and a horizontal cut into it would read as a penetration).
 *
 * Three resistances, each its own law (pile_resistance.h):
 *   cutting      on side s, the law's draft H_s against t_s and its normal force N_s along n_s,
 *                at depth d_s and the rake between the tip-to-pin line and -t_s. The rake is kept
 *                in [SOIL_CUT_RAKE_MIN, 90 deg]: the wedge model holds for faces up to normal to
 *                the surface (McKyes 1985, ch. 4); a face leaning further forward, or the
 *                bucket's back leading, traps a dead wedge of soil that cuts as a face normal to
 *                the surface (the "false nose" of blunt tools).
 *   penetration  pushing into the soil along -n_0: pile_penetration_resistance along +n_0;
 *   lift-out     pulling out along +n_0 with the tip below a side's line:
 *                pile_lift_resistance along -n_0, at the deeper side's depth (the wall the
 *                bucket slides along).
 * Mobilisation. Soil resists by deforming: passive resistance is fully mobilised only after the
 * tool has moved into it by a mobilisation length delta (about 1-5 % of the wall height for
 * passive earth pressure; Clough & Duncan 1991). Each resistance carries a state mu that the
 * tip's move (dy, dz) advances: mu_s += (dy, dz) . t_s / delta, clamped to [0, 1] (0 when side s
 * is out of contact); mu_n -= (dy, dz) . n_0 / delta, clamped to [-1, 1] (> 0: penetration,
 * < 0: lift-out), and decays as exp(-travel along the surface / edge_thickness): moving along
 * the surface, the edge leaves the soil it pressed on behind. The force is
 *   F = sum_s mu_s (-H_s t_s + N_s n_s) + mu_n (mu_n > 0 ? R_pen : R_lift) n_0.
 * This is an elastic-perfectly plastic element per resistance (a spring of stiffness R/delta in
 * series with a slider at R): the force is a function of the tip's path up to the end of the
 * step, not of a velocity, so there is no rate to difference one step late and no switch on the
 * sign of a velocity; reversing the tip unloads the soil along the spring instead of flipping
 * the whole force (which made the explicitly coupled arm chatter). The soil is passive: it gives
 * back at most the elastic energy mu^2 R delta / 2 it stored.
 */
#include <math.h>

#include "pile_resistance.h"
#include "tip_force.h"

#define PI 3.14159265358979323846
#define LOOK_AHEAD_CELLS 1.5 /* where the undisturbed surface starts beside the tip */
#define SLOPE_POINTS 5       /* points of each side's surface line, one cell apart */

typedef struct {
    double theta; /* rad, inclination, clamped to +-repose */
    double depth; /* m, normal to the line, >= 0 */
} SurfaceLine;

static double clamp(double x, double low, double high)
{
    return x < low ? low : (x > high ? high : x);
}

/* Least-squares line through the surface on side s of y, clamped to the repose angle; the tip's
 * depth below it at (y, z). */
static SurfaceLine side_line(const Profile *p, const Grid *g, double y, double z, double s,
                             double repose)
{
    double sum_x = 0.0, sum_z = 0.0, sum_xx = 0.0, sum_xz = 0.0;
    for (int k = 0; k < SLOPE_POINTS; ++k) {
        const double x = s * (LOOK_AHEAD_CELLS + k) * g->dy; /* from the tip */
        const double h = profile_surface_at(p, g, y + x);
        sum_x += x;
        sum_z += h;
        sum_xx += x * x;
        sum_xz += x * h;
    }
    const double n = SLOPE_POINTS;
    const double slope = (n * sum_xz - sum_x * sum_z) / (n * sum_xx - sum_x * sum_x);
    SurfaceLine line;
    line.theta = clamp(atan(slope), -repose, repose);
    /* The line through the points' centroid with the clamped slope, evaluated at the tip. */
    const double at_tip = sum_z / n - tan(line.theta) * sum_x / n;
    line.depth = fmax(0.0, (at_tip - z) * cos(line.theta));
    return line;
}

TipForce tip_force(const double *v, const Profile *p, const Grid *g, double y, double z,
                   double dy, double dz, double bucket_angle, int full, Mobilization *m)
{
    TipForce f = {0.0, 0.0, 0.0};
    const double repose = v[VR_repose_angle], delta = v[VR_mobilization_length];
    const double line_y = cos(bucket_angle), line_z = sin(bucket_angle);
    double wall = 0.0, fy = 0.0, fz = 0.0, theta0 = 0.0;
    for (int i = 0; i < 2; ++i) {
        const double s = i == 0 ? 1.0 : -1.0;
        const SurfaceLine line = side_line(p, g, y, z, s, repose);
        const double c = cos(line.theta), sn = sin(line.theta);
        const double ty = s * c, tz = s * sn, ny = -sn, nz = c;
        wall = fmax(wall, line.depth);
        theta0 += 0.5 * line.theta;
        if (!(line.depth > 0.0)) {
            m->side[i] = 0.0; /* out of contact: the soil on this side is unloaded */
            continue;
        }
        m->side[i] = clamp(m->side[i] + (dy * ty + dz * tz) / delta, 0.0, 1.0);
        if (m->side[i] == 0.0) continue;
        const double cos_rake = clamp(-(line_y * ty + line_z * tz), -1.0, 1.0);
        const double rake = clamp(acos(cos_rake), SOIL_CUT_RAKE_MIN, 0.5 * PI);
        double draft, normal;
        pile_cutting_force(v, rake, line.depth, full, &draft, &normal);
        fy += m->side[i] * (-draft * ty + normal * ny);
        fz += m->side[i] * (-draft * tz + normal * nz);
    }
    const double ny0 = -sin(theta0), nz0 = cos(theta0);
    const double under = fmax(0.0, (profile_surface_at(p, g, y) - z) * cos(theta0));
    f.depth = fmax(under, wall);
    if (!(f.depth > 0.0)) {
        m->normal = 0.0;
    } else {
        m->normal = clamp(m->normal - (dy * ny0 + dz * nz0) / delta, -1.0, 1.0);
        /* Travel along the surface leaves the soil the edge pressed on (or slid along): it
         * unloads over one edge thickness of travel. */
        m->normal *= exp(-fabs(dy * nz0 - dz * ny0) / v[VR_edge_thickness]);
        double resistance = 0.0;
        if (m->normal > 0.0) resistance = pile_penetration_resistance(v, f.depth);
        else if (m->normal < 0.0 && wall > 0.0) resistance = pile_lift_resistance(v, wall);
        fy += m->normal * resistance * ny0;
        fz += m->normal * resistance * nz0;
    }
    f.F_y = fy;
    f.F_z = fz;
    return f;
}
