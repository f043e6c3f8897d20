/*
 * The rules of the shared FMI layers, written once for FMI 2.0 (fmi2_cs.c, fmi2_state.c) and
 * FMI 3.0 (fmi3_cs.c, fmi3_state.c), which include it after their own instance header (Instance,
 * Phase, LOG_ERROR) and wrap it in their API's names and status codes: instance life cycle, when
 * a variable may be set and which values it may take, the initial values in initialization mode,
 * the step, and the checks of what the model computes. Functions that return int give 0 on
 * success and -1 on an error they have logged. They are static inline so a file that includes
 * this header without using all of them compiles warning-free (-Werror).
 */
#ifndef EXCOSIM_LAYER_CORE_H
#define EXCOSIM_LAYER_CORE_H

#include <math.h>
#include <stdlib.h>
#include <string.h>

static const char *const PHASE_NAMES[] = {
    "instantiated", "initialization mode", "step mode", "terminated", "error"
};

#define PH(p) (1u << (p))

/* Returns nonzero (and logs) when `c` is not in one of the phases in `allowed` (bit per Phase). */
static inline int wrong_phase(const Instance *c, unsigned allowed, const char *function) {
    if (allowed & PH(c->phase)) return 0;
    LOG_ERROR(c, "%s must not be called in %s", function, PHASE_NAMES[c->phase]);
    return 1;
}

static inline void set_start_values(Instance *c) {
    int i;
    for (i = 0; i < N_VARIABLES; i++) c->v[i] = VARIABLES[i].start;
    memset(c->state, 0, excosim_state_bytes());
    c->time = c->start_time = 0.0;
    c->phase = PHASE_INSTANTIATED;
    c->scratch_fresh = 0;
}

/* A new instance with the logger of `probe` and a copy of `name`, at its start values. */
static inline Instance *instance_new(const Instance *probe, const char *name, int logging_on) {
    Instance *c = calloc(1, sizeof *c);
    if (c == NULL) return NULL;
    *c = *probe;
    c->name = malloc(strlen(name) + 1);
    c->state = calloc(1, excosim_state_bytes());
    c->scratch_state = calloc(1, excosim_state_bytes());
    if (c->name == NULL || c->state == NULL || c->scratch_state == NULL) {
        free(c->name);
        free(c->state);
        free(c->scratch_state);
        free(c);
        return NULL;
    }
    strcpy(c->name, name);
    c->logging_on = logging_on;
    set_start_values(c);
    return c;
}

static inline void instance_free(Instance *c) {
    if (c == NULL) return;
    free(c->scratch_state);
    free(c->state);
    free(c->name);
    free(c);
}

/* ---- values ---------------------------------------------------------------------------------- */

/* Checks that every variable in vr may be set now (FMI 2.0 section 4.2.4, FMI 3.0 2.3.4). */
static inline int not_settable(const Instance *c, const unsigned vr[], size_t nvr,
                               const char *function) {
    static const int phase_bit[] = {SET_INSTANTIATED, SET_INIT, SET_STEP, 0, 0};
    size_t i;
    for (i = 0; i < nvr; i++) {
        if (!(VARIABLES[vr[i]].set_phases & phase_bit[c->phase])) {
            LOG_ERROR(c, "%s: variable '%s' cannot be set in %s", function, VARIABLES[vr[i]].name,
                      PHASE_NAMES[c->phase]);
            return 1;
        }
    }
    return 0;
}

/* What is wrong with `value` for variable vr, or NULL: a Real must be finite, an Integer a 32-bit
 * integer, a Boolean 0 or 1, and a parameter or input must lie in the table's [min, max] (FMI
 * lets an FMU refuse a value outside it with an error; the model never sees one). */
static inline const char *value_problem(unsigned vr, double value) {
    const excosim_variable *var = &VARIABLES[vr];
    if (!isfinite(value)) return "is not finite";
    if (var->type == VT_INTEGER
        && (value != floor(value) || value < -2147483648.0 || value > 2147483647.0)) {
        return "is not a 32-bit integer";
    }
    if (var->type == VT_BOOLEAN && value != 0.0 && value != 1.0) return "is not a Boolean";
    if ((var->causality == CA_PARAMETER || var->causality == CA_INPUT)
        && !(value >= var->min && value <= var->max)) {
        return "lies outside its range";
    }
    return NULL;
}

/* Returns nonzero (and logs, naming the variable) when vr may not take `value`. */
static inline int bad_value(const Instance *c, unsigned vr, double value, const char *function) {
    const char *problem = value_problem(vr, value);
    if (problem == NULL) return 0;
    if (isfinite(value) && VARIABLES[vr].type != VT_BOOLEAN) {
        LOG_ERROR(c, "%s: value of '%s' %s [%g, %g]: %.17g", function, VARIABLES[vr].name,
                  problem, VARIABLES[vr].min, VARIABLES[vr].max, value);
    } else {
        LOG_ERROR(c, "%s: value of '%s' %s: %g", function, VARIABLES[vr].name, problem, value);
    }
    return 1;
}

/* Returns nonzero (and logs, naming the variable) unless every value the model computed is
 * finite and its state passes the model's own check. An output clipped by the model (fmax(p, 0)
 * of a NaN is 0) can hide a broken state, hence the state check. `what` names the call. */
