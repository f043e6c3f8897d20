"""Continue a run log after its last complete period (`excosim run --resume`; the campaign side
is orchestrator.campaign.resume).

A run log cannot be appended to in place: a killed run's file may end inside a chunk (the
period it was digging), and a finished or interrupted one ends with its end record and summary.
So a resumed run writes a new file: the old file's bytes up to the end of the chunk of the
period it resumes after (everything before it is whole records: metadata, attachments, the
periods' chunks with their message indexes), that chunk's message indexes rebuilt from its
records (the killed run may have written only some of them), then the metadata record
`excosim.resumed`, then the new periods, as the writer that wrote the prefix would have
written them (orchestrator.runlog.mcap_records.McapChunkWriter.continued). When the run was
killed after it flushed a period, the copy's first bytes are the old file's.

In place (the default), the copy is written under a temporary name in the log's folder, forced
to the disk and renamed over the old file before the first new period is dug: at every moment
the file at the log's path is a readable run log with at least the periods it had, so a
resumed run that is killed again can be resumed again. With another output path the old file
is left as it is.

The same cut closes the log of a run whose process died (`close_unfinished`, for the supervisor
of orchestrator.campaign.isolation): its whole periods, then the end record with the reason.
"""

from __future__ import annotations

import io
import os
import stat
import struct
import tempfile
from collections.abc import Mapping
from pathlib import Path

import numpy as np
from mcap.data_stream import ReadDataStream
from mcap.opcode import Opcode
from mcap.records import Channel, Schema

from orchestrator.runlog.description import LogSettings
from orchestrator.runlog.inflate import ChunkRefused
from orchestrator.runlog.inflate import records as chunk_records
from orchestrator.runlog.lock import being_written
from orchestrator.runlog.mcap_records import MAGIC, McapChunkWriter
from orchestrator.runlog.reader import parse_run
from orchestrator.runlog.writer import RunLog
from plant_models.geometry import ExcavatorGeometry

_RECORD_PREFIX = struct.Struct("<BQ")


def continuation_prefix(data: bytes, chunk: tuple[int, int]) -> bytes:
    """The bytes of a run log `data` up to the end of the chunk record at `chunk` (offsets
    [start, end)), followed by that chunk's message indexes rebuilt from its records: a data
    section that McapChunkWriter.continued takes. ValueError for a chunk that is not whole."""
    start, end = chunk
    try:
        records, damage = chunk_records(memoryview(data)[start + _RECORD_PREFIX.size:end])
    except ChunkRefused as error:
        raise ValueError(f"the chunk at byte {start} {error}") from None
    if records is None:
        raise ValueError(f"the chunk at byte {start} is damaged ({damage})")
    return data[:end] + message_indexes(records)


def check_prefix(prefix: bytes) -> None:
    """ValueError (one line) unless `prefix` (continuation_prefix) is a data section that a
    continued writer takes as its own (McapChunkWriter.continued: schema and channel ids 1, 2,
    ... in order) and goes on with unambiguously: each schema and channel recorded once (not a
    duplicated record), every channel's schema present, no schema name twice, no topic twice
    with the same metadata."""
    schemas: dict[int, str] = {}
    channels: dict[int, str] = {}
    keys = set()
    pos = len(MAGIC)
    while pos + _RECORD_PREFIX.size <= len(prefix):
        opcode, length = _RECORD_PREFIX.unpack_from(prefix, pos)
        body = ReadDataStream(io.BytesIO(prefix[pos + _RECORD_PREFIX.size:
                                                pos + _RECORD_PREFIX.size + length]))
        pos += _RECORD_PREFIX.size + length
        if opcode == Opcode.SCHEMA:
            schema = Schema.read(body)
            if schema.id in schemas or schema.name in schemas.values():
                raise ValueError(f"schema {schema.id} ({schema.name}) is recorded twice")
            schemas[schema.id] = schema.name
        elif opcode == Opcode.CHANNEL:
            channel = Channel.read(body)
            key = (channel.topic, tuple(sorted(channel.metadata.items())))
            if channel.id in channels or key in keys:
                raise ValueError(f"channel {channel.id} ({channel.topic}) is recorded twice")
            if channel.schema_id != 0 and channel.schema_id not in schemas:
                raise ValueError(f"channel {channel.id} ({channel.topic}) names schema "
                                 f"{channel.schema_id}, which the log does not hold before it")
            channels[channel.id] = channel.topic
            keys.add(key)
    McapChunkWriter.continued(io.BytesIO(), prefix).abandon()  # its own checks


