"""fmi2_step.c bound with ctypes: one foreign call per FMI 2.0 step (fmus.runs.FastSlave).

`library()` builds it on first use (fmus.shared_library: the FMUs' gcc and flags, cached beside
them) and returns the loaded library, or None when it cannot be had (no gcc): FastSlave then
makes the three FMI calls one by one, as before.
"""

from __future__ import annotations

import ctypes
from functools import lru_cache
from pathlib import Path


class Fmi2Step(ctypes.Structure):
    """fmi2_step.c's Fmi2Step: the instance, its three entry points, the bound buffers."""

    _fields_ = [("component", ctypes.c_void_p), ("set_real", ctypes.c_void_p),
                ("get_real", ctypes.c_void_p), ("do_step", ctypes.c_void_p),
                ("vr_in", ctypes.c_void_p), ("n_in", ctypes.c_size_t),
                ("inputs", ctypes.c_void_p), ("vr_out", ctypes.c_void_p),
                ("n_out", ctypes.c_size_t), ("outputs", ctypes.c_void_p)]


@lru_cache(maxsize=1)
def library() -> ctypes.CDLL | None:
    """The loaded fmi2_step library, None without a C compiler."""
    from fmus.builder import BuildError
    from fmus.shared_library import build_library

    try:
        path = build_library("fmi2_step", Path(__file__).resolve().parent, ("fmi2_step.c",))
    except BuildError:
        return None
    loaded = ctypes.CDLL(str(path))
    if loaded.fmi2_step_size() != ctypes.sizeof(Fmi2Step):
        return None
    loaded.fmi2_step.argtypes = [ctypes.c_void_p, ctypes.c_double, ctypes.c_double]
    loaded.fmi2_step.restype = ctypes.c_int
    return loaded
