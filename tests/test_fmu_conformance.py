"""FMI conformance and robustness of every FMU (FMI 2.0 and 3.0 builds), as the shared layers
(fmus/common/) and the code generators give it: initial values readable in initialization mode,
refused non-finite and out-of-range values, non-finite results as errors, output dependencies in
modelDescription.xml, fully validated deserialized states, and no crash for any input (fuzzed in
a subprocess, tests/fmu_fuzz.py)."""

from __future__ import annotations

import json
import math
import struct
import subprocess
import sys
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path

import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Slave
from fmpy.fmi3 import FMU3Slave
from fmpy.validation import validate_fmu

import fmus

VERSIONS = (2, 3)
CASES = [(name, version) for name in fmus.MODELS for version in VERSIONS]
IDS = [f"{name}-fmi{version}" for name, version in CASES]


class Slave:
    """One instance of a model's FMI 2 or 3 build through fmpy's low-level classes, by name."""

    def __init__(self, name: str, version: int, folder: Path, fmu: Path | None = None) -> None:
        self.fmu_path = fmu or fmus.build(name, version)
        self.version = version
        md = read_model_description(str(self.fmu_path))
        self.variables = {v.name: v for v in md.modelVariables}
        self.computed = [v.name for v in md.modelVariables if v.type in ("Real", "Float64")
                         and v.causality in ("output", "calculatedParameter")]
        unzip = extract(str(self.fmu_path), unzipdir=str(folder))
        kind = FMU2Slave if version == 2 else FMU3Slave
        self.fmu = kind(guid=md.guid, unzipDirectory=unzip, modelIdentifier=md.modelName,
                        instanceName=folder.name)
        self.fmu.instantiate()
        self.time = 0.0

    def vrs(self, names: list[str]) -> list[int]:
        return [self.variables[n].valueReference for n in names]

    def get(self, names: list[str]) -> list[float]:
        getter = self.fmu.getReal if self.version == 2 else self.fmu.getFloat64
        return list(getter(self.vrs(names)))

    def set(self, **values: float) -> None:
        for name, value in values.items():
            kind = self.variables[name].type
            setter = {"Real": "setReal", "Float64": "setFloat64", "Integer": "setInteger",
                      "Int32": "setInt32"}[kind]
            getattr(self.fmu, setter)(self.vrs([name]), [value])

    def enter(self) -> None:
        if self.version == 2:
            self.fmu.setupExperiment(startTime=0.0)
            self.fmu.enterInitializationMode()
        else:
            self.fmu.enterInitializationMode(startTime=0.0)

    def step(self, h: float = 1e-3) -> None:
        self.fmu.doStep(self.time, h)
        self.time += h

    def close(self) -> None:
        self.fmu.freeInstance()


@pytest.fixture
def open_slave(tmp_path):
    opened: list[Slave] = []

    def open_(name: str, version: int, fmu: Path | None = None) -> Slave:
        opened.append(Slave(name, version, tmp_path / f"{name}{version}-{len(opened)}", fmu))
        return opened[-1]

    yield open_
    for slave in opened:
        slave.close()


# ---- 1. initial values in initialization mode ---------------------------------------------------

@pytest.mark.parametrize("name, version", CASES, ids=IDS)
def test_initial_values_are_readable_in_initialization_mode(open_slave, name, version):
    slave = open_slave(name, version)
    if "F_ext" in slave.variables:
        slave.set(F_ext=1.2e5)
    slave.enter()
    during = slave.get(slave.computed)
    slave.fmu.exitInitializationMode()
    after = slave.get(slave.computed)
    assert during == after and any(value != 0.0 for value in during)


@pytest.mark.parametrize("version", VERSIONS)
def test_a_coupled_load_starts_at_its_initial_value(open_slave, version):
    """libcosim-style initialization: one cylinder's F feeds another's F_ext in init mode."""
    a, b = open_slave("HydraulicCylinder", version), open_slave("HydraulicCylinder", version)
    a.set(F_ext=1.2e5)
    a.enter(), b.enter()
    load = a.get(["F"])[0]
    b.set(F_ext=load)
    during = b.get(["F", "p_A"])
    a.fmu.exitInitializationMode(), b.fmu.exitInitializationMode()
    assert load == pytest.approx(1.2e5, rel=1e-12)
    assert during == b.get(["F", "p_A"]) and during[0] == pytest.approx(1.2e5, rel=1e-12)


