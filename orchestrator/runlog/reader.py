"""Read an excosim run log (`orchestrator.runlog.writer`): the period records, metadata, attachments
and whether the run finished.

The file is read record by record from the start, so a run that was killed (no summary, maybe
a partly written last chunk) still gives every period whose chunk is complete. A record is used
only when all its bytes are there and a chunk only when its CRC matches; chunks are inflated
within bounds (orchestrator.runlog.inflate).

A file that ends inside a record is cut short (a killed run: `truncated`). A file whose bytes
were changed is damaged (`damage`, e.g. "damaged at byte 1014917 (chunk CRC)"): a whole chunk
whose records do not match the CRC the writer stored, or that do not inflate; in a closed file
(one that ends with the MCAP magic), a record that runs past its end; the CRC of the data
section that the writer stores at its end. What precedes a damaged chunk is read.
"""

from __future__ import annotations

import io
import stat
import struct
import zlib
from collections.abc import Collection
from pathlib import Path

import numpy as np
from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.opcode import Opcode
from mcap.records import Attachment, Channel, Metadata, Schema

from orchestrator.runlog import records
from orchestrator.runlog.decode import DecodeError, decode, is_numeric, numeric_schema
from orchestrator.runlog.inflate import CHUNK_HEAD, ChunkRefused
from orchestrator.runlog.inflate import records as chunk_records
from orchestrator.runlog.mcap_records import MAGIC
from orchestrator.runlog.metadata import FORMAT
from orchestrator.runlog.run_file import ChannelSamples, RunFile, RunLogError

__all__ = ["ChannelSamples", "RunFile", "RunLogError", "parse_run", "read_run"]

_RECORD_PREFIX = struct.Struct("<BQ")
_CHUNK_HEAD = CHUNK_HEAD
_MESSAGE_DATA = 2 + 4 + 8 + 8  # channel id, sequence, log time, publish time


class _Scan:
    def __init__(self, run: RunFile, collect: frozenset[str]) -> None:
        self.run = run
        self.topics: dict[int, str] = {}
        self.channels: dict[int, Channel] = {}
        self.schemas: dict[int, Schema] = {}
        self.collect = collect
        self.collected: dict[int, list[tuple[int, int, bytes]]] = {}

    def schema(self, body: bytes) -> None:
        schema = Schema.read(ReadDataStream(io.BytesIO(body)))
        self.schemas[schema.id] = schema

    def channel(self, body: bytes) -> None:
        channel = Channel.read(ReadDataStream(io.BytesIO(body)))
        self.topics[channel.id] = channel.topic
        self.channels[channel.id] = channel

    def message(self, body: memoryview) -> None:
        channel_id, _, log_time = struct.unpack_from("<HIQ", body)
        topic = self.topics.get(channel_id, f"<channel {channel_id}>")
        self.run.message_counts[topic] = self.run.message_counts.get(topic, 0) + 1
        if topic == "/period":
            self.period(body[_MESSAGE_DATA:], log_time)
        elif topic == "/resume":  # after its period's record, in the same chunk
            self.run.resume_states[len(self.run.periods)] = bytes(body[_MESSAGE_DATA:])
        elif topic in self.collect:
            self.collected.setdefault(channel_id, []).append(
                (len(self.run.periods) + 1, log_time, bytes(body[_MESSAGE_DATA:])))

    def period(self, data: memoryview, log_time: int) -> None:
        k = len(self.run.periods) + 1
        try:
            record = records.loads(bytes(data), f"/period record {k}")
        except ValueError as error:
            raise RunLogError(f"{self.run.path}: {error}") from None
        problem = records.period_problem(record, k)
        if problem is not None:
            raise RunLogError(f"{self.run.path}: {problem}")
        self.run.periods.append(record)
        self.run.period_end_ns.append(log_time)

    def decode_collected(self) -> None:
        """Decode the collected messages into run.channels (one entry per topic)."""
        by_topic: dict[str, list[tuple[int, int, bytes]]] = {}
        channel_of: dict[str, Channel] = {}
        for channel_id, messages in self.collected.items():
            topic = self.topics[channel_id]
            by_topic.setdefault(topic, []).extend(messages)
            channel_of.setdefault(topic, self.channels[channel_id])
        for topic, messages in by_topic.items():
            channel = channel_of[topic]
            schema = self.schemas.get(channel.schema_id)
            if schema is None or schema.encoding != "protobuf":
                raise RunLogError(f"{self.run.path}: channel {topic} is not a protobuf channel")
            messages.sort(key=lambda item: item[:2])
            try:
                fields = decode(numeric_schema(schema.name, schema.data),
                                [data for _, _, data in messages])
            except DecodeError as error:
                raise RunLogError(f"{self.run.path}: channel {topic}: {error}") from None
            n = len(messages)
            periods = np.fromiter((k for k, _, _ in messages), dtype=np.int64, count=n)
            times = np.fromiter((t for _, t, _ in messages), dtype=np.int64, count=n)
            self.run.channels[topic] = ChannelSamples(topic, schema.name, times, periods,
                                                      fields, dict(channel.metadata))

    def _indexed(self, view: memoryview, index: dict[int, np.ndarray]) -> bool:
        """Whether the message index can stand for the chunk: every channel known and the
        /period entries pointing at /period messages."""
        if not all(channel in self.topics for channel in index):
            return False
        return all(_points_at_messages(view, channel, offsets)
                   for channel, offsets in index.items() if self.topics[channel] == "/period")

    def chunk(self, body: memoryview, index: dict[int, np.ndarray] | None) -> str | None:
        """Read a chunk's records, through its message `index` (channel id -> record offsets)
        when given and every channel in it is known; None, or why the chunk is damaged
        ("chunk CRC", ...). ChunkRefused for a chunk beyond the bounds (inflate)."""
        records, damage = chunk_records(body)
        if records is None:
            return damage
        size = len(records)
        view = memoryview(records)
        if index is not None and self._indexed(view, index):
            wanted = []
            for channel, offsets in index.items():
                topic = self.topics[channel]
                if topic in ("/period", "/resume") or topic in self.collect:
                    wanted.append(offsets)
                else:
                    self.run.message_counts[topic] = self.run.message_counts.get(topic, 0)
                    self.run.message_counts[topic] += len(offsets)
            # In file order, so each message is counted in the period whose record follows it.
            for offset in np.sort(np.concatenate(wanted)).tolist() if wanted else ():
                (length,) = struct.unpack_from("<Q", view, offset + 1)
                self.message(view[offset + 9:offset + 9 + length])
            return None
        pos = 0
        while pos + _RECORD_PREFIX.size <= size:
            opcode, length = _RECORD_PREFIX.unpack_from(view, pos)
            inner = view[pos + 9:pos + 9 + length]
            if opcode == Opcode.MESSAGE:
                self.message(inner)
            elif opcode == Opcode.CHANNEL:
                self.channel(bytes(inner))
            elif opcode == Opcode.SCHEMA:
                self.schema(bytes(inner))
            pos += 9 + length
        return None if pos == size else "chunk records"


