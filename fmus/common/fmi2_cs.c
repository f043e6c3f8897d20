/*
 * Shared FMI 2.0 Co-Simulation layer: life cycle, get/set, stepping. Every model links this file
 * (and fmi2_state.c) with its own model.c; the model supplies only model_state_size,
 * model_initialize and model_do_step (see model.h), and the builder generates the variable table
 * (variables.h).
 *
 * An instance holds the value array v[] (indexed by value reference; Integer and Boolean values
 * stored as doubles), the model's private state blob and the time. There are no mutable globals,
 * so any number of instances can share one loaded binary.
 */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "instance.h"
#include "layer_core.h"

size_t excosim_state_bytes(void) { return model_state_size > 0 ? model_state_size : 1; }

void excosim_log(const Instance *c, fmi2Status status, const char *category, const char *format,
                 ...) {
    char text[512];
    va_list args;
    if (c == NULL || c->logger == NULL || (status == fmi2OK && !c->logging_on)) return;
    va_start(args, format);
    vsnprintf(text, sizeof text, format, args);
    va_end(args);
    /* Pass the text as an argument so a '%' in a name never reaches the format. */
    c->logger(c->environment, c->name, status, category, "%s", text);
}

/* ---- inquiry, instantiation ---------------------------------------------------------------- */

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }

const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation,
                              const fmi2CallbackFunctions *functions, fmi2Boolean visible,
                              fmi2Boolean loggingOn) {
    Instance probe = {0};
    Instance *c;
    (void)fmuResourceLocation;
    (void)visible;
    probe.logger = functions != NULL ? functions->logger : NULL;
    probe.environment = functions != NULL ? functions->componentEnvironment : NULL;
    probe.name = (char *)(instanceName != NULL ? instanceName : "?");
    if (instanceName == NULL || instanceName[0] == '\0') {
        LOG_ERROR(&probe, "fmi2Instantiate: instanceName must be a non-empty string");
        return NULL;
    }
    if (fmuType != fmi2CoSimulation) {
        LOG_ERROR(&probe, "fmi2Instantiate: %s supports Co-Simulation only",
                  MODEL_IDENTIFIER_STRING);
        return NULL;
    }
    if (fmuGUID == NULL || strcmp(fmuGUID, MODEL_GUID) != 0) {
        LOG_ERROR(&probe, "fmi2Instantiate: GUID %s does not match this binary's %s",
                  fmuGUID != NULL ? fmuGUID : "(null)", MODEL_GUID);
        return NULL;
    }
    c = instance_new(&probe, instanceName, loggingOn != fmi2False);
    if (c == NULL) return NULL;
    LOG_EVENT(c, "instantiated %s", MODEL_IDENTIFIER_STRING);
    return c;
}

void fmi2FreeInstance(fmi2Component component) { instance_free(component); }

fmi2Status fmi2SetDebugLogging(fmi2Component component, fmi2Boolean loggingOn,
                               size_t nCategories, const fmi2String categories[]) {
    static const char *const known[] = {"logStatusError", "logStatusWarning", "logEvents"};
    Instance *c = component;
    size_t i, k;
    if (c == NULL) return fmi2Error;
    for (i = 0; i < nCategories; i++) {
        int found = 0;
        for (k = 0; k < sizeof known / sizeof known[0]; k++) {
            if (categories[i] != NULL && strcmp(categories[i], known[k]) == 0) found = 1;
        }
        if (!found) {
            LOG_ERROR(c, "fmi2SetDebugLogging: unknown log category '%s'",
                      categories[i] != NULL ? categories[i] : "(null)");
            return fmi2Error;
        }
    }
    c->logging_on = loggingOn != fmi2False;
    return fmi2OK;
}

/* ---- initialization, termination --------------------------------------------------------- */

fmi2Status fmi2SetupExperiment(fmi2Component component, fmi2Boolean toleranceDefined,
                               fmi2Real tolerance, fmi2Real startTime, fmi2Boolean stopTimeDefined,
                               fmi2Real stopTime) {
    Instance *c = component;
    (void)toleranceDefined;
    (void)tolerance;
    (void)stopTimeDefined;
    (void)stopTime;
    if (c == NULL || wrong_phase(c, PH(PHASE_INSTANTIATED), "fmi2SetupExperiment")) {
        return fmi2Error;
    }
    if (!isfinite(startTime)) {
        LOG_ERROR(c, "fmi2SetupExperiment: startTime must be finite");
        return fmi2Error;
    }
    c->start_time = startTime;
    c->time = startTime;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component component) {
    Instance *c = component;
    if (c == NULL || wrong_phase(c, PH(PHASE_INSTANTIATED), "fmi2EnterInitializationMode")) {
        return fmi2Error;
    }
    c->phase = PHASE_INITIALIZATION;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component component) {
    Instance *c = component;
    if (c == NULL || wrong_phase(c, PH(PHASE_INITIALIZATION), "fmi2ExitInitializationMode") ||
        exit_initialization(c, "fmi2ExitInitializationMode") != 0) {
        return fmi2Error;
    }
    LOG_EVENT(c, "initialized at t = %g s", c->time);
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component component) {
    Instance *c = component;
    if (c == NULL || wrong_phase(c, PH(PHASE_STEP), "fmi2Terminate")) return fmi2Error;
    c->phase = PHASE_TERMINATED;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component component) {
    Instance *c = component;
    if (c == NULL) return fmi2Error;
    set_start_values(c);
    return fmi2OK;
}

