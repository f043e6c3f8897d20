"""FastSlave's step as one foreign call (fmus/fast_step/fmi2_step.c, fmi3_step.c) against the
three calls it replaces, and FastSlave.run's n steps in one call (steps.c) against n steps from
Python: the same outputs bit for bit, step after step, for a cylinder and the pile, FMI 2.0 and
3.0; the same error naming the failing call, its time and the FMU's reason."""

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


def model_case(model: str) -> tuple[dict, list[str], dict]:
    """(inputs by name (n,), outputs, start values) that move the model through its range."""
    if model == "HydraulicCylinder":
        inputs = {name: values[::10] for name, values in varied_inputs(8000).items()}
        return inputs, ["x", "v", "p_A", "p_B", "F", "E_supply"], {"x0": 0.4}
    t = np.arange(600) * H
    inputs = {"tip_y": -9.0 + 0.3 * t, "tip_z": -0.4 * np.sin(np.pi * t / 6.0),
              "bucket_angle": np.full(600, 0.6), "dump": (t > 5.5).astype(float)}
    return inputs, ["bucket_mass", "F_y", "F_z", "pile_mass"], {}


def test_the_library_is_built_here():
    assert fast_step.library() is not None  # gcc builds the FMUs, so it builds this too


@pytest.mark.parametrize("fmi_version", [2, 3])
@pytest.mark.parametrize("model", ["HydraulicCylinder", "Pile"])
def test_one_call_gives_the_three_calls_bits(model, fmi_version):
    fmu = fmus.build(model, fmi_version=fmi_version)
    inputs, outputs, start = model_case(model)
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


def ran(fmu, inputs: dict, outputs: list[str], start: dict, one_call: bool = True) -> np.ndarray:
    names = list(inputs)
    FastSlave.one_call = one_call
    try:
        with FastSlave(fmu, names, outputs, {**{n: float(inputs[n][0]) for n in names},
                                             **start}) as slave:
            assert (slave.native_step is not None) == one_call
            return slave.run(np.column_stack([inputs[n] for n in names]), H)
    finally:
        FastSlave.one_call = True


@pytest.mark.parametrize("fmi_version", [2, 3])
@pytest.mark.parametrize("model", ["HydraulicCylinder", "Pile"])
def test_run_in_one_call_gives_the_steps_bits(model, fmi_version):
    fmu = fmus.build(model, fmi_version=fmi_version)
    inputs, outputs, start = model_case(model)
    in_c = ran(fmu, inputs, outputs, start)
    assert np.array_equal(in_c, stepped(fmu, inputs, outputs, True, start))
    assert np.array_equal(in_c, ran(fmu, inputs, outputs, start, one_call=False))


@pytest.mark.parametrize("one_call", [True, False])
def test_a_failing_step_in_a_run_names_the_call_its_time_and_the_reason(tmp_path, one_call):
    fmu = patched_cylinder(tmp_path, FAIL, 0.05, "Burst")
    inputs = {"u": np.full(20, 0.5), "F_ext": np.zeros(20)}
    with pytest.raises(RuntimeError, match=r"^instance \(HydraulicCylinder\): fmi2DoStep failed at "
                                           r"t = 0\.05: .*a burst hose"):
        ran(fmu, inputs, ["x"], {"x0": 0.4}, one_call)


def test_a_run_refuses_inputs_of_another_shape():
    with FastSlave(fmus.build("HydraulicCylinder"), ["u", "F_ext"], ["x"]) as slave, \
            pytest.raises(ValueError, match=r"inputs must be \(n, 2\)"):
        slave.run(np.zeros((5, 3)), H)


def test_a_closed_instance_refuses_a_run():
    slave = FastSlave(fmus.build("HydraulicCylinder"), ["u", "F_ext"], ["x"])
    slave.close()
    assert slave.native_step is None
    with pytest.raises(RuntimeError, match="closed"):
        slave.run(np.zeros((5, 2)), H)
