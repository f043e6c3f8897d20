"""The campaign loop against a test double plant (tests/kinematic_plant.py): the records follow
paper eq. 5 and Fig. 5 period by period, every planned spline keeps Table 1's limits (checked by
an independent exact peak search with scipy's PPoly), the plant gets the spline it was planned,
and every way a campaign ends returns normally with the plant closed."""

import json
from pathlib import Path

import numpy as np
import pytest
from kinematic_plant import KinematicPlant
from scipy.interpolate import BSpline, PPoly

from orchestrator.campaign import loop as campaign
from orchestrator.campaign.loop import run_campaign, sample_reference
from orchestrator.campaign.record import joint_columns, reference_spline
from orchestrator.runlog import read_run
from orchestrator.scenario import load_scenario, scenario_from_dict
from planner.digging_path import joint_via_points
from planner.trajectory import plan_trajectory
from plant_models.geometry import Unreachable
from plant_models.plant import JOINTS, PeriodMeasurement, PeriodStopped

PAPER = Path(__file__).resolve().parent.parent / "scenarios" / "paper-2020.toml"


@pytest.fixture(scope="module")
def paper():
    return load_scenario(PAPER)


@pytest.fixture(scope="module")
def dug(paper):
    """30 periods on the paper scenario with the double: it deepens, resets once, deepens."""
    adaptation = {**paper.to_dict()["adaptation"], "dy_0_m": 2.5}
    scenario = scenario_from_dict({**paper.to_dict(), "periods": 30, "adaptation": adaptation})
    plant = KinematicPlant(scenario.geometry())
    seen = []
    result = run_campaign(scenario, plant=plant, progress=seen.append)
    return scenario, plant, result, seen


def _out_of_reach(scenario, y_D, z_D) -> bool:
    """The path through D has a via-point out of reach, or its spline, sampled densely, leaves
    a joint's range (the paper: "positions on the trajectory out of reach")."""
    via = joint_via_points(scenario.geometry(), (y_D, z_D), scenario.path_shape())
    if isinstance(via, Unreachable):
        return True
    spline = plan_trajectory(via, *scenario.limits_rad(), k_T=scenario.trajectory.k_T,
                             k_J=scenario.trajectory.k_J)
    q = spline(np.linspace(0.0, spline.duration, 20001))
    limits = np.array(scenario.geometry().joint_limits_rad)
    return bool(np.any(q < limits[:, 0] - 1e-9) or np.any(q > limits[:, 1] + 1e-9))


def _exact_peak(spline: BSpline, order: int) -> np.ndarray:
    """max |d^order q / dt^order| per joint over the spline, from the piecewise polynomial's
    breakpoints and the real roots of the next derivative (no sampling)."""
    peaks = []
    for joint in range(spline.c.shape[1]):
        single = BSpline(spline.t, spline.c[:, joint], spline.k)
        poly = PPoly.from_spline(single).derivative(order)
        candidates = np.concatenate([poly.x, poly.derivative().roots(extrapolate=False)])
        candidates = candidates[np.isfinite(candidates)]
        peaks.append(np.max(np.abs(poly(candidates))))
    return np.array(peaks)


