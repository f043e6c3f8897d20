"""One run of a sweep inside a worker process (a local pool's or a Dask worker's).

`execute(task, token)` digs the run's campaign into its MCAP log and returns the run's row of
the summary: the axis values, the figures `excosim compare` prints (read back from the log, so
the two always agree), how it ended, its wall time and the log's path and hash. It never raises
for the run's own failure: a failing run is a row with status "failed" and its error, and the
sweep goes on.

The log goes straight to its place when the worker sees the sweep's output folder (a local pool,
a Dask cluster on a shared file system: the folder holds a token file with the sweep's token);
otherwise it is written to a temporary file beside the worker and travels back in the row
(`LOG_BYTES`), for the planner to store.
"""

from __future__ import annotations

import hashlib
import json
import os
import socket
import tempfile
import time
from pathlib import Path
from typing import Any

from orchestrator.review.productivity import RUN_KEYS
from orchestrator.sweep.plan import RunTask

TOKEN_FILE = ".sweep-token"
LOG_BYTES = "_log_bytes"  # row key of a log that travels back (not a summary column)
STEP_TIMEOUT_S = 30.0  # one FMU step that takes longer ends the worker (the run is failed)
FIGURES = ("periods", "resets", "mean_abs_error_kg", "max_abs_error_kg", "within_band",
           "counted", "band_kg", "mean_duration_s", "max_duration_s", "peak_jerk_deg_s3",
           *RUN_KEYS)


def execute(task: RunTask, token: str) -> dict[str, Any]:
    """Run `task` with one BLAS thread; returns its summary row (see module docstring)."""
    from threadpoolctl import threadpool_limits

    with threadpool_limits(1):
        return _execute(task, token)


def _execute(task: RunTask, token: str) -> dict[str, Any]:
    from orchestrator.campaign import run_campaign
    from orchestrator.campaign.isolation import RUN_PREFIX
    from orchestrator.campaign.stale_folders import owned_folder, remove_stale

    started = time.perf_counter()
    target = Path(task.log_path)
    in_place = _sees_folder(target.parent.parent, token)
    if not in_place:
        remove_stale(RUN_PREFIX)  # what killed workers left behind
    log_path = target if in_place else owned_folder(RUN_PREFIX) / target.name
    row: dict[str, Any] = {"run": task.run, **task.point}
    try:
        scenario = _scenario(task)
        result = run_campaign(scenario, log_path=log_path, overwrite=True,
                              step_timeout_s=STEP_TIMEOUT_S, on_step_timeout=_end_worker)
        error = result.message if result.termination == "error" else ""
    except Exception as failure:  # noqa: BLE001 - a failing run is a row, the sweep goes on
        error = f"{type(failure).__name__}: {failure}".replace("\n", " ")
    row.update(log_row(log_path, target))
    row["wall_s"] = time.perf_counter() - started
    row["worker"] = f"{socket.gethostname()}:{os.getpid()}"
    if error:
        row.update(status="failed", error=error)
    if not in_place and log_path.is_file():
        row[LOG_BYTES] = log_path.read_bytes()
        log_path.unlink()
        log_path.parent.rmdir()
    return row


def _end_worker(message: str) -> None:
    # A stuck FMU step never returns: only ending the process frees the worker (the watchdog
    # has closed the log with the message; the pool reports the run as failed).
    os._exit(3)


def _sees_folder(folder: Path, token: str) -> bool:
    try:
        return bool(token) and (folder / TOKEN_FILE).read_text().strip() == token
    except OSError:
        return False


FMU_ROLES = ("boom", "stick", "bucket", "pile")


def _scenario(task: RunTask):
    """The task's Scenario, FMU files materialised where this worker cannot see them."""
    from orchestrator.scenario import scenario_from_dict

    data = task.scenario
    moved = {}
    for name, content in task.fmu_files.items():
        path = Path(name)
        digest = hashlib.sha256(content).hexdigest()
        if path.is_file() and hashlib.sha256(path.read_bytes()).hexdigest() == digest:
            continue
        local = Path(tempfile.gettempdir()) / "excosim-sweep-fmus" / digest / path.name
        # A file found there is used only if it is the one sent: anyone may write to TMPDIR.
        if not (local.is_file() and hashlib.sha256(local.read_bytes()).hexdigest() == digest):
            local.parent.mkdir(parents=True, exist_ok=True)
            partial = local.with_suffix(f".{os.getpid()}.part")
            partial.write_bytes(content)
            partial.replace(local)
        moved[name] = str(local)
    if moved:  # the FMU roles only: plant.supply and plant.lab have no FMU
        plant = {role: {**table, "fmu": moved.get(table.get("fmu"), table.get("fmu"))}
                 if role in FMU_ROLES and isinstance(table, dict) else table
                 for role, table in data["plant"].items()}
        data = {**data, "plant": plant}
    scenario = scenario_from_dict(data, source=task.scenario_name)
    scenario._source_text = task.scenario_text or None
    scenario._overrides = tuple(task.overrides)
    return scenario


def log_row(log_path: Path, shown_as: Path | None = None) -> dict[str, Any]:
    """The summary columns read from a run log: status ("done" when it ended with its end
    record, else "failed"), termination, message, the `compare` figures, log (path), log_sha256,
    fmus (JSON: role -> the FMU's content hash, 12 hex digits)."""
    from orchestrator.review.summary import band_kg, load, run_figures, target_mass_kg
    from orchestrator.runlog import RunLogError

    row: dict[str, Any] = {"status": "failed", "termination": None, "message": "", "error": ""}
    row.update(dict.fromkeys(FIGURES))
    row.update(log=str(shown_as or log_path), log_sha256=None, fmus="{}")
    try:
        run = load(log_path)
    except (OSError, RunLogError) as error:
        row["error"] = f"no readable run log: {error}"
        return row
    row.update(run_figures(run.periods, band_kg(target_mass_kg(run))))
    row.update(termination=run.termination, message=run.termination_message or "",
               log_sha256=_sha256(log_path))
    roles = {}
    for role, text in run.metadata.get("excosim.roles", {}).items():
        try:
            roles[role] = str(json.loads(text).get("content_sha256", ""))[:12]
        except (ValueError, AttributeError):
            continue
    row["fmus"] = json.dumps(roles, sort_keys=True)
    if run.finished and run.termination in ("periods", "workspace_limit"):
        row["status"] = "done"
    elif run.termination == "error":
        row["error"] = run.termination_message or "the run failed"
    elif not run.finished:
        row["error"] = f"the log ends after {len(run.periods)} period(s) without its end record"
    return row


def _sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as file:
        for block in iter(lambda: file.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def without_log_bytes(row: dict[str, Any]) -> dict[str, Any]:
    """The row as the summary keeps it."""
    return {k: v for k, v in row.items() if k != LOG_BYTES}


