/*
 * An FMU's state rollback as one foreign call each: fmi2GetFMUstate / fmi2SetFMUstate (FMI 3.0:
 * fmi3GetFMUState / fmi3SetFMUState, the same shape) into one state block that the FMU
 * allocates on the first save and overwrites on every later one (the standard's rule for a
 * non-NULL state). A master that iterates a communication step saves before the first try and
 * restores before each further one (orchestrator.plants.native's arm coupling).
 */
#define EXPORT __attribute__((visibility("default")))

typedef int (*GetState)(void *instance, void **state);
typedef int (*SetState)(void *instance, void *state);

typedef struct {
    void *instance;
    GetState get_state;
    SetState set_state;
    void *state; /* NULL until the first save; freed with the FMU's free function */
} Rollback;

/* 0, or (5 save, 6 restore) << 8 | the call's status when it returned more than a warning. */
EXPORT int fmu_save_state(Rollback *r) {
    const int status = r->get_state(r->instance, &r->state);
    return status > 1 ? (5 << 8) | (status & 0xff) : 0;
}

EXPORT int fmu_restore_state(const Rollback *r) {
    if (r->state == 0) return 6 << 8;
    const int status = r->set_state(r->instance, r->state);
    return status > 1 ? (6 << 8) | (status & 0xff) : 0;
}