def test_every_period_follows_eq5_and_the_reset_of_fig5(dug):
    scenario, _, result, _ = dug
    rule, defaults = scenario.fuzzy_rule(), scenario.adaptation_defaults()
    records = result.records
    assert [r["k"] for r in records] == list(range(1, len(records) + 1))
    first = records[0]
    assert first["deepest_point_m"] == [defaults.y_D0, defaults.z_D0]
    assert (first["dz_m"], first.get("eps_m"), first["reset"], first["flag"]) == \
        (defaults.dz_0, None, False, False)
    assert "eps_m" not in first and all("eps_m" in r for r in records[1:])
    resets = [r["k"] for r in records if r["reset"]]
    assert len(resets) == 1, "the double digs deep enough to reach the limit once"
    for before, now in zip(records, records[1:], strict=False):
        assert now["eps_m"] == rule(scenario.target_mass_kg - before["mass_kg"])
        assert now["error_kg"] == scenario.target_mass_kg - now["mass_kg"]
        (y0, z0), (y1, z1) = before["deepest_point_m"], now["deepest_point_m"]
        dz = before["dz_m"] + now["eps_m"]
        if now["reset"]:
            # Fig. 5: the eq.-5 candidate was out of reach; back to the defaults, y shifted.
            assert _out_of_reach(scenario, y0, z0 - dz)
            assert (y1, z1, now["dz_m"]) == (defaults.y_D0 + defaults.dy_0, defaults.z_D0,
                                            defaults.dz_0)
            assert now["flag"] and not before["flag"]
        else:
            assert (now["dz_m"], y1, z1) == (dz, y0, z0 - dz)  # eq. 5 exactly
            assert now["flag"] == before["flag"]
            assert not _out_of_reach(scenario, y1, z1)


def test_every_spline_keeps_the_limits_and_passes_its_via_points(dug):
    scenario, _, result, _ = dug
    limits = scenario.limits_rad()
    for record in result.records:
        spline = reference_spline(record)
        for order, key in enumerate(("max_abs_velocity_deg_s", "max_abs_acceleration_deg_s2",
                                     "max_abs_jerk_deg_s3")):
            peak = _exact_peak(spline, order + 1)
            assert np.all(peak <= limits[order] * (1 + 1e-9)), (record["k"], key)
            np.testing.assert_allclose(np.degrees(peak), record[key], rtol=1e-6, atol=1e-9)
        times = np.concatenate([[0.0], np.cumsum(record["segment_durations_s"])])
        np.testing.assert_allclose(spline(times), joint_columns(record["via_points_rad"]),
                                   atol=1e-9)
        assert record["duration_s"] == pytest.approx(times[-1], rel=1e-12)
        # At rest at both ends (paper section 3.1).
        for order in (1, 2, 3):
            np.testing.assert_allclose(spline(times[[0, -1]], nu=order), 0.0, atol=1e-9)


def test_the_plant_gets_the_planned_spline_on_its_grid(dug):
    _, plant, result, _ = dug
    assert len(plant.references) == len(result.records)
    for reference, record in zip(plant.references, result.records, strict=True):
        step = plant.communication_step_s
        assert reference.t_s[1] - reference.t_s[0] == pytest.approx(step)
        assert reference.t_s[-1] >= record["duration_s"] > reference.t_s[-1] - step
        spline = reference_spline(record)
        assert spline.k == 5
        inside = reference.t_s <= record["duration_s"]
        np.testing.assert_allclose(reference.position_rad[inside], spline(reference.t_s[inside]),
                                   atol=1e-12)
        np.testing.assert_allclose(reference.position_rad[-1],
                                   joint_columns(record["via_points_rad"])[-1], atol=1e-12)


def test_the_campaign_reports_what_the_plant_weighed(dug):
    _, plant, result, seen = dug
    assert plant.closed == 1
    assert result.termination == "periods" and result.error is None
    assert seen == result.records  # progress saw every record as it came
    json.dumps(result.records)  # plain data


def test_the_dataframe_has_one_row_per_period(dug):
    _, _, result, _ = dug
    frame = result.to_dataframe()
    assert list(frame.index) == [r["k"] for r in result.records]
    per_joint = [f"{name}_{joint}" for name in ("max_abs_velocity_deg_s",
                                                "max_abs_acceleration_deg_s2",
                                                "max_abs_jerk_deg_s3", "tracking_rms_deg")
                 for joint in JOINTS]
    # The productivity figures a plant without energy signals gives (the test double's).
    productivity = ["cycle_time_s", "rated_payload_kg", "fill_factor", "productivity_t_h"]
    assert list(frame.columns) == ["t0_s", "y_D_m", "z_D_m", "dz_m", "eps_m", "flag", "reset",
                                   "mass_kg", "error_kg", "duration_s", "planner_ms", *per_joint,
                                   *productivity]
    np.testing.assert_array_equal(frame["mass_kg"], [r["mass_kg"] for r in result.records])
    np.testing.assert_array_equal(frame["z_D_m"],
                                  [r["deepest_point_m"][1] for r in result.records])
    assert (frame["tracking_rms_deg_boom"] == 0.0).all()  # the double tracks exactly
    assert (np.diff(frame["t0_s"]) >= frame["duration_s"].iloc[:-1]).all()


