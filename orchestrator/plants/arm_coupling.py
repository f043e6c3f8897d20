"""The arm between the cylinder FMUs and the Pile FMU: strokes -> pose -> cylinder loads.

Per communication step, with scalar math only (this runs once per step in the master loop):

- stroke -> joint angle and moment arm r = d(stroke)/d(angle) per joint, interpolated in
  tables of `plant_models.joint_strokes` (joint_angle_from_stroke, moment_arm_m) on
  TABLE_INTERVALS + 1 uniform strokes: cubic Hermite for the angle (slopes 1/r), linear for the
  arm (errors below 1e-9 rad and 1e-6 relative, tested);
- forward kinematics: bucket tip (y, z) and absolute bucket angle (plant_models.geometry);
- cylinder loads, positive resisting extension: F_ext_i = (G_i - tau_i) / r_i, where G are the
  gravity holding torques of the links and the payload at the bucket's centre of mass
  (as plant_models.geometry.gravity_joint_torques) and tau_i = f . d(tip)/d(q_i) the joint
  torques of the soil force f = (F_y, F_z) acting at the tip (Jacobian transpose).

Links turn in the arm's angle sense: turning about a pin by dq moves a point p by
rot(p - pin) dq with rot(y, z) = (z, -y) (plant_models.geometry).
"""

from __future__ import annotations

import math

import numpy as np

from plant_models.geometry import GRAVITY_M_S2, ExcavatorGeometry
from plant_models.joint_strokes import joint_angle_from_stroke, moment_arm_m
from plant_models.linkage import JOINT_NAMES

TABLE_INTERVALS = 4096
_RANGE_TOLERANCE = 1e-9  # rad of round-off allowed at a joint limit


class _JointTable:
    """Angle (rad) and moment arm (m/rad) against stroke (m) on a uniform grid."""

    def __init__(self, geometry: ExcavatorGeometry, joint: str, stroke_m: float) -> None:
        strokes = np.linspace(0.0, stroke_m, TABLE_INTERVALS + 1)
        angles = np.array([joint_angle_from_stroke(geometry, joint, float(s)) for s in strokes])
        arms = np.array([moment_arm_m(geometry, joint, float(a)) for a in angles])
        self.stroke_m = stroke_m
        self.strokes, self.angles, self.arms = strokes, angles, arms
        self.inv_dx = TABLE_INTERVALS / stroke_m
        # Angle: cubic Hermite per interval with the exact slopes 1/r at the nodes, as
        # angle = a + t (c1 + t (c2 + t c3)), t in [0, 1]; arm: linear. Python lists: scalar
        # indexing of a list is several times faster than of an array.
        h = stroke_m / TABLE_INTERVALS
        rise, left, right = np.diff(angles), h / arms[:-1], h / arms[1:]
        self.angle = angles.tolist()
        self.c1 = left.tolist()
        self.c2 = (3.0 * rise - 2.0 * left - right).tolist()
        self.c3 = (left + right - 2.0 * rise).tolist()
        self.arm = arms.tolist()
        self.arm_slope = np.diff(arms).tolist()
        # Angle -> stroke, arm and d(arm)/d(angle), for the reference (the linkage is monotone).
        order = np.argsort(angles)
        d_arm = np.gradient(arms, angles)
        self.by_angle = (angles[order], strokes[order], arms[order], d_arm[order])


