/*
 * One FMI 3.0 co-simulation step as one foreign call: fmi3SetFloat64 of the inputs, fmi3DoStep,
 * fmi3GetFloat64 of the outputs, through the FMU's own entry points (fmus.runs.FastSlave binds
 * them), as fmi2_step.c does for FMI 2.0. fmi3Boolean is C's bool.
 */
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#define EXPORT __attribute__((visibility("default")))

typedef int (*fmi3_set_float64)(void *instance, const uint32_t *vr, size_t n, const double *value,
                                size_t n_values);
typedef int (*fmi3_get_float64)(void *instance, const uint32_t *vr, size_t n, double *value,
                                size_t n_values);
typedef int (*fmi3_do_step)(void *instance, double t, double h, bool no_set_prior_state,
                            bool *event_handling_needed, bool *terminate, bool *early_return,
                            double *last_successful_time);

typedef struct {
    void *instance;
    fmi3_set_float64 set_float64;
    fmi3_get_float64 get_float64;
    fmi3_do_step do_step;
    const uint32_t *vr_in;
    size_t n_in;
    const double *inputs;
    const uint32_t *vr_out;
    size_t n_out;
    double *outputs;
} Fmi3Step;

/* 0 when all three calls returned fmi3OK or fmi3Warning; else (1 set, 2 step, 3 get) << 8 | the
 * failing call's status (its low byte: an FMU may return anything); 4 << 8 when the FMU asked
 * to terminate the simulation. */
EXPORT int fmi3_step(const Fmi3Step *s, double t, double h) {
    bool event = false, terminate = false, early = false;
    double last = 0.0;
    int status = s->set_float64(s->instance, s->vr_in, s->n_in, s->inputs, s->n_in);
    if (status > 1) return (1 << 8) | (status & 0xff);
    status = s->do_step(s->instance, t, h, true, &event, &terminate, &early, &last);
    if (status > 1) return (2 << 8) | (status & 0xff);
    if (terminate) return 4 << 8;
    status = s->get_float64(s->instance, s->vr_out, s->n_out, s->outputs, s->n_out);
    if (status > 1) return (3 << 8) | (status & 0xff);
    return 0;
}

EXPORT long fmi3_step_size(void) { return (long)sizeof(Fmi3Step); }
