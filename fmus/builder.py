"""Compile a model folder into an FMI 2.0 Co-Simulation FMU with plain gcc, cached by content.

A model folder fmus/<Model>/ holds variables.toml and the physics (model.c and any other .c/.h);
fmus/common/ holds the shared FMI layer. The FMU goes to $EXCOSIM_FMU_DIR (default
~/.cache/excosim/fmus/) as <Model>.fmu. Its GUID is derived from a hash of everything that
goes into it (sources, table, flags, compiler version, FMI headers, this builder), so an FMU whose
GUID matches the current hash is up to date and is not rebuilt.
"""

from __future__ import annotations

import hashlib
import importlib.util
import os
import shutil
import subprocess
import tempfile
import uuid
import zipfile
from functools import lru_cache
from pathlib import Path

from fmus.codegen import model_description, variables_header
from fmus.table import TableError, read_table

__all__ = [
    "BuildError", "MODELS_DIR", "model_names", "fmu_dir", "build", "build_model", "build_all",
]

MODELS_DIR = Path(__file__).resolve().parent
COMMON_DIR = MODELS_DIR / "common"
BUILDER_VERSION = "excosim-fmus-1"
CFLAGS = [
    "-std=c11", "-O2", "-fPIC", "-shared", "-fvisibility=hidden",
    # Reproducible floating point: no fused multiply-add, no fast-math reassociation.
    "-ffp-contract=off",
    "-Wall", "-Wextra", "-Werror", "-Wno-unused-parameter",
]
LIBS = ["-lm"]


class BuildError(RuntimeError):
    """An FMU could not be built; the message says why (missing gcc, compile error, bad table)."""


def model_names() -> list[str]:
    """Names of the model folders (fmus/<Model>/ with a variables.toml), sorted."""
    return sorted(p.parent.name for p in MODELS_DIR.glob("*/variables.toml"))


def fmu_dir() -> Path:
    """Where built FMUs go: $EXCOSIM_FMU_DIR, else ~/.cache/excosim/fmus."""
    configured = os.environ.get("EXCOSIM_FMU_DIR")
    return Path(configured).expanduser() if configured else Path.home() / ".cache/excosim/fmus"


def _fmi_headers() -> Path:
    spec = importlib.util.find_spec("fmpy")
    if spec is None or spec.origin is None:
        raise BuildError("fmpy is not installed: its FMI 2.0 headers (fmpy/c-code) are needed")
    headers = Path(spec.origin).parent / "c-code"
    if not (headers / "fmi2Functions.h").is_file():
        raise BuildError(f"fmpy has no FMI 2.0 headers at {headers}")
    return headers


def _gcc() -> str:
    gcc = shutil.which("gcc")
    if gcc is None:
        raise BuildError("gcc not found on PATH: install a C compiler (e.g. apt install gcc) "
                         "to build the FMUs")
    return gcc


@lru_cache(maxsize=4)
def _gcc_version(gcc: str) -> str:
    try:
        result = subprocess.run([gcc, "--version"], capture_output=True, text=True, check=True)
    except (OSError, subprocess.CalledProcessError) as exc:
        raise BuildError(f"cannot run {gcc} --version: {exc}") from None
    return result.stdout


def _sources(model_dir: Path) -> dict[str, bytes]:
    """All C sources and headers of the model and the shared layer, by flat file name."""
    files: dict[str, bytes] = {}
    for folder in (COMMON_DIR, model_dir):
        for path in sorted(folder.iterdir()):
            if path.suffix not in (".c", ".h") or not path.is_file():
                continue
            if path.name in files or path.name == "variables.h":
                raise BuildError(f"{model_dir.name}: source file name '{path.name}' clashes with "
                                 "a shared or generated file; rename it")
            files[path.name] = path.read_bytes()
    if "model.c" not in files:
        raise BuildError(f"{model_dir.name}: no model.c in {model_dir}")
    return files


def _content_hash(table_bytes: bytes, sources: dict[str, bytes], gcc_version: str,
                  headers: Path) -> str:
    digest = hashlib.sha256()

    def feed(label: str, data: bytes) -> None:
        digest.update(f"{label}:{len(data)}:".encode())
        digest.update(data)

    feed("builder", BUILDER_VERSION.encode())
    for module in ("builder.py", "codegen.py", "table.py"):  # generated code depends on these
        feed(module, (MODELS_DIR / module).read_bytes())
    feed("flags", " ".join(CFLAGS + LIBS).encode())
    feed("gcc", gcc_version.encode())
    feed("variables.toml", table_bytes)
    for name in sorted(sources):
        feed(name, sources[name])
    for name in ("fmi2Functions.h", "fmi2FunctionTypes.h", "fmi2TypesPlatform.h"):
        feed(name, (headers / name).read_bytes())
    return digest.hexdigest()


