"""`excosim fmus info` / `excosim fmus validate` (orchestrator/cli/fmus_info.py): our FMUs, an
FMI 3.0 build (which fills its role like the FMI 2.0 one), a file that is not an FMU and a
model-exchange-only FMU."""

import json
import re
import zipfile

import pytest
from typer.testing import CliRunner

import fmus
from orchestrator.cli.app import app
from orchestrator.cli.fmus_info import inspect_fmu, validate

runner = CliRunner()


def invoke(*args):
    return runner.invoke(app, ["fmus", *args])


def roles(target, *extra):
    result = invoke("info", target, "--json", *extra)
    assert result.exit_code == 0, result.output
    return json.loads(result.stdout)


def test_info_of_our_models_reports_variables_and_roles():
    report = roles("HydraulicCylinder")
    assert report["fmi_version"] == "2.0" and report["kinds"] == ["co-simulation"]
    u = next(v for v in report["variables"] if v["name"] == "u")
    assert (u["causality"], u["variability"], u["type"], u["unit"], u["start"]) == \
           ("input", "continuous", "Real", "1", 0.0)
    n = next(v for v in report["variables"] if v["name"] == "n_substeps")
    assert n["type"] == "Integer" and n["start"] == 10
    assert report["roles"]["cylinder"]["fills"] and not report["roles"]["pile"]["fills"]
    assert report["roles"]["cylinder"]["parts"] == ["boom", "stick", "bucket"]
    for pile in ("Pile", "PileZelenin"):
        assert roles(pile)["roles"]["pile"] == {"parts": ["pile"], "fills": True, "missing": [],
                                                "absent": [], "derived": [], "problems": []}


def test_ideal_actuator_fills_the_cylinder_role_without_the_optional_ports():
    # No oil chambers and no load-mass input: the master runs it without them (its pressures are
    # logged as absent, the arm's inertia is not fed to it), so info says it fills the role.
    cylinder = roles("IdealActuator")["roles"]["cylinder"]
    assert cylinder["fills"] and cylinder["missing"] == []
    assert cylinder["absent"] == ["mass_load", "p_pump", "p_LS", "p_A", "p_B", "E_supply",
                                  "E_throttling"]
    text = invoke("info", "IdealActuator").stdout
    assert re.search(r"cylinder \(boom/stick/bucket\): fills; without the optional "
                     r"mass_load, p_pump, p_LS, p_A, p_B", text)
    assert invoke("validate", "IdealActuator").exit_code == 0


@pytest.mark.parametrize("name, role", [("HydraulicCylinder", "cylinder"), ("Pile", "pile"),
                                        ("PileZelenin", None)])
def test_validate_accepts_our_fmus(name, role):
    args = ["validate", str(fmus.build(name))] + (["--role", role] if role else [])
    result = invoke(*args)
    assert result.exit_code == 0, result.output
    assert result.stdout.strip().endswith(": valid")


def test_validate_with_the_wrong_role_lists_its_problems():
    result = invoke("validate", "Pile", "--role", "cylinder")
    assert result.exit_code == 1 and "cylinder: no variable 'u' (needs a Real input)" in \
        result.stdout.splitlines()


def test_fmi3_build_is_described_and_fills_its_role():
    report = roles("HydraulicCylinder", "--fmi3")
    assert report["fmi_version"] == "3.0" and report["kinds"] == ["co-simulation"]
    assert {v["type"] for v in report["variables"]} == {"Float64", "Int32"}
    cylinder = report["roles"]["cylinder"]
    assert cylinder["missing"] == [] and cylinder["fills"] and cylinder["problems"] == []
    assert roles("Pile", "--fmi3")["roles"]["pile"]["fills"]
    assert validate(fmus.build("HydraulicCylinder", fmi_version=3), "cylinder") == []


def test_a_file_that_is_not_an_fmu_exits_2(tmp_path):
    for path in (tmp_path / "notes.fmu", tmp_path / "empty.zip"):
        if path.suffix == ".zip":
            zipfile.ZipFile(path, "w").close()
        else:
            path.write_text("not a zip")
        for command in ("info", "validate"):
            result = invoke(command, str(path))
            assert result.exit_code == 2 and "not an FMU" in result.output
    assert invoke("info", str(tmp_path / "missing.fmu")).exit_code == 2


def test_model_exchange_only_fmu(tmp_path):
    # Our builder makes co-simulation FMUs only: relabel one as model exchange (the description
    # is what info reads; the binary is not loaded).
    source = fmus.build("IdealActuator")
    target = tmp_path / "IdealActuatorME.fmu"
    with zipfile.ZipFile(source) as old, zipfile.ZipFile(target, "w") as new:
        for item in old.infolist():
            data = old.read(item.filename)
            if item.filename == "modelDescription.xml":
                text = data.decode()
                text = re.sub(r"<CoSimulation [^>]*>", '<ModelExchange modelIdentifier='
                              '"IdealActuator">', text).replace("</CoSimulation>",
                                                                "</ModelExchange>")
                data = text.encode()
            new.writestr(item, data)
    info = inspect_fmu(target)
    assert info.kinds == ["model exchange"]
    assert all("model exchange" in c.problems[0] for c in info.roles)
    report = roles(str(target))
    assert report["kinds"] == ["model exchange"]
    assert invoke("validate", str(target)).exit_code == 1


def test_an_array_variable_shows_its_shape_not_every_start_value():
    """An FMI 3.0 array parameter of 200 values: JSON gives its shape; the text view its shape
    and ends in one short cell, marked with [] after its name."""
    from types import SimpleNamespace

    from orchestrator.cli.fmus_info import _shape, _start_text

    table = SimpleNamespace(name="table", dimensions=[SimpleNamespace(start=200)])
    assert _shape(table) == {"shape": [200]}
    row = {"start": " ".join(str(float(i)) for i in range(200)), "shape": [200]}
    assert _start_text(row) == "[200] 0.0 .. 199.0"
    assert _shape(SimpleNamespace(name="bore")) == {} and _start_text({"start": 0.14}) == "0.14"
