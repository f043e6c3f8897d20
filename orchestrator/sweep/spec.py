"""A sweep file: a base scenario and the axes that vary it, read into plain data.

    scenario = "../scenarios/paper-2020.toml"   # the base, relative to this file
    set = ["periods=5"]                        # --set items applied to every run

    [[axis]]                                   # one scenario key, a list of values
    key = "adaptation.strategy"
    values = ["fuzzy", "proportional"]

    [[axis]]                                   # a random sample (Monte Carlo), seeded
    key = "plant.pile.parameters.density"
    sample = { distribution = "uniform", low = 1280.0, high = 1920.0, count = 20, seed = 1 }
    group = "pile"                             # axes of one group are zipped

    [[axis]]                                   # a study design over a range (designs.py)
    key = "adaptation.centre_fractions[1]"     # [i]: one element of a list value
    sample = { design = "lhs", distribution = "uniform", low = 0.4, high = 0.8, count = 16,
               seed = 1 }

    [[axis]]                                   # a plant substitution: one FMU for some roles
    roles = ["boom", "stick", "bucket"]
    fmu = ["HydraulicCylinder", "IdealActuator"]

    [[axis]]                                   # whole scenario files (a base per value)
    scenario = ["../scenarios/paper-2020.toml", "../scenarios/paper-2020-zelenin.toml"]

Axes without a `group` each form their own; groups combine as a Cartesian product in the order
they first appear, and the axes inside one group are zipped (equal lengths). Every value is a
scenario value as `--set` writes it (orchestrator.scenario.overrides). `SweepError` names the
file, the axis and what is wrong in one line.
"""

from __future__ import annotations

import math
import re
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from orchestrator.scenario.overrides import parse_override
from orchestrator.sweep.designs import DESIGNS, POWER_OF_TWO, Design, design_values, runs_of

ROLES = ("boom", "stick", "bucket", "pile")
DISTRIBUTIONS = {  # name -> its parameters
    "uniform": ("low", "high"),
    "normal": ("mean", "std"),
    "loguniform": ("low", "high"),
    "integers": ("low", "high"),  # low <= n < high
}
_TOP_KEYS = {"name", "description", "scenario", "set", "axis"}
_AXIS_KEYS = {"key", "values", "sample", "roles", "fmu", "scenario", "group", "name"}
_SAMPLE_KEYS = {"distribution", "count", "seed", "design"} | {
    p for ps in DISTRIBUTIONS.values() for p in ps}
MAX_RUNS = 100_000  # a sweep beyond this is a typo in an axis, not a study
INDEXED = re.compile(r"^(?P<key>[^\[\]]+)\[(?P<index>[0-9]+)\]$")  # "a.b[2]": an element


class SweepError(ValueError):
    """A mistake in a sweep file; str() is one line: `<file>: <where>: <reason>`."""

    def __init__(self, source: str, where: str, reason: str) -> None:
        super().__init__(f"{source}: {where}: {reason}" if where else f"{source}: {reason}")


@dataclass(frozen=True)
class Axis:
    """One varied quantity.

    name: its column in the summary (the key; "fmu:<roles>" for a substitution; "scenario").
    values: what each point sets, as `--set` values (a substitution: the FMU name or path).
    keys: the scenario keys each value sets (one; several for a substitution of several roles);
        empty for a scenario axis, whose values are scenario files.
    group: the zip group.
    design: the range and study design it is sampled by (orchestrator.sweep.designs), or None
        (listed values, independent random draws, substitutions, scenario files).
    """

    name: str
    values: tuple[Any, ...]
    keys: tuple[str, ...]
    group: str
    design: Design | None = None


@dataclass(frozen=True)
class Sweep:
    """A parsed sweep file: path (the file), scenario (the base file), overrides (its `set`),
    axes, name."""

    path: Path
    name: str
    description: str
    scenario: Path
    overrides: tuple[str, ...]
    axes: tuple[Axis, ...]

    def points(self) -> list[dict[str, Any]]:
        """Every run's axis values, {axis name: value}, in the file's order (groups as a
        product, the first group outermost; the axes of a group zipped)."""
        groups: dict[str, list[Axis]] = {}
        for axis in self.axes:
            groups.setdefault(axis.group, []).append(axis)
        points: list[dict[str, Any]] = [{}]
        for axes in groups.values():
            rows = [dict(zip([a.name for a in axes], values, strict=True))
                    for values in zip(*[a.values for a in axes], strict=True)]
            points = [{**point, **row} for point in points for row in rows]
        return points


