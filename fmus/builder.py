"""Compile a model folder into an FMI 2.0 (or 3.0) Co-Simulation FMU with plain gcc, cached by
content; or find it built when the package was built (fmus.packaged), without a compiler.

A model folder fmus/<Model>/ holds variables.toml and the physics (model.c and any other .c/.h);
fmus/common/ holds the shared FMI layers (fmi2_*.c for FMI 2.0, fmi3_*.c for FMI 3.0) and
fmus/shared/<name>/ physics that several models compile in (`shared = [...]` in [model]).

Two keys. The source key (`source_key`) hashes what the sources make an FMU of: FMI version,
sources, table, flags, the binaries' platform folder, this builder and its code generators; no
compiler is needed to compute it. The build key adds the compiler's version and the FMI headers;
the GUID (FMI 3: instantiationToken) derives from it. `build(name)` returns the FMU built with
the package (fmus/_built/) when its recorded source key is the sources' now; else (a user's
edit of the C sources, say) it builds with gcc into $EXCOSIM_FMU_DIR (default
~/.cache/excosim/fmus/) as <Model>-<key12>/<Model>.fmu (FMI 3.0: fmi3/<Model>-<key12>/<Model>.fmu),
<key12> the build key's first 12 hex digits: source trees that differ never share a file, trees
that agree share the build. Next to it, content.sha256 holds the FMU's content hash
(fmus.identity.content_hash: model description, binaries, sources) as built. A cached FMU is used
only when its GUID is the key's and its content hash is the recorded one; anything else (a binary
replaced inside the zip, a cut file) is rebuilt. Both files are written to a temporary name and
renamed into place (atomic). Builds are byte-reproducible: gcc runs in the source folder on
relative names (no temporary path gets into the binary), the zip entries are written in a fixed
order with a fixed date and mode. The binary goes under the platform folder fmpy loads it from
(fmus.toolchain.platform_folder). The cache only grows; removing the folder is always safe.
"""

from __future__ import annotations

import hashlib
import os
import tempfile
import uuid
import zipfile
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

from fmus.codegen import model_description, variables_header
from fmus.codegen3 import model_description_fmi3
from fmus.identity import UnsafeArchive, content_hash
from fmus.packaged import packaged_fmu
from fmus.table import ModelTable, TableError, read_table
from fmus.toolchain import (
    CFLAGS,
    HEADERS,
    LIBS,
    BuildError,
    FolderError,
    compile_shared,
    fmi_headers,
    gcc,
    gcc_version,
    platform_folder,
)

__all__ = [
    "BuildError", "FolderError", "MODELS_DIR", "FMI_VERSIONS", "model_names", "fmu_dir", "build",
    "build_model", "build_all", "Model", "read_model", "source_key", "build_key", "write_fmu",
    "cached_content_hashes", "local_content_hashes",
]

MODELS_DIR = Path(__file__).resolve().parent
COMMON_DIR = MODELS_DIR / "common"
SHARED_DIR = MODELS_DIR / "shared"
BUILDER_VERSION = "excosim-fmus-3"
FMI_VERSIONS = (2, 3)
# Shared-layer files that belong to the other FMI version (never compiled into this one).
_OTHER_LAYER = {2: ("fmi3_",), 3: ("fmi2_", "instance.h")}
# The modules whose code decides what an FMU is made of.
_MODULES = ("builder.py", "codegen.py", "codegen3.py", "table.py", "toolchain.py")
CONTENT_RECORD = "content.sha256"  # next to a cached FMU: its content hash as built
ZIP_DATE = (1980, 1, 1, 0, 0, 0)  # fixed entry date: the same inputs give the same zip bytes


def model_names() -> list[str]:
    """Names of the model folders (fmus/<Model>/ with a variables.toml), sorted."""
    return sorted(p.parent.name for p in MODELS_DIR.glob("*/variables.toml"))


def fmu_dir() -> Path:
    """Where built FMUs go: $EXCOSIM_FMU_DIR, else ~/.cache/excosim/fmus."""
    configured = os.environ.get("EXCOSIM_FMU_DIR")
    return Path(configured).expanduser() if configured else Path.home() / ".cache/excosim/fmus"


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


def _feeder(digest):
    def feed(label: str, data: bytes) -> None:
        digest.update(f"{label}:{len(data)}:".encode())
        digest.update(data)
    return feed


@dataclass(frozen=True)
class Model:
    """A model folder read for a build: its table, sources and source key."""

    folder: Path
    fmi_version: int
    table: ModelTable
    sources: dict[str, bytes]
    source: str  # the source key (module docstring)

    @property
    def name(self) -> str:
        return self.folder.name