static inline int bad_results(const Instance *c, const double *v, const void *state,
                              const char *what, double t) {
    const char *error = "unknown error";
    int i;
    for (i = 0; i < N_VARIABLES; i++) {
        if (!isfinite(v[i])) {
            LOG_ERROR(c, "%s at t = %g s produced a non-finite '%s' (%g)", what, t,
                      VARIABLES[i].name, v[i]);
            return 1;
        }
    }
    if (model_check_state != NULL && model_check_state(v, state, &error) != 0) {
        LOG_ERROR(c, "%s at t = %g s left an invalid model state: %s", what, t, error);
        return 1;
    }
    return 0;
}

/* ---- initialization ------------------------------------------------------------------------ */

/* Variables whose values the model computes (read from the initial values in init mode); a
 * value reference past the table (FMI 3's time) is none. */
static inline int computed(unsigned vr) {
    excosim_causality causality;
    if (vr >= N_VARIABLES) return 0;
    causality = VARIABLES[vr].causality;
    return causality == CA_OUTPUT || causality == CA_CALCULATED_PARAMETER || causality == CA_LOCAL;
}

/* The initial values into the scratch copy: model_initialize on the current parameters, start
 * values and state, which stay untouched until fmiXExitInitializationMode commits them. So an
 * importer reads the initial outputs and calculated parameters in initialization mode, as FMI
 * requires (a coupled load then starts at its initial value, not 0). Cached until a set. */
static inline int initial_values(Instance *c, const char *function) {
    const char *error = "unknown error";
    if (c->scratch_fresh) return 0;
    memcpy(c->scratch_v, c->v, sizeof c->v);
    memcpy(c->scratch_state, c->state, excosim_state_bytes());
    if (model_initialize(c->scratch_v, c->scratch_state, &error) != 0) {
        LOG_ERROR(c, "%s: initialization failed: %s", function, error);
        return -1;
    }
    if (bad_results(c, c->scratch_v, c->scratch_state, "initialization", c->time)) return -1;
    c->scratch_fresh = 1;
    return 0;
}

/* Before a get: in initialization mode a computed variable needs the initial values. */
static inline int prepare_get(Instance *c, const unsigned vr[], size_t nvr, const char *function) {
    size_t i;
    if (c->phase != PHASE_INITIALIZATION) return 0;
    for (i = 0; i < nvr; i++) {
        if (computed(vr[i])) return initial_values(c, function);
    }
    return 0;
}

/* The value a get returns (after prepare_get). */
static inline double value_of(const Instance *c, unsigned vr) {
    if (c->phase == PHASE_INITIALIZATION && c->scratch_fresh && computed(vr)) {
        return c->scratch_v[vr];
    }
    return c->v[vr];
}

/* After a successful set: the initial values must be computed again. */
static inline void values_changed(Instance *c) { c->scratch_fresh = 0; }

/* fmiXExitInitializationMode: the initial values become the instance's; on failure nothing
 * changes but the phase (error). */
static inline int exit_initialization(Instance *c, const char *function) {
    void *swap;
    if (initial_values(c, function) != 0) {
        c->phase = PHASE_ERROR;
        return -1;
    }
    memcpy(c->v, c->scratch_v, sizeof c->v);
    swap = c->state, c->state = c->scratch_state, c->scratch_state = swap;
    c->scratch_fresh = 0;
    c->phase = PHASE_STEP;
    return 0;
}

/* ---- stepping ------------------------------------------------------------------------------- */

/* One communication step from t by h. It runs on the scratch copy and is committed only when the
 * model succeeds and its results are finite: after an error the instance keeps the values and
 * state of the last good communication point (and is in the error phase). */
static inline int do_step(Instance *c, double t, double h, const char *function) {
    const char *error = "unknown error";
    void *swap;
    if (!(h > 0.0) || !isfinite(h)) {
        LOG_ERROR(c, "%s: communicationStepSize must be > 0 and finite, got %g", function, h);
        return -1;
    }
    /* The master's clock is authoritative; only a real mismatch (not round-off) is an error. */
    if (!(fabs(t - c->time) <= 1e-9 * fmax(1.0, fabs(c->time)))) {
        LOG_ERROR(c, "%s: currentCommunicationPoint %.17g differs from the FMU time %.17g",
                  function, t, c->time);
        return -1;
    }
    if (!isfinite(t + h)) {
        LOG_ERROR(c, "%s: the step from t = %g s by %g s ends at a non-finite time", function, t,
                  h);
        return -1;
    }
    memcpy(c->scratch_v, c->v, sizeof c->v);
    memcpy(c->scratch_state, c->state, excosim_state_bytes());
    c->scratch_fresh = 0;
    if (model_do_step(c->scratch_v, c->scratch_state, t, h, &error) != 0) {
        c->phase = PHASE_ERROR;
        LOG_ERROR(c, "step at t = %g s failed: %s", t, error);
        return -1;
    }
    if (bad_results(c, c->scratch_v, c->scratch_state, "step", t)) {
        c->phase = PHASE_ERROR;
        return -1;
    }
    memcpy(c->v, c->scratch_v, sizeof c->v);
    swap = c->state, c->state = c->scratch_state, c->scratch_state = swap;
    c->time = t + h;
    return 0;
}

#endif
