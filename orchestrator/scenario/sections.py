"""The tables of a scenario file, as pydantic models (extra keys forbidden, values in file
units: m, deg, deg/s, kg, s). orchestrator.scenario.model assembles them into a Scenario."""

from __future__ import annotations

import math
from typing import Literal

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    StrictInt,
    StrictStr,
    ValidationError,
    field_validator,
    model_validator,
)

from orchestrator.scenario.lab_section import LabSection
from orchestrator.scenario.values import Number, ParameterValue, first_error, numbers
from planner.digging_path import PathShape
from plant_models import presets
from plant_models.linear_cylinder import LinearCylinderModel
from plant_models.model_spec import FmuSpec
from plant_models.supply import M3_S_PER_L_MIN, LoadSensingPump

_positive = (lambda v: v > 0.0, "> 0")


class Section(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class MachineSection(Section):
    preset: StrictStr

    @field_validator("preset")
    @classmethod
    def _known(cls, value: str) -> str:
        if value not in presets.NAMES:
            raise ValueError(f"unknown preset {value!r}; known: {', '.join(presets.NAMES)}")
        return value


class PathSection(Section):
    """planner.digging_path.PathShape in file units (m, deg; absolute angles as in
    plant_models.geometry)."""

    start_tip_m: numbers(2)
    start_bucket_angle_deg: Number
    entry_offset_m: Number = Field(ge=0.0)
    entry_height_m: Number
    entry_bucket_angle_deg: Number
    closed_bucket_joint_deg: Number
    lift_tip_m: numbers(2)

    def shape(self) -> PathShape:
        return PathShape(
            start_tip_m=self.start_tip_m,
            start_bucket_angle_rad=math.radians(self.start_bucket_angle_deg),
            entry_offset_m=self.entry_offset_m,
            entry_height_m=self.entry_height_m,
            entry_bucket_angle_rad=math.radians(self.entry_bucket_angle_deg),
            closed_bucket_joint_rad=math.radians(self.closed_bucket_joint_deg),
            lift_tip_m=self.lift_tip_m,
        )


class LimitsSection(Section):
    """Per-joint bounds [boom, stick, bucket] on |velocity|, |acceleration|, |jerk| (eq. 1)."""

    velocity_deg_s: numbers(3, *_positive)
    acceleration_deg_s2: numbers(3, *_positive)
    jerk_deg_s3: numbers(3, *_positive)


class TrajectorySection(Section):
    """Weights of duration and jerk in the planner's cost (planner.trajectory), each in [0, 1]
    (k_T > 0: without a price on time the plan has no finite optimum)."""

    k_T: Number = Field(gt=0.0, le=1.0)
    k_J: Number = Field(ge=0.0, le=1.0)


class AdaptationSection(Section):
    """D0 and the steps of eq. 5 (planner.adaptation); the fuzzy rule (planner.fuzzy): either
    centre_fractions (ps, pb, vpb as fractions of the target) or all 7 centres_kg.

    strategy: what turns the weight error into eq. 5's correction eps: "fuzzy" (the paper's
    rule), "proportional" (eps = gain_m_per_kg * dm, planner.proportional; without a gain, the
    secant through the fuzzy rule's vpb term), "fixed" (no correction and dz_0 = 0: every
    period digs the same trajectory through D0, the baseline without adaptation) or "terrain"
    (beyond the paper: z_D from the mass predicted on the planner's own surface estimate,
    planner.terrain; it needs assumed_repose_angle_deg, the angle in (0, 90) deg the planner
    assumes trench walls slump to, and ignores the rule's terms)."""

    strategy: Literal["fuzzy", "proportional", "fixed", "terrain"] = "fuzzy"
    gain_m_per_kg: Number | None = Field(default=None, ge=0.0)
    assumed_repose_angle_deg: Number | None = Field(default=None, gt=0.0, lt=90.0)
    y_D0_m: Number
    z_D0_m: Number
    dz_0_m: Number
    dy_0_m: Number
    centre_fractions: numbers(3, *_positive, increasing=True) | None = None
    centres_kg: numbers(7, increasing=True) | None = None
    outputs_m: numbers(7, increasing=True)

    @field_validator("outputs_m")
    @classmethod
    def _signs(cls, value: tuple[float, ...]) -> tuple[float, ...]:
        """r_1..r_3 (too heavy: dig shallower) < 0 < r_5..r_7 (too light: dig deeper)."""
        if not value[2] < 0.0 < value[4]:
            raise ValueError(f"r_1..r_3 must be < 0 and r_5..r_7 > 0 (a too heavy bucket digs "
                             f"shallower, a too light one deeper), got {list(value)}")
        return value

    @model_validator(mode="after")
    def _one_partition(self) -> AdaptationSection:
        if (self.centre_fractions is None) == (self.centres_kg is None):
            raise ValueError("give either centre_fractions or centres_kg (exactly one)")
        if self.strategy == "terrain" and self.assumed_repose_angle_deg is None:
            raise ValueError("strategy \"terrain\" needs assumed_repose_angle_deg (the angle "
                             "of repose the planner assumes, deg)")
        return self


class LinearModelSection(Section):
    """plant_models.linear_cylinder.LinearCylinderModel of a cylinder role (SI units)."""

    velocity_gain_m_s: Number = Field(gt=0.0)
    natural_frequency_rad_s: Number = Field(gt=0.0)
    damping: Number = Field(ge=0.0)
    stroke_m: Number = Field(gt=0.0)


class PortSection(Section):
    """A port mapped with a conversion: role value (SI) = scale * FMU value + offset."""

    variable: StrictStr
    scale: Number = 1.0
    offset: Number = 0.0

    @field_validator("scale")
    @classmethod
    def _not_zero(cls, value: float) -> float:
        if value == 0.0:
            raise ValueError("must not be 0")
        return value


class FmuSection(Section):
    """plant_models.model_spec.FmuSpec: our model's name or a .fmu path, start values, ports;
    linear_model (cylinder roles): the servo's model of the FMU (absent: read or identified);
    piston_areas (cylinder roles): {A_A, A_B} in m^2, for a force derived from the chamber
    pressures of an FMU without one (model_spec.DERIVABLE_OUTPUTS)."""

    fmu: StrictStr
    parameters: dict[StrictStr, ParameterValue] = {}
    ports: dict[StrictStr, StrictStr | PortSection] = {}
    linear_model: LinearModelSection | None = None
    piston_areas: dict[StrictStr, Number] = {}

    @field_validator("piston_areas")
    @classmethod
    def _areas(cls, value: dict[str, float]) -> dict[str, float]:
        for key, area in value.items():
            if key not in ("A_A", "A_B"):
                raise ValueError(f"unknown area {key!r}; give A_A (cap side) and A_B (rod "
                                 "side), in m^2")
            if not (math.isfinite(area) and area > 0.0):
                raise ValueError(f"area {key} must be > 0 m^2, got {area!r}")
        return value

    @field_validator("ports", mode="before")
    @classmethod
    def _port_tables(cls, value):
        """A port table's own mistake names the table's key (ports.x.scale), not the union."""
        if not isinstance(value, dict):
            return value
        out = {}
        for role, entry in value.items():
            if isinstance(entry, dict):
                try:
                    entry = PortSection.model_validate(entry)
                except ValidationError as error:
                    field, reason = first_error(error)
                    raise ValueError(f"{role}.{field}: {reason}") from None
            out[role] = entry
        return out

    def spec(self) -> FmuSpec:
        linear = None if self.linear_model is None \
            else LinearCylinderModel(**self.linear_model.model_dump())
        ports = {role: p if isinstance(p, str) else p.model_dump()
                 for role, p in self.ports.items()}
        return FmuSpec.from_table(self.fmu, self.parameters, ports, linear, self.piston_areas)


class LogSection(Section):
    """What the run log keeps; it changes no result. sample_rate_hz: the rate of the high-rate
    sample channels (/joints, /cylinder/*, /pile/bucket, /signals/*), taken every n-th
    communication step (each period's last sample always kept); absent: every step."""

    sample_rate_hz: Number | None = Field(default=None, gt=0.0)


_LPM = M3_S_PER_L_MIN
_PUMP_FIELDS = ("max_flow_l_min", "cutoff_pa", "margin_pa", "engine_power_w", "pump_efficiency")


class SupplySection(Section):
    """The oil supply of the three valves (plant_models.supply). kind "constant": each valve at
    its cylinder FMU's own p_supply. "load_sensing": one load-sensing pump with flow sharing
    for all three, its meter-in edges pressure compensated: max_flow_l_min (L/min), cutoff_pa
    and margin_pa (Pa), and its power limiter's engine_power_w (W) and pump_efficiency (-, the
    hydraulic power allowed is their product), defaults those of LoadSensingPump (a CAT 320's
    2 x 214.5 L/min, 35 MPa, 121 kW; 2.5 MPa, 0.85), filled in so the run log shows them (and
    cleared under "constant", where they do not apply). Plant kind "sim" only."""

    kind: StrictStr = "constant"
    max_flow_l_min: Number | None = Field(default=None, gt=0.0)
    cutoff_pa: Number | None = Field(default=None, gt=0.0)
    margin_pa: Number | None = Field(default=None, gt=0.0)
    engine_power_w: Number | None = Field(default=None, gt=0.0)
    pump_efficiency: Number | None = Field(default=None, gt=0.0, le=1.0)

    @model_validator(mode="after")
    def _pump(self):
        if self.kind not in ("constant", "load_sensing"):
            raise ValueError(f'unknown supply kind {self.kind!r}; use "constant" or '
                             '"load_sensing"')
        if self.kind == "constant":
            # A base's or --set's pump settings under a constant supply do not apply: cleared,
            # so the run log shows only what the run used.
            for name in _PUMP_FIELDS:
                object.__setattr__(self, name, None)
            return self
        pump = LoadSensingPump()
        defaults = {"max_flow_l_min": pump.max_flow_m3_s / _LPM, "cutoff_pa": pump.cutoff_pa,
                    "margin_pa": pump.margin_pa, "engine_power_w": pump.engine_power_w,
                    "pump_efficiency": pump.pump_efficiency}
        for name, value in defaults.items():
            if getattr(self, name) is None:
                object.__setattr__(self, name, value)
        if not self.margin_pa < self.cutoff_pa:
            raise ValueError("margin_pa must be below cutoff_pa")
        return self

    def pump(self) -> LoadSensingPump | None:
        """The shared pump (SI), None for the constant supply."""
        if self.kind == "constant":
            return None
        return LoadSensingPump(self.max_flow_l_min * _LPM, self.cutoff_pa, self.margin_pa,
                               self.engine_power_w, self.pump_efficiency)


class PlantSection(Section):
    """kind "sim": the simulated excavator of the FMU tables; "lab": the lab excavator over CAN
    ([plant.lab], orchestrator.scenario.lab_section), whose emulated device uses the FMU tables
    and communication_step_s too. supply: the valves' oil supply (SupplySection).
    servo_sample_s: the servos' sample time (s), a multiple of communication_step_s;
    coupling_tolerance_rad_s2, coupling_max_iterations: the arm coupling's agreement per step
    (joint acceleration, rad/s^2) and its most tries (plant_models.sim_config).
    max_tracking_error_deg: the largest |measured - reference|
    joint angle (deg) a period may reach; beyond it the campaign ends with termination "error"
    naming the joint, without reporting the period (orchestrator.campaign.loop)."""

    kind: StrictStr
    communication_step_s: Number = Field(gt=0.0)
    servo_sample_s: Number = Field(gt=0.0)
    coupling_tolerance_rad_s2: Number = Field(gt=0.0, le=1.0)
    coupling_max_iterations: StrictInt = Field(ge=1, le=100)
    load_cell_noise_kg: Number = Field(ge=0.0)
    max_tracking_error_deg: Number = Field(gt=0.0)
    boom: FmuSection
    stick: FmuSection
    bucket: FmuSection
    pile: FmuSection
    supply: SupplySection = SupplySection()
    lab: LabSection | None = None

    @field_validator("kind")
    @classmethod
    def _known_kind(cls, value: str) -> str:
        if value not in ("sim", "lab"):
            raise ValueError(f'unknown plant kind {value!r}; use "sim" or "lab"')
        return value

    @model_validator(mode="after")
    def _supply_on_sim(self):
        if self.kind != "sim" and self.supply.kind != "constant":
            raise ValueError(f'supply kind {self.supply.kind!r} applies to plant kind "sim" '
                             "only (the lab machine has its own pump)")
        return self

    @model_validator(mode="before")
    @classmethod
    def _lab_defaults(cls, data):
        """A lab plant without a [plant.lab] table takes its defaults (resolved, so the run
        log shows every value the link ran with)."""
        if isinstance(data, dict) and data.get("kind") == "lab" and data.get("lab") is None:
            data = {**data, "lab": {}}
        return data
