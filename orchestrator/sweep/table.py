"""A sweep's summary: one row per run, as Parquet and CSV, and an overview plot.

Columns: run; one per axis (its name: the scenario key, "fmu:<roles>" or "scenario"); status
("done" or "failed"); termination; the figures of `excosim compare` (periods, resets,
mean_abs_error_kg, max_abs_error_kg, within_band, counted, band_kg, mean_duration_s,
max_duration_s, peak_jerk_deg_s3; errors counted from period 2 on; the productivity totals
total_payload_kg, digging_time_s, productivity_t_h, mean_fill_factor, energy_kj,
throttled_energy_kj, energy_per_tonne_kj_t, throttled_share, peak_power_kw, mean_power_kw:
orchestrator.review.productivity); wall_s (s, the run in its
worker, plant set-up included); message (the log's end line); error (why a run failed); log
(path relative to the sweep's folder); log_sha256; fmus (JSON, role -> FMU content hash);
worker (host:pid of the process that ran it).

    import pandas as pd
    pd.read_parquet("runs/robustness/summary.parquet").groupby("adaptation.strategy")
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from orchestrator.review.productivity import MIN_PAYLOAD_KG
from orchestrator.sweep.worker import FIGURES

SUMMARY = "summary"  # file stem of summary.parquet and summary.csv
OVERVIEW = "overview.png"
_TAIL = ("status", "termination", *FIGURES, "wall_s", "message", "error", "log", "log_sha256",
         "fmus", "worker")


def summary_frame(rows: Sequence[dict[str, Any]], axis_names: Sequence[str], out_dir: Path):
    """pandas DataFrame of the rows in run order, log paths relative to out_dir. Axis values
    that are not plain numbers, strings or bools (lists) are kept as JSON text."""
    import pandas as pd

    ordered = sorted(rows, key=lambda row: row["run"])
    records = []
    for row in ordered:
        record = {"run": row["run"]}
        for name in axis_names:
            value = row.get(name)
            record[name] = json.dumps(value) if isinstance(value, list | tuple | dict) else value
        for name in _TAIL:
            record[name] = row.get(name)
        record["log"] = _relative(record["log"], out_dir)
        records.append(record)
    frame = pd.DataFrame.from_records(records, columns=["run", *axis_names, *_TAIL])
    for name in axis_names:  # one type per column (Parquet needs it): mixed ones as text
        kinds = {type(v) for v in frame[name] if v is not None}
        if len(kinds - {int, float}) > 0 and len(kinds) > 1:
            frame[name] = frame[name].map(lambda v: v if v is None else json.dumps(v))
    return frame


def _relative(path: Any, out_dir: Path) -> Any:
    if not path:
        return path
    try:
        return str(Path(path).resolve().relative_to(out_dir.resolve()))
    except ValueError:
        return str(path)


def write_summary(frame, out_dir: Path) -> tuple[Path, Path]:
    """summary.parquet and summary.csv in out_dir, each written whole then renamed into place
    (a reader never sees half a table). Returns their paths."""
    parquet, csv = out_dir / f"{SUMMARY}.parquet", out_dir / f"{SUMMARY}.csv"
    for path, write in ((parquet, lambda p: frame.to_parquet(p, index=False)),
                        (csv, lambda p: frame.to_csv(p, index=False))):
        partial = path.with_name(path.name + ".part")
        write(partial)
        partial.replace(path)
    return parquet, csv


def axis_statistics(frame, axis: str) -> list[dict[str, Any]]:
    """Weight-error statistics per value of one axis, over the periods the runs dug (a failed
    run's periods before its failure count too): value, runs, mean_abs_error_kg (mean over
    runs), worst_abs_error_kg, within_band (sum), counted (sum), within_share (within_band /
    counted), resets (sum), failed (runs); and the productivity of the value's runs together
    (`productivity`)."""
    out = []
    for value, group in frame.groupby(axis, sort=False, dropna=False):
        done = group[group["counted"].fillna(0) > 0]
        counted = int(done["counted"].fillna(0).sum())
        within = int(done["within_band"].fillna(0).sum())
        out.append({
            "value": value, "runs": len(group),
            "mean_abs_error_kg": _mean(done["mean_abs_error_kg"]),
            "worst_abs_error_kg": _max(done["max_abs_error_kg"]),
            "within_band": within, "counted": counted,
            "within_share": within / counted if counted else None,
            "resets": int(done["resets"].fillna(0).sum()),
            "failed": int((group["status"] != "done").sum()),
            **productivity(group),
        })
    return out


def productivity(group) -> dict[str, float | None]:
    """The productivity of runs together, as of one run that dug all their periods (the totals
    summed first, then divided: a long run weighs more than a short one): productivity_t_h
    (t per hour of digging), energy_per_tonne_kj_t, throttled_share, peak_power_kw (the
    largest), mean_power_kw (kW). None where no run has the figure (logs before it, a plant
    without energies); runs without it are left out of the sums."""
    payload_kg, time_s = _sums(group, "total_payload_kg", "digging_time_s")
    energy_kj, payload_e_kg = _sums(group, "energy_kj", "total_payload_kg")
    throttled_kj, energy_t_kj = _sums(group, "throttled_energy_kj", "energy_kj")
    energy_p_kj, time_p_s = _sums(group, "energy_kj", "digging_time_s")
    return {
        "productivity_t_h": (payload_kg / 1000.0) / (time_s / 3600.0) if time_s > 0 else None,
        "energy_per_tonne_kj_t": energy_kj / (payload_e_kg / 1000.0)
        if payload_e_kg >= MIN_PAYLOAD_KG else None,
        "throttled_share": throttled_kj / energy_t_kj if energy_t_kj > 0 else None,
        "peak_power_kw": _max(group["peak_power_kw"]) if "peak_power_kw" in group else None,
        "mean_power_kw": energy_p_kj / time_p_s if time_p_s > 0 else None,
    }


def _sums(group, numerator: str, denominator: str) -> tuple[float, float]:
    """Sums of two columns over the rows that have both (0.0, 0.0 when none does)."""
    if numerator not in group or denominator not in group:
        return 0.0, 0.0
    pairs = [(float(a), float(b)) for a, b in zip(group[numerator], group[denominator],
                                                  strict=True)
             if a is not None and b is not None and not _nan(a) and not _nan(b)]
    return math.fsum(a for a, _ in pairs), math.fsum(b for _, b in pairs)


def _mean(series) -> float | None:
    values = [float(v) for v in series if v is not None and not _nan(v)]
    return math.fsum(values) / len(values) if values else None


def _max(series) -> float | None:
    values = [float(v) for v in series if v is not None and not _nan(v)]
    return max(values) if values else None


def _nan(value: Any) -> bool:
    return isinstance(value, float) and math.isnan(value)


def overview_plot(frame, axis_names: Sequence[str], path: Path) -> Path:
    """One panel per axis: each run's mean |weight error| (kg, periods 2..) against the axis
    value (a box per value for up to 12 distinct values, else a scatter), the share of periods
    within the band on a second scale. Returns path (PNG)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    done = frame[frame["counted"].fillna(0) > 0]
    fig, panels = plt.subplots(1, len(axis_names), figsize=(4.8 * len(axis_names), 4.0),
                               squeeze=False)
    for panel, axis in zip(panels[0], axis_names, strict=True):
        stats = axis_statistics(frame, axis)
        values = [s["value"] for s in stats]
        numeric = all(isinstance(v, int | float) and not isinstance(v, bool) for v in values)
        if numeric and len(values) > 12:
            panel.scatter(done[axis], done["mean_abs_error_kg"], s=12)
        else:
            labels = [_label(v) for v in values]
            data = [[float(e) for e in done[done[axis] == v]["mean_abs_error_kg"]
                     if e is not None and not _nan(e)] for v in values]
            panel.boxplot([d if d else [math.nan] for d in data], tick_labels=labels)
            share = panel.twinx()
            share.plot(range(1, len(stats) + 1),
                       [100 * s["within_share"] if s["within_share"] is not None else math.nan
                        for s in stats], "o--", color="tab:green")
            share.set_ylim(0, 105)
            share.set_ylabel("periods within the band (%)", color="tab:green")
            panel.tick_params(axis="x", labelrotation=20)
        panel.set_xlabel(axis)
        panel.set_ylabel("mean |weight error| per run (kg)")
        panel.grid(alpha=0.3)
    failed = int((frame["status"] != "done").sum())
    fig.suptitle(f"{len(frame)} runs, {failed} failed (their periods until then count)")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def _label(value: Any) -> str:
    text = f"{value:.4g}" if isinstance(value, float) else str(value)
    return text if len(text) <= 24 else "..." + text[-21:]
