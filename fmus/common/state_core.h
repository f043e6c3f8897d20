/*
 * FMU state of the shared FMI layers, written once for FMI 2.0 (fmi2_state.c) and FMI 3.0
 * (fmi3_state.c), which include it after their own instance header and wrap it in their API's
 * names and status codes: a copy of the value array, the time, the phase and the model's private
 * state blob; serialized behind a header that names the format version, the model build (GUID)
 * and the sizes and carries a checksum. A serialized state comes from outside (a file, another
 * process), so it is validated in full before it is used: a state from another model or build,
 * a truncated or corrupted one, or one whose values the layer or the model would refuse (not
 * finite, out of range, bad phase, model_check_state) is refused and changes nothing. Each
 * function returns 0 on success, -1 on an error it has logged.
 */
#ifndef EXCOSIM_STATE_CORE_H
#define EXCOSIM_STATE_CORE_H

#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "layer_core.h"

/* What an FMU state holds; the model's private state follows it in the same block. */
typedef struct {
    double v[N_VARIABLES];
    double time;
    double start_time;
    Phase phase;
} Snapshot;

static size_t snapshot_bytes(void) { return sizeof(Snapshot) + excosim_state_bytes(); }

/* Serialized FMU state: this header, then the Snapshot, then the model's private state. */
typedef struct {
    char magic[8];    /* names the FMI version's layer (fmi2_state.c / fmi3_state.c) */
    uint32_t version; /* STATE_FORMAT: the layout of this header and the Snapshot */
    uint32_t zero;
    char guid[40];    /* MODEL_GUID, NUL-padded: the model build the state belongs to */
    uint64_t n_variables;
    uint64_t snapshot_size;
    uint64_t model_state_size;
    uint64_t checksum; /* FNV-1a of everything serialized, this field taken as 0 */
} SerialHeader;

#define STATE_FORMAT 2u

static size_t serialized_bytes(void) { return sizeof(SerialHeader) + snapshot_bytes(); }

/* 64-bit FNV-1a: any change of one byte changes it (each round is a bijection of the hash). */
static uint64_t fnv1a(uint64_t hash, const unsigned char *bytes, size_t n) {
    size_t i;
    for (i = 0; i < n; i++) hash = (hash ^ bytes[i]) * 0x100000001b3u;
    return hash;
}

#define FNV_OFFSET 0xcbf29ce484222325u

static uint64_t checksum_of(const SerialHeader *h, const unsigned char *snapshot) {
    SerialHeader zeroed = *h;
    zeroed.checksum = 0;
    return fnv1a(fnv1a(FNV_OFFSET, (const unsigned char *)&zeroed, sizeof zeroed), snapshot,
                 snapshot_bytes());
}

/* *state (a snapshot block, allocated when NULL) := the instance now. */
static int state_get(const Instance *c, void **state, const char *fn) {
    Snapshot *s;
    /* calloc: the padding after `phase` is serialized too, and should not be heap garbage. */
    if (*state == NULL) *state = calloc(1, snapshot_bytes()); /* else reuse: same size */
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
    values_changed(c);
    return 0;
}

static void make_header(SerialHeader *h, const char magic[8]) {
    memset(h, 0, sizeof *h);
    memcpy(h->magic, magic, sizeof h->magic);
    strncpy(h->guid, MODEL_GUID, sizeof h->guid - 1);
    h->n_variables = N_VARIABLES;
    h->snapshot_size = sizeof(Snapshot);
    h->model_state_size = excosim_state_bytes();
    h->version = STATE_FORMAT;
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
    header.checksum = checksum_of(&header, state);
    memcpy(out, &header, sizeof header);
    memcpy(out + sizeof header, state, snapshot_bytes());
    return 0;
}

/* What is wrong with the header of a serialized state, or NULL. */
static const char *header_problem(const SerialHeader *h, const unsigned char *snapshot,
                                  const char magic[8]) {
    SerialHeader expected;
    make_header(&expected, magic);
    if (memcmp(h->magic, expected.magic, sizeof h->magic) != 0) {
        return "it is not a state of this FMI version's excosim layer (wrong magic)";
    }
    if (h->version != STATE_FORMAT || h->zero != 0) return "its format version is not this one's";
    if (memcmp(h->guid, expected.guid, sizeof h->guid) != 0) {
        return "it was saved by a different model or build (GUID)";
    }
    if (h->n_variables != expected.n_variables || h->snapshot_size != expected.snapshot_size ||
        h->model_state_size != expected.model_state_size) {
        return "its layout differs from this build's";
    }
    if (h->checksum != checksum_of(h, snapshot)) return "it is corrupt (checksum mismatch)";
    return NULL;
}

/* Checks the contents of a snapshot block against what the layer and the model accept. */
static int bad_snapshot(const Instance *c, const Snapshot *s, const char *fn) {
    const char *problem;
    const char *error = "unknown error";
    const int phase = (int)s->phase; /* as an int: the enum may be unsigned */
    int i;
    if (phase < (int)PHASE_INSTANTIATED || phase > (int)PHASE_ERROR) {
        LOG_ERROR(c, "%s: the state has an invalid phase %d", fn, phase);
        return 1;
    }
    if (!isfinite(s->time) || !isfinite(s->start_time)) {
        LOG_ERROR(c, "%s: the state has a non-finite time", fn);
        return 1;
    }
    for (i = 0; i < N_VARIABLES; i++) {
        problem = value_problem((unsigned)i, s->v[i]);
        if (problem != NULL) {
            LOG_ERROR(c, "%s: in the state, the value of '%s' %s (%g)", fn, VARIABLES[i].name,
                      problem, s->v[i]);
            return 1;
        }
    }
    /* Before initialization the private state is the zeroed blob, not yet the model's. */
    if (phase >= (int)PHASE_STEP && model_check_state != NULL &&
        model_check_state(s->v, (const unsigned char *)s + sizeof(Snapshot), &error) != 0) {
        LOG_ERROR(c, "%s: the state's model state is invalid: %s", fn, error);
        return 1;
    }
    return 0;
}

/* *state (allocated when NULL) := the serialized state in[size], if it is this build's and
 * valid; otherwise nothing changes (*state neither). */
static int state_deserialize(const Instance *c, const unsigned char in[], size_t size,
                             void **state, const char magic[8], const char *fn) {
    SerialHeader header;
    const char *problem;
    void *s;
    if (in == NULL || size != serialized_bytes()) {
        LOG_ERROR(c, "%s: %zu bytes is not a serialized %s state (%zu bytes)", fn, size,
                  MODEL_IDENTIFIER_STRING, serialized_bytes());
        return -1;
    }
    s = malloc(snapshot_bytes()); /* aligned for the Snapshot, which `in` need not be */
    if (s == NULL) {
        LOG_ERROR(c, "%s: out of memory", fn);
        return -1;
    }
    memcpy(&header, in, sizeof header);
    memcpy(s, in + sizeof header, snapshot_bytes());
    problem = header_problem(&header, s, magic);
    if (problem != NULL) {
        LOG_ERROR(c, "%s: refused the serialized %s state: %s", fn, MODEL_IDENTIFIER_STRING,
                  problem);
        free(s);
        return -1;
    }
    if (bad_snapshot(c, s, fn)) {
        free(s);
        return -1;
    }
    if (*state != NULL) { /* reuse the caller's block (same size) */
        memcpy(*state, s, snapshot_bytes());
        free(s);
    } else {
        *state = s;
    }
    return 0;
}

#endif
