"""A small MCAP writer that writes whole chunks built with numpy (`orchestrator.runlog.chunk`).

Why not the foxglove SDK or `mcap.writer.Writer`: both take one Python call per message (about
1 us in the SDK, 6 us in `mcap`, measured here), and a campaign logs about 260k high-rate
messages in a run that must take about 2.5 s, of which logging may take a tenth; a whole
period's messages built as numpy arrays cost a few ns each (bench/logging.py). Records other
than messages reuse `mcap.records`, so their byte layout is the `mcap` package's own.
Format: https://mcap.dev/spec

Layout written: magic, Header, then Schema/Channel/Metadata/Attachment records and Chunks (each
followed by its MessageIndex records) in the data section, in the order they are added; at
`finish` DataEnd, the summary (schemas, channels, statistics, chunk/attachment/metadata indexes,
summary offsets), Footer and magic. `flush` pushes everything to the operating system (and
optionally to the disk), so a process killed after a flush leaves a file a streaming reader
reads up to that point.

With `background`, the file work (compressing chunks, CRCs, writes, flushes)
runs in order on the writer's own thread (`orchestrator.runlog.write_behind`): each call
encodes what it adds and hands the bytes over; `flush(wait=True)` and `finish` wait for the
thread. Ids, sequence numbers and the schema and channel lists are the caller's thread's.
"""

from __future__ import annotations

import io
import os
import struct
import zlib
from collections import defaultdict
from collections.abc import Callable
from typing import BinaryIO

import zstandard
from mcap.data_stream import ReadDataStream, RecordBuilder
from mcap.opcode import Opcode
from mcap.records import (
    Attachment,
    AttachmentIndex,
    Channel,
    ChunkIndex,
    DataEnd,
    Footer,
    Header,
    Metadata,
    MetadataIndex,
    Schema,
    Statistics,
    SummaryOffset,
)

from orchestrator.runlog.chunk import BufferPool, ChunkBuilder
from orchestrator.runlog.write_behind import WriteBehind

MAGIC = b"\x89MCAP0\r\n"
_RECORD_PREFIX = struct.Struct("<BQ")


