"""`excosim replay`: a simulated run re-run from its MCAP file alone repeats every period.

The logged numbers come from real campaigns (the paper scenario, two periods); hashes are
checked with hashlib against our own builds; a killed run is a file cut inside a period's
chunk, located through the `mcap` package's own summary reader.
"""

import dataclasses
import hashlib
import json
import shutil
import zipfile
from pathlib import Path

import pytest
from run_log_files import chunks, cut_inside_chunk

import fmus
from orchestrator.campaign import loop as campaign
from orchestrator.campaign import run_campaign
from orchestrator.cli.replay import replay
from orchestrator.review.replay import (
    ReplayRefused,
    ReplayReport,
    check_fmus,
    compare_periods,
    replay_run,
)
from orchestrator.runlog import RunDescription, RunLog, read_run
from orchestrator.scenario import load_scenario, scenario_from_dict

ROOT = Path(__file__).resolve().parent.parent
PAPER = ROOT / "scenarios" / "paper-2020.toml"
TOLERANCE = 1e-9  # kg, m, s: the brief's bound for a deterministic re-run


def _campaign(folder: Path, name: str, scenario):
    path = folder / f"{name}.mcap"
    result = run_campaign(scenario, log_path=path)
    assert result.termination in ("periods", "workspace_limit"), result.message
    return path, result.records


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    return tmp_path_factory.mktemp("runs")


@pytest.fixture(scope="module")
def paper_run(runs):
    return _campaign(runs, "paper", load_scenario(PAPER, ["periods=2"]))


@pytest.fixture(scope="module")
def noisy_run(runs):
    return _campaign(runs, "noisy", load_scenario(
        PAPER, ["periods=2", "plant.load_cell_noise_kg=0.5", "seed=1"]))


@pytest.fixture(scope="module")
def annotated_fmu(runs) -> Path:
    """Our cylinder FMU with one more file in its zip: other bytes, the same model."""
    path = runs / "HydraulicCylinder-annotated.fmu"
    shutil.copyfile(fmus.build("HydraulicCylinder"), path)
    with zipfile.ZipFile(path, "a") as archive:
        archive.writestr("documentation/notes.txt", "built from the excosim sources\n")
    return path


@pytest.fixture(scope="module")
def foreign_fmu(runs) -> Path:
    """Our cylinder FMU with a comment added to its sources/model.c: the same binary, but no
    longer what our sources build (another content hash)."""
    path = runs / "HydraulicCylinder-foreign.fmu"
    with zipfile.ZipFile(fmus.build("HydraulicCylinder")) as ours, \
            zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as theirs:
        for info in ours.infolist():
            data = ours.read(info)
            theirs.writestr(info, data + b"/* vendored */\n" if info.filename ==
                            "sources/model.c" else data)
    return path


def _boom_run(runs, fmu: Path, name: str):
    data = load_scenario(PAPER, ["periods=2"]).to_dict()
    data["plant"]["boom"]["fmu"] = str(fmu)  # its parameters and ports stay
    return _campaign(runs, name, scenario_from_dict(data, source=name))


@pytest.fixture(scope="module")
def annotated_run(runs, annotated_fmu):
    return _boom_run(runs, annotated_fmu, "annotated")


@pytest.fixture(scope="module")
def foreign_run(runs, foreign_fmu):
    return _boom_run(runs, foreign_fmu, "foreign")


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _assert_repeats(report: ReplayReport, records: list[dict]) -> None:
    assert report.matches and report.first_difference() is None
    assert [p.k for p in report.periods] == [r["k"] for r in records]
    for period, record in zip(report.periods, records, strict=True):
        assert period.mass_kg_logged == record["mass_kg"]
        assert period.mass_kg_replayed == pytest.approx(record["mass_kg"], abs=TOLERANCE)
        assert period.deepest_point_m_replayed == pytest.approx(record["deepest_point_m"],
                                                                abs=TOLERANCE)
        assert period.duration_s_replayed == pytest.approx(record["duration_s"], abs=TOLERANCE)


def test_a_simulated_run_replays_to_the_same_periods(paper_run):
    path, records = paper_run
    report = replay_run(path)
    _assert_repeats(report, records)
    assert report.termination_compared and report.replayed_termination == "periods"
    assert report.max_abs_diff_mass_kg <= TOLERANCE
    ours = {"HydraulicCylinder": _sha256(fmus.build("HydraulicCylinder")),
            "Pile": _sha256(fmus.build("Pile"))}
    for component in ("boom", "stick", "bucket", "pile"):
        model = "Pile" if component == "pile" else "HydraulicCylinder"
        assert report.fmus[component].sha256 == ours[model]
        assert report.fmus[component].trusted_by == "local build"


