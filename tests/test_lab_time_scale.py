"""The lab link's timeouts scale with the time scale, and a timeout does not hide the device's own
stop reason (orchestrator.plants.lab.settings.LabSettings.timeout, driver.LabExcavator._abort).

At `plant.lab.time_scale = 20` the timeouts, kept in machine time, used to shrink to 1/20 of
their wall time (the device's command timeout to 2.5 ms): on a loaded machine a run without any
fault then failed (COMMAND_TIMEOUT, a lost heartbeat, late feedback). The load here stalls the
process's threads for about 7 ms every 20 ms (Load): with the timeouts as set (not scaled) the run
fails under it at once, with them scaled it digs its periods."""

import threading
from pathlib import Path

import can
import pytest
from lab_bus import still_reference

from orchestrator.campaign import run_campaign
from orchestrator.plants.lab.driver import LabStop
from orchestrator.plants.lab.factory import first_pose_rad, open_lab_plant
from orchestrator.plants.lab.protocol import State, encode
from orchestrator.plants.lab.settings import LabSettings
from orchestrator.scenario import load_scenario

LAB = Path(__file__).resolve().parent.parent / "scenarios" / "lab.toml"
FAST = ["periods=2", "plant.kind=lab", "plant.lab.emulate=true", "plant.lab.interface=virtual",
        "plant.lab.time_scale=20"]
TIMEOUTS = ("command_timeout_s", "feedback_timeout_s", "heartbeat_timeout_s", "reply_timeout_s",
            "load_cell_timeout_s", "connect_timeout_s")


def test_the_timeouts_keep_their_wall_time_above_real_time():
    fast, real, slow = (LabSettings(time_scale=scale) for scale in (20.0, 1.0, 0.5))
    for name in TIMEOUTS:
        assert fast.timeout(name) == 20.0 * getattr(fast, name)
        assert fast.wall(fast.timeout(name)) == pytest.approx(getattr(real, name))
        assert real.timeout(name) == getattr(real, name) == slow.timeout(name)
    assert fast.frame_period_s == real.frame_period_s  # rates keep their machine values
    with pytest.raises(ValueError, match="not a timeout"):
        fast.timeout("heartbeat_period_s")


class Load:
    """A thread that holds the interpreter lock for about 7 ms every 20 ms (a sum over a range
    runs in C without letting go of it): the stalls a loaded machine gives a process, as a
    collection or another busy thread would."""

    def __init__(self) -> None:
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._spin, daemon=True)

    def _spin(self) -> None:
        while not self._stop.wait(0.02):
            sum(range(400_000))

    def __enter__(self):
        self._thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self._stop.set()
        self._thread.join()


def _run(log_path: Path, extra=()):
    scenario = load_scenario(LAB, [*FAST, *extra])
    with Load():
        return run_campaign(scenario, plant=open_lab_plant(scenario), log_path=log_path)


def test_a_fast_emulated_run_digs_on_a_loaded_machine(tmp_path, monkeypatch):
    result = _run(tmp_path / "scaled.mcap")
    assert result.termination == "periods", result.message
    # The same run with the timeouts as set, not scaled: it fails on the way.
    monkeypatch.setattr(LabSettings, "timeout", lambda self, name: getattr(self, name))
    unscaled = _run(tmp_path / "unscaled.mcap")
    assert unscaled.termination == "error", unscaled.message
    assert any(word in unscaled.message for word in (
        "COMMAND_TIMEOUT", "heartbeat lost", "feedback", "within", "LEASE_LOST")), \
        unscaled.message


def test_a_fast_run_reports_the_emergency_stop(tmp_path):
    result = _run(tmp_path / "estop.mcap", ["plant.lab.faults.estop_at_s=8.0"])
    assert result.termination == "error"
    assert "emergency stop at the device (EMERGENCY_STOP, state ESTOP)" in result.message


def test_a_timeout_of_the_master_does_not_hide_the_devices_own_stop():
    """The device stops (here an AllStop frame from elsewhere on the bus) and the master, before
    it has read the device's status, stops for a timeout: the reason is the device's."""
    scenario = load_scenario(LAB, ["plant.kind=lab", "plant.lab.emulate=true",
                                   "plant.lab.interface=virtual", "plant.lab.time_scale=1",
                                   "plant.lab.stream_rate_hz=20",
                                   "plant.lab.command_timeout_s=0.45",
                                   "plant.lab.feedback_timeout_s=0.55",
                                   "plant.lab.heartbeat_timeout_s=1.0"])
    plant = open_lab_plant(scenario)
    try:
        plant.run_period(still_reference(first_pose_rad(scenario), 0.5, 0.05))
        device = plant.emulator.device
        # A timeout with the device well (it holds because the master says so) stays the reason.
        with pytest.raises(LabStop) as stopped:
            plant._abort("no acknowledgement of DUMP within 0.5 s")
        assert stopped.value.reason == "no acknowledgement of DUMP within 0.5 s"
        assert device.state == State.HOLD
        with can.Bus(interface="virtual", channel=plant.settings.channel) as other:
            other.send(encode("AllStop", Stop=1, Counter=0))
        with pytest.raises(LabStop) as stopped:
            plant._abort("joint feedback 0.600 s old (timeout 0.55 s): a test's")
        assert device.state == State.ESTOP
        assert stopped.value.reason == (
            "emergency stop at the device (ALL_STOP, state ESTOP); the master had stopped for: "
            "joint feedback 0.600 s old (timeout 0.55 s): a test's")
    finally:
        plant.close()
