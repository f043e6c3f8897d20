"""Exact extremes of a quintic span's velocity, acceleration and jerk polynomials on s in [0, 1].

Span i of the spline is q(t_i + s L_i) = sum_k a_k s^k (planner.bspline), so the r-th time
derivative is L_i^-r P_r(s) with P_r(s) = sum_k k!/(k-r)! a_k s^(k-r). The extremes of P_o on
[0, 1] lie at s = 0, s = 1 or a real root in (0, 1) of its slope P_(o+1), found in closed form
for every span and joint at once (vectorised):

- jerk: P_4 = 24 a_4 + 120 a_5 s is a line, its root -a_4 / (5 a_5);
- acceleration: P_3 = 6 a_3 + 24 a_4 s + 60 a_5 s^2, both roots by the quadratic formula in its
  cancellation-free form (Press et al., Numerical Recipes, section 5.6);
- velocity: P_2 is a cubic d_0 + d_1 s + d_2 s^2 + d_3 s^3, its roots by the trigonometric /
  Cardano closed form (Numerical Recipes, section 5.6). Where the cubic term is negligible on
  [0, 1] (|d_3| < 1e-4 (|d_0| + |d_1| + |d_2|)) that form loses digits to cancellation: there the
  quadratic's roots instead, each refined by two Newton steps on the cubic.

A polynomial evaluated at extra points of [0, 1] keeps its maximum there, so every value above is
clipped into [0, 1] and kept as a candidate whatever it is (the real part of a complex pair, a
root outside [0, 1], NaN -> 1). A near-double root that rounding turns into a complex pair thus
still yields a point next to it, where the polynomial differs from its extreme by O(delta^3),
delta being the roots' separation. Over random cubics with leading coefficients down to 1e-16 of
the others and near-double roots, the extremes found this way fell short of those from numpy's
companion-matrix roots by about 1e-15 of their size at most (tests/test_trajectory.py checks
them against scipy's piecewise-polynomial root finder).
"""

from __future__ import annotations

import numpy as np

N_COEF = 6  # quintic span: a_0 .. a_5
ORDERS = (1, 2, 3)  # velocity, acceleration, jerk
# FALLING[k, r] = k! / (k - r)! (0 for k < r): d^r/ds^r s^k = FALLING[k, r] s^(k - r).
FALLING = np.array(
    [[np.prod(np.arange(k - r + 1, k + 1)) if k >= r else 0.0 for r in range(N_COEF)]
     for k in range(N_COEF)], dtype=float)


def _polynomial_rows(order: int, scale: tuple[float, ...]) -> np.ndarray:
    """(len(scale), 3, 6): row i, o maps a to scale[i] times the s^i coefficient of P_(o+order)."""
    rows = np.zeros((len(scale), 3, N_COEF))
    for o in range(3):
        for i, factor in enumerate(scale):
            k = i + o + order
            if k < N_COEF:
                rows[i, o, k] = factor * FALLING[k, o + order]
    return rows


# One matrix product gives, for every order o (velocity, acceleration, jerk) and row i:
# the value polynomial P_o (5 rows), its slope's coefficients d_i (4), d_0/2, d_1/3, d_2/3 (3),
# and the slope's own slope d_1, 2 d_2, 3 d_3 (3). Rows are (i, o): a block reshapes to (i, 3 n).
_TO_ROWS = np.concatenate([
    _polynomial_rows(1, (1.0,) * 5),
    _polynomial_rows(2, (1.0,) * 4),
    _polynomial_rows(2, (0.5, 1.0 / 3.0, 1.0 / 3.0)),
    _polynomial_rows(3, (1.0,) * 3),
]).reshape(-1, N_COEF)
_VALUE, _SLOPE, _SCALED, _CURVATURE = slice(0, 15), slice(15, 27), slice(27, 36), slice(36, 45)
_VALUE_TWICE = np.repeat(_polynomial_rows(1, (1.0,) * 5)[:, None], 2, axis=1).reshape(30, N_COEF)
_ROOTS = 3
N_CANDIDATES = 2 + _ROOTS  # s = 0, s = 1, the roots
_NEARLY_QUADRATIC = 1e-4  # |d_3| below this times |d_0| + |d_1| + |d_2|: solve the quadratic
_TRIGONOMETRIC = (np.array([0.0, 2.0, -2.0]) * np.pi / 3.0)[:, None]  # branches of acos / 3
# 0-d arrays: numpy combines them with arrays faster than Python floats.
_ZERO, _ONE, _MINUS_ONE, _MINUS_TWO = (np.array(v) for v in (0.0, 1.0, -1.0, -2.0))
_HALF, _MINUS_HALF = np.array(0.5), np.array(-0.5)
_THIRD, _ONE_AND_HALF = np.array(1.0 / 3.0), np.array(1.5)


