"""Resume a simulated run from its log: continue after its last complete period so that the
combined log is the uninterrupted run's, period for period (`excosim run --resume RUN.mcap`).

Every period of a simulated run logs, in its own chunk after its record, the state to continue
from (/resume: orchestrator.campaign.resume_state, orchestrator.plants.plant_state). A resume

1. reads the log (tolerantly: a killed run's file ends inside the period it was digging) and
   refuses a lab run (a real machine's state cannot be restored), a run that finished (nothing
   to resume: NothingToResume) and a log without a resume state;
2. validates the scenario the log records (`excosim.scenario`: the scenario file's text with
   its `--set` items applied, resolved) as this version reads it, and checks that the FMUs it
   would run now have the content hashes the log records (`excosim.fmu_content`): with other
   FMUs it would not be the same run; and checks what it copies as strictly as a fresh read:
   the scenario record is the one the header's digest names, the period records, the resume
   state and the header tell one run, the schema and channel records are each there once, the
   file is not damaged;
3. builds the plant and restores the state logged after the last complete period k that has
   one (each FMU validates its own serialized state);
4. only then writes: the log's bytes up to period k, then periods k+1.. (orchestrator.runlog
   .resume: in place by default, or into a new file).

A run that ended in an error (an interrupt, a step timeout, a log that could not be written) is
resumed from its last complete period too; a failure that the scenario itself causes then
comes back at the same place. Refusals are ResumeRefused (one line), before anything is written.
"""

from __future__ import annotations

import io
import math
import struct
from collections.abc import Callable
from contextlib import nullcontext
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from mcap.exceptions import McapError

from orchestrator.campaign.loop import CampaignResult, Start, build_plant, run_opened
from orchestrator.campaign.resume_state import parse_resume_record
from orchestrator.campaign.watchdog import StepWatchdog
from orchestrator.runlog.reader import RunFile, RunLogError, parse_run
from orchestrator.runlog.resume import check_prefix
from orchestrator.scenario.model import Scenario

FINISHED = ("periods", "workspace_limit")  # endings after which nothing is left to dig


class ResumeRefused(ValueError):
    """The log cannot be resumed; the message is one line."""


class NothingToResume(Exception):
    """The logged run finished; the message is one line."""


@dataclass
class ResumeSource:
    """A log checked for resuming: its run, scenario, the period k to continue after, that
    period's resume record (resume_state.parse_resume_record) and the log's bytes to keep
    (orchestrator.runlog.resume.continuation_prefix)."""

    path: Path
    run: RunFile
    scenario: Scenario
    k: int
    record: dict[str, Any]
    prefix: bytes
    lock: Any = None  # the log's file, its writer's lock held (orchestrator.runlog.lock)

    @property
    def records(self) -> list[dict[str, Any]]:
        """The period records the resumed run keeps (periods 1..k)."""
        return self.run.periods[:self.k]

    def release(self) -> None:
        """Drop the lock on the source log (once the continued log has replaced it)."""
        if self.lock is not None:
            self.lock.close()
            self.lock = None


def prepare_resume(path: str | Path) -> ResumeSource:
    """Check the log at `path` for resuming (steps 1-2 of the module docstring) and hold its
    lock, so that no other process writes or resumes it meanwhile (ResumeSource.release).
    Raises ResumeRefused (a log that is being written among others), NothingToResume,
    ScenarioError (its scenario does not validate with this version) and fmus.BuildError (our
    FMUs cannot be built)."""
    path = Path(path)
    run, data, lock = _read(path)
    try:
        source = _prepare(path, run, data)
    except BaseException:
        if lock is not None:
            lock.close()
        raise
    source.lock = lock
    return source


