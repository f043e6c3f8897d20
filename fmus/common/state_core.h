/*
 * FMU state of the shared FMI layers, written once for FMI 2.0 (fmi2_state.c) and FMI 3.0
 * (fmi3_state.c), which include it after their own instance header and wrap it in their API's
 * names and status codes: a copy of the value array, the time, the phase and the model's private
 * state blob; serialized behind a header that names the model build (GUID) and the sizes, so a
 * state from another model or build is refused. Each function returns 0 on success, -1 on an
 * error it has logged.
 */
#ifndef EXCOSIM_STATE_CORE_H
#define EXCOSIM_STATE_CORE_H

#include <stdint.h>
#include <stdlib.h>
#include <string.h>

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

static size_t snapshot_bytes(void) { return sizeof(Snapshot) + excosim_state_bytes(); }

static size_t serialized_bytes(void) { return sizeof(SerialHeader) + snapshot_bytes(); }

/* *state (a snapshot block, allocated when NULL) := the instance now. */
static int state_get(const Instance *c, void **state, const char *fn) {
    Snapshot *s;
    if (*state == NULL) *state = malloc(snapshot_bytes()); /* else reuse: same size */
    if (*state == NULL) {
        LOG_ERROR(c, "%s: out of memory", fn);
        return -1;
    }
    s = *state;
    memcpy(s->v, c->v, sizeof s->v);
    s->time = c->time;
    s->start_time = c->start_time;
    s->phase = c->phase;
    memcpy((unsigned char *)s + sizeof(Snapshot), c->state, excosim_state_bytes());
    return 0;
}

static int state_set(Instance *c, const void *state, const char *fn) {
    const Snapshot *s = state;
    if (s == NULL) {
        LOG_ERROR(c, "%s: FMUstate is NULL", fn);
        return -1;
    }
    memcpy(c->v, s->v, sizeof c->v);
    c->time = s->time;
    c->start_time = s->start_time;
    c->phase = s->phase;
    memcpy(c->state, (const unsigned char *)s + sizeof(Snapshot), excosim_state_bytes());
    return 0;
}

static void make_header(SerialHeader *h, const char magic[8]) {
    memset(h, 0, sizeof *h);
    memcpy(h->magic, magic, sizeof h->magic);
    strncpy(h->guid, MODEL_GUID, sizeof h->guid - 1);
    h->n_variables = N_VARIABLES;
    h->snapshot_size = sizeof(Snapshot);
    h->model_state_size = excosim_state_bytes();
}

static int state_serialize(const Instance *c, const void *state, unsigned char out[],
                           size_t size, const char magic[8], const char *fn) {
    SerialHeader header;
    if (state == NULL || out == NULL) {
        LOG_ERROR(c, "%s: FMUstate and buffer must not be NULL", fn);
        return -1;
    }
    if (size < serialized_bytes()) {
        LOG_ERROR(c, "%s: buffer of %zu bytes is too small (need %zu)", fn, size,
                  serialized_bytes());
        return -1;
    }
    make_header(&header, magic);
    memcpy(out, &header, sizeof header);
    memcpy(out + sizeof header, state, snapshot_bytes());
    return 0;
}

/* *state (allocated when NULL) := the serialized state in[size], if it is this build's. */
static int state_deserialize(const Instance *c, const unsigned char in[], size_t size,
                             void **state, const char magic[8], const char *fn) {
    SerialHeader expected, header;
    void *s;
    if (in == NULL || size != serialized_bytes()) {
        LOG_ERROR(c, "%s: %zu bytes is not a serialized %s state", fn, size,
                  MODEL_IDENTIFIER_STRING);
        return -1;
    }
    make_header(&expected, magic);
    memcpy(&header, in, sizeof header);
    if (memcmp(&header, &expected, sizeof header) != 0) {
        LOG_ERROR(c, "%s: the state was saved by a different model or build", fn);
        return -1;
    }
    s = *state != NULL ? *state : malloc(snapshot_bytes());
    if (s == NULL) {
        LOG_ERROR(c, "%s: out of memory", fn);
        return -1;
    }
    memcpy(s, in + sizeof header, snapshot_bytes());
    *state = s;
    return 0;
}

#endif
