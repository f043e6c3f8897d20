"""The four-stage digging path (planner.digging_path): stage semantics of paper section 2.1,
via-points checked by forward kinematics, and the workspace limits of the paper scenario
(section 3.2: D0 = (-9, -0.1) m reachable, the reach limit after about ten periods, then the path
shifted 3.5 m toward the machine)."""

import dataclasses
import math

import numpy as np
import pytest

from planner.digging_path import (
    LAB_DEEPEST_POINT_M,
    PAPER_DEEPEST_POINT_M,
    VIA_POINT_NAMES,
    PathShape,
    is_reachable,
    joint_via_points,
    paper_joint_via_points,
    path_is_reachable,
    task_via_points,
)
from plant_models import presets
from plant_models.geometry import Unreachable, forward_kinematics

CASES = [
    ("paper", PAPER_DEEPEST_POINT_M),
    ("paper", (-9.0, -1.2)),
    ("paper", (-5.5, -0.1)),
    ("paper", (-5.5, -2.0)),
    ("lab", LAB_DEEPEST_POINT_M),
]


def solved(name, deepest_point):
    geometry, shape = presets.get(name), PathShape.preset(name)
    joints = joint_via_points(geometry, deepest_point, shape)
    assert not isinstance(joints, Unreachable), joints
    return geometry, shape, joints


@pytest.mark.parametrize("name, deepest_point", CASES)
def test_via_points_follow_the_four_stages(name, deepest_point):
    geometry, shape, q = solved(name, deepest_point)
    assert q.shape == (5, 3)
    tip_y, tip_z, bucket_angle = forward_kinematics(geometry, q)
    start, entry, deepest, closed, lifted = range(5)
    # Stage 1 ends on the nominal surface, entry_offset_m beyond D, bucket at the attack angle.
    assert tip_z[entry] == pytest.approx(shape.entry_height_m, abs=1e-9)
    assert tip_y[entry] == pytest.approx(deepest_point[0] - shape.entry_offset_m, abs=1e-9)
    assert bucket_angle[entry] == pytest.approx(shape.entry_bucket_angle_rad, abs=1e-9)
    # Stage 2 keeps the bucket joint and ends at D, the deepest via-point.
    assert q[deepest, 2] == q[entry, 2]
    assert (tip_y[deepest], tip_z[deepest]) == pytest.approx(deepest_point, abs=1e-9)
    assert tip_z[deepest] == min(tip_z)
    # Stage 3 keeps boom and stick and closes the bucket (its joint angle decreases).
    np.testing.assert_array_equal(q[closed, :2], q[deepest, :2])
    assert q[closed, 2] == shape.closed_bucket_joint_rad < q[deepest, 2]
    # Stage 4 keeps the bucket closed and lifts the tip out to the lift pose, above ground.
    assert q[lifted, 2] == q[closed, 2]
    assert (tip_y[lifted], tip_z[lifted]) == pytest.approx(shape.lift_tip_m, abs=1e-9)
    assert tip_z[lifted] > 0.0
    # The period starts at rest at the start pose.
    assert (tip_y[start], tip_z[start]) == pytest.approx(shape.start_tip_m, abs=1e-9)
    assert bucket_angle[start] == pytest.approx(shape.start_bucket_angle_rad, abs=1e-9)


@pytest.mark.parametrize("name, deepest_point", CASES)
def test_joint_via_points_reproduce_the_task_points(name, deepest_point):
    geometry, shape, q = solved(name, deepest_point)
    points = task_via_points(deepest_point, shape)
    assert tuple(p.name for p in points) == VIA_POINT_NAMES
    tip_y, tip_z, bucket_angle = forward_kinematics(geometry, q)
    for i, point in enumerate(points):
        if point.tip_m is not None:
            assert (tip_y[i], tip_z[i]) == pytest.approx(point.tip_m, abs=1e-9)
        if point.bucket_angle_rad is not None:
            assert bucket_angle[i] == pytest.approx(point.bucket_angle_rad, abs=1e-9)
        if point.bucket_joint_rad is not None:
            assert q[i, 2] == point.bucket_joint_rad
    limits = np.array(geometry.joint_limits_rad)
    assert np.all((q >= limits[:, 0]) & (q <= limits[:, 1]))


