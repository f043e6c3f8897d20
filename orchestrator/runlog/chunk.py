"""The records of one MCAP chunk, a whole batch of messages at a time.

Message records (https://mcap.dev/spec#message-op0x05): opcode 0x05, record length (u64),
channel id (u16), sequence (u32), log time and publish time (u64, ns), then the payload. The
message index of a chunk maps each channel to (log time, offset in the chunk's records) pairs.

Speed (a paper period: 11 channels x 1,400 samples, 1.3 MB of records): the rows are encoded
when the records are made, straight to their places, by `orchestrator.runlog.native` (rows.c:
one pass, the GIL free, so on the log's writer thread while the run goes on); the message
indexes come from the rows' places alone, before that. Large buffers are reused from chunk to
chunk (`BufferPool`). tests/run_log_reference.py builds the same bytes the plain way (the
tests' oracle).
"""

from __future__ import annotations

import struct
import threading
from collections import defaultdict
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from mcap.opcode import Opcode

from orchestrator.runlog import native

MESSAGE_HEADER = struct.Struct("<BQHIQQ")
_SEQUENCE_AT, _LOG_TIME_AT = 11, 15  # byte offsets in MESSAGE_HEADER; publish time follows
_RECORD_PREFIX = struct.Struct("<BQ")


@dataclass(frozen=True)
class DoubleBatch:
    """Fixed-size messages of one channel, one per sample: payload = for each column j,
    `prefixes[j]` (constant bytes, e.g. a protobuf tag) then the double `columns[j][i]`.
    Columns rather than an (m, k) matrix: each is copied once, straight into the rows."""

    channel_id: int
    first_sequence: int
    prefixes: tuple[bytes, ...]
    columns: tuple[np.ndarray, ...]  # len(prefixes) arrays (m,) of float64


@dataclass(frozen=True)
class _BatchLayout:
    """Where things go in a row of `add_batches`: width (bytes), the row's constant bytes, each
    batch's message header offset; for rows.c, the offsets of the sequence numbers and log
    times (one per batch) and of the doubles (all batches' columns in order)."""

    width: int
    template: np.ndarray  # (width,) uint8
    headers: tuple[int, ...]
    sequence_at: np.ndarray  # (batches,) int64
    time_at: np.ndarray  # (batches,) int64
    double_at: np.ndarray  # (doubles,) int64


@lru_cache(maxsize=64)  # the same channels every period: laid out once per run
def _batch_layout(batches: tuple[tuple[int, tuple[bytes, ...]], ...]) -> _BatchLayout:
    """The row layout of (channel id, prefixes) batches: each message's header then for each
    column its prefix and double."""
    row = bytearray()
    headers, double_at = [], []
    for channel_id, prefixes in batches:
        payload = sum(len(p) for p in prefixes) + 8 * len(prefixes)
        headers.append(len(row))
        row += MESSAGE_HEADER.pack(Opcode.MESSAGE, MESSAGE_HEADER.size - 9 + payload,
                                   channel_id, 0, 0, 0)
        for prefix in prefixes:
            row += prefix
            double_at.append(len(row))
            row += bytes(8)
    at = np.array(headers, dtype=np.int64)
    return _BatchLayout(len(row), np.frombuffer(bytes(row), dtype=np.uint8), tuple(headers),
                        at + _SEQUENCE_AT, at + _LOG_TIME_AT, np.array(double_at, dtype=np.int64))


class _SampleRows:
    """The rows of one `add_batches` call, kept as their values until the chunk's records are
    made: its rows.c `job` puts row i at byte at[i]. Holds copies, not
    the caller's arrays: the records may be made on another thread after the caller moved on."""

    def __init__(self, layout: _BatchLayout, batches: list[DoubleBatch],
                 times: np.ndarray) -> None:
        place: dict[int, int] = {}  # id of a column array -> its row in `values`
        arrays, column = [], []
        for batch in batches:
            for values in batch.columns:
                if id(values) not in place:  # e.g. the sample times, a column of every batch
                    place[id(values)] = len(arrays)
                    arrays.append(values)
                column.append(place[id(values)])
        self.layout = layout
        self.values = (np.stack(arrays).astype(np.float64, copy=False) if arrays  # (columns, m)
                       else np.empty((0, len(times))))
        self.column = np.array(column, dtype=np.int64)  # per double, its row in values
        self.first = np.array([batch.first_sequence for batch in batches], dtype=np.uint32)
        self.times = np.array(times, dtype=np.uint64)

    def job(self, records: np.ndarray, at: np.ndarray, keep: list) -> list[int]:
        """The rows.c job that writes these rows (`keep`: where arrays it points to are kept
        alive until it has run)."""
        layout, p = self.layout, native.pointer
        at = np.ascontiguousarray(at, dtype=np.int64)
        keep.append(at)
        return native.job(
            native.FILL_ROWS, p(records), p(at), len(self.times), layout.width,
            p(layout.template), p(self.times), len(self.first), p(layout.sequence_at),
            p(self.first), p(layout.time_at), len(self.column), p(layout.double_at),
            p(self.column), p(self.values))


