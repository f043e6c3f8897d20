/*
 * Valve-controlled asymmetric hydraulic cylinder (SI units, gauge pressures).
 *
 * States x (stroke), v, psi_A, psi_B (chamber pressure, or a cavitation void when negative).
 * Inputs u (spool), F_ext (load, positive resists extension), mass_load (reflected load mass),
 *   p_pump and p_LS (a shared load-sensing pump's pressure and the load-sensing pressure).
 * Valve: critical-centre 4/3, a = clamp(u, -1, 1), q = q_rated*|a|, meter-out edges r*q
 *   (r = meter_out_ratio), f(dp) = sign(dp)*sqrt(|dp|/dp_rated) (below dp_laminar the odd cubic
 *   of equal value and slope: finite gain at dp = 0), p_S = min(p_pump, p_supply):
 *   a > 0: Q_PA = q*f(max(p_S - max(p_LS, p_A), 0)), Q_BT = r*q*f(p_B - p_T)   (P->A, B->T)
 *   a < 0: Q_PB = q*f(max(p_S - max(p_LS, p_B), 0)), Q_AT = r*q*f(p_A - p_T)   (P->B, A->T)
 *   max(., 0): the load-holding check in the P channel passes no flow back into the supply.
 *   max(p_LS, p): a post-compensator (flow sharing, LUDV) between the meter-in edge and the
 *   chamber holds the edge's outlet at the highest load pressure p_LS of all sections, so every
 *   open section sees the same edge drop p_S - p_LS; p_LS = 0 (the start): no compensator.
 * Regeneration (a > 0 only): Q_BA = g*q*f(max(p_B - p_A, 0)), g = regeneration_ratio, a passage
 *   from the rod side to the piston side through a check, opened with the extending spool: a
 *   pulling load (the stick's arm-in under its own weight) drives the rod side's return into the
 *   piston side instead of letting that side cavitate; 0 (default): none.
 * Per chamber: relief to tank Q_rl = k_relief*max(p - p_relief, 0); make-up (anti-cavitation)
 *   check from tank Q_mu = k_makeup*max(p_T - dp_makeup - p, 0).
 * Chambers: V_A = V_dead_A + A_A*x, V_B = V_dead_B + A_B*(stroke - x), net inflow
 *   Q_A = Q_PA - Q_AT + Q_BA - Q_rl,A + Q_mu,A, Q_B = Q_PB - Q_BT - Q_BA - Q_rl,B + Q_mu,B;
 *   p = max(psi, 0), dpsi/dt = beta/V*(Q - dV/dt) - [psi < 0]*psi/V*dV/dt: where the make-up
 *   cannot keep up the pressure reaches 0 gauge and the oil cavitates; psi < 0 is then a void
 *   V_void = -psi*V/beta that inflow fills before p rises (the oil volume is conserved).
 * Piston: M*dv/dt = p_A*A_A - p_B*A_B - F_ext - F_coulomb*tanh(v/v_coulomb) - b_viscous*v,
 *   M = mass + mass_load (held over a step; v is kept when M changes). |F_ext| is clamped at
 *   1000*max(p_S, p_relief)*A_B, far beyond what the relief holds: the state stays finite.
 * End stops: inelastic; at 0 or stroke, pushed into the stop, dx/dt = dv/dt = 0 (the stop takes
 *   the force); after each substep x is clamped to [0, stroke], a velocity into the stop zeroed.
 * Energy outputs (J since initialization; RK4 quadrature of the stage powers, see derivatives()):
 *   E_supply + E_mass_load = E_tank + E_throttling + E_relief + E_friction + E_load
 *                            + E_end_stop + E_stored - E_stored(0),
 *   E_stored = M*v^2/2 + E_oil, E_oil = sum over both chambers of the integral of p*(Q - dV/dt);
 *   E_compensator, the compensator's share of E_throttling (not a term of its own).
 * Integration (integration.c): integrator = 0, classical RK4 with n_substeps per step, more when
 *   h/n_substeps exceeds 2/lambda, lambda a bound of the Jacobian's spectral radius
 *   (stiffness_terms), recomputed each step for M; integrator = 1, RODAS3 with the analytic
 *   Jacobian (cylinder_jacobian), substeps sized by `tolerance`, the powers by the trapezoidal
 *   rule. Energy outputs above: "RK4 quadrature" reads "the integrator's quadrature".
 */

