"""The simulated excavator: tracking of the paper's first period, statics and mass bookkeeping
against closed-form references, load-cell noise, and the arm coupling against the geometry."""

import dataclasses
import math

import numpy as np
import pytest
from finite_differences import central_difference

from orchestrator.plants.arm_coupling import ArmCoupling
from orchestrator.plants.simulated_excavator import SimulatedExcavator
from planner.digging_path import (
    LAB_DEEPEST_POINT_M,
    PAPER_DEEPEST_POINT_M,
    PathShape,
    joint_via_points,
    paper_joint_via_points,
)
from planner.trajectory import plan_trajectory
from plant_models import presets
from plant_models.geometry import forward_kinematics, gravity_joint_torques
from plant_models.hydraulics import DESIGN_POSE_RAD, default_config
from plant_models.joint_strokes import joint_angle_from_stroke, moment_arm_m
from plant_models.linkage import JOINT_NAMES
from plant_models.plant import JointReference, Plant

PAPER = presets.get("paper")
DEEPEST_POINT = {"paper": PAPER_DEEPEST_POINT_M, "lab": LAB_DEEPEST_POINT_M}
LIMITS = {"v_max": math.radians(100), "a_max": math.radians(60), "j_max": math.radians(60),
          "k_T": 0.1, "k_J": 0.9}  # the paper's Table 1 and case 2


def sampled(trajectory, dt):
    """The trajectory on t = k dt up to its end (at rest after it)."""
    t = np.arange(int(math.ceil(trajectory.duration / dt)) + 1) * dt
    return JointReference(t, trajectory(t, 0), trajectory(t, 1), trajectory(t, 2))


def move(start, end, duration, hold, dt=0.01):
    """Rest-to-rest minimum-jerk move from `start` to `end` (rad) and a hold at the end."""
    t = np.arange(int(round((duration + hold) / dt)) + 1) * dt
    s = np.clip(t / duration, 0.0, 1.0)
    shape = 10 * s**3 - 15 * s**4 + 6 * s**5
    rate = (30 * s**2 - 60 * s**3 + 30 * s**4) / duration
    accel = (60 * s - 180 * s**2 + 120 * s**3) / duration**2
    delta = np.asarray(end) - np.asarray(start)
    return JointReference(t, start + np.outer(shape, delta), np.outer(rate, delta),
                          np.outer(accel, delta))


@pytest.fixture(scope="module")
def paper_path():
    return plan_trajectory(paper_joint_via_points(), **LIMITS)


@pytest.fixture(scope="module")
def paper_periods(paper_path):
    """Three periods on the paper's first path: sampled at the communication step twice, then
    at 23.7 ms (a grid the plant must interpolate)."""
    with SimulatedExcavator(default_config("paper")) as plant:
        assert isinstance(plant, Plant) and plant.kind == "sim"
        periods = [plant.run_period(sampled(paper_path, dt)) for dt in (0.01, 0.01, 0.0237)]
    plant.close()  # safe twice
    with pytest.raises(RuntimeError, match="closed"):
        plant.run_period(sampled(paper_path, 0.01))
    return periods


def test_tracking_rms_below_half_a_degree_on_the_papers_first_period(paper_periods, paper_path):
    first = paper_periods[0]
    assert np.all(first.tracking_rms_rad < math.radians(0.5)), np.degrees(first.tracking_rms_rad)
    np.testing.assert_allclose(first.reference_rad, paper_path(first.t_s), atol=1e-12)
    np.testing.assert_allclose(first.t_s, np.arange(len(first.t_s)) * 0.01)


def test_lab_preset_tracks_and_digs_its_first_period():
    lab = presets.get("lab")
    via = joint_via_points(lab, LAB_DEEPEST_POINT_M, PathShape.preset("lab"))
    with SimulatedExcavator(default_config("lab")) as plant:
        period = plant.run_period(sampled(plan_trajectory(via, **LIMITS), 0.01))
    assert np.all(period.tracking_rms_rad < math.radians(0.5))
    assert period.weighed_mass_kg > 0.1


