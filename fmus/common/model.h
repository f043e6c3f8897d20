/*
 * The contract between one model's physics (fmus/<Model>/model.c) and the shared FMI 2.0 and
 * 3.0 co-simulation layers (fmus/common/). A model file includes only this header and its
 * generated variable table; it never sees an fmi2* or fmi3* type or function.
 *
 * The builder reads fmus/<Model>/variables.toml and generates, in the build directory:
 *   variables.h          MODEL_IDENTIFIER, MODEL_GUID, N_VARIABLES, one `VR_<name>` per variable
 *                        (array entries `h[1]..h[n]` become VR_h_1..VR_h_<n>, plus `N_h` = n),
 *                        and the table VARIABLES[N_VARIABLES] (name, type, causality,
 *                        variability, when settable, start, min, max)
 *   modelDescription.xml generated from the same table
 * Value reference == index into the value array `v`. Integer and Boolean variables are stored in
 * `v` as doubles too (the shared layer converts at the FMI boundary).
 */
#ifndef EXCOSIM_MODEL_H
#define EXCOSIM_MODEL_H

#include <stddef.h>
#include "variables.h"

/* Size in bytes of the model's private state (a plain struct, no pointers), allocated and
 * zeroed by the shared layer, copied whole by fmi2GetFMUstate / fmi2SerializeFMUstate. */
extern const size_t model_state_size;

/* Computes the initial values from the parameters and start values: checks parameters, sets up
 * the private state and writes the initial outputs and calculated parameters. The shared layer
 * calls it on a scratch copy of v and the state in initialization mode (when an importer reads a
 * computed variable) and at fmi2ExitInitializationMode, so it must depend on nothing but its
 * arguments. Returns 0 on success; otherwise sets *error to a static message naming what is
 * wrong. */
int model_initialize(double *v, void *state, const char **error);

/* Advances the model from time t by h seconds with the inputs currently in v, and writes the
 * outputs at t + h into v. Returns 0 on success; otherwise sets *error (static string). */
int model_do_step(double *v, void *state, double t, double h, const char **error);

/* Optional (a weak symbol: a model without it links too): checks the private state, e.g. that
 * its reals are finite and its indices in range. The shared layer calls it after
 * model_initialize and every step (an output the model clips, like fmax(p, 0) of a NaN, can hide
 * a broken state) and on a deserialized FMU state before using it (a state from outside must not
 * make the model index out of bounds). v holds the values that go with the state. Returns 0 when
 * the state is valid; otherwise sets *error (static string). */
int model_check_state(const double *v, const void *state, const char **error)
    __attribute__((weak, visibility("hidden")));

#endif
