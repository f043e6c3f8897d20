"""`excosim review` and `excosim compare` read a run log alone: the summary and JSON give back what
the campaign wrote, the figures are drawn, a killed run is reviewed up to its last complete period,
and a file that is not a run log is refused in one line."""

import json
import math
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap.writer import Writer
from mcap_protobuf.decoder import DecoderFactory
from run_log_files import cut_inside_chunk
from typer.testing import CliRunner

from orchestrator.campaign import run_campaign
from orchestrator.cli.app import app
from orchestrator.review.plots import PLOT_TOPICS, pile_profile_periods, tip_path_periods
from orchestrator.review.summary import run_figures
from orchestrator.runlog import read_run
from orchestrator.scenario import load_scenario

ROOT = Path(__file__).resolve().parent.parent
PAPER = ROOT / "scenarios" / "paper-2020.toml"
runner = CliRunner()


def _campaign(path: Path, *overrides: str):
    return run_campaign(load_scenario(PAPER, ["periods=3", *overrides]), log_path=path)


@pytest.fixture(scope="module")
def paper_run(tmp_path_factory):
    path = tmp_path_factory.mktemp("review") / "paper.mcap"
    return path, _campaign(path)


def _review(*args: str):
    return runner.invoke(app, ["review", *map(str, args)])


def test_json_gives_back_what_the_campaign_wrote(paper_run):
    path, result = paper_run
    done = _review(path, "--json")
    assert done.exit_code == 0, done.output
    data = json.loads(done.stdout)
    assert data["scenario"] == "paper-2020" and data["plant"] == "sim"
    assert data["target_mass_kg"] == 30.0 and data["termination"] == "periods"
    assert data["finished"] and not data["truncated"]
    assert data["periods"] == json.loads(json.dumps(result.records))
    errors = [abs(r["error_kg"]) for r in result.records[1:]]
    figures = data["figures"]
    assert figures["max_abs_error_kg"] == max(errors)
    assert math.isclose(figures["mean_abs_error_kg"], sum(errors) / len(errors))
    assert figures["within_band"] == sum(e <= 3.0 for e in errors) and figures["counted"] == 2


def test_the_table_shows_every_period_and_how_the_run_ended(paper_run):
    path, result = paper_run
    done = _review(path)
    assert done.exit_code == 0
    assert "dug all 3 planned periods" in done.stdout
    for record in result.records:
        assert f"{record['mass_kg']:.2f}" in done.stdout


def test_samples_decode_like_the_mcap_protobuf_decoder(paper_run):
    """Our vectorised decoder against mcap-protobuf-support's (protobuf's own parser)."""
    path, _ = paper_run
    run = read_run(path, topics=PLOT_TOPICS)
    with open(path, "rb") as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        for topic in ("/joints", "/cylinder/stick", "/pile/bucket", "/pile/profile"):
            messages = list(reader.iter_decoded_messages(topics=[topic]))
            channel = run.channels[topic]
            assert len(messages) == len(channel.log_time_ns)
            times = np.array([m.message.log_time for m in messages])
            assert np.array_equal(times, channel.log_time_ns)
            for name, values in channel.fields.items():
                expected = np.array([list(getattr(m.decoded_message, name))
                                     if values.ndim == 2 else getattr(m.decoded_message, name)
                                     for m in messages])
                assert np.array_equal(values, expected), (topic, name)


def test_samples_are_split_into_their_periods(paper_run):
    path, result = paper_run
    run = read_run(path, topics=("/joints",))
    joints = run.channels["/joints"]
    counts = []
    for record, end_ns in zip(result.records, run.period_end_ns, strict=True):
        samples = joints.of_period(record["k"])
        counts.append(len(samples["t_s"]))
        assert samples["t_s"][0] == pytest.approx(record["t0_s"], abs=1e-9)
        assert samples["t_s"][-1] == pytest.approx(end_ns * 1e-9, abs=1e-9)
    assert sum(counts) == len(joints.log_time_ns)


def test_plots_are_written_and_show_something(paper_run, tmp_path):
    import matplotlib.image

    path, _ = paper_run
    done = _review(path, "--plots", tmp_path / "figures", "--period", "2")
    assert done.exit_code == 0, done.output
    names = sorted(p.name for p in (tmp_path / "figures").iterdir())
    assert names == ["period_02_cylinder_pressures.png", "period_02_joints.png",
                     "pile_profiles.png", "productivity.png", "tip_paths.png",
                     "weight_error.png"]
    for name in names:
        image = matplotlib.image.imread(tmp_path / "figures" / name)
        assert image.shape[0] > 300 and image.shape[1] > 500
        assert image[..., :3].std() > 0.05, name  # not a blank canvas


