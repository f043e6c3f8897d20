"""Terrain-aware adaptation of the deepest point D: dig where the predicted mass is the target.

The paper's rule (planner.adaptation with planner.fuzzy) reacts to the last weight error only.
The ground remembers earlier cuts: a trench's walls slump into it over the next periods, and
after the shift of y_D the first trench's slopes may reach the new D. This strategy keeps what
the planner itself knows, and nothing of the plant's state:

- its own estimate of the surface (planner.surface_estimate): flat at the path's nominal entry
  height, lowered after each period to the tip path the arm executed (forward kinematics of the
  measured joint angles), then slumped at an angle of repose;
- the material's mass per swept area kappa (planner.mass_per_area), re-estimated from each
  weighing with its uncertainty. The area a weighing is set against is the one the period's
  planned path sweeps on the surface it was planned on (the arm's own path only cuts the
  surface): the arm tracks its spline with a lag, and on the paper arm the executed tip path
  sweeps 1-8 % more than the planned one, growing as a trench deepens, so a kappa per executed
  area would make every prediction from a plan fall short by that much (the mass then came out
  1-3 kg over m* in every period of the first trench); per planned area, kappa lumps the
  tracking with the density, the slice width and the spill;
- since the angle it is told may be off, one such surface and kappa per hypothesis of the angle
  (the told one and REPOSE_OFFSETS_DEG around it), weighed by how well each predicted the
  weighings (planner.repose_bank).

For the next period it solves m(z_D) = m* for z_D at the current y_D, m(z_D) the bank's mixture
of kappa_j A_j(z_D), A_j the area between hypothesis j's surface and the tip path of the planned
trajectory through D (the period's own plan, planner.period_plan, so the prediction sees the
spline the arm will follow). When even the deepest reachable D is predicted to fall short by
more than `shortfall_share` of m*, y_D shifts once by dy_0 (paper Fig. 5's flag) and the first
depth there is chosen by the plausible hypothesis that predicts the most (the old trench's
slopes reach the new path, and only the angle says how far); with the flag set, the campaign
ends at the workspace limit. Period 1 digs at the paper's D0 (nothing weighed yet).

Decisions are planner.adaptation.Decision, with the predicted mass and kappa (with its standard
deviation) filled in; dz is the step z_D(k) - z_D(k+1) actually taken and eps its change, so the
record reads like eq. 5's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from scipy.optimize import brentq

from planner.adaptation import (
    WORKSPACE_LIMIT,
    AdaptationDefaults,
    AdaptationState,
    Decision,
    initial_state,
)
from planner.period_plan import PeriodPlanner
from planner.repose_bank import ReposeBank
from planner.surface_estimate import Relax, SurfaceEstimate
from plant_models.geometry import Unreachable, forward_kinematics

SURFACE_CELLS = 240
"""Cells of the surface estimate over the arm's reach (5 cm on the paper arm)."""
PLAN_SAMPLE_S = 0.02
"""Sampling of a planned trajectory for its tip path (s): 4 mm at the tip's 0.2 m/s in the cut."""
REACH_BISECTIONS = 6
REPOSE_OFFSETS_DEG = (-12.0, -8.0, -4.0, 0.0, 4.0, 8.0, 12.0)
"""The repose hypotheses around the assumed angle (deg): a told angle may be some degrees off."""
REPOSE_PRIOR_SIGMA_DEG = 6.0
PLAUSIBLE_WEIGHT = 0.2
"""Weight from which a repose hypothesis is plausible for the first cut after the shift."""