def _prepare(path: Path, run: RunFile, data: bytes) -> ResumeSource:
    from orchestrator.runlog.resume import continuation_prefix
    from orchestrator.scenario import scenario_from_dict

    problem = run.not_simulated("be resumed")
    if problem is not None:
        raise ResumeRefused(problem)
    if run.finished and run.termination in FINISHED:
        n = len(run.periods)
        how = f"dug all {n} planned periods" if run.termination == "periods" else \
            f"stopped at the workspace limit after {n} periods"
        raise NothingToResume(f"{path}: nothing to resume: the run finished ({how})")
    if run.damage is not None:  # not a killed run: resuming would dig again over the damage
        n = len(run.periods)
        raise ResumeRefused(f"{path} is {run.damage}, after {n} complete period"
                            f"{'s' if n != 1 else ''}: it is not resumed over the damage "
                            f"(`excosim log repair` copies the periods before it into a new "
                            "log, which can be resumed)")
    candidates = [k for k in run.resume_states if 1 <= k <= len(run.period_chunks)]
    if not candidates:
        if not run.periods:
            raise ResumeRefused(f"{path} holds no complete period: nothing to resume from "
                                "(run the scenario again)")
        raise ResumeRefused(f"{path} holds no resume state (a log of an older version, or of "
                            "a plant whose FMUs cannot save their state): it cannot be resumed")
    k = max(candidates)
    from orchestrator.runlog.records import loads

    try:
        loads(run.resume_states[k], "it")  # "nested too deeply" before the parser recurses
        record = parse_resume_record(run.resume_states[k], k)
    except ValueError as error:
        raise ResumeRefused(f"{path}: the resume state after period {k}: {error}") from None
    try:
        scenario_data = run.scenario
    except (KeyError, ValueError):
        raise ResumeRefused(f"{path} holds no readable scenario record (excosim.scenario)"
                            ) from None
    from orchestrator.runlog.records import runs_problem

    problem = runs_problem(run.periods[:k])  # what is copied is checked as review checks it
    if problem is not None:
        raise ResumeRefused(f"{path}: {problem}")
    if not isinstance(scenario_data, dict):
        raise ResumeRefused(f"{path}: the scenario record (excosim.scenario) is not an object")
    _check_digest(path, run)
    scenario = scenario_from_dict(scenario_data, source=path.name)
    _check_agreement(path, run, float(scenario.target_mass_kg), record, k)
    if k > scenario.periods:
        raise ResumeRefused(f"{path} holds {k} periods, more than its scenario's "
                            f"{scenario.periods}")
    _check_fmus(path, run, scenario)
    _check_strategy(path, scenario, record, k)
    try:
        prefix = continuation_prefix(data, run.period_chunks[k - 1])
    except (ValueError, IndexError) as error:
        raise ResumeRefused(f"{path}: period {k}'s chunk: {error}") from None
    try:
        check_prefix(prefix)
    except (ValueError, struct.error, McapError) as error:
        raise ResumeRefused(f"{path}: the part a resume copies is not as its writer left it: "
                            f"{error}") from None
    return ResumeSource(path, run, scenario, k, record, prefix)


_EDITED = "the log was edited, and a resumed run would mix two scenarios"


def _check_digest(path: Path, run: RunFile) -> None:
    """The scenario record is the one the header's digest names (logs from before the digest:
    nothing to check here; _check_agreement still compares the target)."""
    from orchestrator.runlog.metadata import scenario_digest

    digest = run.metadata.get("excosim.run", {}).get("scenario_sha256")
    if digest is None:
        return
    if scenario_digest(run.metadata["excosim.scenario"]["json"]) != digest:
        raise ResumeRefused(f"{path}: its scenario record (excosim.scenario) is not the one its "
                            f"header recorded at the start (scenario_sha256 {digest[:12]}): "
                            + _EDITED)


