"""HydraulicCylinder FMU against hydraulics worked out here by hand, run through fmpy.

The references below are derived from the orifice law, the force balance and the oil's bulk
modulus with the parameters read from the FMU's modelDescription; none of them comes from the
C code.
"""

import math

import numpy as np
import pytest
from fmpy import read_model_description

import fmus
from fmus.runs import FastSlave, run_fmpy

OUTPUTS = ["x", "v", "p_A", "p_B", "F"]
H = 1e-3  # communication step, s


@pytest.fixture(scope="module")
def fmu():
    return fmus.build("HydraulicCylinder")


@pytest.fixture(scope="module")
def par(fmu):
    """Start values of the parameters, plus the piston and annulus areas."""
    values = {v.name: float(v.start) for v in read_model_description(str(fmu)).modelVariables
              if v.causality == "parameter"}
    values["A_A"] = math.pi / 4 * values["bore"] ** 2
    values["A_B"] = math.pi / 4 * (values["bore"] ** 2 - values["rod"] ** 2)
    return values


def run(fmu, u, F_ext, step=H, **start):
    u = np.asarray(u, dtype=float)
    F_ext = np.broadcast_to(np.asarray(F_ext, dtype=float), u.shape)
    return run_fmpy(fmu, {"u": u, "F_ext": F_ext}, OUTPUTS, step, start)


def steady_state(par, u, F_ext):
    """Steady velocity and chamber pressures of the unobstructed cylinder, from first principles.

    With opening a = |u| the edge conductance is k = q_rated*a/sqrt(dp_rated), so an edge passing
    Q drops dp = (Q/k)^2. Extending (u > 0): Q_A = A_A*v enters from supply, Q_B = A_B*v leaves
    to tank, so p_A = p_S - (A_A v/k)^2 and p_B = p_T + (A_B v/k)^2. The force balance
    p_A*A_A - p_B*A_B = F_ext + F_c + b*v (tanh(v/v_c) = 1 at these speeds) then gives
        (A_A^3 + A_B^3)/k^2 * v^2 + b*v - (p_S*A_A - p_T*A_B - F_ext - F_c) = 0.
    Retracting (u < 0) with w = -v: p_B = p_S - (A_B w/k)^2, p_A = p_T + (A_A w/k)^2 and
        (A_A^3 + A_B^3)/k^2 * w^2 + b*w - (p_S*A_B - p_T*A_A + F_ext - F_c) = 0.
    """
    A_A, A_B, p_S, p_T = par["A_A"], par["A_B"], par["p_supply"], par["p_tank"]
    k2 = (par["q_rated"] * abs(u)) ** 2 / par["dp_rated"]
    c, b, F_c = (A_A**3 + A_B**3) / k2, par["b_viscous"], par["F_coulomb"]
    if u > 0:
        drive = p_S * A_A - p_T * A_B - F_ext - F_c
    else:
        drive = p_S * A_B - p_T * A_A + F_ext - F_c
    w = (-b + math.sqrt(b * b + 4 * c * drive)) / (2 * c)
    if u > 0:
        return w, p_S - (A_A * w) ** 2 / k2, p_T + (A_B * w) ** 2 / k2
    return -w, p_T + (A_A * w) ** 2 / k2, p_S - (A_B * w) ** 2 / k2


@pytest.mark.parametrize("u, F_ext", [(1.0, 0.0), (-1.0, 0.0), (0.5, 1.0e5), (-0.6, -5.0e4)])
def test_steady_velocity_and_pressures_follow_the_orifice_law(fmu, par, u, F_ext):
    v_ref, p_A_ref, p_B_ref = steady_state(par, u, F_ext)
    # The square-root law holds only outside the laminar region around dp = 0.
    edge_drops = [par["p_supply"] - p_A_ref, p_B_ref - par["p_tank"]] if u > 0 else \
        [par["p_supply"] - p_B_ref, p_A_ref - par["p_tank"]]
    assert min(edge_drops) > 10 * par["dp_laminar"]

    x0 = 0.2 if u > 0 else 1.1
    r = run(fmu, np.full(1000, u), F_ext, x0=x0)
    tail = slice(-100, None)
    assert np.mean(r["v"][tail]) == pytest.approx(v_ref, rel=0.02)
    assert np.mean(r["p_A"][tail]) == pytest.approx(p_A_ref, rel=0.02)
    assert np.mean(r["p_B"][tail]) == pytest.approx(p_B_ref, rel=0.02)
    # Newton at constant velocity: the hydraulic force carries the load plus the friction
    # F_c*tanh(v/v_c) + b*v, to within 1 % of that friction.
    v = r["v"][tail]
    friction = par["F_coulomb"] * np.tanh(v / par["v_coulomb"]) + par["b_viscous"] * v
    assert np.mean(r["F"][tail]) == pytest.approx(F_ext + np.mean(friction),
                                                  abs=0.01 * abs(np.mean(friction)))


