/*
 * FMU state of the shared FMI 3.0 layer: the FMI 3.0 names around state_core.h (the same state
 * as FMI 2.0's; its own magic, so an FMI 2 state is not taken for an FMI 3 one).
 */
#include "fmi3_instance.h"
#include "state_core.h"

static const char SERIAL_MAGIC[8] = "EXCOSI3";

fmi3Status fmi3GetFMUState(fmi3Instance component, fmi3FMUState *FMUstate) {
    if (component == NULL || FMUstate == NULL) return fmi3Error;
    return state_get(component, FMUstate, "fmi3GetFMUState") ? fmi3Error : fmi3OK;
}

fmi3Status fmi3SetFMUState(fmi3Instance component, fmi3FMUState FMUstate) {
    if (component == NULL) return fmi3Error;
    return state_set(component, FMUstate, "fmi3SetFMUState") ? fmi3Error : fmi3OK;
}

fmi3Status fmi3FreeFMUState(fmi3Instance component, fmi3FMUState *FMUstate) {
    if (component == NULL) return fmi3Error;
    if (FMUstate != NULL) {
        free(*FMUstate);
        *FMUstate = NULL;
    }
    return fmi3OK;
}

fmi3Status fmi3SerializedFMUStateSize(fmi3Instance component, fmi3FMUState FMUstate,
                                      size_t *size) {
    (void)FMUstate;
    if (component == NULL || size == NULL) return fmi3Error;
    *size = serialized_bytes();
    return fmi3OK;
}

fmi3Status fmi3SerializeFMUState(fmi3Instance component, fmi3FMUState FMUstate,
                                 fmi3Byte serializedState[], size_t size) {
    if (component == NULL) return fmi3Error;
    return state_serialize(component, FMUstate, (unsigned char *)serializedState, size,
                           SERIAL_MAGIC, "fmi3SerializeFMUState") ? fmi3Error : fmi3OK;
}

fmi3Status fmi3DeserializeFMUState(fmi3Instance component, const fmi3Byte serializedState[],
                                   size_t size, fmi3FMUState *FMUstate) {
    if (component == NULL || FMUstate == NULL) return fmi3Error;
    return state_deserialize(component, (const unsigned char *)serializedState, size, FMUstate,
                             SERIAL_MAGIC, "fmi3DeserializeFMUState") ? fmi3Error : fmi3OK;
}
