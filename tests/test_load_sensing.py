"""The load-sensing supply: HydraulicCylinder's compensated meter-in edge and meter-out ratio, the
servo's valve law on it, and the shared pump's law (plant_models.supply), against the orifice
law, the force balance and the flow balance worked out here (scipy's root finder for the
pump's drop); none of the references comes from the code under test."""

import json
import math
from pathlib import Path

import numpy as np
import pytest
from cylinder_start import start_parameters
from cylinder_variants import own_supply_cylinder
from scipy.optimize import brentq

import fmus
from fmus.runs import run_fmpy
from orchestrator.plants.master import Master
from plant_models.cylinder_model import CylinderModel
from plant_models.model_spec import FmuSpec
from plant_models.supply import LoadSensingPump

H = 1e-3  # communication step, s
OUTPUTS = ["x", "v", "p_A", "p_B", "E_supply", "E_compensator", "E_throttling"]
MARGIN = 2.5e6  # Pa
RATIO = 1.3  # meter_out_ratio


@pytest.fixture(scope="module")
def fmu():
    return fmus.build("HydraulicCylinder")


@pytest.fixture(scope="module")
def par(fmu):
    return {**start_parameters(fmu), "meter_out_ratio": RATIO}


def run(fmu, n, u, F_ext, p_pump, p_LS, **start):
    inputs = {"u": np.full(n, u), "F_ext": np.full(n, F_ext), "p_pump": np.full(n, p_pump),
              "p_LS": np.full(n, p_LS)}
    return run_fmpy(fmu, inputs, OUTPUTS, H, {"meter_out_ratio": RATIO, **start})


def tail_rate(r, name, n=200):
    """d(name)/dt over the last n steps (energy outputs: W)."""
    return (r[name][-1] - r[name][-1 - n]) / (n * H)


@pytest.mark.parametrize("u, F_ext", [(0.5, 5.0e4), (0.5, 2.5e5), (0.8, 1.5e5)])
def test_compensated_meter_in_flow_does_not_depend_on_the_load(fmu, par, u, F_ext):
    # The compensator holds the meter-in edge's outlet at p_LS, so it drops p_pump - p_LS =
    # MARGIN and passes Q = q u sqrt(MARGIN / dp_rated), whatever the chamber needs (below p_LS).
    p_ls = 20.0e6
    r = run(fmu, 1500, u, F_ext, p_ls + MARGIN, p_ls, x0=0.2)
    A_A, A_B = par["A_A"], par["A_B"]
    q = par["q_rated"] * u
    v = q * math.sqrt(MARGIN / par["dp_rated"]) / A_A
    assert np.mean(r["v"][-100:]) == pytest.approx(v, rel=2e-3)
    # Force balance with the meter-out edge r q u: p_B = p_T + dp_rated (A_B v / (r q))^2.
    p_B = par["p_tank"] + par["dp_rated"] * (A_B * v / (RATIO * q)) ** 2
    p_A = (F_ext + par["F_coulomb"] * math.tanh(v / par["v_coulomb"]) + par["b_viscous"] * v
           + p_B * A_B) / A_A
    assert p_A < p_ls  # the compensator throttles the rest
    assert r["p_B"][-1] == pytest.approx(p_B, rel=5e-3)
    assert r["p_A"][-1] == pytest.approx(p_A, rel=5e-3)
    # Powers: the pump delivers p_pump Q; the compensator burns (p_LS - p_A) Q of it.
    assert tail_rate(r, "E_supply") == pytest.approx((p_ls + MARGIN) * A_A * v, rel=5e-3)
    assert tail_rate(r, "E_compensator") == pytest.approx((p_ls - p_A) * A_A * v, rel=5e-3)


