"""The terrain slump in numpy: the oracle that planner/native/slump.c (the one kernel the
strategy runs, orchestrator.campaign.native_slump) is compared with, bit for bit
(tests/test_native_slump.py). It was the planner's own kernel before the C one replaced it."""

from __future__ import annotations

import numpy as np

from planner.surface_estimate import RELAX_MAX_SWEEPS, RELAX_TOLERANCE_M


def relax_steps(z_m: np.ndarray, allowed_m: float) -> None:
    """Conservative transfers between neighbours of z_m (n,) m, in place: half-sweeps over the
    even, then the odd pairs (each set of pairs is disjoint, so every transfer levels its pair
    to the allowed step exactly), until no step exceeds allowed_m (m) by more than
    RELAX_TOLERANCE_M, or RELAX_MAX_SWEEPS."""
    z = z_m
    for _ in range(RELAX_MAX_SWEEPS):
        worst = 0.0
        for first in (0, 1):
            left, right = z[first:-1:2], z[first + 1::2]
            n = min(len(left), len(right))
            left, right = left[:n], right[:n]
            step = left - right
            excess = np.abs(step) - allowed_m
            move = np.where(excess > 0.0, 0.5 * excess * np.sign(step), 0.0)
            z[first:first + 2 * n:2] -= move
            z[first + 1:first + 1 + 2 * n:2] += move
            worst = max(worst, float(excess.max(initial=0.0)))
        if worst <= RELAX_TOLERANCE_M:
            break