#include <math.h>

#include "cylinder.h"
#include "model.h"

static const double PI = 3.14159265358979323846;

/* |F_ext| is clamped to this many times the largest force the port pressures put on the smaller
 * area (s->F_limit): far beyond it the piston reaches its stop within microseconds whatever the
 * load, and the clamp keeps pressures and energies finite for any finite input. */
static const double LOAD_LIMIT_FACTOR = 1000.0;
static const double MASS_LOAD_MAX = 1.0e12; /* kg: keeps M*v^2 finite */
static const double MIN_AREA = 1.0e-7;      /* m^2: a 0.36 mm bore; smaller is no cylinder */

typedef struct {
    Y y;
    double A_A, A_B;
    double spring, damping, flow; /* terms of the stiffness bound, see stiffness() */
    double F_limit;               /* N, LOAD_LIMIT_FACTOR times the largest port force */
    double M;                     /* mass + mass_load of the last step, kg */
    double energy[N_POWER];       /* J since initialization (E_OIL: from the initial state) */
    double E_mass_load;           /* J: M v^2/2 gained when mass_load changed */
    double scale[N_STATES];       /* RODAS3's error scales: m, m/s, Pa, Pa */
    double h_next;                /* s, RODAS3's next substep (0: none yet) */
    double substeps, rejected;    /* since initialization */
} State;

const size_t model_state_size = sizeof(State);

static double clamp(double value, double low, double high) {
    return value < low ? low : (value > high ? high : value);
}

/* sign(dp)*sqrt(|dp|/dp_rated), with the cubic c1*dp + c3*dp^3 below dp_laminar that matches
 * value and slope at |dp| = dp_laminar: c1 = 5/(4s), c3 = -1/(4 s dp_laminar^2),
 * s = sqrt(dp_rated*dp_laminar). */
static double orifice(const P *p, double dp) {
    double r;
    if (fabs(dp) >= p->dp_laminar) return copysign(sqrt(fabs(dp) * p->inv_dp_rated), dp);
    r = dp / p->dp_laminar;
    return dp * p->inv_sqrt_rated_laminar * (1.25 - 0.25 * r * r);
}

/* dpsi/dt of one chamber of volume V (m^3) changing at dV/dt, with net oil inflow Q (m^3/s). */
static double chamber_rate(double beta, double V, double dV_dt, double Q, double psi) {
    double rate = beta / V * (Q - dV_dt);
    return psi < 0.0 ? rate - psi / V * dV_dt : rate;
}

/* State derivatives dy and stage powers w (W) at y.
 *
 * Load-holding check: the P edges pass max(p_S - p, 0). It has no cracking pressure, so flow
 * from the supply is exactly the edge's (a real check cracks at a few tenths of a bar, which
 * would only shift the metering); the flow stays continuous and only its slope jumps at
 * dp = 0, from the laminar gain to 0, so RK4 loses accuracy at most in the substep crossing it.
 * Make-up: linear in the pressure below p_T - dp_makeup, like the relief: a port relief
 * cartridge carries the anti-cavitation check, and its poppet opens either way.
 *
 * Powers, from the flows above (Q_PA... all >= 0 in their arrow's direction but Q_AT, Q_BT,
 * which reverse when p < p_T): supply p_S*(Q_PA + Q_PB); tank p_T*(Q_AT + Q_BT + Q_rl - Q_mu);
 * throttling the sum of dp*Q over the four edges (the meter-in edge's from p_S to the chamber:
 * its compensator's part (max(p_LS, p) - p)*Q is E_compensator), the regeneration passage
 * (p_B - p_A)*Q_BA and both make-up checks; relief
 * (p - p_T)*Q_rl; oil p*(Q - dV/dt). Their balance is p_A*A_A*dx - p_B*A_B*dx = F*dx exactly
 * (p*Q telescopes edge by edge). The piston turns F*dx into load F_ext*dx, friction F_f*dx and
 * kinetic M*v*dv (dx = v off the stops); on a stop (dx = 0) the stage's kinetic power M*v*dv
 * goes to the stop. So the powers balance at every stage, their RK4 quadrature balances too,
 * and E_oil is the compression work p dV_oil with dV_oil = (Q - dV/dt) dt = V/beta dp: the
 * energy stored in the oil as the model's chamber law has it (V*p^2/(2 beta) for a chamber of
 * fixed volume). In a void p = 0: no power. What does not close is the kinetic energy, kept as
 * M v^2/2 of the state rather than integrated: the difference is the RK4 error of v. */
