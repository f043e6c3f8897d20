"""What a run log records of its run (`RunDescription`, the metadata records it starts with:
orchestrator.runlog.metadata) and how it is written (`LogSettings`)."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from plant_models.geometry import ExcavatorGeometry


@dataclass(frozen=True)
class RunDescription:
    """A run as its log's metadata records it.

    scenario: the resolved scenario (JSON-able dict); scenario_text: the scenario file's text;
    scenario_name: its name; fmus: name -> path of every FMU used; plant_kind: "sim" or "lab";
    target_mass_kg: the target dug mass, kg; geometry: the arm, for the 3D channels (None: no
    /tf, /scene/arm, /scene/plan); overrides: the `--set` items applied to the scenario file;
    derived: FMU name -> {output role: how it is derived} for outputs the master computes
    (orchestrator.plants.derived); arm_coupling: cylinder role -> how the step loop couples the
    arm's cross inertia into it (orchestrator.plants.native.arm_coupling_notes); notes: role ->
    further fields in words (orchestrator.plants.role_notes).
    """

    scenario: Mapping
    scenario_text: str
    scenario_name: str
    fmus: Mapping[str, str | Path]
    plant_kind: str
    target_mass_kg: float
    geometry: ExcavatorGeometry | None = None
    overrides: Sequence[str] = ()
    derived: Mapping[str, Mapping[str, str]] | None = None
    arm_coupling: Mapping[str, str] | None = None
    notes: Mapping[str, Mapping[str, str]] | None = field(default=None)

    def __post_init__(self) -> None:
        target = self.target_mass_kg
        if not (isinstance(target, int | float) and math.isfinite(target)):
            raise ValueError(f"target_mass_kg must be a finite number, got {target!r}")


@dataclass(frozen=True)
class LogSettings:
    """How a run log is written.

    transform_rate_hz: rate of /tf and /display (decimated from the samples), Hz;
    sample_rate_hz: rate of the high-rate sample channels (None: every sample;
    orchestrator.runlog.samples.decimated), Hz; fsync: also force each period to the disk
    (survives a power loss, not only a killed process; log_period then returns once its period
    is on the disk); background: compress and write on the log's own thread (False: every
    period is written and flushed before log_period returns).
    """

    transform_rate_hz: float = 25.0
    sample_rate_hz: float | None = None
    fsync: bool = False
    background: bool = False

    def __post_init__(self) -> None:
        if not self.transform_rate_hz > 0.0:
            raise ValueError(f"transform_rate_hz must be > 0, got {self.transform_rate_hz!r}")
        if self.sample_rate_hz is not None and not self.sample_rate_hz > 0.0:
            raise ValueError(f"sample_rate_hz must be > 0 or None, got {self.sample_rate_hz!r}")
