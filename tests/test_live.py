"""`excosim run --live`: a real WebSocket client speaking the Foxglove protocol (subprotocol
`foxglove.sdk.v1`, as Foxglove and Lichtblick connect) subscribes to a run served live and
receives what the run's MCAP log holds, byte for byte: the same topics, schemas, log times and
message data.

The client is tornado's WebSocket client (a library independent of the foxglove-sdk server);
the protocol's frames are the ones the Foxglove WebSocket specification gives: JSON
`serverInfo` and `advertise` from the server, `subscribe` from the client, binary
`messageData` (opcode 1, subscription id u32, timestamp u64, payload).
"""

from __future__ import annotations

import asyncio
import base64
import json
import os
import re
import socket
import struct
import subprocess
import sys
import time
from pathlib import Path

import pytest
from mcap.reader import make_reader
from tornado.websocket import websocket_connect

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "scenarios" / "paper-2020.toml"
EXCOSIM = Path(sys.executable).parent / "excosim"
FACTOR = 25.0  # 2 paper periods (25 s of log time) play in about a second


def _excosim(*args: str, cwd: Path) -> subprocess.Popen:
    return subprocess.Popen([str(EXCOSIM), *args], cwd=cwd, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env={**os.environ})


async def _watch(url: str, deadline_s: float) -> tuple[dict, list[tuple[str, int, bytes]]]:
    """Subscribe to every channel the server advertises until it closes; (channels by topic,
    received (topic, log time ns, data))."""
    connection = await websocket_connect(url, subprotocols=["foxglove.sdk.v1"])
    assert connection.selected_subprotocol == "foxglove.sdk.v1"
    channels, by_subscription, received = {}, {}, []
    end = time.monotonic() + deadline_s
    while time.monotonic() < end:
        message = await connection.read_message()
        if message is None:  # the server stopped: the run is over
            break
        if isinstance(message, str):
            data = json.loads(message)
            if data["op"] == "advertise":
                subscriptions = []
                for channel in data["channels"]:
                    channels[channel["topic"]] = channel
                    by_subscription[len(by_subscription) + 1] = channel["topic"]
                    subscriptions.append({"id": len(by_subscription),
                                          "channelId": channel["id"]})
                await connection.write_message(json.dumps({"op": "subscribe",
                                                           "subscriptions": subscriptions}))
        else:
            assert message[0] == 1  # messageData
            subscription, log_time = struct.unpack_from("<IQ", message, 1)
            received.append((by_subscription[subscription], log_time, bytes(message[13:])))
    return channels, received


def _log_messages(path: Path) -> tuple[dict, set[tuple[str, int, bytes]]]:
    with open(path, "rb") as stream:
        reader = make_reader(stream)
        summary = reader.get_summary()
        schemas = {c.topic: (c, summary.schemas.get(c.schema_id))
                   for c in summary.channels.values()}
        messages = {(channel.topic, message.log_time, message.data)
                    for _, channel, message in reader.iter_messages(log_time_order=False)}
    return schemas, messages


def test_a_live_client_receives_what_the_log_holds(tmp_path):
    log = tmp_path / "live.mcap"
    started = time.monotonic()
    process = _excosim("run", str(PAPER), "--periods", "2", "-o", str(log), "--live",
                       "--port", "0", "--real-time-factor", str(FACTOR), cwd=tmp_path)
    try:
        line = ""
        while "live: ws://" not in line:
            line = process.stderr.readline()
            assert line, process.communicate()
        url = re.search(r"ws://[0-9.]+:\d+", line).group(0)
        channels, received = asyncio.run(_watch(url, 120.0))
        out, err = process.communicate(timeout=120)
    finally:
        process.kill()
    elapsed = time.monotonic() - started
    assert process.returncode == 0, err
    schemas, logged = _log_messages(log)
    # The same channels: topic, encoding, schema name, encoding and bytes.
    assert set(channels) == set(schemas)
    for topic, advertised in channels.items():
        channel, schema = schemas[topic]
        assert advertised["encoding"] == channel.message_encoding
        assert advertised["schemaName"] == schema.name
        assert advertised["schemaEncoding"] == schema.encoding
        data = advertised["schema"].encode() if schema.encoding == "jsonschema" else \
            base64.b64decode(advertised["schema"])
        assert data == schema.data, topic
    # Every message received is one of the log's, with its log time; /period and /tf among them.
    assert received and set(received) <= logged
    topics = [topic for topic, _, _ in received]
    assert topics.count("/period") >= 1 and topics.count("/tf") >= 100
    assert "/scene/plan" in topics and "/scene/tip_trail" in topics
    times = [t for _, t, _ in received]
    assert times == sorted(times)  # played in log-time order
    # Paced: the run cannot end before its log time has played out at the factor (a lower
    # bound that a loaded machine only makes safer).
    span_s = (max(t for _, t, _ in logged) - min(t for _, t, _ in logged)) / 1e9
    assert elapsed >= 0.9 * span_s / FACTOR
    assert f"log: {log}" in out


def test_live_refuses_bad_settings_in_one_line_before_any_log(tmp_path):
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        cases = {
            ("--port", "70000"): "--port must be 0..65535",
            ("--real-time-factor", "0"): "--real-time-factor must be a number > 0",
            ("--real-time-factor", "nan"): "--real-time-factor must be a number > 0",
            ("--port", str(port)): f"--live: cannot serve on 127.0.0.1:{port}",
        }
        for extra, expected in cases.items():
            log = tmp_path / "refused.mcap"
            done = subprocess.run([str(EXCOSIM), "run", str(PAPER), "--periods", "1", "-o",
                                   str(log), "--live", *extra], cwd=tmp_path,
                                  capture_output=True, text=True, timeout=120)
            assert done.returncode == 2, (extra, done.stderr)
            lines = [line for line in done.stderr.splitlines()
                     if not line.startswith("logging to")]
            assert len(lines) == 1 and expected in lines[0], (extra, done.stderr)
            assert "Traceback" not in done.stderr
            assert not log.exists() or log.stat().st_size == 0


@pytest.mark.parametrize("option", [("--port", "8765"), ("--real-time-factor", "2")])
def test_live_settings_need_live(tmp_path, option):
    done = subprocess.run([str(EXCOSIM), "run", str(PAPER), "--periods", "1", *option],
                          cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert done.returncode == 2 and "--live" in done.stderr
    assert not (tmp_path / "runs").exists()
