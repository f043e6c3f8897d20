"""`excosim run --resume`: a run killed or interrupted after period k, resumed from its log,
gives the log of the uninterrupted run, message for message.

The reference is a 5-period paper campaign with load-cell noise and a seed (so the noise
generator's restore is tested). The kills are real (a subprocess of a 14-period run ended by
SIGKILL once its log holds two periods) and simulated (the log's bytes cut inside a period's
chunk, inside its message indexes, at its end); an interrupt is a KeyboardInterrupt after a
period. Compared: every message of every channel (topic, sequence, log time, bytes) through the
`mcap` package's indexed reader, the period records without their planner wall time, exactly
(stronger than the 1e-9 asked for masses, D and durations).
"""

from __future__ import annotations

import base64
import functools
import json
import os
import signal
import subprocess
import sys
import time
import zipfile
from pathlib import Path

import jsonschema
import numpy as np
import pytest
from kinematic_plant import KinematicPlant
from mcap.reader import make_reader
from mcap.records import DataEnd
from mcap.stream_reader import StreamReader
from run_log_files import chunks
from test_run_log_viewers import viewer_schema_errors
from typer.testing import CliRunner

import fmus
from orchestrator.campaign import run_campaign
from orchestrator.campaign.loop import open_run_log
from orchestrator.campaign.resume import ResumeRefused, prepare_resume, resume_campaign
from orchestrator.cli.app import app
from orchestrator.plants.master import Master
from orchestrator.plants.simulated_excavator import SimulatedExcavator
from orchestrator.runlog import RunLogError, read_run
from orchestrator.runlog.schemas import RESUME_STATE_SCHEMA
from orchestrator.scenario import load_scenario
from plant_models.model_spec import FmuSpec

ROOT = Path(__file__).resolve().parent.parent
PAPER = ROOT / "scenarios" / "paper-2020.toml"
PERIODS = 5
SETTINGS = [f"periods={PERIODS}", "plant.load_cell_noise_kg=0.5", "seed=7"]
TOLERANCE = 1e-9  # kg, m, s


def scenario(extra=()):
    return load_scenario(PAPER, [*SETTINGS, *extra])


