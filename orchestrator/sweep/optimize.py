"""A sweep file's design axes as a search space (`excosim optimize`): Optuna's TPE sampler, seeded,
chooses the runs; they run on the sweep's executors (orchestrator.sweep.executors) with the same
per-run logs and summary rows.

    from orchestrator.sweep.optimize import run_optimize
    result = run_optimize("sweeps/fuzzy-centres.toml", "runs/fuzzy-centres-optimize",
                          objective="mean_abs_error_kg", trials=12, workers=2)
    result.best  # {"number", "value", "params"}

Search space: every axis sampled by a design (`sample = { design = "lhs" | "sobol" | "saltelli",
low, high, ... }`, orchestrator.sweep.designs) is one dimension over its range (log scale for
`distribution = "loguniform"`); the design's own points are not run. Every other axis (values,
random samples, substitutions) is a condition: one trial runs the product of their groups
(e.g. 20 piles), and its objective is the mean of the figure over the trial's runs that have it
(a trial none of whose runs has it fails, as does one whose values make no valid scenario).

Executors: the trials are a stream of runs on one local pool (its processes kept between trials)
or on the Dask cluster: the next trial is asked as soon as a worker would otherwise idle (TPE's
constant liar stands in for the trials in flight), and each trial is told as its last run ends.

Storage: the study is Optuna's RDB storage on sqlite, `study.db` beside the logs (runs/
trial-NNNN-KK.mcap and their .json rows), named after the sweep. The same command again goes on
with the trials still missing of --trials (the total); a trial that was running when a session
stopped is marked failed ("interrupted") and its values are run again first.
"""

from __future__ import annotations

import math
import os
import secrets
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from orchestrator.sweep.plan import RunTask, attach_fmu_files, plan_runs
from orchestrator.sweep.spec import Axis, Sweep, SweepError, load_sweep
from orchestrator.sweep.table import summary_frame, write_summary
from orchestrator.sweep.worker import FIGURES, TOKEN_FILE, without_log_bytes

STUDY = "study.db"
FIGURE = "optimize.png"
OBJECTIVES = (*FIGURES, "wall_s")


@dataclass
class OptimizeResult:
    """What an optimisation did. trials: one dict per trial of the study (number, state,
    value, params, runs, error); best: the best complete trial's {number, value, params} or
    None; ran: trials run in this session; frame: the summary (one row per run, a `trial`
    column first); parquet, csv, figure, study: the files."""

    sweep: Sweep
    objective: str
    direction: str
    trials: list[dict[str, Any]]
    best: dict[str, Any] | None
    ran: int
    frame: Any
    out_dir: Path
    parquet: Path
    csv: Path
    figure: Path | None
    study: Path


def search_space(sweep: Sweep) -> list[Axis]:
    """The design axes (the dimensions searched); SweepError when there is none or when an
    axis that is not one shares their group."""
    axes = [a for a in sweep.axes if a.design is not None]
    if not axes:
        raise SweepError(sweep.path.name, "axis", "no axis with a range to search: give one a "
                         "sample = { design = \"lhs\", low = ..., high = ..., count, seed }")
    for other in sweep.axes:
        if other.design is None and other.group in {a.group for a in axes}:
            raise SweepError(sweep.path.name, other.name, "zipped with searched axes: give it "
                             "a group of its own (a condition every trial runs)")
    return axes


def check_objective(objective: str) -> None:
    """SweepError (one line) for a figure the summary does not have."""
    if objective not in OBJECTIVES:
        raise SweepError("--objective", objective, "not a summary figure (one of: "
                         f"{', '.join(OBJECTIVES)})")


def conditions(sweep: Sweep, search: list[Axis]) -> list[dict[str, Any]]:
    """The points of the other axes every trial runs ([{}] without any)."""
    others = tuple(a for a in sweep.axes if a not in search)
    return replace(sweep, axes=others).points() if others else [{}]


def prepare_optimize(sweep: Sweep | str | Path, out_dir: Path, objective: str
                     ) -> tuple[Sweep, list[Axis], list[dict[str, Any]], list[RunTask]]:
    """Sweep, search axes, conditions and the runs of the trial at the centre of the space,
    checked before any run (the objective, every scenario: SweepError, one line)."""
    check_objective(objective)
    sweep = sweep if isinstance(sweep, Sweep) else load_sweep(sweep)
    search = search_space(sweep)
    points = conditions(sweep, search)
    centre = {a.name: a.design.centre() for a in search}
    tasks = plan_runs(sweep, out_dir, [{**p, **centre} for p in points],
                      [f"centre-{k:02d}" for k in range(1, len(points) + 1)])
    return sweep, search, points, tasks


