"""Figures 13 and 14 of Vu & Tran 2020 (section 3.3) on scenarios/lab.toml: the joint angles of
the lab machine in periods 2 and 4, planned (the via-points that bound the four stages) and
measured (the simulated lab machine at the via-points' times, from the run log).

The paper's text (its figures are not in the copy we have): "In the first stage, the bucket
opens to reach a suitable angle (about -82 degree), and the boom and stick angles are unchanged.
Next, the bucket angle is remained, and the bucket is forced inside the material by increasing
the boom angle from initial value (about -72 degree) to the value of -35 degree. In the 3rd
stage, the bucket angle increases to close the bucket ... Finally, the boom angle changes to move
the material out of the ground. During the cycle of digging, the stick angle is kept constant.
[Period 4:] the angle of the stick is reduced to -25 degree." Section 2.1: in stage 4 the
bucket's angle stays "nearly zero".

The paper's angle convention, read from that text (the paper defines none):
    bucket  paper = CLOSED - bucket: it "increases to close" (ours decreases) and reads about 0
            when closed (stage 4), so the zero is the path's closed bucket joint, -120 deg;
    boom    paper = BOOM_ZERO - boom: "increasing" it forces the bucket into the material, which
            with stick and bucket held is the boom lowering (ours decreasing); its zero is not
            given, BOOM_ZERO puts period 2's entry (where stage 2 starts) at the paper's -72 deg;
    stick   paper = stick + STICK_ZERO: it is "reduced" when D changes in period 4, which here
            moves D toward the machine and folds the stick in (ours decreasing); STICK_ZERO puts
            period 4's stick at D at the paper's -25 deg.
So only the bucket's -82 deg (an opening of 82 deg from closed) and the directions are checks of
our path; the -72 and -25 deg are where the unknown zeros are fixed.

Reproduced (tests below): stage 1 opens the bucket to -82.8 deg (period 2); stage 2 holds the
bucket and the boom angle increases (the boom lowers); stage 3 closes the bucket to 0 with boom
and stick still (at the via-points); stage 4 holds the bucket closed and lifts the load back to
the start; in period 4 the stick is reduced (-25 deg at D, from +58 deg in period 2) and stays
within 7 deg of that while digging (entry, D, closed).

Not reproduced, measured (planned = measured to 0.01 deg; paper convention, deg):
    period 2 (Figure 13)  start -> entry -> D (= closed) -> lifted: boom -92.4 -> -72.0 ->
        -70.9 -> -92.4, stick +22.4 -> +67.4 -> +58.1 -> +22.4, bucket 0 -> -82.8 -> -82.8 -> 0
        -> 0: stage 1 moves boom (20.4 deg) and stick (45 deg) too, stage 2 moves the boom 1.1
        deg (paper 37) and the stick 9.2 deg (paper 0);
    period 4 (Figure 14)  boom -92.4 -> -89.5 -> -88.8 -> -92.4, stick +22.4 -> -18.6 -> -25.0
        -> +22.4, bucket 0 -> -151.2 -> -151.2 -> 0 (the entry's fixed attack angle with the
        stick folded in; the paper gives no bucket angle for period 4).
Why, exactly:
  1. The path keeps one start pose for every period (planner.digging_path: start_tip_m and
     lift_tip_m are fixed, so each period ends where it began and the next can start there; the
     lab driver refuses a period whose start is away from the arm). The stick can then be
     constant over a period only at that pose's stick angle: it cannot change between periods
     (Figure 14's -25 deg in period 4) and stay constant within each.
  2. Stage 2 holds the bucket joint and reaches D by inverse kinematics, so the stick is still in
     stage 2 only if D lies on the entry's circle about the boom foot: one z_D per y_D, while
     eq. 5 moves z_D in every period.
  3. Figure 13 is constructible for one period (test_the_figure_13_path_fits_the_path_structure):
     entry = the lifted pose with the bucket open, a 37 deg boom swing down to D. But the lifted
     pose is then 0.35 m above the sand, and the planned B-spline passes D with the boom still
     moving: it swings on 15-18 deg past D while the bucket closes, about 0.1 m below D. With the
     lab's 20 bar cylinders and the sandbox's sand the bucket then stalls while closing (tracking
     errors up to 48 deg, rms up to 10 deg) and the masses jump by up to 1.6 kg for a 1 mm change
     of D; e.g. the exact Figure 13 path with D0 = (-0.65, +0.039) m misses by 3.5, 0.75 and
     2.08 kg and ends at the workspace limit after period 3. Smaller swings with the stick held
     leave period 3 1.5-3 kg short or stall too; stage 1 moving the bucket alone with this
     scenario's drag overfills period 2 (6.4 kg) or stalls, and keeps period 4's deeper D
     reachable (no change of trajectory). A search over D0, dz_0, dy_0, the sandbox floor, the
     entry's height and offset, the bucket's open and closed angles and the boom swing (over
     1000 campaigns, swings of 2-40 deg) found no setting with Figure 15's errors within
     tests/test_lab_reproduction.py's tolerances, its change of trajectory in period 4 and
     tracking within 0.5 deg. So the lab scenario keeps the path that reproduces Figure 15.

Tolerances: planned via-points within 0.01 deg (the scenario gives the start pose's bucket
angle, and this module the convention's zeros, to 0.01 deg); measured angles at the via-points
are checked within 2 deg: the 20 bar bucket lags its reference by up to 1.3 deg as it closes
through the sand (the soil force acts on the whole 0.24 m edge), 2 deg is the plant's start
tolerance for the next period, and the motions Figures 13 and 14 tell apart are 20-150 deg;
"about -82" is checked within 2 deg (the paper's own rounding and a reading of its figure).
"""

