"""Time-jerk optimal quintic B-spline (planner.trajectory), checked by independent means.

Peaks are recomputed with scipy's PPoly (roots of the next derivative on every piece) and a dense
sample, time-optimality against a derivative-free search over the segment-duration shape, the jerk
term against numerical quadrature. The building blocks: closed-form roots against numpy's
companion-matrix roots, span extremes against scipy's PPoly root finder, analytic derivatives
against central differences, the B-spline coefficients against scipy's collocation solve.
"""

import json

import numpy as np
import pytest
from finite_differences import assert_derivative, central_difference
from scipy.integrate import quad
from scipy.interpolate import BSpline, PPoly, make_interp_spline
from scipy.optimize import minimize

from planner import bspline
from planner.bspline import rest_to_rest_system
from planner.digging_path import paper_joint_via_points
from planner.span_extremes import cubic_roots, span_extremes
from planner.timing import TimingProblem
from planner.trajectory import JointTrajectory, plan_trajectory

DEG = np.pi / 180.0
# Vu & Tran 2020, Table 1: every joint 100 deg/s, 60 deg/s^2, 60 deg/s^3.
TABLE1 = (100.0 * DEG, 60.0 * DEG, 60.0 * DEG)
BOUND = 1.0 + 1e-9


def random_via_points(rng: np.random.Generator, n_via: int, n_joints: int = 3) -> np.ndarray:
    """Random walks of up to 60 deg per segment and joint, some joints still on some segments."""
    steps = rng.uniform(-60.0, 60.0, (n_via - 1, n_joints)) * DEG
    steps[rng.random(steps.shape) < 0.2] = 0.0
    steps[np.all(steps == 0.0, axis=1), 0] = 10.0 * DEG
    return np.vstack([np.zeros(n_joints), np.cumsum(steps, axis=0)]) + rng.uniform(-1, 1, n_joints)


def independent_peaks(spline: BSpline) -> np.ndarray:
    """max |velocity|, |acceleration|, |jerk| per joint (3, n_joints): scipy's PPoly form of
    the spline, numpy's companion-matrix roots of the next derivative on every piece."""
    n_joints = spline.c.shape[1]
    peaks = np.zeros((3, n_joints))
    for joint in range(n_joints):
        pp = PPoly.from_spline(BSpline(spline.t, spline.c[:, joint], spline.k))
        for i, order in enumerate((1, 2, 3)):
            derivative, slope = pp.derivative(order), pp.derivative(order + 1)
            points = [pp.x]
            for piece in range(pp.x.size - 1):
                width = pp.x[piece + 1] - pp.x[piece]
                if width <= 0.0 or not np.any(slope.c[:, piece]):
                    continue
                roots = np.roots(slope.c[:, piece])  # local coordinate t - x[piece]
                real = roots[np.abs(roots.imag) <= 1e-9 * (1.0 + np.abs(roots))].real
                points.append(pp.x[piece] + real[(real >= 0.0) & (real <= width)])
            peaks[i, joint] = np.max(np.abs(derivative(np.concatenate(points))))
    return peaks


def ppoly_peaks(spline: BSpline) -> np.ndarray:
    """The same as independent_peaks, faster: scipy's PPoly root finder (for the search)."""
    peaks = np.zeros((3, spline.c.shape[1]))
    for joint in range(spline.c.shape[1]):
        pp = PPoly.from_spline(BSpline(spline.t, spline.c[:, joint], spline.k))
        for i, order in enumerate((1, 2, 3)):
            roots = pp.derivative(order + 1).roots(discontinuity=False, extrapolate=False)
            points = np.concatenate([pp.x, roots[np.isfinite(roots)]])
            peaks[i, joint] = np.max(np.abs(pp.derivative(order)(points)))
    return peaks


def limits_array(v_max, a_max, j_max, n_joints):
    return np.stack([np.broadcast_to(v, (n_joints,)) for v in (v_max, a_max, j_max)])


def assert_valid(trajectory: JointTrajectory, via_points, limits) -> np.ndarray:
    """Interpolation, rest at both ends, limits everywhere; returns the limit ratios (3, nq)."""
    spline = trajectory.spline
    assert spline.k == 5
    assert spline.c.shape == (via_points.shape[0] + 6, via_points.shape[1])
    np.testing.assert_allclose(spline(trajectory.via_times), via_points, rtol=0, atol=1e-9)
    np.testing.assert_allclose(np.diff(trajectory.via_times), trajectory.segment_durations,
                               rtol=1e-12)
    for end in (0.0, trajectory.duration):
        for order in (1, 2, 3):
            assert np.all(np.abs(spline(end, nu=order)) < 1e-9)
    ratios = independent_peaks(spline) / limits
    assert ratios.max() <= BOUND
    np.testing.assert_allclose(trajectory.limit_ratios, ratios, rtol=1e-9, atol=1e-12)
    samples = np.linspace(0.0, trajectory.duration, 20001)
    for i, order in enumerate((1, 2, 3)):
        assert np.max(np.abs(trajectory(samples, order)) / limits[i]) <= BOUND
    return ratios


