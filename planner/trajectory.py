"""Time-jerk optimal quintic B-spline through joint via-points (Vu & Tran 2020, section 2.2, eq. 1).

The decision variables are the segment durations h_i between consecutive via-points. For given
durations the trajectory is the degree-5 B-spline through the via-points at rest at both ends
(velocity, acceleration and jerk zero; knot layout in planner.bspline). The durations minimise

    cost = k_T * T + k_J * (1/N) sum_j int_0^T (jerk_j(t) / JC_j)^2 dt        [s]

with T = sum h_i, N joints and JC_j joint j's jerk limit, subject to |velocity_j| <= VC_j,
|acceleration_j| <= AC_j and |jerk_j| <= JC_j over the whole trajectory. This is the paper's
eq. (1), k_T N sum h + k_J sum_j int jerk_j^2 dt, divided by N and with each joint's jerk measured
in units of its own limit: both terms are then seconds, and k_T, k_J mean the same whatever the
angle unit, the limits and the joint count. (For Table 1's 60 deg/s^3 = 1.047 rad/s^3 this is the
paper's cost in SI units divided by N, up to a factor 1.097 on the jerk term.)

With the paper's case-2 weights (k_T = 0.1, k_J = 0.9) this cost stretches the paper path by
about 1.5x and brings the peak jerk to about 17 deg/s^3, where the paper reports 18.38 s against
16.17 s (1.14x) and about 40 deg/s^3; our trade-off curve passes through the paper's case-2 point
(relative to case 1) near k_J = 0.58, k_T = 0.42 (bench/planner.py prints and plots it).

Solver: SLSQP on x = log(h / h_start), with analytic gradients. The limits enter as the exact
maximum and minimum of each derivative on each knot span (span ends and real roots of the next
derivative), one pair of constraints per span, joint and derivative order. The start h_start is a
simple per-segment estimate, uniformly time-scaled so that the largest limit ratio is exactly 1
(and, for k_J > 0, stretched by the best uniform factor for the cost), so it is feasible.
The output B-spline is built from the solver's last per-span solve (planner.bspline), and its
exact peaks are then computed from the B-spline itself: if a limit is exceeded,
time is scaled uniformly by the smallest factor that restores it (scaling time by s divides
velocity by s, acceleration by s^2, jerk by s^3). With k_J = 0 time is also scaled down until a
limit is reached exactly, since a trajectory below every limit is not time-optimal. If the solver
fails or ends worse than its start, the start is returned (solver_status says so).
"""

from __future__ import annotations

import contextlib
import math
import time
from dataclasses import dataclass, fields

import numpy as np
from numpy.typing import ArrayLike
from scipy.interpolate import BSpline
from scipy.optimize import minimize
from threadpoolctl import ThreadpoolController

from planner import bspline
from planner.bspline import rest_to_rest_system
from planner.span_extremes import FALLING, ORDERS, peak_ratios
from planner.timing import TimingProblem, uniform_scale

_SLSQP_OPTIONS = {"maxiter": 200, "ftol": 1e-10}
_ORDER_COLUMN = np.array(ORDERS, dtype=float)[:, None]
# max over s in [0, 1] of |P_o(s)| for coefficients of size |a_k| is at most sum_k k!/(k-o)! |a_k|.
_DERIVATIVE_BOUND = FALLING[:, list(ORDERS)].T
_BLAS = ThreadpoolController()
_BLAS_LIBRARIES = _BLAS.select(user_api="blas").lib_controllers


def _one_blas_thread():
    """Small dense solves in a loop: one BLAS thread (a multithreaded one made a 24 x 24
    solve 40x slower). Setting the limit costs about 20 us a call, so only when needed."""
    if all(library.num_threads == 1 for library in _BLAS_LIBRARIES):
        return contextlib.nullcontext()
    return _BLAS.limit(limits=1, user_api="blas")


