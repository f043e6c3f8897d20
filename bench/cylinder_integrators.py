"""The cylinder's integrators on the paper's own inputs: accuracy and cost, side by side.

    python bench/cylinder_integrators.py

Runs period 1 of scenarios/paper-2020.toml (RK4, as before the scenario chose RODAS3) and
records each cylinder's inputs per 10 ms step (u, F_ext, mass_load, the pump's p_pump and p_LS).
The reference: the same inputs through tests/cylinder_ode.py, the cylinder's law written
again in Python, under scipy's Radau at rtol 1e-10 (about 7 s per joint). Then replays them open
loop through each joint's HydraulicCylinder FMU (the scenario's parameters) with: RK4 at 2000
substeps per step (5 us), RK4 at its stable substep (the old default), and RODAS3 at tolerances
1e-5 .. 1e-8 (3e-7: the paper scenario's). Prints per joint: us per step, substeps per step,
rejected substeps, and the largest stroke (m) and chamber-pressure (bar) differences from the
reference. The process is pinned to one CPU.
"""

from __future__ import annotations

import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from fmpy import read_model_description

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))  # the test oracle

from cylinder_ode import reference_run  # noqa: E402

import fmus  # noqa: E402
from fmus.runs import FastSlave  # noqa: E402
from orchestrator.campaign import run_campaign  # noqa: E402
from orchestrator.plants import simulated_excavator  # noqa: E402
from orchestrator.scenario import load_scenario  # noqa: E402
from plant_models.linkage import JOINT_NAMES  # noqa: E402

SCENARIO = Path(__file__).resolve().parents[1] / "scenarios" / "paper-2020.toml"
INPUTS = ("u", "F_ext", "mass_load", "p_pump", "p_LS")
OUTPUTS = ("x", "v", "p_A", "p_B", "substeps", "rejected_substeps")
RK4 = [f"plant.{j}.parameters.integrator=0" for j in JOINT_NAMES]


def recorded_period() -> dict[str, np.ndarray]:
    """The signals of period 1 (RK4) by name."""
    kept = []
    original = simulated_excavator.SimulatedExcavator.run_period

    def keep(self, reference):
        kept.append(original(self, reference))
        return kept[-1]
    simulated_excavator.SimulatedExcavator.run_period = keep
    try:
        with tempfile.TemporaryDirectory() as folder:
            run_campaign(load_scenario(SCENARIO, ["periods=1", *RK4]),
                         log_path=Path(folder) / "period.mcap")
    finally:
        simulated_excavator.SimulatedExcavator.run_period = original
    return kept[0].signals


def replay(fmu, parameters: dict, signals: dict, joint: str, h: float, extra: dict):
    columns = [signals[f"{joint}.{n}"] if f"{joint}.{n}" in signals else signals[f"supply.{n}"]
               for n in INPUTS]
    matrix = np.column_stack(columns)
    start = {**parameters, "x0": float(signals[f"{joint}.x"][0]),
             **dict(zip(INPUTS, matrix[0], strict=True)), **extra}
    with FastSlave(fmu, list(INPUTS), list(OUTPUTS), start) as slave:
        begin = time.perf_counter()
        rows = [slave.step(k * h, h, matrix[k]).copy() for k in range(len(matrix))]
        seconds = time.perf_counter() - begin
    return np.array(rows), seconds / len(matrix)


def main() -> None:
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
    scenario = load_scenario(SCENARIO)
    h = scenario.plant.communication_step_s
    signals = recorded_period()
    fmu = fmus.build("HydraulicCylinder")
    defaults = {v.name: float(v.start) for v in read_model_description(str(fmu)).modelVariables
                if v.causality == "parameter"}
    print(f"period 1 of {SCENARIO.name}: {len(signals['boom.u'])} steps of {h * 1e3:g} ms")
    for joint in JOINT_NAMES:
        parameters = {k: v for k, v in getattr(scenario.plant, joint).parameters.items()
                      if k not in ("integrator", "tolerance")}
        held = {name: signals.get(f"{joint}.{name}", signals.get(f"supply.{name}"))
                for name in INPUTS}
        begin = time.perf_counter()
        reference = reference_run({**defaults, **parameters}, float(signals[f"{joint}.x"][0]),
                                  held, h)
        print(f"{joint} (reference: Radau, rtol 1e-10, {time.perf_counter() - begin:.1f} s):")
        runs = [("RK4, 2000 substeps", {"integrator": 0, "n_substeps": 2000}),
                ("RK4, stable substep", {"integrator": 0})] + [
            (f"RODAS3, tolerance {tol:g}", {"integrator": 1, "tolerance": tol})
            for tol in (1e-5, 1e-6, 3e-7, 1e-7, 1e-8)]
        for label, extra in runs:
            rows, per_step = replay(fmu, parameters, signals, joint, h, extra)
            stroke = np.abs(rows[:, 0] - reference[:, 0]).max()
            pressure = np.abs(rows[:, 2:4] - reference[:, 2:4]).max() / 1e5
            print(f"  {label:26s} {per_step * 1e6:6.1f} us/step  "
                  f"{rows[-1, 4] / len(rows):5.1f} substeps/step  {rows[-1, 5]:5.0f} rejected  "
                  f"stroke {stroke:.1e} m  pressure {pressure:.1e} bar")


if __name__ == "__main__":
    main()
