"""The campaign: digging period after period, adapting the deepest point D to the weighed mass.

For k = 1..periods (paper section 2.3, Fig. 5, Fig. 4's loop):

1. the adaptation strategy (orchestrator.campaign.strategy) decides D: period 1 at D0, later
   ones from the last weighing (the paper's rule, planner.adaptation, from the weighed mass;
   the terrain strategy, planner.terrain, also from the executed joint angles); a terminated
   decision ends the campaign with termination "workspace_limit", a normal outcome;
2. the path's joint via-points around D (planner.digging_path) are timed by the time-jerk
   optimal B-spline (planner.trajectory) under the scenario's limits and weights; a D whose
   via-points or spline leave the arm's joint ranges is out of reach for the adaptation
   (planner.period_plan);
3. the spline, sampled on the plant's communication grid, goes to the plant, which tracks it,
   weighs the bucket and empties it;
4. the period's record goes to the run log (MCAP) before period k+1 starts.

    result = run_campaign("scenarios/paper-2020.toml", log_path="runs/paper.mcap")
    result.termination, result.to_dataframe()[["mass_kg", "error_kg"]]
"""

from __future__ import annotations

import contextlib
import math
import shutil
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from threadpoolctl import threadpool_limits

from orchestrator.campaign.heap import frozen_heap
from orchestrator.campaign.productivity import rated_payload_kg
from orchestrator.campaign.record import period_record, records_dataframe
from orchestrator.campaign.resume_state import resume_record
from orchestrator.campaign.strategy import adaptation_strategy
from orchestrator.campaign.watchdog import StepWatchdog
from orchestrator.scenario.model import Scenario, load_scenario
from planner.adaptation import AdaptationState, Decision
from planner.trajectory import JointTrajectory
from plant_models.geometry import Unreachable
from plant_models.plant import (
    JOINTS,
    JointReference,
    PeriodMeasurement,
    PeriodStopped,
    Plant,
    communication_step_s,
    initial_pile_surface,
    temporary_folders,
)

# End message of a campaign stopped from outside (Ctrl-C, SystemExit): its ending says nothing
# about the campaign (orchestrator.review.replay does not compare it).
INTERRUPTED = "interrupted"


@dataclass
class CampaignResult:
    """What a campaign did.

    records: one plain dict per dug period (keys: orchestrator.campaign.record.period_record).
    termination: "periods" (all periods dug), "workspace_limit" (the adaptation ran out of
        workspace: normal) or "error" (a runtime failure; `message` says what, `error` holds it).
    """

    records: list[dict[str, Any]]
    termination: str
    message: str
    scenario: Scenario
    log_path: Path | None
    error: BaseException | None = field(default=None, repr=False)

    def to_dataframe(self):
        """pandas DataFrame, one row per period (index k); per-joint values as <name>_<joint>."""
        return records_dataframe(self.records)

    def periods_within(self, tolerance_kg: float, first_period: int = 2) -> tuple[int, int]:
        """(periods with |error| <= tolerance_kg, periods counted), from `first_period` on."""
        errors = [r["error_kg"] for r in self.records if r["k"] >= first_period]
        return sum(abs(e) <= tolerance_kg for e in errors), len(errors)


def build_plant(scenario: Scenario) -> Plant:
    """The plant a scenario names: plant.kind "sim", the FMU-based simulated excavator; "lab",
    the lab excavator over CAN (orchestrator.plants.lab; with plant.lab.emulate its emulated
    device runs in this process)."""
    if scenario.plant.kind == "lab":
        from orchestrator.plants.lab.factory import open_lab_plant

        return open_lab_plant(scenario)
    from orchestrator.plants.simulated_excavator import SimulatedExcavator

    return SimulatedExcavator(scenario.sim_config())


def arm_coupling_of(scenario: Scenario) -> dict[str, str]:
    """cylinder role -> how the simulated plant's step loop couples the arm's cross inertia
    into it (orchestrator.plants.native.arm_coupling_notes); {} for another plant kind."""
    if scenario.plant.kind != "sim":
        return {}
    from fmus.descriptions import model_description
    from orchestrator.plants.master import fmu_path
    from orchestrator.plants.native import arm_coupling_notes

    specs = scenario.fmu_specs()
    return arm_coupling_notes({role: model_description(fmu_path(specs[role], role))
                               for role in ("boom", "stick", "bucket")})


