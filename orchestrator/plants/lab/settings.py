"""Settings of the lab link (bus, rates, timeouts, time scale) and of the emulator's faults.

Every duration is machine time in s: the time of the excavator and its controller. The time
scale maps it to wall time, wall = machine / time_scale (1: real time, for hardware; above 1 an
emulated run goes faster, every rate with it; timeouts: below). The defaults and why:

    stream_rate_hz 100       the reference stream (10 ms): the lab trajectories move at most
                             about 33 deg/s, so a frame lost costs 0.3 deg of extrapolation
    command_timeout_s 0.05   the device holds after 50 ms without a setpoint while streaming
                             (J1939-style command timeout: 5 cycles; a PC master on an ordinary
                             OS misses a few ms now and then, not 50)
    feedback_timeout_s 0.1   the master stops when the newest joint feedback is older; longer
                             than the command timeout, so that when setpoints stop reaching the
                             device, the device holds first (and says why)
    heartbeat_period_s 0.1   both heartbeats (CANopen producer time)
    heartbeat_timeout_s 0.3  heartbeat consumer time, above the producer's as CANopen requires
                             (three missed heartbeats); on the device it is the motion lease
    reply_timeout_s 0.5      a command's acknowledgement (DeviceStatus.AckSeq)
    load_cell_timeout_s 2.0  a fresh, valid load-cell reading after PERIOD_END
    connect_timeout_s 10.0   the device's first heartbeat

Timeouts scale with the time scale (`timeout`): above 1, each is the time scale times longer in
machine time, so that in wall time it stays what it is in real time. A timeout guards against
the link's failures, and how long a thread of an ordinary OS may be held up (by the scheduler,
a loaded machine, the interpreter lock the emulated device and the master share) is wall time:
at a time scale of 20 the command timeout would otherwise be 2.5 ms of wall time, which a
loaded machine misses in a run without any fault. Rates and periods (the stream, the
heartbeats) keep their machine values, and so do the frame counts the 4-bit counter needs: the
stream's lead over the feedback and the lag that stops it (driver.max_lead_cycles,
link.DeviceView) are counted from the timeouts as set.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

# The 4-bit rolling counter aliases a gap of 16 frames to none: both stream timeouts must trip
# well before (docs/can-protocol.md, "Feedback").
MAX_TIMEOUT_FRAMES = 12


@dataclass(frozen=True)
class FaultPlan:
    """Faults the emulated device injects (docs/can-protocol.md, "Fault injection"). Times are
    campaign time (machine s since the device accepted the first PERIOD_START); None: never.

    drop_fraction: share of setpoint cycles (all three Ref frames of a Counter) the device loses
        on receive, drawn from a generator seeded with `seed`.
    drop_from_s: from then, the device receives no setpoint at all (a broken master-to-device
        path: the device's command timeout).
    feedback_delay_s: from feedback_delay_from_s on, every FbPosition/FbPressure* frame leaves
        this late (s).
    heartbeat_stop_s: the device's heartbeat stops (and stays stopped).
    corrupt_from_s: from then, every frame the device sends has a wrong checksum.
    estop_at_s: the device's emergency-stop button is pressed.
    freeze_load_cell_at_s: the load cell's converter stops delivering samples.
    """

    drop_fraction: float = 0.0
    seed: int = 0
    drop_from_s: float | None = None
    feedback_delay_s: float = 0.0
    feedback_delay_from_s: float = 0.0
    heartbeat_stop_s: float | None = None
    corrupt_from_s: float | None = None
    estop_at_s: float | None = None
    freeze_load_cell_at_s: float | None = None

    def __post_init__(self) -> None:
        if not 0.0 <= self.drop_fraction < 1.0:
            raise ValueError(f"drop_fraction must be in [0, 1), got {self.drop_fraction!r}")
        if not (math.isfinite(self.feedback_delay_s) and self.feedback_delay_s >= 0.0):
            raise ValueError(f"feedback_delay_s must be >= 0, got {self.feedback_delay_s!r}")

    @property
    def any(self) -> bool:
        """Whether any fault is planned."""
        return self != FaultPlan(seed=self.seed)


@dataclass(frozen=True)
class LabSettings:
    """The lab plant's link (module docstring for the defaults). interface, channel, bitrate:
    python-can's `can.Bus(interface=..., channel=..., bitrate=...)`. start_tolerance_rad: how far
    (rad, per joint) a period's first setpoint may be from the measured arm. emulate: run the
    emulated device in this process on the `virtual` interface. faults: the emulator's."""

    interface: str = "virtual"
    channel: str = "excosim-lab"
    bitrate: int = 500_000
    stream_rate_hz: float = 100.0
    command_timeout_s: float = 0.05
    feedback_timeout_s: float = 0.1
    heartbeat_period_s: float = 0.1
    heartbeat_timeout_s: float = 0.3
    reply_timeout_s: float = 0.5
    load_cell_timeout_s: float = 2.0
    connect_timeout_s: float = 10.0
    start_tolerance_rad: float = math.radians(2.0)
    time_scale: float = 1.0
    emulate: bool = False
    faults: FaultPlan = field(default_factory=FaultPlan)

    def __post_init__(self) -> None:
        positive = ("stream_rate_hz", "command_timeout_s", "feedback_timeout_s",
                    "heartbeat_period_s", "heartbeat_timeout_s", "reply_timeout_s",
                    "load_cell_timeout_s", "connect_timeout_s", "start_tolerance_rad",
                    "time_scale")
        for name in positive:
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"LabSettings.{name} must be > 0, got {value!r}")
        if self.heartbeat_timeout_s <= self.heartbeat_period_s:
            raise ValueError("LabSettings.heartbeat_timeout_s must exceed heartbeat_period_s")
        for name in ("command_timeout_s", "feedback_timeout_s"):
            frames = getattr(self, name) * self.stream_rate_hz
            if not 2.0 - 1e-9 <= frames <= MAX_TIMEOUT_FRAMES + 1e-9:
                raise ValueError(f"LabSettings.{name} is {frames:.3g} frame periods; it must be "
                                 f"2 to {MAX_TIMEOUT_FRAMES} (the 4-bit counter aliases at 16)")
        if self.command_timeout_s >= self.feedback_timeout_s:
            raise ValueError("LabSettings.command_timeout_s must be below feedback_timeout_s")

    @property
    def frame_period_s(self) -> float:
        """Machine time between two stream cycles (s)."""
        return 1.0 / self.stream_rate_hz

    def wall(self, machine_s: float) -> float:
        """Wall-clock seconds of `machine_s` machine seconds."""
        return machine_s / self.time_scale

    def timeout(self, name: str) -> float:
        """The timeout `name` (e.g. "command_timeout_s") in machine s as the link applies it:
        as set, times the time scale above 1 (module docstring)."""
        if not name.endswith("_timeout_s"):
            raise ValueError(f"{name!r} is not a timeout of LabSettings")
        return getattr(self, name) * max(1.0, self.time_scale)
