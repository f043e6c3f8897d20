"""A recursive estimate of the material's mass per swept area, kappa (kg/m^2), from weighings.

The terrain strategy (planner.terrain) predicts a period's mass as kappa A, A the area (m^2)
between its surface estimate and the planned tip path. kappa lumps what the planner does not know:
the bulk density, the width of the slice the pile tracks, the share of a swept area that enters
the bucket, how much deeper the arm runs than its plan. Each weighing m (kg) of a period whose
planned path swept A is a measurement

    m = kappa A + v,   var(v) = R = sigma_w^2 + (model_share kappa A)^2,

sigma_w the load cell's noise (kg) and model_share the prediction's own relative error (cell
resolution, slumping at an assumed angle, spill). A scalar Kalman filter (the recursive least
squares estimate with a random walk) keeps kappa and its variance P: between periods kappa may
drift (P grows by (drift_share kappa)^2: the density varies along the ground), on new ground it
may jump (new_ground_share).

>>> estimate = MassPerArea()                       # nothing weighed yet
>>> estimate = estimate.weighed(mass_kg=8.7, area_m2=0.30, noise_sigma_kg=0.5, model_share=0.05)
>>> round(estimate.kappa_kg_m2, 6), round(estimate.sigma_kg_m2, 3)
(29.0, 2.209)
>>> estimate = estimate.weighed(30.0, 1.0, 0.5, 0.05)  # a second weighing narrows it
>>> round(estimate.kappa_kg_m2, 3), round(estimate.sigma_kg_m2, 3)
(29.675, 1.26)
"""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class MassPerArea:
    """kappa_kg_m2 (kg/m^2; None before the first weighing) and its variance (kg^2/m^4)."""

    kappa_kg_m2: float | None = None
    variance_kg2_m4: float = math.inf

    @property
    def sigma_kg_m2(self) -> float:
        """Standard deviation of kappa (kg/m^2); inf before the first weighing."""
        return math.sqrt(self.variance_kg2_m4)

    def predict_mass_kg(self, area_m2: float) -> float | None:
        """kappa A (kg) for a swept area A (m^2), or None before the first weighing."""
        return None if self.kappa_kg_m2 is None else self.kappa_kg_m2 * float(area_m2)

    def weighed(self, mass_kg: float, area_m2: float, noise_sigma_kg: float,
                model_share: float) -> MassPerArea:
        """The estimate after a weighing mass_kg (kg) of a period that swept area_m2 (m^2,
        > 0); noise_sigma_kg (kg, >= 0) the load cell's noise, model_share (>= 0) the
        prediction's relative error."""
        if not (math.isfinite(mass_kg) and math.isfinite(area_m2) and area_m2 > 0.0):
            raise ValueError(f"a weighing needs a finite mass and an area > 0 m^2, got "
                             f"{mass_kg!r} kg over {area_m2!r} m^2")
        if self.kappa_kg_m2 is None:  # the first weighing: kappa = m / A, no prior
            kappa = max(mass_kg, 0.0) / area_m2
            noise = noise_sigma_kg**2 + (model_share * kappa * area_m2) ** 2
            return MassPerArea(kappa, noise / area_m2**2)
        predicted = self.kappa_kg_m2 * area_m2
        noise = noise_sigma_kg**2 + (model_share * predicted) ** 2
        gain = self.variance_kg2_m4 * area_m2 / (area_m2**2 * self.variance_kg2_m4 + noise)
        kappa = max(self.kappa_kg_m2 + gain * (mass_kg - predicted), 0.0)
        return MassPerArea(kappa, (1.0 - gain * area_m2) * self.variance_kg2_m4)

    def drifted(self, share: float) -> MassPerArea:
        """The estimate a period later: kappa may have moved by `share` of itself (1 sigma)."""
        if self.kappa_kg_m2 is None:
            return self
        return MassPerArea(self.kappa_kg_m2,
                           self.variance_kg2_m4 + (share * self.kappa_kg_m2) ** 2)
