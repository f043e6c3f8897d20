"""A sweep from start to summary: plan and check every run, skip the finished ones, run the rest
on a local pool or a Dask cluster, and write the summary as the runs end.

    from orchestrator.sweep import run_sweep
    result = run_sweep("sweeps/robustness.toml", "runs/robustness", workers=2)
    result.frame.groupby("adaptation.strategy")["mean_abs_error_kg"].mean()

Output folder: runs/<run>.mcap (one log per run, written as the run goes), runs/<run>.json (its
summary row, once it has ended), summary.parquet, summary.csv, overview.png.

Resume: started again with the same sweep file and folder, a run whose log is complete (its end
record says it dug its periods, reached the workspace limit, or failed for a reason of its own
rather than being interrupted) and whose logged scenario equals the planned one is not run
again; any other log of a planned run (killed, interrupted, of another scenario) is run anew.
"""

from __future__ import annotations

import json
import math
import os
import secrets
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from orchestrator.sweep.plan import RunTask, attach_fmu_files, plan_runs
from orchestrator.sweep.spec import Sweep, SweepError, load_sweep
from orchestrator.sweep.table import OVERVIEW, overview_plot, summary_frame, write_summary
from orchestrator.sweep.worker import LOG_BYTES, TOKEN_FILE, log_row, without_log_bytes

RECYCLE_AFTER = 10  # runs per local worker process before it is replaced


@dataclass
class SweepResult:
    """What a sweep did. frame: the summary (orchestrator.sweep.table); ran / skipped / failed:
    run names; out_dir: its folder; parquet, csv, overview: the files written."""

    sweep: Sweep
    frame: Any
    ran: list[str]
    skipped: list[str]
    failed: list[str]
    out_dir: Path
    parquet: Path
    csv: Path
    overview: Path | None


def prepare(sweep: Sweep | str | Path, out_dir: str | Path) -> tuple[Sweep, list[RunTask]]:
    """The sweep and its checked runs (SweepError, one line, for any mistake); writes nothing."""
    if not isinstance(sweep, Sweep):
        sweep = load_sweep(sweep)
    return sweep, plan_runs(sweep, Path(out_dir))


def run_sweep(sweep: Sweep | str | Path, out_dir: str | Path, *, workers: int | None = None,
              scheduler: str | None = None, recycle_after: int = RECYCLE_AFTER,
              tasks: list[RunTask] | None = None,
              progress: Callable[[dict[str, Any]], None] | None = None,
              on_start: Callable[[int, int], None] | None = None) -> SweepResult:
    """Run every run of `sweep` not already complete in out_dir, then write the summary.

    workers: local processes (default: the machine's cores); scheduler: a Dask scheduler's
    address instead (the local pool is then not used). tasks: the runs from `prepare` (planned
    here when None). progress(row) is called as each run ends; on_start(to_run, skipped) once
    the runs to do are known. SweepError / SchedulerUnreachable (one line) before any run for a
    bad sweep, a bad option or an unreachable scheduler. A run's own failure never raises: it
    is a row with status "failed".
    """
    from orchestrator.sweep import executors

    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int)
                                or workers < 1):
        raise SweepError("--workers", "", f"a number of processes >= 1, got {workers!r}")
    if isinstance(recycle_after, bool) or not isinstance(recycle_after, int) or recycle_after < 1:
        raise SweepError("--recycle-after", "", f"a number of runs >= 1, got {recycle_after!r}")
    if tasks is None:
        sweep, tasks = prepare(sweep, out_dir)
    elif not isinstance(sweep, Sweep):
        sweep = load_sweep(sweep)
    out_dir = Path(out_dir)
    client = executors.connect(scheduler) if scheduler else None
    try:
        _build_our_fmus()
        (out_dir / "runs").mkdir(parents=True, exist_ok=True)
        token = secrets.token_hex(8)
        (out_dir / TOKEN_FILE).write_text(token + "\n")
        rows, todo = _resume(tasks)
        skipped = [row["run"] for row in rows]
        if on_start is not None:
            on_start(len(todo), len(skipped))
        ran: list[str] = []

        def ended(row: dict[str, Any]) -> None:
            _store(row, tasks_by_run[row["run"]])
            rows.append(without_log_bytes(row))
            ran.append(row["run"])
            if progress is not None:
                progress(rows[-1])

        tasks_by_run = {task.run: task for task in todo}
        try:
            if client is not None:
                executors.run_dask(attach_fmu_files(todo), token, client, ended)
            elif todo:
                executors.run_local(todo, token, workers or os.cpu_count() or 1,
                                    recycle_after, ended)
        finally:
            axes = [axis.name for axis in sweep.axes]
            frame = summary_frame(rows, axes, out_dir)
            parquet, csv = write_summary(frame, out_dir)
        overview = overview_plot(frame, axes, out_dir / OVERVIEW) if len(frame) else None
    finally:
        if client is not None:
            client.close()
    failed = [row["run"] for row in rows if row.get("status") != "done"]
    return SweepResult(sweep, frame, ran, skipped, failed, out_dir, parquet, csv, overview)


def _build_our_fmus() -> None:
    """Build our models once here, so that local workers find them built instead of racing."""
    import fmus

    for model in fmus.MODELS:
        fmus.build(model)


def _resume(tasks: list[RunTask]) -> tuple[list[dict[str, Any]], list[RunTask]]:
    """(rows of the runs already complete, the tasks still to run); removes what a run to do
    left behind (a killed run's log, an old row)."""
    rows, todo = [], []
    for task in tasks:
        log, side = Path(task.log_path), Path(task.log_path).with_suffix(".json")
        row = _complete(task, log)
        if row is not None:
            rows.append({**row, "wall_s": _stored_wall(side, row.get("log_sha256"))})
            continue
        log.unlink(missing_ok=True)
        side.unlink(missing_ok=True)
        todo.append(task)
    return rows, todo


def _complete(task: RunTask, log: Path) -> dict[str, Any] | None:
    """The summary row of task's log if it is complete and of the same scenario, else None."""
    from orchestrator.runlog import RunLogError, read_run

    if not log.is_file():
        return None
    try:
        run = read_run(log, tolerant=True)
        same = json.dumps(run.scenario, sort_keys=True) == task.resolved_json()
    except (OSError, RunLogError, KeyError, ValueError):
        return None
    interrupted = run.termination == "error" and run.termination_message == "interrupted"
    if not (same and run.finished and not interrupted):
        return None
    return {"run": task.run, **task.point, **log_row(log)}


def _stored_wall(side: Path, log_sha256: str | None) -> float | None:
    try:
        stored = json.loads(side.read_text())
    except (OSError, ValueError):
        return None
    wall = stored.get("wall_s") if stored.get("log_sha256") == log_sha256 else None
    return float(wall) if isinstance(wall, int | float) and math.isfinite(wall) else None


def _store(row: dict[str, Any], task: RunTask) -> None:
    """A run that ended: its log in place (if it travelled back) and its row beside it."""
    log = Path(task.log_path)
    content = row.get(LOG_BYTES)
    if content is not None:
        partial = log.with_name(log.name + ".part")
        partial.write_bytes(content)
        partial.replace(log)
    side = log.with_suffix(".json")
    partial = side.with_name(side.name + ".part")
    plain = {k: None if isinstance(v, float) and not math.isfinite(v) else v
             for k, v in without_log_bytes(row).items()}
    partial.write_text(json.dumps(plain, default=str, allow_nan=False))
    partial.replace(side)
