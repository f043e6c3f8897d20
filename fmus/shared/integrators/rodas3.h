/*
 * RODAS3: a linearly implicit (Rosenbrock) method of order 3, 4 stages, 3 evaluations of f and
 * one LU of (I/(h gamma) - J) per step, L-stable and stiffly accurate, with an embedded
 * solution of order 2 for the error estimate (Sandu et al., "Benchmarking stiff ODE solvers for
 * atmospheric chemistry problems II: Rosenbrock solvers", Atmos. Environ. 31, 1997; the form of
 * Hairer & Wanner, Solving ODEs II, IV.7):
 *
 *   (I/(h gamma) - J) k_i = f(y + sum_j a_ij k_j) + sum_j (c_ij/h) k_j,   i = 1..4,
 *   y1 = y + sum_i m_i k_i,   error = k_4 (y1 minus the order-2 solution),
 *
 * gamma = 1/2; a_31 = a_41 = 2, a_43 = 1 (other a_ij 0: stage 2 reuses f(y));
 * c_21 = 4, c_31 = 1, c_32 = -1, c_41 = 1, c_42 = -1, c_43 = -8/3; m = (2, 0, 1, 1).
 * The system is autonomous over the step (its inputs are held). J = df/dy at y, exact: with
 * another matrix the order drops (a Rosenbrock method is not a W-method).
 */
#ifndef EXCOSIM_RODAS3_H
#define EXCOSIM_RODAS3_H

#define RODAS3_MAX_N 8

/* dy = f(y) of a system of n <= RODAS3_MAX_N states. */
typedef void (*rodas3_rhs)(const void *context, const double *y, double *dy);

/* One step of size h from y, f0 = f(y), J = df/dy at y (n x n, row-major; the caller
 * evaluates it once per state, so a rejected step retried from the same y does not pay for it
 * again): writes y1 and returns the error's root-mean-square norm with the weights 1/scale
 * (<= 1: within tolerance), or -1 when I/(h gamma) - J is singular or a value is not finite. */
double rodas3_attempt(const void *context, rodas3_rhs f, int n, const double *y,
                      const double *f0, const double *J, double h, const double *scale,
                      double *y1);

/* The next step size after a step of size h with error norm err (> 1: rejected), the usual
 * controller for an order-2 estimate: h * clamp(0.9 err^(-1/3), 0.2, 5). */
double rodas3_next_step(double h, double err);

#endif
