"""Compile a plain shared library (not an FMU) from C sources with the FMU builder's gcc and flags,
cached by content: for the orchestrator's own C (orchestrator.plants.native,
orchestrator.runlog.native).

The build key hashes the sources, the flags, the compiler's version and this module; the library
goes to <fmu_dir()>/native/<name>-<key12>.so, compiled in the source folder on relative names
(no temporary path gets into the binary: byte-reproducible like the FMUs) into a temporary name
renamed into place (atomic: concurrent builds of one key agree).
"""

from __future__ import annotations

import hashlib
import os
import tempfile
from pathlib import Path

from fmus.builder import CFLAGS, LIBS, BuildError, _compile, _gcc, _gcc_version, fmu_dir

__all__ = ["build_library"]


def _ours(*paths: Path) -> bool:
    """A library is loaded only when it and its folder belong to this user and nobody else may
    write them (as the FMU cache's entries: fmus.builder.cached_content_hashes)."""
    try:
        stats = [os.stat(path) for path in paths]
    except OSError:
        return False
    return all(st.st_uid == os.getuid() and not st.st_mode & 0o022 for st in stats)


def build_library(name: str, source_dir: Path, c_files: tuple[str, ...]) -> Path:
    """Path of the shared library `name` built from `c_files` (names in `source_dir`), building
    it unless cached. BuildError: no gcc, a compile error, or a cache folder that others may
    write (the message says which)."""
    gcc = _gcc()
    digest = hashlib.sha256()
    for label, data in (("module", Path(__file__).read_bytes()),
                        ("flags", " ".join(CFLAGS + LIBS).encode()),
                        ("gcc", _gcc_version(gcc).encode()),
                        *((f, (source_dir / f).read_bytes()) for f in sorted(c_files))):
        digest.update(f"{label}:{len(data)}:".encode())
        digest.update(data)
    target = fmu_dir() / "native" / f"{name}-{digest.hexdigest()[:12]}.so"
    if _ours(target.parent, target):
        return target
    target.parent.mkdir(mode=0o700, parents=True, exist_ok=True)
    if not _ours(target.parent):
        raise BuildError(f"{target.parent} is not this user's alone (or others may write it): "
                         "no library is loaded from it")
    handle, temporary = tempfile.mkstemp(prefix=f".{name}-", suffix=".so", dir=target.parent)
    os.close(handle)
    try:
        _compile(gcc, source_dir, list(c_files), source_dir, Path(temporary), name)
        os.chmod(temporary, 0o755)  # whatever mode the linker left
        os.replace(temporary, target)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise
    return target
