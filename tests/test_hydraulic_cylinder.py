"""HydraulicCylinder FMU against hydraulics worked out here by hand, run through fmpy.

The references below are derived from the orifice law, the force balance and the oil's bulk
modulus with the parameters read from the FMU's modelDescription; none of them comes from the
C code.
"""

import math
from pathlib import Path

import numpy as np
import pytest
from cylinder_start import start_parameters
from fmpy import read_model_description

import fmus
from fmus.runs import FastSlave, run_fmpy
from fmus.table import read_table

OUTPUTS = ["x", "v", "p_A", "p_B", "F"]
ALL_OUTPUTS = OUTPUTS + ["E_supply", "E_tank", "E_throttling", "E_relief", "E_friction",
                         "E_load", "E_end_stop", "E_mass_load", "E_stored"]
TABLE = read_table(Path(fmus.__file__).parent / "HydraulicCylinder" / "variables.toml")
H = 1e-3  # communication step, s


@pytest.fixture(scope="module")
def fmu():
    return fmus.build("HydraulicCylinder")


@pytest.fixture(scope="module")
def par(fmu):
    return start_parameters(fmu)


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


@pytest.mark.parametrize("u, F_ext", [(1.0, 0.0), (-1.0, 0.0), (0.5, 1.0e5), (-0.6, -5.0e4),
                                      (0.5, 3.5e5)])
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


@pytest.mark.parametrize("makeup", [True, False])
@pytest.mark.parametrize("load", [1.5e5, -8.0e4])
def test_closed_valve_holds_a_load_step_with_the_pressure_that_balances_it(fmu, par, load,
                                                                          makeup):
    """u = 0 traps both chambers; a load step compresses one of them until it carries the load.

    Pushing (load > 0) the piston in compresses A and expands B; B falls below tank pressure long
    before A carries the load. Without a make-up valve B cavitates (a void opens at p_B = 0), so
    at rest p_A*A_A = load exactly. With it, B draws oil from tank while it is below
    p_T - dp_makeup and keeps it (the check), so at rest p_A*A_A - p_B*A_B = load with
    p_B >= p_T - dp_makeup. Either way A's oil is trapped and obeys dp = -beta*dV/V, so A's volume
    shrinks to V_A0*exp(-(p_A - p_A0)/beta), which fixes where the piston comes to rest. A
    pulling load mirrors this on the rod side.
    """
    n = 1500
    F_ext = np.full(n, load)
    F_ext[:50] = 0.0
    start = {"x0": 0.65} if makeup else {"x0": 0.65, "k_makeup": 0.0}
    r = run(fmu, np.zeros(n), F_ext, **start)
    assert abs(r["v"][-1]) < 1e-6 and abs(r["v"][-100]) < 1e-6  # at rest
    A_A, A_B, beta, stroke = par["A_A"], par["A_B"], par["beta"], par["stroke"]
    opens = par["p_tank"] - par["dp_makeup"]
    trapped, other = ("p_A", "p_B") if load > 0 else ("p_B", "p_A")
    if makeup:  # the expanding chamber was fed from tank and kept the oil
        assert r[other][-1] >= opens * (1 - 1e-9)
    else:
        assert r[other][-1] < 1e-3 * r[trapped][-1] and r[other].min() == 0.0
    assert r["p_A"][-1] * A_A - r["p_B"][-1] * A_B == pytest.approx(load, rel=1e-4)
    if load > 0:
        V0 = par["V_dead_A"] + A_A * 0.65
        V = V0 * math.exp(-(r["p_A"][-1] - r["p_A"][0]) / beta)
        x_ref = (V - par["V_dead_A"]) / A_A
    else:
        V0 = par["V_dead_B"] + A_B * (stroke - 0.65)
        V = V0 * math.exp(-(r["p_B"][-1] - r["p_B"][0]) / beta)
        x_ref = stroke - (V - par["V_dead_B"]) / A_B
    assert r["x"][-1] - 0.65 == pytest.approx(x_ref - 0.65, rel=0.01)


