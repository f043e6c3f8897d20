"""Where a sweep's runs execute: a local process pool, or an existing Dask cluster.

Local pool (default): `workers` processes started fresh ("spawn": no state inherited from the
planner), each with one BLAS thread, each replaced after `recycle_after` runs so that whatever a
long sweep leaks or fragments in a process does not pile up. A worker that dies (a crash inside
an FMU, a stuck step ended by the watchdog) breaks the pool: the runs that had started are run
again one by one in a pool of their own, where the run that kills its worker again is recorded
as failed; the runs that had not started go on in a new pool.

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
from collections.abc import Callable, Iterator
from concurrent.futures import ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from orchestrator.sweep.plan import RunTask
from orchestrator.sweep.worker import execute, log_row

OnRow = Callable[[dict[str, Any]], None]
_BLAS_VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")
_ONE_AT_A_TIME = threading.Lock()  # a Dask worker's threads share one process and its FMUs


class SchedulerUnreachable(ConnectionError):
    """The Dask scheduler cannot be reached; str() is one line naming its address."""


def run_local(tasks: list[RunTask], token: str, workers: int, recycle_after: int,
              on_row: OnRow) -> None:
    """Run `tasks` on a local pool of `workers` processes; on_row(row) in this process as each
    run ends, in the order they end."""
    pending = list(tasks)
    while pending:
        broken = _pool_pass(pending, token, workers, recycle_after, on_row)
        started = [task for task in broken if Path(task.log_path).exists()]
        pending = [task for task in broken if task not in started]
        for task in started:  # alone, so that a second death is its own
            if _pool_pass([task], token, 1, 1, on_row):
                on_row(_died(task))


def _pool_pass(tasks: list[RunTask], token: str, workers: int, recycle_after: int,
               on_row: OnRow) -> list[RunTask]:
    """One pool over `tasks`; returns the tasks lost to a broken pool."""
    broken = []
    with _one_blas_thread(), ProcessPoolExecutor(
            max_workers=workers, mp_context=multiprocessing.get_context("spawn"),
            max_tasks_per_child=recycle_after, initializer=_init_worker) as pool:
        futures = {pool.submit(execute, task, token): task for task in tasks}
        try:
            for future in as_completed(futures):
                task = futures[future]
                try:
                    row = future.result()
                except BrokenProcessPool:
                    broken.append(task)
                    continue
                except Exception as failure:  # noqa: BLE001 - e.g. a row that cannot travel
                    row = _failed(task, f"{type(failure).__name__}: {failure}")
                on_row(row)
        except BaseException:
            _stop(pool)
            raise
    return broken


def _init_worker() -> None:
    # SIGTERM from the planner (a stopped sweep) ends the run like Ctrl-C: its log gets the
    # end record "interrupted", and the next start of the sweep runs it again.
    signal.signal(signal.SIGTERM, signal.default_int_handler)


def _stop(pool: ProcessPoolExecutor) -> None:
    """End a pool now: cancel what has not started, stop the workers (they close their logs)."""
    processes = list(getattr(pool, "_processes", {}).values())  # no public handle on them
    pool.shutdown(wait=False, cancel_futures=True)
    for process in processes:
        if process.is_alive():
            process.terminate()
    for process in processes:
        process.join(timeout=10)


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


def run_dask(tasks: list[RunTask], token: str, client, on_row: OnRow) -> None:
    """Run `tasks` as tasks of the Dask cluster behind `client`; on_row(row) as each ends."""
    from distributed import as_completed as dask_completed

    futures = {client.submit(_execute_alone, task, token, key=f"excosim-{token}-{task.run}",
                             pure=False): task for task in tasks}
    try:
        for future in dask_completed(list(futures), loop=client.loop):
            task = futures[future]
            try:
                row = future.result()
            except Exception as failure:  # noqa: BLE001 - a lost worker, a task error
                row = _failed(task, f"{type(failure).__name__}: {failure}")
            on_row(row)
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


def _died(task: RunTask) -> dict[str, Any]:
    row = _failed(task, "the worker process died during the run (a crash inside an FMU or a "
                  "stuck step)")
    if row.get("termination") == "error" and row.get("message"):
        row["error"] = row["message"]  # the step watchdog's line names the FMU
    return row
