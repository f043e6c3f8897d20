"""What MCAP run logging costs a campaign: seconds per paper-sized period and messages/s.

    python bench/run_log.py

A paper-sized period: about 13 s of digging sampled at 200 Hz (2,600 samples) with the joints,
three cylinders (x, v, p_A, p_B, F) and the pile/bucket outputs, a 221-cell pile profile and the
3D channels (/tf at 25 Hz). A campaign is 20 periods; the campaign benchmark aims at a real-time
factor >= 100 (about 2.6 s for 260 s simulated), of which logging should take at most 10 %.

Also printed: the same number of messages through the foxglove SDK's `Channel.log`, one call per
pre-encoded message (what `orchestrator.runlog.mcap_records` avoids), and reading the file back.
"""

from __future__ import annotations

import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from orchestrator.runlog import RunDescription, RunLog, read_run
from plant_models import presets
from plant_models.plant import JOINTS, PeriodMeasurement

SAMPLES = 2600  # 13 s at 200 Hz
STEP_S = 0.005
PERIODS = 20
CAMPAIGN_WALL_S = 2.6  # 260 s simulated at a real-time factor of 100


def paper_period(seed: int) -> PeriodMeasurement:
    """Smooth synthetic signals of paper-sized magnitude (joint swings of ~0.5 rad, pressures of
    ~10 MPa) with a little noise, so compression sees realistic, not random, doubles."""
    rng = np.random.default_rng(seed)
    t = np.arange(SAMPLES) * STEP_S
    geometry = presets.get("paper")
    middle = np.array(geometry.joint_limits_rad).mean(axis=1)
    joints = middle + 0.5 * np.sin(2 * np.pi * t[:, None] / 13.0 + rng.uniform(0, 6, 3))
    signals = {}
    for j, joint in enumerate(JOINTS):
        wave = np.sin(2 * np.pi * t / 13.0 + j)
        signals.update({f"{joint}.x": 0.6 + 0.4 * wave, f"{joint}.v": 0.2 * np.cos(t + j),
                        f"{joint}.p_A": 1e7 * (1 + 0.5 * wave) + rng.normal(0, 1e3, SAMPLES),
                        f"{joint}.p_B": 5e6 * (1 - 0.5 * wave) + rng.normal(0, 1e3, SAMPLES),
                        f"{joint}.F": 1e5 * wave + rng.normal(0, 10.0, SAMPLES)})
    ramp = np.clip((t - 4.0) / 5.0, 0.0, 1.0)
    signals.update({"pile.bucket_mass": 8.5 * ramp, "pile.F_y": -2e4 * ramp * (1 - ramp),
                    "pile.F_z": 1e4 * ramp * (1 - ramp), "pile.surface_z_at_tip": -0.1 * ramp,
                    "tip.y": -9 + np.sin(t), "tip.z": -0.1 * np.cos(t),
                    "tip.bucket_angle": -1.0 + 0.5 * np.sin(t)})
    grid = np.linspace(-13.0, -2.0, 221)
    profile = -0.4 * np.exp(-((grid + 9.0) ** 2)) * (1 + 0.05 * seed)
    return PeriodMeasurement(t, joints, joints + 1e-3, 8.5, signals, profile, grid)


def main() -> None:
    periods = [paper_period(k) for k in range(PERIODS)]
    fmu_dir = Path(tempfile.mkdtemp())
    fmu = fmu_dir / "HydraulicCylinder.fmu"
    fmu.write_bytes(np.random.default_rng(0).bytes(60_000))
    path = fmu_dir / "run.mcap"
    seconds, cpu_seconds = [], []
    with RunLog(path, RunDescription(
            scenario={"name": "bench"}, scenario_text="", scenario_name="bench",
            fmus={"HydraulicCylinder": fmu}, plant_kind="sim", target_mass_kg=8.5,
            geometry=presets.get("paper"))) as log:
        for k, period in enumerate(periods):
            begin, cpu = time.perf_counter(), time.process_time()
            log.log_period({"k": k + 1, "mass_kg": 8.5}, period, k * SAMPLES * STEP_S)
            seconds.append(time.perf_counter() - begin)
            cpu_seconds.append(time.process_time() - cpu)
    begin = time.perf_counter()
    run = read_run(path)
    read_s = time.perf_counter() - begin
    messages = sum(run.message_counts.values())
    total = sum(seconds)
    print(f"{PERIODS} periods x {SAMPLES} samples, {messages} messages, "
          f"{path.stat().st_size / 1e6:.1f} MB")
    print(f"  per period      {statistics.median(seconds) * 1e3:7.2f} ms (median), "
          f"{max(seconds) * 1e3:.2f} ms (max)")
    print(f"  whole campaign  {total:7.3f} s = {100 * total / CAMPAIGN_WALL_S:.1f} % of a "
          f"{CAMPAIGN_WALL_S} s campaign (CPU time of this process: {sum(cpu_seconds):.3f} s)")
    print(f"  messages/s      {messages / total:12,.0f}")
    print(f"  read back       {read_s:7.3f} s (read_run: records, metadata, attachments)")
    print(f"  foxglove SDK    {sdk_seconds(messages):7.3f} s for the same number of messages, "
          "one Channel.log call each (payloads pre-encoded)")


def sdk_seconds(count: int) -> float:
    """Wall time of `count` Channel.log calls of 60-byte payloads into an MCAP file."""
    from foxglove.mcap import MCAPWriteOptions

    import foxglove

    context = foxglove.Context()
    target = Path(tempfile.mkdtemp()) / "sdk.mcap"
    options = MCAPWriteOptions(compression_level=1, compression_threads=0)
    with foxglove.open_mcap(target, context=context, writer_options=options):
        channel = foxglove.Channel("/x", schema=foxglove.Schema(name="x", encoding="protobuf",
                                                                 data=b""),
                                   message_encoding="protobuf", context=context).base
        payload = bytes(60)
        begin = time.perf_counter()
        for i in range(count):
            channel.log(payload, i)
        return time.perf_counter() - begin


if __name__ == "__main__":
    main()
