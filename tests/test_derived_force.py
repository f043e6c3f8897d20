"""A cylinder FMU without the force output: the master derives F = p_A A_A - p_B A_B from its
chamber pressures and the piston areas (plant_models.model_spec.DERIVABLE_OUTPUTS), says so in
the run log, and refuses in one line an FMU from which F can be neither read nor derived.

The FMU is our HydraulicCylinder built without its F output: it declares its piston areas (as
calculated parameters) and its servo reads F, so a run on the derived force digs bit-identical
masses; IdealActuator without F has no pressures to derive it from."""

import json
import math
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import fmus
from orchestrator.campaign import run_campaign
from orchestrator.plants.master import Master
from orchestrator.runlog import read_run
from orchestrator.scenario import ScenarioError, load_scenario
from plant_models.hydraulics import cylinder_parameters
from plant_models.model_spec import FmuSpec

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "scenarios" / "paper-2020.toml"
STEP = 0.005


def without_force(tmp_path_factory, model: str) -> Path:
    """Our `model` built without its F output (same physics, same other variables)."""
    root = tmp_path_factory.mktemp(f"{model}-without-F")
    folder = root / model
    shutil.copytree(ROOT / "fmus" / model, folder)
    table = folder / "variables.toml"
    blocks = table.read_text().split("[[variable]]")
    kept = [b for b in blocks if not re.search(r'^name = "F"$', b, re.M)]
    assert len(kept) == len(blocks) - 1
    table.write_text("[[variable]]".join(kept))
    code = (folder / "model.c").read_text()
    assert code.count("v[VR_F] =") == 1
    (folder / "model.c").write_text(re.sub(r"^\s*v\[VR_F\] = .*\n", "", code, flags=re.M))
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("EXCOSIM_FMU_DIR", str(root / "fmu"))
        return fmus.build_model(folder)


@pytest.fixture(scope="module")
def forceless(tmp_path_factory) -> Path:
    """HydraulicCylinder without F: it still declares its piston areas A_A, A_B (calculated
    parameters, m2) and has the pressures."""
    return without_force(tmp_path_factory, "HydraulicCylinder")


@pytest.fixture(scope="module")
def underivable(tmp_path_factory) -> Path:
    """IdealActuator without F: no pressures either, so F can be neither read nor derived."""
    return without_force(tmp_path_factory, "IdealActuator")


def areas(joint: str) -> dict[str, float]:
    """The piston areas HydraulicCylinder computes from the preset's bore and rod (m^2)."""
    bore, rod = (cylinder_parameters("paper")[joint][k] for k in ("bore", "rod"))
    return {"A_A": math.pi / 4.0 * bore * bore, "A_B": math.pi / 4.0 * (bore * bore - rod * rod)}


def test_the_master_computes_f_from_the_pressures_each_step(forceless):
    parameters = cylinder_parameters("paper")["bucket"]
    specs = {"ours": FmuSpec("HydraulicCylinder", parameters),
             "declared": FmuSpec(str(forceless), parameters),  # the FMU's own A_A, A_B
             "given": FmuSpec(str(forceless), parameters, piston_areas=areas("bucket"))}
    start = {name: {"x0": 0.5, "F_ext": 1e4} for name in specs}
    with Master({n: ("cylinder", s) for n, s in specs.items()}, STEP, start) as master:
        for name in ("declared", "given"):
            assert master[name].missing_outputs == () and list(master[name].derived) == ["F"]
        assert master["declared"].derived_notes["F"] == (
            "F = p_A * A_A - p_B * A_B (not an FMU output), A_A = 0.0103869 m2 (FMU "
            "calculatedParameter A_A), A_B = 0.00536034 m2 (FMU calculatedParameter A_B)")
        assert "A_A = 0.0103869 m2 (scenario piston_areas)" in master["given"].derived_notes["F"]
        rows = []
        for k in range(300):
            for component in master.components.values():
                component.inputs[component.input_index["u"]] = 0.4 * math.sin(0.03 * k)
                component.inputs[component.input_index["F_ext"]] = 1e4
                component.step(k * STEP, STEP)
            rows.append([master[name].outputs.copy() for name in specs])
    ours, declared, given = (np.array(r) for r in zip(*rows, strict=True))
    assert np.ptp(ours[:, 4]) > 1e3  # the force moved
    np.testing.assert_array_equal(declared, ours)  # x, v, p_A, p_B and F
    np.testing.assert_array_equal(given, ours)