def run_optimize(sweep: Sweep | str | Path, out_dir: str | Path, objective: str, *,
                 maximize: bool = False, trials: int = 20, seed: int = 0,
                 workers: int | None = None, scheduler: str | None = None,
                 recycle_after: int = 10,
                 progress: Callable[[dict[str, Any]], None] | None = None) -> OptimizeResult:
    """Run the study until it holds `trials` finished trials (see the module docstring).
    progress(event) after each trial: number, value (or None), state, best (value or None),
    done, total. SweepError / SchedulerUnreachable (one line) before any run."""

    from orchestrator.sweep import executors
    from orchestrator.sweep.runner import _build_our_fmus

    for name, value, low in (("--trials", trials, 1), ("--workers", workers, 1),
                             ("--recycle-after", recycle_after, 1)):
        if value is not None and (isinstance(value, bool) or not isinstance(value, int)
                                  or value < low):
            raise SweepError(name, "", f"a whole number >= {low}, got {value!r}")
    out_dir = Path(out_dir)
    sweep, search, points, _ = prepare_optimize(sweep, out_dir, objective)
    direction = "maximize" if maximize else "minimize"
    client = executors.connect(scheduler) if scheduler else None
    try:
        (out_dir / "runs").mkdir(parents=True, exist_ok=True)
        study = _study(sweep, out_dir, objective, direction, seed, trials)
        _build_our_fmus()
        token = secrets.token_hex(8)
        (out_dir / TOKEN_FILE).write_text(token + "\n")
        rows = _earlier_rows(out_dir)
        stream = _Stream(study, _Context(sweep, out_dir, search, points, objective, trials,
                                         progress), rows, attach=client is not None)
        try:
            _execute(stream, client, token, workers, recycle_after)
        finally:
            axes = ["trial", *[a.name for a in sweep.axes]]
            frame = summary_frame(rows, axes, out_dir)
            parquet, csv = write_summary(frame, out_dir)
        interrupted = set(study.user_attrs.get("interrupted", []))
        trial_list = [{**_trial(t), "interrupted": t.number in interrupted}
                      for t in study.get_trials(deepcopy=False)]
        figure = _plot(trial_list, objective, direction, out_dir / FIGURE) if trial_list \
            else None
    finally:
        if client is not None:
            client.close()
    best = _best(study)
    return OptimizeResult(sweep, objective, direction, trial_list, best, stream.ran, frame,
                          out_dir, parquet, csv, figure, out_dir / STUDY)


@dataclass(frozen=True)
class _Context:
    sweep: Sweep
    out_dir: Path
    search: list[Axis]
    points: list[dict[str, Any]]
    objective: str
    total: int
    progress: Callable[[dict[str, Any]], None] | None


class _Stream:
    """The trials as a stream of runs: more() asks the next trial and gives its runs (while
    the study lacks trials), ended(row) stores a run's row and tells its trial once its last
    run has ended."""

    def __init__(self, study, context: _Context, rows: list[dict[str, Any]],
                 attach: bool) -> None:
        self.study, self.context, self.rows, self.attach = study, context, rows, attach
        self.asked: dict[int, Any] = {}  # trial number -> its optuna Trial, until told
        self.pending: dict[int, list[RunTask]] = {}
        self.trial_rows: dict[int, list[dict[str, Any]]] = {}
        self.by_run: dict[str, tuple[RunTask, int]] = {}
        self.ran = 0

    def more(self) -> list[RunTask]:
        while _finished(self.study) + len(self.asked) < self.context.total:
            trial = self.study.ask()
            self.ran += 1
            tasks = _plan(self.context, trial, self.study)
            if tasks is None:
                _report(self.study, trial, self.context)
                continue
            self.asked[trial.number], self.pending[trial.number] = trial, tasks
            self.trial_rows[trial.number] = []
            self.by_run.update({t.run: (t, trial.number) for t in tasks})
            return attach_fmu_files(tasks) if self.attach else tasks
        return []

    def ended(self, row: dict[str, Any]) -> None:
        from orchestrator.sweep.runner import _store

        task, number = self.by_run[row["run"]]
        row = {"trial": number, **row}
        _store(row, task)
        self.rows.append(without_log_bytes(row))
        self.trial_rows[number].append(self.rows[-1])
        if len(self.trial_rows[number]) == len(self.pending[number]):
            trial = self.asked.pop(number)
            _tell(self.study, trial, self.trial_rows[number], self.context.objective)
            _report(self.study, trial, self.context)


def _execute(stream: _Stream, client, token: str, workers: int | None,
             recycle_after: int) -> None:
    """The stream's runs on the Dask cluster or the local pool, the workers kept busy."""
    from orchestrator.sweep import executors

    if client is not None:
        executors.run_dask([], token, client, stream.ended, more=stream.more)
    else:
        executors.run_local([], token, workers or os.cpu_count() or 1, recycle_after,
                            stream.ended, more=stream.more)