void cylinder_derivatives(const P *p, const Y *y, Y *dy, double *w) {
    double p_A = fmax(y->psi_A, 0.0), p_B = fmax(y->psi_B, 0.0);
    double x = clamp(y->x, 0.0, p->stroke);
    double Q_PA = 0.0, Q_AT = 0.0, Q_PB = 0.0, Q_BT = 0.0, Q_BA = 0.0, Q_A, Q_B, force, dx, dv;
    double tanh_v;
    double outlet_A = fmax(p->p_LS, p_A), outlet_B = fmax(p->p_LS, p_B); /* compensator */
    double relief_A = p->k_relief * fmax(p_A - p->p_relief, 0.0);
    double relief_B = p->k_relief * fmax(p_B - p->p_relief, 0.0);
    double makeup_A = p->k_makeup * fmax(p->p_makeup - p_A, 0.0);
    double makeup_B = p->k_makeup * fmax(p->p_makeup - p_B, 0.0);
    int on_stop = 0;
    if (p->a > 0.0) {
        Q_PA = p->q_open * orifice(p, fmax(p->p_S - outlet_A, 0.0));
        Q_BT = p->q_out * orifice(p, p_B - p->p_T);
        if (p->q_regen > 0.0) Q_BA = p->q_regen * orifice(p, fmax(p_B - p_A, 0.0));
    } else if (p->a < 0.0) { /* q_open < 0 */
        Q_AT = -(p->q_out * orifice(p, p_A - p->p_T));
        Q_PB = -(p->q_open * orifice(p, fmax(p->p_S - outlet_B, 0.0)));
    }
    Q_A = Q_PA - Q_AT + Q_BA;
    Q_B = Q_PB - Q_BT - Q_BA;
    Q_A -= relief_A;
    Q_B -= relief_B;
    Q_A += makeup_A;
    Q_B += makeup_B;

    tanh_v = tanh(y->v * p->inv_v_c);
    force = p_A * p->A_A - p_B * p->A_B - p->F_ext - p->F_c * tanh_v - p->b * y->v;
    dx = y->v;
    dv = force * p->inv_mass;
    if (y->x <= 0.0 && y->v <= 0.0) { /* resting on (or pushed into) the bottom stop */
        dx = 0.0;
        dv = fmax(dv, 0.0);
        on_stop = 1;
    } else if (y->x >= p->stroke && y->v >= 0.0) {
        dx = 0.0;
        dv = fmin(dv, 0.0);
        on_stop = 1;
    }
    dy->x = dx;
    dy->v = dv;
    dy->psi_A = chamber_rate(p->beta, p->V_dead_A + p->A_A * x, p->A_A * dx, Q_A, y->psi_A);
    dy->psi_B = chamber_rate(p->beta, p->V_dead_B + p->A_B * (p->stroke - x), -p->A_B * dx, Q_B,
                             y->psi_B);

    w[W_SUPPLY] = p->p_S * (Q_PA + Q_PB);
    w[W_TANK] = p->p_T * (Q_AT + Q_BT + relief_A + relief_B - makeup_A - makeup_B);
    w[W_THROTTLING] = (p->p_S - p_A) * Q_PA + (p_A - p->p_T) * Q_AT + (p->p_S - p_B) * Q_PB
                      + (p_B - p->p_T) * Q_BT + (p_B - p_A) * Q_BA + (p->p_T - p_A) * makeup_A
                      + (p->p_T - p_B) * makeup_B;
    w[W_RELIEF] = (p_A - p->p_T) * relief_A + (p_B - p->p_T) * relief_B;
    w[W_FRICTION] = (p->F_c * tanh_v + p->b * y->v) * dx;
    w[W_LOAD] = p->F_ext * dx;
    w[W_END_STOP] = on_stop ? -p->M * y->v * dv : 0.0;
    w[W_OIL] = p_A * (Q_A - p->A_A * dx) + p_B * (Q_B + p->A_B * dx);
    w[W_COMPENSATOR] = (outlet_A - p_A) * Q_PA + (outlet_B - p_B) * Q_PB;
}

