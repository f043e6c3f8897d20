"""Read and validate a model's variable table (fmus/<Model>/variables.toml).

The table is the single source of the FMI variables: the builder generates both the C header
(variables.h) and modelDescription.xml from it. Value references are assigned in table order
starting at 0; an array entry (``count = n``) takes n consecutive value references.
"""

from __future__ import annotations

import math
import re
import tomllib
from dataclasses import dataclass
from pathlib import Path

__all__ = ["TableError", "Variable", "ModelTable", "read_table"]

MODEL_KEYS = {"identifier", "description", "default_step_size", "default_stop_time", "shared"}
VARIABLE_KEYS = {
    "name", "causality", "variability", "type", "start", "unit", "description", "count",
    "min", "max",
}
CAUSALITIES = ("parameter", "calculatedParameter", "input", "output", "local")
VARIABILITIES = ("constant", "fixed", "tunable", "discrete", "continuous")
TYPES = ("Real", "Integer", "Boolean")

# FMI 2.0 standard, section 2.2.7: the causality/variability pairs a variable may have.
ALLOWED = {
    "parameter": {"fixed", "tunable"},
    "calculatedParameter": {"fixed", "tunable"},
    "input": {"discrete", "continuous"},
    "output": {"constant", "discrete", "continuous"},
    "local": {"constant", "fixed", "tunable", "discrete", "continuous"},
}
C_IDENTIFIER = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")


class TableError(ValueError):
    """A variables.toml that breaks the format; the message names the file and the entry."""


@dataclass(frozen=True)
class Variable:
    """One scalar FMI variable (array tables are already expanded into scalars)."""

    name: str  # FMI name, e.g. "x" or "h[3]"
    macro: str  # C macro suffix, e.g. "x" or "h_3" (VR_<macro>)
    value_reference: int
    type: str  # Real | Integer | Boolean
    causality: str
    variability: str
    start: float | int | bool | None
    unit: str | None
    description: str | None
    min: float | None
    max: float | None

    @property
    def initial(self) -> str | None:
        """FMI 2.0 `initial` attribute implied by causality, variability and start."""
        if self.causality == "input":
            return None
        if self.variability == "constant" or self.causality == "parameter":
            return "exact"
        return "approx" if self.start is not None else "calculated"


@dataclass(frozen=True)
class ModelTable:
    """A validated variable table. `arrays` maps an array's name to (first VR, count)."""

    identifier: str
    description: str
    variables: tuple[Variable, ...]
    arrays: dict[str, tuple[int, int]]
    default_step_size: float | None
    default_stop_time: float | None
    shared: tuple[str, ...] = ()  # source folders fmus/shared/<name>/ compiled in as well

    def units(self) -> list[str]:
        """Units used by the Real variables, sorted."""
        return sorted({v.unit for v in self.variables if v.unit})


def read_table(path: Path) -> ModelTable:
    """Parse and validate `path` (a variables.toml). Raises TableError with one clear message."""
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise TableError(f"{path}: file not found") from None
    except tomllib.TOMLDecodeError as exc:
        raise TableError(f"{path}: not valid TOML: {exc}") from None
    return parse_table(data, str(path))


def parse_table(data: dict, where: str) -> ModelTable:
    """Validate an already parsed table; `where` names it in error messages."""
    unknown = set(data) - {"model", "variable"}
    if unknown:
        raise TableError(f"{where}: unknown top-level key(s) {sorted(unknown)}; "
                         "expected [model] and [[variable]]")
    model = data.get("model")
    if not isinstance(model, dict):
        raise TableError(f"{where}: missing [model] table")
    _check_keys(model, MODEL_KEYS, f"{where} [model]")
    identifier = model.get("identifier")
    if not isinstance(identifier, str) or not C_IDENTIFIER.match(identifier):
        raise TableError(f"{where} [model]: identifier must be a C identifier, got {identifier!r}")
    description = model.get("description", "")
    if not isinstance(description, str):
        raise TableError(f"{where} [model]: description must be a string")
    shared = model.get("shared", [])
    if not isinstance(shared, list) or not all(
            isinstance(n, str) and C_IDENTIFIER.match(n) for n in shared):
        raise TableError(f"{where} [model]: shared must be a list of folder names under "
                         f"fmus/shared/, got {shared!r}")
    step = _positive_or_none(model, "default_step_size", f"{where} [model]")
    stop = _positive_or_none(model, "default_stop_time", f"{where} [model]")

    entries = data.get("variable")
    if not isinstance(entries, list) or not entries:
        raise TableError(f"{where}: no [[variable]] entries")
    variables: list[Variable] = []
    arrays: dict[str, tuple[int, int]] = {}
    names: set[str] = set()
    macros: set[str] = set()
    for index, entry in enumerate(entries, start=1):
        label = f"{where} variable #{index}" + (
            f" '{entry['name']}'" if isinstance(entry, dict) and "name" in entry else "")
        if not isinstance(entry, dict):
            raise TableError(f"{label}: must be a table")
        expanded = _expand(entry, label, len(variables))
        base = entry["name"]
        if base in names or ("count" in entry and f"N_{base}" in macros):
            raise TableError(f"{label}: duplicate name '{base}'")
        names.add(base)
        if "count" in entry:
            arrays[base] = (len(variables), entry["count"])
            macros.add(f"N_{base}")
        for var in expanded:
            if var.macro in macros:
                raise TableError(f"{label}: C macro VR_{var.macro} collides with another variable")
            macros.add(var.macro)
        variables.extend(expanded)
    return ModelTable(identifier, description, tuple(variables), arrays, step, stop,
                      tuple(shared))


