/*
 * Pile with the McKyes wedge resistance. The mechanics (cutting, capacity, slumping, dumping,
 * outputs) are shared with every pile model: fmus/shared/pile/pile.c. This file is the
 * resistance law only: the fundamental earthmoving equation with McKyes' N-factors
 * (soil_force.h), on the slice of width `width`.
 */
#include <math.h>
#include <stddef.h>

#include "pile_resistance.h"
#include "soil_force.h"

#define PI 3.14159265358979323846

static SoilStrength soil_of(const double *v)
{
    SoilStrength s = {v[VR_density] * v[VR_gravity], v[VR_cohesion], v[VR_adhesion],
                      v[VR_surcharge], v[VR_friction_angle], v[VR_tool_friction_angle]};
    return s;
}

const char *pile_check_resistance(const double *v)
{
    if (!(v[VR_friction_angle] >= 0.0 && v[VR_friction_angle] < PI / 3.0))
        return "friction_angle must lie in [0, pi/3) rad";
    if (!(v[VR_tool_friction_angle] >= 0.0 && v[VR_tool_friction_angle] <= v[VR_friction_angle]))
        return "tool_friction_angle must lie in [0, friction_angle] rad";
    if (!(v[VR_cohesion] >= 0.0 && isfinite(v[VR_cohesion]))) return "cohesion must be >= 0 Pa";
    if (!(v[VR_adhesion] >= 0.0 && isfinite(v[VR_adhesion]))) return "adhesion must be >= 0 Pa";
    if (!(v[VR_surcharge] >= 0.0 && isfinite(v[VR_surcharge])))
        return "surcharge must be >= 0 Pa";
    if (!(v[VR_gravity] > 0.0 && isfinite(v[VR_gravity]))) return "gravity must be > 0 m/s2";
    return NULL;
}

double pile_draft(const double *v, double rake, double depth)
{
    const SoilStrength soil = soil_of(v);
    return v[VR_width] * soil_draft(&soil, rake, depth, NULL);
}