def test_trapped_oil_is_conserved_through_cavitation(fmu, par):
    """u = 0 traps the oil in A (no make-up valve here). A 300 kN pull drives the rod side over
    its relief, the piston extends about 0.4 m and A cavitates (a void of several litres opens);
    a 20 kN push then drives it back. A's oil never left (A stays below its relief), so once the
    void is refilled and the piston rests, A obeys the trapped-chamber law
    V_A = V_A0*exp(-(p_A - p_A0)/beta) exactly as if the excursion had never happened."""
    n, x0 = 2500, 0.4
    F_ext = np.zeros(n)
    F_ext[50:200], F_ext[200:] = -3.0e5, 2.0e4
    r = run(fmu, np.zeros(n), F_ext, x0=x0, k_makeup=0.0)
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


@pytest.mark.parametrize("mass_load", [0.0, 750.0])
def test_hydraulic_natural_frequency(fmu, par, mass_load):
    """Without friction, a small load step on the closed cylinder rings at the oil-spring
    frequency omega = sqrt(beta*(A_A^2/V_A + A_B^2/V_B)/(mass + mass_load)) (Merritt's hydraulic
    natural frequency). A raised tank pressure keeps both chambers pressurized throughout."""
    step, n, x0 = 1e-4, 5000 if mass_load == 0.0 else 10000, 0.5
    load = np.full(n, 1.0e4)
    load[:10] = 0.0
    r = run_fmpy(fmu, {"u": np.zeros(n), "F_ext": load, "mass_load": np.full(n, mass_load)},
                 OUTPUTS, step,
                 {"x0": x0, "p_tank": 5e6, "F_coulomb": 0.0, "b_viscous": 0.0})
    assert r["p_A"].min() > 1e6 and r["p_B"].min() > 1e6
    V_A = par["V_dead_A"] + par["A_A"] * x0
    V_B = par["V_dead_B"] + par["A_B"] * (par["stroke"] - x0)
    omega = math.sqrt(par["beta"] * (par["A_A"] ** 2 / V_A + par["A_B"] ** 2 / V_B)
                      / (par["mass"] + mass_load))
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


# ---- load-holding check, make-up -----------------------------------------------------------------

@pytest.mark.parametrize("u, load", [(0.5, 5.0e5), (-0.5, -2.4e5)])
def test_load_holding_check_stops_a_load_above_supply_pressure(fmu, par, u, load):
    """u = +0.5 and a 500 kN load: holding it takes p_A = (load + p_T*A_B)/A_A = 32.6 MPa, above
    the 30 MPa supply (below the 35 MPa relief). The P->A check closes, so A's oil is trapped
    and the piston stops instead of being driven back with oil flowing into the supply; B
    drains to tank through B->T. At rest p_B = p_T and p_A*A_A - p_T*A_B = load, and the supply
    delivers nothing. Mirrored: u = -0.5 with a 240 kN pull, 32.4 MPa on the rod side.

    The load rises over 0.4 s (a step would overshoot into the relief). Once the held chamber
    is above p_S its oil is trapped: from then on its volume follows V = V_k*exp(-(p - p_k)/beta)
    exactly, which fixes where the piston comes to rest."""
    n = 1500
    F_ext = load * np.clip((np.arange(n) - 50) / 400.0, 0.0, 1.0)
    r = run_fmpy(fmu, {"u": np.full(n, u), "F_ext": F_ext}, OUTPUTS + ["E_supply"], H,
                 {"x0": 0.65})
    A_A, A_B, p_T, beta = par["A_A"], par["A_B"], par["p_tank"], par["beta"]
    held, drained = ("p_A", "p_B") if u > 0 else ("p_B", "p_A")
    assert r[held].max() < par["p_relief"] and r[held][-1] > par["p_supply"]
    assert np.all(np.abs(r["v"][-500:]) < 1e-6) and np.ptp(r["x"][-500:]) < 1e-9
    assert r[drained][-1] == pytest.approx(p_T, rel=1e-6)
    assert r["p_A"][-1] * A_A - r["p_B"][-1] * A_B == pytest.approx(load, rel=1e-6)
    # No flow back into the supply at any time, and none at all while the load is held.
    assert np.all(np.diff(r["E_supply"]) >= 0.0) and np.ptp(r["E_supply"][-500:]) == 0.0
    k = int(np.argmax(r[held] > par["p_supply"]))
    assert np.all(r[held][k:] > par["p_supply"])
    if u > 0:
        volume = par["V_dead_A"] + A_A * r["x"]
    else:
        volume = par["V_dead_B"] + A_B * (par["stroke"] - r["x"])
    trapped = volume[k] * np.exp(-(r[held][k:] - r[held][k]) / beta)
    moved = np.max(np.abs(r["x"][k:] - r["x"][k]))
    area = A_A if u > 0 else A_B
    assert moved > 1e-3  # the oil's compression is visible
    assert np.max(np.abs(volume[k:] - trapped)) / area < 1e-3 * moved


