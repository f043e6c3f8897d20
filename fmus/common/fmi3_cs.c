/*
 * Shared FMI 3.0 Co-Simulation layer: life cycle, get/set, stepping. The same model.c that the
 * FMI 2.0 layer (fmi2_cs.c) drives links against this one instead: the model contract
 * (model.h) and the generated variable table (variables.h) do not depend on the FMI version,
 * so an FMI 3.0 build computes exactly what the FMI 2.0 build does.
 *
 * Real variables are Float64, Integer Int32, Boolean Boolean. Co-simulation only, without
 * event mode, intermediate update or early return (the modelDescription says so). Like the
 * FMI 2.0 layer there are no mutable globals. fmi3_state.c and fmi3_stubs.c hold the rest of
 * the API: a binary must export every fmi3* function or importers (fmpy) refuse to load it.
 */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi3_instance.h"
#include "layer_core.h"

static const char *const TYPE_NAMES[] = {"Float64", "Int32", "Boolean"};

size_t excosim_state_bytes(void) { return model_state_size > 0 ? model_state_size : 1; }

void excosim_log(const Instance *c, fmi3Status status, const char *category, const char *format,
                 ...) {
    char text[512];
    va_list args;
    if (c == NULL || c->logger == NULL || (status == fmi3OK && !c->logging_on)) return;
    va_start(args, format);
    vsnprintf(text, sizeof text, format, args);
    va_end(args);
    c->logger(c->environment, status, category, text); /* FMI 3 takes a plain message */
}

const char *fmi3GetVersion(void) { return fmi3Version; }

fmi3Instance fmi3InstantiateCoSimulation(
    fmi3String instanceName, fmi3String instantiationToken, fmi3String resourcePath,
    fmi3Boolean visible, fmi3Boolean loggingOn, fmi3Boolean eventModeUsed,
    fmi3Boolean earlyReturnAllowed, const fmi3ValueReference requiredIntermediateVariables[],
    size_t nRequiredIntermediateVariables, fmi3InstanceEnvironment instanceEnvironment,
    fmi3LogMessageCallback logMessage, fmi3IntermediateUpdateCallback intermediateUpdate) {
    Instance probe = {0};
    Instance *c;
    (void)resourcePath, (void)visible, (void)earlyReturnAllowed;
    (void)requiredIntermediateVariables, (void)nRequiredIntermediateVariables;
    (void)intermediateUpdate;
    probe.logger = logMessage;
    probe.environment = instanceEnvironment;
    if (instanceName == NULL || instanceName[0] == '\0') {
        LOG_ERROR(&probe, "fmi3InstantiateCoSimulation: instanceName must be non-empty");
        return NULL;
    }
    if (eventModeUsed) {
        LOG_ERROR(&probe, "fmi3InstantiateCoSimulation: %s has no event mode",
                  MODEL_IDENTIFIER_STRING);
        return NULL;
    }
    if (instantiationToken == NULL || strcmp(instantiationToken, MODEL_GUID) != 0) {
        LOG_ERROR(&probe, "fmi3InstantiateCoSimulation: token %s does not match this binary's %s",
                  instantiationToken != NULL ? instantiationToken : "(null)", MODEL_GUID);
        return NULL;
    }
    c = instance_new(&probe, instanceName, loggingOn);
    if (c == NULL) return NULL;
    LOG_EVENT(c, "instantiated %s", MODEL_IDENTIFIER_STRING);
    return c;
}

void fmi3FreeInstance(fmi3Instance instance) { instance_free(instance); }

fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn, size_t nCategories,
                               const fmi3String categories[]) {
    Instance *c = instance;
    (void)nCategories, (void)categories; /* every category follows the one switch */
    if (c == NULL) return fmi3Error;
    c->logging_on = loggingOn;
    return fmi3OK;
}

fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined,
                                       fmi3Float64 tolerance, fmi3Float64 startTime,
                                       fmi3Boolean stopTimeDefined, fmi3Float64 stopTime) {
    Instance *c = instance;
    (void)toleranceDefined, (void)tolerance, (void)stopTimeDefined, (void)stopTime;
    if (c == NULL || wrong_phase(c, PH(PHASE_INSTANTIATED), "fmi3EnterInitializationMode"))
        return fmi3Error;
    if (!isfinite(startTime)) {
        LOG_ERROR(c, "fmi3EnterInitializationMode: startTime must be finite");
        return fmi3Error;
    }
    c->start_time = c->time = startTime;
    c->phase = PHASE_INITIALIZATION;
    return fmi3OK;
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance instance) {
    Instance *c = instance;
    if (c == NULL || wrong_phase(c, PH(PHASE_INITIALIZATION), "fmi3ExitInitializationMode") ||
        exit_initialization(c, "fmi3ExitInitializationMode") != 0) {
        return fmi3Error;
    }
    LOG_EVENT(c, "initialized at t = %g s", c->time);
    return fmi3OK;
}

fmi3Status fmi3Terminate(fmi3Instance instance) {
    Instance *c = instance;
    if (c == NULL || wrong_phase(c, PH(PHASE_STEP), "fmi3Terminate")) return fmi3Error;
    c->phase = PHASE_TERMINATED;
    return fmi3OK;
}

