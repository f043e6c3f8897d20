"""Compile a model folder into an FMI 2.0 (or 3.0) Co-Simulation FMU with plain gcc, cached by
content.

A model folder fmus/<Model>/ holds variables.toml and the physics (model.c and any other .c/.h);
fmus/common/ holds the shared FMI layers (fmi2_*.c for FMI 2.0, fmi3_*.c for FMI 3.0) and
fmus/shared/<name>/ physics that several models compile in (`shared = [...]` in [model]).

The build key is a hash of everything that goes into an FMU (FMI version, sources, table, flags,
compiler version, FMI headers, this builder); the GUID (FMI 3: instantiationToken) is derived
from it. The FMU goes to $EXCOSIM_FMU_DIR (default ~/.cache/excosim/fmus/) as
<Model>-<key12>/<Model>.fmu (FMI 3.0: fmi3/<Model>-<key12>/<Model>.fmu), <key12> the key's first
12 hex digits: source trees that differ never share a file, trees that agree share the build.
Next to it, content.sha256 holds the FMU's content hash (fmus.identity.content_hash: model
description, binaries, sources) as built. A cached FMU is used only when its GUID is the key's and
its content hash is the recorded one; anything else (a binary replaced inside the zip, a cut
file) is rebuilt. Both files are written to a temporary name and renamed into place (atomic).
Builds are byte-reproducible: gcc runs in the source folder on relative names (no temporary path
gets into the binary), the zip entries are written in a fixed order with a fixed date and mode.
The cache only grows; removing the folder is always safe.
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
from fmus.codegen3 import model_description_fmi3
from fmus.identity import UnsafeArchive, content_hash
from fmus.table import TableError, read_table

__all__ = [
    "BuildError", "MODELS_DIR", "FMI_VERSIONS", "model_names", "fmu_dir", "build", "build_model",
    "build_all", "cached_content_hashes", "local_content_hashes",
]

MODELS_DIR = Path(__file__).resolve().parent
COMMON_DIR = MODELS_DIR / "common"
SHARED_DIR = MODELS_DIR / "shared"
BUILDER_VERSION = "excosim-fmus-2"
FMI_VERSIONS = (2, 3)
# The FMI headers (from fmpy's c-code folder) each version compiles against.
HEADERS = {
    2: ("fmi2Functions.h", "fmi2FunctionTypes.h", "fmi2TypesPlatform.h"),
    3: ("fmi3Functions.h", "fmi3FunctionTypes.h", "fmi3PlatformTypes.h"),
}
# Shared-layer files that belong to the other FMI version (never compiled into this one).
_OTHER_LAYER = {2: ("fmi3_",), 3: ("fmi2_", "instance.h")}
CONTENT_RECORD = "content.sha256"  # next to a cached FMU: its content hash as built
ZIP_DATE = (1980, 1, 1, 0, 0, 0)  # fixed entry date: the same inputs give the same zip bytes
CFLAGS = [
    "-std=c11", "-O2", "-fPIC", "-shared", "-fvisibility=hidden",
    # Reproducible floating point: no fused multiply-add, no fast-math reassociation.
    "-ffp-contract=off",
    "-Wall", "-Wextra", "-Werror", "-Wno-unused-parameter",
]
LIBS = ["-lm"]


class BuildError(RuntimeError):
    """An FMU could not be built; the message says why (missing gcc, compile error, bad table).
    `exit_status`: 2 when the cause is the user's setting (an FMU folder that cannot be made),
    1 for a failure of the build itself."""

    exit_status = 1


class FolderError(BuildError):
    """The FMU folder ($EXCOSIM_FMU_DIR) cannot be made: the user's setting."""

    exit_status = 2


def model_names() -> list[str]:
    """Names of the model folders (fmus/<Model>/ with a variables.toml), sorted."""
    return sorted(p.parent.name for p in MODELS_DIR.glob("*/variables.toml"))