def _steady_overrun(par, speed=None, pull=None):
    """Closed valve, the piston pulled out at constant speed v by a load F_ext = -pull.

    B is trapped and shrinks: its oil leaves through the relief, A_B*v = k_relief*(p_B -
    p_relief). A grows and is fed only by its make-up check, A_A*v = k_makeup*(p_T - dp_makeup -
    p_A), while that leaves p_A >= 0; beyond, A cavitates (p_A = 0, a void grows at A_A*v -
    k_makeup*(p_T - dp_makeup)). Force balance p_A*A_A - p_B*A_B + pull = F_c*tanh(v/v_c) + b*v.
    Given the speed: the pull; given the pull: the speed (the balance is monotone in v).
    Returns (v, pull, p_A, p_B)."""
    A_A, A_B = par["A_A"], par["A_B"]

    def pressures(v):
        p_A = max(par["p_tank"] - par["dp_makeup"] - A_A * v / par["k_makeup"], 0.0)
        return p_A, par["p_relief"] + A_B * v / par["k_relief"]

    def needed(v):  # the pull that holds speed v
        p_A, p_B = pressures(v)
        friction = par["F_coulomb"] * math.tanh(v / par["v_coulomb"]) + par["b_viscous"] * v
        return p_B * A_B - p_A * A_A + friction

    if speed is None:
        low, high = 1e-6, 100.0
        for _ in range(200):
            mid = 0.5 * (low + high)
            low, high = (mid, high) if needed(mid) < pull else (low, mid)
        speed = 0.5 * (low + high)
    return (speed, needed(speed), *pressures(speed))


@pytest.mark.parametrize("case", ["make-up keeps up", "make-up cannot keep up"])
def test_makeup_check_feeds_an_overrunning_chamber_from_tank(fmu, par, case):
    """u = 0 and a pull beyond what the rod side's relief holds: the piston runs out at the
    constant speed that `_steady_overrun` works out from the relief and make-up laws. At 5 cm/s
    the make-up feeds A (p_A between 0 and p_T - dp_makeup); a 300 kN pull asks for 2 m/s, 33 L/s
    into A, far more than the 1.25 L/s the make-up passes at p_A = 0, so A cavitates."""
    if case == "make-up keeps up":
        v, pull, p_A, p_B = _steady_overrun(par, speed=0.05)
        n, tail = 1500, slice(-300, None)
        assert 0.0 < p_A < par["p_tank"] - par["dp_makeup"]
    else:
        v, pull, p_A, p_B = _steady_overrun(par, pull=3.0e5)
        n, tail = 350, slice(250, 350)  # the piston reaches the end stop after about 400 steps
        assert p_A == 0.0 and v > 1.0
    F_ext = np.full(n, -pull)
    F_ext[:20] = 0.0
    if p_A > 0.0:  # a slow rise: a step would jerk the piston out and leave A a void to fill
        F_ext = -pull * np.clip(np.arange(n) / 400.0, 0.0, 1.0)
    r = run(fmu, np.zeros(n), F_ext, x0=0.3)
    assert r["x"][-1] < par["stroke"]  # still running
    assert np.mean(r["v"][tail]) == pytest.approx(v, rel=2e-3)
    assert np.mean(r["p_B"][tail]) == pytest.approx(p_B, rel=1e-4)
    if p_A > 0.0:
        assert np.mean(r["p_A"][tail]) == pytest.approx(p_A, rel=2e-3)
    else:
        assert np.all(r["p_A"][tail] == 0.0)


