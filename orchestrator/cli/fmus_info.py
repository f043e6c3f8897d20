"""`excosim fmus info` and `excosim fmus validate`: what an FMU is and which plant roles it fills.

An FMU is named by a path to a .fmu file or by one of our model names (built on demand, FMI 2.0
unless fmi3 is asked for). The role check uses the default port map: a role's port is the FMU
variable of the same name (plant_models.model_spec), a Real of the right causality; the
parameter roles (orchestrator.plants.master.PARAMETER_ROLES, e.g. the cylinder's x0) must be
settable parameters. The master loads FMI 2.0 and 3.0 co-simulation FMUs, so a
model-exchange-only FMU (or one of another FMI version) is reported as not filling a role even
when its variables would.
"""

from __future__ import annotations

import json
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from plant_models.model_spec import (
    CYLINDER_INPUTS,
    DERIVABLE_OUTPUTS,
    OPTIONAL_PORTS,
    PILE_INPUTS,
    ROLE_OF,
    ROLES,
    FmuSpec,
)

__all__ = ["NotAnFmu", "RoleCheck", "FmuInfo", "resolve", "inspect_fmu", "validate",
           "info_command", "validate_command"]

# Which parts of the excavator each role plays (for people reading the report).
ROLE_PARTS = {"cylinder": ("boom", "stick", "bucket"), "pile": ("pile",)}
_ROLE_INPUTS = {"cylinder": CYLINDER_INPUTS, "pile": PILE_INPUTS}
_REAL = ("Real", "Float64")  # FMI 2.0 / FMI 3.0 name of a double
_SETTABLE = ("parameter", "input")


class NotAnFmu(ValueError):
    """The file is missing, not a zip, or has no readable modelDescription.xml."""


@dataclass
class RoleCheck:
    """Whether an FMU fills one role with the default port map, and why not."""

    role: str
    parts: tuple[str, ...]
    missing: list[str] = field(default_factory=list)  # role variables the FMU lacks
    absent: list[str] = field(default_factory=list)  # optional role variables it lacks
    derived: list[str] = field(default_factory=list)  # outputs the master derives for it
    problems: list[str] = field(default_factory=list)  # every reason it cannot fill the role

    @property
    def fills(self) -> bool:
        return not self.problems


@dataclass
class FmuInfo:
    """What `fmus info` reports about one FMU."""

    path: str
    model_name: str
    fmi_version: str
    kinds: list[str]
    variables: list[dict[str, Any]]
    roles: list[RoleCheck]

    def as_dict(self) -> dict[str, Any]:
        return {"path": self.path, "model_name": self.model_name,
                "fmi_version": self.fmi_version, "kinds": self.kinds,
                "variables": self.variables,
                "roles": {r.role: {"parts": list(r.parts), "fills": r.fills,
                                   "missing": r.missing, "absent": r.absent,
                                   "derived": r.derived,
                                   "problems": r.problems}
                          for r in self.roles}}


def resolve(target: str, fmi3: bool = False) -> Path:
    """The .fmu file for `target`: one of our model names (built now) or a path.

    Raises NotAnFmu for a path that does not exist; fmus.BuildError if a build fails.
    """
    import fmus

    if target in fmus.MODELS:
        return fmus.build(target, fmi_version=3 if fmi3 else 2)
    path = Path(target)
    if not path.is_file():
        raise NotAnFmu(f"{target}: no such file, and not one of our models "
                       f"({', '.join(fmus.MODELS)})")
    return path


def _read(path: Path):
    from fmpy import read_model_description

    if not zipfile.is_zipfile(path):
        raise NotAnFmu(f"{path}: not an FMU (not a zip archive)")
    try:
        return read_model_description(str(path), validate=False)
    except Exception as exc:  # fmpy raises many types for a broken archive or XML
        raise NotAnFmu(f"{path}: not an FMU ({exc})") from None


def _start(variable) -> Any:
    if variable.start is None:
        return None
    if variable.type in ("Boolean",):
        return str(variable.start).lower() in ("true", "1")
    try:
        number = float(variable.start)
    except (TypeError, ValueError):
        return variable.start
    return int(number) if variable.type not in _REAL and number.is_integer() else number


def _shape(variable) -> dict[str, Any]:
    """{"shape": [sizes]} of an FMI 3.0 array variable (its start a list of numbers), {} for a
    scalar."""
    dimensions = getattr(variable, "dimensions", None) or []
    if not dimensions:
        return {}
    return {"shape": [getattr(d, "start", None) for d in dimensions]}


