"""The FMU builder (cache, errors, code generation) and the shared FMI 2.0 layer's rules."""

import shutil
import zipfile
from pathlib import Path

import numpy as np
import pytest
from fmpy import read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.validation import validate_fmu

import fmus
from fmus.__main__ import main
from fmus.builder import MODELS_DIR
from fmus.codegen import variables_header
from fmus.runs import FastSlave
from fmus.table import TableError, parse_table

# A small model that exercises arrays, Integer and Boolean variables and private state:
# acc integrates a; y[i] = i * k * acc (negated when `on` is false); count counts steps.
PROBE_TABLE = """
[model]
identifier = "Probe"
description = "builder probe"

[[variable]]
name = "a"
causality = "input"
variability = "continuous"
type = "Real"
start = 2.0
unit = "m/s"

[[variable]]
name = "on"
causality = "input"
variability = "discrete"
type = "Boolean"
start = true

[[variable]]
name = "k"
causality = "parameter"
variability = "fixed"
type = "Integer"
start = 3

[[variable]]
name = "gain"
causality = "parameter"
variability = "tunable"
type = "Real"
start = 1.0

[[variable]]
name = "y"
causality = "output"
variability = "continuous"
type = "Real"
unit = "m"
count = 3

[[variable]]
name = "count"
causality = "output"
variability = "discrete"
type = "Integer"
"""

PROBE_C = """
#include "model.h"

typedef struct { double acc; } State;
const size_t model_state_size = sizeof(State);

static void outputs(double *v, const State *s) {
    int i;
    for (i = 0; i < N_y; i++) {
        v[VR_y_1 + i] = (i + 1) * v[VR_k] * v[VR_gain] * s->acc * (v[VR_on] != 0.0 ? 1.0 : -1.0);
    }
}

int model_initialize(double *v, void *state, const char **error) {
    if (v[VR_k] < 0) { *error = "k must be >= 0"; return 1; }
    ((State *)state)->acc = 0.0;
    v[VR_count] = 0;
    outputs(v, state);
    return 0;
}

int model_do_step(double *v, void *state, double t, double h, const char **error) {
    ((State *)state)->acc += h * v[VR_a];
    v[VR_count] += 1;
    outputs(v, state);
    return 0;
}
"""


@pytest.fixture
def out_dir(tmp_path, monkeypatch):
    folder = tmp_path / "fmus-out"
    monkeypatch.setenv("EXCOSIM_FMU_DIR", str(folder))
    return folder


@pytest.fixture
def probe_dir(tmp_path):
    folder = tmp_path / "src" / "Probe"
    folder.mkdir(parents=True)
    (folder / "variables.toml").write_text(PROBE_TABLE)
    (folder / "model.c").write_text(PROBE_C)
    return folder


@pytest.fixture
def cylinder_copy(tmp_path):
    return Path(shutil.copytree(MODELS_DIR / "HydraulicCylinder", tmp_path / "HydraulicCylinder"))


def test_models_lists_every_model_folder():
    assert "HydraulicCylinder" in fmus.MODELS
    assert list(fmus.MODELS) == sorted(p.parent.name for p in MODELS_DIR.glob("*/variables.toml"))


def test_build_writes_a_complete_fmu_into_the_configured_folder(out_dir, cylinder_copy):
    path = fmus.build_model(cylinder_copy)
    assert path.parent.parent == out_dir and path.name == "HydraulicCylinder.fmu"
    assert path.parent.name.startswith("HydraulicCylinder-") and len(path.parent.name) == 30
    names = zipfile.ZipFile(path).namelist()
    assert {"modelDescription.xml", "binaries/linux64/HydraulicCylinder.so",
            "sources/model.c", "sources/fmi2_cs.c", "sources/variables.h",
            "sources/model.h"} <= set(names)
    assert validate_fmu(str(path)) == []


