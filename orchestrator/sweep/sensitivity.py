"""Sobol sensitivity indices of a sweep's summary figures to its sampled axes
(`excosim sweep --sensitivity`).

The sweep needs one group of axes sampled by the "saltelli" design (orchestrator.sweep.designs:
SALib's Saltelli sample, count x (d + 2) runs). For each summary figure (the numeric columns of
orchestrator.sweep.table: mean_abs_error_kg, productivity_t_h, ...) and each of those axes,
SALib.analyze.sobol.analyze (calc_second_order=False, 1000 bootstrap resamples seeded by the
design's seed, 95 % confidence) gives the first-order index S1 (the share of the figure's
variance the axis explains alone) and the total index ST (with all its interactions), each with
the half-width of its confidence interval. Other axes of the sweep (a strategy, say) are
conditions: the indices are computed for each combination of their values apart.

A figure that is the same in every run has no variance to share ("constant"); one that some run
lacks (a failed run, a log before the figure) gets no indices ("missing in N runs").
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from orchestrator.sweep.designs import unit_problem
from orchestrator.sweep.spec import Axis, Sweep, SweepError
from orchestrator.sweep.worker import FIGURES

SENSITIVITY = "sensitivity"  # file stem of sensitivity.csv / .json / .png
RESAMPLES = 1000
CONFIDENCE = 0.95


def sampled_axes(sweep: Sweep) -> list[Axis]:
    """The axes of the sweep's one saltelli group; SweepError (one line) when there is none,
    or more than one such group."""
    groups = {a.group for a in sweep.axes if a.design is not None
              and a.design.design == "saltelli"}
    if len(groups) != 1:
        raise SweepError(sweep.path.name, "--sensitivity", "needs one group of axes sampled by "
                         "design = \"saltelli\" (SALib's Saltelli sample), found "
                         f"{len(groups)}")
    group = groups.pop()
    return [a for a in sweep.axes if a.group == group and a.design is not None]


def sensitivity(frame, sweep: Sweep, figures: Sequence[str] = FIGURES) -> list[dict[str, Any]]:
    """One record per condition, figure and sampled axis: condition ({axis: value} of the
    other axes, {} without any), figure, axis, S1, S1_conf, ST, ST_conf (None with `note` when
    the figure is constant or missing), runs (of the condition)."""
    from SALib.analyze import sobol

    axes = sampled_axes(sweep)
    names = [a.name for a in axes]
    first = axes[0].design
    others = [a.name for a in sweep.axes if a.name not in names and a.group != axes[0].group]
    problem = unit_problem(len(axes), names)
    per_condition = first.count * (len(axes) + 2)
    records = []
    for condition, rows in _conditions(frame, others):
        if len(rows) != per_condition:
            raise SweepError(sweep.path.name, "--sensitivity", f"{len(rows)} runs for "
                             f"{condition or 'the sweep'}, the design has {per_condition}")
        for figure in figures:
            y = np.array([_number(v) for v in rows[figure]], dtype=float)
            missing = int(np.isnan(y).sum())
            note = (f"missing in {missing} runs" if missing else
                    "constant" if np.ptp(y) == 0.0 else "")
            result = None if note else sobol.analyze(
                problem, y, calc_second_order=False, num_resamples=RESAMPLES,
                conf_level=CONFIDENCE, seed=first.seed)
            for i, axis in enumerate(names):
                record = {"condition": condition, "figure": figure, "axis": axis,
                          "runs": len(rows), "note": note}
                for key in ("S1", "S1_conf", "ST", "ST_conf"):
                    record[key] = None if result is None else _finite(result[key][i])
                records.append(record)
    return records


def _conditions(frame, others: list[str]):
    """(condition, rows in run order) per combination of the other axes' values."""
    ordered = frame.sort_values("run", kind="stable")
    if not others:
        yield {}, ordered
        return
    for values, rows in ordered.groupby(others, sort=False, dropna=False):
        values = values if isinstance(values, tuple) else (values,)
        yield {k: _plain(v) for k, v in zip(others, values, strict=True)}, rows


def _plain(value: Any) -> Any:
    return value.item() if hasattr(value, "item") else value


def _number(value: Any) -> float:
    if value is None or isinstance(value, bool | str):
        return math.nan
    return float(value)


def _finite(value: Any) -> float | None:
    value = float(value)
    return value if math.isfinite(value) else None


def write_sensitivity(records: list[dict[str, Any]], out_dir: Path) -> tuple[Path, Path]:
    """sensitivity.csv (one row per record, the condition as JSON) and sensitivity.json."""
    import pandas as pd

    csv, plain = out_dir / f"{SENSITIVITY}.csv", out_dir / f"{SENSITIVITY}.json"
    frame = pd.DataFrame.from_records(
        [{**r, "condition": json.dumps(r["condition"], sort_keys=True)} for r in records],
        columns=["condition", "figure", "axis", "S1", "S1_conf", "ST", "ST_conf", "runs", "note"])
    frame.to_csv(csv, index=False)
    plain.write_text(json.dumps(records, indent=1, allow_nan=False) + "\n")
    return csv, plain


def sensitivity_plot(records: list[dict[str, Any]], path: Path,
                     figures: Sequence[str] | None = None) -> Path:
    """One panel per figure with indices (up to 12: the weight errors and productivity first),
    S1 and ST per axis as bars with their 95 % intervals, one colour pair per condition.
    Returns path (PNG)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    shown = [f for f in (figures or FIGURES)
             if any(r["figure"] == f and r["S1"] is not None for r in records)][:12]
    columns = min(3, max(1, len(shown)))
    rows = max(1, math.ceil(len(shown) / columns))
    fig, panels = plt.subplots(rows, columns, figsize=(5.2 * columns, 3.6 * rows),
                               squeeze=False)
    conditions = list(dict.fromkeys(json.dumps(r["condition"], sort_keys=True)
                                    for r in records))
    axes = list(dict.fromkeys(r["axis"] for r in records))
    width = 0.8 / (2 * len(conditions))
    for panel, figure in zip(panels.flat, shown, strict=False):
        for c, condition in enumerate(conditions):
            chosen = {r["axis"]: r for r in records if r["figure"] == figure
                      and json.dumps(r["condition"], sort_keys=True) == condition}
            for k, index in enumerate(("S1", "ST")):
                x = np.arange(len(axes)) - 0.4 + width * (2 * c + k + 0.5)
                y = [chosen[a][index] if chosen[a][index] is not None else math.nan for a in axes]
                e = [chosen[a][f"{index}_conf"] or 0.0 for a in axes]
                label = index + (f" {condition}" if condition != "{}" else "")
                panel.bar(x, y, width, yerr=e, capsize=2, label=label, alpha=0.85)
        panel.set_xticks(range(len(axes)), [a.rsplit(".", 1)[-1][-18:] for a in axes],
                         rotation=20)
        panel.set_title(figure)
        panel.axhline(0.0, color="black", linewidth=0.5)
        panel.grid(alpha=0.3, axis="y")
        panel.legend(fontsize=7)
    for panel in list(panels.flat)[len(shown):]:
        panel.set_visible(False)
    fig.suptitle("Sobol indices (first-order S1, total ST; bars: 95 % intervals)")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path
