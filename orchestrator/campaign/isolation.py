"""A campaign in a supervised child process: an FMU that crashes (a segfault, `abort()`) or ends
the process (`exit()`) ends the run with its reason in the log's end record, not with the
whole program gone and the log left without one (`excosim run`; sweeps have their own worker
processes, orchestrator.sweep.executors).

`supervised(body, log_path)` forks once the scenario is checked and the log's path is known; the
child runs `body` (the campaign and everything it prints) and hands its outcome back through a
file, the parent waits. When the child ends without handing an outcome back, the parent

- names the cause: the signal, or the exit status of an `exit()`; and the FMU. A fatal signal's
  faulthandler dump names it: each FMU instance's step function carries the instance's name
  (fmus.runs.STEP_NAME); an `exit()` is caught by a C `atexit` handler that reads the step's
  frame as the step watchdog does (orchestrator.campaign.watchdog.stuck_step);
- closes the log (orchestrator.runlog.resume.close_unfinished): its whole periods and the end
  record termination "error" with that reason, so it is indexed, readable by any MCAP reader and
  can be resumed (`excosim run --resume`);
- removes the child's temporary folders (the extracted FMUs): the child's temporary folder is
  one the parent made.

Signals: the child has its own process group, so a Ctrl-C at the terminal reaches the parent
alone, which passes SIGINT and SIGTERM on to the child: the child stops as an unsupervised run
does (orchestrator.cli.signals) and its outcome comes back. The child is killed when the parent
dies (Linux's PR_SET_PDEATHSIG), so SIGKILL on the parent still ends the run at once.

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
import traceback
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

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


def supervised(body: Callable[[], Any], log_path: Path, period_offset: int = 0
               ) -> Any | ChildDied:
    """body() in a child process; its return value (JSON-able) when it returns, else ChildDied.
    log_path: the run log the child writes (closed here if the child dies before closing it);
    period_offset: periods the log held before the child started (a resumed run), for the
    period named in the message when the log cannot be read."""
    folder = Path(tempfile.mkdtemp(prefix="excosim-run-"))
    try:
        (folder / "tmp").mkdir()
        sys.stdout.flush()
        sys.stderr.flush()
        child = [0]
        previous = {signum: signal.signal(signum, _forward_to(child)) for signum in _FORWARDED}
        try:
            gc.freeze()  # the child's collector then leaves the parent's objects (and pages) be
            pid = os.fork()
            if pid == 0:
                _child(body, folder, previous)  # never returns
            gc.unfreeze()
            child[0] = pid
            try:
                os.setpgid(pid, pid)  # also done by the child: whichever comes first
            except OSError:
                pass
            _, status = os.waitpid(pid, 0)  # PEP 475: a forwarded signal does not end the wait
        finally:
            for signum, handler in previous.items():
                signal.signal(signum, handler)
        outcome = folder / "outcome.json"
        if outcome.exists():
            return json.loads(outcome.read_text())
        return _died(status, folder / "crash.txt", log_path, period_offset)
    finally:
        shutil.rmtree(folder, ignore_errors=True)


def _forward_to(child: list[int]) -> Callable[[int, Any], None]:
    def forward(signum: int, frame: Any) -> None:
        if child[0] > 0:
            try:
                os.kill(child[0], signum)
            except ProcessLookupError:
                pass
    return forward


def _child(body: Callable[[], Any], folder: Path, handlers: dict) -> None:
    code = 1
    try:
        for signum, handler in handlers.items():
            signal.signal(signum, handler)
        os.setpgid(0, 0)
        _die_with_parent()
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
    written = folder / "outcome.json.part"
    written.write_text(json.dumps(outcome))
    written.replace(folder / "outcome.json")


def _die_with_parent() -> None:
    libc = ctypes.CDLL(None, use_errno=True)
    parent = os.getppid()
    libc.prctl(_PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
    if os.getppid() != parent:  # the parent died before the request was in place
        os._exit(1)


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
    from orchestrator.runlog.reader import RunLogError
    from orchestrator.runlog.resume import close_unfinished

    code = os.waitstatus_to_exitcode(status)
    how = f"died (signal {-code}, {signal.Signals(-code).name})" if code < 0 else \
        f"ended (exit status {code})"
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
    try:
        from orchestrator.runlog.reader import read_run

        done = len(read_run(log_path).periods)
    except (OSError, RunLogError):
        done = period_offset
    message = f"period {done + 1}: the run's process {how}{where}"
    try:
        kept = close_unfinished(log_path, message)
    except (OSError, RunLogError, ValueError) as error:
        return ChildDied(message, None, f"the log could not be closed: {error}")
    return ChildDied(message, done if kept is None else kept)
