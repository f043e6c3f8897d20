"""Test helper: a run log's records edited one at a time, the rest of the file as it was.

The file is taken apart into its top-level records (a killed run's file: the data section up to
a partly written chunk, kept as it is at the end). A record inside a chunk (/period, /resume) is
changed by making the chunk again: its records, zstd, the CRC and sizes, the message indexes
after it. A top-level record (channel, metadata) is replaced, repeated or left out as bytes
made with the `mcap` package's own record classes. Everything the reader checks on a record's
framing stays right, so what is tested is what the commands make of the records' content.
"""

from __future__ import annotations

import io
import json
import math
import struct
import zlib
from typing import Any

import zstandard
from mcap.data_stream import ReadDataStream, RecordBuilder
from mcap.opcode import Opcode
from mcap.records import Channel, Metadata

from orchestrator.runlog.inflate import head
from orchestrator.runlog.resume import message_indexes

MAGIC = b"\x89MCAP0\r\n"
PREFIX = struct.Struct("<BQ")


class LogParts:
    """The top-level records of a run log (`records`: [opcode, bytes of the whole record]) and
    the bytes after the last whole one (`tail`)."""

    def __init__(self, data: bytes) -> None:
        self.records: list[list[Any]] = []
        pos = len(MAGIC)
        while pos + PREFIX.size <= len(data):
            opcode, length = PREFIX.unpack_from(data, pos)
            end = pos + PREFIX.size + length
            if end > len(data):
                break
            self.records.append([opcode, data[pos:end]])
            pos = end
        self.tail = data[pos:]

    def bytes(self) -> bytes:
        return MAGIC + b"".join(record for _, record in self.records) + self.tail

    def channels(self) -> list[tuple[int, Channel]]:
        """(record index, Channel) of the top-level channel records."""
        return [(i, Channel.read(_body(record))) for i, (opcode, record)
                in enumerate(self.records) if opcode == Opcode.CHANNEL]

    def metadata(self) -> list[tuple[int, Metadata]]:
        return [(i, Metadata.read(_body(record))) for i, (opcode, record)
                in enumerate(self.records) if opcode == Opcode.METADATA]

    def topic_id(self, topic: str) -> int:
        return next(c.id for _, c in self.channels() if c.topic == topic)

    def message(self, topic: str, nth: int = 0) -> bytes:
        """The data of the nth message on `topic` in the chunks."""
        channel = self.topic_id(topic)
        found = [data for _, inner in self._chunks() for data in _messages(inner, channel)]
        return found[nth]

    def replace_message(self, topic: str, data: bytes, nth: int = 0) -> None:
        """The nth message on `topic` gets `data` (its chunk and indexes made again)."""
        channel, seen = self.topic_id(topic), 0
        for index, inner in self._chunks():
            count = len(_messages(inner, channel))
            if seen + count > nth:
                self._rewrite_chunk(index, _set_message(inner, channel, nth - seen, data))
                return
            seen += count
        raise IndexError(f"no message {nth} on {topic}")

    def _chunks(self) -> list[tuple[int, bytes]]:
        out = []
        for i, (opcode, record) in enumerate(self.records):
            if opcode == Opcode.CHUNK:
                compression, size, _, data = head(memoryview(record)[PREFIX.size:])
                assert compression == "zstd"
                out.append((i, zstandard.ZstdDecompressor().decompress(bytes(data),
                                                                       max_output_size=size)))
        return out

    def _rewrite_chunk(self, index: int, inner: bytes) -> None:
        record = self.records[index][1]
        start, end = struct.unpack_from("<QQ", record, PREFIX.size)
        packed = zstandard.ZstdCompressor().compress(inner)
        body = struct.pack("<QQQI", start, end, len(inner), zlib.crc32(inner))
        body += struct.pack("<I", 4) + b"zstd" + struct.pack("<Q", len(packed)) + packed
        self.records[index][1] = PREFIX.pack(Opcode.CHUNK, len(body)) + body
        after = index + 1
        while after < len(self.records) and self.records[after][0] == Opcode.MESSAGE_INDEX:
            del self.records[after]
        indexes = message_indexes(inner)
        pos = 0
        while pos < len(indexes):
            _, length = PREFIX.unpack_from(indexes, pos)
            self.records.insert(after, [Opcode.MESSAGE_INDEX,
                                        indexes[pos:pos + PREFIX.size + length]])
            after += 1
            pos += PREFIX.size + length


