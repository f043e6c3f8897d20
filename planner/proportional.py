"""A proportional correction beside the paper's fuzzy rule, for eq. 5 of Vu & Tran 2020.

    eps(dm) = gain * dm        (m, dm = m* - m in kg)

It takes the fuzzy rule's place in the same update, dz(k+1) = dz(k) + eps, z_D(k+1) = z_D(k) -
dz(k+1) (planner.adaptation): a linear law against the paper's saturating one, so a sweep can
show what the fuzzy rule's shape buys. With gain 0 and dz_0 = 0 the deepest point never moves:
the "fixed" strategy, one trajectory dug over and over.

>>> ProportionalRule(0.01)(-20.0)   # 20 kg too heavy: 0.2 m shallower
-0.2
>>> round(ProportionalRule.secant_of(0.4, 26.8)(10.0), 6)
0.149254
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class ProportionalRule:
    """eps(dm) = gain_m_per_kg * dm; gain_m_per_kg >= 0 and finite (m of depth per kg short).

    Calling it with dm (kg; a float or an array) returns eps (m; a float or an ndarray)."""

    gain_m_per_kg: float

    def __post_init__(self) -> None:
        gain = self.gain_m_per_kg
        if isinstance(gain, bool) or not (isinstance(gain, int | float) and math.isfinite(gain)
                                          and gain >= 0.0):
            raise ValueError(f"gain_m_per_kg must be a finite number >= 0 m/kg, got {gain!r}")
        object.__setattr__(self, "gain_m_per_kg", float(gain))

    @classmethod
    def secant_of(cls, output_m: float, centre_kg: float) -> ProportionalRule:
        """The line through 0 and a fuzzy rule's outermost term (centre_kg, output_m): the same
        correction as the fuzzy rule where it saturates, more below it."""
        return cls(output_m / centre_kg)

    def __call__(self, dm_kg):
        if np.ndim(dm_kg) == 0:
            return self.gain_m_per_kg * float(dm_kg)
        return self.gain_m_per_kg * np.asarray(dm_kg, dtype=float)
