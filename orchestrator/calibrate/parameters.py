"""The parameters a calibration fits: `--param KEY=LOW:HIGH`, checked against the scenario.

KEY is any `--set` key whose value in the scenario is a number (a scenario key such as
plant.load_cell_noise_kg, or an FMU parameter such as plant.pile.parameters.density, set in the
file or taken from the FMU's declared start). The range must have LOW < HIGH and both ends must
be values the scenario accepts: the scenario is loaded with KEY at each end (the FMUs' own
ranges, the sanity and physics bounds of orchestrator.scenario), so a range outside the key's
physical bounds is refused before any run.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from orchestrator.calibrate.errors import CalibrationError
from orchestrator.scenario import Scenario, ScenarioError, load_scenario


@dataclass(frozen=True)
class Parameter:
    """One fitted parameter: its `--set` key, its range [low, high] and the scenario's value
    (start: where the search begins, clipped into the range)."""

    key: str
    low: float
    high: float
    start: float

    def item(self, value: float) -> str:
        """The `--set` item of `value`."""
        return f"{self.key}={float(value)!r}"

    def to_unit(self, value: float) -> float:
        return (value - self.low) / (self.high - self.low)

    def from_unit(self, unit: float) -> float:
        return self.low + min(max(unit, 0.0), 1.0) * (self.high - self.low)


def parse_param(text: str) -> tuple[str, float, float]:
    """(key, low, high) of 'KEY=LOW:HIGH'; CalibrationError (one line) when malformed."""
    key, sep, span = text.partition("=")
    low_text, colon, high_text = span.partition(":")
    key = key.strip()
    if not sep or not key or not colon:
        raise CalibrationError(f"--param {text!r}: expected KEY=LOW:HIGH, e.g. "
                               "plant.pile.parameters.density=1500:2000")
    try:
        low, high = float(low_text), float(high_text)
    except ValueError:
        raise CalibrationError(f"--param {text!r}: LOW and HIGH must be numbers") from None
    if not (math.isfinite(low) and math.isfinite(high)):
        raise CalibrationError(f"--param {text!r}: LOW and HIGH must be finite numbers")
    if low >= high:
        raise CalibrationError(f"--param {key}: the range {low:g}:{high:g} is empty "
                               "(LOW must be less than HIGH)")
    return key, low, high


def scenario_value(scenario: Scenario, key: str) -> Any:
    """The scenario's value of a dotted key: from its resolved data, else (an FMU parameter
    the file leaves to the FMU) the FMU's declared start; None when it has none."""
    from orchestrator.scenario.sanity import resolved_values

    value: Any = scenario.to_dict()
    for part in key.split("."):
        value = value.get(part) if isinstance(value, dict) else None
    if value is not None:
        return value
    parts = key.split(".")
    if len(parts) == 4 and parts[0] == "plant" and parts[2] == "parameters":
        pile, cylinders = resolved_values(scenario, True)
        table = pile if parts[1] == "pile" else cylinders.get(parts[1], {})
        return table.get(parts[3])
    return None


def check_parameters(scenario_path: Path, overrides: Sequence[str], texts: Sequence[str]
                     ) -> list[Parameter]:
    """The parameters of `--param` texts, each checked (module docstring); CalibrationError for
    the first bad one (none given, malformed, repeated, unknown, not a number, out of bounds)."""
    if not texts:
        raise CalibrationError("no --param: name at least one parameter to fit, e.g. "
                               "--param plant.pile.parameters.density=1500:2000")
    try:
        scenario = load_scenario(scenario_path, overrides)
    except ScenarioError as error:
        raise CalibrationError(str(error)) from None
    parameters: list[Parameter] = []
    for text in texts:
        key, low, high = parse_param(text)
        if key in {p.key for p in parameters}:
            raise CalibrationError(f"--param {key}: given twice")
        probe = f"{key}={(low + high) / 2!r}"
        try:
            load_scenario(scenario_path, [*overrides, probe], check_fmus=True)
        except ScenarioError as error:
            if "unknown key" in str(error) or "has no parameter" in str(error) or \
                    "is not a table" in str(error):
                raise CalibrationError(f"--param {key}: unknown parameter ({error})") from None
        value = scenario_value(scenario, key)
        if isinstance(value, bool) or not isinstance(value, int | float):
            what = "has no value" if value is None else f"is {value!r}, not a number"
            raise CalibrationError(f"--param {key}: the scenario's {key} {what}: only a "
                                   "numeric key can be fitted")
        for end in (low, high):
            try:
                load_scenario(scenario_path, [*overrides, f"{key}={end!r}"])
            except ScenarioError as error:
                raise CalibrationError(f"--param {key}: {end:g} (of the range {low:g} to "
                                       f"{high:g}) is outside what the scenario accepts: "
                                       f"{error}") from None
        parameters.append(Parameter(key, low, high, min(max(float(value), low), high)))
    return parameters