@pytest.mark.parametrize("version", VERSIONS)
def test_initial_values_follow_each_set_and_name_a_failure(open_slave, version, capfd):
    slave = open_slave("IdealActuator", version)
    slave.set(x0=1.5)  # inside the table's range, beyond the stroke: the model refuses it
    slave.enter()
    with pytest.raises(FMICallException):
        slave.get(["x"])
    assert "initialization failed: x0 must lie in [0, stroke]" in capfd.readouterr().out
    assert slave.get(["x0"]) == [1.5]  # a parameter reads as set
    slave.set(x0=0.5, F_ext=3.0)
    assert slave.get(["x", "F"]) == [0.5, 3.0]
    slave.set(F_ext=-4.0)
    assert slave.get(["F"]) == [-4.0]


# ---- 2. non-finite and out-of-range values ------------------------------------------------------

@pytest.mark.parametrize("version", VERSIONS)
@pytest.mark.parametrize("model, name, value, message", [
    ("IdealActuator", "F_ext", math.nan, "value of 'F_ext' is not finite"),
    ("IdealActuator", "tau", math.inf, "value of 'tau' is not finite"),
    ("IdealActuator", "u", 1.5, "value of 'u' lies outside its range [-1, 1]: 1.5"),
    ("HydraulicCylinder", "n_substeps", 0, "value of 'n_substeps' lies outside its range"),
])
def test_bad_values_are_refused_when_set(open_slave, capfd, version, model, name, value,
                                         message):
    slave = open_slave(model, version)
    with pytest.raises(FMICallException):
        slave.set(**{name: value})
    assert message in capfd.readouterr().out


@pytest.mark.parametrize("version", VERSIONS)
def test_a_non_finite_initial_output_is_an_error(open_slave, probes, version, capfd):
    # The probe's initial y = a^2: finite inputs, an infinite output. (Our cylinder no longer
    # serves here: it clamps a load like F_ext = 1e308 onto its end stop, finitely.)
    slave = open_slave("Probe", version, probes[version])
    slave.set(a=1e308)
    slave.enter()
    with pytest.raises(FMICallException):
        slave.get(["y"])
    with pytest.raises(FMICallException):
        slave.fmu.exitInitializationMode()
    assert capfd.readouterr().out.count("produced a non-finite 'y' (inf)") == 2


PROBE_TABLE = """
[model]
identifier = "Probe"
[[variable]]
name = "a"
causality = "input"
variability = "continuous"
type = "Real"
start = 1.0
[[variable]]
name = "y"
causality = "output"
variability = "continuous"
type = "Real"
"""

PROBE_C = """
#include "model.h"
typedef struct { double acc; } State;
const size_t model_state_size = sizeof(State);
int model_initialize(double *v, void *s, const char **e) {
    ((State *)s)->acc = 0.0; v[VR_y] = v[VR_a] * v[VR_a]; (void)e; return 0;
}
int model_do_step(double *v, void *s, double t, double h, const char **e) {
    v[VR_y] = ((State *)s)->acc += h * v[VR_a]; (void)t; (void)e; return 0;
}
int model_check_state(const double *v, const void *s, const char **e) {
    (void)v; if (((const State *)s)->acc > 100.0) { *e = "acc above 100"; return 1; } return 0;
}
"""


@pytest.fixture(scope="module")
def probes(tmp_path_factory) -> dict[int, Path]:
    """The probe model's FMI 2 and 3 builds."""
    root = tmp_path_factory.mktemp("probe")
    folder = root / "src" / "Probe"
    folder.mkdir(parents=True)
    (folder / "variables.toml").write_text(PROBE_TABLE)
    (folder / "model.c").write_text(PROBE_C)
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("EXCOSIM_FMU_DIR", str(root / "out"))
        return {version: fmus.build_model(folder, version) for version in VERSIONS}


