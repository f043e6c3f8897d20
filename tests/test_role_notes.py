"""What a substitute cylinder FMU does not take of the plant is said, per role, in `scenario
show`, the run log's excosim.roles and `review` (orchestrator.plants.role_notes): the arm's
inertia (an FMU without mass_load) and the shared pump (an FMU without p_pump / p_LS)."""

import json
import subprocess
import sys
from pathlib import Path

import pytest
from cylinder_variants import own_supply_cylinder

from orchestrator.campaign import run_campaign
from orchestrator.plants.role_notes import cylinder_notes, reflected_range_kg
from orchestrator.runlog import read_run
from orchestrator.scenario import load_scenario
from plant_models.arm_inertia import mass_matrix
from plant_models.joint_strokes import moment_arm_m

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "scenarios" / "paper-2020.toml"
IDEAL = ROOT / "scenarios" / "paper-2020-ideal-actuators.toml"


@pytest.fixture(scope="module")
def own_supply(tmp_path_factory):
    return own_supply_cylinder(tmp_path_factory.mktemp("own"))


def test_ours_are_fed_and_on_the_pump():
    notes = cylinder_notes(load_scenario(PAPER))
    for role in ("boom", "stick", "bucket"):
        assert notes[role]["arm_inertia"].startswith("fed as mass_load")
        assert notes[role]["supply"] == "the shared load-sensing pump"


def test_the_reflected_range_is_the_arms_mass_matrix_over_the_moment_arm():
    """Against the arm's mass matrix (plant_models.arm_inertia) at the range's end poses."""
    scenario = load_scenario(PAPER)
    ranges = reflected_range_kg(scenario)
    from orchestrator.plants.simulated_excavator import shared_coupling

    geometry = scenario.geometry()
    coupling = shared_coupling(geometry)
    design = [0.5 * t.stroke_m for t in coupling.tables]
    for index, role in enumerate(("boom", "stick", "bucket")):
        values = []
        for fraction in (0.05, 0.95):
            strokes = list(design)
            strokes[index] = fraction * coupling.tables[index].stroke_m
            joints = [coupling.joint_state(i, s)[0] for i, s in enumerate(strokes)]
            arm = moment_arm_m(geometry, role, joints[index])
            values.append(mass_matrix(geometry, joints)[index, index] / arm**2)
        assert ranges[role] == pytest.approx((min(values), max(values)), rel=1e-9)
    assert 1_000.0 < ranges["bucket"][0] < ranges["bucket"][1]


def test_an_fmu_without_mass_load_or_pump_ports_is_named_in_show_log_and_review(own_supply,
                                                                                 tmp_path):
    ideal = cylinder_notes(load_scenario(IDEAL))
    assert ideal["bucket"]["arm_inertia"].startswith("not fed: the FMU has no mass_load input")
    scenario = load_scenario(PAPER, ["periods=1", f'plant.stick.fmu="{own_supply}"',
                                     "plant.stick.parameters.p_pump=30e6"])
    notes = cylinder_notes(scenario)
    assert notes["stick"]["supply"].startswith("its own supply: the FMU has no p_pump/p_LS")
    assert notes["boom"]["supply"] == "the shared load-sensing pump"
    log = tmp_path / "own.mcap"
    result = run_campaign(scenario, log_path=log)
    assert result.termination == "periods", result.message
    roles = {k: json.loads(v) for k, v in read_run(log).metadata["excosim.roles"].items()}
    assert roles["stick"]["supply"] == notes["stick"]["supply"]
    assert roles["bucket"]["arm_inertia"] == notes["bucket"]["arm_inertia"]
    review = subprocess.run([sys.executable, "-m", "orchestrator.cli.app", "review", str(log)],
                            capture_output=True, text=True, timeout=120, check=True).stdout
    assert "stick: " in review and "; off the shared pump" in review
    show = subprocess.run([sys.executable, "-m", "orchestrator.cli.app", "scenario", "show",
                           str(IDEAL)], capture_output=True, text=True, timeout=120,
                          check=True).stdout
    assert show.count("  arm inertia: not fed: the FMU has no mass_load input") == 3
