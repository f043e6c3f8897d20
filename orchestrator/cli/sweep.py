"""`excosim sweep SWEEP.toml`: many campaigns over a sweep file's axes, on a local pool or a Dask
cluster, with a progress bar over runs, a summary table (Parquet, CSV), an overview plot and
resume (orchestrator.sweep); with --sensitivity, the Sobol indices of every summary figure to the
axes of a saltelli design (orchestrator.sweep.sensitivity).

Exit status: 0 when every run dug its campaign; 1 when some run failed (its row says why, the
others went on); 2 for a mistake found before any run (the sweep file, a scenario value, an
option, an output folder that holds something else, an unreachable scheduler, an FMU file that
is not ours without --trust); 130 for Ctrl-C and 143 for SIGTERM, after which the same command
goes on where the sweep stopped.
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Annotated, Any

import typer
from rich.console import Console
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)

from orchestrator.cli.conventions import fail, json_text
from orchestrator.cli.options import AsJson, Quiet, RecycleAfter, Scheduler, Trust, Workers
from orchestrator.cli.signals import (
    INTERRUPTED_EXIT,
    TERMINATED_EXIT,
    Terminated,
    terminate_like_ctrl_c,
)

SWEEP_FILE = "sweep.toml"  # the sweep file's copy in its output folder: whose runs these are


def sweep(
    sweep_file: Annotated[Path, typer.Argument(metavar="SWEEP.toml", help="Sweep file, e.g. "
                                               "sweeps/robustness.toml.")],
    output: Annotated[Path | None, typer.Option(
        "-o", "--output", metavar="DIR", help="Folder of the run logs and the summary "
        "(default: runs/<sweep name>); the same folder again resumes the sweep.")] = None,
    workers: Workers = None,
    scheduler: Scheduler = None,
    recycle_after: RecycleAfter = 10,
    as_json: AsJson = False,
    quiet: Quiet = False,
    trust: Trust = False,
    sensitivity: Annotated[bool, typer.Option(
        "--sensitivity", help="Also compute first-order and total Sobol indices (with 95 % "
        "intervals) of each summary figure to the axes of the sweep's saltelli design: a "
        "table, sensitivity.csv/.json and sensitivity.png in the folder.")] = False,
) -> None:
    """Run many campaigns over a sweep file's axes; summarise them in one table."""
    if workers is not None and scheduler is not None:
        _exit("--workers and --scheduler exclude each other (a cluster has its own workers)", 2)
    if as_json and quiet:
        _exit("--json and --quiet exclude each other", 2)
    with terminate_like_ctrl_c():
        try:
            code = _sweep(sweep_file, output, workers, scheduler, recycle_after, as_json,
                          quiet, trust, sensitivity)
        except Terminated:
            code = _stopped("terminated (SIGTERM)", TERMINATED_EXIT)
        except KeyboardInterrupt:
            code = _stopped("interrupted", INTERRUPTED_EXIT)
    if code:
        raise typer.Exit(code)


TABLE_VALUES = 12  # an axis with more distinct values gets no table of its own
_WHERE: dict[str, Any] = {}  # what a stop reports: the folder, runs done of how many


def _stopped(what: str, code: int) -> int:
    if "out_dir" not in _WHERE:
        fail(f"{what} before any run started")
        return code
    fail(f"{what}: {_WHERE['done']} of {_WHERE['total']} runs done, summary in "
         f"{_WHERE['out_dir']}; the same command goes on from there")
    return code


def _exit(message: str, code: int) -> None:
    fail(message)
    raise typer.Exit(code)


