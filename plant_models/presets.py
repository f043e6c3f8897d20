"""Named excavator geometries: `paper` (a full-size machine for the paper's simulation) and `lab`
(the paper's laboratory excavator, section 3.3).

Use `get(name)`; `NAMES` lists the presets. Conventions and frames: `plant_models.geometry`.

paper
    A 20 t class machine with a long stick. Boom 5.7 m and bucket 1.5 m are typical published
    figures of that class (e.g. 5.7 m "reach" booms of 20-22 t excavators). The class's standard
    stick is 2.9 m (STANDARD_STICK_LENGTH_M, the arm the lab preset scales); most makers also offer
    a short and a long stick, and this machine carries a long one of 3.18 m
    (PAPER_STICK_LENGTH_M; the long sticks of the class are about 3.0-3.2 m). Boom foot at
    y = -0.5 m, z = 1.9 m (about 0.5 m ahead of the swing centre and 1.9 m above ground, typical
    of the class). Joint ranges: boom -50..+60 deg, stick -152.3..-25.1 deg, bucket -135..+45 deg
    (180 deg of bucket rotation); they give a maximum digging depth of 7.14 m and a maximum tip
    height of 10.13 m (standard-stick figures of the class: 6.6-6.7 m and 9.5-10 m).
    The paper gives no machine data, so the stick and its range were chosen for the paper's
    scenario (section 3.2: the reach limit after about ten periods of digging straight down at
    y = -9 m, then a shift toward the machine): the planned spline at y = -9 m leaves the stick's
    outer stop from z_D = -2.30 m (planner.period_plan; the via-points alone from -2.94 m),
    which the calibrated paper scenario reaches after period 8; the inner stop leaves room for
    the scenario's shift. With the standard 2.9 m stick the limit is at z_D = -1.36 m (reached in
    period 6).
    Cylinder mounts were chosen by a search for realistic cylinders over the standard ranges
    (retracted length / stroke: boom 1.95 / 1.29 m, stick 2.11 / 1.44 m, bucket 1.74 / 1.04 m; 20 t
    class cylinders have strokes of about 1.3, 1.5 and 1.1 m) with linkage transmission angles of
    at least 25 deg; the end stops are then the joint limits. The long stick keeps the standard
    stick cylinder's mounts; its own cylinder (retracted 2.07 m, stroke 1.47 m, within the class's
    1.5 m) has the end stops PAPER_STICK_RANGE_DEG.
    Masses are estimates for the class (front attachment about 3.5 t of a 20 t machine: boom with
    its cylinders 1800 kg, stick with the bucket cylinder 900 kg, 1.0 m^3 bucket with linkage
    800 kg); centres of mass near the middle of each link, slightly on the side of its cylinders.
    The paper's dug masses (8.5-30 kg) fit a lab-scale bucket, not this one: the pile model scales
    density x width instead (see ARCHITECTURE).

lab
    The paper's laboratory excavator (section 3.3: length 1.15 m, height 0.832 m, digging depth
    0.414 m, 10 kg maximum load, 20 bar maximum oil pressure). Its arm dimensions are not published,
    so the standard (2.9 m stick) arm is scaled by LAB_SCALE = 0.0855, chosen so the maximum tip
    height is the published 0.832 m (read as the tip's highest point); the boom's lower limit is
    raised to about -24.3 deg (a shorter boom cylinder stroke) so the maximum digging depth is the
    published 0.414 m.
    Masses scale with LAB_SCALE^3 (about 0.6 g per kg). The 1.15 m length includes the
    undercarriage, which this planar arm model does not describe; the 10 kg load and 20 bar belong
    to the payload and hydraulics models (plant_models.hydraulics: the bucket holds the 10 kg
    maximum load of sand heaped, over the machine's 0.24 m width).
"""

from __future__ import annotations

import math
from dataclasses import replace

from plant_models.geometry import ExcavatorGeometry, LinkMass
from plant_models.linkage import BucketLinkage, PinJointCylinder

NAMES = ("paper", "lab")
# Paper section 3.3: the lab excavator's published envelope and load.
LAB_LENGTH_M = 1.15
LAB_HEIGHT_M = 0.832
LAB_WIDTH_M = 0.24
LAB_DIGGING_DEPTH_M = 0.414
LAB_MAX_LOAD_KG = 10.0
# Lab arm / standard arm lengths: the standard arm's maximum tip height (9.736 m) scaled to
# LAB_HEIGHT_M.
LAB_SCALE = LAB_HEIGHT_M / 9.736
# The class's standard stick (the lab arm scales the arm with it) and the paper machine's long
# stick with the joint range (inner, outer stop) of its cylinder; see the module docstring.
STANDARD_STICK_LENGTH_M = 2.9
PAPER_STICK_LENGTH_M = 3.18
PAPER_STICK_RANGE_DEG = (-152.3, -25.1)


