"""`excosim optimize SWEEP.toml --objective FIGURE`: a sweep file's design axes as a search space,
Optuna's TPE choosing the runs on the sweep's executors, the study resumable beside the logs
(orchestrator.sweep.optimize).

Exit status: 0 when the study holds its trials and one of them is complete; 1 when none is;
2 for a mistake found before any run (the sweep file, an objective the summary does not have,
an option, an output folder that holds something else, an unreachable scheduler, an FMU file
that is not ours without --trust); 130 for Ctrl-C and 143 for SIGTERM, after which the same
command goes on with the study.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path
from typing import Annotated, Any

import typer
from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

from orchestrator.cli.conventions import fail, json_text
from orchestrator.cli.options import AsJson, Quiet, RecycleAfter, Scheduler, Trust, Workers
from orchestrator.cli.signals import (
    INTERRUPTED_EXIT,
    TERMINATED_EXIT,
    Terminated,
    terminate_like_ctrl_c,
)

_WHERE: dict[str, Any] = {}


def optimize(
    sweep_file: Annotated[Path, typer.Argument(metavar="SWEEP.toml", help="Sweep file whose "
                                               "design axes (a sample with a design, low and high) "
                                               "are the search space, e.g. "
                                               "sweeps/fuzzy-centres.toml.")],
    objective: Annotated[str, typer.Option(
        "--objective", metavar="FIGURE", help="The summary figure to optimise (its mean over "
        "a trial's runs), e.g. mean_abs_error_kg or productivity_t_h.")],
    maximize: Annotated[bool, typer.Option(
        "--maximize/--minimize", help="Look for the largest (--maximize) or the smallest "
        "(--minimize, the default) objective.")] = False,
    trials: Annotated[int, typer.Option(
        "--trials", metavar="N", help="Trials the study holds when done (again with the same "
        "folder: only the missing ones run).")] = 20,
    seed: Annotated[int, typer.Option("--seed", metavar="S", help="Seed of the TPE sampler.")
                    ] = 0,
    output: Annotated[Path | None, typer.Option(
        "-o", "--output", metavar="DIR", help="Folder of the run logs, the summary and the "
        "study (study.db; default: runs/<sweep name>-optimize); the same folder again goes "
        "on with the study.")] = None,
    workers: Workers = None,
    scheduler: Scheduler = None,
    recycle_after: RecycleAfter = 10,
    as_json: AsJson = False,
    quiet: Quiet = False,
    trust: Trust = False,
) -> None:
    """Search a sweep file's design axes for the best value of a summary figure (Optuna TPE)."""
    if workers is not None and scheduler is not None:
        _exit("--workers and --scheduler exclude each other (a cluster has its own workers)")
    if as_json and quiet:
        _exit("--json and --quiet exclude each other")
    with terminate_like_ctrl_c():
        try:
            code = _optimize(sweep_file, objective, maximize, trials, seed, output, workers,
                             scheduler, recycle_after, as_json, quiet, trust)
        except Terminated:
            code = _stopped("terminated (SIGTERM)", TERMINATED_EXIT)
        except KeyboardInterrupt:
            code = _stopped("interrupted", INTERRUPTED_EXIT)
    if code:
        raise typer.Exit(code)


def _exit(message: str, code: int = 2) -> None:
    fail(message)
    raise typer.Exit(code)


def _stopped(what: str, code: int) -> int:
    if "out_dir" not in _WHERE:
        fail(f"{what} before any run started")
    else:
        fail(f"{what}: {_WHERE.get('done', 0)} of {_WHERE['total']} trials done, study in "
             f"{_WHERE['out_dir']}; the same command goes on from there")
    return code


