"""Byte-level functions for encoding many protobuf messages or MCAP records at once with numpy.

Rows of bytes are (n, w) uint8 arrays: row i is message i (the pile scene's point lists, the
rows' constant parts; rows.c writes the sample and /tf records themselves). Protobuf wire format: https://protobuf.dev/programming-guides/encoding/
"""

from __future__ import annotations

import numpy as np

_SMALL_VARINTS = [bytes((value,)) for value in range(0x80)]


def varint(value: int) -> bytes:
    """Protobuf base-128 varint of a non-negative integer."""
    if value < 0x80:
        return _SMALL_VARINTS[value]
    out = bytearray()
    while value > 0x7F:
        out.append((value & 0x7F) | 0x80)
        value >>= 7
    out.append(value)
    return bytes(out)


def rows(n: int, segments) -> np.ndarray:
    """(n, w) uint8: each row the concatenation of `segments`, each either bytes (the same in
    every row) or an (n, k) uint8 array."""
    parts = [np.broadcast_to(np.frombuffer(s, dtype=np.uint8), (n, len(s)))
             if isinstance(s, bytes) else s for s in segments]
    return np.concatenate(parts, axis=1)


def doubles(numbers, values: np.ndarray) -> np.ndarray:
    """(n, 9k) uint8: protobuf double fields `numbers` (k) with values (n, k), zeros included."""
    values = np.ascontiguousarray(values, dtype="<f8")
    n, k = values.shape
    out = np.empty((n, k, 9), dtype=np.uint8)
    out[:, :, 0] = [number << 3 | 1 for number in numbers]  # tag: field number, type fixed64
    out[:, :, 1:] = values.view(np.uint8).reshape(n, k, 8)
    return out.reshape(n, 9 * k)


def field(number: int, payload: bytes) -> bytes:
    """A protobuf length-delimited field (message, string, bytes or packed values)."""
    return bytes([number << 3 | 2]) + varint(len(payload)) + payload


