"""The simulated excavator: three HydraulicCylinder FMUs and one Pile FMU behind the Plant
protocol (plant_models.plant), one instance each for the whole run (the ground has memory).

One communication step h from t_k (the reference is interpolated onto the grid t_k = k h):

1. strokes (cylinder outputs at t_k) -> joint angles, moment arms, tip and bucket angle
   (orchestrator.plants.arm_coupling);
2. the Pile steps with the tip at t_k: it cuts along the tip's path since the last step and
   returns the bucket's content and the soil force there (a function of the tip's path, so
   nothing lags a step);
3. the arm's loads: gravity (links and payload), the soil force through the Jacobian, the
   velocity products and the pose-dependent mass matrix (orchestrator.plants.arm_dynamics);
   each servo (plant_models.servo; plant_models.linear_servo for a cylinder FMU known only by
   its linear model, given or identified) samples at its own sample time
   (config.servo_sample_s, a multiple of the step) and turns the stroke reference, the
   measured stroke and force into a spool command it holds until its next sample; with a
   load-sensing supply (config.supply, plant_models.supply) the pump's pressure and the
   load-sensing pressure follow from the commands and the chamber pressures at t_k (a
   cylinder FMU without the inputs p_pump and p_LS stays off the pump, on whatever supply it
   models itself);
4. the cylinders step from t_k to t_k + h, each with its own diagonal inertia (mass_load) and
   the arm's cross inertia in its load F_ext; where the three FMUs can roll back their state
   the step is repeated until that cross inertia agrees with the accelerations it produces
   (config.coupling_tolerance_rad_s2), else it comes from the planned accelerations
   (`coupling_note` says why).

The loop runs in C (orchestrator.plants.native), one implementation for every plant.

At the end of a period the load cell reads the Pile's bucket mass (plus Gaussian noise from one
generator seeded per plant), then the Pile steps once more with `dump` high and the bucket
empties; the profile h[1..n] and the cell centres go into the measurement. The next period
continues from there: its reference must start within `start_tolerance_rad` of the arm. So
before the weighing, an arm that ends further than half that from its reference's last pose (a
joint lagging, e.g. a bucket slowed in the soil) is held on that pose until it is within it, at
most SETTLE_MAX_S; the held samples are part of the period (its reference held).

Measurement rows are samples at t_k (period time from 0): joints and cylinder outputs at t_k,
the Pile's outputs after its step to the tip at t_k, and the inputs (u, F_ext) held from t_k.
Signals: "<joint>.x, .v, .p_A, .p_B, .F" (cylinder outputs by role), "<joint>.u, .F_ext,
.mass_load" (inputs),
"pile.<output role>", "tip.y", "tip.z", "tip.bucket_angle", "coupling.iterations" (the tries
of the step from t_k: 1 when the first agreed, or in an explicit coupling); with a
load-sensing supply also "supply.p_pump", "supply.p_LS" (Pa) and "supply.sharing" (the
flow-sharing factor, 1: the pump keeps up).
"""

from __future__ import annotations

import math
import re
from dataclasses import replace
from functools import lru_cache

import numpy as np

from orchestrator.plants.arm_coupling import ArmCoupling
from orchestrator.plants.arm_dynamics import ArmInertia
from orchestrator.plants.fmu_support import check_fixed_step
from orchestrator.plants.identify import CylinderIdentification
from orchestrator.plants.master import Master, check_component, fmu_path, port_conversions
from orchestrator.plants.native import NativeCoupling
from orchestrator.plants.plant_state import ResumableState
from orchestrator.plants.port_checks import check_cylinder, static_load_n
from orchestrator.plants.servo_setup import (
    design_servo_cached,
    fmu_description,
    linear_servo,
    model_from_fmu,
    start_values,
)
from plant_models.hydraulics import reflected_mass_kg
from plant_models.linear_cylinder import LinearCylinderModel
from plant_models.linear_servo import LinearJointServo, LinearServoDesign
from plant_models.linkage import JOINT_NAMES
from plant_models.model_spec import CYLINDER_OUTPUTS, PILE_OUTPUTS, SUPPLY_INPUTS
from plant_models.plant import JointReference, PeriodMeasurement
from plant_models.servo import JointServo, ServoDesign
from plant_models.sim_config import SimulatedExcavatorConfig

