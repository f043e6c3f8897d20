"""`excosim run`: load a scenario, run its campaign with a progress bar, print a table per period.

Exit status (set by the caller from the returned failure): 0 when the campaign ends by its period
count or at the workspace limit; 2 for a user's mistake (scenario, --set, output path); 1 for a
runtime failure, whose MCAP log stays readable up to the last finished period.
"""

from __future__ import annotations

import re
import sys
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from rich import box
from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Table

from orchestrator.review.summary import band_kg


def default_output(scenario_name: str, now: datetime | None = None) -> Path:
    """runs/<scenario-name>-<UTC time>.mcap, the name made safe for a file name."""
    stamp = (now or datetime.now(UTC)).strftime("%Y%m%dT%H%M%SZ")
    safe = re.sub(r"[^A-Za-z0-9_.-]+", "-", scenario_name).strip("-.") or "run"
    return Path("runs") / f"{safe}-{stamp}.mcap"


def run(scenario_path: Path, output: Path | None, overrides: list[str]) -> tuple[str, int] | None:
    """Run the campaign; None on success, else (one-line message, exit status)."""
    import fmus
    from orchestrator.campaign import run_campaign
    from orchestrator.scenario import ScenarioError, load_scenario

    try:
        scenario = load_scenario(scenario_path, overrides)
    except ScenarioError as error:
        return str(error), 2
    except fmus.BuildError as error:
        return str(error), 1
    log_path = output if output is not None else default_output(scenario.name)
    problem = _check_output(log_path)
    if problem is not None:
        return problem, 2

    # Piped output has no terminal width; rich would assume 80 columns and cut the table.
    out = Console(highlight=False, width=None if sys.stdout.isatty() else 120)
    err = Console(stderr=True, highlight=False)
    columns = (TextColumn("[progress.description]{task.description}"), BarColumn(),
               MofNCompleteColumn(), TimeElapsedColumn())
    with Progress(*columns, console=err, transient=True, disable=not err.is_terminal) as bar:
        task = bar.add_task(f"{scenario.name}: period 1", total=scenario.periods)

        def progress(record: dict[str, Any]) -> None:
            bar.update(task, advance=1, description=f"{scenario.name}: period {record['k'] + 1}"
                       f" (last {record['mass_kg']:.1f} kg)")

        result = run_campaign(scenario, log_path=log_path, progress=progress)
    out.print(period_table(result.records, scenario.target_mass_kg))
    out.print(summary_line(result, scenario.target_mass_kg), markup=False, soft_wrap=True)
    if result.termination == "error":
        done = len(result.records)
        return (f"run failed: {result.message} (log {log_path} is readable up to period "
                f"{done})"), 1
    return None


def _check_output(path: Path) -> str | None:
    if path.suffix != ".mcap":
        return f"output {str(path)!r}: expected a file name ending in .mcap"
    if path.is_dir():
        return f"output {str(path)!r} is a folder; give a file name ending in .mcap"
    if path.exists():
        return f"output {str(path)!r} already exists; remove it or choose another name"
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        return f"output {str(path)!r}: cannot create its folder: {error.strerror or error}"
    return None


def period_table(records: list[dict[str, Any]], target_mass_kg: float) -> Table:
    """A rich table, one row per period: k, D, mass, error (green within the on-target band,
    `orchestrator.review.summary.band_kg`), reset, duration, peak jerk, planner."""
    band = band_kg(target_mass_kg)
    table = Table(title=f"Digging periods (target {target_mass_kg:g} kg)", box=box.SIMPLE_HEAD,
                  caption="duration: of the planned trajectory; peak jerk: largest |jerk| of "
                  "the three joints; planner: optimisation wall time")
    for header in ("k", "D (y, z) m", "mass kg", "error kg", "reset", "duration s",
                   "peak jerk °/s³", "planner ms"):
        table.add_column(header, justify="right", no_wrap=header.startswith("D"),
                         min_width=max(len(word) for word in header.split()))
    for r in records:
        y, z = r["deepest_point_m"]
        error = r["error_kg"]
        style = "green" if abs(error) <= band else "yellow"
        table.add_row(str(r["k"]), f"({y:.2f}, {z:.3f})", f"{r['mass_kg']:.2f}",
                      f"[{style}]{error:+.2f}[/]", "yes" if r["reset"] else "",
                      f"{r['duration_s']:.2f}", f"{max(r['max_abs_jerk_deg_s3']):.1f}",
                      f"{r['planner_ms']:.1f}")
    return table


def summary_line(result, target_mass_kg: float) -> str:
    """termination, periods dug, periods within the on-target band after period 1 (+-3 kg at
    the paper's 30 kg), log path."""
    band = band_kg(target_mass_kg)
    within, counted = result.periods_within(band, first_period=2)
    share = f"{within}/{counted} ({100.0 * within / counted:.0f} %)" if counted else "none"
    log = f"; log: {result.log_path}" if result.log_path is not None else ""
    return (f"termination: {result.termination} ({len(result.records)} periods dug); within "
            f"+/-{band:g} kg after period 1: {share}{log}")
