"""Wall time of the paper campaign with full MCAP logging, where it goes, and the master's cost
per step next to the ecos master stepping the same FMUs.

    python bench/campaign.py

1. Runs scenarios/paper-2020.toml (20 periods, the simulated excavator, MCAP log in a temporary
   folder) with perf_counter accumulators around the planner (PeriodPlanner._plan: via-points,
   spline, range check), the plant (SimulatedExcavator.run_period), the log (RunLog: open,
   log_period, close) and the capture of each period's resume state (the four FMUs' serialized
   states and the master's: orchestrator.campaign.resume_state; its encoding and writing are
   in the log's share). Real-time factor = simulated time / wall time (target >= 100); logging
   share of wall time (target <= 10 %).
2. Splits the plant's time into FMUs and master: the FMUs are stepped again, alone, through the
   same fast path (fmus.runs.FastSlave) with the inputs the run recorded (cylinder u, F_ext,
   mass_load and, on the load-sensing pump, p_pump and p_LS; the Pile's tip inputs); the rest
   of the plant's time is the master (kinematic coupling, servos, the pump's law, bookkeeping).
3. Steps the same FMUs with the same inputs under the ecos master (ecospy: set_real per input,
   step, get_real per output, as fmus.runs.run_ecospy does) for comparison per step.
The process is pinned to one CPU so the figures do not wander between cores.
"""

from __future__ import annotations

import os
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from fmus.runs import FastSlave, run_ecospy  # noqa: E402
from orchestrator.campaign import loop as campaign  # noqa: E402
from orchestrator.plants import simulated_excavator  # noqa: E402
from orchestrator.plants.master import fmu_path  # noqa: E402
from orchestrator.runlog import read_run  # noqa: E402
from orchestrator.runlog import writer as run_log  # noqa: E402
from orchestrator.scenario import load_scenario  # noqa: E402
from planner import period_plan  # noqa: E402
from plant_models.linkage import JOINT_NAMES  # noqa: E402
from plant_models.model_spec import CYLINDER_OUTPUTS, PILE_OUTPUTS  # noqa: E402

SCENARIO = Path(__file__).resolve().parents[1] / "scenarios" / "paper-2020.toml"
RTF_TARGET, LOG_SHARE_TARGET = 100.0, 0.10


def timed(owner, name: str, bucket: str, seconds: dict, keep: list | None = None) -> None:
    """Replace owner.name by a wrapper adding its wall time to seconds[bucket]."""
    original = getattr(owner, name)

    def wrapper(*args, **kwargs):
        begin = time.perf_counter()
        try:
            result = original(*args, **kwargs)
        finally:
            seconds[bucket] += time.perf_counter() - begin
        if keep is not None:
            keep.append(result)
        return result

    setattr(owner, name, wrapper)


def run_instrumented(scenario, folder: Path):
    seconds: dict[str, float] = defaultdict(float)
    measurements: list = []
    timed(period_plan.PeriodPlanner, "_plan", "planner", seconds)
    timed(simulated_excavator.SimulatedExcavator, "run_period", "plant", seconds, measurements)
    for name in ("__init__", "log_period", "close"):
        timed(run_log.RunLog, name, "logging", seconds)
    timed(campaign, "build_plant", "plant setup", seconds)
    timed(campaign, "sample_reference", "sampling", seconds)
    timed(campaign, "resume_record", "resume states", seconds)
    begin = time.perf_counter()
    result = campaign.run_campaign(scenario, log_path=folder / "paper.mcap")
    seconds["total"] = time.perf_counter() - begin
    return result, seconds, measurements


def recorded_inputs(scenario, measurements) -> dict[str, tuple[dict, dict]]:
    """component -> (input series by FMU input name, start values) over the whole run; the
    Pile gets one dump step after every period, as the plant does."""
    series = {}
    for joint in JOINT_NAMES:
        spec = getattr(scenario.plant, joint)
        inputs = {spec.ports.get(role, role): np.concatenate(
            [m.signals[f"{joint}.{role}"] for m in measurements])
            for role in ("u", "F_ext", "mass_load")}
        if "supply.p_pump" in measurements[0].signals:  # the load-sensing pump's, per step
            for role in ("p_pump", "p_LS"):
                inputs[spec.ports.get(role, role)] = np.concatenate(
                    [m.signals[f"supply.{role}"] for m in measurements])
        x0 = float(measurements[0].signals[f"{joint}.x"][0])
        series[joint] = (inputs, {**spec.parameters, spec.ports.get("x0", "x0"): x0})
    pile = scenario.plant.pile
    columns = {"tip_y": [], "tip_z": [], "bucket_angle": [], "dump": []}
    for m in measurements:
        n = len(m.t_s)
        for role, values in (("tip_y", m.signals["tip.y"]), ("tip_z", m.signals["tip.z"]),
                             ("bucket_angle", -m.signals["tip.bucket_angle"]),
                             ("dump", np.zeros(n))):
            columns[role].append(values)
        for role in ("tip_y", "tip_z", "bucket_angle"):
            columns[role].append(columns[role][-1][-1:])
        columns["dump"].append(np.ones(1))
    inputs = {pile.ports.get(role, role): np.concatenate(v) for role, v in columns.items()}
    series["pile"] = (inputs, dict(pile.parameters))
    return series