@pytest.mark.parametrize("version", VERSIONS)
@pytest.mark.parametrize("a, h, message", [(1e308, 1e3, "produced a non-finite 'y' (inf)"),
                                           (150.0, 1.0, "invalid model state: acc above 100")])
def test_a_failed_step_is_an_error_and_keeps_the_last_good_values(
        open_slave, probes, capfd, version, a, h, message):
    slave = open_slave("Probe", version, probes[version])
    slave.enter()
    slave.fmu.exitInitializationMode()
    slave.step(1.0)
    slave.set(a=a)
    with pytest.raises(FMICallException):
        slave.step(h)
    assert message in capfd.readouterr().out
    assert slave.get(["y"]) == [1.0]


# ---- 3. output dependencies ---------------------------------------------------------------------

@pytest.mark.parametrize("name, version", CASES, ids=IDS)
def test_outputs_depend_on_no_input_and_initial_unknowns_on_every_known(name, version):
    path = fmus.build(name, version)
    assert validate_fmu(str(path)) == []
    md = read_model_description(str(path))
    outputs = [v for v in md.modelVariables if v.causality == "output"]
    assert [u.variable for u in md.outputs] == outputs
    assert all(u.dependencies == [] for u in md.outputs)
    assert {u.variable.name for u in md.initialUnknowns} == {
        v.name for v in md.modelVariables if v.causality == "calculatedParameter"
        or (v.causality == "output" and v.initial != "exact")}
    assert all(u.dependencies is None for u in md.initialUnknowns)
    with zipfile.ZipFile(path) as archive:
        root = ET.fromstring(archive.read("modelDescription.xml"))
    tag = ".//Outputs/Unknown" if version == 2 else ".//ModelStructure/Output"
    assert [e.get("dependencies") for e in root.iterfind(tag)] == [""] * len(outputs)


# ---- 4. deserialized states ---------------------------------------------------------------------

HEADER = struct.Struct("<8sII40sQQQQ")  # state_core.h SerialHeader; the checksum is last


def reseal(data: bytes | bytearray) -> bytes:
    """The state with its FNV-1a checksum recomputed (so that only the edited content is bad)."""
    data = bytearray(data)
    data[HEADER.size - 8:HEADER.size] = bytes(8)
    h = 0xCBF29CE484222325
    for byte in data:
        h = ((h ^ byte) * 0x100000001B3) & 0xFFFFFFFFFFFFFFFF
    data[HEADER.size - 8:HEADER.size] = struct.pack("<Q", h)
    return bytes(data)


def edited(data: bytes, offset: int, value: bytes) -> bytes:
    out = bytearray(data)
    out[offset:offset + len(value)] = value
    return reseal(out)


def stepped(open_slave, name: str, version: int) -> Slave:
    slave = open_slave(name, version)
    slave.enter()
    slave.fmu.exitInitializationMode()
    for _ in range(20):
        slave.step()
    return slave


