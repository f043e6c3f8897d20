"""The straightforward encoders that orchestrator.runlog replaced with faster ones, kept as the
references those must match byte for byte (tests/test_run_log_fast_paths.py): ChunkBuilder (one
structured field write per double, a join of slices in log-time order) and
encode_frame_transforms (/tf rows concatenated part by part) and sample_channels (the channel
layout worked out again every period). The lines these share with the new code are the parts
that did not change: kept whole here so that the reference does not lean on what it checks.
"""

from __future__ import annotations

import json
import struct
from collections import defaultdict
from dataclasses import dataclass

import numpy as np
from mcap.opcode import Opcode

from orchestrator.runlog.chunk import MESSAGE_HEADER
from orchestrator.runlog.samples import CheckedPeriod, _packed_tag, double_tag
from orchestrator.runlog.schemas import (
    CYLINDER_STATE,
    JOINT_STATE,
    PILE_BUCKET_STATE,
    SIGNAL_SAMPLE,
    cylinder_signals,
)
from orchestrator.runlog.units import signal_unit
from orchestrator.runlog.wire import doubles, field, rows, varint
from plant_models.plant import JOINTS

MESSAGE_HEADER_FIELDS = (
    ("opcode", "u1"), ("length", "<u8"), ("channel", "<u2"), ("sequence", "<u4"),
    ("log_time", "<u8"), ("publish_time", "<u8"),
)
_RECORD_PREFIX = struct.Struct("<BQ")


@dataclass(frozen=True)
class DoubleBatch:
    """Fixed-size messages of one channel, one per sample: payload = for each column j,
    `prefixes[j]` (constant bytes, e.g. a protobuf tag) then the float64 `values[:, j]`."""

    channel_id: int
    first_sequence: int
    prefixes: tuple[bytes, ...]
    values: np.ndarray  # (m, len(prefixes)) float64


@dataclass(frozen=True)
class SampleChannel:
    """One high-rate channel of a period, its values as an (m, k) matrix."""

    topic: str
    message: object
    metadata: dict[str, str]
    prefixes: tuple[bytes, ...]
    values: np.ndarray


