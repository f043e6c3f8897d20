"""The `excosim` command line.

Every user mistake ends in one line on stderr and exit status 2; a runtime failure in one line and
exit status 1. No traceback reaches a user.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console

app = typer.Typer(
    help="Co-simulation of an autonomous excavator that digs to a target weight.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)
fmus_app = typer.Typer(help="Build and try the FMUs (FMI 2.0 co-simulation).", no_args_is_help=True)
app.add_typer(fmus_app, name="fmus")

_err = Console(stderr=True, highlight=False)


def _fail(message: str, code: int) -> None:
    _err.print(f"excosim: {message}", markup=False, soft_wrap=True)
    raise typer.Exit(code)


@fmus_app.command("build")
def fmus_build(
    names: Annotated[
        list[str] | None, typer.Argument(help="Models to build (default: all).")
    ] = None,
) -> None:
    """Build FMUs from fmus/<Model>/ and print one line per FMU: name and path."""
    import fmus

    wanted = names or list(fmus.MODELS)
    for name in wanted:
        if name not in fmus.MODELS:
            _fail(f"unknown model {name!r}; known: {', '.join(fmus.MODELS)}", 2)
    try:
        for name in wanted:
            print(f"{name}\t{fmus.build(name)}")
    except fmus.BuildError as exc:
        _fail(str(exc), 1)


@fmus_app.command("demo")
def fmus_demo() -> None:
    """Simulate each FMU briefly and print a short summary."""
    import fmus

    try:
        print(fmus.demo())
    except fmus.BuildError as exc:
        _fail(str(exc), 1)


@app.command("run")
def run(
    scenario: Annotated[Path, typer.Argument(help="Scenario TOML file.")],
    output: Annotated[
        Path | None,
        typer.Option("-o", "--output", help="MCAP log to write "
                     "(default: runs/<scenario-name>-<UTC time>.mcap)."),
    ] = None,
    periods: Annotated[
        int | None, typer.Option("--periods", min=1, help="Dig this many periods.")
    ] = None,
    overrides: Annotated[
        list[str] | None,
        typer.Option("--set", help="Override a scenario value, e.g. --set periods=5 or "
                     "--set plant.pile.parameters.density=1800 (repeatable)."),
    ] = None,
) -> None:
    """Run a digging campaign: plan, dig and weigh period after period; log it to MCAP."""
    from orchestrator.cli import run as run_command

    items = [*(overrides or []), *([f"periods={periods}"] if periods is not None else [])]
    failure = run_command.run(scenario, output, items)
    if failure is not None:
        _fail(*failure)


@app.command("review")
def review(
    run_log: Annotated[Path, typer.Argument(help="Run log (.mcap) written by `excosim run`.")],
    as_json: Annotated[
        bool, typer.Option("--json", help="Print one JSON object (scenario, plant, "
                           "target_mass_kg, termination, periods, ...).")
    ] = False,
    plots: Annotated[
        Path | None, typer.Option("--plots", help="Write PNG figures into this folder.")
    ] = None,
    period: Annotated[
        int, typer.Option("--period", min=1, help="Period of the per-period figures.")
    ] = 1,
) -> None:
    """Summarise a run from its log alone: scenario, how it ended, one row per period."""
    from orchestrator.cli.review import review_run

    failure = review_run(run_log, as_json, plots, period)
    if failure is not None:
        _fail(*failure)


@app.command("compare")
def compare(
    run_logs: Annotated[list[Path], typer.Argument(help="Run logs (.mcap) to compare.")],
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
    plots: Annotated[
        Path | None, typer.Option("--plots", help="Write the weight-error overlay here.")
    ] = None,
) -> None:
    """Set runs side by side: errors, periods on target, durations, jerk, resets."""
    from orchestrator.cli.review import compare_runs

    failure = compare_runs(run_logs, as_json, plots)
    if failure is not None:
        _fail(*failure)


@app.command("replay")
def replay(
    run_log: Annotated[Path, typer.Argument(help="Run log (.mcap) of a simulated run.")],
    trust: Annotated[
        bool, typer.Option("--trust", help="Run attached FMUs even when they differ from "
                           "FMUs built here from our sources (they are native code).")
    ] = False,
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
) -> None:
    """Re-run a campaign from the scenario and FMUs in its log; check every period matches."""
    from orchestrator.cli.replay import replay as replay_log

    failure = replay_log(run_log, trust, as_json)
    if failure is not None:
        _fail(*failure)


def main() -> None:
    """Console-script entry point."""
    try:
        app()
    except KeyboardInterrupt:
        _err.print("excosim: interrupted")
        sys.exit(130)


if __name__ == "__main__":
    main()
