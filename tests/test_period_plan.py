"""A deepest point is reachable only if the arm can follow the whole planned spline: checked on
the paper arm, where the stick's spline leaves its range before any via-point does."""

import math

import numpy as np
import pytest
from scipy.interpolate import BSpline

from planner.digging_path import PathShape, joint_via_points
from planner.period_plan import PeriodPlanner, joint_ranges
from planner.trajectory import plan_trajectory
from plant_models import presets
from plant_models.geometry import Unreachable

PAPER = presets.get("paper")
SHAPE = PathShape.preset("paper")
TABLE_1 = np.radians([[100.0] * 3, [60.0] * 3, [60.0] * 3])  # paper Table 1


def _planner() -> PeriodPlanner:
    return PeriodPlanner(PAPER, SHAPE, TABLE_1, k_T=0.1, k_J=0.9)


def test_joint_ranges_match_a_dense_sample():
    via = np.array([[0.0, 0.0], [1.0, -0.5], [0.2, 0.4], [0.9, 0.1]])
    spline = plan_trajectory(via, 1.0, 1.0, 1.0).spline
    low, high = joint_ranges(spline)
    t = np.linspace(spline.t[0], spline.t[-1], 200001)
    q = spline(t)
    np.testing.assert_allclose(low, q.min(axis=0), atol=1e-9)
    np.testing.assert_allclose(high, q.max(axis=0), atol=1e-9)
    assert np.all(high > via.max(axis=0) + 1e-3)  # the spline overshoots its via-points here


def test_a_spline_beyond_the_stick_range_is_out_of_reach():
    planner = _planner()
    # At z_D = -2.5 m below y = -9 m every via-point is inside the joint ranges ...
    via = joint_via_points(PAPER, (-9.0, -2.5), SHAPE)
    assert not isinstance(via, Unreachable)
    # ... but the timed spline swings the stick past its outer stop between two of them.
    spline = plan_trajectory(via, *TABLE_1, k_T=0.1, k_J=0.9).spline
    stick = spline(np.linspace(spline.t[0], spline.t[-1], 20001))[:, 1]
    assert stick.max() > PAPER.joint_limits_rad[1][1]
    plan = planner.plan(-9.0, -2.5)
    assert isinstance(plan, Unreachable)
    assert plan.reason.startswith("the stick spline swings to")
    assert f"{math.degrees(PAPER.joint_limits_rad[1][1]):.2f}] deg" in plan.reason
    assert not planner.reachable(-9.0, -2.5)


def test_a_reachable_point_gives_the_planners_trajectory_and_is_remembered():
    planner = _planner()
    plan = planner.plan(-9.0, -0.1)
    assert planner.reachable(-9.0, -0.1)
    assert planner.plan(-9.0, -0.1) is plan  # planned once
    via = joint_via_points(PAPER, (-9.0, -0.1), SHAPE)
    np.testing.assert_allclose(plan.via_points, via)
    low, high = joint_ranges(plan.spline)
    limits = np.array(PAPER.joint_limits_rad)
    assert np.all(low >= limits[:, 0]) and np.all(high <= limits[:, 1])
    assert isinstance(plan.spline, BSpline)


def test_a_via_point_out_of_reach_keeps_its_reason():
    plan = _planner().plan(-20.0, -0.1)
    assert isinstance(plan, Unreachable) and plan.reason.startswith("entry via-point")


@pytest.mark.parametrize("z_D", [-0.1, -0.6, -1.2])
def test_reachable_points_stay_reachable_while_digging_down_to_the_limit(z_D):
    assert _planner().reachable(-9.0, z_D)
