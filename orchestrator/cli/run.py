"""`excosim run`: load a scenario, run its campaign with a progress bar, print a table per period
(or one JSON object with --json, or nothing with --quiet).

Exit status (set by the caller from the returned failure): 0 when the campaign ends by its period
count or at the workspace limit; 2 for a user's mistake (scenario, --set, output path, an FMU
file that is not ours without --trust); 1 for a runtime failure, whose MCAP log stays readable
up to the last finished period; 130 for Ctrl-C and 143 for SIGTERM (orchestrator.cli.signals),
which both close the log after the last finished period with its end record, remove the FMUs'
temporary folders and say in one line how many periods were done and where the log is.

`run --resume RUN.mcap` continues such a run after its last complete period
(orchestrator.campaign.resume), with the same exit statuses; a log that cannot be resumed is a
mistake (2), one whose run finished is "nothing to resume" (0).
"""

from __future__ import annotations

import math
import os
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

from orchestrator.cli import tables
from orchestrator.cli.conventions import count, fail, json_text, status_on_terminal
from orchestrator.cli.results import RUNS, reserve_default_output, results_folder
from orchestrator.cli.run_output import logged_json, period_grid, run_json, summary_line
from orchestrator.cli.signals import (
    INTERRUPTED_EXIT,
    TERMINATED_EXIT,
    Terminated,
    terminate_like_ctrl_c,
)

STEP_TIMEOUT_S = 30.0  # default bound on one FMU step (a 10 ms step takes well under 1 ms)


@dataclass(frozen=True)
class LiveSettings:
    """`run --live`: serve the run over the Foxglove WebSocket protocol on host:port (port 0:
    any free one), paced at real_time_factor (1: wall-clock speed; orchestrator.live)."""

    port: int = 8765
    real_time_factor: float = 1.0
    host: str = "127.0.0.1"

    def problem(self) -> str | None:
        """One line on what is wrong with these settings, or None."""
        if not 0 <= self.port <= 65535:
            return f"--port must be 0..65535 (0: any free port), got {self.port}"
        if not (math.isfinite(self.real_time_factor) and self.real_time_factor > 0.0):
            return ("--real-time-factor must be a number > 0 (1: as fast as the machine "
                    f"digs), got {self.real_time_factor!r}")
        return None


@dataclass(frozen=True)
class RunOptions:
    """How `excosim run` digs and reports. as_json: one JSON object on stdout; quiet: nothing
    but errors; force: overwrite -o; trust: run FMU files that are not our builds
    (orchestrator.cli.trust); step_timeout_s: bound on one FMU step, s (0: none); isolate: dig
    in a supervised child (run()); live: serve the run live (None: no); out_dir: make a results
    folder per run in this folder (log, resolved scenario, layout, CSV, figures)."""

    as_json: bool = False
    quiet: bool = False
    force: bool = False
    trust: bool = False
    step_timeout_s: float = STEP_TIMEOUT_S
    isolate: bool = False
    live: LiveSettings | None = None
    out_dir: Path | None = None

    def problem(self) -> str | None:
        """One line on what is wrong with these options, or None."""
        if not (math.isfinite(self.step_timeout_s) and self.step_timeout_s >= 0.0):
            return f"--step-timeout must be a number of seconds >= 0, got {self.step_timeout_s!r}"
        return None if self.live is None else self.live.problem()


def run(scenario_path: Path, output: Path | None, overrides: list[str],
        options: RunOptions = RunOptions()) -> tuple[str, int] | None:
    """Run the campaign; None on success, else (one-line message, exit status). An FMU file
    that is not one of our builds runs only with `options.trust` (orchestrator.cli.trust); an
    FMU step that does not return within step_timeout_s (0: no bound) ends the process with
    status 1. options.isolate: dig in a supervised child process
    (orchestrator.campaign.isolation; where `can_isolate()`), so that an FMU that crashes or
    exits ends the run with the reason in its log."""
    problem = options.problem()
    if problem is not None:
        return problem, 2
    if output is not None and options.out_dir is not None:
        return "-o and --out-dir exclude each other: --out-dir names the log itself", 2
    with terminate_like_ctrl_c():
        try:
            return _run(scenario_path, output, overrides, options)
        except Terminated:  # before or after the campaign: no log of ours is open
            return f"terminated (SIGTERM) {_OUTSIDE}", TERMINATED_EXIT
        except KeyboardInterrupt:
            return f"interrupted {_OUTSIDE}", INTERRUPTED_EXIT