def _start_text(v: dict[str, Any]) -> str:
    """A variable's start for the text view: an array's as its shape and ends, not all of it."""
    if v["start"] is None:
        return ""
    if "shape" not in v:
        return repr(v["start"])
    values = str(v["start"]).split()
    shape = "x".join(str(n) for n in v["shape"])
    ends = values[0] if len(values) < 2 else f"{values[0]} .. {values[-1]}"
    return f"[{shape}] {ends}"


def _role_check(role: str, description, parameter_roles: tuple[str, ...]) -> RoleCheck:
    from orchestrator.plants.derived import derive_outputs
    from orchestrator.plants.fmu_support import not_co_simulation

    check = RoleCheck(role, ROLE_PARTS[role])
    variables = {v.name: v for v in description.modelVariables}
    refusal = not_co_simulation(description)
    if refusal:
        check.problems.append(f"{role}: {refusal}")
    for port in ROLES[role]:
        wanted = "input" if port in _ROLE_INPUTS[role] else "output"
        variable = variables.get(port)
        if variable is None and port in OPTIONAL_PORTS[role]:
            check.absent.append(port)
        elif variable is None and port in DERIVABLE_OUTPUTS[role]:
            try:  # from the other outputs and the FMU's own parameters (default names)
                present = {p: p for p in ROLES[role] if p in variables}
                check.derived += list(derive_outputs(role, role, FmuSpec(""), description,
                                                     present))
            except ValueError as error:
                check.missing.append(port)
                check.problems.append(str(error))
        elif variable is None:
            check.missing.append(port)
            check.problems.append(f"{role}: no variable {port!r} (needs a Real {wanted})")
        elif variable.causality != wanted or variable.type not in _REAL:
            check.problems.append(f"{role}: {port!r} must be a Real {wanted}, is a "
                                  f"{variable.type} {variable.causality}")
    for port in parameter_roles:
        variable = variables.get(port)
        if variable is None:
            check.missing.append(port)
            check.problems.append(f"{role}: no parameter {port!r}")
        elif variable.causality not in _SETTABLE or variable.variability == "constant":
            check.problems.append(f"{role}: {port!r} must be a settable parameter, is a "
                                  f"{variable.variability} {variable.causality}")
    return check


def inspect_fmu(path: Path) -> FmuInfo:
    """Read `path` (a .fmu) into an FmuInfo. Raises NotAnFmu if it is not one."""
    from orchestrator.plants.master import PARAMETER_ROLES

    description = _read(path)
    kinds = [kind for kind, present in (("co-simulation", description.coSimulation),
                                        ("model exchange", description.modelExchange)) if present]
    variables = [{"name": v.name, "causality": v.causality, "variability": v.variability,
                  "type": v.type, "unit": v.unit, "start": _start(v),
                  "description": v.description, **_shape(v)}
                 for v in description.modelVariables]
    roles = [_role_check(role, description, tuple(PARAMETER_ROLES.get(role, ())))
             for role in ROLES]
    return FmuInfo(str(path), description.modelName, description.fmiVersion, kinds, variables,
                   roles)


PLANT_ROLES = ROLE_OF  # plant role -> the role kind its FMU fills


def validate(path: Path, role: str | None = None, ports: dict | None = None,
             parameters: dict | None = None) -> list[str]:
    """Problems of `path`: fmpy's validation, then the role checks (one line each; [] = valid).

    With `role` (cylinder, pile, or a plant role: boom, stick, bucket, pile), the FMU must fill
    that role; without, at least one role. With a port map `ports` (role -> FMU variable, or
    {"variable", "scale", "offset"}) or `parameters`, the FMU is checked as the master checks
    it under that map (orchestrator.plants.master.check_component), which needs `role`.
    Raises NotAnFmu if it is not an FMU.
    """
    from fmpy.validation import validate_fmu

    info = inspect_fmu(path)
    problems = [str(p) for p in validate_fmu(str(path))]
    kind = PLANT_ROLES.get(role or "", role)
    if ports or parameters:
        from orchestrator.plants.master import check_component
        from plant_models.model_spec import FmuSpec

        try:
            spec = FmuSpec.from_table(str(path), dict(parameters or {}), dict(ports or {}))
            check_component(role or kind, kind, spec, _read(path))
        except ValueError as error:
            problems.append(str(error).splitlines()[0])
        return problems
    checks = [c for c in info.roles if kind is None or c.role == kind]
    if not any(c.fills for c in checks):  # report the role it comes closest to filling
        problems += min(checks, key=lambda c: len(c.problems)).problems
    return problems


