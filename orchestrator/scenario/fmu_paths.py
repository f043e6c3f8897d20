"""Find the scenario's FMUs and check its parameters and port maps against their variables.

Our models (`fmus.MODELS`) are named by name and built on demand; anything else is a path to an
FMI 2.0 or 3.0 co-simulation .fmu, relative to the scenario's folder, stored resolved
(absolute). The checks are the co-simulation master's own
(`orchestrator.plants.master.check_component`), run before any FMU is instantiated, so that a
mistake is reported against the scenario field it is in; on top, each start value must fit its
variable's type (the master would convert it).
"""

from __future__ import annotations

import copy
import math
import re
from pathlib import Path
from typing import Any

from fmus.descriptions import model_description as fmus_description
from fmus.runs import value_kind
from orchestrator.plants.master import check_component, fmu_path
from orchestrator.scenario.errors import ScenarioError
from plant_models.model_spec import ROLE_OF, FmuSpec
from plant_models.port_units import si_to_declared

# The role each FMU of the plant plays (plant_models.model_spec.ROLES).
_PORT_IN_MESSAGE = re.compile(r"role '([^']+)'")


def resolve_fmus(plant: dict[str, Any], source: str, base_dir: Path,
                 given: dict[str, set[str]] | None = None) -> dict[str, Any]:
    """A copy of the resolved [plant] table with every `fmu` found; ScenarioError names the
    first wrong file, parameter or port.

    given: role -> the parameters the scenario itself sets; every other parameter (a preset
    default) is kept only where the FMU declares a settable variable of that name and type, so
    that swapping in a copy of a default FMU, or one with the same parameter names, keeps the
    defaults. None: every parameter counts as given."""
    import fmus

    plant = copy.deepcopy(plant)
    for component, role in ROLE_OF.items():
        table, where = plant[component], f"plant.{component}"
        if table["fmu"] not in fmus.MODELS:
            path = Path(table["fmu"]).expanduser()
            path = path if path.is_absolute() else base_dir / path
            try:
                found = path.is_file()
            except OSError as error:  # a name longer than the file system takes, and the like
                raise ScenarioError(source, f"{where}.fmu", f"cannot look at the file: "
                                    f"{error.strerror or error}") from None
            if not found:
                raise ScenarioError(source, f"{where}.fmu", f"no such file {table['fmu']!r} and "
                                    f"no model of that name (models: {', '.join(fmus.MODELS)})")
            _check_archive(path, source, f"{where}.fmu")
            table["fmu"] = str(path.resolve())
        try:
            spec = FmuSpec.from_table(table["fmu"], table["parameters"], table["ports"],
                                      piston_areas=table.get("piston_areas"))
            description = model_description(fmu_path(spec, component))
            check_component(component, role, FmuSpec(spec.fmu, {}, spec.ports,
                                                     port_maps=spec.port_maps,
                                                     piston_areas=spec.piston_areas),
                            description)
        except ValueError as error:
            port = _PORT_IN_MESSAGE.search(str(error))
            field = f"{where}.ports.{port.group(1)}" if port else f"{where}.fmu"
            raise ScenarioError(source, field, _without_component(error, component)) from None
        if table["fmu"] not in fmus.MODELS:
            _check_binary(Path(table["fmu"]), description, source, f"{where}.fmu")
        variables = {v.name: v for v in description.modelVariables}
        if given is not None:
            table["parameters"] = _kept(table["parameters"], given[component], variables,
                                        description)
            spec = FmuSpec.from_table(table["fmu"], table["parameters"], table["ports"],
                                      piston_areas=table.get("piston_areas"))
        for name, value in spec.parameters.items():
            field = f"{where}.parameters.{name}"
            try:
                check_component(component, role, FmuSpec(spec.fmu, {name: value}, spec.ports,
                                                         port_maps=spec.port_maps,
                                                         piston_areas=spec.piston_areas),
                                description)
            except ValueError as error:
                raise ScenarioError(source, field, _without_component(error, component)) from None
            _check_type(variables[name], description.modelName, value, source, field)
    return plant


def _check_archive(path: Path, source: str, field: str) -> None:
    """An FMU file from outside is a safe archive before anything reads it (fmus.identity)."""
    import fmus

    try:
        fmus.check_archive(path.read_bytes(), str(path))
    except OSError as error:
        raise ScenarioError(source, field, f"cannot read {path}: {error.strerror}") from None
    except fmus.UnsafeArchive as error:
        raise ScenarioError(source, field, f"not a readable FMU: {error}") from None


def _check_binary(path: Path, description, source: str, field: str) -> None:
    """An FMU file from outside carries a binary for this platform (FMI 2.0
    binaries/<platform>/, FMI 3.0 binaries/<arch-os>/): else it could not run here, and the
    run would stop after writing its log."""
    import zipfile

    import fmpy

    folder = fmpy.platform if description.fmiVersion.startswith("2") else fmpy.platform_tuple
    co = description.coSimulation
    identifier = co.modelIdentifier if co is not None else description.modelName
    wanted = f"binaries/{folder}/{identifier}{fmpy.sharedLibraryExtension}"
    with zipfile.ZipFile(path) as archive:
        names = archive.namelist()
    if wanted not in names:
        built = sorted({n.split("/")[1] for n in names
                        if n.startswith("binaries/") and n.count("/") >= 2 and n.split("/")[1]})
        raise ScenarioError(source, field, f"{path.name} has no binary for this platform "
                            f"({wanted}); it carries {', '.join(built) or 'no binaries'}")


def model_description(path: Path):
    """fmpy's model description of the FMU file at `path`, read once per version of the file;
    ValueError for a file that is not an FMU."""
    try:
        return fmus_description(path)
    except Exception as error:  # fmpy raises many kinds for a file that is not an FMU
        raise ValueError(f"not a readable FMU: {error}") from None


def _without_component(error: ValueError, component: str) -> str:
    return str(error).removeprefix(f"{component}: ")


def _kept(parameters: dict[str, Any], given: set[str], variables: dict, description
          ) -> dict[str, Any]:
    """The scenario's own parameters, and the preset's defaults (SI, like our models) that the
    FMU declares: converted into the FMU's declared unit (a stroke of 1.289 m is 1289 for a
    variable in mm), dropped where they do not fit or the unit is not known."""
    definitions = {u.name: u for u in getattr(description, "unitDefinitions", [])}
    out = {}
    for name, value in parameters.items():
        if name in given:
            out[name] = value
            continue
        variable = variables.get(name)
        if not _fits(variable, value):
            continue
        if value_kind(variable.type) == "Real":
            value = si_to_declared(float(value), variable, definitions)
        if value is not None:
            out[name] = value
    return out


def _fits(variable, value: Any) -> bool:
    """A preset default can be kept for `variable`: a settable variable of the value's type."""
    if variable is None or variable.causality not in ("parameter", "input") \
            or variable.variability == "constant":
        return False
    return _type_fits(value_kind(variable.type), value)


def _type_fits(kind: str | None, value: Any) -> bool:
    """`value` fits a variable of value_kind `kind` (Real, Integer, Boolean; FMI 2.0 or 3.0)."""
    number = isinstance(value, int | float) and not isinstance(value, bool)
    return {"Real": number and math.isfinite(value),
            "Integer": isinstance(value, int) and not isinstance(value, bool),
            "Boolean": isinstance(value, bool)}.get(kind, False)


def _check_type(variable, model: str, value: Any, source: str, field: str) -> None:
    if not _type_fits(value_kind(variable.type), value):
        raise ScenarioError(source, field, f"{model}.{variable.name} is a {variable.type}, "
                            f"got {value!r}")