def test_cache_hit_does_not_rebuild_and_a_source_change_does(out_dir, cylinder_copy):
    first = fmus.build_model(cylinder_copy)
    stamp, content = first.stat().st_mtime_ns, first.read_bytes()
    guid = read_model_description(str(first)).guid

    (cylinder_copy / "model.c").touch()  # a new mtime alone is no change
    again = fmus.build_model(cylinder_copy)
    assert again == first and again.stat().st_mtime_ns == stamp and again.read_bytes() == content

    with open(cylinder_copy / "model.c", "a") as source:
        source.write("\n/* changed */\n")
    rebuilt = fmus.build_model(cylinder_copy)
    assert rebuilt.read_bytes() != content
    assert read_model_description(str(rebuilt)).guid != guid


def test_compile_error_names_the_file_and_line_and_keeps_the_old_fmu(out_dir, cylinder_copy):
    built = fmus.build_model(cylinder_copy)
    good = built.read_bytes()
    source = cylinder_copy / "model.c"
    lines = source.read_text().splitlines()
    at = lines.index('#include "model.h"') + 1  # code, past the header comment
    lines.insert(at, "int broken = ;")
    source.write_text("\n".join(lines) + "\n")
    with pytest.raises(fmus.BuildError) as error:
        fmus.build_model(cylinder_copy)
    message = str(error.value)
    assert "HydraulicCylinder: gcc failed" in message and f"model.c:{at + 1}" in message
    assert "error" in message and "Traceback" not in message
    assert built.read_bytes() == good  # untouched
    assert list(out_dir.glob("HydraulicCylinder-*")) == [built.parent]  # nothing half-made


@pytest.mark.parametrize("edit, expected", [
    (lambda t: t.replace('type = "Real"\nstart = 0.14', 'type = "Real"\nstart = 0.14\nsize = 1'),
     "unknown key(s) ['size']"),
    (lambda t: t.replace('name = "u"\ncausality = "input"\nvariability = "continuous"',
                         'name = "u"\ncausality = "input"\nvariability = "fixed"'),
     "causality 'input' cannot have variability 'fixed'"),
    (lambda t: t.replace("start = 0.14\n", ""), "'bore': a fixed parameter needs a start value"),
    (lambda t: t.replace('identifier = "HydraulicCylinder"',
                         'identifier = "HydraulicCylinder"\nn_substeps_hint = 3'),
     "[model]: unknown key(s) ['n_substeps_hint']"),
    (lambda t: t.replace('name = "rod"', 'name = "bore"'), "duplicate name 'bore'"),
])
def test_bad_table_gives_one_clear_message(out_dir, cylinder_copy, edit, expected):
    table = cylinder_copy / "variables.toml"
    table.write_text(edit(table.read_text()))
    with pytest.raises(fmus.BuildError) as error:
        fmus.build_model(cylinder_copy)
    assert expected in str(error.value)
    assert "variables.toml" in str(error.value)


def test_unknown_model_and_missing_gcc_are_clear_errors(out_dir, monkeypatch, tmp_path,
                                                        cylinder_copy):
    with pytest.raises(fmus.BuildError, match="unknown model 'Crane'"):
        fmus.build("Crane")
    monkeypatch.setenv("PATH", str(tmp_path))  # a folder without gcc
    with pytest.raises(fmus.BuildError, match="gcc not found"):
        fmus.build_model(cylinder_copy)


def test_command_line_reports_failures_without_traceback(out_dir, monkeypatch, capsys):
    monkeypatch.setattr("fmus.__main__.model_names", lambda: ["HydraulicCylinder", "Crane"])
    assert main(["build"]) == 1
    captured = capsys.readouterr()
    assert f"HydraulicCylinder: {fmus.build('HydraulicCylinder')}" in captured.out
    assert "error: unknown model 'Crane'" in captured.err and "Traceback" not in captured.err
    assert main(["bogus"]) == 2


