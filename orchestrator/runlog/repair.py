"""Index a run log that a killed run left without its summary (`excosim log repair`).

A killed run's file holds every period it finished, each in a complete chunk, but no summary
(schemas, channels, chunk indexes, statistics): stream readers (ours, `excosim review`) read it
as it is; Lichtblick (and Foxglove Studio 1.x) read such a file whole into memory with a warning
("This file is unindexed"), and `mcap`'s `make_reader` needs the summary to seek. This copies
every complete record, in file order, into a new file written by the `mcap` package's own
writer (its `mcap recover` counterpart), which adds the summary. The part of a chunk that was
being written when the run died is left out, so the copy holds whole periods only. A run that
did not finish stays marked so: no end record is made up.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from pathlib import Path

import zstandard
from mcap.exceptions import McapError
from mcap.records import Attachment, Channel, DataEnd, Header, Message, Metadata, Schema
from mcap.stream_reader import StreamReader
from mcap.writer import CompressionType, Writer

from orchestrator.runlog.reader import RunLogError, read_run

# Chunk size of the copy: about one period of a paper run (the writer splits the data at this
# size; readers find periods by their /period records, not by chunks).
_CHUNK_BYTES = 1 << 20


@dataclass(frozen=True)
class RepairReport:
    """source and target paths; messages copied; truncated: the source ended inside a record
    (a killed run); periods: complete periods in the copy; finished: the run closed its log."""

    source: Path
    target: Path
    messages: int
    truncated: bool
    periods: int
    finished: bool


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
    with open(source, "rb") as stream, out:
        writer = Writer(out, chunk_size=_CHUNK_BYTES, compression=CompressionType.ZSTD)
        schemas: dict[int, int] = {}
        channels: dict[int, int] = {}
        messages, truncated, started = 0, False, False
        try:
            for record in StreamReader(stream, emit_chunks=False).records:
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
        except (McapError, zstandard.ZstdError, EOFError, struct.error, ValueError, KeyError,
                OverflowError, MemoryError):
            # the record being written when the run died, or damaged bytes whose lengths
            # overflow or ask for more memory than there is: left out from there on
            truncated = True
        if not started:
            raise RunLogError(f"{source}: no MCAP header to start the copy from")
        writer.finish()
    copy = read_run(target, tolerant=False)
    return RepairReport(source, target, messages, truncated or run.truncated,
                        len(copy.periods), copy.finished)
