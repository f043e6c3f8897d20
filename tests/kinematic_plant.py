"""A test double of the Plant protocol: a rigid arm that tracks its reference exactly, digging
a ground profile whose cut area sets the weighed mass.

The tip (forward kinematics of the reference) lowers every ground cell it passes over to its own
height; the mass is density x width x the area removed (kg). No slumping, no capacity, no noise:
just enough ground memory that digging the same spot deeper is needed to keep the mass up.
"""

from __future__ import annotations

import numpy as np

from plant_models.geometry import ExcavatorGeometry, forward_kinematics
from plant_models.plant import JointReference, PeriodMeasurement


class KinematicPlant:
    kind = "sim"

    def __init__(self, geometry: ExcavatorGeometry, communication_step_s: float = 0.02,
                 density_width_kg_m2: float = 61.0, y_range_m: tuple[float, float] = (-13, -2),
                 cells: int = 1100, fail_in_period: int | None = None) -> None:
        self.geometry = geometry
        self.communication_step_s = communication_step_s
        self.density_width_kg_m2 = density_width_kg_m2
        self.y_m = np.linspace(*y_range_m, cells)
        self.cell_m = self.y_m[1] - self.y_m[0]
        self.ground_m = np.zeros(cells)
        self.fail_in_period = fail_in_period
        self.references: list[JointReference] = []
        self.closed = 0

    def run_period(self, reference: JointReference) -> PeriodMeasurement:
        self.references.append(reference)
        if self.fail_in_period == len(self.references):
            raise RuntimeError("hydraulic hose burst (test double)")
        tip_y, tip_z, _ = forward_kinematics(self.geometry, reference.position_rad)
        # Sample the tip path finely enough that no cell is jumped over.
        fine = np.linspace(0.0, len(tip_y) - 1.0, 20 * len(tip_y))
        index = np.arange(len(tip_y))
        path_y, path_z = np.interp(fine, index, tip_y), np.interp(fine, index, tip_z)
        cell = np.clip(np.round((path_y - self.y_m[0]) / self.cell_m).astype(int), 0,
                       len(self.y_m) - 1)
        lowest = np.full_like(self.ground_m, np.inf)
        np.minimum.at(lowest, cell, path_z)
        cut = np.clip(self.ground_m - lowest, 0.0, None)
        self.ground_m -= cut
        mass = self.density_width_kg_m2 * float(cut.sum()) * self.cell_m
        return PeriodMeasurement(
            t_s=reference.t_s, joints_rad=reference.position_rad,
            reference_rad=reference.position_rad, weighed_mass_kg=mass,
            pile_profile_m=self.ground_m.copy(), pile_grid_m=self.y_m.copy())

    def close(self) -> None:
        self.closed += 1
