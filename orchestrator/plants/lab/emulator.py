"""The emulated lab excavator: the device state machine (device.py) around the simulated
excavator (sim_arm.py), on a CAN bus, in a thread of its own.

    with LabEmulator(arm, settings, joint_limits_rad, velocity_limits_rad_s) as emulator:
        ...  # a driver on the same bus digs with it

The thread runs the device's cycle clock (one `tick` per stream period of machine time),
receives frames in between, applies the fault plan (faults.py) and sends the device's frames,
holding back the delayed ones until they are due. `close()` stops and joins the thread, shuts
the bus down and frees the FMUs.
"""

from __future__ import annotations

import heapq
import itertools
import threading

import can

from orchestrator.plants.lab.bus import open_bus
from orchestrator.plants.lab.device import ExcavatorDevice
from orchestrator.plants.lab.faults import FaultInjector, Outgoing
from orchestrator.plants.lab.protocol import decode, encode
from orchestrator.plants.lab.settings import LabSettings
from orchestrator.plants.lab.sim_arm import SteppedExcavator
from orchestrator.plants.lab.timing import ScaledClock


class LabEmulator:
    """The emulated device (module docstring). bus: an open bus to use (closed by `close`),
    default: settings' interface and channel. seed: the device's arm challenges."""

    def __init__(self, arm: SteppedExcavator, settings: LabSettings, joint_limits_rad,
                 velocity_limits_rad_s, *, bus: can.BusABC | None = None, seed: int = 0) -> None:
        self.settings = settings
        self.clock = ScaledClock(settings.time_scale)
        self.faults = FaultInjector(settings.faults)
        self.arm = arm
        self.device = ExcavatorDevice(arm, settings, joint_limits_rad, velocity_limits_rad_s,
                                      self.faults, self._transmit, seed=seed)
        self._bus = bus if bus is not None else open_bus(settings)
        self._delayed: list[tuple[float, int, can.Message]] = []
        self._order = itertools.count()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="lab-emulator", daemon=True)
        self._closed = False
        self.error: BaseException | None = None  # the arm's failure, if any (device holds)
        self.frames_sent = self.frames_received = self.send_failures = 0

    def start(self) -> LabEmulator:
        """Start the device thread; returns self."""
        self._thread.start()
        return self

    def __enter__(self) -> LabEmulator:
        return self.start() if not self._thread.is_alive() else self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        """Stop and join the device thread, shut the bus down, free the FMUs; safe twice."""
        if self._closed:
            return
        self._closed = True
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join()
        self._bus.shutdown()
        self.arm.close()

    # ---- the thread ----------------------------------------------------------------------------

    def _transmit(self, name: str, signals: dict, fate: Outgoing) -> None:
        frame = encode(name, corrupt=fate.corrupt, **signals)
        if fate.delay_s > 0.0:
            heapq.heappush(self._delayed, (self.clock.now() + fate.delay_s, next(self._order),
                                           frame))
        else:
            self._send(frame)

    def _send(self, frame: can.Message) -> None:
        try:
            self._bus.send(frame)
            self.frames_sent += 1
        except can.CanError:
            self.send_failures += 1

    def _run(self) -> None:
        clock, device, period = self.clock, self.device, self.settings.frame_period_s
        next_tick = clock.now()
        while not self._stop.is_set():
            now = clock.now()
            while self._delayed and self._delayed[0][0] <= now:
                self._send(heapq.heappop(self._delayed)[2])
            if now >= next_tick:
                # Frames first: a device's receive interrupt runs before its timeout checks, so
                # a late thread must not judge the lease on a heartbeat still in its queue. A
                # few cycles' worth only: a master that keeps sending must not hold the tick
                # (and the device's own heartbeat) off.
                self._drain(12)
                self._guarded(device.tick, clock.now())
                next_tick += period
                if next_tick < now:  # fell behind (a loaded machine): no burst of ticks
                    next_tick = now + period
            wake = min(next_tick, self._delayed[0][0]) if self._delayed else next_tick
            self._receive(clock.wall(wake - clock.now()))
        self._drain()  # what the master said last (HOLD, DISARM) is still acted on

    def _drain(self, limit: int = 10_000) -> None:
        for _ in range(limit):
            if not self._receive(0.0):
                return

    def _receive(self, timeout_s: float) -> bool:
        """Take one frame (waiting up to timeout_s wall s); whether one came."""
        try:
            message = self._bus.recv(timeout=timeout_s)
        except can.CanError:
            return False
        if message is None:
            return False
        frame = decode(message)
        if frame is not None:
            self.frames_received += 1
            now = self.clock.now()
            if self.faults.keep_received(frame, self.device.campaign_time(now)):
                self._guarded(self.device.on_frame, frame, now)
        return True

    def _guarded(self, action, *args) -> None:
        """Run a device step; an arm failure puts the device in HOLD (fault INTERNAL) and is
        kept in `error`, the thread goes on (a faulted device still talks)."""
        try:
            action(*args)
        except Exception as failure:  # the FMUs or the coupling
            self.error = failure
            self.device.internal_fault(self.clock.now())
