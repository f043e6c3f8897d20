"""Sugeno fuzzy rule eps(dm): dug-weight error (kg) -> change of the dig-depth step (m).

Vu & Tran 2020, section 2.3: one input, the weight error dm = m* - m (kg) of the last period;
seven triangular membership functions (eq. 6) named vnb, nb, ns, zero, ps, pb, vpb; a
zero-order Sugeno rule base "if dm is <term i> then eps is r_i" with
r = [-0.4, -0.25, -0.1, 0, 0.1, 0.25, 0.4] m; weighted-average defuzzification

    eps(dm) = sum_i mu_i(dm) r_i / sum_i mu_i(dm).

The partition is the standard one of adjacent triangles: term i peaks at its centre c_i and its
feet (a, c of eq. 6) are the neighbouring centres c_{i-1} and c_{i+1}. The two outer terms are
shoulders (vnb is 1 for every dm <= c_1, vpb is 1 for every dm >= c_7), so every dm has full
membership: the memberships add up to 1 everywhere and at most two adjacent terms fire. The rule
is then the piecewise-linear curve through (c_i, r_i), constant beyond the outer centres.

Sign convention: dm > 0 means the bucket came up too light, so eps > 0 enlarges the next depth
step dz and the deepest point goes down (paper eq. 5, see planner.adaptation).

Example (the default partition for a 30 kg target: centres 0, +-3, +-9, +-18 kg):

>>> rule = FuzzyRule.paper(target_mass_kg=30.0)
>>> rule.centres_kg
(-18.0, -9.0, -3.0, 0.0, 3.0, 9.0, 18.0)
>>> rule(21.5)            # first period of the paper's Figure 9: 8.5 kg dug for 30 kg wanted
0.4
>>> round(rule(6.0), 12)  # halfway between the ps and pb centres
0.175
>>> rule([-3.0, 0.0, 1.5]).tolist()
[-0.1, 0.0, 0.05]
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from numbers import Real

import numpy as np
from numpy.typing import ArrayLike

TERMS: tuple[str, ...] = ("vnb", "nb", "ns", "zero", "ps", "pb", "vpb")
"""Linguistic terms of the input, most negative first (paper section 2.3)."""

PAPER_OUTPUTS_M: tuple[float, ...] = (-0.4, -0.25, -0.1, 0.0, 0.1, 0.25, 0.4)
"""Crisp rule outputs r_1..r_7 in metres, as printed in the paper (section 2.3)."""

PAPER_CENTRE_FRACTIONS: tuple[float, float, float] = (0.1, 0.3, 0.6)
"""Centres of ps, pb, vpb as fractions of the target mass m* (the negative terms mirror them).

The paper prints the outputs r_i but no breakpoints for eq. 6, so they are chosen here:
- vpb at 0.6 m*: a kinematic re-run of the paper's Figure 9 scenario kept the error within
  +-5 kg after period 1 only with the outer centres in 0.5-0.67 m*; 0.6 lies inside that window.
  The first period's error in the paper (30 - 8.5 = 21.5 kg = 0.72 m*) then saturates at the
  largest correction r_7 = 0.4 m.
- ps at 0.1 m* (3 kg for m* = 30 kg): the +-3 kg band the paper's Figure 9 holds after period 1,
  so an error inside the band moves the step by at most r_5 = 0.1 m.
- pb at 0.3 m*: between them; the spacing widens away from zero (ratios 3 and 2), giving fine
  resolution for small errors and a quick ramp to the largest corrections for gross ones.
