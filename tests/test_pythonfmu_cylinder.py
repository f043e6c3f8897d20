"""An FMU from another tool: the cylinder of examples/pythonfmu_cylinder.py, exported by pythonfmu
(PyPI `pythonfmu`, test extra) at test time, with names and units of its own (percent, kN, mm,
mm/s, bar), digs the paper scenario in the bucket role through a port map on its identified
linear servo; its variant without a force output runs on the force the master derives from its
pressures and the piston areas it declares (in cm2)."""

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest
from fmpy import read_model_description
from fmpy.validation import validate_fmu

from orchestrator.campaign import run_campaign
from orchestrator.campaign.loop import build_plant
from orchestrator.plants.master import Master
from orchestrator.runlog import read_run
from orchestrator.scenario import ScenarioError, load_scenario
from plant_models.hydraulics import cylinder_parameters
from plant_models.model_spec import FmuSpec

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "scenarios" / "paper-2020.toml"
MODEL = ROOT / "examples" / "pythonfmu_cylinder.py"
# role -> the FMU's variable and its scale to SI (si = scale * fmu value).
PORTS = {"u": ("spool_cmd", 0.01), "F_ext": ("load_force", 1e3), "x": ("rod_position", 1e-3),
         "v": ("rod_speed", 1e-3), "x0": ("rod_position_start", 1e-3)}
FORCE = {"F": ("rod_force", 1e3)}
PRESSURES = {"p_A": ("cap_pressure", 1e5), "p_B": ("rod_pressure", 1e5)}
AREAS = {"A_A": ("bore_area", 1e-4), "A_B": ("annulus_area", 1e-4)}


@pytest.fixture(scope="module")
def exported(tmp_path_factory) -> dict[str, Path]:
    """{"force": PyCylinder.fmu, "pressures": PyCylinderP.fmu (no rod_force)}, built by
    pythonfmu from the model file; each variant a module of its own name (the FMU imports it
    by name into this process)."""
    from pythonfmu import FmuBuilder

    folder = tmp_path_factory.mktemp("pythonfmu")
    text = MODEL.read_text()
    variants = {"force": ("excosim_pycylinder", text),
                "pressures": ("excosim_pycylinder_p", text.replace(
                    "WITH_FORCE = True", "WITH_FORCE = False").replace(
                    "class PyCylinder(", "class PyCylinderP("))}
    out = {}
    for key, (module, source) in variants.items():
        script = folder / f"{module}.py"
        script.write_text(source)
        out[key] = Path(FmuBuilder.build_FMU(script, dest=folder / "fmu"))
    return out


def port_table(ports: dict[str, tuple[str, float]]) -> str:
    entries = [f'{role} = {{variable = "{name}", scale = {scale!r}}}'
               for role, (name, scale) in ports.items()]
    return "{" + ", ".join(entries) + "}"


def bucket(fmu: Path, ports: dict) -> list[str]:
    stroke_mm = 1000.0 * cylinder_parameters("paper")["bucket"]["stroke"]
    return [f"plant.bucket.fmu={fmu}", f"plant.bucket.ports={port_table(ports)}",
            f"plant.bucket.parameters={{stroke_length = {stroke_mm!r}}}"]


def test_the_exported_fmu_is_another_tools_and_valid(exported):
    for path in exported.values():
        description = read_model_description(str(path))
        assert description.generationTool.startswith("PythonFMU 0.7")
        assert (description.fmiVersion, description.coSimulation is not None) == ("2.0", True)
        # pythonfmu 0.7 leaves its outputs out of <InitialUnknowns>, the one thing fmpy's
        # validator (and so `excosim fmus validate`) reports; the master does not need it.
        problems = validate_fmu(str(path))
        assert len(problems) == 1 and problems[0].startswith(
            "ModelStructure/InitialUnknowns does not contain the expected set of variables")
    names = {v.name for v in read_model_description(str(exported["pressures"])).modelVariables}
    assert "rod_force" not in names and {"cap_pressure", "bore_area"} <= names
    done = subprocess.run([sys.executable, "-m", "orchestrator.cli.app", "fmus", "info",
                           str(exported["force"]), "--json"], capture_output=True, text=True,
                          timeout=120)
    cylinder = json.loads(done.stdout)["roles"]["cylinder"]
    assert not cylinder["fills"] and "u" in cylinder["missing"]  # its own names: a port map
    # `fmus validate` takes that port map (--ports, or a scenario's with --scenario): then the
    # only problem left is pythonfmu's InitialUnknowns; a wrong variable is named.
    ports = {role: {"variable": name, "scale": scale}
             for role, (name, scale) in {**PORTS, **FORCE}.items()}
    for mapping, expected in ((ports, "ModelStructure/InitialUnknowns"),
                              ({**ports, "u": "spool"}, "bucket: role 'u' maps to variable "
                               "'spool', which PyCylinder does not have")):
        done = subprocess.run([sys.executable, "-m", "orchestrator.cli.app", "fmus", "validate",
                               str(exported["force"]), "--role", "bucket", "--ports",
                               json.dumps(mapping)], capture_output=True, text=True,
                              timeout=120)
        lines = done.stdout.strip().splitlines()
        assert done.returncode == 1 and lines[-1].startswith(expected), done.stdout
        assert len(lines) == 1 + (expected.startswith("bucket")), lines


