"""A run served live over the Foxglove WebSocket protocol as it is logged.

`LiveView` starts foxglove-sdk's WebSocket server (`foxglove.start_server`, subprotocol
`foxglove.sdk.v1`) and, attached to a run log (`RunLog.attach_live`), receives each chunk's
records as the log makes them: every message goes out on a channel with the log channel's
topic, encoding, schema and metadata, with its log time as the message time, byte for byte
what the file holds. So a Foxglove layout made for the file works live, and a test can compare
what a client receives with the log.

Pacing: messages go out when the wall clock reaches their log time divided by the real-time
factor (1: as fast as the machine dug). A simulated run computes a period in a fraction of its
duration; the view holds at most `AHEAD` chunks, so the run waits for the viewer. A lab run
hands over each period at its end; when a message is late, the clock is set back so that it
goes out now and the period plays at its own pace while the next one is dug.
"""

from __future__ import annotations

import math
import queue
import struct
import threading
import time
from collections.abc import Iterator
from typing import Any

from mcap.opcode import Opcode

_RECORD_PREFIX = struct.Struct("<BQ")
_MESSAGE_HEAD = struct.Struct("<HIQQ")  # channel id, sequence, log time, publish time
AHEAD = 2  # chunks waiting to be played before the run is held
_LATE_S = 0.25  # a message this late moves the clock (a lab period arrives at its end)
_STOP = object()


class LiveError(RuntimeError):
    """The live view cannot start (the port is taken, the host is not this machine's); one
    line."""


def messages(records: bytes) -> Iterator[tuple[int, int, bytes]]:
    """(channel id, log time ns, data) of every Message record in a chunk's records."""
    view, pos = memoryview(records), 0
    while pos + _RECORD_PREFIX.size <= len(view):
        opcode, length = _RECORD_PREFIX.unpack_from(view, pos)
        body = pos + _RECORD_PREFIX.size
        if opcode == Opcode.MESSAGE:
            channel, _, log_time, _ = _MESSAGE_HEAD.unpack_from(view, body)
            yield channel, log_time, bytes(view[body + _MESSAGE_HEAD.size:body + length])
        pos = body + length


class LiveView:
    """Serve a run log's messages live on ws://host:port (`port` 0: any free port; the one
    taken is `port`). real_time_factor: > 0, how much faster than log time the messages go
    out (1: real time); None: as soon as logged. LiveError when the server cannot start.
    Use as a context manager, or call `close`."""

    def __init__(self, port: int = 8765, host: str = "127.0.0.1",
                 real_time_factor: float | None = 1.0, name: str = "excosim") -> None:
        if real_time_factor is not None and not (math.isfinite(real_time_factor)
                                                 and real_time_factor > 0.0):
            raise ValueError(f"real_time_factor must be a number > 0, got {real_time_factor!r}")
        import foxglove

        self._foxglove = foxglove
        self._context = foxglove.Context()
        try:
            self._server = foxglove.start_server(name=name, host=host, port=port,
                                                 context=self._context,
                                                 message_backlog_size=65536)
        except (RuntimeError, ValueError, OSError) as error:
            raise LiveError(f"cannot serve on {host}:{port}: "
                            f"{str(error).splitlines()[0]}") from None
        self.host, self.port = host, int(self._server.port)
        self._factor = real_time_factor
        self._channels: dict[int, Any] = {}
        self._anchor: tuple[float, int] | None = None  # (wall clock s, log time ns)
        self._chunks: queue.Queue = queue.Queue(maxsize=AHEAD)
        self._failed: BaseException | None = None
        self._player = threading.Thread(target=self._play, name="excosim-live", daemon=True)
        self._player.start()

    @property
    def url(self) -> str:
        """ws://host:port, what Foxglove's "Open connection" takes."""
        return f"ws://{self.host}:{self.port}"

    def take_chunk(self, records: bytes, writer) -> None:
        """Queue a chunk's records (McapChunkWriter.tap; `writer` knows their channels); waits
        while AHEAD chunks are still to be played."""
        for channel_id, _, _ in messages(records):
            if channel_id not in self._channels:
                self._channels[channel_id] = self._channel(writer, channel_id)
        if self._failed is None:
            self._chunks.put(records)

    def _channel(self, writer, channel_id: int):
        channel = next(c for c in writer.channels if c.id == channel_id)
        schema = next((s for s in writer.schemas if s.id == channel.schema_id), None)
        fox = self._foxglove
        return fox.Channel(
            channel.topic, message_encoding=channel.message_encoding, context=self._context,
            schema=None if schema is None else fox.Schema(name=schema.name,
                                                          encoding=schema.encoding,
                                                          data=schema.data),
            metadata=dict(channel.metadata) or None)

    def _play(self) -> None:
        try:
            while (records := self._chunks.get()) is not _STOP:
                for channel_id, log_time, data in messages(records):
                    self._wait_for(log_time)
                    self._channels[channel_id].log(data, log_time=log_time)
        except BaseException as error:  # noqa: BLE001 - reported by close(); the run goes on
            self._failed = error
            while self._chunks.get() is not _STOP:  # unblock the log's writer
                pass

    def _wait_for(self, log_time_ns: int) -> None:
        if self._factor is None:
            return
        now = time.monotonic()
        if self._anchor is None:
            self._anchor = (now, log_time_ns)
        wall, log = self._anchor
        due = wall + (log_time_ns - log) * 1e-9 / self._factor
        if due < now - _LATE_S:
            self._anchor = (now, log_time_ns)
            return
        while due > now + 0.002 and self._factor is not None:  # close(drain=False) cuts it
            time.sleep(min(due - now, 0.1))
            now = time.monotonic()

    def close(self, drain: bool = True) -> None:
        """Stop serving; with `drain`, after the messages handed over have gone out. A second
        call does nothing."""
        if self._server is None:
            return
        if not drain:
            self._factor = None
            while True:
                try:
                    self._chunks.get_nowait()
                except queue.Empty:
                    break
        self._chunks.put(_STOP)
        self._player.join()
        self._server.stop()
        self._server = None

    def __enter__(self) -> LiveView:
        return self

    def __exit__(self, exc_type, exc, traceback) -> None:
        self.close(drain=exc_type is None)
