"""The Plant protocol: what the campaign talks to once per digging period.

A plant receives the joint reference of one period as plain sampled data, drives the arm along
it, weighs the bucket at the end and empties it, and returns what it measured. Implementations:
the simulated excavator (FMUs, in the orchestrator) and the lab excavator (CAN, later). The
campaign, the logger and the tests depend only on this module's types.

Joint order everywhere: boom, stick, bucket; angles relative to the previous link
(plant_models.geometry).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np

JOINTS: tuple[str, str, str] = ("boom", "stick", "bucket")


@dataclass(frozen=True, eq=False)
class JointReference:
    """The joint reference of one period, sampled on a uniform grid from t = 0 to its end.

    t_s: (n,) s, uniform, t_s[0] == 0.
    position_rad: (n, 3) rad. velocity_rad_s: (n, 3) rad/s. acceleration_rad_s2: (n, 3) rad/s^2
    (the plant may use velocity and acceleration as feed-forward).
    """

    t_s: np.ndarray
    position_rad: np.ndarray
    velocity_rad_s: np.ndarray
    acceleration_rad_s2: np.ndarray

    def __post_init__(self) -> None:
        n = len(self.t_s)
        if n < 2:
            raise ValueError("a joint reference needs at least two samples")
        for name in ("position_rad", "velocity_rad_s", "acceleration_rad_s2"):
            if np.shape(getattr(self, name)) != (n, len(JOINTS)):
                raise ValueError(f"JointReference.{name} must have shape ({n}, {len(JOINTS)})")


@dataclass(frozen=True, eq=False)
class PeriodMeasurement:
    """What a plant measured during one period.

    t_s: (m,) s, the plant's sample times (the communication grid for a simulation).
    joints_rad: (m, 3) rad measured joint angles. reference_rad: (m, 3) rad, the reference at t_s.
    weighed_mass_kg: the load cell's reading at the end of the period (noise included), before
        the bucket was emptied.
    signals: name -> (m,) array of further signals in SI units, e.g. "boom.p_A" (Pa),
        "pile.bucket_mass" (kg); names are "<component>.<variable>".
    pile_profile_m: (n_cells,) surface heights after the period (m), or None if unknown;
        pile_grid_m: (n_cells,) cell-centre y positions (m) or None.
    """

    t_s: np.ndarray
    joints_rad: np.ndarray
    reference_rad: np.ndarray
    weighed_mass_kg: float
    signals: dict[str, np.ndarray] = field(default_factory=dict)
    pile_profile_m: np.ndarray | None = None
    pile_grid_m: np.ndarray | None = None

    @property
    def tracking_rms_rad(self) -> np.ndarray:
        """(3,) rad RMS of measured minus reference joint angle over the period."""
        error = np.asarray(self.joints_rad) - np.asarray(self.reference_rad)
        return np.sqrt(np.mean(error**2, axis=0))


@runtime_checkable
class Plant(Protocol):
    """A machine the campaign can dig with, period after period."""

    kind: str  # "sim" or "lab"

    def run_period(self, reference: JointReference) -> PeriodMeasurement:
        """Track `reference`, weigh the bucket at the end, empty it, and report."""
        ...

    def close(self) -> None:
        """Release every resource (FMU instances, buses); safe to call twice."""
        ...


def initial_pile_surface(plant: Plant) -> tuple[np.ndarray, np.ndarray] | None:
    """The pile surface before the first period, (y (n,) m, z (n,) m), or None.

    Optional for a plant (a simulation knows its pile, a real machine does not): a plant that
    knows it offers an `initial_pile_surface()` method returning the same, at the latest once
    its first period has run."""
    method = getattr(plant, "initial_pile_surface", None)
    return method() if callable(method) else None
