"""A damaged or edited record of a run log is one line naming the record and what is wrong, the
same in every command that reads it (orchestrator.runlog.records), never a traceback: a /period
record that is not an object, lacks a key, holds an empty or non-finite figure or is nested too
deeply, and a scenario record that is not an object. The logs are a real campaign's, with one
record rewritten through the MCAP library's own reader and writer."""

import json
import subprocess
import sys
from pathlib import Path

import pytest
from mcap.records import Attachment, Channel, DataEnd, Header, Message, Metadata, Schema
from mcap.stream_reader import StreamReader
from mcap.writer import Writer

from orchestrator.campaign import run_campaign
from orchestrator.runlog import RunLogError, read_run
from orchestrator.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "scenarios" / "paper-2020.toml"


@pytest.fixture(scope="module")
def log(tmp_path_factory):
    path = tmp_path_factory.mktemp("records") / "run.mcap"
    run_campaign(load_scenario(PAPER, ["periods=2"]), log_path=path)
    return path


def rewrite(source: Path, target: Path, period=None, scenario=None,
            unfinished: bool = False, header=None) -> Path:
    """A copy of the log with /period record 2 (period: old JSON text -> new bytes) or the
    scenario record (scenario: -> new JSON text) replaced; unfinished: without its end record
    (a run that was stopped); header: a function that changes the excosim.run record (dict)."""
    with open(source, "rb") as stream, open(target, "wb") as out:
        writer = Writer(out)
        topics, seen = {}, 0
        for record in StreamReader(stream, emit_chunks=False).records:
            if isinstance(record, Header):
                writer.start(profile=record.profile, library=record.library)
            elif isinstance(record, Schema):
                writer.register_schema(record.name, record.encoding, record.data)
            elif isinstance(record, Channel):
                topics[record.id] = record.topic
                writer.register_channel(record.topic, record.message_encoding,
                                        record.schema_id, dict(record.metadata))
            elif isinstance(record, Message):
                data = record.data
                if topics[record.channel_id] == "/period":
                    seen += 1
                    if seen == 2 and period is not None:
                        data = period(data.decode())
                writer.add_message(record.channel_id, record.log_time, data,
                                   record.publish_time, record.sequence)
            elif isinstance(record, Attachment):
                writer.add_attachment(record.create_time, record.log_time, record.name,
                                      record.media_type, record.data)
            elif isinstance(record, Metadata):
                if unfinished and record.name == "excosim.end":
                    continue
                values = dict(record.metadata)
                if record.name == "excosim.scenario" and scenario is not None:
                    values["json"] = scenario
                if record.name == "excosim.run" and header is not None:
                    values = header(values)
                writer.add_metadata(record.name, values)
            elif isinstance(record, DataEnd):
                break
        writer.finish()
    return target


def without_digest(header: dict) -> dict:
    """The excosim.run record as versions before the scenario digest wrote it."""
    return {key: value for key, value in header.items() if key != "scenario_sha256"}


def _edit(key, value):
    def change(text: str) -> bytes:
        record = json.loads(text)
        if value is KeyError:
            del record[key]
        else:
            record[key] = value
        return json.dumps(record).encode()
    return change


CASES = [
    ("null", lambda text: b"null", "/period record 2 is a JSON null, not an object"),
    ("list", lambda text: b"[1, 2]", "/period record 2 is a JSON array, not an object"),
    ("no mass", _edit("mass_kg", KeyError), "/period record 2 has no mass_kg"),
    ("empty jerks", _edit("max_abs_jerk_deg_s3", []),
     "max_abs_jerk_deg_s3 is [], not three finite numbers"),
    ("NaN mass", lambda text: text.replace('"mass_kg": ', '"mass_kg": NaN, "x": ').encode(),
     "mass_kg is nan, not a finite number"),
    ("huge", lambda text: text.replace('"error_kg": ', '"error_kg": 1e400, "y": ').encode(),
     "error_kg is inf, not a finite number"),
    ("nested", lambda text: text[:-1].encode() + b', "deep": ' + b"[" * 100000 +
     b"]" * 100000 + b"}", "/period record 2 is nested too deeply"),
    # Python's parser takes 900 levels; what recurses over the record (--json) would not.
    ("nested 900", lambda text: text[:-1].encode() + b', "deep": ' + b"[" * 900 +
     b"]" * 900 + b"}", "/period record 2 is nested too deeply (more than 32 levels)"),
    ("planner_ms a string", _edit("planner_ms", "x"),
     "/period record 2: planner_ms is 'x', not a finite number"),
]


