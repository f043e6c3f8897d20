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
 * The width term is not proportional to B (edge effects), so the law is evaluated for the whole
 * bucket edge (blade_width) and the slice of width `width` takes its share width/blade_width.
 * alpha is clamped to [20, 90] deg, the range of the cutting angles of buckets and blades the
 * fit comes from; a bucket curled past 90 deg is treated as 90 deg. The density does not enter:
 * C measures the soil's strength, density included.
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

const char *pile_check_resistance(const double *v)
{
    if (!(v[VR_blows] >= 1.0 && v[VR_blows] <= 35.0))
        return "blows must lie in [1, 35] (DorNII blows, soil categories I-IV)";
    if (!(v[VR_blade_width] > 0.0 && isfinite(v[VR_blade_width])))
        return "blade_width must be > 0 m";
    if (!(v[VR_width] <= v[VR_blade_width])) return "width must not exceed blade_width";
    if (!(v[VR_cutting_factor] > 0.0 && v[VR_cutting_factor] <= 3.0))
        return "cutting_factor must lie in (0, 3]";
    return NULL;
}

double pile_draft(const double *v, double rake, double depth)
{
    const double blade = v[VR_blade_width];
    const double alpha = fmin(ALPHA_MAX_DEG, fmax(ALPHA_MIN_DEG, rake * 180.0 / PI));
    const double full = KGF * v[VR_blows] * pow(100.0 * depth, DEPTH_EXPONENT)
                        * (1.0 + WIDTH_COEFFICIENT * blade) * (1.0 + ANGLE_COEFFICIENT * alpha)
                        * v[VR_cutting_factor];
    return full * v[VR_width] / blade;
}
