"""The HydraulicCylinder's regeneration passage (rod side -> piston side through a check, open
while the spool extends) against a flow balance worked by hand, and its energy and Jacobian
against the model's other checks.

Steady extension under a pulling load, without friction and make-up, spool a = 0.5 (rated flow
q per edge at dp_rated, meter-out ratio r, regeneration ratio g, square-root edges):

    piston side:  q a sqrt((p_S - p_A) / dp_rated) + g q a sqrt((p_B - p_A) / dp_rated) = A_A v
    rod side:     r q a sqrt((p_B - p_T) / dp_rated) + g q a sqrt((p_B - p_A) / dp_rated) = A_B v
    piston:       p_A A_A - p_B A_B = F_ext

three equations in p_A, p_B and v, solved here by scipy.optimize.fsolve from the law alone.
"""

import math

import numpy as np
import pytest
from cylinder_ode import reference_run
from cylinder_start import start_parameters
from scipy.optimize import fsolve
from test_cylinder_rodas3 import H, run

import fmus

SPOOL = 0.5
PULL_N = -15.0e3  # a pulling load (the stick's weight drawing it in) the pump keeps up with
STRONG_PULL_N = -60.0e3  # one it does not: the piston side needs the make-up's oil


@pytest.fixture(scope="module")
def fmu():
    return fmus.build("HydraulicCylinder")


def steady_state(par: dict, g: float) -> tuple[float, float, float]:
    """(p_A Pa, p_B Pa, v m/s) of the balance in the module docstring."""
    q, dp, r = par["q_rated"] * SPOOL, par["dp_rated"], par["meter_out_ratio"]
    p_S, p_T, A_A, A_B = par["p_supply"], par["p_tank"], par["A_A"], par["A_B"]

    def balance(unknowns):
        p_A, p_B, v = unknowns[0] * 1e6, unknowns[1] * 1e6, unknowns[2]
        regeneration = g * q * math.sqrt(max(p_B - p_A, 0.0) / dp)
        return [(q * math.sqrt(max(p_S - p_A, 0.0) / dp) + regeneration - A_A * v) / A_A,
                (r * q * math.sqrt(max(p_B - p_T, 0.0) / dp) + regeneration - A_B * v) / A_B,
                (p_A * A_A - p_B * A_B - PULL_N) / (A_A * 1e6)]

    p_A, p_B, v = fsolve(balance, [1.0, 5.0, 0.3], xtol=1e-13)
    assert np.max(np.abs(balance([p_A, p_B, v]))) < 1e-10
    return p_A * 1e6, p_B * 1e6, v


def steady_run(fmu, g: float, pull_n: float = PULL_N, k_makeup: float = 0.0,
               seconds: float = 1.2) -> dict:
    n = int(round(seconds / H))
    inputs = {"u": np.full(n, SPOOL), "F_ext": np.full(n, pull_n)}
    start = {"x0": 0.05, "integrator": 1, "tolerance": 1e-9, "regeneration_ratio": g,
             "F_coulomb": 0.0, "b_viscous": 0.0, "k_makeup": k_makeup, "mass": 50.0}
    return run(fmu, start, inputs)


@pytest.mark.parametrize("g", [0.5, 1.0])
def test_steady_extension_matches_the_hand_worked_flow_balance(fmu, g):
    par = start_parameters(fmu)
    p_A, p_B, v = steady_state(par, g)
    assert p_B > p_A + par["dp_laminar"]  # the check is open, on the square-root law
    assert p_A > par["dp_laminar"] and p_B - par["p_tank"] > par["dp_laminar"]
    out = steady_run(fmu, g)
    assert out["x"][-1] < 0.9 * par["stroke"]  # still moving, off the stop
    assert out["v"][-1] == pytest.approx(v, rel=1e-6)
    assert out["p_A"][-1] == pytest.approx(p_A, rel=1e-6)
    assert out["p_B"][-1] == pytest.approx(p_B, rel=1e-6)
    # The rod side's oil that went to the piston side, from the balance and from the run.
    regeneration = g * par["q_rated"] * SPOOL * math.sqrt((p_B - p_A) / par["dp_rated"])
    assert regeneration / (par["A_B"] * v) > 0.2  # a real share of the return regenerates
    q_pump = par["q_rated"] * SPOOL * math.sqrt((par["p_supply"] - out["p_A"][-1])
                                                / par["dp_rated"])
    assert par["A_A"] * out["v"][-1] - q_pump == pytest.approx(regeneration, rel=1e-5)


def test_a_strong_pull_needs_the_make_up_sized_for_the_pump(fmu):
    """Regeneration alone does not keep the piston side full under a strong pull: the rod
    side's oil then has two ways out and the piston runs faster still (the balance above has no
    solution with p_A >= 0), and without a make-up check the piston side is a void. The check
    sized for the pump's flow (the paper machine's 3e-8 m^3/(s Pa), plant_models.hydraulics)
    holds it above 0 Pa."""
    for g in (0.0, 0.5):
        assert np.mean(steady_run(fmu, g, STRONG_PULL_N)["p_A"][20:] <= 0.0) > 0.9
        assert np.all(steady_run(fmu, g, STRONG_PULL_N, 3.0e-8)["p_A"][20:] > 0.0)


def test_regeneration_under_radau_and_the_energy_balance(fmu):
    """The same law written in Python (tests/cylinder_ode.py) under Radau, through the
    passage's opening and closing (the load turns from pulling to pushing), and the energy
    outputs' balance with the passage's throttling in E_throttling."""
    n = 150
    t = np.arange(n) * H
    inputs = {"u": np.where(t < 1.2, SPOOL, -0.3),
              "F_ext": PULL_N + 1.5e5 * np.clip(t - 0.4, 0.0, 0.4)}
    par = {**start_parameters(fmu), "regeneration_ratio": 1.0}
    reference = reference_run(par, 0.05, inputs, H)
    out = run(fmu, {"x0": 0.05, "integrator": 1, "tolerance": 1e-8,
                    "regeneration_ratio": 1.0}, inputs)
    assert np.max(np.abs(out["x"] - reference[:, 0])) < 1e-6
    for i, port in ((2, "p_A"), (3, "p_B")):
        assert np.max(np.abs(out[port] - reference[:, i])) < 0.01e5  # 0.01 bar
    balance = (out["E_supply"] + out["E_mass_load"] - out["E_tank"] - out["E_throttling"]
               - out["E_relief"] - out["E_friction"] - out["E_load"] - out["E_end_stop"]
               - (out["E_stored"] - out["E_stored"][0]))
    # from the first step on (E_stored(0) is the state before it): the balance holds
    assert np.ptp(balance) < 1e-6 * np.max(out["E_supply"])
