"""Opening the CAN bus of the lab link through python-can (any interface it supports)."""

from __future__ import annotations

import uuid

import can

from orchestrator.plants.lab.settings import LabSettings


class LabLinkError(RuntimeError):
    """The CAN link cannot be used (interface missing, bus closed, send failed)."""


def open_bus(settings: LabSettings, channel: str | None = None) -> can.BusABC:
    """`can.Bus` for settings.interface and channel (default settings.channel) at
    settings.bitrate (bit/s). The `virtual` interface connects buses of this process only and
    takes no bitrate; it does not receive its own frames. LabLinkError with the interface's
    reason when the bus cannot be opened."""
    channel = settings.channel if channel is None else channel
    try:
        if settings.interface == "virtual":
            return can.Bus(interface="virtual", channel=channel, receive_own_messages=False)
        return can.Bus(interface=settings.interface, channel=channel, bitrate=settings.bitrate)
    except (can.CanError, OSError, ValueError, ImportError) as error:
        raise LabLinkError(f"cannot open CAN interface {settings.interface!r} channel "
                           f"{channel!r}: {error}") from None


def private_virtual_channel(prefix: str = "excosim") -> str:
    """A virtual-bus channel name no other link in this process uses (python-can's virtual
    buses meet by channel name)."""
    return f"{prefix}-{uuid.uuid4().hex[:12]}"
