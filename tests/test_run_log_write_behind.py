"""The run log's writer thread (orchestrator.runlog.write_behind): the same file as writing
directly, byte for byte, also when resumed; a failed write is raised by the run's next call to
the log and the file is still closed; the thread ends with the log."""

import io
import threading

import numpy as np
import pytest
from test_run_log import PERIOD_S, fake_fmus, measurement, open_log, record

from orchestrator.runlog import native, read_run
from orchestrator.runlog.chunk import ChunkBuilder
from orchestrator.runlog.mcap_records import McapChunkWriter
from orchestrator.runlog.reader import parse_run
from orchestrator.runlog.resume import continuation_prefix, open_continued
from orchestrator.runlog.write_behind import THREAD_NAME


@pytest.fixture
def fmus(tmp_path):
    return fake_fmus(tmp_path)


def log_threads() -> list[threading.Thread]:
    return [t for t in threading.enumerate() if t.name.startswith(THREAD_NAME)]


def write(path, fmus, background: bool, periods: int = 3) -> None:
    with open_log(path, fmus, background=background) as log:
        log.log_pile_surface(np.linspace(-13, -2, 45), np.zeros(45))
        for k in range(1, periods + 1):
            log.log_period(record(k), measurement(k), (k - 1) * PERIOD_S,
                           resume_state={"k": k, "fmus": {}, "master": {}})
            if background and k == 2:
                log.wait_written()
        log.log_unfinished(measurement(9), periods * PERIOD_S)


def test_the_writer_thread_writes_the_same_file_as_writing_directly(tmp_path, fmus):
    before = set(log_threads())
    write(tmp_path / "direct.mcap", fmus, background=False)
    write(tmp_path / "behind.mcap", fmus, background=True)
    assert (tmp_path / "behind.mcap").read_bytes() == (tmp_path / "direct.mcap").read_bytes()
    assert set(log_threads()) == before  # each log's thread ended at its close


def test_a_resumed_log_on_the_writer_thread_equals_one_written_directly(tmp_path, fmus):
    source = tmp_path / "source.mcap"
    write(source, fmus, background=False)
    data = source.read_bytes()
    prefix = continuation_prefix(data, parse_run(source, data).period_chunks[1])
    outputs = {}
    for background in (False, True):
        output = tmp_path / f"resumed-{background}.mcap"
        with open_continued(source, output, prefix, periods=2, note={"after_period": "2"},
                            geometry=None, sample_rate_hz=None,
                            background=background) as log:
            log.log_period(record(3), measurement(3), 2 * PERIOD_S)
        outputs[background] = output.read_bytes()
    assert outputs[True] == outputs[False]
    assert [r["k"] for r in read_run(tmp_path / "resumed-True.mcap").periods] == [1, 2, 3]


class FullDisk(io.BytesIO):
    """A stream that takes `room` bytes, then fails as a full disk does."""

    def __init__(self, room: int) -> None:
        super().__init__()
        self.room = room

    def write(self, data) -> int:
        if self.tell() + len(data) > self.room:
            raise OSError(28, "No space left on device")
        return super().write(data)


def chunk_of(n: int) -> ChunkBuilder:
    chunk, rng = ChunkBuilder(), np.random.default_rng(n)
    for k in range(n):
        chunk.add_message(1, k, k, rng.bytes(1000))  # random: compression keeps the size
    return chunk


def test_a_failed_write_is_raised_by_the_next_call_and_the_stream_closed():
    stream = FullDisk(room=20_000)
    writer = McapChunkWriter(stream, library="test", background=True)
    channel = writer.add_channel("/x", "json", 0)
    writer.write_chunk(chunk_of(5))  # fits
    writer.flush(wait=True)
    writer.write_chunk(chunk_of(50))  # does not: fails on the thread, not here
    with pytest.raises(OSError, match="No space left"):
        writer.flush(wait=True)
    with pytest.raises(OSError, match="No space left"):  # and again on every later call
        writer.add_channel("/y", "json", 0)
    with pytest.raises(OSError, match="No space left"):
        writer.finish()
    assert stream.closed
    assert channel == 1
    assert not [t for t in log_threads() if t.is_alive() and t.native_id == writer.native_id]


