"""The plan beside the dig in the 3D channels (orchestrator.runlog.plan_scene), decoded as a
viewer decodes them (mcap-protobuf-support with the schemas stored in the file) and checked
against what the same log says elsewhere: the period records (D, via-points, the lowest tip
point), the measured joints on /joints composed through the arm's forward kinematics
(plant_models.geometry, a second implementation of the tip position), and /pile/profile."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap_protobuf.decoder import DecoderFactory

from orchestrator.campaign import run_campaign
from orchestrator.runlog import read_run
from orchestrator.runlog.plan_scene import START_KEYS, TRAIL_PERIOD_S
from orchestrator.scenario import load_scenario
from plant_models.geometry import forward_kinematics
from plant_models.plant import JOINTS

ROOT = Path(__file__).resolve().parents[1]
PERIODS = 3


@pytest.fixture(scope="module")
def logged(tmp_path_factory):
    path = tmp_path_factory.mktemp("plan") / "run.mcap"
    scenario = load_scenario(ROOT / "scenarios" / "paper-2020.toml", [f"periods={PERIODS}"])
    result = run_campaign(scenario, log_path=path)
    assert result.termination == "periods", result.message
    return path, scenario, read_run(path, topics=("/joints", "/pile/profile"))


def decoded(path: Path, topic: str) -> list[tuple[int, object]]:
    with open(path, "rb") as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        return [(m.log_time, d) for _, _, m, d in reader.iter_decoded_messages(topics=[topic])]


def tip(scenario, joints_rad: np.ndarray) -> np.ndarray:
    """Bucket tip (n, 3) in `world` (x = -y_machine, 0, z) by plant_models.geometry."""
    y, z, _ = forward_kinematics(scenario.geometry(), np.atleast_2d(joints_rad))
    return np.column_stack([-y, np.zeros_like(y), z])


def starts_ns(run) -> list[int]:
    return [int(round(r["t0_s"] * 1e9)) for r in run.periods]


def test_each_period_starts_with_its_planned_record(logged):
    path, _, run = logged
    with open(path, "rb") as stream:
        starts = [(m.log_time, json.loads(m.data)) for _, _, m in
                  make_reader(stream).iter_messages(topics=["/period/start"])]
    assert [t for t, _ in starts] == starts_ns(run)
    for (_, start), record in zip(starts, run.periods, strict=True):
        assert start == {key: record[key] for key in START_KEYS if key in record}


def test_the_plan_shows_d_the_via_points_and_at_the_end_the_lowest_point(logged):
    path, scenario, run = logged
    plans = decoded(path, "/scene/plan")
    assert [t for t, _ in plans[::2]] == starts_ns(run)
    assert [t for t, _ in plans[1::2]] == run.period_end_ns
    for k, record in enumerate(run.periods, start=1):
        for at_end, (_, update) in enumerate(plans[2 * k - 2:2 * k]):
            entities = {e.id: e for e in update.entities}
            assert [d.type for d in update.deletions] == [1]  # ALL: the last period's go
            assert set(entities) == {"plan/path", "plan/via_points", "plan/deepest_point",
                                     *(["dig/lowest_point"] if at_end else [])}
            d = entities["plan/deepest_point"].spheres[0].pose.position
            y_d, z_d = record["deepest_point_m"]
            assert (d.x, d.y, d.z) == pytest.approx((-y_d, 0.0, z_d), abs=1e-12)
            via = np.column_stack([record["via_points_rad"][j] for j in JOINTS])
            shown = [(s.pose.position.x, s.pose.position.z)
                     for s in entities["plan/via_points"].spheres]
            np.testing.assert_allclose(shown, tip(scenario, via)[:, [0, 2]], atol=1e-9)
            path_points = [(p.x, p.z) for p in entities["plan/path"].lines[0].points]
            reference = run.channels["/joints"].of_period(k)
            planned = tip(scenario, np.column_stack(
                [reference[f"reference_{j}_rad"] for j in JOINTS]))[:, [0, 2]]
            # The planned path starts and ends where the reference does, through the tip's
            # lowest planned point (decimated to the /tf rate: within 2 cm at the paper's speeds)
            np.testing.assert_allclose(path_points[0], planned[0], atol=1e-9)
            assert min(z for _, z in path_points) == pytest.approx(planned[:, 1].min(), abs=0.02)
            if at_end:
                low = entities["dig/lowest_point"].spheres[0].pose.position
                assert (low.x, low.z) == pytest.approx(
                    (-record["lowest_tip_m"][0], record["lowest_tip_m"][1]), abs=1e-12)


def test_the_trail_follows_the_measured_tip_during_the_period(logged):
    path, scenario, run = logged
    trails = decoded(path, "/scene/tip_trail")
    joints = run.channels["/joints"]
    times = joints.log_time_ns
    measured = np.column_stack([joints.fields[f"measured_{j}_rad"] for j in JOINTS])
    for k in range(1, PERIODS + 1):
        lo, hi = run.period_end_ns[k - 2] if k > 1 else 0, run.period_end_ns[k - 1]
        mine = [(t, u) for t, u in trails if lo < t <= hi]
        duration_s = (hi - lo) / 1e9
        assert abs(len(mine) - duration_s / TRAIL_PERIOD_S) <= 1.0
        assert mine[-1][0] == hi  # the last one at the period's end
        for t, update in mine[::7]:
            points = np.array([(p.x, p.y, p.z) for p in update.entities[0].lines[0].points])
            in_period = (joints.period == k) & (times <= t)
            expected = tip(scenario, measured[in_period])
            np.testing.assert_allclose(points[-1], expected[-1], atol=1e-9)  # the tip now
            np.testing.assert_allclose(points[0], expected[0], atol=1e-9)  # the start
            # every trail point is a measured tip position of the period up to now
            gaps = np.min(np.linalg.norm(points[:, None] - expected[None], axis=2), axis=1)
            assert gaps.max() < 1e-9


def test_earlier_trench_profiles_fade_behind_the_surface(logged):
    path, _, run = logged
    profiles = run.channels["/pile/profile"]
    scenes = decoded(path, "/scene/pile")
    assert len(scenes) == PERIODS + 1
    for index, (_, update) in enumerate(scenes):
        earlier = sorted((e for e in update.entities if e.id.startswith("pile/earlier/")),
                         key=lambda e: e.id)
        assert len(earlier) == min(index, 4)
        alphas = [e.lines[0].color.a for e in earlier]
        assert alphas == sorted(alphas, reverse=True) and all(0 < a < 1 for a in alphas)
        for age, entity in enumerate(earlier, start=1):
            shown = np.array([(p.x, p.z) for p in entity.lines[0].points])
            y, z = profiles.fields["y_m"][index - age], profiles.fields["z_m"][index - age]
            np.testing.assert_allclose(shown, np.column_stack([-y, z]), atol=1e-12)