class ArmCoupling:
    """Kinematics and cylinder loads of one arm geometry (see the module docstring)."""

    def __init__(self, geometry: ExcavatorGeometry) -> None:
        self.geometry = geometry
        strokes = (geometry.boom_cylinder.stroke_m, geometry.stick_cylinder.stroke_m,
                   geometry.bucket_linkage.stroke_m)
        self.tables = tuple(_JointTable(geometry, joint, stroke)
                            for joint, stroke in zip(JOINT_NAMES, strokes, strict=True))
        self._lengths = (geometry.boom_length_m, geometry.stick_length_m,
                         geometry.bucket_length_m)
        self._foot = (float(geometry.boom_foot_m[0]), float(geometry.boom_foot_m[1]))
        masses = (geometry.boom_mass, geometry.stick_mass, geometry.bucket_mass)
        self._weights = tuple(m.mass_kg * GRAVITY_M_S2 for m in masses)
        self._coms = tuple((float(m.com_m[0]), float(m.com_m[1])) for m in masses)

    def joint_state(self, index: int, stroke_m: float) -> tuple[float, float]:
        """(angle rad, moment arm m/rad) of joint `index` (0 boom, 1 stick, 2 bucket) at
        stroke_m (m), clamped to the stroke range."""
        return self._joint(index, stroke_m)[:2]

    def _joint(self, index: int, stroke_m: float) -> tuple[float, float, float]:
        """joint_state and d(arm)/d(angle) (m/rad): the linear arm's slope per stroke times
        the arm (d/dq = r d/dx)."""
        table = self.tables[index]
        position = stroke_m * table.inv_dx
        i = int(position)
        i = 0 if i < 0 else (TABLE_INTERVALS - 1 if i >= TABLE_INTERVALS else i)
        fraction = position - i
        t = 0.0 if fraction < 0.0 else (1.0 if fraction > 1.0 else fraction)
        arm = table.arm[i] + table.arm_slope[i] * t
        return (table.angle[i] + t * (table.c1[i] + t * (table.c2[i] + t * table.c3[i])),
                arm, table.arm_slope[i] * table.inv_dx * arm)

    def pose(self, q0: float, q1: float, q2: float) -> tuple[float, float, float]:
        """Bucket tip y, z (m) and absolute bucket angle (rad) at joint angles (rad)."""
        (l1, l2, l3), (y, z) = self._lengths, self._foot
        phi1 = q0
        phi2 = phi1 + q1
        phi3 = phi2 + q2
        return (y - l1 * math.cos(phi1) - l2 * math.cos(phi2) - l3 * math.cos(phi3),
                z + l1 * math.sin(phi1) + l2 * math.sin(phi2) + l3 * math.sin(phi3), phi3)

    def kinematics(self, x0: float, x1: float, x2: float) -> tuple[float, ...]:
        """Pose and lever arms at strokes x0, x1, x2 (m) of boom, stick and bucket.

        Returns a flat tuple (for speed): q0, q1, q2 (rad), tip_y, tip_z (m), bucket angle (rad),
        then what `loads` needs: moment arms r0, r1, r2 (m/rad), gravity holding torques of the
        links (N m), holding torque per kg of payload (N m/kg) per joint, and the tip's offsets
        from the three pins (m); then d(arm)/d(angle) per joint (m/rad) and cos, sin of the
        three links' absolute angles (for orchestrator.plants.arm_dynamics).
        """
        q0, r0, d0 = self._joint(0, x0)
        q1, r1, d1 = self._joint(1, x1)
        q2, r2, d2 = self._joint(2, x2)
        (l1, l2, l3), (foot_y, foot_z) = self._lengths, self._foot
        phi2 = q0 + q1
        phi3 = phi2 + q2
        c1, s1, c2, s2 = math.cos(q0), math.sin(q0), math.cos(phi2), math.sin(phi2)
        c3, s3 = math.cos(phi3), math.sin(phi3)
        stick_y, stick_z = foot_y - l1 * c1, foot_z + l1 * s1
        pin_y, pin_z = stick_y - l2 * c2, stick_z + l2 * s2
        tip_y, tip_z = pin_y - l3 * c3, pin_z + l3 * s3
        # y of each centre of mass: pin + u (-cos, sin) + v (sin, cos).
        (u1, v1), (u2, v2), (u3, v3) = self._coms
        com1 = foot_y - u1 * c1 + v1 * s1
        com2 = stick_y - u2 * c2 + v2 * s2
        com3 = pin_y - u3 * c3 + v3 * s3
        w1, w2, w3 = self._weights
        return (
            q0, q1, q2, tip_y, tip_z, phi3, r0, r1, r2,
            w1 * (foot_y - com1) + w2 * (foot_y - com2) + w3 * (foot_y - com3),
            w2 * (stick_y - com2) + w3 * (stick_y - com3),
            w3 * (pin_y - com3),
            GRAVITY_M_S2 * (foot_y - com3), GRAVITY_M_S2 * (stick_y - com3),
            GRAVITY_M_S2 * (pin_y - com3),
            tip_y - foot_y, tip_z - foot_z, tip_y - stick_y, tip_z - stick_z,
            tip_y - pin_y, tip_z - pin_z,
            d0, d1, d2, c1, s1, c2, s2, c3, s3,
        )

    @staticmethod
    def loads(kinematics: tuple[float, ...], force_y: float, force_z: float,
              payload_kg: float) -> tuple[float, float, float]:
        """Cylinder loads F_ext (N, positive resisting extension) of boom, stick and bucket,
        from `kinematics(...)`, the soil force (N) at the tip and the payload (kg)."""
        (r0, r1, r2, hold0, hold1, hold2, per_kg0, per_kg1, per_kg2,
         dy0, dz0, dy1, dz1, dy2, dz2) = kinematics[6:21]
        return ((hold0 + payload_kg * per_kg0 - (force_y * dz0 - force_z * dy0)) / r0,
                (hold1 + payload_kg * per_kg1 - (force_y * dz1 - force_z * dy1)) / r1,
                (hold2 + payload_kg * per_kg2 - (force_y * dz2 - force_z * dy2)) / r2)

    def stroke_reference(self, position_rad: np.ndarray, velocity_rad_s: np.ndarray,
                         acceleration_rad_s2: np.ndarray) -> tuple[np.ndarray, ...]:
        """Stroke (m), stroke rate (m/s) and stroke acceleration (m/s^2), each (n, 3), of a
        joint reference given as (n, 3) arrays (rad, rad/s, rad/s^2).

        ValueError if an angle lies beyond its joint's range (the cylinder's end stops).
        """
        strokes, rates, accelerations = (np.empty_like(position_rad) for _ in range(3))
        for j, table in enumerate(self.tables):
            angles, by_stroke, arms, d_arms = table.by_angle
            q = position_rad[:, j]
            if q.min() < angles[0] - _RANGE_TOLERANCE or q.max() > angles[-1] + _RANGE_TOLERANCE:
                raise ValueError(
                    f"{JOINT_NAMES[j]} reference leaves the joint range "
                    f"[{math.degrees(angles[0]):.2f}, {math.degrees(angles[-1]):.2f}] deg")
            arm = np.interp(q, angles, arms)
            d_arm = np.interp(q, angles, d_arms)
            qd = velocity_rad_s[:, j]
            strokes[:, j] = np.interp(q, angles, by_stroke)
            rates[:, j] = qd * arm
            accelerations[:, j] = acceleration_rad_s2[:, j] * arm + qd * qd * d_arm
        return strokes, rates, accelerations
