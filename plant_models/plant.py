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
    """A machine the campaign can dig with, period after period: run_period and close; the
    optional parts are PlantExtras, a failure mid-period may be a PeriodStopped."""

    kind: str  # "sim" or "lab"

    def run_period(self, reference: JointReference) -> PeriodMeasurement:
        """Track `reference`, weigh the bucket at the end, empty it, and report."""
        ...

    def close(self) -> None:
        """Release every resource (FMU instances, buses); safe to call twice."""
        ...


class PeriodStopped(RuntimeError):
    """A plant's failure in the middle of a period that hands over what it measured until then
    (`partial`, or None): the campaign logs it without a period record, so nothing measured is
    lost. Raised from `Plant.run_period` (the lab excavator's LabStop; a tracking bound)."""

    def __init__(self, message: str, partial: PeriodMeasurement | None = None) -> None:
        super().__init__(message)
        self.partial = partial


class PlantExtras(Protocol):
    """The optional parts of a plant: each is used when the plant has it, through the function
    of the same name below (which says what holds without it). The simulated excavator has all
    of them; the lab excavator none.

    communication_step_s: its sample step, s (without: the scenario's plant.communication_step_s).
    temporary_folders(): folders it made that must go when a stuck run is ended from another
        thread (extracted FMUs).
    initial_pile_surface(): the pile surface before the first period (y (n,) m, z (n,) m).
    resume_state(): JSON-able state after the last period, for `run --resume`
        (orchestrator.campaign.resume_state); None when it cannot save one.
    """

    communication_step_s: float

    def temporary_folders(self) -> list[str]: ...

    def initial_pile_surface(self) -> tuple[np.ndarray, np.ndarray] | None: ...

    def resume_state(self) -> dict | None: ...


def communication_step_s(plant: Plant, default_s: float) -> float:
    """The plant's sample step (s), or `default_s` for a plant that does not say."""
    return float(getattr(plant, "communication_step_s", default_s))


def temporary_folders(plant: Plant) -> list[str]:
    """The folders the plant asks to be removed if a run is ended for it; [] without."""
    method = getattr(plant, "temporary_folders", None)
    return list(method()) if callable(method) else []


def resume_state(plant: Plant) -> dict | None:
    """The plant's saved state after the last period, or None (a plant that cannot save one)."""
    method = getattr(plant, "resume_state", None)
    return method() if callable(method) else None


def initial_pile_surface(plant: Plant) -> tuple[np.ndarray, np.ndarray] | None:
    """The pile surface before the first period, (y (n,) m, z (n,) m), or None.

    Optional for a plant (a simulation knows its pile, a real machine does not): a plant that
    knows it offers an `initial_pile_surface()` method returning the same, at the latest once
    its first period has run."""
    method = getattr(plant, "initial_pile_surface", None)
    return method() if callable(method) else None