def open_run_log(scenario: Scenario, log_path: str | Path, overwrite: bool = False):
    """The MCAP run log of a campaign (orchestrator.runlog.writer.RunLog)."""
    from orchestrator.plants.master import derivation_notes, fmu_path
    from orchestrator.plants.role_notes import cylinder_notes
    from orchestrator.runlog.description import LogSettings, RunDescription
    from orchestrator.runlog.writer import RunLog
    from plant_models.model_spec import ROLE_OF

    specs = scenario.fmu_specs()
    fmus = {role: fmu_path(spec, role) for role, spec in specs.items()}
    derived = {role: derivation_notes(role, ROLE_OF[role], spec) for role, spec in specs.items()}
    run = RunDescription(
        scenario=scenario.to_dict(), scenario_text=scenario_source_text(scenario),
        scenario_name=scenario.name, fmus=fmus, plant_kind=scenario.plant.kind,
        target_mass_kg=scenario.target_mass_kg, geometry=scenario.geometry(),
        overrides=scenario.overrides, derived=derived, arm_coupling=arm_coupling_of(scenario),
        notes=cylinder_notes(scenario))
    settings = LogSettings(sample_rate_hz=scenario.log.sample_rate_hz, background=True)
    return RunLog(Path(log_path), run, settings, overwrite=overwrite)


def scenario_source_text(scenario: Scenario) -> str:
    """The text the scenario was read from (comments included), or its resolved data as JSON."""
    import json

    text = scenario.source_text
    return text if text is not None else json.dumps(scenario.to_dict(), indent=2)


def run_campaign(
    scenario: Scenario | str | Path,
    *,
    log_path: str | Path | None = None,
    progress: Callable[[dict[str, Any]], None] | None = None,
    plant: Plant | None = None,
    overwrite: bool = False,
    step_timeout_s: float | None = None,
    on_step_timeout: Callable[[str], None] | None = None,
    on_log_opened: Callable[[Any], None] | None = None,
) -> CampaignResult:
    """Dig `scenario.periods` periods (fewer if the workspace runs out) and report.

    scenario: a Scenario or the path of a TOML scenario file.
    log_path: where to write the run's MCAP log (None: no log).
    progress: called with each period's record once the period is done.
    plant: the plant to dig with instead of the scenario's own (it is closed at the end too).
    overwrite: replace an existing file at log_path (default: refuse it).
    step_timeout_s, on_step_timeout: when one FMU step does not return within step_timeout_s
        (orchestrator.campaign.watchdog), the log is closed with termination "error" and a
        message naming the FMU, the plant's temporary FMU folders are removed, and
        on_step_timeout(message) is called from the watchdog's thread; it must end the process
        (the stuck call never returns: `excosim run` exits with status 1).
    on_log_opened: called with the RunLog once it is open, before anything is dug (e.g. to
        say where it is, or RunLog.attach_live).
    A log that cannot be opened (FileExistsError for an existing file, OSError) raises before
    anything is dug, and so does a plant the scenario's FMUs cannot make (PlantRefused, a
    ValueError naming the role: a port that does not fit, a load of the wrong sign, a stroke
    short of the linkage's, a servo without its margins); the plant is built before the log is
    opened. After that it never raises for a runtime failure: the result's termination is
    "error" and the log is closed with it. KeyboardInterrupt closes plant and log, then
    propagates.
    """
    if not isinstance(scenario, Scenario):
        scenario = load_scenario(scenario)
    if plant is None:
        plant = _plant_before_log(scenario, step_timeout_s, on_step_timeout)
    try:
        log = open_run_log(scenario, log_path, overwrite) if log_path is not None else None
        if log is not None and on_log_opened is not None:
            on_log_opened(log)
    except BaseException:
        if plant is not None:
            plant.close()
        raise
    return run_opened(scenario, log, plant, Start(), progress, step_timeout_s, on_step_timeout,
                      Path(log_path) if log_path is not None else None)


class PlantRefused(ValueError):
    """The scenario's FMUs cannot make the plant (one line: "plant.<role>: <why>")."""


def _plant_before_log(scenario: Scenario, step_timeout_s: float | None,
                      on_step_timeout: Callable[[str], None] | None) -> Plant | None:
    """The scenario's plant, built under the step watchdog; PlantRefused for a ValueError
    (what the scenario asks of its FMUs); None for any other failure, which the run then meets
    again and logs as before (an FMU that fails to instantiate is a runtime failure)."""
    watchdog = StepWatchdog(step_timeout_s, on_step_timeout) \
        if step_timeout_s and on_step_timeout else contextlib.nullcontext()
    try:
        with watchdog:
            return build_plant(scenario)
    except ValueError as error:
        line = str(error).splitlines()[0]
        role = line.partition(": ")[0]
        raise PlantRefused(f"plant.{line}" if role in scenario.fmu_specs() else line) from None
    except Exception:  # noqa: BLE001 - a runtime failure: the run reports it with its log
        return None


