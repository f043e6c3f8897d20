"""Reading scenario files: a file and the `base` files under it merged into plain data, which
FMU parameters the files themselves set per plant role (fmu_paths.resolve_fmus checks those and
drops the preset's that a swapped FMU lacks), and the plant's SSP references resolved
(orchestrator.ssp.read)."""

from __future__ import annotations

import tomllib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from orchestrator.scenario.errors import ScenarioError

PLANT_ROLES = ("boom", "stick", "bucket", "pile")

_MAX_BASES = 8  # base files a scenario may stack (a circle is refused before this)


def expand_ssp(data: dict[str, Any], path: Path, user: dict[str, set], source: str
               ) -> tuple[dict[str, Any], dict[str, set]]:
    """The plant's `ssp` references resolved (orchestrator.ssp.read.expand_ssp)."""
    plant = data.get("plant")
    if not isinstance(plant, dict) or not ("ssp" in plant or any(
            isinstance(plant.get(role), dict) and "ssp" in plant[role] for role in PLANT_ROLES)):
        return data, {}
    from orchestrator.ssp.read import expand_ssp as expand_archives

    try:
        return expand_archives(data, path.resolve().parent, user)
    except ValueError as error:
        field, _, reason = str(error).partition(": ")
        raise ScenarioError(source, field, reason) from None


def read_scenario_file(path: Path, chain: tuple[Path, ...]
                       ) -> tuple[str, dict[str, Any], dict[str, set[str]]]:
    """(the file's text, its data with its `base` merged under it, role -> the FMU parameters
    the files set for the FMU the role ends up with: a base's parameters for a role whose FMU
    this file replaces are not counted, so resolve_fmus keeps those the new FMU declares and
    drops the rest as it does the preset's)."""
    source = path.name if not chain else f"{chain[0].name} (base {path.name})"
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ScenarioError(str(path), "", "no such scenario file") from None
    except (OSError, UnicodeDecodeError) as error:
        raise ScenarioError(str(path), "", f"cannot read the file: {error}") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as error:
        raise ScenarioError(source, "", f"not valid TOML: {error}") from None
    except RecursionError:  # arrays or tables nested hundreds deep: no scenario has them
        raise ScenarioError(source, "", "not valid TOML: nested too deeply") from None
    base = data.pop("base", None)
    own = given_parameters(data)
    if base is None:
        return text, data, own
    if not isinstance(base, str) or not base:
        raise ScenarioError(source, "base", f"expected a scenario file name, got {base!r}")
    base_path = (path.parent / base).resolve()
    if base_path in (*chain, path.resolve()):
        raise ScenarioError(source, "base", f"{base!r} is this scenario or one it is based on")
    if len(chain) >= _MAX_BASES:
        raise ScenarioError(source, "base", f"more than {_MAX_BASES} base files in a row")
    _, below, given = read_scenario_file(base_path, (*chain, path.resolve()))
    below.pop("name", None)
    merged = merge(below, data, ())
    for role in PLANT_ROLES:
        swapped = fmu_of(merged, role) != fmu_of(below, role)
        given[role] = own[role] if swapped else given[role] | own[role]
    return text, merged, given


def fmu_of(data: Mapping[str, Any], role: str) -> str:
    """The FMU a role ends up with in `data`: its table's `fmu`, else the presets' own (both
    presets run our HydraulicCylinder and Pile)."""
    fmu = role_table(data, role).get("fmu")
    return fmu if isinstance(fmu, str) else ("Pile" if role == "pile" else "HydraulicCylinder")


def role_table(data: Mapping[str, Any], role: str) -> Mapping[str, Any]:
    plant = data.get("plant")
    table = plant.get(role) if isinstance(plant, Mapping) else None
    return table if isinstance(table, Mapping) else {}


def given_parameters(data: Mapping[str, Any]) -> dict[str, set[str]]:
    """role -> names of the FMU parameters the scenario itself sets (not the preset)."""
    given: dict[str, set[str]] = {}
    for role in PLANT_ROLES:
        parameters = role_table(data, role).get("parameters")
        given[role] = set(parameters) if isinstance(parameters, Mapping) else set()
    return given


def merge(base: Mapping[str, Any], override: Mapping[str, Any], where: tuple) -> dict:
    """`override` deep-merged over `base`. An FMU table naming another FMU keeps base's
    parameters (resolve_fmus keeps those the new FMU declares) but not its port map (names of
    the default FMU's variables)."""
    merged = dict(base)
    for key, value in override.items():
        below = base.get(key)
        if isinstance(value, Mapping) and isinstance(below, Mapping):
            if where == ("plant",) and key in PLANT_ROLES and value.get("fmu", below.get("fmu")) \
                    != below.get("fmu"):
                below = {"parameters": dict(below.get("parameters", {}))}
            merged[key] = merge(below, value, (*where, key))
        else:
            merged[key] = value
    return merged
