"""scenarios/excavator-20t.toml: the paper's machine digging a full-width pile with a Cat 320's
1.19 m^3 bucket to 1,600 kg a period. Its set-up is consistent (the mass slice is the bucket's
width, the capacity the bucket's rated heaped one), its calibrated adaptation lands near the
target once the trench is open, the payload's weight and inertia reach the arm (the arm's
equation of motion, evaluated from the log by orchestrator.review.arm_equation with the Pile's
logged payload, holds; without the payload it does not), and the servos hold the full bucket."""

from pathlib import Path

import numpy as np
import pytest

from orchestrator.campaign import run_campaign
from orchestrator.review.arm_equation import (
    LOGGED_TOPICS,
    arm_residual,
    cylinder_parameters,
    logged_periods,
)
from orchestrator.runlog import read_run
from orchestrator.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[1]
FULL_SCALE = ROOT / "scenarios" / "excavator-20t.toml"
RATED_M3 = 1.19  # Cat 320 HD bucket, 1,200 mm: heaped capacity (ISO 7451)


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    scenario = load_scenario(FULL_SCALE, ["periods=4"])
    log = tmp_path_factory.mktemp("full") / "run.mcap"
    result = run_campaign(scenario, log_path=log)
    assert result.termination == "periods", result.message
    return scenario, result, read_run(log, topics=LOGGED_TOPICS)


def test_the_scenario_is_the_consistent_full_scale_case():
    scenario = load_scenario(FULL_SCALE)
    pile = scenario.plant.pile.parameters
    assert pile["slice_width"] == pile["bucket_width"] == 1.2
    assert pile["capacity"] == RATED_M3
    rated = pile["capacity"] * pile["density"]
    assert rated == pytest.approx(1904.0)
    assert 0.8 <= scenario.target_mass_kg / rated <= 1.0  # a fill factor of common earth


def test_once_the_trench_is_open_the_periods_land_near_the_target(campaign):
    scenario, result, _ = campaign
    masses = [r["mass_kg"] for r in result.records]
    rated = scenario.plant.pile.parameters["capacity"] * scenario.plant.pile.parameters["density"]
    # Periods 1 and 2 dig fresh ground at the default depth (753, 386 kg); then within
    # 3/30 of m* (the paper's +-3 kg at 30 kg).
    assert masses[0] < 0.6 * scenario.target_mass_kg
    for mass in masses[2:]:
        assert abs(mass - scenario.target_mass_kg) <= 0.1 * scenario.target_mass_kg, masses
        assert mass < rated  # the bucket never overflows its rating
    for record in result.records:
        assert record["fill_factor"] == pytest.approx(record["mass_kg"] / rated, rel=1e-12)


def test_the_payload_reaches_the_arm_and_its_equation_holds(campaign):
    scenario, result, logged = campaign
    periods = logged_periods(logged)
    full = [p for p in periods if np.max(p["pile.bucket_mass"]) > 1500.0]
    assert full, [np.max(p["pile.bucket_mass"]) for p in periods]
    parameters = cylinder_parameters(scenario)
    with_payload = arm_residual(scenario.geometry(), full, parameters)
    # As on the paper machine (tests/test_native_coupling.py): RMS below 1 %, peak below 5 % of
    # the RMS cylinder force per joint, here with up to 1.8 t in the bucket.
    assert np.all(with_payload.rms_ratio < 0.01), with_payload.rms_ratio
    assert np.all(with_payload.peak_ratio < 0.05), with_payload.peak_ratio
    # The same signals with the payload taken out of the arm's model: unbalanced.
    empty = [{**p, "pile.bucket_mass": np.zeros_like(p["pile.bucket_mass"])} for p in full]
    without = arm_residual(scenario.geometry(), empty, parameters)
    assert without.rms_ratio[0] > 5 * with_payload.rms_ratio[0]
    assert without.rms_ratio[0] > 0.02, without.rms_ratio


def test_the_servos_hold_the_full_bucket(campaign):
    """The servos schedule their gains on the inertia the arm reflects onto the rod
    (plant_models.servo.JointServo): with 1.7-1.8 t in the bucket the tracking stays within a
    few degrees, where the design's fixed gains let the bucket oscillate past the 15 deg bound
    (before the scheduling: period 3 ended on the tracking bound)."""
    _, result, _ = campaign
    for record in result.records:
        assert max(record["tracking_rms_deg"]) < 3.0, record["tracking_rms_deg"]