/* d orifice / d dp (1/sqrt(Pa)): the slope of the law above, finite at dp = 0. */
static double orifice_slope(const P *p, double dp) {
    double r;
    if (fabs(dp) >= p->dp_laminar) return 0.5 * sqrt(p->inv_dp_rated / fabs(dp));
    r = dp / p->dp_laminar;
    return p->inv_sqrt_rated_laminar * (1.25 - 0.75 * r * r);
}

/* dQ/dp (m^3/(s Pa)) of one chamber's net inflow: its open metering edge (meter-in P->chamber
 * through the load-holding check and compensator, or meter-out chamber->T), relief, make-up. */
static double inflow_slope(const P *p, double pressure, int meter_in, double q_edge) {
    double slope = 0.0, outlet = fmax(p->p_LS, pressure), drop = p->p_S - outlet;
    if (meter_in) {
        if (drop > 0.0 && pressure > p->p_LS) slope = -q_edge * orifice_slope(p, drop);
    } else {
        slope = -q_edge * orifice_slope(p, pressure - p->p_T);
    }
    if (pressure > p->p_relief) slope -= p->k_relief;
    if (pressure < p->p_makeup) slope -= p->k_makeup;
    return slope;
}

/* J = df/dy of cylinder_derivatives (rows dx, dv, dpsi_A, dpsi_B; columns x, v, psi_A, psi_B),
 * differentiated branch by branch: on a stop the rows of the frozen states are 0; where a max()
 * or the void switch sits exactly on its kink, the side the derivatives take. */
