"""SIGTERM handled like Ctrl-C: inside `terminate_like_ctrl_c()`, SIGTERM raises Terminated in
the main thread, where Ctrl-C raises KeyboardInterrupt, so the same clean-up runs (the campaign
closes its plant, whose FMU folders are removed, and writes the log's end record).

Once the first SIGTERM has arrived, further ones are ignored until the block ends: the clean-up
is short (closing files and FMU instances) and must not be cut in half; SIGKILL still ends the
process at once. Exit status: 143 (128 + 15, what a shell reports for a process that SIGTERM
ended), against 130 (128 + 2) for Ctrl-C, so a caller can tell a stop by its supervisor (a
timeout, `docker stop`, a CI runner cancelling the job) from one at the keyboard.
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager

TERMINATED_EXIT = 128 + signal.SIGTERM  # 143
INTERRUPTED_EXIT = 128 + signal.SIGINT  # 130


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
