/*
 * Ideal actuator: a cylinder without hydraulics, as a first-order velocity servo (SI units).
 *
 *   v' = (w - v) / tau,  w = clamp(u, -1, 1) * v_max,   x' = v,   F = F_ext
 *
 * Within a communication step u is constant, so the step is the exact solution, not a numerical
 * integration (no step-size error, any step length):
 *   v(s) = w + (v0 - w) e^(-s/tau),   x(s) = x0 + w s + (v0 - w) tau (1 - e^(-s/tau)).
 * End stops at 0 and stroke, inelastic like HydraulicCylinder's: when x reaches a stop moving
 * into it, v drops to 0 and the stop holds the rod for as long as the target w points into it;
 * a target pointing away starts the rod from rest again (the same exact solution from v = 0).
 * The crossing time is found by bisection on a piece of the step where x is monotone (v changes
 * sign at most once per step, so there are at most two such pieces).
 * The load F_ext does not change the motion (an ideal servo is infinitely stiff and strong); it
 * is reported as the force F the actuator delivers to hold it.
 */
#include <math.h>

#include "model.h"

#define CROSSING_BISECTIONS 80 /* halves the step 80 times: far below round-off of s */
#define MAX_CONTACTS 4         /* stop hits per step: hit, leave, hit the other stop, held */

typedef struct {
    double x, v; /* m, m/s */
} State;

const size_t model_state_size = sizeof(State);

typedef struct {
    double w, tau, stroke; /* target velocity m/s, time constant s, stroke m */
} Servo;

/* The exact solution after time s (s) from (x, v). */
static State advance(const Servo *p, State y, double s)
{
    const double decay = -expm1(-s / p->tau); /* 1 - e^(-s/tau), accurate for small s */
    State out = {y.x + p->w * s + (y.v - p->w) * p->tau * decay, y.v - (y.v - p->w) * decay};
    return out;
}

static int outside(const Servo *p, double x) { return x < 0.0 || x > p->stroke; }

/* First time in (a, b] at which x leaves [0, stroke], x monotone on [a, b] and inside at a. */
static double crossing(const Servo *p, State y, double a, double b)
{
    for (int k = 0; k < CROSSING_BISECTIONS; ++k) {
        const double mid = 0.5 * (a + b);
        if (outside(p, advance(p, y, mid).x)) b = mid; else a = mid;
    }
    return b;
}

/* Advances y by h, with the end stops. */
static State step(const Servo *p, State y, double h)
{
    double left = h;
    for (int contact = 0; contact < MAX_CONTACTS && left > 0.0; ++contact) {
        if ((y.x <= 0.0 && y.v <= 0.0 && p->w <= 0.0)
            || (y.x >= p->stroke && y.v >= 0.0 && p->w >= 0.0)) {
            y.v = 0.0; /* held by the stop for the rest of the step */
            return y;
        }
        /* v = 0 at s_turn if v and w have opposite signs: split the step there. */
        double s_turn = left;
        if (y.v * p->w < 0.0) s_turn = fmin(left, p->tau * log1p(-y.v / p->w));
        const double ends[2] = {s_turn, left};
        double hit = -1.0, start = 0.0;
        for (int piece = 0; piece < 2 && hit < 0.0; ++piece) {
            if (outside(p, advance(p, y, ends[piece]).x)) hit = crossing(p, y, start, ends[piece]);
            start = ends[piece];
        }
        if (hit < 0.0) return advance(p, y, left);
        State at = advance(p, y, hit);
        y.x = at.x > p->stroke ? p->stroke : (at.x < 0.0 ? 0.0 : at.x); /* onto the stop */
        y.v = 0.0;                                                        /* inelastic */
        left -= hit;
    }
    return y;
}

static const char *check_parameters(const double *v)
{
    if (!(v[VR_v_max] > 0.0 && isfinite(v[VR_v_max]))) return "v_max must be > 0 m/s";
    if (!(v[VR_tau] > 0.0 && isfinite(v[VR_tau]))) return "tau must be > 0 s";
    if (!(v[VR_stroke] > 0.0 && isfinite(v[VR_stroke]))) return "stroke must be > 0 m";
    if (!(v[VR_x0] >= 0.0 && v[VR_x0] <= v[VR_stroke])) return "x0 must lie in [0, stroke]";
    return NULL;
}

static void write_outputs(double *v, const State *s)
{
    v[VR_x] = s->x;
    v[VR_v] = s->v;
    v[VR_F] = v[VR_F_ext];
}

int model_initialize(double *v, void *state, const char **error)
{
    State *s = state;
    const char *problem = check_parameters(v);
    if (problem != NULL) {
        *error = problem;
        return 1;
    }
    s->x = v[VR_x0];
    s->v = 0.0;
    write_outputs(v, s);
    return 0;
}

/* The state from outside (a deserialized FMU state) must be one the model can continue. */
int model_check_state(const double *v, const void *state, const char **error)
{
    const State *s = state;
    if (!(isfinite(s->v) && s->x >= 0.0 && s->x <= v[VR_stroke])) {
        *error = "x must lie in [0, stroke] and v be finite";
        return 1;
    }
    return 0;
}

int model_do_step(double *v, void *state, double t, double h, const char **error)
{
    State *s = state;
    const double u = fmin(1.0, fmax(-1.0, v[VR_u]));
    const Servo p = {u * v[VR_v_max], v[VR_tau], v[VR_stroke]};
    (void)t;
    (void)error;
    *s = step(&p, *s, h);
    write_outputs(v, s);
    return 0;
}