@dataclass(frozen=True)
class Start:
    """Where a campaign starts: at period 1 (the default), or after period k of a logged run
    (orchestrator.campaign.resume) with its records, the next period's start time t0_s (s),
    the adaptation state period k dug with, the mass weighed after it (kg) and what the
    strategy had learnt by then (its `snapshot()`, None for the rule strategies)."""

    k: int = 0
    records: tuple[dict[str, Any], ...] = ()
    t0_s: float = 0.0
    state: AdaptationState | None = None
    weighed_mass_kg: float = math.nan
    strategy: dict[str, Any] | None = None


def run_opened(scenario: Scenario, log, plant: Plant | None, start: Start,
               progress: Callable[[dict[str, Any]], None] | None = None,
               step_timeout_s: float | None = None,
               on_step_timeout: Callable[[str], None] | None = None,
               log_path: Path | None = None) -> CampaignResult:
    """run_campaign on an open log (a RunLog or None; log_path: its path) from `start`; the
    result's records include start.records. The plant (built from the scenario when None) and
    the log are closed at the end."""
    records: list[dict[str, Any]] = list(start.records)
    termination, message, error = "periods", "", None

    def hang(detail: str) -> None:  # the watchdog's thread; the main thread is in a step
        message = f"period {len(records) + 1}: {detail}"
        if log is not None:
            try:
                log.close("error", message)
            except Exception:  # noqa: BLE001 - a full disk must not keep the run hanging
                pass
        for folder in temporary_folders(plant) if plant is not None else ():
            shutil.rmtree(folder, ignore_errors=True)
        on_step_timeout(message)

    watchdog = StepWatchdog(step_timeout_s, hang) if step_timeout_s and on_step_timeout \
        else contextlib.nullcontext()
    try:
        with watchdog:
            if plant is None:
                plant = build_plant(scenario)
            # One BLAS thread while digging: the small dense algebra of the loop gains nothing
            # from more, and OpenBLAS's idle threads spin for the CPU the loop runs on (on one
            # CPU a paper campaign took 18 % longer).
            with frozen_heap(), threadpool_limits(limits=1, user_api="blas"):
                termination, message = _dig(scenario, plant, log, records, progress, start)
    except Exception as failure:
        termination, error = "error", failure
        period = len(records) + 1
        message = f"period {period}: {type(failure).__name__}: {failure}".replace("\n", " ")
    except BaseException:
        _close_all(plant, log, "error", INTERRUPTED)
        raise
    termination, message, error = _close_all(plant, log, termination, message, error)
    return CampaignResult(records, termination, message, scenario, log_path, error)