def load_sweep(path: str | Path) -> Sweep:
    """Read and check a sweep file; SweepError (one line) for any mistake in it."""
    path = Path(path)
    source = path.name
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise SweepError(str(path), "", "no such sweep file") from None
    except (OSError, UnicodeDecodeError) as error:
        raise SweepError(str(path), "", f"cannot read the file: {error}") from None
    except tomllib.TOMLDecodeError as error:
        raise SweepError(source, "", f"not TOML: {error}") from None
    except RecursionError:
        raise SweepError(source, "", "not TOML: nested too deeply") from None
    unknown = sorted(set(data) - _TOP_KEYS)
    if unknown:
        raise SweepError(source, unknown[0], f"unknown key (known: {', '.join(sorted(_TOP_KEYS))})")
    scenario = data.get("scenario")
    if not isinstance(scenario, str) or not scenario:
        raise SweepError(source, "scenario", "give the base scenario file, e.g. "
                         "scenario = \"../scenarios/paper-2020.toml\"")
    overrides = data.get("set", [])
    if not (isinstance(overrides, list) and all(isinstance(item, str) for item in overrides)):
        raise SweepError(source, "set", "a list of KEY=VALUE strings")
    for item in overrides:
        try:
            parse_override(item)
        except ValueError as error:
            raise SweepError(source, "set", str(error)) from None
    tables = data.get("axis", [])
    if not isinstance(tables, list) or not tables:
        raise SweepError(source, "axis", "no axis: give at least one [[axis]] table")
    axes = _with_designs(source, tuple(_axis(source, path.parent, i, table)
                                       for i, table in enumerate(tables, 1)))
    names = [axis.name for axis in axes]
    for name in names:
        if names.count(name) > 1:
            raise SweepError(source, name, "two axes vary the same quantity")
    _check_groups(source, axes)
    total = math.prod(len(next(a for a in axes if a.group == g).values)
                      for g in dict.fromkeys(a.group for a in axes))
    if total > MAX_RUNS:
        raise SweepError(source, "axis", f"{total} runs, more than {MAX_RUNS}")
    name = data.get("name", path.stem)
    description = data.get("description", "")
    if not isinstance(name, str) or not isinstance(description, str):
        raise SweepError(source, "name" if not isinstance(name, str) else "description",
                         "must be a string")
    return Sweep(path=path, name=name, description=description,
                 scenario=(path.parent / scenario), overrides=tuple(overrides), axes=axes)


def _axis(source: str, folder: Path, index: int, table: Any) -> Axis:
    where = f"axis {index}"
    if not isinstance(table, dict):
        raise SweepError(source, where, "an [[axis]] table")
    unknown = sorted(set(table) - _AXIS_KEYS)
    if unknown:
        raise SweepError(source, f"{where}: {unknown[0]}",
                         f"unknown key (known: {', '.join(sorted(_AXIS_KEYS))})")
    kinds = [k for k in ("key", "roles", "scenario") if k in table]
    if len(kinds) != 1:
        raise SweepError(source, where, "give exactly one of key (a scenario key), roles with "
                         "fmu (a plant substitution) or scenario (scenario files)")
    group = table.get("group", f"#{index}")
    if not isinstance(group, str) or not group:
        raise SweepError(source, f"{where}: group", "must be a non-empty string")
    if kinds == ["key"]:
        key = table["key"]
        if not isinstance(key, str):
            raise SweepError(source, f"{where}: key", "must be a dotted scenario key")
        indexed = INDEXED.match(key)
        try:
            parse_override(f"{indexed['key'] if indexed else key}=0")
        except ValueError:
            raise SweepError(source, f"{where}: key", f"{key!r} is not a dotted scenario key "
                             "(letters, digits, _ and -; [i] for an element of a list)") from None
        design = _design(source, f"{where} ({key})", table)
        if design is not None:
            return Axis(str(table.get("name", key)), (), (key,), group, design)
        values = _values(source, f"{where} ({key})", table, allow_sample=True)
        return Axis(str(table.get("name", key)), values, (key,), group)
    if kinds == ["roles"]:
        roles = table["roles"]
        roles = [roles] if isinstance(roles, str) else roles
        if not (isinstance(roles, list) and roles and all(r in ROLES for r in roles)):
            raise SweepError(source, f"{where}: roles",
                             f"a list of plant roles ({', '.join(ROLES)})")
        if "values" in table or "sample" in table:
            raise SweepError(source, where, "a substitution axis lists its FMUs in fmu = [...]")
        fmus = _values(source, f"{where} (fmu)", {"values": table.get("fmu")}, allow_sample=False)
        if not all(isinstance(f, str) and f for f in fmus):
            raise SweepError(source, f"{where}: fmu", "FMU names or .fmu paths (strings)")
        fmus = tuple(_fmu_value(folder, f) for f in fmus)
        keys = tuple(f"plant.{role}.fmu" for role in roles)
        return Axis(str(table.get("name", "fmu:" + ",".join(roles))), fmus, keys, group)
    files = _values(source, f"{where} (scenario)", {"values": table["scenario"]},
                    allow_sample=False)
    if not all(isinstance(f, str) and f for f in files):
        raise SweepError(source, f"{where}: scenario", "scenario file paths (strings)")
    return Axis(str(table.get("name", "scenario")), tuple(files), (), group)