class BufferPool:
    """Byte buffers that chunks hand back once written, for the next chunk to fill: each period
    needs buffers of about the same sizes (MBs), and fresh memory costs a page fault per 4 kB
    (about 1.6 us each here: 1 ms a paper period) where reused memory costs nothing."""

    def __init__(self) -> None:
        self._free: list[np.ndarray] = []
        self._lock = threading.Lock()  # chunks are built on one thread, written on another

    def take(self, size: int) -> np.ndarray:
        """A uint8 buffer of at least `size` bytes (the smallest free one that fits)."""
        with self._lock:
            fits = [i for i, buffer in enumerate(self._free) if len(buffer) >= size]
            if fits:
                return self._free.pop(min(fits, key=lambda i: len(self._free[i])))
        # Headroom for the next period's slightly longer one; untouched pages cost nothing.
        return np.empty(size + size // 4, dtype=np.uint8)

    def give_back(self, buffers: list[np.ndarray]) -> None:
        with self._lock:
            self._free.extend(buffers)


class ChunkBuilder:
    """The uncompressed records of one chunk plus their message index.

    Messages may be added in any time order, in groups (a batch of sample rows, a run of
    transforms, single messages); `records()` writes them in log-time order (ties keep the
    order they were added in), because readers that go through a chunk in file order (and
    `mcap doctor`) expect log time never to go back inside a chunk. With a `pool`, the large
    buffers come from it and go back to it at `release()` (after the chunk is written).
    Raises fmus.BuildError when rows.c cannot be had (orchestrator.runlog.native), here rather
    than on the thread that makes the records.
    """

    def __init__(self, pool: BufferPool | None = None) -> None:
        native.library()
        # Each group: (rows' log times (n,), row width w (bytes), data (one message record of
        # add_message, or an object with a rows.c job for its rows: _SampleRows, add_rows),
        # [(channel id, message offsets inside a row (n,))], whether the times never go back).
        # A row holds one message, or one message per channel of a batch of samples taken at
        # the same time.
        self._groups: list[tuple[np.ndarray, int, bytes | object,
                                 list[tuple[int, np.ndarray]], bool]] = []
        self.size = 0
        self.start_time: int | None = None
        self.end_time = 0
        self.counts: dict[int, int] = defaultdict(int)
        # The records buffer, each row's offset in it (n,) and the message indexes; then the
        # records themselves.
        self._placed: tuple[np.ndarray, np.ndarray, dict[int, bytes]] | None = None
        self._records: memoryview | None = None
        self._pool = pool
        self._taken: list[np.ndarray] = []

    def _buffer(self, size: int) -> np.ndarray:
        if self._pool is None:
            return np.empty(size, dtype=np.uint8)
        buffer = self._pool.take(size)
        self._taken.append(buffer)
        return buffer[:size]

    def release(self) -> None:
        """Hand the buffers back to the pool; the chunk's records are then no longer valid."""
        if self._pool is not None:
            self._pool.give_back(self._taken)
        # The groups point into the buffers handed back: nothing may rebuild from them.
        self._taken, self._placed, self._records, self._groups = [], None, None, []

    def _add_group(self, times: np.ndarray, width: int, data,
                   entries: list[tuple[int, np.ndarray]]) -> None:
        times = np.asarray(times, dtype=np.uint64)
        if len(times) == 0:
            return
        in_order = len(times) == 1 or bool(np.all(times[1:] >= times[:-1]))
        self._groups.append((times, width, data, entries, in_order))
        for channel_id, _ in entries:
            self.counts[channel_id] += len(times)
        low, high = int(times.min()), int(times.max())
        self.start_time = low if self.start_time is None else min(self.start_time, low)
        self.end_time = max(self.end_time, high)
        self.size += width * len(times)
        self._placed = self._records = None

    def add_batches(self, batches: list[DoubleBatch], log_time_ns: np.ndarray) -> None:
        """Messages of several channels at the same sample times `log_time_ns` (m,) uint64,
        interleaved sample by sample (one row per sample)."""
        m = len(log_time_ns)
        for batch in batches:
            if len(batch.columns) != len(batch.prefixes) or any(
                    np.shape(column) != (m,) for column in batch.columns):
                raise ValueError(f"batch for channel {batch.channel_id} has the wrong shape")
        if m == 0:
            return
        layout = _batch_layout(tuple((b.channel_id, tuple(b.prefixes)) for b in batches))
        rows = _SampleRows(layout, batches, log_time_ns)
        entries = [(batch.channel_id, np.full(m, header_at, dtype=np.int64))
                   for batch, header_at in zip(batches, layout.headers, strict=True)]
        self._add_group(rows.times, layout.width, rows, entries)

    def add_message(self, channel_id: int, sequence: int, log_time_ns: int, data: bytes) -> None:
        """One message of any size."""
        header = MESSAGE_HEADER.pack(
            Opcode.MESSAGE, MESSAGE_HEADER.size - 9 + len(data), channel_id, sequence,
            log_time_ns, log_time_ns,
        )
        record = header + data
        self._add_group(np.array([log_time_ns], dtype=np.uint64), len(record), record,
                        [(channel_id, np.zeros(1, dtype=np.int64))])

    def add_rows(self, channel_id: int, log_time_ns: np.ndarray, width: int, rows) -> None:
        """Message records of one channel at times (n,) ns, each `width` bytes, that the
        rows.c job `rows.job(records, at, keep)` writes (record i at byte at[i] of the records,
        a uint8 array) when the chunk's records are made, maybe on another thread: `rows`
        holds its own data. Used for /tf (scene.transform_records)."""
        times = np.asarray(log_time_ns, dtype=np.uint64)
        self._add_group(times, width, rows, [(channel_id, np.zeros(len(times), dtype=np.int64))])

    def _place(self) -> tuple[np.ndarray, np.ndarray, dict[int, bytes]]:
        """Where each row goes (log-time order) and the message indexes; the records buffer."""
        if self._placed is not None:
            return self._placed
        groups = self._groups
        times = np.concatenate([g[0] for g in groups])
        lengths = np.repeat([g[1] for g in groups], [len(g[0]) for g in groups])
        order = np.argsort(times, kind="stable")  # stable: ties keep the order of adding
        placed = np.empty(len(times), dtype=np.int64)  # each row's offset in the chunk
        placed[order] = np.cumsum(lengths[order]) - lengths[order]
        records = self._buffer(self.size)
        index: dict[int, list[tuple[np.ndarray, np.ndarray, bool]]] = defaultdict(list)
        base = 0
        for g_times, _, _, entries, in_order in groups:
            at = placed[base:base + len(g_times)]
            base += len(g_times)
            for channel_id, within in entries:
                index[channel_id].append((g_times, at + within, in_order))
        indexes = {}
        for channel_id, parts in index.items():
            if len(parts) == 1 and parts[0][2]:
                t, offsets, _ = parts[0]  # a group in time order keeps its order in the chunk
            else:
                t = np.concatenate([p[0] for p in parts])
                offsets = np.concatenate([p[1] for p in parts])
                # Records are in log-time order, so offset order is (log time, offset) order.
                o = np.argsort(offsets, kind="stable")
                t, offsets = t[o], offsets[o]
            entries = np.empty((len(t), 2), dtype="<u8")
            entries[:, 0], entries[:, 1] = t, offsets
            head = _RECORD_PREFIX.pack(Opcode.MESSAGE_INDEX, 6 + entries.nbytes)
            indexes[channel_id] = (int(offsets[0]), head + struct.pack(
                "<HI", channel_id, entries.nbytes) + entries.tobytes())
        # One order for every writer, whatever order messages were added in: the order the
        # channels first appear in the records (orchestrator.runlog.resume rebuilds it so).
        indexes = {channel_id: record for channel_id, (_, record)
                   in sorted(indexes.items(), key=lambda item: item[1][0])}
        self._placed = (records, placed, indexes)
        return self._placed

    def records(self) -> memoryview:
        """The chunk's records, in log-time order (a bytes-like view). Once
        `message_indexes` has been called, this may be called on another thread (nothing is
        added meanwhile): the rows are written here, all in one call of rows.c with the GIL
        free."""
        if not self._groups:
            return memoryview(b"")
        if self._records is None:
            records, placed, _ = self._place()
            base, jobs, keep = 0, [], []
            for g_times, width, data, _, _ in self._groups:
                at = placed[base:base + len(g_times)]
                base += len(g_times)
                if int(at.max()) + width > len(records):
                    raise RuntimeError("a chunk's rows do not fit its records (a bug)")
                if hasattr(data, "job"):  # _SampleRows, or rows of add_rows
                    jobs.append(data.job(records, at, keep))
                else:  # one message record (add_message)
                    rows = np.frombuffer(data, dtype=np.uint8)
                    keep.append(rows)
                    jobs.append(native.job(native.PLACE_ROWS, native.pointer(records),
                                           native.pointer(at), len(at), width,
                                           native.pointer(rows)))
            native.write(jobs)
            self._records = memoryview(records)
        return self._records

    def message_indexes(self) -> dict[int, bytes]:
        """Channel id -> its MessageIndex record (entries sorted by log time)."""
        return self._place()[2] if self._groups else {}