/* ---- get and set ---------------------------------------------------------------------------- */

static const char *const TYPE_NAMES[] = {"Real", "Integer", "Boolean"};

/* Checks a get/set call's arguments; returns nonzero (and logs) on a bad one. */
static int bad_access(Instance *c, const fmi2ValueReference vr[], size_t nvr, const void *values,
                      excosim_type type, const char *function) {
    size_t i;
    if (nvr > 0 && (vr == NULL || values == NULL)) {
        LOG_ERROR(c, "%s: vr and value arrays must not be NULL", function);
        return 1;
    }
    for (i = 0; i < nvr; i++) {
        if (vr[i] >= N_VARIABLES) {
            LOG_ERROR(c, "%s: unknown value reference %u (the model has %d variables)", function,
                      vr[i], N_VARIABLES);
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

fmi2Status fmi2GetReal(fmi2Component component, const fmi2ValueReference vr[], size_t nvr,
                       fmi2Real value[]) {
    Instance *c = component;
    size_t i;
    if (c == NULL || bad_access(c, vr, nvr, value, VT_REAL, "fmi2GetReal") ||
        prepare_get(c, vr, nvr, "fmi2GetReal")) {
        return fmi2Error;
    }
    for (i = 0; i < nvr; i++) value[i] = value_of(c, vr[i]);
    return fmi2OK;
}

fmi2Status fmi2GetInteger(fmi2Component component, const fmi2ValueReference vr[], size_t nvr,
                          fmi2Integer value[]) {
    Instance *c = component;
    size_t i;
    if (c == NULL || bad_access(c, vr, nvr, value, VT_INTEGER, "fmi2GetInteger") ||
        prepare_get(c, vr, nvr, "fmi2GetInteger")) {
        return fmi2Error;
    }
    for (i = 0; i < nvr; i++) value[i] = (fmi2Integer)value_of(c, vr[i]);
    return fmi2OK;
}

fmi2Status fmi2GetBoolean(fmi2Component component, const fmi2ValueReference vr[], size_t nvr,
                          fmi2Boolean value[]) {
    Instance *c = component;
    size_t i;
    if (c == NULL || bad_access(c, vr, nvr, value, VT_BOOLEAN, "fmi2GetBoolean") ||
        prepare_get(c, vr, nvr, "fmi2GetBoolean")) {
        return fmi2Error;
    }
    for (i = 0; i < nvr; i++) value[i] = value_of(c, vr[i]) != 0.0 ? fmi2True : fmi2False;
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component component, const fmi2ValueReference vr[], size_t nvr,
                       const fmi2Real value[]) {
    Instance *c = component;
    size_t i;
    if (c == NULL || bad_access(c, vr, nvr, value, VT_REAL, "fmi2SetReal") ||
        not_settable(c, vr, nvr, "fmi2SetReal")) {
        return fmi2Error;
    }
    for (i = 0; i < nvr; i++) {
        if (bad_value(c, vr[i], value[i], "fmi2SetReal")) return fmi2Error;
    }
    for (i = 0; i < nvr; i++) c->v[vr[i]] = value[i];
    values_changed(c);
    return fmi2OK;
}

fmi2Status fmi2SetInteger(fmi2Component component, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Integer value[]) {
    Instance *c = component;
    size_t i;
    if (c == NULL || bad_access(c, vr, nvr, value, VT_INTEGER, "fmi2SetInteger") ||
        not_settable(c, vr, nvr, "fmi2SetInteger")) {
        return fmi2Error;
    }
    for (i = 0; i < nvr; i++) {
        if (bad_value(c, vr[i], (double)value[i], "fmi2SetInteger")) return fmi2Error;
    }
    for (i = 0; i < nvr; i++) c->v[vr[i]] = (double)value[i];
    values_changed(c);
    return fmi2OK;
}

fmi2Status fmi2SetBoolean(fmi2Component component, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Boolean value[]) {
    Instance *c = component;
    size_t i;
    if (c == NULL || bad_access(c, vr, nvr, value, VT_BOOLEAN, "fmi2SetBoolean") ||
        not_settable(c, vr, nvr, "fmi2SetBoolean")) {
        return fmi2Error;
    }
    for (i = 0; i < nvr; i++) c->v[vr[i]] = value[i] != fmi2False ? 1.0 : 0.0;
    values_changed(c);
    return fmi2OK;
}

/* Our models have no String variables: any value reference is an error. */
static fmi2Status no_strings(Instance *c, const fmi2ValueReference vr[], size_t nvr,
                             const char *function) {
    if (c == NULL) return fmi2Error;
    if (nvr == 0) return fmi2OK;
    if (vr == NULL || vr[0] >= N_VARIABLES) {
        LOG_ERROR(c, "%s: unknown value reference", function);
    } else {
        LOG_ERROR(c, "%s: variable '%s' is not a String", function, VARIABLES[vr[0]].name);
    }
    return fmi2Error;
}

fmi2Status fmi2GetString(fmi2Component component, const fmi2ValueReference vr[], size_t nvr,
                         fmi2String value[]) {
    (void)value;
    return no_strings(component, vr, nvr, "fmi2GetString");
}

fmi2Status fmi2SetString(fmi2Component component, const fmi2ValueReference vr[], size_t nvr,
                         const fmi2String value[]) {
    (void)value;
    return no_strings(component, vr, nvr, "fmi2SetString");
}

/* ---- stepping ------------------------------------------------------------------------------- */

fmi2Status fmi2DoStep(fmi2Component component, fmi2Real currentCommunicationPoint,
                      fmi2Real communicationStepSize,
                      fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    Instance *c = component;
    (void)noSetFMUStatePriorToCurrentPoint;
    if (c == NULL || wrong_phase(c, PH(PHASE_STEP), "fmi2DoStep") ||
        do_step(c, currentCommunicationPoint, communicationStepSize, "fmi2DoStep") != 0) {
        return fmi2Error;
    }
    return fmi2OK;
}

fmi2Status fmi2CancelStep(fmi2Component component) {
    Instance *c = component;
    if (c == NULL) return fmi2Error;
    LOG_ERROR(c, "fmi2CancelStep: steps are synchronous, there is no pending step to cancel");
    return fmi2Error;
}

fmi2Status fmi2GetStatus(fmi2Component component, const fmi2StatusKind s, fmi2Status *value) {
    (void)s;
    (void)value;
    return component == NULL ? fmi2Error : fmi2Discard; /* no asynchronous step */
}

fmi2Status fmi2GetRealStatus(fmi2Component component, const fmi2StatusKind s, fmi2Real *value) {
    Instance *c = component;
    if (c == NULL || value == NULL) return fmi2Error;
    if (s != fmi2LastSuccessfulTime) return fmi2Discard;
    *value = c->time;
    return fmi2OK;
}

fmi2Status fmi2GetIntegerStatus(fmi2Component component, const fmi2StatusKind s,
                                fmi2Integer *value) {
    (void)s;
    (void)value;
    return component == NULL ? fmi2Error : fmi2Discard;
}

fmi2Status fmi2GetBooleanStatus(fmi2Component component, const fmi2StatusKind s,
                                fmi2Boolean *value) {
    if (component == NULL || value == NULL) return fmi2Error;
    if (s != fmi2Terminated) return fmi2Discard;
    *value = fmi2False; /* the model never asks the master to stop */
    return fmi2OK;
}

fmi2Status fmi2GetStringStatus(fmi2Component component, const fmi2StatusKind s,
                               fmi2String *value) {
    (void)s;
    (void)value;
    return component == NULL ? fmi2Error : fmi2Discard;
}

/* ---- not provided: directional derivatives, input/output derivatives ------------------------ */

fmi2Status fmi2GetDirectionalDerivative(fmi2Component component,
                                        const fmi2ValueReference vUnknown_ref[], size_t nUnknown,
                                        const fmi2ValueReference vKnown_ref[], size_t nKnown,
                                        const fmi2Real dvKnown[], fmi2Real dvUnknown[]) {
    (void)vUnknown_ref, (void)nUnknown, (void)vKnown_ref, (void)nKnown, (void)dvKnown;
    (void)dvUnknown;
    LOG_ERROR((Instance *)component, "fmi2GetDirectionalDerivative is not provided");
    return fmi2Error;
}

fmi2Status fmi2SetRealInputDerivatives(fmi2Component component, const fmi2ValueReference vr[],
                                       size_t nvr, const fmi2Integer order[],
                                       const fmi2Real value[]) {
    (void)vr, (void)nvr, (void)order, (void)value;
    LOG_ERROR((Instance *)component, "fmi2SetRealInputDerivatives: inputs are not interpolated");
    return fmi2Error;
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component component, const fmi2ValueReference vr[],
                                        size_t nvr, const fmi2Integer order[],
                                        fmi2Real value[]) {
    (void)vr, (void)nvr, (void)order, (void)value;
    LOG_ERROR((Instance *)component, "fmi2GetRealOutputDerivatives: not provided");
    return fmi2Error;
}
