"""Configuration of the simulated excavator (plain, frozen data; defaults in
`plant_models.hydraulics.default_config`)."""

from __future__ import annotations

import math
from dataclasses import dataclass

from plant_models.cylinder_model import CylinderModel
from plant_models.geometry import ExcavatorGeometry
from plant_models.model_spec import FmuSpec
from plant_models.supply import LoadSensingPump

# The servo's design targets (plant_models.servo.design_servo): the DPF-closed hydraulic mode's
# damping (the usual 0.5-0.8 of servo design), and margins above the required 45 deg / 6 dB so
# the changes of load and pose keep a reserve. Here, not in servo.py, so that reading a
# configuration does not import python-control (seconds).
DEFAULT_DAMPING = 0.7
DEFAULT_GAIN_MARGIN_DB = 10.0
DEFAULT_PHASE_MARGIN_DEG = 60.0
# The floor: a servo design target below these is refused (the 6 dB / 45 deg).
REQUIRED_GAIN_MARGIN_DB = 6.0
REQUIRED_PHASE_MARGIN_DEG = 45.0


@dataclass(frozen=True)
class SimulatedExcavatorConfig:
    """The FMUs, step, load cell and servo settings of one simulated excavator.

    geometry: the arm. boom, stick, bucket: cylinder FMUs (role "cylinder"); pile: the Pile FMU
        (role "pile"); see plant_models.model_spec. A cylinder FMU also needs a parameter that
        sets its initial stroke, the role "x0" (map it in `ports` if it is named otherwise).
    communication_step_s: s, the co-simulation step.
    servo_sample_s: s, the servos' sample time, a property of the controller (the machine's
        ECU), independent of the step: a multiple of communication_step_s; the servos are
        designed for it and hold their command between samples.
    coupling_tolerance_rad_s2: rad/s^2, how closely each step's cross inertia of the arm must
        agree with the joint accelerations it produces, as joint acceleration (the arm
        coupling, orchestrator.plants.native); coupling_max_iterations: the most tries of one
        step (a step still above the tolerance then is counted as unconverged).
    load_cell_noise_kg: standard deviation (kg) of the Gaussian load-cell noise (0: exact).
    seed: seed of the load-cell noise generator (one generator per plant: reproducible).
    start_pose_rad: (3,) rad joint angles the arm starts at, at rest; None: the first
        reference's first sample.
    start_tolerance_rad: how far (rad, per joint) a period's reference may start from where
        the arm is; farther is a ValueError.
    design_strokes_m: (3,) m strokes at which each servo is linearised (None: mid-stroke).
    servo_damping, servo_gain_margin_db, servo_phase_margin_deg: design targets
        (plant_models.servo.design_servo).
    cylinder_models: per joint, the servo's model of a cylinder whose FMU does not have our
        HydraulicCylinder's parameter names (None: read from the FMU's parameters). A joint
        without one whose FmuSpec gives a `linear_model`, or whose FMU has other parameter
        names, gets the linear servo (plant_models.linear_servo) on that model or on the one
        identified from the FMU (orchestrator.plants.identify).
    supply: the pump the three valves share (plant_models.supply.LoadSensingPump: flow
        sharing, compensated meter-in edges), for every cylinder FMU with the inputs p_pump and
        p_LS (one without them runs on the supply it models itself); None: each valve at its
        own constant supply pressure p_supply.
    """

    geometry: ExcavatorGeometry
    boom: FmuSpec
    stick: FmuSpec
    bucket: FmuSpec
    pile: FmuSpec
    communication_step_s: float = 0.01
    servo_sample_s: float = 0.01
    coupling_tolerance_rad_s2: float = 1e-2
    coupling_max_iterations: int = 8
    load_cell_noise_kg: float = 0.0
    seed: int = 0
    start_pose_rad: tuple[float, float, float] | None = None
    start_tolerance_rad: float = math.radians(2.0)
    design_strokes_m: tuple[float, float, float] | None = None
    servo_damping: float = DEFAULT_DAMPING
    servo_gain_margin_db: float = DEFAULT_GAIN_MARGIN_DB
    servo_phase_margin_deg: float = DEFAULT_PHASE_MARGIN_DEG
    cylinder_models: tuple[CylinderModel | None, CylinderModel | None,
                           CylinderModel | None] | None = None
    supply: LoadSensingPump | None = None

    def __post_init__(self) -> None:
        for name in ("boom", "stick", "bucket", "pile"):
            if not isinstance(getattr(self, name), FmuSpec):
                raise ValueError(f"SimulatedExcavatorConfig.{name} must be an FmuSpec")
        checks = (
            ("communication_step_s", self.communication_step_s > 0.0, "> 0 s"),
            ("servo_sample_s", self.servo_sample_s > 0.0, "> 0 s"),
            ("coupling_tolerance_rad_s2", self.coupling_tolerance_rad_s2 > 0.0, "> 0 rad/s^2"),
            ("coupling_max_iterations", self.coupling_max_iterations >= 1, ">= 1"),
            ("load_cell_noise_kg", self.load_cell_noise_kg >= 0.0, ">= 0 kg"),
            ("start_tolerance_rad", self.start_tolerance_rad > 0.0, "> 0 rad"),
            ("servo_damping", 0.0 < self.servo_damping < 2.0, "in (0, 2)"),
            ("servo_gain_margin_db", self.servo_gain_margin_db >= 6.0, ">= 6 dB"),
            ("servo_phase_margin_deg", 45.0 <= self.servo_phase_margin_deg < 90.0,
             "in [45, 90) deg"),
        )
        for name, ok, requirement in checks:
            value = getattr(self, name)
            if not (math.isfinite(value) and ok):
                raise ValueError(f"SimulatedExcavatorConfig.{name} must be {requirement}, "
                                 f"got {value!r}")
        every = self.servo_sample_s / self.communication_step_s
        if abs(every - round(every)) > 1e-9 * every or round(every) < 1:
            raise ValueError(f"SimulatedExcavatorConfig.servo_sample_s {self.servo_sample_s!r} s "
                             f"must be a multiple of communication_step_s "
                             f"{self.communication_step_s!r} s")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int):
            raise ValueError(f"SimulatedExcavatorConfig.seed must be an int, got {self.seed!r}")
        if self.supply is not None and not isinstance(self.supply, LoadSensingPump):
            raise ValueError("SimulatedExcavatorConfig.supply must be a LoadSensingPump or None")
        if self.pile.linear_model is not None:
            raise ValueError("SimulatedExcavatorConfig.pile.linear_model: only the cylinder "
                             "roles (boom, stick, bucket) take a linear model")
        for name in ("start_pose_rad", "design_strokes_m", "cylinder_models"):
            value = getattr(self, name)
            if value is not None and len(value) != 3:
                raise ValueError(f"SimulatedExcavatorConfig.{name} needs 3 entries "
                                 "(boom, stick, bucket)")
        for name in ("start_pose_rad", "design_strokes_m"):
            value = getattr(self, name)
            if value is not None and not all(math.isfinite(v) for v in value):
                raise ValueError(f"SimulatedExcavatorConfig.{name} must be finite")

    @property
    def cylinders(self) -> tuple[FmuSpec, FmuSpec, FmuSpec]:
        """(boom, stick, bucket) FmuSpecs."""
        return (self.boom, self.stick, self.bucket)