def _fmu_value(folder: Path, name: str) -> str:
    """A model name stays a name; a .fmu path resolves against the sweep file's folder."""
    return str((folder / name).resolve()) if name.endswith(".fmu") else name


def _values(source: str, where: str, table: dict, allow_sample: bool) -> tuple[Any, ...]:
    has_values, has_sample = "values" in table and table["values"] is not None, "sample" in table
    if has_values == has_sample:
        needs = "values = [...] or sample = {...}" if allow_sample else "a list"
        raise SweepError(source, where, f"give {needs}")
    if has_sample:
        if not allow_sample:
            raise SweepError(source, where, "only a scenario key can be sampled")
        return _sample(source, where, table["sample"])
    values = table["values"]
    if not isinstance(values, list):
        raise SweepError(source, where, "values must be a list")
    if not values:
        raise SweepError(source, where, "empty axis: give at least one value")
    for value in values:
        if isinstance(value, float) and not math.isfinite(value):
            raise SweepError(source, where, f"{value} is not a finite number")
        if isinstance(value, dict):
            raise SweepError(source, where, "a value must be a number, string, bool or list")
    return tuple(values)


def _sample(source: str, where: str, sample: Any) -> tuple[Any, ...]:
    if not isinstance(sample, dict):
        raise SweepError(source, where, "sample must be a table {distribution, count, seed, ...}")
    unknown = sorted(set(sample) - _SAMPLE_KEYS)
    if unknown:
        raise SweepError(source, f"{where}: sample", f"unknown key {unknown[0]!r}")
    kind = sample.get("distribution")
    if kind not in DISTRIBUTIONS:
        raise SweepError(source, f"{where}: sample", f"distribution must be one of "
                         f"{', '.join(DISTRIBUTIONS)}, got {kind!r}")
    count, seed = sample.get("count"), sample.get("seed")
    if isinstance(count, bool) or not isinstance(count, int) or not 1 <= count <= MAX_RUNS:
        raise SweepError(source, f"{where}: sample", f"count must be an integer in 1..{MAX_RUNS}")
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise SweepError(source, f"{where}: sample", "seed must be an integer >= 0 (a sample "
                         "is reproducible)")
    params = {}
    for name in DISTRIBUTIONS[kind]:
        value = sample.get(name)
        if isinstance(value, bool) or not isinstance(value, int | float) \
                or not math.isfinite(value):
            raise SweepError(source, f"{where}: sample", f"{kind} needs a finite number {name}")
        params[name] = float(value)
    a, b = params.get("low", 0.0), params.get("high", 1.0)
    if kind in ("uniform", "loguniform", "integers") and not a < b:
        raise SweepError(source, f"{where}: sample", f"low must be below high, got {a}, {b}")
    if kind == "loguniform" and not a > 0.0:
        raise SweepError(source, f"{where}: sample", "loguniform needs low > 0")
    if kind == "normal" and not params["std"] > 0.0:
        raise SweepError(source, f"{where}: sample", "std must be > 0")
    rng = np.random.default_rng(seed)
    if kind == "uniform":
        drawn = rng.uniform(a, b, count)
    elif kind == "loguniform":
        drawn = np.exp(rng.uniform(math.log(a), math.log(b), count))
    elif kind == "normal":
        drawn = rng.normal(params["mean"], params["std"], count)
    else:
        return tuple(int(n) for n in rng.integers(math.ceil(a), math.ceil(b), count))
    return tuple(float(x) for x in drawn)


