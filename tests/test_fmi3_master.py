"""FMI 3.0 co-simulation FMUs in the master: every role of the paper scenario filled by our FMI 3.0
builds digs the masses of the FMI 2.0 run, the checks and `fmus info` accept them, and a
model-exchange-only FMU is refused in one line."""

import re
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

import fmus
from fmus.runs import FastSlave
from orchestrator.campaign import run_campaign
from orchestrator.plants.master import Master
from orchestrator.review.summary import differing_roles, summary
from orchestrator.runlog import read_run
from orchestrator.scenario import ScenarioError, load_scenario
from plant_models.model_spec import FmuSpec

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "scenarios" / "paper-2020.toml"
ROLES = {"boom": "HydraulicCylinder", "stick": "HydraulicCylinder",
         "bucket": "HydraulicCylinder", "pile": "Pile"}
STEP = 0.005


def fmi3_overrides() -> list[str]:
    return [f"plant.{role}.fmu={fmus.build(model, fmi_version=3)}"
            for role, model in ROLES.items()]


def test_the_paper_scenario_on_fmi3_builds_digs_the_fmi2_masses(tmp_path):
    runs = {}
    for version, items in (("fmi2", []), ("fmi3", fmi3_overrides())):
        scenario = load_scenario(PAPER, ["periods=3", *items])
        result = run_campaign(scenario, log_path=tmp_path / f"{version}.mcap")
        assert result.termination == "periods", result.message
        runs[version] = [r["mass_kg"] for r in result.records]
    assert len(runs["fmi3"]) == 3 and all(m > 0.0 for m in runs["fmi3"])
    # Same C sources, same doubles: bit-identical here; the requirement is 1e-9 kg.
    np.testing.assert_allclose(runs["fmi3"], runs["fmi2"], rtol=0.0, atol=1e-9)
    summaries = [summary(read_run(tmp_path / f"{v}.mcap")) for v in ("fmi2", "fmi3")]
    roles = summaries[1]["roles"]
    assert roles["boom"]["fmu"] == str(fmus.build("HydraulicCylinder", fmi_version=3))
    assert roles["pile"]["file"] == "Pile.fmu"
    assert (summaries[0]["roles"]["boom"]["fmi_version"], roles["boom"]["fmi_version"]) == \
        ("2.0", "3.0")
    # compare says so, beside the other differences of the role
    assert "FMI version (2.0 | 3.0)" in differing_roles(summaries)["boom"]


def test_fastslave_steps_an_fmi3_build_like_its_fmi2_build():
    inputs, outputs = ["u", "F_ext"], ["x", "v", "p_A", "p_B", "F"]
    t = np.arange(600) * 1e-3
    series = np.column_stack([np.clip(1.5 * np.sin(2 * np.pi * 0.7 * t), -1, 1),
                              2e4 * np.sin(2 * np.pi * 0.3 * t)])
    rows = {}
    for version in (2, 3):
        with FastSlave(fmus.build("HydraulicCylinder", fmi_version=version), inputs, outputs,
                       {"x0": 0.5, "n_substeps": 10}) as slave:
            assert slave.fmi_version == version
            rows[version] = np.array([slave.step(k * 1e-3, 1e-3, series[k]).copy()
                                      for k in range(len(t))])
            assert slave.read(["x"])[0] == rows[version][-1, 0]
    assert np.ptp(rows[2][:, 0]) > 0.01
    np.testing.assert_array_equal(rows[3], rows[2])


def test_an_fmi3_error_names_the_fmi3_call():
    spec = FmuSpec(str(fmus.build("HydraulicCylinder", fmi_version=3)))
    with Master({"boom": ("cylinder", spec)}, STEP, {"boom": {"x0": 0.6}}) as master:
        boom = master["boom"]
        assert boom.read(["x"])[0] == pytest.approx(0.6)
        boom.inputs[boom.input_index["F_ext"]] = float("nan")  # the FMU rejects non-finite
        with pytest.raises(RuntimeError, match="fmi3SetFloat64 failed"):
            boom.step(0.0, STEP)


def test_fmus_info_and_validate_accept_an_fmi3_build():
    for target, role in (("HydraulicCylinder", "cylinder"), ("Pile", "pile")):
        done = subprocess.run([sys.executable, "-m", "orchestrator.cli.app", "fmus",
                               "validate", target, "--fmi3", "--role", role],
                              capture_output=True, text=True, timeout=120)
        assert done.returncode == 0 and done.stdout.strip().endswith(": valid"), done.stdout


def model_exchange_copy(source: Path, target: Path) -> Path:
    """`source` relabelled as model exchange only (the description is all the checks read)."""
    with zipfile.ZipFile(source) as old, zipfile.ZipFile(target, "w") as new:
        for item in old.infolist():
            data = old.read(item.filename)
            if item.filename == "modelDescription.xml":
                text = re.sub(r"<CoSimulation\b[^>]*?(/?)>", r'<ModelExchange modelIdentifier='
                              r'"IdealActuator"\1>', data.decode())
                data = text.replace("</CoSimulation>", "</ModelExchange>").encode()
            new.writestr(item, data)
    return target


@pytest.mark.parametrize("version", [2, 3])
def test_a_model_exchange_only_fmu_is_refused_in_one_line(version, tmp_path):
    fmu = model_exchange_copy(fmus.build("IdealActuator", fmi_version=version),
                              tmp_path / f"IdealActuatorME{version}.fmu")
    with pytest.raises(ValueError) as caught:
        Master({"boom": ("cylinder", FmuSpec(str(fmu)))}, STEP)
    message = str(caught.value)
    assert message == (f"boom: IdealActuator is an FMI {version}.0 FMU for model exchange "
                       "only; the master runs co-simulation FMUs (export it with "
                       "co-simulation, i.e. its own solver)")
    with pytest.raises(ScenarioError, match=r"plant\.boom\.fmu: IdealActuator is an FMI "
                                            r"\d\.0 FMU for model exchange only") as caught:
        load_scenario(PAPER, [f"plant.boom.fmu={fmu}"])
    assert "\n" not in str(caught.value)
    done = subprocess.run([sys.executable, "-m", "orchestrator.cli.app", "run", str(PAPER),
                           "--set", f"plant.boom.fmu={fmu}", "-o", str(tmp_path / "no.mcap")],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 2 and done.stderr.count("\n") == 1, done.stderr
    assert "for model exchange only" in done.stderr and not (tmp_path / "no.mcap").exists()