_OUTSIDE = "while loading the scenario or printing the results; no period was cut"


def resume(log: Path | None, output: Path | None, given: tuple,
           options: RunOptions = RunOptions()) -> tuple[str, int] | None:
    """`run --resume LOG`: continue the logged run after its last complete period
    (orchestrator.campaign.resume), in place or into `output`; None on success, else (one
    line, exit status). given: (SCENARIO.toml, --set, --periods, --plant, --emulate) as given,
    none of which may be (the run goes on as it was logged). A run that finished: one line
    "nothing to resume", exit status 0. options: as for run() (no out_dir)."""
    names = ("SCENARIO.toml", "--set", "--periods", "--plant", "--emulate")
    extra = [name for name, value in zip(names, given, strict=True)
             if value is not None and value is not False]
    if log is None:
        return "missing argument 'SCENARIO.toml' (see 'excosim run -h')", 2
    if options.out_dir is not None:
        extra.append("--out-dir")
    if extra:
        return (f"--resume continues the run as its log recorded it: no {', '.join(extra)} "
                "with it"), 2
    problem = options.problem()
    if problem is not None:
        return problem, 2
    with terminate_like_ctrl_c():
        try:
            return _resume(log, output, options)
        except Terminated:
            return f"terminated (SIGTERM) {_OUTSIDE}", TERMINATED_EXIT
        except KeyboardInterrupt:
            return f"interrupted {_OUTSIDE}", INTERRUPTED_EXIT


def _resume(log: Path, output: Path | None, options: RunOptions) -> tuple[str, int] | None:
    import fmus
    from orchestrator.campaign.resume import NothingToResume, ResumeRefused, prepare_resume
    from orchestrator.cli.trust import trust_problem
    from orchestrator.scenario import ScenarioError

    try:
        source = prepare_resume(log)
    except NothingToResume as finished:
        if options.as_json:
            print(json_text({"path": str(log), "resumed": False, "message": str(finished)}))
        elif not options.quiet:
            print(finished)
        return None
    except (ResumeRefused, ScenarioError) as error:
        return str(error), 2
    except fmus.BuildError as error:
        return str(error), 1
    refused = trust_problem(source.scenario, options.trust, options.quiet)
    if refused is not None:
        return refused
    in_place = output is None or (output.exists() and output.resolve() == log.resolve())
    if not in_place:
        problem = _check_output(output, options.force)
        if problem is not None:
            return problem, 2
    return _dig(source.scenario, log if in_place else output, options, reserved=False,
                resume=source)


def _run(scenario_path: Path, output: Path | None, overrides: list[str], options: RunOptions
         ) -> tuple[str, int] | None:
    import fmus
    from orchestrator.cli.trust import trust_problem
    from orchestrator.scenario import ScenarioError, load_scenario

    try:
        status_on_terminal(options.quiet)
        scenario = load_scenario(scenario_path, overrides)
    except ScenarioError as error:
        return str(error), 2
    except fmus.BuildError as error:
        return str(error), 1
    refused = trust_problem(scenario, options.trust, options.quiet)
    if refused is not None:
        return refused
    if output is not None:
        problem = _check_output(output, options.force)
        if problem is not None:
            return problem, 2
        log_path = output
    elif options.out_dir is not None:
        try:
            log_path = results_folder(scenario, options.out_dir) / "run.mcap"
        except OSError as error:
            return (f"--out-dir {str(options.out_dir)!r}: cannot make the run's folder: "
                    f"{error.strerror or error}"), 2
    else:
        try:
            log_path = reserve_default_output(scenario)
        except OSError as error:
            return f"cannot create a log in {RUNS}/: {error.strerror or error}", 2
    return _dig(scenario, log_path, options, reserved=output is None)