@dataclass(frozen=True, eq=False)
class JointTrajectory:
    """A rest-to-rest joint trajectory through via-points. Angles in rad, times in s.

    spline: scipy BSpline of degree 5, knots in s, coefficients (n_via + 6, n_joints) rad.
    Peaks are exact maxima over the whole trajectory, per joint (n_joints,). jerk_integrals:
    int jerk_j^2 dt per joint, rad^2/s^5. time_term and jerk_term (s) are the two parts of the
    cost k_T * time_term + k_J * jerk_term (see the module docstring).
    """

    via_points: np.ndarray  # (n_via, n_joints) rad
    via_times: np.ndarray  # (n_via,) s
    segment_durations: np.ndarray  # (n_via - 1,) s
    spline: BSpline
    limits: np.ndarray  # (3, n_joints): rad/s, rad/s^2, rad/s^3
    k_T: float
    k_J: float
    peak_velocity: np.ndarray  # (n_joints,) rad/s
    peak_acceleration: np.ndarray  # (n_joints,) rad/s^2
    peak_jerk: np.ndarray  # (n_joints,) rad/s^3
    jerk_integrals: np.ndarray  # (n_joints,) rad^2/s^5
    time_term: float  # s
    jerk_term: float  # s
    cost: float  # s
    iterations: int
    function_evaluations: int
    solver_status: int
    solver_message: str
    time_scale_repair: float  # uniform time scale applied after the solver (1.0 = none)
    solve_time_ms: float

    @property
    def duration(self) -> float:
        """Total duration T (s)."""
        return float(self.via_times[-1])

    @property
    def limit_ratios(self) -> np.ndarray:
        """Peak |velocity|, |acceleration|, |jerk| over their limits, (3, n_joints)."""
        peaks = np.stack([self.peak_velocity, self.peak_acceleration, self.peak_jerk])
        return peaks / self.limits

    def __call__(self, t: ArrayLike, derivative: int = 0) -> np.ndarray:
        """Joint angles (derivative 0, rad) or their derivative 1..5 (rad/s^k) at times t (s).

        t: scalar or (n,) s; returns (n, n_joints). Before 0 and after the duration the arm is
        at rest at the first or last via-point.
        """
        if derivative not in range(bspline.DEGREE + 1):
            raise ValueError(f"derivative must be 0..5, got {derivative}")
        times = np.atleast_1d(np.asarray(t, dtype=float))
        if times.ndim != 1 or not np.all(np.isfinite(times)):
            raise ValueError("t must be a finite scalar or 1-D array of times in s")
        inside = np.clip(times, 0.0, self.duration)
        out = self.spline(inside, nu=derivative)
        if derivative > 0:
            out[(times < 0.0) | (times > self.duration)] = 0.0
        return out

    def as_record(self) -> dict:
        """Plain-data (lists, floats, strings) summary for a log record, spline included."""
        record = {f.name: getattr(self, f.name) for f in fields(self) if f.name != "spline"}
        record = {k: v.tolist() if isinstance(v, np.ndarray) else v for k, v in record.items()}
        record.update(duration=self.duration, spline_degree=int(self.spline.k),
                      spline_knots=self.spline.t.tolist(),
                      spline_coefficients=self.spline.c.tolist())
        return record


def plan_trajectory(via_points: ArrayLike, v_max: ArrayLike, a_max: ArrayLike, j_max: ArrayLike,
                    k_T: float = 1.0, k_J: float = 0.0) -> JointTrajectory:
    """Time-jerk optimal rest-to-rest quintic B-spline through the via-points.

    via_points: (n_via >= 2, n_joints) rad. v_max, a_max, j_max: per-joint limits, (n_joints,)
    or scalars, in rad/s, rad/s^2, rad/s^3. k_T > 0, k_J >= 0: weights of duration and of the
    normalised jerk integral (module docstring). Raises ValueError on invalid input.
    """
    started = time.perf_counter()
    q, limits, k_T, k_J = _validated(via_points, v_max, a_max, j_max, k_T, k_J)
    system = rest_to_rest_system(q.shape[0])
    with _one_blas_thread():
        problem = TimingProblem(system, q, limits, k_T, k_J)
        try:
            result = minimize(problem.cost, np.zeros_like(problem.h_start),
                              jac=problem.cost_gradient, method="SLSQP",
                              bounds=[(lb, None) for lb in problem.x_lower],
                              constraints=[{"type": "ineq", "fun": problem.constraints,
                                            "jac": problem.constraints_jacobian}],
                              options=_SLSQP_OPTIONS)
            x, status, message = result.x, int(result.status), str(result.message)
            iterations, evaluations = int(result.get("nit", 0)), int(result.get("nfev", 0))
        except (ArithmeticError, ValueError, np.linalg.LinAlgError) as error:
            x, status, message, iterations, evaluations = None, -1, repr(error), 0, 0
        finished = None
        if x is not None and np.all(np.isfinite(x)):
            x = np.maximum(x, problem.x_lower)
            h = problem.h_start * np.exp(x)
            finished = _finish(system, q, limits, k_T, k_J, h, problem.solution(x))
        if finished is None or finished[-1] > problem.start_cost * (1.0 + 1e-9):
            # The solver failed or ended worse than its feasible start: keep the start.
            finished = _finish(system, q, limits, k_T, k_J, problem.h_start)
    spline, repair, peaks, jerk_integrals, jerk_term, cost = finished
    via_times = spline.t[bspline.DEGREE:-bspline.DEGREE][system.via_knot]
    return JointTrajectory(
        via_points=q, via_times=via_times, segment_durations=np.diff(via_times),
        spline=spline, limits=limits, k_T=k_T, k_J=k_J, peak_velocity=peaks[0],
        peak_acceleration=peaks[1], peak_jerk=peaks[2], jerk_integrals=jerk_integrals,
        time_term=float(via_times[-1]), jerk_term=jerk_term, cost=cost,
        iterations=iterations, function_evaluations=evaluations, solver_status=status,
        solver_message=message,
        time_scale_repair=repair, solve_time_ms=(time.perf_counter() - started) * 1e3)


