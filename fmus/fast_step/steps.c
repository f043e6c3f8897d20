/*
 * n co-simulation steps of one FMU as one foreign call: before step k the inputs' row k into
 * the bound input buffer, the one-call step (fmi2_step or fmi3_step) from t0 + k h, after it
 * the bound output buffer into the outputs' row k. A replay without Python between the steps
 * (fmus.runs.FastSlave.run: run_fmpy, bench/), stepping as a loop in C steps a plant
 * (orchestrator.plants.native).
 */
#include <stddef.h>
#include <string.h>

#define EXPORT __attribute__((visibility("default")))

/* The common head of Fmi2Step and Fmi3Step (fmus.fast_step.StepCall): one layout. */
typedef struct {
    void *instance;
    void *set_values, *get_values, *do_step;
    const unsigned int *vr_in;
    size_t n_in;
    double *inputs;
    const unsigned int *vr_out;
    size_t n_out;
    double *outputs;
} StepCall;

typedef int (*StepFunction)(const StepCall *call, double t, double h);

/* inputs (n, n_in) and outputs (n, n_out), row-major; outputs may be NULL. Returns 0, or the
 * failing step's code (fmi2_step.c) with *done = the steps completed before it. */
EXPORT int fmi_steps(StepFunction step, const StepCall *call, const double *inputs,
                     double *outputs, long n, double t0, double h, long *done)
{
    const size_t n_in = call->n_in, n_out = call->n_out;
    for (long k = 0; k < n; k++) {
        memcpy(call->inputs, inputs + (size_t)k * n_in, n_in * sizeof(double));
        const int code = step(call, t0 + (double)k * h, h);
        if (code) {
            *done = k;
            return code;
        }
        if (outputs != NULL) memcpy(outputs + (size_t)k * n_out, call->outputs,
                                    n_out * sizeof(double));
    }
    *done = n;
    return 0;
}
