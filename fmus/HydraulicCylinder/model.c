/*
 * Valve-controlled asymmetric hydraulic cylinder (SI units, gauge pressures).
 *
 * States: stroke x, velocity v and the chamber states psi_A, psi_B (pressure, or cavitation void
 * when negative; see below).
 *
 * Valve: critical-centre 4/3 proportional valve, opening a = clamp(u, -1, 1), four metering edges
 *   a > 0:  Q_A =  q_rated*a*f(p_S - p_A)   (P->A)    Q_B = -q_rated*a*f(p_B - p_T)   (B->T)
 *   a < 0:  Q_A = -q_rated*|a|*f(p_A - p_T) (A->T)    Q_B =  q_rated*|a|*f(p_S - p_B) (P->B)
 *   orifice law f(dp) = sign(dp)*sqrt(|dp|/dp_rated); below |dp| = dp_laminar it is replaced by
 *   the odd cubic with the same value and slope at dp_laminar (a small "laminar" region), so the
 *   flow gain stays finite at dp = 0 and the stiff ODE stays well-behaved.
 * Relief: each chamber drains to tank through Q_relief = k_relief*max(p - p_relief, 0).
 * Chambers (stroke-dependent volumes):
 *   V_A = V_dead_A + A_A*x,  V_B = V_dead_B + A_B*(stroke - x)
 *   dp_A/dt = beta/V_A*(Q_A - Q_relief,A - A_A*v),  dp_B/dt = beta/V_B*(Q_B - Q_relief,B + A_B*v)
 * Cavitation: a chamber's pressure does not fall below 0 (gauge, about atmospheric; oil releases
 *   air and vapour there). Further expansion opens a void, and the pressure stays 0 until inflow
 *   has filled the void again, so the oil volume is conserved through cavitation. Each chamber's
 *   state psi carries both: p = max(psi, 0) and void volume V_void = max(-psi, 0)*V/beta, with
 *   dpsi/dt = beta/V*(net inflow) - [psi < 0]*psi/V*dV/dt (the second term keeps V_void exact
 *   while V changes). The right-hand side is continuous at psi = 0, so RK4 keeps its accuracy.
 * Piston: mass*dv/dt = p_A*A_A - p_B*A_B - F_ext - F_coulomb*tanh(v/v_coulomb) - b_viscous*v
 * End stops: inelastic. At x = 0 (or stroke) with the piston pushed into the stop, the stop takes
 *   the force (dx/dt = dv/dt = 0); after every substep x is clamped to [0, stroke] and a velocity
 *   into the stop is zeroed, so x never leaves [0, stroke].
 *
 * Integration: classical RK4 with n_substeps fixed substeps per communication step. RK4 is
 * explicit, so the substep must stay inside its stability region: at initialization we bound the
 * largest Jacobian eigenvalue (hydraulic spring-mass frequency at the dead volumes, friction
 * slope, orifice and relief flow gains) and, if h/n_substeps exceeds 2/lambda, take more
 * substeps. This keeps any communication step stable without an implicit solver; with the
 * defaults 2/lambda is about 0.2 ms, so 10 substeps cover a 1 ms step.
 */
#include <math.h>

#include "model.h"

static const double PI = 3.14159265358979323846;

typedef struct {
    double x, v, psi_A, psi_B;
} Y;

typedef struct {
    Y y;
    double A_A, A_B;
    double h_stable; /* longest stable RK4 substep, s */
} State;

const size_t model_state_size = sizeof(State);

/* Parameters and inputs gathered once per communication step. */
typedef struct {
    double A_A, A_B, stroke, V_dead_A, V_dead_B, beta, p_S, p_T, p_relief, k_relief;
    double dp_laminar, inv_dp_rated, inv_sqrt_rated_laminar, inv_mass, F_c, inv_v_c, b;
    double q_open; /* q_rated*a: flow of one edge at dp_rated at the current opening, m^3/s */
    double a, F_ext;
} P;

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

