/*
 * FMU state of the shared FMI 3.0 layer, as in the FMI 2.0 layer's fmi2_state.c with FMI 3
 * names: a copy of the value array, the time, the phase and the model's private state blob; serialized behind a header that names the model build (GUID) and
 * the sizes, so a state from another model or build is refused.
 */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "fmi3_instance.h"

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

static const char SERIAL_MAGIC[8] = "EXCOSI3";

static size_t snapshot_bytes(void) { return sizeof(Snapshot) + excosim_state_bytes(); }

static void take_snapshot(const Instance *c, Snapshot *s) {
    memcpy(s->v, c->v, sizeof s->v);
    s->time = c->time;
    s->start_time = c->start_time;
    s->phase = c->phase;
    memcpy((unsigned char *)s + sizeof(Snapshot), c->state, excosim_state_bytes());
}

fmi3Status fmi3GetFMUState(fmi3Instance component, fmi3FMUState *FMUstate) {
    Instance *c = component;
    if (c == NULL || FMUstate == NULL) return fmi3Error;
    if (*FMUstate == NULL) *FMUstate = malloc(snapshot_bytes()); /* else reuse: same size */
    if (*FMUstate == NULL) {
        LOG_ERROR(c, "fmi3GetFMUState: out of memory");
        return fmi3Error;
    }
    take_snapshot(c, *FMUstate);
    return fmi3OK;
}

fmi3Status fmi3SetFMUState(fmi3Instance component, fmi3FMUState FMUstate) {
    Instance *c = component;
    const Snapshot *s = FMUstate;
    if (c == NULL) return fmi3Error;
    if (s == NULL) {
        LOG_ERROR(c, "fmi3SetFMUState: FMUstate is NULL");
        return fmi3Error;
    }
    memcpy(c->v, s->v, sizeof c->v);
    c->time = s->time;
    c->start_time = s->start_time;
    c->phase = s->phase;
    memcpy(c->state, (const unsigned char *)s + sizeof(Snapshot), excosim_state_bytes());
    return fmi3OK;
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
    *size = sizeof(SerialHeader) + snapshot_bytes();
    return fmi3OK;
}

static void make_header(SerialHeader *h) {
    memset(h, 0, sizeof *h);
    memcpy(h->magic, SERIAL_MAGIC, sizeof h->magic);
    strncpy(h->guid, MODEL_GUID, sizeof h->guid - 1);
    h->n_variables = N_VARIABLES;
    h->snapshot_size = sizeof(Snapshot);
    h->model_state_size = excosim_state_bytes();
}

fmi3Status fmi3SerializeFMUState(fmi3Instance component, fmi3FMUState FMUstate,
                                 fmi3Byte serializedState[], size_t size) {
    Instance *c = component;
    SerialHeader header;
    if (c == NULL) return fmi3Error;
    if (FMUstate == NULL || serializedState == NULL) {
        LOG_ERROR(c, "fmi3SerializeFMUState: FMUstate and buffer must not be NULL");
        return fmi3Error;
    }
    if (size < sizeof header + snapshot_bytes()) {
        LOG_ERROR(c, "fmi3SerializeFMUState: buffer of %zu bytes is too small (need %zu)", size,
                  sizeof header + snapshot_bytes());
        return fmi3Error;
    }
    make_header(&header);
    memcpy(serializedState, &header, sizeof header);
    memcpy(serializedState + sizeof header, FMUstate, snapshot_bytes());
    return fmi3OK;
}

fmi3Status fmi3DeserializeFMUState(fmi3Instance component, const fmi3Byte serializedState[],
                                   size_t size, fmi3FMUState *FMUstate) {
    Instance *c = component;
    SerialHeader expected, header;
    void *s;
    if (c == NULL || FMUstate == NULL) return fmi3Error;
    if (serializedState == NULL || size != sizeof header + snapshot_bytes()) {
        LOG_ERROR(c, "fmi3DeserializeFMUState: %zu bytes is not a serialized %s state", size,
                  MODEL_IDENTIFIER_STRING);
        return fmi3Error;
    }
    make_header(&expected);
    memcpy(&header, serializedState, sizeof header);
    if (memcmp(&header, &expected, sizeof header) != 0) {
        LOG_ERROR(c, "fmi3DeserializeFMUState: the state was saved by a different model or build");
        return fmi3Error;
    }
    s = *FMUstate != NULL ? *FMUstate : malloc(snapshot_bytes());
    if (s == NULL) {
        LOG_ERROR(c, "fmi3DeserializeFMUState: out of memory");
        return fmi3Error;
    }
    memcpy(s, serializedState + sizeof header, snapshot_bytes());
    *FMUstate = s;
    return fmi3OK;
}
