"""Values that validate one by one but are physically meaningless together, or would make a run
hang: refused when the scenario loads (ScenarioError naming the quantity), before a log exists.

The bounds (docs/reliability.md):

- target_mass_kg at most what the bucket holds: the pile's density x capacity (kg);
- adaptation.z_D0_m below the ground at y_D0_m (the pile's z_surface0 plus its heap there);
- the fuzzy rule can be built (its centres, the fractions times the target, strictly increasing);
- plant.load_cell_noise_kg at most MAX_NOISE_FRACTION of the target;
- the first period's plan at most MAX_PERIOD_S long, and at most MAX_STEPS_PER_PERIOD
  communication steps;
- a HydraulicCylinder at most MAX_RK4_SUBSTEPS RK4 substeps per communication step: its own
  n_substeps, or the stability guard's ceil(h / h_stable) computed from its parameters as
  fmus/HydraulicCylinder/model.c does (stiffness_terms, stable_substep) at mass_load = 0, where
  it needs the most;
- no parameter the plant sets itself (a cylinder's initial stroke, the role x0);
- every one of our FMUs initialises with its parameters (asked at load:
  orchestrator.scenario.fmu_probe), and the simulated excavator's servos can be designed for
  them at the communication step (the plant is built once and closed; FMU files of unknown
  origin are not run at load, their mistakes show when the run starts).
"""

from __future__ import annotations

import math
from functools import lru_cache
from pathlib import Path
from typing import Any

from orchestrator.scenario.errors import ScenarioError

MAX_PERIOD_S = 120.0
MAX_STEPS_PER_PERIOD = 50_000
MAX_RK4_SUBSTEPS = 1_000  # per communication step; the paper's boom needs 43 at h = 10 ms
MAX_NOISE_FRACTION = 0.25  # of the target mass: a noisier load cell cannot steer the adaptation
CYLINDERS = ("boom", "stick", "bucket")


def check_values(scenario: Any, source: str, check_fmus: bool,
                 given: dict[str, set[str]] | None = None) -> None:
    """The checks of the module docstring that need no plan (ScenarioError on the first).
    given: role -> the parameters the scenario itself sets (named first in a refusal)."""
    plant = scenario.plant
    every = plant.servo_sample_s / plant.communication_step_s
    if round(every) < 1 or abs(every - round(every)) > 1e-9 * every:
        raise ScenarioError(source, "plant.servo_sample_s",
                            f"{plant.servo_sample_s:g} s is not a whole number of communication "
                            f"steps of {plant.communication_step_s:g} s (the servo samples on "
                            "the step grid)")
    for role in CYLINDERS:
        spec = getattr(plant, role).spec()
        stroke_variable = spec.variable("x0")
        if stroke_variable in spec.parameters:
            raise ScenarioError(source, f"plant.{role}.parameters.{stroke_variable}",
                                "the plant sets the initial stroke (x0) from the path's start "
                                "pose; remove it")
    try:  # fractions that validate one by one can still give equal centres (m* x 5e-324)
        scenario.fuzzy_rule()
    except ValueError as error:
        field = "adaptation.centres_kg" if scenario.adaptation.centres_kg is not None \
            else "adaptation.centre_fractions"
        raise ScenarioError(source, field, f"the fuzzy rule cannot be built: {error}") from None
    noise, target = plant.load_cell_noise_kg, scenario.target_mass_kg
    if noise > MAX_NOISE_FRACTION * target:
        raise ScenarioError(source, "plant.load_cell_noise_kg",
                            f"{noise:g} kg is more than {MAX_NOISE_FRACTION:g} of the target "
                            f"mass {target:g} kg: the weighings could not steer the adaptation")
    pile = _values(plant.pile.spec(), check_fmus)
    if {"density", "capacity"} <= set(pile):
        holds = pile["density"] * pile["capacity"]
        if target > holds:
            raise ScenarioError(source, "target_mass_kg",
                                f"{target:g} kg is more than the bucket holds: density x "
                                f"capacity = {pile['density']:g} kg/m^3 x {pile['capacity']:g} "
                                f"m^3 = {holds:.4g} kg (plant.pile.parameters)")
    if "z_surface0" in pile:
        ground = _ground_at(pile, scenario.adaptation.y_D0_m)
        if scenario.adaptation.z_D0_m >= ground:
            raise ScenarioError(source, "adaptation.z_D0_m",
                                f"{scenario.adaptation.z_D0_m:g} m is not below the ground at "
                                f"y_D0_m = {scenario.adaptation.y_D0_m:g} m (z = {ground:g} m): "
                                "the first period would dig nothing")
    step = plant.communication_step_s
    for role in CYLINDERS:
        spec = getattr(plant, role).spec()
        values = _values(spec, check_fmus)
        if values.get("n_substeps", 1) > MAX_RK4_SUBSTEPS:
            raise ScenarioError(source, f"plant.{role}.parameters.n_substeps",
                                f"{values['n_substeps']:g} RK4 substeps per communication step "
                                f"are more than the {MAX_RK4_SUBSTEPS} allowed")
        needed = rk4_substeps(values, step) if _model_name(spec, check_fmus) == \
            "HydraulicCylinder" else None
        if needed is not None and needed > MAX_RK4_SUBSTEPS:
            raise ScenarioError(source, f"plant.{role}.parameters",
                                f"the cylinder's stability guard needs {needed} RK4 substeps per "
                                f"communication step of {step:g} s, more than the "
                                f"{MAX_RK4_SUBSTEPS} allowed (a stiffer oil column, a lighter "
                                "piston or a wider valve need more; so does a longer step)")
    if check_fmus:
        for role in (*CYLINDERS, "pile"):
            _check_initialises(getattr(plant, role).spec(), role, source,
                               (given or {}).get(role, set()))
        _check_plant_builds(scenario, source)