def _study(sweep: Sweep, out_dir: Path, objective: str, direction: str, seed: int,
           trials: int):
    """The study in out_dir/study.db (created, or loaded to go on); an interrupted trial is
    failed and its values enqueued again."""
    import optuna
    from optuna.trial import TrialState

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    storage = optuna.storages.RDBStorage(f"sqlite:///{(out_dir / STUDY).resolve()}")
    sampler = optuna.samplers.TPESampler(seed=seed, n_startup_trials=max(2, min(10, trials // 3)),
                                         constant_liar=True)
    study = optuna.create_study(storage=storage, sampler=sampler, study_name=sweep.name,
                                direction=direction, load_if_exists=True)
    stored = (study.user_attrs.get("objective"), study.direction.name.lower())
    if "objective" in study.user_attrs and stored != (objective, direction):
        raise SweepError(str(out_dir / STUDY), "", f"holds a study that {stored[1]}s "
                         f"{stored[0]}; give another -o")
    study.set_user_attr("objective", objective)
    interrupted = list(study.user_attrs.get("interrupted", []))
    for trial in study.get_trials(deepcopy=False, states=(TrialState.RUNNING,)):
        interrupted.append(trial.number)
        study.set_user_attr("interrupted", interrupted)
        study.tell(trial.number, state=TrialState.FAIL)
        study.enqueue_trial(trial.params, skip_if_exists=False)
    return study


def _finished(study) -> int:
    """Trials that ended (complete or failed), not counting interrupted ones."""
    from optuna.trial import TrialState

    interrupted = set(study.user_attrs.get("interrupted", []))
    return sum(t.state in (TrialState.COMPLETE, TrialState.FAIL)
               and t.number not in interrupted for t in study.get_trials(deepcopy=False))


def _plan(context: _Context, trial, study) -> list[RunTask] | None:
    """The runs of an asked trial; None (the trial failed) when its values make no valid
    scenario."""
    from optuna.trial import TrialState

    params = {a.name: trial.suggest_float(a.name, a.design.low, a.design.high,
                                          log=a.design.log) for a in context.search}
    names = [f"trial-{trial.number:04d}-{k:02d}" for k in range(1, len(context.points) + 1)]
    try:
        return plan_runs(context.sweep, context.out_dir,
                         [{**p, **params} for p in context.points], names)
    except SweepError as error:
        trial.set_user_attr("error", str(error))
        study.tell(trial, state=TrialState.FAIL)
        return None


def _tell(study, trial, rows: list[dict[str, Any]], objective: str) -> None:
    from optuna.trial import TrialState

    values = [float(r[objective]) for r in rows if isinstance(r.get(objective), int | float)
              and not isinstance(r.get(objective), bool) and math.isfinite(r[objective])]
    trial.set_user_attr("runs", len(rows))
    trial.set_user_attr("failed", sum(r.get("status") != "done" for r in rows))
    if not values:
        trial.set_user_attr("error", f"no run has {objective}")
        study.tell(trial, state=TrialState.FAIL)
    else:
        study.tell(trial, math.fsum(values) / len(values))


def _report(study, trial, context: _Context) -> None:
    if context.progress is None:
        return
    frozen = next(t for t in study.get_trials(deepcopy=False) if t.number == trial.number)
    best = _best(study)
    context.progress({"number": trial.number, "value": frozen.value,
                      "state": frozen.state.name, "error": frozen.user_attrs.get("error", ""),
                      "params": frozen.params, "best": best, "done": _finished(study),
                      "total": context.total})


def _best(study) -> dict[str, Any] | None:
    try:
        best = study.best_trial
    except ValueError:  # no complete trial yet
        return None
    return {"number": best.number, "value": best.value, "params": dict(best.params)}


def _trial(trial) -> dict[str, Any]:
    return {"number": trial.number, "state": trial.state.name, "value": trial.value,
            "params": dict(trial.params), "runs": trial.user_attrs.get("runs"),
            "failed": trial.user_attrs.get("failed"), "error": trial.user_attrs.get("error", "")}


def _earlier_rows(out_dir: Path) -> list[dict[str, Any]]:
    """The rows of runs an earlier session ended (runs/trial-*.json)."""
    import json

    rows = []
    for side in sorted((out_dir / "runs").glob("trial-*.json")):
        try:
            rows.append(json.loads(side.read_text()))
        except (OSError, ValueError):
            continue
    return rows


def _plot(trials: list[dict[str, Any]], objective: str, direction: str, path: Path) -> Path:
    """The objective of each complete trial and the best so far. Returns path (PNG)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    complete = [t for t in trials if t["value"] is not None]
    fig, panel = plt.subplots(figsize=(6.4, 3.8))
    xs, ys = [t["number"] for t in complete], [t["value"] for t in complete]
    panel.plot(xs, ys, "o", label="trial")
    best, line = None, []
    for y in ys:
        best = y if best is None else (min(best, y) if direction == "minimize" else max(best, y))
        line.append(best)
    panel.step(xs, line, where="post", color="tab:red", label="best so far")
    panel.set_xlabel("trial")
    panel.set_ylabel(f"{objective} (mean over a trial's runs)")
    panel.grid(alpha=0.3)
    panel.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path