def test_the_workspace_limit_ends_a_campaign_normally(paper):
    # A heavy target drives D down every period: the limit at y = -9 m, one shift toward the
    # machine by 0.5 m, the limit again there, and the end (paper Fig. 5). The pile's capacity
    # goes up with it: a scenario may not ask for more than the bucket holds.
    data = paper.to_dict()
    data["plant"]["pile"]["parameters"]["capacity"] = 0.25  # m^3: 400 kg at 1600 kg/m^3
    scenario = scenario_from_dict({**data, "periods": 60, "target_mass_kg": 300.0,
                                   "adaptation": {**data["adaptation"], "dy_0_m": 0.5}})
    plant = KinematicPlant(scenario.geometry())
    result = run_campaign(scenario, plant=plant)
    assert result.termination == "workspace_limit"
    assert 2 < len(result.records) < 60
    assert sum(r["reset"] for r in result.records) == 1
    assert result.records[-1]["flag"]
    last = result.records[-1]
    dz = last["dz_m"] + scenario.fuzzy_rule()(scenario.target_mass_kg - last["mass_kg"])
    y, z = last["deepest_point_m"]
    assert _out_of_reach(scenario, y, z - dz)
    assert plant.closed == 1


class RecordingLog:
    def __init__(self):
        self.periods, self.closed = [], []

    def log_period(self, record, measurement, t0_s):
        self.periods.append((record["k"], t0_s))

    def wait_written(self):
        pass

    def close(self, termination, message=""):
        self.closed.append((termination, message))


def test_a_runtime_failure_closes_plant_and_log_and_returns_an_error(paper, monkeypatch):
    log = RecordingLog()
    monkeypatch.setattr(campaign, "open_run_log", lambda scenario, path, overwrite: log)
    plant = KinematicPlant(paper.geometry(), fail_in_period=3)
    result = run_campaign(paper, plant=plant, log_path="unused.mcap")
    assert result.termination == "error"
    assert result.message == "period 3: RuntimeError: hydraulic hose burst (test double)"
    assert isinstance(result.error, RuntimeError)
    assert [r["k"] for r in result.records] == [1, 2]
    assert [k for k, _ in log.periods] == [1, 2]
    assert log.closed == [("error", result.message)]
    assert plant.closed == 1


def test_a_normal_end_closes_the_log_with_its_termination(paper, monkeypatch):
    log = RecordingLog()
    monkeypatch.setattr(campaign, "open_run_log", lambda scenario, path, overwrite: log)
    scenario = scenario_from_dict({**paper.to_dict(), "periods": 3})
    result = run_campaign(scenario, plant=KinematicPlant(scenario.geometry()), log_path="x.mcap")
    assert result.termination == "periods"
    assert log.closed == [("periods", result.message)]
    t0 = [t for _, t in log.periods]
    assert t0[0] == 0.0 and all(b > a for a, b in zip(t0, t0[1:], strict=False))


def test_a_campaign_is_deterministic(paper):
    scenario = scenario_from_dict({**paper.to_dict(), "periods": 4})
    runs = [run_campaign(scenario, plant=KinematicPlant(scenario.geometry())) for _ in range(2)]
    for first, second in zip(*(r.records for r in runs), strict=True):
        first, second = dict(first), dict(second)
        first.pop("planner_ms"), second.pop("planner_ms")  # wall time
        assert first == second


def test_a_scenario_path_is_accepted(tmp_path):
    path = tmp_path / "short.toml"
    path.write_text("periods = 2\n")
    plant = KinematicPlant(load_scenario(path).geometry())
    result = run_campaign(path, plant=plant)
    assert result.scenario.name == "short" and len(result.records) == 2


