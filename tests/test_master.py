"""Co-simulation master: port maps (a renamed FMU behaves identically), clear errors for wrong
names, and every instance and extraction freed after many runs and after errors."""

import gc
import os
import re
import shutil
import tempfile
from pathlib import Path

import numpy as np
import pytest

import fmus
from orchestrator.plants.master import Master
from plant_models.model_spec import FmuSpec

STEP = 0.005
CYLINDER = FmuSpec("HydraulicCylinder", {"mass": 2000.0})


@pytest.fixture(scope="module")
def renamed_cylinder(tmp_path_factory):
    """HydraulicCylinder with u -> spool and x -> stroke_pos, built into its own FMU folder."""
    root = tmp_path_factory.mktemp("renamed")
    folder = root / "HydraulicCylinder"
    shutil.copytree(Path(fmus.__file__).parent / "HydraulicCylinder", folder)
    table = folder / "variables.toml"
    text = table.read_text()
    text = text.replace('name = "u"', 'name = "spool"').replace('name = "x"',
                                                                'name = "stroke_pos"')
    table.write_text(text)
    model = folder / "model.c"
    code = re.sub(r"\bVR_u\b", "VR_spool", model.read_text())
    model.write_text(re.sub(r"\bVR_x\b", "VR_stroke_pos", code))
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("EXCOSIM_FMU_DIR", str(root / "fmu"))
        path = fmus.build_model(folder)
    assert path.parent.parent == root / "fmu"  # <dir>/<Model>-<key>/<Model>.fmu
    return path


def run_cylinder(spec, n=400):
    """Drive one cylinder through the master; (n, 7) outputs in role order x, v, p_A, p_B, F,
    E_supply, E_throttling."""
    t = np.arange(n) * STEP
    rows = np.empty((n, 7))
    with Master({"boom": ("cylinder", spec)}, STEP, {"boom": {"x0": 0.6, "F_ext": 2e4}}) as m:
        boom = m["boom"]
        for k in range(n):
            boom.inputs[boom.input_index["u"]] = np.sin(2 * np.pi * 0.7 * t[k])
            boom.inputs[boom.input_index["F_ext"]] = 2e4 + 1e4 * np.sin(2 * np.pi * 0.3 * t[k])
            boom.step(t[k], STEP)
            rows[k] = boom.outputs
    return rows


def test_renamed_fmu_with_a_port_map_gives_identical_outputs(renamed_cylinder):
    ours = run_cylinder(CYLINDER)
    renamed = FmuSpec(str(renamed_cylinder), CYLINDER.parameters,
                      {"u": "spool", "x": "stroke_pos"})
    theirs = run_cylinder(renamed)
    assert np.ptp(ours[:, 0]) > 0.05  # the cylinder really moved
    np.testing.assert_array_equal(ours, theirs)


def test_renamed_fmu_without_the_port_map_is_a_clear_error(renamed_cylinder):
    spec = FmuSpec(str(renamed_cylinder), CYLINDER.parameters)
    with pytest.raises(ValueError, match=r"boom: role 'u' maps to variable 'u', which "
                                         r"HydraulicCylinder does not have"):
        Master({"boom": ("cylinder", spec)}, STEP)


@pytest.mark.parametrize("spec,message", [
    (FmuSpec("HydraulicCylinder", ports={"u": "spool"}), r"role 'u' maps to variable 'spool'"),
    (FmuSpec("HydraulicCylinder", ports={"x": "u"}),
     r"role 'x' needs a Real output, but variable 'u' .* is a Real input"),
    (FmuSpec("HydraulicCylinder", ports={"spool": "u"}), r"unknown role 'spool'"),
    (FmuSpec("HydraulicCylinder", {"bored": 0.1}), r"has no parameter 'bored'"),
    (FmuSpec("HydraulicCylinder", {"F": 1.0}), r"parameter 'F' has causality output"),
    (FmuSpec("HydraulicCylinder", ports={"x0": "stroke0"}), r"role 'x0' maps to variable"),
    (FmuSpec("no/such/file.fmu"), r"neither one of our models .* nor an existing \.fmu file"),
])
def test_wrong_names_are_value_errors_naming_component_role_and_variable(spec, message):
    with pytest.raises(ValueError, match=message) as caught:
        Master({"boom": ("cylinder", spec)}, STEP)
    assert str(caught.value).startswith("boom: ")


def test_a_rejected_start_value_is_a_value_error_and_leaks_nothing(private_tmp):
    with pytest.raises(ValueError, match="boom: HydraulicCylinder did not initialise"):
        Master({"boom": ("cylinder", CYLINDER)}, STEP, {"boom": {"x0": 5.0}})  # beyond stroke
    assert _extractions(private_tmp) == [] and _mapped(private_tmp) == 0


@pytest.fixture
def private_tmp(tmp_path, monkeypatch):
    """A temp folder of this test's own for every extraction (other processes share /tmp)."""
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    gc.collect()  # objects of earlier tests must not close their files during the count
    return tmp_path


def _extractions(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir())


def _open_files() -> int:
    return len(os.listdir("/proc/self/fd"))


def _mapped(folder: Path) -> int:
    with open("/proc/self/maps") as maps:
        return sum(str(folder) in line for line in maps)


def _plant_components():
    return {"boom": ("cylinder", CYLINDER), "stick": ("cylinder", CYLINDER),
            "bucket": ("cylinder", CYLINDER), "pile": ("pile", FmuSpec("Pile"))}


def test_many_runs_free_every_instance_and_extraction(private_tmp):
    Master(_plant_components(), STEP).close()  # warm-up: imports, builds
    files = _open_files()
    for _ in range(40):
        with Master(_plant_components(), STEP) as master:
            for name in ("boom", "pile"):
                master[name].step(0.0, STEP)
            assert len(_extractions(private_tmp)) == 2  # one per FMU file, shared
            assert _mapped(private_tmp) > 0
    assert _extractions(private_tmp) == [] and _mapped(private_tmp) == 0
    assert _open_files() == files


def test_an_exception_mid_run_frees_everything(private_tmp):
    master = None
    with pytest.raises(RuntimeError, match="stop here"):
        with Master(_plant_components(), STEP) as master:
            master["stick"].step(0.0, STEP)
            raise RuntimeError("stop here")
    assert _extractions(private_tmp) == [] and _mapped(private_tmp) == 0
    assert all(c._slave.slave is None for c in master.components.values())
    master.close()  # safe twice
    with pytest.raises(RuntimeError, match="stick: the FMU instance is closed"):
        master["stick"].step(STEP, STEP)


def test_an_fmu_error_mid_run_raises_and_close_still_frees(private_tmp):
    with Master(_plant_components(), STEP) as master:
        boom = master["boom"]
        boom.inputs[boom.input_index["F_ext"]] = float("nan")  # the FMU rejects non-finite
        with pytest.raises(RuntimeError, match="fmi2SetReal failed"):
            boom.step(0.0, STEP)
    assert _extractions(private_tmp) == [] and _mapped(private_tmp) == 0


def test_read_gives_any_real_variable():
    with Master({"pile": ("pile", FmuSpec("Pile"))}, STEP) as master:
        pile = master["pile"]
        profile = pile.read([f"h[{i}]" for i in range(1, 221)])
        assert profile.shape == (220,)
        np.testing.assert_array_equal(profile, 0.0)  # flat ground at z = 0 (FMU default)
        assert pile.read(["density"])[0] == 1600.0