@pytest.mark.parametrize("u, F_ext", [(0.6, 1.0e5), (-0.6, -5.0e4), (-0.4, 1.2e5)])
def test_a_pump_below_p_supply_feeds_the_port_without_a_compensator(fmu, par, u, F_ext):
    # p_LS = 0: no compensator; the port sees min(p_pump, p_supply) = p_pump. Both edges pass the
    # piston's flow, the meter-out edge RATIO times wider (see steady_state in
    # test_hydraulic_cylinder, with k_out = RATIO k):
    #   (A_in^3 + A_out^3 / RATIO^2) / k^2 w^2 + b w - drive = 0.
    p_pump = 18.0e6
    r = run(fmu, 1500, u, F_ext, p_pump, 0.0, x0=0.2 if u > 0 else 1.1)
    A_A, A_B, p_T = par["A_A"], par["A_B"], par["p_tank"]
    k2 = (par["q_rated"] * abs(u)) ** 2 / par["dp_rated"]
    if u > 0:
        c, drive = (A_A**3 + A_B**3 / RATIO**2) / k2, p_pump * A_A - p_T * A_B - F_ext
    else:
        c, drive = (A_A**3 / RATIO**2 + A_B**3) / k2, p_pump * A_B - p_T * A_A + F_ext
    drive -= par["F_coulomb"]
    b = par["b_viscous"]
    w = (-b + math.sqrt(b * b + 4 * c * drive)) / (2 * c)
    assert np.mean(r["v"][-100:]) == pytest.approx(math.copysign(w, u), rel=5e-3)
    assert tail_rate(r, "E_compensator") == 0.0


def test_a_load_sensing_pressure_above_the_pump_passes_no_oil(fmu):
    # Outlet held at p_LS above the pump: the edge has nothing to drop, the check holds the load.
    r = run(fmu, 500, 1.0, 5.0e4, 10.0e6, 12.0e6, x0=0.5)
    assert r["E_supply"][-1] == 0.0
    assert abs(r["x"][-1] - 0.5) < 1e-4  # only the oil's compression


@pytest.mark.parametrize("w, F_ext", [(0.06, 1.5e5), (-0.1, 8.0e4), (0.2, -1.5e5),
                                      (-0.15, 2.2e5)])
def test_the_servo_valve_law_drives_the_commanded_velocity_on_a_compensated_valve(fmu, par, w,
                                                                                  F_ext):
    # CylinderModel.opening for a compensated valve, fed to the FMU with the pump MARGIN above
    # the chamber the valve meters into: the piston runs at the commanded velocity, driven
    # (meter-in) or pulled by its load (overrunning: F_ext pulling the way it moves, the
    # meter-out edge sets the speed).
    model = CylinderModel.from_fmu_parameters(par)
    model = CylinderModel(**{**model.__dict__, "compensated_drop_pa": MARGIN})
    u = model.opening(w, F_ext)
    assert 0.05 < abs(u) < 1.0
    p_ls = 25.0e6  # above every chamber pressure these loads need
    r = run(fmu, 1500, u, F_ext, p_ls + MARGIN, p_ls, x0=0.3 if w > 0 else 1.0)
    # Overrunning: the oil's make-up and friction, which the law leaves out, cost ~1 %.
    assert np.mean(r["v"][-100:]) == pytest.approx(w, rel=0.02)


def _drop_for(pump, flows, openings):
    """The meter-in drop (Pa) at which the sections' flows add up to the pump's, by root
    finding: sum q_i |a_i| sqrt(drop / dp_i) = Q_max."""
    def excess(drop):
        return sum(q * abs(a) * math.sqrt(drop / dp) for (q, dp), a in zip(flows, openings,
                                                                            strict=True)) \
            - pump.max_flow_m3_s
    return brentq(excess, 1e-9, pump.margin_pa, xtol=1e-6, rtol=1e-14)


def _models(flows):
    return [CylinderModel(bore_m=0.14, rod_m=0.1, stroke_m=1.3, dead_volume_a_m3=1e-3,
                          dead_volume_b_m3=1e-3, bulk_modulus_pa=1e9, supply_pressure_pa=30e6,
                          tank_pressure_pa=0.3e6, rated_flow_m3_s=q, rated_pressure_drop_pa=dp,
                          mass_kg=100.0, viscous_friction_n_s_m=0.0) for q, dp in flows]


