"""Wall time of the paper campaign with full MCAP logging, where it goes, and the master's cost
per step next to the ecos master stepping the same FMUs; the same figures of an earlier commit
side by side.

    python bench/campaign.py [--against REV] [--pairs N]

1. Runs scenarios/paper-2020.toml (20 periods, the simulated excavator, MCAP log in a temporary
   folder) with perf_counter accumulators around the planner (PeriodPlanner._plan: via-points,
   spline, range check), the plant (SimulatedExcavator.run_period), the log (RunLog: open,
   log_period, wait_written, close) and the capture of each period's resume state (the four
   FMUs' serialized states and the master's: orchestrator.campaign.resume_state; its encoding
   and writing are in the log's share). Real-time factor = simulated time / wall time (target
   >= 600); logging share of wall time (target <= 10 %): what the run's thread spends in the
   log. The log's writer thread (orchestrator.runlog.write_behind: compression, CRCs, writes)
   runs on the second CPU; its busy time is printed beside, not in the share.
2. Splits the plant's time into FMUs and master: the FMUs are stepped again, alone, from C
   (fmus.runs.FastSlave.run, as the plant's loop in C steps them) with the inputs the run
   recorded (cylinder u, F_ext, mass_load and, on the load-sensing pump, p_pump and p_LS; the
   Pile's tip inputs); the rest
   of the plant's time is the master (kinematic coupling, servos, the pump's law, bookkeeping;
   target <= 5 us per step). The FMUs' time alone is the floor: the real-time factor a master
   that cost nothing would reach with these FMUs at their substeps.
3. Steps the same FMUs with the same inputs under the ecos master (ecospy: set_real per input,
   step, get_real per output, as fmus.ecos_runs.run_ecospy does) for comparison per step.
4. Side by side: checks REV (default HEAD~1, the previous commit) out into a temporary git
   worktree and measures both trees with this script's own code (steps 1-2), each in a fresh
   process, alternately N times (default 2) so that a shared machine's drift hits both; prints
   each tree's median. --against none skips it.
The run's thread is pinned to one CPU and the log's writer thread to another (the same one
where there is only one), so the figures do not wander between cores.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parents[1]
# --tree PATH (the side-by-side runs): import the package from that checkout instead of this one.
TREE = Path(sys.argv[sys.argv.index("--tree") + 1]) if "--tree" in sys.argv else HERE
sys.path.insert(0, str(TREE))

from fmus.ecos_runs import run_ecospy  # noqa: E402
from fmus.runs import FastSlave  # noqa: E402
from orchestrator.campaign import loop as campaign  # noqa: E402
from orchestrator.plants import simulated_excavator  # noqa: E402
from orchestrator.plants.master import fmu_path  # noqa: E402
from orchestrator.runlog import read_run  # noqa: E402
from orchestrator.runlog import writer as run_log  # noqa: E402
from orchestrator.scenario import load_scenario  # noqa: E402
from planner import period_plan  # noqa: E402
from plant_models.linkage import JOINT_NAMES  # noqa: E402
from plant_models.model_spec import CYLINDER_OUTPUTS, PILE_OUTPUTS  # noqa: E402

try:
    from orchestrator.runlog import write_behind  # noqa: E402
except ImportError:  # a tree from before the log's writer thread
    write_behind = None

SCENARIO = TREE / "scenarios" / "paper-2020.toml"
WRITER_CPU: int | None = None
# The CPUs the first process was allowed, handed to the side-by-side runs (which would
# otherwise inherit its own pinning to one CPU, and run the log's thread on the run's CPU).
CPUS_VARIABLE = "EXCOSIM_BENCH_CPUS"


def pin_threads() -> None:
    """This thread to the first CPU allowed; the log's writer threads, when made, to the
    second (the first where there is one only)."""
    global WRITER_CPU
    if not hasattr(os, "sched_setaffinity"):
        return
    given = os.environ.get(CPUS_VARIABLE)
    cpus = sorted(map(int, given.split(","))) if given else sorted(os.sched_getaffinity(0))
    os.environ[CPUS_VARIABLE] = ",".join(map(str, cpus))
    os.sched_setaffinity(0, {cpus[0]})
    WRITER_CPU = cpus[min(1, len(cpus) - 1)]
    if write_behind is None:
        return
    made = write_behind.WriteBehind.__init__

    def pinned(self, *args, **kwargs):
        made(self, *args, **kwargs)
        os.sched_setaffinity(self.native_id, {WRITER_CPU})

    write_behind.WriteBehind.__init__ = pinned
RTF_TARGET, LOG_SHARE_TARGET, MASTER_TARGET_US = 600.0, 0.10, 5.0


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
    for name in ("__init__", "log_period", "wait_written", "close"):
        if hasattr(run_log.RunLog, name):  # a tree from before the writer thread: no waiting
            timed(run_log.RunLog, name, "logging", seconds)
    if write_behind is not None:
        timed(write_behind.WriteBehind, "_run", "log writer thread", seconds)
        timed(run_log.RunLog, "wait_written", "log wait", seconds)  # also in "logging"
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


def replay_fast(scenario, series) -> tuple[dict[str, float], int]:
    """Seconds per FMU to step it through its recorded inputs with FastSlave.run; steps per
    FMU."""
    seconds, steps = {}, 0
    h = scenario.plant.communication_step_s
    for component, (inputs, start) in series.items():
        spec = getattr(scenario.plant, component)
        role_outputs = PILE_OUTPUTS if component == "pile" else CYLINDER_OUTPUTS
        outputs = [spec.ports.get(role, role) for role in role_outputs]
        matrix = np.column_stack(list(inputs.values()))
        first = {name: float(column[0]) for name, column in inputs.items()}
        with FastSlave(fmu_path(spec, component), list(inputs), outputs,
                       {**first, **start}) as slave:
            # Stepped from C, as the plant's loop in C steps them (orchestrator.plants.native):
            # no Python between the steps. The replay's copies of each row into the input
            # buffer and of the outputs out (the plant writes them in place) are left in:
            # about 0.02 us a step.
            # A tree from before FastSlave.run: step by step from Python, the row copies
            # timed alone and taken off.
            begin = time.perf_counter()
            if hasattr(slave, "run"):
                slave.run(matrix, h)
            else:
                for k in range(len(matrix)):
                    slave.step(k * h, h, matrix[k])
                copied = time.perf_counter()
                for k in range(len(matrix)):
                    slave.inputs[:] = matrix[k]
                begin += time.perf_counter() - copied
            seconds[component] = time.perf_counter() - begin
        steps = len(matrix)
    return seconds, steps


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


SHARES = (("FMUs (replayed alone)", "fmus"), ("master (plant - FMUs)", "master"),
          ("plant setup (servo design, FMU load)", "plant setup"), ("planner", "planner"),
          ("reference sampling", "sampling"), ("logging", "logging"),
          ("resume states (capture)", "resume states"), ("campaign, adaptation, other", "other"))


def measure(ecos: bool) -> dict:
    """One instrumented paper campaign of this process's tree: plain figures (s, us, bytes)."""
    scenario = load_scenario(SCENARIO)
    h = scenario.plant.communication_step_s
    with tempfile.TemporaryDirectory() as folder:
        result, seconds, measurements = run_instrumented(scenario, Path(folder))
        log_bytes = (Path(folder) / "paper.mcap").stat().st_size
        states = read_run(Path(folder) / "paper.mcap").resume_states
    series = recorded_inputs(scenario, measurements)
    per_fmu, steps = replay_fast(scenario, series)
    figures = {key: seconds[key] for key in ("total", "plant", "plant setup", "planner",
                                             "sampling", "logging", "resume states",
                                             "log writer thread", "log wait")}
    figures["fmus"] = sum(per_fmu.values())
    figures["master"] = seconds["plant"] - figures["fmus"]
    figures["other"] = seconds["total"] - sum(seconds[k] for k in (
        "plant", "planner", "logging", "plant setup", "sampling", "resume states"))
    figures.update(
        periods=len(result.records), termination=str(result.termination), steps=steps,
        step_s=h, simulated=sum(float(m.t_s[-1]) + h for m in measurements),
        log_bytes=log_bytes, state_bytes=float(np.mean([len(d) for d in states.values()])),
        fmu_us={name: value / steps * 1e6 for name, value in per_fmu.items()})
    tries = [m.signals["coupling.iterations"] for m in measurements
             if "coupling.iterations" in m.signals]  # absent in a tree before the coupling
    if tries:
        figures["tries"] = float(np.mean(np.concatenate(tries)))
    if ecos:
        try:
            figures["ecos_us"] = replay_ecos(scenario, series, min(steps, 5000)) * 1e6
        except Exception as error:  # ecospy is a test extra; say why it did not run
            figures["ecos_error"] = f"{type(error).__name__}: {error}"
    return figures