def test_load_cell_noise_replays_from_the_files_seed(noisy_run, paper_run):
    path, records = noisy_run
    # The noise is really there (0.5 kg standard deviation): the weighings differ from the
    # noiseless run's, and so does period 2's D, which the adaptation took from them.
    noiseless = paper_run[1]
    assert abs(records[0]["mass_kg"] - noiseless[0]["mass_kg"]) > 0.05
    assert records[1]["deepest_point_m"] != noiseless[1]["deepest_point_m"]
    _assert_repeats(replay_run(path), records)


def test_an_fmu_that_is_not_our_build_needs_trust(foreign_run, foreign_fmu, paper_run):
    path, records = foreign_run
    digest = _sha256(foreign_fmu)
    assert fmus.content_hash(foreign_fmu) != fmus.content_hash(fmus.build("HydraulicCylinder"))
    with pytest.raises(ReplayRefused) as refused:
        replay_run(path)
    message = str(refused.value)
    assert "\n" not in message and "--trust" in message and "native code" in message
    assert "component boom (fmus/HydraulicCylinder-foreign.fmu" in message
    assert digest[:12] in message and "stick" not in message

    report = replay_run(path, trust=True)
    _assert_repeats(report, records)
    assert report.fmus["boom"].trusted_by == "--trust" and report.fmus["boom"].sha256 == digest
    assert report.fmus["boom"].content_sha256 == fmus.content_hash(foreign_fmu)
    assert report.fmus["stick"].trusted_by == "local build"
    # Only a comment in the sources changed, not the binary: the run equals the plain one.
    assert [r["mass_kg"] for r in records] == [r["mass_kg"] for r in paper_run[1]]


def test_our_build_in_another_zip_is_our_build(annotated_run, annotated_fmu, paper_run):
    """Identity is content: a documentation file more changes the zip's bytes, not the FMU."""
    path, records = annotated_run
    assert _sha256(annotated_fmu) != _sha256(fmus.build("HydraulicCylinder"))
    report = replay_run(path)
    _assert_repeats(report, records)
    assert report.fmus["boom"].trusted_by == "local build"
    assert report.fmus["boom"].sha256 == _sha256(annotated_fmu)
    assert read_run(path).metadata["excosim.fmu_content"]["boom"] == fmus.content_hash(
        fmus.build("HydraulicCylinder"))
    assert [r["mass_kg"] for r in records] == [r["mass_kg"] for r in paper_run[1]]


def _linked_fmu(folder: Path) -> Path:
    """Our cylinder FMU with one more entry: a symbolic link out of the extraction folder."""
    path = folder / "linked.fmu"
    shutil.copyfile(fmus.build("HydraulicCylinder"), path)
    link = zipfile.ZipInfo("resources/passwd")
    link.create_system, link.external_attr = 3, (0o120777 << 16)
    with zipfile.ZipFile(path, "a") as archive:
        archive.writestr(link, "/etc/passwd")
    return path


def test_an_unsafe_attachment_is_refused_even_with_trust(paper_run, tmp_path):
    cylinder, pile = _linked_fmu(tmp_path), fmus.build("Pile")
    data = load_scenario(PAPER, ["periods=1"]).to_dict()
    path = tmp_path / "linked.mcap"
    log = RunLog(path, RunDescription(
        scenario=data, scenario_text=json.dumps(data), scenario_name="linked",
        fmus={"boom": cylinder, "stick": fmus.build("HydraulicCylinder"),
              "bucket": fmus.build("HydraulicCylinder"), "pile": pile},
        plant_kind="sim", target_mass_kg=30.0))
    log.close("error", "period 1: RuntimeError: stopped")  # a replay would dig period 1
    for trust in (False, True):
        with pytest.raises(ReplayRefused) as refused:
            replay_run(path, trust=trust)
        message = str(refused.value)
        assert "\n" not in message and "'resources/passwd' is a link" in message
        assert "component boom: attachment 'fmus/linked.fmu'" in message
        assert "not even with --trust" in message


@pytest.mark.parametrize("name", ["fmus/../../x.fmu", "/tmp/x.fmu", "fmus/x\x00.fmu"])
def test_an_attachment_name_that_reaches_outside_is_refused(paper_run, name):
    run = read_run(paper_run[0])
    attachments = dict(run.metadata["excosim.fmu_attachments"], boom=name)
    forged = dataclasses.replace(run, metadata={**run.metadata,
                                                "excosim.fmu_attachments": attachments})
    with pytest.raises(ReplayRefused, match="component boom: attachment .* not replayed "
                       r"\(not even with --trust\)"):
        check_fmus(forged, trust=True)


