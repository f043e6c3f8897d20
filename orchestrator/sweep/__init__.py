"""Sweeps: many campaigns over axes of scenario values, plant substitutions and seeds, on a local
process pool or an existing Dask cluster, with a summary table and resume.

    from orchestrator.sweep import run_sweep
    result = run_sweep("sweeps/robustness.toml", "runs/robustness", workers=2)
    result.frame  # one row per run: axis values, compare figures, termination, wall time, log

The sweep file: orchestrator.sweep.spec; the runs: orchestrator.sweep.plan; where they run:
orchestrator.sweep.executors; the summary: orchestrator.sweep.table; study designs over ranges
(Latin hypercube, Sobol, Saltelli): orchestrator.sweep.designs; Sobol indices of the summary's
figures: orchestrator.sweep.sensitivity; an Optuna search over the design axes:
orchestrator.sweep.optimize.
"""

from orchestrator.sweep.executors import SchedulerUnreachable
from orchestrator.sweep.runner import SweepResult, prepare, run_sweep
from orchestrator.sweep.spec import Sweep, SweepError, load_sweep

__all__ = ["SchedulerUnreachable", "Sweep", "SweepError", "SweepResult", "load_sweep", "prepare",
           "run_sweep"]
