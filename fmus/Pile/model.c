/*
 * Pile with the McKyes wedge resistance. The mechanics (cutting, capacity, slumping, dumping,
 * the surface frame of the force) are shared with every pile model: fmus/shared/pile/. This file
 * is the resistance law only, on the bucket's cutting edge of width bucket_width:
 *
 * Cutting: the fundamental earthmoving equation with McKyes' N-factors (soil_force.h): draft H
 *   and normal force N of the wedge at rake beta in [10, 90] deg.
 * Penetration: the edge, edge_thickness B thick, is a strip footing pushed into the soil at depth
 *   d (Terzaghi's bearing capacity with the Prandtl-Reissner factors and Vesic's N_gamma; Das,
 *   "Principles of Foundation Engineering", ch. 3):
 *     q_ult = c N_c + (gamma d + q) N_q + gamma B N_gamma / 2,
 *     N_q = e^(pi tan phi) tan^2(45 deg + phi/2), N_c = (N_q - 1) cot phi (pi + 2 at phi = 0),
 *     N_gamma = 2 (N_q + 1) tan phi;
 *   R = q_ult B w min(1, d/B): the bearing builds up over the first edge thickness of contact,
 *   so the force is continuous as the edge touches the soil.
 * Full bucket: what the edge cuts heaps up in front of it (a surcharge mound), taken as the
 *   weight of a layer as thick as the cut on the wedge: q + gamma d.
 * Lift-out: the bucket's outer face slides up along the soil it leaves, held by the soil's
 *   lateral pressure at rest (Jaky: K0 = 1 - sin phi) through the soil-tool friction and the
 *   adhesion: R = w (c_a d + (K0 gamma d^2 / 2 + K0 q d) tan delta). The material inside the
 *   bucket rises with it (payload), so nothing is sheared through.
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
    if (!(v[VR_adhesion] >= 0.0 && v[VR_adhesion] <= v[VR_cohesion]))
        return "adhesion must lie in [0, cohesion] Pa";
    if (!(v[VR_surcharge] >= 0.0 && isfinite(v[VR_surcharge])))
        return "surcharge must be >= 0 Pa";
    if (!(v[VR_gravity] > 0.0 && isfinite(v[VR_gravity]))) return "gravity must be > 0 m/s2";
    if (!(v[VR_edge_thickness] > 0.0 && v[VR_edge_thickness] <= 0.5))
        return "edge_thickness must lie in (0, 0.5] m";
    return NULL;
}

void pile_cutting_force(const double *v, double rake, double depth, int full, double *draft,
                        double *normal)
{
    SoilStrength soil = soil_of(v);
    if (full) soil.surcharge += soil.unit_weight * depth;
    const SoilBladeForce f = soil_blade_force(&soil, rake, depth);
    *draft = v[VR_bucket_width] * f.draft;
    *normal = v[VR_bucket_width] * f.normal;
}

double pile_penetration_resistance(const double *v, double depth)
{
    const double phi = v[VR_friction_angle], gamma = v[VR_density] * v[VR_gravity];
    const double b = v[VR_edge_thickness];
    const double n_q = exp(PI * tan(phi)) * pow(tan(0.25 * PI + 0.5 * phi), 2.0);
    const double n_c = phi > 0.0 ? (n_q - 1.0) / tan(phi) : PI + 2.0;
    const double n_gamma = 2.0 * (n_q + 1.0) * tan(phi);
    const double q_ult = v[VR_cohesion] * n_c + (gamma * depth + v[VR_surcharge]) * n_q
                         + 0.5 * gamma * b * n_gamma;
    return q_ult * b * v[VR_bucket_width] * fmin(1.0, depth / b);
}

double pile_lift_resistance(const double *v, double depth)
{
    const double k0 = 1.0 - sin(v[VR_friction_angle]), gamma = v[VR_density] * v[VR_gravity];
    return v[VR_bucket_width]
           * (v[VR_adhesion] * depth
              + (0.5 * k0 * gamma * depth * depth + k0 * v[VR_surcharge] * depth)
                    * tan(v[VR_tool_friction_angle]));
}
