"""FastSlave's step as one foreign call (fmus/fast_step/fmi2_step.c, fmi3_step.c) against the
three calls it replaces: the same outputs bit for bit, step after step, for a cylinder and the
pile, FMI 2.0 and 3.0; the same error naming the failing call and the FMU's reason."""

import numpy as np
import pytest
from faulty_fmus import FAIL, patched_cylinder
from test_hydraulic_cylinder_energy import varied_inputs

import fmus
from fmus import fast_step
from fmus.runs import FastSlave

H = 0.01


def stepped(fmu, inputs: dict, outputs: list[str], one_call: bool, start: dict) -> np.ndarray:
    names = list(inputs)
    matrix = np.column_stack([inputs[n] for n in names])
    FastSlave.one_call = one_call
    try:
        with FastSlave(fmu, names, outputs, {**{n: float(inputs[n][0]) for n in names},
                                             **start}) as slave:
            assert (getattr(slave, "_fast", None) is not None) == one_call
            return np.array([slave.step(k * H, H, matrix[k]).copy()
                             for k in range(len(matrix))])
    finally:
        FastSlave.one_call = True


def test_the_library_is_built_here():
    assert fast_step.library() is not None  # gcc builds the FMUs, so it builds this too


@pytest.mark.parametrize("fmi_version", [2, 3])
@pytest.mark.parametrize("model", ["HydraulicCylinder", "Pile"])
def test_one_call_gives_the_three_calls_bits(model, fmi_version):
    fmu = fmus.build(model, fmi_version=fmi_version)
    if model == "HydraulicCylinder":
        inputs = {name: values[::10] for name, values in varied_inputs(8000).items()}
        outputs, start = ["x", "v", "p_A", "p_B", "F", "E_supply"], {"x0": 0.4}
    else:
        t = np.arange(600) * H
        inputs = {"tip_y": -9.0 + 0.3 * t, "tip_z": -0.4 * np.sin(np.pi * t / 6.0),
                  "bucket_angle": np.full(600, 0.6), "dump": (t > 5.5).astype(float)}
        outputs, start = ["bucket_mass", "F_y", "F_z", "pile_mass"], {}
    one = stepped(fmu, inputs, outputs, True, start)
    three = stepped(fmu, inputs, outputs, False, start)
    assert np.array_equal(one, three)
    assert np.ptp(one, axis=0).max() > 0.0  # the model moved


@pytest.mark.parametrize("one_call", [True, False])
def test_a_failing_step_names_the_call_and_the_fmus_reason(tmp_path, one_call):
    fmu = patched_cylinder(tmp_path, FAIL, 0.05, "Burst")
    inputs = {"u": np.full(20, 0.5), "F_ext": np.zeros(20)}
    with pytest.raises(RuntimeError, match=r"fmi2DoStep failed at t = 0\.05.*a burst hose"):
        stepped(fmu, inputs, ["x"], one_call, {"x0": 0.4})
