"""Wall time of a terrain-strategy campaign with the C slump kernel against the numpy one.

    python bench/terrain_slump.py [--pairs N] [--periods K]

Runs scenarios/paper-2020.toml with adaptation.strategy = "terrain" (told 40.4 deg, no log) K
periods (default 20), once with the strategy's slump kernel in C
(orchestrator.campaign.native_slump) and once with the numpy oracle of the tests
(tests/slump_reference.py, the planner's kernel before the C one), alternately N times
(default 2) so that a shared machine's drift hits both; prints each kernel's median wall time,
the share of it spent slumping, the ratio, and whether both gave the same masses and deepest
points (they must: the same arithmetic in the same order). Pinned to one CPU; BLAS on one
thread.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from slump_reference import relax_steps  # noqa: E402

import orchestrator.campaign.native_slump as native_slump  # noqa: E402
import orchestrator.campaign.strategy as strategy  # noqa: E402
from orchestrator.campaign import run_campaign  # noqa: E402
from orchestrator.scenario import load_scenario  # noqa: E402

PAPER = Path(__file__).resolve().parents[1] / "scenarios" / "paper-2020.toml"


def timed(kernel, clock: list[float]):
    def relax(z, allowed):
        started = time.perf_counter()
        kernel(z, allowed)
        clock[0] += time.perf_counter() - started
    return relax


def campaign(kernel, periods: int) -> tuple[float, float, list]:
    clock = [0.0]
    strategy.native_relax = lambda: timed(kernel, clock)  # the kernel the strategy is handed
    scenario = load_scenario(PAPER, [f"periods={periods}", 'adaptation.strategy="terrain"',
                                     "adaptation.assumed_repose_angle_deg=40.4"])
    started = time.perf_counter()
    result = run_campaign(scenario)
    wall = time.perf_counter() - started
    if result.termination == "error":
        raise SystemExit(f"the campaign failed: {result.message}")
    return wall, clock[0], [(r["deepest_point_m"], r["mass_kg"]) for r in result.records]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pairs", type=int, default=2)
    parser.add_argument("--periods", type=int, default=20)
    args = parser.parse_args()
    c_kernel = native_slump.native_relax()
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
    runs: dict[str, list[tuple[float, float]]] = {"C": [], "numpy": []}
    outcomes = {}
    for _ in range(args.pairs):
        for name, kernel in (("C", c_kernel), ("numpy", relax_steps)):
            wall, slumping, outcome = campaign(kernel, args.periods)
            runs[name].append((wall, slumping))
            outcomes[name] = outcome
    print(f"terrain campaign, paper scenario, {args.periods} periods, median of {args.pairs}:")
    medians = {}
    for name, measured in runs.items():
        wall = statistics.median(w for w, _ in measured)
        slumping = statistics.median(s for _, s in measured)
        medians[name] = wall
        print(f"  {name:6s} kernel: wall {wall:6.2f} s, slumping {slumping:6.2f} s "
              f"({100 * slumping / wall:4.1f} %)")
    print(f"  numpy / C wall time: {medians['numpy'] / medians['C']:.2f}x")
    same = outcomes["C"] == outcomes["numpy"]
    print(f"  same deepest points and masses in every period: {'yes' if same else 'NO'}")
    if not same:
        raise SystemExit(1)


if __name__ == "__main__":
    main()