_COLUMNS = (
    *(f"{j}.{n}" for j in JOINT_NAMES for n in (*CYLINDER_OUTPUTS, "u", "F_ext", "mass_load")),
    *(f"pile.{n}" for n in PILE_OUTPUTS),
    "tip.y", "tip.z", "tip.bucket_angle", "coupling.iterations",
)
_SUPPLY_COLUMNS = ("supply.p_pump", "supply.p_LS", "supply.sharing")
_PROFILE = re.compile(r"^h\[(\d+)\]$")
SETTLE_MAX_S = 5.0  # s: the longest an arm is held on a period's last pose (run_period)
SETTLE_CHUNK = 10  # communication steps held between looks at the pose


class SimulatedExcavator(ResumableState):
    """Plant of kind "sim" (see the module docstring). Use as a context manager or close();
    resume_state() / restore_state() save and restore what carries across periods."""

    kind = "sim"

    def __init__(self, config: SimulatedExcavatorConfig) -> None:
        self.config = config
        self.coupling = shared_coupling(config.geometry)
        self.inertia = ArmInertia(config.geometry)
        reflected = self._reflected_design_inertia()
        self._master: Master | None = None
        self.coupling_note: str | None = None
        """Why the step loop's arm coupling is explicit (one line naming the roles), None when
        it is implicit or before the FMUs start (orchestrator.plants.native.coupling_note)."""
        self._closed = False
        self._rng = np.random.default_rng(config.seed)
        self._steps = 0  # communication steps taken by the cylinders
        self._pile_time = 0.0
        self._initial_surface: tuple[np.ndarray, np.ndarray] | None = None
        designs, linear_models, identifications, supplied = [], [], [], []
        design_loads: list[float] = []  # kg per joint: the reflected inertia its servo holds
        static = self.coupling.loads(self.coupling.kinematics(*self._design_strokes()),
                                     0.0, 0.0, 0.0)  # N per cylinder: the sign test's load
        pump = config.supply
        for index, (joint, spec) in enumerate(zip(JOINT_NAMES, config.cylinders, strict=True)):
            description = fmu_description(joint, spec)
            ports = check_component(joint, "cylinder", spec, description)
            conversions = port_conversions(joint, spec, description, ports)
            stroke = self.coupling.tables[index].stroke_m
            fixed = check_fixed_step(joint, description, config.communication_step_s)
            check_cylinder(joint, fmu_path(spec, joint), ports, spec.parameters, stroke,
                           static_load_n(static, index), config.communication_step_s,
                           conversions, fixed)
            given = config.cylinder_models[index] if config.cylinder_models else None
            # An explicit model wins; then our HydraulicCylinder's parameters (the paper
            # scenario: unchanged); only an FMU with other parameter names is identified.
            model = given if given is not None or spec.linear_model is not None \
                else model_from_fmu(description, spec.parameters)
            design_loads.append(0.0)
            if given is None and model is not None and "mass_load" in ports:
                # The FMU's mass is the piston's; the arm's inertia comes through mass_load,
                # and the servo schedules its gains on it (plant_models.servo.JointServo).
                model = replace(model, mass_kg=model.mass_kg + reflected[index])
                design_loads[-1] = reflected[index]
            if pump is not None and all(p in ports for p in SUPPLY_INPUTS):
                valve = model or model_from_fmu(description, spec.parameters)
                if valve is None:
                    raise ValueError(f"{joint}: the load-sensing supply needs the valve's rated "
                                     f"flow: our HydraulicCylinder's parameters (q_rated, "
                                     f"dp_rated) of the cylinder FMU {spec.fmu!r}")
                if pump.cutoff_pa > valve.supply_pressure_pa:
                    raise ValueError(
                        f"{joint}: the pump's cut-off {pump.cutoff_pa / 1e6:g} MPa is above the "
                        f"valve's p_supply {valve.supply_pressure_pa / 1e6:g} MPa, the most its "
                        "port takes: lower plant.supply.cutoff_pa or raise p_supply")
                if model is not None:
                    model = replace(model, compensated_drop_pa=pump.margin_pa)
                supplied.append(valve)
            else:  # without the supply's inputs it runs on its own supply, off the pump
                supplied.append(None)
            if model is None:
                load_mass = {ports["mass_load"]: reflected[index]} if "mass_load" in ports else None
                try:
                    design, linear, identified = linear_servo(joint, spec, stroke, config,
                                                               conversions, load_mass, fixed)
                except ValueError as error:
                    if load_mass is not None:
                        raise
                    raise ValueError(f"{error}; its FMU has no mass_load input, so it was "
                                     f"identified without the {reflected[index]:,.0f} kg the "
                                     "arm reflects onto its rod at the design pose: map the "
                                     "FMU's load-mass input as ports.mass_load") from None
                designs.append(design)
                linear_models.append(linear)
                identifications.append(identified)
                continue
            if not math.isclose(model.stroke_m, stroke, rel_tol=1e-9):
                raise ValueError(f"{joint}: cylinder stroke {model.stroke_m} m differs from the "
                                 f"linkage's stroke {stroke} m")
            design_stroke = None if config.design_strokes_m is None \
                else config.design_strokes_m[index]
            try:
                designs.append(design_servo_cached(
                    model, config.servo_sample_s, design_stroke, config.servo_damping,
                    config.servo_gain_margin_db, config.servo_phase_margin_deg))
            except ValueError as error:  # the design's own message does not name the joint
                raise ValueError(f"{joint}: {error}") from None
            linear_models.append(None)
            identifications.append(None)
        self.servo_designs: tuple[ServoDesign | LinearServoDesign, ...] = tuple(designs)
        # Per joint: the linear model the servo was designed on (given in the FmuSpec or
        # identified; None for a joint on the CylinderModel servo), and the identification
        # (its per-operating-point fits; None when none was run). For printing and logging.
        self.linear_models: tuple[LinearCylinderModel | None, ...] = tuple(linear_models)
        self.identifications: tuple[CylinderIdentification | None, ...] = \
            tuple(identifications)
        self._design_loads = tuple(design_loads)
        self._supply_parameters = None if pump is None else pump.law_parameters(supplied)
        self._columns = _COLUMNS + (_SUPPLY_COLUMNS if pump is not None else ())
        pile_description = fmu_description("pile", config.pile)
        check_component("pile", "pile", config.pile, pile_description)
        check_fixed_step("pile", pile_description, config.communication_step_s)
        self._profile_names = sorted(
            (v.name for v in pile_description.modelVariables if _PROFILE.match(v.name)),
            key=lambda name: int(_PROFILE.match(name).group(1)))
        pile_values = {**start_values(pile_description), **config.pile.parameters}
        self._grid_limits = (pile_values.get("y_min"), pile_values.get("y_max"))
        if config.start_pose_rad is not None:
            self._start(np.asarray(config.start_pose_rad, dtype=float))

    def _design_strokes(self) -> tuple[float, ...]:
        """The servos' design strokes (m): the config's, else mid-stroke."""
        return tuple(self.config.design_strokes_m or tuple(
            0.5 * table.stroke_m for table in self.coupling.tables))

    def _reflected_design_inertia(self) -> tuple[float, float, float]:
        """M_ii / r_i^2 (kg) of each joint at the servo design pose (design strokes, else
        mid-stroke): the load inertia each servo is designed for."""
        joints = [self.coupling.joint_state(i, s)[0]
                  for i, s in enumerate(self._design_strokes())]
        return tuple(reflected_mass_kg(self.config.geometry, joint, joints)
                     for joint in JOINT_NAMES)

    # ---- life cycle ----------------------------------------------------------------------------

    def _start(self, pose: np.ndarray) -> None:
        """Instantiate the FMUs with the arm at rest at `pose` (3,) rad, in equilibrium with
        its gravity loads."""
        zero = np.zeros((1, 3))
        strokes = self.coupling.stroke_reference(pose[None, :], zero, zero)[0][0]
        kinematics = self.coupling.kinematics(*strokes)
        loads = self.coupling.loads(kinematics, 0.0, 0.0, 0.0)
        tip_y, tip_z, angle = kinematics[3:6]
        cfg = self.config
        components = {j: ("cylinder", spec) for j, spec in zip(JOINT_NAMES, cfg.cylinders,
                                                                 strict=True)}
        components["pile"] = ("pile", cfg.pile)
        diagonal = self.inertia.at(*kinematics[:3], 0.0, 0.0, 0.0, 0.0)[:3]
        start = {j: {"x0": float(s), "F_ext": float(f), "mass_load": m / (r * r)}
                 for j, s, f, m, r in zip(JOINT_NAMES, strokes, loads, diagonal, kinematics[6:9],
                                          strict=True)}
        start["pile"] = {"tip_y": tip_y, "tip_z": tip_z, "bucket_angle": -angle, "dump": 0.0}
        self._master = Master(components, cfg.communication_step_s, start)
        self._start_pose = tuple(float(angle) for angle in pose)
        self._servos = tuple(JointServo(d, load) if isinstance(d, ServoDesign)
                             else LinearJointServo(d)
                             for d, load in zip(self.servo_designs, self._design_loads,
                                                strict=True))
        self._loop = self._step_loop()
        profile, grid = self._profile()
        self._initial_surface = None if profile is None or grid is None else (grid, profile)

    def _step_loop(self) -> NativeCoupling:
        """The step loop (orchestrator.plants.native); `coupling_note` says why its arm
        coupling is explicit (None: implicit, iterated with rollback)."""
        cfg = self.config
        loop = NativeCoupling(self._master, self.coupling, self.inertia, self._servos,
                              self._supply_parameters, cfg.communication_step_s,
                              cfg.servo_sample_s, cfg.coupling_tolerance_rad_s2,
                              cfg.coupling_max_iterations)
        self.coupling_note = loop.note
        return loop

    def temporary_folders(self) -> list[str]:
        """The folders the FMUs are extracted into (removed by close()); for a clean-up that
        cannot close the FMUs (one of them is stuck in a step: orchestrator.campaign.watchdog)."""
        folders = getattr(self._master, "_unzip_dirs", None) or {}
        board = getattr(getattr(self, "_loop", None), "temporary_folders", list)()
        return list(folders.values()) + board

    def close(self) -> None:
        """Free every FMU instance; safe twice."""
        self._closed = True
        try:
            if self._master is not None:
                self._master.close()  # a failed terminate raises once all is freed
        finally:
            getattr(getattr(self, "_loop", None), "close", lambda: None)()

    def __enter__(self) -> SimulatedExcavator:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # ---- one period ----------------------------------------------------------------------------

    def joints_rad(self) -> np.ndarray | None:
        """(3,) rad: where the arm is now (None before the first period without a start pose)."""
        if self._master is None or self._closed:
            return None
        strokes = [self._master[j].outputs[0] for j in JOINT_NAMES]
        return np.array(self.coupling.kinematics(*strokes)[:3])

    def initial_pile_surface(self) -> tuple[np.ndarray, np.ndarray] | None:
        """The pile's surface before the first period: (cell-centre y (n,) m, height z (n,) m);
        None before the FMUs have started or when the pile FMU has no profile outputs."""
        return self._initial_surface

    def run_period(self, reference: JointReference) -> PeriodMeasurement:
        """Track `reference`, weigh the bucket, empty it, and report (see the module doc)."""
        if self._closed:
            raise RuntimeError("the simulated excavator is closed")
        position, velocity, acceleration, t = self._on_grid(reference)
        if self._master is None:
            self._start(position[0])
        now = self.joints_rad()
        gap = np.abs(position[0] - now)
        if np.any(gap > self.config.start_tolerance_rad):
            worst = int(np.argmax(gap))
            raise ValueError(
                f"reference starts {math.degrees(gap[worst]):.2f} deg from the arm's "
                f"{JOINT_NAMES[worst]} angle ({math.degrees(now[worst]):.2f} deg); allowed: "
                f"{math.degrees(self.config.start_tolerance_rad):.2f} deg")
        stroke_ref = self.coupling.stroke_reference(position, velocity, acceleration)
        chunks = [self._track(*stroke_ref)] + self._settle(position[-1], stroke_ref[0][-1])
        table = np.concatenate([rows for rows, _ in chunks])
        joints = np.concatenate([angles for _, angles in chunks])
        if len(table) > len(position):  # the held samples: the reference's last pose
            held = len(table) - len(position)
            position = np.vstack([position, np.repeat(position[-1:], held, axis=0)])
            t = np.arange(len(position)) * self.config.communication_step_s
        signals = {name: table[:, i].copy() for i, name in enumerate(self._columns)}
        for joint in JOINT_NAMES:  # an FMU without e.g. chamber pressures measured none
            for port in self._master[joint].missing_outputs:
                del signals[f"{joint}.{port}"]
        weighed = float(signals["pile.bucket_mass"][-1])
        weighed += self.config.load_cell_noise_kg * float(self._rng.standard_normal())
        self._dump()
        profile, grid = self._profile()
        return PeriodMeasurement(t_s=t, joints_rad=joints, reference_rad=position,
                                 weighed_mass_kg=weighed, signals=signals,
                                 pile_profile_m=profile, pile_grid_m=grid)

    def _on_grid(self, reference: JointReference):
        """Reference position, velocity, acceleration (m, 3) on the communication grid t (m,),
        linear interpolation, held at the end."""
        t_ref = np.asarray(reference.t_s, dtype=float)
        arrays = [np.asarray(a, dtype=float) for a in (
            reference.position_rad, reference.velocity_rad_s, reference.acceleration_rad_s2)]
        if not (np.all(np.isfinite(t_ref)) and all(np.all(np.isfinite(a)) for a in arrays)):
            raise ValueError("the joint reference contains NaN or infinite values")
        if t_ref[0] != 0.0 or np.any(np.diff(t_ref) <= 0.0):
            raise ValueError("the joint reference's t_s must start at 0 s and increase")
        h = self.config.communication_step_s
        count = int(math.ceil(t_ref[-1] / h - 1e-9)) + 1
        t = np.arange(count) * h
        on_grid = [np.column_stack([np.interp(t, t_ref, a[:, j]) for j in range(3)])
                   for a in arrays]
        return (*on_grid, t)

    def _track(self, strokes: np.ndarray, rates: np.ndarray, accelerations: np.ndarray):
        """The step loop of one stroke reference (each (n, 3)): signal rows (n, columns) and
        joint angles (n, 3) (orchestrator.plants.native)."""
        pile = self._master["pile"]
        pile.inputs[pile.input_index["dump"]] = 0.0
        try:
            rows, joints, _, _ = self._loop.track(strokes, rates, accelerations,
                                                  len(self._columns), self._steps,
                                                  self._pile_time)
        finally:
            self._steps, self._pile_time = self._loop.clock
        return rows, joints

    def _settle(self, pose_rad: np.ndarray, stroke_m: np.ndarray) -> list:
        """Hold the strokes `stroke_m` (3,) of the reference's last pose `pose_rad` (3,) while
        the arm is further than half the start tolerance from it, at most SETTLE_MAX_S, in
        steps of SETTLE_CHUNK. Returns the held chunks, (rows, joints) each."""
        h = self.config.communication_step_s
        limit, tolerance = round(SETTLE_MAX_S / h), 0.5 * self.config.start_tolerance_rad
        still = np.zeros((SETTLE_CHUNK, 3))
        held: list = []
        while len(held) * SETTLE_CHUNK < limit \
                and np.max(np.abs(self.joints_rad() - pose_rad)) > tolerance:
            n = min(SETTLE_CHUNK, limit - len(held) * SETTLE_CHUNK)
            held.append(self._track(np.repeat(stroke_m[None, :], n, axis=0), still[:n],
                                    still[:n]))
        return held

    def _dump(self) -> None:
        """One Pile step with `dump` high (tip where it is): the bucket empties."""
        pile, h = self._master["pile"], self.config.communication_step_s
        dump = pile.input_index["dump"]
        pile.inputs[dump] = 1.0
        pile.step(self._pile_time, h)
        self._pile_time += h
        pile.inputs[dump] = 0.0

    def _profile(self) -> tuple[np.ndarray | None, np.ndarray | None]:
        if not self._profile_names:
            return None, None
        profile = self._master["pile"].read(self._profile_names)
        y_min, y_max = self._grid_limits
        if y_min is None or y_max is None:
            return profile, None
        n = len(profile)
        return profile, y_min + (np.arange(n) + 0.5) * (y_max - y_min) / n


@lru_cache(maxsize=8)
def shared_coupling(geometry) -> ArmCoupling:
    """One ArmCoupling per geometry: its tables take a fifth of a second and never change."""
    return ArmCoupling(geometry)
