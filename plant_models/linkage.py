"""Cylinder linkages of the excavator arm: cylinder stroke <-> joint angle, and its Jacobian.

Frames (see `plant_models.geometry` for the sketch): every link has a local frame (u, v) whose u
axis runs along the link's pin line (boom: boom foot -> stick pin; stick: stick pin -> bucket pin;
bucket: bucket pin -> tip) and whose v axis is u turned +90 deg in the arm's angle sense (positive
angles turn the forward direction -y toward +z). The chassis frame has u = forward (-y), v = up.
Mount points are given in metres in the frame of the link they sit on, *relative to the pin of the
joint they actuate*.

- Boom and stick: `PinJointCylinder`, a cylinder between a point fixed on the previous link and one
  on the next link; its length follows from the law of cosines in the triangle (pin, mount, mount).
- Bucket: `BucketLinkage`, a four-bar: the bucket cylinder runs from a point on the stick to the
  joint J where the rocker (pivoting on the stick) meets the connecting link, and the connecting
  link drives a pin on the bucket. Both closing points are intersections of two circles; the
  assembly mode (which of the two intersections) is fixed per linkage by the `*_side` fields.

Cylinder length = retracted_length_m + stroke (m), stroke in [0, stroke_m]. Bore and rod belong to
the hydraulics, not here. The moment arm ds/dtheta (m/rad) maps a cylinder force F (N) to the joint
torque tau = F * ds/dtheta (N m) by virtual work; dtheta/ds maps cylinder speed to joint rate.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

JOINT_NAMES = ("boom", "stick", "bucket")


def wrap_angle(angle_rad: float) -> float:
    """Angle wrapped into (-pi, pi] (rad)."""
    wrapped = math.remainder(angle_rad, 2.0 * math.pi)
    return math.pi if wrapped == -math.pi else wrapped


def _circle_intersection(c1, r1, c2, r2, side):
    """Point at distance r1 from c1 and r2 from c2, left (side=+1) or right (-1) of c1 -> c2.

    Returns None when the circles do not meet (the linkage cannot be assembled there).
    """
    dx, dy = c2[0] - c1[0], c2[1] - c1[1]
    d2 = dx * dx + dy * dy
    d = math.sqrt(d2)
    along = (r1 * r1 - r2 * r2 + d2) / (2.0 * d)
    h2 = r1 * r1 - along * along
    if d == 0.0 or h2 < 0.0:
        return None
    h = side * math.sqrt(h2)
    return (c1[0] + (along * dx - h * dy) / d, c1[1] + (along * dy + h * dx) / d)


def _rotate(point, angle_rad):
    c, s = math.cos(angle_rad), math.sin(angle_rad)
    return (c * point[0] - s * point[1], s * point[0] + c * point[1])


def _cross(a, b) -> float:
    return a[0] * b[1] - a[1] * b[0]


@dataclass(frozen=True)
class PinJointCylinder:
    """A cylinder acting directly across one revolute joint (boom or stick).

    prev_mount_m: (u, v) m of the cylinder end on the previous link (chassis for the boom, boom for
        the stick), in that link's frame, relative to the actuated joint's pin.
    next_mount_m: (u, v) m of the other end on the next link, in the next link's frame, relative to
        the same pin.
    branch: +1 if, seen from the pin, the next-link mount lies at a positive angle (arm angle sense)
        from the previous-link mount over the whole stroke, else -1.
    """

    prev_mount_m: tuple[float, float]
    next_mount_m: tuple[float, float]
    retracted_length_m: float
    stroke_m: float
    branch: int = 1

    def _arms(self) -> tuple[float, float, float]:
        a = math.hypot(*self.prev_mount_m)
        b = math.hypot(*self.next_mount_m)
        offset = math.atan2(self.next_mount_m[1], self.next_mount_m[0]) - math.atan2(
            self.prev_mount_m[1], self.prev_mount_m[0]
        )
        return a, b, offset

    def length_from_angle(self, angle_rad: float) -> float:
        """Pin-to-pin cylinder length (m) at joint angle angle_rad (rad): law of cosines."""
        a, b, offset = self._arms()
        psi = angle_rad + offset
        return math.sqrt(a * a + b * b - 2.0 * a * b * math.cos(psi))

    def angle_from_length(self, length_m: float) -> float | None:
        """Joint angle (rad, wrapped into (-pi, pi]) at cylinder length length_m (m); None if the
        triangle cannot close."""
        a, b, offset = self._arms()
        cos_psi = (a * a + b * b - length_m * length_m) / (2.0 * a * b)
        if not -1.0 <= cos_psi <= 1.0:
            return None
        return wrap_angle(self.branch * math.acos(cos_psi) - offset)

    def angle_per_length(self, angle_rad: float) -> float:
        """d(joint angle)/d(cylinder length) (rad/m) at joint angle angle_rad (rad)."""
        a, b, offset = self._arms()
        psi = angle_rad + offset
        return self.length_from_angle(angle_rad) / (a * b * math.sin(psi))


@dataclass(frozen=True)
class BucketLinkage:
    """Bucket cylinder -> rocker -> connecting link -> bucket (a four-bar on the stick).

    Points on the stick are in the stick frame relative to the bucket pin (m); the bucket's link
    pin is in the bucket frame relative to the bucket pin (m).
    cylinder_mount_m: cylinder end on the stick.
    rocker_pivot_m: rocker (side link) pivot on the stick.
    rocker_length_m: rocker pivot -> joint J (rocker, connecting link and cylinder rod share J).
    link_length_m: joint J -> bucket link pin.
    bucket_pin_offset_m: (u, v) of the bucket link pin in the bucket frame.
    rocker_side: side of J relative to the line rocker pivot -> bucket link pin (+1 left, -1 right).
    cylinder_side: side of J relative to the line cylinder mount -> rocker pivot.
    link_side: side of the bucket link pin relative to the line bucket pin -> J.
    The three sides describe one assembly mode; `ExcavatorGeometry` checks that they agree over
    the whole stroke.
    """

    cylinder_mount_m: tuple[float, float]
    rocker_pivot_m: tuple[float, float]
    rocker_length_m: float
    link_length_m: float
    bucket_pin_offset_m: tuple[float, float]
    retracted_length_m: float
    stroke_m: float
    rocker_side: int = 1
    cylinder_side: int = 1
    link_side: int = 1

    def _points(self, angle_rad: float):
        link_pin = _rotate(self.bucket_pin_offset_m, angle_rad)
        joint = _circle_intersection(
            self.rocker_pivot_m, self.rocker_length_m, link_pin, self.link_length_m,
            self.rocker_side,
        )
        return link_pin, joint

    def joint_points(self, angle_rad: float) -> dict[str, tuple[float, float]] | None:
        """Rocker/link joint J and bucket link pin (stick frame, m, relative to the bucket pin) at
        bucket joint angle angle_rad (rad); None if the four-bar cannot be assembled there."""
        link_pin, joint = self._points(angle_rad)
        if joint is None:
            return None
        return {"rocker_link_joint": joint, "bucket_link_pin": link_pin}

    def length_from_angle(self, angle_rad: float) -> float | None:
        """Bucket cylinder length (m) at bucket joint angle angle_rad (rad); None if the four-bar
        cannot be assembled there."""
        _, joint = self._points(angle_rad)
        if joint is None:
            return None
        return math.dist(joint, self.cylinder_mount_m)

    def angle_from_length(self, length_m: float) -> float | None:
        """Bucket joint angle (rad, in (-pi, pi]) at cylinder length length_m (m); None if the
        four-bar cannot be assembled."""
        joint = _circle_intersection(
            self.cylinder_mount_m, length_m, self.rocker_pivot_m, self.rocker_length_m,
            self.cylinder_side,
        )
        if joint is None:
            return None
        link_pin = _circle_intersection(
            (0.0, 0.0), math.hypot(*self.bucket_pin_offset_m), joint, self.link_length_m,
            self.link_side,
        )
        if link_pin is None:
            return None
        offset = math.atan2(self.bucket_pin_offset_m[1], self.bucket_pin_offset_m[0])
        return wrap_angle(math.atan2(link_pin[1], link_pin[0]) - offset)

    def angle_per_length(self, angle_rad: float) -> float:
        """d(bucket joint angle)/d(cylinder length) (rad/m) at angle_rad (rad), by velocity
        analysis: J turns about the rocker pivot, the link pin about the bucket pin, and
        |J - link pin| stays fixed."""
        link_pin, joint = self._points(angle_rad)
        if joint is None:
            raise ValueError(f"bucket four-bar cannot be assembled at {angle_rad} rad")
        rocker = (joint[0] - self.rocker_pivot_m[0], joint[1] - self.rocker_pivot_m[1])
        cylinder = (joint[0] - self.cylinder_mount_m[0], joint[1] - self.cylinder_mount_m[1])
        link = (joint[0] - link_pin[0], joint[1] - link_pin[1])
        # dJ = perp(rocker) dphi and dK = perp(link_pin) dtheta, with perp(x, y) = (-y, x);
        # cylinder . dJ = length dlength and link . (dJ - dK) = 0 give the ratio below.
        length = math.hypot(*cylinder)
        rocker_rate = length / _cross(rocker, cylinder)
        return rocker_rate * _cross(rocker, link) / _cross(link_pin, link)