# ---- parameter and input bounds --------------------------------------------------------------

def test_every_parameter_has_physical_bounds_and_the_inputs_are_open(fmu):
    variables = read_model_description(str(fmu)).modelVariables
    for v in variables:
        if v.causality == "parameter":
            assert v.min is not None and v.max is not None, v.name
            assert float(v.min) <= float(v.start) <= float(v.max), v.name
    inputs = {v.name: v for v in variables if v.causality == "input"}
    assert set(inputs) == {"u", "F_ext", "mass_load", "p_pump", "p_LS"}
    assert inputs["u"].min is None and inputs["u"].max is None  # clamped by the model
    assert inputs["F_ext"].min is None and inputs["F_ext"].max is None
    assert float(inputs["mass_load"].min) == 0.0
    # Pressures are gauge (>= 0); the pump's start lies above every p_supply the table allows,
    # so a cylinder on its own sees its constant supply.
    p_supply = next(v for v in variables if v.name == "p_supply")
    for name in ("p_pump", "p_LS"):
        assert float(inputs[name].min) == 0.0 and float(inputs[name].max) == 1.0e9
    assert float(inputs["p_pump"].start) > float(p_supply.max)
    assert float(inputs["p_LS"].start) == 0.0


@pytest.mark.parametrize("start, message", [
    ({"bore": 1e-200, "rod": 5e-201}, "piston area pi/4*bore^2 and annulus"),  # areas: 0
    ({"bore": 1e-150, "rod": 1e-151}, "piston area pi/4*bore^2 and annulus"),
    ({"rod": 0.14 * (1 - 1e-12)}, "piston area pi/4*bore^2 and annulus"),  # no annulus left
    ({"stroke": 1e308, "bore": 2.0, "rod": 1.0, "x0": 1.0},
     "chamber volumes V_dead + area*stroke must be finite"),
    ({"dp_rated": 1e-300, "dp_laminar": 1e-310}, "1/dp_rated"),
    ({"beta": 1e300, "V_dead_A": 1e-300}, "non-finite stiffness bound"),
    ({"k_makeup": -1e-9}, "k_makeup and dp_makeup must be >= 0"),
    ({"dp_makeup": -1.0}, "k_makeup and dp_makeup must be >= 0"),
    ({"mass_load": -1.0}, "mass_load must lie in [0, 1e12] kg"),
])
def test_meaningless_parameters_are_refused_at_initialization(fmu, capfd, start, message):
    # Refused by the model at initialization (a condition across variables), or already when
    # set by the shared layer (a value outside the table's range, named with it).
    with pytest.raises(Exception, match="fmi2ExitInitializationMode|fmi2SetReal"):
        FastSlave(fmu, ["u"], ["x"], start)
    out = capfd.readouterr().out
    assert message in out or any(f"'{name}' lies outside its range" in out for name in start)


@pytest.mark.parametrize("name, value", [
    (v.name, bound) for v in TABLE.variables
    if v.causality == "parameter" and v.name != "n_substeps" for bound in (v.min, v.max)])
def test_a_parameter_at_its_table_bound_runs_finite_or_is_refused(fmu, capfd, name, value):
    """Each parameter at its min or max, the others at their defaults: the model either refuses
    it at initialization (a condition across variables, e.g. rod < bore) with a message, or runs
    with every output finite through a spool and load swing."""
    start = {name: value}
    if name == "stroke":
        start["x0"] = 0.5 * value
    inputs = ["u", "F_ext"]
    try:
        slave = FastSlave(fmu, inputs, ALL_OUTPUTS, start)
    except Exception:
        assert "initialization failed" in capfd.readouterr().out
        return
    step = 1e-5  # short steps: at some bounds a step needs ~1e6 stable substeps
    with slave:
        for k, (u, load) in enumerate([(1.0, 1e5), (-1.0, -1e5), (0.0, 3e5)]):
            assert np.all(np.isfinite(slave.step(k * step, step, np.array([u, load]))))


