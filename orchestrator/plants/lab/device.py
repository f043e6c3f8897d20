"""The excavator's firmware side of the protocol: the device state machine (docs/can-protocol.md).

States: DISARMED -ARM(challenge)-> ARMED -PERIOD_START-> STREAMING -PERIOD_END-> WEIGHING
-DUMP-> DUMPING -> ARMED. HOLD (a fault, or the master's HOLD) and ESTOP (the button or an
AllStop frame) are latched: only RESET leaves them, to DISARMED, and ESTOP only once the button
is released. The arm moves only in STREAMING; in every other state the valves are closed and it
holds. All-stop wins over everything.

The state machine is transport-free: frames come in as `on_frame(Decoded, now)`, time passes in
`tick(now)` (called once per stream cycle), and frames go out through the `emit` callback with
their signals in DBC units. `now` is machine time (s).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from orchestrator.plants.lab.faults import FaultInjector, Outgoing
from orchestrator.plants.lab.protocol import (
    Cmd,
    Decoded,
    Fault,
    State,
    joint_signals,
    pressure_signals,
)
from orchestrator.plants.lab.settings import LabSettings
from orchestrator.plants.lab.sim_arm import SteppedExcavator, within_limits

MOVING = (State.ARMED, State.STREAMING, State.WEIGHING, State.DUMPING)  # need the lease
Emit = Callable[[str, dict, Outgoing], None]


@dataclass
class LoadCell:
    """The load cell as the device reports it: reading (kg), validity, converter sample count,
    and the period a weighing belongs to (0: live reading)."""

    mass_kg: float = 0.0
    valid: bool = True
    sample: int = 0
    period: int = 0
    frozen: bool = False


class ExcavatorDevice:
    """The device state machine around an arm (module docstring).

    joint_limits_rad: (3, 2) ranges; velocity_limits_rad_s: (3,) bounds the device enforces on
    every setpoint (a second line behind the master's check). seed: the arm challenges."""

    def __init__(self, arm: SteppedExcavator, settings: LabSettings, joint_limits_rad,
                 velocity_limits_rad_s, faults: FaultInjector, emit: Emit, seed: int = 0) -> None:
        self.arm, self.settings, self.faults, self._emit_frame = arm, settings, faults, emit
        self.joint_limits_rad = tuple(tuple(map(float, r)) for r in joint_limits_rad)
        self.velocity_limits_rad_s = np.asarray(velocity_limits_rad_s, dtype=float)
        self._rng = np.random.default_rng(seed)
        self.state, self.fault, self.estop_input = State.DISARMED, Fault.NONE, False
        self.ack_seq, self.challenge = 0, self._new_challenge()
        self.period = self.cycles = self.cycles_done = self.expected_counter = 0
        self.rx_lost = self.rx_bad = 0
        self.load = LoadCell()
        self.transitions: list[tuple[float, State, Fault]] = []
        self._setpoint: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        self._rates: dict[str, dict[int, tuple]] = {"RefVelocity": {}, "RefAcceleration": {}}
        self._last_setpoint_at = self._master_heartbeat_at = None
        self._campaign_origin: float | None = None
        self._weigh_pending = False
        self._next_slow = -math.inf
        self._counters: dict[str, int] = {}
        self._now = 0.0

    # ---- time ----------------------------------------------------------------------------------

    def campaign_time(self, now: float) -> float | None:
        """Machine s since the first PERIOD_START was accepted (None before): the faults' clock."""
        return None if self._campaign_origin is None else now - self._campaign_origin

    def lease_valid(self, now: float) -> bool:
        """Whether the master's heartbeat arrived within the consumer time."""
        at = self._master_heartbeat_at
        return at is not None and now - at <= self.settings.timeout("heartbeat_timeout_s")

    # ---- output --------------------------------------------------------------------------------

    def _emit(self, name: str, signals: dict, counter: int | None = None) -> None:
        if counter is None:
            counter = self._counters.get(name, 0)
            self._counters[name] = (counter + 1) % 16
        fate = self.faults.outgoing(name, self.campaign_time(self._now))
        if fate.send:
            self._emit_frame(name, {**signals, "Counter": counter}, fate)

    def _status(self) -> None:
        self._emit("DeviceStatus", {
            "State": int(self.state), "EStop": int(self.estop_input or self.state == State.ESTOP),
            "LeaseValid": int(self.lease_valid(self._now)),
            "Fault": int(self.fault), "AckSeq": self.ack_seq, "Challenge": self.challenge,
            "Period": self.period})

    def _feedback(self, counter: int | None, streaming: bool) -> None:
        joints = self.arm.joints_rad()
        p_a, p_b = self.arm.pressures_pa()
        if counter is None:  # idle: a rolling counter of its own
            counter = self._counters.get("FbPosition", 0)
            self._counters["FbPosition"] = (counter + 1) % 16
        self._emit("FbPosition", {**joint_signals(joints), "Streaming": int(streaming)}, counter)
        self._emit("FbPressureA", pressure_signals(p_a), counter)
        self._emit("FbPressureB", pressure_signals(p_b), counter)

    def _load_cell(self) -> None:
        load = self.load
        self._emit("LoadCell", {"Mass": min(max(load.mass_kg, -32.768), 32.767),
                                "Valid": int(load.valid), "Sample": load.sample % 256,
                                "Period": load.period})

    # ---- state changes -------------------------------------------------------------------------

    def _new_challenge(self) -> int:
        return int(self._rng.integers(1, 256))

    def _enter(self, state: State, fault: Fault | None = None) -> None:
        if self.state == State.ESTOP and state != State.DISARMED:
            return  # all-stop wins: only RESET leaves ESTOP
        if self.state == State.HOLD and state not in (State.DISARMED, State.ESTOP):
            return  # HOLD is latched too
        self.state = state
        if fault is not None:
            self.fault = fault
        if state == State.DISARMED:
            self.fault, self.challenge = Fault.NONE, self._new_challenge()
        self.transitions.append((self._now, self.state, self.fault))
        self._status()

    def internal_fault(self, now: float) -> None:
        """The arm model failed: hold (valves closed) with fault INTERNAL."""
        self._now = now
        self._enter(State.HOLD, Fault.INTERNAL)

    # ---- input ---------------------------------------------------------------------------------

    def on_frame(self, frame: Decoded, now: float) -> None:
        """React to one received frame at machine time `now`."""
        self._now = now
        if frame.name == "AllStop":  # whatever its checksum: stopping is always safe
            self._enter(State.ESTOP, Fault.ALL_STOP)
            return
        if not frame.checksum_ok:
            self.rx_bad += 1
            return
        if frame.name == "HeartbeatMaster":
            self._master_heartbeat_at = now
        elif frame.name == "Command":
            self._command(frame.signals)
        elif frame.name in self._rates and self.state == State.STREAMING:
            self._rates[frame.name][int(frame.signals["Counter"])] = frame.joints_rad()
        elif frame.name == "RefPosition" and self.state == State.STREAMING:
            self._setpoint_frame(frame)

    def _command(self, signals: dict) -> None:
        seq = int(signals["Seq"])
        if seq == self.ack_seq:
            self._status()  # a repeated command: answer again, do it once
            return
        self.ack_seq = seq
        cmd, period = int(signals["Cmd"]), int(signals["Period"])
        argument = int(signals["Argument"])
        lease = self.lease_valid(self._now)
        if cmd == Cmd.HOLD:
            self._enter(State.HOLD, Fault.MASTER_HOLD)
        elif cmd == Cmd.RESET and self.state in (State.HOLD, State.ESTOP) \
                and not self.estop_input:
            self._enter(State.DISARMED)
        elif cmd == Cmd.DISARM and self.state in MOVING:
            self._enter(State.DISARMED)
        elif cmd == Cmd.ARM and self.state == State.DISARMED and argument == self.challenge \
                and lease and not self.estop_input:
            self._enter(State.ARMED)
        elif cmd == Cmd.PERIOD_START and self.state == State.ARMED and lease and argument > 0:
            self.period, self.cycles, self.cycles_done = period, argument, 0
            self.expected_counter, self.rx_lost, self.rx_bad = 0, 0, 0
            self._setpoint, self._last_setpoint_at = None, self._now
            for table in self._rates.values():
                table.clear()
            if self._campaign_origin is None:
                self._campaign_origin = self._now
            self._enter(State.STREAMING)
        elif cmd == Cmd.PERIOD_END and self.state == State.STREAMING and period == self.period:
            if self.cycles_done == self.cycles:
                self._weigh_pending = True
                self._enter(State.WEIGHING)
            else:
                self._enter(State.HOLD, Fault.PROTOCOL)
        elif cmd == Cmd.DUMP and self.state == State.WEIGHING and period == self.period \
                and self.load.period == period:
            self.arm.dump()
            self._enter(State.DUMPING)
        else:
            self._status()  # refused: the ack shows it was seen, State that nothing changed

    def _setpoint_frame(self, frame: Decoded) -> None:
        counter = int(frame.signals["Counter"])
        gap = (counter - self.expected_counter) % 16
        if self.cycles_done and gap == 15:
            return  # the previous cycle's counter again: a repeat
        if self.cycles_done + gap + 1 > self.cycles:
            self._enter(State.HOLD, Fault.PROTOCOL)  # more setpoints than PERIOD_START announced
            return
        position = np.array(frame.joints_rad())
        previous = self._setpoint
        velocity = self._rates["RefVelocity"].pop(counter, None)
        acceleration = self._rates["RefAcceleration"].pop(counter, None)
        velocity = np.array(velocity) if velocity is not None else (
            previous[1] if previous is not None else np.zeros(3))
        acceleration = np.array(acceleration) if acceleration is not None else np.zeros(3)
        if not within_limits(position, self.joint_limits_rad) or np.any(
                np.abs(velocity) > self.velocity_limits_rad_s * 1.05 + 1e-3):
            self._enter(State.HOLD, Fault.SETPOINT_LIMIT)
            return
        if self.cycles_done == 0 and gap == 0 and \
                self.arm.start_pose_error_rad(position) > self.settings.start_tolerance_rad:
            self._enter(State.HOLD, Fault.START_POSE)
            return
        for _ in range(gap):  # cycles lost: extrapolate the last setpoint (or hold the arm)
            self.rx_lost += 1
            self._execute(self._extrapolated(), self.expected_counter)
        self._execute((position, velocity, acceleration), counter)
        self._last_setpoint_at = self._now

    def _extrapolated(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        if self._setpoint is None:
            return self.arm.joints_rad(), np.zeros(3), np.zeros(3)
        p, v, a = self._setpoint
        t = self.settings.frame_period_s
        return p + v * t + 0.5 * a * t * t, v + a * t, a

    def _execute(self, setpoint, counter: int) -> None:
        """One stream cycle: report the arm as it is (the sample at the cycle's start), then
        track the setpoint for T."""
        self._feedback(counter, streaming=True)
        self.arm.cycle(*setpoint)
        self._setpoint = setpoint
        self.cycles_done += 1
        self.expected_counter = (counter + 1) % 16

    # ---- time ----------------------------------------------------------------------------------

    def tick(self, now: float) -> None:
        """Once per stream cycle: faults due, timeouts, weighing, and the 10 Hz frames."""
        self._now = now
        t = self.campaign_time(now)
        if self.faults.estop_pressed(t) and not self.estop_input:
            self.estop_input = True
            self._enter(State.ESTOP, Fault.EMERGENCY_STOP)
        self.load.frozen = self.load.frozen or self.faults.load_cell_frozen(t)
        if self.state in MOVING and not self.lease_valid(now):
            self._enter(State.HOLD, Fault.LEASE_LOST)
        if self.state == State.STREAMING and self.cycles_done < self.cycles \
                and now - self._last_setpoint_at > self.settings.timeout("command_timeout_s"):
            self._enter(State.HOLD, Fault.COMMAND_TIMEOUT)
        if self.state == State.WEIGHING and self._weigh_pending and not self.load.frozen:
            self._weigh_pending = False
            self.load = LoadCell(self.arm.weigh(), True, self.load.sample + 1, self.period)
            self._load_cell()
        if self.state == State.DUMPING:
            self._enter(State.ARMED)
        if now >= self._next_slow:
            self._next_slow = max(self._next_slow + self.settings.heartbeat_period_s, now)
            self._slow_frames()

    def _slow_frames(self) -> None:
        self._emit("HeartbeatDevice", {"State": int(self.state), "RxLost": min(self.rx_lost, 65535),
                                       "RxBad": min(self.rx_bad, 65535)})
        self._status()
        if not self.load.frozen and self.state != State.WEIGHING:
            self.load = LoadCell(self.arm.bucket_mass_kg(), True, self.load.sample + 1, 0)
        self._load_cell()
        if self.state != State.STREAMING:
            self._feedback(None, streaming=False)
