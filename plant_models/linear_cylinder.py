"""The linear model of a cylinder role, for an FMU whose physics the servo does not know.

A valve-controlled cylinder seen from its spool command u (-1..1) to its stroke x (m)::

    x/u = K_v w_h^2 / (s (s^2 + 2 zeta w_h s + w_h^2))

K_v (m/s per unit command): the steady piston velocity per unit of spool command; w_h
(rad/s): the hydraulic natural frequency (oil columns against the moving mass); zeta: its
damping (friction and the valve's flow-pressure coefficient; >= 1 for an overdamped or
first-order plant such as a velocity-servoed actuator). It is the classical third-order
valve-cylinder model (Merritt, Hydraulic Control Systems, 1967, ch. 5) with the load
pressure's effect on the flow gain folded into K_v. A scenario can give it
(`[plant.boom.linear_model]`) or excosim identifies it from the FMU
(orchestrator.plants.identify).

Plain data: reading a model does not import python-control (seconds); only
`transfer_function` does.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import control

_FIELD_UNITS = {"velocity_gain_m_s": "m/s per unit command", "natural_frequency_rad_s": "rad/s",
                "damping": "", "stroke_m": "m"}


@dataclass(frozen=True)
class LinearCylinderModel:
    """x/u = K_v w_h^2 / (s (s^2 + 2 zeta w_h s + w_h^2)) of one cylinder (SI units).

    velocity_gain_m_s: K_v, steady piston velocity (m/s) per unit spool command (> 0).
    natural_frequency_rad_s: w_h (rad/s, > 0). damping: zeta (>= 0; >= 1 overdamped).
    stroke_m: usable stroke (m, > 0).
    """

    velocity_gain_m_s: float
    natural_frequency_rad_s: float
    damping: float
    stroke_m: float

    def __post_init__(self) -> None:
        for item in fields(self):
            value = getattr(self, item.name)
            if isinstance(value, bool) or not isinstance(value, int | float) \
                    or not math.isfinite(value):
                raise ValueError(f"LinearCylinderModel.{item.name} must be a finite number, "
                                 f"got {value!r}")
            if item.name == "damping":
                if value < 0.0:
                    raise ValueError(f"LinearCylinderModel.damping must be >= 0, got {value!r}")
            elif value <= 0.0:
                unit = _FIELD_UNITS[item.name]
                raise ValueError(f"LinearCylinderModel.{item.name} must be > 0 {unit}, "
                                 f"got {value!r}".replace("  ", " "))

    def transfer_function(self) -> control.TransferFunction:
        """Continuous x/u (m per unit command) as a python-control transfer function."""
        import control  # seconds to import: only when a servo is designed

        w, z = self.natural_frequency_rad_s, self.damping
        return control.tf([self.velocity_gain_m_s * w * w], [1.0, 2.0 * z * w, w * w, 0.0])

    def describe(self) -> str:
        """One line for a person: K_v, w_h (and Hz), zeta, stroke."""
        return (f"K_v {self.velocity_gain_m_s:.4g} m/s per unit command, w_h "
                f"{self.natural_frequency_rad_s:.4g} rad/s "
                f"({self.natural_frequency_rad_s / (2.0 * math.pi):.3g} Hz), damping "
                f"{self.damping:.3g}, stroke {self.stroke_m:.4g} m")
