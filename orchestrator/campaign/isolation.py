"""A campaign in a supervised child process: an FMU that crashes (a segfault, `abort()`) or ends
the process (`exit()`) ends the run with its reason in the log's end record, not with the
whole program gone and the log left without one (`excosim run`; sweeps have their own worker
processes, orchestrator.sweep.executors).

`supervised(body, log_path)` forks once the scenario is checked and the log's path is known; the
child runs `body` (the campaign and everything it prints) and hands its outcome back through a
file, the parent waits. When the child ends without handing an outcome back, the parent

- names the cause: the signal, or the exit status of an `exit()`; and the FMU. A fatal signal's
  faulthandler dump names it: each FMU instance's step function carries the instance's name
  (fmus.runs.STEP_NAME); the step loop in C has no frame per FMU step, and its board, a file
  in the child's temporary folder, names the FMU it was stepping
  (orchestrator.plants.native.board); an `exit()` is caught by a C `atexit` handler that reads
  the step's frame as the step watchdog does (orchestrator.campaign.watchdog.stuck_step);
- closes the log (orchestrator.runlog.resume.close_unfinished): its whole periods and the end
  record termination "error" with that reason, so it is indexed, readable by any MCAP reader and
  can be resumed (`excosim run --resume`);
- removes the child's temporary folders (the extracted FMUs): the child's temporary folder is
  one the parent made.

Signals: the child stays in the terminal's process group (so Ctrl-Z stops both, and a terminal
with `tostop` lets it write); the parent passes SIGINT and SIGTERM on to the child, which acts
on the first SIGINT it gets (a Ctrl-C at the terminal reaches it twice) and stops as an
unsupervised run does (orchestrator.cli.signals); its outcome comes back. The child is killed
when the parent dies (Linux's PR_SET_PDEATHSIG), so SIGKILL on the parent still ends the run at
once.

Linux only (fork, PR_SET_PDEATHSIG): elsewhere `available()` is False and the caller runs the
campaign in its own process.
"""

from __future__ import annotations

import ctypes
import faulthandler
import gc
import json
import os
import shutil
import signal
import sys
import tempfile
import threading
import traceback
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from orchestrator.campaign.stale_folders import owned_folder, remove_stale

RUN_PREFIX = "excosim-run-"

_PR_SET_PDEATHSIG = 1
_CHILD_FOLDER: list[Path] = []  # in a supervised child: the folder its outcome goes to
_FORWARDED = (signal.SIGINT, signal.SIGTERM)


def available() -> bool:
    """Whether a campaign can run in a supervised child process here (Linux)."""
    return sys.platform.startswith("linux") and hasattr(os, "fork")


@dataclass(frozen=True)
class ChildDied:
    """The child ended without handing its outcome back. message: one line, the cause (also
    the log's end record when it could be closed); periods: the whole periods its log keeps
    (None: no log of the run could be closed); log_note: why the log was not closed ("" when
    it was)."""

    message: str
    periods: int | None
    log_note: str = ""


def supervised(body: Callable[[], Any], log_path: Path, period_offset: int = 0,
               release: Callable[[], None] | None = None) -> Any | ChildDied:
    """body() in a child process; its return value (JSON-able) when it returns, else ChildDied.
    log_path: the run log the child writes (closed here if the child dies before closing it);
    period_offset: periods the log held before the child started (a resumed run), for the
    period named in the message when the log cannot be read; release: called once the child
    has ended, before the log is looked at (e.g. to drop a lock the child inherited)."""
    remove_stale(RUN_PREFIX)  # what earlier runs killed by SIGKILL left behind
    folder = owned_folder(RUN_PREFIX)
    try:
        (folder / "tmp").mkdir()
        sys.stdout.flush()
        sys.stderr.flush()
        ctypes.CDLL(None).fflush(None)  # C stdio buffers, or the child would write them again
        parent, child = os.getpid(), [0]
        previous = {signum: signal.signal(signum, _forward_to(child)) for signum in _FORWARDED}
        gc.freeze()  # the child's collector then leaves the parent's objects (and pages) be
        try:
            pid = os.fork()
            if pid == 0:
                _child(body, folder, previous, parent)  # never returns
            child[0] = pid
            _, status = os.waitpid(pid, 0)  # PEP 475: a forwarded signal does not end the wait
        finally:
            gc.unfreeze()
            for signum, handler in previous.items():
                signal.signal(signum, handler)
        if release is not None:
            release()
        try:
            return json.loads((folder / "outcome.json").read_text())
        except (OSError, ValueError):  # none handed back (or half of one): the child died
            return _died(status, folder / "crash.txt", log_path, period_offset)
    finally:
        shutil.rmtree(folder, ignore_errors=True)


def _forward_to(child: list[int]) -> Callable[[int, Any], None]:
    """A handler that passes the signal on to the child. The child shares the terminal's
    process group, so a Ctrl-C at the terminal reaches it twice (from the terminal and from
    here): it acts on the first (_interrupt_once)."""
    def forward(signum: int, frame: Any) -> None:
        if child[0] > 0:
            try:
                os.kill(child[0], signum)
            except ProcessLookupError:
                pass
    return forward


def _interrupt_once(signum: int, frame: Any) -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the clean-up runs once, to its end
    raise KeyboardInterrupt


