"""How the simulated excavator's servos are made from a scenario's FMUs: the FMU's model
description and start values, our cylinder's physical model from its parameters, a linear
servo on a given or identified linear model, and the designs, remembered (pure functions of
frozen values, and the scenario loader designs every servo once before the run does again)."""

from __future__ import annotations

import hashlib
import math
from collections.abc import Callable
from functools import lru_cache

from fmus.descriptions import model_description
from fmus.runs import value_kind
from orchestrator.plants.design_cache import remembered
from orchestrator.plants.identify import identify_cylinder
from orchestrator.plants.master import fmu_path
from plant_models.cylinder_model import CylinderModel
from plant_models.linear_servo import design_linear_servo
from plant_models.servo import ServoDesign, design_servo
from plant_models.sim_config import SimulatedExcavatorConfig


def start_values(description) -> dict[str, float]:
    values = {}
    for variable in description.modelVariables:
        if variable.start is not None and value_kind(variable.type) in ("Real", "Integer"):
            values[variable.name] = float(variable.start)
    return values


# Told when a substitute FMU's identification runs (seconds; then remembered): the CLI says so.
on_identify: Callable[[str], None] | None = None


@lru_cache(maxsize=64)
def design_servo_cached(model: CylinderModel, *settings) -> ServoDesign:
    """plant_models.servo.design_servo, remembered in this process and on disk
    (orchestrator.plants.design_cache): a pure function of frozen values, and the scenario
    loader designs every servo once before the run designs it again."""
    return remembered("servo", (model, *settings), lambda: design_servo(model, *settings))


def fmu_description(component: str, spec):
    path = fmu_path(spec, component)
    try:
        return model_description(path)
    except Exception as error:
        raise ValueError(f"{component}: cannot read {path.name}: {error}") from None


def model_from_fmu(description, parameters) -> CylinderModel | None:
    """Our HydraulicCylinder's model from the FMU's parameters; None for an FMU with other
    parameter names (its servo then works on a linear model)."""
    try:
        return CylinderModel.from_fmu_parameters({**start_values(description), **parameters})
    except ValueError:
        return None


def linear_servo(joint: str, spec, stroke_m: float, config: SimulatedExcavatorConfig,
                  conversions=None, load_mass: dict[str, float] | None = None,
                  sample_s: float | None = None):
    """(design, linear model, identification or None) of `joint`'s linear servo: on the
    FmuSpec's linear_model, else on the model identified from the FMU (with `load_mass`, the
    FMU variable taking the arm's reflected inertia -> kg, set during the test; `sample_s`, the
    test's step for an FMU that takes only its own fixed step)."""
    identified = None
    model = spec.linear_model
    if model is None:
        parameters = {**spec.parameters, **(load_mass or {})}
        path = fmu_path(spec, joint)

        def identify():
            if on_identify is not None:
                on_identify(f"identifying the {joint} FMU {path.name} for its servo (once; "
                            "remembered after)")
            return identify_cylinder(path, spec.ports, parameters, stroke_m,
                                     config.communication_step_s, conversions=conversions,
                                     sample_s=sample_s)

        inputs = (hashlib.sha256(path.read_bytes()).hexdigest(),
                  tuple(sorted(parameters.items())), tuple(sorted(spec.ports.items())),
                  tuple(sorted((conversions or {}).items())), float(stroke_m),
                  float(config.communication_step_s), sample_s)
        identified = remembered("identify", inputs, identify)
        model = identified.model
    elif not math.isclose(model.stroke_m, stroke_m, rel_tol=0.01):
        raise ValueError(f"{joint}: linear_model.stroke_m {model.stroke_m} m differs from the "
                         f"linkage's stroke {stroke_m:.4g} m by more than 1 %")
    points = tuple(f.model for f in identified.fits) if identified is not None else ()
    settings = (model, config.servo_sample_s, joint, points, config.servo_gain_margin_db,
                config.servo_phase_margin_deg)
    design = remembered("linear_servo", settings, lambda: design_linear_servo(*settings))
    return design, model, identified
