"""Role outputs the master derives for an FMU that lacks them (plant_models.model_spec
DERIVABLE_OUTPUTS): a cylinder's force F = p_A A_A - p_B A_B from its chamber pressures and
piston areas.

derive_outputs() decides, before anything is instantiated, which outputs are derived and where
each coefficient comes from: the scenario's `piston_areas` (m^2), else the FMU's parameter or
calculated parameter that the port map names (converted to m^2 by the port's scale or the
variable's declared unit), or refuses in one line naming the component, the FMU and what is
missing. The co-simulation master (orchestrator.plants.master.Component) reads the FMU's areas
from the initialised instance (DerivedOutput.coefficients: a calculated parameter has no value
before), then computes each derived output after every step from the role outputs in SI units.
DerivedOutput.note says how, for the run log.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

from plant_models.model_spec import DERIVABLE_OUTPUTS, FmuSpec
from plant_models.port_units import PortMap, unit_conversion

_PARAMETER_CAUSALITIES = ("parameter", "calculatedParameter")


@dataclass(frozen=True)
class Coefficient:
    """One term's factor: sign * the parameter's value (m^2), given in the scenario (`value`)
    or read from the FMU's `variable` after initialization (SI = conversion of it)."""

    parameter: str
    sign: float
    value: float | None = None
    variable: str | None = None
    conversion: PortMap | None = None
    source: str = ""


@dataclass(frozen=True)
class DerivedOutput:
    """output = sum(coefficient * term) over `terms`, ((role output, Coefficient), ...), in SI
    units; formula: the rule ("p_A * A_A - p_B * A_B")."""

    output: str
    terms: tuple[tuple[str, Coefficient], ...]
    formula: str

    def coefficients(self, read: Callable[[Sequence[str]], Sequence[float]], where: str
                     ) -> tuple[tuple[str, float], ...]:
        """((term, sign * value), ...), the FMU's parameters read with `read` (names -> values)
        from the initialised instance; ValueError naming `where` for an area that is not > 0."""
        out = []
        for term, c in self.terms:
            value = c.value
            if c.variable is not None:  # the instance's value, also for a parameter
                raw = float(read([c.variable])[0])
                value = raw if c.conversion is None else c.conversion.to_si(raw)
            _check_area(where, c.parameter, value, c.source)
            out.append((term, c.sign * value))
        return tuple(out)

    def note(self, coefficients: Sequence[tuple[str, float]] | None = None) -> str:
        """How the output is derived, with each coefficient's value and source; a value read
        at initialization is shown when `coefficients` (as coefficients() gave them) are."""
        parts = []
        for index, (_, c) in enumerate(self.terms):
            value = abs(coefficients[index][1]) if coefficients is not None else c.value
            parts.append(f"{c.parameter} = {value:.6g} m2 ({c.source})" if value is not None
                         else f"{c.parameter} from the {c.source}, read after initialization")
        return f"{self.output} = {self.formula} (not an FMU output), {', '.join(parts)}"


def derive_outputs(component: str, role: str, spec: FmuSpec, description,
                   ports: Mapping[str, str]) -> dict[str, DerivedOutput]:
    """output role -> DerivedOutput for every derivable output of `role` that `ports` (role ->
    FMU variable, as check_component found them) lacks. ValueError (one line) when such an
    output cannot be derived."""
    out = {}
    variables = {v.name: v for v in description.modelVariables}
    for output, rule in DERIVABLE_OUTPUTS.get(role, {}).items():
        if output in ports:
            continue
        formula = " ".join(f"{'+' if sign > 0 else '-'} {term} * {parameter}"
                           for term, parameter, sign in rule).removeprefix("+ ")
        lacking = [term for term, _, _ in rule if term not in ports]
        terms, unknown = [], []
        for term, parameter, sign in rule:
            coefficient = _coefficient(component, spec, description, variables, parameter, sign)
            if coefficient is None:
                unknown.append(parameter)
            terms.append((term, coefficient))
        if lacking or unknown:
            needs = []
            if lacking:
                needs.append(f"the outputs {', '.join(lacking)}")
            if unknown:
                needs.append(f"{', '.join(unknown)} (m^2: the role's piston_areas, or FMU "
                             f"parameters named by ports.{' and ports.'.join(unknown)})")
            raise ValueError(f"{component}: {description.modelName} has no variable "
                             f"{spec.variable(output)!r} for role {output!r} and the master "
                             f"cannot derive it as {output} = {formula}: it lacks "
                             f"{' and '.join(needs)}")
        out[output] = DerivedOutput(output, tuple(terms), formula)
    return out


def _coefficient(component: str, spec: FmuSpec, description, variables: Mapping,
                 parameter: str, sign: float) -> Coefficient | None:
    """Where a derivation parameter comes from; None if nowhere. ValueError for a mapping to a
    variable that is missing or not a parameter, or a value that is not > 0."""
    if parameter in spec.piston_areas:
        value = float(spec.piston_areas[parameter])
        _check_area(component, parameter, value, "scenario piston_areas")
        return Coefficient(parameter, sign, value, source="scenario piston_areas")
    name = spec.variable(parameter)
    variable = variables.get(name)
    if variable is None:
        if parameter in spec.ports:  # named explicitly: a mistake, not an absence
            raise ValueError(f"{component}: role {parameter!r} maps to variable {name!r}, "
                             f"which {description.modelName} does not have")
        return None
    if variable.causality not in _PARAMETER_CAUSALITIES or variable.type not in ("Real",
                                                                               "Float64"):
        raise ValueError(f"{component}: role {parameter!r} needs a Real parameter, but "
                         f"variable {name!r} of {description.modelName} is a {variable.type} "
                         f"{variable.causality}")
    conversion = spec.port_maps.get(parameter)
    if conversion is None:
        try:
            conversion = unit_conversion(parameter, variable, {
                u.name: u for u in getattr(description, "unitDefinitions", [])})
        except ValueError as error:
            raise ValueError(f"{component}: {error}") from None
    source = f"FMU {variable.causality} {name}"
    # A parameter's value is known now (the scenario's, else its start), for the run log; the
    # master reads it from the instance all the same. A calculated one is known only then.
    raw = spec.parameters.get(name, variable.start) if variable.causality == "parameter" \
        else None
    value = None
    if raw is not None:
        value = float(raw) if conversion is None else conversion.to_si(float(raw))
        _check_area(component, parameter, value, source)
    return Coefficient(parameter, sign, value, name, conversion, source)


def _check_area(component: str, parameter: str, value: float, source: str) -> None:
    if not (math.isfinite(value) and value > 0.0):
        raise ValueError(f"{component}: piston area {parameter} must be > 0 m^2, got {value!r} "
                         f"({source})")
