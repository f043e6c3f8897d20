"""Excavator geometry (plant_models.geometry, .linkage, .presets), checked by independent means.

Inverse kinematics against forward kinematics, the cylinder laws against plain vector geometry
of the world points, Jacobians against central differences, the moment arm against the
perpendicular distance from the pin to the cylinder line, gravity torques against the derivative
of the potential energy, and the lab preset against the paper's published envelope.
"""

import dataclasses
import math

import numpy as np
import pytest
from finite_differences import assert_derivative, central_difference
from scipy.optimize import minimize

from plant_models import presets
from plant_models.geometry import (
    GRAVITY_M_S2,
    ExcavatorGeometry,
    Unreachable,
    arm_points,
    forward_kinematics,
    gravity_joint_torques,
    inverse_kinematics,
    inverse_kinematics_with_bucket_joint,
    pile_bucket_angle,
)
from plant_models.joint_strokes import (
    joint_angle_from_stroke,
    joint_rate_per_stroke_rate,
    moment_arm_m,
    stroke_from_joint_angle,
)
from plant_models.linkage import JOINT_NAMES

PRESETS = [presets.get(name) for name in presets.NAMES]
IDS = list(presets.NAMES)


def random_joints(geometry: ExcavatorGeometry, n: int, seed: int) -> np.ndarray:
    limits = np.array(geometry.joint_limits_rad)
    rng = np.random.default_rng(seed)
    return rng.uniform(limits[:, 0], limits[:, 1], (n, 3))


def direction(angle: float) -> np.ndarray:
    return np.array([-math.cos(angle), math.sin(angle)])


@pytest.mark.parametrize("geometry", PRESETS, ids=IDS)
def test_inverse_of_forward_kinematics_returns_the_joints(geometry):
    joints = random_joints(geometry, 400, seed=1)
    limits = np.array(geometry.joint_limits_rad)
    joints = np.vstack([joints, limits[:, 0], limits[:, 1]])  # every joint at both end stops
    tip_y, tip_z, bucket_angle = forward_kinematics(geometry, joints)
    for q, y, z, phi in zip(joints, tip_y, tip_z, bucket_angle, strict=True):
        solved = inverse_kinematics(geometry, y, z, phi)
        assert not isinstance(solved, Unreachable), solved
        np.testing.assert_allclose(solved, q, rtol=0, atol=1e-9)
        held = inverse_kinematics_with_bucket_joint(geometry, y, z, q[2])
        assert not isinstance(held, Unreachable), held
        assert forward_kinematics(geometry, held)[:2] == pytest.approx((y, z), abs=1e-9)
        assert held[2] == q[2]
        if preferred_branch(geometry, q):
            np.testing.assert_allclose(held, q, rtol=0, atol=1e-9)


def preferred_branch(geometry: ExcavatorGeometry, q: np.ndarray) -> bool:
    """True if the rigid stick+bucket link (stick pin -> tip) is folded down from the boom line,
    the branch inverse_kinematics_with_bucket_joint prefers."""
    rigid = geometry.stick_length_m + geometry.bucket_length_m * np.exp(1j * q[2])
    return math.remainder(q[1] + np.angle(rigid), 2 * math.pi) < 0.0


def test_held_bucket_ik_takes_the_other_branch_only_when_it_must():
    """With stick and bucket both fully curled the rigid link folds past the boom line; both
    branches can be within limits there, and the preferred one must then be used."""
    geometry = presets.get("paper")
    q = np.radians([8.0, -152.5, -120.0])
    assert not preferred_branch(geometry, q)
    tip = forward_kinematics(geometry, q)[:2]
    held = inverse_kinematics_with_bucket_joint(geometry, *tip, q[2])
    assert preferred_branch(geometry, held)
    assert forward_kinematics(geometry, held)[:2] == pytest.approx(tip, abs=1e-9)
    assert held[1] > q[1]  # the other solution: stick less folded


