"""Where a sweep's runs execute: a local process pool, or an existing Dask cluster.

Local pool (default): `workers` processes started fresh ("spawn": no state inherited from the
planner), each with one BLAS thread, each replaced after `recycle_after` runs so that whatever a
long sweep leaks or fragments in a process does not pile up. Each worker takes one run at a
time over its own pipe, so the planner knows which run every worker is on: a worker that dies
(a crash inside an FMU, a stuck step ended by the watchdog) fails that run alone, and a new
worker takes the next one. (The standard ProcessPoolExecutor is not used: its
max_tasks_per_child deadlocks on Python 3.11-3.13 once a worker retires, CPython gh-115634, and
a dead worker breaks the whole pool without saying whose run killed it.)

Dask (`scheduler="tcp://host:8786"`): each run is one task on the cluster (distributed's own
scheduling, retries of lost workers and as_completed). Our FMUs are built on each worker from
its installed excosim sources (the builds are byte-reproducible, and the run log records each
FMU's content hash, which the summary shows), so a worker needs the same excosim version; FMU
files a scenario names travel with the task. Recycling a Dask worker is the cluster's setting
(`dask worker --lifetime`); campaigns in one worker process run one at a time.
"""

from __future__ import annotations

import multiprocessing
import os
import signal
import threading
from collections import deque
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from multiprocessing.connection import wait
from pathlib import Path
from typing import Any

from orchestrator.sweep.plan import RunTask
from orchestrator.sweep.worker import execute, log_row

OnRow = Callable[[dict[str, Any]], None]
More = Callable[[], list[RunTask]]  # more tasks once the queue is empty ([] when none)
_BLAS_VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")
_ONE_AT_A_TIME = threading.Lock()  # a Dask worker's threads share one process and its FMUs


class SchedulerUnreachable(ConnectionError):
    """The Dask scheduler cannot be reached; str() is one line naming its address."""


def run_local(tasks: list[RunTask], token: str, workers: int, recycle_after: int,
              on_row: OnRow, more: More | None = None) -> None:
    """Run `tasks` on `workers` local processes; on_row(row) in this process as each run ends,
    in the order they end. more(): called whenever the queue is empty, its tasks join it (an
    optimisation's next trial, so that the workers stay busy and alive between trials)."""
    context = multiprocessing.get_context("spawn")
    queue, pool = deque(tasks), []
    with _one_blas_thread():
        try:
            while _refill(queue, more, workers - _busy(pool)) or _busy(pool):
                while len(pool) < min(workers, len(queue) + _busy(pool)):
                    pool.append(_Worker(context, token))
                for worker in pool:
                    if worker.task is None and queue:
                        worker.give(queue.popleft())
                busy = [w for w in pool if w.task is not None]
                wait([w.connection for w in busy] + [w.process.sentinel for w in busy])
                for worker in busy:
                    row = worker.result()
                    if row is None:
                        continue
                    on_row(row)
                    if worker.task is None and worker.done >= recycle_after or worker.dead:
                        worker.stop()
                        pool.remove(worker)
                for worker in [w for w in pool if w.task is None and not queue]:
                    worker.stop()  # nothing left for it: free its memory now
                    pool.remove(worker)
        finally:
            for worker in pool:
                worker.stop()


def _refill(queue: deque, more: More | None, idle: int) -> bool:
    """Whether tasks wait in the queue, after asking `more` for some while fewer wait than
    there are idle workers."""
    while more is not None and len(queue) < idle:
        batch = more()
        if not batch:
            break
        queue.extend(batch)
    return bool(queue)


def _busy(pool: list[_Worker]) -> int:
    return sum(worker.task is not None for worker in pool)


class _Worker:
    """One spawned worker process and the run it is on (so a death is that run's alone)."""

    def __init__(self, context, token: str) -> None:
        self.connection, child = context.Pipe()
        self.process = context.Process(target=_serve, args=(child, token), daemon=True,
                                       name="excosim-sweep-worker")
        self.process.start()
        child.close()
        self.task: RunTask | None = None
        self.done, self.dead = 0, False

    def give(self, task: RunTask) -> None:
        self.task = task
        self.connection.send(task)

    def result(self) -> dict[str, Any] | None:
        """The row of the run it was on once that ended (a failed row if the process died),
        else None (still running)."""
        task = self.task
        if task is None:
            return None
        if self.connection.poll():
            try:
                row = self.connection.recv()
            except (EOFError, OSError):
                row = None
            if row is not None:
                self.task, self.done = None, self.done + 1
                return row
        elif self.process.is_alive():
            return None
        self.task, self.dead = None, True
        # A dying process closes its end of the pipe a moment before it can be reaped (longer
        # with more threads to end): wait for it, or its exit status would read None.
        self.process.join(timeout=10)
        return _died(task, self.process.exitcode)

    def stop(self) -> None:
        """End the process: idle, by asking; on a run, by SIGTERM (its log gets its end record)."""
        if self.process.is_alive():
            if self.task is None:
                try:
                    self.connection.send(None)
                except OSError:
                    pass
            else:
                self.process.terminate()
            self.process.join(timeout=10)
            if self.process.is_alive():
                self.process.kill()
                self.process.join()
        self.connection.close()


