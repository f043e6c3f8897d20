"""01 - The digging path of one period: five via-points around the deepest point D.

The paper's four stages (open the bucket and reach the surface; drag to D with the bucket joint
fixed; close the bucket with boom and stick fixed; lift out) give five via-points; inverse
kinematics turns them into joint angles. A D beyond the arm's reach is a value, not an exception.
"""

import numpy as np

from planner.digging_path import VIA_POINT_NAMES, PathShape, joint_via_points
from plant_models import presets
from plant_models.geometry import forward_kinematics

geometry = presets.get("paper")
shape = PathShape.preset("paper")
deepest_point = (-9.0, -0.1)  # m, the paper's default D (section 3.2)

joints = joint_via_points(geometry, deepest_point, shape)  # (5, 3) rad
tip_y, tip_z, bucket_angle = forward_kinematics(geometry, joints)
print("via-point   boom   stick  bucket (deg) |  tip y    tip z (m)  bucket angle (deg)")
for i, name in enumerate(VIA_POINT_NAMES):
    boom, stick, bucket = np.degrees(joints[i])
    print(f"{name:8s} {boom:7.2f} {stick:7.2f} {bucket:7.2f}      | "
          f"{tip_y[i]:7.3f}  {tip_z[i]:7.3f}   {np.degrees(bucket_angle[i]):8.2f}")

too_deep = joint_via_points(geometry, (-9.0, -3.0), shape)
print(f"D = (-9, -3.0) m: reachable = {too_deep.ok}; {too_deep.reason}")