def _check_agreement(path: Path, run: RunFile, target: float, record: dict[str, Any],
                     k: int) -> None:
    """The header, the period records 1..k and the resume state after k tell one run: the
    header's target is the scenario's, each record is the period of its place and its error
    the target minus its mass, and the state's weighing is period k's mass."""
    header = run.metadata.get("excosim.run", {}).get("target_mass_kg")
    try:
        edited = header is not None and float(header) != target
    except ValueError:
        edited = True
    if edited:
        raise ResumeRefused(f"{path}: its header's target ({header} kg) and its scenario "
                            f"record's ({target:g} kg) disagree: " + _EDITED)
    for place, period in enumerate(run.periods[:k], start=1):
        if period["k"] != place:
            raise ResumeRefused(f"{path}: /period record {place} says it is period "
                                f"{period['k']}: the records were edited or duplicated")
        if not math.isclose(period["error_kg"], target - period["mass_kg"], rel_tol=1e-12,
                            abs_tol=1e-9):
            raise ResumeRefused(f"{path}: /period record {place}: its error "
                                f"({period['error_kg']:g} kg) is not the scenario's target "
                                f"({target:g} kg) minus its mass ({period['mass_kg']:g} kg): "
                                + _EDITED)
    if record["weighed_mass_kg"] != run.periods[k - 1]["mass_kg"]:
        raise ResumeRefused(f"{path}: the resume state after period {k} weighed "
                            f"{record['weighed_mass_kg']:g} kg, its /period record "
                            f"{run.periods[k - 1]['mass_kg']:g} kg: the log was edited")


def _check_strategy(path: Path, scenario, record: dict[str, Any], k: int) -> None:
    """A strategy that learns (terrain) needs what it had learnt, and it must fit."""
    from orchestrator.campaign.strategy import adaptation_strategy

    strategy = adaptation_strategy(scenario, scenario.period_planner())
    if strategy.snapshot() is None:  # a rule strategy: nothing to restore
        return
    if record["strategy"] is None:
        raise ResumeRefused(f"{path}: the resume state after period {k} lacks the "
                            f"{scenario.adaptation.strategy} strategy's estimate: it cannot "
                            "be resumed")
    try:
        strategy.restore(record["strategy"])
    except ValueError as error:
        raise ResumeRefused(f"{path}: the resume state after period {k}: {error}") from None


def _read(path: Path) -> tuple[RunFile, bytes, Any]:
    import stat

    from orchestrator.runlog.lock import hold

    try:
        if not stat.S_ISREG(path.stat().st_mode):
            raise ResumeRefused(f"{path} is not a regular file (a folder, FIFO or device)")
        try:
            lock = hold(path)
        except BlockingIOError:
            raise ResumeRefused(f"{path} is being written by a run that is still going (its "
                                "writer holds the file's lock): stop it first") from None
        data = path.read_bytes()
    except OSError as error:
        raise ResumeRefused(f"cannot read {path}: {error.strerror or error}") from None
    try:
        return parse_run(path, data, topics=("/pile/profile",)), data, lock
    except RunLogError as error:
        if lock is not None:
            lock.close()
        raise ResumeRefused(str(error)) from None


def _check_fmus(path: Path, run: RunFile, scenario: Scenario) -> None:
    """ResumeRefused unless every FMU the scenario runs now has the content the log records."""
    from fmus.identity import UnsafeArchive, content_hash
    from orchestrator.plants.master import fmu_path

    logged = run.metadata.get("excosim.fmu_content", {})
    for role, spec in scenario.fmu_specs().items():
        recorded = logged.get(role)
        if not recorded:
            raise ResumeRefused(f"{path} records no content hash for the {role} FMU: it "
                                "cannot be checked, so it is not resumed")
        fmu = fmu_path(spec, role)
        try:
            now = content_hash(fmu, f"plant.{role}.fmu: {fmu}")
        except (OSError, UnsafeArchive) as error:
            raise ResumeRefused(str(error).splitlines()[0]) from None
        if now != recorded:
            raise ResumeRefused(
                f"{path}: the {role} FMU that would run now ({spec.fmu}, content "
                f"{now[:12]}) is not the one the run used (content {recorded[:12]}); a run "
                "resumed with other FMUs is not the same run")


def _profiles(run: RunFile, k: int) -> list[tuple[Any, Any]]:
    """The pile surfaces the log holds up to period k's end, oldest first: (grid, profile)."""
    samples = run.channels.get("/pile/profile")
    if samples is None:
        return []
    keep = samples.period <= k
    return list(zip(samples.fields["y_m"][keep], samples.fields["z_m"][keep], strict=True))