def _standard_arm(name: str) -> ExcavatorGeometry:
    """The class's standard 2.9 m stick arm (the lab arm scales it)."""
    return ExcavatorGeometry(
        name=name,
        boom_length_m=5.7,
        stick_length_m=STANDARD_STICK_LENGTH_M,
        bucket_length_m=1.5,
        boom_foot_m=(-0.5, 1.9),
        boom_cylinder=PinJointCylinder(
            prev_mount_m=(0.16, -0.78),
            next_mount_m=(2.56, 0.22),
            retracted_length_m=1.954,
            stroke_m=1.289,
            branch=1,
        ),
        stick_cylinder=PinJointCylinder(
            prev_mount_m=(-2.66, 0.84),
            next_mount_m=(-0.79, 0.24),
            retracted_length_m=2.109,
            stroke_m=1.443,
            branch=-1,
        ),
        bucket_linkage=BucketLinkage(
            cylinder_mount_m=(-2.46, 0.45),
            rocker_pivot_m=(-0.30, 0.0),
            rocker_length_m=0.70,
            link_length_m=0.645,
            bucket_pin_offset_m=(0.11, 0.30),
            retracted_length_m=1.743,
            stroke_m=1.038,
            rocker_side=1,
            cylinder_side=1,
            link_side=-1,
        ),
        boom_mass=LinkMass(mass_kg=1800.0, com_m=(2.6, 0.25)),
        stick_mass=LinkMass(mass_kg=900.0, com_m=(1.1, 0.15)),
        bucket_mass=LinkMass(mass_kg=800.0, com_m=(0.75, 0.35)),
    )


def _paper() -> ExcavatorGeometry:
    standard = _standard_arm("paper")
    stick = standard.stick_cylinder
    # The long stick's cylinder: the standard one's mounts, with the end stops (joint angles)
    # of PAPER_STICK_RANGE_DEG; its lengths follow from the mounts.
    inner, outer = (stick.length_from_angle(math.radians(a)) for a in PAPER_STICK_RANGE_DEG)
    retracted, extended = sorted((inner, outer))
    long_stick = PinJointCylinder(stick.prev_mount_m, stick.next_mount_m, retracted,
                                  extended - retracted, stick.branch)
    return replace(standard, stick_length_m=PAPER_STICK_LENGTH_M, stick_cylinder=long_stick)


def _scaled(point: tuple[float, float], scale: float) -> tuple[float, float]:
    return (point[0] * scale, point[1] * scale)


def _lab() -> ExcavatorGeometry:
    standard = _standard_arm("lab")
    s = LAB_SCALE
    boom = standard.boom_cylinder
    boom_prev, boom_next = _scaled(boom.prev_mount_m, s), _scaled(boom.next_mount_m, s)
    # A shorter boom stroke, retracted at the boom angle whose deepest pose (stick and bucket
    # hanging straight down) reaches the published digging depth.
    hanging = (standard.stick_length_m + standard.bucket_length_m) * s
    foot_z = standard.boom_foot_m[1] * s
    lowest_boom = math.asin((hanging - LAB_DIGGING_DEPTH_M - foot_z) / (standard.boom_length_m * s))
    lowest = PinJointCylinder(boom_prev, boom_next, 1.0, 1.0).length_from_angle(lowest_boom)
    fully_raised = (boom.retracted_length_m + boom.stroke_m) * s
    stick, bucket = standard.stick_cylinder, standard.bucket_linkage
    return ExcavatorGeometry(
        name="lab",
        boom_length_m=standard.boom_length_m * s,
        stick_length_m=standard.stick_length_m * s,
        bucket_length_m=standard.bucket_length_m * s,
        boom_foot_m=_scaled(standard.boom_foot_m, s),
        boom_cylinder=PinJointCylinder(
            boom_prev, boom_next, lowest, fully_raised - lowest, boom.branch
        ),
        stick_cylinder=PinJointCylinder(
            _scaled(stick.prev_mount_m, s),
            _scaled(stick.next_mount_m, s),
            stick.retracted_length_m * s,
            stick.stroke_m * s,
            stick.branch,
        ),
        bucket_linkage=BucketLinkage(
            cylinder_mount_m=_scaled(bucket.cylinder_mount_m, s),
            rocker_pivot_m=_scaled(bucket.rocker_pivot_m, s),
            rocker_length_m=bucket.rocker_length_m * s,
            link_length_m=bucket.link_length_m * s,
            bucket_pin_offset_m=_scaled(bucket.bucket_pin_offset_m, s),
            retracted_length_m=bucket.retracted_length_m * s,
            stroke_m=bucket.stroke_m * s,
            rocker_side=bucket.rocker_side,
            cylinder_side=bucket.cylinder_side,
            link_side=bucket.link_side,
        ),
        boom_mass=LinkMass(
            standard.boom_mass.mass_kg * s**3, _scaled(standard.boom_mass.com_m, s)
        ),
        stick_mass=LinkMass(
            standard.stick_mass.mass_kg * s**3, _scaled(standard.stick_mass.com_m, s)
        ),
        bucket_mass=LinkMass(
            standard.bucket_mass.mass_kg * s**3, _scaled(standard.bucket_mass.com_m, s)
        ),
    )


_BUILDERS = {"paper": _paper, "lab": _lab}
_CACHE: dict[str, ExcavatorGeometry] = {}


def get(name: str) -> ExcavatorGeometry:
    """The preset geometry called `name` ("paper" or "lab"); ValueError for an unknown name."""
    if name not in _BUILDERS:
        raise ValueError(f"unknown excavator preset {name!r}; known presets: {', '.join(NAMES)}")
    if name not in _CACHE:
        _CACHE[name] = _BUILDERS[name]()
    return _CACHE[name]
