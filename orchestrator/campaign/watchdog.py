"""A watchdog on FMU steps that costs the step loop nothing.

An FMU step is native code: Python cannot interrupt it, and one that never returns hangs the run
with no word. The watchdog is a daemon thread that looks at the main thread's innermost Python
frame every `poll_s` (sys._current_frames): while an FMU steps, that frame is a FastSlave's step
function (fmus.runs.STEP_CODES), or the step loop in C, whose board names the FMU it is
stepping (orchestrator.plants.native.board); ctypes releases the GIL during the call, so the
thread runs. A
step is identified by its instance and its start time `t` (each instance's time only grows), so
the same (instance, t) seen for `timeout_s` is one step that did not return. The loading and
initialization of an instance (FastSlave's constructor: dlopen, fmi2Instantiate, the
initialization mode) are watched the same way, identified by a serial number per construction.
Nothing is added to the step loop itself: no counter, no clock read, no lock; the thread takes
the GIL for some microseconds per poll.

What then: the stuck call cannot be undone, so the owner decides (`on_hang(message)`, called in
the watchdog thread): the campaign writes the log's end record (the main thread is inside the
plant's period, never inside the log) and hands over to its caller; `excosim run` then prints
the line and ends the process with exit status 1 (os._exit: the stuck thread never returns).
"""

from __future__ import annotations

import sys
import threading
import time
from collections.abc import Callable
from types import FrameType


def stuck_step(frame: FrameType | None) -> tuple[int, float, str] | None:
    """(id of the instance, step start time t (s), "instance (model)") when `frame` is an FMU
    step (a FastSlave's step function, fmus.runs.STEP_CODES) or the step loop in C while it
    steps an FMU (its board: orchestrator.plants.native.board), else None."""
    from fmus.runs import STEP_CODES
    from orchestrator.plants.native.board import stepping_in

    if frame is None or frame.f_code not in STEP_CODES:
        return stepping_in(frame)
    local = frame.f_locals  # the main thread is in C with the GIL released: a stable snapshot
    component, t, label = local.get("component"), local.get("t"), local.get("label")
    if component is None or not isinstance(t, int | float):
        return None
    return id(component), float(t), str(label)


def stuck_call(frame: FrameType | None) -> tuple[tuple, str, str] | None:
    """(key, "instance (model)", which call) for the FMU call the main thread's innermost
    frame `frame` is in: a step ("its step at t = ... s"; key: instance and step time) or the
    loading and initialization of an instance ("its instantiation and initialization", inside
    FastSlave.__init__, whichever of fmpy's functions is innermost; key: that construction's
    serial number); None otherwise. The same key seen twice is the same call."""
    step = stuck_step(frame)
    if step is not None:
        return step[:2], step[2], f"its step at t = {step[1]:.6g} s"
    from fmus.runs import FastSlave

    constructor = FastSlave.__init__.__code__
    for _ in range(32):  # fmpy's calls nest a few frames deep
        if frame is None:
            return None
        if frame.f_code is constructor:
            making = getattr(frame.f_locals.get("self"), "making", None)
            if making is None:  # still reading the model description (pure Python)
                return None
            label, serial = making
            return ("init", serial), label, "its instantiation and initialization"
        frame = frame.f_back
    return None


class StepWatchdog:
    """Calls `on_hang(message)` once when one FMU step has not returned for `timeout_s`."""

    def __init__(self, timeout_s: float, on_hang: Callable[[str], None],
                 poll_s: float | None = None) -> None:
        if not timeout_s > 0.0:
            raise ValueError(f"step timeout must be > 0 s, got {timeout_s!r}")
        self.timeout_s = float(timeout_s)
        self.poll_s = float(poll_s) if poll_s is not None else min(1.0, self.timeout_s / 4.0)
        self._on_hang = on_hang
        self._main = threading.main_thread().ident
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._watch, name="excosim-step-watchdog",
                                        daemon=True)

    def __enter__(self) -> StepWatchdog:
        self._thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self._stop.set()

    def _watch(self) -> None:
        calls = SameCall(self.timeout_s)
        while not self._stop.wait(self.poll_s):
            call = stuck_call(sys._current_frames().get(self._main))
            if calls.stuck(None if call is None else call[0], time.monotonic()) \
                    and not self._stop.is_set():
                self._on_hang(f"FMU {call[1]} did not return from {call[2]} within "
                              f"{self.timeout_s:g} s")
                return


class SameCall:
    """The watchdog's judgement, apart from its thread and clock: fed the key of the call the
    main thread is in at each poll (None: no FMU call) and the time (s), says when one key has
    been seen for timeout_s."""

    def __init__(self, timeout_s: float) -> None:
        self.timeout_s = timeout_s
        self._seen, self._since = None, 0.0

    def stuck(self, key, now_s: float) -> bool:
        """Whether `key`, seen now, has been the main thread's call for timeout_s."""
        if key is None or key != self._seen:
            self._seen, self._since = key, now_s
            return False
        return now_s - self._since >= self.timeout_s
