"""Hydraulics of the two presets and the default configuration of the simulated excavator.

`default_config(preset)` gives the `SimulatedExcavatorConfig` of "paper" or "lab": three
HydraulicCylinder FmuSpecs (boom, stick, bucket) with the cylinder data below, and the Pile
FmuSpec. Each cylinder's `stroke` is its linkage's stroke (plant_models.presets); its initial
stroke `x0` is set by the plant from the start pose.

Link inertia: the cylinder FMU's `mass` is the piston and rod's own. The arm's inertia is the
coupling's (orchestrator.plants.arm_dynamics): each step it feeds the pose's diagonal term of
the arm's mass matrix (plant_models.arm_inertia) reflected onto the rod, M_ii / r_i^2 with
r_i = d(stroke)/d(angle), to the FMU's `mass_load` input, and the off-diagonal and
velocity-product terms into F_ext. The servo is designed on the reflected inertia at
DESIGN_POSE_RAD (lab: LAB_DESIGN_POSE_RAD) plus the piston's (`cylinder_model`).

paper (a 20 t class machine; round figures of the class's specification sheets)
    boom     two 120/85 mm cylinders, modelled as one of the same total areas (bore 169.7 mm,
             rod 120.2 mm); stroke 1.289 m (linkage)
    stick    one 135/95 mm cylinder, stroke 1.472 m (the long stick's); bucket one 115/80 mm,
             stroke 1.038 m
    dead volumes: the lines from the main valve (1" = 25 mm bore) along the arm plus end
             clearance: boom 2 x 1 L (about 2 m of line each), stick 3 L (6 m), bucket 4.5 L
             (9 m, the line runs along boom and stick)
    beta 1.0 GPa, supply 35 MPa (the main relief and pump cut-off of a CAT 320; the class
             sets 34.3-37.3 MPa), tank 0.3 MPa (the return line's back-pressure check), port
             reliefs 39 MPa (set above the main relief, as overload reliefs of the class are)
    make-up  the anti-cavitation checks of the port relief cartridges pass the pump's whole
             flow: k_makeup 3e-8 m^3/(s Pa), 450 L/min at the 0.25 MPa the return line's back
             pressure leaves above a chamber at 0 Pa (the FMU's default, 5e-9, passes 75 L/min:
             the stick's piston side then cavitated 17 % of the paper run)
    regeneration the stick section's arm-in regeneration (rod side to piston side through a
             check, opened with the extending spool; Kawasaki KMX and Rexroth M7 main valves of
             the class have it): a passage half the meter-in edge's size (regeneration_ratio
             0.5). It cuts the pump's energy by 2 % on the paper run (bench/hydraulics.py) and
             feeds the piston side from the rod side's return rather than the tank line. Boom
             lowering regeneration (piston side to rod side) is left out: the boom's rod side
             never empties (0.03 % of the samples before the make-up was sized)
    valve    rated flow per metering edge at 3.5 MPa: boom 200 L/min (two pumps join for boom
             raising, about 2 x 220 L/min on the class), stick 160 L/min, bucket 100 L/min:
             unloaded speeds 0.41, 0.51, 0.44 m/s, about twice the paper trajectory's peak
             stroke rates (0.10, 0.22, 0.19 m/s at D = (-9, -0.1) m, case 2)
    friction Coulomb 2 kN and viscous 5 kN s/m per cylinder (FMU defaults; doubled on the boom)
    rod, piston and oil: boom 2 x 150 kg, stick 200 kg, bucket 120 kg

lab (the paper's lab excavator, section 3.3: 20 bar maximum oil pressure, 100 ml of oil,
    10 kg maximum load, BLDC pump; no cylinder data are published)
    boom 25/12 mm, stick 20/10 mm, bucket 16/8 mm: a 25 mm boom cylinder at 20 bar (982 N)
             holds the scaled arm plus 7.4 kg in the bucket at the digging pose D, more closer in
    dead volumes 6 mL per side (0.5 m of 4 mm bore hose); the swept piston volumes (41, 39 and
             18 mL) are within the 100 mL of oil
    beta 0.7 GPa (the low end of the usual range: thin flexible hoses), supply 2.0 MPa (the
             20 bar maximum), tank 0.05 MPa, port relief 2.2 MPa
    valve    rated at 0.5 MPa per edge (small proportional valves are rated at 1 MPa across two
             edges): boom 0.5 L/min, stick 0.6 L/min, bucket 0.3 L/min; unloaded speeds 28, 53,
             41 mm/s, 2.5-3 times the lab trajectory's peak stroke rates; 1.4 L/min in all, a
             small gear pump's flow
    friction Coulomb 10 N (about 1-2 % of the stall forces), smoothing speed 1 mm/s, viscous
             50 N s/m; rod and piston 0.05 kg
    Pile: the paper pile scaled like the arm (LAB_SCALE) in y, z, heap and soil-force speed ramp;
    a slice of the machine's 0.24 m width of 1600 kg/m^3 sand. The bucket is sized by the
    published 10 kg maximum load: heaped, it holds 10 kg of the sand (6.25 L). (The paper arm's
    bucket scaled by LAB_SCALE would hold 1.4 L, 2.2 kg: too small for Figure 15, whose first
    period falls 3.5 kg short of the target.)
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from plant_models import presets
from plant_models.cylinder_model import CylinderModel
from plant_models.geometry import ExcavatorGeometry, arm_points
from plant_models.joint_strokes import moment_arm_m, stroke_from_joint_angle
from plant_models.linkage import JOINT_NAMES
from plant_models.model_spec import FmuSpec
from plant_models.sim_config import SimulatedExcavatorConfig
from plant_models.supply import M3_S_PER_L_MIN

# The paper scenario's first-period pose at D = (-9, -0.1) m (planner.digging_path,
# paper_joint_via_points()[2]).
DESIGN_POSE_RAD: tuple[float, float, float] = (
    math.radians(14.46504987), math.radians(-53.85275241), math.radians(-30.20802183))
# The lab's: its arm is the standard 2.9 m stick arm scaled and its path the paper path scaled,
# so the standard arm's pose at D = (-9, -0.1) m.
LAB_DESIGN_POSE_RAD: tuple[float, float, float] = (
    math.radians(10.4633846), math.radians(-44.33907499), math.radians(-37.17639685))
_DESIGN_POSES = {"paper": DESIGN_POSE_RAD, "lab": LAB_DESIGN_POSE_RAD}

_LPM = M3_S_PER_L_MIN


def _paper_cylinders() -> dict[str, dict[str, float]]:
    common = {"beta": 1.0e9, "p_supply": 35.0e6, "p_tank": 0.3e6, "p_relief": 39.0e6,
              "k_relief": 5.0e-9, "k_makeup": 3.0e-8, "dp_rated": 3.5e6, "dp_laminar": 1.0e5,
              "v_coulomb": 0.01}
    twin = math.sqrt(2.0)  # two boom cylinders in parallel: same total areas
    return {
        "boom": {**common, "bore": 0.120 * twin, "rod": 0.085 * twin, "V_dead_A": 2.0e-3,
                 "V_dead_B": 2.0e-3, "q_rated": 200.0 * _LPM, "F_coulomb": 4000.0,
                 "b_viscous": 10000.0, "mass": 300.0},
        "stick": {**common, "bore": 0.135, "rod": 0.095, "V_dead_A": 3.0e-3, "V_dead_B": 3.0e-3,
                  "q_rated": 160.0 * _LPM, "F_coulomb": 2000.0, "b_viscous": 5000.0,
                  "mass": 200.0, "regeneration_ratio": 0.5},
        "bucket": {**common, "bore": 0.115, "rod": 0.080, "V_dead_A": 4.5e-3,
                   "V_dead_B": 4.5e-3, "q_rated": 100.0 * _LPM, "F_coulomb": 2000.0,
                   "b_viscous": 5000.0, "mass": 120.0},
    }


def _lab_cylinders() -> dict[str, dict[str, float]]:
    common = {"beta": 0.7e9, "p_supply": 2.0e6, "p_tank": 0.05e6, "p_relief": 2.2e6,
              "k_relief": 5.0e-11, "dp_rated": 0.5e6, "dp_laminar": 5.0e4, "V_dead_A": 6.0e-6,
              "V_dead_B": 6.0e-6, "F_coulomb": 10.0, "v_coulomb": 0.001, "b_viscous": 50.0,
              "mass": 0.05}
    return {
        "boom": {**common, "bore": 0.025, "rod": 0.012, "q_rated": 0.5 * _LPM},
        "stick": {**common, "bore": 0.020, "rod": 0.010, "q_rated": 0.6 * _LPM},
        "bucket": {**common, "bore": 0.016, "rod": 0.008, "q_rated": 0.3 * _LPM},
    }


LAB_SAND_DENSITY = 1600.0  # kg/m^3, the lab sandbox's sand (the Pile FMU's default soil)


def _lab_pile() -> dict[str, float]:
    s = presets.LAB_SCALE
    return {"y_min": -13.0 * s, "y_max": -2.0 * s, "z_floor": -5.0 * s,
            "heap_center_y": -9.0 * s, "heap_half_width": 2.0 * s,
            "slice_width": presets.LAB_WIDTH_M, "bucket_width": presets.LAB_WIDTH_M,
            "edge_thickness": 0.04 * s,
            "density": LAB_SAND_DENSITY, "capacity": presets.LAB_MAX_LOAD_KG / LAB_SAND_DENSITY,
            "mobilization_length": 0.02 * s}


# Communication step per preset (s), also the servo's sample time. paper: 10 ms keeps every
# joint's margins with the pressure feedback's damping (design_servo; the bucket's mode,
# 54 rad/s, gets 0.45 instead of 0.7) at a fifth of the cost of 2 ms. lab: the small
# cylinders' hydraulic modes (290-1000 rad/s: link masses scale with LAB_SCALE^3, piston areas
# much less) need 1 ms for the pressure feedback to damp them.
COMMUNICATION_STEP_S = {"paper": 0.01, "lab": 0.001}
# The servo's sample time (its ECU's cycle): 10 ms on the 20 t machine; the lab's 16 mm cylinders
# resonate near 100 Hz, beyond what a 10 ms servo damps, so their controller runs at 1 ms.
SERVO_SAMPLE_S = {"paper": 0.01, "lab": 0.001}


def link_inertia_diagonal(geometry: ExcavatorGeometry, joints, payload_kg: float = 0.0
                          ) -> np.ndarray:
    """Diagonal of the arm's mass matrix (3,) kg m^2 at joints (3,) rad: the inertia each joint
    turns with the joints after it locked. Links: point masses at their centres of mass plus a
    uniform rod's m L^2 / 12 (L the link's pin-to-pin length); payload_kg at the bucket's."""
    points = arm_points(geometry, joints)
    links = (
        ("boom_com", geometry.boom_mass.mass_kg, geometry.boom_length_m),
        ("stick_com", geometry.stick_mass.mass_kg, geometry.stick_length_m),
        ("bucket_com", geometry.bucket_mass.mass_kg + payload_kg, geometry.bucket_length_m),
    )
    inertia = np.zeros(3)
    for index, pin in enumerate(("boom_foot", "stick_pin", "bucket_pin")):
        for com, mass, length in links[index:]:
            offset = points[com] - points[pin]
            inertia[index] += mass * (length * length / 12.0 + float(offset @ offset))
    return inertia


