"""Replay a simulated run from its MCAP log alone and check that it repeats the log.

A run log (`orchestrator.runlog.writer`) holds the resolved scenario, the FMUs as attachments and
their sha256 in the metadata. A simulated run is deterministic: the same scenario (its noise
seed included) and the same FMU bytes give the same numbers, so a replay of a faithful file
repeats every period's weighed mass, deepest point D and trajectory duration exactly
(compared within TOLERANCE, 1e-9 in kg, m and s).

An FMU is native code that runs inside this process. A replay therefore runs only FMUs whose content
(fmus.identity.content_hash: model description, binaries, sources; not the zip's bytes) equals that
of an FMU built from this version's sources (`fmus.build`) or one this machine built from earlier
sources and its build cache still holds (`fmus.cached_content_hashes`: the logs of earlier versions'
runs made here), unless the caller trusts the file. Refused even then: an attachment whose bytes do
not hash to the file's own metadata (it was altered after it was written), and one that is not a
safe archive (too many or too large entries, links, absolute or escaping names, NUL bytes:
fmus.identity.check_archive).

    report = replay_run("runs/paper.mcap")
    report.matches, report.first_difference(), report.as_dict()
"""

from __future__ import annotations

import copy
import hashlib
import math
import tempfile
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path, PurePosixPath
from typing import Any

from orchestrator.campaign import INTERRUPTED
from orchestrator.review.replay_compare import TOLERANCE, PeriodComparison, compare_periods
from orchestrator.review.summary import load
from orchestrator.runlog import RunFile
from orchestrator.scenario import PLANT_ROLES, ScenarioError

__all__ = ["TOLERANCE", "FmuCheck", "PeriodComparison", "ReplayRefused", "ReplayReport",
           "check_fmus", "compare_periods", "replay_run"]

SHORT_HASH = 12  # hex digits of a sha256 shown to a person
LOCAL_BUILD, TRUSTED = "local build", "--trust"
EARLIER_BUILD = "earlier local build"  # built here from earlier sources (the build cache)


class ReplayRefused(ValueError):
    """The file cannot or may not be replayed; the message is one line."""


@dataclass(frozen=True)
class FmuCheck:
    """The FMU a component ran: its attachment, the attachment's sha256, its content hash and
    why the replay runs it (trusted_by: "local build", the same content as our build;
    "earlier local build", built here from earlier sources; or "--trust")."""

    attachment: str
    sha256: str
    trusted_by: str
    content_sha256: str = ""


@dataclass
class ReplayReport:
    """A replay compared with its log.

    periods: one comparison per period k in either run (orchestrator.review.replay_compare).
    fmus: component (boom, stick, bucket, pile) -> the FMU the replay ran.
    logged_termination: how the logged run ended (None: it was killed).
    replayed_termination, replayed_message: how the replay ended (orchestrator.campaign.loop).
    termination_compared: whether the two endings were compared (not for a killed or an
        interrupted run: its ending says nothing about the campaign).
    tolerance: the largest absolute difference taken as equal (kg, m, s).
    damage: where the log's file is damaged (RunFile.damage; the periods before it were
        replayed), None if it is not.
    """

    path: Path
    tolerance: float
    periods: list[PeriodComparison]
    fmus: dict[str, FmuCheck]
    logged_termination: str | None
    replayed_termination: str
    replayed_message: str
    termination_compared: bool
    damage: str | None = None

    @property
    def termination_matches(self) -> bool:
        return not self.termination_compared or self.logged_termination == \
            self.replayed_termination

    @property
    def matches(self) -> bool:
        """Every period on both sides and equal within the tolerance, and the same ending."""
        return all(p.matches for p in self.periods) and self.termination_matches

    @property
    def max_abs_diff_mass_kg(self) -> float | None:
        return _largest(p.abs_diff_mass_kg for p in self.periods)

    @property
    def max_abs_diff_deepest_point_m(self) -> float | None:
        return _largest(p.abs_diff_deepest_point_m for p in self.periods)

    @property
    def max_abs_diff_duration_s(self) -> float | None:
        return _largest(p.abs_diff_duration_s for p in self.periods)

    def first_difference(self) -> str | None:
        """One line on the first difference ("period 2: mass 8.5 kg logged, 8.6 kg
        replayed", or the ending), None when the replay matches."""
        for period in self.periods:
            if not period.matches:
                if period.mass_kg_replayed is None:
                    return (f"period {period.k}: logged, not replayed (the replay ended: "
                            f"{self.replayed_termination}: {self.replayed_message})")
                return f"period {period.k}: {period.difference()}"
        if not self.termination_matches:
            return (f"the ending: logged {self.logged_termination!r}, replayed "
                    f"{self.replayed_termination!r} ({self.replayed_message})")
        return None

    def as_dict(self) -> dict[str, Any]:
        """Plain JSON-able data (infinite differences as None)."""
        return {
            "path": str(self.path), "matches": self.matches, "tolerance": self.tolerance,
            "periods": [p.as_dict() for p in self.periods],
            "max_abs_diff_mass_kg": _finite(self.max_abs_diff_mass_kg),
            "max_abs_diff_deepest_point_m": _finite(self.max_abs_diff_deepest_point_m),
            "max_abs_diff_duration_s": _finite(self.max_abs_diff_duration_s),
            "termination": {"logged": self.logged_termination,
                            "replayed": self.replayed_termination,
                            "replayed_message": self.replayed_message,
                            "compared": self.termination_compared},
            "damage": self.damage,
            "fmus": {component: asdict(check) for component, check in self.fmus.items()},
        }