def shape_time(via_points, limits, log_h) -> float:
    """Shortest duration with segment durations proportional to exp(log_h): a second,
    independent implementation (scipy's own B-spline solve on the documented knot layout)."""
    h = np.exp(log_h - np.max(log_h))
    times = np.concatenate([[0.0], np.cumsum(h)])
    # Documented layout: one extra knot a quarter of the end segment away from each rest end.
    extra = [times[0] + h[0] / 4.0, times[-1] - h[-1] / 4.0]
    breaks = np.sort(np.concatenate([times, extra]))
    knots = np.concatenate([[0.0] * 5, breaks, [times[-1]] * 5])
    rest = [(1, np.zeros(via_points.shape[1])), (2, np.zeros(via_points.shape[1])),
            (3, np.zeros(via_points.shape[1]))]
    spline = make_interp_spline(times, via_points, k=5, t=knots, bc_type=(rest, rest))
    ratios = ppoly_peaks(spline) / limits
    scale = max(ratios[0].max(), ratios[1].max() ** 0.5, ratios[2].max() ** (1 / 3))
    return scale * times[-1]


@pytest.mark.parametrize("n_via, seeds", [(5, range(12)), (2, range(4)), (8, range(4))])
@pytest.mark.parametrize("k_J", [0.0, 0.5])
def test_limits_hold_everywhere_on_random_via_points(n_via, seeds, k_J):
    for seed in seeds:
        rng = np.random.default_rng(1000 * n_via + seed)
        q = random_via_points(rng, n_via)
        v_max, a_max, j_max = rng.uniform(0.5, 2.0, 3) * np.array(TABLE1)
        trajectory = plan_trajectory(q, v_max, a_max, j_max, k_T=1.0 - k_J, k_J=k_J)
        assert_valid(trajectory, q, limits_array(v_max, a_max, j_max, 3))


@pytest.mark.parametrize("seed", range(6))
def test_time_optimal_solution_reaches_a_limit(seed):
    rng = np.random.default_rng(seed)
    q = random_via_points(rng, 5)
    trajectory = plan_trajectory(q, *TABLE1, k_T=1.0, k_J=0.0)
    ratios = assert_valid(trajectory, q, limits_array(*TABLE1, 3))
    assert abs(ratios.max() - 1.0) < 1e-6


@pytest.mark.parametrize("seed", [0, 1])
def test_time_optimal_duration_matches_a_direct_search(seed):
    rng = np.random.default_rng(50 + seed)
    q = random_via_points(rng, 5)
    limits = limits_array(*TABLE1, 3)
    trajectory = plan_trajectory(q, *TABLE1, k_T=1.0, k_J=0.0)
    # Nelder-Mead over the duration shape, from equal segments: no gradients, no constraints.
    search = minimize(lambda x: shape_time(q, limits, x), np.zeros(4), method="Nelder-Mead",
                      options={"xatol": 1e-4, "fatol": 1e-7, "maxfev": 600})
    assert trajectory.duration <= search.fun * (1.0 + 1e-4)
    # ... and the search, started at the planner's answer, finds nothing better.
    polish = minimize(lambda x: shape_time(q, limits, x), np.log(trajectory.segment_durations),
                      method="Nelder-Mead", options={"maxfev": 150})
    assert trajectory.duration <= polish.fun * (1.0 + 1e-6)


def test_more_jerk_weight_trades_time_for_smoothness():
    q = random_via_points(np.random.default_rng(7), 5)
    results = [plan_trajectory(q, *TABLE1, k_T=1.0 - w, k_J=w) for w in (0.0, 0.1, 0.3, 0.6, 0.9)]
    durations = np.array([r.duration for r in results])
    jerk_terms = np.array([r.jerk_term for r in results])
    assert np.all(np.diff(durations) >= -1e-6 * durations[:-1])
    assert np.all(np.diff(jerk_terms) <= 1e-6 * jerk_terms[:-1])
    assert durations[-1] > 1.1 * durations[0]