void cylinder_jacobian(const P *p, const Y *y, const Y *dy, double *J) {
    double p_A = fmax(y->psi_A, 0.0), p_B = fmax(y->psi_B, 0.0);
    double x = clamp(y->x, 0.0, p->stroke);
    int inside = y->x > 0.0 && y->x < p->stroke;
    double V_A = p->V_dead_A + p->A_A * x, V_B = p->V_dead_B + p->A_B * (p->stroke - x);
    double g_A, g_B, g_regen, tanh_v = tanh(y->v * p->inv_v_c), dx, force;
    int on_stop = (y->x <= 0.0 && y->v <= 0.0) || (y->x >= p->stroke && y->v >= 0.0);
    double void_A = y->psi_A < 0.0 ? y->psi_A : 0.0, void_B = y->psi_B < 0.0 ? y->psi_B : 0.0;
    int i;
    for (i = 0; i < N_STATES * N_STATES; i++) J[i] = 0.0;
    if (p->a > 0.0) { /* P->A, B->T */
        g_A = inflow_slope(p, p_A, 1, p->q_open);
        g_B = inflow_slope(p, p_B, 0, p->q_out);
    } else if (p->a < 0.0) { /* P->B, A->T; q_open, q_out < 0 */
        g_A = inflow_slope(p, p_A, 0, -p->q_out);
        g_B = inflow_slope(p, p_B, 1, -p->q_open);
    } else {
        g_A = inflow_slope(p, p_A, 0, 0.0);
        g_B = inflow_slope(p, p_B, 0, 0.0);
    }
    force = p_A * p->A_A - p_B * p->A_B - p->F_ext - p->F_c * tanh_v - p->b * y->v;
    dx = dy->x;
    if (!on_stop) J[0 * 4 + 1] = 1.0;
    /* dv: the force law, off the stops or while it pushes away from the stop */
    if (!on_stop || (y->x <= 0.0 ? force > 0.0 : force < 0.0)) {
        J[1 * 4 + 1] = (-p->F_c * p->inv_v_c * (1.0 - tanh_v * tanh_v) - p->b) * p->inv_mass;
        J[1 * 4 + 2] = y->psi_A > 0.0 ? p->A_A * p->inv_mass : 0.0;
        J[1 * 4 + 3] = y->psi_B > 0.0 ? -p->A_B * p->inv_mass : 0.0;
    }
    /* chambers: rate = (beta (Q - dV/dt) - void dV/dt) / V, dV_A/dt = A_A dx, dV_B/dt = -A_B dx */
    if (inside) {
        J[2 * 4 + 0] = -dy->psi_A * p->A_A / V_A;
        J[3 * 4 + 0] = dy->psi_B * p->A_B / V_B;
    }
    if (!on_stop) {
        J[2 * 4 + 1] = -p->A_A * (p->beta + void_A) / V_A;
        J[3 * 4 + 1] = p->A_B * (p->beta + void_B) / V_B;
    }
    /* the regeneration passage: dQ_BA/dp_B = g_regen = -dQ_BA/dp_A, into A and out of B; a
     * void's pressure (psi < 0) is 0 whatever psi, so its column takes no part */
    if (p->q_regen > 0.0 && p_B > p_A) {
        g_regen = p->q_regen * orifice_slope(p, p_B - p_A);
        g_A -= g_regen;
        g_B -= g_regen;
        if (y->psi_B > 0.0) J[2 * 4 + 3] = p->beta / V_A * g_regen;
        if (y->psi_A > 0.0) J[3 * 4 + 2] = p->beta / V_B * g_regen;
    }
    J[2 * 4 + 2] = y->psi_A > 0.0 ? p->beta / V_A * g_A : -p->A_A * dx / V_A;
    J[3 * 4 + 3] = y->psi_B > 0.0 ? p->beta / V_B * g_B : p->A_B * dx / V_B;
}

static void gather(const double *v, const State *s, P *p) {
    p->A_A = s->A_A;
    p->A_B = s->A_B;
    p->stroke = v[VR_stroke];
    p->V_dead_A = v[VR_V_dead_A];
    p->V_dead_B = v[VR_V_dead_B];
    p->beta = v[VR_beta];
    p->p_S = fmin(v[VR_p_pump], v[VR_p_supply]);
    p->p_LS = v[VR_p_LS];
    p->p_T = v[VR_p_tank];
    p->p_relief = v[VR_p_relief];
    p->k_relief = v[VR_k_relief];
    p->k_makeup = v[VR_k_makeup];
    p->p_makeup = v[VR_p_tank] - v[VR_dp_makeup];
    p->dp_laminar = v[VR_dp_laminar];
    p->inv_dp_rated = 1.0 / v[VR_dp_rated];
    p->inv_sqrt_rated_laminar = 1.0 / sqrt(v[VR_dp_rated] * v[VR_dp_laminar]);
    p->M = s->M;
    p->inv_mass = 1.0 / s->M;
    p->F_c = v[VR_F_coulomb];
    p->inv_v_c = 1.0 / v[VR_v_coulomb];
    p->b = v[VR_b_viscous];
    p->a = clamp(v[VR_u], -1.0, 1.0);
    p->q_open = v[VR_q_rated] * p->a;
    p->q_out = v[VR_meter_out_ratio] * p->q_open;
    p->q_regen = p->a > 0.0 ? v[VR_regeneration_ratio] * p->q_open : 0.0;
    p->F_ext = clamp(v[VR_F_ext], -s->F_limit, s->F_limit);
}