@pytest.mark.parametrize("geometry", PRESETS, ids=IDS)
def test_forward_kinematics_matches_chained_link_vectors(geometry):
    """Tip = foot + each link's length along its absolute angle; vectorised = one at a time."""
    joints = random_joints(geometry, 50, seed=2)
    tip_y, tip_z, bucket_angle = forward_kinematics(geometry, joints)
    lengths = (geometry.boom_length_m, geometry.stick_length_m, geometry.bucket_length_m)
    for i, q in enumerate(joints):
        tip = np.array(geometry.boom_foot_m, dtype=float)
        for length, angle in zip(lengths, np.cumsum(q), strict=True):
            tip = tip + length * direction(angle)
        assert (tip_y[i], tip_z[i]) == pytest.approx(tuple(tip), abs=1e-12)
        assert forward_kinematics(geometry, q) == pytest.approx(
            (tip_y[i], tip_z[i], bucket_angle[i]), abs=1e-12
        )
        points = arm_points(geometry, q)
        np.testing.assert_allclose(points["bucket_tip"], tip, atol=1e-12)


def test_hand_computed_pose():
    """Paper preset, boom straight up, stick straight down, bucket in line with the stick."""
    geometry = presets.get("paper")
    q = np.radians([59.0, -149.0, 0.0])
    y, z, phi = forward_kinematics(geometry, q)
    foot_y, foot_z = geometry.boom_foot_m
    boom = math.radians(59.0)
    assert y == pytest.approx(foot_y - 5.7 * math.cos(boom), abs=1e-12)
    expected_z = foot_z + 5.7 * math.sin(boom) + (3.18 + 1.5) * math.sin(math.radians(-90.0))
    assert z == pytest.approx(expected_z, abs=1e-12)
    assert phi == pytest.approx(math.radians(-90.0), abs=1e-15)


@pytest.mark.parametrize("geometry", PRESETS, ids=IDS)
def test_out_of_reach_and_beyond_limit_poses_are_reported(geometry):
    scale = geometry.boom_length_m
    cases = {
        "reach": (-3.0 * scale, 0.0, -math.pi / 2),  # three boom lengths away
        "fold": (geometry.boom_foot_m[0], geometry.boom_foot_m[1], -math.pi / 2),  # at the foot
        "bucket": (-1.2 * scale, 0.0, math.radians(150.0)),  # bucket line pointing up and back
    }
    for expected, (y, z, phi) in cases.items():
        result = inverse_kinematics(geometry, y, z, phi)
        assert isinstance(result, Unreachable)
        assert result.ok is False
        assert expected in result.reason
    held = inverse_kinematics_with_bucket_joint(geometry, -3.0 * scale, 0.0, 0.0)
    assert isinstance(held, Unreachable) and "reach" in held.reason
    beyond = inverse_kinematics_with_bucket_joint(geometry, -scale, 0.0, math.radians(90.0))
    assert isinstance(beyond, Unreachable) and "bucket" in beyond.reason


def test_a_limit_violation_names_the_joint_and_the_limit():
    geometry = presets.get("paper")
    q = np.array(geometry.joint_limits_rad)[:, 1].copy()
    q[1] += math.radians(2.0)  # stick 2 deg beyond its outer stop
    result = inverse_kinematics(geometry, *forward_kinematics(geometry, q))
    assert isinstance(result, Unreachable)
    assert result.reason.startswith("stick angle -23.10 deg beyond its limits")