def _sweep(sweep_file: Path, output: Path | None, workers: int | None, scheduler: str | None,
           recycle_after: int, as_json: bool, quiet: bool, trust: bool,
           sensitivity: bool = False) -> int:
    from orchestrator.sweep import SchedulerUnreachable, SweepError, load_sweep, prepare, run_sweep
    from orchestrator.sweep.sensitivity import sampled_axes

    _WHERE.clear()
    try:
        spec = load_sweep(sweep_file)
        if sensitivity:
            sampled_axes(spec)
        out_dir = output or Path("runs") / (re.sub(r"[^A-Za-z0-9_.-]+", "-", spec.name)
                                             .strip("-.") or "sweep")
        problem = _folder_problem(out_dir, spec)
        if problem:
            _exit(problem, 2)
        spec, tasks = prepare(spec, out_dir)
    except SweepError as error:
        _exit(str(error), 2)
    refused = _trust(tasks, trust, quiet)
    if refused:
        _exit(*refused)
    err = Console(stderr=True, highlight=False)
    columns = (TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
               TimeElapsedColumn(), TextColumn("ETA"), TimeRemainingColumn())
    with Progress(*columns, console=err, transient=True,
                  disable=quiet or not err.is_terminal) as bar:
        task = bar.add_task(f"{spec.name}: planning", total=len(tasks))
        failed: list[str] = []

        def started(to_run: int, skipped: int) -> None:
            _WHERE.update(out_dir=out_dir, done=skipped, total=to_run + skipped)
            _copy_sweep_file(spec, out_dir)
            bar.update(task, completed=skipped, description=f"{spec.name}: {skipped} skipped")

        def ended(row: dict[str, Any]) -> None:
            _WHERE["done"] += 1
            failed.extend([row["run"]] if row.get("status") != "done" else [])
            bar.update(task, advance=1, description=f"{spec.name}: {len(failed)} failed")

        try:
            result = run_sweep(spec, out_dir, workers=workers, scheduler=scheduler,
                               recycle_after=recycle_after, tasks=tasks, progress=ended,
                               on_start=started)
        except (SweepError, SchedulerUnreachable) as error:
            _exit(str(error), 2)
        except OSError as error:
            _exit(f"{out_dir}: {error.strerror or error}", 2)
    indices = _sensitivity(result) if sensitivity else None
    if as_json:
        print(json_text({**_report(result), **({"sensitivity": indices} if sensitivity else {})}))
    elif not quiet:
        _print_table(result)
        if indices is not None:
            _print_indices(indices, result.out_dir)
    return 1 if result.failed else 0


def _sensitivity(result) -> list[dict[str, Any]]:
    """The Sobol indices of the sweep's figures, written beside its summary."""
    from orchestrator.sweep.sensitivity import (
        SENSITIVITY,
        sensitivity,
        sensitivity_plot,
        write_sensitivity,
    )

    records = sensitivity(result.frame, result.sweep)
    write_sensitivity(records, result.out_dir)
    sensitivity_plot(records, result.out_dir / f"{SENSITIVITY}.png")
    return records


def _print_indices(records: list[dict[str, Any]], out_dir: Path) -> None:
    out = Console(highlight=False)
    out.print("\nSobol indices (S1 first-order, ST total; +- the 95 % interval's half-width)",
              markup=False)
    skipped: dict[str, str] = {}
    for condition in dict.fromkeys(json.dumps(r["condition"]) for r in records):
        chosen = [r for r in records if json.dumps(r["condition"]) == condition]
        if condition != "{}":
            out.print(f"\n{condition}", markup=False)
        for figure in dict.fromkeys(r["figure"] for r in chosen):
            rows = [r for r in chosen if r["figure"] == figure]
            if rows[0]["S1"] is None:
                skipped[figure] = rows[0]["note"]
                continue
            out.print(f"  {figure}", markup=False)
            for r in rows:
                out.print(f"    {r['axis'][-40:]:>40}  S1 {_index(r, 'S1')}  "
                          f"ST {_index(r, 'ST')}", markup=False, soft_wrap=True)
    if skipped:
        out.print("  no indices: " + ", ".join(f"{f} ({n})" for f, n in skipped.items()),
                  markup=False, soft_wrap=True)
    out.print(f"indices: {out_dir / 'sensitivity.csv'}, {out_dir / 'sensitivity.png'}",
              markup=False, soft_wrap=True)


def _index(record: dict[str, Any], key: str) -> str:
    value, conf = record[key], record[f"{key}_conf"]
    return f"{value:6.3f} +- {conf:5.3f}" if conf is not None else f"{value:6.3f}         "


def _folder_problem(out_dir: Path, spec, command: str = "sweep") -> str | None:
    """Why out_dir cannot hold this sweep's runs, or None (new, empty, or a sweep's of the same
    name: an edited sweep file goes on there, and only runs whose logged scenario is still the
    planned one are skipped)."""
    if out_dir.exists() and not out_dir.is_dir():
        return f"-o {out_dir}: not a folder"
    if not out_dir.is_dir() or not any(out_dir.iterdir()):
        return None
    copy = out_dir / SWEEP_FILE
    try:
        first = copy.read_text(encoding="utf-8").splitlines()[0]
    except (OSError, IndexError, UnicodeDecodeError):
        return f"-o {out_dir}: holds files but no {SWEEP_FILE}: not a sweep's folder"
    if not first.startswith(_header(spec, command) + " "):
        return (f"-o {out_dir}: holds the runs of another {command} ({first.removeprefix('# ')}); "
                "give another -o")
    return None


