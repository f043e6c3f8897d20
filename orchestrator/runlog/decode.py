"""Decode the numeric channels of a run log into numpy arrays, from the schemas stored in the file.

A reviewer may hold only the file, so field names and numbers come from each channel's protobuf
schema (a FileDescriptorSet), not from this version's `orchestrator.runlog.schemas`. Only
double fields are decoded (the run log's high-rate messages hold nothing else); a message of
another kind (e.g. foxglove.SceneUpdate) is not a numeric channel.

Why a decoder of our own: a campaign logs about 13k samples per channel; protobuf's Python
objects cost a few us each. Messages of one channel that share a byte layout (the writer
encodes a whole period with one layout) are decoded as one numpy array; any other message
is parsed field by field.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from google.protobuf import descriptor_pb2
from google.protobuf.message import DecodeError as ProtobufDecodeError

_DOUBLE = descriptor_pb2.FieldDescriptorProto.TYPE_DOUBLE
_REPEATED = descriptor_pb2.FieldDescriptorProto.LABEL_REPEATED


class DecodeError(ValueError):
    """A message or schema that is not what a numeric run-log channel holds."""


@dataclass(frozen=True)
class NumericSchema:
    """The double fields of a protobuf message: number -> name, and which are repeated."""

    name: str
    names: dict[int, str]
    repeated: frozenset[int]


def numeric_schema(name: str, data: bytes) -> NumericSchema:
    """The double fields of message `name` (e.g. "excosim.JointState") in the serialized
    FileDescriptorSet `data`; DecodeError if it is absent or has a field of another type."""
    files = descriptor_pb2.FileDescriptorSet.FromString(data)
    for file in files.file:
        for message in file.message_type:
            if f"{file.package}.{message.name}".lstrip(".") != name:
                continue
            names, repeated = {}, set()
            for field in message.field:
                if field.type != _DOUBLE:
                    raise DecodeError(f"{name}.{field.name} is not a double field")
                names[field.number] = field.name
                if field.label == _REPEATED:
                    repeated.add(field.number)
            return NumericSchema(name, names, frozenset(repeated))
    raise DecodeError(f"schema data does not define message {name}")


def is_numeric(schema: Any) -> bool:
    """Whether an MCAP schema record (None: none) is a protobuf message of doubles only, which
    `numeric_schema` and `decode` read."""
    if schema is None or schema.encoding != "protobuf":
        return False
    try:
        numeric_schema(schema.name, schema.data)
    except (DecodeError, ProtobufDecodeError):
        return False
    return True


def _varint(data: bytes, at: int) -> tuple[int, int]:
    value, shift = 0, 0
    while True:
        if at >= len(data):
            raise DecodeError("message ends inside a varint")
        byte = data[at]
        value |= (byte & 0x7F) << shift
        at += 1
        if byte < 0x80:
            return value, at
        shift += 7


def _layout(data: bytes) -> list[tuple[int, int, int]]:
    """(field number, offset of its first double, number of doubles) per field of a message
    of doubles, in byte order; DecodeError for any other wire type."""
    out, at = [], 0
    while at < len(data):
        key, at = _varint(data, at)
        number, wire = key >> 3, key & 7
        if wire == 1:
            out.append((number, at, 1))
            at += 8
        elif wire == 2:
            length, at = _varint(data, at)
            if length % 8:
                raise DecodeError(f"field {number}: packed length {length} is not 8 * n")
            out.append((number, at, length // 8))
            at += length
        else:
            raise DecodeError(f"field {number} has wire type {wire}, not a double")
        if at > len(data):
            raise DecodeError("message ends inside a field")
    return out


def _fields(schema: NumericSchema, layout: list[tuple[int, int, int]]) -> dict[int, list]:
    by_number: dict[int, list] = {}
    for number, at, count in layout:
        if number not in schema.names:
            continue  # a field added after this reader: skip it, as protobuf does
        by_number.setdefault(number, []).append((at, count))
    return by_number


def decode(schema: NumericSchema, payloads: list[bytes]) -> dict[str, np.ndarray]:
    """Field name -> values of n messages: scalar fields (n,) with NaN where a message lacks
    the field; repeated fields (n, k) when every message has k values, else an object array
    of (k_i,) arrays. Fields no message has are left out."""
    n = len(payloads)
    scalars: dict[int, np.ndarray] = {}
    repeated: dict[int, list] = {}
    groups: dict[int, list[int]] = {}
    for i, payload in enumerate(payloads):
        groups.setdefault(len(payload), []).append(i)
    for length, rows in groups.items():
        block = np.frombuffer(b"".join(payloads[i] for i in rows), dtype=np.uint8)
        block = block.reshape(len(rows), length)
        layout = _layout(payloads[rows[0]])
        same = _same_tags(block, layout)
        rows_arr = np.asarray(rows)
        if not same:
            for i in rows:
                _decode_one(schema, payloads[i], i, n, scalars, repeated)
            continue
        for number, parts in _fields(schema, layout).items():
            values = np.concatenate(
                [block[:, at:at + 8 * count].copy().view("<f8") for at, count in parts], axis=1)
            if number in schema.repeated:
                for row, value in zip(rows, values, strict=True):
                    repeated.setdefault(number, [None] * n)[row] = value
            else:
                scalars.setdefault(number, np.full(n, np.nan))[rows_arr] = values[:, -1]
    out = {schema.names[number]: values for number, values in sorted(scalars.items())}
    for number, values in sorted(repeated.items()):
        values = [np.empty(0) if v is None else v for v in values]
        sizes = {v.size for v in values}
        if len(sizes) == 1:
            out[schema.names[number]] = np.vstack(values) if values else np.empty((0, 0))
        else:
            column = np.empty(n, dtype=object)
            column[:] = values
            out[schema.names[number]] = column
    return out


def _same_tags(block: np.ndarray, layout: list[tuple[int, int, int]]) -> bool:
    """Whether every row of `block` has the first row's bytes outside the double values."""
    mask = np.ones(block.shape[1], dtype=bool)
    for _, at, count in layout:
        mask[at:at + 8 * count] = False
    tags = block[:, mask]
    return bool(np.all(tags == tags[:1]))


def _decode_one(schema: NumericSchema, payload: bytes, row: int, n: int,
                scalars: dict[int, np.ndarray], repeated: dict[int, list]) -> None:
    for number, parts in _fields(schema, _layout(payload)).items():
        values = np.concatenate([np.frombuffer(payload, "<f8", count, at)
                                 for at, count in parts])
        if number in schema.repeated:
            repeated.setdefault(number, [None] * n)[row] = values
        elif values.size:
            scalars.setdefault(number, np.full(n, np.nan))[row] = values[-1]
