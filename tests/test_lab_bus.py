"""One lab period on the bus, read back by an independent listener (cantools from the DBC, a
bitwise CRC): the stream is the reference, the handshake and the period's commands come in the
documented order, the measurement is what the device sent, and the bus statistics count what
the bus carried.

The period is a short bucket wiggle at the emulated device's start pose (2 s of machine time at
a time scale of 2), so the test is about the protocol, not digging."""

import math
from pathlib import Path

import numpy as np
import pytest
from lab_bus import Capture, still_reference

from orchestrator.plants.lab.factory import first_pose_rad, open_lab_plant
from orchestrator.plants.lab.protocol import Cmd, State
from orchestrator.scenario import load_scenario

LAB = Path(__file__).resolve().parent.parent / "scenarios" / "lab.toml"


@pytest.fixture(scope="module")
def period():
    # Timeouts of 8 and 12 frames and a 1 s heartbeat consumer time: at a time scale of 2 the
    # defaults would be 25 ms of wall time, tighter than a loaded test machine (the timeouts
    # themselves are test_lab_faults.py's).
    scenario = load_scenario(LAB, ["plant.kind=lab", "plant.lab.emulate=true",
                                   "plant.lab.interface=virtual", "plant.lab.time_scale=1",
                                   "plant.lab.command_timeout_s=0.08",
                                   "plant.lab.feedback_timeout_s=0.12",
                                   "plant.lab.heartbeat_timeout_s=1.0"])
    plant = open_lab_plant(scenario)
    capture = Capture(plant.settings.channel)
    reference = still_reference(first_pose_rad(scenario), 2.0, plant.communication_step_s,
                                wiggle_deg=10.0)
    try:
        measurement = plant.run_period(reference)
        summary = plant.bus_summary()
    finally:
        plant.close()
    return reference, measurement, capture.frames(), summary


def _master_frames(frames):
    return [f for f in frames if f.name in ("Command", "RefAcceleration", "RefVelocity",
                                            "RefPosition", "AllStop")]


def test_every_frame_on_the_bus_has_a_valid_checksum(period):
    _, _, frames, _ = period
    assert frames and all(f.checksum_ok for f in frames)


def test_the_stream_is_the_reference_in_cycles_of_acceleration_velocity_position(period):
    reference, _, frames, _ = period
    stream = [f for f in frames if f.name.startswith("Ref")]
    n = len(reference.t_s)
    assert [f.name for f in stream] == ["RefAcceleration", "RefVelocity", "RefPosition"] * n
    for offset, values, scale in ((2, reference.position_rad, 1.0),
                                  (1, reference.velocity_rad_s, 1.0),
                                  (0, reference.acceleration_rad_s2, 1.0)):
        got = np.array([[f.signals[j] for j in ("Boom", "Stick", "Bucket")]
                        for f in stream[offset::3]])
        np.testing.assert_allclose(got, np.degrees(values) * scale, atol=0.005 + 1e-9)
    assert [f.signals["Counter"] for f in stream[2::3]] == [i % 16 for i in range(n)]


def test_the_handshake_and_the_period_commands_come_in_order(period):
    reference, measurement, frames, _ = period
    commands = [f for f in frames if f.name == "Command"]
    assert [int(c.signals["Cmd"]) for c in commands] == [
        Cmd.ARM, Cmd.PERIOD_START, Cmd.PERIOD_END, Cmd.DUMP, Cmd.DISARM]
    arm = commands[0]
    before = [f for f in frames if f.name == "DeviceStatus" and f.t <= arm.t]
    assert arm.signals["Argument"] == before[-1].signals["Challenge"]  # the challenge echoed
    start = commands[1]
    assert start.signals["Argument"] == len(reference.t_s) and start.signals["Period"] == 1
    statuses = [int(f.signals["State"]) for f in frames if f.name == "DeviceStatus"]
    for state in (State.ARMED, State.STREAMING, State.WEIGHING, State.DUMPING, State.DISARMED):
        assert state in statuses
    refs = [f.t for f in frames if f.name == "RefPosition"]
    assert start.t < refs[0] and refs[-1] < commands[2].t < commands[3].t


def test_the_measurement_is_the_feedback_the_device_sent(period):
    reference, measurement, frames, _ = period
    feedback = [f for f in frames if f.name == "FbPosition" and f.signals["Streaming"]]
    assert len(feedback) == len(reference.t_s) == len(measurement.t_s)  # nothing lost
    sent = np.radians([[f.signals[j] for j in ("Boom", "Stick", "Bucket")] for f in feedback])
    np.testing.assert_allclose(measurement.joints_rad, sent, atol=1e-12)
    np.testing.assert_allclose(measurement.t_s, reference.t_s)
    pressures = [f for f in frames if f.name == "FbPressureA"][-len(feedback):]
    assert measurement.signals["boom.p_A"][-1] == pytest.approx(
        pressures[-1].signals["Boom"] * 1e5, abs=1e-6)
    # The device tracked the 10 deg wiggle (the measured bucket follows the reference).
    error = np.abs(measurement.joints_rad[:, 2] - reference.position_rad[:, 2])
    assert error.max() < math.radians(1.0)


def test_the_weighing_is_the_load_cell_frame_of_the_period(period):
    _, measurement, frames, _ = period
    weighings = [f for f in frames if f.name == "LoadCell" and f.signals["Period"] == 1]
    assert weighings and all(f.signals["Valid"] for f in weighings)
    assert measurement.weighed_mass_kg == pytest.approx(weighings[0].signals["Mass"], abs=1e-9)


def test_the_bus_statistics_count_what_the_bus_carried(period):
    reference, measurement, frames, summary = period
    master = _master_frames(frames)
    start = next(i for i, f in enumerate(master) if f.name == "Command"
                 and f.signals["Cmd"] == Cmd.PERIOD_START)
    refs = [i for i, f in enumerate(master) if f.name == "RefPosition"]
    expected = np.array([i - start + 1 for i in refs])  # PERIOD_START .. cycle i's position
    np.testing.assert_array_equal(measurement.signals["bus.frames_sent"], expected)
    assert not measurement.signals["bus.feedback_lost"].any()
    assert not measurement.signals["bus.setpoints_lost"].any()
    assert (measurement.signals["bus.send_jitter_s"] >= 0.0).all()
    assert summary["cycles"] == len(reference.t_s)
    # Never faster than the stream rate (100 Hz): a late master slips, it does not burst. How
    # close to 100 Hz it stays is a real-time figure (a loaded test machine slows it): the
    # bench measures it (bench/lab_bus.py).
    assert 0.0 < summary["rate_hz_machine"] <= 100.0 * 1.01
