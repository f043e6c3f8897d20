"""Does the paper campaign's answer converge as the communication step shrinks?

    python bench/convergence.py                      # steps 10, 5, 2, 1 ms, 20 periods
    python bench/convergence.py --periods 5 --steps 0.01 0.005 --tolerances 1e-2 1e-3

For each communication step (and, at the first step, each arm-coupling tolerance) it runs the
paper scenario with full logging at every step, then prints:

- per period: the dug mass (kg), the tracking RMS (deg) and the peak chamber pressure (bar)
  per joint; the largest differences between successive steps, and the observed order
  log(d1 / d2) / log(h1 / h2) of the mass differences;
- the residual of the arm's equation of motion evaluated from the logged signals alone
  (orchestrator.review.arm_equation: M(q) qdd + velocity products + gravity - joint torques of
  the cylinder forces and the soil force), RMS and peak relative to the RMS cylinder force, per
  joint, over the periods it is asked for (--residual-periods, default 1 and 5: the residual
  costs a few seconds per period at 1 ms);
- the arm coupling's tries per step (the coupling.iterations signal) and the largest joint
  accelerations measured against the planned limit (second differences of /joints), with the
  samples beyond 1.5 times it sorted by what lies within 0.3 s: a cavitation void in a
  cylinder chamber, else soil contact, else neither.
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from orchestrator.campaign import run_campaign  # noqa: E402
from orchestrator.review.arm_equation import (  # noqa: E402
    LOGGED_TOPICS,
    arm_residual,
    cylinder_parameters,
    logged_periods,
)
from orchestrator.runlog import read_run  # noqa: E402
from orchestrator.scenario import load_scenario  # noqa: E402

SCENARIO = ROOT / "scenarios" / "paper-2020.toml"
JOINTS = ("boom", "stick", "bucket")
LIMIT_RAD_S2 = math.radians(60.0)  # Table 1's joint acceleration limit
VOID_WINDOW_S = 0.3  # s either side of a sample in which a void or soil contact counts


def run(step_s: float, tolerance: float | None, periods: int, folder: Path) -> dict:
    """One campaign: its records, and what its log says (residual read later)."""
    overrides = [f"plant.communication_step_s={step_s}", f"periods={periods}",
                 f"log.sample_rate_hz={1.0 / step_s}"]
    if tolerance is not None:
        overrides.append(f"plant.coupling_tolerance_rad_s2={tolerance}")
    scenario = load_scenario(SCENARIO, overrides)
    log = folder / f"h{step_s}-tol{tolerance}.mcap"
    result = run_campaign(scenario, log_path=log, overwrite=True)
    if result.termination not in ("periods", "workspace"):
        raise SystemExit(f"step {step_s} s: {result.message}")
    topics = (*LOGGED_TOPICS, "/signals/coupling")  # /pile/bucket is among them
    logged = read_run(log, topics=topics)
    pressures = []
    for k in range(1, len(result.records) + 1):
        pressures.append([max(np.max(logged.channels[f"/cylinder/{j}"].of_period(k)[f])
                              for f in ("p_A_Pa", "p_B_Pa")) / 1e5 for j in JOINTS])
    tries = logged.channels["/signals/coupling"].fields["values"].ravel()
    joints = logged.channels["/joints"]
    accelerations, causes = [], np.zeros((3, 3), dtype=int)
    window = int(round(VOID_WINDOW_S / step_s))
    for k in range(1, len(result.records) + 1):
        q = np.column_stack([joints.of_period(k)[f"measured_{j}_rad"] for j in JOINTS])
        qdd = np.abs(np.diff(q, 2, axis=0)) / step_s**2
        accelerations.append(np.max(qdd, axis=0))
        # Where the samples beyond 1.5 x the planned limit lie: near a cavitation void (a
        # chamber at 0 Pa) of any cylinder, else near soil contact, else elsewhere.
        cylinders = [logged.channels[f"/cylinder/{j}"].of_period(k) for j in JOINTS]
        void = np.any([(c["p_A_Pa"] <= 0.0) | (c["p_B_Pa"] <= 0.0) for c in cylinders], axis=0)
        soil = logged.channels["/pile/bucket"].of_period(k)
        contact = np.hypot(soil["F_y_N"], soil["F_z_N"]) > 0.0
        near_void, near_soil = (np.convolve(flag, np.ones(2 * window + 1), "same") > 0
                                for flag in (void, contact))
        for j in range(3):
            high = np.nonzero(qdd[:, j] > 1.5 * LIMIT_RAD_S2)[0] + 1
            causes[j] += (int(near_void[high].sum()), int((near_soil[high] & ~near_void[high])
                                                          .sum()),
                          int((~near_soil[high] & ~near_void[high]).sum()))
    return {"step": step_s, "tolerance": tolerance, "scenario": scenario, "log": log,
            "mass": np.array([r["mass_kg"] for r in result.records]),
            "rms": np.array([r["tracking_rms_deg"] for r in result.records]),
            "pressure": np.array(pressures), "tries": float(np.mean(tries)),
            "acceleration": np.degrees(np.array(accelerations)), "causes": causes}


def residual(entry: dict, periods: list[int]):
    logged = read_run(entry["log"], topics=LOGGED_TOPICS)
    signals = logged_periods(logged)
    chosen = [signals[k - 1] for k in periods if k <= len(signals)]
    return arm_residual(entry["scenario"].geometry(), chosen,
                        cylinder_parameters(entry["scenario"]))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=float, nargs="+", default=[0.01, 0.005, 0.002, 0.001])
    parser.add_argument("--tolerances", type=float, nargs="*", default=[1e-1, 1e-3],
                        help="arm-coupling tolerances (rad/s^2) also run at the first step")
    parser.add_argument("--periods", type=int, default=20)
    parser.add_argument("--residual-periods", type=int, nargs="*", default=[1, 5])
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="excosim-convergence-") as folder:
        runs = [run(h, None, args.periods, Path(folder)) for h in args.steps]
        variants = [run(args.steps[0], tol, args.periods, Path(folder))
                    for tol in args.tolerances]
        n = min(len(r["mass"]) for r in runs)
        print(f"paper campaign, {n} periods: mass (kg) | tracking RMS boom/stick/bucket (deg) | "
              "peak pressure (bar)")
        for k in range(n):
            cells = "  ".join(f"{r['mass'][k]:6.2f} {'/'.join(f'{x:.2f}' for x in r['rms'][k])}"
                              for r in runs)
            print(f"  {k + 1:2d}  {cells}")
        header = "  ".join(f"{1e3 * r['step']:g} ms" for r in runs)
        print(f"  (columns: {header}; peak pressures per step, bar: " + "; ".join(
            "/".join(f"{p:.0f}" for p in r["pressure"].max(axis=0)) for r in runs) + ")")
        print("largest differences between successive steps (all periods):")
        previous = None
        for a, b in zip(runs, runs[1:], strict=False):
            mass = np.max(np.abs(a["mass"][:n] - b["mass"][:n]))
            rms = np.max(np.abs(a["rms"][:n] - b["rms"][:n]))
            pressure = np.max(np.abs(a["pressure"][:n] - b["pressure"][:n]))
            order = ""
            if previous is not None and mass > 0 and previous[0] > 0:
                observed = math.log(previous[0] / mass) / math.log(previous[1])
                order = f", observed order {observed:.2f}"
            print(f"  {1e3 * a['step']:g} -> {1e3 * b['step']:g} ms: mass {mass:.3f} kg, "
                  f"tracking RMS {rms:.3f} deg, peak pressure {pressure:.1f} bar{order}")
            previous = (mass, a["step"] / b["step"])
        finest = runs[-1]
        for r in runs[:-1]:
            print(f"  {1e3 * r['step']:g} vs {1e3 * finest['step']:g} ms: mass "
                  f"{np.max(np.abs(r['mass'][:n] - finest['mass'][:n])):.3f} kg, tracking RMS "
                  f"{np.max(np.abs(r['rms'][:n] - finest['rms'][:n])):.3f} deg")
        print(f"arm coupling at {1e3 * runs[0]['step']:g} ms, tolerance (rad/s^2): tries per "
              "step, largest mass and tracking RMS difference from the default's:")
        for v in variants:
            print(f"  {v['tolerance']:g}: {v['tries']:.2f} tries, mass "
                  f"{np.max(np.abs(v['mass'][:n] - runs[0]['mass'][:n])):.3f} kg, RMS "
                  f"{np.max(np.abs(v['rms'][:n] - runs[0]['rms'][:n])):.4f} deg")
        print(f"  default: {runs[0]['tries']:.2f} tries per step")
        print("largest measured joint acceleration of any period, boom/stick/bucket (deg/s^2; "
              "planned limit 60):")
        for r in runs:
            print(f"  {1e3 * r['step']:g} ms: " + "/".join(
                f"{a:.0f}" for a in r["acceleration"].max(axis=0)) + "; samples beyond 1.5 x "
                "the limit (within 0.3 s of a cavitation void, else of soil contact, else "
                "neither): " + ", ".join(f"{j} {'/'.join(str(n) for n in c)}"
                                         for j, c in zip(JOINTS, r["causes"], strict=True)))
        print(f"equation-of-motion residual over periods {args.residual_periods}, "
              "boom/stick/bucket, of the RMS cylinder force:")
        for r in runs:
            found = residual(r, args.residual_periods)
            print(f"  {1e3 * r['step']:g} ms: RMS " + "/".join(
                f"{100 * x:.2f}" for x in found.rms_ratio) + " %, peak " + "/".join(
                f"{100 * x:.2f}" for x in found.peak_ratio) + " %")
    return 0


if __name__ == "__main__":
    sys.exit(main())