def _header(spec, command: str = "sweep") -> str:
    return f"# excosim {command} {json.dumps(spec.name)}"


def _copy_sweep_file(spec, out_dir: Path, command: str = "sweep") -> None:
    """The sweep file as it was run, under a first line naming the sweep (and the command)."""
    out_dir.mkdir(parents=True, exist_ok=True)
    text = spec.path.read_text(encoding="utf-8")
    (out_dir / SWEEP_FILE).write_text(f"{_header(spec, command)} (from {spec.path})\n{text}",
                                      encoding="utf-8")


def _trust(tasks, trust: bool, quiet: bool) -> tuple[str, int] | None:
    """The --trust rule of `excosim run`, once per distinct set of FMU files."""
    from orchestrator.cli.trust import trust_problem
    from orchestrator.scenario import scenario_from_dict

    seen = set()
    for task in tasks:
        files = tuple(task.scenario["plant"][role]["fmu"]
                      for role in ("boom", "stick", "bucket", "pile"))
        if files in seen:
            continue
        seen.add(files)
        scenario = scenario_from_dict(task.scenario, source=task.scenario_name,
                                      check_fmus=False)
        refused = trust_problem(scenario, trust, quiet)
        if refused is not None:
            return f"{task.run}: {refused[0]}", refused[1]
    return None


def _report(result) -> dict[str, Any]:
    from orchestrator.sweep.table import axis_statistics

    return {
        "sweep": result.sweep.name, "out_dir": str(result.out_dir),
        "runs": len(result.frame), "ran": len(result.ran), "skipped": len(result.skipped),
        "failed": result.failed,
        "files": {"parquet": str(result.parquet), "csv": str(result.csv),
                  "overview": str(result.overview) if result.overview else None},
        "axes": {axis.name: axis_statistics(result.frame, axis.name)
                 for axis in result.sweep.axes},
    }


def _print_table(result) -> None:
    from orchestrator.sweep.table import axis_statistics

    out = Console(highlight=False)
    out.print(f"{result.sweep.name}: {len(result.frame)} runs ({len(result.ran)} run now, "
              f"{len(result.skipped)} already complete, {len(result.failed)} failed) in "
              f"{result.out_dir}", markup=False, soft_wrap=True)
    for axis in result.sweep.axes:
        distinct = len({json.dumps(v) for v in axis.values})  # list values too
        if axis.design is not None or distinct > TABLE_VALUES:
            how = f" ({axis.design.design} design)" if axis.design is not None else ""
            out.print(f"\n{axis.name}: {distinct} values{how} (per run in the "
                      "summary, per value in overview.png)", markup=False, soft_wrap=True)
            continue
        out.print(f"\n{axis.name}", markup=False)
        out.print(f"  {'value':>24}  runs  mean|err| kg  worst kg  within band  resets"
                  "      t/h     kJ/t", markup=False)
        for s in axis_statistics(result.frame, axis.name):
            mean = "-" if s["mean_abs_error_kg"] is None else f"{s['mean_abs_error_kg']:.2f}"
            worst = "-" if s["worst_abs_error_kg"] is None else f"{s['worst_abs_error_kg']:.2f}"
            share = "-" if s["within_share"] is None else f"{100 * s['within_share']:.0f} %"
            value = json.dumps(s["value"]) if not isinstance(s["value"], str) else s["value"]
            rate = "-" if s["productivity_t_h"] is None else f"{s['productivity_t_h']:.2f}"
            per_t = "-" if s["energy_per_tonne_kj_t"] is None \
                else f"{s['energy_per_tonne_kj_t']:.0f}"
            out.print(f"  {value[-24:]:>24}  {s['runs']:>4}  {mean:>12}  {worst:>8}  "
                      f"{share:>11}  {s['resets']:>6}  {rate:>7}  {per_t:>7}", markup=False)
    out.print(f"\nsummary: {result.parquet}, {result.csv}", markup=False, soft_wrap=True)
