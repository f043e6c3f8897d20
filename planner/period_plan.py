"""The plan of one period: the path's joint via-points around D, timed by the time-jerk optimal
B-spline, and whether the arm can follow it.

The paper ends a path when "some positions on the trajectory are out of reach of the
manipulator" (section 2.3). The via-points being within the joint ranges is not enough: near the
reach limit the quintic spline between two via-points can swing a joint past its end stop (the
stick, at about z_D = -1.4 m below y = -9 m on the paper arm). So a deepest point D counts as
reachable only if every via-point is, and the planned spline stays inside every joint's range
over its whole duration (exact extremes: the spline at its knots and at the real roots of its
velocity).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.interpolate import BSpline, PPoly

from planner.digging_path import PathShape, joint_via_points
from planner.trajectory import JointTrajectory, plan_trajectory
from plant_models.geometry import LIMIT_TOLERANCE_RAD, ExcavatorGeometry, Unreachable
from plant_models.plant import JOINTS


class PeriodPlanner:
    """Plans periods for one machine, path shape, limits and weights; remembers its plans.

    limits_rad: (3, 3) rows velocity (rad/s), acceleration (rad/s^2), jerk (rad/s^3), columns
    boom, stick, bucket. k_T, k_J: planner.trajectory's weights.
    """

    def __init__(self, geometry: ExcavatorGeometry, shape: PathShape, limits_rad: np.ndarray,
                 k_T: float, k_J: float) -> None:
        self.geometry, self.shape = geometry, shape
        self.limits_rad = np.asarray(limits_rad, dtype=float)
        self.k_T, self.k_J = k_T, k_J
        self._plans: dict[tuple[float, float], JointTrajectory | Unreachable] = {}

    def plan(self, y_D: float, z_D: float) -> JointTrajectory | Unreachable:
        """The trajectory of the period through D = (y_D, z_D) m, or Unreachable saying why."""
        key = (float(y_D), float(z_D))
        if key not in self._plans:
            self._plans[key] = self._plan(*key)
        return self._plans[key]

    def reachable(self, y_D: float, z_D: float) -> bool:
        """planner.adaptation's `reachable(y_D_m, z_D_m)` for this machine and path."""
        return not isinstance(self.plan(y_D, z_D), Unreachable)

    def _plan(self, y_D: float, z_D: float) -> JointTrajectory | Unreachable:
        via = joint_via_points(self.geometry, (y_D, z_D), self.shape)
        if isinstance(via, Unreachable):
            return via
        trajectory = plan_trajectory(via, *self.limits_rad, k_T=self.k_T, k_J=self.k_J)
        low, high = joint_ranges(trajectory.spline)
        for j, joint in enumerate(JOINTS):
            lower, upper = self.geometry.joint_limits_rad[j]
            if low[j] < lower - LIMIT_TOLERANCE_RAD or high[j] > upper + LIMIT_TOLERANCE_RAD:
                return Unreachable(
                    f"the {joint} spline swings to [{math.degrees(low[j]):.2f}, "
                    f"{math.degrees(high[j]):.2f}] deg between via-points, beyond its range "
                    f"[{math.degrees(lower):.2f}, {math.degrees(upper):.2f}] deg")
        return trajectory


def joint_ranges(spline: BSpline) -> tuple[np.ndarray, np.ndarray]:
    """Exact (min, max) of each joint angle over the spline's knot range: (n_joints,) each."""
    low, high = [], []
    for j in range(spline.c.shape[1]):
        poly = PPoly.from_spline(BSpline(spline.t, spline.c[:, j], spline.k))
        times = np.concatenate([poly.x, poly.derivative().roots(extrapolate=False)])
        values = poly(times[np.isfinite(times)])
        low.append(values.min())
        high.append(values.max())
    return np.array(low), np.array(high)
