"""The four-stage digging path of one period (paper section 2.1, Figs. 2-3) and its via-points.

Five via-points bound the paper's four stages (frames and angles: `plant_models.geometry`):

0. start    - the arm at rest at the start pose (tip position, absolute bucket angle).
1. entry    - stage 1 opens the bucket and brings the tip to the surface entry point, entry_offset_m
              beyond D (farther from the machine) at the nominal surface z = entry_height_m, with
              the absolute bucket (attack) angle entry_bucket_angle_rad. The planner never sees the
              pile: the surface is nominal.
2. deepest  - stage 2 keeps the bucket JOINT of the entry pose and drags the tip to D with boom and
              stick. The bucket joint being given, stick and bucket form one rigid link from the
              stick pin to the tip, so boom and stick follow from a two-link inverse kinematics with
              the tip at D (`inverse_kinematics_with_bucket_joint`); the absolute bucket angle at D
              is whatever that gives. D is the deepest via-point (with the bucket line above
              -90 deg at D, the tip's arc while closing can dip up to L_bucket (1 + sin angle)
              below it between via-points).
3. closed   - stage 3 closes the bucket joint to closed_bucket_joint_rad, boom and stick fixed (a
              pose set in joint space).
4. lifted   - stage 4 keeps the bucket joint closed and lifts the tip out to lift_tip_m, a fixed
              place above ground near the machine (fixed, not relative to D, so that it stays
              within reach when D moves toward the machine).

A pose out of reach or beyond a joint limit makes the path `Unreachable`, naming the via-point.

Paper path shape and the paper's 16.17 s. Entry 0.5 m beyond D at z = 0 with the bucket line at
-62 deg sets where the stick reaches its outer limit below y = -9 m (via-points: z_D = -2.94 m;
the timed spline already at -2.30 m, see plant_models.presets); the bucket closes to -120 deg,
15 deg short of its curl stop; the full bucket is lifted to (-6, 2) m; the start pose is the
lifted pose (tip (-6, 2) m, bucket line at -170.64 deg on the paper arm), so every period ends
where it began.
The paper's case 1 (k_T = 1, k_J = 0, Table 1 limits) takes 16.17 s; planner.trajectory plans
this path in 8.3 s (case 2: 12.7 s; paper 18.38 s), and no choice of start pose, lift pose and
closed bucket angle brings it near 16 s: a random search over them found at most 11.0 s and a
period that starts and ends fully tucked 12.7 s (both on the standard 2.9 m stick). With Table
1's limits a single 180 deg rest-to-rest move takes 5.9 s; only via-points that reverse every
joint across its whole range at every via-point (17.5 s) get past 16 s, which is no digging
path. The paper's via-points are unknown, and the shape is kept physical rather than fitted to
the time.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from plant_models import presets
from plant_models.geometry import (
    ExcavatorGeometry,
    Unreachable,
    inverse_kinematics,
    inverse_kinematics_with_bucket_joint,
)

VIA_POINT_NAMES = ("start", "entry", "deepest", "closed", "lifted")
PAPER_DEEPEST_POINT_M = (-9.0, -0.1)  # paper section 3.2: default D = (y_D, z_D)
# The lab's default D: the paper's, scaled like the lab arm (plant_models.presets.LAB_SCALE).
LAB_DEEPEST_POINT_M = tuple(v * presets.LAB_SCALE for v in PAPER_DEEPEST_POINT_M)


@dataclass(frozen=True)
class PathShape:
    """Shape of the digging path around D (m, rad; absolute angles as in plant_models.geometry).

    start_tip_m: (y, z) of the tip where each period starts, at rest.
    start_bucket_angle_rad: absolute bucket angle at the start.
    entry_offset_m: horizontal distance from D out to the surface entry point (> 0: farther out).
    entry_height_m: z of the nominal surface at entry.
    entry_bucket_angle_rad: absolute bucket angle at entry (bucket opened, the attack angle).
    closed_bucket_joint_rad: bucket joint angle once closed (stages 3 and 4).
    lift_tip_m: (y, z) of the tip once lifted out (stage 4 end).
    """

    start_tip_m: tuple[float, float]
    start_bucket_angle_rad: float
    entry_offset_m: float
    entry_height_m: float
    entry_bucket_angle_rad: float
    closed_bucket_joint_rad: float
    lift_tip_m: tuple[float, float]

    def __post_init__(self) -> None:
        for field_name, value in vars(self).items():
            if not np.all(np.isfinite(value)):
                raise ValueError(f"PathShape.{field_name} must be finite, got {value!r}")
        if self.entry_offset_m < 0.0:
            raise ValueError(f"PathShape.entry_offset_m must be >= 0 m, got {self.entry_offset_m}")

    @staticmethod
    def preset(name: str) -> PathShape:
        """Default path shape for the geometry preset `name` ("paper" or "lab").

        paper: see the module docstring. lab: the paper shape with lengths scaled by LAB_SCALE,
        starting at the lifted pose of the lab's (scaled standard) arm.
        """
        if name == "paper":
            return PAPER_PATH_SHAPE
        if name == "lab":
            standard = replace(PAPER_PATH_SHAPE,
                               start_bucket_angle_rad=STANDARD_ARM_START_BUCKET_ANGLE_RAD)
            return _scaled(standard, presets.LAB_SCALE)
        raise ValueError(f"unknown path shape preset {name!r}; known presets: paper, lab")


# The bucket line at the lifted pose (tip (-6, 2) m, bucket joint -120 deg) of the paper arm
# (3.18 m stick) and of the standard 2.9 m stick arm the lab arm scales: the start pose is the
# lifted pose, so every period ends where it began.
PAPER_START_BUCKET_ANGLE_RAD = math.radians(-170.64)
STANDARD_ARM_START_BUCKET_ANGLE_RAD = math.radians(-169.33)

PAPER_PATH_SHAPE = PathShape(
    start_tip_m=(-6.0, 2.0),
    start_bucket_angle_rad=PAPER_START_BUCKET_ANGLE_RAD,
    entry_offset_m=0.5,
    entry_height_m=0.0,
    entry_bucket_angle_rad=math.radians(-62.0),
    closed_bucket_joint_rad=math.radians(-120.0),
    lift_tip_m=(-6.0, 2.0),
)


def _scaled(shape: PathShape, scale: float) -> PathShape:
    return PathShape(
        start_tip_m=(shape.start_tip_m[0] * scale, shape.start_tip_m[1] * scale),
        start_bucket_angle_rad=shape.start_bucket_angle_rad,
        entry_offset_m=shape.entry_offset_m * scale,
        entry_height_m=shape.entry_height_m * scale,
        entry_bucket_angle_rad=shape.entry_bucket_angle_rad,
        closed_bucket_joint_rad=shape.closed_bucket_joint_rad,
        lift_tip_m=(shape.lift_tip_m[0] * scale, shape.lift_tip_m[1] * scale),
    )


@dataclass(frozen=True)
class TaskViaPoint:
    """One via-point as the path defines it.

    tip_m: tip (y, z) m, or None where the pose is set in joint space (closed).
    bucket_angle_rad: absolute bucket angle (rad) where the path sets it (start, entry), else None.
    bucket_joint_rad: bucket joint (rad) where the path holds it at a given value (closed,
        lifted), else None (deepest holds the entry pose's bucket joint, known only after IK).
    """

    name: str
    tip_m: tuple[float, float] | None
    bucket_angle_rad: float | None
    bucket_joint_rad: float | None


def task_via_points(
    deepest_point: tuple[float, float], shape: PathShape
) -> tuple[TaskViaPoint, ...]:
    """The five via-points (start, entry, deepest, closed, lifted) around D = deepest_point
    (y, z) m."""
    y_d, z_d = _check_point(deepest_point)
    closed = shape.closed_bucket_joint_rad
    return (
        TaskViaPoint("start", tuple(shape.start_tip_m), shape.start_bucket_angle_rad, None),
        TaskViaPoint(
            "entry", (y_d - shape.entry_offset_m, shape.entry_height_m),
            shape.entry_bucket_angle_rad, None,
        ),
        TaskViaPoint("deepest", (y_d, z_d), None, None),
        TaskViaPoint("closed", None, None, closed),
        TaskViaPoint("lifted", tuple(shape.lift_tip_m), None, closed),
    )


def _check_point(point) -> tuple[float, float]:
    y, z = (float(v) for v in point)
    if not (math.isfinite(y) and math.isfinite(z)):
        raise ValueError(f"deepest point must be finite (y, z) m, got {point!r}")
    return y, z


def joint_via_points(
    geometry: ExcavatorGeometry, deepest_point: tuple[float, float], shape: PathShape
) -> np.ndarray | Unreachable:
    """Joint via-points (5, 3) rad [boom, stick, bucket] of the path around D = deepest_point
    (y, z) m, or `Unreachable` naming the first via-point out of reach or beyond a limit."""
    start, entry, deepest, closed, lifted = task_via_points(deepest_point, shape)
    solved = []

    def fail(point: TaskViaPoint, result: Unreachable) -> Unreachable:
        return Unreachable(f"{point.name} via-point: {result.reason}")

    for point in (start, entry):
        joints = inverse_kinematics(geometry, *point.tip_m, point.bucket_angle_rad)
        if isinstance(joints, Unreachable):
            return fail(point, joints)
        solved.append(joints)
    at_d = inverse_kinematics_with_bucket_joint(geometry, *deepest.tip_m, solved[1][2])
    if isinstance(at_d, Unreachable):
        return fail(deepest, at_d)
    solved.append(at_d)
    low, high = geometry.joint_limits_rad[2]
    if not low <= closed.bucket_joint_rad <= high:
        return fail(closed, Unreachable(
            f"bucket angle {math.degrees(closed.bucket_joint_rad):.2f} deg beyond its limits "
            f"[{math.degrees(low):.2f}, {math.degrees(high):.2f}] deg"
        ))
    solved.append(np.array([at_d[0], at_d[1], closed.bucket_joint_rad]))
    up = inverse_kinematics_with_bucket_joint(geometry, *lifted.tip_m, lifted.bucket_joint_rad)
    if isinstance(up, Unreachable):
        return fail(lifted, up)
    solved.append(up)
    return np.array(solved)


def path_is_reachable(
    geometry: ExcavatorGeometry, shape: PathShape, y_d: float, z_d: float
) -> bool:
    """True if every via-point of the path around D = (y_d, z_d) m is reachable within limits."""
    return not isinstance(joint_via_points(geometry, (y_d, z_d), shape), Unreachable)


def is_reachable(geometry: ExcavatorGeometry, shape: PathShape) -> Callable[[float, float], bool]:
    """`path_is_reachable` bound to one geometry and shape: (y_D, z_D) m -> bool."""
    return lambda y_d, z_d: path_is_reachable(geometry, shape, y_d, z_d)


def paper_joint_via_points() -> np.ndarray:
    """Joint via-points (5, 3) rad of the paper scenario's first period: D0 = (-9, -0.1) m, the
    `paper` geometry and path shape."""
    paper = presets.get("paper")
    result = joint_via_points(paper, PAPER_DEEPEST_POINT_M, PathShape.preset("paper"))
    if isinstance(result, Unreachable):
        raise RuntimeError(f"paper preset cannot reach its own default path: {result.reason}")
    return result