@dataclass(frozen=True)
class TerrainSettings:
    """What the terrain strategy assumes.

    repose_angle_rad: the angle (rad, in (0, pi/2)) the planner is told trench walls slump to
        (the centre of its hypotheses).
    weighing_sigma_kg: the load cell's noise (kg, 1 sigma, >= 0; a floor of 0.1 kg is added).
    model_share: relative error of a predicted mass (the cell resolution, the assumed repose,
        spill); it weights a weighing against the estimate.
    drift_share: how far kappa may move from one period to the next (relative, 1 sigma).
    new_ground_share: the same after the shift of y_D (0 by default: a kappa let loose there
        takes up the error of the surface under the new path, which the repose weights should
        take; measured on sweeps/terrain.toml, 0.2 left the period after the shift 5-7 kg short).
    shortfall_share: the share of m* by which the deepest reachable D may fall short before
        y_D shifts (or the campaign ends).
    depth_step_m: step (m, > 0) of the scan for the depth bracket before the root search.
    """

    repose_angle_rad: float
    weighing_sigma_kg: float = 0.0
    model_share: float = 0.05
    drift_share: float = 0.05
    new_ground_share: float = 0.0
    shortfall_share: float = 0.05
    depth_step_m: float = 0.1

    def __post_init__(self) -> None:
        if not 0.0 < self.repose_angle_rad < 0.5 * math.pi:
            raise ValueError(f"repose_angle_rad must lie in (0, pi/2), got "
                             f"{self.repose_angle_rad!r}")
        for name in ("weighing_sigma_kg", "model_share", "drift_share", "new_ground_share",
                     "shortfall_share"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise ValueError(f"{name} must be a finite number >= 0, got {value!r}")
        if not (math.isfinite(self.depth_step_m) and self.depth_step_m > 0.0):
            raise ValueError(f"depth_step_m must be > 0 m, got {self.depth_step_m!r}")


class TerrainAdaptation:
    """The terrain-aware strategy for one campaign: `initial()`, then per period `learn(...)` and
    `decide(...)` (orchestrator.campaign.strategy).

    planner: plans (and checks the reach of) the period through a D (its geometry and path
    shape give the forward kinematics and the nominal surface). defaults: D0, dy_0 (dz_0 is
    not used: the depth comes from the prediction). target_mass_kg: m* (kg, > 0). relax: the
    slump kernel (planner.surface_estimate.Relax: the C one, orchestrator.campaign.native_slump).
    """

    def __init__(self, planner: PeriodPlanner, defaults: AdaptationDefaults,
                 target_mass_kg: float, settings: TerrainSettings, relax: Relax) -> None:
        if not (math.isfinite(target_mass_kg) and target_mass_kg > 0.0):
            raise ValueError(f"target_mass_kg must be a finite mass > 0 kg, got "
                             f"{target_mass_kg!r}")
        self.planner, self.defaults, self.settings = planner, defaults, settings
        self.target_mass_kg = float(target_mass_kg)
        geometry = planner.geometry
        reach = geometry.boom_length_m + geometry.stick_length_m + geometry.bucket_length_m
        foot_y = geometry.boom_foot_m[0]
        surface = SurfaceEstimate.flat(foot_y - reach - 0.05 * reach, foot_y + 0.05 * reach,
                                       SURFACE_CELLS, planner.shape.entry_height_m)
        assumed = settings.repose_angle_rad
        angles = assumed + np.radians(REPOSE_OFFSETS_DEG)
        angles = angles[(angles > math.radians(15.0)) & (angles < math.radians(80.0))]
        self._cautious = False
        self._planned_D: tuple[float, float] | None = None
        self._envelopes: dict[tuple[float, float], np.ndarray | None] = {}
        self.bank = ReposeBank(surface, angles, assumed, math.radians(REPOSE_PRIOR_SIGMA_DEG),
                               relax)

    def initial(self) -> Decision:
        """Period 1 at D0 (or after the shift, if D0 is out of reach)."""
        decision = initial_state(self.defaults, self.planner.reachable)
        if decision.next_state is not None:
            self._planned_D = (decision.next_state.y_D, decision.next_state.z_D)
        return decision

    def learn(self, weighed_mass_kg: float, joints_rad: np.ndarray) -> None:
        """Take in a period: its weighing (kg) against the area its planned path swept (the
        last D this strategy handed out) scores the repose hypotheses and updates their kappa;
        then each surface is cut to the executed path (joints_rad, (m, 3) rad) and slumped
        (planner.repose_bank)."""
        _check_mass(weighed_mass_kg)
        s = self.settings
        tip_y, tip_z, _ = forward_kinematics(self.planner.geometry, np.asarray(joints_rad))
        planned = None if self._planned_D is None else self._envelope(*self._planned_D)
        self.bank.learn(float(weighed_mass_kg), self.bank.envelope(tip_y, tip_z),
                        math.hypot(s.weighing_sigma_kg, 0.1), s.model_share, s.drift_share,
                        planned_lowest_m=planned)

    def snapshot(self) -> dict[str, object]:
        """What `learn` has learnt, as JSON-able data (a resume record keeps it)."""
        return self.bank.snapshot()

    def restore(self, saved: dict[str, object]) -> None:
        """Take back a `snapshot`; ValueError (one line) when it does not fit this machine."""
        if not isinstance(saved, dict):
            raise ValueError("the terrain strategy's state is not an object")
        self.bank.restore(saved)

    def decide(self, state: AdaptationState, weighed_mass_kg: float) -> Decision:
        """The deepest point of period k+1 on what has been learnt (`learn`) so far."""
        _check_mass(weighed_mass_kg)
        dm_kg = self.target_mass_kg - float(weighed_mass_kg)
        kappa = self.bank.kappa_kg_m2
        if kappa is None or kappa <= 0.0:  # nothing learnt: eq. 5's last step again
            return self._decide(state, state.y_D, state.z_D - state.dz, False, dm_kg)
        depth = self._depth_for_target(state.y_D)
        if depth is not None and depth[1]:
            return self._decide(state, state.y_D, depth[0], False, dm_kg)
        if not state.flag:
            y_shifted = state.y_D + self.defaults.dy_0
            self.bank.drift(self.settings.new_ground_share)
            self._cautious = True  # the first cut at the new site: the old slopes reach it
            try:
                shifted = self._depth_for_target(y_shifted)
                if shifted is not None:
                    return self._decide(replace(state, flag=True), y_shifted, shifted[0], True,
                                        dm_kg)
            finally:
                self._cautious = False
        return Decision(None, reset=False, terminated=True, reason=WORKSPACE_LIMIT,
                        dm_kg=dm_kg, **self._estimate_fields(None))

    def predicted_mass_kg(self, y_D: float, z_D: float) -> float | None:
        """The mass (kg) the period through D is predicted to dig on what has been learnt;
        None when D is out of reach or nothing is weighed yet."""
        lowest = self._envelope(y_D, z_D)
        return None if lowest is None else self.bank.predicted_mass_kg(lowest)

    @property
    def repose_angle_estimate_rad(self) -> float:
        """The weighed mean of the repose hypotheses (rad)."""
        return self.bank.repose_angle_rad

    def _decide(self, state: AdaptationState, y_D: float, z_D: float, reset: bool,
                dm_kg: float) -> Decision:
        dz = (state.z_D if not reset else self.defaults.z_D0) - z_D
        eps = dz - state.dz
        if not self.planner.reachable(y_D, z_D):  # only without an estimate: eq. 5's step
            return Decision(None, reset=False, terminated=True, reason=WORKSPACE_LIMIT,
                            dm_kg=dm_kg)
        nxt = AdaptationState(y_D=y_D, z_D=z_D, dz=dz, flag=state.flag, k=state.k + 1)
        self._planned_D = (y_D, z_D)
        return Decision(nxt, reset=reset, terminated=False, reason=None, eps_m=eps, dm_kg=dm_kg,
                        **self._estimate_fields(self._mass(y_D, z_D)))

    def _estimate_fields(self, predicted: float | None) -> dict[str, float | None]:
        return {"predicted_mass_kg": predicted,
                "mass_per_area_kg_m2": self.bank.kappa_kg_m2,
                "mass_per_area_sigma_kg_m2": self.bank.kappa_sigma_kg_m2}

    def _envelope(self, y_D: float, z_D: float) -> np.ndarray | None:
        """The planned path's lowest tip height per cell through D, None out of reach; kept
        per D like the planner's plans (it depends on the plan and the grid only)."""
        key = (float(y_D), float(z_D))
        if key not in self._envelopes:
            plan = self.planner.plan(*key)
            if isinstance(plan, Unreachable):
                self._envelopes[key] = None
            else:
                t = np.linspace(0.0, plan.duration,
                                max(2, math.ceil(plan.duration / PLAN_SAMPLE_S) + 1))
                tip_y, tip_z, _ = forward_kinematics(self.planner.geometry, plan(t))
                self._envelopes[key] = self.bank.envelope(tip_y, tip_z)
        return self._envelopes[key]

    def _mass(self, y_D: float, z_D: float) -> float | None:
        """The predicted mass (kg) through D, or None out of reach (the search's measure); in
        the first period after the shift, the most any plausible repose hypothesis predicts."""
        if not self._cautious:
            return self.predicted_mass_kg(y_D, z_D)
        lowest = self._envelope(y_D, z_D)
        return None if lowest is None else self.bank.cautious_mass_kg(lowest, PLAUSIBLE_WEIGHT)

    def _depth_for_target(self, y_D: float) -> tuple[float, bool] | None:
        """(z_D, enough) at y_D: the z_D whose predicted mass is m*, enough = True; or the
        deepest reachable z_D, enough = False when even it falls short by more than
        shortfall_share; None when no z_D from the surface down is reachable."""
        wanted = self.target_mass_kg
        step = self.settings.depth_step_m
        surface = self.bank.hypotheses[0].surface  # where the ground starts, near enough
        top = float(np.interp(y_D, surface.y_m, surface.z_m))
        high = self.planner.shape.entry_height_m + 10 * step
        z, mass = top, self._mass(y_D, top)
        if mass is None:
            return None
        while mass >= wanted and z + step <= high:  # heaped ground: the target above it
            z_above, mass_above = z + step, self._mass(y_D, z + step)
            if mass_above is None or mass_above < wanted:
                return self._root(y_D, z_above, z, wanted), True
            z, mass = z_above, mass_above
        if mass >= wanted:
            return z, True
        while True:
            z_below = z - step
            mass_below = self._mass(y_D, z_below)
            if mass_below is None:
                z_below, mass_below = self._reach_limit(y_D, z, z_below)
                if mass_below is None or z_below >= z:
                    z_below, mass_below = z, mass
                if mass_below < wanted:
                    short = mass_below < (1.0 - self.settings.shortfall_share) * wanted
                    return z_below, not short
            if mass_below >= wanted:
                return self._root(y_D, z, z_below, wanted), True
            z, mass = z_below, mass_below

    def _reach_limit(self, y_D: float, reachable_z: float,
                     unreachable_z: float) -> tuple[float, float | None]:
        """The deepest reachable z_D between the two (bisection) and its predicted mass."""
        for _ in range(REACH_BISECTIONS):
            middle = 0.5 * (reachable_z + unreachable_z)
            if self.planner.reachable(y_D, middle):
                reachable_z = middle
            else:
                unreachable_z = middle
        return reachable_z, self._mass(y_D, reachable_z)

    def _root(self, y_D: float, z_high: float, z_low: float, wanted: float) -> float:
        """z_D in [z_low, z_high] predicted to dig `wanted` kg (less at z_high, not at z_low)."""
        def excess(z: float) -> float:
            mass = self._mass(y_D, z)
            return (-wanted if mass is None else mass - wanted)

        return float(brentq(excess, z_low, z_high, xtol=2e-3))


def _check_mass(weighed_mass_kg: float) -> None:
    if isinstance(weighed_mass_kg, bool) or not (
            isinstance(weighed_mass_kg, (int, float)) and math.isfinite(weighed_mass_kg)):
        raise ValueError(f"dug_mass_kg must be a finite mass in kg, got {weighed_mass_kg!r}")
