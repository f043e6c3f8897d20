"""The paper machine's hydraulics before and after issue 33's circuit (make-up checks sized for
the pump, the stick's regeneration, the pump's power limiter and the CAT 320's pump figures),
side by side from one command:

    python bench/hydraulics.py                  # 20 paper periods, both circuits
    python bench/hydraulics.py --periods 5 --scenario scenarios/excavator-20t.toml

"before" runs the scenario with the old circuit's values as --set overrides (BEFORE), "after"
as it is. Per circuit, from each run's log (every communication step):

- per cylinder, the share of samples with a chamber at 0 Pa (a cavitation void), the number of
  such episodes and the longest (s);
- the supply's power per step, sum over the cylinders of dE_supply / dt (the FMUs' own
  integrals of p_S x Q): its peak and mean (kW) against the power limiter's setting;
- the supply's energy per period (kJ), and its throttled share (E_throttling / E_supply);
- the samples whose joint acceleration (second differences of the measured angles) exceeds
  1.5 times Table 1's 60 deg/s^2, per joint (bench/convergence.py traced most of them to
  cavitation voids before this circuit);
- the tracking RMS per joint (deg, mean over the periods) and the periods whose mass lies
  within 3/30 of the target (the paper's +-3 kg at 30 kg; after period 1, the reset period left
  out).
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from orchestrator.campaign import run_campaign  # noqa: E402
from orchestrator.runlog import read_run  # noqa: E402
from orchestrator.scenario import load_scenario  # noqa: E402

JOINTS = ("boom", "stick", "bucket")
LIMIT_RAD_S2 = np.radians(60.0)  # Table 1's joint acceleration limit
# The circuit before issue 33: the FMU's default make-up (75 L/min at 0 Pa), no regeneration,
# no power limiter, 2 x 220 L/min at 30 MPa with 35 MPa port reliefs.
BEFORE = (*(f"plant.{j}.parameters.{name}={value}" for j in JOINTS for name, value in (
    ("k_makeup", 5e-9), ("regeneration_ratio", 0.0), ("p_supply", 30e6), ("p_relief", 35e6))),
    "plant.supply.engine_power_w=1e12", "plant.supply.cutoff_pa=30e6",
    "plant.supply.max_flow_l_min=440")


def figures(log: Path, target_kg: float) -> dict:
    """The module docstring's figures of one run log."""
    topics = [f"/cylinder/{j}" for j in JOINTS] + [f"/signals/{j}" for j in JOINTS] + ["/joints"]
    run = read_run(log, topics=topics)
    out: dict = {"voids": {}}
    for joint in JOINTS:
        fields = run.channels[f"/cylinder/{joint}"].fields
        t = fields["t_s"]
        void = (fields["p_A_Pa"] <= 0.0) | (fields["p_B_Pa"] <= 0.0)
        edges = np.flatnonzero(np.diff(np.concatenate([[0], void.astype(int), [0]])))
        lengths = [t[min(end, len(t) - 1)] - t[start]
                   for start, end in zip(edges[::2], edges[1::2], strict=True)]
        out["voids"][joint] = (100.0 * float(np.mean(void)), len(lengths),
                               max(lengths, default=0.0))
    supplied = throttled = duration = 0.0
    power = []
    for k in range(1, len(run.periods) + 1):
        per = []
        for joint in JOINTS:
            channel = run.channels[f"/signals/{joint}"]
            names = json.loads(channel.metadata["names"])
            values = channel.of_period(k)["values"]
            per.append((values[:, names.index(f"{joint}.E_supply")],
                        values[:, names.index(f"{joint}.E_throttling")]))
        t = run.channels["/signals/boom"].of_period(k)["t_s"]
        energy = sum(e for e, _ in per)
        power.append(np.diff(energy) / np.diff(t))
        duration += float(t[-1] - t[0])
        supplied += float(energy[-1] - energy[0])
        throttled += float(sum(h[-1] - h[0] for _, h in per))
    power = np.concatenate(power)
    jumps = np.zeros(len(JOINTS), dtype=int)
    for k in range(1, len(run.periods) + 1):
        joints = run.channels["/joints"].of_period(k)
        q = np.column_stack([joints[f"measured_{j}_rad"] for j in JOINTS])
        step = float(np.median(np.diff(joints["t_s"])))
        jumps += np.sum(np.abs(np.diff(q, 2, axis=0)) / step**2 > 1.5 * LIMIT_RAD_S2, axis=0)
    out["jumps"] = jumps.tolist()
    records = run.periods
    counted = [r["mass_kg"] for r in records[1:] if not r["reset"]]
    out.update(peak_kw=float(power.max()) / 1e3,
               mean_kw=supplied / max(duration, 1e-9) / 1e3,
               energy_kj=supplied / len(records) / 1e3,
               throttled=throttled / supplied,
               tracking=[float(np.mean([r["tracking_rms_deg"][i] for r in records]))
                         for i in range(len(JOINTS))],
               within=(sum(abs(m - target_kg) <= 0.1 * target_kg for m in counted),
                       len(counted)),
               periods=len(records))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", type=Path, default=ROOT / "scenarios" / "paper-2020.toml")
    parser.add_argument("--periods", type=int, default=20)
    args = parser.parse_args()
    rows = {}
    with tempfile.TemporaryDirectory() as folder:
        for name, overrides in (("before", BEFORE), ("after", ())):
            scenario = load_scenario(args.scenario, [f"periods={args.periods}", *overrides])
            log = Path(folder) / f"{name}.mcap"
            run_campaign(scenario, log_path=log)
            rows[name] = figures(log, scenario.target_mass_kg)
            supply = scenario.plant.supply
            rows[name]["limit_kw"] = (supply.engine_power_w * supply.pump_efficiency / 1e3
                                      if supply.engine_power_w < 1e11 else None)
    print(f"{args.scenario.name}, {args.periods} periods, every step logged")
    print("| figure | before | after |\n|---|---|---|")
    for joint in JOINTS:
        cells = ["{:.2f} % ({} episodes, longest {:.2f} s)".format(*rows[n]["voids"][joint])
                 for n in rows]
        print(f"| {joint}: samples with a chamber at 0 Pa | " + " | ".join(cells) + " |")
    limit = ["none" if rows[n]["limit_kw"] is None else f"{rows[n]['limit_kw']:.1f} kW"
             for n in rows]
    print("| power limit | " + " | ".join(limit) + " |")
    for key, label, form in (("peak_kw", "peak hydraulic power", "%.1f kW"),
                             ("mean_kw", "mean hydraulic power", "%.1f kW"),
                             ("energy_kj", "supply energy per period", "%.0f kJ"),
                             ("throttled", "throttled share", "%.3f")):
        print(f"| {label} | " + " | ".join(form % rows[n][key] for n in rows) + " |")
    print("| tracking RMS boom / stick / bucket | " + " | ".join(
        " / ".join(f"{v:.3f}" for v in rows[n]["tracking"]) + " deg" for n in rows) + " |")
    print("| samples beyond 1.5 x the acceleration limit, boom / stick / bucket | " + " | ".join(
        " / ".join(str(v) for v in rows[n]["jumps"]) for n in rows) + " |")
    print("| periods within 3/30 of m* (+-3 kg at 30 kg) | " + " | ".join(
        "{} of {}".format(*rows[n]["within"]) for n in rows) + " |")


if __name__ == "__main__":
    main()
