"""Reading hostile files: no hang on a FIFO or a device, no memory blow-up from a chunk that
claims more than it holds; the reader refuses such files instead (one line; more cases in
test_run_log_damage.py)."""

import os
import struct
import threading
from pathlib import Path

import pytest
from run_log_files import chunks

from orchestrator.campaign import run_campaign
from orchestrator.runlog import RunLogError, read_run
from orchestrator.runlog.inflate import MAX_CHUNK_BYTES
from orchestrator.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def two_periods(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("hostile") / "run.mcap"
    scenario = load_scenario(ROOT / "scenarios" / "paper-2020.toml", ["periods=2"])
    assert run_campaign(scenario, log_path=path).termination == "periods"
    return path


def read_within(path: Path, seconds: float = 10.0):
    """read_run in a thread: (result or exception), failing the test if it blocks."""
    box: list = []

    def target():
        try:
            box.append(read_run(path))
        except Exception as error:  # noqa: BLE001 - handed to the test
            box.append(error)

    thread = threading.Thread(target=target, daemon=True)
    thread.start()
    thread.join(seconds)
    assert not thread.is_alive(), f"read_run({path}) blocked"
    return box[0]


def test_a_fifo_and_a_device_are_refused_without_blocking(tmp_path):
    fifo = tmp_path / "pipe.mcap"
    os.mkfifo(fifo)
    for path in (fifo, Path("/dev/zero"), tmp_path):
        error = read_within(path)
        assert isinstance(error, RunLogError) and "not a regular file" in str(error)


def test_a_chunk_claiming_too_many_bytes_is_refused(two_periods, tmp_path):
    data = bytearray(two_periods.read_bytes())
    second = chunks(two_periods)[1]
    # Chunk record: opcode, length, then start, end, uncompressed size (u64 each).
    at = second.chunk_start_offset + 1 + 8 + 8 + 8
    assert struct.unpack_from("<Q", data, at)[0] == second.uncompressed_size
    struct.pack_into("<Q", data, at, 1 << 40)
    crafted = tmp_path / "crafted.mcap"
    crafted.write_bytes(bytes(data))
    error = read_within(crafted)  # at once, without asking for the 2^40 bytes
    assert isinstance(error, RunLogError), error
    assert str(error) == (f"{crafted}: the chunk at byte {second.chunk_start_offset} declares "
                          "1099511627776 bytes (1 TiB) uncompressed, more than the "
                          "256 MiB a chunk may hold (a period of a run is 1-130 MB): refused "
                          "(a damaged or crafted file)")
    assert (1 << 40) > MAX_CHUNK_BYTES


def test_review_json_never_prints_a_bare_nan(two_periods, tmp_path):
    import json
    import subprocess
    import sys

    data = two_periods.read_bytes()
    # A foreign or damaged writer's NaN in a period record (JSON readers accept it, JSON
    # writers must not pass it on); same byte length, so no record length changes.
    old = b'"mass_kg": '
    at = data.index(old) + len(old)
    end = data.index(b",", at)
    value = data[at:end]
    crafted = data[:at] + b"NaN".ljust(len(value)) + data[end:]
    path = tmp_path / "nan.mcap"
    path.write_bytes(crafted)
    done = subprocess.run([sys.executable, "-m", "orchestrator.cli.app", "review", str(path),
                           "--json"], capture_output=True, text=True, timeout=120)
    assert "NaN" not in done.stdout
    if done.returncode == 0:
        json.loads(done.stdout, parse_constant=lambda name: pytest.fail(f"bare {name}"))