static void write_outputs(double *v, const State *s) {
    double p_A = fmax(s->y.psi_A, 0.0), p_B = fmax(s->y.psi_B, 0.0);
    v[VR_x] = s->y.x;
    v[VR_v] = s->y.v;
    v[VR_p_A] = p_A;
    v[VR_p_B] = p_B;
    v[VR_F] = p_A * s->A_A - p_B * s->A_B;
    v[VR_E_supply] = s->energy[W_SUPPLY];
    v[VR_E_tank] = s->energy[W_TANK];
    v[VR_E_throttling] = s->energy[W_THROTTLING];
    v[VR_E_relief] = s->energy[W_RELIEF];
    v[VR_E_friction] = s->energy[W_FRICTION];
    v[VR_E_load] = s->energy[W_LOAD];
    v[VR_E_end_stop] = s->energy[W_END_STOP];
    v[VR_E_mass_load] = s->E_mass_load;
    v[VR_E_stored] = 0.5 * s->M * s->y.v * s->y.v + s->energy[W_OIL];
    v[VR_E_compensator] = s->energy[W_COMPENSATOR];
    v[VR_substeps] = s->substeps;
    v[VR_rejected_substeps] = s->rejected;
}

static int finite_positive(double value) { return isfinite(value) && value > 0.0; }

/* The parameters one by one (what variables.toml's min/max cannot say: strict bounds), across
 * variables, and every derived quantity the integration divides by or multiplies with. */
static const char *check_parameters(const double *v) {
    double A_A = PI / 4.0 * v[VR_bore] * v[VR_bore];
    double A_B = PI / 4.0 * (v[VR_bore] * v[VR_bore] - v[VR_rod] * v[VR_rod]);
    if (!(v[VR_bore] > 0.0)) return "bore must be > 0";
    if (!(v[VR_rod] > 0.0 && v[VR_rod] < v[VR_bore])) return "rod must be > 0 and < bore";
    if (!(isfinite(A_A) && A_A >= MIN_AREA && isfinite(A_B) && A_B >= MIN_AREA)) {
        return "piston area pi/4*bore^2 and annulus pi/4*(bore^2 - rod^2) must be finite and "
               ">= 1e-7 m^2";
    }
    if (!(v[VR_stroke] > 0.0)) return "stroke must be > 0";
    if (!(v[VR_V_dead_A] > 0.0 && v[VR_V_dead_B] > 0.0)) return "V_dead_A and V_dead_B must be > 0";
    if (!(isfinite(v[VR_V_dead_A] + A_A * v[VR_stroke])
          && isfinite(v[VR_V_dead_B] + A_B * v[VR_stroke]))) {
        return "chamber volumes V_dead + area*stroke must be finite";
    }
    if (!(v[VR_beta] > 0.0)) return "beta must be > 0";
    if (!(v[VR_p_tank] >= 0.0)) return "p_tank must be >= 0";
    if (!(v[VR_p_supply] > v[VR_p_tank])) return "p_supply must be > p_tank";
    if (!(v[VR_p_relief] > v[VR_p_tank])) return "p_relief must be > p_tank";
    if (!(v[VR_k_relief] > 0.0)) return "k_relief must be > 0";
    if (!(v[VR_k_makeup] >= 0.0 && v[VR_dp_makeup] >= 0.0)) {
        return "k_makeup and dp_makeup must be >= 0";
    }
    if (!(v[VR_q_rated] > 0.0 && v[VR_dp_rated] > 0.0)) return "q_rated and dp_rated must be > 0";
    if (!(v[VR_dp_laminar] > 0.0 && v[VR_dp_laminar] < v[VR_dp_rated])) {
        return "dp_laminar must be > 0 and < dp_rated";
    }
    if (!(finite_positive(1.0 / v[VR_dp_rated])
          && finite_positive(1.0 / sqrt(v[VR_dp_rated] * v[VR_dp_laminar])))) {
        return "dp_rated and dp_laminar must keep 1/dp_rated and 1/sqrt(dp_rated*dp_laminar) "
               "finite";
    }
    if (!(v[VR_mass] > 0.0 && finite_positive(1.0 / v[VR_mass]))) return "mass must be > 0";
    if (!(v[VR_F_coulomb] >= 0.0 && v[VR_b_viscous] >= 0.0)) {
        return "F_coulomb and b_viscous must be >= 0";
    }
    if (!(v[VR_v_coulomb] > 0.0 && finite_positive(1.0 / v[VR_v_coulomb]))) {
        return "v_coulomb must be > 0";
    }
    if (!(v[VR_x0] >= 0.0 && v[VR_x0] <= v[VR_stroke])) return "x0 must lie in [0, stroke]";
    if (!(v[VR_n_substeps] >= 1.0)) return "n_substeps must be >= 1";
    if (!(v[VR_integrator] == 0.0 || v[VR_integrator] == 1.0)) {
        return "integrator must be 0 (RK4) or 1 (RODAS3)";
    }
    if (!(v[VR_tolerance] >= 1e-12 && v[VR_tolerance] <= 1e-2)) {
        return "tolerance must lie in [1e-12, 1e-2]";
    }
    if (!finite_positive(v[VR_q_rated] / (PI / 4.0 * (v[VR_bore] * v[VR_bore]
                                                       - v[VR_rod] * v[VR_rod])))) {
        return "q_rated/A_B (the full speed) must be finite";
    }
    return NULL;
}

