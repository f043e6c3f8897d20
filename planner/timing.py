"""The segment-duration problem of eq. (1) for SLSQP: cost, exact limit constraints, gradients.

Variables x = log(h / h_start), h the segment durations (s). Cost (scaled to 1 at the start):
k_T * T + k_J * mean_j int (jerk_j / JC_j)^2 dt (planner.trajectory explains the normalisation).
Constraints g = 1 - ratio >= 0, one per knot span, joint, derivative order (velocity,
acceleration, jerk) and side (the span's maximum over the limit, and minus its minimum over the
limit). The maxima and minima are exact (planner.span_extremes); their gradients follow
from the envelope theorem (the slope vanishes at an interior extreme, span ends are fixed at
s = 0 and 1 in span coordinates) and the analytic sensitivity of the spline coefficients.
"""

from __future__ import annotations

import numpy as np

from planner import bspline
from planner.bspline import RestToRestQuintic
from planner.span_extremes import ORDERS, extreme_value_gradients, span_extremes

# A segment may not become shorter than this fraction of the start's mean segment duration: it
# bounds the span-length ratios that condition the spline system. In practice only a segment
# between equal via-points (no joint moving) comes near it.
MIN_SEGMENT_FRACTION = 1e-2
_ORDER_COLUMN = np.array(ORDERS, dtype=float)[:, None]


def segment_estimate(q: np.ndarray, limits: np.ndarray) -> np.ndarray:
    """Rough per-segment durations (s), (n_via - 1,): the slowest joint's single-limit times."""
    step = np.abs(q[1:] - q[:-1])
    per_joint = np.maximum(step / limits[0], np.sqrt(step / limits[1]))
    np.maximum(per_joint, np.cbrt(step / limits[2]), out=per_joint)
    estimate = per_joint.max(axis=1)
    return np.maximum(estimate, (0.1 / estimate.size) * estimate.sum())


def uniform_scale(ratios: np.ndarray) -> float:
    """Time scale that brings the largest limit ratio (3, n_joints) to exactly 1."""
    per_order = ratios.max(axis=1) ** (1.0 / np.array(ORDERS, dtype=float))
    return float(per_order.max())


