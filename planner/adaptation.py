"""Period-to-period adaptation of the deepest point D = (y_D, z_D) (Vu & Tran 2020, section 2.3).

After each digging period k the weighed mass m_k gives the error dm_k = m* - m_k (kg); the fuzzy
rule eps (planner.fuzzy) turns it into a change of the depth step dz, and D moves (paper eq. 5):

    dz(k+1)  = dz(k) + eps(dm_k)
    z_D(k+1) = z_D(k) - dz(k+1)

so dz > 0 digs deeper. Periods are numbered from 1 as in the paper's Figures 9 and 15; the
paper's initial values z_D(0) = z_D0, dz(0) = dz_0 are the deepest point of period 1 and the step
that "produced" it.

Workspace limit (paper section 2.3 and Fig. 5): when the path through the next D is out of reach
or beyond a joint limit, z_D and dz go back to their defaults and y_D shifts by dy_0, and the
flag records that y_D has been shifted. If the path is still out of reach after the shift, or
the flag was already set, the algorithm ends. Reading of Fig. 5 used here: the flag is never
cleared, so y_D shifts at most once per campaign. The paper's text supports this ("the variable
flag in the algorithm indicates that y_D is already changed"; one shift in Figure 9's 20 periods),
and it keeps the dig site to two trenches. Ending is a normal outcome, returned as a Decision with
reason WORKSPACE_LIMIT, never an exception.

Reachability is injected as ``reachable(y_D_m, z_D_m) -> bool`` so this module needs no
geometry; the caller binds the machine and path shape into it.

Example, with a stub workspace that reaches down to z = -1.8 m:

>>> from planner.fuzzy import FuzzyRule
>>> rule = FuzzyRule.paper(target_mass_kg=30.0)
>>> defaults = AdaptationDefaults()           # the paper's D0 = (-9, -0.1) m
>>> reachable = lambda y_D, z_D: z_D > -1.8
>>> first = initial_state(defaults, reachable).next_state
>>> (first.k, first.y_D, first.z_D, first.dz)
(1, -9.0, -0.1, -0.075)
>>> d = next_deepest_point(first, 8.5, 30.0, rule, defaults, reachable)  # 21.5 kg short
>>> (d.eps_m, d.next_state.k, round(d.next_state.dz, 12), round(d.next_state.z_D, 12))
(0.4, 2, 0.325, -0.425)
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace

WORKSPACE_LIMIT = "workspace limit"
"""Decision.reason when the path is out of reach even after the one shift of y_D."""

Reachable = Callable[[float, float], bool]
"""reachable(y_D_m, z_D_m): True when the digging path through D is inside the workspace and
every joint limit (the caller binds machine geometry and path shape)."""

Rule = Callable[[float], float]
"""eps_m = rule(dm_kg), e.g. a planner.fuzzy.FuzzyRule."""


@dataclass(frozen=True)
class AdaptationDefaults:
    """Default deepest point and steps of a campaign; all in metres.

    Attributes:
        y_D0: horizontal position of D (m), negative in front of the machine. Paper section 3.2:
            D0 = (-9, -0.1) m.
        z_D0: height of D (m), ground at 0, up positive. Paper section 3.2: -0.1 m.
        dz_0: initial depth step dz(0) (m), positive digs deeper. -0.075 m: the value a
            kinematic re-run of the paper's Figure 9 scenario found to work (the paper gives
            none); it only seeds the integrator of eq. 5.
        dy_0: shift of y_D (m) at the workspace limit, positive toward the machine (y_D goes
            from -9 to -5.5 m). 3.5 m from the same re-run: less lands the new path in the old
            trench, more runs into the inner reach limit.
    """

    y_D0: float = -9.0
    z_D0: float = -0.1
    dz_0: float = -0.075
    dy_0: float = 3.5

    def __post_init__(self) -> None:
        _require_finite(self, ("y_D0", "z_D0", "dz_0", "dy_0"))


@dataclass(frozen=True)
class AdaptationState:
    """Where period k digs and how it got there.

    Attributes:
        y_D: horizontal position of the deepest point D (m), negative in front of the machine.
        z_D: height of D (m), ground at 0, up positive.
        dz: the last depth step dz(k) (m) of eq. 5, positive digs deeper.
        flag: True once y_D has been shifted by dy_0 (paper Fig. 5's flag; never cleared).
        k: period index, 1 for the first period.
    """

    y_D: float
    z_D: float
    dz: float
    flag: bool
    k: int

    def __post_init__(self) -> None:
        _require_finite(self, ("y_D", "z_D", "dz"))
        if not isinstance(self.flag, bool):
            raise ValueError(f"flag must be a bool, got {self.flag!r}")
        if isinstance(self.k, bool) or not isinstance(self.k, int) or self.k < 1:
            raise ValueError(f"k (period index) must be an int >= 1, got {self.k!r}")


@dataclass(frozen=True)
class Decision:
    """Outcome of one adaptation step.

    Attributes:
        next_state: the state for the next period, or None when the campaign ends.
        reset: True when z_D and dz went back to their defaults and y_D shifted by dy_0.
        terminated: True when the campaign ends (next_state is None).
        reason: WORKSPACE_LIMIT when terminated, else None.
        eps_m: the rule's correction eps(dm) (m), reported even when a reset discards it;
            None for the first period (no weighing yet).
        dm_kg: the weight error m* - m (kg) that drove the step; None for the first period.
        predicted_mass_kg: the mass the next period is predicted to dig (kg), from a strategy
            that predicts it (planner.terrain); None otherwise.
        mass_per_area_kg_m2, mass_per_area_sigma_kg_m2: that strategy's estimate of the
            material's mass per swept area and its standard deviation (kg/m^2); None otherwise.
    """

    next_state: AdaptationState | None
    reset: bool
    terminated: bool
    reason: str | None
    eps_m: float | None = None
    dm_kg: float | None = None
    predicted_mass_kg: float | None = None
    mass_per_area_kg_m2: float | None = None
    mass_per_area_sigma_kg_m2: float | None = None


def initial_state(defaults: AdaptationDefaults, reachable: Reachable) -> Decision:
    """The deepest point of period 1: D0 = (y_D0, z_D0) with dz = dz_0 (eq. 5's initial values).

    Checked like every later period: if D0 is out of reach, y_D shifts once by dy_0; if that is
    out of reach too, the Decision is terminated with reason WORKSPACE_LIMIT.
    """
    candidate = AdaptationState(
        y_D=defaults.y_D0, z_D=defaults.z_D0, dz=defaults.dz_0, flag=False, k=1
    )
    return _place(candidate, defaults, reachable, eps_m=None, dm_kg=None)


def next_deepest_point(
    state: AdaptationState,
    dug_mass_kg: float,
    target_mass_kg: float,
    rule: Rule,
    defaults: AdaptationDefaults,
    reachable: Reachable,
) -> Decision:
    """The deepest point of period k+1 from period k's state and weighed mass (paper eq. 5).

    Args:
        state: the state period k dug with.
        dug_mass_kg: m_k, the mass weighed after period k (kg); any finite value (a noisy load
            cell may read slightly below zero).
        target_mass_kg: m*, the wanted mass per period (kg), finite and > 0.
        rule: eps_m = rule(dm_kg), e.g. planner.fuzzy.FuzzyRule.paper(target_mass_kg).
        defaults: D0 and the steps dz_0, dy_0 to fall back on at the workspace limit.
        reachable: reachable(y_D_m, z_D_m) -> bool for the path through a candidate D.

    Returns:
        A Decision: the next state (k+1), possibly after the reset-and-shift, or terminated
        with reason WORKSPACE_LIMIT. Raises ValueError only for bad input (a non-finite mass,
        a non-positive target, a rule returning a non-finite correction).
    """
    if not _is_finite_number(dug_mass_kg):
        raise ValueError(f"dug_mass_kg must be a finite mass in kg, got {dug_mass_kg!r}")
    if not (_is_finite_number(target_mass_kg) and target_mass_kg > 0.0):
        raise ValueError(f"target_mass_kg must be a finite mass > 0 kg, got {target_mass_kg!r}")
    dm_kg = float(target_mass_kg) - float(dug_mass_kg)
    eps_m = rule(dm_kg)
    if not _is_finite_number(eps_m):
        raise ValueError(f"rule returned a non-finite correction {eps_m!r} m for dm = {dm_kg} kg")
    eps_m = float(eps_m)
    dz = state.dz + eps_m
    candidate = replace(state, z_D=state.z_D - dz, dz=dz, k=state.k + 1)
    return _place(candidate, defaults, reachable, eps_m=eps_m, dm_kg=dm_kg)


class RuleAdaptation:
    """Eq. 5 driven by a rule, as a strategy object with the interface
    planner.terrain.TerrainAdaptation shares (orchestrator.campaign.strategy). rule:
    eps_m = rule(dm_kg); target_mass_kg: m* (kg); reachable: as for next_deepest_point."""

    def __init__(self, rule: Rule, defaults: AdaptationDefaults, target_mass_kg: float,
                 reachable: Reachable) -> None:
        self.rule, self.defaults, self.reachable = rule, defaults, reachable
        self.target_mass_kg = target_mass_kg

    def initial(self) -> Decision:
        return initial_state(self.defaults, self.reachable)

    def learn(self, weighed_mass_kg: float, joints_rad: object) -> None:
        """Nothing: eq. 5 holds all it knows in the AdaptationState."""

    def decide(self, state: AdaptationState, weighed_mass_kg: float) -> Decision:
        return next_deepest_point(state, weighed_mass_kg, self.target_mass_kg, self.rule,
                                  self.defaults, self.reachable)

    def snapshot(self) -> None:
        """None: nothing beyond the AdaptationState to keep for a resume."""
        return None

    def restore(self, saved: object) -> None:
        """Nothing to take back (snapshot is None)."""


def _place(
    candidate: AdaptationState,
    defaults: AdaptationDefaults,
    reachable: Reachable,
    eps_m: float | None,
    dm_kg: float | None,
) -> Decision:
    """Accept the candidate D, or apply Fig. 5's reset-and-shift once, or end the campaign."""
    if reachable(candidate.y_D, candidate.z_D):
        return Decision(candidate, reset=False, terminated=False, reason=None,
                        eps_m=eps_m, dm_kg=dm_kg)
    if not candidate.flag:
        shifted = replace(candidate, y_D=candidate.y_D + defaults.dy_0, z_D=defaults.z_D0,
                          dz=defaults.dz_0, flag=True)
        if reachable(shifted.y_D, shifted.z_D):
            return Decision(shifted, reset=True, terminated=False, reason=None,
                            eps_m=eps_m, dm_kg=dm_kg)
    return Decision(None, reset=False, terminated=True, reason=WORKSPACE_LIMIT,
                    eps_m=eps_m, dm_kg=dm_kg)


def _is_finite_number(value: object) -> bool:
    try:
        return not isinstance(value, bool) and math.isfinite(value)  # type: ignore[arg-type]
    except TypeError:
        return False


def _require_finite(obj: object, names: tuple[str, ...]) -> None:
    """Check that the named fields are finite numbers and store them as plain floats."""
    for name in names:
        value = getattr(obj, name)
        if not _is_finite_number(value):
            raise ValueError(f"{name} must be a finite number of metres, got {value!r}")
        object.__setattr__(obj, name, float(value))
