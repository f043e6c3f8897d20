"""The linear servo (plant_models.linear_servo): margins checked on loops built here with
python-control, refusal in one line, the runtime law, tracking of a copy of our cylinder FMU
driven only through it, and its use in the simulated excavator and the scenario."""

import dataclasses
import math
import shutil
import warnings

import control
import numpy as np
import pytest

import fmus
from fmus.runs import FastSlave
from plant_models.hydraulics import cylinder_model, default_config, design_cylinder_parameters
from plant_models.linear_cylinder import LinearCylinderModel
from plant_models.linear_servo import LinearJointServo, design_linear_servo

STICK = LinearCylinderModel(0.435, 28.2, 0.032, 1.4715)  # paper stick, as identified
BUCKET = LinearCylinderModel(0.375, 54.0, 0.025, 1.038)  # paper bucket
LAB = LinearCylinderModel(0.038, 1000.0, 0.02, 0.0887)  # lab bucket (1 ms step)
SERVO = LinearCylinderModel(0.3, 800.0, 20.0, 1.3)  # a first-order velocity servo, tau 50 ms
CASES = [(STICK, 0.01), (BUCKET, 0.01), (LAB, 0.001), (SERVO, 0.01)]


def loop_from_scratch(model, plant, step, gain):
    """(K_p / K_v) ZOH{K_v,i w^2 / (s (s^2 + 2 zeta w s + w^2))}."""
    w, z = plant.natural_frequency_rad_s, plant.damping
    continuous = control.tf([plant.velocity_gain_m_s * w * w], [1.0, 2.0 * z * w, w * w, 0.0])
    return gain / model.velocity_gain_m_s * control.c2d(continuous, step, "zoh")


def margins(loop):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # python-control's "falling back to frd" note
        gm, pm, _, _ = control.margin(loop)
    return 20.0 * math.log10(gm), pm


@pytest.mark.parametrize("model,step", CASES)
def test_margins_of_the_discrete_loop(model, step):
    design = design_linear_servo(model, step, "bucket")
    gm_db, pm = margins(loop_from_scratch(model, model, step, design.position_gain_1_s))
    assert gm_db >= 10.0 - 1e-6 and pm >= 60.0 - 1e-6  # sim_config's targets
    closed = control.feedback(loop_from_scratch(model, model, step, design.position_gain_1_s))
    assert np.max(np.abs(control.poles(closed))) < 1.0
    # The largest such gain: 5 % more breaks a target.
    gm_db, pm = margins(loop_from_scratch(model, model, step, 1.05 * design.position_gain_1_s))
    assert gm_db < 10.0 or pm < 60.0
    assert design.gain_margin_db == pytest.approx(
        margins(design.position_loop())[0], rel=1e-6)


def test_margins_hold_at_every_operating_point():
    """Extending and retracting gains differ (asymmetric cylinder): the law divides by the
    mean, so the faster direction has more loop gain; w_h and zeta change along the stroke."""
    points = [dataclasses.replace(STICK, velocity_gain_m_s=k, natural_frequency_rad_s=w,
                                  damping=z)
              for k, w, z in [(0.51, 35.0, 0.032), (0.36, 33.2, 0.045), (0.51, 28.2, 0.053),
                              (0.36, 28.4, 0.057)]]
    design = design_linear_servo(STICK, 0.01, "stick", points, 6.0, 45.0)
    assert design.gain_margin_target_db == 6.0 and len(design.operating_points) == 4
    worst_gm = min(margins(loop_from_scratch(STICK, p, 0.01, design.position_gain_1_s))[0]
                   for p in points)
    worst_pm = min(margins(loop_from_scratch(STICK, p, 0.01, design.position_gain_1_s))[1]
                   for p in points)
    assert worst_gm >= 6.0 - 1e-6 and worst_pm >= 45.0 - 1e-6
    assert worst_gm < 6.5  # the binding point sets the gain


def test_a_model_that_cannot_be_servoed_is_refused_in_one_line():
    undamped = dataclasses.replace(STICK, damping=0.0)
    with pytest.raises(ValueError, match=r"^boom: no servo gain .* 0\.01 s step .*shorten the "
                                         r"communication step or give the linear model more "
                                         r"damping$") as error:
        design_linear_servo(undamped, 0.01, "boom")
    assert "\n" not in str(error.value)
    with pytest.raises(ValueError, match=r"^stick: servo margins 3\.0 dB / 45\.0 deg are below "
                                         r"the required 6 dB / 45 deg"):
        design_linear_servo(STICK, 0.01, "stick", gain_margin_db=3.0, phase_margin_deg=45.0)


@pytest.mark.parametrize("field,value,message", [
    ("velocity_gain_m_s", 0.0, "velocity_gain_m_s must be > 0"),
    ("natural_frequency_rad_s", math.nan, "natural_frequency_rad_s must be a finite number"),
    ("damping", -0.1, "damping must be >= 0"),
    ("stroke_m", "1", "stroke_m must be a finite number"),
])
def test_model_validation_names_the_field(field, value, message):
    with pytest.raises(ValueError, match=f"^LinearCylinderModel.{message}"):
        dataclasses.replace(STICK, **{field: value})


