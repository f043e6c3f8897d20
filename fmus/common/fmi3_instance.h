/*
 * The instance record of the shared FMI 3.0 layer, used by fmi3_cs.c (life cycle, get/set,
 * stepping), fmi3_state.c (FMU state) and fmi3_stubs.c (functions we do not provide). It holds
 * the same things as the FMI 2.0 instance (instance.h): models never see either.
 */
#ifndef EXCOSIM_FMI3_INSTANCE_H
#define EXCOSIM_FMI3_INSTANCE_H

#include "fmi3Functions.h"
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
    fmi3LogMessageCallback logger;
    fmi3InstanceEnvironment environment;
    char *name;
    void *state; /* model_state_size bytes, at least 1 */
    /* Scratch values and state (layer_core.h): the initial values computed in initialization
     * mode (valid while scratch_fresh), and the step being taken, so a failed one changes
     * nothing. */
    double scratch_v[N_VARIABLES];
    void *scratch_state;
    int scratch_fresh;
} Instance;

size_t excosim_state_bytes(void);

/* Sends a printf-style message to the importer's logger; fmi3OK ones only when logging is on. */
void excosim_log(const Instance *c, fmi3Status status, const char *category, const char *format,
                 ...);

#define LOG_ERROR(c, ...) excosim_log((c), fmi3Error, "logStatusError", __VA_ARGS__)
#define LOG_EVENT(c, ...) excosim_log((c), fmi3OK, "logEvents", __VA_ARGS__)

#endif
