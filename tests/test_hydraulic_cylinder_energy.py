"""HydraulicCylinder's energy outputs: the balance over a long varied run, and each term against
powers worked out here from continuity, the force balance and the trapped-oil law.

Balance (fmus/HydraulicCylinder/model.c):
    E_supply + E_mass_load = E_tank + E_throttling + E_relief + E_friction + E_load
                             + E_end_stop + E_stored - E_stored(0)
Every power is integrated with the RK4 stage weights, and the stage powers balance exactly
(p*Q telescopes edge by edge into the piston's F*dx, which splits into load, friction, kinetic
and end-stop power), so the balance holds but for one term: the stored kinetic energy is
M*v^2/2 of RK4's v, not the RK4 quadrature of M*v*dv/dt. Per substep the two differ by
(M h^2/6)(d1 d2 + d2 d3 + d3 d4), d_i the stage accelerations' deviations from their weighted
mean: RK4's local error, O(h^5) where the motion is smooth. So the residual must be small and
shrink like h^4 when the substep is halved; a bookkeeping error would not shrink at all.
"""

import math

import numpy as np
import pytest
from cylinder_start import start_parameters

import fmus
from fmus.runs import run_fmpy

H = 1e-3
ENERGIES = ["E_supply", "E_tank", "E_throttling", "E_relief", "E_friction", "E_load",
            "E_end_stop", "E_mass_load", "E_stored"]
OUTPUTS = ["x", "v", "p_A", "p_B", "F"] + ENERGIES


@pytest.fixture(scope="module")
def fmu():
    return fmus.build("HydraulicCylinder")


@pytest.fixture(scope="module")
def par(fmu):
    return start_parameters(fmu)


def residual(r):
    """supply + mass change - everything it went to, J, per sample."""
    spent = (r["E_tank"] + r["E_throttling"] + r["E_relief"] + r["E_friction"] + r["E_load"]
             + r["E_end_stop"] + r["E_stored"] - r["E_stored"][0])
    return r["E_supply"] + r["E_mass_load"] - spent


def varied_inputs(n):
    """8 s: spool swings, loads both ways, a closed valve under an overrunning 300 kN pull (the
    rod side over its relief, the piston side cavitating), 500 kN above supply pressure (the
    load-holding checks), the top end stop, and a reflected mass swinging 0..1600 kg."""
    t = np.arange(n) * H
    u = np.clip(1.6 * np.sin(2 * np.pi * 0.45 * t) + 0.3 * np.sin(2 * np.pi * 2.3 * t), -1, 1)
    u[(t > 3.0) & (t < 3.8)] = 0.0
    load = 1.5e5 * np.sin(2 * np.pi * 0.35 * t + 0.4)
    load[(t > 3.0) & (t < 3.4)] = -3.0e5
    load[(t > 5.0) & (t < 5.6)] = 5.0e5
    mass_load = 400.0 * (1 + np.sin(2 * np.pi * 0.8 * t)) ** 2
    return {"u": u, "F_ext": load, "mass_load": mass_load}


def test_energy_balance_closes_to_the_rk4_error(fmu, par):
    """Measured: residual -8.2e-4 J at 10 substeps per 1 ms step (h = 0.1 ms) against 5.9e5 J
    supplied (1.4e-9 of it), -5.6e-5 J at 20 substeps (a factor 14.6: fourth order)."""
    n = 8000
    inputs = varied_inputs(n)
    runs = {n_sub: run_fmpy(fmu, inputs, OUTPUTS, H, {"x0": 0.4, "n_substeps": n_sub})
            for n_sub in (10, 20)}
    r = runs[10]
    # The run has every kind of event.
    assert r["E_relief"][-1] > 1e4 and r["E_end_stop"][-1] > 10.0
    assert np.sum(r["p_A"] == 0.0) > 100 and np.sum(r["p_B"] == 0.0) > 100  # cavitation
    makeup_open = par["p_tank"] - par["dp_makeup"]
    assert np.sum((r["p_A"] > 0.0) & (r["p_A"] < makeup_open)) > 10
    u = np.concatenate([[inputs["u"][0]], inputs["u"]])
    assert np.sum((u > 0) & (r["p_A"] > par["p_supply"])) > 100  # the P->A check closed
    assert abs(r["E_mass_load"][-1]) > 100.0
    # Losses are losses.
    for name in ("E_supply", "E_throttling", "E_relief", "E_friction", "E_end_stop"):
        assert np.all(np.diff(r[name]) >= -1e-9 * r["E_supply"][-1]), name
    throughput = sum(abs(r[name][-1]) for name in ENERGIES)
    coarse, fine = (np.max(np.abs(residual(runs[k]))) for k in (10, 20))
    assert coarse < 1e-8 * throughput
    assert fine < coarse / 8  # RK4's h^4 (16x); an error in the bookkeeping would not shrink