def _text(info: FmuInfo) -> str:
    lines = [f"{info.model_name}: FMI {info.fmi_version} {', '.join(info.kinds) or 'no kind'}",
             f"  file: {info.path}", "  variables:"]
    rows = [(v["name"] + ("[]" if "shape" in v else ""), v["causality"], v["variability"],
             v["type"], v["unit"] or "", _start_text(v), v["description"] or "")
            for v in info.variables if not v["name"].startswith("h[")]
    arrays = [v["name"] for v in info.variables if v["name"].startswith("h[")]
    widths = [max(len(r[i]) for r in rows) for i in range(6)] if rows else [0] * 6
    for row in rows:
        cells = [row[i].ljust(widths[i]) for i in range(6)]
        lines.append("    " + "  ".join(cells) + ("  " + row[6][:60] if row[6] else ""))
    if arrays:
        lines.append(f"    h[1]..h[{len(arrays)}]: {len(arrays)} array entries (as h[1])")
    lines.append("  roles (default port map):")
    for check in info.roles:
        parts = f" ({'/'.join(check.parts)})" if check.parts != (check.role,) else ""
        state = "fills" if check.fills else "cannot fill"
        detail = f"; missing: {', '.join(check.missing)}" if check.missing else ""
        if check.absent:
            detail += f"; without the optional {', '.join(check.absent)}"
        if check.derived:
            detail += f"; the master derives {', '.join(check.derived)}"
        lines.append(f"    {check.role}{parts}: {state}{detail}")
        if not check.fills and not check.missing:
            lines += [f"      {p}" for p in check.problems]
    return "\n".join(lines)


def info_command(target: str, as_json: bool = False, fmi3: bool = False) -> int:
    """`excosim fmus info`: print the report; return the exit status (0, or 2: not an FMU)."""
    import fmus

    try:
        info = inspect_fmu(resolve(target, fmi3))
    except NotAnFmu as exc:
        _error(str(exc))
        return 2
    except fmus.BuildError as exc:
        _error(str(exc))
        return 1
    print(json.dumps(info.as_dict(), indent=2) if as_json else _text(info))
    return 0


def validate_command(target: str, role: str | None = None, fmi3: bool = False,
                     ports: str | None = None, scenario: str | None = None) -> int:
    """`excosim fmus validate`: 0 valid (prints "valid"), 1 one line per problem, 2 not an FMU
    or a bad option. ports: a JSON object (role -> FMU variable or {"variable", "scale",
    "offset"}); scenario: a scenario file whose plant `role` gives the port map and
    parameters."""
    import fmus

    if role is not None and role not in ROLES and role not in PLANT_ROLES:
        _error(f"unknown role {role!r}; roles: {', '.join([*ROLES, *PLANT_ROLES])}")
        return 2
    try:
        mapping, parameters = _port_map(role, ports, scenario)
    except ValueError as error:
        _error(str(error))
        return 2
    try:
        path = resolve(target, fmi3)
        problems = validate(path, role, mapping, parameters)
    except NotAnFmu as exc:
        _error(str(exc))
        return 2
    except fmus.BuildError as exc:
        _error(str(exc))
        return 1
    if problems:
        for problem in problems:
            print(problem)
        return 1
    print(f"{path}: valid")
    return 0


def _port_map(role: str | None, ports: str | None, scenario: str | None
              ) -> tuple[dict, dict]:
    """(port map, parameters) from --ports (JSON) and --scenario (its plant role's); ValueError
    (one line) for a bad option."""
    if (ports or scenario) and role is None:
        raise ValueError("--ports and --scenario need --role (e.g. --role bucket)")
    mapping: dict = {}
    parameters: dict = {}
    if scenario:
        from orchestrator.scenario import ScenarioError, load_scenario

        if role not in PLANT_ROLES:
            raise ValueError(f"--scenario needs a plant role (boom, stick, bucket, pile), got "
                             f"{role!r}")
        try:
            spec = load_scenario(scenario).fmu_specs()[role]
        except (ScenarioError, OSError) as error:
            raise ValueError(f"--scenario: {error}") from None
        mapping = {port: name for port, name in spec.ports.items()}
        mapping.update({port: {"variable": m.variable, "scale": m.scale, "offset": m.offset}
                        for port, m in spec.port_maps.items()})
        parameters = dict(spec.parameters)
    if ports:
        try:
            given = json.loads(ports)
        except ValueError as error:
            raise ValueError(f"--ports: not a JSON object ({error})") from None
        if not isinstance(given, dict):
            raise ValueError("--ports: not a JSON object of role -> FMU variable")
        for port, value in given.items():
            if isinstance(value, str) or (isinstance(value, dict)
                                          and isinstance(value.get("variable"), str)):
                mapping[port] = value
            else:
                raise ValueError(f"--ports: {port}: a variable name or {{\"variable\", "
                                 f"\"scale\", \"offset\"}}, got {value!r}")
    return mapping, parameters


def _error(message: str) -> None:
    from orchestrator.cli.conventions import fail

    fail(message)
