"""The segment-duration problem of eq. (1) for SLSQP: cost, exact limit constraints, gradients.

Variables x = log(h / h_start), h the segment durations (s). Cost (scaled to 1 at the start):
k_T * T + k_J * mean_j int (jerk_j / JC_j)^2 dt (planner.trajectory explains the normalisation).
Constraints g = 1 - ratio >= 0, one per knot span, joint, derivative order (velocity,
acceleration, jerk) and side (the span's maximum over the limit, and minus its minimum over the
limit). The maxima and minima are exact (planner.bspline.span_extremes); their gradients follow
from the envelope theorem (the slope vanishes at an interior extreme, span ends are fixed at
s = 0 and 1 in span coordinates) and the analytic sensitivity of the spline coefficients.
"""

from __future__ import annotations

import numpy as np

from planner import bspline
from planner.bspline import ORDERS, RestToRestQuintic

# A segment may not become shorter than this fraction of the start's mean segment duration: it
# bounds the span-length ratios that condition the spline system. In practice only a segment
# between equal via-points (no joint moving) comes near it.
MIN_SEGMENT_FRACTION = 1e-2
_ORDER_COLUMN = np.array(ORDERS, dtype=float)[:, None]


def segment_estimate(q: np.ndarray, limits: np.ndarray) -> np.ndarray:
    """Rough per-segment durations (s), (n_via - 1,): the slowest joint's single-limit times."""
    step = np.abs(np.diff(q, axis=0))
    per_joint = np.maximum.reduce([step / limits[0], np.sqrt(step / limits[1]),
                                   np.cbrt(step / limits[2])])
    estimate = per_joint.max(axis=1)
    return np.maximum(estimate, 0.1 * estimate.mean())


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
        self._eye = np.eye(system.n_span)
        # ratio = sign * value / limit <= 1 for the maxima (sign +1) and minima (sign -1).
        self._ratio_weight = (np.array([1.0, -1.0])[:, None, None, None]
                              * (1.0 / limits)[None, :, None, :])
        self.h_start = segment_estimate(q, limits)
        self._key, self.cost_scale = None, 1.0
        zeros = np.zeros_like(self.h_start)
        self._evaluate(zeros)
        peaks = self._ratio.max(axis=(0, 2, 3))  # per order
        scale = float(np.max(peaks ** (1.0 / _ORDER_COLUMN[:, 0])))
        if k_J > 0.0:
            # Best uniform stretch s >= 1 of this shape: k_T s T + k_J s^-5 J is least at
            # s^6 = 5 k_J J / (k_T T); stretching keeps the limits (it only lowers the peaks).
            time_sum, jerk = self._time * scale, self._jerk * scale**-5.0
            scale *= max(1.0, (5.0 * k_J * jerk / (k_T * time_sum)) ** (1.0 / 6.0))
        self.h_start = self.h_start * scale
        order_factor = scale ** -_ORDER_COLUMN[None, :, :, None]  # (1, 3, 1, 1)
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
        h = self.h_start * np.exp(x)
        spans = self.system.span_lengths(h)
        span_of_x = self.system.span_of_segments * h[None, :]  # dL/dx
        coef, dcoef = self.system.solve(spans, self.q, sensitivity=True)
        values, points = bspline.span_extremes(coef)  # (2, 3, m, nq)
        scale = spans[None, :] ** -_ORDER_COLUMN  # (3, m): derivative = L^-o P_o
        dvalue = np.einsum("eomqk,mkql->eomql", bspline.monomials(points), dcoef)
        dvalue *= scale[None, :, :, None, None]
        dscale = -_ORDER_COLUMN * scale / spans  # d(L_j^-o)/dL_j
        dvalue += (values * dscale[None, :, :, None])[..., None] * self._eye[:, None, :]
        self._ratio = self._ratio_weight * values * scale[None, :, :, None]
        self._dratio = (self._ratio_weight[..., None] * dvalue) @ span_of_x
        self._time, self._dtime = float(h.sum()), h
        self._jerk, self._djerk = 0.0, 0.0
        if self.k_J > 0.0:
            jerk = bspline.jerk_squared_integrals(coef, spans).sum(axis=0)
            djerk = bspline.jerk_integral_gradient(coef, dcoef, spans)
            self._jerk = float(self._jerk_weight @ jerk)
            self._djerk = (self._jerk_weight @ djerk) @ span_of_x
        self._key = key
        self._combine()

    def _combine(self) -> None:
        self._f = self.cost_scale * (self.k_T * self._time + self.k_J * self._jerk)
        self._df = self.cost_scale * (self.k_T * self._dtime + self.k_J * self._djerk)
        self._g = 1.0 - self._ratio.ravel()
        self._dg = -self._dratio.reshape(self._g.size, -1)

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
