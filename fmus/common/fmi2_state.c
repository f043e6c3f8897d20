/*
 * FMU state of the shared FMI 2.0 layer: the FMI 2.0 names around state_core.h.
 */
#include "instance.h"
#include "state_core.h"

static const char SERIAL_MAGIC[8] = "EXCOSIM";

fmi2Status fmi2GetFMUstate(fmi2Component component, fmi2FMUstate *FMUstate) {
    if (component == NULL || FMUstate == NULL) return fmi2Error;
    return state_get(component, FMUstate, "fmi2GetFMUstate") ? fmi2Error : fmi2OK;
}

fmi2Status fmi2SetFMUstate(fmi2Component component, fmi2FMUstate FMUstate) {
    if (component == NULL) return fmi2Error;
    return state_set(component, FMUstate, "fmi2SetFMUstate") ? fmi2Error : fmi2OK;
}

fmi2Status fmi2FreeFMUstate(fmi2Component component, fmi2FMUstate *FMUstate) {
    if (component == NULL) return fmi2Error;
    if (FMUstate != NULL) {
        free(*FMUstate);
        *FMUstate = NULL;
    }
    return fmi2OK;
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component component, fmi2FMUstate FMUstate,
                                      size_t *size) {
    (void)FMUstate;
    if (component == NULL || size == NULL) return fmi2Error;
    *size = serialized_bytes();
    return fmi2OK;
}

fmi2Status fmi2SerializeFMUstate(fmi2Component component, fmi2FMUstate FMUstate,
                                 fmi2Byte serializedState[], size_t size) {
    if (component == NULL) return fmi2Error;
    return state_serialize(component, FMUstate, (unsigned char *)serializedState, size,
                           SERIAL_MAGIC, "fmi2SerializeFMUstate") ? fmi2Error : fmi2OK;
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component component, const fmi2Byte serializedState[],
                                   size_t size, fmi2FMUstate *FMUstate) {
    if (component == NULL || FMUstate == NULL) return fmi2Error;
    return state_deserialize(component, (const unsigned char *)serializedState, size, FMUstate,
                             SERIAL_MAGIC, "fmi2DeSerializeFMUstate") ? fmi2Error : fmi2OK;
}