def test_figure_period_choices_follow_the_paper():
    assert tip_path_periods(20) == [1, 3, 5, 7, 11, 13, 15, 17]
    assert tip_path_periods(4) == [1, 3]
    assert tip_path_periods(1) == [1]
    assert pile_profile_periods(20) == [10, 20] and pile_profile_periods(3) == [3]


def test_a_period_beyond_the_run_is_refused(paper_run, tmp_path):
    path, _ = paper_run
    done = _review(path, "--plots", tmp_path, "--period", "4")
    assert done.exit_code == 2
    assert done.stderr.strip() == f"excosim: --period 4: {path} holds periods 1-3"


def test_a_file_cut_inside_a_chunk_is_reviewed_up_to_its_last_complete_period(paper_run,
                                                                              tmp_path):
    path, result = paper_run
    cut = cut_inside_chunk(path, tmp_path / "killed.mcap")
    data = json.loads(_review(cut, "--json").stdout)
    assert data["periods"] == json.loads(json.dumps(result.records[:2]))
    assert not data["finished"] and data["truncated"] and data["termination"] is None
    done = _review(cut, "--plots", tmp_path / "figures")
    assert done.exit_code == 0
    assert "did not finish: the log holds 2 complete periods" in done.stdout
    assert (tmp_path / "figures" / "tip_paths.png").stat().st_size > 10_000


def test_files_that_are_not_run_logs_exit_2_in_one_line(tmp_path):
    text = tmp_path / "notes.mcap"
    text.write_text("not a log")
    other = tmp_path / "other.mcap"
    with open(other, "wb") as stream:
        writer = Writer(stream)
        writer.start()
        writer.finish()
    for path, reason in ((text, "is not an MCAP file"), (other, "not an excosim run log"),
                         (tmp_path / "missing.mcap", "cannot read")):
        for command in ("review", "compare"):
            done = runner.invoke(app, [command, str(path)])
            assert done.exit_code == 2
            assert done.stderr.count("\n") == 1 and reason in done.stderr
            assert "Traceback" not in done.stderr


def test_compare_shows_runs_with_different_noise_seeds_differ(tmp_path):
    paths = [tmp_path / f"seed{seed}.mcap" for seed in (1, 2)]
    for seed, path in zip((1, 2), paths, strict=True):
        _campaign(path, "plant.load_cell_noise_kg=1.0", f"seed={seed}", "periods=2")
    done = runner.invoke(app, ["compare", *map(str, paths), "--json"])
    assert done.exit_code == 0, done.output
    runs = json.loads(done.stdout)["runs"]
    assert [r["label"] for r in runs] == ["seed1", "seed2"]
    assert runs[0]["errors_kg"] != runs[1]["errors_kg"]
    assert runs[0]["figures"]["mean_abs_error_kg"] != runs[1]["figures"]["mean_abs_error_kg"]
    for run, path in zip(runs, paths, strict=True):
        records = read_run(path).periods
        assert run["errors_kg"] == [r["error_kg"] for r in records]
        assert run["figures"] == run_figures(records)
    done = runner.invoke(app, ["compare", *map(str, paths), "--plots", str(tmp_path / "cmp")])
    assert done.exit_code == 0
    assert "seed1" in done.stdout and "seed2" in done.stdout
    assert (tmp_path / "cmp" / "weight_error_compare.png").stat().st_size > 10_000


def test_compare_says_when_the_runs_differ_in_their_numerics(tmp_path):
    """Runs at another communication step dig other masses for a numerical reason; compare
    says which setting differs (table and --json), so it is not taken for the plant's."""
    paths = [tmp_path / "h10.mcap", tmp_path / "h5.mcap"]
    _campaign(paths[0], "periods=1")
    _campaign(paths[1], "periods=1", "plant.communication_step_s=0.005")
    done = runner.invoke(app, ["compare", *map(str, paths), "--json"])
    assert done.exit_code == 0, done.output
    assert json.loads(done.stdout)["differing_numerics"] == {
        "communication_step_s": [0.01, 0.005]}
    done = runner.invoke(app, ["compare", *map(str, paths)])
    assert "numerics that differ: communication_step_s 0.01 | 0.005" in \
        " ".join(done.stdout.split())
