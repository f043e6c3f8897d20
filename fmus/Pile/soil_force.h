/*
 * Soil resistance on a blade: the fundamental earthmoving equation (Reece 1964) with the
 * N-factors of the McKyes two-dimensional wedge model (McKyes 1985, "Soil Cutting and Tillage",
 * ch. 4; McKyes & Ali 1977). All quantities SI: m, rad, N, Pa, N/m3.
 *
 *   P = w (gamma d^2 N_gamma + c d N_c + c_a d N_ca + q d N_q)          force on the blade face
 *
 *   with D(rho) = cos(beta + delta) + sin(beta + delta) cot(rho + phi):
 *   N_gamma = (cot beta + cot rho) / (2 D)
 *   N_c     = (1 + cot rho cot(rho + phi)) / D
 *   N_ca    = (1 - cot beta cot(rho + phi)) / D
 *   N_q     = (cot beta + cot rho) / D
 *
 * beta: rake angle of the blade from the direction of travel (90 deg = vertical blade),
 * rho: inclination of the wedge's failure plane, chosen where P is least (the passive failure
 * happens on the weakest plane); phi: internal friction angle; delta: soil-tool friction angle;
 * c: cohesion; c_a: adhesion; q: surcharge; gamma: unit weight (density * g); d: depth; w: width.
 * P acts at delta from the blade normal; the adhesion force c_a d w / sin(beta) acts along the
 * blade. The draft (force component against the travel) is
 *
 *   H = P sin(beta + delta) + c_a d w cot beta,
 *
 * and the force normal to the travel, positive away from the soil (the same vector sum: P
 * pushes the face at delta from its normal, the adhesion pulls it up along the face),
 *
 *   N = c_a d w - P cos(beta + delta)     (< 0 for sharp rakes: the cut pulls the blade in).
 *
 * Check: for a smooth vertical blade (beta = 90 deg, delta = 0, c_a = 0) the minimum lies at
 * rho = 45 deg - phi/2 and H = w (gamma d^2 Kp / 2 + 2 c d sqrt(Kp) + q d Kp), Kp =
 * (1 + sin phi) / (1 - sin phi): Rankine's passive earth pressure.
 */
#ifndef PILE_SOIL_FORCE_H
#define PILE_SOIL_FORCE_H

typedef struct {
    double unit_weight;         /* gamma = density * g, N/m3 */
    double cohesion;            /* c, Pa */
    double adhesion;            /* c_a, Pa */
    double surcharge;           /* q, Pa */
    double friction_angle;      /* phi, rad, in [0, 60 deg) */
    double tool_friction_angle; /* delta, rad, in [0, phi] */
} SoilStrength;

/* Rake angles are clamped to [SOIL_RAKE_MIN, pi - delta - phi - SOIL_RAKE_MIN]: outside it the
 * wedge model has no failure plane (the blade slices along itself or pushes with its back). */
#define SOIL_RAKE_MIN 0.17453292519943295 /* 10 deg */

/* The rake angle actually used for `beta` (rad), after clamping. */
double soil_clamped_rake(const SoilStrength *soil, double beta);

typedef struct {
    double draft;  /* H per unit width, N/m, >= 0 */
    double normal; /* N per unit width, N/m, > 0 pushes the blade out of the soil */
    double rho;    /* failure angle used, rad */
} SoilBladeForce;

/* Draft and normal force per unit width for a blade at rake `beta` (rad) and depth `depth`
 * (m) >= 0, with rho minimised (all 0 at depth 0). */
SoilBladeForce soil_blade_force(const SoilStrength *soil, double beta, double depth);

/* Draft H per unit width (N/m) for a blade at rake `beta` (rad) and depth `depth` (m) >= 0,
 * with rho minimised; writes the failure angle used to *rho if rho is not NULL. */
double soil_draft(const SoilStrength *soil, double beta, double depth, double *rho);

#endif