def test_cost_terms_match_their_definition():
    q = random_via_points(np.random.default_rng(3), 5)
    j_max = np.array([0.8, 1.0, 1.3])
    trajectory = plan_trajectory(q, 1.5, 1.0, j_max, k_T=0.4, k_J=0.6)
    per_joint = [quad(lambda t, j=j: trajectory.spline(t, nu=3)[j] ** 2, 0.0, trajectory.duration,
                      points=trajectory.spline.t[5:-5], limit=200, epsabs=0, epsrel=1e-11)[0]
                 for j in range(3)]
    np.testing.assert_allclose(trajectory.jerk_integrals, per_joint, rtol=1e-8)
    np.testing.assert_allclose(trajectory.jerk_term, np.mean(np.array(per_joint) / j_max**2),
                               rtol=1e-8)
    assert trajectory.time_term == pytest.approx(trajectory.duration, rel=1e-12)
    assert trajectory.cost == pytest.approx(0.4 * trajectory.duration + 0.6 * trajectory.jerk_term)


def test_paper_cases():
    """Section 3.1: case 1 (k_T=1, k_J=0) has a joint at the 60 deg/s^3 jerk limit; case 2
    (k_T=0.1, k_J=0.9) is slower (paper: 16.17 s -> 18.38 s) with peak jerk well below
    (paper: about 40 deg/s^3)."""
    q = paper_joint_via_points()
    limits = limits_array(*TABLE1, 3)
    case1 = plan_trajectory(q, *TABLE1, k_T=1.0, k_J=0.0)
    case2 = plan_trajectory(q, *TABLE1, k_T=0.1, k_J=0.9)
    ratios1 = assert_valid(case1, q, limits)
    assert_valid(case2, q, limits)
    assert abs(ratios1[2].max() - 1.0) < 1e-6
    assert case2.duration > case1.duration
    assert case2.peak_jerk.max() <= 0.75 * case1.peak_jerk.max()


def test_deterministic():
    q = random_via_points(np.random.default_rng(11), 5)
    first = plan_trajectory(q, *TABLE1, k_T=0.3, k_J=0.7)
    second = plan_trajectory(q.copy(), *TABLE1, k_T=0.3, k_J=0.7)
    np.testing.assert_array_equal(first.segment_durations, second.segment_durations)
    np.testing.assert_array_equal(first.spline.c, second.spline.c)


@pytest.mark.parametrize("q", [
    np.array([[0.0, 0.0], [0.0, 0.0], [1.0, 0.5], [1.0, 0.5], [1.0, 0.5], [2.0, 0.0]]),
    np.array([[0.0], [1e-6], [3.0]]),  # one tiny and one huge segment, one joint
    np.array([[0.0, 0.0, 0.0], [2.0, -2.0, 0.1], [0.0, 0.0, 0.0]]),  # there and back
    np.linspace(0.0, 1.0, 8)[:, None] * np.ones((1, 6)),  # straight line, six joints
])
def test_awkward_via_points_still_give_a_valid_trajectory(q):
    for k_J in (0.0, 0.9):
        trajectory = plan_trajectory(q, *TABLE1, k_T=1.0 - k_J, k_J=k_J)
        assert_valid(trajectory, q, limits_array(*TABLE1, q.shape[1]))


def test_evaluation_outside_the_trajectory_is_at_rest():
    q = random_via_points(np.random.default_rng(5), 4)
    trajectory = plan_trajectory(q, *TABLE1)
    t = np.array([-1.0, 0.0, trajectory.duration, trajectory.duration + 2.0])
    np.testing.assert_allclose(trajectory(t), q[[0, 0, -1, -1]], atol=1e-9)
    assert np.all(trajectory(t[[0, 3]], derivative=1) == 0.0)
    assert trajectory(0.5).shape == (1, 3)


def test_record_is_plain_data_and_rebuilds_the_spline():
    q = random_via_points(np.random.default_rng(6), 5)
    trajectory = plan_trajectory(q, *TABLE1, k_T=0.5, k_J=0.5)
    record = json.loads(json.dumps(trajectory.as_record()))
    rebuilt = BSpline(np.array(record["spline_knots"]), np.array(record["spline_coefficients"]),
                      record["spline_degree"])
    t = np.linspace(0.0, trajectory.duration, 101)
    np.testing.assert_array_equal(rebuilt(t), trajectory(t))
    assert record["segment_durations"] == trajectory.segment_durations.tolist()
    assert record["via_points"] == q.tolist()


