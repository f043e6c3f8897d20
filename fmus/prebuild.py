"""Build every FMU (FMI 2.0 and 3.0) and every native library into a built folder, with their
records: what setup.py's build_native runs when the package is built (`pip install .`, `pip
install -e .`, `pip wheel .`); fmus.packaged says how they are found at run time.

    python -m fmus.prebuild [FOLDER]     # default: fmus/_built of this tree

An artifact whose record already has this machine's build key and whose file hashes to it is
kept (an editable reinstall compiles only what changed); files of models or libraries that no
longer exist are removed. Byte-reproducible as every build (fmus.builder).
"""

from __future__ import annotations

import sys
import tempfile
from collections.abc import Callable
from pathlib import Path

from fmus.builder import (
    FMI_VERSIONS,
    MODELS_DIR,
    build_key,
    model_names,
    read_model,
    write_fmu,
)
from fmus.identity import content_hash
from fmus.packaged import (
    BUILT_DIR,
    file_sha256,
    fmu_target,
    library_target,
    read_record,
    record_path,
    write_record,
)
from fmus.shared_library import LIBRARIES, compile_library, library_sources, source_key
from fmus.shared_library import build_key as library_build_key
from fmus.toolchain import fmi_headers, gcc, gcc_version

__all__ = ["prebuild", "stale"]


def _current(target: Path, key: str, check: str, digest: Callable[[Path], str]) -> bool:
    """Whether `target` is already the build of `key` (its record says so, its file agrees)."""
    record = read_record(target)
    if record is None or record.get("build") != key or not target.is_file():
        return False
    try:
        return digest(target) == record.get(check)
    except (OSError, ValueError):
        return False


def prebuild(root: Path = BUILT_DIR, log: Callable[[str], None] = print) -> list[Path]:
    """Build everything into `root` (fmi2/, fmi3/, native/); return every file written or kept
    there (artifacts and records). BuildError: no gcc, no FMI headers, a compile error."""
    root = Path(root).absolute()
    compiler = gcc()
    version = gcc_version(compiler)
    kept: list[Path] = []
    for fmi_version in FMI_VERSIONS:
        headers = fmi_headers(fmi_version)
        for name in model_names():
            model = read_model(MODELS_DIR / name, fmi_version)
            key = build_key(model, version, headers)
            target = fmu_target(root, name, fmi_version)
            if not _current(target, key, "content", content_hash):
                log(f"building {name} (FMI {fmi_version}.0)")
                target.parent.mkdir(parents=True, exist_ok=True)
                with tempfile.TemporaryDirectory(prefix=f".{name}-", dir=target.parent) as tmp:
                    fmu = write_fmu(model, key, Path(tmp), compiler, headers)
                    content = content_hash(fmu)
                    fmu.replace(target)
                write_record(target, {"source": model.source, "build": key, "content": content})
            kept += [target, record_path(target)]
    for name in LIBRARIES:
        source_dir, c_files = library_sources(name)
        source = source_key(source_dir, c_files)
        key = library_build_key(source, version)
        target = library_target(root, name)
        if not _current(target, key, "sha256", file_sha256):
            log(f"building the {name} library")
            target.parent.mkdir(parents=True, exist_ok=True)
            compile_library(name, source_dir, c_files, target, compiler)
            write_record(target, {"source": source, "build": key, "sha256": file_sha256(target)})
        kept += [target, record_path(target)]
    for stale in sorted({path for folder in {p.parent for p in kept} for path in folder.iterdir()}
                        - set(kept)):
        if stale.is_file():
            stale.unlink()
    return kept


def stale(root: Path = BUILT_DIR) -> list[str]:
    """The artifacts under `root` (as fmi2/Pile.fmu, native/slump.so) that are missing or were
    built from other sources than this tree's now: what building the package again would
    compile (`pip install -e .` after an edit of the C sources). No compiler needed."""
    out = []
    for fmi_version in FMI_VERSIONS:
        for name in model_names():
            record = read_record(fmu_target(root, name, fmi_version))
            if record is None or record.get("source") != read_model(MODELS_DIR / name,
                                                                    fmi_version).source:
                out.append(f"fmi{fmi_version}/{name}.fmu")
    for name in LIBRARIES:
        record = read_record(library_target(root, name))
        if record is None or record.get("source") != source_key(*library_sources(name)):
            out.append(f"native/{name}.so")
    return out


if __name__ == "__main__":
    prebuild(Path(sys.argv[1]) if len(sys.argv) > 1 else BUILT_DIR)