static void derivatives(const P *p, const Y *y, Y *dy) {
    double p_A = fmax(y->psi_A, 0.0), p_B = fmax(y->psi_B, 0.0);
    double x = clamp(y->x, 0.0, p->stroke);
    double Q_A = 0.0, Q_B = 0.0, force, dx, dv;
    if (p->a > 0.0) {
        Q_A = p->q_open * orifice(p, p->p_S - p_A);
        Q_B = -p->q_open * orifice(p, p_B - p->p_T);
    } else if (p->a < 0.0) {
        Q_A = p->q_open * orifice(p, p_A - p->p_T);
        Q_B = -p->q_open * orifice(p, p->p_S - p_B);
    }
    Q_A -= p->k_relief * fmax(p_A - p->p_relief, 0.0);
    Q_B -= p->k_relief * fmax(p_B - p->p_relief, 0.0);

    force = p_A * p->A_A - p_B * p->A_B - p->F_ext - p->F_c * tanh(y->v * p->inv_v_c)
            - p->b * y->v;
    dx = y->v;
    dv = force * p->inv_mass;
    if (y->x <= 0.0 && y->v <= 0.0) { /* resting on (or pushed into) the bottom stop */
        dx = 0.0;
        dv = fmax(dv, 0.0);
    } else if (y->x >= p->stroke && y->v >= 0.0) {
        dx = 0.0;
        dv = fmin(dv, 0.0);
    }
    dy->x = dx;
    dy->v = dv;
    dy->psi_A = chamber_rate(p->beta, p->V_dead_A + p->A_A * x, p->A_A * dx, Q_A, y->psi_A);
    dy->psi_B = chamber_rate(p->beta, p->V_dead_B + p->A_B * (p->stroke - x), -p->A_B * dx, Q_B,
                             y->psi_B);
}

static void axpy(Y *out, const Y *y, double h, const Y *k) {
    out->x = y->x + h * k->x;
    out->v = y->v + h * k->v;
    out->psi_A = y->psi_A + h * k->psi_A;
    out->psi_B = y->psi_B + h * k->psi_B;
}

static void rk4_substep(const P *p, Y *y, double h) {
    Y k1, k2, k3, k4, t;
    derivatives(p, y, &k1);
    axpy(&t, y, 0.5 * h, &k1);
    derivatives(p, &t, &k2);
    axpy(&t, y, 0.5 * h, &k2);
    derivatives(p, &t, &k3);
    axpy(&t, y, h, &k3);
    derivatives(p, &t, &k4);
    y->x += h / 6.0 * (k1.x + 2.0 * k2.x + 2.0 * k3.x + k4.x);
    y->v += h / 6.0 * (k1.v + 2.0 * k2.v + 2.0 * k3.v + k4.v);
    y->psi_A += h / 6.0 * (k1.psi_A + 2.0 * k2.psi_A + 2.0 * k3.psi_A + k4.psi_A);
    y->psi_B += h / 6.0 * (k1.psi_B + 2.0 * k2.psi_B + 2.0 * k3.psi_B + k4.psi_B);
    if (y->x <= 0.0) {
        y->x = 0.0;
        y->v = fmax(y->v, 0.0);
    } else if (y->x >= p->stroke) {
        y->x = p->stroke;
        y->v = fmin(y->v, 0.0);
    }
}

static void gather(const double *v, const State *s, P *p) {
    p->A_A = s->A_A;
    p->A_B = s->A_B;
    p->stroke = v[VR_stroke];
    p->V_dead_A = v[VR_V_dead_A];
    p->V_dead_B = v[VR_V_dead_B];
    p->beta = v[VR_beta];
    p->p_S = v[VR_p_supply];
    p->p_T = v[VR_p_tank];
    p->p_relief = v[VR_p_relief];
    p->k_relief = v[VR_k_relief];
    p->dp_laminar = v[VR_dp_laminar];
    p->inv_dp_rated = 1.0 / v[VR_dp_rated];
    p->inv_sqrt_rated_laminar = 1.0 / sqrt(v[VR_dp_rated] * v[VR_dp_laminar]);
    p->inv_mass = 1.0 / v[VR_mass];
    p->F_c = v[VR_F_coulomb];
    p->inv_v_c = 1.0 / v[VR_v_coulomb];
    p->b = v[VR_b_viscous];
    p->a = clamp(v[VR_u], -1.0, 1.0);
    p->q_open = v[VR_q_rated] * p->a;
    p->F_ext = v[VR_F_ext];
}

static void write_outputs(double *v, const State *s) {
    double p_A = fmax(s->y.psi_A, 0.0), p_B = fmax(s->y.psi_B, 0.0);
    v[VR_x] = s->y.x;
    v[VR_v] = s->y.v;
    v[VR_p_A] = p_A;
    v[VR_p_B] = p_B;
    v[VR_F] = p_A * s->A_A - p_B * s->A_B;
}