def per_step_us(figures: dict) -> tuple[float, float, float]:
    """(plant, FMUs alone, master) in us per communication step."""
    steps = figures["steps"]
    return (figures["plant"] / steps * 1e6, figures["fmus"] / steps * 1e6,
            figures["master"] / steps * 1e6)


def report(figures: dict) -> None:
    total, simulated = figures["total"], figures["simulated"]
    print(f"paper-2020: {figures['periods']} periods, termination {figures['termination']}, "
          f"{simulated:.1f} s simulated in {total:.2f} s wall: real-time factor "
          f"{simulated / total:.1f} (target >= {RTF_TARGET:g})")
    print(f"  {figures['steps']} communication steps of {figures['step_s'] * 1e3:g} ms, "
          f"MCAP log {figures['log_bytes'] / 1e6:.1f} MB, resume states "
          f"{figures['state_bytes'] / 1e3:.1f} kB of JSON per period")
    if "tries" in figures:
        print(f"  arm coupling: {figures['tries']:.2f} tries of the cylinders per step (the FMU "
              "replay below steps them once: the master's share holds the other tries)")
    print("share of wall time:")
    for label, key in SHARES:
        print(f"  {label:38s} {figures[key]:7.3f} s  {100 * figures[key] / total:5.1f} %")
    share = figures["logging"] / total
    print(f"logging {100 * share:.1f} % of wall time (target <= {100 * LOG_SHARE_TARGET:g} %)")
    if figures.get("log writer thread"):
        print(f"  of which waiting for the log's writer thread {figures['log wait']:.3f} s; "
              f"the thread, on CPU {WRITER_CPU} beside the run: "
              f"{figures['log writer thread']:.3f} s busy (rows, compression, CRCs, writes)")
    ours, fmus_only, master = per_step_us(figures)
    print("per communication step, all four FMUs (3 cylinders, pile):")
    print(f"  excosim plant (master + FMUs)  {ours:7.1f} us")
    print(f"  FMUs alone, stepped from C     {fmus_only:7.1f} us  ("
          + ", ".join(f"{name} {us:.1f}" for name, us in figures["fmu_us"].items())
          + f") -> master overhead {master:.1f} us (target <= {MASTER_TARGET_US:g} us)")
    print(f"  floor: the FMUs alone cap the real-time factor at "
          f"{figures['step_s'] * 1e6 / fmus_only:.0f} (a master and log that cost nothing)")
    if "ecos_us" in figures:
        print(f"  ecos master (set/step/get)     {figures['ecos_us']:7.1f} us  -> overhead "
              f"{figures['ecos_us'] - fmus_only:.1f} us (no coupling, no servos)")
    elif "ecos_error" in figures:
        print(f"  ecos master                    not run: {figures['ecos_error']}")