@pytest.mark.parametrize("kwargs, message", [
    (dict(via_points=np.zeros((1, 3))), "at least 2 via-points"),
    (dict(via_points=np.zeros(5)), "shape"),
    (dict(via_points=[[0.0, 1.0], [np.nan, 0.0]]), "NaN"),
    (dict(via_points=[["a", "b"], ["c", "d"]]), "numeric"),
    (dict(via_points=np.ones((4, 3))), "all via_points are equal"),
    (dict(v_max=0.0), "v_max"),
    (dict(a_max=[1.0, -1.0, 1.0]), "a_max"),
    (dict(j_max=[1.0, 1.0]), "j_max"),
    (dict(j_max=np.inf), "j_max"),
    (dict(k_T=-0.1), "k_T"),
    (dict(k_J=-1.0), "k_J"),
    (dict(k_T=0.0, k_J=0.0), "k_T"),
    (dict(k_T=0.0, k_J=1.0), "k_T"),
    (dict(k_J=float("nan")), "k_J"),
])
def test_bad_input_is_a_clear_value_error(kwargs, message):
    arguments = dict(via_points=random_via_points(np.random.default_rng(0), 3),
                     v_max=1.0, a_max=1.0, j_max=1.0, k_T=1.0, k_J=0.0)
    arguments.update(kwargs)
    with pytest.raises(ValueError, match=message):
        plan_trajectory(**arguments)


# --- building blocks of the planner, each against an independent reference -------------------

