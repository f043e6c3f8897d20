"""A run log that is being written is locked: its writer holds an exclusive advisory lock
(flock) on the open file until it closes it or its process ends, however it ends (the system
drops the lock with the process). `excosim run --resume` takes the same lock on the log it
continues (held until the continued log has replaced it), `-f` does not write over a locked
log, and the closing of a dead run's log checks it: a run that is still digging is never
continued, overwritten or closed by another process.
POSIX only; elsewhere nothing is locked and nothing is found locked.
"""

from __future__ import annotations

from pathlib import Path
from typing import BinaryIO

try:
    import fcntl
except ImportError:  # Windows
    fcntl = None


def lock_for_writing(stream: BinaryIO) -> None:
    """Take the writer's lock on the open log file `stream` (a file of ours, just made, that
    nobody else holds)."""
    if fcntl is not None:
        try:
            fcntl.flock(stream.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:  # a file system without locks: the log is written all the same
            pass


def hold(path: str | Path) -> BinaryIO | None:
    """The open file `path` with the writer's lock taken (closing it drops the lock); None
    where nothing is locked. BlockingIOError when another process holds it."""
    if fcntl is None:
        return None
    stream = open(path, "rb")  # noqa: SIM115 (the caller holds it, and the lock)
    try:
        fcntl.flock(stream.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        stream.close()
        raise
    except OSError:  # a file system without locks
        pass
    return stream


def being_written(path: str | Path) -> bool:
    """Whether a live process holds the writer's lock on the run log at `path`."""
    if fcntl is None:
        return False
    try:
        with open(path, "rb") as stream:
            try:
                fcntl.flock(stream.fileno(), fcntl.LOCK_SH | fcntl.LOCK_NB)
            except BlockingIOError:
                return True
            except OSError:
                return False
            fcntl.flock(stream.fileno(), fcntl.LOCK_UN)
    except OSError:
        return False
    return False