@pytest.mark.parametrize("geometry", PRESETS, ids=IDS)
@pytest.mark.parametrize("joint", JOINT_NAMES)
def test_stroke_angle_round_trips(geometry, joint):
    cylinder = (geometry.boom_cylinder, geometry.stick_cylinder, geometry.bucket_linkage)[
        JOINT_NAMES.index(joint)
    ]
    for stroke in np.linspace(0.0, cylinder.stroke_m, 101):
        angle = joint_angle_from_stroke(geometry, joint, stroke)
        assert stroke_from_joint_angle(geometry, joint, angle) == pytest.approx(stroke, abs=1e-9)
    low, high = geometry.joint_limits_rad[JOINT_NAMES.index(joint)]
    for angle in np.linspace(low, high, 101):
        stroke = stroke_from_joint_angle(geometry, joint, angle)
        assert 0.0 <= stroke <= cylinder.stroke_m
        assert joint_angle_from_stroke(geometry, joint, stroke) == pytest.approx(angle, abs=1e-9)
    ends = sorted(joint_angle_from_stroke(geometry, joint, s) for s in (0.0, cylinder.stroke_m))
    assert ends == pytest.approx([low, high], abs=1e-15)


def test_stroke_and_angle_out_of_range_raise():
    geometry = presets.get("paper")
    with pytest.raises(ValueError, match="boom stroke"):
        joint_angle_from_stroke(geometry, "boom", -0.01)
    with pytest.raises(ValueError, match="stick stroke"):
        joint_angle_from_stroke(geometry, "stick", geometry.stick_cylinder.stroke_m + 0.01)
    with pytest.raises(ValueError, match="bucket angle"):
        stroke_from_joint_angle(geometry, "bucket", math.radians(90.0))
    with pytest.raises(ValueError, match="joint must be one of"):
        joint_angle_from_stroke(geometry, "arm", 0.1)


@pytest.mark.parametrize("geometry", PRESETS, ids=IDS)
def test_cylinder_lengths_match_the_distance_between_world_mount_points(geometry):
    """Law of cosines and four-bar closure against plain vector geometry of arm_points."""
    bucket = geometry.bucket_linkage
    for q in random_joints(geometry, 30, seed=3):
        p = arm_points(geometry, q)
        lengths = [
            np.linalg.norm(p["boom_cylinder_rod"] - p["boom_cylinder_base"]),
            np.linalg.norm(p["stick_cylinder_rod"] - p["stick_cylinder_base"]),
            np.linalg.norm(p["rocker_link_joint"] - p["bucket_cylinder_base"]),
        ]
        cylinders = (geometry.boom_cylinder, geometry.stick_cylinder, bucket)
        for joint, angle, length, cylinder in zip(JOINT_NAMES, q, lengths, cylinders, strict=True):
            stroke = stroke_from_joint_angle(geometry, joint, angle)
            assert cylinder.retracted_length_m + stroke == pytest.approx(length, abs=1e-12)
        # The four-bar closes: rocker and link keep their lengths, the link pin rides the bucket.
        joint_j = p["rocker_link_joint"]
        assert np.linalg.norm(joint_j - p["rocker_pivot"]) == pytest.approx(bucket.rocker_length_m)
        assert np.linalg.norm(joint_j - p["bucket_link_pin"]) == pytest.approx(bucket.link_length_m)
        to_pin = p["bucket_link_pin"] - p["bucket_pin"]
        to_tip = p["bucket_tip"] - p["bucket_pin"]
        offset = bucket.bucket_pin_offset_m
        angle_in_bucket = math.atan2(offset[1], offset[0])
        # angle from the bucket line to the link pin, in the arm's angle sense (mirror of y)
        measured = math.atan2(-to_pin[0], to_pin[1]) - math.atan2(-to_tip[0], to_tip[1])
        assert math.remainder(-measured - angle_in_bucket, 2 * math.pi) == pytest.approx(
            0.0, abs=1e-12
        )