def _guid_of(fmu: Path) -> str | None:
    try:
        with zipfile.ZipFile(fmu) as archive:
            text = archive.read("modelDescription.xml").decode("utf-8")
    except (OSError, KeyError, zipfile.BadZipFile):
        return None
    start = text.find('guid="')
    return text[start + 6:text.find('"', start + 6)] if start >= 0 else None


def _compile(gcc: str, source_dir: Path, c_files: list[str], headers: Path, output: Path,
             model: str) -> None:
    command = [gcc, *CFLAGS, "-I", str(source_dir), "-I", str(headers),
               *[str(source_dir / name) for name in c_files], "-o", str(output), *LIBS]
    result = subprocess.run(command, capture_output=True, text=True)
    if result.returncode != 0:
        lines = [line for line in result.stderr.splitlines() if line.strip()]
        errors = [line for line in lines if "error" in line] or lines
        shown = "\n  ".join(line.replace(str(source_dir) + os.sep, "") for line in errors[:5])
        raise BuildError(f"{model}: gcc failed to compile the model:\n  {shown}")


def build(name: str) -> Path:
    """Build fmus/<name>/ into <fmu_dir()>/<name>.fmu if its content changed; return the path.

    Raises BuildError with one clear message for a missing model, a bad variables.toml,
    a missing gcc or a compile error.
    """
    if not (MODELS_DIR / name / "variables.toml").is_file():
        known = ", ".join(model_names()) or "none"
        raise BuildError(f"unknown model '{name}': no {name}/variables.toml under the fmus "
                         f"package (models: {known})")
    return build_model(MODELS_DIR / name)


def build_model(model_dir: Path) -> Path:
    """Build any model folder (variables.toml, model.c, ...) like `build`; return the FMU path.

    The folder's name is the model identifier; the shared FMI layer comes from fmus/common.
    """
    model_dir = Path(model_dir)
    name = model_dir.name
    if not (model_dir / "variables.toml").is_file():
        raise BuildError(f"{model_dir} is not a model folder: it has no variables.toml")
    try:
        table = read_table(model_dir / "variables.toml")
    except TableError as exc:
        raise BuildError(str(exc)) from None
    if table.identifier != name:
        raise BuildError(f"{name}/variables.toml: [model] identifier '{table.identifier}' "
                         f"must equal the folder name '{name}'")
    headers = _fmi_headers()
    gcc = _gcc()
    sources = _sources(model_dir)
    content = _content_hash((model_dir / "variables.toml").read_bytes(), sources,
                            _gcc_version(gcc), headers)
    guid = "{" + str(uuid.UUID(content[:32])) + "}"

    out_dir = fmu_dir()
    target = out_dir / f"{name}.fmu"
    if target.is_file() and _guid_of(target) == guid:
        return target
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise BuildError(f"cannot create the FMU folder {out_dir}: {exc}") from None

    with tempfile.TemporaryDirectory(prefix=f".{name}-", dir=out_dir) as tmp:
        staging = Path(tmp)
        source_dir = staging / "sources"
        source_dir.mkdir()
        for file_name, data in sources.items():
            (source_dir / file_name).write_bytes(data)
        (source_dir / "variables.h").write_text(variables_header(table, guid), encoding="utf-8")
        c_files = sorted(n for n in sources if n.endswith(".c"))
        binary = staging / f"{name}.so"
        _compile(gcc, source_dir, c_files, headers, binary, name)
        description = model_description(table, guid, c_files, f"excosim fmus builder "
                                         f"({BUILDER_VERSION})")
        partial = staging / f"{name}.fmu"
        with zipfile.ZipFile(partial, "w", zipfile.ZIP_DEFLATED) as archive:
            archive.writestr("modelDescription.xml", description)
            archive.write(binary, f"binaries/linux64/{name}.so")
            for path in sorted(source_dir.iterdir()):
                archive.write(path, f"sources/{path.name}")
        os.replace(partial, target)  # atomic: readers see the old or the new FMU, never half
    return target


def build_all() -> dict[str, Path]:
    """Build every model folder; return {model name: FMU path}.

    Tries every model even when one fails, then raises BuildError naming each failure.
    """
    built: dict[str, Path] = {}
    errors: list[str] = []
    for name in model_names():
        try:
            built[name] = build(name)
        except BuildError as exc:
            errors.append(str(exc))
    if errors:
        raise BuildError("\n".join(errors))
    return built