def test_sampling_reaches_the_end_of_the_trajectory():
    trajectory = plan_trajectory([[0.0, 0.0, 0.0], [0.5, -0.2, 0.3]], 1.0, 1.0, 1.0)
    reference = sample_reference(trajectory, 0.05)
    assert reference.t_s[-1] >= trajectory.duration > reference.t_s[-1] - 0.05
    np.testing.assert_allclose(reference.position_rad[-1], [0.5, -0.2, 0.3], atol=1e-12)
    np.testing.assert_allclose(reference.velocity_rad_s[[0, -1]], 0.0, atol=1e-12)
    with pytest.raises(ValueError, match="communication step"):
        sample_reference(trajectory, 0.0)


def test_an_existing_log_is_refused_before_anything_is_dug_unless_overwritten(paper, tmp_path):
    scenario = scenario_from_dict({**paper.to_dict(), "periods": 1})
    path = tmp_path / "run.mcap"
    path.write_bytes(b"an earlier run")
    plant = KinematicPlant(scenario.geometry())
    with pytest.raises(FileExistsError, match="already exists"):
        run_campaign(scenario, plant=plant, log_path=path)
    assert path.read_bytes() == b"an earlier run"  # nothing already computed is lost
    assert plant.closed == 1 and not plant.ground_m.any()  # closed, and it never dug
    result = run_campaign(scenario, plant=KinematicPlant(scenario.geometry()), log_path=path,
                          overwrite=True)
    assert result.termination == "periods"
    assert read_run(path).periods == result.records


class StopsMidPeriod(KinematicPlant):
    """Stops in period 2 after half of it, handing over what it measured as the Plant contract
    says (a PeriodStopped, like the lab driver's LabStop)."""

    def run_period(self, reference):
        measured = super().run_period(reference)
        if len(self.references) == 2:
            half = len(measured.t_s) // 2
            raise PeriodStopped("emergency stop (test double)", PeriodMeasurement(
                measured.t_s[:half], measured.joints_rad[:half], measured.reference_rad[:half],
                float("nan")))
        return measured


def test_what_a_stopped_period_measured_is_in_the_log(paper, tmp_path):
    scenario = scenario_from_dict({**paper.to_dict(), "periods": 3})
    path = tmp_path / "stopped.mcap"
    result = run_campaign(scenario, plant=StopsMidPeriod(scenario.geometry()), log_path=path)
    assert result.termination == "error" and "emergency stop" in result.message
    run = read_run(path, topics=("/joints",))
    assert len(run.periods) == 1 and run.termination == "error"
    joints = run.channels["/joints"]
    complete, unfinished = joints.of_period(1), joints.of_period(2)
    assert len(unfinished["t_s"]) > 10  # the half period is there, after period 1's samples
    assert unfinished["t_s"][0] == pytest.approx(result.records[0]["duration_s"], abs=0.05)
    assert len(complete["t_s"]) > len(unfinished["t_s"])


def _strategy(paper, **adaptation):
    data = paper.to_dict()
    return scenario_from_dict({**data, "periods": 6,
                               "adaptation": {**data["adaptation"], **adaptation}})


def test_the_proportional_strategy_corrects_by_gain_times_error_in_eq5(paper):
    """eps = gain * dm, in the same eq. 5 as the fuzzy rule; a larger error, a larger step (no
    saturation, unlike the fuzzy rule's r_7)."""
    scenario = _strategy(paper, strategy="proportional", gain_m_per_kg=0.02)
    result = run_campaign(scenario, plant=KinematicPlant(scenario.geometry()))
    records = result.records
    assert len(records) == 6
    for before, now in zip(records, records[1:], strict=False):
        dm = scenario.target_mass_kg - before["mass_kg"]
        assert now["eps_m"] == pytest.approx(0.02 * dm, rel=1e-15)
        if not now["reset"]:
            assert now["deepest_point_m"][1] == pytest.approx(
                before["deepest_point_m"][1] - (before["dz_m"] + now["eps_m"]), abs=1e-15)


