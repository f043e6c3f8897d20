"""The planner's own estimate of the ground surface, kept from the tip paths the arm executed.

The planner never sees the pile. It starts from flat ground at the nominal surface height and,
after each period, lowers the surface to the lower envelope of the tip path the arm really
followed (forward kinematics of the measured joint angles), then lets the walls slump to an
assumed angle of repose: steps between neighbouring cells steeper than dy tan(repose) relax by
conservative transfers, so the material that falls back into the trench is the material the
walls lose (the soil's memory of earlier cuts that a rule reacting to the last weight alone
does not have). The area between this surface and the envelope of a planned path is the area
that path is predicted to cut.

Units: m throughout; the surface z(y) is sampled at cell centres `y_m` (n,) of width `cell_m`.

The slump needs a kernel (`Relax`) that the caller hands in: the planner builds no native
code, and the one kernel is C (planner/native/slump.c, loaded by
orchestrator.campaign.native_slump; tests/slump_reference.py is the numpy oracle of the tests).

>>> surface = SurfaceEstimate.flat(-3.0, 0.0, cells=60, height_m=0.0)
>>> tip_y, tip_z = np.array([-2.49, -1.51]), np.array([-0.2, -0.2])  # 20 cells, 0.2 m deep
>>> round(surface.swept_area(tip_y, tip_z), 9)
0.2
>>> cut = surface.cut(tip_y, tip_z)
>>> round(float(cut.z_m.sum() * cut.cell_m), 9)        # the cut's 0.2 m^2 is gone, no more
-0.2
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

RELAX_TOLERANCE_M = 1e-5
"""A step may exceed dy tan(repose) by this much (m) when the slump stops."""
RELAX_MAX_SWEEPS = 20_000


@dataclass(frozen=True)
class SurfaceEstimate:
    """Surface heights z_m (n,) (m) at cell centres y_m (n,) (m, increasing, spacing cell_m)."""

    y_m: np.ndarray
    z_m: np.ndarray

    @staticmethod
    def flat(y_low_m: float, y_high_m: float, cells: int, height_m: float) -> SurfaceEstimate:
        """Flat ground at height_m (m) over [y_low_m, y_high_m] (m) in `cells` cells."""
        if not (math.isfinite(y_low_m) and math.isfinite(y_high_m) and y_low_m < y_high_m):
            raise ValueError(f"the surface needs a finite range y_low < y_high, got "
                             f"[{y_low_m}, {y_high_m}] m")
        if cells < 2:
            raise ValueError(f"the surface needs at least 2 cells, got {cells}")
        if not math.isfinite(height_m):
            raise ValueError(f"height_m must be finite, got {height_m!r}")
        edges = np.linspace(y_low_m, y_high_m, cells + 1)
        return SurfaceEstimate(0.5 * (edges[1:] + edges[:-1]), np.full(cells, float(height_m)))

    @property
    def cell_m(self) -> float:
        return float(self.y_m[1] - self.y_m[0])

    def envelope(self, tip_y_m: np.ndarray, tip_z_m: np.ndarray) -> np.ndarray:
        """(n,) m: the lowest height of the tip path (tip_y_m, tip_z_m) (m, (p,) each) over each
        cell (+inf where it does not pass). The path is resampled along its length at a quarter
        cell so that no cell it crosses is skipped."""
        y, z = np.asarray(tip_y_m, dtype=float), np.asarray(tip_z_m, dtype=float)
        if y.shape != z.shape or y.ndim != 1 or not (np.all(np.isfinite(y))
                                                     and np.all(np.isfinite(z))):
            raise ValueError("the tip path must be two finite arrays of the same shape (p,)")
        step = np.hypot(np.diff(y), np.diff(z))
        length = np.concatenate([[0.0], np.cumsum(step)])
        samples = np.linspace(0.0, length[-1], max(2, int(length[-1] / (0.25 * self.cell_m)) + 2))
        keep = np.concatenate([[True], step > 0.0])  # np.interp needs increasing abscissae
        path_y = np.interp(samples, length[keep], y[keep])
        path_z = np.interp(samples, length[keep], z[keep])
        cell = np.floor((path_y - self.y_m[0]) / self.cell_m + 0.5).astype(int)
        inside = (cell >= 0) & (cell < len(self.y_m))
        lowest = np.full(len(self.y_m), np.inf)
        np.minimum.at(lowest, cell[inside], path_z[inside])
        return lowest

    def swept_area(self, tip_y_m: np.ndarray, tip_z_m: np.ndarray) -> float:
        """Area (m^2) of ground above the tip path: what the path is predicted to cut."""
        return self.area_above(self.envelope(tip_y_m, tip_z_m))

    def area_above(self, lowest_m: np.ndarray) -> float:
        """Area (m^2) of ground above an `envelope` (n,) m (of any surface on this grid)."""
        depth = self.z_m - lowest_m
        return float(np.sum(depth[depth > 0.0]) * self.cell_m)

    def cut(self, tip_y_m: np.ndarray, tip_z_m: np.ndarray) -> SurfaceEstimate:
        """The surface lowered to the tip path wherever the path ran below it."""
        return self.lowered(self.envelope(tip_y_m, tip_z_m))

    def lowered(self, lowest_m: np.ndarray) -> SurfaceEstimate:
        """The surface lowered to an `envelope` (n,) m wherever it runs below it."""
        return SurfaceEstimate(self.y_m, np.minimum(self.z_m, lowest_m))

    def slumped(self, repose_angle_rad: float, relax: Relax) -> SurfaceEstimate:
        """The surface after its walls slumped to repose_angle_rad (rad, in (0, pi/2)).

        relax: the kernel that levels the steps (`Relax`)."""
        if not 0.0 < repose_angle_rad < 0.5 * math.pi:
            raise ValueError(f"repose_angle_rad must lie in (0, pi/2), got {repose_angle_rad!r}")
        z = self.z_m.copy()
        relax(z, self.cell_m * math.tan(repose_angle_rad))
        return SurfaceEstimate(self.y_m, z)


Relax = Callable[[np.ndarray, float], None]
"""A slump kernel: relax(z_m, allowed_m) levels the heights z_m (n,) m in place, by conservative
transfers between neighbours: half-sweeps over the even, then the odd pairs (each set of pairs
is disjoint, so every transfer levels its pair to the allowed step exactly), until no step
exceeds allowed_m (m) by more than RELAX_TOLERANCE_M, or RELAX_MAX_SWEEPS."""
