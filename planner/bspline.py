"""Quintic spline through via-points, at rest at both ends, and its exact per-span extremes.

Knot layout (degree p = 5). A B-spline with clamped ends (each end knot repeated p + 1 = 6 times)
and simple interior knots is C^4 and has n_knots - 6 control points. The conditions are the
n_via positions at the via times plus velocity = acceleration = jerk = 0 at both ends (6), so it
needs n_via + 6 control points, i.e. n_via interior knots. The n_via - 2 interior via times give
n_via - 2 of them; the other two go inside the first and the last segment, a quarter of the
segment away from the rest end (with a single segment, at 1/4 and 3/4 of it). As in
Gasparetto & Zanotto (2008), the fifth-order B-spline has the via times as knots; the two extra
knots carry the extra rest conditions (jerk zero at both ends). The quarter is a measured
choice: over 25 digging periods (bench/planner.py) the time-optimal duration was 6 % shorter
than with the extra knots at the middle of the end segments (as a fraction of the
stop-at-every-via-point duration: 1/2 0.779, 0.35 0.747, 1/4 0.729, 0.2 0.730, 0.15 0.742).
The collocation system is square; scipy.interpolate.make_interp_spline solves it for the output.

During the optimisation the same spline is held in a better-conditioned per-span form: span i
(length L_i) is q(t_i + s L_i) = sum_k a_ik s^k with s in [0, 1], so the r-th time derivative is
L_i^-r P_ir(s) with P_ir(s) = sum_k k!/(k-r)! a_ik s^(k-r). Continuity of derivatives 0..4 at the
interior knots then involves only ratios of neighbouring span lengths, and the end points of a span
are s = 0 and s = 1 whatever the durations, which makes the extremes' derivatives simple (envelope
theorem: at an interior extreme P' = 0).
"""

from __future__ import annotations

import functools

import numpy as np
from scipy.interpolate import BSpline, PPoly, make_interp_spline
from scipy.linalg.lapack import dgetrf as _getrf
from scipy.linalg.lapack import dgetrs as _getrs

DEGREE = 5
N_COEF = DEGREE + 1
ORDERS = (1, 2, 3)  # velocity, acceleration, jerk: the limited derivatives
EXTRA_KNOT_FRACTION = 0.25  # extra knot's distance from a rest end, in end-segment durations
# FALLING[k, r] = k! / (k - r)! (0 for k < r): d^r/ds^r s^k = FALLING[k, r] s^(k - r).
FALLING = np.array(
    [[np.prod(np.arange(k - r + 1, k + 1)) if k >= r else 0.0 for r in range(N_COEF)]
     for k in range(N_COEF)], dtype=float)
# int_0^1 s^(i+k) ds for the jerk polynomial's three coefficients (s^0, s^1, s^2).
_HILBERT3 = 1.0 / (np.arange(3)[:, None] + np.arange(3)[None, :] + 1.0)
_ORDER_COLUMN = np.array(ORDERS, dtype=float)[:, None]
# P_o(s) = sum_i _TO_POLY[o, k, i] a_k s^i for the three limited orders, padded to degree 4.
_TO_POLY = np.zeros((3, N_COEF, 5))
for _o, _order in enumerate(ORDERS):
    for _k in range(_order, N_COEF):
        _TO_POLY[_o, _k, _k - _order] = FALLING[_k, _order]
# The same as monomial weights: P_o(s) = sum_k _WEIGHT[o, k] s^_POWER[o, k] a_k.
_WEIGHT = np.array([FALLING[:, order] for order in ORDERS])
_POWER = np.array([np.maximum(np.arange(N_COEF) - order, 0) for order in ORDERS], dtype=float)
_SLOPE = np.arange(1.0, 5.0)
# A cubic has at most 3 roots; a root on a shared piece edge may be reported for both pieces.
_MAX_ROOTS = 5


