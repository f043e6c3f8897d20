/*
 * The instance record of the shared FMI 2.0 layer, used by fmi2_cs.c (life cycle, get/set,
 * stepping) and fmi2_state.c (FMU state and its serialization). Internal: models never see it.
 */
#ifndef EXCOSIM_INSTANCE_H
#define EXCOSIM_INSTANCE_H

#include "fmi2Functions.h"
#include "model.h"

typedef enum {
    PHASE_INSTANTIATED, PHASE_INITIALIZATION, PHASE_STEP, PHASE_TERMINATED, PHASE_ERROR
} Phase;

typedef struct {
    double v[N_VARIABLES];
    double time;
    double start_time;
    Phase phase;
    int logging_on;
    fmi2CallbackLogger logger;
    fmi2ComponentEnvironment environment;
    char *name;
    void *state; /* model_state_size bytes, at least 1 */
    /* Scratch values and state (layer_core.h): the initial values computed in initialization
     * mode (valid while scratch_fresh), and the step being taken, so a failed one changes
     * nothing. */
    double scratch_v[N_VARIABLES];
    void *scratch_state;
    int scratch_fresh;
} Instance;

/* Size of the model's private state blob as allocated (at least 1 byte). */
size_t excosim_state_bytes(void);

/* Sends a printf-style message to the master's logger; fmi2OK messages only when logging is on. */
void excosim_log(const Instance *c, fmi2Status status, const char *category, const char *format,
                 ...);

#define LOG_ERROR(c, ...) excosim_log((c), fmi2Error, "logStatusError", __VA_ARGS__)
#define LOG_EVENT(c, ...) excosim_log((c), fmi2OK, "logEvents", __VA_ARGS__)

#endif
