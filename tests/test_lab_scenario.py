"""The [plant.lab] table: plant.kind = "lab" selects it, its defaults are resolved into the
scenario, and every mistake is one line naming the field (as the other sections)."""

import math
from pathlib import Path

import pytest

from orchestrator.cli.lab import run_overrides
from orchestrator.plants.lab.settings import LabSettings
from orchestrator.scenario import ScenarioError, load_scenario, scenario_from_dict

LAB = Path(__file__).resolve().parent.parent / "scenarios" / "lab.toml"


def _write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "s.toml"
    path.write_text(f'name = "s"\n[machine]\npreset = "lab"\n{text}\n', encoding="utf-8")
    return path


def test_the_lab_plant_takes_the_documented_defaults(tmp_path):
    scenario = load_scenario(_write(tmp_path, '[plant]\nkind = "lab"'))
    settings = scenario.plant.lab.settings()
    assert settings == LabSettings(start_tolerance_rad=math.radians(2.0))
    assert settings.command_timeout_s == 0.05 and settings.feedback_timeout_s == 0.1
    resolved = scenario.to_dict()["plant"]["lab"]  # what the run log keeps
    assert resolved["stream_rate_hz"] == 100.0 and resolved["heartbeat_timeout_s"] == 0.3
    assert resolved["emulate"] is False and resolved["time_scale"] == 1.0


def test_a_simulated_scenario_has_no_lab_table(tmp_path):
    assert "lab" not in load_scenario(_write(tmp_path, "")).to_dict()["plant"]


def test_the_lab_scenario_names_the_real_machines_link():
    scenario = load_scenario(LAB, ["plant.kind=lab"])
    settings = scenario.plant.lab.settings()
    assert (settings.interface, settings.channel, settings.time_scale) == ("socketcan", "can0", 1.0)
    assert scenario_from_dict(scenario.to_dict()) == scenario  # what a run log keeps reloads


def test_run_dash_dash_plant_and_emulate_are_set_items():
    items, problem = run_overrides("lab", True)
    assert problem is None
    scenario = load_scenario(LAB, items)
    assert scenario.plant.kind == "lab" and scenario.plant.lab.emulate
    assert scenario.plant.lab.interface == "virtual"
    assert run_overrides("sim", True)[1] is not None
    assert run_overrides("real", False)[1].startswith("--plant: unknown plant 'real'")
    assert run_overrides(None, False) == ([], None)


MISTAKES = [
    ("[plant.lab]\ninterface = \"usb9\"",
     "plant.lab.interface: unknown python-can interface 'usb9'; known: "),
    ("[plant.lab]\nstream_rate_hz = -5", "plant.lab.stream_rate_hz: must be greater than 0"),
    ("[plant.lab]\ncommand_timeout_s = 0.5",
     "plant.lab: command_timeout_s = 0.5 s is 50 frame periods at 100 Hz; it must be 2 to 12"),
    ("[plant.lab]\ncommand_timeout_s = 0.1",
     "plant.lab: command_timeout_s must be below feedback_timeout_s"),
    ("[plant.lab]\nfeedback_timeout_s = 0.01",
     "plant.lab: feedback_timeout_s = 0.01 s is 1 frame periods at 100 Hz; it must be 2 to 12"),
    ("[plant.lab]\nheartbeat_timeout_s = 0.1",
     "plant.lab: heartbeat_timeout_s must exceed heartbeat_period_s"),
    ("[plant.lab]\nemulate = true\ninterface = \"socketcan\"",
     "plant.lab: emulate = true runs the device in this process: it needs interface = "),
    ("[plant.lab]\nbitrate = \"fast\"", "plant.lab.bitrate: expected an integer, got 'fast'"),
    ("[plant.lab]\ntime_scale = 0", "plant.lab.time_scale: must be greater than 0"),
    ("[plant.lab]\nchanel = \"vcan0\"", "plant.lab.chanel: unknown key (known: interface, "),
    ("[plant.lab.faults]\ndrop_fraction = 1.5",
     "plant.lab.faults.drop_fraction: must be less than 1"),
    ("[plant.lab.faults]\nestop_at = 3", "plant.lab.faults.estop_at: unknown key"),
]


@pytest.mark.parametrize(("text", "expected"), MISTAKES, ids=[m[1].split(":")[0] + str(i)
                                                               for i, m in enumerate(MISTAKES)])
def test_a_lab_mistake_is_one_line_naming_the_field(tmp_path, text, expected):
    path = _write(tmp_path, f'[plant]\nkind = "lab"\n{text}')
    with pytest.raises(ScenarioError) as caught:
        load_scenario(path)
    message = str(caught.value)
    assert "\n" not in message
    assert message.startswith(f"s.toml: {expected}"), message