def test_the_pump_law_shares_its_flow_and_holds_its_margin():
    lpm = 1e-3 / 60
    pump = LoadSensingPump(440 * lpm, 30e6, MARGIN, engine_power_w=1e9)  # no power limit
    flows = [(440 * lpm, 2.5e6), (440 * lpm, 2.5e6), (100 * lpm, 3.5e6)]
    law = pump.law(_models(flows))
    # Little demand: the margin above the highest meter-in chamber (p_A extending, p_B
    # retracting; a closed section does not count).
    assert law(0.3, -0.2, 0.0, 8e6, 1e6, 2e6, 12e6, 1e6, 29e6) == (12e6 + MARGIN, 12e6, 1.0)
    assert law(0.0, 0.0, 0.0, 8e6, 9e6, 2e6, 12e6, 1e6, 29e6) == (MARGIN, 0.0, 1.0)
    # Too much demand: the drop falls until the flows add up to the pump's.
    openings = (1.0, 0.8, -1.0)
    p_pump, p_ls, sharing = law(*openings, 15e6, 1e6, 3e6, 1e6, 1e6, 6e6)
    drop = _drop_for(pump, flows, openings)
    assert p_ls == 15e6
    assert p_pump - p_ls == pytest.approx(drop, rel=1e-9)
    assert sharing == pytest.approx(math.sqrt(drop / MARGIN), rel=1e-9)
    # Spools beyond full opening count as fully open.
    assert law(3.0, 0.8, -7.0, 15e6, 1e6, 3e6, 1e6, 1e6, 6e6) == (p_pump, p_ls, sharing)
    # The LS pressure limiter: a stalled section at its port relief cannot raise the pump above
    # its cut-off; the others keep their margin.
    assert law(0.5, 0.1, 0.0, 34e6, 1e6, 3e6, 1e6, 1e6, 1e6) == (30e6, 30e6 - MARGIN, 1.0)
    with pytest.raises(ValueError, match="margin_pa must be below cutoff_pa"):
        LoadSensingPump(440 * lpm, 2e6, MARGIN)


@pytest.mark.parametrize("p_ls", [5e6, 15e6, 27e6])
def test_the_power_limiter_holds_p_times_q_at_the_engines_power(p_ls):
    """p_pump x Q = P when the flow-limited pump would take more (Q = s D, the sections' flows
    at the drop p_pump - p_LS = margin s^2, summed here from their orifice law), and the law is
    the flow limiter's alone when it takes less."""
    lpm = 1e-3 / 60
    flows = [(440 * lpm, 2.5e6), (440 * lpm, 2.5e6), (220 * lpm, 3.5e6)]
    openings = (0.9, -0.5, 0.7)
    pressures = (p_ls, 1e6, 2e6, p_ls - 1e6, 1e6, 3e6)  # the boom's p_A is the highest load
    limited = LoadSensingPump(429 * lpm, 35e6, MARGIN, 121e3, 0.85)
    unlimited = LoadSensingPump(429 * lpm, 35e6, MARGIN, 1e9)
    p_pump, p_got, sharing = limited.law(_models(flows))(*openings, *pressures)
    free = unlimited.law(_models(flows))(*openings, *pressures)
    drop = p_pump - p_got
    flow = sum(q * abs(a) * math.sqrt(drop / dp) for (q, dp), a in zip(flows, openings,
                                                                       strict=True))
    assert p_got == p_ls and drop == pytest.approx(MARGIN * sharing**2, rel=1e-12)
    if free[0] * free[2] * sum(q * abs(a) * math.sqrt(MARGIN / dp) for (q, dp), a in
                               zip(flows, openings, strict=True)) > 121e3 * 0.85:
        assert sharing < free[2]
        assert p_pump * flow == pytest.approx(121e3 * 0.85, rel=1e-12)
    else:
        assert (p_pump, p_got, sharing) == free
    assert p_pump * flow <= 121e3 * 0.85 * (1 + 1e-12)
    with pytest.raises(ValueError, match="pump_efficiency must be at most 1"):
        LoadSensingPump(429 * lpm, 35e6, MARGIN, 121e3, 1.2)


