"""The lab link in real time: achieved stream rate and send jitter of the master.

    python bench/lab_bus.py [--seconds 10] [--rate 100] [--time-scale 1] [--json]

Streams one period of `--seconds` machine seconds (default 10 s: a slow bucket swing at the
emulated device's start pose) from the LabExcavator to the emulated device (the lab machine's
FMUs) over python-can's virtual bus in this process, at the lab scenario's link settings, and
prints the achieved rate (cycles per machine second and per wall second), the send jitter (how
late each cycle's frames left after their deadline: median, p99, max, in wall ms), the schedule
slips (a cycle a whole period late), frames sent and received, and how late feedback came back.

This is where the real-time claims are checked: the tests run at a time scale above 1 on a
loaded machine and assert only what holds there (no burst, no loss, the safety reactions).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

# The repository first: bench/planner.py would shadow the planner package.
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from orchestrator.plants.lab.factory import first_pose_rad, open_lab_plant  # noqa: E402
from orchestrator.scenario import load_scenario  # noqa: E402
from plant_models.plant import JointReference  # noqa: E402

LAB = Path(__file__).resolve().parent.parent / "scenarios" / "lab.toml"


def swing(pose_rad: np.ndarray, seconds: float, step_s: float, degrees: float = 20.0
          ) -> JointReference:
    """The bucket turns by `degrees` (1 - cos) and back over `seconds`, from `pose_rad`."""
    t = np.arange(int(round(seconds / step_s)) + 1) * step_s
    w, amplitude = 2 * math.pi / seconds, math.radians(degrees) / 2
    position = np.tile(pose_rad, (len(t), 1))
    velocity, acceleration = np.zeros_like(position), np.zeros_like(position)
    position[:, 2] += amplitude * (1 - np.cos(w * t))
    velocity[:, 2] = amplitude * w * np.sin(w * t)
    acceleration[:, 2] = amplitude * w * w * np.cos(w * t)
    return JointReference(t, position, velocity, acceleration)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=10.0, help="stream length (machine s)")
    parser.add_argument("--rate", type=float, default=100.0, help="stream rate (Hz)")
    parser.add_argument("--time-scale", type=float, default=1.0, help="1: real time")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    args = parser.parse_args()
    scenario = load_scenario(LAB, ["plant.kind=lab", "plant.lab.emulate=true",
                                   "plant.lab.interface=virtual",
                                   f"plant.lab.stream_rate_hz={args.rate}",
                                   f"plant.lab.time_scale={args.time_scale}"])
    plant = open_lab_plant(scenario)
    try:
        reference = swing(first_pose_rad(scenario), args.seconds, plant.communication_step_s)
        started = time.perf_counter()
        measurement = plant.run_period(reference)
        wall = time.perf_counter() - started
        summary = plant.bus_summary()
    finally:
        plant.close()
    latency = measurement.signals["bus.feedback_latency_s"]
    result = {
        "stream_s": args.seconds, "time_scale": args.time_scale, "rate_hz": args.rate,
        "achieved_rate_hz_machine": summary["rate_hz_machine"],
        "achieved_rate_hz_wall": summary["rate_hz_wall"],
        "jitter_ms": {k: 1e3 * summary[f"jitter_{k}_s"] for k in ("median", "p99", "max")},
        "slips": summary["slips"], "cycles": summary["cycles"],
        "frames_sent": summary["frames_sent"], "frames_received": summary["frames_received"],
        "feedback_lost": int(measurement.signals["bus.feedback_lost"][-1]),
        "feedback_latency_ms_median": 1e3 * float(np.median(latency)) / args.time_scale,
        "period_wall_s": wall,
    }
    if args.json:
        print(json.dumps(result))
        return
    jitter = result["jitter_ms"]
    print(f"stream {args.seconds:g} s at {args.rate:g} Hz, time scale {args.time_scale:g}: "
          f"{result['cycles']} cycles in {wall:.2f} s wall (period incl. weighing and dump)")
    print(f"achieved rate   {result['achieved_rate_hz_machine']:.2f} Hz (machine), "
          f"{result['achieved_rate_hz_wall']:.2f} Hz (wall)")
    print(f"send jitter     median {jitter['median']:.3f} ms, p99 {jitter['p99']:.3f} ms, "
          f"max {jitter['max']:.3f} ms; schedule slips {result['slips']}")
    print(f"frames          sent {result['frames_sent']}, received {result['frames_received']}, "
          f"feedback lost {result['feedback_lost']}; feedback latency median "
          f"{result['feedback_latency_ms_median']:.3f} ms (wall)")


if __name__ == "__main__":
    main()
