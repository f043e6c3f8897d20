"""The lab excavator's CAN protocol: the DBC file next to this module, and the frame helpers.

Every frame is encoded and decoded by cantools from `excavator.dbc` (no bytes packed by hand).
Each frame carries a 4-bit rolling `Counter` and, in byte 7, a `Checksum`: CRC-8/SAE-J1850
(polynomial 0x1D, initial value 0xFF, final XOR 0xFF) over the identifier's low and high byte
and then data bytes 0-6. The identifier in the CRC (AUTOSAR E2E's "data ID") makes a frame that
arrives under a wrong identifier fail its check. Frame list, rates and the device's state machine:
docs/can-protocol.md.

    frame = encode("RefPosition", Boom=10.0, Stick=-50.0, Bucket=-120.0, Counter=3)
    decoded = decode(frame)          # Decoded("RefPosition", {...}, checksum_ok=True)
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any

import can
import cantools

DBC_PATH = Path(__file__).with_name("excavator.dbc")
JOINT_SIGNALS = ("Boom", "Stick", "Bucket")  # the DBC's names of boom, stick, bucket
PA_PER_BAR = 1.0e5


class State(enum.IntEnum):
    """DeviceStatus.State: the device's state machine (docs/can-protocol.md)."""

    DISARMED = 0
    ARMED = 1
    STREAMING = 2
    WEIGHING = 3
    DUMPING = 4
    HOLD = 5
    ESTOP = 6


class Fault(enum.IntEnum):
    """DeviceStatus.Fault: why the device left normal operation (0: none)."""

    NONE = 0
    COMMAND_TIMEOUT = 1
    LEASE_LOST = 2
    SETPOINT_LIMIT = 3
    START_POSE = 4
    PROTOCOL = 5
    EMERGENCY_STOP = 6
    ALL_STOP = 7
    LOAD_CELL = 8
    INTERNAL = 9
    MASTER_HOLD = 10


class Cmd(enum.IntEnum):
    """Command.Cmd."""

    ARM = 1
    DISARM = 2
    PERIOD_START = 3
    PERIOD_END = 4
    DUMP = 5
    HOLD = 6
    RESET = 7


class MasterState(enum.IntEnum):
    """HeartbeatMaster.State."""

    BOOT = 0
    IDLE = 1
    RUNNING = 2
    STOPPED = 3


@lru_cache(maxsize=1)
def database() -> cantools.database.can.Database:
    """The protocol's DBC (loaded once)."""
    return cantools.database.load_file(str(DBC_PATH))


def _crc_table() -> tuple[int, ...]:
    table = []
    for byte in range(256):
        crc = byte
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1D) & 0xFF if crc & 0x80 else (crc << 1) & 0xFF
        table.append(crc)
    return tuple(table)


_CRC_TABLE = _crc_table()


def crc8_sae_j1850(data: bytes) -> int:
    """CRC-8/SAE-J1850 of `data` (poly 0x1D, init 0xFF, xorout 0xFF, not reflected)."""
    crc = 0xFF
    for byte in data:
        crc = _CRC_TABLE[crc ^ byte]
    return crc ^ 0xFF


def crc8(frame_id: int, payload: bytes) -> int:
    """A frame's Checksum: CRC-8/SAE-J1850 of the identifier (low byte, high byte) then
    `payload` (data bytes 0-6)."""
    return crc8_sae_j1850(bytes((frame_id & 0xFF, (frame_id >> 8) & 0xFF)) + bytes(payload))


def frame_id(name: str) -> int:
    """The 11-bit identifier of frame `name`."""
    return database().get_message_by_name(name).frame_id


def cycle_time_s(name: str) -> float | None:
    """The DBC's nominal cycle time of frame `name` (s), None for an event frame."""
    cycle = database().get_message_by_name(name).cycle_time
    return None if not cycle else cycle / 1000.0


def encode(name: str, *, corrupt: bool = False, **signals: Any) -> can.Message:
    """Frame `name` with `signals` in DBC units (deg, deg/s, bar, kg); Counter defaults to 0,
    Checksum is computed. cantools refuses a value outside the DBC's range (EncodeError).
    corrupt: give the frame a wrong checksum (fault injection)."""
    message, zeros = _messages()[name]
    values = {**zeros, **signals, "Checksum": 0}
    data = message.encode(values)  # strict: a value outside the DBC's range raises
    values["Checksum"] = crc8(message.frame_id, data[:7]) ^ (0x5A if corrupt else 0)
    # The values were checked above; only the checksum changed (a third of the cost).
    return can.Message(arbitration_id=message.frame_id, is_extended_id=False,
                       data=message.encode(values, strict=False))


@lru_cache(maxsize=1)
def _messages() -> dict[str, tuple[Any, dict[str, int]]]:
    """name -> (cantools message, every signal at 0)."""
    return {m.name: (m, {s.name: 0 for s in m.signals}) for m in database().messages}


@dataclass(frozen=True)
class Decoded:
    """A received frame: its DBC name, signal values (DBC units; enums as ints), whether its
    checksum holds, and its bus timestamp (s, the interface's clock)."""

    name: str
    signals: dict[str, float]
    checksum_ok: bool
    timestamp: float

    def joints_rad(self) -> tuple[float, float, float]:
        """Boom, stick, bucket of an angle frame in rad (or rad/s, rad/s^2 for the rate ones)."""
        return tuple(math.radians(self.signals[name]) for name in JOINT_SIGNALS)

    def joints_pa(self) -> tuple[float, float, float]:
        """Boom, stick, bucket of a pressure frame in Pa."""
        return tuple(self.signals[name] * PA_PER_BAR for name in JOINT_SIGNALS)


def decode(frame: can.Message) -> Decoded | None:
    """The frame decoded by the DBC, or None for an identifier the protocol does not have, an
    extended or remote frame, or a frame of the wrong length."""
    if frame.is_extended_id or frame.is_remote_frame or frame.is_error_frame:
        return None
    try:
        message = database().get_message_by_frame_id(frame.arbitration_id)
    except KeyError:
        return None
    data = bytes(frame.data)
    if len(data) != message.length:
        return None
    signals = message.decode(data, decode_choices=False)
    ok = crc8(message.frame_id, data[:7]) == signals["Checksum"]
    return Decoded(message.name, signals, ok, float(frame.timestamp))


def joint_signals(values_rad) -> dict[str, float]:
    """{Boom, Stick, Bucket} in deg (deg/s, deg/s^2) from three values in rad (rad/s,
    rad/s^2)."""
    return {name: math.degrees(float(v)) for name, v in zip(JOINT_SIGNALS, values_rad,
                                                              strict=True)}


def pressure_signals(values_pa) -> dict[str, float]:
    """{Boom, Stick, Bucket} in bar from three pressures in Pa, clipped to the DBC's 0..65.5
    bar (a transducer's range: a cavitating chamber reads 0)."""
    return {name: min(max(float(v) / PA_PER_BAR, 0.0), 65.535)
            for name, v in zip(JOINT_SIGNALS, values_pa, strict=True)}


def signal_range(name: str, signal: str) -> tuple[float, float]:
    """(minimum, maximum) of `signal` in frame `name`, DBC units."""
    spec = database().get_message_by_name(name).get_signal_by_name(signal)
    return float(spec.minimum), float(spec.maximum)
