"""Plain shared libraries (not FMUs) from C sources with the FMU builder's gcc and flags: the
orchestrator's and the FMUs' own C (LIBRARIES), loaded with ctypes.

A library's source key hashes its sources, the flags and this module; its build key adds the
compiler's version. `build_library` returns the library built with the package (fmus.packaged:
fmus/_built/native/<name>.so) when its recorded source key is the sources' now, no compiler
needed; else (a user's edit of the C sources) it builds it with gcc into
<fmu_dir()>/native/<name>-<build key12>.so, compiled in the source folder on relative names (no
temporary path gets into the binary: byte-reproducible like the FMUs) into a temporary name
renamed into place (atomic: concurrent builds of one key agree).
"""

from __future__ import annotations

import hashlib
import os
import tempfile
from pathlib import Path

from fmus.builder import fmu_dir
from fmus.packaged import packaged_library
from fmus.toolchain import (
    CFLAGS,
    LIBS,
    BuildError,
    FolderError,
    compile_shared,
    gcc,
    gcc_version,
)

__all__ = ["LIBRARIES", "ROOT", "build_library", "compile_library", "library_sources",
           "source_key", "build_key"]

ROOT = Path(__file__).resolve().parent.parent  # the folder that holds the packages
# Every library the packages load: name -> (its source folder under ROOT, its C files).
LIBRARIES: dict[str, tuple[str, tuple[str, ...]]] = {
    "fast_step": ("fmus/fast_step", ("fmi2_step.c", "fmi3_step.c", "steps.c", "rollback.c")),
    "runlog_rows": ("orchestrator/runlog/native", ("rows.c",)),
    "coupling": ("orchestrator/plants/native", ("coupling.c",)),
    "slump": ("planner/native", ("slump.c",)),
}


def library_sources(name: str) -> tuple[Path, tuple[str, ...]]:
    """(source folder, C files) of the library `name` of LIBRARIES."""
    folder, c_files = LIBRARIES[name]
    return ROOT / folder, c_files


def _digest(parts) -> str:
    digest = hashlib.sha256()
    for label, data in parts:
        digest.update(f"{label}:{len(data)}:".encode())
        digest.update(data)
    return digest.hexdigest()


def source_key(source_dir: Path, c_files: tuple[str, ...]) -> str:
    """What the sources make a library of: this module, the flags and the C files."""
    return _digest([("module", Path(__file__).read_bytes()),
                    ("flags", " ".join(CFLAGS + LIBS).encode()),
                    *((f, (source_dir / f).read_bytes()) for f in sorted(c_files))])


def build_key(source: str, compiler_version: str) -> str:
    """The build key: the source key `source` with the compiler's version."""
    return _digest([("source", source.encode()), ("gcc", compiler_version.encode())])


def _ours(*paths: Path) -> bool:
    """A library is loaded from the cache only when it and its folder belong to this user and
    nobody else may write them (as the FMU cache's entries: fmus.builder.cached_content_hashes)."""
    try:
        stats = [os.stat(path) for path in paths]
    except OSError:
        return False
    return all(st.st_uid == os.getuid() and not st.st_mode & 0o022 for st in stats)


def compile_library(name: str, source_dir: Path, c_files: tuple[str, ...], target: Path,
                    compiler: str) -> None:
    """Compile `c_files` (names in `source_dir`) into `target` with `compiler`, through a
    temporary name in target's folder renamed into place. BuildError: a compile error."""
    handle, temporary = tempfile.mkstemp(prefix=f".{name}-", suffix=".so", dir=target.parent)
    os.close(handle)
    try:
        compile_shared(compiler, source_dir, list(c_files), source_dir, Path(temporary), name)
        os.chmod(temporary, 0o755)  # whatever mode the linker left
        os.replace(temporary, target)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise


def build_library(name: str, source_dir: Path, c_files: tuple[str, ...]) -> Path:
    """Path of the shared library `name` built from `c_files` (names in `source_dir`): the
    package's when built from these sources, else built with gcc unless cached. BuildError: no
    gcc, a compile error, or a cache folder that others may write (the message says which)."""
    source = source_key(source_dir, c_files)
    packaged = packaged_library(name, source)
    if packaged is not None:
        return packaged
    compiler = gcc()
    target = fmu_dir() / "native" / f"{name}-{build_key(source, gcc_version(compiler))[:12]}.so"
    if _ours(target.parent, target):
        return target
    try:
        target.parent.mkdir(mode=0o700, parents=True, exist_ok=True)
    except OSError as exc:
        raise FolderError(f"cannot create the library folder {target.parent}: {exc}") from None
    if not _ours(target.parent):
        raise BuildError(f"{target.parent} is not this user's alone (or others may write it): "
                         "no library is loaded from it")
    compile_library(name, source_dir, c_files, target, compiler)
    return target