@pytest.mark.parametrize("u", [0.0, 1.0, -1.0])
@pytest.mark.parametrize("load", [1e300, -1e300, 1.7e308])
def test_any_finite_load_keeps_the_state_finite(fmu, par, u, load):
    """A load of any finite size (the model clamps it at 1000 times what the port pressures
    put on the annulus, far above what the relief holds) drives the piston into its end stop,
    which takes the force; pressures, velocity and energies stay finite."""
    n = 300
    r = run_fmpy(fmu, {"u": np.full(n, u), "F_ext": np.full(n, load)}, ALL_OUTPUTS, H,
                 {"x0": 0.65})
    for name in ALL_OUTPUTS:
        assert np.all(np.isfinite(r[name])), name
    assert r["x"][-1] == (0.0 if load > 0 else par["stroke"])
    assert r["v"][-1] == 0.0
    # On the stop the chamber carrying the load has relieved down to about p_relief.
    carrying = r["p_A"] if load > 0 else r["p_B"]
    assert carrying[-1] < 1.5 * par["p_relief"]


# ---- reflected load mass ---------------------------------------------------------------------

def test_mass_load_adds_to_mass(fmu):
    """mass 250 kg + mass_load 750 kg moves exactly as mass 1000 kg (same arithmetic)."""
    n = 1500
    t = np.arange(n) * H
    u = np.clip(1.5 * np.sin(2 * np.pi * 1.1 * t), -1, 1)
    load = 1.2e5 * np.sin(2 * np.pi * 0.6 * t)
    split = run_fmpy(fmu, {"u": u, "F_ext": load, "mass_load": np.full(n, 750.0)}, ALL_OUTPUTS,
                     H, {"mass": 250.0})
    whole = run_fmpy(fmu, {"u": u, "F_ext": load}, ALL_OUTPUTS, H, {"mass": 1000.0})
    for name in ALL_OUTPUTS:
        assert np.array_equal(split[name], whole[name]), name


def test_changing_mass_load_stays_stable_and_books_its_kinetic_energy(fmu, par):
    """A light piston (10 kg) whose reflected mass jumps between 20 t and 0 every 5 steps of
    10 ms, with n_substeps = 1: the stable substep is recomputed for each step's mass (kept from
    the 20 t start it would be ~45 times too long for 10 kg), so the run stays stable and
    matches one with 50 times as many substeps. Each change keeps v and adds
    (M_new - M_old)*v^2/2 of kinetic energy to E_mass_load."""
    n, step = 300, 0.01
    t = np.arange(n) * step
    mass_load = np.where((np.arange(n) // 5) % 2 == 0, 2.0e4, 0.0)
    inputs = {"u": np.clip(1.5 * np.sin(2 * np.pi * 0.7 * t), -1, 1),
              "F_ext": 8.0e4 * np.sin(2 * np.pi * 0.4 * t), "mass_load": mass_load}
    runs = [run_fmpy(fmu, inputs, ALL_OUTPUTS, step, {"mass": 10.0, "n_substeps": n_sub})
            for n_sub in (1, 50)]
    coarse, fine = runs
    assert np.all(np.isfinite(coarse["x"])) and np.ptp(coarse["x"]) > 0.1
    assert np.max(np.abs(coarse["x"] - fine["x"])) < 1e-6
    # Sample k holds v at the start of step k, whose mass is 10 + mass_load[k].
    M = 10.0 + mass_load
    booked = np.cumsum(0.5 * np.diff(M) * coarse["v"][1:-1] ** 2)
    assert coarse["E_mass_load"][2:] == pytest.approx(booked, rel=1e-12, abs=1e-9)


def test_negative_mass_load_is_refused_at_the_step(fmu, capfd):
    with FastSlave(fmu, ["u", "mass_load"], ["x"], {}) as slave:
        slave.step(0.0, H, np.array([0.0, 10.0]))
        with pytest.raises(Exception, match="fmi2SetReal|fmi2DoStep"):
            slave.step(H, H, np.array([0.0, -1.0]))
    out = capfd.readouterr().out  # the shared layer's range check, or the model's own
    assert "mass_load must lie in [0, 1e12] kg" in out or "'mass_load' lies outside" in out