def fmu_dir() -> Path:
    """Where built FMUs go: $EXCOSIM_FMU_DIR, else ~/.cache/excosim/fmus."""
    configured = os.environ.get("EXCOSIM_FMU_DIR")
    return Path(configured).expanduser() if configured else Path.home() / ".cache/excosim/fmus"


def _fmi_headers(fmi_version: int = 2) -> Path:
    spec = importlib.util.find_spec("fmpy")
    if spec is None or spec.origin is None:
        raise BuildError(f"fmpy is not installed: its FMI {fmi_version}.0 headers (fmpy/c-code) "
                         "are needed")
    headers = Path(spec.origin).parent / "c-code"
    if not all((headers / name).is_file() for name in HEADERS[fmi_version]):
        raise BuildError(f"fmpy has no FMI {fmi_version}.0 headers at {headers}")
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


def _sources(model_dir: Path, shared: tuple[str, ...] = (),
             fmi_version: int = 2) -> dict[str, bytes]:
    """All C sources and headers of the model, its shared folders and the FMI layer of
    `fmi_version`, by flat file name."""
    files: dict[str, bytes] = {}
    folders = [COMMON_DIR]
    for name in shared:
        if not (SHARED_DIR / name).is_dir():
            raise BuildError(f"{model_dir.name}: shared source folder '{name}' not found "
                             f"(no {SHARED_DIR / name})")
        folders.append(SHARED_DIR / name)
    for folder in (*folders, model_dir):
        for path in sorted(folder.iterdir()):
            if path.suffix not in (".c", ".h") or not path.is_file():
                continue
            if folder == COMMON_DIR and path.name.startswith(_OTHER_LAYER[fmi_version]):
                continue
            if path.name in files or path.name == "variables.h":
                raise BuildError(f"{model_dir.name}: source file name '{path.name}' clashes with "
                                 "a shared or generated file; rename it")
            files[path.name] = path.read_bytes()
    if "model.c" not in files:
        raise BuildError(f"{model_dir.name}: no model.c in {model_dir}")
    return files


def _content_hash(table_bytes: bytes, sources: dict[str, bytes], gcc_version: str,
                  headers: Path, fmi_version: int = 2) -> str:
    digest = hashlib.sha256()

    def feed(label: str, data: bytes) -> None:
        digest.update(f"{label}:{len(data)}:".encode())
        digest.update(data)

    feed("builder", BUILDER_VERSION.encode())
    feed("fmi", str(fmi_version).encode())  # an FMI 3 build never hits an FMI 2 cache entry
    # The generated code depends on these modules.
    for module in ("builder.py", "codegen.py", "codegen3.py", "table.py"):
        feed(module, (MODELS_DIR / module).read_bytes())
    feed("flags", " ".join(CFLAGS + LIBS).encode())
    feed("gcc", gcc_version.encode())
    feed("variables.toml", table_bytes)
    for name in sorted(sources):
        feed(name, sources[name])
    for name in HEADERS[fmi_version]:
        feed(name, (headers / name).read_bytes())
    return digest.hexdigest()


def _guid_of(fmu: Path) -> str | None:
    try:
        with zipfile.ZipFile(fmu) as archive:
            text = archive.read("modelDescription.xml").decode("utf-8")
    except (OSError, KeyError, zipfile.BadZipFile):
        return None
    for key in ('guid="', 'instantiationToken="'):  # FMI 2 / FMI 3
        start = text.find(key)
        if start >= 0:
            return text[start + len(key):text.find('"', start + len(key))]
    return None


def _compile(gcc: str, source_dir: Path, c_files: list[str], headers: Path, output: Path,
             model: str) -> None:
    # Relative source names in the source folder: the binary holds no temporary path.
    command = [gcc, *CFLAGS, "-I", ".", "-I", str(headers), *c_files, "-o", str(output), *LIBS]
    result = subprocess.run(command, capture_output=True, text=True, cwd=source_dir)
    if result.returncode != 0:
        lines = [line for line in result.stderr.splitlines() if line.strip()]
        errors = [line for line in lines if "error" in line] or lines
        shown = "\n  ".join(line.replace(str(source_dir) + os.sep, "") for line in errors[:5])
        raise BuildError(f"{model}: gcc failed to compile the model:\n  {shown}")


