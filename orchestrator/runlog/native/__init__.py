"""The run log's row filling in C (rows.c), bound with ctypes.

`library()` is the built library (gcc, built on first use and cached like the FMUs:
fmus.shared_library), or None where it cannot be had (no gcc, a cache folder that cannot be
written, a big-endian host): the chunk
builder then fills its rows with numpy, to the same bytes (tests/test_run_log_fast_paths.py).
`write(jobs)` runs a table of rows.c jobs (`job(kind, *arguments)` each) in one call;
`pointer(array)` is the address of an array, as a job's argument.
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
        loaded = ctypes.CDLL(str(path))
    except (BuildError, OSError):  # no gcc; a cache folder that cannot be written or read
        return None
    loaded.write_records.argtypes = [ctypes.c_void_p, ctypes.c_long]
    loaded.write_records.restype = ctypes.c_long
    return loaded


def pointer(array: np.ndarray) -> int:
    """The address of a C-contiguous array's first element."""
    return array.ctypes.data


PLACE_ROWS, FILL_ROWS, FILL_TRANSFORMS = 0, 1, 2  # rows.c's job kinds
_SLOTS = 16


def job(kind: int, *arguments: int) -> list[int]:
    """One row of a job table: rows.c's kind and its arguments (ints; addresses for arrays)."""
    return [kind, *arguments, *(0,) * (_SLOTS - 1 - len(arguments))]


def write(jobs: list[list[int]]) -> None:
    """Run rows.c's jobs, in order, in one call with the GIL free. The caller keeps every
    array a job points to alive meanwhile."""
    table = np.array(jobs, dtype=np.int64)
    failed = library().write_records(pointer(table), len(jobs))
    if failed >= 0:
        raise ValueError(f"rows.c job {failed} has an unknown kind {jobs[failed][0]}")
