"""A machine's joints through its cylinders: stroke <-> joint angle, joint rate per stroke rate,
and the moment arm that maps a cylinder force to a joint torque.

The mechanisms themselves (law-of-cosines pin-joint cylinders, the bucket's four-bar) are in
`plant_models.linkage`; this module applies them to the cylinders of an `ExcavatorGeometry`.
Strokes in m, angles in rad, moment arms in m/rad.
"""

from __future__ import annotations

import math

from plant_models.geometry import ExcavatorGeometry
from plant_models.linkage import JOINT_NAMES


def _joint_index(joint: str) -> int:
    if joint not in JOINT_NAMES:
        raise ValueError(f"joint must be one of {JOINT_NAMES}, got {joint!r}")
    return JOINT_NAMES.index(joint)


def _cylinder(geometry: ExcavatorGeometry, joint: str):
    return (geometry.boom_cylinder, geometry.stick_cylinder, geometry.bucket_linkage)[
        _joint_index(joint)
    ]


def joint_angle_from_stroke(geometry: ExcavatorGeometry, joint: str, stroke_m: float) -> float:
    """Joint angle (rad) of `joint` ("boom", "stick" or "bucket") at cylinder stroke stroke_m (m).

    Raises ValueError if stroke_m is outside [0, stroke] of that cylinder.
    """
    cylinder = _cylinder(geometry, joint)
    if not 0.0 <= stroke_m <= cylinder.stroke_m:
        raise ValueError(
            f"{joint} stroke {stroke_m} m outside [0, {cylinder.stroke_m}] m"
        )
    angle = cylinder.angle_from_length(cylinder.retracted_length_m + stroke_m)
    if angle is None:
        raise ValueError(f"{joint} linkage cannot be assembled at stroke {stroke_m} m")
    return angle


def stroke_from_joint_angle(geometry: ExcavatorGeometry, joint: str, angle_rad: float) -> float:
    """Cylinder stroke (m) of `joint` at joint angle angle_rad (rad).

    Raises ValueError if the angle is outside the joint limits (the cylinder's end stops).
    """
    index = _joint_index(joint)
    low, high = geometry.joint_limits_rad[index]
    if not low <= angle_rad <= high:
        raise ValueError(
            f"{joint} angle {math.degrees(angle_rad):.3f} deg outside "
            f"[{math.degrees(low):.3f}, {math.degrees(high):.3f}] deg"
        )
    cylinder = _cylinder(geometry, joint)
    stroke = cylinder.length_from_angle(angle_rad) - cylinder.retracted_length_m
    # End stops are the joint limits: clip the round-off of a limit angle onto the stroke range.
    return min(max(stroke, 0.0), cylinder.stroke_m)


def joint_rate_per_stroke_rate(geometry: ExcavatorGeometry, joint: str, angle_rad: float) -> float:
    """Jacobian d(joint angle)/d(stroke) (rad/m) of `joint` at joint angle angle_rad (rad)."""
    return _cylinder(geometry, joint).angle_per_length(angle_rad)


def moment_arm_m(geometry: ExcavatorGeometry, joint: str, angle_rad: float) -> float:
    """Moment arm d(stroke)/d(joint angle) (m/rad) at angle_rad (rad): joint torque (N m) =
    cylinder force (N, positive pushing the cylinder longer) * moment arm."""
    return 1.0 / joint_rate_per_stroke_rate(geometry, joint, angle_rad)