"""


@dataclass(frozen=True)
class FuzzyRule:
    """Zero-order Sugeno rule eps(dm) with seven adjacent triangles (paper eq. 6).

    Attributes:
        centres_kg: the 7 membership centres c_1 < ... < c_7 of vnb..vpb, in kg of weight error.
            Term i is the triangle (a, b, c) = (c_{i-1}, c_i, c_{i+1}) of eq. 6; vnb and vpb are
            shoulders that stay at 1 below c_1 and above c_7.
        outputs_m: the 7 crisp outputs r_1..r_7, in metres (default: the paper's values).

    Calling the rule with dm (kg; a float, or an array of any shape) returns eps (m; a float, or
    an ndarray of the same shape).
    """

    centres_kg: tuple[float, ...]
    outputs_m: tuple[float, ...] = PAPER_OUTPUTS_M

    def __post_init__(self) -> None:
        centres = _seven_finite("centres_kg", self.centres_kg)
        outputs = _seven_finite("outputs_m", self.outputs_m)
        if any(right <= left for left, right in zip(centres, centres[1:], strict=False)):
            raise ValueError(f"centres_kg must be strictly increasing, got {centres}")
        # Store plain float tuples so equality, hashing and repr do not depend on the input type.
        object.__setattr__(self, "centres_kg", centres)
        object.__setattr__(self, "outputs_m", outputs)

    @classmethod
    def paper(
        cls,
        target_mass_kg: float,
        centre_fractions: tuple[float, float, float] = PAPER_CENTRE_FRACTIONS,
    ) -> FuzzyRule:
        """The paper's rule for a target dug mass m* (kg), with the outputs r_i of section 2.3.

        Centres are 0 and +-f*m* for f in ``centre_fractions`` (see PAPER_CENTRE_FRACTIONS for
        why 0.1, 0.3, 0.6), so the rule scales with the target: the same relative error gives
        the same correction for any m*.
        """
        if not (_is_finite_real(target_mass_kg) and target_mass_kg > 0.0):
            raise ValueError(f"target_mass_kg must be a finite mass > 0 kg, got {target_mass_kg!r}")
        fractions = tuple(float(f) for f in centre_fractions)
        if len(fractions) != 3:
            raise ValueError(f"centre_fractions must have 3 values (ps, pb, vpb), got {fractions}")
        positive = tuple(f * float(target_mass_kg) for f in fractions)
        return cls(centres_kg=(*(-c for c in reversed(positive)), 0.0, *positive))

    @property
    def breakpoints_kg(self) -> tuple[tuple[float, float, float], ...]:
        """The (a, b, c) of eq. 6 for each term vnb..vpb, in kg.

        The shoulders have a = -inf (vnb) or c = +inf (vpb): their membership stays 1 there.
        """
        c = (-math.inf, *self.centres_kg, math.inf)
        return tuple((c[i], c[i + 1], c[i + 2]) for i in range(len(TERMS)))

    def memberships(self, dm_kg: ArrayLike) -> np.ndarray:
        """Degrees of membership of dm (kg) in vnb..vpb: shape dm.shape + (7,), each in [0, 1].

        Eq. 6 in its max-min form mu = clip(min((x - a)/(b - a), (c - x)/(c - b)), 0, 1); a
        shoulder has no rising (vnb) or falling (vpb) side.
        """
        x = _finite_array(dm_kg)[..., np.newaxis]
        c = np.asarray(self.centres_kg)
        rising = np.full(x.shape[:-1] + (len(TERMS),), np.inf)
        falling = np.full_like(rising, np.inf)
        rising[..., 1:] = (x - c[:-1]) / (c[1:] - c[:-1])
        falling[..., :-1] = (c[1:] - x) / (c[1:] - c[:-1])
        return np.clip(np.minimum(rising, falling), 0.0, 1.0)

    def __call__(self, dm_kg: ArrayLike) -> float | np.ndarray:
        """eps (m) for a weight error dm = m* - m (kg), by weighted-average defuzzification.

        A float (or int, or numpy scalar) gives a float; an array or list gives an ndarray of
        the same shape. Raises ValueError for a non-finite dm.
        """
        mu = self.memberships(dm_kg)
        eps = (mu @ np.asarray(self.outputs_m)) / mu.sum(axis=-1)
        return float(eps) if isinstance(dm_kg, Real) else eps


def _is_finite_real(value: object) -> bool:
    return isinstance(value, Real) and not isinstance(value, bool) and math.isfinite(value)


def _seven_finite(name: str, values: Sequence[float]) -> tuple[float, ...]:
    try:
        floats = tuple(float(v) for v in values)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be 7 numbers, got {values!r}") from None
    if len(floats) != len(TERMS):
        raise ValueError(f"{name} must have 7 values ({', '.join(TERMS)}), got {len(floats)}")
    if not all(math.isfinite(v) for v in floats):
        raise ValueError(f"{name} must be finite numbers, got {floats}")
    return floats


def _finite_array(dm_kg: ArrayLike) -> np.ndarray:
    try:
        x = np.asarray(dm_kg, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"dm_kg must be a number or an array of numbers, got {dm_kg!r}") from None
    if not np.all(np.isfinite(x)):
        raise ValueError(f"dm_kg (weight error, kg) must be finite, got {dm_kg!r}")
    return x
