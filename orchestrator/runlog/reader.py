"""Read an excosim run log (`orchestrator.runlog.writer`): the period records, metadata, attachments
and whether the run finished.

The file is read record by record from the start, so a run that was killed (no summary, maybe
a partly written last chunk) still gives every period whose chunk is complete. A record is used
only when all its bytes are there and a chunk only when its CRC matches.
"""

from __future__ import annotations

import io
import json
import stat
import struct
import zlib
from collections.abc import Collection
from dataclasses import dataclass, field
from pathlib import Path

import lz4.frame
import numpy as np
import zstandard
from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.opcode import Opcode
from mcap.records import Attachment, Channel, Metadata, Schema

from orchestrator.runlog import records
from orchestrator.runlog.decode import DecodeError, decode, is_numeric, numeric_schema
from orchestrator.runlog.mcap_records import MAGIC
from orchestrator.runlog.metadata import FORMAT

_RECORD_PREFIX = struct.Struct("<BQ")
_CHUNK_HEAD = struct.Struct("<QQQII")  # start, end, uncompressed size, crc, compression length
_MESSAGE_DATA = 2 + 4 + 8 + 8  # channel id, sequence, log time, publish time


class RunLogError(ValueError):
    """A file that is not a readable excosim run log; the message is one line."""


@dataclass
class ChannelSamples:
    """The messages of one numeric channel, decoded with the schema stored in the file.

    log_time_ns: (n,) campaign time of each message (ns since the start of period 1).
    period: (n,) the period (1-based) each message belongs to: the one whose /period record
    follows it in the file (a period's last sample and the next one's first share a time).
    fields: field name -> (n,) values (NaN where a message lacks the field) or (n, k) for a
    repeated field. schema: its name (e.g. "excosim.JointState"). metadata: the channel's
    metadata (e.g. "names" of a /signals channel as a JSON list).
    """

    topic: str
    schema: str
    log_time_ns: np.ndarray
    period: np.ndarray
    fields: dict[str, np.ndarray]
    metadata: dict[str, str]

    def of_period(self, k: int) -> dict[str, np.ndarray]:
        """The fields of the messages of period k (1-based)."""
        lo, hi = np.searchsorted(self.period, [k, k + 1])
        return {name: values[lo:hi] for name, values in self.fields.items()}


@dataclass
class RunFile:
    """What a run log holds.

    periods: the /period records in order (dicts as the campaign wrote them).
    metadata: record name -> key -> value (e.g. metadata["excosim.versions"]["numpy"]).
    attachments: name -> bytes ("scenario.toml", "fmus/<file name>").
    message_counts: topic -> number of messages read.
    period_end_ns: log time (ns) of each /period message, i.e. of each period's end.
    channels: topic -> ChannelSamples of the numeric channels asked for (`read_run(topics=)`).
    finished: the run closed its log (an end record is present); termination and
    termination_message come from it (None if not finished).
    truncated: the file ends inside a record, lacks its footer or has a damaged chunk (a
    killed run); everything before that point was read.
    resume_states: period k -> the JSON bytes of its /resume message (what a resumed run
    continues from: orchestrator.campaign.resume), for the periods that have one.
    period_chunks: per period, the file offsets [start, end) of the chunk record that holds its
    /period record.
    numeric_topics: the topics whose schema is a protobuf message of doubles (what `topics=`
    decodes), in the order of their channel records.
    """

    path: Path
    periods: list[dict] = field(default_factory=list)
    metadata: dict[str, dict[str, str]] = field(default_factory=dict)
    attachments: dict[str, bytes] = field(default_factory=dict)
    message_counts: dict[str, int] = field(default_factory=dict)
    period_end_ns: list[int] = field(default_factory=list)
    channels: dict[str, ChannelSamples] = field(default_factory=dict)
    finished: bool = False
    termination: str | None = None
    termination_message: str | None = None
    truncated: bool = False
    resume_states: dict[int, bytes] = field(default_factory=dict)
    period_chunks: list[tuple[int, int]] = field(default_factory=list)
    numeric_topics: list[str] = field(default_factory=list)

    @property
    def scenario(self) -> dict:
        """The resolved scenario the run used."""
        return json.loads(self.metadata["excosim.scenario"]["json"])

    @property
    def scenario_text(self) -> str:
        """The text of the scenario file the run was started with."""
        return self.attachments[self.metadata["excosim.run"]["scenario_attachment"]].decode()

    def not_simulated(self, cannot: str) -> str | None:
        """Why a run that must be simulated again ("be re-simulated", "be resumed": `cannot`)
        cannot be (one line: a lab run, another plant kind); None for a simulated run."""
        kind = self.metadata.get("excosim.run", {}).get("plant_kind")
        if kind == "lab":
            return (f"{self.path} is a lab run: it was measured on the real machine, so it "
                    f"cannot {cannot}")
        if kind != "sim":
            return f"{self.path}: plant kind {kind!r} cannot {cannot} (only 'sim')"
        return None


# A chunk may declare at most this many uncompressed bytes: a paper period is about 1 MB, a
# 1 kHz lab period about 8 MB; a crafted chunk declaring 2^40 bytes (or a bomb that inflates a
# few KB to GBs) is refused as damaged instead of exhausting memory and time.
MAX_CHUNK_BYTES = 512 << 20


def _decompress(compression: str, data: bytes, size: int) -> bytes | None:
    """The chunk's records, or None when they would not be `size` bytes (damaged or crafted:
    never inflated beyond the size declared)."""
    if size > MAX_CHUNK_BYTES:
        return None
    if compression == "zstd":
        return zstandard.ZstdDecompressor().decompress(data, max_output_size=size)
    if compression == "lz4":
        decompressor = lz4.frame.LZ4FrameDecompressor()
        out = decompressor.decompress(data, max_length=size)
        return out if decompressor.eof else None
    if compression == "":
        return data
    raise RunLogError(f"unsupported chunk compression {compression!r}")


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

    def chunk(self, body: memoryview, index: dict[int, np.ndarray] | None) -> bool:
        """Read a chunk's records, through its message `index` (channel id -> record offsets)
        when given and every channel in it is known; False if the chunk is damaged."""
        _, _, size, crc, name_length = _CHUNK_HEAD.unpack_from(body)
        at = _CHUNK_HEAD.size
        compression = bytes(body[at:at + name_length]).decode()
        at += name_length
        (data_length,) = struct.unpack_from("<Q", body, at)
        try:
            records = _decompress(compression, bytes(body[at + 8:at + 8 + data_length]), size)
        except (zstandard.ZstdError, RuntimeError):
            return False
        if records is None or len(records) != size or (crc != 0 and zlib.crc32(records) != crc):
            return False
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
            return True
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
        return pos == size


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
    """Every complete record of `data`; returns the scan and whether the footer was reached.

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
            break
        body = view[pos + _RECORD_PREFIX.size:end]
        if chunk is not None and opcode == Opcode.MESSAGE_INDEX:
            channel, offsets = _message_index(body)
            index[channel] = offsets
            pos = end
            continue
        if chunk is not None:
            damaged = not scan.chunk(chunk, index)
            chunk, index = None, {}
            if damaged:
                return scan, False
            _spans(run, span)
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
        pos = end
    if chunk is not None and scan.chunk(chunk, None):
        _spans(run, span)
    return scan, False


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
    if run.truncated and not tolerant:
        raise RunLogError(f"{path} is truncated or damaged after {len(run.periods)} complete "
                          "periods (a killed run?); read it with tolerant=True")
    return run
