"""The runs of a sweep: each point of its axes as a checked scenario, before anything runs.

Every run's scenario is loaded and validated here (the same checks as `excosim run`, FMUs
included), so that a bad value, an axis over a key the scenario does not have or a value of the
wrong type stops the sweep with one line before its first run. What travels to a worker is
plain data (`RunTask`): the resolved scenario, the text it was read from and the overrides, so
that a worker on another machine needs neither the sweep file nor the scenario files.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from orchestrator.scenario import ScenarioError, load_scenario
from orchestrator.sweep.spec import INDEXED, Sweep, SweepError


@dataclass(frozen=True)
class RunTask:
    """One run of a sweep, as plain data a worker process can take.

    run: its name ("run-0001"), also its log's file name.
    point: {axis name: value} of this run.
    scenario: the resolved scenario (Scenario.to_dict()); scenario_name, scenario_text and
        overrides: what the run log records about where it came from.
    log_path: where the log goes (absolute, on the machine that plans the sweep).
    fmu_files: {path: content} of FMU files the scenario names (not our models), for a worker
        that does not see the planner's files (a Dask worker elsewhere); empty otherwise.
    """

    run: str
    point: dict[str, Any]
    scenario: dict[str, Any]
    scenario_name: str
    scenario_text: str
    overrides: tuple[str, ...]
    log_path: str
    fmu_files: dict[str, bytes] = field(default_factory=dict, repr=False)

    def resolved_json(self) -> str:
        """The resolved scenario as canonical JSON: a run log holds the same run if its
        scenario record equals this."""
        return json.dumps(self.scenario, sort_keys=True)


def toml_value(value: Any) -> str:
    """`value` as the TOML text `--set KEY=VALUE` reads back to the same value."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if not math.isfinite(value):
            raise ValueError(f"{value} is not a finite number")
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value)  # a TOML basic string: quotes and escapes as in JSON
    if isinstance(value, list | tuple):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    raise ValueError(f"cannot set a scenario value to {type(value).__name__}")


def plan_runs(sweep: Sweep, out_dir: Path, points: list[dict[str, Any]] | None = None,
              names: list[str] | None = None) -> list[RunTask]:
    """Every run of `sweep` (or of `points`, {axis name: value} each, named `names`), checked,
    with its log path under out_dir/runs. SweepError (one line: the sweep file, the axis and
    value, what the scenario says) for any run whose scenario is not valid."""
    points = sweep.points() if points is None else points
    width = max(4, len(str(len(points))))
    names = names or [f"run-{index:0{width}d}" for index in range(1, len(points) + 1)]
    axes = {axis.name: axis for axis in sweep.axes}
    lists: dict[tuple[str, str], list[Any]] = {}  # (base file, key) -> its list, for [i] keys
    tasks = []
    for run, point in zip(names, points, strict=True):
        base, items = sweep.scenario, list(sweep.overrides)
        for name, value in point.items():
            axis = axes[name]
            if not axis.keys:  # a scenario axis: this value is the base file
                base = sweep.path.parent / value
                continue
            try:
                items += [f"{key}={toml_value(value)}" for key in axis.keys]
            except ValueError as error:
                raise SweepError(sweep.path.name, name, str(error)) from None
        items = _elements(sweep, base, items, point, lists)
        scenario = _load(sweep, base, items, point)
        tasks.append(RunTask(
            run=run, point=point, scenario=scenario.to_dict(), scenario_name=scenario.name,
            scenario_text=scenario.source_text or "", overrides=tuple(items),
            log_path=str((out_dir / "runs" / f"{run}.mcap").resolve())))
    return tasks


def _elements(sweep: Sweep, base: Path, items: list[str], point: dict[str, Any],
              lists: dict[tuple[str, str], list[Any]]) -> list[str]:
    """items with every `key[i]=value` turned into `key=[...]`: the list of the base scenario
    (with the sweep's `set`) with those elements replaced."""
    plain, elements = [], {}
    for item in items:
        key, _, text = item.partition("=")
        match = INDEXED.match(key.strip())
        if match is None:
            plain.append(item)
        else:
            elements.setdefault(match["key"], {})[int(match["index"])] = text
    for key, changes in elements.items():
        if (str(base), key) not in lists:
            value: Any = _load(sweep, base, list(sweep.overrides), point).to_dict()
            for part in key.split("."):
                value = value.get(part) if isinstance(value, dict) else None
            if not isinstance(value, list):
                raise SweepError(sweep.path.name, key, "is not a list in the scenario, so "
                                 f"{key}[i] names no element")
            lists[(str(base), key)] = value
        texts = [toml_value(v) for v in lists[(str(base), key)]]
        for index, text in changes.items():
            if index >= len(texts):
                raise SweepError(sweep.path.name, f"{key}[{index}]", f"the list has "
                                 f"{len(texts)} elements")
            texts[index] = text
        plain.append(f"{key}=[{', '.join(texts)}]")
    return plain


def _load(sweep: Sweep, base: Path, items: list[str], point: dict[str, Any]):
    try:
        return load_scenario(base, items)
    except ScenarioError as error:
        where = ", ".join(f"{k} = {_short(v)}" for k, v in point.items())
        raise SweepError(sweep.path.name, f"run with {where}", str(error)) from None
    except RecursionError:
        raise SweepError(sweep.path.name, str(base), "scenario nested too deeply") from None


def _short(value: Any) -> str:
    text = json.dumps(value) if not isinstance(value, float) else f"{value:.6g}"
    return text if len(text) <= 60 else text[:57] + "..."


def attach_fmu_files(tasks: list[RunTask]) -> list[RunTask]:
    """The tasks with the content of every FMU file their scenarios name (read once per file),
    for workers that may not see this machine's files."""
    from dataclasses import replace

    import fmus

    cache: dict[str, bytes] = {}
    out = []
    for task in tasks:
        files = {}
        for role in ("boom", "stick", "bucket", "pile"):
            name = task.scenario["plant"][role]["fmu"]
            if name not in fmus.MODELS:
                if name not in cache:
                    cache[name] = Path(name).read_bytes()
                files[name] = cache[name]
        out.append(replace(task, fmu_files=files))
    return out
