"""Test helper: a HydraulicCylinder FMU's parameter start values, with its piston areas."""

import math

from fmpy import read_model_description


def start_parameters(fmu) -> dict[str, float]:
    """Start values of the FMU's parameters, plus the piston and annulus areas A_A, A_B (m^2)."""
    values = {v.name: float(v.start) for v in read_model_description(str(fmu)).modelVariables
              if v.causality == "parameter"}
    values["A_A"] = math.pi / 4 * values["bore"] ** 2
    values["A_B"] = math.pi / 4 * (values["bore"] ** 2 - values["rod"] ** 2)
    return values