@pytest.mark.parametrize("load", [1.5e5, -8.0e4])
def test_closed_valve_holds_a_load_step_with_the_pressure_that_balances_it(fmu, par, load):
    """u = 0 traps both chambers; a load step compresses one of them until it carries the load.

    Pushing (load > 0) the piston in compresses A and expands B; B drops to 0 (cavitation: the
    rod side opens a void) long before A carries the load, so at rest p_A*A_A = load exactly.
    The trapped oil obeys dp = -beta*dV/V, so A's volume shrinks to V_A0*exp(-(p_A - p_A0)/beta),
    which fixes where the piston comes to rest. A pulling load mirrors this on the rod side.
    """
    n = 1500
    F_ext = np.full(n, load)
    F_ext[:50] = 0.0
    r = run(fmu, np.zeros(n), F_ext, x0=0.65)
    assert abs(r["v"][-1]) < 1e-6 and abs(r["v"][-100]) < 1e-6  # at rest
    A_A, A_B, beta, stroke = par["A_A"], par["A_B"], par["beta"], par["stroke"]
    if load > 0:
        assert r["p_A"][-1] == pytest.approx(load / A_A, rel=0.01)
        assert r["p_B"][-1] < 1e-3 * r["p_A"][-1]
        V0 = par["V_dead_A"] + A_A * 0.65
        V = V0 * math.exp(-(r["p_A"][-1] - r["p_A"][0]) / beta)
        x_ref = (V - par["V_dead_A"]) / A_A
    else:
        assert r["p_B"][-1] == pytest.approx(-load / A_B, rel=0.01)
        assert r["p_A"][-1] < 1e-3 * r["p_B"][-1]
        V0 = par["V_dead_B"] + A_B * (stroke - 0.65)
        V = V0 * math.exp(-(r["p_B"][-1] - r["p_B"][0]) / beta)
        x_ref = stroke - (V - par["V_dead_B"]) / A_B
    assert r["x"][-1] - 0.65 == pytest.approx(x_ref - 0.65, rel=0.01)


def test_trapped_oil_is_conserved_through_cavitation(fmu, par):
    """u = 0 traps the oil in A. A 300 kN pull drives the rod side over its relief, the piston
    extends about 0.4 m and A cavitates (a void of several litres opens); a 20 kN push then
    drives it back. A's oil never left (A stays below its relief), so once the void is refilled
    and the piston rests, A obeys the trapped-chamber law V_A = V_A0*exp(-(p_A - p_A0)/beta)
    exactly as if the excursion had never happened."""
    n, x0 = 2500, 0.4
    F_ext = np.zeros(n)
    F_ext[50:200], F_ext[200:] = -3.0e5, 2.0e4
    r = run(fmu, np.zeros(n), F_ext, x0=x0)
    A_A = par["A_A"]
    assert r["x"].max() > x0 + 0.3 and np.sum(r["p_A"] == 0.0) > 100  # a long cavitated stroke
    assert r["p_B"].max() > par["p_relief"] and r["p_A"].max() < par["p_relief"]
    assert abs(r["v"][-1]) < 1e-6
    assert r["p_A"][-1] * A_A == pytest.approx(2.0e4, rel=1e-3)  # B is empty: p_B = 0
    V0 = par["V_dead_A"] + A_A * x0
    V = V0 * math.exp(-(r["p_A"][-1] - r["p_A"][0]) / par["beta"])
    x_ref = (V - par["V_dead_A"]) / A_A
    assert r["x"][-1] - x0 == pytest.approx(x_ref - x0, rel=1e-3)


@pytest.mark.parametrize("u", [1.0, -1.0])
@pytest.mark.parametrize("supply_over_relief", [None, 1.2])
def test_relief_caps_chamber_pressure_when_driven_into_an_end_stop(fmu, par, u,
                                                                    supply_over_relief):
    start = {"x0": 1.1 if u > 0 else 0.2}
    if supply_over_relief:  # without the relief the fed chamber would settle at p_supply
        start["p_supply"] = supply_over_relief * par["p_relief"]
    r = run(fmu, np.full(1500, u), 0.0, **start)
    fed = r["p_A"] if u > 0 else r["p_B"]
    assert r["x"][-1] == (par["stroke"] if u > 0 else 0.0)  # it did reach the stop
    assert fed.max() <= 1.05 * par["p_relief"]
    if supply_over_relief:
        assert fed.max() > par["p_relief"]  # the relief valve, not the supply, set the limit