import math
from pathlib import Path

import numpy as np
import pytest

from orchestrator.campaign import run_campaign
from orchestrator.runlog import read_run
from orchestrator.scenario import load_scenario
from planner.digging_path import PathShape, joint_via_points
from planner.period_plan import PeriodPlanner
from plant_models import presets
from plant_models.geometry import forward_kinematics, inverse_kinematics_with_bucket_joint

SCENARIO = Path(__file__).resolve().parent.parent / "scenarios" / "lab.toml"
JOINTS = ("boom", "stick", "bucket")
START, ENTRY, DEEPEST, CLOSED, LIFTED = range(5)
CLOSED_BUCKET_DEG = -120.0  # the path's closed bucket joint: the paper's bucket zero
BOOM_ZERO_DEG = -65.53      # period 2's start boom (6.47 deg) reads -72 deg
STICK_ZERO_DEG = 98.65      # period 4's stick at D (-123.65 deg) reads -25 deg
PLANNED_DEG, MEASURED_DEG = 0.01, 2.0


def paper_angles(joints_deg) -> np.ndarray:
    """Our joint angles (n, 3) deg [boom, stick, bucket] in the paper's lab convention."""
    q = np.asarray(joints_deg, dtype=float)
    return np.stack([BOOM_ZERO_DEG - q[:, 0], q[:, 1] + STICK_ZERO_DEG,
                     CLOSED_BUCKET_DEG - q[:, 2]], axis=1)


@pytest.fixture(scope="module")
def periods(tmp_path_factory):
    """k -> (planned, measured): the paper-convention angles (5, 3) deg at the via-points."""
    path = tmp_path_factory.mktemp("figures") / "lab.mcap"
    result = run_campaign(load_scenario(SCENARIO, ["periods=4"]), log_path=path)
    assert result.termination == "periods", result.message
    joints = read_run(path, topics=["/joints"]).channels["/joints"]
    out = {}
    for record in result.records:
        samples = joints.of_period(record["k"])
        times = record["t0_s"] + np.concatenate([[0.0], np.cumsum(record["segment_durations_s"])])
        planned = np.degrees([record["via_points_rad"][j] for j in JOINTS]).T
        measured = np.degrees([np.interp(times, samples["t_s"], samples[f"measured_{j}_rad"])
                               for j in JOINTS]).T
        out[record["k"]] = (paper_angles(planned), paper_angles(measured))
    return out


def each(periods, k):
    planned, measured = periods[k]
    return ((planned, PLANNED_DEG), (measured, MEASURED_DEG))


def test_stage_1_opens_the_bucket_to_about_minus_82_deg(periods):
    for angles, tol in each(periods, 2):
        assert angles[START, 2] == pytest.approx(0.0, abs=tol)  # closed: "nearly zero"
        assert angles[ENTRY, 2] == pytest.approx(-82.0, abs=2.0)


@pytest.mark.parametrize("k", [2, 4])
def test_stage_2_holds_the_bucket_and_increases_the_boom_angle(periods, k):
    for angles, tol in each(periods, k):
        assert angles[DEEPEST, 2] == pytest.approx(angles[ENTRY, 2], abs=tol)
    planned = periods[k][0]  # the boom lowers into the sand: by 1 deg, within the tracking
    assert planned[DEEPEST, 0] > planned[ENTRY, 0] + PLANNED_DEG


