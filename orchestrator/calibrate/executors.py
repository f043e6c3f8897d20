"""Where a calibration's trials run: in this process (one worker), on a local process pool
(spawned workers, each holding the Problem once), or on a Dask cluster (the Problem scattered
to every worker once, one task per trial). The Dask connection is the sweep's
(orchestrator.sweep.executors.connect: SchedulerUnreachable, one line); the sweep's own local
pool runs sweep runs only (RunTask in, summary row out), so trials use the standard pool.

The problem is any picklable object with `evaluate(values: {key: value}) -> Fit` (never
raising for a failing trial): orchestrator.calibrate.objective.Problem, or another score, as
bench/calibrate_paper.py's Figure 9 campaign score."""

from __future__ import annotations

import multiprocessing
from collections.abc import Callable, Sequence
from concurrent.futures import Future, ProcessPoolExecutor

from orchestrator.calibrate.objective import Fit, Problem

_PROBLEM: list[Problem] = []  # the problem of a pool worker (set by its initializer)


def _init(problem: Problem) -> None:
    _PROBLEM[:] = [problem]


def _evaluate_here(values: dict[str, float]) -> Fit:
    return _PROBLEM[0].evaluate(values)


def _evaluate_on(problem: Problem, values: dict[str, float]) -> Fit:
    return problem.evaluate(values)


class Trials:
    """map(points) -> Fits in order, on the executor chosen; a context manager."""

    def __init__(self, problem: Problem, workers: int = 1, scheduler: str | None = None) -> None:
        self.problem, self.workers, self.scheduler = problem, max(1, workers), scheduler
        self._pool: ProcessPoolExecutor | None = None
        self._client = self._scattered = None

    @property
    def parallel(self) -> int:
        """How many trials are worth asking for at once."""
        if self._client is not None:
            return max(1, sum(self._client.nthreads().values()))
        return self.workers

    def __enter__(self) -> Trials:
        if self.scheduler is not None:
            from orchestrator.sweep.executors import connect

            self._client = connect(self.scheduler)
            self._scattered = self._client.scatter(self.problem, broadcast=True)
        elif self.workers > 1:
            self._pool = ProcessPoolExecutor(self.workers, multiprocessing.get_context("spawn"),
                                             initializer=_init, initargs=(self.problem,))
        return self

    def __exit__(self, *exc) -> None:
        if self._pool is not None:
            self._pool.shutdown(cancel_futures=True)
        if self._client is not None:
            self._client.close()

    def map(self, points: Sequence[dict[str, float]],
            done: Callable[[], None] | None = None) -> list[Fit]:
        if self._client is not None:
            futures = [self._client.submit(_evaluate_on, self._scattered, p, pure=False)
                       for p in points]
            return [_result(f, done) for f in futures]
        if self._pool is not None:
            pool_futures: list[Future] = [self._pool.submit(_evaluate_here, p) for p in points]
            return [_result(f, done) for f in pool_futures]
        fits = []
        for point in points:
            fits.append(self.problem.evaluate(point))
            if done is not None:
                done()
        return fits


def _result(future, done: Callable[[], None] | None) -> Fit:
    try:
        fit = future.result()
    except Exception as failure:  # noqa: BLE001 - a lost worker fails its trial alone
        fit = Fit(float("inf"), error=f"{type(failure).__name__}: {failure}".splitlines()[0])
    if done is not None:
        done()
    return fit
