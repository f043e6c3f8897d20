"""What a run log says about its run before the first period: metadata records (format,
scenario, package versions, FMU hashes, geometry) and attachments (scenario file, FMUs)."""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
import platform
import tomllib
from collections.abc import Mapping
from importlib import metadata as importlib_metadata
from pathlib import Path

import numpy as np

from orchestrator.runlog.mcap_records import McapChunkWriter
from orchestrator.runlog.scene import FRAMES_DOC
from plant_models.geometry import ExcavatorGeometry

FORMAT = "excosim-run-log"
FORMAT_VERSION = "1"
# Distribution names of the packages whose versions a run records.
_PACKAGES = (("excosim", "excosim"), ("fmpy", "fmpy"), ("numpy", "numpy"), ("scipy", "scipy"),
             ("control", "control"), ("foxglove", "foxglove-sdk"), ("mcap", "mcap"))


def package_versions() -> dict[str, str]:
    """Versions of excosim, its numerical and logging dependencies and Python (a new dict)."""
    return dict(_installed_versions())


@functools.lru_cache(maxsize=1)
def _installed_versions() -> dict[str, str]:
    """Once per process: reading the installed packages' metadata took 10 ms a call, twice per
    run log, a tenth of a paper campaign's logging time."""
    out = {}
    for name, distribution in _PACKAGES:
        try:
            out[name] = _version(distribution)
        except importlib_metadata.PackageNotFoundError:
            out[name] = "not installed"
    out["python"] = platform.python_version()
    return out


def _version(distribution: str) -> str:
    """importlib.metadata.version(distribution), read from the METADATA file's header block:
    importlib parses the whole file with the email package (long descriptions included), 5 of
    the 9 ms a campaign's first run log spent on versions."""
    found = importlib_metadata.distribution(distribution)
    text = found.read_text("METADATA") or ""
    for line in text.split("\n\n", 1)[0].splitlines():
        if line.startswith("Version:"):
            return line.removeprefix("Version:").strip()
    return found.version  # no METADATA header (PKG-INFO, egg-info): importlib's own reading


def scenario_attachment(text: str) -> tuple[str, str]:
    """Attachment name and media type for a scenario file's text: TOML, JSON or plain text."""
    try:
        tomllib.loads(text)
        return "scenario.toml", "application/toml"
    except tomllib.TOMLDecodeError:
        pass
    try:
        json.loads(text)
        return "scenario.json", "application/json"
    except ValueError:
        return "scenario.txt", "text/plain"


def _plain(value):
    """JSON fallback for numpy values and paths."""
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, Path):
        return str(value)
    raise TypeError(f"{type(value).__name__} is not JSON-serializable")


def to_json(value, what: str) -> str:
    """JSON text of `value` (numpy values become lists and numbers); ValueError naming `what`
    if it is not JSON-able (NaN and infinities included)."""
    try:
        return json.dumps(value, default=_plain, allow_nan=False)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{what} is not JSON-serializable: {exc}") from None


def read_fmus(fmus: Mapping[str, str | Path]) -> dict[str, tuple[str, bytes]]:
    """FMU name -> (file name, bytes); ValueError naming an FMU whose file is missing."""
    out = {}
    for name, path in fmus.items():
        if not Path(path).is_file():
            raise ValueError(f"FMU {name!r}: no file at {path}")
        out[name] = (Path(path).name, Path(path).read_bytes())
    return out


def fmu_content(data: bytes) -> str:
    """The content hash of an FMU's bytes (fmus.identity.content_hash), "" if it is not a
    readable FMU archive (the run log still records its file sha256)."""
    from fmus.identity import UnsafeArchive, content_hash

    try:
        return content_hash(data)
    except UnsafeArchive:
        return ""


_CONTENTS: dict[str, str] = {}  # FMU file sha256 -> fmu_content: one FMU file often fills
# several roles, and a sweep's campaigns use the same files over and over


def _content_of(digest: str, data: bytes) -> str:
    """fmu_content(data), once per distinct file (`digest`: the sha256 of `data`)."""
    if digest not in _CONTENTS:
        if len(_CONTENTS) >= 256:
            _CONTENTS.clear()
        _CONTENTS[digest] = fmu_content(data)
    return _CONTENTS[digest]


