"""The run log's row filling in C (rows.c), bound with ctypes: the one implementation.

`library()` is the library built with the package (fmus.shared_library: compiled when the
package was built, or by gcc after an edit of rows.c); BuildError where it cannot be had, and on
a big-endian host (rows.c copies native integers and doubles into little-endian records).
tests/run_log_reference.py encodes the same bytes the plain way, as the tests' oracle.
`write(jobs)` runs a table of rows.c jobs (`job(kind, *arguments)` each) in one call;
`pointer(array)` is the address of an array, as a job's argument.
"""

from __future__ import annotations

import ctypes
import sys
from functools import lru_cache

import numpy as np


@lru_cache(maxsize=1)
def library() -> ctypes.CDLL:
    """rows.c built and loaded. BuildError (fmus.BuildError) when it cannot be had."""
    from fmus.builder import BuildError
    from fmus.shared_library import build_library, library_sources

    if sys.byteorder != "little":
        raise BuildError("the run log's rows.c writes little-endian records from native "
                         "integers and doubles: this big-endian host cannot write run logs")
    path = build_library("runlog_rows", *library_sources("runlog_rows"))
    try:
        loaded = ctypes.CDLL(str(path))
    except OSError as error:
        raise BuildError(f"cannot load {path}: {error}") from None
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