def test_law_of_cosines_angle_between_mount_vectors():
    """The boom cylinder's length fixes the angle between the two mount vectors at the pin."""
    geometry = presets.get("paper")
    cylinder = geometry.boom_cylinder
    a, b = np.hypot(*cylinder.prev_mount_m), np.hypot(*cylinder.next_mount_m)
    for stroke in np.linspace(0.0, cylinder.stroke_m, 7):
        q = np.array([joint_angle_from_stroke(geometry, "boom", stroke), -1.0, 0.0])
        p = arm_points(geometry, q)
        u = p["boom_cylinder_base"] - p["boom_foot"]
        v = p["boom_cylinder_rod"] - p["boom_foot"]
        between = math.acos(np.dot(u, v) / (np.linalg.norm(u) * np.linalg.norm(v)))
        length = cylinder.retracted_length_m + stroke
        assert length**2 == pytest.approx(a * a + b * b - 2 * a * b * math.cos(between), abs=1e-9)


@pytest.mark.parametrize("geometry", PRESETS, ids=IDS)
@pytest.mark.parametrize("joint", JOINT_NAMES)
def test_jacobian_matches_central_difference(geometry, joint):
    index = JOINT_NAMES.index(joint)
    cylinder = (geometry.boom_cylinder, geometry.stick_cylinder, geometry.bucket_linkage)[index]
    for stroke in np.linspace(0.05, 0.95, 10) * cylinder.stroke_m:
        angle = joint_angle_from_stroke(geometry, joint, stroke)
        numeric = central_difference(
            lambda s: joint_angle_from_stroke(geometry, joint, float(s[0])), np.array([stroke]))
        analytic = joint_rate_per_stroke_rate(geometry, joint, angle)
        assert_derivative(np.array([analytic]), numeric)
        assert moment_arm_m(geometry, joint, angle) * analytic == pytest.approx(1.0)


@pytest.mark.parametrize("joint", ["boom", "stick"])
def test_moment_arm_is_the_pin_to_cylinder_line_distance(joint):
    geometry = presets.get("paper")
    pin = {"boom": "boom_foot", "stick": "stick_pin"}[joint]
    for q in random_joints(geometry, 20, seed=4):
        p = arm_points(geometry, q)
        base, rod = p[f"{joint}_cylinder_base"], p[f"{joint}_cylinder_rod"]
        line = (rod - base) / np.linalg.norm(rod - base)
        offset = rod - p[pin]
        distance = abs(offset[0] * line[1] - offset[1] * line[0])
        arm = moment_arm_m(geometry, joint, q[JOINT_NAMES.index(joint)])
        assert abs(arm) == pytest.approx(distance, rel=1e-9)


@pytest.mark.parametrize("geometry", PRESETS, ids=IDS)
def test_extending_cylinders_raise_the_boom_and_curl_stick_and_bucket(geometry):
    """Sign conventions of a backhoe: boom cylinder out lifts, stick and bucket cylinders out curl
    toward the machine (joint angles decrease)."""
    mid = np.mean(np.array(geometry.joint_limits_rad), axis=1)
    signs = [np.sign(joint_rate_per_stroke_rate(geometry, j, a)) for j, a in zip(
        JOINT_NAMES, mid, strict=True)]
    assert signs == [1.0, -1.0, -1.0]


@pytest.mark.parametrize("geometry", PRESETS, ids=IDS)
def test_gravity_torques_are_the_gradient_of_potential_energy(geometry):
    def potential(q, payload):
        p = arm_points(geometry, q)
        masses = (geometry.boom_mass.mass_kg, geometry.stick_mass.mass_kg,
                  geometry.bucket_mass.mass_kg + payload)
        coms = (p["boom_com"], p["stick_com"], p["bucket_com"])
        return GRAVITY_M_S2 * sum(m * c[1] for m, c in zip(masses, coms, strict=True))

    for payload in (0.0, 5.0 * geometry.bucket_mass.mass_kg):
        for q in random_joints(geometry, 10, seed=5):
            numeric = central_difference(lambda joints, m=payload: potential(joints, m), q)
            assert_derivative(gravity_joint_torques(geometry, q, payload_kg=payload), numeric)