class TimingProblem:
    """Objective and constraints of eq. (1) in x = log(h / h_start), with analytic gradients.

    The start h_start: per-segment estimates, uniformly scaled so that the largest limit ratio is
    exactly 1 and, when k_J > 0, stretched further by the best uniform factor for the cost.
    Uniform time scaling by s multiplies the order-o ratios by s^-o, the duration by s and the
    jerk integral by s^-5, values and x-gradients alike, so the estimate's evaluation is rescaled
    to the start instead of being computed again.
    """

    def __init__(self, system: RestToRestQuintic, q: np.ndarray, limits: np.ndarray,
                 k_T: float, k_J: float):
        """q: via-points (n_via, n_joints) rad; limits (3, n_joints) rad/s, rad/s^2, rad/s^3."""
        self.system, self.q, self.limits, self.k_T, self.k_J = system, q, limits, k_T, k_J
        self._jerk_weight = 1.0 / (q.shape[1] * limits[2] ** 2)  # mean over joints, in limit units
        # ratio = sign * value / limit <= 1 for the maxima (sign +1) and minima (sign -1).
        self._ratio_weight = (np.array([1.0, -1.0])[:, None, None, None]
                              * (1.0 / limits)[None, :, None, :])
        self.h_start = segment_estimate(q, limits)
        self._key, self.cost_scale = None, 1.0
        self._evaluate(np.zeros_like(self.h_start))
        peaks = self._ratio.max(axis=(0, 2, 3))  # per order
        scale = float(np.max(peaks ** (1.0 / _ORDER_COLUMN[:, 0])))
        if k_J > 0.0:
            # Best uniform stretch s >= 1 of this shape: k_T s T + k_J s^-5 J is least at
            # s^6 = 5 k_J J / (k_T T); stretching keeps the limits (it only lowers the peaks).
            time_sum, jerk = self._time * scale, self._jerk * scale**-5.0
            scale *= max(1.0, (5.0 * k_J * jerk / (k_T * time_sum)) ** (1.0 / 6.0))
        self.h_start = self.h_start * scale
        order_factor = scale ** -_ORDER_COLUMN[:, :, None]  # (3, 1, 1): order, span, joint
        self._ratio = self._ratio * order_factor
        self._dratio = self._dratio * order_factor[..., None]
        self._time, self._dtime = self._time * scale, self._dtime * scale
        self._jerk, self._djerk = self._jerk * scale**-5.0, self._djerk * scale**-5.0
        self.x_lower = np.log(MIN_SEGMENT_FRACTION * self.h_start.mean() / self.h_start)
        # The optimiser sees the cost divided by its start value: its quasi-Newton start (unit
        # Hessian) is then about the right size.
        self.start_cost = k_T * self._time + k_J * self._jerk
        self.cost_scale = 1.0 / self.start_cost
        self._combine()

    def _evaluate(self, x: np.ndarray) -> None:
        key = x.tobytes()
        if key == self._key:
            return
        system = self.system
        h = self.h_start * np.exp(x)
        spans = system.span_of_segments @ h
        span_of_x = system.span_of_segments * h  # dL/dx
        coef, dcoef = system.solve_with_sensitivity(spans, self.q, span_of_x)  # d/dx
        values, points = span_extremes(coef)  # (2, 3, m, nq)
        dvalue = extreme_value_gradients(points, dcoef)  # (2, 3, m, nq, n)
        inverse = 1.0 / spans
        # ratio = sign value L^-o / limit; d(L^-o)/dx = -o L^-o (dL/dx) / L.
        ratio_scale = self._ratio_weight * (inverse ** _ORDER_COLUMN)[:, :, None]
        ratio = ratio_scale * values
        shrink = _ORDER_COLUMN[:, :, None] * (inverse[:, None] * span_of_x)  # (3, m, n)
        dratio = ratio_scale[..., None] * dvalue
        dratio -= ratio[..., None] * shrink[:, :, None, :]
        self._ratio, self._dratio, self._coef = ratio, dratio, coef
        self._time, self._dtime = float(h.sum()), h
        self._jerk, self._djerk = 0.0, 0.0
        if self.k_J > 0.0:
            self._jerk, self._djerk = bspline.jerk_cost_and_gradient(
                coef, dcoef, spans, span_of_x, self._jerk_weight)
        self._key = key
        self._combine()

    def _combine(self) -> None:
        self._f = self.cost_scale * (self.k_T * self._time + self.k_J * self._jerk)
        self._df = self.cost_scale * (self.k_T * self._dtime + self.k_J * self._djerk)
        self._g = 1.0 - self._ratio.ravel()
        self._dg = -self._dratio.reshape(self._g.size, -1)

    def solution(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
        """(span coefficients (6, n_span, n_joints), exact peak |derivative| / limit (3,
        n_joints)) of the last evaluation if it was at x, else None. (The coefficients are in
        span coordinates, so the start's uniform rescale leaves them as they are.)"""
        if x.tobytes() != self._key:
            return None
        return self._coef, self._ratio.max(axis=(0, 2))

    def cost(self, x: np.ndarray) -> float:
        """Scaled cost at x (n_via - 1,); the next three give its gradient, g and dg/dx."""
        self._evaluate(x)
        return self._f

    def cost_gradient(self, x: np.ndarray) -> np.ndarray:
        self._evaluate(x)
        return self._df

    def constraints(self, x: np.ndarray) -> np.ndarray:
        self._evaluate(x)
        return self._g

    def constraints_jacobian(self, x: np.ndarray) -> np.ndarray:
        self._evaluate(x)
        return self._dg
