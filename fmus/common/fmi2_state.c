/*
 * FMU state of the shared FMI 2.0 layer: a copy of the value array, the time, the phase and the
 * model's private state blob; serialized behind a header that names the model build (GUID) and
 * the sizes, so a state from another model or build is refused.
 */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "instance.h"

/* What an FMU state holds; the model's private state follows it in the same block. */
typedef struct {
    double v[N_VARIABLES];
    double time;
    double start_time;
    Phase phase;
} Snapshot;

/* Serialized FMU state: this header, then the Snapshot, then the model's private state. */
typedef struct {
    char magic[8];
    char guid[40];
    uint64_t n_variables;
    uint64_t snapshot_size;
    uint64_t model_state_size;
} SerialHeader;

static const char SERIAL_MAGIC[8] = "EXCOSIM";

static size_t snapshot_bytes(void) { return sizeof(Snapshot) + excosim_state_bytes(); }

static void take_snapshot(const Instance *c, Snapshot *s) {
    memcpy(s->v, c->v, sizeof s->v);
    s->time = c->time;
    s->start_time = c->start_time;
    s->phase = c->phase;
    memcpy((unsigned char *)s + sizeof(Snapshot), c->state, excosim_state_bytes());
}

fmi2Status fmi2GetFMUstate(fmi2Component component, fmi2FMUstate *FMUstate) {
    Instance *c = component;
    if (c == NULL || FMUstate == NULL) return fmi2Error;
    if (*FMUstate == NULL) *FMUstate = malloc(snapshot_bytes()); /* else reuse: same size */
    if (*FMUstate == NULL) {
        LOG_ERROR(c, "fmi2GetFMUstate: out of memory");
        return fmi2Error;
    }
    take_snapshot(c, *FMUstate);
    return fmi2OK;
}

fmi2Status fmi2SetFMUstate(fmi2Component component, fmi2FMUstate FMUstate) {
    Instance *c = component;
    const Snapshot *s = FMUstate;
    if (c == NULL) return fmi2Error;
    if (s == NULL) {
        LOG_ERROR(c, "fmi2SetFMUstate: FMUstate is NULL");
        return fmi2Error;
    }
    memcpy(c->v, s->v, sizeof c->v);
    c->time = s->time;
    c->start_time = s->start_time;
    c->phase = s->phase;
    memcpy(c->state, (const unsigned char *)s + sizeof(Snapshot), excosim_state_bytes());
    return fmi2OK;
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
    *size = sizeof(SerialHeader) + snapshot_bytes();
    return fmi2OK;
}

static void make_header(SerialHeader *h) {
    memset(h, 0, sizeof *h);
    memcpy(h->magic, SERIAL_MAGIC, sizeof h->magic);
    strncpy(h->guid, MODEL_GUID, sizeof h->guid - 1);
    h->n_variables = N_VARIABLES;
    h->snapshot_size = sizeof(Snapshot);
    h->model_state_size = excosim_state_bytes();
}

fmi2Status fmi2SerializeFMUstate(fmi2Component component, fmi2FMUstate FMUstate,
                                 fmi2Byte serializedState[], size_t size) {
    Instance *c = component;
    SerialHeader header;
    if (c == NULL) return fmi2Error;
    if (FMUstate == NULL || serializedState == NULL) {
        LOG_ERROR(c, "fmi2SerializeFMUstate: FMUstate and buffer must not be NULL");
        return fmi2Error;
    }
    if (size < sizeof header + snapshot_bytes()) {
        LOG_ERROR(c, "fmi2SerializeFMUstate: buffer of %zu bytes is too small (need %zu)", size,
                  sizeof header + snapshot_bytes());
        return fmi2Error;
    }
    make_header(&header);
    memcpy(serializedState, &header, sizeof header);
    memcpy(serializedState + sizeof header, FMUstate, snapshot_bytes());
    return fmi2OK;
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component component, const fmi2Byte serializedState[],
                                   size_t size, fmi2FMUstate *FMUstate) {
    Instance *c = component;
    SerialHeader expected, header;
    void *s;
    if (c == NULL || FMUstate == NULL) return fmi2Error;
    if (serializedState == NULL || size != sizeof header + snapshot_bytes()) {
        LOG_ERROR(c, "fmi2DeSerializeFMUstate: %zu bytes is not a serialized %s state", size,
                  MODEL_IDENTIFIER_STRING);
        return fmi2Error;
    }
    make_header(&expected);
    memcpy(&header, serializedState, sizeof header);
    if (memcmp(&header, &expected, sizeof header) != 0) {
        LOG_ERROR(c, "fmi2DeSerializeFMUstate: the state was saved by a different model or build");
        return fmi2Error;
    }
    s = *FMUstate != NULL ? *FMUstate : malloc(snapshot_bytes());
    if (s == NULL) {
        LOG_ERROR(c, "fmi2DeSerializeFMUstate: out of memory");
        return fmi2Error;
    }
    memcpy(s, serializedState + sizeof header, snapshot_bytes());
    *FMUstate = s;
    return fmi2OK;
}