class ChunkBuilder:
    """The uncompressed records of one chunk plus their message index.

    Messages may be added in any time order, in groups (a batch of sample rows, a run of
    transforms, single messages); `records()` writes them in log-time order (ties keep the
    order they were added in), because readers that go through a chunk in file order (and
    `mcap doctor`) expect log time never to go back inside a chunk.
    """

    def __init__(self) -> None:
        # Each group: (rows' log times (n,), rows' byte offsets in `data` (n,), rows' lengths
        # (n,), data, [(channel id, message offsets inside a row (n,))]). A row holds one
        # message, or one message per channel of a batch of samples taken at the same time.
        self._groups: list[tuple[np.ndarray, np.ndarray, np.ndarray, bytes | np.ndarray,
                                 list[tuple[int, np.ndarray]]]] = []
        self.size = 0
        self.start_time: int | None = None
        self.end_time = 0
        self.counts: dict[int, int] = defaultdict(int)
        self._built: tuple[bytes, dict[int, bytes]] | None = None

    def _add_group(self, times: np.ndarray, starts: np.ndarray, lengths: np.ndarray, data,
                   entries: list[tuple[int, np.ndarray]]) -> None:
        times = np.asarray(times, dtype=np.uint64)
        if len(times) == 0:
            return
        self._groups.append((times, np.asarray(starts, dtype=np.int64),
                             np.asarray(lengths, dtype=np.int64), data, entries))
        for channel_id, _ in entries:
            self.counts[channel_id] += len(times)
        low, high = int(times.min()), int(times.max())
        self.start_time = low if self.start_time is None else min(self.start_time, low)
        self.end_time = max(self.end_time, high)
        self.size += int(lengths.sum())
        self._built = None

    def add_batches(self, batches: list[DoubleBatch], log_time_ns: np.ndarray) -> None:
        """Messages of several channels at the same sample times `log_time_ns` (m,) uint64,
        interleaved sample by sample (one row per sample)."""
        m = len(log_time_ns)
        fields: list[tuple] = []
        for c, batch in enumerate(batches):
            if batch.values.shape != (m, len(batch.prefixes)):
                raise ValueError(f"batch for channel {batch.channel_id} has the wrong shape")
            fields += [(f"c{c}_{name}", kind) for name, kind in MESSAGE_HEADER_FIELDS]
            for j, prefix in enumerate(batch.prefixes):
                if prefix:
                    fields.append((f"c{c}_p{j}", "u1", (len(prefix),)))
                fields.append((f"c{c}_v{j}", "<f8"))
        dtype = np.dtype(fields)
        # Constant bytes (record headers, protobuf tags) once in a template row, copied to all.
        template = np.zeros(1, dtype=dtype)
        for c, batch in enumerate(batches):
            payload = sum(len(p) for p in batch.prefixes) + 8 * len(batch.prefixes)
            template[f"c{c}_opcode"] = Opcode.MESSAGE
            template[f"c{c}_length"] = MESSAGE_HEADER.size - 9 + payload
            template[f"c{c}_channel"] = batch.channel_id
            for j, prefix in enumerate(batch.prefixes):
                if prefix:
                    template[f"c{c}_p{j}"] = np.frombuffer(prefix, dtype=np.uint8)
        block = np.empty(m, dtype=dtype)
        block.view(np.uint8).reshape(m, -1)[:] = template.view(np.uint8)  # bytes: fast copy
        entries = []
        for c, batch in enumerate(batches):
            block[f"c{c}_sequence"] = batch.first_sequence + np.arange(m, dtype=np.uint32)
            block[f"c{c}_log_time"] = log_time_ns
            block[f"c{c}_publish_time"] = log_time_ns
            for j in range(len(batch.prefixes)):
                block[f"c{c}_v{j}"] = batch.values[:, j]
            within = np.full(m, dtype.fields[f"c{c}_opcode"][1], dtype=np.int64)
            entries.append((batch.channel_id, within))
        width = dtype.itemsize
        self._add_group(log_time_ns, width * np.arange(m, dtype=np.int64),
                        np.full(m, width, dtype=np.int64), block.view(np.uint8), entries)

    def add_message(self, channel_id: int, sequence: int, log_time_ns: int, data: bytes) -> None:
        """One message of any size."""
        header = MESSAGE_HEADER.pack(
            Opcode.MESSAGE, MESSAGE_HEADER.size - 9 + len(data), channel_id, sequence,
            log_time_ns, log_time_ns,
        )
        record = header + data
        self._add_group(np.array([log_time_ns], dtype=np.uint64), np.zeros(1, dtype=np.int64),
                        np.array([len(record)]), record,
                        [(channel_id, np.zeros(1, dtype=np.int64))])

    def add_grouped(self, channel_id: int, first_sequence: int, log_time_ns: np.ndarray,
                    groups) -> None:
        """Messages of one channel at times (n,) ns whose payloads come in groups of equal size,
        [(sample indices (n_g,), payloads (n_g, w_g) uint8)], together covering 0..n-1."""
        times = np.asarray(log_time_ns, dtype=np.uint64)
        n = len(times)
        head = np.empty(n, dtype=np.dtype(list(MESSAGE_HEADER_FIELDS)))
        head["opcode"] = Opcode.MESSAGE
        head["channel"] = channel_id
        head["sequence"] = first_sequence + np.arange(n, dtype=np.uint32)
        head["log_time"] = times
        head["publish_time"] = times
        for index, payload in groups:
            head["length"][index] = MESSAGE_HEADER.size - 9 + payload.shape[1]
        head_bytes = head.view(np.uint8).reshape(n, -1)
        data, starts = interleave(n, [(index, np.concatenate([head_bytes[index], payload], axis=1))
                                      for index, payload in groups])
        lengths = np.diff(np.append(starts, len(data)))
        self._add_group(times, starts, lengths, data, [(channel_id, np.zeros(n, dtype=np.int64))])

    def _build(self) -> tuple[bytes, dict[int, bytes]]:
        if self._built is not None:
            return self._built
        groups = self._groups
        times = np.concatenate([g[0] for g in groups])
        group = np.concatenate([np.full(len(g[0]), i) for i, g in enumerate(groups)])
        row = np.concatenate([np.arange(len(g[0])) for g in groups])
        starts = np.concatenate([g[1] for g in groups])
        lengths = np.concatenate([g[2] for g in groups])
        order = np.argsort(times, kind="stable")  # stable: ties keep the order of adding
        group, row, starts, lengths = group[order], row[order], starts[order], lengths[order]
        new_start = np.cumsum(lengths) - lengths  # of each sorted row, in the chunk
        # Consecutive rows of one group are copied as one slice of its data.
        first = np.flatnonzero(np.r_[True, (np.diff(group) != 0) | (np.diff(row) != 1)])
        last = np.r_[first[1:], len(row)] - 1
        views = [memoryview(g[3]) for g in groups]  # bytes or a flat uint8 array
        records = b"".join([views[g][b:e] for g, b, e in zip(
            group[first].tolist(), starts[first].tolist(),
            (starts[last] + lengths[last]).tolist(), strict=True)])
        # Where each group's rows went: sorted position -> chunk offset, back to (group, row).
        placed = np.empty(len(times), dtype=np.int64)
        placed[order] = new_start
        index: dict[int, list[tuple[np.ndarray, np.ndarray]]] = defaultdict(list)
        base = 0
        for g_times, _, _, _, entries in self._groups:
            rows_at = placed[base:base + len(g_times)]
            for channel_id, within in entries:
                index[channel_id].append((g_times, (rows_at + within).astype(np.uint64)))
            base += len(g_times)
        indexes = {}
        for channel_id, parts in index.items():
            t = np.concatenate([p[0] for p in parts])
            offsets = np.concatenate([p[1] for p in parts])
            o = np.lexsort((offsets, t))
            entries = np.stack([t[o], offsets[o]], axis=1).astype("<u8").tobytes()
            head = _RECORD_PREFIX.pack(Opcode.MESSAGE_INDEX, 6 + len(entries))
            indexes[channel_id] = head + struct.pack("<HI", channel_id, len(entries)) + entries
        self._built = (records, indexes)
        return self._built

    def records(self) -> bytes:
        """The chunk's records, in log-time order."""
        return self._build()[0] if self._groups else b""

    def message_indexes(self) -> dict[int, bytes]:
        """Channel id -> its MessageIndex record (entries sorted by log time)."""
        return self._build()[1] if self._groups else {}