def test_it_digs_two_paper_periods_in_the_bucket_role_on_its_identified_servo(exported,
                                                                              tmp_path):
    scenario = load_scenario(PAPER, ["periods=2", *bucket(exported["force"], PORTS | FORCE)])
    plant = build_plant(scenario)
    identified = plant.identifications[2]
    assert plant.identifications[:2] == (None, None)  # boom, stick: our HydraulicCylinder
    # 300 mm/s at 100 % (slowed by the valve's sqrt(1 - F / 500 kN) only under load): 0.3 m/s.
    assert identified.model.velocity_gain_m_s == pytest.approx(0.3, rel=0.01)
    assert identified.model.damping >= 1.0  # first order: no oscillation
    result = run_campaign(scenario, log_path=tmp_path / "py.mcap", plant=plant)
    assert result.termination == "periods", result.message
    masses = [r["mass_kg"] for r in result.records]
    hydraulic = [r["mass_kg"] for r in run_campaign(load_scenario(PAPER, ["periods=2"])).records]
    assert len(masses) == 2 and masses == pytest.approx(hydraulic, abs=0.5), (masses, hydraulic)
    roles = read_run(tmp_path / "py.mcap").metadata["excosim.roles"]
    bucket_role = json.loads(roles["bucket"])
    assert bucket_role["ports"]["u"] == {"variable": "spool_cmd", "scale": 0.01, "offset": 0.0}
    assert bucket_role["derived"] == {}


def test_without_a_force_output_the_master_derives_it_from_the_pressures(exported, tmp_path):
    runs = {}
    for key, ports in (("force", PORTS | FORCE), ("pressures", PORTS | PRESSURES | AREAS)):
        scenario = load_scenario(PAPER, ["periods=2", *bucket(exported[key], ports)])
        result = run_campaign(scenario, log_path=tmp_path / f"{key}.mcap")
        assert result.termination == "periods", result.message
        runs[key] = [r["mass_kg"] for r in result.records]
    # The linear servo does not read F: the same motion, so the same masses.
    assert runs["pressures"] == runs["force"]
    note = json.loads(read_run(tmp_path / "pressures.mcap").metadata["excosim.roles"]
                      ["bucket"])["derived"]["F"]
    assert re.fullmatch(r"F = p_A \* A_A - p_B \* A_B \(not an FMU output\), A_A = 0\.010387 "
                        r"m2 \(FMU parameter bore_area\), A_B = 0\.005361 m2 \(FMU parameter "
                        r"annulus_area\)", note), note
    # The derived force is the one the model reports: p_A A_A - p_B A_B = rod_force.
    start = {"x0": 0.4, "F_ext": -2e4}
    specs = {key: load_scenario(PAPER, bucket(exported[key], ports)).fmu_specs()["bucket"]
             for key, ports in (("force", PORTS | FORCE),
                                ("pressures", PORTS | PRESSURES | AREAS))}
    with Master({k: ("cylinder", s) for k, s in specs.items()}, 0.005,
                {k: start for k in specs}) as master:
        for k in range(50):
            for component in master.components.values():
                component.inputs[component.input_index["u"]] = 0.3
                component.inputs[component.input_index["F_ext"]] = -2e4 + 800.0 * k
                component.step(k * 0.005, 0.005)
            force, derived = (master[k].outputs[master[k].output_index["F"]] for k in specs)
            assert derived == pytest.approx(force, rel=1e-12, abs=1e-6)
            assert force == pytest.approx(-2e4 + 800.0 * k, rel=1e-12)


def test_pressures_without_areas_or_a_mapping_are_refused_in_one_line(exported):
    fmu = exported["pressures"]
    with pytest.raises(ScenarioError) as caught:
        load_scenario(PAPER, bucket(fmu, PORTS))  # neither F nor the pressures mapped
    assert str(caught.value) == (
        "paper-2020.toml: plant.bucket.ports.F: PyCylinderP has no variable 'F' for role 'F' "
        "and the master cannot derive it as F = p_A * A_A - p_B * A_B: it lacks the outputs "
        "p_A, p_B and A_A, A_B (m^2: the role's piston_areas, or FMU parameters named by "
        "ports.A_A and ports.A_B)")
    # The areas from the scenario instead of the FMU's parameters.
    spec = load_scenario(PAPER, [*bucket(fmu, PORTS | PRESSURES),
                                 "plant.bucket.piston_areas={A_A = 0.0104, A_B = 0.0054}"]
                         ).fmu_specs()["bucket"]
    assert spec.piston_areas == {"A_A": 0.0104, "A_B": 0.0054}
    with Master({"bucket": ("cylinder", spec)}, 0.005, {"bucket": {"x0": 0.4}}) as master:
        assert "A_A = 0.0104 m2 (scenario piston_areas)" in master["bucket"].derived_notes["F"]
    names = {role: name for role, (name, _) in PORTS.items()}
    with pytest.raises(ValueError, match=r"^bucket: PyCylinderP has no variable 'F'"):
        Master({"bucket": ("cylinder", FmuSpec(str(fmu), ports=names))}, 0.005)
