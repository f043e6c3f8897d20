/*
 * Pile with Zelenin's empirical cutting resistance. The mechanics (cutting, capacity, slumping,
 * dumping, outputs) are the Pile's, shared in fmus/shared/pile/pile.c; this file is the law only.
 *
 * Zelenin's formula for the tangential cutting resistance of a straight blade (A. N. Zelenin,
 * "Fundamentals of Soil Cutting", 1959; Zelenin, Balovnev & Kerov, "Machines for Moving the
 * Earth", 1985; reviewed by Blouin, Hemami & Lipsett, J. Aerospace Eng. 14(3), 2001):
 *
 *   P = C h^1.35 (1 + 2.6 B) (1 + 0.0075 alpha) z        [kgf]
 *
 * C: soil strength as blows of the DorNII impact penetrometer (1-35), h: cut depth in cm,
 * B: blade width in m, alpha: cutting angle in degrees (blade face to the direction of travel),
 * z: correction for wear and cutting mode (1 = sharp blade, blocked cutting). The fit is
 * dimensional: the units above are part of it. In SI, with d the depth in m:
 *
 *   H = g0 C (100 d)^1.35 (1 + 2.6 B) (1 + 0.0075 alpha_deg) z   [N],  g0 = 9.80665 N/kgf.
 *
 * The law is evaluated for the whole bucket edge (bucket_width B): the force acts on the bucket,
 * not on the material slice whose mass the pile tracks. alpha is clamped to [20, 90] deg, the
 * range of the cutting angles of buckets and blades the fit comes from (the shared mechanics
 * already cap the rake at 90 deg). The density does not enter: C measures the soil's strength,
 * density included.
 *
 * Normal force: N = normal_ratio * H (Balovnev's ratio of the normal to the tangential cutting
 * force, 0.1-0.45 from a sharp to a worn edge).
 * Penetration: the DorNII tester that defines C drives a 1 cm^2 rod 10 cm with C blows of a
 *   2.5 kg weight falling 0.4 m, so C measures a mean penetration pressure
 *   q_p = C * 2.5 kg * g0 * 0.4 m / (1e-4 m^2 * 0.1 m) = 0.981 C MPa; the edge (edge_thickness
 *   b) meets R = q_p b B min(1, d/b), built up over its first thickness of contact.
 * Lift-out: Zelenin's fits give no law for an edge pulled out of the soil; the material above
 *   the edge rises in the bucket (payload), so this law takes no resistance (R = 0).
 */
#include <math.h>
#include <stddef.h>

#include "pile_resistance.h"

#define PI 3.14159265358979323846
#define KGF 9.80665                /* N per kgf */
#define DEPTH_EXPONENT 1.35
#define WIDTH_COEFFICIENT 2.6      /* 1/m */
#define ANGLE_COEFFICIENT 0.0075   /* 1/deg */
#define ALPHA_MIN_DEG 20.0
#define ALPHA_MAX_DEG 90.0
/* Pa per DorNII blow: 2.5 kg * 9.80665 m/s2 * 0.4 m / (1e-4 m2 * 0.1 m) */
#define DORNII_PRESSURE_PER_BLOW 980665.0

const char *pile_check_resistance(const double *v)
{
    if (!(v[VR_blows] >= 1.0 && v[VR_blows] <= 35.0))
        return "blows must lie in [1, 35] (DorNII blows, soil categories I-IV)";
    if (!(v[VR_edge_thickness] > 0.0 && v[VR_edge_thickness] <= 0.5))
        return "edge_thickness must lie in (0, 0.5] m";
    if (!(fabs(v[VR_normal_ratio]) <= 1.0)) return "normal_ratio must lie in [-1, 1]";
    if (!(v[VR_cutting_factor] > 0.0 && v[VR_cutting_factor] <= 3.0))
        return "cutting_factor must lie in (0, 3]";
    return NULL;
}

void pile_cutting_force(const double *v, double rake, double depth, int full, double *draft,
                        double *normal)
{
    (void)full; /* blocked cutting (z = 1) already describes a blade pushing its own spoil */
    const double blade = v[VR_bucket_width];
    const double alpha = fmin(ALPHA_MAX_DEG, fmax(ALPHA_MIN_DEG, rake * 180.0 / PI));
    *draft = KGF * v[VR_blows] * pow(100.0 * depth, DEPTH_EXPONENT)
             * (1.0 + WIDTH_COEFFICIENT * blade) * (1.0 + ANGLE_COEFFICIENT * alpha)
             * v[VR_cutting_factor];
    *normal = v[VR_normal_ratio] * *draft;
}

double pile_penetration_resistance(const double *v, double depth)
{
    const double b = v[VR_edge_thickness];
    return DORNII_PRESSURE_PER_BLOW * v[VR_blows] * b * v[VR_bucket_width] * fmin(1.0, depth / b);
}

double pile_lift_resistance(const double *v, double depth)
{
    (void)v;
    (void)depth;
    return 0.0;
}
