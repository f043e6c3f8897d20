"""What kinds of FMU the master runs, read from a model description: FMI 2.0 and 3.0
co-simulation FMUs without clocks, stepped at the communication step (one that takes only its
own fixed step must be given that step)."""

from __future__ import annotations

import math

from fmus.runs import fmi_major


def not_co_simulation(description) -> str | None:
    """Why the master cannot run the FMU of `description` (one line), None when it can: an FMI
    2.0 or 3.0 FMU with co-simulation (model exchange needs a solver the master does not have)."""
    version, name = description.fmiVersion, description.modelName
    if fmi_major(description) is None:
        return f"{name} is an FMI {version} FMU; the master runs FMI 2.0 and 3.0 co-simulation"
    if description.coSimulation is None:
        kind = "scheduled execution" if getattr(description, "scheduledExecution", None) \
            else "model exchange"
        return (f"{name} is an FMI {version} FMU for {kind} only; the master runs "
                "co-simulation FMUs (export it with co-simulation, i.e. its own solver)")
    clocks = [v.name for v in description.modelVariables
              if v.type == "Clock" and v.causality == "input"]
    if clocks:
        return (f"{name} has input clocks ({', '.join(clocks[:3])}), which the master never "
                "ticks: it runs co-simulation FMUs without clocks (export it without them)")
    return None


def fixed_step_s(description) -> float | None:
    """The one communication step (s) the FMU of `description` takes, None when it takes any:
    an FMU that cannot handle a variable communication step size
    (canHandleVariableCommunicationStepSize false) and names a default experiment stepSize."""
    co = description.coSimulation
    step = getattr(description.defaultExperiment, "stepSize", None) \
        if description.defaultExperiment is not None else None
    if co is None or co.canHandleVariableCommunicationStepSize or step is None:
        return None
    return float(step)


def check_fixed_step(component: str, description, step_s: float) -> float | None:
    """The FMU's fixed step (fixed_step_s), None when it takes any; ValueError (one line) when
    it has one and the communication step step_s (s) is another: the master steps every FMU at
    the communication step."""
    fixed = fixed_step_s(description)
    if fixed is not None and not math.isclose(fixed, step_s, rel_tol=1e-9):
        raise ValueError(f"{component}: {description.modelName} steps only at its fixed step "
                         f"{fixed:g} s (canHandleVariableCommunicationStepSize false, "
                         f"defaultExperiment stepSize), not at the communication step "
                         f"{step_s:g} s: set plant.communication_step_s = {fixed:g} (and "
                         "servo_sample_s a multiple of it)")
    return fixed