def _serve(connection, token: str) -> None:
    """A worker's loop: a task in, its row out, until told to stop (None)."""
    _init_worker()
    try:
        while True:
            task = connection.recv()
            if task is None:
                return
            connection.send(execute(task, token))
    except (EOFError, BrokenPipeError):  # the planner is gone
        return
    except KeyboardInterrupt:  # stopped (Ctrl-C, SIGTERM): the run has closed its log
        return


def _init_worker() -> None:
    # SIGTERM from the planner (a stopped sweep) ends the run like Ctrl-C: its log gets the
    # end record "interrupted", and the next start of the sweep runs it again.
    signal.signal(signal.SIGTERM, signal.default_int_handler)


@contextmanager
def _one_blas_thread() -> Iterator[None]:
    """Workers inherit the environment: one BLAS thread each, without changing ours for good."""
    saved = {name: os.environ.get(name) for name in _BLAS_VARIABLES}
    os.environ.update(dict.fromkeys(_BLAS_VARIABLES, "1"))
    try:
        yield
    finally:
        for name, value in saved.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value


def connect(address: str, timeout_s: float = 10.0):
    """A distributed.Client of the scheduler at `address`; SchedulerUnreachable (one line)."""
    from distributed import Client

    try:
        return Client(address, timeout=timeout_s, set_as_default=False)
    except (OSError, TimeoutError, ValueError) as error:
        reason = str(error).splitlines()[0] if str(error) else type(error).__name__
        raise SchedulerUnreachable(f"--scheduler {address}: cannot reach the Dask scheduler "
                                   f"({reason})") from None


def run_dask(tasks: list[RunTask], token: str, client, on_row: OnRow,
             more: More | None = None) -> None:
    """Run `tasks` as tasks of the Dask cluster behind `client`; on_row(row) as each ends.
    more(): called when no submitted task waits to start (see run_local); its tasks are
    submitted too."""
    from distributed import as_completed as dask_completed

    def submit(batch: list[RunTask]) -> list:
        new = {client.submit(_execute_alone, task, token, key=f"excosim-{token}-{task.run}",
                             pure=False): task for task in batch}
        futures.update(new)
        return list(new)

    futures: dict[Any, RunTask] = {}
    waiting = submit(tasks) or submit(more() if more is not None else [])
    try:
        running = dask_completed(waiting, loop=client.loop)
        for future in running:
            task = futures[future]
            try:
                row = future.result()
            except Exception as failure:  # noqa: BLE001 - a lost worker, a task error
                row = _failed(task, f"{type(failure).__name__}: {failure}")
            on_row(row)
            while more is not None and running.count() < len(client.nthreads()):
                new = submit(more())
                if not new:
                    break
                for one in new:
                    running.add(one)
    except BaseException:
        client.cancel(list(futures))
        raise


def _execute_alone(task: RunTask, token: str) -> dict[str, Any]:
    with _ONE_AT_A_TIME:
        return execute(task, token)


def _failed(task: RunTask, error: str) -> dict[str, Any]:
    row = {"run": task.run, **task.point, **log_row(Path(task.log_path))}
    row.update(status="failed", error=error.replace("\n", " "), wall_s=None)
    return row


def _died(task: RunTask, exit_code: int | None) -> dict[str, Any]:
    how = f"signal {-exit_code}" if exit_code is not None and exit_code < 0 else \
        f"exit status {exit_code}"
    row = _failed(task, f"the worker process died during the run ({how}: a crash inside an "
                  "FMU, or a stuck step ended by the watchdog)")
    if row.get("termination") == "error" and row.get("message"):
        row["error"] = row["message"]  # the step watchdog's line names the FMU
    return row
