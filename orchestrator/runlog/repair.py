"""Index a run log that a killed run left without its summary (`excosim log repair`).

A killed run's file holds every period it finished, each in a complete chunk, but no summary
(schemas, channels, chunk indexes, statistics): stream readers (ours, `excosim review`) read it
as it is; Lichtblick (and Foxglove Studio 1.x) read such a file whole into memory with a warning
("This file is unindexed"), and `mcap`'s `make_reader` needs the summary to seek. This copies
every complete record, in file order, into a new file written by the `mcap` package's own
writer (its `mcap recover` counterpart), which adds the summary. The part of a chunk that was
being written when the run died is left out, so the copy holds whole periods only. A run that
did not finish stays marked so: no end record is made up.

Damaged or hostile bytes end the copy where they begin: a chunk is inflated within the bounds
of orchestrator.runlog.inflate and used only when its CRC matches (a chunk beyond the bounds
is refused by the reader that checks the file first), and no record may be longer than the
file.
"""

from __future__ import annotations

import io
import struct
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.opcode import Opcode
from mcap.records import Attachment, Channel, Chunk, DataEnd, Header, Message, Metadata, Schema
from mcap.stream_reader import StreamReader
from mcap.writer import CompressionType, Writer

from orchestrator.runlog.inflate import ChunkRefused, checked
from orchestrator.runlog.reader import RunLogError, read_run

# Chunk size of the copy: about one period of a paper run (the writer splits the data at this
# size; readers find periods by their /period records, not by chunks).
_CHUNK_BYTES = 1 << 20


@dataclass(frozen=True)
class RepairReport:
    """source and target paths; messages copied; truncated: the source ended inside a record
    (a killed run) or was damaged; periods: complete periods in the copy; finished: the run
    closed its log; damage: where the source is damaged (RunFile.damage), None if it is not."""

    source: Path
    target: Path
    messages: int
    truncated: bool
    periods: int
    finished: bool
    damage: str | None = None


def repair(source: str | Path, target: str | Path) -> RepairReport:
    """Copy the run log `source` into a new, indexed file `target` (which must not exist).

    Raises RunLogError (one line) when source is not a run log and FileExistsError when target
    exists; nothing is written then.
    """
    source, target = Path(source), Path(target)
    run = read_run(source)  # RunLogError for anything that is not a run log of ours
    if source.resolve() == target.resolve():
        raise FileExistsError(f"{target} is the file to repair: choose another output")
    try:
        out = open(target, "xb")
    except FileExistsError:
        raise FileExistsError(f"{target} already exists; remove it or choose another name"
                              ) from None
    try:
        data = source.read_bytes()
    except OSError as error:
        out.close()
        target.unlink()
        raise RunLogError(f"cannot read {source}: {error.strerror or error}") from None
    # From memory: a damaged length then asks a BytesIO, which gives what there is, not a
    # file object, which would first allocate what the length says.
    with io.BytesIO(data) as stream, out:
        writer = Writer(out, chunk_size=_CHUNK_BYTES, compression=CompressionType.ZSTD)
        schemas: dict[int, int] = {}
        channels: dict[int, int] = {}
        messages, truncated, started = 0, False, False
        try:
            for record in _records(stream, len(data)):
                if isinstance(record, Header):
                    writer.start(profile=record.profile, library=record.library)
                    started = True
                elif isinstance(record, Schema):
                    schemas[record.id] = writer.register_schema(record.name, record.encoding,
                                                                record.data)
                elif isinstance(record, Channel):
                    channels[record.id] = writer.register_channel(
                        record.topic, record.message_encoding, schemas.get(record.schema_id, 0),
                        dict(record.metadata))
                elif isinstance(record, Message):
                    writer.add_message(channels[record.channel_id], record.log_time,
                                       record.data, record.publish_time, record.sequence)
                    messages += 1
                elif isinstance(record, Attachment):
                    writer.add_attachment(record.create_time, record.log_time, record.name,
                                          record.media_type, record.data)
                elif isinstance(record, Metadata):
                    writer.add_metadata(record.name, dict(record.metadata))
                elif isinstance(record, DataEnd):
                    break
        except (McapError, EOFError, struct.error, ValueError, KeyError, OverflowError,
                MemoryError):
            # the record being written when the run died, or damaged bytes whose lengths
            # overflow or ask for more memory than there is: left out from there on
            truncated = True
        if not started:
            raise RunLogError(f"{source}: no MCAP header to start the copy from")
        writer.finish()
    copy = read_run(target, tolerant=False)
    return RepairReport(source, target, messages, truncated or run.truncated,
                        len(copy.periods), copy.finished, run.damage)


def _records(stream: io.BytesIO, limit: int) -> Iterator:
    """The records of the MCAP file in `stream` in order, a chunk's records in its place
    (inflated within bounds; ValueError for a damaged or refused chunk). limit: the file's
    length, which no record exceeds."""
    for record in StreamReader(stream, emit_chunks=True, record_size_limit=limit).records:
        if not isinstance(record, Chunk):
            yield record
            continue
        try:
            data, damage = checked(record.compression, record.data, record.uncompressed_size,
                                   record.uncompressed_crc)
        except ChunkRefused as error:
            raise ValueError(f"a chunk {error}") from None
        if data is None:
            raise ValueError(f"a damaged chunk ({damage})")
        inner = ReadDataStream(io.BytesIO(data))
        while inner.count < len(data):
            opcode, length = inner.read1(), inner.read8()
            if opcode == Opcode.CHANNEL:
                yield Channel.read(inner)
            elif opcode == Opcode.MESSAGE:
                yield Message.read(inner, length)
            elif opcode == Opcode.SCHEMA:
                yield Schema.read(inner)
            else:
                inner.read(length)
