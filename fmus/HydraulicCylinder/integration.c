/*
 * The cylinder's two integrators over one communication step, inputs held (cylinder.h):
 *
 * RK4 (integrator = 0): n equal substeps, the stage powers integrated with the RK4 weights.
 *   Explicit: the substep must stay inside RK4's stability region (model.c's stiffness bound),
 *   which the hydraulic mode and the orifice gain put near 0.2 ms.
 * RODAS3 (integrator = 1, fmus/shared/integrators/rodas3.h): linearly implicit with the exact
 *   Jacobian (model.c), L-stable, so the substep is sized for accuracy only: each substep's
 *   error estimate is held within tolerance * (stroke, full speed q_rated/A_B, the higher of
 *   supply and relief pressure) in the root-mean-square norm, and the next substep follows
 *   from it. The next communication step starts from the smaller of the size proposed at this
 *   step's end and the one proposed after its first substep: the inputs jump at every step's
 *   start, and a size grown over the smooth rest of a step was rejected there about twice per
 *   step on the paper's boom (2798 of 8000 attempts at 1e-7, 52 now). The powers
 *   are integrated with the trapezoidal rule over each substep (f at its end is the next
 *   substep's f(y) anyway), so the energy balance closes to that rule's error, O(h^3) per
 *   substep where the motion is smooth. The Jacobian is evaluated once per accepted state,
 *   from the f(y) at hand: a rejected substep retried from the same state reuses it.
 * Both: after each substep the stroke is clamped to [0, stroke] and a velocity into the stop
 *   zeroed; the stop takes the kinetic energy of what is zeroed.
 */
#include <math.h>

#include "cylinder.h"
#include "rodas3.h"

/* Accepted and rejected RODAS3 substeps of one communication step at most: far beyond the
 * few tens a step takes, it stops a step that can make no progress. */
static const long MAX_ATTEMPTS = 100000;

static void axpy(Y *out, const Y *y, double h, const Y *k) {
    out->x = y->x + h * k->x;
    out->v = y->v + h * k->v;
    out->psi_A = y->psi_A + h * k->psi_A;
    out->psi_B = y->psi_B + h * k->psi_B;
}

/* The inelastic end stops after a substep; their kinetic energy goes to energy[W_END_STOP]. */
static void end_stops(const P *p, Y *y, double *energy) {
    double v_before = y->v;
    if (y->x <= 0.0) {
        y->x = 0.0;
        y->v = fmax(y->v, 0.0);
    } else if (y->x >= p->stroke) {
        y->x = p->stroke;
        y->v = fmin(y->v, 0.0);
    }
    energy[W_END_STOP] += 0.5 * p->M * (v_before * v_before - y->v * y->v);
}

static void rk4_substep(const P *p, Y *y, double *energy, double h) {
    Y k1, k2, k3, k4, t;
    double w1[N_POWER], w2[N_POWER], w3[N_POWER], w4[N_POWER];
    int i;
    cylinder_derivatives(p, y, &k1, w1);
    axpy(&t, y, 0.5 * h, &k1);
    cylinder_derivatives(p, &t, &k2, w2);
    axpy(&t, y, 0.5 * h, &k2);
    cylinder_derivatives(p, &t, &k3, w3);
    axpy(&t, y, h, &k3);
    cylinder_derivatives(p, &t, &k4, w4);
    y->x += h / 6.0 * (k1.x + 2.0 * k2.x + 2.0 * k3.x + k4.x);
    y->v += h / 6.0 * (k1.v + 2.0 * k2.v + 2.0 * k3.v + k4.v);
    y->psi_A += h / 6.0 * (k1.psi_A + 2.0 * k2.psi_A + 2.0 * k3.psi_A + k4.psi_A);
    y->psi_B += h / 6.0 * (k1.psi_B + 2.0 * k2.psi_B + 2.0 * k3.psi_B + k4.psi_B);
    for (i = 0; i < N_POWER; i++) {
        energy[i] += h / 6.0 * (w1[i] + 2.0 * w2[i] + 2.0 * w3[i] + w4[i]);
    }
    end_stops(p, y, energy);
}

void cylinder_rk4(const P *p, Y *y, double *energy, double h, long substeps) {
    double h_sub = h / (double)substeps;
    long i;
    for (i = 0; i < substeps; i++) rk4_substep(p, y, energy, h_sub);
}

static void rhs(const void *context, const double *y, double *dy) {
    double w[N_POWER];
    cylinder_derivatives(context, (const Y *)y, (Y *)dy, w);
}

const char *cylinder_rodas3(const P *p, Y *y, double *energy, double h, const double *scale,
                            double *h_next, double *accepted, double *rejected) {
    Y f0, f1, y1;
    double w0[N_POWER], w1[N_POWER], J[N_STATES * N_STATES], done = 0.0, proposed, err, hs;
    double first = 0.0; /* what the controller proposed after this step's first substep */
    long attempts = 0;
    int i, last;
    proposed = *h_next > 0.0 ? *h_next : 0.1 * h;
    cylinder_derivatives(p, y, &f0, w0);
    cylinder_jacobian(p, y, &f0, J);
    while (done < h) {
        if (++attempts > MAX_ATTEMPTS) {
            return "RODAS3 made no progress: 100000 substeps in one communication step";
        }
        /* the last substep of the step takes what is left, never leaving a sliver after it */
        last = done + 1.05 * proposed >= h;
        hs = last ? h - done : proposed;
        err = rodas3_attempt(p, rhs, N_STATES, (const double *)y, (const double *)&f0, J, hs,
                             scale, (double *)&y1);
        if (err < 0.0 || err > 1.0) { /* rejected: smaller (a quarter if not finite) */
            *rejected += 1.0;
            proposed = err < 0.0 ? 0.25 * hs : rodas3_next_step(hs, err);
            if (!(proposed > 1e-14 * h)) return "RODAS3 substep underflow (below 1e-14 h)";
            continue;
        }
        *accepted += 1.0;
        if (first == 0.0) first = rodas3_next_step(hs, err);
        end_stops(p, &y1, energy);
        cylinder_derivatives(p, &y1, &f1, w1);
        for (i = 0; i < N_POWER; i++) energy[i] += 0.5 * hs * (w0[i] + w1[i]);
        *y = y1;
        f0 = f1;
        for (i = 0; i < N_POWER; i++) w0[i] = w1[i];
        if (!last) cylinder_jacobian(p, y, &f0, J); /* the next step starts with its own */
        done = last ? h : done + hs;
        /* a last substep cut short says nothing against the size before it */
        proposed = last ? fmax(proposed, rodas3_next_step(hs, err))
                        : rodas3_next_step(hs, err);
    }
    *h_next = fmin(proposed, first);
    return 0;
}