def _points_at_messages(view: memoryview, channel: int, offsets: np.ndarray) -> bool:
    """Whether every offset is a complete Message record of `channel` in the chunk records."""
    for offset in offsets.tolist():
        if offset + 11 > len(view) or view[offset] != Opcode.MESSAGE:
            return False
        length, record_channel = struct.unpack_from("<QH", view, offset + 1)
        if record_channel != channel or offset + 9 + length > len(view):
            return False
    return True


def _message_index(body: memoryview) -> tuple[int, np.ndarray]:
    """(channel id, record offsets in the chunk) of a MessageIndex record."""
    channel, length = struct.unpack_from("<HI", body)
    entries = np.frombuffer(body, dtype="<u8", offset=6, count=length // 8)
    return channel, entries[1::2]


def _scan(path: Path, data: bytes, collect: frozenset[str]) -> tuple[_Scan, bool]:
    """Every complete record of `data` up to any damage; returns the scan and whether the
    footer was reached (run.damage set when the file is damaged: module docstring).

    A chunk is read through the MessageIndex records after it only once a complete record
    follows them (so none of them is missing); otherwise by walking its records.
    """
    run = RunFile(path=path)
    scan = _Scan(run, collect)
    view = memoryview(data)
    pos = len(MAGIC)
    chunk, index, span = None, {}, (0, 0)
    while pos + _RECORD_PREFIX.size <= len(data):
        opcode, length = _RECORD_PREFIX.unpack_from(view, pos)
        end = pos + _RECORD_PREFIX.size + length
        if end > len(data):
            if data.endswith(MAGIC) and len(data) > 2 * len(MAGIC):  # a closed file
                run.damage = f"damaged at byte {pos} (a record runs past the end of the file)"
            break
        body = view[pos + _RECORD_PREFIX.size:end]
        if chunk is not None and opcode == Opcode.MESSAGE_INDEX:
            channel, offsets = _message_index(body)
            index[channel] = offsets
            pos = end
            continue
        if chunk is not None:
            if not _read_chunk(scan, chunk, index, span):
                return scan, False
            chunk, index = None, {}
        if opcode == Opcode.FOOTER:
            return scan, data[end:end + len(MAGIC)] == MAGIC
        if opcode == Opcode.CHUNK:
            chunk, span = body, (pos, end)
        elif opcode == Opcode.SCHEMA:
            scan.schema(bytes(body))
        elif opcode == Opcode.CHANNEL:
            scan.channel(bytes(body))
        elif opcode == Opcode.MESSAGE:
            scan.message(body)
        elif opcode == Opcode.METADATA:
            record = Metadata.read(ReadDataStream(io.BytesIO(bytes(body))))
            run.metadata[record.name] = record.metadata
        elif opcode == Opcode.ATTACHMENT:
            record = Attachment.read(ReadDataStream(io.BytesIO(bytes(body))))
            run.attachments[record.name] = record.data
        elif opcode == Opcode.DATA_END and length >= 4:
            (stored,) = struct.unpack_from("<I", body)
            if stored != 0 and stored != zlib.crc32(view[:pos]):
                run.damage = (f"damaged before byte {pos} (data section CRC; every chunk's "
                              "own CRC matches)")
        pos = end
    if chunk is not None:
        _read_chunk(scan, chunk, None, span)
    return scan, False


def _read_chunk(scan: _Scan, chunk: memoryview, index: dict[int, np.ndarray] | None,
                span: tuple[int, int]) -> bool:
    """scan.chunk of the chunk at `span`; False (run.damage set) when it is damaged."""
    try:
        damage = scan.chunk(chunk, index)
    except ChunkRefused as error:
        raise RunLogError(f"{scan.run.path}: the chunk at byte {span[0]} {error}: refused "
                          "(a damaged or crafted file)") from None
    if damage is not None:
        scan.run.damage = f"damaged at byte {span[0]} ({damage})"
        return False
    _spans(scan.run, span)
    return True


def _spans(run: RunFile, span: tuple[int, int]) -> None:
    """The chunk at `span` holds the records of the periods read since the last chunk."""
    run.period_chunks.extend([span] * (len(run.periods) - len(run.period_chunks)))


def read_run(path: str | Path, tolerant: bool = True, topics: Collection[str] = ()) -> RunFile:
    """Read the run log at `path`. tolerant: a killed or truncated run gives what it holds
    (`truncated` True); otherwise such a file raises RunLogError. topics: numeric channels to
    decode into `channels` (e.g. "/joints", "/cylinder/boom"; a topic the file lacks is left
    out). A file that is not MCAP or not an excosim run log raises RunLogError."""
    path = Path(path)
    try:
        if not stat.S_ISREG(path.stat().st_mode):  # a FIFO or a device would block or not end
            raise RunLogError(f"{path} is not a regular file (a folder, FIFO or device)")
        data = path.read_bytes()
    except OSError as exc:
        raise RunLogError(f"cannot read {path}: {exc.strerror}") from None
    return parse_run(path, data, tolerant, topics)


def parse_run(path: Path, data: bytes, tolerant: bool = True, topics: Collection[str] = ()
              ) -> RunFile:
    """read_run of the bytes `data` of the file at `path` (named in messages)."""
    if not data.startswith(MAGIC):
        raise RunLogError(f"{path} is not an MCAP file (it does not start with the MCAP magic)")
    try:
        scan, complete = _scan(path, data, frozenset(topics))
        run = scan.run
    except (struct.error, UnicodeDecodeError, ValueError, McapError) as exc:
        if isinstance(exc, RunLogError):
            raise
        reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise RunLogError(f"{path} is a damaged MCAP file: {reason}") from None
    if run.metadata.get("excosim.run", {}).get("format") != FORMAT:
        raise RunLogError(f"{path} is an MCAP file but not an excosim run log "
                          "(no excosim.run metadata record)")
    problem = records.header_problem(run.metadata["excosim.run"])
    if problem is not None:
        raise RunLogError(f"{path}: {problem}")
    if "json" in run.metadata.get("excosim.scenario", {}):
        try:
            problem = records.scenario_problem(records.loads(
                run.metadata["excosim.scenario"]["json"], "the scenario record"))
        except ValueError as error:
            problem = str(error)
        if problem is not None:
            raise RunLogError(f"{path}: {problem}")
    scan.decode_collected()
    run.numeric_topics = list(dict.fromkeys(channel.topic for channel in scan.channels.values()
                                            if is_numeric(scan.schemas.get(channel.schema_id))))
    end = run.metadata.get("excosim.end")
    run.finished = end is not None
    if end is not None:
        run.termination = end.get("termination")
        run.termination_message = end.get("message")
    run.truncated = not complete
    if (run.truncated or run.damage) and not tolerant:
        how = run.damage or "truncated"
        raise RunLogError(f"{path} is {how} after {len(run.periods)} complete periods"
                          f"{'' if run.damage else ' (the file ends early: a killed run?)'}; "
                          "read it with tolerant=True")
    return run
