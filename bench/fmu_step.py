"""Microseconds per communication step of every FMU, through several masters, side by side.

    python bench/fmu_step.py

Paths (each sets the inputs, steps once, reads every Real output, per step):
  fmpy fast      the FMU's fmi2SetReal/fmi2DoStep/fmi2GetReal with pre-allocated arrays in
                 one foreign call (fmus.runs.FastSlave through fmus/fast_step/fmi2_step.c,
                 what a Python master should use)
  3 calls        the same three entry points as three ctypes calls (FastSlave.one_call off)
  fmi3 fast      the same for the model's FMI 3.0 build: fmi3SetFloat64/fmi3DoStep/
                 fmi3GetFloat64 (FastSlave on fmus.build(name, fmi_version=3))
  fmpy doStep    the raw fmi2DoStep alone: model compute plus one ctypes call
  fmpy high      fmpy's FMU2Slave.setReal/doStep/getReal (Python lists each call)
  ecos           the ecos master (ecospy), set_real/step/get_real per variable and step
  ecos step(n)   ecos stepping n steps in one call, no Python in the loop
The process is pinned to one CPU so the figures do not wander between cores.
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import fmus  # noqa: E402
from fmus.ecos_runs import load_ecospy  # noqa: E402
from fmus.runs import FastSlave  # noqa: E402

STEP = 1e-3  # communication step, s
N_STEPS = {"HydraulicCylinder": 20000}
DEFAULT_STEPS = 2000


def input_series(name: str, description, n: int) -> dict[str, np.ndarray]:
    """A series that keeps the model busy: spool and load swings; a bucket pass through the pile."""
    t = np.arange(n) * STEP
    s = t / t[-1]
    if name in ("HydraulicCylinder", "IdealActuator"):
        return {"u": np.clip(1.5 * np.sin(2 * np.pi * 1.1 * t), -1, 1),
                "F_ext": 1.2e5 * np.sin(2 * np.pi * 0.6 * t)}
    if name in ("Pile", "PileZelenin"):  # a pile's inputs: dump must stay within [0, 1]
        return {"tip_y": -10.0 + 2.5 * s, "tip_z": 0.5 - 1.3 * np.sin(np.pi * s),
                "bucket_angle": 2.3 - 1.2 * s, "dump": (s > 0.9).astype(float)}
    return {v.name: float(v.start) + 0.1 * (1 + abs(float(v.start))) * np.sin(np.pi * t)
            for v in description.modelVariables if v.causality == "input" and v.type == "Real"}


def per_step_us(seconds: float, n: int) -> float:
    return seconds / n * 1e6


def bench_fmi3(fmu: Path, inputs: dict, outputs: list[str], n: int) -> dict[str, float]:
    matrix = np.column_stack(list(inputs.values()))
    with FastSlave(fmu, list(inputs), outputs, {k: s[0] for k, s in inputs.items()}) as slave:
        begin = time.perf_counter()
        for k in range(n):
            slave.step(k * STEP, STEP, matrix[k])
        return {"fmi3 fast": per_step_us(time.perf_counter() - begin, n)}


def bench_fmpy(fmu: Path, inputs: dict, outputs: list[str], n: int) -> dict[str, float]:
    matrix = np.column_stack(list(inputs.values()))
    start = {k: s[0] for k, s in inputs.items()}
    figures = {}
    with FastSlave(fmu, list(inputs), outputs, start) as slave:
        begin = time.perf_counter()
        for k in range(n):
            slave.step(k * STEP, STEP, matrix[k])
        figures["fmpy fast"] = per_step_us(time.perf_counter() - begin, n)
        do_step, component = slave.slave._functions["fmi2DoStep"], slave.slave.component
        begin = time.perf_counter()
        for k in range(n, 2 * n):
            do_step(component, k * STEP, STEP, 1)
        figures["fmpy doStep"] = per_step_us(time.perf_counter() - begin, n)
    FastSlave.one_call = False
    try:
        with FastSlave(fmu, list(inputs), outputs, start) as slave:
            begin = time.perf_counter()
            for k in range(n):
                slave.step(k * STEP, STEP, matrix[k])
            figures["3 calls"] = per_step_us(time.perf_counter() - begin, n)
    finally:
        FastSlave.one_call = True
    variables = {v.name: v.valueReference for v in read_description(fmu).modelVariables}
    vr_in = [variables[name] for name in inputs]
    vr_out = [variables[name] for name in outputs]
    with FastSlave(fmu, list(inputs), outputs, start) as slave:
        high = slave.slave
        begin = time.perf_counter()
        for k in range(n):
            high.setReal(vr_in, list(matrix[k]))
            high.doStep(k * STEP, STEP)
            high.getReal(vr_out)
        figures["fmpy high"] = per_step_us(time.perf_counter() - begin, n)
    return figures


def read_description(fmu: Path):
    from fmpy import read_model_description

    return read_model_description(str(fmu))


def bench_ecos(fmu: Path, inputs: dict, outputs: list[str], n: int) -> dict[str, float]:
    ecospy = load_ecospy()
    ecospy.EcosLib.set_log_level("warn")
    figures = {}
    matrix = np.column_stack(list(inputs.values()))
    in_ids = [f"fmu::{name}" for name in inputs]
    out_ids = [f"fmu::{name}" for name in outputs]
    structure = ecospy.EcosSimulationStructure()
    structure.add_model("fmu", str(fmu))
    structure.add_parameter_set("start", {i: float(s[0]) for i, s in zip(in_ids, matrix.T,
                                                                          strict=True)})
    sim = ecospy.EcosSimulation(structure=structure, step_size=STEP)
    try:
        sim.init(parameter_set="start")
        begin = time.perf_counter()
        for k in range(n):
            for identifier, value in zip(in_ids, matrix[k], strict=True):
                sim.set_real(identifier, float(value))
            sim.step()
            for identifier in out_ids:
                sim.get_real(identifier)
        figures["ecos"] = per_step_us(time.perf_counter() - begin, n)
        begin = time.perf_counter()
        sim.step(n)
        figures["ecos step(n)"] = per_step_us(time.perf_counter() - begin, n)
        sim.terminate()
    finally:
        sim.free()
        structure.free()
    return figures


def main() -> None:
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})
    columns = ["fmpy fast", "3 calls", "fmi3 fast", "fmpy doStep", "fmpy high", "ecos",
               "ecos step(n)"]
    print(f"us per step (communication step {STEP * 1e3:g} ms; set inputs, step, get outputs)")
    print(f"{'model':<20}{'in/out':>8}" + "".join(f"{c:>14}" for c in columns))
    for name, fmu in fmus.build_all().items():
        description = read_description(fmu)
        n = N_STEPS.get(name, DEFAULT_STEPS)
        inputs = input_series(name, description, n)
        outputs = [v.name for v in description.modelVariables
                   if v.causality == "output" and v.type == "Real"]
        figures = {**bench_fmpy(fmu, inputs, outputs, n), **bench_ecos(fmu, inputs, outputs, n),
                   **bench_fmi3(fmus.build(name, fmi_version=3), inputs, outputs, n)}
        print(f"{name:<20}{f'{len(inputs)}/{len(outputs)}':>8}"
              + "".join(f"{figures[c]:>14.2f}" for c in columns))


if __name__ == "__main__":
    main()