def test_a_run_on_the_derived_force_digs_the_same_masses_and_logs_it(forceless, tmp_path):
    logs = {"ours": tmp_path / "ours.mcap", "derived": tmp_path / "derived.mcap"}
    masses = {}
    for name, extra in (("ours", []), ("derived", [f"plant.bucket.fmu={forceless}"])):
        result = run_campaign(load_scenario(PAPER, ["periods=2", *extra]), log_path=logs[name])
        assert result.termination == "periods", result.message
        masses[name] = [r["mass_kg"] for r in result.records]
    assert masses["derived"] == masses["ours"]  # its servo reads F: the derived one is exact
    roles = {k: json.loads(v) for k, v in read_run(logs["derived"]).metadata["excosim.roles"]
             .items()}
    assert roles["boom"]["derived"] == {}
    assert roles["bucket"]["derived"] == {"F": (
        "F = p_A * A_A - p_B * A_B (not an FMU output), A_A from the FMU calculatedParameter "
        "A_A, read after initialization, A_B from the FMU calculatedParameter A_B, read after "
        "initialization")}
    review = subprocess.run([sys.executable, "-m", "orchestrator.cli.app", "review",
                             str(logs["derived"])], capture_output=True, text=True, timeout=120)
    assert "F derived by the master" in review.stdout


def test_f_neither_read_nor_derived_is_refused_in_one_line(underivable, tmp_path):
    with pytest.raises(ScenarioError) as caught:
        load_scenario(PAPER, [f"plant.bucket.fmu={underivable}"])
    assert str(caught.value) == (
        "paper-2020.toml: plant.bucket.ports.F: IdealActuator has no variable 'F' for role "
        "'F' and the master cannot derive it as F = p_A * A_A - p_B * A_B: it lacks the outputs "
        "p_A, p_B and A_A, A_B (m^2: the role's piston_areas, or FMU parameters named by "
        "ports.A_A and ports.A_B)")
    with pytest.raises(ValueError, match=r"^bucket: IdealActuator has no variable 'F' for role"):
        Master({"bucket": ("cylinder", FmuSpec(str(underivable)))}, STEP)
    done = subprocess.run([sys.executable, "-m", "orchestrator.cli.app", "run", str(PAPER),
                           "--set", f"plant.bucket.fmu={underivable}",
                           "-o", str(tmp_path / "no.mcap")],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 2 and done.stderr.count("\n") == 1, done.stderr
    assert "cannot derive it as F = p_A * A_A - p_B * A_B" in done.stderr
    assert not (tmp_path / "no.mcap").exists()
    info = subprocess.run([sys.executable, "-m", "orchestrator.cli.app", "fmus", "info",
                           str(underivable), "--json"], capture_output=True, text=True,
                          timeout=120)
    cylinder = json.loads(info.stdout)["roles"]["cylinder"]
    assert not cylinder["fills"] and cylinder["missing"] == ["F"]
    assert "cannot derive it as F = p_A * A_A - p_B * A_B" in cylinder["problems"][0]


def test_fmus_info_says_the_master_derives_f(forceless):
    info = subprocess.run([sys.executable, "-m", "orchestrator.cli.app", "fmus", "info",
                           str(forceless), "--json"], capture_output=True, text=True, timeout=120)
    cylinder = json.loads(info.stdout)["roles"]["cylinder"]
    assert cylinder["fills"] and cylinder["derived"] == ["F"] and cylinder["missing"] == []


def test_a_bad_area_is_refused_with_its_field(forceless):
    with pytest.raises(ScenarioError, match=r"plant\.bucket\.piston_areas: area A_B must be > 0"):
        load_scenario(PAPER, ["plant.bucket.piston_areas={A_A = 0.01, A_B = -1.0}"])
    with pytest.raises(ScenarioError, match=r"unknown area 'A_C'"):
        load_scenario(PAPER, ["plant.bucket.piston_areas={A_C = 0.01}"])
    with pytest.raises(ScenarioError, match=r"plant\.bucket\.ports\.A_A: role 'A_A' maps to "
                                            r"variable 'bore_area', which HydraulicCylinder"):
        load_scenario(PAPER, [f"plant.bucket.fmu={forceless}",
                              'plant.bucket.ports.A_A="bore_area"'])