def test_runtime_law():
    design = design_linear_servo(BUCKET, 0.01, "bucket")
    servo = LinearJointServo(design)
    k_p, k_v = design.position_gain_1_s, BUCKET.velocity_gain_m_s
    for x_ref, v_ref, x in [(0.5, 0.1, 0.49), (0.5, -0.2, 0.52), (0.5, 0.0, 0.1), (0.2, 1.0, 0.2)]:
        expected = min(1.0, max(-1.0, (v_ref + k_p * (x_ref - x)) / k_v))
        assert servo.command(x_ref, v_ref, 3.0, x, 1e5) == pytest.approx(expected, rel=1e-12)
        assert servo.velocity_command(x_ref, v_ref, 0.0, x, 0.0) == v_ref + k_p * (x_ref - x)


def test_given_model_tracks_a_copy_of_our_cylinder(tmp_path):
    """A copy of our FMU (the bucket of the paper preset) driven only through the linear servo
    designed on a given model (K_v and w_h analytic, damping as identified at small openings):
    a campaign-like stroke move (25 -> 75 % of the stroke and back, smooth quintics of 4 s,
    peak 0.24 m/s, held 1 s at each end) under a constant 20 kN load. Tracking RMS < 20 mm,
    worst < 35 mm (15 and 27 mm of the 0.52 m move when written): without pressure feedback the
    lightly damped plant allows K_p = 0.88 1/s only, and one K_v for both directions leaves the
    asymmetric cylinder's feed-forward 17 % off either way."""
    copy = tmp_path / "MyCylinder.fmu"
    shutil.copy(fmus.build("HydraulicCylinder"), copy)
    analytic = cylinder_model("paper", "bucket")
    stroke = analytic.stroke_m
    given = LinearCylinderModel(
        velocity_gain_m_s=0.5 * (0.1 / analytic.opening(0.1, 0.0)
                                 + 0.1 / analytic.opening(-0.1, 0.0) * -1.0),
        natural_frequency_rad_s=analytic.natural_frequency(0.75 * stroke), damping=0.025,
        stroke_m=stroke)
    step = 0.01
    design = design_linear_servo(given, step, "bucket")
    servo = LinearJointServo(design)
    t_move = 4.0
    s = np.linspace(0.0, 1.0, int(t_move / step) + 1)
    shape = 10 * s**3 - 15 * s**4 + 6 * s**5
    rate = (30 * s**2 - 60 * s**3 + 30 * s**4) / t_move
    hold = np.ones(int(1.0 / step))
    low, high = 0.25 * stroke, 0.75 * stroke
    x_ref = np.concatenate([low * hold, low + (high - low) * shape, high * hold,
                            high - (high - low) * shape, low * hold])
    v_ref = np.concatenate([0 * hold, (high - low) * rate, 0 * hold, -(high - low) * rate,
                            0 * hold])
    load = 2.0e4
    start = {**design_cylinder_parameters("paper")["bucket"], "x0": low, "F_ext": load}
    errors = []
    with FastSlave(copy, ["u", "F_ext"], ["x", "F"], start) as slave:
        x, force = slave.outputs()
        for k in range(len(x_ref)):
            errors.append(x_ref[k] - x)
            u = servo.command(x_ref[k], v_ref[k], 0.0, x, force)
            x, force = slave.step(k * step, step, np.array([u, load]))
    errors = np.array(errors)
    assert np.sqrt(np.mean(errors**2)) < 0.020  # 15 mm when written
    assert np.max(np.abs(errors)) < 0.035  # 27 mm


def test_excavator_uses_the_linear_servo_for_a_given_model(tmp_path):
    from orchestrator.plants.simulated_excavator import SimulatedExcavator
    from plant_models.linear_servo import LinearServoDesign
    from plant_models.servo import ServoDesign

    copy = tmp_path / "MyCylinder.fmu"
    shutil.copy(fmus.build("HydraulicCylinder"), copy)
    config = default_config("paper")
    given = dataclasses.replace(BUCKET, stroke_m=config.bucket.parameters["stroke"])
    bucket = dataclasses.replace(config.bucket, fmu=str(copy), linear_model=given)
    plant = SimulatedExcavator(dataclasses.replace(config, bucket=bucket))
    try:
        assert isinstance(plant.servo_designs[0], ServoDesign)
        assert isinstance(plant.servo_designs[2], LinearServoDesign)
        assert plant.linear_models == (None, None, given)
        assert plant.identifications == (None, None, None)
    finally:
        plant.close()
    with pytest.raises(ValueError, match="only the cylinder roles"):
        dataclasses.replace(config, pile=dataclasses.replace(config.pile, linear_model=given))


def test_scenario_carries_the_linear_model_and_names_a_bad_field():
    from orchestrator.scenario.errors import ScenarioError
    from orchestrator.scenario.model import scenario_from_dict

    table = {"velocity_gain_m_s": 0.375, "natural_frequency_rad_s": 54.0, "damping": 0.025,
             "stroke_m": 1.038}
    data = {"name": "t", "plant": {"bucket": {"linear_model": table}}}
    scenario = scenario_from_dict(data, check_fmus=False)
    assert scenario.fmu_specs()["bucket"].linear_model == LinearCylinderModel(**table)
    assert scenario.fmu_specs()["boom"].linear_model is None
    bad = {"name": "t", "plant": {"bucket": {"linear_model": {**table, "damping": -1.0}}}}
    with pytest.raises(ScenarioError, match=r"plant\.bucket\.linear_model\.damping") as error:
        scenario_from_dict(bad, check_fmus=False)
    assert "\n" not in str(error.value)