def test_a_run_log_reports_a_failed_write_at_its_next_period(tmp_path, fmus, monkeypatch):
    log = open_log(tmp_path / "full.mcap", fmus, background=True)
    log.log_period(record(1), measurement(1), 0.0)
    log.wait_written()

    def full(data):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(log._writer._stream, "write", full)
    log.log_period(record(2), measurement(2), PERIOD_S)  # handed over; written later
    with pytest.raises(OSError, match="No space left"):
        log.wait_written()
    with pytest.raises(OSError, match="No space left"):
        log.close("error", "disk full")
    assert log._writer._stream.closed  # the file is closed (and unlocked) all the same
    assert not [t for t in log_threads() if t.native_id == log._writer.native_id]


def test_rows_c_comes_with_the_package_whatever_the_cache(tmp_path, fmus, monkeypatch):
    """rows.c is compiled when the package is built: where the build cache cannot be written
    (a read-only home) and there is no gcc, the log is written all the same, to the same
    bytes."""
    write(tmp_path / "before.mcap", fmus, background=True)
    blocked = tmp_path / "not-a-folder"
    blocked.write_text("")
    monkeypatch.setenv("EXCOSIM_FMU_DIR", str(blocked / "cache"))
    monkeypatch.setenv("PATH", str(tmp_path))  # a folder without gcc
    native.library.cache_clear()
    try:
        write(tmp_path / "blocked.mcap", fmus, background=True)
    finally:
        monkeypatch.undo()
        native.library.cache_clear()
    assert (tmp_path / "blocked.mcap").read_bytes() == (tmp_path / "before.mcap").read_bytes()


def test_a_campaign_whose_log_cannot_be_written_ends_with_an_error(tmp_path, monkeypatch):
    """A write that fails on the log's thread (a full disk) ends the campaign as a failure
    does: a result with termination "error" naming the period whose log failed, the plant
    closed, the file closed, no thread left; nothing raised."""
    from kinematic_plant import KinematicPlant
    from test_campaign import PAPER

    from orchestrator.campaign import run_campaign
    from orchestrator.scenario import load_scenario

    written, chunks = McapChunkWriter._write_chunk, []

    def failing(self, chunk, indexes):
        chunks.append(chunk)
        if len(chunks) == 3:  # period 3's (the test double has no pile surface to log)
            raise OSError(28, "No space left on device")
        written(self, chunk, indexes)

    monkeypatch.setattr(McapChunkWriter, "_write_chunk", failing)
    scenario = load_scenario(PAPER)
    plant = KinematicPlant(scenario.geometry())
    before = set(log_threads())
    result = run_campaign(scenario, plant=plant, log_path=tmp_path / "full.mcap")
    assert result.termination == "error"
    assert result.message.startswith("period 4: OSError: writing the log of period 3")
    assert "No space left" in result.message
    assert plant.closed == 1 and set(log_threads()) == before
    assert [r["k"] for r in read_run(tmp_path / "full.mcap").periods] == [1, 2]


def test_a_ctrl_c_while_closing_waits_for_the_file_work_first():
    """Ctrl-C while the writer thread finishes the file: the KeyboardInterrupt comes once the
    thread is done, so that nobody closes the stream under it."""
    import os
    import signal
    import time

    from orchestrator.runlog.write_behind import WriteBehind

    behind, done = WriteBehind(), []
    behind.submit(lambda: (time.sleep(0.4), done.append(True)))
    timer = threading.Timer(0.1, os.kill, (os.getpid(), signal.SIGINT))
    timer.start()
    with pytest.raises(KeyboardInterrupt):
        behind.close()
    timer.join()
    assert done == [True]  # the work was done before the KeyboardInterrupt came
    for thread in [t for t in log_threads() if t.native_id == behind.native_id]:
        thread.join(timeout=5)  # and the thread, with nothing left to do, ends
        assert not thread.is_alive()
