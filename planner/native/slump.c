/*
 * The surface estimate's slump kernel (planner.surface_estimate.Relax): half-sweeps over the
 * even, then the odd neighbour pairs (each set disjoint, so a pair's transfer does not depend on
 * the order within its set), each transfer levelling its pair to the allowed step exactly, until
 * no step exceeds it by more than `tolerance`. Built with the package and bound by the
 * orchestrator (orchestrator.campaign.native_slump), which hands it to the planner;
 * tests/slump_reference.py does the same arithmetic in the same order in numpy (the same bits).
 */
#include <math.h>

#define EXPORT __attribute__((visibility("default")))

/* Relaxes z (n heights, m) in place; returns the sweeps taken (max_sweeps if it did not settle). */
EXPORT long slump_relax(double *z, long n, double allowed, double tolerance, long max_sweeps)
{
    for (long sweep = 1; sweep <= max_sweeps; ++sweep) {
        double worst = 0.0;
        for (long first = 0; first < 2; ++first) {
            for (long i = first; i + 1 < n; i += 2) {
                const double step = z[i] - z[i + 1];
                const double excess = fabs(step) - allowed;
                if (excess > worst) worst = excess;
                /* A pair within the step moves 0.0, as the numpy form does (-0.0 + 0.0 is +0.0). */
                const double move = excess > 0.0 ? (step > 0.0 ? 0.5 * excess : -(0.5 * excess))
                                                 : 0.0;
                z[i] -= move;
                z[i + 1] += move;
            }
        }
        if (worst <= tolerance) return sweep;
    }
    return max_sweeps;
}