def replay_fast(scenario, series) -> tuple[float, int]:
    """Seconds to step every FMU through its recorded inputs with FastSlave; steps per FMU."""
    total, steps = 0.0, 0
    h = scenario.plant.communication_step_s
    for component, (inputs, start) in series.items():
        spec = getattr(scenario.plant, component)
        role_outputs = PILE_OUTPUTS if component == "pile" else CYLINDER_OUTPUTS
        outputs = [spec.ports.get(role, role) for role in role_outputs]
        matrix = np.column_stack(list(inputs.values()))
        first = {name: float(column[0]) for name, column in inputs.items()}
        with FastSlave(fmu_path(spec, component), list(inputs), outputs,
                       {**first, **start}) as slave:
            begin = time.perf_counter()
            for k in range(len(matrix)):
                slave.step(k * h, h, matrix[k])
            total += time.perf_counter() - begin
        steps = len(matrix)
    return total, steps


def replay_ecos(scenario, series, limit: int) -> float:
    """Seconds per step for all four FMUs under ecos, from the first `limit` steps."""
    per_step = 0.0
    h = scenario.plant.communication_step_s
    for component, (inputs, start) in series.items():
        spec = getattr(scenario.plant, component)
        role_outputs = PILE_OUTPUTS if component == "pile" else CYLINDER_OUTPUTS
        outputs = [spec.ports.get(role, role) for role in role_outputs]
        cut = {name: column[:limit] for name, column in inputs.items()}
        begin = time.perf_counter()
        run_ecospy(fmu_path(spec, component), cut, outputs, h, start)
        per_step += (time.perf_counter() - begin) / limit
    return per_step


def main() -> None:
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
    scenario = load_scenario(SCENARIO)
    with tempfile.TemporaryDirectory() as folder:
        result, seconds, measurements = run_instrumented(scenario, Path(folder))
        log_bytes = (Path(folder) / "paper.mcap").stat().st_size
        states = read_run(Path(folder) / "paper.mcap").resume_states
    simulated = sum(float(m.t_s[-1]) + scenario.plant.communication_step_s
                    for m in measurements)
    total = seconds["total"]
    series = recorded_inputs(scenario, measurements)
    fmu_seconds, steps = replay_fast(scenario, series)
    master = seconds["plant"] - fmu_seconds
    other = total - sum(seconds[k] for k in ("plant", "planner", "logging", "plant setup",
                                              "sampling", "resume states"))
    print(f"paper-2020: {len(result.records)} periods, termination {result.termination}, "
          f"{simulated:.1f} s simulated in {total:.2f} s wall: real-time factor "
          f"{simulated / total:.1f} (target >= {RTF_TARGET:g})")
    print(f"  {steps} communication steps of {scenario.plant.communication_step_s * 1e3:g} ms, "
          f"MCAP log {log_bytes / 1e6:.1f} MB, resume states "
          f"{np.mean([len(d) for d in states.values()]) / 1e3:.1f} kB of JSON per period")
    print("share of wall time:")
    for label, value in (("FMUs (replayed alone)", fmu_seconds), ("master (plant - FMUs)", master),
                         ("plant setup (servo design, FMU load)", seconds["plant setup"]),
                         ("planner", seconds["planner"]),
                         ("reference sampling", seconds["sampling"]),
                         ("logging", seconds["logging"]),
                         ("resume states (capture)", seconds["resume states"]),
                         ("campaign, adaptation, other", other)):
        print(f"  {label:38s} {value:7.3f} s  {100 * value / total:5.1f} %")
    share = seconds["logging"] / total
    print(f"logging {100 * share:.1f} % of wall time (target <= {100 * LOG_SHARE_TARGET:g} %)")
    ours = seconds["plant"] / steps * 1e6
    fmus_only = fmu_seconds / steps * 1e6
    print("per communication step, all four FMUs (3 cylinders, pile):")
    print(f"  excosim plant (master + FMUs)  {ours:7.1f} us")
    print(f"  FMUs alone via FastSlave       {fmus_only:7.1f} us  -> master overhead "
          f"{ours - fmus_only:.1f} us")
    try:
        ecos = replay_ecos(scenario, series, min(steps, 5000)) * 1e6
    except Exception as error:  # ecospy is a test extra; say why it did not run
        print(f"  ecos master                    not run: {type(error).__name__}: {error}")
    else:
        print(f"  ecos master (set/step/get)     {ecos:7.1f} us  -> overhead "
              f"{ecos - fmus_only:.1f} us (no coupling, no servos)")


if __name__ == "__main__":
    main()