def test_stroke_stays_within_the_end_stops(fmu, par):
    n = 5000
    t = np.arange(n) * H
    u = np.where(t < 2.0, 1.0, -1.0)
    load = 1e5 * np.sin(2 * np.pi * 0.7 * t)
    # A faster valve so that both stops are hit hard within 5 s.
    r = run(fmu, u, load, x0=0.2, q_rated=5e-3)
    x, stroke = r["x"], par["stroke"]
    assert x.min() >= 0.0 and x.max() <= stroke
    assert (x == stroke).sum() > 100 and (x == 0.0).sum() > 100  # both stops were reached
    assert np.all(r["v"][x == stroke] <= 0.0) and np.all(r["v"][x == 0.0] >= 0.0)


def test_10_and_100_substeps_agree(fmu):
    """Bang-bang spool and a swinging load, with cavitation episodes, over 2 s."""
    n = 2000
    t = np.arange(n) * H
    u = np.sign(np.sin(2 * np.pi * 1.3 * t)) * np.minimum(1.0, 3 * np.abs(np.sin(0.8 * np.pi * t)))
    load = 1.5e5 * np.sin(2 * np.pi * 0.9 * t)
    coarse = run(fmu, u, load, n_substeps=10)
    fine = run(fmu, u, load, n_substeps=100)
    assert np.max(np.abs(coarse["x"] - fine["x"])) < 1e-6
    assert np.ptp(fine["x"]) > 0.05  # the piston did travel


def test_hydraulic_natural_frequency(fmu, par):
    """Without friction, a small load step on the closed cylinder rings at the oil-spring
    frequency omega = sqrt(beta*(A_A^2/V_A + A_B^2/V_B)/mass) (Merritt's hydraulic natural
    frequency). A raised tank pressure keeps both chambers pressurized throughout."""
    step, n, x0 = 1e-4, 5000, 0.5
    load = np.full(n, 1.0e4)
    load[:10] = 0.0
    r = run(fmu, np.zeros(n), load, step=step, x0=x0, p_tank=5e6, F_coulomb=0.0, b_viscous=0.0)
    assert r["p_A"].min() > 1e6 and r["p_B"].min() > 1e6
    V_A = par["V_dead_A"] + par["A_A"] * x0
    V_B = par["V_dead_B"] + par["A_B"] * (par["stroke"] - x0)
    omega = math.sqrt(par["beta"] * (par["A_A"] ** 2 / V_A + par["A_B"] ** 2 / V_B) / par["mass"])
    x = r["x"][20:] - np.mean(r["x"][20:])
    i = np.flatnonzero(np.signbit(x[1:]) != np.signbit(x[:-1]))
    crossings = (i - x[i] / (x[i + 1] - x[i])) * step  # linear interpolation, s
    assert len(crossings) > 40
    assert math.pi / np.mean(np.diff(crossings)) == pytest.approx(omega, rel=0.005)


@pytest.mark.parametrize("u, x0, expected", [(1.0, 0.2, "velocity"), (-1.0, 0.3, "stop")])
def test_long_communication_step_stays_stable_and_accurate(fmu, par, u, x0, expected):
    """20 ms steps with n_substeps = 10 would put RK4 outside its stability region where the
    system is stiff (a nearly empty chamber draining through the laminar region of its metering
    edge: beta/V_dead times the edge's flow gain is about 3500 1/s). The model adds substeps,
    so the results are those of the exact equilibria."""
    outputs = ["v", "p_A", "p_B"]
    with FastSlave(fmu, ["u", "F_ext"], outputs, {"x0": x0, "n_substeps": 10}) as slave:
        last = np.array([slave.step(k * 0.02, 0.02, np.array([u, 0.0])).copy()
                         for k in range(100)])[-10:]
    if expected == "velocity":
        assert np.all(np.abs(last[:, 0] / steady_state(par, u, 0.0)[0] - 1) < 1e-3)
    else:  # resting on the bottom stop: no flow, so each chamber sits at its port's pressure
        assert np.all(last[:, 0] == 0.0)
        assert np.all(np.abs(last[:, 1] / par["p_tank"] - 1) < 1e-3)
        assert np.all(np.abs(last[:, 2] / par["p_supply"] - 1) < 1e-6)


def test_bad_parameter_is_reported_at_initialization(fmu, capfd):
    with pytest.raises(Exception, match="fmi2ExitInitializationMode"):
        FastSlave(fmu, ["u"], ["x"], {"rod": 0.2})  # rod wider than the 0.14 m bore
    assert "rod must be > 0 and < bore" in capfd.readouterr().out