@pytest.mark.parametrize("name, change, message", CASES, ids=[c[0] for c in CASES])
def test_a_bad_period_record_is_one_line_in_every_command(log, tmp_path, name, change, message):
    bad = rewrite(log, tmp_path / "bad.mcap", period=change)
    for command in (["review", bad], ["review", bad, "--json"], ["compare", log, bad],
                    ["replay", bad, "--json"]):
        done = subprocess.run([sys.executable, "-m", "orchestrator.cli.app",
                               *map(str, command)], capture_output=True, text=True, timeout=120)
        assert done.returncode == 2, (command, done.stderr[-300:])
        lines = done.stderr.strip().splitlines()
        assert len(lines) == 1 and message in lines[0], (command, lines)
        assert "Traceback" not in done.stderr


@pytest.mark.parametrize("text, kind", [("null", "null"), ("[]", "array"), ('"x"', "string"),
                                        ("NaN", "number")])
def test_a_scenario_record_that_is_not_an_object_is_refused(log, tmp_path, text, kind):
    bad = rewrite(log, tmp_path / "scenario.mcap", scenario=text)
    with pytest.raises(RunLogError, match=f"the scenario record .* is a JSON {kind}, not an "
                       "object"):
        read_run(bad)
    done = subprocess.run([sys.executable, "-m", "orchestrator.cli.app", "review", str(bad)],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 2 and len(done.stderr.strip().splitlines()) == 1


def test_the_untouched_copy_reads_as_the_original(log, tmp_path):
    same = rewrite(log, tmp_path / "same.mcap")
    assert read_run(same).periods == read_run(log).periods


def test_resume_refuses_what_it_would_copy_wrongly(log, tmp_path):
    """A bad period record, or a scenario record whose target disagrees with the header (in a
    log of a version without the header's digest), is refused in one line before anything is
    written (exit 2)."""
    from orchestrator.campaign.resume import ResumeRefused, prepare_resume

    scenario = read_run(log).scenario
    edited = rewrite(log, tmp_path / "edited.mcap",
                     scenario=json.dumps({**scenario, "target_mass_kg": 20.0}),
                     unfinished=True, header=without_digest)
    bad = rewrite(log, tmp_path / "bad.mcap", period=lambda text: b"[1, 2]", unfinished=True)
    for source, words in ((edited, "its header's target (30.0 kg) and its scenario record's "
                           "(20 kg) disagree"), (bad, "/period record 2 is a JSON array")):
        with pytest.raises(ResumeRefused, match=words.replace("(", r"\(").replace(")", r"\)")):
            prepare_resume(source)


def excosim(*args) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "orchestrator.cli.app", *map(str, args)],
                          capture_output=True, text=True, timeout=300)


def refused_by_resume(path: Path, words: str) -> None:
    """`run --resume` of `path`: one line holding `words`, exit 2, nothing written."""
    before = {p.name: p.read_bytes() for p in path.parent.iterdir()}
    done = excosim("run", "--resume", path)
    lines = done.stderr.strip().splitlines()
    assert done.returncode == 2, done.stderr[-500:]
    assert len(lines) == 1 and words in lines[0], lines
    assert "Traceback" not in done.stderr and done.stdout == ""
    assert {p.name: p.read_bytes() for p in path.parent.iterdir()} == before


def test_the_header_holds_the_digest_of_the_scenario_record(log):
    from orchestrator.runlog.metadata import scenario_digest

    run = read_run(log)
    assert run.metadata["excosim.run"]["scenario_sha256"] == scenario_digest(
        run.metadata["excosim.scenario"]["json"])


@pytest.mark.parametrize("edit", [
    ("target_mass_kg", 20.0), ("plant", "pile", "parameters", "density", 1200.0),
    ("adaptation", "y_D0_m", -8.5)], ids=["target", "density", "y_D0"])