def header_prefix(data: bytes) -> bytes:
    """The bytes of a run log `data` before its first chunk (magic, header, the run's metadata
    and attachments): the prefix of a log that holds no period. Whole records only."""
    pos = len(MAGIC)
    while pos + _RECORD_PREFIX.size <= len(data):
        opcode, length = _RECORD_PREFIX.unpack_from(data, pos)
        end = pos + _RECORD_PREFIX.size + length
        if opcode in (Opcode.CHUNK, Opcode.DATA_END) or end > len(data):
            break
        pos = end
    return data[:pos]


def close_unfinished(path: str | Path, message: str) -> int | None:
    """Give the log at `path`, which its writer left without an end record (its process died),
    the end record termination "error" with `message` (one line), in place: its whole periods
    are kept (the bytes up to the last complete period, as a resume keeps them), the period
    being dug when the process died is dropped. Returns the periods kept; None when the log
    has its end record already (it is left as it is). RunLogError for a file that is not a run
    log, OSError when it cannot be read or replaced."""
    path = Path(path)
    if not stat.S_ISREG(path.stat().st_mode):
        raise OSError(f"{path} is not a regular file")
    if being_written(path):
        raise OSError(f"{path} is still being written by a live process")
    data = path.read_bytes()
    run = parse_run(path, data)
    if run.finished:
        return None
    kept = len(run.period_chunks)
    prefix = continuation_prefix(data, run.period_chunks[-1]) if kept else header_prefix(data)
    log = open_continued(path, None, prefix, periods=kept, note=None, geometry=None,
                         sample_rate_hz=None)
    log.close("error", message)
    return kept


def message_indexes(records: bytes) -> bytes:
    """The MessageIndex records of a chunk's `records`: one per channel, in the order the
    channels first appear, entries (log time, offset) sorted by time then offset (as
    orchestrator.runlog.chunk.ChunkBuilder writes them)."""
    entries: dict[int, list[tuple[int, int]]] = {}
    pos = 0
    while pos + _RECORD_PREFIX.size <= len(records):
        opcode, length = _RECORD_PREFIX.unpack_from(records, pos)
        if opcode == Opcode.MESSAGE:
            channel, _, log_time = struct.unpack_from("<HIQ", records, pos + 9)
            entries.setdefault(channel, []).append((log_time, pos))
        pos += _RECORD_PREFIX.size + length
    if pos != len(records):
        raise ValueError("a chunk's records do not end where the chunk says")
    out = []
    for channel, pairs in entries.items():
        table = np.array(sorted(pairs), dtype="<u8").tobytes()
        out.append(_RECORD_PREFIX.pack(Opcode.MESSAGE_INDEX, 6 + len(table))
                   + struct.pack("<HI", channel, len(table)) + table)
    return b"".join(out)


def open_continued(source: Path, output: Path | None, prefix: bytes, *, periods: int,
                   note: Mapping[str, str] | None, geometry: ExcavatorGeometry | None,
                   sample_rate_hz: float | None, overwrite: bool = False,
                   background: bool = False) -> RunLog:
    """The RunLog that continues `prefix` (continuation_prefix of `source`) after period
    `periods`: at `output` (a new file; an existing one only with `overwrite`), or, with
    output None or the source itself, in place (module docstring). OSError (FileExistsError)
    when the file cannot be made; nothing is left behind then. background: as RunLog's."""
    settings = {"periods": periods, "note": note, "geometry": geometry,
                "settings": LogSettings(sample_rate_hz=sample_rate_hz, background=background)}
    if output is not None and not _same_file(source, output):
        try:
            stream = open(output, "wb" if overwrite else "xb")
        except FileExistsError:
            raise FileExistsError(f"run log {output} already exists") from None
        try:
            return RunLog.continued(stream, prefix, path=output, **settings)
        except BaseException:
            stream.close()
            output.unlink(missing_ok=True)
            raise
    descriptor, temporary = tempfile.mkstemp(dir=source.parent, prefix=f".{source.name}.",
                                             suffix=".resuming")
    stream = os.fdopen(descriptor, "wb")
    try:
        os.chmod(temporary, stat.S_IMODE(source.stat().st_mode))
        log = RunLog.continued(stream, prefix, path=source, **settings)  # flushed to the disk
        os.replace(temporary, source)
    except BaseException:
        stream.close()
        Path(temporary).unlink(missing_ok=True)
        raise
    return log


def _same_file(a: Path, b: Path) -> bool:
    try:
        return a.resolve() == b.resolve() or (b.exists() and os.path.samefile(a, b))
    except OSError:
        return False