def can_isolate() -> bool:
    """Whether `excosim run` can dig in a supervised child process here: on Linux, with
    standard output and error that are files (a forked child writes to the same ones; a
    caller that captures them in memory, such as click's test runner, keeps the run in its
    own process)."""
    from orchestrator.campaign.isolation import available

    try:
        sys.stdout.fileno()
        sys.stderr.fileno()
    except (AttributeError, OSError, ValueError):
        return False
    return available()


def _dig(scenario: Any, log_path: Path, options: RunOptions, *, reserved: bool,
         resume: Any = None) -> tuple[str, int] | None:
    """Run the campaign (or resume the ResumeSource `resume`) with a progress bar, print the
    results; None on success, else (one line, exit status). options.isolate: in a supervised
    child process (run())."""
    settings = {"reserved": reserved, "resume": resume}
    if not options.isolate:
        return _dig_here(scenario, log_path, options, **settings)
    from orchestrator.campaign.isolation import ChildDied, supervised

    def body() -> tuple[str, int] | None:  # what run() would make of a stop outside _dig_here
        try:
            return _dig_here(scenario, log_path, options, **settings)
        except Terminated:
            return f"terminated (SIGTERM) {_OUTSIDE}", TERMINATED_EXIT
        except KeyboardInterrupt:
            return f"interrupted {_OUTSIDE}", INTERRUPTED_EXIT

    before = len(resume.records) if resume is not None else 0
    outcome = supervised(body, log_path, before,
                         release=resume.release if resume is not None else None)
    if not isinstance(outcome, ChildDied):
        return None if outcome is None else (str(outcome[0]), int(outcome[1]))
    if sys.stderr.isatty():  # the child's progress bar hid the cursor and holds the line
        sys.stderr.write("\r\x1b[2K\x1b[?25h")
    if outcome.periods is not None:
        where = f"log {log_path} is readable up to period {outcome.periods}"
        if options.as_json:
            print(json_text(logged_json(log_path, outcome.message)))
    elif _drop_if_empty(log_path, reserved):
        where = "no log was written"
    else:
        where = f"log {log_path}: {outcome.log_note}"
    return f"run failed: {outcome.message} ({where})", 1


def _dig_here(scenario: Any, log_path: Path, options: RunOptions, *, reserved: bool,
              resume: Any) -> tuple[str, int] | None:
    from orchestrator.cli.results import serving
    from orchestrator.live import LiveError

    try:
        with serving(options.live, scenario, log_path, options.quiet) as live:
            return _dig_live(scenario, log_path, options, reserved, resume, live)
    except LiveError as error:  # the live view could not start: nothing was dug
        _drop_if_empty(log_path, reserved)
        return str(error), 2