def plant_roles(scenario: Mapping, fmus: Mapping[str, tuple[str, bytes]],
                hashes: Mapping[str, str],
                derived: Mapping[str, Mapping[str, str]] | None = None,
                contents: Mapping[str, str] | None = None,
                arm_coupling: Mapping[str, str] | None = None,
                notes: Mapping[str, Mapping[str, str]] | None = None) -> dict[str, str]:
    """role -> JSON {"fmu": as the scenario names it, "file", "sha256" (of the file),
    "content_sha256" (fmu_content), "parameters", "ports", "derived"} of every FMU role: which
    model filled each role, so that a review can tell substitutions apart; "derived":
    {output: how} of the outputs the master computed instead of reading them from the FMU
    ({}: none); "arm_coupling", for a cylinder role of a simulated plant: how the step loop
    coupled the arm's cross inertia into it; `notes`: role -> further fields in words (the
    simulated plant's "arm_inertia" and "supply", orchestrator.plants.role_notes)."""
    plant = scenario.get("plant", {}) if isinstance(scenario, Mapping) else {}
    out = {}
    for role, (file_name, _) in fmus.items():
        table = plant.get(role, {}) if isinstance(plant, Mapping) else {}
        table = table if isinstance(table, Mapping) else {}
        entry = {"fmu": table.get("fmu", file_name), "file": file_name,
                 "fmi_version": fmi_version(fmus[role][1]),
                 "sha256": hashes[role], "content_sha256": (contents or {}).get(role, ""),
                 "parameters": table.get("parameters", {}), "ports": table.get("ports", {}),
                 "derived": dict((derived or {}).get(role, {}))}
        if role in (arm_coupling or {}):
            entry["arm_coupling"] = arm_coupling[role]
        entry.update((notes or {}).get(role, {}))
        out[role] = to_json(entry, f"role {role}")
    return out


def fmi_version(data: bytes) -> str:
    """The fmiVersion of the FMU file `data` (its modelDescription.xml), "" if unreadable."""
    import io
    import xml.etree.ElementTree as ElementTree
    import zipfile

    try:
        with zipfile.ZipFile(io.BytesIO(data)) as archive:
            root = ElementTree.fromstring(archive.read("modelDescription.xml"))
        return str(root.attrib.get("fmiVersion", ""))
    except (zipfile.BadZipFile, KeyError, ElementTree.ParseError):
        return ""


def scenario_digest(scenario_json: str) -> str:
    """The sha256 (hex) of the resolved scenario's JSON text as the excosim.scenario record
    holds it."""
    return hashlib.sha256(scenario_json.encode()).hexdigest()


def write_run_description(writer: McapChunkWriter, *, scenario_json: str, scenario_text: str,
                          scenario_name: str, fmus: dict[str, tuple[str, bytes]],
                          plant_kind: str, target_mass_kg: float,
                          geometry: ExcavatorGeometry | None,
                          overrides: list[str] | None = None,
                          derived: Mapping[str, Mapping[str, str]] | None = None,
                          arm_coupling: Mapping[str, str] | None = None,
                          notes: Mapping[str, Mapping[str, str]] | None = None) -> None:
    """The metadata records and attachments a run log starts with (`orchestrator.runlog.writer`).
    The header (excosim.run) records scenario_sha256, the digest of the scenario record
    (`scenario_digest`): a resume refuses a log whose scenario record was edited since."""
    versions = package_versions()
    scenario_file, scenario_media = scenario_attachment(scenario_text)
    writer.add_metadata("excosim.run", {
        "format": FORMAT, "format_version": FORMAT_VERSION, "scenario_name": scenario_name,
        "plant_kind": plant_kind, "target_mass_kg": repr(float(target_mass_kg)),
        "scenario_attachment": scenario_file,
        "geometry": geometry.name if geometry is not None else "",
        "time_base": "log time = campaign time in ns since the start of period 1",
        "frames": FRAMES_DOC,
        "overrides": to_json(list(overrides or []), "overrides"),
        "scenario_sha256": scenario_digest(scenario_json),
    })
    writer.add_metadata("excosim.scenario", {"json": scenario_json})
    writer.add_metadata("excosim.versions", versions)
    # One attachment per distinct FMU, named by its file (by FMU name too if two files differ).
    # Attachments are stored by file bytes (each role's bytes must be its attachment's); the
    # FMUs' identity is their content (excosim.fmu_content), which review and replay compare.
    hashes, contents, names, attached = {}, {}, {}, {}
    to_attach: list[tuple[str, bytes]] = []
    for name, (file_name, data) in fmus.items():
        digest = hashlib.sha256(data).hexdigest()
        hashes[name] = digest
        contents[name] = _content_of(digest, data)
        if digest not in attached:
            attachment = f"fmus/{file_name}"
            if attachment in attached.values():
                attachment = f"fmus/{name}/{file_name}"
            attached[digest] = attachment
            to_attach.append((attachment, data))
        names[name] = attached[digest]
    writer.add_metadata("excosim.fmus", hashes)
    writer.add_metadata("excosim.fmu_content", contents)
    writer.add_metadata("excosim.roles", plant_roles(json.loads(scenario_json), fmus, hashes,
                                                     derived, contents, arm_coupling, notes))
    writer.add_metadata("excosim.fmu_attachments", names)
    if geometry is not None:
        writer.add_metadata("excosim.geometry", {
            "name": geometry.name, "json": to_json(dataclasses.asdict(geometry), "geometry"),
        })
    writer.add_attachment(scenario_file, scenario_media, scenario_text.encode())
    for attachment, data in to_attach:
        writer.add_attachment(attachment, "application/zip", data)
