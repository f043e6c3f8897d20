"""A run log's chunks opened with bounds: every reader of ours (the reader, resume, close of a
dead run's log, `excosim log repair`) inflates a chunk here, never with an unbounded call.

The bound, MAX_CHUNK_BYTES = 256 MiB uncompressed: a chunk of ours holds one period. A paper
period is 1.4 MB (1 272 samples of 1.1 kB at 100 Hz), a lab period 10.5 MB (12 942 samples of
0.8 kB at 1 kHz); the longest period a scenario may plan is 120 s (MAX_PERIOD_S,
orchestrator.scenario.sanity), which at 1 kHz and 1.1 kB a sample is 132 MB. 256 MiB is twice
that, and small enough that a file crafted to declare more (2^40 bytes) or to inflate to more
than it declares (a bomb: a few KB of lz4 that make GBs) is refused at once, with one line,
without the memory or the minutes it would take.

What is refused (ChunkRefused, one line): a chunk that declares more than the bound, whose zstd
frame declares another size than the chunk, or whose data inflate to more than the chunk
declares. The decompressors are never asked for more than the declared size plus one byte
(zstandard's stream reader, lz4.frame's max_length), so nothing larger is ever allocated.
What is damaged (a reason, the chunk left unread): data that are not a valid stream or make
fewer bytes than declared ("chunk compression"), and records whose CRC-32 is not the one the
writer stored ("chunk CRC").
"""

from __future__ import annotations

import io
import struct
import zlib

import lz4.frame
import zstandard

MAX_CHUNK_BYTES = 256 << 20
CHUNK_HEAD = struct.Struct("<QQQII")  # start, end, uncompressed size, crc, compression length


class ChunkRefused(ValueError):
    """A chunk that would inflate beyond the bound or beyond its declared size (one line)."""


def _mib(n: int) -> str:
    """n bytes, with the binary unit that fits from MiB up ("1099511627776 bytes (1 TiB)")."""
    if n < 1 << 20:
        return f"{n} bytes"
    power, unit = max((p, u) for p, u in ((20, "MiB"), (30, "GiB"), (40, "TiB"), (50, "PiB"))
                      if n >= 1 << p)
    return f"{n} bytes ({n / (1 << power):.4g} {unit})"


def head(body: memoryview) -> tuple[str, int, int, memoryview]:
    """(compression, declared uncompressed size, stored CRC, compressed data) of a Chunk
    record's body; struct.error or ValueError when it is too short for what it says."""
    _, _, size, crc, name_length = CHUNK_HEAD.unpack_from(body)
    at = CHUNK_HEAD.size
    compression = bytes(body[at:at + name_length]).decode()
    (length,) = struct.unpack_from("<Q", body, at + name_length)
    at += name_length + 8
    if at + length > len(body):
        raise ValueError("a chunk's data run past its record")
    return compression, size, crc, body[at:at + length]


def inflate(compression: str, data: bytes | memoryview, size: int) -> bytes | None:
    """The chunk's records, exactly `size` bytes; None when `data` is not a valid stream or
    makes fewer bytes (damaged). ChunkRefused when `size` exceeds MAX_CHUNK_BYTES or the data
    would make more than `size` bytes (at most size + 1 bytes are ever made)."""
    if size > MAX_CHUNK_BYTES:
        raise ChunkRefused(f"declares {_mib(size)} uncompressed, more than the "
                           f"{MAX_CHUNK_BYTES >> 20} MiB a chunk may hold (a period of a run "
                           "is 1-130 MB)")
    if compression == "zstd":
        out = _zstd(bytes(data), size)
    elif compression == "lz4":
        out = _lz4(bytes(data), size)
    elif compression == "":
        out = bytes(data)
    else:
        raise ChunkRefused(f"has an unsupported compression {compression!r}")
    if out is not None and len(out) > size:
        raise ChunkRefused(f"inflates to more than the {_mib(size)} it declares")
    return out if out is not None and len(out) == size else None


def _zstd(data: bytes, size: int) -> bytes | None:
    try:
        declared = zstandard.get_frame_parameters(data).content_size
    except zstandard.ZstdError:
        return None
    if declared != zstandard.CONTENTSIZE_UNKNOWN and declared > size:
        raise ChunkRefused(f"holds a zstd frame that declares {_mib(declared)}, more than "
                           f"the {_mib(size)} the chunk declares")
    reader = zstandard.ZstdDecompressor().stream_reader(io.BytesIO(data),
                                                        read_across_frames=True)
    parts, made = [], 0
    try:
        while made <= size:
            part = reader.read(size + 1 - made)
            if not part:
                break
            parts.append(part)
            made += len(part)
    except zstandard.ZstdError:
        return None
    return parts[0] if len(parts) == 1 else b"".join(parts)


def _lz4(data: bytes, size: int) -> bytes | None:
    decompressor = lz4.frame.LZ4FrameDecompressor()
    try:
        out = decompressor.decompress(data, max_length=size + 1)
        if len(out) == size and not decompressor.eof:  # the frame's end not read yet
            out += decompressor.decompress(b"", max_length=1)
    except RuntimeError:
        return None
    if len(out) == size and not decompressor.eof:
        return None  # the frame is cut short
    return out


def records(body: memoryview) -> tuple[bytes | None, str | None]:
    """(the chunk's records, None) or (None, why it is damaged: "chunk compression", "chunk
    CRC") for the body of a Chunk record; ChunkRefused as `inflate`."""
    try:
        compression, size, crc, data = head(body)
    except (struct.error, ValueError, UnicodeDecodeError):
        return None, "chunk header"
    return checked(compression, data, size, crc)


def checked(compression: str, data: bytes | memoryview, size: int, crc: int
            ) -> tuple[bytes | None, str | None]:
    """`records` of a chunk given by its fields (e.g. an mcap.records.Chunk's)."""
    out = inflate(compression, data, size)
    if out is None:
        return None, "chunk compression"
    if crc != 0 and zlib.crc32(out) != crc:
        return None, "chunk CRC"
    return out, None