fmi3Status fmi3Reset(fmi3Instance instance) {
    Instance *c = instance;
    if (c == NULL) return fmi3Error;
    set_start_values(c);
    return fmi3OK;
}

/* ---- get and set: the checks of the FMI 2.0 layer, with FMI 3's nValues ---------------------- */

/* FMI 3 requires an independent variable: "time", value reference N_VARIABLES (one past the
 * table), readable with fmi3GetFloat64 only. */
#define VR_TIME N_VARIABLES

static double value_at(const Instance *c, fmi3ValueReference vr) {
    return vr == VR_TIME ? c->time : value_of(c, vr);
}

static int bad_access(Instance *c, const fmi3ValueReference vr[], size_t nvr, const void *values,
                      size_t n_values, excosim_type type, int getter, const char *function) {
    size_t i;
    if (nvr > 0 && (vr == NULL || values == NULL)) {
        LOG_ERROR(c, "%s: value reference and value arrays must not be NULL", function);
        return 1;
    }
    if (n_values != nvr) { /* scalars only: one value per value reference */
        LOG_ERROR(c, "%s: nValues %zu differs from nValueReferences %zu", function, n_values, nvr);
        return 1;
    }
    for (i = 0; i < nvr; i++) {
        if (vr[i] == VR_TIME && getter && type == VT_REAL) continue;
        if (vr[i] >= N_VARIABLES) {
            LOG_ERROR(c, "%s: unknown or read-only value reference %u", function, vr[i]);
            return 1;
        }
        if (VARIABLES[vr[i]].type != type) {
            LOG_ERROR(c, "%s: variable '%s' (vr %u) is a %s, not a %s", function,
                      VARIABLES[vr[i]].name, vr[i], TYPE_NAMES[VARIABLES[vr[i]].type],
                      TYPE_NAMES[type]);
            return 1;
        }
    }
    return 0;
}

/* One getter and one setter per type; CONVERT_GET / CONVERT_SET map the stored double. */
#define ACCESSORS(Name, T, VT, CONVERT_GET, CONVERT_SET)                                        \
    fmi3Status fmi3Get##Name(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, \
                             T values[], size_t nValues) {                                      \
        Instance *c = instance;                                                                 \
        size_t i;                                                                               \
        if (c == NULL || bad_access(c, vr, nvr, values, nValues, VT, 1, "fmi3Get" #Name)        \
            || prepare_get(c, vr, nvr, "fmi3Get" #Name))                                        \
            return fmi3Error;                                                                   \
        for (i = 0; i < nvr; i++) values[i] = CONVERT_GET(value_at(c, vr[i]));                  \
        return fmi3OK;                                                                          \
    }                                                                                           \
    fmi3Status fmi3Set##Name(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, \
                             const T values[], size_t nValues) {                                \
        Instance *c = instance;                                                                 \
        size_t i;                                                                               \
        if (c == NULL || bad_access(c, vr, nvr, values, nValues, VT, 0, "fmi3Set" #Name)        \
            || not_settable(c, vr, nvr, "fmi3Set" #Name))                                       \
            return fmi3Error;                                                                   \
        for (i = 0; i < nvr; i++) {                                                             \
            if (bad_value(c, vr[i], CONVERT_SET(values[i]), "fmi3Set" #Name)) return fmi3Error; \
        }                                                                                       \
        for (i = 0; i < nvr; i++) c->v[vr[i]] = CONVERT_SET(values[i]);                         \
        values_changed(c);                                                                      \
        return fmi3OK;                                                                          \
    }

#define AS_IS(x) (x)
#define TO_INT32(x) ((fmi3Int32)(x))
#define TO_BOOL(x) ((x) != 0.0)
#define FROM_BOOL(x) ((x) ? 1.0 : 0.0)

ACCESSORS(Float64, fmi3Float64, VT_REAL, AS_IS, AS_IS)
ACCESSORS(Int32, fmi3Int32, VT_INTEGER, TO_INT32, (double))
ACCESSORS(Boolean, fmi3Boolean, VT_BOOLEAN, TO_BOOL, FROM_BOOL)

/* ---- stepping ------------------------------------------------------------------------------- */

fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint,
                      fmi3Float64 communicationStepSize,
                      fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                      fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation,
                      fmi3Boolean *earlyReturn, fmi3Float64 *lastSuccessfulTime) {
    Instance *c = instance;
    (void)noSetFMUStatePriorToCurrentPoint;
    if (c == NULL || wrong_phase(c, PH(PHASE_STEP), "fmi3DoStep")) return fmi3Error;
    if (eventHandlingNeeded != NULL) *eventHandlingNeeded = fmi3False;
    if (terminateSimulation != NULL) *terminateSimulation = fmi3False;
    if (earlyReturn != NULL) *earlyReturn = fmi3False;
    if (lastSuccessfulTime != NULL) *lastSuccessfulTime = c->time;
    if (do_step(c, currentCommunicationPoint, communicationStepSize, "fmi3DoStep") != 0) {
        return fmi3Error;
    }
    if (lastSuccessfulTime != NULL) *lastSuccessfulTime = c->time;
    return fmi3OK;
}