def _check_plant_builds(scenario: Any, source: str) -> None:
    """Build the simulated excavator (servo designs, no FMU instance) when every FMU is ours."""
    import fmus
    from orchestrator.plants.simulated_excavator import SimulatedExcavator

    specs = scenario.fmu_specs()
    if scenario.plant.kind != "sim" or any(s.fmu not in fmus.MODELS for s in specs.values()):
        return
    try:
        SimulatedExcavator(scenario.sim_config()).close()
    except ValueError as error:
        role, _, reason = str(error).partition(": ")
        if role in specs:
            raise ScenarioError(source, f"plant.{role}", reason.splitlines()[0]) from None
        raise ScenarioError(source, "plant", str(error).splitlines()[0]) from None


def check_first_period(scenario: Any, source: str) -> None:
    """Fail early when no period can be dug (D0 out of reach even after the shift by dy_0), or
    when the first period's plan is too long or too many communication steps."""
    from planner.adaptation import initial_state
    from plant_models.geometry import Unreachable

    planner = scenario.period_planner()
    defaults = scenario.adaptation_defaults()
    try:
        decision = initial_state(defaults, planner.reachable)
    except (ValueError, ArithmeticError) as error:  # e.g. limits of 1e-308 deg/s: no spline
        raise ScenarioError(source, "limits", f"the first period cannot be planned with these "
                            f"limits and trajectory weights: {error}") from None
    if decision.terminated:
        result = planner.plan(defaults.y_D0, defaults.z_D0)
        reason = result.reason if isinstance(result, Unreachable) else "out of reach"
        raise ScenarioError(
            source, "adaptation",
            f"the path through D0 = ({defaults.y_D0:g}, {defaults.z_D0:g}) m is out of reach, "
            f"also shifted by dy_0_m: {reason}")
    state = decision.next_state
    duration = planner.plan(state.y_D, state.z_D).duration
    if duration > MAX_PERIOD_S:
        raise ScenarioError(source, "trajectory",
                            f"the first period's plan lasts {duration:.4g} s, more than the "
                            f"{MAX_PERIOD_S:g} s allowed (k_T = {scenario.trajectory.k_T:g}, "
                            f"k_J = {scenario.trajectory.k_J:g}, and the limits)")
    steps = math.ceil(duration / scenario.plant.communication_step_s)
    if steps > MAX_STEPS_PER_PERIOD:
        raise ScenarioError(source, "plant.communication_step_s",
                            f"{scenario.plant.communication_step_s:g} s makes the first period "
                            f"({duration:.4g} s) {steps} communication steps, more than the "
                            f"{MAX_STEPS_PER_PERIOD} allowed")


def rk4_substeps(values: dict[str, float], step_s: float) -> int | None:
    """RK4 substeps a HydraulicCylinder takes per communication step `step_s` at mass_load = 0:
    max(n_substeps, ceil(step_s / h_stable)), h_stable = 2 / (sqrt(spring/M) + damping/M +
    flow) with the terms of model.c's stiffness_terms(); None if a parameter is missing or the
    terms are not finite (the FMU's own initialization check refuses those)."""
    names = ("bore", "rod", "V_dead_A", "V_dead_B", "beta", "q_rated", "dp_rated", "dp_laminar",
             "p_tank", "dp_makeup", "k_relief", "k_makeup", "b_viscous", "F_coulomb",
             "v_coulomb", "mass", "n_substeps")
    if not all(isinstance(values.get(n), int | float) for n in names):
        return None
    v = {n: float(values[n]) for n in names}
    try:
        area_a = math.pi / 4.0 * v["bore"] ** 2
        area_b = math.pi / 4.0 * (v["bore"] ** 2 - v["rod"] ** 2)
        # the larger edge plus the regeneration passage twice (model.c's stiffness_terms)
        edge = max(1.0, float(values.get("meter_out_ratio", 1.0))) \
            + 2.0 * float(values.get("regeneration_ratio", 0.0))
        valve = 1.25 * (v["q_rated"] * edge) * (1.0 / math.sqrt(v["dp_rated"] * v["dp_laminar"]))
        k_port = max(v["k_relief"], v["k_makeup"]) if v["p_tank"] > v["dp_makeup"] \
            else v["k_relief"]
        spring = v["beta"] * (area_a ** 2 / v["V_dead_A"] + area_b ** 2 / v["V_dead_B"])
        damping = v["b_viscous"] + v["F_coulomb"] * (1.0 / v["v_coulomb"])
        flow = v["beta"] / min(v["V_dead_A"], v["V_dead_B"]) * (valve + k_port)
        stable = 2.0 / (math.sqrt(spring / v["mass"]) + damping / v["mass"] + flow)
        needed = math.ceil(step_s / stable)
    except (ValueError, ZeroDivisionError, OverflowError):
        return None
    return max(int(v["n_substeps"]), needed) if math.isfinite(stable) and stable > 0 else None


