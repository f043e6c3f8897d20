"""What a calibration writes into its output folder:

- calibrated.toml: the calibrated scenario, `base =` the original file (relative to the
  folder) with the run's --set items and the fitted values on top, so `excosim run
  OUT/calibrated.toml` digs with the calibrated plant;
- fit.csv: per period the measured (weighed) mass, the start's and the calibrated plant's mass
  (kg), and the tracking RMS against the measured joint angles of both (deg), with the log's
  own tracking RMS (measured vs reference, deg);
- fit.png: measured vs calibrated (and start) masses per period, and one period's joint angles
  with their residuals.
"""

from __future__ import annotations

import csv
import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from orchestrator.calibrate.measured import MeasuredRun
from orchestrator.calibrate.objective import Fit
from plant_models.plant import JOINTS

TOML_FILE, CSV_FILE, FIGURE_FILE = "calibrated.toml", "fit.csv", "fit.png"


def write_toml(out_dir: Path, scenario_path: Path, name: str, overrides: Sequence[str],
               values: dict[str, float], header: str) -> Path:
    from orchestrator.scenario.overrides import apply_overrides
    from orchestrator.scenario.toml_text import toml_text

    base = os.path.relpath(scenario_path.resolve(), out_dir.resolve())
    items = [*overrides, *(f"{key}={value!r}" for key, value in values.items())]
    data = apply_overrides({"base": Path(base).as_posix(), "name": f"{name}-calibrated"},
                           items, scenario_path.name)
    path = out_dir / TOML_FILE
    path.write_text(toml_text(data, header), encoding="utf-8")
    return path


def fit_rows(measured: MeasuredRun, start: Fit, calibrated: Fit) -> list[dict]:
    rows = []
    for i, period in enumerate(measured.periods):
        rows.append({
            "k": period.k, "measured_mass_kg": period.mass_kg,
            "start_mass_kg": _at(start.masses_kg, i),
            "calibrated_mass_kg": _at(calibrated.masses_kg, i),
            "calibrated_mass_error_kg": _at(calibrated.masses_kg, i) - period.mass_kg,
            "start_tracking_rms_deg": _at(start.tracking_rms_deg, i),
            "calibrated_tracking_rms_deg": _at(calibrated.tracking_rms_deg, i),
            "log_tracking_rms_deg": period.own_tracking_rms_deg})
    return rows


def _at(values: list[float], i: int) -> float:
    return float(values[i]) if i < len(values) else float("nan")


def write_csv(out_dir: Path, rows: list[dict]) -> Path:
    path = out_dir / CSV_FILE
    with open(path, "w", newline="", encoding="utf-8") as file:
        writer = csv.DictWriter(file, fieldnames=list(rows[0]))
        writer.writeheader()
        for row in rows:
            writer.writerow({k: f"{v:.6g}" if isinstance(v, float) else v
                             for k, v in row.items()})
    return path


def write_figure(out_dir: Path, measured: MeasuredRun, start: Fit, calibrated: Fit) -> Path:
    """Masses per period; the joint angles of the period the start fitted worst, and their
    residuals (simulated - measured) at the start and calibrated."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ks = [p.k for p in measured.periods]
    figure, (masses, joints, residuals) = plt.subplots(1, 3, figsize=(15, 4))
    masses.plot(ks, [p.mass_kg for p in measured.periods], "ko-", label="measured")
    if start.masses_kg:
        masses.plot(ks, start.masses_kg, "s--", color="0.6", label="start")
    masses.plot(ks, calibrated.masses_kg, "x-", color="C3", label="calibrated")
    masses.set(xlabel="period k", ylabel="weighed mass (kg)", title="Masses per period",
               xticks=ks)
    masses.legend()
    worst = int(np.argmax(start.tracking_rms_deg)) if start.tracking_rms_deg else 0
    period = measured.periods[worst]
    for j, joint in enumerate(JOINTS):
        colour = f"C{j}"
        joints.plot(period.t_s, np.degrees(period.measured_rad[:, j]), color=colour,
                    label=f"{joint} measured")
        for fit, style, name in ((calibrated, "--", "calibrated"), (start, ":", "start")):
            if len(fit.periods) > worst:
                simulated = np.degrees(fit.periods[worst].joints_rad[:, j])
                if name == "calibrated":
                    joints.plot(period.t_s, simulated, style, color=colour,
                                label=f"{joint} {name}")
                residuals.plot(period.t_s, simulated - np.degrees(period.measured_rad[:, j]),
                               style, color=colour, label=f"{joint} {name}")
    joints.set(xlabel="t (s)", ylabel="joint angle (deg)",
               title=f"Period {period.k}: joint angles")
    joints.legend(fontsize="small", ncol=2)
    residuals.set(xlabel="t (s)", ylabel="simulated - measured (deg)",
                  title=f"Period {period.k}: joint residuals")
    residuals.legend(fontsize="small", ncol=2)
    figure.tight_layout()
    path = out_dir / FIGURE_FILE
    figure.savefig(path, dpi=110)
    plt.close(figure)
    return path