static const char *check_parameters(const double *v) {
    if (!(v[VR_bore] > 0.0)) return "bore must be > 0";
    if (!(v[VR_rod] > 0.0 && v[VR_rod] < v[VR_bore])) return "rod must be > 0 and < bore";
    if (!(v[VR_stroke] > 0.0)) return "stroke must be > 0";
    if (!(v[VR_V_dead_A] > 0.0 && v[VR_V_dead_B] > 0.0)) return "V_dead_A and V_dead_B must be > 0";
    if (!(v[VR_beta] > 0.0)) return "beta must be > 0";
    if (!(v[VR_p_tank] >= 0.0)) return "p_tank must be >= 0";
    if (!(v[VR_p_supply] > v[VR_p_tank])) return "p_supply must be > p_tank";
    if (!(v[VR_p_relief] > v[VR_p_tank])) return "p_relief must be > p_tank";
    if (!(v[VR_k_relief] > 0.0)) return "k_relief must be > 0";
    if (!(v[VR_q_rated] > 0.0 && v[VR_dp_rated] > 0.0)) return "q_rated and dp_rated must be > 0";
    if (!(v[VR_dp_laminar] > 0.0 && v[VR_dp_laminar] < v[VR_dp_rated])) {
        return "dp_laminar must be > 0 and < dp_rated";
    }
    if (!(v[VR_mass] > 0.0)) return "mass must be > 0";
    if (!(v[VR_F_coulomb] >= 0.0 && v[VR_b_viscous] >= 0.0)) {
        return "F_coulomb and b_viscous must be >= 0";
    }
    if (!(v[VR_v_coulomb] > 0.0)) return "v_coulomb must be > 0";
    if (!(v[VR_x0] >= 0.0 && v[VR_x0] <= v[VR_stroke])) return "x0 must lie in [0, stroke]";
    if (!(v[VR_n_substeps] >= 1.0)) return "n_substeps must be >= 1";
    return NULL;
}

/* Upper bound of the Jacobian's spectral radius, 1/s: hydraulic spring-mass frequency with both
 * chambers at their dead volumes, plus the friction slope, plus the largest flow gain
 * (orifice slope at dp = 0 is 1.25*q_rated/sqrt(dp_rated*dp_laminar); relief k_relief)
 * over the smallest chamber's capacitance V/beta. */
static double stiffness_bound(const P *p, double q_rated) {
    double V_min = fmin(p->V_dead_A, p->V_dead_B);
    double spring = p->beta * (p->A_A * p->A_A / p->V_dead_A + p->A_B * p->A_B / p->V_dead_B);
    double hydraulic = sqrt(spring * p->inv_mass);
    double friction = (p->b + p->F_c * p->inv_v_c) * p->inv_mass;
    double flow = p->beta / V_min * (1.25 * q_rated * p->inv_sqrt_rated_laminar + p->k_relief);
    return hydraulic + friction + flow;
}

int model_initialize(double *v, void *state, const char **error) {
    State *s = state;
    P p;
    double F0, p_T;
    const char *problem = check_parameters(v);
    if (problem != NULL) {
        *error = problem;
        return 1;
    }
    s->A_A = PI / 4.0 * v[VR_bore] * v[VR_bore];
    s->A_B = PI / 4.0 * (v[VR_bore] * v[VR_bore] - v[VR_rod] * v[VR_rod]);
    v[VR_A_A] = s->A_A;
    v[VR_A_B] = s->A_B;
    gather(v, s, &p);
    s->h_stable = 2.0 / stiffness_bound(&p, v[VR_q_rated]);

    /* Start at rest in static equilibrium with the start load: the lower-pressure chamber at
     * tank pressure, the other one carrying F0 (p_A*A_A - p_B*A_B = F0). */
    F0 = v[VR_F_ext];
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
    write_outputs(v, s);
    return 0;
}

int model_do_step(double *v, void *state, double t, double h, const char **error) {
    State *s = state;
    P p;
    double n = v[VR_n_substeps], needed, h_sub;
    long i, count;
    (void)t;
    needed = ceil(h / s->h_stable);
    if (needed > n) n = needed;
    if (n > 1e8) {
        *error = "communication step too long: more than 1e8 stable RK4 substeps needed";
        return 1;
    }
    count = (long)n;
    h_sub = h / (double)count;
    gather(v, s, &p);
    for (i = 0; i < count; i++) rk4_substep(&p, &s->y, h_sub);
    write_outputs(v, s);
    return 0;
}
