"""A bank of surface estimates, one per hypothesis of the angle of repose, weighed by how well
each predicted the weighings.

The angle the soil's walls slump to is not known well (a planner is told one, perhaps 5 deg
off). It decides how much of a trench's walls falls back into it, and how far the slopes of an
old trench reach toward a new one, so a wrong angle biases every prediction. Each hypothesis j
keeps its own surface (planner.surface_estimate, slumped at its angle) and its own mass per area
kappa_j (planner.mass_per_area). A weighing m of a period whose planned path swept A_j on
hypothesis j's surface scores it by the likelihood of its innovation (a multiple-model
estimator):

    w_j <- w_j N(m; kappa_j A_j, A_j^2 P_j + R_j),   then w <- (1 - floor) w + floor / n,

the floor keeping every hypothesis alive in case the ground changes. A path's predicted mass is
the mixture sum_j w_j kappa_j A_j(path), its standard deviation the mixture's. The prior weights
are a normal distribution around the assumed angle (prior_sigma_rad).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from planner.mass_per_area import MassPerArea
from planner.surface_estimate import Relax, SurfaceEstimate

WEIGHT_FLOOR = 0.02
"""Share of the weight spread evenly after each weighing: no hypothesis is ever ruled out."""


@dataclass(frozen=True)
class Hypothesis:
    """One angle of repose (rad) with its surface and its estimate of the mass per area."""

    repose_angle_rad: float
    surface: SurfaceEstimate
    estimate: MassPerArea


class ReposeBank:
    """Hypotheses at the angles `repose_angles_rad` ((n,) rad in (0, pi/2)), all starting from
    `surface`; prior weights normal around assumed_rad with sigma prior_sigma_rad (rad). relax:
    the slump kernel (SurfaceEstimate.slumped)."""

    def __init__(self, surface: SurfaceEstimate, repose_angles_rad: np.ndarray,
                 assumed_rad: float, prior_sigma_rad: float, relax: Relax) -> None:
        self.relax = relax
        angles = np.asarray(repose_angles_rad, dtype=float)
        if angles.ndim != 1 or len(angles) == 0 or not np.all((angles > 0.0)
                                                             & (angles < 0.5 * math.pi)):
            raise ValueError("the repose angles must be a non-empty (n,) array in (0, pi/2) rad")
        self.hypotheses = [Hypothesis(float(a), surface, MassPerArea()) for a in angles]
        prior = np.exp(-0.5 * ((angles - assumed_rad) / prior_sigma_rad) ** 2)
        self.weights = prior / prior.sum()

    @property
    def kappa_kg_m2(self) -> float | None:
        """The weights' mean mass per area (kg/m^2), None before the first weighing."""
        kappas = [h.estimate.kappa_kg_m2 for h in self.hypotheses]
        if any(k is None for k in kappas):
            return None
        return float(self.weights @ np.array(kappas))

    @property
    def kappa_sigma_kg_m2(self) -> float | None:
        """Standard deviation of the mixture of the kappa estimates (kg/m^2)."""
        mean = self.kappa_kg_m2
        if mean is None:
            return None
        second = sum(w * (h.estimate.variance_kg2_m4 + h.estimate.kappa_kg_m2**2)
                     for w, h in zip(self.weights, self.hypotheses, strict=True))
        return math.sqrt(max(second - mean**2, 0.0))

    @property
    def repose_angle_rad(self) -> float:
        """The weights' mean angle of repose (rad)."""
        return float(self.weights @ np.array([h.repose_angle_rad for h in self.hypotheses]))

    def envelope(self, tip_y_m: np.ndarray, tip_z_m: np.ndarray) -> np.ndarray:
        """The tip path's lowest height per cell (SurfaceEstimate.envelope): the same for every
        hypothesis (one grid), so a path's is computed once and passed to the methods below."""
        return self.hypotheses[0].surface.envelope(tip_y_m, tip_z_m)

    def predicted_mass_kg(self, lowest_m: np.ndarray) -> float | None:
        """The mixture's mass (kg) for a path's `envelope` (n,) m, None before a weighing."""
        masses = [h.estimate.predict_mass_kg(h.surface.area_above(lowest_m))
                  for h in self.hypotheses]
        if any(m is None for m in masses):
            return None
        return float(self.weights @ np.array(masses))

    def cautious_mass_kg(self, lowest_m: np.ndarray, min_weight: float) -> float | None:
        """The largest mass (kg) a hypothesis of weight >= min_weight predicts for a path's
        `envelope` (n,) m (None before a weighing). Where the angle decides the ground (an
        old trench's slopes under a new path) the mixture of surfaces slumped at different
        angles describes no ground at all; the plausible hypothesis that predicts most digs
        least deep."""
        masses = [h.estimate.predict_mass_kg(h.surface.area_above(lowest_m))
                  for h, w in zip(self.hypotheses, self.weights, strict=True)
                  if w >= min_weight]
        if not masses:  # min_weight above every weight: the most likely one
            h = self.hypotheses[int(np.argmax(self.weights))]
            masses = [h.estimate.predict_mass_kg(h.surface.area_above(lowest_m))]
        if any(m is None for m in masses):
            return None
        return float(max(masses))

    def learn(self, mass_kg: float, lowest_m: np.ndarray, noise_sigma_kg: float,
              model_share: float, drift_share: float,
              planned_lowest_m: np.ndarray | None = None) -> None:
        """Take in a weighing mass_kg (kg) of a period whose executed tip path had the
        `envelope` lowest_m (n,) m, planned_lowest_m (n,) m that of its planned path (None:
        the executed one): weights, then each kappa, both on the area of the planned path,
        then each surface cut to the executed path and slumped."""
        likelihoods, updated = [], []
        for h in self.hypotheses:
            area = h.surface.area_above(lowest_m if planned_lowest_m is None
                                        else planned_lowest_m)
            estimate = h.estimate
            if area > 1e-6 * h.surface.cell_m:  # a period that swept nothing says nothing
                if estimate.kappa_kg_m2 is not None:
                    predicted = estimate.kappa_kg_m2 * area
                    variance = (area**2 * estimate.variance_kg2_m4 + noise_sigma_kg**2
                                + (model_share * predicted) ** 2)
                    likelihoods.append(-0.5 * ((mass_kg - predicted) ** 2 / variance
                                               + math.log(variance)))
                estimate = estimate.weighed(mass_kg, area, noise_sigma_kg, model_share)
            surface = h.surface.lowered(lowest_m).slumped(h.repose_angle_rad, self.relax)
            updated.append(replace(h, surface=surface, estimate=estimate.drifted(drift_share)))
        if len(likelihoods) == len(self.hypotheses):
            log_w = np.log(self.weights) + np.array(likelihoods)
            w = np.exp(log_w - log_w.max())
            self.weights = (1.0 - WEIGHT_FLOOR) * w / w.sum() + WEIGHT_FLOOR / len(w)
        self.hypotheses = updated

    def drift(self, share: float) -> None:
        """Every kappa may move by `share` of itself (1 sigma): new ground."""
        self.hypotheses = [replace(h, estimate=h.estimate.drifted(share))
                           for h in self.hypotheses]

    def snapshot(self) -> dict[str, object]:
        """The bank as JSON-able data (weights, and per hypothesis its surface and kappa)."""
        saved: dict[str, object] = {"weights": self.weights.tolist(), "hypotheses": []}
        for h in self.hypotheses:
            entry: dict[str, object] = {"surface_z_m": h.surface.z_m.tolist()}
            if h.estimate.kappa_kg_m2 is not None:
                entry["mass_per_area_kg_m2"] = h.estimate.kappa_kg_m2
                entry["variance_kg2_m4"] = h.estimate.variance_kg2_m4
            saved["hypotheses"].append(entry)
        return saved

    def restore(self, saved: dict[str, object]) -> None:
        """Take back a `snapshot`; ValueError (one line) when it does not fit this bank."""
        try:
            weights = np.asarray(saved["weights"], dtype=float)
            entries = list(saved["hypotheses"])
        except (KeyError, TypeError, ValueError):
            raise ValueError("the terrain strategy's state lacks its weights or "
                             "hypotheses") from None
        n = len(self.hypotheses)
        if weights.shape != (n,) or len(entries) != n or not np.all(weights >= 0.0) \
                or not math.isclose(float(weights.sum()), 1.0, rel_tol=1e-9):
            raise ValueError(f"the terrain strategy's state must hold {n} hypotheses with "
                             "weights >= 0 summing to 1")
        restored = [_restored(h, entry) for h, entry in zip(self.hypotheses, entries,
                                                            strict=True)]
        self.weights, self.hypotheses = weights, restored


def _restored(h: Hypothesis, entry: object) -> Hypothesis:
    try:
        z = np.asarray(entry["surface_z_m"], dtype=float)  # type: ignore[index]
        kappa = entry.get("mass_per_area_kg_m2")  # type: ignore[union-attr]
        variance = float(entry.get("variance_kg2_m4", math.inf))  # type: ignore[union-attr]
    except (KeyError, TypeError, ValueError, AttributeError):
        raise ValueError("a hypothesis of the terrain strategy's state lacks its surface_z_m "
                         "or holds a mass per area that is not a number") from None
    if z.shape != h.surface.z_m.shape or not np.all(np.isfinite(z)):
        raise ValueError(f"the terrain strategy's surfaces must be {len(h.surface.z_m)} "
                         "finite heights")
    if kappa is not None and not (isinstance(kappa, float) and math.isfinite(kappa)
                                  and kappa >= 0.0 and 0.0 <= variance < math.inf):
        raise ValueError("the terrain strategy's mass per area and its variance must be "
                         "finite numbers >= 0")
    return replace(h, surface=SurfaceEstimate(h.surface.y_m, z),
                   estimate=MassPerArea(kappa, variance if kappa is not None else math.inf))