def _ground_at(pile: dict[str, float], y: float) -> float:
    """The pile's initial surface at y (fmus/shared/pile/profile.c: an inclined ground line
    through z_surface0 at heap_center_y plus a triangular heap)."""
    ground = float(pile["z_surface0"])
    height, centre, half, slope = (pile.get(k) for k in ("heap_height", "heap_center_y",
                                                          "heap_half_width", "ground_slope"))
    if isinstance(slope, int | float) and isinstance(centre, int | float) and abs(slope) < 1.5:
        ground += math.tan(slope) * (y - centre)
    if all(isinstance(x, int | float) for x in (height, centre, half)) and height > 0 < half:
        ground += height * max(0.0, 1.0 - abs(y - centre) / half)
    return ground


def resolved_values(scenario: Any, check_fmus: bool
                    ) -> tuple[dict[str, Any], dict[str, dict[str, Any]]]:
    """(the pile's, {cylinder role: its}) parameter values: the FMU's declared starts with the
    scenario's over them (numbers only; another tool's FMU's only when check_fmus)."""
    plant = scenario.plant
    return _values(plant.pile.spec(), check_fmus), {
        role: _values(getattr(plant, role).spec(), check_fmus) for role in CYLINDERS}


def _values(spec, check_fmus: bool) -> dict[str, Any]:
    """The FMU's declared start values with the spec's parameters over them (numbers only)."""
    values = dict(_declared(spec.fmu, check_fmus))
    values.update({k: v for k, v in spec.parameters.items() if not isinstance(v, bool)})
    return values


def _declared(fmu: str, check_fmus: bool) -> dict[str, Any]:
    import fmus

    if fmu in fmus.MODELS:  # the table, not the build: no compiler needed
        return _table_starts(fmu)
    if not check_fmus:
        return {}
    description = _description(fmu)
    return {v.name: float(v.start) for v in description.modelVariables
            if v.type in ("Real", "Integer") and v.start is not None}


@lru_cache(maxsize=16)
def _table_starts(model: str) -> dict[str, Any]:
    from fmus.builder import MODELS_DIR
    from fmus.table import read_table

    table = read_table(MODELS_DIR / model / "variables.toml")
    return {v.name: v.start for v in table.variables
            if isinstance(v.start, int | float) and not isinstance(v.start, bool)}


def _model_name(spec, check_fmus: bool) -> str | None:
    import fmus

    if spec.fmu in fmus.MODELS:
        return spec.fmu
    return _description(spec.fmu).modelName if check_fmus else None


def _description(path: str):
    from orchestrator.scenario.fmu_paths import model_description

    return model_description(Path(path))


def _check_initialises(spec, role: str, source: str, given: set[str]) -> None:
    """Our models only: they initialise with the scenario's parameters (fmu_probe)."""
    import fmus
    from orchestrator.plants.master import fmu_path
    from orchestrator.scenario.fmu_probe import initialization_error

    if spec.fmu not in fmus.MODELS:
        return
    start = dict(spec.parameters)
    if role in CYLINDERS:  # the plant sets x0 within the stroke; any such value does here
        stroke = _values(spec, False).get("stroke")
        if isinstance(stroke, int | float) and stroke > 0:
            start[spec.variable("x0")] = 0.5 * stroke
    problem = initialization_error(fmu_path(spec, role), start)
    if problem is None:
        return
    problem = problem.rpartition("initialization failed: ")[2]
    # The field: a parameter the message names, one the scenario sets first, else the first named.
    named = sorted((name not in given, at, name) for name in spec.parameters
                   if (at := _position(problem, name)) is not None)
    field = f"plant.{role}.parameters" + (f".{named[0][2]}" if named else "")
    raise ScenarioError(source, field, f"{spec.fmu} does not initialise with these parameters: "
                        f"{problem}")


def _position(text: str, word: str) -> int | None:
    import re

    found = re.search(rf"(?<![A-Za-z0-9_]){re.escape(word)}(?![A-Za-z0-9_])", text)
    return None if found is None else found.start()