def test_a_reference_on_another_grid_is_interpolated_onto_the_step(paper_periods, paper_path):
    third = paper_periods[2]
    np.testing.assert_allclose(np.diff(third.t_s), 0.01)
    assert third.t_s[-1] >= paper_path.duration - 1e-9
    np.testing.assert_allclose(third.reference_rad, paper_path(third.t_s), atol=1e-4)
    assert np.all(third.tracking_rms_rad < math.radians(0.5))


def test_the_first_period_digs_and_the_load_cell_reads_the_bucket(paper_periods):
    first = paper_periods[0]
    assert first.signals["tip.z"].min() < -0.1  # the path goes below the ground
    assert first.weighed_mass_kg > 1.0
    assert first.weighed_mass_kg == first.signals["pile.bucket_mass"][-1]  # no noise


def test_mass_bookkeeping_across_periods(paper_periods):
    """Initial pile = density x width x depth x length (the Pile's defaults); afterwards every
    kilogram is in the pile, weighed in the bucket, or dumped by the plant after weighing."""
    initial = 1600.0 * 0.038 * 5.0 * 11.0
    first, second, _ = paper_periods
    assert first.signals["pile.pile_mass"][0] == pytest.approx(initial, rel=1e-12)
    assert first.weighed_mass_kg + first.signals["pile.pile_mass"][-1] \
        == pytest.approx(initial, rel=1e-12)
    assert second.signals["pile.dumped_mass"][0] == pytest.approx(first.weighed_mass_kg,
                                                                  rel=1e-12)
    assert second.weighed_mass_kg + second.signals["pile.dumped_mass"][-1] \
        + second.signals["pile.pile_mass"][-1] == pytest.approx(initial, rel=1e-12)
    # The profile read after the period holds the pile's mass: sum of cells above z_floor.
    cell = 11.0 / 220
    assert second.pile_grid_m[0] == pytest.approx(-13.0 + cell / 2)
    profile_mass = 1600.0 * 0.038 * cell * np.sum(second.pile_profile_m + 5.0)
    assert profile_mass == pytest.approx(second.signals["pile.pile_mass"][-1], rel=1e-9)
    assert second.pile_profile_m.min() < -0.1  # a trench


def test_a_path_above_the_ground_digs_nothing():
    shape = dataclasses.replace(PathShape.preset("paper"), entry_height_m=1.5)
    via = joint_via_points(PAPER, (-8.0, 1.0), shape)
    with SimulatedExcavator(default_config("paper")) as plant:
        period = plant.run_period(sampled(plan_trajectory(via, **LIMITS), 0.01))
    assert period.signals["tip.z"].min() > 0.05
    assert period.weighed_mass_kg == 0.0


@pytest.mark.parametrize("preset", ["paper", "lab"])
def test_statics_cylinder_forces_carry_the_gravity_torques(preset):
    """Move to a pose and hold: each cylinder's hydraulic force equals the gravity holding
    torque (plant_models.geometry, an energy derivative) over the moment arm, within 1 %."""
    geometry = presets.get(preset)
    start = joint_via_points(geometry, DEEPEST_POINT[preset], PathShape.preset(preset))[0]
    end = start + np.radians([-6.0, 8.0, 15.0])
    config = dataclasses.replace(default_config(preset), start_pose_rad=tuple(start))
    with SimulatedExcavator(config) as plant:
        period = plant.run_period(move(start, end, 3.0, 4.0))
    q = period.joints_rad[-1]
    np.testing.assert_allclose(q, end, atol=math.radians(0.05))
    torques = gravity_joint_torques(geometry, q)
    for j, joint in enumerate(JOINT_NAMES):
        expected = torques[j] / moment_arm_m(geometry, joint, q[j])
        assert period.signals[f"{joint}.F"][-1] == pytest.approx(expected, rel=0.01), joint


def run_short_periods(seed, count, noise=0.5):
    pose = paper_joint_via_points()[0]
    config = dataclasses.replace(default_config("paper"), load_cell_noise_kg=noise, seed=seed,
                                 start_pose_rad=tuple(pose))
    hold = move(pose, pose, 0.05, 0.0)
    with SimulatedExcavator(config) as plant:
        return np.array([plant.run_period(hold).weighed_mass_kg for _ in range(count)])


