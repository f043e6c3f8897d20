"""`excosim calibrate SCENARIO --against RUN.mcap --param KEY=LOW:HIGH ...`: fit scenario
parameters so the simulated plant reproduces a logged run (orchestrator.calibrate).

Exit status: 0 when the study ran; 2 for a mistake found before any trial (a parameter, a range,
the log, an option, an unreachable scheduler); 1 when every trial failed; 130 for Ctrl-C and 143
for SIGTERM, after which the same command continues the study.
"""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Annotated, Any

import typer
from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

from orchestrator.cli.conventions import fail, json_text
from orchestrator.cli.options import AsJson, Quiet, Scheduler
from orchestrator.cli.signals import (
    INTERRUPTED_EXIT,
    TERMINATED_EXIT,
    Terminated,
    terminate_like_ctrl_c,
)


def _exit(message: str, code: int) -> None:
    fail(message)
    raise typer.Exit(code)


def main(
    scenario: Annotated[Path, typer.Argument(metavar="SCENARIO.toml", help="Scenario whose "
                                             "simulated plant is fitted, e.g. "
                                             "scenarios/paper-2020.toml.")],
    against: Annotated[Path, typer.Option("--against", metavar="RUN.mcap", help="Run log to "
                                          "reproduce: a simulated or a lab run of the same "
                                          "machine preset.")],
    params: Annotated[list[str] | None, typer.Option(
        "--param", metavar="KEY=LOW:HIGH", help="A numeric scenario key to fit and its range, "
        "e.g. plant.pile.parameters.density=1500:2000 (repeatable, at least one).")] = None,
    overrides: Annotated[list[str] | None, typer.Option(
        "--set", metavar="KEY=VALUE", help="Override a scenario value, as for excosim run "
        "(repeatable); the calibrated scenario keeps it.")] = None,
    trials: Annotated[int, typer.Option("--trials", metavar="N", help="Trials in the "
                                        "study, those it already holds included: 60 % TPE, "
                                        "then Nelder-Mead.")] = 60,
    workers: Annotated[int | None, typer.Option(
        "--workers", metavar="N", help="Local worker processes (default 1: trials in "
        "this process).")] = None,
    scheduler: Scheduler = None,
    output: Annotated[Path | None, typer.Option(
        "-o", "--output", metavar="DIR", help="Folder of the study and the outputs (default: "
        "runs/calibrate-<scenario>); the same command again continues its study.")] = None,
    seed: Annotated[int, typer.Option("--seed", metavar="N", help="Seed of the TPE "
                                      "sampler.")] = 0,
    mass_weight: Annotated[float, typer.Option(
        "--mass-weight", metavar="W", help="Weight of the mass term, 0..1 "
        "(the joint term has 1 - W).")] = 0.5,
    mass_scale: Annotated[float | None, typer.Option(
        "--mass-scale-kg", metavar="KG", help="Mass residual worth one unit of score (default: "
        "2 % of the log's target mass).")] = None,
    joint_scale: Annotated[float | None, typer.Option(
        "--joint-scale-deg", metavar="DEG", help="Joint RMS residual worth one unit of score "
        "(default 0.05 deg).")] = None,
    as_json: AsJson = False,
    quiet: Quiet = False,
) -> None:
    """Fit scenario parameters so the simulated plant reproduces a logged run."""
    if workers is not None and scheduler is not None:
        _exit("--workers and --scheduler exclude each other (a cluster has its own workers)", 2)
    for name, value, low in (("--trials", trials, 1), ("--workers", workers, 1),
                             ("--seed", seed, 0)):
        if value is not None and value < low:
            _exit(f"{name} must be at least {low}, got {value}", 2)
    if not (math.isfinite(mass_weight) and 0.0 <= mass_weight <= 1.0):
        _exit(f"--mass-weight must be a number in 0..1, got {mass_weight:g}", 2)
    for name, value in (("--mass-scale-kg", mass_scale), ("--joint-scale-deg", joint_scale)):
        if value is not None and not (math.isfinite(value) and value > 0.0):
            _exit(f"{name} must be a number > 0, got {value:g}", 2)
    weighting = {"mass_weight": mass_weight, "mass_scale_kg": mass_scale,
                 "joint_scale_deg": joint_scale}
    out_dir = output or Path("runs") / ("calibrate-" + (re.sub(r"[^A-Za-z0-9_.-]+", "-",
                                                               scenario.stem) or "scenario"))
    if out_dir.exists() and not out_dir.is_dir():
        _exit(f"-o {out_dir}: not a folder", 2)
    with terminate_like_ctrl_c():
        try:
            code = _calibrate(scenario, against, params or [], overrides or [], trials,
                              workers or 1, scheduler, out_dir, seed, weighting, as_json, quiet)
        except Terminated:
            code = _stopped("terminated (SIGTERM)", out_dir, TERMINATED_EXIT)
        except KeyboardInterrupt:
            code = _stopped("interrupted", out_dir, INTERRUPTED_EXIT)
    if code:
        raise typer.Exit(code)