def _design(source: str, where: str, table: dict) -> Design | None:
    """The axis's study design, or None for a sample of independent draws or a list."""
    sample = table.get("sample")
    if not isinstance(sample, dict) or sample.get("design", "random") == "random":
        return None
    if "values" in table:
        raise SweepError(source, where, "give values = [...] or sample = {...}")
    unknown = sorted(set(sample) - _SAMPLE_KEYS)
    if unknown:
        raise SweepError(source, f"{where}: sample", f"unknown key {unknown[0]!r}")
    design, kind = sample["design"], sample.get("distribution", "uniform")
    if design not in DESIGNS:
        raise SweepError(source, f"{where}: sample", f"design must be one of "
                         f"{', '.join(DESIGNS)}, got {design!r}")
    if kind not in ("uniform", "loguniform"):
        raise SweepError(source, f"{where}: sample", f"a {design} design samples a range: "
                         f"distribution uniform or loguniform, got {kind!r}")
    count, seed = sample.get("count"), sample.get("seed")
    if isinstance(count, bool) or not isinstance(count, int) or not 2 <= count <= MAX_RUNS:
        raise SweepError(source, f"{where}: sample", f"count must be an integer in 2..{MAX_RUNS}")
    if design in POWER_OF_TWO and count & (count - 1):
        raise SweepError(source, f"{where}: sample", f"a {design} design needs a count that "
                         f"is a power of 2 (its balance), got {count}")
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise SweepError(source, f"{where}: sample", "seed must be an integer >= 0 (a design "
                         "is reproducible)")
    bounds = []
    for name in ("low", "high"):
        value = sample.get(name)
        if isinstance(value, bool) or not isinstance(value, int | float) \
                or not math.isfinite(value):
            raise SweepError(source, f"{where}: sample", f"{design} needs a finite number {name}")
        bounds.append(float(value))
    if not bounds[0] < bounds[1]:
        raise SweepError(source, f"{where}: sample",
                         f"low must be below high, got {bounds[0]}, {bounds[1]}")
    if kind == "loguniform" and not bounds[0] > 0.0:
        raise SweepError(source, f"{where}: sample", "loguniform needs low > 0")
    return Design(design, bounds[0], bounds[1], kind == "loguniform", count, seed)


def _with_designs(source: str, axes: tuple[Axis, ...]) -> tuple[Axis, ...]:
    """The axes with the values of their group's design drawn (all design axes of a group
    together, in the file's order)."""
    from dataclasses import replace

    out = list(axes)
    for group in dict.fromkeys(a.group for a in axes):
        members = [i for i, a in enumerate(axes) if a.group == group and a.design is not None]
        if not members:
            continue
        first = axes[members[0]].design
        for i in members:
            d = axes[i].design
            if (d.design, d.count, d.seed) != (first.design, first.count, first.seed):
                raise SweepError(source, axes[i].name, f"its design ({d.design}, count "
                                 f"{d.count}, seed {d.seed}) differs from {axes[members[0]].name}"
                                 f"'s in group {group!r}: one design per group")
        if runs_of(first.design, first.count, len(members)) > MAX_RUNS:
            raise SweepError(source, axes[members[0]].name, f"the design has more than "
                             f"{MAX_RUNS} runs")
        values = design_values([axes[i].design for i in members])
        for i, column in zip(members, values, strict=True):
            out[i] = replace(axes[i], values=column)
    return tuple(out)


def _check_groups(source: str, axes: tuple[Axis, ...]) -> None:
    lengths: dict[str, tuple[str, int]] = {}
    for axis in axes:
        first = lengths.setdefault(axis.group, (axis.name, len(axis.values)))
        if first[1] != len(axis.values):
            raise SweepError(source, axis.name, f"{len(axis.values)} values, but {first[0]} in "
                             f"its group {axis.group!r} has {first[1]}: zipped axes need as "
                             "many values each")