def test_three_cylinders_on_one_pump_slow_down_together():
    # Three cylinders fully open on a pump that gives 60 % of their demand: each gets the same
    # share s of its own demand, and their inflows add up to the pump's flow.
    lpm = 1e-3 / 60
    parameters = {"q_rated": 200 * lpm, "dp_rated": MARGIN, "meter_out_ratio": RATIO}
    specs = {name: ("cylinder", FmuSpec("HydraulicCylinder", {**parameters, "bore": bore,
                                                              "rod": 0.5 * bore}))
             for name, bore in (("a", 0.12), ("b", 0.14), ("c", 0.10))}
    pump = LoadSensingPump(0.6 * 3 * 200 * lpm, 30e6, MARGIN)
    cylinder = start_parameters(fmus.build("HydraulicCylinder"))
    models = _models([(200 * lpm, MARGIN)] * 3)
    law = pump.law(models)
    loads = {"a": 4e4, "b": 1.2e5, "c": 1e4}
    start = {n: {"x0": 0.2, "F_ext": f} for n, f in loads.items()}
    with Master(specs, 0.01, start) as master:
        parts = [master[n] for n in ("a", "b", "c")]
        for k in range(150):
            pressures = [float(p) for c in parts for p in c.outputs[2:4]]
            p_pump, p_ls, sharing = law(1.0, 1.0, 1.0, *pressures)
            for c, name in zip(parts, ("a", "b", "c"), strict=True):
                c.inputs[:] = [1.0, loads[name], 0.0, p_pump, p_ls]
                c.step(k * 0.01, 0.01)
        velocities = [float(c.outputs[1]) for c in parts]
    areas = [math.pi / 4 * b * b for b in (0.12, 0.14, 0.10)]
    inflows = [a * v for a, v in zip(areas, velocities, strict=True)]
    assert sharing == pytest.approx(0.6, rel=1e-9)
    assert sum(inflows) == pytest.approx(pump.max_flow_m3_s, rel=0.01)
    for flow in inflows:  # each the same share of its full demand, 200 L/min
        assert flow == pytest.approx(0.6 * 200 * lpm, rel=0.01)
    assert cylinder["stroke"] > 0.2 + 1.5 * max(velocities)  # no cylinder reached its stop


def test_a_cylinder_with_its_own_supply_parameter_stays_off_the_pump(tmp_path):
    # An FMU whose p_pump is a parameter (its own supply setting), not an input: the master does
    # not take it for the pump's port, and the cylinder runs on the supply it models.
    path = own_supply_cylinder(tmp_path)
    spec = FmuSpec(str(path), {"p_pump": 20.0e6})
    with Master({"boom": ("cylinder", spec)}, 0.01, {"boom": {"x0": 0.2}}) as master:
        boom = master["boom"]
        assert set(boom.missing_inputs) == {"p_pump"}
        for k in range(100):
            boom.inputs[boom.input_index["u"]] = 1.0
            boom.step(k * 0.01, 0.01)
        x = float(boom.outputs[0])
    assert x > 0.25  # it extended, fed by its own 20 MPa


def test_the_paper_machine_stays_within_its_engine_and_keeps_its_chambers_full(tmp_path):
    """Three paper periods on a 70 kW engine (the paper's 121 kW reaches its limit only in the
    deep trench of periods 9-14): the supply's power, from the cylinder FMUs' own E_supply
    integrals (p_S x Q over each step), never exceeds the limiter's 70 kW x 0.85 and reaches it
    (the limiter acts); no chamber sits at 0 Pa (make-up sized for the pump, stick
    regeneration)."""
    from orchestrator.campaign import run_campaign
    from orchestrator.runlog import read_run
    from orchestrator.scenario import load_scenario

    scenario = load_scenario(Path(__file__).resolve().parents[1] / "scenarios"
                             / "paper-2020.toml", ["periods=3",
                                                   "plant.supply.engine_power_w=70e3"])
    supply = scenario.plant.supply
    limit = supply.engine_power_w * supply.pump_efficiency
    assert limit == pytest.approx(59.5e3)
    run_campaign(scenario, log_path=tmp_path / "run.mcap")
    joints = ("boom", "stick", "bucket")
    logged = read_run(tmp_path / "run.mcap", topics=[f"/signals/{j}" for j in joints]
                      + [f"/cylinder/{j}" for j in joints])
    power = []
    for k in range(1, 4):
        channels = [logged.channels[f"/signals/{j}"] for j in joints]
        fields = [c.of_period(k) for c in channels]
        energy = sum(f["values"][:, json.loads(c.metadata["names"]).index(f"{j}.E_supply")]
                     for f, c, j in zip(fields, channels, joints, strict=True))
        power.append(np.diff(energy) / np.diff(fields[0]["t_s"]))
    power = np.concatenate(power)
    assert power.max() <= limit * (1 + 1e-9)
    assert power.max() > 0.99 * limit
    for j in joints:
        cylinder = logged.channels[f"/cylinder/{j}"].fields
        assert np.all(cylinder["p_A_Pa"] > 0.0) and np.all(cylinder["p_B_Pa"] > 0.0), j
