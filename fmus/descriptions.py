"""fmpy's model description of an FMU file, read once per version of the file.

A campaign reads each FMU's description several times (the scenario's checks, the master, every
instance, the run log's notes), and a sweep's worker again for every run: parsing one took about
3 ms, 12 reads per paper campaign. A version of the file is its path, size, modification and
change times, so a file rebuilt or replaced in place is read anew. The description is shared:
read it, never change it.
"""

from __future__ import annotations

import os
from functools import lru_cache


def model_description(path: str | os.PathLike):
    """fmpy.read_model_description(path), cached per version of the file (an extracted FMU's
    folder is read every time: its files change without it); fmpy's exception for a file that
    is not an FMU (OSError for a missing one)."""
    stat = os.stat(path)
    if not os.path.isfile(path):
        return _read.__wrapped__(os.fspath(path))
    return _read(os.fspath(path), stat.st_mtime_ns, stat.st_ctime_ns, stat.st_size)


@lru_cache(maxsize=64)
def _read(path: str, *version: int):
    from fmpy import read_model_description

    return read_model_description(path)
