"""Central differences with an estimate of their own error, for checking analytic derivatives.

A fixed tolerance on a finite difference is either loose enough to hide a wrong derivative or
tight enough to fail on another CPU's rounding (AVX-512 rounds sums differently from AVX2). So
each estimate comes with a bound built from the two errors a central difference has:
- truncation: the estimate is the Richardson extrapolation of the differences at steps h and
  h/2 (error O(h^4)); the same extrapolation from h/2 and h/4 differs from it by about that error;
- rounding: the function's own round-off noise (measured at x by a second difference over a step
  too small for curvature to show), amplified by 1/h.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

# Steps for the round-off probe, relative to the difference step: f(x+d) + f(x-d) - 2 f(x) is
# d^2 f'' + noise; at d <= 1e-4 h (h <= 1e-4) the curvature term is below 1e-16 |f''|.
_NOISE_PROBES = (1e-5, 3e-5, 1e-4)
SAFETY = 4.0  # the bound is an estimate: keep a margin over it


@dataclass(frozen=True)
class Derivative:
    """estimate: df/dx (output shape + (n,)); error: a bound on |estimate - df/dx|, same shape."""

    estimate: np.ndarray
    error: np.ndarray


def central_difference(function: Callable[[np.ndarray], np.ndarray], x: np.ndarray,
                       step: float = 1e-4) -> Derivative:
    """Derivative of `function` (any output shape) in each component of x (n,), stacked last."""
    x = np.asarray(x, dtype=float)

    def f(y: np.ndarray) -> np.ndarray:
        return np.array(function(y), dtype=float, copy=True)

    centre = f(x)
    estimates, errors = [], []
    for i in range(x.size):
        unit = np.zeros_like(x)
        unit[i] = 1.0
        d = [(f(x + h * unit) - f(x - h * unit)) / (2.0 * h) for h in (step, step / 2, step / 4)]
        noise = np.max([np.abs(f(x + p * step * unit) + f(x - p * step * unit) - 2.0 * centre)
                        for p in _NOISE_PROBES], axis=0)
        noise = np.maximum(noise, np.finfo(float).eps * np.abs(centre))
        coarse, fine = (4.0 * d[1] - d[0]) / 3.0, (4.0 * d[2] - d[1]) / 3.0
        truncation = np.abs(coarse - fine)
        rounding = noise / (step / 4)
        estimates.append(coarse)
        errors.append(SAFETY * (truncation + rounding))
    return Derivative(np.stack(estimates, axis=-1), np.stack(errors, axis=-1))


def assert_derivative(analytic: np.ndarray, numeric: Derivative, rtol: float = 1e-9) -> None:
    """analytic within the finite difference's own error bound (plus rtol of its size)."""
    analytic = np.asarray(analytic, dtype=float)
    allowed = numeric.error + rtol * np.abs(numeric.estimate)
    miss = np.abs(analytic - numeric.estimate) > allowed
    if miss.any():
        where = np.argwhere(miss)[:5]
        lines = [f"{tuple(int(i) for i in w)}: analytic {analytic[tuple(w)]:.6e}, "
                 f"numeric {numeric.estimate[tuple(w)]:.6e} +- {allowed[tuple(w)]:.1e}"
                 for w in where]
        raise AssertionError(f"{int(miss.sum())} of {miss.size} derivatives off:\n"
                             + "\n".join(lines))
