"""Test helpers for the lab link: an independent reading of the bus (cantools straight from the
DBC, a bitwise CRC written from the CRC catalogue's definition), a capture bus, and short
references at the emulated device's start pose."""

from __future__ import annotations

import math
import threading
import time
from dataclasses import dataclass
from pathlib import Path

import can
import cantools
import numpy as np

from plant_models.plant import JointReference

DBC = Path(__file__).resolve().parent.parent / "orchestrator" / "plants" / "lab" / "excavator.dbc"
_DB = cantools.database.load_file(str(DBC))


def crc8_bitwise(data: bytes) -> int:
    """CRC-8/SAE-J1850, bit by bit (poly 0x1D, init 0xFF, xorout 0xFF, not reflected)."""
    crc = 0xFF
    for byte in data:
        crc ^= byte
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1D) & 0xFF if crc & 0x80 else (crc << 1) & 0xFF
    return crc ^ 0xFF


@dataclass(frozen=True)
class Frame:
    """A captured frame: bus time (s, time.time() of the sender), DBC name, signals, checksum."""

    t: float
    name: str
    signals: dict
    checksum_ok: bool


def read_frame(message: can.Message) -> Frame:
    spec = _DB.get_message_by_frame_id(message.arbitration_id)
    data = bytes(message.data)
    signals = spec.decode(data, decode_choices=False)
    ident = bytes((message.arbitration_id & 0xFF, message.arbitration_id >> 8))
    return Frame(message.timestamp, spec.name, signals,
                 crc8_bitwise(ident + data[:7]) == signals["Checksum"])


class Capture:
    """A listener on a virtual channel: every frame sent on it from now on."""

    def __init__(self, channel: str) -> None:
        self.bus = can.Bus(interface="virtual", channel=channel)

    def frames(self) -> list[Frame]:
        """Everything received so far (and closes the listener)."""
        out = []
        while (message := self.bus.recv(timeout=0.0)) is not None:
            out.append(read_frame(message))
        self.bus.shutdown()
        return out


def still_reference(pose_rad, duration_s: float, step_s: float,
                    wiggle_deg: float = 0.0) -> JointReference:
    """A reference on the grid k step_s from `pose_rad` (3,) rad: the bucket turns by
    wiggle_deg (1 - cos) and back over duration_s, boom and stick still."""
    t = np.arange(int(round(duration_s / step_s)) + 1) * step_s
    w = 2 * math.pi / duration_s
    amplitude = math.radians(wiggle_deg) / 2
    position = np.tile(np.asarray(pose_rad, dtype=float), (len(t), 1))
    velocity, acceleration = np.zeros_like(position), np.zeros_like(position)
    position[:, 2] += amplitude * (1 - np.cos(w * t))
    velocity[:, 2] = amplitude * w * np.sin(w * t)
    acceleration[:, 2] = amplitude * w * w * np.cos(w * t)
    return JointReference(t, position, velocity, acceleration)


class StallMonitor:
    """A thread that sleeps `tick_s` at a time and keeps how late each wake-up came (bus time,
    time.time(), as Frame.t): what the machine held this process back, whatever the cause (the
    OS, a collector pause, the interpreter lock). Reaction times read off the bus are bounded by
    the protocol's figure plus the stall seen over the same window."""

    def __init__(self, tick_s: float = 0.002) -> None:
        self._tick_s, self._late = tick_s, []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="stall-monitor", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.is_set():
            before = time.time()
            time.sleep(self._tick_s)
            after = time.time()
            if after - before > 2 * self._tick_s:
                self._late.append((after, after - before - self._tick_s))

    def stop(self) -> StallMonitor:
        self._stop.set()
        self._thread.join()
        return self

    def worst(self, start: float, end: float) -> float:
        """The longest stall (s) that ended in [start, end] (bus time), 0 if none."""
        return max((late for at, late in self._late if start <= at <= end), default=0.0)