@pytest.mark.parametrize("k", [2, 4])
def test_stage_3_closes_the_bucket_with_boom_and_stick_still(periods, k):
    for angles, tol in each(periods, k):
        np.testing.assert_allclose(angles[CLOSED, :2], angles[DEEPEST, :2], atol=tol)
        assert angles[CLOSED, 2] == pytest.approx(0.0, abs=tol)


@pytest.mark.parametrize("k", [2, 4])
def test_stage_4_keeps_the_bucket_closed_and_lifts_back_to_the_start(periods, k):
    for angles, tol in each(periods, k):
        assert angles[LIFTED, 2] == pytest.approx(0.0, abs=tol)
        np.testing.assert_allclose(angles[LIFTED], angles[START], atol=tol)
        assert angles[LIFTED, 0] < angles[CLOSED, 0] - 3.0  # the boom rises: out of the sand


def test_period_4_reduces_the_stick_to_minus_25_deg(periods):
    for (angles_2, tol), (angles_4, _) in zip(each(periods, 2), each(periods, 4), strict=True):
        assert angles_4[DEEPEST, 1] == pytest.approx(-25.0, abs=tol)
        assert angles_2[DEEPEST, 1] > angles_4[DEEPEST, 1] + 45.0  # "reduced"
        # While digging (entry, D, closed) the stick stays within 7 deg.
        assert np.ptp(angles_4[ENTRY:LIFTED, 1]) < 7.0


def figure_13_path(deepest_point, open_bucket_deg, closed_bucket_deg, boom_swing_deg):
    """The lab's PathShape with Figure 13's pattern around D: entry = D's pose (bucket joint
    open) with the boom raised by boom_swing_deg, start = lift = the entry with the bucket
    closed; the stick is the same at start, entry and D."""
    lab = presets.get("lab")
    at_d = inverse_kinematics_with_bucket_joint(lab, *deepest_point, math.radians(open_bucket_deg))
    entry = at_d + np.radians([boom_swing_deg, 0.0, 0.0])
    entry_y, entry_z, attack = forward_kinematics(lab, entry)
    start_y, start_z, start_angle = forward_kinematics(
        lab, [entry[0], entry[1], math.radians(closed_bucket_deg)])
    return PathShape(start_tip_m=(start_y, start_z), start_bucket_angle_rad=start_angle,
                     entry_offset_m=deepest_point[0] - entry_y, entry_height_m=entry_z,
                     entry_bucket_angle_rad=attack,
                     closed_bucket_joint_rad=math.radians(closed_bucket_deg),
                     lift_tip_m=(start_y, start_z))


def test_the_figure_13_path_fits_the_path_structure():
    """Figure 13's pattern exactly, for one D: 0.12 m closer in and 3 mm deeper than period 2's
    (the 37 deg swing must end at least 18.5 deg below the boom foot's level, or the entry would
    be closer to the machine than D). The lab scenario does not dig with it (docstring, 3.)."""
    scenario = load_scenario(SCENARIO)
    deepest = (-0.65, -0.06)
    shape = figure_13_path(deepest, CLOSED_BUCKET_DEG + 82.0, CLOSED_BUCKET_DEG, 37.0)
    assert shape.entry_offset_m >= 0.0 and shape.entry_height_m > 0.3  # the lifted pose
    via = np.degrees(joint_via_points(scenario.geometry(), deepest, shape))
    angles = paper_angles(via)
    angles[:, 0] += -72.0 - angles[START, 0]  # this path's own boom zero
    np.testing.assert_allclose(angles[:, 1], angles[START, 1], atol=1e-6)  # the stick: constant
    np.testing.assert_allclose(angles[ENTRY, :2], angles[START, :2], atol=1e-6)
    np.testing.assert_allclose(angles[:, 2], [0.0, -82.0, -82.0, 0.0, 0.0], atol=1e-6)
    np.testing.assert_allclose(angles[:, 0], [-72.0, -72.0, -35.0, -35.0, -72.0], atol=1e-6)
    planner = PeriodPlanner(scenario.geometry(), shape, scenario.limits_rad(),
                            scenario.trajectory.k_T, scenario.trajectory.k_J)
    assert planner.reachable(*deepest)  # within every joint's range and Table 1's limits
