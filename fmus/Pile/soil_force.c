/* McKyes wedge model of the soil force on a blade; formulas and references in soil_force.h. */
#include <math.h>
#include <stddef.h>

#include "soil_force.h"

#define PI 3.14159265358979323846
/* Failure angles searched: (RHO_MARGIN, pi - beta - delta - phi - RHO_MARGIN); P grows without
 * bound at both ends (cot rho -> inf; the denominator D -> 0+). */
#define RHO_MARGIN 0.008726646259971648 /* 0.5 deg */
#define RHO_GRID 16                     /* coarse scan that brackets the minimum */
#define RHO_GOLDEN_ITERATIONS 30        /* bracket 0.2 rad -> 0.2 * 0.618^30 ~ 1e-7 rad */

double soil_clamped_rake(const SoilStrength *soil, double beta)
{
    const double high = PI - soil->tool_friction_angle - soil->friction_angle - SOIL_RAKE_MIN;
    if (beta > high) beta = high;
    if (beta < SOIL_RAKE_MIN) beta = SOIL_RAKE_MIN;
    return beta;
}

/* The rake-dependent part of the wedge model, computed once per call. */
typedef struct {
    double cot_beta, cos_bd, sin_bd; /* cot(beta), cos(beta + delta), sin(beta + delta) */
    double cos_phi, sin_phi;
} Wedge;

static Wedge wedge_of(const SoilStrength *soil, double beta)
{
    const double bd = beta + soil->tool_friction_angle;
    Wedge w = {cos(beta) / sin(beta), cos(bd), sin(bd), cos(soil->friction_angle),
               sin(soil->friction_angle)};
    return w;
}

/* Blade face force P per unit width (N/m) at failure angle rho (rad); one sin/cos pair. */
static double blade_force(const SoilStrength *soil, const Wedge *w, double rho, double depth)
{
    const double s = sin(rho), c = cos(rho);
    const double cot_rho = c / s;
    const double cot_rho_phi = (c * w->cos_phi - s * w->sin_phi) / (s * w->cos_phi + c * w->sin_phi);
    const double denominator = w->cos_bd + w->sin_bd * cot_rho_phi;
    const double n_gamma = (w->cot_beta + cot_rho) / (2.0 * denominator);
    const double n_c = (1.0 + cot_rho * cot_rho_phi) / denominator;
    const double n_ca = (1.0 - w->cot_beta * cot_rho_phi) / denominator;
    const double n_q = (w->cot_beta + cot_rho) / denominator;
    return soil->unit_weight * depth * depth * n_gamma
           + depth * (soil->cohesion * n_c + soil->adhesion * n_ca + soil->surcharge * n_q);
}

/* Failure angle where the blade force is least: scan a fixed grid, then golden-section search
 * between the grid neighbours of the best point (deterministic, no tolerance-driven loop). */
static double weakest_failure_angle(const SoilStrength *soil, const Wedge *w, double beta,
                                    double depth)
{
    const double low = RHO_MARGIN;
    const double high = PI - beta - soil->tool_friction_angle - soil->friction_angle - RHO_MARGIN;
    const double step = (high - low) / (RHO_GRID - 1);
    int best = 0;
    double best_force = blade_force(soil, w, low, depth);
    for (int j = 1; j < RHO_GRID; ++j) {
        const double force = blade_force(soil, w, low + j * step, depth);
        if (force < best_force) {
            best_force = force;
            best = j;
        }
    }
    double a = low + (best > 0 ? best - 1 : 0) * step;
    double b = low + (best < RHO_GRID - 1 ? best + 1 : RHO_GRID - 1) * step;
    const double ratio = 0.6180339887498949; /* (sqrt(5) - 1) / 2 */
    double x1 = b - ratio * (b - a), x2 = a + ratio * (b - a);
    double f1 = blade_force(soil, w, x1, depth), f2 = blade_force(soil, w, x2, depth);
    for (int k = 0; k < RHO_GOLDEN_ITERATIONS; ++k) {
        if (f1 <= f2) {
            b = x2;
            x2 = x1;
            f2 = f1;
            x1 = b - ratio * (b - a);
            f1 = blade_force(soil, w, x1, depth);
        } else {
            a = x1;
            x1 = x2;
            f1 = f2;
            x2 = a + ratio * (b - a);
            f2 = blade_force(soil, w, x2, depth);
        }
    }
    return 0.5 * (a + b);
}

SoilBladeForce soil_blade_force(const SoilStrength *soil, double beta, double depth)
{
    SoilBladeForce f = {0.0, 0.0, 0.0};
    if (!(depth > 0.0)) return f;
    beta = soil_clamped_rake(soil, beta);
    const Wedge w = wedge_of(soil, beta);
    f.rho = weakest_failure_angle(soil, &w, beta, depth);
    const double blade = blade_force(soil, &w, f.rho, depth);
    const double draft = blade * w.sin_bd + soil->adhesion * depth * w.cot_beta;
    /* A resistance never drives the bucket along its travel. */
    f.draft = draft > 0.0 ? draft : 0.0;
    f.normal = soil->adhesion * depth - blade * w.cos_bd;
    return f;
}

double soil_draft(const SoilStrength *soil, double beta, double depth, double *rho)
{
    const SoilBladeForce f = soil_blade_force(soil, beta, depth);
    if (rho != NULL) *rho = f.rho;
    return f.draft;
}
