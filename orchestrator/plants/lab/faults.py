"""Fault injection on the emulated device's side of the bus (plan: settings.FaultPlan).

The injector sits between the device state machine and the bus: it decides which received
setpoints are lost, which outgoing frames are late, corrupted or not sent, and when the device's
emergency-stop button and load cell fail. It counts what it did, so that tests compare what the
driver and the device report with what was really injected.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from orchestrator.plants.lab.protocol import Decoded
from orchestrator.plants.lab.settings import FaultPlan

FEEDBACK_FRAMES = frozenset({"FbPosition", "FbPressureA", "FbPressureB"})


@dataclass(frozen=True)
class Outgoing:
    """What happens to one frame the device sends: sent or not, corrupted, delay (machine s)."""

    send: bool = True
    corrupt: bool = False
    delay_s: float = 0.0


class FaultInjector:
    """Applies a FaultPlan. Times are campaign time t (machine s since the device accepted the
    first PERIOD_START), None before that (no fault is due before the campaign starts)."""

    def __init__(self, plan: FaultPlan) -> None:
        self.plan = plan
        self._rng = np.random.default_rng(plan.seed)
        self.dropped_setpoints = 0
        self.corrupted = 0
        self.delayed = 0
        self.heartbeats_suppressed = 0

    @staticmethod
    def _due(at_s: float | None, t: float | None) -> bool:
        return at_s is not None and t is not None and t >= at_s

    def keep_received(self, frame: Decoded, t: float | None) -> bool:
        """Whether the device gets `frame` (a dropped RefPosition loses its whole cycle: the
        velocity and acceleration frames only feed forward the cycle it commits)."""
        if frame.name != "RefPosition":
            return True
        if self._due(self.plan.drop_from_s, t) or (
                self.plan.drop_fraction > 0.0 and self._rng.random() < self.plan.drop_fraction):
            self.dropped_setpoints += 1
            return False
        return True

    def outgoing(self, name: str, t: float | None) -> Outgoing:
        """The fate of frame `name` sent at campaign time t."""
        plan = self.plan
        if name == "HeartbeatDevice" and self._due(plan.heartbeat_stop_s, t):
            self.heartbeats_suppressed += 1
            return Outgoing(send=False)
        corrupt = self._due(plan.corrupt_from_s, t)
        delay = 0.0
        if name in FEEDBACK_FRAMES and plan.feedback_delay_s > 0.0 and t is not None \
                and t >= plan.feedback_delay_from_s:
            delay = plan.feedback_delay_s
            self.delayed += 1
        self.corrupted += corrupt
        return Outgoing(True, corrupt, delay)

    def estop_pressed(self, t: float | None) -> bool:
        """Whether the emergency-stop button is pressed at t (it stays pressed)."""
        return self._due(self.plan.estop_at_s, t)

    def load_cell_frozen(self, t: float | None) -> bool:
        """Whether the load cell's converter has stopped delivering samples at t."""
        return self._due(self.plan.freeze_load_cell_at_s, t)