def _dig_live(scenario: Any, log_path: Path, options: RunOptions, reserved: bool, resume: Any,
              live: Any) -> tuple[str, int] | None:
    from orchestrator.campaign import PlantRefused, run_campaign
    from orchestrator.campaign.isolation import end_child
    from orchestrator.campaign.resume import ResumeRefused, resume_campaign

    as_json, quiet, force = options.as_json, options.quiet, options.force
    step_timeout_s = options.step_timeout_s
    err = Console(stderr=True, highlight=False)

    def opened(log: Any) -> None:
        if live is not None:
            log.attach_live(live)
        # At a terminal, where to look while it runs (a script gets the path at the end).
        if not quiet and not as_json and err.is_terminal:
            err.print(f"logging to {log_path}", markup=False, soft_wrap=True)

    done: list[dict[str, Any]] = list(resume.records) if resume is not None else []
    columns = (TextColumn("[progress.description]{task.description}"), BarColumn(),
               MofNCompleteColumn(), TimeElapsedColumn())
    try:
        with Progress(*columns, console=err, transient=True,
                      disable=quiet or not err.is_terminal) as bar:
            task = bar.add_task(f"{scenario.name}: period {len(done) + 1}",
                                total=scenario.periods, completed=len(done))

            def progress(record: dict[str, Any]) -> None:
                done.append(record)
                bar.update(task, advance=1, description=f"{scenario.name}: period "
                           f"{record['k'] + 1} (last {record['mass_kg']:.1f} kg)")

            def stuck(message: str) -> None:  # the watchdog's thread; the log is closed
                bar.stop()
                if log_path.exists() and log_path.stat().st_size > 0:
                    where = f"log {log_path} is readable up to period {len(done)}"
                else:  # stuck building the plant, before the log
                    _drop_if_empty(log_path, reserved)
                    where = "no log was written"
                line = f"run stopped: {message} ({where})"
                end_child((line, 1))  # a supervised child: its parent prints it
                fail(line)
                sys.stdout.flush()
                sys.stderr.flush()
                os._exit(1)  # the main thread is stuck in native code: nothing else ends it

            if resume is not None:
                result = resume_campaign(resume, log_path, progress=progress, overwrite=force,
                                         step_timeout_s=step_timeout_s, on_step_timeout=stuck,
                                         on_log_opened=opened)
            else:  # a reserved default name is an empty file of ours: no loss to write over
                result = run_campaign(scenario, log_path=log_path, progress=progress,
                                      overwrite=force or reserved,
                                      step_timeout_s=step_timeout_s, on_step_timeout=stuck,
                                      on_log_opened=opened)
    except ResumeRefused as error:
        return str(error), 2
    except KeyboardInterrupt:
        return _interrupted(log_path, len(done), scenario.periods, reserved), INTERRUPTED_EXIT
    except Terminated:
        return _interrupted(log_path, len(done), scenario.periods, reserved,
                            "terminated (SIGTERM)"), TERMINATED_EXIT
    except PlantRefused as error:  # before the log: the scenario's mistake, nothing written
        _drop_if_empty(log_path, reserved)
        return str(error), 2
    except FileExistsError:  # created by someone else since _check_output looked
        return f"output {str(log_path)!r} already exists; remove it or add --force", 2
    except OSError as error:
        _drop_if_empty(log_path, reserved)
        return f"output {str(log_path)!r}: cannot write it: {error.strerror or error}", 2
    if options.out_dir is not None:
        from orchestrator.cli.results import write_results

        write_results(log_path, scenario)
    resumed = f"resumed after period {resume.k}: " if resume is not None else ""
    if as_json:
        payload = run_json(result, log_path)
        if resume is not None:
            payload["resumed_after_period"] = resume.k
        print(json_text(payload))
    elif not quiet:
        out = tables.console()
        tables.show(out, period_grid(result.records, scenario.target_mass_kg))
        out.print(resumed + summary_line(result, scenario.target_mass_kg), markup=False,
                  soft_wrap=True)
    if result.termination == "error":
        return (f"run failed: {result.message} (log {log_path} is readable up to period "
                f"{len(result.records)})"), 1
    return None


def _drop_if_empty(path: Path, reserved: bool) -> bool:
    """Remove our reserved, still empty log file (nothing was written to it); whether we did."""
    try:
        if reserved and path.stat().st_size == 0:
            path.unlink()
            return True
    except OSError:
        pass
    return False


def _interrupted(log_path: Path, periods_done: int, planned: int, reserved: bool,
                 how: str = "interrupted") -> str:
    if _drop_if_empty(log_path, reserved) or not log_path.exists():
        where = "no log was written"
    elif periods_done:
        where = f"log {log_path} is readable up to period {periods_done}"
    else:
        where = f"log {log_path} holds no period"
    return f"{how} after {periods_done} of {count(planned, 'period')}; {where}"


def _check_output(path: Path, force: bool) -> str | None:
    if path.suffix != ".mcap":
        return f"output {str(path)!r}: expected a file name ending in .mcap"
    if path.is_dir():
        return f"output {str(path)!r} is a folder; give a file name ending in .mcap"
    if path.exists() and not force:
        return (f"output {str(path)!r} already exists; remove it, choose another name or add "
                "--force")
    from orchestrator.runlog.lock import being_written

    if path.exists() and being_written(path):
        return (f"output {str(path)!r} is being written by a run that is still going; not "
                "even --force writes over it")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        return f"output {str(path)!r}: cannot create its folder: {error.strerror or error}"
    return None
