"""Excavator arm geometry: forward and inverse kinematics, arm points, gravity loads.

Conventions (SI: m, rad, kg, N m)::

          z (up)
          ^                 stick pin
          |      boom   __o.
          |        __--'    `.  stick
          |   __--'           `.
          |  o boom foot        o bucket pin
          |  |                 /  \\  bucket
   -------+--+---------------+-----*--------------------> y
          |                  ground     * = bucket tip
       y < 0: in front of the machine, where it digs (the paper's D = (-9, -0.1) m)

- The arm moves in the (y, z) plane; z = 0 is the undisturbed ground surface.
- Angles are measured from the forward horizontal (the -y direction), positive turning up toward
  +z. A direction of absolute angle phi is the unit vector (y, z) = (-cos phi, sin phi).
- Joint angles, each relative to the previous link, each in (-pi, pi]:
  boom   = absolute angle of the boom line (boom foot -> stick pin),
  stick  = angle of the stick line (stick pin -> bucket pin) relative to the boom line,
  bucket = angle of the bucket line (bucket pin -> tip) relative to the stick line.
  The stick is always folded down below the boom line (stick < 0, "elbow up"); the bucket closes
  (curls toward the machine) as its angle decreases.
- Absolute bucket angle = boom + stick + bucket: the absolute angle of the bucket pin-to-tip line,
  not wrapped (a closed bucket pointing back at the machine has an angle near -pi or below).
  The Pile FMU's `bucket_angle` input is the tip-to-pin line counter-clockwise from +y, which is
  minus this angle: `pile_bucket_angle`.
- Joint limits are the angles the cylinders reach at their end stops (stroke 0 and full stroke), so
  any stroke in [0, stroke] maps into them (see `plant_models.linkage`).

Inverse kinematics never raises for a pose out of reach or beyond a joint limit: it returns an
`Unreachable` value whose `reason` says which and by how much.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from plant_models.linkage import JOINT_NAMES, BucketLinkage, PinJointCylinder, wrap_angle

GRAVITY_M_S2 = 9.80665  # standard gravity
LIMIT_TOLERANCE_RAD = 1e-9  # round-off allowed at a joint limit before a pose counts as beyond it


@dataclass(frozen=True)
class LinkMass:
    """Mass (kg) and centre of mass (u, v) m of a link (link frame, from its proximal pin)."""

    mass_kg: float
    com_m: tuple[float, float]


@dataclass(frozen=True)
class Unreachable:
    """A pose the arm cannot take; `reason` names the cause (one line)."""

    reason: str
    ok: bool = field(default=False, init=False)


@dataclass(frozen=True)
class ExcavatorGeometry:
    """Planar excavator arm: link lengths (m), boom foot (y, z) m, cylinders, link masses.

    `joint_limits_rad` ((3, 2) nested tuple, rad) is derived from the cylinders' end stops.
    """

    name: str
    boom_length_m: float
    stick_length_m: float
    bucket_length_m: float
    boom_foot_m: tuple[float, float]
    boom_cylinder: PinJointCylinder
    stick_cylinder: PinJointCylinder
    bucket_linkage: BucketLinkage
    boom_mass: LinkMass
    stick_mass: LinkMass
    bucket_mass: LinkMass
    joint_limits_rad: tuple[tuple[float, float], ...] = field(init=False, compare=False)

    def __post_init__(self) -> None:
        for label in ("boom_length_m", "stick_length_m", "bucket_length_m"):
            if not getattr(self, label) > 0.0:
                raise ValueError(f"{self.name}: {label} must be > 0, got {getattr(self, label)}")
        limits = []
        cylinders = (self.boom_cylinder, self.stick_cylinder, self.bucket_linkage)
        for joint, cylinder in zip(JOINT_NAMES, cylinders, strict=True):
            limits.append(_check_cylinder(self.name, joint, cylinder))
        object.__setattr__(self, "joint_limits_rad", tuple(limits))


def _check_cylinder(machine: str, joint: str, cylinder) -> tuple[float, float]:
    """Joint range (rad) over the cylinder's stroke; ValueError if the linkage does not assemble,
    does not round-trip or is not monotone over the whole stroke (a wrong assembly mode)."""
    if not (cylinder.retracted_length_m > 0.0 and cylinder.stroke_m > 0.0):
        raise ValueError(f"{machine}: {joint} cylinder retracted length and stroke must be > 0")
    lengths = cylinder.retracted_length_m + np.linspace(0.0, cylinder.stroke_m, 41)
    angles = []
    for length in lengths:
        angle = cylinder.angle_from_length(float(length))
        back = None if angle is None else cylinder.length_from_angle(angle)
        if back is None or abs(back - length) > 1e-9:
            raise ValueError(
                f"{machine}: {joint} linkage does not assemble consistently at cylinder length "
                f"{length:.4f} m (check mount points and assembly sides)"
            )
        angles.append(angle)
    steps = np.diff(angles)
    if not (np.all(steps > 0.0) or np.all(steps < 0.0)):
        raise ValueError(f"{machine}: {joint} angle is not monotone over the cylinder stroke")
    return (float(min(angles[0], angles[-1])), float(max(angles[0], angles[-1])))


def _direction(angle):
    """Unit vector(s) (y, z) of absolute angle(s) `angle` (rad)."""
    return np.stack([-np.cos(angle), np.sin(angle)], axis=-1)


def _to_world(origin, angle, local):
    """World (y, z) of `local` = (u, v) in a frame at `origin` whose u axis has angle `angle`."""
    return origin + local[0] * _direction(angle) + local[1] * _direction(angle + math.pi / 2.0)


def forward_kinematics(geometry: ExcavatorGeometry, joints):
    """Bucket tip position and absolute bucket angle for joint angles.

    joints: (3,) or (n, 3) rad, [boom, stick, bucket].
    Returns (tip_y_m, tip_z_m, bucket_angle_rad): floats for one pose, (n,) arrays for n poses.
    """
    q = np.asarray(joints, dtype=float)
    if q.shape[-1:] != (3,) or q.ndim > 2:
        raise ValueError(f"joints must have shape (3,) or (n, 3), got {q.shape}")
    if not np.all(np.isfinite(q)):
        raise ValueError("joints must be finite angles in rad")
    phi1 = q[..., 0]
    phi2 = phi1 + q[..., 1]
    phi3 = phi2 + q[..., 2]
    tip = (
        np.asarray(geometry.boom_foot_m)
        + geometry.boom_length_m * _direction(phi1)
        + geometry.stick_length_m * _direction(phi2)
        + geometry.bucket_length_m * _direction(phi3)
    )
    if q.ndim == 1:
        return float(tip[0]), float(tip[1]), float(phi3)
    return tip[:, 0], tip[:, 1], phi3


def pile_bucket_angle(bucket_angle_rad):
    """The Pile FMU's `bucket_angle` (rad: tip-to-pin line, counter-clockwise from +y) for an
    absolute bucket angle (rad, this module's convention); scalar or array."""
    angle = -np.asarray(bucket_angle_rad, dtype=float)
    return float(angle) if angle.ndim == 0 else angle


def _limit_violation(geometry: ExcavatorGeometry, index: int, angle: float) -> Unreachable | None:
    low, high = geometry.joint_limits_rad[index]
    if low - LIMIT_TOLERANCE_RAD <= angle <= high + LIMIT_TOLERANCE_RAD:
        return None
    return Unreachable(
        f"{JOINT_NAMES[index]} angle {math.degrees(angle):.2f} deg beyond its limits "
        f"[{math.degrees(low):.2f}, {math.degrees(high):.2f}] deg"
    )


def _check_limits(geometry: ExcavatorGeometry, joints) -> np.ndarray | Unreachable:
    """Joints clipped onto their limits if within round-off of them, else Unreachable."""
    for index, angle in enumerate(joints):
        violation = _limit_violation(geometry, index, angle)
        if violation is not None:
            return violation
    limits = geometry.joint_limits_rad
    return np.array([min(max(a, lo), hi) for a, (lo, hi) in zip(joints, limits, strict=True)])


def _check_finite(**values: float) -> None:
    for name, value in values.items():
        if not math.isfinite(value):
            raise ValueError(f"{name} must be finite, got {value!r}")


def _two_link(geometry: ExcavatorGeometry, target, second_length: float, elbow_signs):
    """Boom angle and relative angle of a second link of length second_length (m) from the stick
    pin to `target` (y, z) m, one solution per elbow sign; or an Unreachable reason string."""
    forward = -(target[0] - geometry.boom_foot_m[0])
    up = target[1] - geometry.boom_foot_m[1]
    distance = math.hypot(forward, up)
    l1 = geometry.boom_length_m
    if distance > l1 + second_length:
        reach = l1 + second_length
        return f"{distance:.3f} m from the boom foot, beyond the arm's reach {reach:.3f} m"
    if distance < abs(l1 - second_length):
        return f"{distance:.3f} m from the boom foot, closer than the arm can fold"
    cos_elbow = (distance**2 - l1**2 - second_length**2) / (2.0 * l1 * second_length)
    elbow = math.acos(min(1.0, max(-1.0, cos_elbow)))
    solutions = []
    for sign in elbow_signs:
        relative = sign * elbow
        boom = math.atan2(up, forward) - math.atan2(
            second_length * math.sin(relative), l1 + second_length * math.cos(relative)
        )
        solutions.append((wrap_angle(boom), relative))
    return solutions


def inverse_kinematics(
    geometry: ExcavatorGeometry, tip_y: float, tip_z: float, bucket_angle: float
) -> np.ndarray | Unreachable:
    """Joint angles (3,) rad putting the bucket tip at (tip_y, tip_z) m with absolute bucket angle
    bucket_angle (rad); `Unreachable` if out of reach or beyond a joint limit.

    Elbow branch: the stick folded down below the boom line (stick angle < 0), as on an excavator.
    """
    _check_finite(tip_y=tip_y, tip_z=tip_z, bucket_angle=bucket_angle)
    bucket_pin = np.array([tip_y, tip_z]) - geometry.bucket_length_m * _direction(bucket_angle)
    solved = _two_link(geometry, bucket_pin, geometry.stick_length_m, (-1.0,))
    if isinstance(solved, str):
        return Unreachable(f"bucket pin {solved}")
    boom, stick = solved[0]
    bucket = wrap_angle(bucket_angle - boom - stick)
    return _check_limits(geometry, (boom, stick, bucket))


def inverse_kinematics_with_bucket_joint(
    geometry: ExcavatorGeometry, tip_y: float, tip_z: float, bucket_joint: float
) -> np.ndarray | Unreachable:
    """Boom and stick angles putting the tip at (tip_y, tip_z) m with the bucket JOINT (relative
    angle) held at bucket_joint (rad). Returns joints (3,) rad or `Unreachable`.

    Stick and bucket then form one rigid link from the stick pin to the tip, of length
    |L_stick + L_bucket e^(i bucket_joint)| and offset angle delta from the stick line, so this is a
    two-link problem. Of its two elbow solutions, the one with that rigid link folded down from the
    boom line (stick + delta in (-pi, 0]) is preferred; the other is used only if the first is
    beyond a limit and it is not (possible only with stick and bucket both curled far in).
    """
    _check_finite(tip_y=tip_y, tip_z=tip_z, bucket_joint=bucket_joint)
    violation = _limit_violation(geometry, 2, bucket_joint)
    if violation is not None:
        return violation
    rigid = geometry.stick_length_m + geometry.bucket_length_m * complex(
        math.cos(bucket_joint), math.sin(bucket_joint)
    )
    delta = math.atan2(rigid.imag, rigid.real)
    solved = _two_link(geometry, (tip_y, tip_z), abs(rigid), (-1.0, 1.0))
    if isinstance(solved, str):
        return Unreachable(f"bucket tip {solved} with the bucket joint fixed")
    candidates = [
        _check_limits(geometry, (boom, wrap_angle(relative - delta), bucket_joint))
        for boom, relative in solved
    ]
    for candidate in candidates:
        if not isinstance(candidate, Unreachable):
            return candidate
    return candidates[0]


def arm_points(geometry: ExcavatorGeometry, joints) -> dict[str, np.ndarray]:
    """World (y, z) m of the arm's pins, link centres of mass and cylinder ends for joints (3,) rad.

    Keys: boom_foot, stick_pin, bucket_pin, bucket_tip, boom_com, stick_com, bucket_com,
    boom_cylinder_base, boom_cylinder_rod, stick_cylinder_base, stick_cylinder_rod,
    bucket_cylinder_base, rocker_pivot, rocker_link_joint, bucket_link_pin; each an array (2,).
    """
    q = np.asarray(joints, dtype=float)
    if q.shape != (3,):
        raise ValueError(f"joints must have shape (3,), got {q.shape}")
    phi1, phi2, phi3 = np.cumsum(q)
    foot = np.asarray(geometry.boom_foot_m, dtype=float)
    stick_pin = foot + geometry.boom_length_m * _direction(phi1)
    bucket_pin = stick_pin + geometry.stick_length_m * _direction(phi2)
    tip = bucket_pin + geometry.bucket_length_m * _direction(phi3)
    boom_cyl, stick_cyl, bucket = (
        geometry.boom_cylinder, geometry.stick_cylinder, geometry.bucket_linkage
    )
    points = {
        "boom_foot": foot,
        "stick_pin": stick_pin,
        "bucket_pin": bucket_pin,
        "bucket_tip": tip,
        "boom_com": _to_world(foot, phi1, geometry.boom_mass.com_m),
        "stick_com": _to_world(stick_pin, phi2, geometry.stick_mass.com_m),
        "bucket_com": _to_world(bucket_pin, phi3, geometry.bucket_mass.com_m),
        "boom_cylinder_base": _to_world(foot, 0.0, boom_cyl.prev_mount_m),
        "boom_cylinder_rod": _to_world(foot, phi1, boom_cyl.next_mount_m),
        "stick_cylinder_base": _to_world(stick_pin, phi1, stick_cyl.prev_mount_m),
        "stick_cylinder_rod": _to_world(stick_pin, phi2, stick_cyl.next_mount_m),
        "bucket_cylinder_base": _to_world(bucket_pin, phi2, bucket.cylinder_mount_m),
        "rocker_pivot": _to_world(bucket_pin, phi2, bucket.rocker_pivot_m),
    }
    linkage = bucket.joint_points(float(q[2]))
    if linkage is None:
        raise ValueError(f"bucket four-bar cannot be assembled at bucket angle {q[2]} rad")
    for key, local in linkage.items():
        points[key] = _to_world(bucket_pin, phi2, local)
    return points


def gravity_joint_torques(
    geometry: ExcavatorGeometry, joints, payload_kg: float = 0.0
) -> np.ndarray:
    """Joint torques (3,) N m that hold the arm still against gravity at joints (3,) rad.

    This is dV/dq of the potential energy V = g * sum(m z_com); positive torque turns a joint
    toward positive angles. payload_kg (kg) of material is placed at the bucket's centre of mass.
    """
    points = arm_points(geometry, joints)
    masses = (
        ("boom_com", geometry.boom_mass.mass_kg),
        ("stick_com", geometry.stick_mass.mass_kg),
        ("bucket_com", geometry.bucket_mass.mass_kg + payload_kg),
    )
    pins = ("boom_foot", "stick_pin", "bucket_pin")
    torques = np.zeros(3)
    for index, pin in enumerate(pins):
        for com, mass in masses[index:]:
            # Turning about the pin by d(theta) raises a point by -(y - y_pin) d(theta).
            torques[index] += mass * GRAVITY_M_S2 * -(points[com][0] - points[pin][0])
    return torques
