"""FMI 3.0 co-simulation builds of our models (fmus.build(name, fmi_version=3)): valid for fmpy,
a cache entry of their own, and the same numbers as the FMI 2.0 build of the same sources over a
paper-like digging period (both simulated by fmpy with the same inputs)."""

import zipfile

import numpy as np
import pytest
from fmpy import read_model_description, simulate_fmu
from fmpy.validation import validate_fmu

import fmus
from fmus.toolchain import platform_folder

PERIOD, STEP = 3.0, 1e-3  # s: one digging pass of the paper's period length scale


def _cylinder(t):
    return {"u": np.clip(1.5 * np.sin(2 * np.pi * 0.4 * t), -1, 1),
            "F_ext": 1.2e5 * np.sin(2 * np.pi * 0.3 * t + 0.5)}


def _pile(t):
    s = t / PERIOD
    return {"tip_y": -10.0 + 2.5 * s, "tip_z": 0.5 - 1.3 * np.sin(np.pi * s),
            "bucket_angle": 2.3 - 1.2 * s, "dump": (s > 0.9).astype(float)}


SERIES = {"HydraulicCylinder": _cylinder, "IdealActuator": _cylinder, "Pile": _pile,
          "PileZelenin": _pile}


def _simulate(fmu, series):
    t = np.arange(0.0, PERIOD + STEP / 2, STEP)
    values = series(t)
    signals = np.zeros(len(t), dtype=[("time", float)] + [(k, float) for k in values])
    signals["time"] = t
    for key, column in values.items():
        signals[key] = column
    start = {key: float(column[0]) for key, column in values.items()}
    return simulate_fmu(str(fmu), stop_time=PERIOD, step_size=STEP, output_interval=STEP,
                        input=signals, start_values=start)


@pytest.fixture(scope="module", params=sorted(SERIES))
def builds(request):
    name = request.param
    return name, fmus.build(name), fmus.build(name, fmi_version=3)


def test_fmi3_build_is_valid_and_cached_separately(builds):
    name, fmu2, fmu3 = builds
    assert fmu3 != fmu2 and "fmi3" in fmu3.parts  # packaged (_built/fmi3) or cached (fmi3/...)
    assert validate_fmu(str(fmu3)) == []
    d2, d3 = read_model_description(str(fmu2)), read_model_description(str(fmu3))
    assert (d2.fmiVersion, d3.fmiVersion) == ("2.0", "3.0")
    assert d3.instantiationToken != d2.guid  # the version is part of the content hash
    assert f"binaries/{platform_folder(3)}/{name}.so" in zipfile.ZipFile(fmu3).namelist()
    assert fmus.build(name, fmi_version=3).read_bytes() == fmu3.read_bytes()  # cache hit
    # The same table: value references, causality, variability, start and unit per variable.
    v2 = {v.name: v for v in d2.modelVariables}
    v3 = {v.name: v for v in d3.modelVariables if v.causality != "independent"}
    assert v2.keys() == v3.keys()
    for key, a in v2.items():
        b = v3[key]
        assert (a.valueReference, a.causality, a.variability, a.unit, a.start) == \
               (b.valueReference, b.causality, b.variability, b.unit, b.start), key
    assert {u.name for u in d2.unitDefinitions} <= {u.name for u in d3.unitDefinitions}


def test_fmi3_build_equals_the_fmi2_build(builds):
    name, fmu2, fmu3 = builds
    r2, r3 = _simulate(fmu2, SERIES[name]), _simulate(fmu3, SERIES[name])
    assert r2.dtype.names == r3.dtype.names and len(r2) == len(r3)
    moved = 0
    for key in r2.dtype.names:
        np.testing.assert_allclose(r3[key], r2[key], rtol=0, atol=1e-12, err_msg=key)
        moved += bool(np.ptp(r2[key]) > 0)
    assert moved > 1  # the inputs exercised the model


def test_fmi3_state_save_restore_and_serialization(builds, tmp_path):
    from fmpy import extract
    from fmpy.fmi3 import FMU3Slave

    name, _, fmu3 = builds
    description = read_model_description(str(fmu3))
    variables = {v.name: v.valueReference for v in description.modelVariables}
    inputs = [variables[k] for k in SERIES[name](np.zeros(1))]
    outputs = [v.valueReference for v in description.modelVariables if v.causality == "output"]
    slave = FMU3Slave(guid=description.instantiationToken, unzipDirectory=extract(str(fmu3)),
                      modelIdentifier=name, instanceName="a")
    slave.instantiate()
    slave.enterInitializationMode(startTime=0.0)
    slave.exitInitializationMode()
    t = np.arange(400) * STEP
    series = np.column_stack(list(SERIES[name](t + 0.3 * PERIOD).values()))

    def run(ks):
        rows = []
        for k in ks:
            slave.setFloat64(inputs, list(series[k]))
            slave.doStep(currentCommunicationPoint=k * STEP, communicationStepSize=STEP)
            rows.append(slave.getFloat64(outputs))
        return np.array(rows)

    run(range(200))
    state = slave.getFMUState()
    blob = slave.serializeFMUState(state)
    first = run(range(200, 400))
    slave.setFMUState(slave.deserializeFMUState(blob))
    second = run(range(200, 400))
    slave.terminate()
    slave.freeInstance()
    assert not np.array_equal(first[0], first[-1]) and np.array_equal(first, second)