def test_steady_extension_powers(fmu, par):
    """u = 1 against 100 kN at constant speed: A takes A_A*v from the supply at p_S, B sends
    A_B*v to tank; each edge throttles dp*Q; friction (F_c tanh(v/v_c) + b v) v; load F v."""
    n = 1000
    r = run_fmpy(fmu, {"u": np.ones(n), "F_ext": np.full(n, 1.0e5)}, OUTPUTS, H, {"x0": 0.2})
    tail = slice(-101, None)
    v, p_A, p_B = (np.mean(r[k][tail]) for k in ("v", "p_A", "p_B"))
    assert np.ptp(r["v"][tail]) < 1e-6 * v  # steady
    Q_A, Q_B = par["A_A"] * v, par["A_B"] * v
    p_S, p_T = par["p_supply"], par["p_tank"]
    friction = par["F_coulomb"] * math.tanh(v / par["v_coulomb"]) + par["b_viscous"] * v
    expected = {"E_supply": p_S * Q_A, "E_tank": p_T * Q_B,
                "E_throttling": (p_S - p_A) * Q_A + (p_B - p_T) * Q_B,
                "E_friction": friction * v, "E_load": 1.0e5 * v, "E_relief": 0.0,
                "E_end_stop": 0.0, "E_mass_load": 0.0, "E_stored": 0.0}
    duration = 100 * H
    for name, power in expected.items():
        measured = (r[name][-1] - r[name][-101]) / duration
        assert measured == pytest.approx(power, rel=1e-5, abs=1e-6 * p_S * Q_A), name


def test_relief_and_end_stop_losses(fmu, par):
    """u = 1 with a 42 MPa supply, above the 35 MPa relief, into the top stop: the stop takes
    the piston's kinetic energy M v^2/2 on impact; then all the edge's flow leaves through A's
    relief, Q = k_relief*(p_A - p_relief) (and also Q = q_rated*sqrt((p_S - p_A)/dp_rated),
    the edge's law), so the supply's p_S*Q splits into edge throttling (p_S - p_A)*Q, relief
    loss (p_A - p_T)*Q and tank p_T*Q."""
    n, p_S = 1500, 1.2 * par["p_relief"]
    r = run_fmpy(fmu, {"u": np.ones(n), "F_ext": np.zeros(n)}, OUTPUTS, H,
                 {"x0": 1.1, "p_supply": p_S})
    hit = int(np.argmax(r["x"] == par["stroke"]))
    assert 0 < hit < n - 500
    kinetic = 0.5 * par["mass"] * r["v"][hit - 1] ** 2
    assert r["E_end_stop"][hit] - r["E_end_stop"][hit - 1] == pytest.approx(kinetic, rel=0.05)
    assert r["E_end_stop"][-1] == r["E_end_stop"][hit + 10]  # resting on the stop: no more
    p_A = r["p_A"][-1]
    Q = par["k_relief"] * (p_A - par["p_relief"])
    assert Q == pytest.approx(par["q_rated"] * math.sqrt((p_S - p_A) / par["dp_rated"]),
                              rel=1e-6)
    duration = 100 * H
    for name, power in {"E_supply": p_S * Q, "E_throttling": (p_S - p_A) * Q,
                        "E_relief": (p_A - par["p_tank"]) * Q, "E_tank": par["p_tank"] * Q,
                        "E_friction": 0.0, "E_load": 0.0, "E_stored": 0.0}.items():
        measured = (r[name][-1] - r[name][-101]) / duration
        assert measured == pytest.approx(power, rel=1e-6, abs=1e-9 * p_S * Q), name


def _trapped_work(V0, p0, p1, beta):
    """Compression work on trapped oil taken from p0 to p1, J: the integral of p dV_oil with
    dV_oil = V dp/beta and V = V0*exp(-(p - p0)/beta) (dp = -beta dV/V)."""
    def antiderivative(p):  # of p*V0*exp(-(p - p0)/beta)/beta
        return -V0 * math.exp(-(p - p0) / beta) * (p + beta)
    return antiderivative(p1) - antiderivative(p0)


def test_trapped_oil_stores_its_compression_work(fmu, par):
    """u = 0, no make-up valve, a 150 kN push: A's trapped oil is compressed until it carries
    the load, B's expands to 0 and cavitates; the piston rings down to rest. The change of
    E_stored is the compression work along each chamber's trapped-oil law (independent of the
    path, as V is a function of p), the load's work is F times the stroke change, and the
    friction took the rest: no supply, relief or stop."""
    n, load = 1500, 1.5e5
    F_ext = np.full(n, load)
    F_ext[:50] = 0.0
    r = run_fmpy(fmu, {"u": np.zeros(n), "F_ext": F_ext}, OUTPUTS, H,
                 {"x0": 0.65, "k_makeup": 0.0})
    assert abs(r["v"][-1]) < 1e-9 and r["p_B"][-1] == 0.0
    beta, x0 = par["beta"], 0.65
    V_A0 = par["V_dead_A"] + par["A_A"] * x0
    V_B0 = par["V_dead_B"] + par["A_B"] * (par["stroke"] - x0)
    stored = (_trapped_work(V_A0, r["p_A"][0], r["p_A"][-1], beta)
              + _trapped_work(V_B0, r["p_B"][0], 0.0, beta))
    assert r["E_stored"][-1] - r["E_stored"][0] == pytest.approx(stored, rel=1e-5)  # 1.2e-6
    # E_stored(0) is V*p^2/(2 beta) of the start pressures.
    assert r["E_stored"][0] == pytest.approx(
        (V_A0 * r["p_A"][0] ** 2 + V_B0 * r["p_B"][0] ** 2) / (2 * beta), rel=1e-12)
    assert r["E_load"][-1] == pytest.approx(load * (r["x"][-1] - x0), rel=1e-9)
    for name in ("E_supply", "E_relief", "E_end_stop", "E_throttling", "E_tank"):
        assert r[name][-1] == 0.0, name
    assert r["E_friction"][-1] > 0.0
    assert abs(residual(r)[-1]) < 1e-7 * abs(r["E_load"][-1])  # 1.9e-5 J of 1008 J
