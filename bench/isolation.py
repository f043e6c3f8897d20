"""What digging in a supervised child costs `excosim run` (orchestrator.campaign.isolation),
side by side in one run: the supervisor's own round trip (fork, hand the outcome back, wait,
remove the folder) with a campaign's modules loaded, and the wall time of the same paper
campaign through the command with and without `--in-process`, interleaved.

    .venv/bin/python bench/isolation.py [--rounds 20] [--runs 3] [--periods 20] [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path[0] = str(ROOT)  # this folder's planner.py would shadow the planner package
PAPER = ROOT / "scenarios" / "paper-2020.toml"
MAIN = "from orchestrator.cli.app import main; main()"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=20)
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--periods", type=int, default=20)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()

    import orchestrator.campaign  # noqa: F401  (what a forked `excosim run` has loaded)
    from orchestrator.campaign.isolation import available, supervised

    if not available():
        sys.exit("supervised runs need Linux")
    with tempfile.TemporaryDirectory() as folder:
        log = Path(folder) / "none.mcap"
        trips = []
        for _ in range(args.rounds):
            start = time.perf_counter()
            assert supervised(lambda: ["ok", 0], log) == ["ok", 0]
            trips.append(time.perf_counter() - start)
        walls: dict[str, list[float]] = {"supervised": [], "--in-process": []}
        for _ in range(args.runs):
            for how, extra in (("supervised", []), ("--in-process", ["--in-process"])):
                start = time.perf_counter()
                subprocess.run([sys.executable, "-c", MAIN, "run", str(PAPER), "--periods",
                                str(args.periods), "-q", "-f", "-o", str(Path(folder) / "r.mcap"),
                                *extra], check=True, cwd=folder,
                               env={**os.environ, "PYTHONPATH": str(ROOT)})
                walls[how].append(time.perf_counter() - start)
    figures = {
        "supervisor_round_trip_ms": 1e3 * statistics.median(trips),
        "campaign_s": {how: statistics.median(times) for how, times in walls.items()},
        "campaign_spread_s": {how: [min(t), max(t)] for how, t in walls.items()},
        "periods": args.periods, "runs": args.runs,
    }
    if args.json:
        print(json.dumps(figures, indent=2))
        return
    print(f"supervisor round trip (fork, outcome, wait), median of {args.rounds}: "
          f"{figures['supervisor_round_trip_ms']:.1f} ms")
    for how, median in figures["campaign_s"].items():
        low, high = figures["campaign_spread_s"][how]
        print(f"excosim run, {args.periods} paper periods, {how}: median {median:.2f} s "
              f"(range {low:.2f}-{high:.2f} s, {args.runs} runs interleaved)")


if __name__ == "__main__":
    main()
