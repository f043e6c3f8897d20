"""Servo designs and cylinder identifications remembered on disk between runs.

Both are pure functions of frozen values (a cylinder model or an FMU's content, parameters,
ports and settings) that take seconds: python-control alone takes about a second to import,
and identifying a substitute FMU runs it 24 times. A run, `scenario show` and the scenario
loader's own check each need them, so they are computed once per machine and read back
after: the file is named by the SHA-256 of the inputs' repr, the code that computes them
(the source of the modules below) and the numeric libraries' versions, and holds that key, so
a change of any of these computes anew. It lives beside the FMU cache ($EXCOSIM_FMU_DIR/designs,
default ~/.cache/excosim/fmus/designs) and only grows; removing it is always safe. A file that
cannot be read or written is passed over: the value is computed as without the cache.
"""

from __future__ import annotations

import hashlib
import os
import pickle
import tempfile
from collections.abc import Callable
from functools import lru_cache
from importlib import metadata
from pathlib import Path
from typing import TypeVar

T = TypeVar("T")
_ROOT = Path(__file__).resolve().parents[2]
# The code whose results are remembered: a change to any of it is a new key.
_CODE = ("plant_models/servo.py", "plant_models/linear_servo.py", "plant_models/cylinder_model.py",
         "plant_models/linear_cylinder.py", "orchestrator/plants/identify.py",
         "orchestrator/plants/design_cache.py")
_LIBRARIES = ("control", "numpy", "scipy", "fmpy")


@lru_cache(maxsize=1)
def _code_key() -> str:
    digest = hashlib.sha256()
    for name in _CODE:
        digest.update(name.encode() + b"\0" + (_ROOT / name).read_bytes())
    for library in _LIBRARIES:
        digest.update(f"{library}={metadata.version(library)}".encode())
    return digest.hexdigest()


def folder() -> Path:
    """Where the remembered values are."""
    from fmus.builder import fmu_dir

    return fmu_dir() / "designs"


def remembered(kind: str, inputs: tuple, compute: Callable[[], T]) -> T:
    """compute() for these inputs (a tuple of values with an exact, stable repr: numbers,
    strings, tuples, frozen dataclasses of them), read from disk when this machine computed it
    before. An exception of compute() is raised and nothing is remembered."""
    key = hashlib.sha256(f"{kind}\0{inputs!r}\0{_code_key()}".encode()).hexdigest()
    path = folder() / f"{kind}-{key[:32]}.pickle"
    try:
        stored_key, value = pickle.loads(path.read_bytes())
        if stored_key == key:
            return value
    except (OSError, pickle.UnpicklingError, EOFError, ValueError, TypeError, AttributeError,
            ImportError, IndexError):
        pass
    value = compute()
    temporary = None
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        descriptor, temporary = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.")
        with os.fdopen(descriptor, "wb") as stream:
            pickle.dump((key, value), stream, protocol=pickle.HIGHEST_PROTOCOL)
        os.replace(temporary, path)  # atomic: a reader sees the old file or the whole new one
    except (OSError, pickle.PicklingError, TypeError, AttributeError):
        if temporary is not None:
            Path(temporary).unlink(missing_ok=True)
    return value