def test_load_cell_noise_is_reproducible_per_seed():
    first, again, other = (run_short_periods(seed, 200) for seed in (7, 7, 8))
    np.testing.assert_array_equal(first, again)
    assert not np.allclose(first, other)
    # The bucket is empty, so the readings are the noise itself: mean 0, std 0.5 kg.
    assert abs(first.mean()) < 4 * 0.5 / math.sqrt(200)
    assert first.std() == pytest.approx(0.5, rel=0.15)
    np.testing.assert_array_equal(run_short_periods(7, 3, noise=0.0), 0.0)


def test_a_reference_starting_elsewhere_is_a_clear_error():
    pose = paper_joint_via_points()[0]
    config = dataclasses.replace(default_config("paper"), start_pose_rad=tuple(pose))
    with SimulatedExcavator(config) as plant:
        away = pose + np.radians([0.0, 10.0, 0.0])
        with pytest.raises(ValueError, match=r"reference starts 10\.00 deg from the arm's stick"):
            plant.run_period(move(away, away, 0.1, 0.0))


def test_default_config_matches_the_linkage_and_the_design_pose():
    np.testing.assert_allclose(DESIGN_POSE_RAD, paper_joint_via_points()[2], atol=1e-8)
    for preset in ("paper", "lab"):
        config = default_config(preset)
        geometry = presets.get(preset)
        strokes = (geometry.boom_cylinder.stroke_m, geometry.stick_cylinder.stroke_m,
                   geometry.bucket_linkage.stroke_m)
        for spec, stroke in zip(config.cylinders, strokes, strict=True):
            assert spec.parameters["stroke"] == stroke
    with pytest.raises(ValueError, match="communication_step_s"):
        dataclasses.replace(default_config("paper"), communication_step_s=0.0)
    with pytest.raises(ValueError, match="unknown preset"):
        default_config("moon")


# ---- the arm coupling against plant_models.geometry and linkage -------------------------------

@pytest.fixture(scope="module")
def coupling():
    return ArmCoupling(PAPER)


def random_strokes(rng, n):
    return rng.uniform(0.0, 1.0, (n, 3)) * [PAPER.boom_cylinder.stroke_m,
                                             PAPER.stick_cylinder.stroke_m,
                                             PAPER.bucket_linkage.stroke_m]


def test_tables_match_the_linkage(coupling):
    rng = np.random.default_rng(1)
    for x in random_strokes(rng, 50):
        for j, joint in enumerate(JOINT_NAMES):
            angle, arm = coupling.joint_state(j, x[j])
            exact = joint_angle_from_stroke(PAPER, joint, x[j])
            assert angle == pytest.approx(exact, abs=1e-9)
            assert arm == pytest.approx(moment_arm_m(PAPER, joint, exact), rel=1e-6)


def test_kinematics_and_loads_match_the_geometry(coupling):
    """Pose from forward_kinematics; loads: gravity (with payload) from gravity_joint_torques,
    soil torques from the tip's Jacobian by central differences of forward_kinematics."""
    rng = np.random.default_rng(2)
    for x in random_strokes(rng, 20):
        kin = coupling.kinematics(*x)
        q = np.array(kin[:3])
        np.testing.assert_allclose(kin[3:6], forward_kinematics(PAPER, q), atol=1e-12)
        force, payload = rng.normal(0.0, 5e3, 2), rng.uniform(0.0, 500.0)
        jacobian = central_difference(lambda joints: forward_kinematics(PAPER, joints)[:2], q)
        holding = gravity_joint_torques(PAPER, q, payload) - jacobian.estimate.T @ force
        arms = np.array([moment_arm_m(PAPER, joint, q[j]) for j, joint in enumerate(JOINT_NAMES)])
        # Allowed: the coupling's table interpolation (moment arms linear between 4097 strokes,
        # about 1e-6 relative) plus the reference's own error (the difference's bound through
        # J^T F / arm).
        error = jacobian.error.T @ np.abs(force) / np.abs(arms)
        np.testing.assert_array_less(
            np.abs(coupling.loads(kin, *force, payload) - holding / arms),
            error + 1e-6 * np.abs(holding / arms) + 1e-3)