def test_an_altered_attachment_is_refused_even_with_trust(paper_run, tmp_path):
    path, _ = paper_run
    cylinder = fmus.build("HydraulicCylinder").read_bytes()
    data = bytearray(path.read_bytes())
    start = data.find(cylinder)
    assert start > 0  # attachments are stored as they are
    data[start + len(cylinder) // 2] ^= 0x01  # one bit of the attached FMU
    altered = tmp_path / "altered.mcap"
    altered.write_bytes(bytes(data))
    assert read_run(altered).periods == read_run(path).periods  # still a readable run log
    for trust in (False, True):
        with pytest.raises(ReplayRefused, match=r"component boom: attachment "
                           r"fmus/HydraulicCylinder\.fmu has sha256 .* the file was altered"):
            replay_run(altered, trust=trust)


def test_a_killed_run_replays_its_complete_periods(paper_run, tmp_path):
    path, records = paper_run
    cut = cut_inside_chunk(path, tmp_path / "killed.mcap", index=1)  # one chunk per period
    report = replay_run(cut)
    _assert_repeats(report, records[:1])
    assert report.logged_termination is None and not report.termination_compared


def test_a_run_that_hit_the_workspace_limit_replays_to_the_same_end(runs):
    # A deep D0 and a target far above what the periods dig: the steps reach the long stick's
    # reach (z = -2.30 m at y = -9 m) in period 3, and the shift by 20 m is out of reach too. A
    # bucket that never fills: a full one dragged deep pushes more spoil than it can cut. That
    # deep cut makes the bucket lag 19.6 deg in period 3: a bound of 30 deg lets the run reach
    # its workspace limit (the bound's own test is tests/test_tracking_bound.py).
    path, records = _campaign(runs, "workspace", load_scenario(PAPER, [
        "periods=5", "adaptation.z_D0_m=-0.6", "adaptation.dy_0_m=20", "target_mass_kg=300",
        "plant.pile.parameters.capacity=0.5", "plant.max_tracking_error_deg=30"]))
    assert read_run(path).termination == "workspace_limit" and len(records) < 5
    report = replay_run(path)
    _assert_repeats(report, records)
    assert report.termination_compared and report.replayed_termination == "workspace_limit"


def test_a_lab_run_is_refused(paper_run, tmp_path):
    scenario = load_scenario(PAPER)
    path = tmp_path / "lab.mcap"
    with RunLog(path, RunDescription(
            scenario=scenario.to_dict(), scenario_text=scenario.source_text, scenario_name="lab",
            fmus={"pile": fmus.build("Pile")}, plant_kind="lab", target_mass_kg=3.5)):
        pass
    with pytest.raises(ReplayRefused, match="lab run: it was measured on the real machine"):
        replay_run(path, trust=True)


def _record(k: int, mass: float, z: float = -0.1, duration: float = 12.7) -> dict:
    return {"k": k, "mass_kg": mass, "deepest_point_m": [-9.0, z], "duration_s": duration}


def test_compare_periods_flags_each_difference_beyond_the_tolerance():
    logged = [_record(1, 8.5), _record(2, 12.5, z=-0.3)]
    same = compare_periods(logged, [dict(r) for r in logged])
    assert [p.matches for p in same] == [True, True]
    assert [p.abs_diff_mass_kg for p in same] == [0.0, 0.0]

    heavier = compare_periods(logged, [_record(1, 8.5), _record(2, 12.5 + 1e-6, z=-0.3)])
    assert [p.matches for p in heavier] == [True, False]
    assert heavier[1].abs_diff_mass_kg == pytest.approx(1e-6, rel=1e-6)
    assert heavier[1].difference().startswith("mass 12.5 kg logged, 12.500001")

    within = compare_periods(logged, [_record(1, 8.5 + 4e-10), _record(2, 12.5, z=-0.3)])
    assert all(p.matches for p in within)
    deeper = compare_periods(logged, [_record(1, 8.5), _record(2, 12.5, z=-0.3 - 1e-6)])
    assert not deeper[1].matches and deeper[1].abs_diff_deepest_point_m > TOLERANCE
    longer = compare_periods(logged, [_record(1, 8.5, duration=12.8), logged[1]])
    assert not longer[0].matches and longer[0].abs_diff_duration_s == pytest.approx(0.1)


def test_compare_periods_flags_a_different_number_of_periods():
    logged = [_record(1, 8.5), _record(2, 12.5)]
    shorter = compare_periods(logged, logged[:1])
    assert [(p.k, p.matches) for p in shorter] == [(1, True), (2, False)]
    assert shorter[1].mass_kg_replayed is None and shorter[1].difference() == \
        "logged, not replayed"
    longer = compare_periods(logged[:1], logged)
    assert longer[1].mass_kg_logged is None and not longer[1].matches


def test_compare_periods_names_a_bad_record():
    with pytest.raises(ValueError, match="logged period record 1: mass_kg must be a number"):
        compare_periods([{"k": 1, "deepest_point_m": [-9, -0.1], "duration_s": 1.0}], [])
    with pytest.raises(ValueError, match="tolerance must be a finite number >= 0"):
        compare_periods([], [], tolerance=-1.0)


def test_a_report_differs_when_the_ending_differs():
    periods = compare_periods([_record(1, 8.5)], [_record(1, 8.5)])
    report = ReplayReport(path=Path("run.mcap"), tolerance=TOLERANCE, periods=periods, fmus={},
                          logged_termination="workspace_limit", replayed_termination="periods",
                          replayed_message="1 period(s) dug", termination_compared=True)
    assert not report.matches
    assert report.first_difference().startswith("the ending: logged 'workspace_limit'")
    killed = dataclasses.replace(report, logged_termination=None, termination_compared=False)
    assert killed.matches


def test_replay_command_json_and_exit_status(paper_run, capsys):
    path, records = paper_run
    assert replay(path, trust=False, as_json=True) is None
    answer = json.loads(capsys.readouterr().out)
    assert answer["matches"] is True and answer["tolerance"] == TOLERANCE
    assert answer["path"] == str(path)
    assert [p["mass_kg_logged"] for p in answer["periods"]] == [r["mass_kg"] for r in records]
    assert all(abs(p["mass_kg_replayed"] - p["mass_kg_logged"]) <= TOLERANCE
               for p in answer["periods"])
    assert answer["fmus"]["pile"]["sha256"] == _sha256(fmus.build("Pile"))


def test_replay_command_prints_a_table_and_refuses_in_one_line(foreign_run, tmp_path,
                                                                capsys):
    text = tmp_path / "notes.mcap"
    text.write_text("not a run log\n")
    message, status = replay(text, trust=False, as_json=False)
    assert status == 2 and "\n" not in message and "is not an MCAP file" in message

    message, status = replay(foreign_run[0], trust=False, as_json=True)
    assert status == 2 and "--trust" in message
    assert capsys.readouterr().out == ""


def test_replay_command_reports_a_plant_that_weighs_differently(paper_run, tmp_path,
                                                                monkeypatch, capsys):
    path, records = paper_run
    second = chunks(path)[1]
    cut = tmp_path / "one-period.mcap"
    cut.write_bytes(path.read_bytes()[:second.chunk_start_offset])
    real_build = campaign.build_plant

    class HeavierLoadCell:
        """The simulated excavator with its load cell reading 1e-6 kg more."""

        def __init__(self, scenario):
            self._plant = real_build(scenario)

        def run_period(self, reference):
            measured = self._plant.run_period(reference)
            return dataclasses.replace(measured, weighed_mass_kg=measured.weighed_mass_kg + 1e-6)

        def __getattr__(self, name):
            return getattr(self._plant, name)

    monkeypatch.setattr(campaign, "build_plant", HeavierLoadCell)
    message, status = replay(cut, trust=False, as_json=False)
    assert status == 1
    assert message.startswith("replay differs from the log in period 1: mass "
                              f"{records[0]['mass_kg']!r} kg logged")
    out = capsys.readouterr().out
    assert "replay differs from the log: 1 period," in out and "killed" in out
    assert "1e-06" in out  # |d mass| in the table


def test_replay_command_refuses_a_scenario_this_version_does_not_accept(tmp_path):
    data = load_scenario(PAPER).to_dict()
    data["trajectory"]["k_S"] = 0.5  # a key of another version
    cylinder, pile = fmus.build("HydraulicCylinder"), fmus.build("Pile")
    path = tmp_path / "future.mcap"
    log = RunLog(path, RunDescription(
        scenario=data, scenario_text=json.dumps(data), scenario_name="future",
        fmus={"boom": cylinder, "stick": cylinder, "bucket": cylinder, "pile": pile},
        plant_kind="sim", target_mass_kg=30.0))
    log.close("error", "period 1: RuntimeError: stopped")
    message, status = replay(path, trust=False, as_json=False)
    assert status == 2 and "\n" not in message
    assert "the run's scenario does not validate with this version" in message
    assert "trajectory.k_S: unknown key" in message


def test_the_command_line_replays_and_refuses(paper_run, foreign_run):
    from typer.testing import CliRunner

    from orchestrator.cli.app import app

    runner = CliRunner()
    done = runner.invoke(app, ["replay", str(paper_run[0])])
    assert done.exit_code == 0, done.output
    assert "replay matches the log: 2 periods" in done.stdout
    done = runner.invoke(app, ["replay", str(foreign_run[0])])
    assert done.exit_code == 2 and done.stderr.count("\n") == 1
    assert "boom" in done.stderr and "--trust" in done.stderr