def random_cubics(rng: np.random.Generator, n: int) -> np.ndarray:
    """(4, n) rows d_0..d_3: generic cubics, tiny or zero leading coefficients, lower degrees,
    and cubics built from real roots in and around [0, 1] (near-double and at 0 and 1)."""
    d = rng.normal(size=(4, n))
    part = n // 6
    d[3, :part] *= 10.0 ** rng.uniform(-16, -1, part)  # nearly quadratic
    d[3, part:2 * part] = 0.0  # quadratic
    d[2:, 2 * part:2 * part + part // 2] = 0.0  # a line
    roots = rng.uniform(-0.5, 1.5, (3, n))
    near = slice(3 * part, 4 * part)
    roots[1, near] = roots[0, near] + 10.0 ** rng.uniform(-10, -2, part)
    roots[0, 4 * part:5 * part] = rng.choice([0.0, 1.0], part)
    built = slice(3 * part, n)
    k = rng.normal(size=n)[built]
    r0, r1, r2 = roots[:, built]
    d[:, built] = k * np.stack([-r0 * r1 * r2, r0 * r1 + r0 * r2 + r1 * r2, -(r0 + r1 + r2),
                                np.ones_like(r0)])
    return d


def test_cubic_roots_contain_every_real_root_in_the_unit_interval():
    d = random_cubics(np.random.default_rng(40), 3000)
    candidates = cubic_roots(d)
    assert candidates.shape == (3, d.shape[1])
    assert np.all((candidates >= 0.0) & (candidates <= 1.0))
    # The contract that matters: the antiderivative's extremes over [0, 1] are found. numpy's
    # companion-matrix roots are the reference; a near-double root it reports as complex is
    # kept as its real part there too.
    quartic = np.vstack([np.zeros(d.shape[1]), d / np.arange(1.0, 5.0)[:, None]])
    for i in range(d.shape[1]):
        degree = np.flatnonzero(d[:, i])[-1]
        roots = np.roots(d[degree::-1, i])
        roots = roots[np.abs(roots.imag) <= 1e-6 * (1.0 + np.abs(roots))].real
        reference = np.concatenate([[0.0, 1.0], roots[(roots >= 0.0) & (roots <= 1.0)]])
        ours = np.concatenate([[0.0, 1.0], candidates[:, i]])
        values = np.polynomial.polynomial.polyval(reference, quartic[:, i])
        found = np.polynomial.polynomial.polyval(ours, quartic[:, i])
        scale = np.abs(values).max() + np.abs(quartic[:, i]).max()
        assert found.max() >= values.max() - 1e-13 * scale
        assert found.min() <= values.min() + 1e-13 * scale
        # A simple, well separated root in the interval is found to full precision.
        simple = roots[(roots > 1e-3) & (roots < 1.0 - 1e-3)]
        if simple.size and np.min(np.abs(np.subtract.outer(roots, roots))
                                  + np.eye(roots.size)) > 1e-2:
            assert np.min(np.abs(candidates[:, i][:, None] - simple), axis=0).max() < 1e-9


def test_span_extremes_match_scipy_root_finder():
    rng = np.random.default_rng(41)
    coef = rng.normal(size=(6, 40, 3))
    coef[5, :10] = 0.0  # lower degree spans
    coef[4:, 10:15] = 0.0
    coef[1:, 15:18] = 0.0  # constant: every derivative zero
    coef[:, 18:24] = rng.normal(size=(6, 6, 3)) * 10.0 ** rng.uniform(-8, 3, (6, 1, 1))
    values, points = span_extremes(coef)
    assert values.shape == points.shape == (2, 3, 40, 3)
    for order in (1, 2, 3):
        for span in range(40):
            for joint in range(3):
                pp = PPoly(coef[::-1, span, joint][:, None], [0.0, 1.0])
                derivative = pp.derivative(order)
                roots = pp.derivative(order + 1).roots(extrapolate=False)
                at = np.concatenate([[0.0, 1.0], roots[np.isfinite(roots)]])
                reference = derivative(at)
                scale = np.abs(reference).max() + 1e-300
                got = values[:, order - 1, span, joint]
                np.testing.assert_allclose(got, [reference.max(), reference.min()],
                                           rtol=0, atol=1e-13 * scale)
                # ... and they are the values at the points reported.
                np.testing.assert_allclose(derivative(points[:, order - 1, span, joint]), got,
                                           rtol=0, atol=1e-13 * scale)


def test_spline_solve_sensitivity_matches_finite_differences():
    system = rest_to_rest_system(5)
    q = random_via_points(np.random.default_rng(42), 5)
    log_spans = np.log(np.random.default_rng(43).uniform(0.3, 2.0, system.n_span))
    spans = np.exp(log_spans)
    coef, dcoef = system.solve_with_sensitivity(spans, q, np.diag(spans))  # d/d log L
    np.testing.assert_array_equal(coef, system.solve(spans, q))
    assert_derivative(dcoef, central_difference(lambda x: system.solve(np.exp(x), q), log_spans))


def collocation_matrix(knots: np.ndarray, via_times: np.ndarray) -> np.ndarray:
    """The square system make_interp_spline solves: values at the via times, then velocity,
    acceleration and jerk at both ends, one column per quintic B-spline basis function."""
    basis = BSpline(knots, np.eye(knots.size - 6), 5)
    ends = [basis(t, nu=nu) for t in via_times[[0, -1]] for nu in (1, 2, 3)]
    return np.vstack([basis(via_times), *ends])


def test_bspline_coefficients_match_scipy_collocation():
    for n_via, seed in ((2, 0), (3, 1), (5, 2), (8, 3)):
        rng = np.random.default_rng(44 + seed)
        q = random_via_points(rng, n_via)
        system = bspline.rest_to_rest_system(n_via)
        h = rng.uniform(0.2, 3.0, n_via - 1)
        via_times = np.concatenate([[0.0], np.cumsum(h)])
        knots = bspline.knot_vector(system.span_lengths(h), via_times, system.via_knot)
        breaks = knots[5:-5]
        coef = system.solve(np.diff(breaks), q)
        ours = system.bspline_coefficients(coef, knots, q[0], q[-1])
        rest = [(1, np.zeros(3)), (2, np.zeros(3)), (3, np.zeros(3))]
        scipy_spline = make_interp_spline(via_times, q, k=5, t=knots, bc_type=(rest, rest))
        # Two LU solves, rounded by the BLAS kernel: eps * Skeel cond * |c| each (seen <= 0.26x)
        a = collocation_matrix(knots, via_times)
        skeel = np.max(np.abs(np.linalg.inv(a)) @ np.abs(a) @ np.ones(a.shape[1]))
        bound = np.finfo(float).eps * skeel * np.abs(scipy_spline.c).max()
        np.testing.assert_allclose(ours, scipy_spline.c, rtol=0, atol=4.0 * bound)


def test_timing_gradients_match_finite_differences():
    q = random_via_points(np.random.default_rng(45), 5)
    limits = limits_array(*TABLE1, 3)
    problem = TimingProblem(rest_to_rest_system(5), q, limits, k_T=0.4, k_J=0.6)
    x = np.random.default_rng(46).uniform(-0.2, 0.2, 4)
    # Constraints at zero (a span whose extreme is exactly 0) are round-off noise of ~1e-13, so
    # their central difference is noise / step: the bound of the difference's own error says how
    # close the analytic gradient must be, on any CPU's rounding.
    assert_derivative(problem.cost_gradient(x).copy(), central_difference(problem.cost, x))
    assert_derivative(problem.constraints_jacobian(x).copy(),
                      central_difference(problem.constraints, x))
