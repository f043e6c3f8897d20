"""The `excosim` command line.

Every user mistake ends in one line on stderr and exit status 2; a runtime failure in one line and
exit status 1; Ctrl-C in one line and 130, SIGTERM in one line and 143 (orchestrator.cli.signals).
No traceback reaches a user. `-h`/`--help` on every command, `--version`, `excosim completion
SHELL` (orchestrator.cli.conventions).
"""

from __future__ import annotations

import signal
import sys
from pathlib import Path
from typing import Annotated

import typer

from orchestrator.cli import export_command, plot, run_command, signals
from orchestrator.cli.conventions import (
    HELP_OPTIONS,
    PROG,
    Command,
    Group,
    completion,
    enable_completion,
    fail,
    failures,
    version,
)
from orchestrator.cli.layout import layout_command
from orchestrator.cli.options import AsJson, Trust
from orchestrator.cli.ssp import export_ssp_command
from orchestrator.cli.sweep import sweep as sweep_command

app = typer.Typer(
    cls=Group, name=PROG, no_args_is_help=True, context_settings=HELP_OPTIONS,
    help="Co-simulation of an autonomous excavator that digs to a target weight.",
    add_completion=False,  # `excosim completion SHELL` instead: no shell detection to fail
    pretty_exceptions_enable=False,
)
fmus_app = typer.Typer(cls=Group, help="Build and try the FMUs (FMI 2.0 and 3.0 co-simulation).",
                       no_args_is_help=True, context_settings=HELP_OPTIONS)
app.add_typer(fmus_app, name="fmus")
log_app = typer.Typer(cls=Group, help="Work on run logs as files.", no_args_is_help=True,
                      context_settings=HELP_OPTIONS)
app.add_typer(log_app, name="log")
scenario_app = typer.Typer(cls=Group, help="Look at scenarios; export their plant (SSP).",
                           no_args_is_help=True, context_settings=HELP_OPTIONS)
app.add_typer(scenario_app, name="scenario")

RUN_LOG = run_command.RUN_LOG


def _fail(message: str, code: int) -> None:
    fail(message)
    raise typer.Exit(code)


def _show_version(value: bool) -> None:
    if value:
        print(f"excosim {version()}")
        raise typer.Exit(0)


@app.callback()
def main_options(
    show_version: Annotated[
        bool, typer.Option("--version", "-V", callback=_show_version, is_eager=True,
                           help="Print `excosim <version>` and exit.")
    ] = False,
) -> None:
    """Co-simulation of an autonomous excavator that digs to a target weight."""


@fmus_app.command("build", cls=Command)
def fmus_build(
    names: Annotated[
        list[str] | None,
        typer.Argument(metavar="MODEL", help="Models to build, e.g. HydraulicCylinder "
                       "(default: all)."),
    ] = None,
    fmi3: Annotated[bool, typer.Option("--fmi3", help="Build FMI 3.0 co-simulation FMUs.")] = False,
) -> None:
    """Build FMUs from fmus/<Model>/ and print one line per FMU: name and path."""
    import fmus

    wanted = names or list(fmus.MODELS)
    for name in wanted:
        if name not in fmus.MODELS:
            _fail(f"unknown model {name!r}; known: {', '.join(fmus.MODELS)}", 2)
    try:
        for name in wanted:
            print(f"{name}\t{fmus.build(name, fmi_version=3 if fmi3 else 2)}")
    except fmus.BuildError as exc:
        _fail(str(exc), exc.exit_status)


@fmus_app.command("info", cls=Command)
def fmus_info(
    target: Annotated[str, typer.Argument(metavar="FMU_OR_NAME", help="A .fmu file or one of "
                                          "our model names.")],
    as_json: AsJson = False,
    fmi3: Annotated[bool, typer.Option("--fmi3", help="For a model name: its FMI 3.0 build.")
                    ] = False,
) -> None:
    """FMI version, kind, variables, and the plant roles the FMU fills (default port map)."""
    from orchestrator.cli.fmus_info import info_command

    raise typer.Exit(info_command(target, as_json, fmi3))


@fmus_app.command("validate", cls=Command)
def fmus_validate(
    target: Annotated[str, typer.Argument(metavar="FMU", help="A .fmu file or one of our model "
                                          "names.")],
    role: Annotated[str | None, typer.Option("--role", metavar="ROLE", help="cylinder, pile, "
                                             "boom, stick or bucket (default: any).")] = None,
    fmi3: Annotated[bool, typer.Option(help="For a model name: its FMI 3.0 build.")] = False,
    ports: Annotated[str | None, typer.Option(metavar="JSON", help="Port map (JSON, role -> "
                                              "variable); needs --role.")] = None,
    scenario: Annotated[str | None, typer.Option(metavar="FILE", help="Use its --role's port "
                                                 "map and parameters.")] = None,
) -> None:
    """fmpy's validation plus the role checks: exit 0 valid, 1 problems, 2 not an FMU."""
    from orchestrator.cli.fmus_info import validate_command

    raise typer.Exit(validate_command(target, role, fmi3, ports, scenario))