def _largest(values) -> float | None:
    present = [v for v in values if v is not None]
    return max(present) if present else None


def _finite(value: float | None) -> float | None:
    return value if value is not None and math.isfinite(value) else None


def replay_run(path: str | Path, *, trust: bool = False,
               progress: Callable[[dict[str, Any], int], None] | None = None) -> ReplayReport:
    """Re-run the campaign logged at `path` from its own scenario and FMUs and compare.

    trust: run FMUs that differ from our builds (never one that differs from its own record).
    progress: called after each replayed period with its record and the number of periods
        the replay digs.
    Raises RunLogError (not a readable run log), ReplayRefused (a lab run, an altered or
    untrusted FMU, nothing to replay), ScenarioError (the file's scenario does not validate
    with this version) and fmus.BuildError (our FMUs cannot be built to compare with).
    """
    from orchestrator.campaign import run_campaign
    from orchestrator.scenario import scenario_from_dict

    path = Path(path)
    run = load(path)  # the records checked as review checks them (runlog.records)
    problem = run.not_simulated("be re-simulated")
    if problem is not None:
        raise ReplayRefused(problem)
    data = _scenario_data(run)
    try:  # the logged records are checked before the replay spends its time
        compare_periods(run.periods, [])
    except ValueError as error:
        raise ReplayRefused(f"{path}: {error}") from None
    periods, compare_end = _replay_length(run, data.get("periods"))
    fmus = check_fmus(run, trust=trust)
    with tempfile.TemporaryDirectory(prefix="excosim-replay-") as folder:
        data["periods"] = periods
        for component, fmu in _extract(run, fmus, Path(folder)).items():
            data["plant"][component]["fmu"] = str(fmu)
        scenario = scenario_from_dict(data, source=path.name, base_dir=folder)
        report = None if progress is None else (lambda record: progress(record, periods))
        result = run_campaign(scenario, progress=report)
    return ReplayReport(
        path=path, tolerance=TOLERANCE,
        periods=compare_periods(run.periods, result.records, TOLERANCE), fmus=fmus,
        logged_termination=run.termination,
        replayed_termination=result.termination, replayed_message=result.message,
        termination_compared=compare_end, damage=run.damage,
    )


def _scenario_data(run: RunFile) -> dict[str, Any]:
    """The resolved scenario of the run, checked to have a table per plant component."""
    try:
        data = run.scenario
    except (KeyError, ValueError):
        raise ReplayRefused(f"{run.path} holds no readable scenario record "
                            "(excosim.scenario)") from None
    if not isinstance(data, dict) or not isinstance(data.get("plant"), dict):
        raise ScenarioError(run.path.name, "plant", "the file's scenario has no [plant] table")
    for component in PLANT_ROLES:
        if not isinstance(data["plant"].get(component), dict):
            raise ScenarioError(run.path.name, f"plant.{component}",
                                "the file's scenario has no table for this component")
    return copy.deepcopy(data)