def _optimize(sweep_file: Path, objective: str, maximize: bool, trials: int, seed: int,
              output: Path | None, workers: int | None, scheduler: str | None,
              recycle_after: int, as_json: bool, quiet: bool, trust: bool) -> int:
    from orchestrator.cli.sweep import _copy_sweep_file, _folder_problem, _trust
    from orchestrator.sweep import SchedulerUnreachable, SweepError, load_sweep
    from orchestrator.sweep.optimize import check_objective, prepare_optimize, run_optimize

    _WHERE.clear()
    try:
        check_objective(objective)
        if trials < 1:
            raise SweepError("--trials", "", f"a whole number >= 1, got {trials}")
        spec = load_sweep(sweep_file)
        out_dir = output or Path("runs") / ((re.sub(r"[^A-Za-z0-9_.-]+", "-", spec.name)
                                             .strip("-.") or "sweep") + "-optimize")
        problem = _folder_problem(out_dir, spec, "optimize")
        if problem:
            _exit(problem)
        spec, _, _, tasks = prepare_optimize(spec, out_dir, objective)
    except SweepError as error:
        _exit(str(error))
    refused = _trust(tasks, trust, quiet)
    if refused:
        _exit(*refused)
    err = Console(stderr=True, highlight=False)
    lines = not quiet and not as_json and not err.is_terminal
    columns = (TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
               TimeElapsedColumn())
    with Progress(*columns, console=err, transient=True,
                  disable=quiet or not err.is_terminal) as bar:
        task = bar.add_task(f"{spec.name}: trials", total=trials)

        def ended(event: dict[str, Any]) -> None:
            _WHERE.update(done=event["done"])
            best = event["best"]
            text = (f"trial {event['number']}: " + (
                f"{objective} {event['value']:.4g}" if event["value"] is not None
                else f"failed ({event['error'] or event['state'].lower()})")
                + (f", best {best['value']:.4g} (trial {best['number']})" if best else ""))
            bar.update(task, completed=event["done"], description=f"{spec.name}: {text}")
            if lines:
                print(f"{event['done']}/{event['total']} {text}", file=sys.stderr, flush=True)

        _WHERE.update(out_dir=out_dir, total=trials)
        _copy_sweep_file(spec, out_dir, "optimize")
        try:
            result = run_optimize(spec, out_dir, objective, maximize=maximize, trials=trials,
                                  seed=seed, workers=workers, scheduler=scheduler,
                                  recycle_after=recycle_after, progress=ended)
        except (SweepError, SchedulerUnreachable) as error:
            _exit(str(error))
        except OSError as error:
            _exit(f"{out_dir}: {error.strerror or error}")
    if as_json:
        print(json_text(_report(result)))
    elif not quiet:
        _print(result)
    return 0 if result.best is not None else 1


def _report(result) -> dict[str, Any]:
    return {"sweep": result.sweep.name, "out_dir": str(result.out_dir),
            "objective": result.objective, "direction": result.direction,
            "trials": result.trials, "ran": result.ran, "best": result.best,
            "files": {"study": str(result.study), "parquet": str(result.parquet),
                      "csv": str(result.csv),
                      "figure": str(result.figure) if result.figure else None}}


TOP = 10  # trials the table shows, best first


def _print(result) -> None:
    out = Console(highlight=False)
    done = [t for t in result.trials if t["value"] is not None]
    failed = [t for t in result.trials if t["value"] is None and not t["interrupted"]]
    out.print(f"{result.sweep.name}: {result.direction} {result.objective} over "
              f"{len(result.trials)} trials ({result.ran} run now, {len(failed)} failed) in "
              f"{result.out_dir}", markup=False, soft_wrap=True)
    names = list(result.trials[0]["params"]) if result.trials else []
    done.sort(key=lambda t: t["value"], reverse=result.direction == "maximize")
    out.print("  trial  " + "  ".join(f"{n.rsplit('.', 1)[-1][-24:]:>24}" for n in names)
              + f"  {result.objective:>20}  runs", markup=False, soft_wrap=True)
    for t in done[:TOP]:
        out.print(f"  {t['number']:>5}  " + "  ".join(f"{t['params'].get(n, float('nan')):>24.6g}"
                                                    for n in names)
                  + f"  {t['value']:>20.4f}  {t['runs'] or '-':>4}", markup=False,
                  soft_wrap=True)
    if result.best is not None:
        values = ", ".join(f"{k} = {v:.6g}" for k, v in result.best["params"].items())
        out.print(f"\nbest: trial {result.best['number']}, {result.objective} = "
                  f"{result.best['value']:.4f} at {values}", markup=False, soft_wrap=True)
    out.print(f"summary: {result.parquet}; study: {result.study}", markup=False,
              soft_wrap=True)
