"""The MCAP run log of a campaign: one file per run, written period by period.

Every period goes into the file as one chunk, flushed to the operating system as the run
goes, so a run that is killed leaves its finished periods readable
(`orchestrator.runlog.reader.read_run`): before `log_period` returns, or, with `background`,
on the log's own thread (`orchestrator.runlog.write_behind`) while the run plans its next
period, and surely when `wait_written`, the next `log_period` or `close` returns. The
campaign logs in the background and waits for the log before the plant runs again
(`orchestrator.campaign.loop`): filling, compression and writing (about 1.7 ms a paper
period) overlap the planning on a second core, and a crash in a plant still finds every
finished period on file. Log time is campaign time: ns since the start of
period 1 (t0 of a period + the plant's sample time).

Channels (schemas in `orchestrator.runlog.schemas`, frames in `orchestrator.runlog.scene`):

=================== ========================= =================================================
topic               schema (encoding)         one message per
=================== ========================= =================================================
/period/start       excosim.PeriodStart       period, at its start: the record's planned part
                    (JSON)                    (orchestrator.runlog.plan_scene)
/period             excosim.PeriodSummary     period, at its end: the campaign's record
                    (JSON)
/resume             excosim.ResumeState       period, at its end, after /period: what a
                    (JSON)                    resumed run continues from (simulated plants)
/joints             excosim.JointState        sample: reference and measured joints, rad
/cylinder/<joint>   excosim.CylinderState     sample: signals <joint>.x, v, p_A, p_B, F, u, F_ext
/pile/bucket        excosim.PileBucketState   sample: pile.* bucket outputs and tip.y/z/angle
/signals/<comp>     excosim.SignalSample      sample: any other signals of component <comp>;
                                              channel metadata "names" orders the values
/pile/profile       excosim.PileProfile       period, at its end: pile surface z(y), m
/tf                 foxglove.FrameTransforms  sample, decimated to `transform_rate_hz`
/scene/arm          foxglove.SceneUpdate      period, at its start: a box per arm link
/scene/pile         foxglove.SceneUpdate      period, at its end: pile surface, tip path,
                                              the last profiles fading
/scene/plan         foxglove.SceneUpdate      period, at its start and end: planned tip path,
                                              via-points, D; the lowest tip point at the end
/scene/tip_trail    foxglove.SceneUpdate      4 Hz: the measured tip path of the period so far
=================== ========================= =================================================

Metadata records: `excosim.run` (format, scenario name, plant kind, target mass, time base,
frames), `excosim.scenario` (the resolved scenario as JSON), `excosim.versions`, `excosim.fmus`
(FMU file sha256 by name), `excosim.fmu_content` (FMU content hash by name:
fmus.identity.content_hash, what an FMU is whatever its zip), `excosim.roles`,
`excosim.fmu_attachments`, `excosim.geometry` (JSON) and, at close,
`excosim.end` (termination, message, periods): a file without it is a run that did not finish;
`excosim.resumed` (after_period, source, source_ending) where a resumed run took over.
Attachments: `scenario.toml` (the scenario file's text; `.json` or `.txt` if it is not TOML, see
`excosim.run` "scenario_attachment") and `fmus/<file name>` (each distinct FMU once;
`excosim.fmu_attachments` maps each FMU name to its attachment). Module map: metadata
(these records), samples and scene (message content), chunk and mcap_records (the file
format), reader (reading it back).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import BinaryIO

import numpy as np
from foxglove.messages import FrameTransforms, SceneUpdate

from orchestrator.runlog import scene
from orchestrator.runlog.channels import ChannelTable
from orchestrator.runlog.chunk import ChunkBuilder, DoubleBatch
from orchestrator.runlog.description import LogSettings, RunDescription
from orchestrator.runlog.lock import being_written, lock_for_writing
from orchestrator.runlog.mcap_records import McapChunkWriter
from orchestrator.runlog.metadata import (
    FORMAT,
    FORMAT_VERSION,
    package_versions,
    read_fmus,
    to_json,
    write_run_description,
)
from orchestrator.runlog.plan_scene import (
    PERIOD_START_SCHEMA,
    period_start,
    plan_scene,
    trail_messages,
)
from orchestrator.runlog.samples import (
    checked,
    decimated,
    display_channel,
    profile_message,
    sample_channels,
)
from orchestrator.runlog.schemas import (
    PERIOD_SUMMARY_SCHEMA,
    PILE_PROFILE,
    RESUME_STATE_SCHEMA,
)
from plant_models.geometry import ExcavatorGeometry
from plant_models.plant import PeriodMeasurement

__all__ = ["FORMAT", "FORMAT_VERSION", "TERMINATIONS", "RunLog", "package_versions"]

TERMINATIONS = ("periods", "workspace_limit", "error")


class RunLog:
    """Writes one campaign run to an MCAP file at `path` (refuses an existing file unless
    `overwrite`).

    run: what the log records of the run (its metadata); settings: how it is written
    (orchestrator.runlog.description).
    Use as a context manager: an exception inside closes the log with termination "error";
    leaving the block normally closes it with "periods" unless `close` was called.
    """

    def __init__(self, path: str | Path, run: RunDescription,
                 settings: LogSettings | None = None, *, overwrite: bool = False) -> None:
        settings = settings or LogSettings()
        fmu_files = read_fmus(run.fmus)
        scenario_json = to_json(dict(run.scenario), "scenario")
        if overwrite and being_written(path):
            raise OSError(f"run log {path} is being written by a run that is still going")
        try:
            stream = open(Path(path), "wb" if overwrite else "xb")
        except FileExistsError:
            raise FileExistsError(f"run log {path} already exists") from None
        self._setup(path, run.geometry, settings)
        library = f"excosim {package_versions()['excosim']}"
        lock_for_writing(stream)
        self._writer = McapChunkWriter(stream, library=library, background=settings.background)
        self._table = ChannelTable(self._writer)
        try:
            write_run_description(
                self._writer, scenario_json=scenario_json, scenario_text=run.scenario_text,
                scenario_name=run.scenario_name, fmus=fmu_files, plant_kind=run.plant_kind,
                target_mass_kg=run.target_mass_kg, geometry=run.geometry,
                overrides=list(run.overrides), derived=run.derived,
                arm_coupling=run.arm_coupling, notes=run.notes,
            )
            self._writer.flush(settings.fsync, wait=settings.fsync)
        except BaseException:
            self._writer.abandon()
            raise

    def _setup(self, path: str | Path, geometry: ExcavatorGeometry | None,
               settings: LogSettings) -> None:
        self.path = Path(path)
        self._geometry = geometry
        self._rate_hz = float(settings.transform_rate_hz)
        self._sample_rate_hz = settings.sample_rate_hz
        self._fsync = settings.fsync
        self._periods = 0
        self._closed = False
        self._earlier: list[tuple[np.ndarray, np.ndarray]] = []  # newest first

    @classmethod
    def continued(cls, stream: BinaryIO, prefix: bytes, *, path: str | Path, periods: int,
                  note: Mapping[str, str] | None, geometry: ExcavatorGeometry | None = None,
                  settings: LogSettings | None = None) -> RunLog:
        """A run log that goes on from `prefix`, the first `periods` periods of a log this class
        wrote (its data section up to the end of period `periods`'s chunk and message indexes:
        orchestrator.runlog.resume), written to `stream` (closed at close()) and flushed with
        the metadata record `excosim.resumed` (`note`; None: none) after it. The next
        log_period is period periods + 1, on the same channels, as the run that wrote the
        prefix would have written it. geometry, settings: as the run's own (__init__).
        ValueError when the prefix is not such a data section."""
        self = cls.__new__(cls)
        settings = settings or LogSettings()
        self._setup(path, geometry, settings)
        lock_for_writing(stream)
        self._writer = McapChunkWriter.continued(stream, prefix, background=settings.background)
        self._table = ChannelTable(self._writer)
        self._periods = periods
        try:
            if note is not None:
                self._writer.add_metadata("excosim.resumed", dict(note))
            # The copy is on the disk before it may replace the original.
            self._writer.flush(True, wait=True)
        except BaseException:
            self._writer.abandon()  # the caller closes the stream and removes the copy
            raise
        return self

    # -- periods ----------------------------------------------------------------------------

    def log_period(self, record: Mapping, measurement: PeriodMeasurement, t0_s: float,
                   resume_state: Mapping | None = None) -> None:
        """Write one period and flush it (when: see the module docstring): `record` (any
        JSON-able dict; numpy values become lists) on /period, the measurement's samples at log
        time t0_s + t_s (s), the pile profile and the 3D scene; `resume_state` (JSON-able,
        schemas.RESUME_STATE_SCHEMA) on /resume, after the record in the same chunk. t0_s:
        campaign time (s) at the period's start, >= 0."""
        if self._closed:
            raise ValueError(f"run log {self.path} is closed")
        period = self._periods + 1
        if not isinstance(record, Mapping):
            raise ValueError(f"period {period} record must be a dict, got {type(record)}")
        record_json = to_json(dict(record), f"period {period} record").encode()
        resume_json = None if resume_state is None else \
            to_json(dict(resume_state), f"period {period} resume state").encode()
        period_data = decimated(checked(measurement), self._sample_rate_hz)
        chunk = ChunkBuilder(self._writer.pool)
        times, tip_path = self._add_samples(chunk, period_data, t0_s)
        start_ns, end_ns = int(round(t0_s * 1e9)), int(np.rint(times[-1] * 1e9))
        self._one(chunk, self._table.json("/period/start", PERIOD_START_SCHEMA), start_ns,
                  to_json(period_start(record, period), f"period {period} start").encode())
        if self._geometry is not None:
            plan = self._table.foxglove("/scene/plan", SceneUpdate)
            reference = period_data.reference_rad[
                np.arange(0, len(times), scene.decimation_stride(times, self._rate_hz))]
            for time_ns, lowest in ((start_ns, None), (end_ns, record.get("lowest_tip_m"))):
                self._one(chunk, plan, time_ns, plan_scene(time_ns, period, record, reference,
                                                           self._geometry, lowest))
        grid, profile = period_data.pile_grid_m, period_data.pile_profile_m
        if profile is not None:
            channel = self._table.proto("/pile/profile", PILE_PROFILE, {})
            self._one(chunk, channel, end_ns, profile_message(times[-1], grid, profile))
        if profile is not None or tip_path is not None:
            data = scene.pile_scene(end_ns, grid, profile, tip_path, self._geometry,
                                    self._earlier)
            self._one(chunk, self._table.foxglove("/scene/pile", SceneUpdate), end_ns, data)
        self._one(chunk, self._table.json("/period", PERIOD_SUMMARY_SCHEMA), end_ns,
                  record_json)
        if resume_json is not None:
            self._one(chunk, self._table.json("/resume", RESUME_STATE_SCHEMA), end_ns,
                      resume_json)
        if profile is not None:
            self.remember_profiles([(grid, profile)])
        self._writer.write_chunk(chunk)
        self._writer.flush(self._fsync, wait=self._fsync)
        self._periods = period

    def _one(self, chunk: ChunkBuilder, channel: int, time_ns: int, data: bytes) -> None:
        chunk.add_message(channel, self._writer.reserve_sequence(channel, 1), time_ns, data)

    def remember_profiles(self, profiles) -> None:
        """Take pile surfaces [(grid (n,) m, profile (n,) m)], oldest first, as the latest ones
        logged (the trench profiles /scene/pile draws fading; a resumed log is given those of
        the periods it keeps)."""
        for grid, profile in profiles:
            self._earlier.insert(0, (np.array(grid, dtype=float),
                                     np.array(profile, dtype=float)))
        del self._earlier[scene.EARLIER_PROFILES:]

    def log_unfinished(self, measurement: PeriodMeasurement, t0_s: float) -> None:
        """Write the samples of a period that did not finish (a plant that stopped mid-period
        hands over what it measured) as one flushed chunk, without a /period record: nothing
        measured is lost, and readers count only complete periods."""
        if self._closed:
            raise ValueError(f"run log {self.path} is closed")
        chunk = ChunkBuilder(self._writer.pool)
        self._add_samples(chunk, decimated(checked(measurement), self._sample_rate_hz), t0_s)
        self._writer.write_chunk(chunk)
        self._writer.flush(self._fsync, wait=self._fsync)

    def _add_samples(self, chunk: ChunkBuilder, period_data, t0_s: float):
        """The sample channels, /display and the arm of a period into `chunk`; returns the
        campaign times (m,) s and the bucket-tip path (or None without a geometry)."""
        t, joints = period_data.t_s, period_data.joints_rad
        if not (math.isfinite(t0_s) and t0_s >= 0.0 and t0_s + t[0] >= 0.0):
            raise ValueError(f"t0_s must be finite and t0_s + t_s >= 0, got t0_s = {t0_s!r}")
        times = t0_s + t
        log_ns = np.rint(times * 1e9).astype(np.uint64)
        start_ns = int(round(t0_s * 1e9))
        batches = []
        for sample in sample_channels(period_data, times):
            channel = self._table.proto(sample.topic, sample.message, sample.metadata)
            first = self._writer.reserve_sequence(channel, len(times))
            batches.append(DoubleBatch(channel, first, sample.prefixes, sample.columns))
        chunk.add_batches(batches, log_ns)
        picked = np.arange(0, len(t), scene.decimation_stride(t, self._rate_hz))
        display = display_channel(period_data, times, picked)
        channel = self._table.proto(display.topic, display.message, display.metadata)
        chunk.add_batches([DoubleBatch(channel, self._writer.reserve_sequence(channel, len(picked)),
                                       display.prefixes, display.columns)], log_ns[picked])
        tip_path = None
        if self._geometry is not None:
            self._add_arm(chunk, joints[picked], log_ns[picked], start_ns)
            tip_path = scene.tip_positions(self._geometry, joints[picked])
            trail = self._table.foxglove("/scene/tip_trail", SceneUpdate)
            for time_ns, data in trail_messages(self._geometry, t, joints, log_ns):
                self._one(chunk, trail, time_ns, data)
        return times, tip_path

    def log_pile_surface(self, grid_m: np.ndarray, profile_m: np.ndarray, t_s: float = 0.0
                         ) -> None:
        """Write the pile surface (cell-centre y (n,) m, height z (n,) m) at campaign time t_s
        (s) on /pile/profile and /scene/pile, as one flushed chunk: the surface before the first
        period, so that a viewer draws the pile from the start."""
        if self._closed:
            raise ValueError(f"run log {self.path} is closed")
        grid, profile = np.asarray(grid_m, dtype=float), np.asarray(profile_m, dtype=float)
        if grid.ndim != 1 or grid.shape != profile.shape or not (
                np.isfinite(grid).all() and np.isfinite(profile).all()):
            raise ValueError("pile surface: grid and profile must be finite arrays of one shape")
        if not (math.isfinite(t_s) and t_s >= 0.0):
            raise ValueError(f"t_s must be finite and >= 0, got {t_s!r}")
        time_ns = int(round(t_s * 1e9))
        chunk = ChunkBuilder(self._writer.pool)
        self._one(chunk, self._table.proto("/pile/profile", PILE_PROFILE, {}), time_ns,
                  profile_message(t_s, grid, profile))
        self._one(chunk, self._table.foxglove("/scene/pile", SceneUpdate), time_ns,
                  scene.pile_scene(time_ns, grid, profile, None, self._geometry))
        self._writer.write_chunk(chunk)
        self._writer.flush(self._fsync, wait=self._fsync)
        self.remember_profiles([(grid, profile)])

    def _add_arm(self, chunk: ChunkBuilder, joints: np.ndarray, log_ns: np.ndarray,
                 start_ns: int) -> None:
        """/scene/arm at the period's start, /tf for joints (n, 3) rad at times (n,) ns."""
        arm = self._table.foxglove("/scene/arm", SceneUpdate)
        data = scene.arm_scene(self._geometry, start_ns)
        chunk.add_message(arm, self._writer.reserve_sequence(arm, 1), start_ns, data)
        channel = self._table.foxglove("/tf", FrameTransforms)
        first = self._writer.reserve_sequence(channel, len(log_ns))
        transforms = scene.link_transforms(self._geometry, joints)
        for index, width, rows in scene.transform_records(transforms, log_ns, channel, first):
            chunk.add_rows(channel, log_ns[index], width, rows)

    def attach_live(self, view) -> None:
        """Hand every chunk from now on to `view` (orchestrator.live.LiveView) as it is made."""
        self._writer.tap = view.take_chunk

    def wait_written(self) -> None:
        """Block until everything logged so far is in the file (flushed to the operating
        system); raise what failed writing it, if anything. Returns at once without
        `background`."""
        self._writer.wait()

    # -- closing ----------------------------------------------------------------------------

    @property
    def periods(self) -> int:
        """Number of periods logged so far."""
        return self._periods

    def close(self, termination: str, message: str = "") -> None:
        """Write the end record (termination: one of TERMINATIONS; message: one line) and the
        file's summary. A second call does nothing."""
        if self._closed:
            return
        if termination not in TERMINATIONS:
            raise ValueError(f"termination must be one of {', '.join(TERMINATIONS)}, "
                             f"got {termination!r}")
        self._closed = True
        try:
            self._writer.add_metadata("excosim.end", {
                "termination": termination, "message": str(message),
                "periods": str(self._periods),
            })
        finally:  # a write that failed on the writer thread raises above: still close
            self._writer.finish()

    def __enter__(self) -> RunLog:
        return self

    def __exit__(self, exc_type, exc, traceback) -> None:
        if exc_type is not None:
            self.close("error", f"{exc_type.__name__}: {exc}".splitlines()[0])
        else:
            self.close("periods")

