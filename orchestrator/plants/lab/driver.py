"""The lab excavator behind the Plant protocol: the campaign's master over CAN.

One period (docs/can-protocol.md has the frames and the device's side):

1. the reference goes onto the stream grid and is checked (safety.py): joint ranges, velocity
   and acceleration limits, protocol ranges. A violation refuses the period before any frame of
   it leaves (ReferenceRefused, a ValueError); the first period also connects only after that;
2. once: the master heartbeat starts (the device's motion lease), the device's heartbeat and
   status are awaited, then its LeaseValid (it hears the master), and the arm handshake runs
   (ARM echoing the device's challenge);
3. the first setpoint must be within the start tolerance of the arm's reported pose;
4. PERIOD_START(k, n), then n cycles of RefAcceleration, RefVelocity, RefPosition at the stream
   rate, on absolute deadlines in machine time (paced by the time scale), while the frames from
   the device are taken in between;
5. PERIOD_END; the load cell's weighing of period k (fresh and valid); DUMP; back to ARMED.

Watchdog, checked after every received frame and at every deadline: an emergency stop or a fault
reported by the device, its heartbeat older than the consumer time, joint feedback older than the
feedback timeout, a command not acknowledged in time, no fresh load-cell reading. Any of them
stops the stream, commands HOLD and raises LabStop (the campaign ends with its reason; every
finished period is already in the run log; the stopped period's feedback is in LabStop.partial).
Ctrl-C while streaming sends an AllStop before it propagates. The cyclic garbage collector is
off while a period streams (timing.collector_paused): a full collection of a large heap would
stop the process for longer than the feedback timeout.
"""

from __future__ import annotations

import math
import threading
import time

import can
import numpy as np

from orchestrator.plants.lab.bus import LabLinkError, open_bus
from orchestrator.plants.lab.link import DeviceView
from orchestrator.plants.lab.measurement import CycleLog, period_measurement
from orchestrator.plants.lab.protocol import Cmd, MasterState, State, decode, encode, joint_signals
from orchestrator.plants.lab.safety import ReferenceRefused, check_stream, on_stream_grid
from orchestrator.plants.lab.settings import LabSettings
from orchestrator.plants.lab.timing import Heartbeat, ScaledClock, collector_paused
from plant_models.plant import JOINTS, JointReference, PeriodMeasurement, PeriodStopped


class LabStop(PeriodStopped):
    """The lab plant stopped the campaign (`reason`); `partial`: what the stopped period had
    measured (None if nothing)."""

    def __init__(self, reason: str, partial: PeriodMeasurement | None = None) -> None:
        super().__init__(reason, partial)
        self.reason = reason