def cubic_roots(coefficients: np.ndarray) -> np.ndarray:
    """Candidates (3, n) in [0, 1] for the real roots of d_0 + d_1 s + d_2 s^2 + d_3 s^3.

    coefficients: (4, n), rows d_0 .. d_3 (d_3 = 0 or d_3 = d_2 = 0 allowed). Every real root
    in [0, 1] is among the candidates (to rounding); the rest are harmless points of [0, 1].
    """
    d = np.asarray(coefficients, dtype=float)
    out = np.empty((_ROOTS, d.shape[1]))
    scaled = d[:3] / np.array([2.0, 3.0, 3.0])[:, None]
    curvature = d[1:] * np.array([1.0, 2.0, 3.0])[:, None]
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        _cubic_roots_into(out, d, scaled, curvature)
        _clip_unit(out)
    return out


def _clip_unit(points: np.ndarray) -> None:
    np.fmax(np.fmin(points, _ONE, out=points), _ZERO, out=points)  # fmin/fmax: NaN -> 1


def _quadratic_roots_into(out, d0, d1, d2) -> None:
    """Both roots of d0 + d1 s + d2 s^2 into out (2, n) (a line's root and +-inf if d2 = 0; for
    a complex pair its real part and another point). -(b + sign(b) sqrt(b^2 - a c)) for
    a + 2 b s + c s^2 has no cancellation; the roots are its quotients with c and a."""
    half_d1 = _HALF * d1
    part = np.sqrt(np.fmax(half_d1 * half_d1 - d0 * d2, _ZERO))
    np.copysign(part, half_d1, out=part)
    part += half_d1
    np.negative(part, out=part)
    np.divide(part, d2, out=out[0])
    np.divide(d0, part, out=out[1])


def _cubic_roots_into(out, cubic, scaled, curvature) -> None:
    """Unclipped candidates of the roots of the cubics (4, n) into out (3, n); scaled: (3, n)
    their d_0 / 2, d_1 / 3, d_2 / 3; curvature: (3, n) the coefficients of their derivatives."""
    d0, d1, d2, d3 = cubic
    half_d0, third_d1, third_d2 = scaled
    inverse = 1.0 / d3
    shift = third_d2 * inverse  # s = y - shift removes the square term
    third_c = third_d1 * inverse
    shift_squared = shift * shift
    q = shift_squared - third_c
    r = shift * (shift_squared - _ONE_AND_HALF * third_c) + half_d0 * inverse
    cubed = q * q
    cubed *= q
    disc = r * r - cubed
    root_q = np.sqrt(q)
    # disc < 0: three real roots -2 sqrt(q) cos((acos(r / q^1.5) + 2 pi k) / 3) - shift, ...
    angle = np.arccos(np.fmax(np.fmin(r / (q * root_q), _ONE), _MINUS_ONE))
    angle *= _THIRD
    roots = np.cos(angle + _TRIGONOMETRIC, out=out)
    roots *= root_q * _MINUS_TWO
    # ... otherwise one, A + q / A - shift, A = -sign(r) (|r| + sqrt(disc))^(1/3) (q = 0 if A = 0),
    # and a complex pair whose real part -(A + q / A) / 2 - shift marks a near-double root.
    big = np.cbrt(np.abs(r) + np.sqrt(np.fmax(disc, _ZERO)))
    np.copysign(big, -r, out=big)
    one = q / (big + (big == 0.0))
    one += big
    one_real = disc >= 0.0
    np.copyto(roots[0], one, where=one_real)
    np.copyto(roots[1:], _MINUS_HALF * one, where=one_real)
    roots -= shift
    size = np.abs(cubic)
    nearly_quadratic = size[3] < _NEARLY_QUADRATIC * size[:3].sum(axis=0)
    if nearly_quadratic.any():  # the closed form loses digits to cancellation here
        rows = np.flatnonzero(nearly_quadratic)
        quadratic = np.empty((2, rows.size))
        _quadratic_roots_into(quadratic, d0[rows], d1[rows], d2[rows])
        x = np.fmax(np.fmin(quadratic[[0, 1, 1]], _ONE), _ZERO)
        # Two Newton steps on the cubic: the quadratic's roots are off by the neglected term
        # (relatively by less than 1e-4, then 1e-8, then rounding).
        c0, c1, c2, c3 = cubic[:, rows]
        e0, e1, e2 = curvature[:, rows]
        for _ in range(2):
            step = x - (((c3 * x + c2) * x + c1) * x + c0) / ((e2 * x + e1) * x + e0)
            x = np.where(np.isfinite(step), step, x)
        roots[:, rows] = x


