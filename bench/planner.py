"""Time-jerk optimal quintic B-spline planner: solve time, duration against a baseline, trade-off.

    python bench/planner.py

Prints
  - the median solve time of planner.trajectory.plan_trajectory for k_J = 0 and for the paper's
    k_T = 0.1, k_J = 0.9, over seeded plausible digging periods (3 joints x 5 via-points) and the
    paper case (each set solved 5 times, best kept, then the median over sets); targets 2 ms and
    3 ms on one core (the speed issue's; 5 and 10 ms before);
  - the duration (k_J = 0) against a baseline that stops at every via-point with ruckig's
    jerk-limited time-optimal segments, joints synchronised; target at least 25 % shorter;
  - the paper's two cases (Vu & Tran 2020, section 3.1: 16.17 s with the jerk limit reached,
    18.38 s with peak jerk about 40 deg/s^3) next to ours, and the k_J at which our duration
    grows by the paper's 18.38 / 16.17.
Writes bench/out/planner_tradeoff.png: duration versus peak jerk as k_J sweeps 0..0.99
(k_T = 1 - k_J) on the paper case, with the paper's two points.
Limits everywhere: Table 1 of the paper, 100 deg/s, 60 deg/s^2, 60 deg/s^3 for every joint.
The process is pinned to one CPU and BLAS to one thread; solve times are the process's CPU time,
so other work on a shared machine does not inflate them (on an idle machine they equal wall time).
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import matplotlib  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from ruckig import InputParameter, Result, Ruckig, Trajectory  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from planner.digging_path import paper_joint_via_points  # noqa: E402
from planner.trajectory import plan_trajectory  # noqa: E402

DEG = np.pi / 180.0
LIMITS = (100.0 * DEG, 60.0 * DEG, 60.0 * DEG)  # paper Table 1, every joint
# k_T, k_J, duration (s), peak jerk (deg/s^3) of the paper's two cases, section 3.1.
PAPER = {"case 1": (1.0, 0.0, 16.17, 60.0), "case 2": (0.1, 0.9, 18.38, 40.0)}
SWEEP = np.unique(np.round(np.concatenate([np.linspace(0.0, 0.1, 6), np.linspace(0.1, 0.9, 9),
                                           [0.95, 0.99]]), 6))
LABELLED = (0.0, 0.1, 0.3, 0.5, 0.7, 0.9, 0.99)
N_SETS = 24
REPEATS = 5
OUT = Path(__file__).resolve().parent / "out"


def digging_period(rng: np.random.Generator) -> np.ndarray:
    """Five via-points (deg -> rad) with the paper's four stages: open the bucket while reaching
    the surface, push in with the bucket fixed, close the bucket with boom and stick fixed, lift
    out. Joint order boom, stick, bucket; magnitudes like the paper's Fig. 13 and our paper path."""
    start = np.array([rng.uniform(15, 40), rng.uniform(-90, -60), rng.uniform(-130, -100)])
    stages = [
        [rng.uniform(-30, -10), rng.uniform(20, 50), rng.uniform(40, 90)],
        [rng.uniform(-5, 10), rng.uniform(-25, -5), 0.0],
        [0.0, 0.0, rng.uniform(-100, -50)],
        [rng.uniform(5, 30), rng.uniform(-45, -10), rng.uniform(-5, 5)],
    ]
    return np.vstack([start, start + np.cumsum(stages, axis=0)]) * DEG


def stop_at_every_via(q: np.ndarray) -> float:
    """Duration (s) of ruckig's time-optimal jerk-limited rest-to-rest moves between via-points."""
    dofs = q.shape[1]
    otg, inp, trajectory = Ruckig(dofs), InputParameter(dofs), Trajectory(dofs)
    inp.max_velocity, inp.max_acceleration, inp.max_jerk = ([limit] * dofs for limit in LIMITS)
    total = 0.0
    for start, target in zip(q[:-1], q[1:], strict=True):
        inp.current_position, inp.target_position = start.tolist(), target.tolist()
        if otg.calculate(inp, trajectory) not in (Result.Working, Result.Finished):
            raise RuntimeError("ruckig failed on a segment")
        total += trajectory.duration
    return total


def best_time_ms(q: np.ndarray, k_T: float, k_J: float):
    times, result = [], None
    for _ in range(REPEATS):
        started = time.process_time()
        result = plan_trajectory(q, *LIMITS, k_T=k_T, k_J=k_J)
        times.append((time.process_time() - started) * 1e3)
    return min(times), result


