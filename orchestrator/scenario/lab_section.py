"""The [plant.lab] table of a scenario: the CAN link to the lab excavator (plant kind "lab"),
and [plant.lab.faults], the faults an emulated device injects. File units: s, Hz, deg, bit/s.
Defaults and their reasons: orchestrator.plants.lab.settings."""

from __future__ import annotations

import math

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    StrictBool,
    StrictInt,
    StrictStr,
    field_validator,
    model_validator,
)

from orchestrator.plants.lab.settings import MAX_TIMEOUT_FRAMES, FaultPlan, LabSettings
from orchestrator.scenario.values import Number

_DEFAULTS = LabSettings()
_NO_FAULTS = FaultPlan()


class Section(BaseModel):
    """As orchestrator.scenario.sections.Section (which imports this module): extra keys
    forbidden, frozen."""

    model_config = ConfigDict(extra="forbid", frozen=True)


class FaultsSection(Section):
    """orchestrator.plants.lab.settings.FaultPlan: times in campaign s, absent: never."""

    drop_fraction: Number = Field(default=_NO_FAULTS.drop_fraction, ge=0.0, lt=1.0)
    seed: StrictInt = Field(default=0, ge=0)
    drop_from_s: Number | None = Field(default=None, ge=0.0)
    feedback_delay_s: Number = Field(default=0.0, ge=0.0)
    feedback_delay_from_s: Number = Field(default=0.0, ge=0.0)
    heartbeat_stop_s: Number | None = Field(default=None, ge=0.0)
    corrupt_from_s: Number | None = Field(default=None, ge=0.0)
    estop_at_s: Number | None = Field(default=None, ge=0.0)
    freeze_load_cell_at_s: Number | None = Field(default=None, ge=0.0)

    def plan(self) -> FaultPlan:
        return FaultPlan(**self.model_dump())


class LabSection(Section):
    """The lab link (python-can interface, channel, bitrate), stream rate, timeouts, time scale,
    and `emulate`: run the emulated device in this process on the `virtual` interface."""

    interface: StrictStr = _DEFAULTS.interface
    channel: StrictStr = Field(default=_DEFAULTS.channel, min_length=1)
    bitrate: StrictInt = Field(default=_DEFAULTS.bitrate, gt=0)
    stream_rate_hz: Number = Field(default=_DEFAULTS.stream_rate_hz, gt=0.0, le=1000.0)
    command_timeout_s: Number = Field(default=_DEFAULTS.command_timeout_s, gt=0.0)
    feedback_timeout_s: Number = Field(default=_DEFAULTS.feedback_timeout_s, gt=0.0)
    heartbeat_period_s: Number = Field(default=_DEFAULTS.heartbeat_period_s, gt=0.0)
    heartbeat_timeout_s: Number = Field(default=_DEFAULTS.heartbeat_timeout_s, gt=0.0)
    reply_timeout_s: Number = Field(default=_DEFAULTS.reply_timeout_s, gt=0.0)
    load_cell_timeout_s: Number = Field(default=_DEFAULTS.load_cell_timeout_s, gt=0.0)
    connect_timeout_s: Number = Field(default=_DEFAULTS.connect_timeout_s, gt=0.0)
    start_tolerance_deg: Number = Field(default=math.degrees(_DEFAULTS.start_tolerance_rad),
                                        gt=0.0)
    time_scale: Number = Field(default=_DEFAULTS.time_scale, gt=0.0, le=100.0)
    emulate: StrictBool = False
    faults: FaultsSection = FaultsSection()

    @field_validator("interface")
    @classmethod
    def _known_interface(cls, value: str) -> str:
        import can

        known = sorted(can.interfaces.VALID_INTERFACES)
        if value not in known:
            raise ValueError(f"unknown python-can interface {value!r}; known: {', '.join(known)}")
        return value

    @model_validator(mode="after")
    def _consistent(self) -> LabSection:
        frame = 1.0 / self.stream_rate_hz
        for name in ("command_timeout_s", "feedback_timeout_s"):
            frames = getattr(self, name) / frame
            if not 2.0 - 1e-9 <= frames <= MAX_TIMEOUT_FRAMES + 1e-9:
                raise ValueError(
                    f"{name} = {getattr(self, name):g} s is {frames:.3g} frame periods at "
                    f"{self.stream_rate_hz:g} Hz; it must be 2 to {MAX_TIMEOUT_FRAMES} (one "
                    "late frame must not trip it; the 4-bit counter aliases at 16)")
        if self.command_timeout_s >= self.feedback_timeout_s:
            raise ValueError("command_timeout_s must be below feedback_timeout_s (when "
                             "setpoints stop reaching the device, the device holds first)")
        if self.heartbeat_timeout_s <= self.heartbeat_period_s:
            raise ValueError("heartbeat_timeout_s must exceed heartbeat_period_s (a heartbeat "
                             "consumer waits longer than its producer's period)")
        if self.emulate and self.interface != "virtual":
            raise ValueError('emulate = true runs the device in this process: it needs '
                             f'interface = "virtual", got {self.interface!r}')
        return self

    def settings(self, channel: str | None = None) -> LabSettings:
        """The link's settings in SI units (channel: another channel name, e.g. a private
        virtual one)."""
        values = self.model_dump(exclude={"faults", "start_tolerance_deg"})
        if channel is not None:
            values["channel"] = channel
        return LabSettings(**values, start_tolerance_rad=math.radians(self.start_tolerance_deg),
                           faults=self.faults.plan())
