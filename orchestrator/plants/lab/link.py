"""The master's view of the device, built from the frames it receives: status, heartbeat, joint
feedback of the current period, load cell, and the receive statistics.

Feedback frames of a period carry the 4-bit Counter of the setpoint their cycle executed; the
view maps them back to the cycle index from the last cycle sent (`sent_index`): the newest cycle
with that counter. That is unambiguous while the device lags fewer than 16 cycles, which the
feedback timeout (at most 12 frame periods, settings) guarantees before anything aliases.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from orchestrator.plants.lab.protocol import Decoded, Fault, State
from orchestrator.plants.lab.settings import LabSettings


@dataclass
class PeriodFeedback:
    """What came back during one period, by cycle index: joint angles (3,) rad, chamber
    pressures (3,) Pa, the machine time each angle frame arrived."""

    joints: dict[int, tuple] = field(default_factory=dict)
    p_a: dict[int, tuple] = field(default_factory=dict)
    p_b: dict[int, tuple] = field(default_factory=dict)
    arrived_at: dict[int, float] = field(default_factory=dict)
    newest: int = -1  # highest cycle index with angle feedback


class DeviceView:
    """Frames in (`handle`), the device's state out (`problem`, attributes). Times: machine s."""

    def __init__(self, settings: LabSettings) -> None:
        self.settings = settings
        self.status: dict | None = None
        self.heartbeat: dict | None = None
        self.heartbeat_at: float | None = None
        self.load_cell: dict | None = None
        self.pose_rad: tuple | None = None
        self.pose_at: float | None = None
        self.feedback: PeriodFeedback | None = None  # set while a period streams
        self.sent_index = -1
        self.frames_received = self.bad_checksums = 0
        self._period_started_at = 0.0

    def start_period(self, now: float) -> None:
        """A period begins: feedback is counted from here (`now`: its PERIOD_START ack)."""
        self.feedback, self.sent_index = PeriodFeedback(), -1
        self._period_started_at = now

    def handle(self, frame: Decoded | None, now: float) -> None:
        """Take in one received frame (None: a frame the protocol does not know)."""
        if frame is None:
            return
        self.frames_received += 1
        if not frame.checksum_ok:
            self.bad_checksums += 1
            return
        name, signals = frame.name, frame.signals
        if name == "DeviceStatus":
            self.status = signals
        elif name == "HeartbeatDevice":
            self.heartbeat, self.heartbeat_at = signals, now
        elif name == "LoadCell":
            self.load_cell = signals
        elif name == "FbPosition":
            self.pose_rad, self.pose_at = frame.joints_rad(), now
            if signals["Streaming"]:
                index = self._cycle(signals)
                if index is not None:
                    feedback = self.feedback
                    feedback.joints[index], feedback.arrived_at[index] = self.pose_rad, now
                    feedback.newest = max(feedback.newest, index)
        elif name in ("FbPressureA", "FbPressureB"):
            index = self._cycle(signals)
            if index is not None:
                table = self.feedback.p_a if name == "FbPressureA" else self.feedback.p_b
                table[index] = frame.joints_pa()

    def _cycle(self, signals: dict) -> int | None:
        if self.feedback is None or self.sent_index < 0:
            return None
        index = self.sent_index - (self.sent_index - int(signals["Counter"])) % 16
        return index if index >= 0 else None

    @property
    def state(self) -> State | None:
        return None if self.status is None else State(int(self.status["State"]))

    def problem(self, now: float, streaming: bool) -> str | None:
        """Why the master must stop now, or None: an emergency stop or a fault reported by the
        device, or the earliest expired of: its heartbeat older than the consumer time,
        (streaming) joint feedback older than the feedback timeout (by arrival, or by how many
        cycles it lags the stream)."""
        status = self.status
        if status is not None and (status["EStop"] or int(status["State"]) == State.ESTOP):
            return f"emergency stop at the device ({_fault(status)})"
        if status is not None and (int(status["Fault"]) or int(status["State"]) == State.HOLD):
            return f"the device holds: fault {_fault(status)}"
        expired = [(at, why) for at, why in self._deadlines(streaming) if now > at]
        return min(expired)[1](now) if expired else None

    def next_deadline(self, streaming: bool) -> float:
        """The machine time at which `problem` could next report a timeout (inf: none)."""
        return min((at for at, _ in self._deadlines(streaming)), default=float("inf"))

    def _deadlines(self, streaming: bool) -> list:
        """(expiry time, message(now)) of the heartbeat and (streaming) feedback timeouts."""
        settings = self.settings
        hb = settings.timeout("heartbeat_timeout_s")
        if self.heartbeat_at is None:
            out = [(-float("inf"), lambda now: f"device heartbeat lost (none received; "
                    f"consumer time {hb:g} s)")]
        else:
            out = [(self.heartbeat_at + hb, lambda now: f"device heartbeat lost (last "
                    f"{now - self.heartbeat_at:.3f} s ago; consumer time {hb:g} s)")]
        if streaming and self.feedback is not None:
            feedback, timeout = self.feedback, settings.timeout("feedback_timeout_s")
            last = feedback.arrived_at.get(feedback.newest, self._period_started_at)
            lag = (self.sent_index - feedback.newest) * settings.frame_period_s \
                if feedback.newest >= 0 else 0.0
            # Late by arrival at last + timeout; behind the stream once the lag exceeds the
            # timeout as set (frames: the 4-bit counter's bound, not scaled).
            at = last + timeout if lag <= settings.feedback_timeout_s else -float("inf")
            out.append((at, lambda now: f"joint feedback {max(now - last, lag):.3f} s old "
                        f"(timeout {timeout:g} s): newest for cycle {feedback.newest} of "
                        f"{self.sent_index} sent"))
        return out

    def own_stop(self) -> str | None:
        """The stop the device reports of its own (an emergency stop, or a hold for a fault of
        its own), None for none or for the hold the master commanded (MASTER_HOLD)."""
        status = self.status
        if status is None or not (status["EStop"] or int(status["State"]) == State.ESTOP
                                  or int(status["Fault"]) not in (Fault.NONE, Fault.MASTER_HOLD)):
            return None
        return self.problem(-float("inf"), False)

    def device_lost_setpoints(self) -> int:
        """Setpoint cycles the device reported missing in this period (HeartbeatDevice)."""
        return 0 if self.heartbeat is None else int(self.heartbeat["RxLost"])

    def rows(self) -> np.ndarray:
        """Sorted cycle indices with angle feedback in this period."""
        return np.array(sorted(self.feedback.joints), dtype=int) if self.feedback else \
            np.zeros(0, dtype=int)


def _fault(status: dict) -> str:
    try:
        fault = Fault(int(status["Fault"])).name
    except ValueError:
        fault = f"code {int(status['Fault'])}"
    try:
        state = State(int(status["State"])).name
    except ValueError:
        state = f"state {int(status['State'])}"
    return f"{fault}, state {state}"
