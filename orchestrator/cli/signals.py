"""SIGTERM handled like Ctrl-C: inside `terminate_like_ctrl_c()`, SIGTERM raises Terminated in
the main thread, where Ctrl-C raises KeyboardInterrupt, so the same clean-up runs (the campaign
closes its plant, whose FMU folders are removed, and writes the log's end record).

Once the first SIGTERM has arrived, further ones are ignored until the block ends: the clean-up
is short (closing files and FMU instances) and must not be cut in half; SIGKILL still ends the
process at once. Exit status: 143 (128 + 15, what a shell reports for a process that SIGTERM
ended), against 130 (128 + 2) for Ctrl-C, so a caller can tell a stop by its supervisor (a
timeout, `docker stop`, a CI runner cancelling the job) from one at the keyboard.

The `excosim` process says one line for a stop at any moment, in three phases:

- starting (`at_start`, from the first import of orchestrator.cli while the process is the
  `excosim` program, until main() runs): Python imports the command line's modules; nothing
  has been done, so the handler prints `excosim: interrupted while starting; nothing was done`
  (or `terminated (SIGTERM) ...`) and ends the process at once (130, 143). Before that (the
  interpreter's own start, a few tens of ms) a signal still ends the process silently.
- in a command (`in_command`, main()): Ctrl-C raises KeyboardInterrupt and SIGTERM Terminated
  anywhere, which the commands and main() turn into their one line (`stopped_by` finds the
  stop under an exception it caused, e.g. an ImportError of a module whose loading it cut).
- exiting (`at_exit`, once the command has returned, while the interpreter shuts down): the
  command has said what it did; a stop then prints `excosim: terminated (SIGTERM) as it
  exited; the command had ended` and ends the process at once.
"""

from __future__ import annotations

import atexit
import os
import signal
import sys
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

TERMINATED_EXIT = 128 + signal.SIGTERM  # 143
INTERRUPTED_EXIT = 128 + signal.SIGINT  # 130
_STOPS = {signal.SIGINT: "interrupted", signal.SIGTERM: "terminated (SIGTERM)"}


class Terminated(BaseException):
    """SIGTERM arrived (a BaseException like KeyboardInterrupt: `except Exception` passes it
    on)."""


def _raise_terminated(signum, frame) -> None:
    signal.signal(signal.SIGTERM, signal.SIG_IGN)  # the clean-up runs once, to its end
    raise Terminated()


@contextmanager
def terminate_like_ctrl_c() -> Iterator[None]:
    """Within the block, SIGTERM raises Terminated (main thread only; elsewhere a no-op)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGTERM, _raise_terminated)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def stop_line(signum: int) -> str:
    """"interrupted" (SIGINT) or "terminated (SIGTERM)"."""
    return _STOPS[signum]


def stopped_by(error: BaseException) -> int | None:
    """SIGINT or SIGTERM when `error` is the stop (KeyboardInterrupt, Terminated) or was caused
    by it (e.g. "ImportError: initialization failed" of an extension whose loading a Ctrl-C
    cut), else None."""
    seen = set()
    while error is not None and id(error) not in seen:
        seen.add(id(error))
        if isinstance(error, KeyboardInterrupt):
            return signal.SIGINT
        if isinstance(error, Terminated):
            return signal.SIGTERM
        error = error.__cause__ or error.__context__
    return None


def is_program() -> bool:
    """Whether this process is the `excosim` program (its console script, or `python -m
    orchestrator.cli.app`), not a program that imports the command line (a test, a notebook)
    nor a process that multiprocessing started for it (a sweep's worker: spawned, it is given
    the program's argv and imports its main module)."""
    processes = sys.modules.get("multiprocessing")
    if processes is not None and processes.parent_process() is not None:
        return False
    if sys.argv and Path(sys.argv[0]).name == "excosim":
        return True
    arguments = list(getattr(sys, "orig_argv", ()))
    return any(a == "-m" and b == "orchestrator.cli.app"
               for a, b in zip(arguments, arguments[1:], strict=False))


_PROGRAM: list[int | None] = []  # [exit status once main() is done] when this is the program


def _exit_now(when: str):
    def handler(signum: int, frame) -> None:
        _flush()
        os.write(2, f"excosim: {_STOPS[signum]} {when}\n".encode())
        os._exit(128 + signum)
    return handler


def _flush() -> None:
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except Exception:  # noqa: BLE001, S110 - a closed or broken stream: nothing to keep
            pass
    try:
        import ctypes

        ctypes.CDLL(None).fflush(None)  # what native code printed through C stdio
    except (OSError, AttributeError):
        pass


def _install(sigint, sigterm) -> None:
    if not _PROGRAM or threading.current_thread() is not threading.main_thread():
        return
    if signal.getsignal(signal.SIGINT) is not signal.SIG_IGN:  # ignored: a background job's
        signal.signal(signal.SIGINT, sigint)
    signal.signal(signal.SIGTERM, sigterm)


def at_start() -> None:
    """The starting phase (module docstring), in the `excosim` program only: its handlers, and
    the end of the process once main() is done (_leave)."""
    if _PROGRAM or not is_program():
        return
    _PROGRAM.append(None)
    atexit.register(_leave)  # the first registered: the last to run
    handler = _exit_now("while starting; nothing was done")
    _install(handler, handler)


def in_command() -> None:
    """The command phase's handlers: KeyboardInterrupt and Terminated (module docstring)."""
    _install(signal.default_int_handler, _raise_terminated)


def at_exit(status: int) -> None:
    """The exiting phase (module docstring): main() is done and ends with `status`."""
    if _PROGRAM:
        _PROGRAM[0] = status
        handler = _exit_now("as it exited; the command had ended")
        _install(handler, handler)


def _leave() -> None:
    """The last exit function: once the others have run, the process ends with main()'s
    status, without the interpreter's tear-down (collecting and freeing every module, a few
    hundred ms after a run, during which Python no longer handles signals: a SIGTERM then
    ended the process silently)."""
    if _PROGRAM and _PROGRAM[0] is not None:
        _flush()
        os._exit(_PROGRAM[0])
