"""Real-time factor and per-step cost of the simulated excavator, and the master's overhead
next to the ecos master stepping the same four FMUs.

    python bench/simulated_excavator.py [periods]

Runs the paper preset on the paper's first-period path (case 2, Table 1 limits) for `periods`
periods (default 5), then replays the last period's recorded FMU inputs through
  ours          fmus.runs.FastSlave per FMU: fmi2SetReal + fmi2DoStep + fmi2GetReal, raw ctypes
  doStep only   the fmi2DoStep calls of that replay alone (the FMUs' own compute)
  ecos          the ecos master (ecospy): set_real per input, step(), get_real per output
and prints microseconds per communication step. Master overhead = replay - doStep only.
The process is pinned to one CPU so the figures do not wander between cores.
"""

from __future__ import annotations

import math
import os
import sys
import time
from pathlib import Path

import numpy as np

# The repository instead of bench/ on the path: a bench script must not shadow a module.
sys.path[0] = str(Path(__file__).resolve().parents[1])

from fmus.ecos_runs import load_ecospy  # noqa: E402
from fmus.runs import FastSlave  # noqa: E402
from orchestrator.plants.master import fmu_path  # noqa: E402
from orchestrator.plants.simulated_excavator import SimulatedExcavator  # noqa: E402
from planner.digging_path import paper_joint_via_points  # noqa: E402
from planner.trajectory import plan_trajectory  # noqa: E402
from plant_models.hydraulics import default_config  # noqa: E402
from plant_models.model_spec import CYLINDER_OUTPUTS, PILE_OUTPUTS  # noqa: E402
from plant_models.plant import JointReference  # noqa: E402

JOINTS = ("boom", "stick", "bucket")
PILE_INPUTS = ("tip_y", "tip_z", "bucket_angle", "dump")


def paper_reference(step: float) -> JointReference:
    limit = math.radians
    trajectory = plan_trajectory(paper_joint_via_points(), v_max=limit(100), a_max=limit(60),
                                 j_max=limit(60), k_T=0.1, k_J=0.9)
    t = np.arange(int(math.ceil(trajectory.duration / step)) + 1) * step
    return JointReference(t, trajectory(t, 0), trajectory(t, 1), trajectory(t, 2))


def replay_inputs(signals: dict) -> dict[str, np.ndarray]:
    """(n, n_inputs) per FMU, the inputs each one got in the recorded period."""
    inputs = {j: np.column_stack([signals[f"{j}.u"], signals[f"{j}.F_ext"]]) for j in JOINTS}
    inputs["pile"] = np.column_stack([signals["tip.y"], signals["tip.z"],
                                      -signals["tip.bucket_angle"],
                                      np.zeros_like(signals["tip.y"])])
    return inputs


def start_values(config, signals) -> dict[str, dict[str, float]]:
    values = {}
    for joint, spec in zip(JOINTS, config.cylinders, strict=True):
        values[joint] = {**spec.parameters, "x0": float(signals[f"{joint}.x"][0]),
                         "F_ext": float(signals[f"{joint}.F_ext"][0])}
    values["pile"] = {**config.pile.parameters, "tip_y": float(signals["tip.y"][0]),
                      "tip_z": float(signals["tip.z"][0]),
                      "bucket_angle": -float(signals["tip.bucket_angle"][0])}
    return values


def bench_ours(config, inputs, starts, step: float) -> tuple[float, float]:
    names = {**{j: (["u", "F_ext"], list(CYLINDER_OUTPUTS)) for j in JOINTS},
             "pile": (list(PILE_INPUTS), list(PILE_OUTPUTS))}
    specs = {**dict(zip(JOINTS, config.cylinders, strict=True)), "pile": config.pile}
    slaves = {n: FastSlave(fmu_path(specs[n], n), *names[n], starts[n], instance_name=n)
              for n in names}
    n = len(inputs["pile"])
    do_step_ns = 0
    try:
        rows = {name: inputs[name].tolist() for name in slaves}
        begin = time.perf_counter()
        for k in range(n):
            t = k * step
            for name, slave in slaves.items():
                slave.inputs[:] = rows[name][k]
                if slave._set() > 1:
                    raise RuntimeError("fmi2SetReal failed")
                started = time.perf_counter_ns()
                status = slave._do_step(t, step, 1)
                do_step_ns += time.perf_counter_ns() - started
                if status > 1:
                    raise RuntimeError("fmi2DoStep failed")
                slave.outputs()
        total = time.perf_counter() - begin
    finally:
        for slave in slaves.values():
            slave.close()
    return total / n * 1e6, do_step_ns / n / 1e3


