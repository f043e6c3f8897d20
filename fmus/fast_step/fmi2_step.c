/*
 * One FMI 2.0 co-simulation step as one foreign call: fmi2SetReal of the inputs, fmi2DoStep,
 * fmi2GetReal of the outputs, through the FMU's own entry points (fmus.runs.FastSlave binds
 * them). From Python each foreign call costs more than the FMI call itself, so three calls per
 * step become one. The caller's Python frame stays on the stack through the call: a step that
 * hangs or crashes is still named by it (the step watchdog, the crash report).
 */
#include <stddef.h>

#define EXPORT __attribute__((visibility("default")))

typedef int (*fmi2_set_real)(void *component, const unsigned int *vr, size_t n,
                             const double *value);
typedef int (*fmi2_get_real)(void *component, const unsigned int *vr, size_t n, double *value);
typedef int (*fmi2_do_step)(void *component, double t, double h, int no_set_prior_state);

typedef struct {
    void *component;
    fmi2_set_real set_real;
    fmi2_get_real get_real;
    fmi2_do_step do_step;
    const unsigned int *vr_in;
    size_t n_in;
    const double *inputs;
    const unsigned int *vr_out;
    size_t n_out;
    double *outputs;
} Fmi2Step;

/* 0 when all three calls returned fmi2OK or fmi2Warning; else (1 set, 2 step, 3 get) << 8 | the
 * failing call's status (its low byte: an FMU may return anything). */
EXPORT int fmi2_step(const Fmi2Step *s, double t, double h) {
    int status = s->set_real(s->component, s->vr_in, s->n_in, s->inputs);
    if (status > 1) return (1 << 8) | (status & 0xff);
    status = s->do_step(s->component, t, h, 1);
    if (status > 1) return (2 << 8) | (status & 0xff);
    status = s->get_real(s->component, s->vr_out, s->n_out, s->outputs);
    if (status > 1) return (3 << 8) | (status & 0xff);
    return 0;
}

EXPORT long fmi2_step_size(void) { return (long)sizeof(Fmi2Step); }