def varint_digits(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Varints of non-negative integers (n,): digits (n, k) uint8, k the longest varint's
    length (row i's varint is digits[i, :lengths[i]]), and lengths (n,)."""
    v = np.asarray(values, dtype=np.uint64)
    # Only as many 7-bit groups as the largest value needs (timestamps: 5 of the 10).
    count = max(1, min(10, (int(v.max(initial=0)).bit_length() + 6) // 7))
    groups = np.arange(count, dtype=np.uint64)
    lengths = 1 + np.sum(v[:, None] >= (np.uint64(1) << (np.uint64(7) * groups[1:])), axis=1)
    digits = ((v[:, None] >> (np.uint64(7) * groups)) & np.uint64(0x7F)).astype(np.uint8)
    digits[np.arange(count)[None, :] < (lengths - 1)[:, None]] |= 0x80
    return digits, lengths.astype(np.int64)


def interleave(n: int, groups) -> tuple[bytes, np.ndarray]:
    """Rows of several equal-size groups [(row indices (n_g,), bytes (n_g, w_g)), ...] covering
    0..n-1, joined in row order. Returns (bytes, start offset of each row (n,))."""
    pieces: list[bytes] = [b""] * n
    lengths = np.zeros(n, dtype=np.int64)
    for index, data in groups:
        lengths[index] = data.shape[1]
        raw, width = data.tobytes(), data.shape[1]
        for k, i in enumerate(index.tolist()):
            pieces[i] = raw[k * width:(k + 1) * width]
    return b"".join(pieces), np.cumsum(lengths) - lengths


def encode_frame_transforms(transforms, log_time_ns: np.ndarray):
    """foxglove.FrameTransforms messages (serialized protobuf), one per sample, from
    `link_transforms` output and the samples' times (n,) ns (the transforms' timestamps).

    Returns groups [(sample indices, payloads (n_g, w_g) uint8)] of equal-size messages (sizes
    differ only through the timestamp varints); `interleave` joins them. Explicit zeros are
    written (valid protobuf) so every other part has a fixed size.
    """
    ns = np.asarray(log_time_ns, dtype=np.uint64)
    billion = np.uint64(1_000_000_000)
    second_digits, second_lengths = varint_digits(ns // billion)
    nano_digits, nano_lengths = varint_digits(ns % billion)
    kinds = second_lengths * _MAX_VARINT + nano_lengths
    fixed = [  # parent, child, translation and rotation of each transform, all samples
        rows(len(ns), [_string_field(2, parent) + _string_field(3, child),
                       b"\x22\x1b", doubles((1, 2, 3), translation),  # Vector3: 27 bytes
                       b"\x2a\x24", doubles((1, 2, 3, 4), rotation)])  # Quaternion: 36 bytes
        for parent, child, translation, rotation in transforms
    ]
    groups = []
    for kind in np.unique(kinds):
        index = np.flatnonzero(kinds == kind)
        n = len(index)
        stamp = rows(n, [b"\x08", second_digits[index, :kind // _MAX_VARINT],
                         b"\x10", nano_digits[index, :kind % _MAX_VARINT]])
        stamp = rows(n, [b"\x0a" + varint(stamp.shape[1]), stamp])  # FrameTransform.timestamp
        parts = []
        for transform in fixed:
            size = stamp.shape[1] + transform.shape[1]
            parts += [b"\x0a" + varint(size), stamp, transform[index]]  # .transforms
        groups.append((index, rows(n, parts)))
    return groups


_MAX_VARINT = 16


def _string_field(number: int, text: str) -> bytes:
    return field(number, text.encode())


def sample_channels(period: CheckedPeriod, times_s: np.ndarray) -> list[SampleChannel]:
    """The high-rate channels of a period with campaign times times_s (m,) s: /joints always;
    /cylinder/<joint> and /pile/bucket with the fields whose signals were measured; every other
    signal on /signals/<component> (the part of its name before the first dot)."""
    out = [SampleChannel("/joints", JOINT_STATE, {},
                         tuple(double_tag(n + 1) for n in range(len(JOINT_STATE.fields))),
                         np.column_stack([times_s, period.reference_rad, period.joints_rad]))]
    groups = [(f"/cylinder/{joint}", CYLINDER_STATE, cylinder_signals(joint))
              for joint in JOINTS]
    groups.append(("/pile/bucket", PILE_BUCKET_STATE, PILE_BUCKET_STATE.signals))
    signals, used = period.signals, set()
    for topic, message, sources in groups:
        mapping = {f: s for f, s in zip(message.fields, sources, strict=True) if s}
        fields = [f for f, s in mapping.items() if s in signals]
        if not fields:
            continue
        used.update(mapping[f] for f in fields)
        out.append(SampleChannel(
            topic, message, {"signals": json.dumps(mapping)},
            tuple(double_tag(message.number(f)) for f in ("t_s", *fields)),
            np.column_stack([times_s] + [signals[mapping[f]] for f in fields]),
        ))
    components: dict[str, list[str]] = {}
    for name in signals:
        if name not in used:
            components.setdefault(name.split(".", 1)[0] if "." in name else "plant",
                                  []).append(name)
    for component, names in components.items():
        packed = _packed_tag(SIGNAL_SAMPLE.number("values"), len(names))
        out.append(SampleChannel(
            f"/signals/{component}", SIGNAL_SAMPLE,
            {"names": json.dumps(names), "units": json.dumps([signal_unit(n) for n in names])},
            (double_tag(1), packed) + (b"",) * (len(names) - 1),
            np.column_stack([times_s] + [signals[n] for n in names]),
        ))
    return out