def span_layout(n_via: int) -> tuple[np.ndarray, np.ndarray]:
    """Knot spans as linear functions of the segment durations.

    Returns (span_of_segments, via_knot): span lengths are ``span_of_segments @ h`` with
    span_of_segments of shape (n_via + 1, n_via - 1); via_knot (n_via,) gives, for each via-point,
    the index of the knot (0 = start, n_via + 1 = end) it sits on.
    """
    n_seg = n_via - 1
    end = EXTRA_KNOT_FRACTION
    if n_seg == 1:
        fractions = [(0, end), (0, 1.0 - 2.0 * end), (0, end)]
    else:
        fractions = ([(0, end), (0, 1.0 - end)] + [(i, 1.0) for i in range(1, n_seg - 1)]
                     + [(n_seg - 1, 1.0 - end), (n_seg - 1, end)])
    span_of_segments = np.zeros((len(fractions), n_seg))
    for span, (segment, fraction) in enumerate(fractions):
        span_of_segments[span, segment] = fraction
    if n_seg == 1:
        via_knot = [0, 3]
    else:  # knot 1 is the first extra knot; via i (0 < i < n_seg) ends span i, the last ends all
        via_knot = [0] + [i + 1 for i in range(1, n_seg)] + [n_seg + 2]
    return span_of_segments, np.array(via_knot)


class RestToRestQuintic:
    """Linear system for the per-span coefficients of the rest-to-rest quintic spline.

    Unknowns: a (n_span, 6) per joint, flattened span-major. Rows: 4 start conditions (position,
    velocity, acceleration, jerk), 5 continuity rows per interior knot plus one position row when
    the knot is a via time, 4 end conditions.
    """

    def __init__(self, n_via: int):
        if n_via < 2:
            raise ValueError(f"need at least 2 via-points, got {n_via}")
        self.n_via = n_via
        self.span_of_segments, self.via_knot = span_layout(n_via)
        m = self.n_span = self.span_of_segments.shape[0]
        size = N_COEF * m
        matrix = np.zeros((size, size))
        via_row = np.zeros(n_via, dtype=int)
        row = 0
        for r in range(4):  # start at rest: a_00 = q_0, a_01 = a_02 = a_03 = 0
            matrix[row, r] = 1.0
            row += 1
        ratio_rows = np.zeros((m - 1, 4), dtype=int)
        for j in range(m - 1):
            for r in range(5):
                matrix[row, N_COEF * j:N_COEF * (j + 1)] = FALLING[:, r]
                if r == 0:
                    matrix[row, N_COEF * (j + 1)] = -1.0
                else:
                    ratio_rows[j, r - 1] = row
                row += 1
            if j + 1 in self.via_knot:
                matrix[row, N_COEF * (j + 1)] = 1.0
                via_row[list(self.via_knot).index(j + 1)] = row
                row += 1
        for r in range(4):  # end at rest: P_r(1) = 0 for r = 1..3, position q_last
            matrix[row, N_COEF * (m - 1):] = FALLING[:, r]
            if r == 0:
                via_row[-1] = row
            row += 1
        assert row == size
        self._constant = matrix
        self._via_row = via_row
        self._ratio_rows = ratio_rows
        self._ratio_cols = N_COEF * np.arange(1, m)[:, None] + np.arange(1, 5)[None, :]
        self._r = np.arange(1, 5, dtype=float)
        self._r_factorial = np.array([1.0, 2.0, 6.0, 24.0])
        self._left_span = np.repeat(np.arange(m - 1)[:, None], 4, axis=1)

    def span_lengths(self, segment_durations: np.ndarray) -> np.ndarray:
        """Span lengths (s), shape (n_span,), from segment durations (s), shape (n_via - 1,)."""
        return self.span_of_segments @ segment_durations

    def solve(self, spans: np.ndarray, via_points: np.ndarray, sensitivity: bool = False):
        """Normalised coefficients a (n_span, 6, n_joints) and, if asked, da/dL.

        spans: span lengths (s), (n_span,); via_points (n_via, n_joints) rad. da/dL has shape
        (n_span, 6, n_joints, n_span): derivative of a with respect to each span length.
        """
        m = self.n_span
        ratio_entry = -((spans[:-1] / spans[1:])[:, None] ** self._r) * self._r_factorial
        matrix = self._constant.copy()
        matrix[self._ratio_rows, self._ratio_cols] = ratio_entry
        lu, pivots, info = _getrf(matrix, overwrite_a=True)
        if info != 0:  # not for positive span lengths; guards against NaN or zero spans
            raise ValueError(f"spline system is singular for span lengths {spans.tolist()}")
        rhs = np.zeros((N_COEF * m, via_points.shape[1]))
        rhs[self._via_row] = via_points
        coef = _getrs(lu, pivots, rhs)[0].reshape(m, N_COEF, -1)
        if not sensitivity:
            return coef, None
        # Row (j, r) holds ratio_entry[j, r] a_{j+1,r}; ratio_j = L_j / L_{j+1}, so its
        # derivative is r * entry / L_j with respect to L_j and -r * entry / L_{j+1} to L_{j+1}.
        entry = (self._r * ratio_entry)[:, :, None] * coef[1:, 1:5, :]  # (m-1, 4, nq)
        nq = coef.shape[2]
        drhs = np.zeros((N_COEF * m, nq, m))
        drhs[self._ratio_rows, :, self._left_span] = entry / spans[:-1, None, None]
        drhs[self._ratio_rows, :, self._left_span + 1] = -entry / spans[1:, None, None]
        dflat = -_getrs(lu, pivots, drhs.reshape(N_COEF * m, nq * m))[0]
        return coef, dflat.reshape(m, N_COEF, coef.shape[2], m)


