"""fmi2_step.c and fmi3_step.c bound with ctypes: one foreign call per FMI 2.0 or 3.0 step
(fmus.runs.FastSlave); steps.c: n steps of one FMU over an input series in one call
(FastSlave.run); rollback.c: an FMU's state saved and restored in one call each
(FastSlave.rollback, for a master that iterates a step).

`library()` loads them as built with the package (fmus.shared_library; built with the FMUs'
gcc and flags after an edit of their sources) and returns the loaded library, or None when it
cannot be had (sources edited on a machine without gcc): FastSlave then makes the three FMI
calls one by one.
"""

from __future__ import annotations

import ctypes
from functools import lru_cache


class StepCall(ctypes.Structure):
    """fmi2_step.c's Fmi2Step and fmi3_step.c's Fmi3Step (one layout): the instance, its set,
    get and step entry points, the bound value references and buffers."""

    _fields_ = [("instance", ctypes.c_void_p), ("set_values", ctypes.c_void_p),
                ("get_values", ctypes.c_void_p), ("do_step", ctypes.c_void_p),
                ("vr_in", ctypes.c_void_p), ("n_in", ctypes.c_size_t),
                ("inputs", ctypes.c_void_p), ("vr_out", ctypes.c_void_p),
                ("n_out", ctypes.c_size_t), ("outputs", ctypes.c_void_p)]


class Rollback(ctypes.Structure):
    """rollback.c's Rollback: the instance, its get and set state entry points, its state
    block (NULL until the first save)."""

    _fields_ = [("instance", ctypes.c_void_p), ("get_state", ctypes.c_void_p),
                ("set_state", ctypes.c_void_p), ("state", ctypes.c_void_p)]


@lru_cache(maxsize=1)
def library() -> ctypes.CDLL | None:
    """The loaded library (fmi2_step, fmi3_step), None without a C compiler."""
    from fmus.builder import BuildError
    from fmus.shared_library import build_library, library_sources

    try:
        path = build_library("fast_step", *library_sources("fast_step"))
    except BuildError:
        return None
    loaded = ctypes.CDLL(str(path))
    for version in (2, 3):
        if getattr(loaded, f"fmi{version}_step_size")() != ctypes.sizeof(StepCall):
            return None
        function = getattr(loaded, f"fmi{version}_step")
        function.argtypes = [ctypes.c_void_p, ctypes.c_double, ctypes.c_double]
        function.restype = ctypes.c_int
    loaded.fmi_steps.argtypes = [ctypes.c_void_p] * 4 + [ctypes.c_long, ctypes.c_double,
                                                         ctypes.c_double, ctypes.c_void_p]
    loaded.fmi_steps.restype = ctypes.c_int
    for name in ("fmu_save_state", "fmu_restore_state"):
        getattr(loaded, name).argtypes = [ctypes.c_void_p]
        getattr(loaded, name).restype = ctypes.c_int
    return loaded


STATE_CALLS = {2: ("fmi2GetFMUstate", "fmi2SetFMUstate", "fmi2FreeFMUstate"),
               3: ("fmi3GetFMUState", "fmi3SetFMUState", "fmi3FreeFMUState")}


def bind_rollback(dll, component: int, version: int) -> tuple[Rollback, dict[str, int]]:
    """An FMU instance's Rollback (rollback.c) through its own fmi2GetFMUstate /
    fmi2SetFMUstate (FMI 3.0: fmi3GetFMUState / fmi3SetFMUState) in the loaded binary `dll`,
    and the NativeStep fields that hand it to a loop in C (save_address, restore_address,
    rollback_address). Keep the Rollback while the instance lives; free_rollback it before
    the instance is freed."""
    get_state, set_state, free_state = (dll._FuncPtr((n, dll)) for n in STATE_CALLS[version])
    loaded = library()
    rollback = Rollback(component, ctypes.cast(get_state, ctypes.c_void_p).value,
                        ctypes.cast(set_state, ctypes.c_void_p).value, None)
    rollback.free_state = free_state  # a ctypes Structure takes extra attributes
    return rollback, {
        "save_address": ctypes.cast(loaded.fmu_save_state, ctypes.c_void_p).value,
        "restore_address": ctypes.cast(loaded.fmu_restore_state, ctypes.c_void_p).value,
        "rollback_address": ctypes.addressof(rollback)}


def free_rollback(rollback: Rollback | None) -> None:
    """Free the FMU state block a Rollback holds (the FMU's own free function); safe twice."""
    if rollback is not None and rollback.state:
        rollback.free_state(ctypes.c_void_p(rollback.instance),
                            ctypes.byref(ctypes.c_void_p(rollback.state)))
        rollback.state = None
