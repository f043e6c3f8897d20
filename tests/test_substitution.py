"""Plant-model substitution: another FMU in a role digs like the default when it is the same
model, and a mistake in a substitution is one line before anything runs."""

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import fmus
from orchestrator.campaign import run_campaign
from orchestrator.review.summary import differing_roles, summary
from orchestrator.runlog import read_run
from orchestrator.scenario import ScenarioError, load_scenario

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "scenarios" / "paper-2020.toml"


@pytest.fixture(scope="module")
def copies(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("substitutes")
    shutil.copy(fmus.build("HydraulicCylinder"), folder / "MyCylinder.fmu")
    shutil.copy(fmus.build("Pile"), folder / "MyPile.fmu")
    return folder


def test_a_byte_identical_copy_substitutes_with_bit_identical_masses(copies, tmp_path):
    overrides = ["periods=2", f"plant.boom.fmu={copies / 'MyCylinder.fmu'}",
                 f"plant.pile.fmu={copies / 'MyPile.fmu'}"]
    default = load_scenario(PAPER, ["periods=2"])
    swapped = load_scenario(PAPER, overrides)
    # Swapping only `fmu` keeps the role's parameters (the preset's and the file's).
    assert swapped.plant.boom.parameters == default.plant.boom.parameters
    assert swapped.plant.pile.parameters == default.plant.pile.parameters
    logs = [tmp_path / "default.mcap", tmp_path / "swapped.mcap"]
    results = [run_campaign(s, log_path=log) for s, log in zip((default, swapped), logs,
                                                                strict=True)]
    masses = [[r["mass_kg"] for r in result.records] for result in results]
    assert masses[0] == masses[1] and len(masses[0]) == 2
    # The logs say which model filled each role, and compare says what differs.
    reviews = [summary(read_run(log)) for log in logs]
    assert reviews[1]["roles"]["boom"]["fmu"] == str(copies / "MyCylinder.fmu")
    assert reviews[1]["roles"]["boom"]["sha256"] == reviews[0]["roles"]["boom"]["sha256"]
    assert reviews[1]["roles"]["boom"]["parameters"] == default.plant.boom.parameters
    assert reviews[1]["overrides"] == overrides and reviews[0]["overrides"] == ["periods=2"]
    assert differing_roles(reviews) == {"boom": ["FMU name (same content)"],
                                        "pile": ["FMU name (same content)"]}


def test_compare_names_the_roles_that_differ(tmp_path):
    logs = []
    for name, items in (("base", []), ("dense", ["plant.pile.parameters.density=2000"])):
        logs.append(tmp_path / f"{name}.mcap")
        run_campaign(load_scenario(PAPER, ["periods=1", *items]), log_path=logs[-1])
    done = subprocess.run([sys.executable, "-m", "orchestrator.cli.app", "compare",
                           *map(str, logs), "--json"], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout)["differing_roles"] == {"pile": ["density"]}
    text = subprocess.run([sys.executable, "-m", "orchestrator.cli.app", "compare",
                           *map(str, logs)], capture_output=True, text=True, timeout=120)
    assert "plant roles that differ: pile: density" in text.stdout
    review = subprocess.run([sys.executable, "-m", "orchestrator.cli.app", "review",
                             str(logs[1])], capture_output=True, text=True, timeout=120)
    assert "pile: Pile (sha256 " in review.stdout
    assert "--set periods=1 --set plant.pile.parameters.density=2000" in review.stdout


def test_a_misspelt_parameter_of_a_substitute_names_the_fmu_and_the_closest(copies):
    with pytest.raises(ScenarioError) as error:
        load_scenario(PAPER, [f"plant.stick.fmu={copies / 'MyCylinder.fmu'}",
                              "plant.stick.parameters.V_dead_b=2e-4"])
    message = str(error.value)
    assert message.startswith("paper-2020.toml: plant.stick.parameters.V_dead_b: "
                              "HydraulicCylinder has no parameter 'V_dead_b' (closest: ")
    assert "V_dead_B" in message and "\n" not in message


def test_the_cli_refuses_it_in_one_line_with_exit_2_before_any_log(copies, tmp_path):
    log = tmp_path / "never.mcap"
    done = subprocess.run(
        [sys.executable, "-m", "orchestrator.cli.app", "run", str(PAPER), "-o", str(log),
         "--set", f"plant.boom.fmu={copies / 'MyCylinder.fmu'}",
         "--set", "plant.boom.parameters.bor=0.2"],
        capture_output=True, text=True, timeout=120)
    assert done.returncode == 2 and done.stderr.count("\n") == 1, done.stderr
    assert "has no parameter 'bor' (closest: bore" in done.stderr
    assert not log.exists()


@pytest.mark.parametrize("name", ["paper-2020-ideal-actuators", "paper-2020-zelenin"])
def test_the_shipped_substitutes_complete_the_paper_campaign(name):
    scenario = load_scenario(ROOT / "scenarios" / f"{name}.toml")
    result = run_campaign(scenario)
    assert result.termination == "periods", result.message
    masses = [r["mass_kg"] for r in result.records]
    capacity_kg = 1600.0 * scenario.fmu_specs()["pile"].parameters["capacity"]
    assert len(masses) == 20 and all(0.0 <= m < capacity_kg for m in masses), masses
    # The adaptation still brings the dug mass near m* after the first corrections.
    assert sum(abs(r["error_kg"]) <= 5.0 for r in result.records[1:]) >= 12