def _body(record: bytes) -> ReadDataStream:
    return ReadDataStream(io.BytesIO(record[PREFIX.size:]))


def _inner_records(inner: bytes) -> list[tuple[int, int, int]]:
    out, pos = [], 0
    while pos + PREFIX.size <= len(inner):
        opcode, length = PREFIX.unpack_from(inner, pos)
        out.append((opcode, pos, pos + PREFIX.size + length))
        pos += PREFIX.size + length
    return out


def _messages(inner: bytes, channel: int) -> list[bytes]:
    return [inner[s + PREFIX.size + 22:e] for opcode, s, e in _inner_records(inner)
            if opcode == Opcode.MESSAGE
            and struct.unpack_from("<H", inner, s + PREFIX.size)[0] == channel]


def _set_message(inner: bytes, channel: int, nth: int, data: bytes) -> bytes:
    seen = 0
    for opcode, s, e in _inner_records(inner):
        if opcode == Opcode.MESSAGE and struct.unpack_from("<H", inner, s + PREFIX.size)[0] \
                == channel:
            if seen == nth:
                head_ = inner[s + PREFIX.size:s + PREFIX.size + 22]
                record = PREFIX.pack(Opcode.MESSAGE, 22 + len(data)) + head_ + data
                return inner[:s] + record + inner[e:]
            seen += 1
    raise IndexError(nth)


def record_bytes(record) -> bytes:
    """An `mcap.records` record as bytes (opcode, length, body)."""
    builder = RecordBuilder()
    record.write(builder)
    return builder.end()


# ---- JSON texts changed at one place -----------------------------------------------------------

def paths(value: Any, prefix: tuple = ()) -> list[tuple]:
    """Every path into a JSON value (keys and list indexes), the root () first."""
    out = [prefix]
    if isinstance(value, dict):
        for key, item in value.items():
            out += paths(item, (*prefix, key))
    elif isinstance(value, list):
        for i, item in enumerate(value):
            out += paths(item, (*prefix, i))
    return out


# Raw JSON texts a value is replaced with: numbers beyond a double, NaN, nesting past Python's
# parser and nesting it parses but that anything recursing over it would not survive.
RAW = {"nan": "NaN", "inf": "Infinity", "1e400": "1e400", "deep": "[" * 5000 + "]" * 5000,
       "900 deep": "[" * 900 + "]" * 900, "big int": str(2 ** 70)}


def edited(text: str, path: tuple, how: str, value: Any) -> bytes:
    """The JSON `text` with the value at `path` set ("set": `value`, or a RAW token when `value`
    names one), scaled ("scale": a number times `value`) or removed ("delete")."""
    data = json.loads(text)
    marker = "\u0000raw\u0000"
    if not path:
        new = marker if how == "set" and value in RAW else None if how == "delete" else value
        out = json.dumps(new)
    else:
        *parents, last = path
        table = data
        for key in parents:
            table = table[key]
        if how == "delete":
            del table[last]
        elif how == "scale":
            old = table[last]
            table[last] = old * value if isinstance(old, int | float) and \
                not isinstance(old, bool) and math.isfinite(old * value) else old
        else:
            table[last] = marker if isinstance(value, str) and value in RAW else value
        out = json.dumps(data)
    if marker in out or json.dumps(marker) in out:
        out = out.replace(json.dumps(marker), RAW[value])
    return out.encode()