def test_a_horizontal_arm_needs_a_lifting_boom_torque():
    geometry = presets.get("paper")
    q = np.radians([0.0, -30.0, -30.0])  # everything in front of the boom foot
    assert gravity_joint_torques(geometry, q)[0] > 0.0
    total = geometry.boom_mass.mass_kg + geometry.stick_mass.mass_kg + geometry.bucket_mass.mass_kg
    # Upper bound: all mass at the farthest point of the arm.
    reach = geometry.boom_length_m + geometry.stick_length_m + geometry.bucket_length_m
    assert gravity_joint_torques(geometry, q)[0] < total * GRAVITY_M_S2 * reach


def test_pile_bucket_angle_is_the_tip_to_pin_line_from_plus_y():
    geometry = presets.get("paper")
    for q in random_joints(geometry, 20, seed=6):
        p = arm_points(geometry, q)
        to_pin = p["bucket_pin"] - p["bucket_tip"]
        expected = math.atan2(to_pin[1], to_pin[0])
        phi = forward_kinematics(geometry, q)[2]
        assert math.remainder(pile_bucket_angle(phi) - expected, 2 * math.pi) == pytest.approx(
            0.0, abs=1e-12
        )
    np.testing.assert_array_equal(pile_bucket_angle(np.array([0.5, -1.0])), [-0.5, 1.0])


def envelope(geometry: ExcavatorGeometry) -> tuple[float, float]:
    """Deepest and highest tip z (m) over the joint limits, by bounded optimisation."""
    limits = np.array(geometry.joint_limits_rad)
    starts = random_joints(geometry, 8, seed=7)
    lowest = min(minimize(lambda q: forward_kinematics(geometry, q)[1], s, bounds=limits).fun
                 for s in starts)
    highest = -min(minimize(lambda q: -forward_kinematics(geometry, q)[1], s, bounds=limits).fun
                   for s in starts)
    return lowest, highest


def test_lab_preset_matches_the_published_envelope():
    """Paper section 3.3: digging depth 414 mm, height 832 mm."""
    lowest, highest = envelope(presets.get("lab"))
    assert lowest == pytest.approx(-0.414, abs=5e-4)
    assert highest == pytest.approx(0.832, abs=5e-4)


def test_paper_preset_envelope_is_that_of_a_20_t_machine():
    """Published 20 t class figures, standard 2.9 m stick: digging depth about 6.6-6.7 m, tip
    height 9.5-10 m; the paper preset's long stick (3.18 m, wider stick range) adds a few tenths
    of a metre to both."""
    lowest, highest = envelope(presets.get("paper"))
    assert -7.3 < lowest < -6.8
    assert 9.6 < highest < 10.3


def test_preset_lookup():
    assert presets.get("paper") is presets.get("paper")  # built once
    assert presets.get("lab").name == "lab"
    with pytest.raises(ValueError, match="unknown excavator preset 'mini'"):
        presets.get("mini")


def test_bad_input_is_rejected():
    paper = presets.get("paper")
    wrong = dataclasses.replace(paper.bucket_linkage, cylinder_side=-1)
    with pytest.raises(ValueError, match="bucket linkage does not assemble consistently"):
        dataclasses.replace(paper, bucket_linkage=wrong)
    with pytest.raises(ValueError, match="stick_length_m must be > 0"):
        dataclasses.replace(paper, stick_length_m=0.0)
    with pytest.raises(ValueError, match=r"joints must have shape"):
        forward_kinematics(paper, np.zeros(4))
    with pytest.raises(ValueError, match=r"joints must be finite"):
        forward_kinematics(paper, [0.0, math.nan, 0.0])
    with pytest.raises(ValueError, match=r"tip_z must be finite"):
        inverse_kinematics(paper, -9.0, math.nan, -1.0)
    with pytest.raises(ValueError, match=r"bucket_joint must be finite"):
        inverse_kinematics_with_bucket_joint(paper, -9.0, 0.0, math.inf)
