"""Values that validate one by one but are meaningless together, or would make a run hang, are
refused when the scenario loads (orchestrator/scenario/sanity.py): one ScenarioError naming the
quantity; on the command line one line, exit status 2, and no log written."""

from __future__ import annotations

import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import fmus
from fmus.runs import FastSlave
from orchestrator.scenario import ScenarioError, load_scenario
from orchestrator.scenario.sanity import (
    MAX_PERIOD_S,
    MAX_RK4_SUBSTEPS,
    MAX_STEPS_PER_PERIOD,
    rk4_substeps,
)
from plant_models.hydraulics import default_config

ROOT = Path(__file__).resolve().parent.parent
PAPER = ROOT / "scenarios" / "paper-2020.toml"


@pytest.mark.parametrize(("overrides", "field", "reason"), [
    (["target_mass_kg=95"], "target_mass_kg",
     "95 kg is more than the bucket holds: density x capacity = 1600 kg/m^3 x 0.047562 m^3 = "
     "76.1 kg"),
    (["plant.pile.parameters.density=500"], "target_mass_kg", "= 23.78 kg"),
    (["adaptation.z_D0_m=0.05"], "adaptation.z_D0_m",
     "0.05 m is not below the ground at y_D0_m = -9 m (z = 0 m)"),
    (["plant.pile.parameters.heap_height=0.5", "plant.pile.parameters.heap_center_y=-9",
      "adaptation.z_D0_m=0.6"], "adaptation.z_D0_m", "(z = 0.5 m)"),
    (["plant.load_cell_noise_kg=8"], "plant.load_cell_noise_kg",
     "8 kg is more than 0.25 of the target mass 30 kg"),
    (["adaptation.outputs_m=[0.4, 0.25, 0.1, 0, -0.1, -0.25, -0.4]"], "adaptation.outputs_m",
     "expected 7 strictly increasing numbers"),
    (["adaptation.outputs_m=[0.1, 0.2, 0.3, 0.35, 0.4, 0.5, 0.6]"], "adaptation.outputs_m",
     "r_1..r_3 must be < 0 and r_5..r_7 > 0"),
    (["trajectory.k_T=1.5"], "trajectory.k_T", "must be less than or equal to 1"),
    (["trajectory.k_J=-0.1"], "trajectory.k_J", "must be greater than or equal to 0"),
    (["limits.jerk_deg_s3=[0.2, 0.2, 0.2]", "trajectory.k_T=0.001"], "trajectory",
     f"the first period's plan lasts 183.5 s, more than the {MAX_PERIOD_S:g} s allowed"),
    (["plant.communication_step_s=0.0002"], "plant.communication_step_s",
     f"more than the {MAX_STEPS_PER_PERIOD} allowed"),
    (["plant.boom.parameters.n_substeps=5000"], "plant.boom.parameters.n_substeps",
     f"5000 RK4 substeps per communication step are more than the {MAX_RK4_SUBSTEPS} allowed"),
    (["plant.stick.parameters.beta=5e9", "plant.stick.parameters.mass=0.01"],
     "plant.stick.parameters", "the cylinder's stability guard needs"),
    (["plant.bucket.parameters.x0=0.5"], "plant.bucket.parameters.x0",
     "the plant sets the initial stroke (x0) from the path's start pose; remove it"),
    (["plant.boom.parameters.rod=0.2"], "plant.boom.parameters.rod",
     "HydraulicCylinder does not initialise with these parameters: rod must be > 0 and < bore"),
    (["plant.pile.parameters.z_floor=0.5"], "plant.pile.parameters.z_floor",
     "Pile does not initialise with these parameters: z_floor must lie below z_surface0"),
    (["plant.pile.parameters.density=1.6e12"], "plant.pile.parameters.density",
     "value of 'density' lies outside its range [100, 10000]"),  # a bucket of 9e10 kg
    (["plant.communication_step_s=0.05", "plant.servo_sample_s=0.05"], "plant.stick",
     "cannot damp the hydraulic mode"),
    (["plant.communication_step_s=0.003"], "plant.servo_sample_s",
     "0.01 s is not a whole number of communication steps of 0.003 s"),
])
def test_nonsense_is_refused_at_load_naming_the_quantity(overrides, field, reason):
    with pytest.raises(ScenarioError) as refused:
        load_scenario(PAPER, ["periods=1", *overrides])
    assert refused.value.field == field, str(refused.value)
    assert reason in refused.value.reason and "\n" not in str(refused.value)