def resume_campaign(source: ResumeSource, output: str | Path | None = None, *,
                    progress: Callable[[dict[str, Any]], None] | None = None,
                    overwrite: bool = False, step_timeout_s: float | None = None,
                    on_step_timeout: Callable[[str], None] | None = None,
                    on_log_opened: Callable[[Any], None] | None = None) -> CampaignResult:
    """Continue the run of `source` (prepare_resume) after its period k; the result holds
    every period's record, 1.. (orchestrator.campaign.loop.run_campaign's result).

    output: where the combined log goes (None or the source's path: in place; another path: a
    new file, an existing one only with `overwrite`). progress, step_timeout_s,
    on_step_timeout, on_log_opened: as run_campaign's. ResumeRefused when the plant refuses
    the state (an FMU that does not take its serialized state), OSError when the log cannot be
    made: nothing is written then. After that it fails as run_campaign does (termination
    "error")."""
    try:
        log, plant, start = _continue(source, output, overwrite, step_timeout_s,
                                      on_step_timeout)
    finally:
        source.release()  # the continued log is in place, or nothing was written
    if on_log_opened is not None:
        on_log_opened(log)
    return run_opened(source.scenario, log, plant, start, progress, step_timeout_s,
                      on_step_timeout, log.path)


def _continue(source: ResumeSource, output: str | Path | None, overwrite: bool,
              step_timeout_s: float | None, on_step_timeout: Callable[[str], None] | None
              ) -> tuple[Any, Any, Start]:
    """The plant restored and the continued log open (resume_campaign), or an exception."""
    from orchestrator.runlog.metadata import package_versions
    from orchestrator.runlog.resume import open_continued
    from orchestrator.scenario.fmu_probe import capture_this_thread

    scenario, record, k = source.scenario, source.record, source.k
    # Loading the FMUs is watched as in a run (nothing is written yet: no log to close).
    def watchdog():
        if not (step_timeout_s and on_step_timeout):
            return nullcontext()
        return StepWatchdog(step_timeout_s,
                            lambda detail: on_step_timeout(f"period {k + 1}: {detail}"))

    try:
        with watchdog():
            plant = build_plant(scenario)
    except ValueError as error:  # what the scenario asks of its FMUs (run: PlantRefused)
        raise ResumeRefused(f"{source.path}: its plant cannot be built again: "
                            f"{str(error).splitlines()[0]}") from None
    printed = io.StringIO()
    try:
        with capture_this_thread(printed), watchdog():  # fmpy prints an FMU's refusal's reason
            plant.restore_state(record["plant"])
    except ValueError as error:
        _close_quietly(plant)
        logged = [line.partition("] ")[2] for line in printed.getvalue().splitlines()
                  if line.startswith(("[ERROR]", "[FATAL]"))]
        why = logged[0] if logged else (str(error.__cause__) if error.__cause__ else "")
        raise ResumeRefused(f"{source.path}: the state after period {k}: {error}"
                            + (f" ({why})" if why else "")) from None
    except BaseException:
        _close_quietly(plant)
        raise
    run = source.run
    ending = "killed (no end record)" if not run.finished else \
        f"{run.termination}: {run.termination_message}"
    note = {"after_period": str(k), "source": source.path.name, "source_ending": ending,
            "excosim": package_versions()["excosim"]}
    try:
        log = open_continued(source.path, None if output is None else Path(output),
                             source.prefix, periods=k, note=note, geometry=scenario.geometry(),
                             sample_rate_hz=scenario.log.sample_rate_hz, overwrite=overwrite,
                             background=True)
    except BaseException:
        _close_quietly(plant)
        raise
    log.remember_profiles(_profiles(run, k))
    start = Start(k=k, records=tuple(source.records), t0_s=record["t0_next_s"],
                  state=record["adaptation"], weighed_mass_kg=record["weighed_mass_kg"],
                  strategy=record["strategy"])
    return log, plant, start



def _close_quietly(plant: Any) -> None:
    """Close the plant on the way out of a refusal or failure, which stays the reason (a
    failed terminate, Master.close, would otherwise replace it)."""
    try:
        plant.close()
    except Exception:  # noqa: BLE001, S110 - the caller's exception is what to report
        pass