class LabExcavator:
    """Plant of kind "lab" (module docstring).

    joint_limits_rad: (3, 2) joint ranges; limits_rad: (>= 2, 3) velocity (rad/s) and
    acceleration (rad/s^2) bounds per joint (the scenario's). bus: an open bus to use (default:
    opened from settings at the first period). emulator: an in-process emulated device that this
    plant owns and closes last."""

    kind = "lab"

    def __init__(self, settings: LabSettings, joint_limits_rad, limits_rad, *,
                 bus: can.BusABC | None = None, emulator=None) -> None:
        self.settings = settings
        self.joint_limits_rad = tuple(tuple(map(float, r)) for r in joint_limits_rad)
        self.limits_rad = np.asarray(limits_rad, dtype=float)
        self.communication_step_s = settings.frame_period_s  # the campaign samples on it
        self.clock = ScaledClock(settings.time_scale)
        self.view = DeviceView(settings)
        self.emulator = emulator
        self._bus, self._heartbeat = bus, None
        self._send_lock = threading.Lock()  # the heartbeat thread sends on the same bus
        self._connected = self._closed = False
        self._stopped: str | None = None
        self._master_state = MasterState.IDLE
        self._seq = 0
        self._counters: dict[str, int] = {}
        self._period = 0
        self._stream = self._log = None
        self._sent_before = 0
        self.frames_sent = 0
        self.jitter_s: list[float] = []  # every cycle's send lateness (wall s), all periods
        self.stream_wall_s = 0.0  # wall time spent streaming, first to last send of each period
        self.cycles_sent = 0
        self.slips = 0  # times the stream's schedule slipped by a cycle or more
        # The stream runs at most this many cycles ahead of the newest feedback: a device that
        # lags holds the stream back instead of queueing setpoints (a healthy one answers each
        # cycle within it). Below the feedback timeout in frames, so the watchdog's lag check
        # and the 4-bit counter never see more.
        self.max_lead_cycles = max(1, int(settings.feedback_timeout_s * settings.stream_rate_hz
                                          + 1e-9) - 1)

    # ---- frames --------------------------------------------------------------------------------

    def _send(self, name: str, counter: int | None = None, **signals) -> None:
        if counter is None:
            counter = self._counters.get(name, 0)
            self._counters[name] = (counter + 1) % 16
        frame = encode(name, Counter=counter, **signals)
        try:
            with self._send_lock:
                self._bus.send(frame)
        except can.CanError as error:
            raise LabLinkError(f"sending {name}: {error}") from None
        self.frames_sent += 1

    def _receive(self, until: float, streaming: bool, check: bool = True) -> None:
        """Take in frames until machine time `until`; with `check`, stop on a problem."""
        clock, view = self.clock, self.view
        while True:
            self._drain()
            now = clock.now()
            if check:
                problem = view.problem(now, streaming)
                if problem is not None:
                    self._abort(problem)
            if now >= until:
                return
            # Wake at the next timeout too, so that one trips when due, not a cycle later.
            wake = min(until, view.next_deadline(streaming) + 1e-4) if check else until
            message = self._bus.recv(timeout=clock.wall(wake - now))
            if message is not None:
                view.handle(decode(message), clock.now())

    def _drain(self, limit: int = 10_000) -> None:
        """Take in every frame already queued before judging any timeout: between periods the
        campaign plans and logs while the device's frames queue up (their ages count from
        here, so a device lost meanwhile is found one consumer time later)."""
        for _ in range(limit):
            message = self._bus.recv(timeout=0.0)
            if message is None:
                return
            self.view.handle(decode(message), self.clock.now())

    def _wait_for(self, ready, timeout_s: float, what: str, check: bool = True,
                  streaming: bool = False) -> None:
        """Take in frames until ready() (checking for problems, the feedback age too while
        `streaming`); stop after timeout_s machine s."""
        end = self.clock.now() + timeout_s
        while not ready():
            if self.clock.now() >= end:
                self._abort(f"no {what} within {timeout_s:g} s")
            self._receive(min(end, self.clock.now() + self.settings.frame_period_s), streaming,
                          check)

    def _command(self, cmd: Cmd, expect: tuple[State, ...], period: int = 0,
                 argument: int = 0) -> None:
        """Send a command and wait for its acknowledgement with the device in `expect`."""
        self._seq = self._seq % 255 + 1
        seq = self._seq
        self._send("Command", Cmd=int(cmd), Seq=seq, Period=period, Argument=argument)

        def acked() -> bool:
            status = self.view.status
            return status is not None and int(status["AckSeq"]) == seq
        self._wait_for(acked, self.settings.timeout("reply_timeout_s"),
                       f"acknowledgement of {cmd.name}")
        state = self.view.state
        if state not in expect and cmd == Cmd.DUMP and state == State.DUMPING:
            self._wait_for(lambda: self.view.state != State.DUMPING,
                           self.settings.timeout("reply_timeout_s"), "end of DUMP")
            state = self.view.state
        if state not in expect:
            self._abort(f"the device refused {cmd.name} in state {state.name}")

    # ---- connection ----------------------------------------------------------------------------

    def _connect(self) -> None:
        settings = self.settings
        if self._bus is None:
            self._bus = open_bus(settings)
        self._heartbeat = Heartbeat(
            self._bus, lambda counter: encode("HeartbeatMaster", State=int(self._master_state),
                                              Counter=counter),
            settings.heartbeat_period_s, self.clock, "lab-master-heartbeat",
            self._send_lock).start()
        self._connected = True
        self._wait_for(lambda: self.view.heartbeat_at is not None and self.view.status
                       is not None and self.view.pose_rad is not None,
                       settings.timeout("connect_timeout_s"),
                       f"device on {settings.interface} channel {settings.channel!r} (no "
                       "heartbeat, status and pose)", check=False)
        problem = self.view.problem(self.clock.now(), False)
        if problem is not None:
            self._abort(f"{problem}: clear it at the machine (RESET) before a campaign")
        if self.view.state != State.DISARMED:
            self._command(Cmd.DISARM, (State.DISARMED,))
        # Arm only once the device hears this master: it refuses ARM without a valid lease.
        self._wait_for(lambda: bool(self.view.status["LeaseValid"]),
                       settings.timeout("connect_timeout_s"),
                       "lease: the device does not report the master's heartbeat")
        self._command(Cmd.ARM, (State.ARMED,), argument=int(self.view.status["Challenge"]))
        self._master_state = MasterState.RUNNING

    # ---- one period ----------------------------------------------------------------------------

    def run_period(self, reference: JointReference) -> PeriodMeasurement:
        """Stream `reference`, weigh, dump, and report (module docstring)."""
        if self._closed:
            raise RuntimeError("the lab plant is closed")
        if self._stopped is not None:
            raise LabStop(f"the lab plant stopped earlier: {self._stopped}")
        settings, clock = self.settings, self.clock
        stream = on_stream_grid(reference, settings.frame_period_s)
        check_stream(stream, self.joint_limits_rad, self.limits_rad)
        n = len(stream.t_s)
        if n > 65535:
            raise ReferenceRefused(f"period refused before any frame was sent: {n} cycles, the "
                                   "protocol counts at most 65535")
        if not self._connected:
            self._connect()
        self._check_start(stream.position_rad[0])
        self._stream, self._log = stream, CycleLog(n)
        self._sent_before = self.frames_sent  # the period's frames count from PERIOD_START on
        k = self._period + 1
        self.view.start_period(clock.now())
        self._command(Cmd.PERIOD_START, (State.STREAMING,), period=k, argument=n)
        self._period = k
        try:
            with collector_paused():  # no collector pause trips a timeout mid-stream
                self._stream_cycles(stream)
        except KeyboardInterrupt:
            self._send("AllStop", Stop=1)
            self._stopped = "interrupted"
            raise
        before = self.view.load_cell  # the weighing must be a newer converter sample
        self._command(Cmd.PERIOD_END, (State.WEIGHING,), period=k)
        mass = self._weighing(k, before)
        self._command(Cmd.DUMP, (State.ARMED,), period=k)
        measurement = period_measurement(stream, self.view, self._log, mass)
        self.view.feedback = None
        if measurement is None:
            self._abort("no joint feedback arrived in the period")
        return measurement

    def _check_start(self, first_rad: np.ndarray) -> None:
        pose = np.array(self.view.pose_rad)
        gap = np.abs(first_rad - pose)
        worst = int(np.argmax(gap))
        if gap[worst] > self.settings.start_tolerance_rad:
            raise ReferenceRefused(
                f"period refused before any frame was sent: the reference starts "
                f"{math.degrees(gap[worst]):.2f} deg from the arm's {JOINTS[worst]} angle "
                f"({math.degrees(pose[worst]):.2f} deg); allowed: "
                f"{math.degrees(self.settings.start_tolerance_rad):.2f} deg")

    def _stream_cycles(self, stream) -> None:
        clock, view, log, period = self.clock, self.view, self._log, self.settings.frame_period_s
        received, bad = view.frames_received, view.bad_checksums
        lead = self.max_lead_cycles
        start = clock.now()
        first_wall = last_wall = time.perf_counter()
        for i in range(len(stream.t_s)):
            deadline = start + i * period
            self._receive(deadline, True)
            if i - view.feedback.newest > lead:  # the device lags: hold the stream back
                self._wait_for(lambda i=i: i - view.feedback.newest <= lead,
                               self.settings.timeout("feedback_timeout_s"), "joint feedback "
                               "(the device "
                               f"lags more than {lead} cycles)", streaming=True)
            sent_at, last_wall = clock.now(), time.perf_counter()
            if i == 0:
                first_wall = last_wall
            if sent_at - deadline > period:  # late by a whole cycle: slip, never burst
                start += sent_at - deadline
                self.slips += 1
                deadline = sent_at
            jitter = clock.wall(sent_at - deadline)
            counter = i % 16
            for name, values in (("RefAcceleration", stream.acceleration_rad_s2[i]),
                                 ("RefVelocity", stream.velocity_rad_s[i]),
                                 ("RefPosition", stream.position_rad[i])):
                self._send(name, counter, **joint_signals(values))
            view.sent_index = i
            log.sent(i, sent_at, jitter, self.frames_sent - self._sent_before, view, received,
                     bad)
            self.jitter_s.append(jitter)
        self.cycles_sent += len(stream.t_s)
        self.stream_wall_s += last_wall - first_wall
        last = len(stream.t_s) - 1
        self._wait_for(lambda: view.feedback.newest >= last,
                       self.settings.timeout("feedback_timeout_s"), "feedback of the last cycle",
                       streaming=True)

    def _weighing(self, k: int, before: dict | None) -> float:
        def fresh() -> bool:
            load = self.view.load_cell
            return load is not None and int(load["Period"]) == k and bool(load["Valid"]) and (
                before is None or load["Sample"] != before["Sample"])
        timeout = self.settings.timeout("load_cell_timeout_s")
        end = self.clock.now() + timeout
        while not fresh():
            if self.clock.now() >= end:
                load = self.view.load_cell
                seen = "no reading" if load is None else (
                    f"Sample {int(load['Sample'])}, Valid {int(load['Valid'])}, "
                    f"Period {int(load['Period'])}")
                self._abort(f"load cell: no fresh valid weighing of period {k} within "
                            f"{timeout:g} s ({seen}): frozen or failed load cell")
            self._receive(min(end, self.clock.now() + self.settings.frame_period_s), False)
        return float(self.view.load_cell["Mass"])

    # ---- stopping ------------------------------------------------------------------------------

    def _abort(self, reason: str) -> None:
        """Stop streaming, command HOLD, raise LabStop with what the period measured. A stop
        of the device's own (an emergency stop, a fault) is the reason whenever the device
        reports one: a timeout of the master's may be only its effect, seen first (the
        device's status still queued, or its thread late), so the acknowledgement of the HOLD
        is awaited (at most the reply timeout) and says what the device had."""
        self._master_state = MasterState.STOPPED
        if self._connected:
            try:
                self._seq = self._seq % 255 + 1
                self._send("Command", Cmd=int(Cmd.HOLD), Seq=self._seq, Period=self._period)
                own = self.view.own_stop()
                if own is None:
                    self._await_ack(self._seq)
                    own = self.view.own_stop()
                if own is not None and own != reason:
                    reason = f"{own}; the master had stopped for: {reason}"
            except LabLinkError:
                pass  # the bus is gone: the device's command timeout and lease hold it
        self._stopped = reason
        partial = None
        if self._stream is not None and self.view.feedback is not None:
            partial = period_measurement(self._stream, self.view, self._log, math.nan)
        raise LabStop(reason, partial)

    def _await_ack(self, seq: int) -> None:
        """Take in frames until the device acknowledges command `seq` or the reply timeout
        passes (no check: the master is stopping already)."""
        end = self.clock.now() + self.settings.timeout("reply_timeout_s")
        while self.clock.now() < end:
            status = self.view.status
            if status is not None and int(status["AckSeq"]) == seq:
                return
            self._receive(min(end, self.clock.now() + self.settings.frame_period_s), False,
                          check=False)

    def close(self) -> None:
        """Disarm (AllStop if a stream was interrupted), stop the heartbeat, shut the bus down,
        close an owned emulator; safe twice."""
        if self._closed:
            return
        self._closed = True
        try:
            if self._connected and self._stopped is None and self.view.state in (
                    State.ARMED, State.WEIGHING, State.DUMPING):
                self._seq = self._seq % 255 + 1
                self._send("Command", Cmd=int(Cmd.DISARM), Seq=self._seq)
        except LabLinkError:
            pass
        finally:
            if self._heartbeat is not None:
                self._heartbeat.stop()
            if self._bus is not None:
                self._bus.shutdown()
            if self.emulator is not None:
                self.emulator.close()

    def __enter__(self) -> LabExcavator:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def bus_summary(self) -> dict[str, float]:
        """Stream statistics over every period so far: cycles, achieved rate (cycles per wall s,
        and per machine s), send jitter median / p99 / max (wall s), frames sent/received."""
        jitter = np.array(self.jitter_s) if self.jitter_s else np.zeros(1)
        wall = self.stream_wall_s
        periods = max(self._period, 1)
        rate = (self.cycles_sent - periods) / wall if wall > 0 else math.nan
        return {"cycles": self.cycles_sent, "rate_hz_wall": rate,
                "rate_hz_machine": rate / self.settings.time_scale,
                "jitter_median_s": float(np.median(jitter)),
                "jitter_p99_s": float(np.percentile(jitter, 99)),
                "jitter_max_s": float(np.max(jitter)), "slips": self.slips,
                "frames_sent": self.frames_sent,
                "frames_received": self.view.frames_received}
