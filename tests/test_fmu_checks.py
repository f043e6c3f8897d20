"""Checks every FMU in fmus.MODELS must pass: FMI validation, exact state save/restore and
serialization, independent instances, and agreement with a second co-simulation master (ecos)."""

import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.validation import validate_fmu

import fmus
from fmus.ecos_runs import run_ecospy
from fmus.runs import FastSlave, run_fmpy

N_STEPS = 1000


def _hydraulic_cylinder(t: np.ndarray) -> dict[str, np.ndarray]:
    # Spool swings through both directions and saturates; the load swings both ways.
    return {"u": np.clip(1.5 * np.sin(2 * np.pi * 1.1 * t), -1, 1),
            "F_ext": 1.2e5 * np.sin(2 * np.pi * 0.6 * t + 0.5)}


def _pile(t: np.ndarray) -> dict[str, np.ndarray]:
    # The bucket tip sweeps towards the machine through the ground and back out, then dumps.
    s = t / t[-1]
    return {"tip_y": -10.0 + 2.5 * s, "tip_z": 0.5 - 1.3 * np.sin(np.pi * s),
            "bucket_angle": 2.3 - 1.2 * s, "dump": (s > 0.9).astype(float)}


SERIES = {"HydraulicCylinder": _hydraulic_cylinder, "Pile": _pile}


class Case:
    """An FMU with an input series (one sample per step) and all its Real outputs."""

    def __init__(self, name: str):
        self.name = name
        self.fmu = fmus.build(name)
        self.description = read_model_description(str(self.fmu))
        experiment = self.description.defaultExperiment
        self.step = float(experiment.stepSize) if experiment and experiment.stepSize else 1e-3
        t = np.arange(N_STEPS) * self.step
        variables = self.description.modelVariables
        if name in SERIES:
            self.inputs = SERIES[name](t)
        else:  # any other model: wiggle every Real input around its start value
            self.inputs = {v.name: float(v.start) + 0.1 * (1 + abs(float(v.start)))
                           * np.sin(2 * np.pi * 0.5 * t)
                           for v in variables if v.causality == "input" and v.type == "Real"}
        self.outputs = [v.name for v in variables if v.causality == "output" and v.type == "Real"]
        self.matrix = np.column_stack(list(self.inputs.values()))

    def slave(self) -> FastSlave:
        start = {k: s[0] for k, s in self.inputs.items()}
        return FastSlave(self.fmu, list(self.inputs), self.outputs, start)

    def steps(self, slave: FastSlave, ks: range) -> np.ndarray:
        return np.array([slave.step(k * self.step, self.step, self.matrix[k]).copy() for k in ks])


@pytest.fixture(scope="module", params=fmus.MODELS)
def case(request):
    return Case(request.param)


def test_fmu_passes_fmpy_validation(case):
    assert validate_fmu(str(case.fmu)) == []


def test_restored_state_continues_identically(case):
    half = N_STEPS // 2
    with case.slave() as slave:
        case.steps(slave, range(half))
        state = slave.slave.getFMUstate()
        serialized = slave.slave.serializeFMUstate(state)
        first = case.steps(slave, range(half, N_STEPS))
        slave.slave.setFMUstate(state)
        slave.slave.freeFMUstate(state)
        second = case.steps(slave, range(half, N_STEPS))
    assert not np.array_equal(first[0], first[-1])  # the model moved after the save point
    assert np.array_equal(first, second)

    with case.slave() as fresh:  # a new instance, initialized at the start values
        state = fresh.slave.deSerializeFMUstate(serialized)
        fresh.slave.setFMUstate(state)
        fresh.slave.freeFMUstate(state)
        third = case.steps(fresh, range(half, N_STEPS))
    assert np.array_equal(first, third)


def test_instances_sharing_one_binary_are_independent(case, tmp_path):
    """Two instances of one unzipped FMU (one dlopen handle) stepped in turns, with different
    inputs, give the same outputs as each run alone."""
    unzip_dir = extract(str(case.fmu), unzipdir=str(tmp_path / "fmu"))
    n = N_STEPS // 4
    series = {"a": case.matrix, "b": case.matrix[::-1].copy()}  # b: the series backwards

    def open_slave(key, **kwargs):
        start = dict(zip(case.inputs, series[key][0], strict=True))
        return FastSlave(case.fmu, list(case.inputs), case.outputs, start, **kwargs)

    def step(slave, key, k):
        return slave.step(k * case.step, case.step, series[key][k]).copy()

    alone = {}
    for key in series:
        with open_slave(key) as slave:
            alone[key] = np.array([step(slave, key, k) for k in range(n)])
    together = {"a": [], "b": []}
    with open_slave("a", unzip_dir=unzip_dir) as a, open_slave("b", unzip_dir=unzip_dir) as b:
        for k in range(n):
            together["a"].append(step(a, "a", k))
            together["b"].append(step(b, "b", k))
    assert not np.array_equal(alone["a"], alone["b"])
    for key in series:
        assert np.array_equal(np.array(together[key]), alone[key])


def test_ecos_master_gives_the_same_outputs(case):
    ours = run_fmpy(case.fmu, case.inputs, case.outputs, case.step)
    peer = run_ecospy(case.fmu, case.inputs, case.outputs, case.step)
    moved = [name for name in case.outputs if np.ptp(ours[name]) > 0]
    assert moved  # the series exercised the model
    for name in case.outputs:
        np.testing.assert_allclose(peer[name], ours[name], rtol=1e-9, atol=1e-9, err_msg=name)