def _replay_length(run: RunFile, scenario_periods: Any) -> tuple[int, bool]:
    """(periods to dig, whether to compare the ending). A run that ended at the workspace
    limit or in an error is given one period more, where it stopped; a killed or interrupted
    run (campaign: termination "error", message "interrupted") replays what it holds."""
    logged = len(run.periods)
    interrupted = run.termination == "error" and run.termination_message == INTERRUPTED
    if run.finished and not interrupted and run.termination in ("workspace_limit", "error"):
        limit = scenario_periods if isinstance(scenario_periods, int) else logged + 1
        return max(1, min(logged + 1, limit)), True
    if logged == 0:
        raise ReplayRefused(f"{run.path} holds no complete period: nothing to replay")
    return logged, run.finished and not interrupted and run.termination == "periods"


def check_fmus(run: RunFile, *, trust: bool = False) -> dict[str, FmuCheck]:
    """component -> the FMU of `run` it may run; ReplayRefused for a missing, altered or unsafe
    attachment (always) or one whose content differs from our builds (unless `trust`)."""
    import fmus as fmu_builder
    from fmus.identity import LIMITS, UnsafeArchive, content_hash, unsafe_name

    hashes = run.metadata.get("excosim.fmus", {})
    attachments = run.metadata.get("excosim.fmu_attachments", {})
    recorded = {}
    for component in PLANT_ROLES:
        name = attachments.get(component)
        if name is None or component not in hashes:
            raise ReplayRefused(f"{run.path} records no FMU for component {component!r}")
        where = f"{run.path}: component {component}: attachment {name!r}"
        problem = unsafe_name(name) if isinstance(name, str) else "is not a name"
        if problem is not None:
            raise ReplayRefused(f"{where} {problem}; not replayed (not even with --trust)")
        if name not in run.attachments:
            raise ReplayRefused(f"{run.path}: component {component}: attachment {name} is "
                                "missing from the file")
        data = run.attachments[name]
        if len(data) > LIMITS.max_total_bytes:
            raise ReplayRefused(f"{where} holds {len(data)} bytes, more than the "
                                f"{LIMITS.max_total_bytes} allowed; not replayed")
        digest = hashlib.sha256(data).hexdigest()
        if digest != hashes[component]:
            raise ReplayRefused(
                f"{run.path}: component {component}: attachment {name} has sha256 "
                f"{digest[:SHORT_HASH]}, the file's metadata records "
                f"{str(hashes[component])[:SHORT_HASH]}: the file was altered after it was "
                "written; not replayed (not even with --trust)")
        try:
            content = content_hash(data, where)
        except UnsafeArchive as error:
            raise ReplayRefused(f"{error} (not even with --trust)") from None
        recorded[component] = (name, digest, content)
    try:
        local = fmu_builder.local_content_hashes()
    except fmu_builder.BuildError:
        if not trust:
            raise
        local = {}
    earlier = {} if all(content in local for _, _, content in recorded.values()) else \
        fmu_builder.cached_content_hashes()  # a log of an earlier version's run, made here
    untrusted = [c for c, (_, _, content) in recorded.items()
                 if content not in local and content not in earlier]
    if untrusted and not trust:
        which = ", ".join(f"{c} ({recorded[c][0]}, sha256 {recorded[c][1][:SHORT_HASH]})"
                          for c in untrusted)
        noun = "component" if len(untrusted) == 1 else "components"
        raise ReplayRefused(
            f"{run.path}: {noun} {which}: not an FMU built from this version's sources; an "
            "FMU is native code: check where the file comes from, then --trust runs it anyway")
    return {c: FmuCheck(name, digest, LOCAL_BUILD if content in local else
                        EARLIER_BUILD if content in earlier else TRUSTED, content)
            for c, (name, digest, content) in recorded.items()}


def _extract(run: RunFile, fmus: dict[str, FmuCheck], folder: Path) -> dict[str, Path]:
    """Write each distinct attachment once into `folder`; component -> its .fmu file."""
    files: dict[str, Path] = {}
    for check in fmus.values():
        if check.attachment not in files:
            # Only the last part of the name: a name from the file must not reach outside.
            file_name = PurePosixPath(check.attachment).name or "model"
            if not file_name.endswith(".fmu"):
                file_name += ".fmu"
            target = folder / str(len(files)) / file_name
            target.parent.mkdir()
            target.write_bytes(run.attachments[check.attachment])
            files[check.attachment] = target
    return {component: files[check.attachment] for component, check in fmus.items()}

