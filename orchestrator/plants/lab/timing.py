"""Machine time for the lab link: a monotonic clock that runs `time_scale` times faster than
the wall clock (1: real time), and a heartbeat producer thread on it.

Both sides of the link (driver and emulated device) keep their rates and timeouts in machine
seconds and sleep in wall seconds (machine / time_scale), so an emulated run at a time scale of
4 is the same run, four times faster.
"""

from __future__ import annotations

import gc
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager

import can


class ScaledClock:
    """Machine time in s since construction: (wall time elapsed) x time_scale."""

    def __init__(self, time_scale: float = 1.0) -> None:
        if not time_scale > 0.0:
            raise ValueError(f"time_scale must be > 0, got {time_scale!r}")
        self.time_scale = float(time_scale)
        self._origin = time.perf_counter()

    def now(self) -> float:
        """Machine time (s)."""
        return (time.perf_counter() - self._origin) * self.time_scale

    def wall(self, machine_s: float) -> float:
        """Wall seconds of a machine duration (s), never negative."""
        return max(machine_s, 0.0) / self.time_scale


class Heartbeat:
    """Sends the frame `make(counter)` every `period_s` machine seconds from its own thread until
    `stop()` (which joins it), holding `lock` while it sends. The first frame goes at once. A
    send that fails (bus closed or full) is counted in `failures`, not raised: the receiver's
    consumer timeout reports the loss.
    """

    def __init__(self, bus: can.BusABC, make: Callable[[int], can.Message], period_s: float,
                 clock: ScaledClock, name: str = "heartbeat",
                 lock: threading.Lock | None = None) -> None:
        self._bus, self._make, self._period_s, self._clock = bus, make, period_s, clock
        # Shared with the owner's own sends: not every python-can interface sends thread-safely.
        self._lock = lock if lock is not None else threading.Lock()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        self.sent = 0
        self.failures = 0

    def start(self) -> Heartbeat:
        self._thread.start()
        return self

    def _run(self) -> None:
        deadline = self._clock.now()
        while not self._stop.is_set():
            try:
                frame = self._make(self.sent % 16)
                with self._lock:
                    self._bus.send(frame)
                self.sent += 1
            except (can.CanError, ValueError, OSError):
                self.failures += 1
            deadline += self._period_s
            # Absolute deadlines: the rate does not drift with the send time.
            self._stop.wait(self._clock.wall(deadline - self._clock.now()))

    def stop(self) -> None:
        """Stop sending and join the thread (safe twice, and before start)."""
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join()


@contextmanager
def collector_paused() -> Iterator[None]:
    """The cyclic garbage collector off inside, as it was outside: a full collection of a large
    heap stops every thread of the process (measured: 120-145 ms in the test suite's process),
    longer than the feedback timeout of a stream. Reference counting still frees what a stream
    allocates; the cycles left wait for the next collection after the block."""
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if enabled:
            gc.enable()