def bench_ecos(config, inputs, starts, step: float) -> float:
    ecospy = load_ecospy()
    ecospy.EcosLib.set_log_level("warn")
    specs = {**dict(zip(JOINTS, config.cylinders, strict=True)), "pile": config.pile}
    in_names = {**{j: ("u", "F_ext") for j in JOINTS}, "pile": PILE_INPUTS}
    out_names = {**{j: CYLINDER_OUTPUTS for j in JOINTS}, "pile": PILE_OUTPUTS}
    structure = ecospy.EcosSimulationStructure()
    parameters = {}
    for name, spec in specs.items():
        structure.add_model(name, str(fmu_path(spec, name)))
        parameters.update({f"{name}::{key}": float(value) for key, value in starts[name].items()})
    structure.add_parameter_set("start", parameters)
    sim = ecospy.EcosSimulation(structure=structure, step_size=step)
    n = len(inputs["pile"])
    try:
        if not sim.init(parameter_set="start"):
            raise RuntimeError(f"ecos failed to initialise: {ecospy.EcosLib.get_last_error()}")
        in_ids = [(f"{m}::{v}", m, i) for m in specs for i, v in enumerate(in_names[m])]
        out_ids = [f"{m}::{v}" for m in specs for v in out_names[m]]
        rows = {name: inputs[name].tolist() for name in specs}
        begin = time.perf_counter()
        for k in range(n):
            for identifier, model, index in in_ids:
                sim.set_real(identifier, rows[model][k][index])
            sim.step()
            for identifier in out_ids:
                sim.get_real(identifier)
        total = time.perf_counter() - begin
        sim.terminate()
    finally:
        sim.free()
        structure.free()
    return total / n * 1e6


def print_servo_designs() -> None:
    print("servo designs (python-control, discrete loops at the communication step):")
    print(f"{'preset':<7}{'joint':<8}{'T ms':>6}{'w_h':>8}{'zeta':>6}{'K_p 1/s':>9}"
          f"{'GM dB':>7}{'PM deg':>8}{'w_c':>7}{'BW':>7}{'DPF sm':>8}")
    for preset in ("paper", "lab"):
        config = default_config(preset)
        for joint, design in zip(JOINTS, SimulatedExcavator(config).servo_designs,
                                 strict=True):
            print(f"{preset:<7}{joint:<8}{design.step_s * 1e3:>6g}"
                  f"{design.natural_frequency_rad_s:>8.1f}{design.damping:>6.2f}"
                  f"{design.position_gain_1_s:>9.2f}{design.gain_margin_db:>7.1f}"
                  f"{design.phase_margin_deg:>8.1f}{design.crossover_rad_s:>7.1f}"
                  f"{design.bandwidth_rad_s:>7.1f}{design.pressure_stability_margin:>8.2f}")
    print("(w_h, w_c = position-loop crossover, BW = -3 dB of x/x_ref: rad/s; zeta: DPF "
          "damping target; DPF sm: stability margin of the pressure loop)")


def main() -> None:
    periods = int(sys.argv[1]) if len(sys.argv) > 1 else 5
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})
    config = default_config("paper")
    step = config.communication_step_s
    reference = paper_reference(step)
    begin = time.perf_counter()
    plant = SimulatedExcavator(config)
    setup = time.perf_counter() - begin
    walls, measurement = [], None
    with plant:
        for _ in range(periods):
            begin = time.perf_counter()
            measurement = plant.run_period(reference)
            walls.append(time.perf_counter() - begin)
    simulated = reference.t_s[-1]
    steps = len(measurement.t_s)
    later = walls[1:] if len(walls) > 1 else walls
    print(f"paper preset, step {step * 1e3:g} ms, period {simulated:.2f} s = {steps} steps; "
          f"plant set-up {setup:.2f} s (servo design, tables)")
    print(f"first period (instantiates the FMUs): {walls[0]:.3f} s wall, "
          f"real-time factor {simulated / walls[0]:.0f}")
    print(f"later periods: {np.mean(later):.3f} s wall, real-time factor "
          f"{simulated / np.mean(later):.0f}, {np.mean(later) / steps * 1e6:.1f} us per step")
    print("tracking RMS (deg): " + ", ".join(
        f"{j} {np.degrees(r):.3f}" for j, r in zip(JOINTS, measurement.tracking_rms_rad,
                                                   strict=True)))
    inputs = replay_inputs(measurement.signals)
    starts = start_values(config, measurement.signals)
    ours, do_step = bench_ours(config, inputs, starts, step)
    ecos = bench_ecos(config, inputs, starts, step)
    plant_step = np.mean(later) / steps * 1e6
    print(f"us per step, 4 FMUs: doStep only {do_step:.1f}; ours (set+doStep+get) {ours:.1f} "
          f"-> master overhead {ours - do_step:.1f}; ecos {ecos:.1f} -> overhead "
          f"{ecos - do_step:.1f}")
    print(f"plant step {plant_step:.1f} us = FMU exchange {ours:.1f} + coupling, servo and "
          f"recording {plant_step - ours:.1f}")
    print_servo_designs()


if __name__ == "__main__":
    main()
