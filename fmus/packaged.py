"""The FMUs and native libraries built when the package was built (`pip install .`, `pip install
-e .`, a wheel: setup.py's build_native runs fmus.prebuild), found without a compiler.

They live in fmus/_built/ (generated, never in git):

    fmi2/<Model>.fmu, fmi3/<Model>.fmu    each with <Model>.json next to it
    native/<name>.so                      each with <name>.json next to it

A record (<...>.json) holds the artifact's source key (the hash of its sources, tables, flags,
builder and platform folder: fmus.builder.source_key, fmus.shared_library.source_key), its
build key (the source key with the compiler's version and the FMI headers: what a build on this
machine hashes; an FMU's GUID derives from it) and the hash that checks the file (an FMU's
content hash, fmus.identity.content_hash; a library's sha256). An artifact serves when its
record's source key is the one of the sources now and the file hashes to its record: a user's
edit of the C sources changes the source key, and that code is built with gcc into the build
cache (fmus.builder.fmu_dir) as before. The package's own folder is trusted as its Python code
is (whoever may write one may write the other), so no owner check as in the cache.
"""

from __future__ import annotations

import hashlib
import json
import os
from functools import lru_cache
from pathlib import Path

from fmus.identity import UnsafeArchive, content_hash

__all__ = ["BUILT_DIR", "RECORD_SUFFIX", "fmu_target", "library_target", "record_path",
           "read_record", "write_record", "packaged_fmu", "packaged_library", "file_sha256"]

BUILT_DIR = Path(__file__).resolve().parent / "_built"
RECORD_SUFFIX = ".json"


def fmu_target(root: Path, name: str, fmi_version: int) -> Path:
    """Where the FMU of model `name` goes under a built folder `root` (BUILT_DIR or a wheel's)."""
    return root / f"fmi{fmi_version}" / f"{name}.fmu"


def library_target(root: Path, name: str) -> Path:
    """Where the native library `name` goes under a built folder `root`."""
    return root / "native" / f"{name}.so"


def record_path(artifact: Path) -> Path:
    """The record file next to `artifact`."""
    return artifact.with_suffix(RECORD_SUFFIX)


def read_record(artifact: Path) -> dict[str, str] | None:
    """The record next to `artifact`, None when there is none or it cannot be read."""
    try:
        record = json.loads(record_path(artifact).read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError):
        return None
    return record if isinstance(record, dict) else None


def write_record(artifact: Path, record: dict[str, str]) -> None:
    """Write `artifact`'s record atomically (a temporary name renamed into place)."""
    path = record_path(artifact)
    temporary = path.with_name(f".{path.name}.tmp")
    temporary.write_text(json.dumps(record, indent=1, sort_keys=True) + "\n", encoding="utf-8")
    os.replace(temporary, path)


def file_sha256(path: Path) -> str:
    """sha256 of a file's bytes."""
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _stat_key(path: Path) -> tuple | None:
    try:
        stat = path.stat()
    except OSError:
        return None
    return str(path), stat.st_ino, stat.st_size, stat.st_mtime_ns, stat.st_ctime_ns


@lru_cache(maxsize=64)
def _fmu_content(key: tuple) -> str | None:
    """The content hash of the FMU that `key` (_stat_key) names, None if it is no FMU."""
    try:
        return content_hash(key[0])
    except (OSError, ValueError, UnsafeArchive):
        return None


@lru_cache(maxsize=64)
def _library_sha256(key: tuple) -> str | None:
    try:
        return file_sha256(Path(key[0]))
    except OSError:
        return None


def packaged_fmu(name: str, fmi_version: int, source: str) -> Path | None:
    """The packaged FMU of model `name` when it was built from the sources of source key
    `source` and is intact, else None."""
    target = fmu_target(BUILT_DIR, name, fmi_version)
    record = read_record(target)
    if record is None or record.get("source") != source:
        return None
    key = _stat_key(target)
    return target if key is not None and _fmu_content(key) == record.get("content") else None


def packaged_library(name: str, source: str) -> Path | None:
    """The packaged library `name` when it was built from the sources of source key `source`
    and is intact, else None."""
    target = library_target(BUILT_DIR, name)
    record = read_record(target)
    if record is None or record.get("source") != source:
        return None
    key = _stat_key(target)
    return target if key is not None and _library_sha256(key) == record.get("sha256") else None
