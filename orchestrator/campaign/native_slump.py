"""The terrain strategy's slump kernel: planner/native/slump.c, bound with ctypes.

The planner's surface estimate levels its steps with a kernel it is handed
(planner.surface_estimate.Relax): some 2,700 half-sweeps of a 240-cell surface per slump, and a
terrain campaign slumps seven hypotheses after every period, so the kernel is most of the
strategy's arithmetic. The planner builds no native code (it imports neither fmus nor
orchestrator); the orchestrator loads the library as built with the package (fmus.shared_library:
compiled when the package was built, or by gcc after an edit of slump.c; byte-reproducible) and
hands the kernel to the strategy. tests/slump_reference.py does the same arithmetic in the same
order in numpy (the tests' oracle: the same bits, tests/test_native_slump.py).
"""

from __future__ import annotations

import ctypes
from functools import lru_cache

import numpy as np

from planner.surface_estimate import RELAX_MAX_SWEEPS, RELAX_TOLERANCE_M, Relax


@lru_cache(maxsize=1)
def _library() -> ctypes.CDLL:
    """The loaded library. fmus.BuildError when it cannot be had (slump.c edited on a machine
    without gcc, say)."""
    from fmus.builder import BuildError
    from fmus.shared_library import build_library, library_sources

    path = build_library("slump", *library_sources("slump"))
    try:
        library = ctypes.CDLL(str(path))
    except OSError as error:
        raise BuildError(f"cannot load {path}: {error}") from None
    library.slump_relax.restype = ctypes.c_long
    library.slump_relax.argtypes = [ctypes.POINTER(ctypes.c_double), ctypes.c_long,
                                    ctypes.c_double, ctypes.c_double, ctypes.c_long]
    return library


def native_relax() -> Relax:
    """The C slump kernel (planner.surface_estimate.Relax). fmus.BuildError when the library
    cannot be had."""
    relax = _library().slump_relax
    pointer = ctypes.POINTER(ctypes.c_double)

    def relax_steps(z_m: np.ndarray, allowed_m: float) -> None:
        if z_m.dtype != np.float64 or z_m.ndim != 1 or not z_m.flags.c_contiguous \
                or not z_m.flags.writeable:
            raise ValueError("the slump kernel needs a writeable contiguous (n,) float64 array")
        relax(z_m.ctypes.data_as(pointer), len(z_m), float(allowed_m), RELAX_TOLERANCE_M,
              RELAX_MAX_SWEEPS)

    return relax_steps