def read_model(model_dir: Path, fmi_version: int = 2) -> Model:
    """Read a model folder for an FMI `fmi_version` build (no compiler needed). BuildError for
    an unsupported FMI version, a folder without variables.toml, a bad table or sources."""
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
    sources = _sources(model_dir, table.shared, fmi_version)
    digest = hashlib.sha256()
    feed = _feeder(digest)
    feed("builder", BUILDER_VERSION.encode())
    feed("fmi", str(fmi_version).encode())  # an FMI 3 build never hits an FMI 2 cache entry
    feed("platform", platform_folder(fmi_version).encode())
    for module in _MODULES:  # the generated code depends on these modules
        feed(module, (MODELS_DIR / module).read_bytes())
    feed("flags", " ".join(CFLAGS + LIBS).encode())
    feed("variables.toml", (model_dir / "variables.toml").read_bytes())
    for file_name in sorted(sources):
        feed(file_name, sources[file_name])
    return Model(model_dir, fmi_version, table, sources, digest.hexdigest())


def source_key(model_dir: Path, fmi_version: int = 2) -> str:
    """The source key of a model folder (module docstring): no compiler needed."""
    return read_model(model_dir, fmi_version).source


def build_key(model: Model, compiler_version: str, headers: Path) -> str:
    """The build key: the source key with the compiler's version and the FMI headers."""
    digest = hashlib.sha256()
    feed = _feeder(digest)
    feed("source", model.source.encode())
    feed("gcc", compiler_version.encode())
    for name in HEADERS[model.fmi_version]:
        feed(name, (headers / name).read_bytes())
    return digest.hexdigest()


def _guid(key: str) -> str:
    return "{" + str(uuid.UUID(key[:32])) + "}"


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


def write_fmu(model: Model, key: str, staging: Path, compiler: str, headers: Path) -> Path:
    """Compile and zip `model` with build key `key` in the empty folder `staging`; return the
    FMU's path there (staging/<Model>.fmu). BuildError: a compile error."""
    name, guid = model.name, _guid(key)
    source_dir = staging / "sources"
    source_dir.mkdir()
    for file_name, data in model.sources.items():
        (source_dir / file_name).write_bytes(data)
    (source_dir / "variables.h").write_text(variables_header(model.table, guid), encoding="utf-8")
    c_files = sorted(n for n in model.sources if n.endswith(".c"))
    binary = staging / f"{name}.so"
    compile_shared(compiler, source_dir, c_files, headers, binary, name)
    tool = f"excosim fmus builder ({BUILDER_VERSION})"
    description = (model_description(model.table, guid, c_files, tool) if model.fmi_version == 2
                   else model_description_fmi3(model.table, guid, c_files, tool))
    fmu = staging / f"{name}.fmu"
    with zipfile.ZipFile(fmu, "w", zipfile.ZIP_DEFLATED) as archive:
        _add(archive, "modelDescription.xml", description)
        _add(archive, f"binaries/{platform_folder(model.fmi_version)}/{name}.so",
             binary.read_bytes())
        for path in sorted(source_dir.iterdir()):
            _add(archive, f"sources/{path.name}", path.read_bytes())
    return fmu


def build(name: str, fmi_version: int = 2) -> Path:
    """The FMU of our model fmus/<name>/ (FMI 3.0: `fmi_version=3`): the one built with the
    package when it was built from these sources, else built (or found cached) like
    `build_model`; return its path.

    Raises BuildError with one clear message for a missing model, a bad variables.toml,
    a missing gcc (when a build is needed) or a compile error.
    """
    if not (MODELS_DIR / name / "variables.toml").is_file():
        known = ", ".join(model_names()) or "none"
        raise BuildError(f"unknown model '{name}': no {name}/variables.toml under the fmus "
                         f"package (models: {known})")
    model = read_model(MODELS_DIR / name, fmi_version)
    return packaged_fmu(name, fmi_version, model.source) or _cached_build(model)


def build_model(model_dir: Path, fmi_version: int = 2) -> Path:
    """Build any model folder (variables.toml, model.c, ...) into the build cache (module
    docstring) unless cached and intact; return the FMU path. Needs gcc.

    The folder's name is the model identifier; the shared FMI layer comes from fmus/common.
    """
    return _cached_build(read_model(model_dir, fmi_version))


def _cached_build(model: Model) -> Path:
    headers = fmi_headers(model.fmi_version)
    compiler = gcc()
    key = build_key(model, gcc_version(compiler), headers)
    name = model.name
    out_dir = fmu_dir() if model.fmi_version == 2 else fmu_dir() / "fmi3"
    folder = out_dir / f"{name}-{key[:12]}"
    target, record = folder / f"{name}.fmu", folder / CONTENT_RECORD
    if _intact(target, record, _guid(key)):
        return target
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise FolderError(f"cannot create the FMU folder {out_dir}: {exc}") from None

    with tempfile.TemporaryDirectory(prefix=f".{name}-", dir=out_dir) as tmp:
        staging = Path(tmp)
        partial = write_fmu(model, key, staging, compiler, headers)
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
    """content hash -> model name of every FMU built from this tree's sources (those built with
    the package, no compiler needed; built now where the sources were edited, BuildError if one
    cannot be): what `fmus.identity.content_hash` of an FMU that came from elsewhere is compared
    with to tell our build from native code of unknown origin."""
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