def test_a_parameter_the_port_map_names_as_x0_is_plant_set_too():
    with pytest.raises(ScenarioError, match=r"plant\.boom\.parameters\.stroke: the plant sets "
                       r"the initial stroke"):
        load_scenario(PAPER, ["plant.boom.ports.x0=stroke"])


def test_the_shipped_scenarios_pass_every_check():
    for path in sorted((ROOT / "scenarios").glob("*.toml")):
        load_scenario(path)


def _one_step(parameters: dict, n_substeps: int, step_s: float) -> np.ndarray:
    outputs = ["x", "v", "p_A", "p_B"]
    with FastSlave(fmus.build("HydraulicCylinder"), ["u"], outputs,
                   {**parameters, "n_substeps": n_substeps}) as slave:
        return slave.step(0.0, step_s, np.array([0.8])).copy()


def test_the_substep_count_is_the_fmus_own(capfd):
    """rk4_substeps mirrors model.c: the FMU takes max(n_substeps, needed) substeps, so its
    result is the same for n_substeps = 1 and = needed, and another one for needed + 1; far
    beyond its own limit of 1e8 substeps per step it refuses the step."""
    paper_boom = {k: v for k, v in default_config("paper").boom.parameters.items()}
    boom = {**_declared("HydraulicCylinder"), **paper_boom}
    # The paper's boom at its 10 ms step: its make-up checks, sized for the pump's flow
    # (k_makeup 3e-8), set the stiffness bound (43 substeps with the FMU's default 5e-9).
    assert rk4_substeps(boom, 0.01) == 105
    stick = {**_declared("HydraulicCylinder"),
             **default_config("paper").stick.parameters, "n_substeps": 1}
    assert stick["regeneration_ratio"] == 0.5  # its passage enters the bound too
    assert rk4_substeps(stick, 0.01) > rk4_substeps({**stick, "regeneration_ratio": 0.0}, 0.01)
    paper_stick = dict(default_config("paper").stick.parameters)
    for parameters, step_s in ((paper_boom, 0.01), (paper_stick, 0.01),
                               ({"mass": 20.0, "beta": 2e9}, 0.02),
                               ({"mass": 20.0, "meter_out_ratio": 2.0, "k_makeup": 0.0}, 0.02)):
        needed = rk4_substeps({**_declared("HydraulicCylinder"), **parameters,
                               "n_substeps": 1}, step_s)
        assert needed > 1
        guarded = _one_step(parameters, 1, step_s)
        assert np.array_equal(guarded, _one_step(parameters, needed, step_s))
        assert not np.array_equal(guarded, _one_step(parameters, needed + 1, step_s))
    defaults = {**_declared("HydraulicCylinder"), "n_substeps": 1}
    step = 1.02e8 / rk4_substeps(defaults, 1.0)  # s: ~1.02e8 substeps predicted
    assert rk4_substeps(defaults, step) > 1e8
    with FastSlave(fmus.build("HydraulicCylinder"), ["u"], ["x"], {"n_substeps": 1}) as slave:
        with pytest.raises(RuntimeError, match="fmi2DoStep failed"):
            slave.step(0.0, step, np.array([0.0]))
    assert "more than 1e8 stable RK4 substeps needed" in capfd.readouterr().out


def _declared(model: str) -> dict:
    from fmpy import read_model_description

    return {v.name: float(v.start) for v in read_model_description(
        str(fmus.build(model))).modelVariables if v.start is not None and v.type != "Boolean"}


def test_on_the_command_line_it_is_one_line_exit_2_and_no_log(tmp_path):
    done = subprocess.run(
        [sys.executable, "-c", "from orchestrator.cli.app import main; main()", "run",
         str(PAPER), "--set", "target_mass_kg=95"], capture_output=True, text=True,
        cwd=tmp_path, env={**os.environ, "PYTHONPATH": str(ROOT)}, timeout=120)
    assert done.returncode == 2 and done.stdout == ""
    assert done.stderr.startswith("excosim: paper-2020.toml: target_mass_kg: 95 kg is more "
                                  "than the bucket holds") and done.stderr.count("\n") == 1
    assert list(tmp_path.iterdir()) == []  # no runs/ folder, no log
    assert math.isfinite(MAX_PERIOD_S)
