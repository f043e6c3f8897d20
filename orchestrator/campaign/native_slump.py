"""The terrain strategy's slump kernel in C (planner/native/slump.c), bound with ctypes.

planner.surface_estimate.relax_steps levels a surface estimate's steps in numpy: some 2,700
half-sweeps of a 240-cell surface per slump, each a handful of numpy calls, and a terrain
campaign slumps seven hypotheses after every period, so the kernel took most of its wall
time. slump.c does the same arithmetic in the same order and gives the same bits
(tests/test_native_slump.py), so the strategy decides the same with either. The planner does
not build native code (it imports neither fmus nor orchestrator); the orchestrator builds the
library like its own coupling (fmus.shared_library: cached by content, byte-reproducible) and
hands the kernel to the strategy. Without gcc, or with a cache folder others may write, the
strategy keeps the numpy kernel (`unavailable()` says why).
"""

from __future__ import annotations

import ctypes
from functools import lru_cache
from pathlib import Path

import numpy as np

import planner
from planner.surface_estimate import RELAX_MAX_SWEEPS, RELAX_TOLERANCE_M, Relax

SOURCE_DIR = Path(planner.__file__).resolve().parent / "native"


@lru_cache(maxsize=1)
def _library() -> ctypes.CDLL | str:
    """The built library, or why it cannot be had (one line)."""
    from fmus.builder import BuildError
    from fmus.shared_library import build_library

    try:
        path = build_library("slump", SOURCE_DIR, ("slump.c",))
    except BuildError as error:
        return str(error).splitlines()[0]
    library = ctypes.CDLL(str(path))
    library.slump_relax.restype = ctypes.c_long
    library.slump_relax.argtypes = [ctypes.POINTER(ctypes.c_double), ctypes.c_long,
                                    ctypes.c_double, ctypes.c_double, ctypes.c_long]
    return library


def unavailable() -> str | None:
    """Why the C kernel cannot serve (one line), None when it can."""
    library = _library()
    return library if isinstance(library, str) else None


def native_relax() -> Relax | None:
    """The C slump kernel (planner.surface_estimate.Relax), None when unavailable."""
    library = _library()
    if isinstance(library, str):
        return None
    relax = library.slump_relax
    pointer = ctypes.POINTER(ctypes.c_double)

    def relax_steps(z_m: np.ndarray, allowed_m: float) -> None:
        if z_m.dtype != np.float64 or z_m.ndim != 1 or not z_m.flags.c_contiguous \
                or not z_m.flags.writeable:
            raise ValueError("the slump kernel needs a writeable contiguous (n,) float64 array")
        relax(z_m.ctypes.data_as(pointer), len(z_m), float(allowed_m), RELAX_TOLERANCE_M,
              RELAX_MAX_SWEEPS)

    return relax_steps