def test_the_proportional_default_gain_is_the_fuzzy_rules_secant(paper):
    scenario = _strategy(paper, strategy="proportional")
    fuzzy = paper.fuzzy_rule()
    gain = fuzzy.outputs_m[-1] / fuzzy.centres_kg[-1]
    assert scenario.adaptation_rule()(fuzzy.centres_kg[-1]) == pytest.approx(fuzzy.outputs_m[-1])
    assert scenario.adaptation_rule().gain_m_per_kg == pytest.approx(gain, rel=1e-15)


def test_the_fixed_strategy_digs_one_trajectory_over_and_over(paper):
    """No adaptation: every period through D0. The double's ground keeps the first cut, so the
    later periods dig nothing: what adaptation is for."""
    scenario = _strategy(paper, strategy="fixed")
    plant = KinematicPlant(scenario.geometry())
    result = run_campaign(scenario, plant=plant)
    points = [r["deepest_point_m"] for r in result.records]
    assert points == [[scenario.adaptation.y_D0_m, scenario.adaptation.z_D0_m]] * 6
    assert result.records[0]["mass_kg"] > 1.0
    assert all(r["mass_kg"] < 1e-9 for r in result.records[1:])
    assert all(np.array_equal(ref.position_rad, plant.references[0].position_rad)
               for ref in plant.references)


def test_an_unknown_strategy_or_a_negative_gain_is_refused(paper):
    from orchestrator.scenario import ScenarioError

    for bad in ({"strategy": "neural"}, {"strategy": "proportional", "gain_m_per_kg": -0.01}):
        with pytest.raises(ScenarioError, match="strategy|gain_m_per_kg"):
            _strategy(paper, **bad)


_CRASHING_CAMPAIGN = """
import os, signal, sys, time
sys.path.insert(0, "tests")
from kinematic_plant import KinematicPlant
from orchestrator.campaign import run_campaign
from orchestrator.runlog import mcap_records
from orchestrator.scenario import load_scenario

written = mcap_records.McapChunkWriter._write_chunk


def slow(self, *args):  # a slow disk: the log's thread is still on period 2 when 3 starts
    time.sleep(0.3)
    written(self, *args)


mcap_records.McapChunkWriter._write_chunk = slow


class Crashing(KinematicPlant):
    def run_period(self, reference):
        if len(self.references) == 2 and sys.argv[3] == "run":  # period 3
            os.kill(os.getpid(), signal.SIGKILL)  # as an FMU that takes the process down
        return super().run_period(reference)

    def close(self):  # as an FMU whose termination takes the process down
        os.kill(os.getpid(), signal.SIGKILL)


scenario = load_scenario(sys.argv[1])
if sys.argv[3] == "close":
    from orchestrator.scenario import scenario_from_dict
    scenario = scenario_from_dict({**scenario.to_dict(), "periods": 3})
run_campaign(scenario, plant=Crashing(scenario.geometry()), log_path=sys.argv[2])
"""


@pytest.mark.parametrize(("crash", "periods"), [("run", [1, 2]), ("close", [1, 2, 3])])
def test_a_plant_that_kills_the_run_finds_every_finished_period_on_file(tmp_path, crash,
                                                                        periods):
    """The campaign's log compresses and writes on a thread of its own, and the campaign waits
    for it before the plant runs again or is closed: a crash in the plant, in period 3 or
    when it is closed after the last period, loses no finished period, however slow the
    disk."""
    import signal
    import subprocess
    import sys

    log = tmp_path / "crashed.mcap"
    done = subprocess.run([sys.executable, "-c", _CRASHING_CAMPAIGN, str(PAPER), str(log), crash],
                          cwd=PAPER.parents[1], timeout=120, check=False)
    assert done.returncode == -signal.SIGKILL
    run = read_run(log)
    assert [record["k"] for record in run.periods] == periods
    assert not run.finished
