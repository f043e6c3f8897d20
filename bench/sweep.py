"""Sweep throughput, side by side in one run on the same sweep (orchestrator.sweep): wall time per
campaign on 1 and 2 local workers, the speed-up of 2 over 1, and the overhead per run of a Dask
LocalCluster (2 worker processes, 1 thread each) over the local pool of 2.

    .venv/bin/python bench/sweep.py [--runs 12] [--periods 5] [--json]

Each configuration runs the same planned runs into its own folder; the planning (scenario checks)
is done once and not timed. Times include starting the workers (a spawned local worker imports
numpy, scipy and fmpy: about 2 s; the LocalCluster is started before its clock starts, as an
existing cluster would be). Run on an otherwise idle machine: the speed-up needs two free cores.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
# This folder holds planner.py, which would shadow the planner package (spawned workers inherit
# sys.path): the project's root takes its place.
sys.path[0] = str(ROOT)
PAPER = ROOT / "scenarios" / "paper-2020.toml"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=12)
    parser.add_argument("--periods", type=int, default=5)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()

    from distributed import LocalCluster

    from orchestrator.sweep import prepare, run_sweep

    with tempfile.TemporaryDirectory(prefix="excosim-bench-sweep-") as folder:
        folder = Path(folder)
        sweep = folder / "bench.toml"
        seeds = ", ".join(str(s) for s in range(args.runs))
        sweep.write_text(f'scenario = "{PAPER}"\nset = ["periods={args.periods}", '
                         f'"plant.load_cell_noise_kg=0.5"]\n[[axis]]\nkey = "seed"\n'
                         f"values = [{seeds}]\n")
        figures = {}
        for label, options in (("local, 1 worker", {"workers": 1}),
                               ("local, 2 workers", {"workers": 2})):
            out = folder / label.replace(", ", "-").replace(" ", "")
            spec, tasks = prepare(sweep, out)
            started = time.perf_counter()
            result = run_sweep(spec, out, tasks=tasks, **options)
            figures[label] = _figures(time.perf_counter() - started, result)
        with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                          dashboard_address=None) as cluster:
            out = folder / "dask"
            spec, tasks = prepare(sweep, out)
            started = time.perf_counter()
            result = run_sweep(spec, out, tasks=tasks, scheduler=cluster.scheduler_address)
            figures["Dask LocalCluster, 2 workers"] = _figures(time.perf_counter() - started,
                                                               result)
    one, two = figures["local, 1 worker"], figures["local, 2 workers"]
    dask = figures["Dask LocalCluster, 2 workers"]
    report = {
        "runs": args.runs, "periods": args.periods, "cores": os.cpu_count(),
        "configurations": figures,
        "speed_up_2_over_1": one["wall_s"] / two["wall_s"],
        "dask_overhead_per_run_s": (dask["wall_s"] - two["wall_s"]) / args.runs,
    }
    if args.json:
        print(json.dumps(report, indent=2))
        return
    print(f"sweep: {args.runs} campaigns of {args.periods} periods (paper scenario, seeds), "
          f"{os.cpu_count()} cores")
    print(f"{'':32}{'wall s':>9}{'s/campaign':>12}{'campaign s':>12}{'failed':>8}")
    for label, f in figures.items():
        print(f"{label:32}{f['wall_s']:9.2f}{f['wall_per_campaign_s']:12.3f}"
              f"{f['mean_run_wall_s']:12.3f}{f['failed']:8d}")
    print(f"speed-up of 2 local workers over 1: {report['speed_up_2_over_1']:.2f} "
          "(target >= 1.8)")
    print(f"Dask LocalCluster overhead per run over the local pool of 2: "
          f"{report['dask_overhead_per_run_s'] * 1e3:+.0f} ms")


def _figures(wall_s: float, result) -> dict:
    """wall_s: the whole sweep; wall_per_campaign_s: wall_s / runs; mean_run_wall_s: the mean of
    the runs' own wall times (inside their workers)."""
    runs = len(result.frame)
    return {"wall_s": wall_s, "wall_per_campaign_s": wall_s / runs,
            "mean_run_wall_s": float(result.frame["wall_s"].mean()),
            "failed": len(result.failed)}


if __name__ == "__main__":
    main()