static const char *check_mass_load(double mass_load) {
    return mass_load >= 0.0 && mass_load <= MASS_LOAD_MAX ? NULL
                                                         : "mass_load must lie in [0, 1e12] kg";
}

/* Upper bound of the Jacobian's spectral radius, 1/s: the hydraulic spring-mass frequency with
 * both chambers at their dead volumes (sqrt(spring/M)), plus the friction slope (damping/M),
 * plus the largest flow gain over the smallest chamber's capacitance V/beta (flow). Per chamber
 * one metering edge is open (slope at most 1.25*q/sqrt(dp_rated*dp_laminar), at dp = 0, q the
 * larger of q_rated and meter_out_ratio*q_rated; a compensator only flattens the meter-in edge;
 * the regeneration passage between the chambers adds its gain to a row twice, on the diagonal and
 * beside it: 2*regeneration_ratio*q_rated),
 * and relief and make-up never open together (p_relief > p_T), so the larger of k_relief and
 * k_makeup counts; k_makeup only if the make-up can open at all (p_T > dp_makeup, as p >= 0).
 * All three terms fall as M grows, so they are kept and combined for each step's M. */
static void stiffness_terms(const double *v, State *s) {
    double V_min = fmin(v[VR_V_dead_A], v[VR_V_dead_B]);
    /* The same operations as the per-stage constants in gather() use. */
    double q_edge = v[VR_q_rated] * (fmax(1.0, v[VR_meter_out_ratio])
                                     + 2.0 * v[VR_regeneration_ratio]);
    double valve = 1.25 * q_edge * (1.0 / sqrt(v[VR_dp_rated] * v[VR_dp_laminar]));
    double k_port = v[VR_p_tank] > v[VR_dp_makeup] ? fmax(v[VR_k_relief], v[VR_k_makeup])
                                                   : v[VR_k_relief];
    s->spring = v[VR_beta] * (s->A_A * s->A_A / v[VR_V_dead_A] + s->A_B * s->A_B / v[VR_V_dead_B]);
    s->damping = v[VR_b_viscous] + v[VR_F_coulomb] * (1.0 / v[VR_v_coulomb]);
    s->flow = v[VR_beta] / V_min * (valve + k_port);
}

static double stable_substep(const State *s) {
    double inv_mass = 1.0 / s->M;
    return 2.0 / (sqrt(s->spring * inv_mass) + s->damping * inv_mass + s->flow);
}

