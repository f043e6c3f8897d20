"""What `excosim run` prints: the period table, the summary line and the --json object
(`excosim review` shows the same table)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from rich.text import Text

from orchestrator.cli import tables
from orchestrator.review.summary import band_kg, ending, run_figures


def run_json(result: Any, log_path: Path) -> dict[str, Any]:
    """The `excosim run --json` object: the keys of `excosim review --json` that a run knows
    (scenario, plant, target_mass_kg, termination, message, path, periods, figures)."""
    return _json(result.scenario.name, result.scenario.plant.kind,
                 result.scenario.target_mass_kg, result.termination, result.message, log_path,
                 result.records)


def _json(scenario: str | None, plant: str | None, target_mass_kg: float, termination: str,
          message: str, log_path: Path, periods: list[dict[str, Any]]) -> dict[str, Any]:
    return {"scenario": scenario, "plant": plant, "target_mass_kg": target_mass_kg,
            "termination": termination, "message": message, "path": str(log_path),
            "periods": periods, "figures": run_figures(periods, band_kg(target_mass_kg))}


def period_grid(records: list[dict[str, Any]], target_mass_kg: float) -> tables.Grid:
    """One row per period: k, D, mass, error (green within the on-target band,
    `orchestrator.review.summary.band_kg`), reset, duration, peak jerk, planner."""
    band = band_kg(target_mass_kg)
    columns = [tables.Column("k"), tables.Column("D (y, z)", "m"), tables.Column("mass", "kg"),
               tables.Column("error", "kg"), tables.Column("reset", blank="no"),
               tables.Column("duration", "s"), tables.Column("peak jerk", "°/s³"),
               tables.Column("planner", "ms")]
    rows: list[list[str | Text]] = []
    for r in records:
        y, z = r["deepest_point_m"]
        error = r["error_kg"]
        style = "green" if abs(error) <= band else "yellow"
        rows.append([str(r["k"]), f"({y:.2f}, {z:.3f})", f"{r['mass_kg']:.2f}",
                     Text(f"{error:+.2f}", style=style), "yes" if r["reset"] else "",
                     f"{r['duration_s']:.2f}", f"{max(r['max_abs_jerk_deg_s3']):.1f}",
                     "–" if r.get("planner_ms") is None else f"{r['planner_ms']:.1f}"])
    return tables.Grid(f"Digging periods (target {target_mass_kg:g} kg)", columns, rows,
                       caption="duration: of the planned trajectory; peak jerk: largest |jerk| "
                       "of the three joints; planner: optimisation wall time",
                       heading="period {}")


def summary_line(result: Any, target_mass_kg: float) -> str:
    """How the campaign ended, periods within the on-target band after period 1 (+-3 kg at
    the paper's 30 kg), log path."""
    band = band_kg(target_mass_kg)
    within, counted = result.periods_within(band, first_period=2)
    share = f"{within}/{counted} ({100.0 * within / counted:.0f} %)" if counted else "none"
    log = f"; log: {result.log_path}" if result.log_path is not None else ""
    how = ending({"periods": result.records, "finished": True, "truncated": False,
                  "termination": result.termination, "message": result.message})
    return f"{how}; within +/-{band:g} kg after period 1: {share}{log}"


def logged_json(log_path: Path, message: str) -> dict[str, Any]:
    """run_json's object for a run whose process died, from its closed log."""
    from orchestrator.runlog import read_run

    run = read_run(log_path)
    described = run.metadata.get("excosim.run", {})
    return _json(described.get("scenario_name"), described.get("plant_kind"),
                 float(described.get("target_mass_kg", "nan")), "error", message, log_path,
                 run.periods)
