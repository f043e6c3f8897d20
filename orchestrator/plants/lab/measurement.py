"""A lab period's PeriodMeasurement from the master's records: joint feedback by cycle, the
stream it sent, and the bus statistics, as the signals the run log stores.

Rows are the stream cycles whose joint feedback arrived (a cycle whose FbPosition was lost has
no row), at t = i T with the setpoint of cycle i as reference, like the simulated plant's rows
at its communication steps. Signals (SI units):

    <joint>.p_A, <joint>.p_B   chamber pressures (Pa), from FbPressureA/B of the same cycle
                               (a lost pressure frame repeats the previous value)
    bus.frames_sent            frames the master sent in the period up to that cycle
    bus.frames_received        frames it received in the period up to the row's arrival
    bus.feedback_lost          cycles before this one whose feedback never arrived
    bus.setpoints_lost         setpoint cycles the device reported missing (HeartbeatDevice)
    bus.bad_checksums          received frames rejected for their checksum, so far
    bus.send_jitter_s          wall s the cycle's frames left after their deadline
    bus.feedback_latency_s     machine s from sending the cycle to its feedback's arrival
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from orchestrator.plants.lab.link import DeviceView
from orchestrator.plants.lab.safety import Stream
from plant_models.plant import JOINTS, PeriodMeasurement


@dataclass
class CycleLog:
    """The master's per-cycle records of one period (arrays of the stream's length n)."""

    n: int
    sent_at: np.ndarray = field(init=False)
    jitter_s: np.ndarray = field(init=False)
    frames_sent: np.ndarray = field(init=False)
    frames_received: np.ndarray = field(init=False)
    setpoints_lost: np.ndarray = field(init=False)
    bad_checksums: np.ndarray = field(init=False)

    def __post_init__(self) -> None:
        for name in ("sent_at", "jitter_s"):
            setattr(self, name, np.full(self.n, np.nan))
        for name in ("frames_sent", "frames_received", "setpoints_lost", "bad_checksums"):
            setattr(self, name, np.zeros(self.n))

    def sent(self, i: int, at: float, jitter_s: float, frames_sent: int, view: DeviceView,
             received_before: int, bad_before: int) -> None:
        """Cycle i went out at machine time `at`, `jitter_s` wall s late."""
        self.sent_at[i], self.jitter_s[i], self.frames_sent[i] = at, jitter_s, frames_sent
        self.frames_received[i] = view.frames_received - received_before
        self.setpoints_lost[i] = view.device_lost_setpoints()
        self.bad_checksums[i] = view.bad_checksums - bad_before


def period_measurement(stream: Stream, view: DeviceView, log: CycleLog, mass_kg: float
                       ) -> PeriodMeasurement | None:
    """The period as measured (module docstring); None if no feedback arrived at all.
    mass_kg: the load cell's weighing (NaN for a period that ended before it)."""
    rows = view.rows()
    rows = rows[rows < len(stream.t_s)]
    if rows.size == 0:
        return None
    feedback = view.feedback
    signals: dict[str, np.ndarray] = {}
    for table, chamber in ((feedback.p_a, "p_A"), (feedback.p_b, "p_B")):
        values = _held([table.get(int(i)) for i in rows])
        for j, joint in enumerate(JOINTS):
            signals[f"{joint}.{chamber}"] = values[:, j]
    sent = np.maximum.accumulate(np.nan_to_num(log.frames_sent, nan=0.0))
    signals["bus.frames_sent"] = sent[rows]
    signals["bus.frames_received"] = log.frames_received[rows]
    signals["bus.feedback_lost"] = (rows - np.arange(rows.size)).astype(float)
    signals["bus.setpoints_lost"] = log.setpoints_lost[rows]
    signals["bus.bad_checksums"] = log.bad_checksums[rows]
    signals["bus.send_jitter_s"] = np.nan_to_num(log.jitter_s[rows], nan=0.0)
    arrived = np.array([feedback.arrived_at[int(i)] for i in rows])
    signals["bus.feedback_latency_s"] = np.nan_to_num(arrived - log.sent_at[rows], nan=0.0)
    return PeriodMeasurement(
        t_s=stream.t_s[rows], joints_rad=np.array([feedback.joints[int(i)] for i in rows]),
        reference_rad=stream.position_rad[rows], weighed_mass_kg=float(mass_kg),
        signals=signals)


def _held(values: list) -> np.ndarray:
    """(m, 3): each missing entry (None) repeats the previous one, the first known one before
    it (NaN if none arrived)."""
    out = np.full((len(values), 3), np.nan)
    known = [v for v in values if v is not None]
    last = known[0] if known else None
    for i, value in enumerate(values):
        last = value if value is not None else last
        if last is not None:
            out[i] = last
    return out
