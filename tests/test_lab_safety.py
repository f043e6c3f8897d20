"""The master refuses a period that breaks a limit before any frame of it leaves: checked on the
safety module's own terms and on the bus (a capture on the driver's virtual channel)."""

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from lab_bus import Capture, still_reference

from orchestrator.campaign.loop import sample_reference
from orchestrator.plants.lab.bus import private_virtual_channel
from orchestrator.plants.lab.driver import LabExcavator
from orchestrator.plants.lab.factory import first_pose_rad, open_lab_plant
from orchestrator.plants.lab.protocol import Cmd
from orchestrator.plants.lab.safety import ReferenceRefused, check_stream, on_stream_grid
from orchestrator.plants.lab.settings import LabSettings
from orchestrator.scenario import load_scenario

LAB = Path(__file__).resolve().parent.parent / "scenarios" / "lab.toml"
STEP_S = 0.01


@pytest.fixture(scope="module")
def scenario():
    return load_scenario(LAB, ["plant.kind=lab"])


@pytest.fixture(scope="module")
def planned(scenario):
    """The lab campaign's first-period reference on the stream grid (the planner's spline)."""
    a = scenario.adaptation
    return sample_reference(scenario.period_planner().plan(a.y_D0_m, a.z_D0_m), STEP_S)


def _check(scenario, reference):
    check_stream(on_stream_grid(reference, STEP_S), scenario.geometry().joint_limits_rad,
                 scenario.limits_rad())


def test_the_planned_period_passes(scenario, planned):
    _check(scenario, planned)


def test_a_setpoint_beyond_a_joint_limit_is_refused_naming_joint_time_and_range(
        scenario, planned):
    low, high = scenario.geometry().joint_limits_rad[0]
    position = planned.position_rad.copy()
    position[400, 0] = high + math.radians(0.5)
    with pytest.raises(ReferenceRefused) as caught:
        _check(scenario, replace(planned, position_rad=position))
    message = str(caught.value)
    assert message.startswith("period refused before any frame was sent: boom setpoint")
    assert "t = 4.000 s" in message and f"{math.degrees(high):.3f}]" in message


def test_a_reference_faster_than_the_scenario_limits_is_refused(scenario, planned):
    # The same path in half the time: twice the velocity, four times the acceleration.
    fast = replace(planned, t_s=planned.t_s / 2, velocity_rad_s=planned.velocity_rad_s * 2,
                   acceleration_rad_s2=planned.acceleration_rad_s2 * 4)
    peak_acc = np.abs(fast.acceleration_rad_s2).max()
    assert peak_acc > scenario.limits_rad()[1].min()
    with pytest.raises(ReferenceRefused, match="acceleration limit"):
        _check(scenario, fast)


def test_feed_forward_that_hides_a_step_is_refused_by_the_finite_differences(
        scenario, planned):
    position = planned.position_rad.copy()
    position[600:, 1] += math.radians(3.0)  # a 3 deg jump of the stick, velocities unchanged
    with pytest.raises(ReferenceRefused, match="stick setpoint step / T"):
        _check(scenario, replace(planned, position_rad=position))


def test_a_refused_first_period_sends_nothing_at_all(scenario, planned):
    channel = private_virtual_channel()
    capture = Capture(channel)
    settings = LabSettings(channel=channel)
    low, high = scenario.geometry().joint_limits_rad[2]
    position = planned.position_rad.copy()
    position[-1, 2] = low - math.radians(1.0)
    plant = LabExcavator(settings, scenario.geometry().joint_limits_rad, scenario.limits_rad())
    try:
        with pytest.raises(ReferenceRefused, match="bucket setpoint"):
            plant.run_period(replace(planned, position_rad=position))
    finally:
        plant.close()
    assert capture.frames() == []  # not even a heartbeat: the link opens after the check


def test_a_reference_away_from_the_arm_is_refused_before_period_start():
    """The emulated device reports its pose; a reference 5 deg off is refused after the arm
    handshake but before PERIOD_START or any setpoint."""
    scenario = load_scenario(LAB, ["plant.kind=lab", "plant.lab.emulate=true",
                                   "plant.lab.interface=virtual"])
    plant = open_lab_plant(scenario)
    capture = Capture(plant.settings.channel)
    pose = first_pose_rad(scenario)
    try:
        with pytest.raises(ReferenceRefused, match="from the arm's boom angle"):
            plant.run_period(still_reference(pose + np.radians([5.0, 0, 0]), 1.0, STEP_S))
    finally:
        plant.close()
    frames = capture.frames()
    commands = [f.signals["Cmd"] for f in frames if f.name == "Command"]
    assert Cmd.ARM in commands and Cmd.PERIOD_START not in commands
    assert not [f for f in frames if f.name == "RefPosition"]
