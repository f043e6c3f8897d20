/*
 * What the cylinder's physics (model.c) and its integrators (integration.c) share: the state,
 * the stage powers, the parameters and inputs of one communication step.
 */
#ifndef EXCOSIM_CYLINDER_H
#define EXCOSIM_CYLINDER_H

/* The states, in this order: stroke (m), velocity (m/s), chamber pressures or voids (Pa). */
typedef struct {
    double x, v, psi_A, psi_B;
} Y;

#define N_STATES 4

/* Stage powers (W) and their integrals (J). */
enum {
    W_SUPPLY, W_TANK, W_THROTTLING, W_RELIEF, W_FRICTION, W_LOAD, W_END_STOP, W_OIL,
    W_COMPENSATOR, /* of W_THROTTLING: the compensator's part */
    N_POWER
};

/* Parameters and inputs gathered once per communication step. */
typedef struct {
    double A_A, A_B, stroke, V_dead_A, V_dead_B, beta, p_S, p_T, p_relief, k_relief;
    double k_makeup, p_makeup; /* make-up opens below p_makeup = p_T - dp_makeup */
    double dp_laminar, inv_dp_rated, inv_sqrt_rated_laminar, M, inv_mass, F_c, inv_v_c, b;
    double q_open; /* q_rated*a: flow of one edge at dp_rated at the current opening, m^3/s */
    double q_out;  /* meter_out_ratio*q_open: the same of a meter-out edge */
    double q_regen; /* regeneration_ratio*q_open while a > 0 (B->A passage), else 0 */
    double p_LS;   /* compensator setting, Pa (0: none) */
    double a, F_ext;
} P;

/* model.c: dy = f(y) with the stage powers w (W), and J = df/dy (4 x 4, row-major, the states'
 * order above) of the same piecewise law, one-sided where it switches, given dy = f(y). */
void cylinder_derivatives(const P *p, const Y *y, Y *dy, double *w);
void cylinder_jacobian(const P *p, const Y *y, const Y *dy, double *J);

/* integration.c: advance y by h (s), adding the powers' integrals to energy (J). */
void cylinder_rk4(const P *p, Y *y, double *energy, double h, long substeps);
/* Adaptive RODAS3 with the error scales scale[4] (the states' units) from the suggested first
 * substep *h_next (0: none yet), which it updates for the next step (integration.c); the accepted and rejected substeps are added
 * to *accepted and *rejected. NULL on success, else a message. */
const char *cylinder_rodas3(const P *p, Y *y, double *energy, double h, const double *scale,
                            double *h_next, double *accepted, double *rejected);

#endif