def build(name: str, fmi_version: int = 2) -> Path:
    """Build fmus/<name>/ into <fmu_dir()>/<name>-<key12>/<name>.fmu (FMI 3.0: under fmi3/)
    unless that FMU is cached and intact (module docstring); return its path.

    Raises BuildError with one clear message for a missing model, a bad variables.toml,
    a missing gcc or a compile error.
    """
    if not (MODELS_DIR / name / "variables.toml").is_file():
        known = ", ".join(model_names()) or "none"
        raise BuildError(f"unknown model '{name}': no {name}/variables.toml under the fmus "
                         f"package (models: {known})")
    return build_model(MODELS_DIR / name, fmi_version)


def build_model(model_dir: Path, fmi_version: int = 2) -> Path:
    """Build any model folder (variables.toml, model.c, ...) like `build`; return the FMU path.

    The folder's name is the model identifier; the shared FMI layer comes from fmus/common.
    """
    if fmi_version not in FMI_VERSIONS:
        raise BuildError(f"FMI version {fmi_version!r} is not supported (use 2 or 3)")
    model_dir = Path(model_dir)
    name = model_dir.name
    if not (model_dir / "variables.toml").is_file():
        raise BuildError(f"{model_dir} is not a model folder: it has no variables.toml")
    try:
        table = _read_table(model_dir / "variables.toml")
    except TableError as exc:
        raise BuildError(str(exc)) from None
    if table.identifier != name:
        raise BuildError(f"{name}/variables.toml: [model] identifier '{table.identifier}' "
                         f"must equal the folder name '{name}'")
    headers = _fmi_headers(fmi_version)
    gcc = _gcc()
    sources = _sources(model_dir, table.shared, fmi_version)
    content = _content_hash((model_dir / "variables.toml").read_bytes(), sources,
                            _gcc_version(gcc), headers, fmi_version)
    guid = "{" + str(uuid.UUID(content[:32])) + "}"

    out_dir = fmu_dir() if fmi_version == 2 else fmu_dir() / "fmi3"
    folder = out_dir / f"{name}-{content[:12]}"
    target, record = folder / f"{name}.fmu", folder / CONTENT_RECORD
    if _intact(target, record, guid):
        return target
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise FolderError(f"cannot create the FMU folder {out_dir}: {exc}") from None

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
        tool = f"excosim fmus builder ({BUILDER_VERSION})"
        description = (model_description(table, guid, c_files, tool) if fmi_version == 2
                       else model_description_fmi3(table, guid, c_files, tool))
        platform = "linux64" if fmi_version == 2 else "x86_64-linux"  # FMI 3 platform tuple
        partial = staging / f"{name}.fmu"
        with zipfile.ZipFile(partial, "w", zipfile.ZIP_DEFLATED) as archive:
            _add(archive, "modelDescription.xml", description)
            _add(archive, f"binaries/{platform}/{name}.so", binary.read_bytes())
            for path in sorted(source_dir.iterdir()):
                _add(archive, f"sources/{path.name}", path.read_bytes())
        (staging / CONTENT_RECORD).write_text(content_hash(partial) + "\n", encoding="ascii")
        folder.mkdir(exist_ok=True)
        # Atomic, record first: a reader sees the old or the new files, never half of one; a
        # new record next to an old FMU only makes that reader build once more.
        os.replace(staging / CONTENT_RECORD, record)
        os.replace(partial, target)
    return target


def _signature(path: Path) -> tuple | None:
    """What changes whenever a file's bytes may have (ctime: any write, rename or chmod)."""
    try:
        stat = path.stat()
    except OSError:
        return None
    return (str(path), stat.st_ino, stat.st_size, stat.st_mtime_ns, stat.st_ctime_ns)