def measured_in(tree: Path) -> dict:
    """measure() of `tree`'s code in a fresh process (this script's code, the tree's package)."""
    done = subprocess.run([sys.executable, str(Path(__file__).resolve()), "--tree", str(tree),
                           "--json"], capture_output=True, text=True, cwd=tree, check=False)
    if done.returncode != 0:
        last = (done.stderr.strip().splitlines() or ["no output"])[-1]
        raise RuntimeError(f"the run in {tree.name} failed: {last}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def side_by_side(revision: str, pairs: int) -> None:
    """Both trees measured alternately `pairs` times; each one's median printed."""
    try:
        commit = subprocess.run(["git", "-C", str(HERE), "rev-parse", "--short", revision],
                                capture_output=True, text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        print(f"side by side: {revision!r} is no commit of this checkout; not run")
        return
    with tempfile.TemporaryDirectory(prefix="excosim-bench-") as folder:
        worktree = Path(folder) / commit
        subprocess.run(["git", "-C", str(HERE), "worktree", "add", "--detach", "--quiet",
                        str(worktree), commit], check=True)
        runs: dict[str, list[dict]] = {"this tree": [], commit: []}
        try:
            for _ in range(pairs):
                runs[commit].append(measured_in(worktree))
                runs["this tree"].append(measured_in(HERE))
        except RuntimeError as error:
            print(f"side by side with {commit}: not comparable ({error})")
            return
        finally:
            subprocess.run(["git", "-C", str(HERE), "worktree", "remove", "--force",
                            str(worktree)], check=False)
    print(f"side by side, median of {pairs} alternate runs each, fresh processes:")
    print(f"  {'':10s} {'RTF':>7s} {'plant us':>9s} {'FMUs us':>8s} {'master us':>10s} "
          f"{'logging':>8s} {'floor RTF':>10s}")
    for name, figures in runs.items():
        rtf = np.median([f["simulated"] / f["total"] for f in figures])
        plant, fmus_only, master = np.median([per_step_us(f) for f in figures], axis=0)
        logging = np.median([f["logging"] / f["total"] for f in figures])
        print(f"  {name:10s} {rtf:7.1f} {plant:9.1f} {fmus_only:8.1f} {master:10.1f} "
              f"{100 * logging:7.1f}% {figures[0]['step_s'] * 1e6 / fmus_only:10.0f}")
    # Runs next to each other share the machine's state of the moment (its speed drifts by
    # 10 % within minutes here): the ratio within each pair is steadier than either median.
    ratios = sorted(new["total"] / old["total"]
                    for new, old in zip(runs["this tree"], runs[commit], strict=True))
    print(f"  wall time of this tree / {commit}'s, pair by pair: median {np.median(ratios):.3f} "
          f"(from {ratios[0]:.3f} to {ratios[-1]:.3f})")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--against", default="HEAD~1",
                        help="the commit measured side by side (none: skip)")
    parser.add_argument("--pairs", type=int, default=2, help="alternate runs of each tree")
    parser.add_argument("--tree", help=argparse.SUPPRESS)
    parser.add_argument("--json", action="store_true", help=argparse.SUPPRESS)
    arguments = parser.parse_args()
    pin_threads()
    if arguments.json:
        print(json.dumps(measure(ecos=False)))
        return
    report(measure(ecos=True))
    if arguments.against != "none" and arguments.pairs > 0:
        side_by_side(arguments.against, arguments.pairs)


if __name__ == "__main__":
    main()