def _stopped(what: str, out_dir: Path, code: int) -> int:
    fail(f"{what}: the study in {out_dir} keeps its trials; the same command continues it")
    return code


def _calibrate(scenario: Path, against: Path, params: list[str], overrides: list[str],
               trials: int, workers: int, scheduler: str | None, out_dir: Path, seed: int,
               weighting: dict[str, Any], as_json: bool, quiet: bool) -> int:
    from orchestrator.calibrate import CalibrationError
    from orchestrator.calibrate.run import calibrate, prepare
    from orchestrator.sweep import SchedulerUnreachable

    try:
        prepare(scenario, against, params, overrides, weighting)  # every check, before a trial
    except CalibrationError as error:
        _exit(str(error), 2)
    err = Console(stderr=True, highlight=False)
    columns = (TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
               TimeElapsedColumn())
    with Progress(*columns, console=err, transient=True,
                  disable=quiet or as_json or not err.is_terminal) as bar:
        task = bar.add_task("calibrating", total=trials)

        def started(held: int, budget: int) -> None:
            bar.update(task, completed=min(held, budget))

        def advanced(done: int, best: float | None) -> None:
            text = "calibrating" if best is None else f"calibrating: best score {best:.4g}"
            bar.update(task, completed=done, description=text)

        try:
            result = calibrate(scenario, against, params, out_dir, overrides=overrides,
                               trials=trials, workers=workers, scheduler=scheduler, seed=seed,
                               weighting=weighting, progress=advanced, on_start=started)
        except CalibrationError as error:
            _exit(str(error), 2)
        except SchedulerUnreachable as error:
            _exit(str(error), 2)
        except OSError as error:
            _exit(f"{out_dir}: {error.strerror or error}", 2)
        except RuntimeError as error:
            _exit(str(error).splitlines()[0], 1)
    if as_json:
        print(json_text(report(result)))
    elif not quiet:
        _print(result)
    return 0


def report(result) -> dict[str, Any]:
    """The calibration as plain JSON-able data."""
    return {
        "parameters": [{"key": p.key, "low": p.low, "high": p.high, "start": p.start,
                        "calibrated": result.best_values[p.key]} for p in result.parameters],
        "score": {"start": result.start_fit.score, "calibrated": result.best_fit.score},
        "weighting": vars(result.weighting), "trials": result.trials, "ran": result.ran,
        "trial_wall_s": result.trial_wall_s,
        "files": {name: str(path) for name, path in result.files.items()},
    }


def _print(result) -> None:
    out = Console(highlight=False)
    width = max(len(p.key) for p in result.parameters)
    out.print(f"{'parameter':<{width}}  {'start':>12}  {'calibrated':>12}  range", markup=False)
    for p in result.parameters:
        out.print(f"{p.key:<{width}}  {p.start:>12.6g}  {result.best_values[p.key]:>12.6g}  "
                  f"{p.low:g}:{p.high:g}", markup=False)
    w = result.weighting
    out.print(f"score {result.start_fit.score:.4g} -> {result.best_fit.score:.4g} (mass scale "
              f"{w.mass_scale_kg:.3g} kg, joint scale {w.joint_scale_deg:.3g} deg, mass weight "
              f"{w.mass_weight:g}); {result.trials} trials ({result.ran} now, "
              f"{result.trial_wall_s:.3g} s each)", markup=False, soft_wrap=True)
    out.print(f"calibrated scenario: {result.files['toml']}; per period: {result.files['csv']};"
              f" figure: {result.files['figure']}", markup=False, soft_wrap=True)