def _read_table(path: Path):
    signature = _signature(path)
    return _parse_table(signature) if signature is not None else read_table(path)


@lru_cache(maxsize=32)
def _parse_table(signature: tuple):
    return read_table(Path(signature[0]))


_VERIFIED: dict[tuple, tuple] = {}  # cached FMU's signature -> (guid, its record's signature)


def _intact(target: Path, record: Path, guid: str) -> bool:
    """Whether the cached FMU at `target` is the build of `guid` with its recorded content.
    Verified once per version of the two files in this process (their signatures)."""
    signatures = _signature(target), _signature(record)
    if None in signatures:
        return False
    if _VERIFIED.get(signatures[0]) == (guid, signatures[1]):
        return True
    if _guid_of(target) != guid:
        return False
    try:
        expected = record.read_text(encoding="ascii").strip()
        if content_hash(target) != expected:
            return False
    except (OSError, UnicodeDecodeError, UnsafeArchive):
        return False
    _VERIFIED[signatures[0]] = (guid, signatures[1])
    return True


def _add(archive: zipfile.ZipFile, name: str, data: bytes) -> None:
    info = zipfile.ZipInfo(name, date_time=ZIP_DATE)
    info.compress_type = zipfile.ZIP_DEFLATED
    info.external_attr = 0o644 << 16  # regular file, rw-r--r--, whatever the umask
    archive.writestr(info, data)


def local_content_hashes(fmi_version: int = 2) -> dict[str, str]:
    """content hash -> model name of every FMU built from this tree's sources (built now if
    needed; BuildError if one cannot be): what `fmus.identity.content_hash` of an FMU that came
    from elsewhere is compared with to tell our build from native code of unknown origin."""
    return {content_hash(build(name, fmi_version)): name for name in model_names()}


def cached_content_hashes() -> dict[str, str]:
    """content hash -> model name of every FMU in the build cache (FMI 2.0 and 3.0), whatever
    version of the sources it was built from: the FMUs this machine built. A log of an earlier
    version's run names such FMUs; they are ours, not native code of unknown origin, for as
    long as the cache keeps them. An entry counts only when its FMU is there and hashes to its
    record (as a cached build is checked before use), and when the folder, the FMU and the
    record belong to this user and nobody else may write them: a file planted in a shared
    cache makes nothing "ours"."""
    found: dict[str, str] = {}
    for root in (fmu_dir(), fmu_dir() / "fmi3"):
        for record in sorted(root.glob(f"*/{CONTENT_RECORD}")):
            model = record.parent.name.rpartition("-")[0]
            fmu = record.parent / f"{model}.fmu"
            try:
                digest = record.read_text(encoding="ascii").strip()
                stats = [os.stat(path) for path in (record.parent, record, fmu)]
            except (OSError, UnicodeDecodeError):
                continue
            if any(st.st_uid != os.getuid() or st.st_mode & 0o022 for st in stats):
                continue
            if _cached_content(str(fmu), stats[2].st_mtime_ns, stats[2].st_size) == digest:
                found[digest] = model
    return found


@lru_cache(maxsize=256)
def _cached_content(path: str, *stat: int) -> str | None:
    """The content hash of the cached FMU at `path` (`stat`: its identity now)."""
    try:
        return content_hash(path)
    except (OSError, ValueError, UnsafeArchive, zipfile.BadZipFile):
        return None


def build_all(fmi_version: int = 2) -> dict[str, Path]:
    """Build every model folder (as FMI `fmi_version`); return {model name: FMU path}.

    Tries every model even when one fails, then raises BuildError naming each failure.
    """
    built: dict[str, Path] = {}
    errors: list[str] = []
    for name in model_names():
        try:
            built[name] = build(name, fmi_version)
        except BuildError as exc:
            errors.append(str(exc))
    if errors:
        raise BuildError("\n".join(errors))
    return built
