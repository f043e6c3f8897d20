"""IdealActuator (fmus/IdealActuator): first-order velocity servo against its closed form,
end stops, the reported load, the valid parameter range and the cylinder role it fills."""

import numpy as np
import pytest
from fmpy import read_model_description, simulate_fmu
from fmpy.fmi1 import FMICallException
from fmpy.validation import validate_fmu

import fmus
from fmus.runs import run_fmpy
from plant_models.model_spec import CYLINDER_INPUTS, CYLINDER_OUTPUTS

V_MAX, TAU, STROKE = 0.3, 0.05, 1.3  # the defaults in variables.toml


@pytest.fixture(scope="module")
def fmu():
    return fmus.build("IdealActuator")


def run(fmu, u, load=None, step=1e-3, start=None):
    u = np.asarray(u, dtype=float)
    load = np.zeros_like(u) if load is None else np.asarray(load, dtype=float)
    return run_fmpy(fmu, {"u": u, "F_ext": load}, ["x", "v", "F"], step, start)


def test_valid_fmu_with_the_cylinder_interface_except_pressures(fmu):
    assert validate_fmu(str(fmu)) == []
    variables = {v.name: v for v in read_model_description(str(fmu)).modelVariables}
    assert all(variables[n].causality == "input" for n in ("u", "F_ext"))
    # Optional: a velocity servo takes no load mass and no oil from a shared pump.
    assert set(CYLINDER_INPUTS) - set(variables) == {"mass_load", "p_pump", "p_LS"}
    assert {"x", "v", "F"} <= {n for n, v in variables.items() if v.causality == "output"}
    # No chambers, so no pressures and no oil energies: those roles are honestly missing.
    assert set(CYLINDER_OUTPUTS) - set(variables) == {"p_A", "p_B", "E_supply", "E_throttling"}
    assert variables["stroke"].causality == variables["x0"].causality == "parameter"


@pytest.mark.parametrize("u, step", [(1.0, 1e-3), (-0.4, 1e-3), (0.7, 0.037)])
def test_step_response_is_the_exact_first_order_solution(fmu, u, step):
    n = int(round(0.4 / step))
    r = run(fmu, np.full(n, u), step=step)
    t = np.arange(n + 1) * step
    w = u * V_MAX
    np.testing.assert_allclose(r["v"], w * (1 - np.exp(-t / TAU)), rtol=0, atol=1e-14)
    x = 0.65 + w * (t - TAU * (1 - np.exp(-t / TAU)))
    np.testing.assert_allclose(r["x"], x, rtol=0, atol=1e-13)


def test_full_command_is_accepted_and_one_outside_its_range_refused(fmu, capfd):
    r = run(fmu, np.full(500, -1.0))
    assert r["v"][-1] == pytest.approx(-V_MAX * (1 - np.exp(-0.5 / TAU)), rel=1e-12)
    with pytest.raises(FMICallException, match="fmi2SetReal"):
        run(fmu, np.full(5, 1.0 + 1e-9))
    assert "value of 'u' lies outside its range [-1, 1]" in capfd.readouterr().out


def test_end_stops_are_inelastic_and_hold(fmu):
    # Full speed out: x reaches the stroke end, stays there at v = 0; then retracts from rest.
    u = np.r_[np.ones(3000), -np.ones(500)]
    r = run(fmu, u, step=1e-3, start={"x0": 1.2})
    assert r["x"].max() == STROKE and r["x"].min() >= 0.0
    held = slice(1000, 3001)
    assert np.all(r["x"][held] == STROKE) and np.all(r["v"][held] == 0.0)
    # Leaving the stop restarts the exact lag from rest.
    t = np.arange(1, 501) * 1e-3
    np.testing.assert_allclose(r["v"][3001:], -V_MAX * (1 - np.exp(-t / TAU)), atol=1e-14)
    # Bottom stop, hit within one long step: clamped exactly to 0.
    r = run(fmu, -np.ones(20), step=0.1, start={"x0": 0.1})
    assert r["x"][-1] == 0.0 and r["v"][-1] == 0.0 and r["x"].min() == 0.0


def test_crossing_inside_a_step_lands_on_the_stop_at_the_right_time(fmu):
    # From x0 = 1.25 at full speed the stroke end (5 cm away) is reached at t_hit; a single step
    # of 1 s ends there with v = 0, as does a fine-stepped run.
    coarse = run(fmu, [1.0], step=1.0, start={"x0": 1.25})
    fine = run(fmu, np.ones(1000), step=1e-3, start={"x0": 1.25})
    assert coarse["x"][-1] == fine["x"][-1] == STROKE
    assert coarse["v"][-1] == fine["v"][-1] == 0.0


def test_load_is_reported_and_does_not_change_the_motion(fmu):
    t = np.arange(800) * 1e-3
    u = np.sin(2 * np.pi * t)
    load = 1e5 * np.cos(3 * t)
    free, loaded = run(fmu, u), run(fmu, u, load)
    assert np.array_equal(free["x"], loaded["x"]) and np.array_equal(free["v"], loaded["v"])
    np.testing.assert_array_equal(loaded["F"][1:], load)


@pytest.mark.parametrize("name, value", [("tau", 0.0), ("v_max", 0.0), ("stroke", 0.0),
                                         ("x0", 1.5)])
def test_invalid_parameters_fail_initialization(fmu, name, value):
    with pytest.raises(FMICallException, match="fmi2ExitInitializationMode"):
        simulate_fmu(str(fmu), stop_time=0.01, start_values={name: value})


@pytest.mark.parametrize("name, value", [("v_max", -1.0), ("x0", -0.1), ("tau", 1e4),
                                         ("F_ext", 2e9)])
def test_values_outside_the_table_range_are_refused_when_set(fmu, name, value):
    with pytest.raises(FMICallException, match="fmi2SetReal"):
        simulate_fmu(str(fmu), stop_time=0.01, start_values={name: value})