@pytest.mark.parametrize("name", ["paper", "lab"])
def test_default_period_ends_where_it_began(name):
    """The start pose is the lifted pose (to 0.01 deg), so periods chain without a jump."""
    _, _, q = solved(name, PAPER_DEEPEST_POINT_M if name == "paper" else LAB_DEEPEST_POINT_M)
    np.testing.assert_allclose(q[0], q[4], rtol=0, atol=math.radians(0.01))


def test_paper_first_period():
    q = paper_joint_via_points()
    np.testing.assert_array_equal(
        q, joint_via_points(presets.get("paper"), (-9.0, -0.1), PathShape.preset("paper"))
    )


def first_unreachable_depth(name, y_d, z_from, z_to, step):
    geometry, shape = presets.get(name), PathShape.preset(name)
    for z_d in np.arange(z_from, z_to, -step):
        result = joint_via_points(geometry, (y_d, z_d), shape)
        if isinstance(result, Unreachable):
            return z_d, result
    return None, None


def test_digging_straight_down_at_y_minus_9_reaches_the_workspace_limit():
    """Paper section 3.2: after about ten periods at y = -9 m the path leaves the workspace."""
    geometry, shape = presets.get("paper"), PathShape.preset("paper")
    assert path_is_reachable(geometry, shape, -9.0, -0.1)
    # The via-points alone (the spline leaves the stick's range earlier, planner.period_plan).
    z_limit, result = first_unreachable_depth("paper", -9.0, -0.1, -3.5, 0.01)
    assert z_limit is not None and -3.0 < z_limit < -1.3
    assert result.reason.startswith("deepest via-point: stick angle")
    # Once out of reach it stays out of reach deeper down.
    deeper = np.arange(z_limit, -4.0, -0.1)
    assert not any(path_is_reachable(geometry, shape, -9.0, z) for z in deeper)


def test_the_shifted_path_is_reachable():
    """Reset z_D and shift y_D by dy_0 = 3.5 m toward the machine: reachable, and deeper too."""
    geometry, shape = presets.get("paper"), PathShape.preset("paper")
    y_shifted = PAPER_DEEPEST_POINT_M[0] + 3.5
    depths = np.arange(-0.1, -2.5, -0.1)
    assert all(path_is_reachable(geometry, shape, y_shifted, z) for z in depths)


def test_unreachable_paths_name_the_via_point():
    geometry, shape = presets.get("paper"), PathShape.preset("paper")
    too_far = joint_via_points(geometry, (-12.0, -0.1), shape)
    assert isinstance(too_far, Unreachable)
    assert too_far.reason.startswith("entry via-point: bucket pin")
    assert "beyond the arm's reach" in too_far.reason
    shut = dataclasses.replace(shape, closed_bucket_joint_rad=math.radians(-170.0))
    beyond = joint_via_points(geometry, PAPER_DEEPEST_POINT_M, shut)
    assert isinstance(beyond, Unreachable)
    assert beyond.reason.startswith("closed via-point: bucket angle -170.00 deg beyond its limits")
    reachable = is_reachable(geometry, shape)
    assert reachable(-9.0, -0.1) and not reachable(-12.0, -0.1)


def test_bad_input_is_a_clear_error():
    shape = PathShape.preset("paper")
    with pytest.raises(ValueError, match="deepest point must be finite"):
        task_via_points((math.nan, -0.1), shape)
    with pytest.raises(ValueError, match="unknown path shape preset 'mini'"):
        PathShape.preset("mini")
    with pytest.raises(ValueError, match="entry_offset_m must be >= 0"):
        dataclasses.replace(shape, entry_offset_m=-1.0)
    with pytest.raises(ValueError, match="lift_tip_m must be finite"):
        dataclasses.replace(shape, lift_tip_m=(math.inf, 1.0))


def test_lab_shape_is_the_paper_shape_scaled():
    paper, lab = PathShape.preset("paper"), PathShape.preset("lab")
    scale = presets.LAB_SCALE
    assert lab.entry_offset_m == pytest.approx(paper.entry_offset_m * scale)
    assert lab.lift_tip_m == pytest.approx(tuple(v * scale for v in paper.lift_tip_m))
    assert lab.entry_bucket_angle_rad == paper.entry_bucket_angle_rad
