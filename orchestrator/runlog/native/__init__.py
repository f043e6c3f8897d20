"""The run log's row filling in C (rows.c), bound with ctypes.

`library()` is the built library (gcc, built on first use and cached like the FMUs:
fmus.shared_library), or None where it cannot be had (no gcc, a big-endian host): the chunk
builder then fills its rows with numpy, to the same bytes (tests/test_run_log_fast_paths.py).
`pointer(array)` is what its functions take for an array (an address; argtypes say c_void_p).
"""

from __future__ import annotations

import ctypes
import sys
from functools import lru_cache
from pathlib import Path

import numpy as np


@lru_cache(maxsize=1)
def library() -> ctypes.CDLL | None:
    """rows.c built and loaded, or None (see the module docstring)."""
    from fmus.builder import BuildError
    from fmus.shared_library import build_library

    if sys.byteorder != "little":  # rows.c copies native integers and doubles
        return None
    try:
        path = build_library("runlog_rows", Path(__file__).resolve().parent, ("rows.c",))
    except BuildError:
        return None
    loaded = ctypes.CDLL(str(path))
    address, size = ctypes.c_void_p, ctypes.c_long
    loaded.fill_rows.argtypes = [address, address, size, size, address, address, size, address,
                                 address, address, size, address, address, address]
    loaded.fill_rows.restype = None
    loaded.place_rows.argtypes = [address, address, size, size, address]
    loaded.place_rows.restype = None
    loaded.fill_transforms.argtypes = [address, address, size, size, address, address, size,
                                       address, address, address]
    loaded.fill_transforms.restype = None
    return loaded


def pointer(array: np.ndarray) -> int:
    """The address of a C-contiguous array's first element."""
    return array.ctypes.data