@fmus_app.command("demo", cls=Command)
def fmus_demo() -> None:
    """Simulate each FMU briefly and print a short summary."""
    import fmus

    try:
        print(fmus.demo())
    except fmus.BuildError as exc:
        _fail(str(exc), 1)


app.command("run", cls=Command)(run_command.run)


@app.command("review", cls=Command)
def review(
    run_log: Annotated[Path, typer.Argument(metavar=RUN_LOG,
                                            help="Run log written by `excosim run`.")],
    as_json: Annotated[
        bool, typer.Option("--json", help="Print one JSON object (scenario, plant, "
                           "target_mass_kg, termination, periods, ...).")
    ] = False,
    plots: Annotated[Path | None, typer.Option("--plots", metavar="DIR",
                                               help="Write PNG figures into DIR.")] = None,
    period: Annotated[
        str | None, typer.Option("--period", metavar="K|all", help="Period of the per-period "
                                 "figures, or all (with --plots; default 1).")
    ] = None,
    csv: Annotated[
        Path | None, typer.Option("--csv", metavar="FILE.csv", help="Write the period table "
                                  "as CSV: one row per period.")
    ] = None,
    csv_channels: Annotated[
        list[str] | None,
        typer.Option("--csv-channels", metavar="TOPIC[,TOPIC]", help="Write these numeric "
                     "channels (e.g. /joints,/cylinder/boom) as CSV, one file per channel: "
                     "t_s, period, one column per field with its unit."),
    ] = None,
    csv_dir: Annotated[
        Path | None, typer.Option("--csv-dir", metavar="DIR", help="Folder of the "
                                  "--csv-channels files (default: the current folder).")
    ] = None,
) -> None:
    """Summarise a run from its log alone: scenario, how it ended, one row per period."""
    from orchestrator.cli.review import CsvRequest, review_run

    request = CsvRequest(csv, csv_channels or [], csv_dir)
    failure = review_run(run_log, as_json, plots, period, request)
    if failure is not None:
        _fail(*failure)


@app.command("compare", cls=Command)
def compare(
    run_logs: Annotated[list[Path], typer.Argument(metavar=RUN_LOG,
                                                   help="Run logs to compare.")],
    as_json: AsJson = False,
    plots: Annotated[
        Path | None, typer.Option("--plots", metavar="DIR",
                                  help="Write the weight-error overlay into DIR.")
    ] = None,
) -> None:
    """Set runs side by side: errors, periods on target, durations, jerk, resets."""
    from orchestrator.cli.review import compare_runs

    failure = compare_runs(run_logs, as_json, plots)
    if failure is not None:
        _fail(*failure)


app.command("sweep", cls=Command)(sweep_command)
app.command("optimize", cls=Command)(__import__("orchestrator.cli.optimize").cli.optimize.optimize)
app.command("calibrate", cls=Command)(__import__("orchestrator.cli.calibrate").cli.calibrate.main)
app.command("plot", cls=Command)(plot.plot)
app.command("export", cls=Command)(export_command.export)
app.command("layout", cls=Command)(layout_command)
scenario_app.command("export-ssp", cls=Command)(export_ssp_command)


@app.command("replay", cls=Command)
def replay(
    run_log: Annotated[Path, typer.Argument(metavar=RUN_LOG, help="Log of a simulated run.")],
    trust: Trust = False,
    as_json: AsJson = False,
) -> None:
    """Re-run a campaign from the scenario and FMUs in its log; check every period matches."""
    from orchestrator.cli.replay import replay as replay_log

    failure = replay_log(run_log, trust, as_json)
    if failure is not None:
        _fail(*failure)


@scenario_app.command("show", cls=Command)
def scenario_show(
    scenario: Annotated[Path, typer.Argument(metavar="SCENARIO.toml", help="Scenario file.")],
    overrides: Annotated[
        list[str] | None, typer.Option("--set", metavar="KEY=VALUE",
                                       help="Override a scenario value (repeatable).")
    ] = None,
    as_json: AsJson = False,
    trust: Trust = False,
) -> None:
    """The resolved scenario with every default, the FMU and sha256 of each plant role and the
    servo designed for each cylinder, without running anything."""
    from orchestrator.cli.scenario_show import show

    failure = show(scenario, overrides or [], as_json, trust)
    if failure is not None:
        _fail(*failure)


