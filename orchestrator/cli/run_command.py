"""`excosim run`'s options (the campaign itself: orchestrator.cli.run)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from orchestrator.cli.conventions import fail
from orchestrator.cli.options import Trust

RUN_LOG = "RUN.mcap"


def _fail(message: str, code: int) -> None:
    fail(message)
    raise typer.Exit(code)


def run(
    scenario: Annotated[Path | None, typer.Argument(
        metavar="SCENARIO.toml", help="Scenario file, e.g. scenarios/paper-2020.toml.")] = None,
    output: Annotated[
        Path | None,
        typer.Option("-o", "--output", metavar=RUN_LOG, help="Log to write (default: a new "
                     "runs/<scenario>-<UTC time>-<scenario hash>.mcap)."),
    ] = None,
    resume: Annotated[
        Path | None, typer.Option("--resume", metavar=RUN_LOG, help="Continue the killed or "
                                  "interrupted run of this log after its last complete period "
                                  "(its own scenario; the log is replaced unless -o).")
    ] = None,
    periods: Annotated[
        int | None, typer.Option("--periods", metavar="N", help="Dig N periods (at least 1).")
    ] = None,
    overrides: Annotated[
        list[str] | None,
        typer.Option("--set", metavar="KEY=VALUE", help="Override a scenario value, e.g. --set "
                     "periods=5 or --set plant.pile.parameters.density=1800 (repeatable)."),
    ] = None,
    as_json: Annotated[
        bool, typer.Option("--json", help="Print one JSON object (scenario, termination, "
                           "path, periods, figures, ...) instead of the table.")
    ] = False,
    quiet: Annotated[
        bool, typer.Option("--quiet", "-q", help="Print nothing but errors.")
    ] = False,
    force: Annotated[
        bool, typer.Option("--force", "-f", help="Overwrite the -o file if it exists.")
    ] = False,
    out_dir: Annotated[
        Path | None, typer.Option("--out-dir", metavar="DIR", help="Make a results folder "
                                  "for the run in DIR: the log (run.mcap), the resolved "
                                  "scenario, its Foxglove layout, the period table as CSV and "
                                  "the review's figures.")
    ] = None,
    live: Annotated[
        bool, typer.Option("--live", help="Serve the run as it goes to Foxglove or Lichtblick "
                           "(Foxglove WebSocket protocol, ws://127.0.0.1:PORT).")
    ] = False,
    port: Annotated[
        int | None, typer.Option("--port", metavar="N", help="Port of --live (default 8765; "
                                 "0: any free port).")
    ] = None,
    real_time_factor: Annotated[
        float | None, typer.Option("--real-time-factor", metavar="X", help="Pace of --live: "
                                   "X times as fast as the machine digs (default 1).")
    ] = None,
    plant: Annotated[
        str | None, typer.Option("--plant", metavar="sim|lab", help="Dig with the simulated "
                                 "excavator or the lab excavator over CAN (table plant.lab).")
    ] = None,
    emulate: Annotated[
        bool, typer.Option("--emulate", help="Lab plant: run the emulated excavator in this "
                           "process on python-can's virtual bus (hardware-in-the-loop).")
    ] = False,
    trust: Trust = False,
    step_timeout: Annotated[
        float, typer.Option("--step-timeout", metavar="S", help="End the run when one FMU step "
                            "does not return within S seconds (0: never).")
    ] = 30.0,
    in_process: Annotated[
        bool, typer.Option("--in-process", help="Dig in this process, not in a supervised "
                           "child (for a debugger or a profiler; a crashing FMU then ends the "
                           "run without an end record in its log).")
    ] = False,
) -> None:
    """Run a digging campaign (or go on with a stopped one: --resume): plan, dig and weigh
    period after period; log it to MCAP."""
    from orchestrator.cli import run as run_command
    from orchestrator.cli.lab import run_overrides

    if as_json and quiet:
        _fail("--json and --quiet exclude each other", 2)
    if not live and (port is not None or real_time_factor is not None):
        _fail(f"{'--port' if port is not None else '--real-time-factor'} goes with --live", 2)
    settings = run_command.LiveSettings(
        8765 if port is None else port, 1.0 if real_time_factor is None else real_time_factor
    ) if live else None
    options = run_command.RunOptions(
        as_json=as_json, quiet=quiet, force=force, trust=trust, step_timeout_s=step_timeout,
        isolate=not in_process and run_command.can_isolate(), live=settings, out_dir=out_dir)
    if resume is not None or scenario is None:  # the scenario then comes from the log
        failure = run_command.resume(resume, output, (scenario, overrides, periods, plant,
                                     emulate), options)
    else:
        lab_items, problem = run_overrides(plant, emulate)
        if problem is not None:
            _fail(problem, 2)
        items = [*lab_items, *(overrides or []),
                 *([f"periods={periods}"] if periods is not None else [])]
        failure = run_command.run(scenario, output, items, options)
    if failure is not None:
        _fail(*failure)
