"""Quintic spline through via-points, at rest at both ends: knot layout, solve, B-spline form.

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

The spline is solved for in a better-conditioned per-span form: span i (length L_i) is
q(t_i + s L_i) = sum_k a_ki s^k with s in [0, 1], so the r-th time derivative is L_i^-r P_ri(s)
with P_ri(s) = sum_k k!/(k-r)! a_ki s^(k-r). Continuity of derivatives 0..4 at the interior
knots then involves only ratios of neighbouring span lengths, and the end points of a span are
s = 0 and s = 1 whatever the durations, which makes the extremes' derivatives simple (envelope
theorem: at an interior extreme P' = 0; planner.span_extremes). Coefficients are held
power-major, a[k, span, joint], so that each power's row is one contiguous block. The output
B-spline's coefficients are the blossoms of these pieces (rest_to_rest_coefficients).
"""

from __future__ import annotations

import functools

import numpy as np
from scipy.interpolate import BSpline
from scipy.linalg.lapack import dgetrf as _getrf
from scipy.linalg.lapack import dgetrs as _getrs

from planner.span_extremes import FALLING, N_COEF

DEGREE = 5
EXTRA_KNOT_FRACTION = 0.25  # extra knot's distance from a rest end, in end-segment durations
# int_0^1 P_3(s)^2 ds = sum_kl a_(3+k) _JERK_GRAM[k, l] a_(3+l), P_3 = 6 a_3 + 24 a_4 s + 60 a_5 s^2
_JERK_FACTOR = FALLING[3:, 3]
_JERK_GRAM = (_JERK_FACTOR[:, None] * _JERK_FACTOR[None, :]
              / (np.arange(3)[:, None] + np.arange(3)[None, :] + 1.0))
