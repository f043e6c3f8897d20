"""`excosim emulate` on its own is the device side of the protocol: a master in the same process
digs a short period with it over a virtual channel; its mistakes are one line with exit 2, a bus
that cannot be opened exit 1 (this machine has no vcan0)."""

import threading

import numpy as np
from lab_bus import still_reference
from typer.testing import CliRunner

from orchestrator.cli import lab
from orchestrator.cli.app import app
from orchestrator.plants.lab.bus import private_virtual_channel
from orchestrator.plants.lab.driver import LabExcavator
from orchestrator.plants.lab.factory import first_pose_rad
from orchestrator.plants.lab.settings import LabSettings
from orchestrator.scenario.model import scenario_from_dict


def test_a_master_digs_with_the_standalone_emulator(capsys):
    channel = private_virtual_channel()
    answers: list = []
    # Loaded first: a scenario load probes the FMUs and designs the servos (seconds of Python,
    # the GIL held), which must not run beside the real-time stream below.
    scenario = scenario_from_dict({"name": "lab-preset", "machine": {"preset": "lab"}})
    device = threading.Thread(target=lambda: answers.append(lab.emulate(
        "virtual", channel, 500_000, None, 2.0, 10.0, [], [])))
    device.start()
    # The device needs a few seconds to start (its FMUs and servo design): a long connect time.
    # Device and master share this process (and the suite's heap): timeouts near the most the
    # protocol allows (12 frames for the feedback, the command's below it), so that a stall of
    # the process is less likely to end the period (once, in a fresh clone's suite, a command
    # timeout of 80 ms did); the timeouts themselves are tested in tests/test_lab_faults.py.
    settings = LabSettings(channel=channel, time_scale=1.0, command_timeout_s=0.11,
                           feedback_timeout_s=0.12, heartbeat_timeout_s=1.0,
                           connect_timeout_s=16.0)
    plant = LabExcavator(settings, scenario.geometry().joint_limits_rad, scenario.limits_rad())
    try:
        reference = still_reference(first_pose_rad(scenario), 2.0, settings.frame_period_s,
                                    wiggle_deg=5.0)
        measurement = plant.run_period(reference)
    finally:
        plant.close()
        device.join()
    assert answers == [None]
    assert len(measurement.t_s) == len(reference.t_s)
    assert np.abs(measurement.joints_rad - reference.position_rad).max() < np.radians(1.0)
    printed = capsys.readouterr().out.splitlines()
    assert printed[0].startswith("emulating the lab excavator of scenario 'lab-preset' on "
                                 f"virtual channel '{channel}'")
    assert printed[-1].startswith("device DISARMED (fault NONE)") and "periods 1" in printed[-1]


def test_an_unknown_fault_is_one_line_with_exit_2():
    done = CliRunner().invoke(app, ["emulate", "--interface", "virtual", "--fault", "smoke=1"])
    assert done.exit_code == 2
    assert done.output.strip().startswith("excosim: --fault 'smoke=1': unknown fault 'smoke'")


def test_a_bus_that_cannot_open_exits_1():
    done = CliRunner().invoke(app, ["emulate", "--interface", "socketcan", "--channel",
                                    "nonexistent0", "--duration", "1"])
    assert done.exit_code == 1
    assert "cannot open CAN interface 'socketcan' channel 'nonexistent0'" in done.output
    assert "Traceback" not in done.output
