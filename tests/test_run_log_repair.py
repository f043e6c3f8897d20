"""`repair`: a killed run's log made indexed, checked with the `mcap` package's indexed reader."""

import subprocess
import sys
from pathlib import Path

import pytest
from mcap.reader import make_reader
from run_log_files import chunks, cut_inside_chunk

from orchestrator.campaign import run_campaign
from orchestrator.runlog import RunLogError, read_run
from orchestrator.runlog.repair import repair
from orchestrator.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def three_periods(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("repair") / "run.mcap"
    scenario = load_scenario(ROOT / "scenarios" / "paper-2020.toml", ["periods=3"])
    assert run_campaign(scenario, log_path=path).termination == "periods"
    return path


def indexed_messages(path: Path) -> list[tuple[str, int, bytes]]:
    """Every message through the summary's chunk indexes (raises without a summary)."""
    with open(path, "rb") as stream:
        reader = make_reader(stream)
        assert reader.get_summary() is not None
        return [(channel.topic, message.log_time, message.data)
                for _, channel, message in reader.iter_messages(log_time_order=False)]


def test_a_killed_run_becomes_indexed_with_its_complete_periods(three_periods, tmp_path):
    killed = cut_inside_chunk(three_periods, tmp_path / "killed.mcap")  # died in period 3
    with open(killed, "rb") as stream, pytest.raises(Exception):  # noqa: B017
        make_reader(stream).get_summary()  # what an indexed reader makes of it
    report = repair(killed, tmp_path / "repaired.mcap")
    assert report.truncated and not report.finished and report.periods == 2
    copied = indexed_messages(report.target)
    # The same messages, in the same order, as the complete file up to period 3's chunk.
    complete = indexed_messages(three_periods)
    cut = chunks(three_periods)[2].message_start_time
    assert [m[0] for m in copied] == [m[0] for m in complete][:len(copied)]
    assert copied == complete[:len(copied)]
    assert len(copied) == report.messages and all(m[1] <= cut for m in copied)
    original = read_run(killed)
    assert len(copied) == sum(original.message_counts.values())
    copy = read_run(report.target)
    assert (copy.periods, copy.attachments, copy.metadata) == \
        (original.periods, original.attachments, original.metadata)


def test_a_finished_log_copies_whole(three_periods, tmp_path):
    report = repair(three_periods, tmp_path / "copy.mcap")
    assert not report.truncated and report.finished and report.periods == 3
    assert indexed_messages(report.target) == indexed_messages(three_periods)


def test_what_cannot_be_repaired_is_refused_and_nothing_is_written(three_periods, tmp_path):
    text = tmp_path / "notes.mcap"
    text.write_text("not a run log\n")
    with pytest.raises(RunLogError):
        repair(text, tmp_path / "out.mcap")
    assert not (tmp_path / "out.mcap").exists()
    existing = tmp_path / "taken.mcap"
    existing.write_bytes(b"keep me")
    with pytest.raises(FileExistsError):
        repair(three_periods, existing)
    assert existing.read_bytes() == b"keep me"
    with pytest.raises(FileExistsError):
        repair(three_periods, three_periods)


def test_the_command_writes_the_copy_and_refuses_in_one_line(three_periods, tmp_path):
    def excosim(*args):
        return subprocess.run([sys.executable, "-m", "orchestrator.cli.app", *args],
                              capture_output=True, text=True, timeout=120)

    killed = cut_inside_chunk(three_periods, tmp_path / "killed.mcap")
    done = excosim("log", "repair", str(killed))
    target = tmp_path / "killed.repaired.mcap"
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith(f"wrote {target}: 2 complete periods") and \
        "did not finish" in done.stdout
    assert read_run(target, tolerant=False).periods == read_run(killed).periods
    again = excosim("log", "repair", str(killed))
    assert again.returncode == 2 and again.stderr.count("\n") == 1
    assert "already exists" in again.stderr and "Traceback" not in again.stderr
    text = tmp_path / "notes.mcap"
    text.write_text("not a run log\n")
    bad = excosim("log", "repair", str(text), "-o", str(tmp_path / "x.mcap"))
    assert bad.returncode == 2 and "not an MCAP file" in bad.stderr
    assert not (tmp_path / "x.mcap").exists()
