"""02 - A time-jerk optimal quintic B-spline through the via-points (paper eq. 1).

k_T = 1, k_J = 0 asks for the fastest trajectory within the velocity, acceleration and jerk
limits; k_T = 0.1, k_J = 0.9 trades time for smoothness. The limits hold over the whole
trajectory, not only on samples.
"""

import numpy as np

from planner.digging_path import paper_joint_via_points
from planner.trajectory import plan_trajectory

via_points = paper_joint_via_points()  # (5, 3) rad: boom, stick, bucket
limits = np.radians([100.0, 60.0, 60.0])  # paper Table 1: deg/s, deg/s^2, deg/s^3, every joint

for k_T, k_J in [(1.0, 0.0), (0.1, 0.9)]:
    trajectory = plan_trajectory(via_points, *limits, k_T=k_T, k_J=k_J)
    print(f"k_T = {k_T}, k_J = {k_J}: duration {trajectory.duration:.2f} s, "
          f"segments {np.round(trajectory.segment_durations, 2)} s, "
          f"solved in {trajectory.solve_time_ms:.1f} ms")
    print(f"  peak |jerk| per joint {np.degrees(trajectory.peak_jerk).round(1)} deg/s^3, "
          f"peak |velocity| {np.degrees(trajectory.peak_velocity).round(1)} deg/s")

t = np.linspace(0.0, trajectory.duration, 5)
print("joint angles (deg) at", t.round(2), "s:")
print(np.degrees(trajectory(t)).round(2))
