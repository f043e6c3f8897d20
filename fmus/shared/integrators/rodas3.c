/* RODAS3 (rodas3.h): one step and its step-size controller. */
#include <math.h>

#include "rodas3.h"

static const double GAMMA = 0.5;

/* LU with partial pivoting of the n x n matrix A in place; 0 if singular. */
static int lu_factor(int n, double *A, int *pivot) {
    int i, j, k, best;
    double t;
    for (k = 0; k < n; k++) {
        best = k;
        for (i = k + 1; i < n; i++) {
            if (fabs(A[i * n + k]) > fabs(A[best * n + k])) best = i;
        }
        pivot[k] = best;
        if (!(A[best * n + k] != 0.0) || !isfinite(A[best * n + k])) return 0;
        if (best != k) {
            for (j = 0; j < n; j++) {
                t = A[k * n + j];
                A[k * n + j] = A[best * n + j];
                A[best * n + j] = t;
            }
        }
        for (i = k + 1; i < n; i++) {
            A[i * n + k] /= A[k * n + k];
            for (j = k + 1; j < n; j++) A[i * n + j] -= A[i * n + k] * A[k * n + j];
        }
    }
    return 1;
}

static void lu_solve(int n, const double *LU, const int *pivot, double *b) {
    int i, j;
    double t;
    for (i = 0; i < n; i++) {
        if (pivot[i] != i) {
            t = b[i];
            b[i] = b[pivot[i]];
            b[pivot[i]] = t;
        }
        for (j = 0; j < i; j++) b[i] -= LU[i * n + j] * b[j];
    }
    for (i = n - 1; i >= 0; i--) {
        for (j = i + 1; j < n; j++) b[i] -= LU[i * n + j] * b[j];
        b[i] /= LU[i * n + i];
    }
}

double rodas3_attempt(const void *context, rodas3_rhs f, int n, const double *y,
                      const double *f0, const double *J, double h, const double *scale,
                      double *y1) {
    double G[RODAS3_MAX_N * RODAS3_MAX_N], k1[RODAS3_MAX_N], k2[RODAS3_MAX_N], k3[RODAS3_MAX_N];
    double k4[RODAS3_MAX_N], stage[RODAS3_MAX_N], sum = 0.0;
    int pivot[RODAS3_MAX_N] = {0}, i;
    const double inv_h = 1.0 / h;
    for (i = 0; i < n * n; i++) G[i] = -J[i];
    for (i = 0; i < n; i++) G[i * n + i] += inv_h / GAMMA;
    if (!lu_factor(n, G, pivot)) return -1.0;

    for (i = 0; i < n; i++) k1[i] = f0[i];
    lu_solve(n, G, pivot, k1);
    for (i = 0; i < n; i++) k2[i] = f0[i] + 4.0 * inv_h * k1[i];
    lu_solve(n, G, pivot, k2);
    for (i = 0; i < n; i++) stage[i] = y[i] + 2.0 * k1[i];
    f(context, stage, k3);
    for (i = 0; i < n; i++) k3[i] += inv_h * (k1[i] - k2[i]);
    lu_solve(n, G, pivot, k3);
    for (i = 0; i < n; i++) stage[i] = y[i] + 2.0 * k1[i] + k3[i];
    f(context, stage, k4);
    for (i = 0; i < n; i++) k4[i] += inv_h * (k1[i] - k2[i] - 8.0 / 3.0 * k3[i]);
    lu_solve(n, G, pivot, k4);

    for (i = 0; i < n; i++) {
        double e = k4[i] / scale[i];
        y1[i] = y[i] + 2.0 * k1[i] + k3[i] + k4[i];
        sum += e * e;
    }
    sum = sqrt(sum / n);
    for (i = 0; i < n; i++) {
        if (!isfinite(y1[i])) return -1.0;
    }
    return isfinite(sum) ? sum : -1.0;
}

double rodas3_next_step(double h, double err) {
    double factor = err > 0.0 ? 0.9 * pow(err, -1.0 / 3.0) : 5.0;
    return h * (factor < 0.2 ? 0.2 : (factor > 5.0 ? 5.0 : factor));
}
