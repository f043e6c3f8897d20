"""Read an excosim run log (`orchestrator.run_log`): the period records, metadata, attachments
and whether the run finished.

The file is read record by record from the start, so a run that was killed (no summary, maybe
a partly written last chunk) still gives every period whose chunk is complete. A record is used
only when all its bytes are there and a chunk only when its CRC matches.
"""

from __future__ import annotations

import io
import json
import struct
import zlib
from dataclasses import dataclass, field
from pathlib import Path

import lz4.frame
import numpy as np
import zstandard
from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.opcode import Opcode
from mcap.records import Attachment, Channel, Metadata

from orchestrator.run_log_mcap import MAGIC
from orchestrator.run_log_metadata import FORMAT

_RECORD_PREFIX = struct.Struct("<BQ")
_CHUNK_HEAD = struct.Struct("<QQQII")  # start, end, uncompressed size, crc, compression length
_MESSAGE_DATA = 2 + 4 + 8 + 8  # channel id, sequence, log time, publish time


class RunLogError(ValueError):
    """A file that is not a readable excosim run log; the message is one line."""


@dataclass
class RunFile:
    """What a run log holds.

    periods: the /period records in order (dicts as the campaign wrote them).
    metadata: record name -> key -> value (e.g. metadata["excosim.versions"]["numpy"]).
    attachments: name -> bytes ("scenario.toml", "fmus/<file name>").
    message_counts: topic -> number of messages read.
    finished: the run closed its log (an end record is present); termination and
    termination_message come from it (None if not finished).
    truncated: the file ends inside a record, lacks its footer or has a damaged chunk (a
    killed run); everything before that point was read.
    """

    path: Path
    periods: list[dict] = field(default_factory=list)
    metadata: dict[str, dict[str, str]] = field(default_factory=dict)
    attachments: dict[str, bytes] = field(default_factory=dict)
    message_counts: dict[str, int] = field(default_factory=dict)
    finished: bool = False
    termination: str | None = None
    termination_message: str | None = None
    truncated: bool = False

    @property
    def scenario(self) -> dict:
        """The resolved scenario the run used."""
        return json.loads(self.metadata["excosim.scenario"]["json"])

    @property
    def scenario_text(self) -> str:
        """The text of the scenario file the run was started with."""
        return self.attachments[self.metadata["excosim.run"]["scenario_attachment"]].decode()


def _decompress(compression: str, data: bytes, size: int) -> bytes:
    if compression == "zstd":
        return zstandard.ZstdDecompressor().decompress(data, max_output_size=size)
    if compression == "lz4":
        return lz4.frame.decompress(data)
    if compression == "":
        return data
    raise RunLogError(f"unsupported chunk compression {compression!r}")


class _Scan:
    def __init__(self, run: RunFile) -> None:
        self.run = run
        self.topics: dict[int, str] = {}

    def channel(self, body: bytes) -> None:
        channel = Channel.read(ReadDataStream(io.BytesIO(body)))
        self.topics[channel.id] = channel.topic

    def message(self, body: memoryview) -> None:
        (channel_id,) = struct.unpack_from("<H", body)
        topic = self.topics.get(channel_id, f"<channel {channel_id}>")
        self.run.message_counts[topic] = self.run.message_counts.get(topic, 0) + 1
        if topic == "/period":
            self.period(body[_MESSAGE_DATA:])

    def period(self, data: memoryview) -> None:
        try:
            self.run.periods.append(json.loads(bytes(data)))
        except ValueError:
            raise RunLogError(f"{self.run.path}: a /period message is not JSON") from None

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
        if len(records) != size or (crc != 0 and zlib.crc32(records) != crc):
            return False
        view = memoryview(records)
        if index is not None and self._indexed(view, index):
            for channel, offsets in index.items():
                topic = self.topics[channel]
                self.run.message_counts[topic] = self.run.message_counts.get(topic, 0)
                self.run.message_counts[topic] += len(offsets)
                if topic == "/period":
                    for offset in offsets.tolist():
                        (length,) = struct.unpack_from("<Q", view, offset + 1)
                        self.period(view[offset + 9 + _MESSAGE_DATA:offset + 9 + length])
            return True
        pos = 0
        while pos + _RECORD_PREFIX.size <= size:
            opcode, length = _RECORD_PREFIX.unpack_from(view, pos)
            inner = view[pos + 9:pos + 9 + length]
            if opcode == Opcode.MESSAGE:
                self.message(inner)
            elif opcode == Opcode.CHANNEL:
                self.channel(bytes(inner))
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


def _scan(path: Path, data: bytes) -> tuple[RunFile, bool]:
    """Every complete record of `data`; returns the run and whether the footer was reached.

    A chunk is read through the MessageIndex records after it only once a complete record
    follows them (so none of them is missing); otherwise by walking its records.
    """
    run = RunFile(path=path)
    scan = _Scan(run)
    view = memoryview(data)
    pos = len(MAGIC)
    chunk, index = None, {}
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
                return run, False
        if opcode == Opcode.FOOTER:
            return run, data[end:end + len(MAGIC)] == MAGIC
        if opcode == Opcode.CHUNK:
            chunk = body
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
    if chunk is not None:
        scan.chunk(chunk, None)
    return run, False


def read_run(path: str | Path, tolerant: bool = True) -> RunFile:
    """Read the run log at `path`. tolerant: a killed or truncated run gives what it holds
    (`truncated` True); otherwise such a file raises RunLogError. A file that is not MCAP or
    not an excosim run log raises RunLogError."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise RunLogError(f"cannot read {path}: {exc.strerror}") from None
    if not data.startswith(MAGIC):
        raise RunLogError(f"{path} is not an MCAP file (it does not start with the MCAP magic)")
    try:
        run, complete = _scan(path, data)
    except (struct.error, UnicodeDecodeError, ValueError, McapError) as exc:
        if isinstance(exc, RunLogError):
            raise
        reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise RunLogError(f"{path} is a damaged MCAP file: {reason}") from None
    if run.metadata.get("excosim.run", {}).get("format") != FORMAT:
        raise RunLogError(f"{path} is an MCAP file but not an excosim run log "
                          "(no excosim.run metadata record)")
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