class McapChunkWriter:
    """Writes an MCAP file to `stream` (opened for binary writing; the writer closes it at
    `finish`). `library` goes in the Header; chunks are zstd-compressed at `compression_level`.
    background: do the file work on a thread of the writer's own (see the module docstring);
    False: every call has written its records when it returns."""

    def __init__(self, stream: BinaryIO, *, library: str, profile: str = "",
                 compression_level: int = -1, background: bool = False) -> None:
        self._empty(stream, compression_level, background)
        self._do(self._write, MAGIC)
        self._do(self._write, _record_bytes(Header(profile=profile, library=library)))

    @classmethod
    def continued(cls, stream: BinaryIO, prefix: bytes, compression_level: int = -1,
                  background: bool = False) -> McapChunkWriter:
        """A writer that first writes `prefix`, the data section of a file this writer began
        (magic, Header, then whole records, each chunk followed by all its message indexes),
        and then goes on as the writer that wrote it would have: the same schema and channel
        ids, sequence numbers, chunk, attachment and metadata indexes, statistics and data
        CRC. ValueError when the prefix is not such a data section."""
        self = cls.__new__(cls)
        if not prefix.startswith(MAGIC):
            raise ValueError("the prefix does not start with the MCAP magic")
        self._empty(stream, compression_level, background)
        try:
            self._index_records(memoryview(prefix))
        except BaseException:
            self._stop(check=False)
            raise
        self._do(self._write, prefix)
        return self

    def _empty(self, stream: BinaryIO, compression_level: int, background: bool) -> None:
        self._behind = WriteBehind() if background else None
        self._stream = stream
        self._offset = 0
        self._data_crc = 0  # CRC-32 of every byte from the magic up to DataEnd (the spec's)
        self._compressor = zstandard.ZstdCompressor(level=compression_level)
        self.pool = BufferPool()  # for this writer's chunks (ChunkBuilder(writer.pool))
        self._schemas: list[Schema] = []
        self._channels: list[Channel] = []
        self._sequences: dict[int, int] = defaultdict(int)
        self._chunk_indexes: list[ChunkIndex] = []
        self._attachment_indexes: list[AttachmentIndex] = []
        self._metadata_indexes: list[MetadataIndex] = []
        self._message_counts: dict[int, int] = defaultdict(int)
        self._start_time: int | None = None
        self._end_time = 0
        # Called with each chunk's records (bytes) and this writer once they are made, before
        # they are written (orchestrator.live: the same messages served as they are logged).
        self.tap: Callable[[bytes, McapChunkWriter], None] | None = None

    def _index_records(self, data: memoryview) -> None:
        """What the writer knows after writing `data` (a data section; see `continued`)."""
        pos, chunk = len(MAGIC), None
        while pos < len(data):
            if pos + _RECORD_PREFIX.size > len(data):
                raise ValueError(f"the prefix ends inside a record at byte {pos}")
            opcode, length = _RECORD_PREFIX.unpack_from(data, pos)
            end = pos + _RECORD_PREFIX.size + length
            if end > len(data):
                raise ValueError(f"the prefix ends inside a record at byte {pos}")
            body = ReadDataStream(io.BytesIO(bytes(data[pos + _RECORD_PREFIX.size:end])))
            if opcode == Opcode.SCHEMA:
                self._schemas.append(Schema.read(body))
            elif opcode == Opcode.CHANNEL:
                self._channels.append(Channel.read(body))
            elif opcode == Opcode.METADATA:
                self._metadata_indexes.append(MetadataIndex(offset=pos, length=end - pos,
                                                            name=Metadata.read(body).name))
            elif opcode == Opcode.ATTACHMENT:
                record = Attachment.read(body)
                self._attachment_indexes.append(AttachmentIndex(
                    offset=pos, length=end - pos, log_time=record.log_time,
                    create_time=record.create_time, data_size=len(record.data),
                    name=record.name, media_type=record.media_type))
            elif opcode == Opcode.CHUNK:
                chunk = self._chunk_index(data, pos, end)
            elif opcode == Opcode.MESSAGE_INDEX and chunk is not None:
                channel_id, entries = struct.unpack_from("<HI", data, pos + 9)
                chunk.message_index_offsets[channel_id] = pos
                chunk.message_index_length += end - pos
                self._message_counts[channel_id] += entries // 16
                # This writer reserves exactly one sequence number per message it writes.
                self._sequences[channel_id] += entries // 16
            elif opcode not in (Opcode.HEADER, Opcode.MESSAGE_INDEX):
                raise ValueError(f"unexpected record (opcode {opcode:#x}) in a data section")
            pos = end
        for records in (self._schemas, self._channels):
            if [record.id for record in records] != list(range(1, len(records) + 1)):
                raise ValueError("schema and channel ids are not this writer's (1, 2, ...)")

    def _chunk_index(self, data: memoryview, pos: int, end: int) -> ChunkIndex:
        start_time, end_time, size = struct.unpack_from("<QQQ", data, pos + 9)
        (name_length,) = struct.unpack_from("<I", data, pos + 9 + 28)
        compression = bytes(data[pos + 9 + 32:pos + 9 + 32 + name_length]).decode()
        (compressed,) = struct.unpack_from("<Q", data, pos + 9 + 32 + name_length)
        chunk = ChunkIndex(
            message_start_time=start_time, message_end_time=end_time, chunk_start_offset=pos,
            chunk_length=end - pos, message_index_offsets={}, message_index_length=0,
            compression=compression, compressed_size=compressed, uncompressed_size=size)
        self._chunk_indexes.append(chunk)
        self._start_time = start_time if self._start_time is None \
            else min(self._start_time, start_time)
        self._end_time = max(self._end_time, end_time)
        return chunk

    @property
    def schemas(self) -> tuple[Schema, ...]:
        """The schemas registered so far, by id (1, 2, ...)."""
        return tuple(self._schemas)

    @property
    def channels(self) -> tuple[Channel, ...]:
        """The channels registered so far, by id (1, 2, ...)."""
        return tuple(self._channels)

    @property
    def native_id(self) -> int | None:
        """The writer thread's id (None without one)."""
        return None if self._behind is None else self._behind.native_id

    def _do(self, task, *args):
        """task(*args) now, or in order on the writer thread (returns its future)."""
        if self._behind is None:
            task(*args)
            return None
        return self._behind.submit(task, *args)

    def _stop(self, check: bool = True) -> None:
        if self._behind is not None:
            self._behind.close(check)

    def abandon(self) -> None:
        """End the writer thread (what it holds is written; its failure, if any, is dropped)
        and close the stream, without the summary: for a file that is given up on, e.g. when
        making it failed. The caller's exception is what to report."""
        try:
            self._stop(check=False)
        finally:
            if not self._stream.closed:
                self._stream.close()

    # Everything below that touches the stream, the offset, the CRC or the indexes runs on the
    # writer thread when there is one.

    def _write(self, data: bytes) -> None:
        self._stream.write(data)
        self._offset += len(data)
        self._data_crc = zlib.crc32(data, self._data_crc)

    def _write_record(self, record) -> int:
        data = _record_bytes(record)
        self._write(data)
        return len(data)

    def add_schema(self, name: str, encoding: str, data: bytes) -> int:
        """Register a schema; returns its id (1, 2, ...)."""
        schema = Schema(id=len(self._schemas) + 1, name=name, encoding=encoding, data=data)
        self._schemas.append(schema)
        self._do(self._write, _record_bytes(schema))
        return schema.id

    def add_channel(self, topic: str, message_encoding: str, schema_id: int,
                    metadata: dict[str, str] | None = None) -> int:
        """Register a channel; returns its id (1, 2, ...)."""
        channel = Channel(id=len(self._channels) + 1, topic=topic, schema_id=schema_id,
                          message_encoding=message_encoding, metadata=dict(metadata or {}))
        self._channels.append(channel)
        self._do(self._write, _record_bytes(channel))
        return channel.id

    def reserve_sequence(self, channel_id: int, count: int) -> int:
        """First of `count` consecutive sequence numbers for messages on `channel_id`."""
        first = self._sequences[channel_id]
        self._sequences[channel_id] = first + count
        return first

    def add_metadata(self, name: str, metadata: dict[str, str]) -> None:
        self._do(self._write_metadata, name, _record_bytes(Metadata(name=name,
                                                                    metadata=metadata)))

    def _write_metadata(self, name: str, data: bytes) -> None:
        self._metadata_indexes.append(MetadataIndex(offset=self._offset, length=len(data),
                                                    name=name))
        self._write(data)

    def add_attachment(self, name: str, media_type: str, data: bytes, time_ns: int = 0) -> None:
        record = Attachment(create_time=time_ns, log_time=time_ns, name=name,
                            media_type=media_type, data=data)
        index = AttachmentIndex(offset=0, length=0, log_time=time_ns, create_time=time_ns,
                                data_size=len(data), name=name, media_type=media_type)
        self._do(self._write_attachment, index, _record_bytes(record))

    def _write_attachment(self, index: AttachmentIndex, data: bytes) -> None:
        index.offset, index.length = self._offset, len(data)
        self._attachment_indexes.append(index)
        self._write(data)

    def write_chunk(self, chunk: ChunkBuilder) -> None:
        """Compress `chunk` and write it with its message indexes (nothing if it is empty),
        then release its buffers. With a writer thread, the rows' places and the message
        indexes are worked out here and the rest is done there, once everything handed to it
        before is written (this call waits for that)."""
        if chunk.start_time is None:
            chunk.release()
            return
        indexes = chunk.message_indexes()  # the records are made on the writer thread
        if self._behind is not None:
            # Everything before (the last chunk and its flush) is done: two chunks' buffers
            # at most, and the last period is with the operating system before the next one
            # is handed over.
            self._behind.wait()
        self._do(self._write_chunk, chunk, indexes)

    def _write_chunk(self, chunk: ChunkBuilder, indexes: dict[int, bytes]) -> None:
        records = chunk.records()
        if self.tap is not None:
            self.tap(bytes(records), self)
        compressed = self._compressor.compress(records)
        compression = b"zstd"
        head = _RECORD_PREFIX.pack(Opcode.CHUNK, 8 * 3 + 4 + 4 + len(compression) + 8
                                   + len(compressed))
        body = struct.pack("<QQQI", chunk.start_time, chunk.end_time, len(records),
                           zlib.crc32(records))
        body += struct.pack("<I", len(compression)) + compression + struct.pack(
            "<Q", len(compressed))
        chunk_offset = self._offset
        self._write(head + body)
        self._write(compressed)
        chunk_length = self._offset - chunk_offset
        index_offsets = {}
        index_start = offset = self._offset
        for channel_id, index in indexes.items():
            index_offsets[channel_id] = offset
            offset += len(index)
        self._write(b"".join(indexes.values()))  # one write (and CRC update) for all
        self._chunk_indexes.append(ChunkIndex(
            message_start_time=chunk.start_time, message_end_time=chunk.end_time,
            chunk_start_offset=chunk_offset, chunk_length=chunk_length,
            message_index_offsets=index_offsets,
            message_index_length=self._offset - index_start, compression="zstd",
            compressed_size=len(compressed), uncompressed_size=len(records),
        ))
        for channel_id, count in chunk.counts.items():
            self._message_counts[channel_id] += count
        if self._start_time is None:
            self._start_time = chunk.start_time
        self._start_time = min(self._start_time, chunk.start_time)
        self._end_time = max(self._end_time, chunk.end_time)
        chunk.release()

    def flush(self, fsync: bool = False, wait: bool = False) -> None:
        """Hand everything added so far to the operating system; with `fsync`, to the disk.
        With a writer thread: once it has written it, or before returning with `wait`."""
        done = self._do(self._flush, fsync)
        if wait and self._behind is not None:
            self._behind.wait(done)

    def wait(self) -> None:
        """Block until the writer thread has done everything handed to it so far; raise what
        failed there, if anything. Returns at once without a writer thread."""
        if self._behind is not None:
            self._behind.wait()

    def _flush(self, fsync: bool) -> None:
        self._stream.flush()
        if fsync:
            os.fsync(self._stream.fileno())

    def finish(self) -> None:
        """Write the summary and footer, flush and close the stream; with a writer thread,
        wait for it, end it and raise what failed on it, if anything (the stream is closed
        either way)."""
        try:
            self._do(self._finish)
        finally:
            try:
                self._stop()
            finally:
                if not self._stream.closed:
                    self._stream.close()

    def _finish(self) -> None:
        self._write_record(DataEnd(data_section_crc=self._data_crc))
        summary_start = self._offset
        builder = RecordBuilder()
        offsets: list[SummaryOffset] = []
        statistics = Statistics(
            message_count=sum(self._message_counts.values()),
            schema_count=len(self._schemas), channel_count=len(self._channels),
            attachment_count=len(self._attachment_indexes),
            metadata_count=len(self._metadata_indexes), chunk_count=len(self._chunk_indexes),
            message_start_time=self._start_time or 0, message_end_time=self._end_time,
            channel_message_counts=dict(self._message_counts),
        )
        groups = (
            (Opcode.SCHEMA, self._schemas), (Opcode.CHANNEL, self._channels),
            (Opcode.STATISTICS, [statistics]), (Opcode.CHUNK_INDEX, self._chunk_indexes),
            (Opcode.ATTACHMENT_INDEX, self._attachment_indexes),
            (Opcode.METADATA_INDEX, self._metadata_indexes),
        )
        for opcode, records in groups:
            if not records:
                continue
            start = builder.count
            for record in records:
                record.write(builder)
            offsets.append(SummaryOffset(group_opcode=opcode, group_start=summary_start + start,
                                         group_length=builder.count - start))
        summary_offset_start = summary_start + builder.count
        for offset in offsets:
            offset.write(builder)
        summary = builder.end()
        footer_head = struct.pack("<BQQQ", Opcode.FOOTER, 8 + 8 + 4, summary_start,
                                  summary_offset_start)
        crc = zlib.crc32(footer_head, zlib.crc32(summary))
        self._write(summary)
        self._write_record(Footer(summary_start=summary_start,
                                  summary_offset_start=summary_offset_start, summary_crc=crc))
        self._write(MAGIC)
        self._stream.flush()
        self._stream.close()
        self.pool = BufferPool()  # the chunks' MBs need not outlive the file


def _record_bytes(record) -> bytes:
    """A record of `mcap.records` as bytes: opcode, length and body."""
    builder = RecordBuilder()
    record.write(builder)
    return builder.end()