def critical_points(slope: np.ndarray) -> np.ndarray:
    """Points in [0, 1] that include every real root in [0, 1] of each row's polynomial.

    slope: (rows, 4) ascending coefficients of polynomials of degree <= 3. Returns
    (rows, 2 + _MAX_ROOTS): the interval ends, the roots, and 0.0 where a row has fewer roots.
    All rows go to scipy's compiled piecewise-polynomial root finder at once, row i as the piece
    on [i, i + 1]. A root it may drop (a near-double root that rounding turned complex) can lower
    a maximum by O(delta^3) only, delta being the roots' separation.
    """
    rows = slope.shape[0]
    pieces = PPoly.construct_fast(np.ascontiguousarray(slope[:, ::-1].T), np.arange(rows + 1.0))
    roots = pieces.roots(discontinuity=False, extrapolate=False)
    roots = roots[np.isfinite(roots)]  # an identically zero piece is reported as (start, nan)
    row = np.minimum(roots.astype(np.int64), rows - 1)
    rank = np.arange(roots.size) - np.searchsorted(row, row)  # roots come sorted
    points = np.zeros((rows, 2 + _MAX_ROOTS))
    points[:, 1] = 1.0
    keep = rank < _MAX_ROOTS
    points[row[keep], 2 + rank[keep]] = roots[keep] - row[keep]
    return points