_INVERSE_FACTORIAL = 1.0 / np.array([1.0, 1.0, 2.0, 6.0, 24.0, 120.0])
_INVERSE_BINOMIAL = 1.0 / np.array([1.0, 5.0, 10.0, 10.0, 5.0, 1.0])  # 1 / C(5, r)


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

    Unknowns: a (6, n_span) per joint, power-major. Rows: 4 start conditions (position,
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
        powers = m * np.arange(N_COEF)  # column of a[k, span] is k m + span
        matrix = np.zeros((size, size))
        via_row = np.zeros(n_via, dtype=int)
        row = 0
        for r in range(4):  # start at rest: a_00 = q_0, a_10 = a_20 = a_30 = 0
            matrix[row, r * m] = 1.0
            row += 1
        ratio_rows = np.zeros((m - 1, 4), dtype=int)
        for j in range(m - 1):
            for r in range(5):  # derivative r, times L_j^r, equal at the knot
                matrix[row, powers + j] = FALLING[:, r]
                if r == 0:
                    matrix[row, j + 1] = -1.0
                else:  # -r! (L_j / L_(j+1))^r a_(r, j+1): set per call
                    ratio_rows[j, r - 1] = row
                row += 1
            if j + 1 in self.via_knot:
                matrix[row, j + 1] = 1.0
                via_row[list(self.via_knot).index(j + 1)] = row
                row += 1
        for r in range(4):  # end at rest: P_r(1) = 0 for r = 1..3, position q_last
            matrix[row, powers + m - 1] = FALLING[:, r]
            if r == 0:
                via_row[-1] = row
            row += 1
        assert row == size
        # Per call only the ratio entries change (flat indices into the C-ordered matrix).
        self._constant = matrix
        ratio_cols = m * np.arange(1, 5)[None, :] + np.arange(1, m)[:, None]
        self._ratio_flat = (ratio_rows * size + ratio_cols).ravel()
        self._r = np.arange(1, 5, dtype=float)
        self._minus_r_factorial = -np.array([1.0, 2.0, 6.0, 24.0])
        self._minus_r_r_factorial = self._r * self._minus_r_factorial
        # Columns of the inverse that are ever needed: via rows (the right-hand side) and ratio
        # rows (the only entries that depend on the span lengths).
        columns = np.concatenate([via_row, ratio_rows.ravel()])
        self._unit_columns = np.asfortranarray(np.eye(size)[:, columns])
        # B-spline coefficient i (4 <= i <= m, the rest are fixed by the rest conditions) sits
        # on spans max(0, i - 5) .. min(m - 1, i) and is the blossom at knots i + 1 .. i + 5.
        self._inside = np.arange(4, m + 1)
        self._support = np.clip(self._inside[:, None] + np.arange(-DEGREE, 1), 0, m - 1)
        self._inner_knots = self._inside[:, None] + np.arange(1, DEGREE + 1)

    def span_lengths(self, segment_durations: np.ndarray) -> np.ndarray:
        """Span lengths (s), shape (n_span,), from segment durations (s), shape (n_via - 1,)."""
        return self.span_of_segments @ segment_durations

    def solve(self, spans: np.ndarray, via_points: np.ndarray) -> np.ndarray:
        """Normalised coefficients a (6, n_span, n_joints) for span lengths (s) (n_span,) and
        via_points (n_via, n_joints) rad."""
        return self._factor_and_solve(spans, via_points)[0]

    def solve_with_sensitivity(self, spans: np.ndarray, via_points: np.ndarray,
                               span_jacobian: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Coefficients a (6, n_span, n_joints) and their derivative (6, n_span, n_joints, n_par)
        with respect to parameters p, given span_jacobian = dL/dp (n_span, n_par) in s."""
        coef, columns, ratio_power = self._factor_and_solve(spans, via_points)
        m, nq = self.n_span, via_points.shape[1]
        # Row (j, r) holds E a_(r,j+1), E = -r! rho_j^r, rho_j = L_j / L_(j+1); dE/dp is
        # r E (dL_j/dp / L_j - dL_(j+1)/dp / L_(j+1)), and da = -A^-1 (dA a).
        entry = ((ratio_power * self._minus_r_r_factorial).T[:, :, None]
                 * coef[1:5, 1:, :])  # (4, m - 1, nq)
        relative = span_jacobian / spans[:, None]
        change = relative[1:] - relative[:-1]  # (m - 1, n_par)
        rhs = entry.transpose(1, 0, 2)[:, :, :, None] * change[:, None, None, :]
        dcoef = columns[:, self.n_via:] @ rhs.reshape(4 * (m - 1), -1)
        return coef, dcoef.reshape(N_COEF, m, nq, -1)

    def bspline_coefficients(self, coef: np.ndarray, knots: np.ndarray, start: np.ndarray,
                             end: np.ndarray) -> np.ndarray:
        """B-spline coefficients (n_span + 5, n_joints) of the rest-to-rest spline whose
        normalised per-span coefficients are coef (6, n_span, n_joints), on the clamped knots
        (n_span + 11,) s; start, end (n_joints,) rad: its first and last via-points.

        On clamped knots, velocity, acceleration and jerk at an end are differences of the four
        coefficients there: at rest they all equal the end position, and so they are set (the
        rest conditions then hold exactly in floating point). Each remaining coefficient i is
        the blossom (polar form) of a polynomial piece under the support of basis function i at
        its five inner knots t_(i+1) .. t_(i+5) (de Boor-Fix dual functional; de Boor, A
        Practical Guide to Splines, ch. IX): c_i = sum_r a_r e_r(sigma) / C(5, r), e_r the
        elementary symmetric polynomials of sigma, the knots in the piece's coordinate s. The
        piece is the longest span under the support, so |sigma| <= 5.
        """
        m = self.n_span
        out = np.empty((m + DEGREE, coef.shape[2]))
        out[:4], out[-4:] = start, end
        if m < 4:  # a single segment: the rest conditions fix every coefficient
            return out
        breaks = knots[DEGREE:DEGREE + m + 1]
        spans = breaks[1:] - breaks[:-1]
        span = self._support[np.arange(self._inside.size), spans[self._support].argmax(axis=1)]
        sigma = (knots[self._inner_knots] - breaks[span, None]) / spans[span, None]
        symmetric = np.zeros((self._inside.size, DEGREE + 1))
        symmetric[:, 0] = 1.0
        for k in range(DEGREE):  # multiply out prod_k (1 + sigma_k z)
            symmetric[:, 1:k + 2] += sigma[:, k:k + 1] * symmetric[:, :k + 1]
        symmetric *= _INVERSE_BINOMIAL
        out[4:m + 1] = (symmetric[:, :, None] * coef[:, span].transpose(1, 0, 2)).sum(axis=1)
        return out

    def _factor_and_solve(self, spans, via_points):
        ratio_power = (spans[:-1] / spans[1:])[:, None] ** self._r  # (m - 1, 4)
        matrix = self._constant.copy()
        matrix.ravel()[self._ratio_flat] = (ratio_power * self._minus_r_factorial).ravel()
        # The transpose of a C-ordered matrix is Fortran-ordered: LAPACK factorises A^T in
        # place, and solves A X = E as (A^T)^T X = E.
        lu, pivots, info = _getrf(matrix.T, overwrite_a=True)
        if info != 0:  # not for positive span lengths; guards against NaN or zero spans
            raise ValueError(f"spline system is singular for span lengths {spans.tolist()}")
        columns = _getrs(lu, pivots, self._unit_columns, trans=1)[0]
        coef = (columns[:, :self.n_via] @ via_points).reshape(N_COEF, self.n_span, -1)
        return coef, columns, ratio_power


def jerk_squared_integrals(coef: np.ndarray, spans: np.ndarray) -> np.ndarray:
    """int jerk^2 dt over each span and joint, (n_span, n_joints) in rad^2/s^5; coef
    (6, n_span, n_joints) power-major, spans (n_span,) s."""
    jerk = coef[3:].reshape(3, -1)
    unit = (jerk * (_JERK_GRAM @ jerk)).sum(axis=0).reshape(spans.size, -1)
    return unit * (spans ** -5.0)[:, None]


def jerk_cost_and_gradient(coef: np.ndarray, dcoef: np.ndarray, spans: np.ndarray,
                           span_jacobian: np.ndarray, joint_weight: np.ndarray
                           ) -> tuple[float, np.ndarray]:
    """sum_j joint_weight_j int jerk_j^2 dt and its gradient (n_par,) with respect to the
    parameters p of solve_with_sensitivity (dcoef, span_jacobian = dL/dp)."""
    jerk = coef[3:].reshape(3, -1)  # (3, m nq)
    gram_jerk = _JERK_GRAM @ jerk
    weight = (spans[:, None] ** -5.0 * joint_weight).ravel()  # (m nq,)
    weighted = (weight * (jerk * gram_jerk).sum(axis=0)).reshape(spans.size, -1)
    grad = 2.0 * ((gram_jerk * weight).ravel() @ dcoef[3:].reshape(jerk.size, -1))
    grad -= 5.0 * (weighted.sum(axis=1) / spans) @ span_jacobian  # d(L^-5)/dL = -5 L^-6
    return float(weighted.sum()), grad


def knot_vector(spans: np.ndarray, via_times: np.ndarray, via_knot: np.ndarray) -> np.ndarray:
    """Clamped knot vector (s), shape (n_span + 11,), with the via times (s) exactly on knots."""
    breaks = np.concatenate([[0.0], np.cumsum(spans)])
    breaks[via_knot] = via_times  # the same numbers bit for bit: interpolation sites on knots
    return np.concatenate([np.full(DEGREE, breaks[0]), breaks, np.full(DEGREE, breaks[-1])])


def spline_span_coefficients(spline: BSpline, breaks: np.ndarray | None = None
                             ) -> tuple[np.ndarray, np.ndarray]:
    """Normalised per-span coefficients (6, n_span, n_joints) and span lengths of a B-spline.

    Taken from the spline's own derivatives at each span start (Taylor coefficients), so extremes
    computed from them belong to exactly this spline. breaks: its distinct knots (s), if known.
    """
    if breaks is None:
        breaks = np.unique(spline.t)
    starts, spans = breaks[:-1], np.diff(breaks)
    taylor = np.stack([spline(starts, nu=k) for k in range(N_COEF)])  # (6, m, nq)
    scale = spans ** np.arange(N_COEF)[:, None] * _INVERSE_FACTORIAL[:, None]
    return taylor * scale[:, :, None], spans


@functools.lru_cache(maxsize=16)
def rest_to_rest_system(n_via: int) -> RestToRestQuintic:
    """The (immutable, shared) spline system for n_via via-points."""
    return RestToRestQuintic(n_via)
