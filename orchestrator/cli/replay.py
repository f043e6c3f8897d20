"""`excosim replay RUN.mcap [--trust] [--json]`: re-run a logged campaign from the scenario and
FMUs in its file and check that every period repeats (orchestrator.review.replay).

Exit status (set by the caller from the returned failure): 0 when the replay matches the log;
1 when it differs (or our FMUs cannot be built to check the file's against); 2 when the file
cannot or may not be replayed (not a run log, a lab run, an altered or untrusted FMU, a
scenario this version no longer accepts); 130 for Ctrl-C and 143 for SIGTERM, after the replay's
plant and temporary folder are cleaned up (orchestrator.cli.signals).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn
from rich.text import Text

from orchestrator.cli import tables
from orchestrator.cli.conventions import count
from orchestrator.cli.signals import (
    INTERRUPTED_EXIT,
    TERMINATED_EXIT,
    Terminated,
    terminate_like_ctrl_c,
)
from orchestrator.review.replay import ReplayReport


def replay(path: Path, trust: bool, as_json: bool) -> tuple[str, int] | None:
    """Replay the run at `path`; None when it matches, else (one-line message, exit status).
    Prints a table per period and a summary line, or with `as_json` one JSON object."""
    with terminate_like_ctrl_c():
        try:
            return _replay(path, trust, as_json)
        except Terminated:
            return f"replay of {path} terminated (SIGTERM); the log is unchanged", \
                TERMINATED_EXIT
        except KeyboardInterrupt:
            return f"replay of {path} interrupted; the log is unchanged", INTERRUPTED_EXIT


def _replay(path: Path, trust: bool, as_json: bool) -> tuple[str, int] | None:
    import fmus
    from orchestrator.campaign import PlantRefused
    from orchestrator.review.replay import ReplayRefused, replay_run
    from orchestrator.runlog import RunLogError
    from orchestrator.scenario import ScenarioError

    err = Console(stderr=True, highlight=False)
    columns = (TextColumn("[progress.description]{task.description}"), BarColumn(),
               MofNCompleteColumn(), TimeElapsedColumn())
    try:
        with Progress(*columns, console=err, transient=True,
                      disable=not err.is_terminal) as bar:
            task = bar.add_task(f"replaying {path.name}", total=None)

            def progress(record: dict[str, Any], total: int) -> None:
                bar.update(task, total=total, advance=1,
                           description=f"replaying {path.name}: period {record['k']}")

            report = replay_run(path, trust=trust, progress=progress)
    except (RunLogError, ReplayRefused) as error:
        return str(error), 2
    except PlantRefused as error:  # what the file's scenario asks of its FMUs
        return f"{path}: the run's plant cannot be built again: {error}", 2
    except ScenarioError as error:
        where = f"{error.field}: " if error.field else ""
        return (f"{path}: the run's scenario does not validate with this version of excosim: "
                f"{where}{error.reason}"), 2
    except fmus.BuildError as error:
        return f"cannot build our FMUs to check the file's FMUs against: {error}", 1

    if as_json:
        print(json.dumps(report.as_dict(), allow_nan=False))
    else:
        out = tables.console()
        tables.show(out, replay_grid(report))
        out.print(summary_line(report), markup=False, soft_wrap=True)
    difference = report.first_difference()
    if difference is not None:
        return f"replay differs from the log in {difference}", 1
    return None


def _amount(value: float | None, digits: str) -> str:
    return "-" if value is None else format(value, digits)


def replay_grid(report: ReplayReport) -> tables.Grid:
    """One row per period: k, mass logged and replayed, the absolute differences of mass,
    deepest point D (larger of y and z) and duration, match."""
    c = tables.Column
    columns = [c("k"), c("mass logged", "kg"), c("mass replayed", "kg"), c("|d mass|", "kg"),
               c("|d D|", "m"), c("|d duration|", "s"), c("match")]
    rows: list[list[str | Text]] = [
        [str(p.k), _amount(p.mass_kg_logged, ".6f"), _amount(p.mass_kg_replayed, ".6f"),
         _amount(p.abs_diff_mass_kg, ".2g"), _amount(p.abs_diff_deepest_point_m, ".2g"),
         _amount(p.abs_diff_duration_s, ".2g"),
         Text("yes", style="green") if p.matches else Text("no", style="red")]
        for p in report.periods]
    return tables.Grid(f"Replay of {report.path.name} (tolerance {report.tolerance:g})",
                       columns, rows, heading="period {}",
                       caption="|d D|: the larger of |d y_D| and |d z_D|; - : no such period")


def summary_line(report: ReplayReport) -> str:
    """Whether the replay matches, over how many periods, the largest differences and how
    each FMU was trusted."""
    largest = (f"max |difference|: mass {_amount(report.max_abs_diff_mass_kg, '.2g')} kg, "
               f"D {_amount(report.max_abs_diff_deepest_point_m, '.2g')} m, duration "
               f"{_amount(report.max_abs_diff_duration_s, '.2g')} s")
    trusted = sorted({f"{c.attachment} ({c.trusted_by})" for c in report.fmus.values()})
    verdict = "matches" if report.matches else "differs from"
    if report.damage is not None and report.logged_termination is None:
        ending = (f"; the log's file is {report.damage}: its complete periods before the "
                  "damage were replayed")
    elif report.termination_compared:
        ending = f"; both ended: {report.replayed_termination}"
    else:
        how = "killed" if report.logged_termination is None else "interrupted"
        ending = f"; the logged run was {how}: its complete periods were replayed"
    if report.damage is not None and report.logged_termination is not None:
        ending += f"; but the log's file is {report.damage}"
    return (f"replay {verdict} the log: {count(len(report.periods), 'period')}, {largest} "
            f"(tolerance {report.tolerance:g}){ending}; FMUs: {', '.join(trusted)}")