def _horner(coef: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Row-wise polynomials coef (rows, n) ascending, evaluated at points s (rows, c)."""
    out = coef[:, -1:] * s + coef[:, -2:-1]
    for i in range(coef.shape[1] - 3, -1, -1):
        out = out * s + coef[:, i:i + 1]
    return out


def span_extremes(coef: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Exact max and min over s in [0, 1] of P_o for o = velocity, acceleration, jerk.

    coef: (n_span, 6, n_joints) normalised coefficients. Returns (values, points), each
    (2, 3, n_span, n_joints): [0] the maxima, [1] the minima, and where on the span (s) they are.
    The time derivative of order o is the value times L_span^-o.
    """
    poly = np.einsum("oki,mkq->omqi", _TO_POLY, coef)  # (3, m, nq, 5), ascending in s
    flat = poly.reshape(-1, 5)
    points = critical_points(flat[:, 1:] * _SLOPE)
    values = _horner(flat, points)
    rows = np.arange(flat.shape[0])
    best = np.stack([values.argmax(axis=1), values.argmin(axis=1)])
    shape = (2,) + poly.shape[:3]
    return values[rows, best].reshape(shape), points[rows, best].reshape(shape)


def monomials(points: np.ndarray) -> np.ndarray:
    """Weights w with P_o(s) = w . a at points (2, 3, ...) from span_extremes: (2, 3, ..., 6)."""
    expand = (None, slice(None)) + (None,) * (points.ndim - 2) + (slice(None),)
    return _WEIGHT[expand] * points[..., None] ** _POWER[expand]


def jerk_squared_integrals(coef: np.ndarray, spans: np.ndarray) -> np.ndarray:
    """int jerk^2 dt over each span and joint, (n_span, n_joints) in rad^2/s^5."""
    jerk_poly = np.moveaxis(coef[:, 3:, :], 1, 2) * FALLING[3:, 3]  # (m, nq, 3)
    unit = np.einsum("mqi,ik,mqk->mq", jerk_poly, _HILBERT3, jerk_poly)
    return unit * spans[:, None] ** -5.0


def jerk_integral_gradient(coef: np.ndarray, dcoef: np.ndarray, spans: np.ndarray) -> np.ndarray:
    """d/dL of the per-joint jerk integral, (n_joints, n_span), from coef and dcoef = da/dL."""
    jerk_poly = np.moveaxis(coef[:, 3:, :], 1, 2) * FALLING[3:, 3]  # (m, nq, 3)
    djerk = dcoef[:, 3:, :, :] * FALLING[3:, 3][None, :, None, None]  # (m, 3, nq, L)
    weight = spans ** -5.0
    grad = 2.0 * np.einsum("m,mqi,ik,mkql->ql", weight, jerk_poly, _HILBERT3, djerk)
    unit = np.einsum("mqi,ik,mqk->mq", jerk_poly, _HILBERT3, jerk_poly)
    grad += (-5.0 * unit * spans[:, None] ** -6.0).T
    return grad


def knot_vector(spans: np.ndarray, via_times: np.ndarray, via_knot: np.ndarray) -> np.ndarray:
    """Clamped knot vector (s), shape (n_span + 11,), with the via times (s) exactly on knots."""
    breaks = np.concatenate([[0.0], np.cumsum(spans)])
    breaks[via_knot] = via_times  # the same numbers bit for bit: interpolation sites on knots
    return np.concatenate([np.full(DEGREE, breaks[0]), breaks, np.full(DEGREE, breaks[-1])])


def interpolating_spline(knots: np.ndarray, via_times: np.ndarray,
                         via_points: np.ndarray) -> BSpline:
    """The degree-5 B-spline on knots (s) through via_points (n_via, n_joints) rad at via_times
    (s), with velocity, acceleration and jerk zero at both ends."""
    zeros = np.zeros(via_points.shape[1])
    at_rest = [(1, zeros), (2, zeros), (3, zeros)]
    spline = make_interp_spline(via_times, via_points, k=DEGREE, t=knots,
                                bc_type=(at_rest, at_rest))
    spline.extrapolate = False
    return spline


def spline_span_coefficients(spline: BSpline) -> tuple[np.ndarray, np.ndarray]:
    """Normalised per-span coefficients (n_span, 6, n_joints) and span lengths of a B-spline.

    Taken from the spline's own derivatives at each span start (Taylor coefficients), so extremes
    computed from them belong to exactly this spline.
    """
    knots = np.unique(spline.t)
    starts, spans = knots[:-1], np.diff(knots)
    taylor = np.stack([spline(starts, nu=k) for k in range(N_COEF)], axis=1)  # (m, 6, nq)
    factorial = np.array([1.0, 1.0, 2.0, 6.0, 24.0, 120.0])
    scale = spans[:, None] ** np.arange(N_COEF)[None, :] / factorial[None, :]
    return taylor * scale[:, :, None], spans


def peak_ratios(coef: np.ndarray, spans: np.ndarray, limits: np.ndarray) -> np.ndarray:
    """Largest |derivative| / limit per order and joint, (3, n_joints).

    coef (n_span, 6, n_joints), spans (n_span,) s; limits: (3, n_joints) velocity, acceleration,
    jerk limits in rad/s, rad/s^2, rad/s^3.
    """
    values, _ = span_extremes(coef)
    peak = np.maximum(values[0], -values[1]) * (spans[None, :] ** -_ORDER_COLUMN)[:, :, None]
    return peak.max(axis=1) / limits


@functools.lru_cache(maxsize=16)
def rest_to_rest_system(n_via: int) -> RestToRestQuintic:
    """The (immutable, shared) spline system for n_via via-points."""
    return RestToRestQuintic(n_via)