def _validated(via_points, v_max, a_max, j_max, k_T, k_J):
    try:
        q = np.array(via_points, dtype=float)
    except (TypeError, ValueError) as error:
        raise ValueError(f"via_points must be a numeric (n_via, n_joints) array: {error}") from None
    if q.ndim != 2:
        raise ValueError(f"via_points must have shape (n_via, n_joints), got {q.shape}")
    if q.shape[0] < 2 or q.shape[1] < 1:
        raise ValueError(f"need at least 2 via-points and 1 joint, got shape {q.shape}")
    if not np.isfinite(q).all():
        raise ValueError("via_points contain NaN or infinity")
    if (q == q[0]).all():
        raise ValueError("all via_points are equal: there is no motion to time")
    n_joints = q.shape[1]
    limits = np.empty((3, n_joints))
    names = ("v_max", "a_max", "j_max")
    for row, name, value in zip(limits, names, (v_max, a_max, j_max), strict=True):
        try:
            row[:] = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            raise ValueError(f"{name} must be a scalar or have shape ({n_joints},), "
                             f"got {np.shape(value)}") from None
    valid = np.isfinite(limits) & (limits > 0.0)
    if not valid.all():
        row = int(np.flatnonzero(~valid.all(axis=1))[0])
        raise ValueError(f"{names[row]} must be finite and > 0, got {limits[row].tolist()}")
    weights = []
    for name, value in (("k_T", k_T), ("k_J", k_J)):
        try:
            weight = float(value)
        except (TypeError, ValueError):
            raise ValueError(f"{name} must be a number, got {value!r}") from None
        if not math.isfinite(weight) or weight < 0.0:
            raise ValueError(f"{name} must be finite and >= 0, got {value!r}")
        weights.append(weight)
    if weights[0] == 0.0:
        raise ValueError("k_T must be > 0: without a time weight the jerk term alone keeps "
                         "falling as the durations grow, so there is no optimum")
    return q, limits, weights[0], weights[1]


def _finish(system, q, limits, k_T, k_J, h, solved=None):
    """Output spline for durations h (s) after the exact limit check and any uniform rescale;
    solved: (span coefficients, their peak ratios) for h if the solver has them."""
    via_times = np.concatenate([[0.0], np.cumsum(h)])
    knots = bspline.knot_vector(system.span_lengths(h), via_times, system.via_knot)
    breaks = knots[bspline.DEGREE:-bspline.DEGREE]
    coef = system.solve(breaks[1:] - breaks[:-1], q) if solved is None else solved[0]
    spline = BSpline.construct_fast(knots, system.bspline_coefficients(coef, knots, q[0], q[-1]),
                                    bspline.DEGREE, extrapolate=False)
    # The check reads the output spline itself, not the solve it came from: its own Taylor
    # coefficients per span, and their exact extremes unless those of the solve, raised by a
    # bound on the difference, are as good to 1e-12.
    taylor, spans = bspline.spline_span_coefficients(spline, breaks)
    ratios = None
    if solved is not None:
        difference = np.abs(taylor - coef).reshape(bspline.N_COEF, -1)
        bound = (_DERIVATIVE_BOUND @ difference).reshape(3, *coef.shape[1:])  # |P_o| change
        bound = (bound * (spans ** -_ORDER_COLUMN)[:, :, None]).max(axis=1) / limits
        if bound.max() <= 1e-12:
            ratios = solved[1] + bound
    if ratios is None:
        ratios = peak_ratios(taylor, spans, limits)
    jerk_integrals = bspline.jerk_squared_integrals(taylor, spans).sum(axis=0)
    repair = uniform_scale(ratios)
    if repair > 1.0 or k_J == 0.0:
        # Same coefficients on knots scaled by s: derivative o is divided by s^o exactly.
        spline = BSpline.construct_fast(spline.t * repair, spline.c, spline.k, extrapolate=False)
        ratios = ratios / repair**_ORDER_COLUMN
        jerk_integrals = jerk_integrals / repair**5
    else:
        repair = 1.0
    jerk_term = float(np.mean(jerk_integrals / limits[2] ** 2))
    cost = k_T * float(spline.t[-1]) + k_J * jerk_term
    return spline, repair, ratios * limits, jerk_integrals, jerk_term, cost
