"""Start-up of the command line: `excosim --help` and a 1-period paper run, wall time of fresh
processes, this tree against another commit side by side (alternating, medians).

    python bench/startup.py [--against REV] [--pairs N]

What a run spends before it digs is imports (scipy, python-control) and the servo designs;
since the designs are remembered on disk (orchestrator.plants.design_cache) a run after the
first imports neither python-control nor redesigns a servo. Each process runs the tree's code
(its folder first on sys.path); both trees share the FMU and design caches, each warmed by one
run before timing. Prints seconds per command and the ratio of this tree to the other, pair by
pair.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parents[1]
PAPER = HERE / "scenarios" / "paper-2020.toml"


def _command(tree: Path, args: list[str]) -> list[str]:
    code = (f"import sys; sys.path.insert(0, {str(tree)!r}); sys.argv = ['excosim', *{args!r}]; "
            "from orchestrator.cli.app import main; main()")
    return [sys.executable, "-c", code]


def timed(tree: Path, args: list[str], folder: Path) -> float:
    """Wall time (s) of `excosim ARGS` run with `tree`'s code in a fresh process."""
    start = time.perf_counter()
    done = subprocess.run(_command(tree, args), cwd=folder, capture_output=True, text=True,
                          check=False)
    elapsed = time.perf_counter() - start
    if done.returncode != 0:
        raise RuntimeError(f"{tree.name}: excosim {' '.join(args)}: "
                           f"{(done.stderr.strip().splitlines() or ['failed'])[-1]}")
    return elapsed


COMMANDS = {
    "--help": ["--help"],
    "run, 1 period": ["run", str(PAPER), "--periods", "1", "-q", "--force", "-o", "s.mcap"],
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--against", default="15048cd", help="commit to compare with "
                        "(default: the last one before the start-up work)")
    parser.add_argument("--pairs", type=int, default=5)
    arguments = parser.parse_args()
    commit = subprocess.run(["git", "-C", str(HERE), "rev-parse", "--short", arguments.against],
                            capture_output=True, text=True, check=False).stdout.strip()
    with tempfile.TemporaryDirectory(prefix="excosim-startup-") as scratch:
        folder = Path(scratch)
        trees = {"this tree": HERE}
        if commit:
            trees[commit] = folder / commit
            subprocess.run(["git", "-C", str(HERE), "worktree", "add", "--detach", "--quiet",
                            str(trees[commit]), commit], check=True)
        try:
            for tree in trees.values():  # warm the FMU and design caches
                timed(tree, COMMANDS["run, 1 period"], folder)
            times = {name: {command: [] for command in COMMANDS} for name in trees}
            for _ in range(arguments.pairs):
                for name, tree in trees.items():
                    for command, args in COMMANDS.items():
                        times[name][command].append(timed(tree, args, folder))
        finally:
            if commit:
                subprocess.run(["git", "-C", str(HERE), "worktree", "remove", "--force",
                                str(trees[commit])], check=False)
    print(f"wall time of fresh processes, median of {arguments.pairs} (s):")
    print(f"  {'':16s}" + "".join(f"{name:>12s}" for name in trees))
    for command in COMMANDS:
        print(f"  {command:16s}" + "".join(f"{statistics.median(times[name][command]):12.3f}"
                                           for name in trees))
    if commit:
        for command in COMMANDS:
            ratios = sorted(a / b for a, b in zip(times["this tree"][command],
                                                    times[commit][command], strict=True))
            print(f"  {command}: this tree / {commit}, pair by pair: median "
                  f"{statistics.median(ratios):.2f} (from {ratios[0]:.2f} to {ratios[-1]:.2f})")


if __name__ == "__main__":
    main()