@log_app.command("repair", cls=Command)
def log_repair(
    run_log: Annotated[Path, typer.Argument(metavar=RUN_LOG, help="A run log, e.g. of a "
                                            "killed run (it is not changed).")],
    output: Annotated[
        Path | None, typer.Option("-o", "--output", metavar="OUT.mcap",
                                  help="The indexed copy (default: RUN.repaired.mcap).")
    ] = None,
) -> None:
    """Copy a run log's complete periods into a new, indexed file that every MCAP reader opens.

    A killed run's log has no index (MCAP writes it at the end); stream readers read it as it
    is, indexed ones (Foxglove, Lichtblick) need the copy. The copy still says that the run did
    not finish.
    """
    from orchestrator.runlog import RunLogError
    from orchestrator.runlog.repair import repair

    target = output if output is not None else run_log.with_suffix(".repaired.mcap")
    if target.suffix != ".mcap":
        _fail(f"output {str(target)!r}: expected a file name ending in .mcap", 2)
    try:
        report = repair(run_log, target)
    except (RunLogError, FileExistsError) as error:
        _fail(str(error).splitlines()[0] if str(error) else type(error).__name__, 2)
    except OSError as error:
        _fail(f"{target}: {error.strerror or error}", 2)
    periods = f"{report.periods} complete period{'s' if report.periods != 1 else ''}"
    state = "finished" if report.finished else "did not finish"
    if report.damage is not None:
        cut = f"; {run_log} is {report.damage}: " + (
            "the copy holds what precedes the damage" if report.truncated
            else "its records were copied as they read")
    else:
        cut = "; the end of the file was cut off and left out" if report.truncated else ""
    print(f"wrote {report.target}: {periods}, {report.messages} messages; the run {state}{cut}")


@app.command("emulate", cls=Command)
def emulate(
    interface: Annotated[str, typer.Option("--interface", metavar="NAME", help="python-can "
                                           "interface, e.g. socketcan, slcan, pcan, virtual.")
                         ] = "socketcan",
    channel: Annotated[str, typer.Option("--channel", metavar="NAME",
                                         help="Bus channel, e.g. vcan0 or can0.")] = "vcan0",
    bitrate: Annotated[int, typer.Option("--bitrate", metavar="BIT/S",
                                         help="Bus bit rate, bit/s.")] = 500_000,
    scenario: Annotated[
        Path | None, typer.Option("--scenario", metavar="FILE.toml", help="The machine to "
                                  "emulate and its plant.lab link (default: the lab preset).")
    ] = None,
    time_scale: Annotated[
        float | None, typer.Option("--time-scale", metavar="X", help="Machine time per wall "
                                   "second (default: the scenario's, 1 = real time).")
    ] = None,
    duration: Annotated[
        float | None, typer.Option("--duration", metavar="S", help="Stop after S wall seconds "
                                   "(default: at Ctrl-C).")
    ] = None,
    faults: Annotated[
        list[str] | None, typer.Option("--fault", metavar="KEY=VALUE", help="Inject a fault, "
                                       "e.g. --fault estop_at_s=5 (keys of plant.lab.faults; "
                                       "repeatable).")
    ] = None,
    overrides: Annotated[
        list[str] | None, typer.Option("--set", metavar="KEY=VALUE",
                                       help="Override a scenario value (repeatable).")
    ] = None,
    trust: Trust = False,
) -> None:
    """Run the emulated lab excavator (our FMUs) as the device side of the CAN protocol."""
    from orchestrator.cli.lab import emulate as emulate_device

    failure = emulate_device(interface, channel, bitrate, scenario, time_scale, duration,
                             faults or [], overrides or [], trust)
    if failure is not None:
        _fail(*failure)


app.command("completion", cls=Command)(completion)


def main() -> None:
    """Console-script entry point. A Ctrl-C or SIGTERM at any moment ends in one line and exit
    status 130 or 143 (orchestrator.cli.signals: the phases): a command's own line, else
    "interrupted" or "terminated (SIGTERM)" here (typer turns a Ctrl-C while it parses the
    command line into a silent exit 130)."""
    signals.in_command()
    said, status = failures(), 1  # 1: an exception that is not a stop (Python shows it)
    try:
        enable_completion()
        # The name, not argv[0]: `python -c`/`-m` would show up in usage lines and would change
        # the variable the completion scripts set.
        app(prog_name=PROG)
        status = 0
    except SystemExit as done:
        status = done.code if isinstance(done.code, int) else 0 if done.code is None else 1
        stop = {signals.INTERRUPTED_EXIT: signal.SIGINT,
                signals.TERMINATED_EXIT: signal.SIGTERM}.get(status)
        if stop is not None and failures() == said:
            fail(signals.stop_line(stop))
        raise
    except BaseException as error:  # a stop outside a command, or an error it caused
        stop = signals.stopped_by(error)
        if stop is None:
            raise
        fail(signals.stop_line(stop))
        status = 128 + stop
        sys.exit(status)
    finally:
        signals.at_exit(status)


if __name__ == "__main__":
    main()