def _child(body: Callable[[], Any], folder: Path, handlers: dict, parent: int) -> None:
    code = 1
    try:
        for signum, handler in handlers.items():
            signal.signal(signum, handler)
        if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
            signal.signal(signal.SIGINT, _interrupt_once)
        _die_with(parent)
        tempfile.tempdir = os.environ["TMPDIR"] = str(folder / "tmp")
        crash = open(folder / "crash.txt", "w")  # noqa: SIM115 (open until the process ends)
        faulthandler.enable(crash, all_threads=False)
        _note_exit_calls(crash)
        _CHILD_FOLDER.append(folder)
        _hand_back(folder, body())
        code = 0
    except BaseException:  # a bug of ours: said as Python says it, the parent closes the log
        traceback.print_exc()
    finally:
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)


def end_child(outcome: Any) -> None:
    """In a supervised child (where the main thread cannot return, e.g. stuck in an FMU
    step), hand `outcome` back as body's return value and end the process; elsewhere return."""
    if _CHILD_FOLDER:
        _hand_back(_CHILD_FOLDER[0], outcome)
        os._exit(0)


def _hand_back(folder: Path, outcome: Any) -> None:
    sys.stdout.flush()
    sys.stderr.flush()
    # The watchdog's thread and the main thread may both hand back: each its own part file.
    written = folder / f"outcome.{threading.get_ident()}.part"
    written.write_text(json.dumps(outcome))
    written.replace(folder / "outcome.json")


def _die_with(parent: int) -> None:
    """Have the kernel kill this child when `parent` (the pid before the fork) dies."""
    ctypes.CDLL(None).prctl(_PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
    if os.getppid() != parent:  # it died before the request was in place
        os._exit(1)


# Signals a process raises on itself in native code (a bad access, abort(), a trap).
_RAISED_SIGNALS = {signal.SIGSEGV, signal.SIGBUS, signal.SIGABRT, signal.SIGFPE, signal.SIGILL}
_EXIT_NOTE = "excosim exit: "  # a line of the crash file the exit handler wrote
_EXIT_HANDLERS: list = []  # the C atexit handler of this process, kept alive


def _note_exit_calls(crash) -> None:
    """A C atexit handler: an `exit()` called by native code (the child itself ends with
    os._exit, which runs none) writes which FMU call made it into the crash file."""
    from orchestrator.campaign.watchdog import stuck_call

    def noted(_: Any) -> None:
        frame, where = sys._getframe(1), "exit() was called outside any FMU call"
        while frame is not None:
            call = stuck_call(frame)
            if call is not None:
                where = f"FMU {call[1]} called exit() in {call[2]}"
                break
            frame = frame.f_back
        crash.write(f"{_EXIT_NOTE}{where}\n")
        crash.flush()

    handler = ctypes.CFUNCTYPE(None, ctypes.c_void_p)(noted)
    _EXIT_HANDLERS.append(handler)
    # atexit() itself is not exported by glibc (a static wrapper of this, the C++ ABI's call)
    ctypes.CDLL(None).__cxa_atexit(handler, None, None)


def _died(status: int, crash: Path, log_path: Path, period_offset: int) -> ChildDied:
    from fmus.runs import STEP_NAME
    from orchestrator.plants.native.board import stepping_after_death
    from orchestrator.runlog.reader import RunLogError
    from orchestrator.runlog.resume import close_unfinished

    code = os.waitstatus_to_exitcode(status)
    if code < 0:
        try:
            name = f", {signal.Signals(-code).name}"
        except ValueError:  # a real-time signal has no name
            name = ""
        how = f"died (signal {-code}{name})"
    else:
        how = f"ended (exit status {code})"
    try:
        dump = crash.read_text(errors="replace")
    except OSError:
        dump = ""
    where = ""
    for line in dump.splitlines():
        if line.startswith(_EXIT_NOTE):
            where = f": {line.removeprefix(_EXIT_NOTE)}"
            break
        step = STEP_NAME.search(line)
        if step is not None:
            where = f" in the step of FMU {step['label']}"
            break
        if line.rstrip().endswith(" in __init__") and "fmus/runs.py" in line:
            where = " while an FMU was loaded and initialized"
            break
    # The step loop in C leaves no frame per FMU step: its board names the FMU, for a signal
    # the process raised itself (a kill from outside, e.g. SIGKILL, would blame the FMU).
    if not where and -code in _RAISED_SIGNALS:
        stepping = stepping_after_death(crash.parent / "tmp")
        if stepping is not None:
            where = f" in the step of FMU {stepping[1]}"
    try:
        from orchestrator.runlog.reader import read_run

        run = read_run(log_path)
        done = len(run.periods)
        if run.finished:  # e.g. a crash while the plant was closed, after the end record
            return ChildDied(f"the run's process {how}{where} after its log was closed "
                             f"(termination {run.termination})", done)
    except (OSError, RunLogError):
        done = period_offset
    message = f"period {done + 1}: the run's process {how}{where}"
    try:
        kept = close_unfinished(log_path, message)
    except (OSError, RunLogError, ValueError) as error:
        return ChildDied(message, None, f"the log could not be closed: {error}")
    return ChildDied(message, done if kept is None else kept)