def test_array_entries_get_consecutive_value_references_and_macros():
    table = parse_table({"model": {"identifier": "M"}, "variable": [
        {"name": "p", "causality": "parameter", "variability": "fixed", "type": "Real",
         "start": 1.0},
        {"name": "h", "causality": "output", "variability": "continuous", "type": "Real",
         "count": 3},
        {"name": "q", "causality": "input", "variability": "continuous", "type": "Real",
         "start": [1.0, 2.0], "count": 2},
    ]}, "test")
    assert [(v.name, v.value_reference) for v in table.variables] == [
        ("p", 0), ("h[1]", 1), ("h[2]", 2), ("h[3]", 3), ("q[1]", 4), ("q[2]", 5)]
    header = variables_header(table, "{guid}")
    for line in ("#define VR_h_1 1", "#define VR_h_3 3", "#define N_h 3", "#define VR_q_2 5",
                 "#define N_VARIABLES 6", '#define MODEL_GUID "{guid}"'):
        assert line in header
    with pytest.raises(TableError, match="start list has 1 entries, count is 2"):
        parse_table({"model": {"identifier": "M"}, "variable": [
            {"name": "q", "causality": "input", "variability": "continuous", "type": "Real",
             "start": [1.0], "count": 2}]}, "test")


def test_probe_model_runs_with_arrays_integers_and_booleans(out_dir, probe_dir):
    path = fmus.build_model(probe_dir)
    assert validate_fmu(str(path)) == []
    names = [v.name for v in read_model_description(str(path)).modelVariables]
    assert names == ["a", "on", "k", "gain", "y[1]", "y[2]", "y[3]", "count"]
    with FastSlave(path, ["a"], ["y[1]", "y[2]", "y[3]"], {"k": 2, "on": False}) as probe:
        for step in range(10):
            y = probe.step(step * 0.1, 0.1, np.array([2.0]))
        # acc = 10 steps * 0.1 s * 2 = 2; y[i] = -(i * k * acc)
        np.testing.assert_allclose(y, [-4.0, -8.0, -12.0], rtol=1e-12)
        assert probe.slave.getInteger([7]) == [10]
        assert probe.slave.getBoolean([1]) == [False]


def test_shared_layer_enforces_fmi_rules(out_dir, probe_dir, capfd):
    path = fmus.build_model(probe_dir)
    with FastSlave(path, ["a"], ["y[1]"]) as probe:
        slave = probe.slave
        slave.setReal([3], [2.0])  # a tunable parameter may change between steps
        cases = [
            (lambda: slave.setInteger([2], [5]), "variable 'k' cannot be set in step mode"),
            (lambda: slave.setReal([4], [1.0]), "variable 'y[1]' cannot be set in step mode"),
            (lambda: slave.getReal([2]), "variable 'k' (vr 2) is a Integer, not a Real"),
            (lambda: slave.getReal([99]), "unknown value reference 99"),
            (lambda: slave.setReal([0], [float("nan")]), "value of 'a' is not finite"),
            (lambda: slave.doStep(5.0, 0.1), "differs from the FMU time"),
            (lambda: slave.doStep(0.0, -0.1), "communicationStepSize must be > 0"),
            (lambda: slave.getDirectionalDerivative([4], [0], [1.0]), "not provided"),
        ]
        for call, message in cases:
            with pytest.raises(FMICallException):
                call()
            assert message in capfd.readouterr().out
        y = probe.step(0.0, 0.5, np.array([1.0]))
        assert y[0] == pytest.approx(1 * 3 * 2.0 * 0.5)  # the new gain 2 took effect


def test_instantiate_rejects_a_wrong_guid(out_dir, probe_dir, tmp_path, capfd):
    from fmpy import extract
    from fmpy.fmi2 import FMU2Slave

    path = fmus.build_model(probe_dir)
    slave = FMU2Slave(guid="{00000000-0000-0000-0000-000000000000}",
                      unzipDirectory=extract(str(path), unzipdir=str(tmp_path / "x")),
                      modelIdentifier="Probe", instanceName="probe")
    with pytest.raises(Exception, match="Failed to instantiate"):
        slave.instantiate()
    assert "does not match this binary's" in capfd.readouterr().out
    slave.freeLibrary()