def _candidates(rows: np.ndarray) -> np.ndarray:
    """Candidates (N_CANDIDATES, 3 n) for all orders from the rows (45, n) of _TO_ROWS @ a."""
    n = rows.shape[1]
    points = np.zeros((N_CANDIDATES, 3 * n))
    points[1] = 1.0
    slope = rows[_SLOPE]  # (4 i x 3 o, n)
    _cubic_roots_into(points[2:, :n], slope[0::3], rows[_SCALED][0::3], rows[_CURVATURE][0::3])
    _quadratic_roots_into(points[2:4, n:2 * n], *slope[1:9:3])  # acceleration's slope P_3
    np.divide(slope[2], -slope[5], out=points[2, 2 * n:])  # jerk's slope P_4, a line
    _clip_unit(points[2:])
    return points


def _extremes(coef: np.ndarray):
    """Values and points (each (2, 3 m nq): max, min) of every span, joint and order."""
    rows = _TO_ROWS @ coef.reshape(N_COEF, -1)
    poly = rows[_VALUE].reshape(5, -1)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        points = _candidates(rows)
    values = poly[4] * points
    for i in (3, 2, 1):
        values += poly[i]
        values *= points
    values += poly[0]
    n = values.shape[1]
    best = np.empty((2, n), dtype=np.intp)
    values.argmax(axis=0, out=best[0])
    values.argmin(axis=0, out=best[1])
    best *= n
    best += np.arange(n)
    return values.ravel()[best], points.ravel()[best]


def candidate_points(coef: np.ndarray) -> np.ndarray:
    """Points of [0, 1] that include every extreme of P_o, (N_CANDIDATES, 3, m, nq).

    coef: (6, m, nq) normalised span coefficients, power-major; axis 1 of the result is the
    order (velocity, acceleration, jerk), axis 0 the candidates (0, 1, then roots).
    """
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        points = _candidates(_TO_ROWS @ coef.reshape(N_COEF, -1))
    return points.reshape((N_CANDIDATES, 3) + coef.shape[1:])


def span_extremes(coef: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Exact max and min over s in [0, 1] of P_o for o = velocity, acceleration, jerk.

    coef: (6, m, nq) normalised coefficients, power-major. Returns (values, points), each
    (2, 3, m, nq): [0] the maxima, [1] the minima, and where on the span (s) they are. The time
    derivative of order o is the value times L_span^-o.
    """
    values, points = _extremes(coef)
    shape = (2, 3) + coef.shape[1:]
    return values.reshape(shape), points.reshape(shape)


def extreme_value_gradients(points: np.ndarray, dcoef: np.ndarray) -> np.ndarray:
    """Derivatives (2, 3, m, nq, n_par) of span_extremes' values given dcoef = da/dp
    (6, m, nq, n_par): by the envelope theorem the extreme moves with the coefficients at its
    fixed point s (a span end, or where the slope is zero)."""
    shape = (2,) + points.shape[1:] + dcoef.shape[-1:]
    # dP_o/dp at fixed s, its coefficients repeated for max and min: all operands of the Horner
    # steps below have one shape (numpy broadcasts small arrays much slower).
    dpoly = (_VALUE_TWICE @ dcoef.reshape(N_COEF, -1)).reshape((5,) + shape)
    s = np.repeat(points[..., None], shape[-1], axis=-1)
    out = dpoly[4] * s
    for i in (3, 2, 1):
        out += dpoly[i]
        out *= s
    out += dpoly[0]
    return out


def peak_ratios(coef: np.ndarray, spans: np.ndarray, limits: np.ndarray) -> np.ndarray:
    """Largest |derivative| / limit per order and joint, (3, n_joints).

    coef (6, n_span, n_joints) power-major, spans (n_span,) s; limits: (3, n_joints) velocity,
    acceleration, jerk limits in rad/s, rad/s^2, rad/s^3.
    """
    values, _ = span_extremes(coef)
    order = np.array(ORDERS, dtype=float)[:, None]
    peak = np.maximum(values[0], -values[1]) * (spans[None, :] ** -order)[:, :, None]
    return peak.max(axis=1) / limits
