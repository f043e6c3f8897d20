"""Units at the ports: what each role's value is in (SI), and how an FMU's declared unit converts
to it, so that an FMU in mm, bar or deg can fill a role through its port map.

A conversion is `si = factor * fmu_value + offset`. An FMU declares its units in its model
description (FMI 2.0: a variable's `unit`, defined under <UnitDefinitions> with a <BaseUnit> of SI
exponents, factor and offset; FMI 3.0 the same); those definitions are used first, then the
common units below for an FMU that names a unit without defining it. A unit of another dimension
than the role's is refused, so is a unit that is neither defined nor known.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

# SI base-unit exponents (kg, m, s, rad), factor and offset of the units a port may carry.
_DIMENSIONS = {
    "1": (0, 0, 0, 0), "m": (0, 1, 0, 0), "m/s": (0, 1, -1, 0), "N": (1, 1, -2, 0),
    "Pa": (1, -1, -2, 0), "kg": (1, 0, 0, 0), "m2": (0, 2, 0, 0), "m3": (0, 3, 0, 0),
    "rad": (0, 0, 0, 1),
}
KNOWN_UNITS: Mapping[str, tuple[tuple[int, int, int, int], float, float]] = {
    "": (_DIMENSIONS["1"], 1.0, 0.0), "1": (_DIMENSIONS["1"], 1.0, 0.0),
    "m": (_DIMENSIONS["m"], 1.0, 0.0), "mm": (_DIMENSIONS["m"], 1e-3, 0.0),
    "cm": (_DIMENSIONS["m"], 1e-2, 0.0),
    "m/s": (_DIMENSIONS["m/s"], 1.0, 0.0), "mm/s": (_DIMENSIONS["m/s"], 1e-3, 0.0),
    "N": (_DIMENSIONS["N"], 1.0, 0.0), "kN": (_DIMENSIONS["N"], 1e3, 0.0),
    "Pa": (_DIMENSIONS["Pa"], 1.0, 0.0), "kPa": (_DIMENSIONS["Pa"], 1e3, 0.0),
    "MPa": (_DIMENSIONS["Pa"], 1e6, 0.0), "bar": (_DIMENSIONS["Pa"], 1e5, 0.0),
    "kg": (_DIMENSIONS["kg"], 1.0, 0.0), "g": (_DIMENSIONS["kg"], 1e-3, 0.0),
    "t": (_DIMENSIONS["kg"], 1e3, 0.0),
    "m2": (_DIMENSIONS["m2"], 1.0, 0.0), "cm2": (_DIMENSIONS["m2"], 1e-4, 0.0),
    "mm2": (_DIMENSIONS["m2"], 1e-6, 0.0),
    "m3": (_DIMENSIONS["m3"], 1.0, 0.0), "L": (_DIMENSIONS["m3"], 1e-3, 0.0),
    "rad": (_DIMENSIONS["rad"], 1.0, 0.0), "deg": (_DIMENSIONS["rad"], math.pi / 180.0, 0.0),
}
# The unit of every role (plant_models.model_spec roles and parameter roles).
ROLE_UNITS: Mapping[str, str] = {
    "u": "1", "F_ext": "N", "x": "m", "v": "m/s", "p_A": "Pa", "p_B": "Pa", "F": "N", "x0": "m",
    "mass_load": "kg", "A_A": "m2", "A_B": "m2", "tip_y": "m", "tip_z": "m",
    "bucket_angle": "rad", "dump": "1", "bucket_mass": "kg",
    "F_y": "N", "F_z": "N", "removed_volume": "m3", "dumped_mass": "kg", "pile_mass": "kg",
    "surface_z_at_tip": "m",
}


@dataclass(frozen=True)
class PortMap:
    """One role's port: the FMU variable and si = scale * fmu_value + offset (scale != 0)."""

    variable: str
    scale: float = 1.0
    offset: float = 0.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.scale) and self.scale != 0.0 and math.isfinite(self.offset)):
            raise ValueError(f"port of {self.variable!r}: scale must be finite and not 0, "
                             f"offset finite; got {self.scale!r}, {self.offset!r}")

    @property
    def identity(self) -> bool:
        return self.scale == 1.0 and self.offset == 0.0

    def to_si(self, value: float) -> float:
        return self.scale * value + self.offset

    def from_si(self, value: float) -> float:
        return (value - self.offset) / self.scale


def _declared(unit: str, definitions: Mapping[str, object]):
    """(dimensions, factor, offset) of an FMU's unit from its own definition, else the table;
    dimensions None for a unit the FMU defines in ampere, kelvin, mole or candela (a quantity no
    role has)."""
    base = getattr(definitions.get(unit), "baseUnit", None)
    if base is not None:
        if base.A or base.K or base.mol or base.cd:
            return None, 1.0, 0.0
        return (base.kg, base.m, base.s, base.rad), float(base.factor), float(base.offset)
    return KNOWN_UNITS.get(unit)


def unit_conversion(role: str, variable, definitions: Mapping[str, object]) -> PortMap | None:
    """The conversion of `variable` (an fmpy ModelVariable) into `role`'s SI unit, None when
    the FMU declares no unit for it or already the role's; ValueError (one line) for a unit of
    another dimension or one that is neither defined in the FMU nor known here."""
    unit = variable.unit or getattr(variable.declaredType, "unit", None)
    wanted = ROLE_UNITS.get(role)
    if not unit or wanted is None or unit == wanted:
        return None
    found = _declared(unit, definitions)
    if found is None:
        raise ValueError(f"role {role!r}: variable {variable.name!r} is in {unit!r}, which the "
                         f"FMU does not define and excosim does not know; give the port's scale "
                         f"and offset to {wanted}")
    dims, factor, offset = found
    if dims != KNOWN_UNITS[wanted][0]:
        defined = " (the FMU defines it in ampere, kelvin, mole or candela)" if dims is None \
            else ""
        raise ValueError(f"role {role!r} is in {wanted}, but variable {variable.name!r} is in "
                         f"{unit!r}, another quantity{defined}; map it with an explicit scale "
                         f"and offset to {wanted}")
    conversion = PortMap(variable.name, factor, offset)
    return None if conversion.identity else conversion


def si_to_declared(value: float, variable, definitions: Mapping[str, object]) -> float | None:
    """A value in SI as `variable`'s declared unit wants it (1.289 m -> 1289 for "mm"); the value
    itself when the variable declares no unit or an SI one; None when its unit is not known."""
    unit = variable.unit or getattr(variable.declaredType, "unit", None)
    if not unit or unit in _DIMENSIONS:
        return value
    found = _declared(unit, definitions)
    if found is None or found[0] is None:
        return None
    _, factor, offset = found
    return (value - offset) / factor
