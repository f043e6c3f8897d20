"""A run whose arm does not follow its path ends with that reason instead of reporting numbers:
`plant.max_tracking_error_deg` bounds each period's largest |measured - reference| joint angle.

The arm is made unable to follow with a bucket valve of a tenth of its rated flow: the scenario
loads (the servo is designed for it, the FMU initialises), and the bucket lags its reference by
about 60 deg in period 1. (A slow stick is no longer the joint named: through the arm's cross
inertia, now coupled per step, its lag shakes the bucket past the bound first.)
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from orchestrator.campaign import run_campaign
from orchestrator.campaign.loop import TrackingError, check_tracking
from orchestrator.cli.app import app
from orchestrator.runlog import read_run
from orchestrator.scenario import ScenarioError, load_scenario
from plant_models.plant import PeriodMeasurement

ROOT = Path(__file__).resolve().parent.parent
PAPER = ROOT / "scenarios" / "paper-2020.toml"
SLOW_BUCKET = "plant.bucket.parameters.q_rated=3.6667e-4"  # m^3/s, a tenth of the paper's


def test_an_arm_that_cannot_follow_ends_the_run_naming_the_joint(tmp_path):
    log = tmp_path / "slow.mcap"
    result = run_campaign(load_scenario(PAPER, ["periods=2", SLOW_BUCKET]), log_path=log)
    assert result.termination == "error"
    assert result.message.startswith("period 1: TrackingError: the bucket joint's tracking "
                                     "error reached ")
    assert result.message.endswith("beyond the bound of 15 deg (plant.max_tracking_error_deg)")
    assert isinstance(result.error, TrackingError)
    reached = float(result.message.split("reached ")[1].split(" deg")[0])
    assert 20.0 < reached < 90.0
    assert result.records == []  # the period's numbers are not reported
    run = read_run(log)
    assert run.finished and run.termination == "error" and run.periods == []
    assert run.message_counts["/joints"] > 1000  # its samples are kept, to see what happened
    review = CliRunner().invoke(app, ["review", str(log)])
    assert review.exit_code == 0 and "failed after 0 periods: period 1: TrackingError" in \
        review.stdout


def test_the_bound_is_the_scenarios_and_the_command_line_fails_in_one_line(tmp_path):
    wide = load_scenario(PAPER, ["periods=1", SLOW_BUCKET, "plant.max_tracking_error_deg=90"])
    assert run_campaign(wide).termination == "periods"
    result = CliRunner().invoke(app, ["run", str(PAPER), "-o", str(tmp_path / "run.mcap"),
                                      "--periods", "1", "--set", SLOW_BUCKET, "--set",
                                      "plant.max_tracking_error_deg=20"])
    assert result.exit_code == 1
    assert result.stderr.startswith("excosim: run failed: period 1: TrackingError: the "
                                    "bucket joint's tracking error reached ")
    assert "beyond the bound of 20 deg" in result.stderr and len(result.stderr.splitlines()) == 1


@pytest.mark.parametrize("value", [0, -1, "wide"])
def test_a_bound_that_is_no_bound_is_refused_at_load(value):
    with pytest.raises(ScenarioError) as refused:
        load_scenario(PAPER, [f"plant.max_tracking_error_deg={value!r}"
                              if isinstance(value, str) else
                              f"plant.max_tracking_error_deg={value}"])
    assert refused.value.field == "plant.max_tracking_error_deg"


def test_the_presets_defaults_and_the_check_itself():
    assert load_scenario(PAPER).plant.max_tracking_error_deg == 15.0
    assert load_scenario(ROOT / "scenarios" / "lab.toml").plant.max_tracking_error_deg == 90.0
    t = np.arange(5) * 0.1
    reference = np.zeros((5, 3))
    joints = reference.copy()
    joints[3, 2] = np.radians(12.0)  # the bucket 12 deg off at t = 0.3 s
    measurement = PeriodMeasurement(t_s=t, joints_rad=joints, reference_rad=reference,
                                    weighed_mass_kg=1.0, signals={})
    check_tracking(measurement, 12.5)
    with pytest.raises(TrackingError, match=r"the bucket joint's tracking error reached 12 deg "
                       r"at t = 0.30 s, beyond the bound of 10 deg") as error:
        check_tracking(measurement, 10.0)
    assert error.value.partial is measurement