def _check_keys(entry: dict, allowed: set[str], label: str) -> None:
    unknown = set(entry) - allowed
    if unknown:
        raise TableError(f"{label}: unknown key(s) {sorted(unknown)}; allowed: {sorted(allowed)}")


def _positive_or_none(entry: dict, key: str, label: str) -> float | None:
    value = entry.get(key)
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int | float) or not value > 0:
        raise TableError(f"{label}: {key} must be a positive number, got {value!r}")
    return float(value)


def _expand(entry: dict, label: str, first_vr: int) -> list[Variable]:
    _check_keys(entry, VARIABLE_KEYS, label)
    for key in ("name", "causality", "variability", "type"):
        if key not in entry:
            raise TableError(f"{label}: missing required key '{key}'")
    name, causality = entry["name"], entry["causality"]
    variability, vtype = entry["variability"], entry["type"]
    if not isinstance(name, str) or not C_IDENTIFIER.match(name):
        raise TableError(f"{label}: name must be a C identifier (letters, digits, _), got {name!r}")
    if causality not in CAUSALITIES:
        raise TableError(f"{label}: causality {causality!r} is not one of {list(CAUSALITIES)}")
    if variability not in VARIABILITIES:
        raise TableError(f"{label}: variability {variability!r} is not one of "
                         f"{list(VARIABILITIES)}")
    if vtype not in TYPES:
        raise TableError(f"{label}: type {vtype!r} is not one of {list(TYPES)}")
    if variability not in ALLOWED[causality]:
        raise TableError(f"{label}: causality '{causality}' cannot have variability "
                         f"'{variability}' (allowed: {sorted(ALLOWED[causality])})")
    if variability == "continuous" and vtype != "Real":
        raise TableError(f"{label}: only Real variables can be continuous; use 'discrete'")
    start = entry.get("start")
    needs_start = causality in ("parameter", "input") or variability == "constant"
    if start is None and needs_start:
        raise TableError(f"{label}: a {variability} {causality} needs a start value")
    if causality == "calculatedParameter" and start is not None:
        raise TableError(f"{label}: a calculatedParameter is computed by the model; remove start")
    count = entry.get("count")
    if count is not None and (isinstance(count, bool) or not isinstance(count, int) or count < 1):
        raise TableError(f"{label}: count must be a positive integer, got {count!r}")
    unit = entry.get("unit")
    if unit is not None and (vtype != "Real" or not isinstance(unit, str) or not unit):
        raise TableError(f"{label}: unit must be a non-empty string and only on Real variables")
    description = entry.get("description")
    if description is not None and not isinstance(description, str):
        raise TableError(f"{label}: description must be a string")
    bounds = [_bound(entry, key, vtype, label) for key in ("min", "max")]
    if bounds[0] is not None and bounds[1] is not None and bounds[0] > bounds[1]:
        raise TableError(f"{label}: min {bounds[0]} is greater than max {bounds[1]}")

    n = 1 if count is None else count
    starts = start if isinstance(start, list) else [start] * n
    if len(starts) != n:
        raise TableError(f"{label}: start list has {len(starts)} entries, count is {n}")
    result = []
    for i, value in enumerate(starts):
        value = _start_value(value, vtype, label)
        if value is not None and not isinstance(value, bool):
            if (bounds[0] is not None and value < bounds[0]) or (
                    bounds[1] is not None and value > bounds[1]):
                raise TableError(f"{label}: start {value} lies outside [min, max]")
        fmi_name, macro = (name, name) if count is None else (f"{name}[{i + 1}]", f"{name}_{i + 1}")
        result.append(Variable(fmi_name, macro, first_vr + i, vtype, causality, variability,
                               value, unit, description, bounds[0], bounds[1]))
    return result


def _bound(entry: dict, key: str, vtype: str, label: str) -> float | None:
    value = entry.get(key)
    if value is None:
        return None
    if vtype == "Boolean" or isinstance(value, bool) or not isinstance(value, int | float):
        raise TableError(f"{label}: {key} must be a number (not on Boolean variables)")
    return value


def _start_value(value, vtype: str, label: str):
    if value is None:
        return None
    if vtype == "Boolean":
        if not isinstance(value, bool):
            raise TableError(f"{label}: start of a Boolean must be true or false, got {value!r}")
        return value
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise TableError(f"{label}: start must be a number, got {value!r}")
    if vtype == "Integer":
        if not isinstance(value, int) or abs(value) > 2**31 - 1:
            raise TableError(f"{label}: start of an Integer must be a 32-bit integer, "
                             f"got {value!r}")
        return value
    if not math.isfinite(value):
        raise TableError(f"{label}: start must be finite, got {value!r}")
    return float(value)