def reflected_mass_kg(geometry: ExcavatorGeometry, joint: str, joints) -> float:
    """Link inertia of `joint` reflected onto its cylinder's rod, M_ii / r^2 (kg), at joints
    (3,) rad; r = d(stroke)/d(angle) (m/rad)."""
    index = JOINT_NAMES.index(joint)
    arm = moment_arm_m(geometry, joint, float(joints[index]))
    return float(link_inertia_diagonal(geometry, joints)[index] / (arm * arm))


def cylinder_parameters(preset: str) -> dict[str, dict[str, float]]:
    """HydraulicCylinder FMU parameters per joint for `preset` ("paper", "lab"), stroke and the
    reflected link inertia included (x0 is left to the plant)."""
    tables = {"paper": _paper_cylinders, "lab": _lab_cylinders}
    if preset not in tables:
        raise ValueError(f"unknown preset {preset!r}; known presets: paper, lab")
    geometry = presets.get(preset)
    strokes = (geometry.boom_cylinder.stroke_m, geometry.stick_cylinder.stroke_m,
               geometry.bucket_linkage.stroke_m)
    parameters = tables[preset]()
    for joint, stroke in zip(JOINT_NAMES, strokes, strict=True):
        parameters[joint]["stroke"] = stroke
    return parameters


