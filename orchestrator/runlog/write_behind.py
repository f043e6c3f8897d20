"""A run log's file work on a thread of its own, in order, while the run goes on.

Filling, compressing, checksumming and writing a paper period's chunk (1.3 MB of records)
costs about 1.7 ms, more than putting it in order; rows.c, zstd, zlib's CRC-32 and the file
write release the GIL, so on a second core they overlap the next period's planning instead of
adding to the run's wall time (bench/campaign.py). Robotics loggers do the same (rosbag2
compresses and writes on threads of its own, behind a bounded queue).

`WriteBehind` runs tasks one at a time in the order they were handed in, on one thread
("excosim-log"). The first task that raises stops it: later tasks are dropped, and the next
`submit`, `wait` or `close` raises that error in the caller's thread, so that a full disk is
reported by the run, not lost on a thread nobody watches.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor

THREAD_NAME = "excosim-log"


class WriteBehind:
    """One worker thread that runs tasks in order (see the module's docstring).

    native_id: the worker's thread id (for pinning it, e.g. in bench/campaign.py).
    """

    def __init__(self) -> None:
        # An executor rather than a bare thread: at interpreter exit it finishes the tasks it
        # holds and ends, where a daemon thread would drop them and a plain one hang.
        self._executor = ThreadPoolExecutor(max_workers=1, thread_name_prefix=THREAD_NAME)
        self._failure: BaseException | None = None
        self._last: Future | None = None
        self._closed = False
        self.native_id: int = self._executor.submit(threading.get_native_id).result()

    def _run(self, task: Callable[..., object], args: tuple) -> None:
        if self._failure is not None:
            return
        try:
            task(*args)
        except BaseException as error:  # noqa: BLE001 - handed to the caller's thread
            self._failure = error

    def _check(self) -> None:
        if self._failure is not None:
            raise self._failure

    def submit(self, task: Callable[..., object], *args: object) -> Future:
        """Run task(*args) after every task submitted before it; returns its future (which
        never raises: a failure is raised by the next call of this object instead)."""
        self._check()
        if self._closed:
            raise ValueError("the log's writer thread is closed")
        self._last = self._executor.submit(self._run, task, args)
        return self._last

    def wait(self, until: Future | None = None) -> None:
        """Block until `until` (default: every task submitted so far) has run; raise the first
        task failure, if any."""
        done = until if until is not None else self._last
        if done is not None:
            done.result()
        self._check()

    def close(self, check: bool = True) -> None:
        """Run what is left, end the thread, and (with `check`) raise the first task failure,
        if any. A second call only raises that failure again. A KeyboardInterrupt meanwhile
        is raised once the thread has ended: the file work it holds is short, and whoever
        closes the stream next must find the thread done with it."""
        interrupted = False
        if not self._closed:
            self._closed = True
            # Waited for on a future, not by joining the thread: a join that Ctrl-C
            # interrupts takes the thread for ended in Python 3.11 (bpo-45274's handling).
            last = self._executor.submit(lambda: None)
            while True:
                try:
                    last.result()
                    break
                except KeyboardInterrupt:
                    interrupted = True
            self._executor.shutdown(wait=not interrupted)
        if interrupted:
            raise KeyboardInterrupt
        if check:
            self._check()