def test_resume_refuses_a_scenario_record_edited_since_the_run_began(log, tmp_path, edit):
    """The header's digest names the scenario record the run began with: any edit of it (the
    saved states would silently override some, and a combined log would mix two scenarios) is
    refused; a log of an older version (no digest) still has its target compared."""
    from orchestrator.campaign.resume import ResumeRefused, prepare_resume

    scenario = read_run(log).scenario
    table = scenario
    for key in edit[:-2]:
        table = table[key]
    assert table.get(edit[-2]) != edit[-1]  # the density is the FMU default's unless set
    table[edit[-2]] = edit[-1]
    folder = tmp_path / "edited"
    folder.mkdir()
    edited = rewrite(log, folder / "run.mcap", scenario=json.dumps(scenario), unfinished=True)
    refused_by_resume(edited, "its scenario record (excosim.scenario) is not the one its "
                      "header recorded at the start (scenario_sha256 ")
    older = rewrite(log, tmp_path / "older.mcap", scenario=json.dumps(scenario),
                    unfinished=True, header=without_digest)
    if edit[0] == "target_mass_kg":
        with pytest.raises(ResumeRefused, match="header's target"):
            prepare_resume(older)
    untouched = rewrite(log, tmp_path / "untouched.mcap", unfinished=True)
    prepare_resume(untouched).release()  # the same copy without the edit resumes


def test_resume_refuses_records_that_disagree_with_the_state_or_each_other(log, tmp_path):
    from orchestrator.campaign.resume import ResumeRefused, prepare_resume

    for change, words in (
            (_edit("mass_kg", 1.0), "/period record 2: its error"),
            (lambda text: text.replace('"k": 2', '"k": 1').encode(),
             "/period record 2 says it is period 1"),
            (lambda text: text.replace('"error_kg": ', '"error_kg": 0.5, "x": ').replace(
                '"mass_kg": ', '"mass_kg": 29.5, "y": ').encode(),
             "the resume state after period 2 weighed")):
        bad = rewrite(log, tmp_path / "bad.mcap", period=change, unfinished=True)
        with pytest.raises(ResumeRefused, match=words):
            prepare_resume(bad)


def test_resume_refuses_a_duplicated_channel_record(log, tmp_path):
    """A channel record repeated in the part a resume copies (bytes as they were, or the same
    channel registered again under a new id) is one line, exit 2, nothing written."""
    import struct

    from mcap.opcode import Opcode
    from run_log_files import cut_inside_chunk

    killed = cut_inside_chunk(log, tmp_path / "killed.mcap")  # died in period 2
    data = killed.read_bytes()
    pos, channels = 8, []
    while pos + 9 <= len(data):
        opcode, length = struct.unpack_from("<BQ", data, pos)
        if opcode == Opcode.CHANNEL:
            channels.append((pos, pos + 9 + length))
        pos += 9 + length
    start, end = channels[3]
    folder = tmp_path / "twice"
    folder.mkdir()
    twice = folder / "run.mcap"
    twice.write_bytes(data[:end] + data[start:end] + data[end:])
    assert len(read_run(twice).periods) == 1  # the reader itself takes it
    refused_by_resume(twice, "the part a resume copies is not as its writer left it: "
                      "channel 4 (/cylinder/boom) is recorded twice")


def test_a_record_without_the_figures_a_log_may_lack_is_reviewed(log, tmp_path):
    """planner_ms and the productivity figures may be absent (older logs, other plants): the
    table shows a dash, the figures None."""
    def without(text: str) -> bytes:
        record = json.loads(text)
        for key in ("planner_ms", "energy_kj", "cycle_time_s"):
            del record[key]
        return json.dumps(record).encode()
    lacking = rewrite(log, tmp_path / "lacking.mcap", period=without)
    done = subprocess.run([sys.executable, "-m", "orchestrator.cli.app", "review", str(lacking)],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0 and done.stderr == "", done.stderr
    assert "–" in done.stdout


def test_a_header_without_a_readable_target_is_one_line(log, tmp_path):
    for header in ({"target_mass_kg": "x"}, {}):
        bad = rewrite(log, tmp_path / "header.mcap", header=lambda values, h=header: {
            **{k: v for k, v in values.items() if k != "target_mass_kg"}, **h})
        with pytest.raises(RunLogError, match="the header \\(excosim.run\\): target_mass_kg is "):
            read_run(bad)
        bad.unlink()