def design_cylinder_parameters(preset: str) -> dict[str, dict[str, float]]:
    """`cylinder_parameters` with the arm's inertia at the design pose folded into `mass`: one
    cylinder FMU alone that moves like the servo's model (`cylinder_model`), for stand-alone
    checks of the servo and of identification."""
    geometry = presets.get(preset)
    parameters = cylinder_parameters(preset)
    for joint in JOINT_NAMES:
        parameters[joint]["mass"] += reflected_mass_kg(geometry, joint, _DESIGN_POSES[preset])
    return parameters


def cylinder_model(preset: str, joint: str) -> CylinderModel:
    """The servo's model of `joint`'s cylinder in `preset`: our FMU's parameters, with the link
    inertia reflected onto the rod at the design pose added to the piston's mass (the FMU gets
    the pose's reflected inertia each step through its `mass_load` input)."""
    model = CylinderModel.from_fmu_parameters(cylinder_parameters(preset)[joint])
    reflected = reflected_mass_kg(presets.get(preset), joint, _DESIGN_POSES[preset])
    return replace(model, mass_kg=model.mass_kg + reflected)


def design_strokes_m(preset: str) -> tuple[float, float, float]:
    """Strokes (m) of boom, stick and bucket at the design pose of `preset` (DESIGN_POSE_RAD,
    LAB_DESIGN_POSE_RAD)."""
    geometry = presets.get(preset)
    return tuple(stroke_from_joint_angle(geometry, joint, angle)
                 for joint, angle in zip(JOINT_NAMES, _DESIGN_POSES[preset], strict=True))


def default_config(preset: str) -> SimulatedExcavatorConfig:
    """The simulated excavator of `preset` ("paper" or "lab"), see the module docstring.

    The Pile of "paper" keeps the FMU's own defaults (its density x width is already scaled to
    the paper's dug masses); the plant starts at the first reference's first sample.
    """
    cylinders = cylinder_parameters(preset)
    pile = {} if preset == "paper" else _lab_pile()
    return SimulatedExcavatorConfig(
        geometry=presets.get(preset),
        boom=FmuSpec("HydraulicCylinder", cylinders["boom"]),
        stick=FmuSpec("HydraulicCylinder", cylinders["stick"]),
        bucket=FmuSpec("HydraulicCylinder", cylinders["bucket"]),
        pile=FmuSpec("Pile", pile),
        communication_step_s=COMMUNICATION_STEP_S[preset],
        servo_sample_s=SERVO_SAMPLE_S[preset],
        design_strokes_m=design_strokes_m(preset),
    )
