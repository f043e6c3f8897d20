"""Byte-level functions for encoding many protobuf messages or MCAP records at once with numpy.

Rows of bytes are (n, w) uint8 arrays: row i is message i. Messages whose sizes differ (only
through varints, e.g. timestamps) are encoded in groups of equal size (ChunkBuilder.add_grouped
puts them in order). Protobuf wire format: https://protobuf.dev/programming-guides/encoding/
"""

from __future__ import annotations

import numpy as np

_SMALL_VARINTS = [bytes((value,)) for value in range(0x80)]
_MAX_VARINT_BYTES = 10  # a 64-bit value needs at most 10 groups of 7 bits


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


def varint_digits(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Varints of non-negative integers (n,): digits (n, k) uint8, k the longest varint's
    length (row i's varint is digits[i, :lengths[i]]), and lengths (n,)."""
    v = np.asarray(values, dtype=np.uint64)
    # Only as many 7-bit groups as the largest value needs (timestamps: 5 of the 10).
    count = max(1, min(_MAX_VARINT_BYTES, (int(v.max(initial=0)).bit_length() + 6) // 7))
    groups = np.arange(count, dtype=np.uint64)
    lengths = 1 + np.sum(v[:, None] >= (np.uint64(1) << (np.uint64(7) * groups[1:])), axis=1)
    digits = ((v[:, None] >> (np.uint64(7) * groups)) & np.uint64(0x7F)).astype(np.uint8)
    digits[np.arange(count)[None, :] < (lengths - 1)[:, None]] |= 0x80
    return digits, lengths.astype(np.int64)


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


def strided(block: np.ndarray, offset: int, dtype: str, shape: tuple, strides: tuple
            ) -> np.ndarray:
    """A writable view of the bytes of `block` (a uint8 array) as `dtype` at byte `offset` with
    byte `strides`: one numpy call writes a field of every row (or several equally spaced
    fields). Such views are unaligned; numpy copies into them about as fast as aligned ones."""
    return np.ndarray(shape, dtype=dtype, buffer=block, offset=offset, strides=strides)