def _dig(scenario: Scenario, plant: Plant, log, records: list,
         progress: Callable[[dict[str, Any]], None] | None, start: Start) -> tuple[str, str]:
    planner = scenario.period_planner()
    adaptation = adaptation_strategy(scenario, planner)
    step_s = communication_step_s(plant, scenario.plant.communication_step_s)
    rated_kg = rated_payload_kg(scenario)  # the fill factor's reference, the same every period
    if start.state is None:
        decision: Decision = adaptation.initial()
    elif start.k < scenario.periods:  # what the run decided after period k, decided again
        if start.strategy is not None:
            adaptation.restore(start.strategy)
        decision = adaptation.decide(start.state, start.weighed_mass_kg)
    t0_s = start.t0_s
    for k in range(start.k + 1, scenario.periods + 1):
        if decision.terminated:
            return "workspace_limit", f"workspace limit after {k - 1} period(s)"
        state = decision.next_state
        trajectory = planner.plan(state.y_D, state.z_D)
        if isinstance(trajectory, Unreachable):  # the adaptation hands out reachable points only
            raise RuntimeError(f"D = ({state.y_D}, {state.z_D}) m: {trajectory.reason}")
        reference = sample_reference(trajectory, step_s)
        if log is not None:
            # The last period went to the file while this one was planned; it is there before
            # the plant runs again (a plant that crashes finds it on file).
            try:
                log.wait_written()
            except OSError as failure:
                raise OSError(f"writing the log of period {k - 1}: {failure}") from failure
        try:
            measurement = plant.run_period(reference)
            check_tracking(measurement, scenario.plant.max_tracking_error_deg)
        except Exception as failure:
            # A plant that stops mid-period may hand over what it measured: log it too.
            partial = failure.partial if isinstance(failure, PeriodStopped) else None
            if log is not None and isinstance(partial, PeriodMeasurement):
                try:
                    log.log_unfinished(partial, t0_s)
                except Exception:  # noqa: BLE001 - the plant's failure is what to report
                    pass
            raise
        record = period_record(state, decision, trajectory, measurement,
                               scenario.target_mass_kg, t0_s, rated_kg)
        if k < scenario.periods:  # before the resume record, which keeps what it learnt
            adaptation.learn(measurement.weighed_mass_kg, measurement.joints_rad)
        if log is not None:
            surface = initial_pile_surface(plant) if k == 1 else None
            if surface is not None:  # so that viewers draw the pile from t = 0
                log.log_pile_surface(*surface, t_s=0.0)
            saved = resume_record(plant, state, measurement.weighed_mass_kg,
                                  t0_s + float(measurement.t_s[-1]), adaptation.snapshot())
            # Without a state (a plant that cannot save one), the call of a log without them.
            log.log_period(record, measurement, t0_s,
                           **({} if saved is None else {"resume_state": saved}))
        records.append(record)
        if progress is not None:
            progress(record)
        t0_s += float(measurement.t_s[-1])
        if k < scenario.periods:
            decision = adaptation.decide(state, measurement.weighed_mass_kg)
    return "periods", f"{scenario.periods} period(s) dug"


class TrackingError(PeriodStopped):
    """A period whose tracking error went beyond the scenario's bound; `partial` holds its
    measurement (logged without a period record: its numbers are not reported)."""


def check_tracking(measurement: PeriodMeasurement, bound_deg: float) -> None:
    """TrackingError when a joint's |measured - reference| angle exceeds bound_deg (deg)
    anywhere in the period: an arm that does not follow its path digs numbers that mean
    nothing (plant.max_tracking_error_deg)."""
    error = np.abs(np.asarray(measurement.joints_rad) - np.asarray(measurement.reference_rad))
    peaks = np.degrees(error.max(axis=0))
    joint = int(np.argmax(peaks))
    if peaks[joint] > bound_deg:
        at_s = float(np.asarray(measurement.t_s)[int(np.argmax(error[:, joint]))])
        raise TrackingError(
            f"the {JOINTS[joint]} joint's tracking error reached {peaks[joint]:.3g} deg at "
            f"t = {at_s:.2f} s, beyond the bound of {bound_deg:g} deg "
            "(plant.max_tracking_error_deg)", measurement)


def sample_reference(trajectory: JointTrajectory, step_s: float) -> JointReference:
    """The trajectory on the grid t = 0, h, 2h, ... up to the first sample at or after its end
    (the arm is at rest at the last via-point from the end on). step_s: h in s."""
    if not (math.isfinite(step_s) and step_s > 0.0):
        raise ValueError(f"communication step must be a finite time > 0 s, got {step_s!r}")
    n = math.ceil(trajectory.duration / step_s - 1e-9) + 1
    t_s = np.arange(n) * step_s
    return JointReference(t_s=t_s, position_rad=trajectory(t_s),
                          velocity_rad_s=trajectory(t_s, 1),
                          acceleration_rad_s2=trajectory(t_s, 2))


def _close_all(plant: Plant | None, log, termination: str, message: str,
               error: BaseException | None = None) -> tuple[str, str, BaseException | None]:
    """Close the plant, then the log; a failure to close the plant, or to write the log,
    turns into an "error" termination (the log records what it can). The log's last periods
    are on file before the plant closes (closing FMUs runs their code, which may crash).
    Returns the final (termination, message, error)."""
    if log is not None:
        try:
            log.wait_written()
        except Exception as failure:
            if termination != "error":
                termination, error = "error", failure
                message = f"writing the log: {type(failure).__name__}: {failure}"
    try:
        if plant is not None:
            plant.close()
    except Exception as failure:
        if termination != "error":
            termination, error = "error", failure
            message = f"closing the plant: {type(failure).__name__}: {failure}"
    if log is not None:
        try:
            log.close(termination, message)
        except Exception as failure:  # e.g. a full disk: the file is closed all the same
            if termination != "error":
                termination, error = "error", failure
                message = f"writing the log: {type(failure).__name__}: {failure}"
    return termination, message, error