@pytest.fixture(scope="module")
def folder(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("resume")


@pytest.fixture(scope="module")
def full(folder) -> Path:
    """The uninterrupted run."""
    path = folder / "full.mcap"
    result = run_campaign(scenario(), log_path=path)
    assert result.termination == "periods", result.message
    return path


def messages(path: Path) -> list[tuple[str, int, int, bytes]]:
    """(topic, sequence, log time, data) of every message, through the file's indexes; the
    /period and /period/start records without their planner wall time."""
    status = path.stat()
    return _messages(str(path), status.st_mtime_ns, status.st_size)


@functools.lru_cache(maxsize=2)
def _messages(path: str, *identity) -> list[tuple[str, int, int, bytes]]:
    out = []
    with open(path, "rb") as stream:
        for _, channel, message in make_reader(stream).iter_messages(log_time_order=False):
            data = message.data
            if channel.topic in ("/period", "/period/start"):
                record = json.loads(data)
                del record["planner_ms"]
                data = json.dumps(record, sort_keys=True).encode()
            out.append((channel.topic, message.sequence, message.log_time, data))
    return out


def assert_same_run(resumed: Path, full: Path, resumes: int = 1, periods: int = PERIODS) -> None:
    a, b = read_run(resumed), read_run(full)
    assert a.finished and a.termination == b.termination == "periods"
    assert len(a.periods) == len(b.periods) == periods
    for mine, theirs in zip(a.periods, b.periods, strict=True):
        for key in ("mass_kg", "error_kg", "duration_s", "t0_s"):
            assert abs(mine[key] - theirs[key]) <= TOLERANCE, (mine["k"], key)
        assert mine["deepest_point_m"] == theirs["deepest_point_m"]
        assert {**mine, "planner_ms": 0} == {**theirs, "planner_ms": 0}
    assert messages(resumed) == messages(full)
    assert a.resume_states == b.resume_states  # the plant's states too, byte for byte
    with open(resumed, "rb") as stream:  # indexes and statistics of a file the mcap reader opens
        summary = make_reader(stream).get_summary()
    with open(full, "rb") as stream:
        reference = make_reader(stream).get_summary()
    assert summary.statistics.channel_message_counts == \
        reference.statistics.channel_message_counts
    assert summary.statistics.chunk_count == reference.statistics.chunk_count
    # One excosim.resumed record per resume.
    assert summary.statistics.metadata_count == reference.statistics.metadata_count + resumes
    with open(resumed, "rb") as stream:  # the data section's CRC covers the copied bytes too
        records = list(StreamReader(stream, validate_crcs=True).records)
    assert next(r for r in records if isinstance(r, DataEnd)).data_section_crc != 0


def cut(full: Path, target: Path, at: int) -> Path:
    target.write_bytes(full.read_bytes()[:at])
    return target


def cut_points(full: Path) -> dict[str, tuple[int, int]]:
    """name -> (byte to cut at, the period a resume continues after)."""
    periods = chunks(full)  # the chunks holding the periods' records
    third, first, fourth = periods[2], periods[0], periods[3]
    return {
        "inside period 3's chunk": (third.chunk_start_offset + third.chunk_length // 2, 2),
        "inside period 1's message indexes": (
            first.chunk_start_offset + first.chunk_length + first.message_index_length // 2, 1),
        "after period 4, as a flush leaves it": (
            fourth.chunk_start_offset + fourth.chunk_length + fourth.message_index_length, 4),
    }


@pytest.mark.parametrize("where", ["inside period 3's chunk", "inside period 1's message "
                                   "indexes", "after period 4, as a flush leaves it"])
def test_a_log_cut_anywhere_resumes_to_the_uninterrupted_run(full, folder, where):
    at, after = cut_points(full)[where]
    path = cut(full, folder / f"cut-{after}.mcap", at)
    source = prepare_resume(path)
    assert source.k == after
    result = resume_campaign(source)
    assert result.termination == "periods", result.message
    assert [r["k"] for r in result.records] == list(range(1, PERIODS + 1))
    assert_same_run(path, full)
    # The kept part is the original's bytes (the rebuilt message indexes included).
    kept = chunks(full)[after].chunk_start_offset if after < PERIODS else None
    assert path.read_bytes()[:kept] == full.read_bytes()[:kept]
    assert read_run(path).metadata["excosim.resumed"]["after_period"] == str(after)
    assert [p.name for p in folder.iterdir() if p.name.endswith(".resuming")] == []


def test_a_run_killed_with_sigkill_resumes_on_the_command_line(folder):
    # Long enough that the kill lands before the end: a period takes some 25 ms here, and
    # looking into the log for its second one up to 15 ms (a 5-period run once ended first).
    periods = 14
    settings = [*SETTINGS, f"periods={periods}"]
    full = folder / "full-14.mcap"
    assert run_campaign(load_scenario(PAPER, settings), log_path=full).termination == "periods"
    path = folder / "killed.mcap"
    command = [sys.executable, "-c", "from orchestrator.cli.app import main; main()", "run",
               str(PAPER), "-o", str(path), "-q", *(f"--set={item}" for item in settings)]
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    child = subprocess.Popen(command, env=env, stdout=subprocess.DEVNULL,
                             stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 300
        while time.monotonic() < deadline and child.poll() is None:
            try:
                if len(read_run(path).periods) >= 2:
                    break
            except RunLogError:  # not written far enough yet
                pass
            time.sleep(0.01)
        child.send_signal(signal.SIGKILL)
    finally:
        child.wait(timeout=60)
    assert child.returncode == -signal.SIGKILL
    killed = read_run(path)
    assert not killed.finished and 2 <= len(killed.periods) < periods
    done = CliRunner().invoke(app, ["run", "--resume", str(path)])
    assert done.exit_code == 0, done.output
    assert f"resumed after period {len(killed.periods)}: dug all {periods}" in done.stdout
    assert_same_run(path, full, periods=periods)
    review = CliRunner().invoke(app, ["review", str(path), "--json"])
    assert review.exit_code == 0, review.output
    summary = json.loads(review.stdout)
    assert summary["finished"] and summary["termination"] == "periods"
    assert len(summary["periods"]) == periods
    assert summary["resumed_after_period"] == len(killed.periods)
    text = CliRunner().invoke(app, ["review", str(path)])
    assert text.exit_code == 0 and f"(resumed after period {len(killed.periods)})" in text.stdout


def test_a_run_that_is_still_writing_its_log_is_not_resumed(folder):
    """The writer holds its log's lock while the run goes (orchestrator.runlog.lock): a resume
    meanwhile is refused, before anything is written; once the run has ended, it is not."""
    path = folder / "going.mcap"
    seen: list[str] = []

    def meanwhile(record):  # period 1 is logged, the run goes on
        with pytest.raises(ResumeRefused, match="is being written by a run that is still "
                           "going") as refused:
            prepare_resume(path)
        seen.append(str(refused.value))
        with pytest.raises(OSError, match="is being written by a run that is still going"):
            open_run_log(scenario(), path, overwrite=True)  # nor is it written over
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_campaign(scenario(), log_path=path, progress=meanwhile)
    assert len(seen) == 1 and len(read_run(path).periods) == 1
    assert prepare_resume(path).k == 1  # the run has ended: its lock is gone


def test_an_interrupted_resume_resumes_again_and_output_leaves_the_original(full, folder):
    at, _ = cut_points(full)["inside period 3's chunk"]
    original = cut(full, folder / "twice.mcap", at)
    before = original.read_bytes()

    def stop_after_period_3(record):
        if record["k"] == 3:
            raise KeyboardInterrupt

    copy = folder / "twice-resumed.mcap"
    with pytest.raises(KeyboardInterrupt):
        resume_campaign(prepare_resume(original), copy, progress=stop_after_period_3)
    assert original.read_bytes() == before  # -o: the original is left as it was
    stopped = read_run(copy)
    assert (stopped.termination, stopped.termination_message) == ("error", "interrupted")
    assert len(stopped.periods) == 3
    result = CliRunner().invoke(app, ["run", "--resume", str(copy), "-q"])
    assert result.exit_code == 0, result.output
    assert_same_run(copy, full, resumes=2)


def test_fmi3_builds_resume_too(folder):
    """Our FMI 3.0 builds serialize through fmi3SerializeFMUState."""
    cylinder, pile = fmus.build("HydraulicCylinder", 3), fmus.build("Pile", 3)
    plant = "fmi3"
    scenario = load_scenario(PAPER, [
        "periods=3", "plant.load_cell_noise_kg=0.3", "seed=2", f"plant.pile.fmu={pile}",
        *(f"plant.{role}.fmu={cylinder}" for role in ("boom", "stick", "bucket"))])
    whole, stopped = folder / f"{plant}.mcap", folder / f"{plant} stopped.mcap"
    run_campaign(scenario, log_path=whole)
    cut(whole, stopped, chunks(whole)[1].chunk_start_offset + 100)
    assert resume_campaign(prepare_resume(stopped)).termination == "periods"
    a, b = read_run(stopped), read_run(whole)
    assert [{**r, "planner_ms": 0} for r in a.periods] == \
        [{**r, "planner_ms": 0} for r in b.periods]
    assert len(a.periods) == 3 and a.resume_states == b.resume_states


def test_a_component_in_other_units_restores_its_outputs_and_continues_identically():
    """A component whose outputs the master converts (here x in mm) keeps its own copies of
    them: a restore refills those too, as the step that reached the state left them."""
    spec = FmuSpec.from_table("HydraulicCylinder", {"mass": 2000.0},
                              {"x": {"variable": "x", "scale": 1e-3}})
    step_s, start = 0.005, {"boom": {"x0": 0.6, "F_ext": 2e4}}

    def drive(component, ks) -> np.ndarray:
        rows = []
        for k in ks:
            component.inputs[component.input_index["u"]] = np.sin(0.02 * k)
            component.step(k * step_s, step_s)
            rows.append(component.outputs.copy())
        return np.array(rows)

    with Master({"boom": ("cylinder", spec)}, step_s, start) as first:
        boom = first["boom"]
        assert boom.conversions  # the master's own output copies, not the FMU's buffer
        drive(boom, range(200))
        saved, at_save = boom.save_state(), boom.outputs.copy()
        after = drive(boom, range(200, 400))
    with Master({"boom": ("cylinder", spec)}, step_s, start) as second:
        boom = second["boom"]
        boom.restore_state(saved)
        assert np.array_equal(boom.outputs, at_save)
        assert np.array_equal(drive(boom, range(200, 400)), after)


def test_the_resume_state_is_small_typed_and_readable_by_the_viewers(full):
    run = read_run(full)
    assert sorted(run.resume_states) == list(range(1, PERIODS + 1))
    assert viewer_schema_errors(RESUME_STATE_SCHEMA) == []
    with open(full, "rb") as stream:
        summary = make_reader(stream).get_summary()
    channel = next(c for c in summary.channels.values() if c.topic == "/resume")
    stored = json.loads(summary.schemas[channel.schema_id].data)
    assert stored == RESUME_STATE_SCHEMA and channel.message_encoding == "json"
    for k, data in run.resume_states.items():
        record = json.loads(data)
        jsonschema.validate(record, stored)
        assert record["k"] == k and len(data) < 16_000  # bytes of JSON per period
        assert set(record["plant"]["fmus"]) == {"boom", "stick", "bucket", "pile"}


# -- what is refused ---------------------------------------------------------------------------


def refused(args: list[str], folder: Path, code: int = 2) -> str:
    """The one line of a refused `excosim run ...`; asserts that nothing in `folder` changed."""
    before = {p.name: p.read_bytes() for p in folder.iterdir() if p.is_file()}
    result = CliRunner().invoke(app, ["run", *args])
    assert result.exit_code == code, result.output
    assert "Traceback" not in result.output
    lines = result.stderr.splitlines()
    assert len(lines) == 1, result.stderr
    assert {p.name: p.read_bytes() for p in folder.iterdir() if p.is_file()} == before
    return lines[0]


@pytest.fixture(scope="module")
def cut_log(full, folder) -> Path:
    """The reference run killed in period 3, in a folder of its own."""
    (folder / "bad").mkdir()
    at, _ = cut_points(full)["inside period 3's chunk"]
    return cut(full, folder / "bad" / "cut.mcap", at)


def test_the_mistakes_of_the_command_line_are_one_line(cut_log):
    bad = cut_log.parent
    assert refused(["--resume", str(bad / "missing.mcap")], bad).endswith(
        "No such file or directory")
    (bad / "text.mcap").write_text("not a log")
    assert "is not an MCAP file" in refused(["--resume", str(bad / "text.mcap")], bad)
    assert refused([str(PAPER), "--resume", str(cut_log)], bad) == (
        "excosim: --resume continues the run as its log recorded it: no SCENARIO.toml with it")
    assert refused(["--resume", str(cut_log), "--set", "periods=9", "--periods", "9"], bad) \
        == ("excosim: --resume continues the run as its log recorded it: no --set, --periods "
            "with it")
    assert refused([], bad).startswith("excosim: missing argument 'SCENARIO.toml'")
    (bad / "taken.mcap").write_bytes(b"precious")
    assert "already exists" in refused(["--resume", str(cut_log), "-o",
                                        str(bad / "taken.mcap")], bad)


def test_a_finished_run_has_nothing_to_resume(full):
    before = full.read_bytes()
    result = CliRunner().invoke(app, ["run", "--resume", str(full)])
    assert result.exit_code == 0, result.output
    assert result.stdout == (f"{full}: nothing to resume: the run finished (dug all "
                             f"{PERIODS} planned periods)\n")
    assert full.read_bytes() == before


def test_a_log_without_resume_states_or_periods_is_refused(full, folder):
    bad = folder / "stateless"
    bad.mkdir()
    plain = load_scenario(PAPER, ["periods=2"])
    plant = KinematicPlant(plain.geometry())  # a plant that cannot save its state
    kinematic = bad / "kinematic.mcap"
    run_campaign(plain, log_path=kinematic, plant=plant)
    cut(kinematic, kinematic, chunks(kinematic)[1].chunk_start_offset + 100)  # killed
    assert "holds no resume state" in refused(["--resume", str(bad / "kinematic.mcap")], bad)
    first = chunks(full)[0]
    cut(full, bad / "early.mcap", first.chunk_start_offset + 100)  # killed in period 1
    assert "holds no complete period" in refused(["--resume", str(bad / "early.mcap")], bad)
    lab = load_scenario(ROOT / "scenarios" / "lab.toml", ["plant.kind=lab"])
    open_run_log(lab, bad / "lab.mcap").close("error", "interrupted")
    assert "is a lab run" in refused(["--resume", str(bad / "lab.mcap")], bad)


def test_other_fmus_than_the_logged_ones_are_refused(folder):
    bad = folder / "other-fmus"
    bad.mkdir()
    copy = bad / "Cylinder.fmu"
    copy.write_bytes(fmus.build("HydraulicCylinder").read_bytes())
    path = bad / "run.mcap"
    run_campaign(load_scenario(PAPER, ["periods=2", f"plant.boom.fmu={copy}"]),
                 log_path=path)
    cut(path, path, chunks(path)[1].chunk_start_offset + 100)  # killed in period 2
    with zipfile.ZipFile(fmus.build("HydraulicCylinder")) as ours, \
            zipfile.ZipFile(copy, "w") as changed:  # the same file name, other sources
        for info in ours.infolist():
            data = ours.read(info)
            changed.writestr(info, data + b"/* changed */\n" if info.filename ==
                             "sources/model.c" else data)
    line = refused(["--resume", str(path), "--trust"], bad)
    assert "the boom FMU that would run now" in line and "not the same run" in line


def _corrupt_pile(state: dict, how: str) -> None:
    data = bytearray(base64.b64decode(state["fmus"]["pile"]))
    if how == "a flipped byte":
        data[len(data) // 2] ^= 0x01
    elif how == "cut short":
        data = data[:-8]
    else:  # another model's state
        data = bytearray(base64.b64decode(state["fmus"]["boom"]))
    state["fmus"]["pile"] = base64.b64encode(bytes(data)).decode()


@pytest.mark.parametrize(("how", "reason"), [
    ("a flipped byte", "checksum mismatch"),
    ("cut short", "is not a serialized Pile state"),
    ("another model's", "is not a serialized Pile state"),
])
def test_the_fmu_refuses_a_damaged_state(cut_log, how, reason):
    source = prepare_resume(cut_log)
    _corrupt_pile(source.record["plant"], how)
    before = cut_log.read_bytes()
    with pytest.raises(ResumeRefused, match=reason) as refusal:
        resume_campaign(source)
    assert "pile: its FMU refused the saved state" in str(refusal.value)
    assert cut_log.read_bytes() == before


def test_a_logged_state_that_its_fmu_refuses_exits_2_before_writing(folder, monkeypatch):
    bad = folder / "corrupt"
    bad.mkdir()
    saved = SimulatedExcavator.resume_state

    def corrupted(plant):
        state = saved(plant)
        _corrupt_pile(state, "a flipped byte")
        return state

    monkeypatch.setattr(SimulatedExcavator, "resume_state", corrupted)
    path = bad / "run.mcap"
    run_campaign(load_scenario(PAPER, ["periods=2"]), log_path=path)
    monkeypatch.undo()
    cut(path, path, chunks(path)[1].chunk_start_offset + 100)
    line = refused(["--resume", str(path)], bad)
    assert line.startswith(f"excosim: {path}: the state after period 1: pile: its FMU refused")
    assert "it is corrupt (checksum mismatch)" in line


def test_a_terrain_run_resumes_with_what_its_strategy_had_learnt(folder):
    """The terrain strategy's surfaces and estimates travel in the resume record: the resumed
    run decides exactly as the uninterrupted one."""
    terrain = scenario(["adaptation.strategy=terrain", "adaptation.assumed_repose_angle_deg=40.4"])
    reference = folder / "terrain-full.mcap"
    assert run_campaign(terrain, log_path=reference).termination == "periods"
    at, after = cut_points(reference)["inside period 3's chunk"]
    path = cut(reference, folder / "terrain-cut.mcap", at)
    result = resume_campaign(prepare_resume(path))
    assert result.termination == "periods", result.message
    assert_same_run(path, reference)
    saved = json.loads(read_run(path).resume_states[after])
    jsonschema.validate(saved, RESUME_STATE_SCHEMA)
    assert len(saved["strategy"]["hypotheses"]) == len(saved["strategy"]["weights"]) > 1