int model_initialize(double *v, void *state, const char **error) {
    State *s = state;
    double F0, p_T, V_A, V_B, p_max;
    int i;
    const char *problem = check_parameters(v);
    if (problem == NULL) problem = check_mass_load(v[VR_mass_load]);
    if (problem != NULL) {
        *error = problem;
        return 1;
    }
    s->A_A = PI / 4.0 * v[VR_bore] * v[VR_bore];
    s->A_B = PI / 4.0 * (v[VR_bore] * v[VR_bore] - v[VR_rod] * v[VR_rod]);
    v[VR_A_A] = s->A_A;
    v[VR_A_B] = s->A_B;
    s->M = v[VR_mass] + v[VR_mass_load];
    for (i = 0; i < N_POWER; i++) s->energy[i] = 0.0;
    s->E_mass_load = 0.0;
    s->h_next = s->substeps = s->rejected = 0.0;
    s->scale[0] = v[VR_tolerance] * v[VR_stroke];
    s->scale[1] = v[VR_tolerance] * v[VR_q_rated] / s->A_B;
    s->scale[2] = s->scale[3] = v[VR_tolerance] * fmax(v[VR_p_supply], v[VR_p_relief]);
    stiffness_terms(v, s);
    p_max = fmax(v[VR_p_supply], v[VR_p_relief]);
    s->F_limit = LOAD_LIMIT_FACTOR * p_max * fmin(s->A_A, s->A_B);
    if (!(finite_positive(s->spring + s->damping + s->flow) && finite_positive(stable_substep(s))
          && finite_positive(s->F_limit))) {
        *error = "parameters give a non-finite stiffness bound or load limit";
        return 1;
    }

    /* Start at rest in static equilibrium with the start load: the lower-pressure chamber at
     * tank pressure, the other one carrying F0 (p_A*A_A - p_B*A_B = F0). */
    F0 = clamp(v[VR_F_ext], -s->F_limit, s->F_limit);
    p_T = v[VR_p_tank];
    s->y.x = v[VR_x0];
    s->y.v = 0.0;
    if (F0 >= p_T * (s->A_A - s->A_B)) {
        s->y.psi_B = p_T;
        s->y.psi_A = (F0 + p_T * s->A_B) / s->A_A;
    } else {
        s->y.psi_A = p_T;
        s->y.psi_B = (p_T * s->A_A - F0) / s->A_B;
    }
    /* The compression energy of the start pressures, V*p^2/(2 beta) per chamber (the chamber
     * law dp = beta/V dV_oil at fixed V). */
    V_A = v[VR_V_dead_A] + s->A_A * s->y.x;
    V_B = v[VR_V_dead_B] + s->A_B * (v[VR_stroke] - s->y.x);
    s->energy[W_OIL] = (V_A * s->y.psi_A * s->y.psi_A + V_B * s->y.psi_B * s->y.psi_B)
                       / (2.0 * v[VR_beta]);
    write_outputs(v, s);
    return 0;
}

int model_do_step(double *v, void *state, double t, double h, const char **error) {
    State *s = state;
    P p;
    double n = v[VR_n_substeps], needed, M, energy[N_POWER], h_next, accepted, rejected;
    long count;
    int i;
    Y y;
    const char *problem = check_mass_load(v[VR_mass_load]);
    (void)t;
    if (problem != NULL) {
        *error = problem;
        return 1;
    }
    /* A new reflected mass keeps the velocity (the coupling's pose moved): the kinetic energy
     * it adds or takes is booked as E_mass_load. */
    M = v[VR_mass] + v[VR_mass_load];
    if (M != s->M) {
        s->E_mass_load += 0.5 * (M - s->M) * s->y.v * s->y.v;
        s->M = M;
    }
    gather(v, s, &p);
    if (v[VR_integrator] == 1.0) { /* on a copy: a step that fails leaves the state as it was */
        y = s->y;
        h_next = s->h_next;
        accepted = rejected = 0.0;
        for (i = 0; i < N_POWER; i++) energy[i] = s->energy[i];
        problem = cylinder_rodas3(&p, &y, energy, h, s->scale, &h_next, &accepted, &rejected);
        s->rejected += rejected;
        if (problem != NULL) {
            *error = problem;
            return 1;
        }
        s->y = y;
        s->h_next = h_next;
        s->substeps += accepted;
        for (i = 0; i < N_POWER; i++) s->energy[i] = energy[i];
    } else {
        needed = ceil(h / stable_substep(s));
        if (needed > n) n = needed;
        if (n > 1e8) {
            *error = "communication step too long: more than 1e8 stable RK4 substeps needed";
            return 1;
        }
        count = (long)n;
        cylinder_rk4(&p, &s->y, s->energy, h, count);
        s->substeps += (double)count;
    }
    write_outputs(v, s);
    return 0;
}
