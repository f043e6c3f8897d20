"""The records of one MCAP chunk, built with numpy a whole batch of messages at a time.

Message records (https://mcap.dev/spec#message-op0x05): opcode 0x05, record length (u64),
channel id (u16), sequence (u32), log time and publish time (u64, ns), then the payload. The
message index of a chunk maps each channel to (log time, offset in the chunk's records) pairs.
"""

from __future__ import annotations

import struct
from collections import defaultdict
from dataclasses import dataclass

import numpy as np
from mcap.opcode import Opcode

from orchestrator.runlog.wire import interleave

MESSAGE_HEADER = struct.Struct("<BQHIQQ")
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


class ChunkBuilder:
    """The uncompressed records of one chunk plus their message index."""

    def __init__(self) -> None:
        self._parts: list[bytes | np.ndarray] = []
        self.size = 0
        self._index: dict[int, list[tuple[np.ndarray, np.ndarray]]] = defaultdict(list)
        self._singles: dict[int, tuple[list[int], list[int]]] = defaultdict(lambda: ([], []))
        self.start_time: int | None = None
        self.end_time = 0
        self.counts: dict[int, int] = defaultdict(int)

    def _note(self, channel_id: int, times: np.ndarray, offsets: np.ndarray) -> None:
        self._index[channel_id].append((times, offsets))
        self.counts[channel_id] += len(times)
        low, high = int(times.min()), int(times.max())
        self.start_time = low if self.start_time is None else min(self.start_time, low)
        self.end_time = max(self.end_time, high)

    def add_batches(self, batches: list[DoubleBatch], log_time_ns: np.ndarray) -> None:
        """Messages of several channels at the same sample times `log_time_ns` (m,) uint64,
        interleaved sample by sample so the chunk stays in log-time order."""
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
        for c, batch in enumerate(batches):
            block[f"c{c}_sequence"] = batch.first_sequence + np.arange(m, dtype=np.uint32)
            block[f"c{c}_log_time"] = log_time_ns
            block[f"c{c}_publish_time"] = log_time_ns
            for j in range(len(batch.prefixes)):
                block[f"c{c}_v{j}"] = batch.values[:, j]
            start = self.size + dtype.fields[f"c{c}_opcode"][1]
            offsets = start + dtype.itemsize * np.arange(m, dtype=np.uint64)
            self._note(batch.channel_id, log_time_ns, offsets)
        data = block.view(np.uint8)
        self._parts.append(data)
        self.size += data.nbytes

    def add_message(self, channel_id: int, sequence: int, log_time_ns: int, data: bytes) -> None:
        """One message of any size."""
        header = MESSAGE_HEADER.pack(
            Opcode.MESSAGE, MESSAGE_HEADER.size - 9 + len(data), channel_id, sequence,
            log_time_ns, log_time_ns,
        )
        times, offsets = self._singles[channel_id]
        times.append(log_time_ns)
        offsets.append(self.size)
        self.counts[channel_id] += 1
        self.start_time = log_time_ns if self.start_time is None else min(self.start_time,
                                                                          log_time_ns)
        self.end_time = max(self.end_time, log_time_ns)
        self._parts += [header, data]
        self.size += len(header) + len(data)

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
        self._note(channel_id, times, self.size + starts.astype(np.uint64))
        self._parts.append(data)
        self.size += len(data)

    def records(self) -> bytes:
        return b"".join(self._parts)

    def message_indexes(self) -> dict[int, bytes]:
        """Channel id -> its MessageIndex record (entries sorted by log time)."""
        out = {}
        for channel_id, (times, offsets) in self._singles.items():
            self._index[channel_id].append((np.array(times, dtype=np.uint64),
                                            np.array(offsets, dtype=np.uint64)))
        self._singles.clear()
        for channel_id, pieces in self._index.items():
            times = np.concatenate([t for t, _ in pieces])
            offsets = np.concatenate([o for _, o in pieces])
            order = np.argsort(times, kind="stable")
            entries = np.stack([times[order], offsets[order]], axis=1).astype("<u8").tobytes()
            head = _RECORD_PREFIX.pack(Opcode.MESSAGE_INDEX, 6 + len(entries))
            out[channel_id] = head + struct.pack("<HI", channel_id, len(entries)) + entries
        return out