@pytest.mark.parametrize("name, version", CASES, ids=IDS)
def test_a_bad_serialized_state_is_refused_and_changes_nothing(open_slave, capfd, name,
                                                               version):
    slave = stepped(open_slave, name, version)
    good = slave.fmu.serializeFMUState(slave.fmu.getFMUState())
    assert reseal(good) == good
    n = HEADER.unpack_from(good)[4]
    v0, phase = HEADER.size, HEADER.size + 8 * n + 16
    first_output = slave.variables[slave.computed[0]].valueReference
    rng = np.random.default_rng(7)
    flips = [bytearray(good) for _ in range(24)]
    for flip, at in zip(flips, [0, 9, 20, 60, 81, phase, len(good) - 1,
                                *rng.integers(0, len(good), 17)], strict=True):
        flip[at] ^= 1 << int(rng.integers(8))
    cases = {
        "truncated": [good[:-1], good[:HEADER.size], b"", good + b"\0"],
        "bit flip": [bytes(f) for f in flips],
        "NaN": [edited(good, v0 + 8 * first_output, struct.pack("<d", math.nan))],
        "phase": [edited(good, phase, struct.pack("<i", 7))],
        "GUID": [edited(good, 17, b"!")],
        "version": [edited(good, 8, struct.pack("<I", 1))],
    }
    reused = slave.fmu.deserializeFMUState(good)
    before = slave.get(slave.computed)
    capfd.readouterr()
    for kind, states in cases.items():
        for bad in states:
            with pytest.raises(FMICallException):
                slave.fmu.deserializeFMUState(bad, reused)
            assert "serializefmustate: " in capfd.readouterr().out.lower(), kind
    assert slave.get(slave.computed) == before  # the instance is unchanged
    slave.step()
    expected = slave.get(slave.computed)
    slave.fmu.setFMUState(reused)  # the block handed in is unchanged too
    slave.time -= 1e-3
    slave.step()
    assert slave.get(slave.computed) == expected


@pytest.mark.parametrize("version", VERSIONS)
def test_refusals_of_a_serialized_state_say_why(open_slave, capfd, version):
    ideal = stepped(open_slave, "IdealActuator", version)
    good = ideal.fmu.serializeFMUState(ideal.fmu.getFMUState())
    n, snapshot_size = HEADER.unpack_from(good)[4:6]
    other = stepped(open_slave, "IdealActuator", 5 - version)
    foreign = stepped(open_slave, "HydraulicCylinder", version)
    x = ideal.variables["x"].valueReference
    cases = [
        (good[:-1], "is not a serialized IdealActuator state"),
        (other.fmu.serializeFMUState(other.fmu.getFMUState()), "wrong magic"),
        (foreign.fmu.serializeFMUState(foreign.fmu.getFMUState()), "not a serialized"),
        (edited(good, 17, b"!"), "different model or build (GUID)"),
        (bytes(good[:-1]) + bytes([good[-1] ^ 4]), "corrupt (checksum mismatch)"),
        (edited(good, HEADER.size + 8 * x, struct.pack("<d", math.inf)),
         "the value of 'x' is not finite"),
        (edited(good, HEADER.size + 8 * n + 16, struct.pack("<i", -1)), "invalid phase -1"),
        (edited(good, HEADER.size + snapshot_size + 8, struct.pack("<d", math.nan)),
         "model state is invalid: x must lie in [0, stroke] and v be finite"),
    ]
    for data, message in cases:
        with pytest.raises(FMICallException):
            ideal.fmu.deserializeFMUState(data)
        assert message in capfd.readouterr().out


# ---- 5. no input crashes an FMU -----------------------------------------------------------------

FUZZ = Path(__file__).with_name("fmu_fuzz.py")


@pytest.mark.parametrize("name, version", CASES, ids=IDS)
def test_no_call_sequence_crashes_or_returns_ok_with_a_non_finite_output(name, version):
    path = fmus.build(name, version)
    seed, n = 2024, 60
    command = [sys.executable, str(FUZZ), str(path), str(version), str(seed), str(n)]
    try:
        run = subprocess.run(command, capture_output=True, text=True, timeout=60)
    except subprocess.TimeoutExpired as exc:
        trace = exc.stderr.decode() if isinstance(exc.stderr, bytes) else exc.stderr or ""
        pytest.fail(f"fuzz of {name} FMI {version} hung; last calls:\n{_last_sequence(trace)}")
    assert run.returncode == 0, (
        f"fuzz of {name} FMI {version} died (exit {run.returncode}); reproducer, "
        f"`{' '.join(command)}`:\n{_last_sequence(run.stderr)}")
    report = json.loads(run.stdout.strip().splitlines()[-1])
    assert report["problems"] == []
    assert report["initialized"] > n // 4 and report["steps"] > n // 4  # it got past init


def _last_sequence(trace: str) -> str:
    start = trace.rfind("sequence ")
    return trace[start:] if start >= 0 else trace[-4000:]