def main() -> None:
    os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})
    rng = np.random.default_rng(2020)
    paper_q = paper_joint_via_points()
    sets = [digging_period(rng) for _ in range(N_SETS)] + [paper_q]
    plan_trajectory(paper_q, *LIMITS)  # warm-up: imports, caches

    print(f"solve time (CPU) over {len(sets)} via-point sets (3 joints x 5 via-points; best of "
          f"{REPEATS}, median over sets, one CPU):")
    ratios = []
    for label, k_T, k_J, target in (("k_J = 0", 1.0, 0.0, 2.0), ("k_T = 0.1, k_J = 0.9", 0.1, 0.9,
                                                                   3.0)):
        runs = [best_time_ms(q, k_T, k_J) for q in sets]
        ms = np.array([r[0] for r in runs])
        evaluations = np.array([r[1].function_evaluations for r in runs])
        print(f"  {label:22s} median {np.median(ms):6.2f} ms (min {ms.min():.2f}, max "
              f"{ms.max():.2f}; target <= {target:.0f} ms); function evaluations median "
              f"{np.median(evaluations):.0f}, max {evaluations.max()}")
        if k_J == 0.0:
            ratios = np.array([r[1].duration / stop_at_every_via(q) for r, q in zip(runs, sets,
                                                                                    strict=True)])
    print(f"duration (k_J = 0) / ruckig stop-at-every-via baseline: median "
          f"{np.median(ratios):.3f} (min {ratios.min():.3f}, max {ratios.max():.3f}; paper case "
          f"{ratios[-1]:.3f}) -> {100 * (1 - np.median(ratios)):.1f} % shorter (target >= 25 %)")

    print("paper case (planner.digging_path.paper_joint_via_points), ours vs paper:")
    results = {}
    for name, (k_T, k_J, paper_s, paper_jerk) in PAPER.items():
        r = plan_trajectory(paper_q, *LIMITS, k_T=k_T, k_J=k_J)
        results[name] = r
        print(f"  {name} (k_T={k_T}, k_J={k_J}): duration {r.duration:6.2f} s (paper {paper_s}), "
              f"peak jerk {np.max(r.peak_jerk) / DEG:5.1f} deg/s^3 (paper {paper_jerk:.0f}), "
              f"per joint {np.round(r.peak_jerk / DEG, 1).tolist()}")
    t1 = results["case 1"].duration
    paper_ratio = PAPER["case 2"][2] / PAPER["case 1"][2]
    print(f"  case 2 / case 1 duration: ours {results['case 2'].duration / t1:.3f}, "
          f"paper {paper_ratio:.3f}")

    weights = SWEEP
    sweep = [plan_trajectory(paper_q, *LIMITS, k_T=1.0 - w, k_J=w) for w in weights]
    durations = np.array([r.duration for r in sweep])
    peaks = np.array([np.max(r.peak_jerk) / DEG for r in sweep])
    w_match = np.interp(paper_ratio, durations / t1, weights)
    match = plan_trajectory(paper_q, *LIMITS, k_T=1.0 - w_match, k_J=w_match)
    print(f"  our duration grows by the paper's {paper_ratio:.3f} at k_J = {w_match:.3f} "
          f"(k_T = {1 - w_match:.3f}): {match.duration:.2f} s, peak jerk "
          f"{np.max(match.peak_jerk) / DEG:.1f} deg/s^3")
    write_plot(weights, durations, peaks, results, t1)


def write_plot(weights, durations, peaks, results, t1) -> None:
    OUT.mkdir(parents=True, exist_ok=True)
    fig, (ax_abs, ax_rel) = plt.subplots(1, 2, figsize=(11, 4.5))
    jerk_limit = LIMITS[2] / DEG
    for ax, scale_t, scale_j, unit_t, unit_j in (
            (ax_abs, 1.0, 1.0, "duration (s)", "peak jerk, largest joint (deg/s$^3$)"),
            (ax_rel, t1, jerk_limit, "duration / case-1 duration",
             "peak jerk / jerk limit")):
        ax.plot(peaks / scale_j, durations / scale_t, "-o", ms=3, color="tab:blue",
                label="ours, k_J = 0 ... 0.99 as marked (k_T = 1 - k_J)")
        groups: list[list] = []  # weights whose points coincide share one label
        for w in LABELLED:
            i = int(np.argmin(np.abs(weights - w)))
            x, y = peaks[i] / scale_j, durations[i] / scale_t
            near = [g for g in groups if abs(g[1] - x) < 0.02 * np.ptp(peaks / scale_j)
                    and abs(g[2] - y) < 0.02 * np.ptp(durations / scale_t)]
            if near:
                near[0][0].append(weights[i])
            else:
                groups.append([[weights[i]], x, y])
        for labels, x, y in groups:
            text = ", ".join(f"{w:g}" for w in labels)
            first = 0.0 in labels  # the bottom-right corner: label below the curve
            ax.annotate(f"k_J = {text}" if first else text, (x, y), textcoords="offset points",
                        xytext=(-10, -2) if first else (5, 3), fontsize=8, color="tab:blue",
                        ha="right" if first else "left", va="top" if first else "bottom")
        for name, marker in (("case 1", "s"), ("case 2", "D")):
            r = results[name]
            ax.plot(np.max(r.peak_jerk) / DEG / scale_j, r.duration / scale_t, marker, ms=9,
                    mfc="none", mec="tab:blue", mew=2, label=f"ours, {name}")
            k_T, k_J, paper_s, paper_jerk = PAPER[name]
            paper_scale_t = PAPER["case 1"][2] if ax is ax_rel else 1.0
            ax.plot(paper_jerk / scale_j, paper_s / paper_scale_t, marker, ms=9, color="tab:red",
                    label=f"paper, {name} (k_T={k_T}, k_J={k_J})")
        ax.set_xlabel(unit_j)
        ax.set_ylabel(unit_t)
        ax.grid(alpha=0.3)
    ax_abs.set_title("paper case: duration vs peak jerk")
    ax_rel.set_title("the same, relative to case 1 and the limit")
    ax_rel.legend(fontsize=8, loc="upper right")
    fig.tight_layout()
    path = OUT / "planner_tradeoff.png"
    fig.savefig(path, dpi=120)
    print(f"wrote {path.relative_to(Path.cwd()) if path.is_relative_to(Path.cwd()) else path}")


if __name__ == "__main__":
    main()
