"""The tables of `run`, `review`, `compare` and `replay` never lose a figure at any width (80 or
200 columns, or a pipe), and `review --csv/--csv-channels` write CSV files that read back equal
to the log."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from kinematic_plant import KinematicPlant
from rich.console import Console
from typer.testing import CliRunner

from orchestrator.campaign import loop as campaign
from orchestrator.campaign import run_campaign
from orchestrator.campaign.record import records_dataframe
from orchestrator.cli import tables
from orchestrator.cli.app import app
from orchestrator.review import summary
from orchestrator.runlog import read_run
from orchestrator.scenario import load_scenario

ROOT = Path(__file__).resolve().parent.parent
PAPER = ROOT / "scenarios" / "paper-2020.toml"
LONG = Path("a folder with a rather long name") / "and another level below it" / "runs"
# Terminal widths to print at; None: a pipe without COLUMNS (the subprocess's stdout).
WIDTHS = ["80", "200", None]


@pytest.fixture(scope="module")
def kinematic_runs(tmp_path_factory):
    """Three 12-period runs (test double), all named run.mcap, deep in long folders."""
    root = tmp_path_factory.mktemp("kinematic")
    paths = []
    for name, target in (("a", 30), ("b", 25), ("c", 40)):
        path = root / name / LONG / "run.mcap"
        path.parent.mkdir(parents=True)
        scenario = load_scenario(PAPER, ["periods=12", f"target_mass_kg={target}"])
        run_campaign(scenario, log_path=path, plant=KinematicPlant(scenario.geometry()))
        paths.append(path)
    return paths


@pytest.fixture(scope="module")
def sim_run(tmp_path_factory):
    """Two periods of the simulated excavator (FMUs: replayable, cylinder channels)."""
    path = tmp_path_factory.mktemp("sim") / LONG / "a-rather-long-run-name-for-a-table.mcap"
    path.parent.mkdir(parents=True)
    run_campaign(load_scenario(PAPER, ["periods=2"]), log_path=path)
    return path


def _show(args: list[str], width: str | None) -> str:
    """stdout of `excosim ARGS` at a terminal width (CliRunner: stdout is not a terminal), or
    piped through a real process without COLUMNS."""
    if width is not None:
        done = CliRunner().invoke(app, args, env={"COLUMNS": width})
        assert done.exit_code == 0, done.output
        return done.stdout
    env = {key: value for key, value in os.environ.items() if key != "COLUMNS"}
    env["PYTHONPATH"] = str(ROOT)
    done = subprocess.run([sys.executable, "-c", "from orchestrator.cli.app import main; main()",
                           *args], capture_output=True, text=True, env=env, timeout=300)
    assert done.returncode == 0, done.stderr
    return done.stdout


def _period_figures(records: list[dict]) -> list[str]:
    figures = []
    for r in records:
        y, z = r["deepest_point_m"]
        figures += [f"({y:.2f}, {z:.3f})", f"{r['mass_kg']:.2f}", f"{r['error_kg']:+.2f}",
                    f"{r['duration_s']:.2f}", f"{max(r['max_abs_jerk_deg_s3']):.1f}",
                    f"{r['planner_ms']:.1f}"]
    return figures


def _assert_whole(out: str, figures: list[str]) -> None:
    assert "…" not in out
    for figure in figures:
        assert figure in out, (figure, out)


@pytest.mark.parametrize("width", WIDTHS)
def test_review_shows_every_figure_of_every_period(kinematic_runs, width):
    out = _show(["review", str(kinematic_runs[0])], width)
    _assert_whole(out, _period_figures(read_run(kinematic_runs[0]).periods))
    for header in ("D (y, z)", "mass", "error", "reset", "duration", "peak jerk", "planner"):
        assert header in out


@pytest.mark.parametrize("width", ["80", "200"])
def test_run_shows_every_figure_of_every_period(tmp_path, monkeypatch, width):
    monkeypatch.setattr(campaign, "build_plant", lambda s: KinematicPlant(s.geometry()))
    log = tmp_path / "run.mcap"
    out = _show(["run", str(PAPER), "--periods", "12", "-o", str(log)], width)
    _assert_whole(out, _period_figures(read_run(log).periods))


def _run_figures(data: dict) -> list[str]:
    f = data["figures"]
    return [f"{data['target_mass_kg']:g}", str(f["periods"]), f"{f['mean_abs_error_kg']:.2f}",
            f"{f['max_abs_error_kg']:.2f}", f"{f['within_band']}/{f['counted']}",
            f"{f['mean_duration_s']:.2f}", f"{f['peak_jerk_deg_s3']:.1f}", "all periods dug"]


@pytest.mark.parametrize("width", WIDTHS)
def test_compare_shows_every_figure_of_every_run_by_a_short_name(kinematic_runs, sim_run,
                                                                  width):
    paths = [*kinematic_runs, sim_run]
    out = _show(["compare", *map(str, paths)], width)
    for path in paths:
        _assert_whole(out, _run_figures(summary.summary(summary.load(path))))
        assert str(path.parent) not in out  # names, not whole paths
    for label in ("a/run", "b/run", "c/run", "a-rather-long-run-name-for-a-table"):
        assert label in out
    for header in ("m*", "mean |err|", "max |err|", "in band", "mean duration", "peak jerk",
                   "resets", "ended"):
        assert header in out


@pytest.mark.parametrize("width", ["80", "200"])
def test_replay_shows_every_figure_of_every_period(sim_run, width):
    out = _show(["replay", str(sim_run)], width)
    for record in read_run(sim_run).periods:
        assert out.count(f"{record['mass_kg']:.6f}") == 2  # logged and replayed
    assert "…" not in out and "replay matches the log: 2 periods" in out


def test_a_wide_grid_turns_into_blocks_that_fit_and_keep_every_cell():
    columns = [tables.Column("run", left=True),
               *(tables.Column(f"figure {i}", "kg") for i in range(11))]
    rows = [[f"run-{r}", *(f"{1000 * r + i + 0.123456:.6f}" for i in range(11))]
            for r in range(3)]
    grid = tables.Grid("wide", columns, rows, caption="a caption")
    for width in (40, 80):
        console = Console(width=width, record=True, file=open(os.devnull, "w"))  # noqa: SIM115
        tables.show(console, grid)
        text = console.export_text()
        assert all(len(line) <= width for line in text.splitlines())
        for row in rows:
            for cell in row:
                assert cell in text
    console = Console(width=400, record=True, file=open(os.devnull, "w"))  # noqa: SIM115
    tables.show(console, grid)
    assert "figure 10 kg" in console.export_text()  # one table, one-line headers


def test_csv_holds_the_period_table(kinematic_runs, tmp_path):
    target = tmp_path / "out" / "periods.csv"
    target.parent.mkdir()  # review makes no folders: a mistyped path is refused, not created
    done = CliRunner().invoke(app, ["review", str(kinematic_runs[0]), "--csv", str(target)])
    assert done.exit_code == 0, done.output
    assert done.stdout.rstrip().endswith(str(target))
    read = pd.read_csv(target, index_col="k")
    expected = records_dataframe(read_run(kinematic_runs[0]).periods)
    pd.testing.assert_frame_equal(read, expected)
    assert len(read) == 12


def test_csv_channels_hold_the_logged_samples_with_units(sim_run, tmp_path):
    folder = tmp_path / "channels"
    done = CliRunner().invoke(app, ["review", str(sim_run), "--json", "--csv-channels",
                                    "/joints,/cylinder/boom", "--csv-channels", "/pile/profile",
                                    "--csv-dir", str(folder)])
    assert done.exit_code == 0, done.output
    json.loads(done.stdout)  # stdout stays one JSON object; the paths go to stderr
    names = {"/joints": "joints.csv", "/cylinder/boom": "cylinder_boom.csv",
             "/pile/profile": "pile_profile.csv"}
    assert done.stderr.split() == [str(folder / name) for name in names.values()]
    run = read_run(sim_run, topics=tuple(names))
    boom = pd.read_csv(folder / "cylinder_boom.csv")
    assert list(boom.columns) == ["t_s", "period", "x_m", "v_m_s", "p_A_Pa", "p_B_Pa", "F_N",
                                  "u_1", "F_ext_N"]
    for topic, name in names.items():
        frame = pd.read_csv(folder / name)
        channel = run.channels[topic]
        assert np.array_equal(frame["t_s"], channel.fields["t_s"])
        assert np.array_equal(frame["period"], channel.period)
        values = frame.drop(columns=["t_s", "period"]).to_numpy()
        logged = np.column_stack([v.reshape(len(channel.period), -1)
                                  for f, v in channel.fields.items() if f != "t_s"])
        assert np.array_equal(values, logged, equal_nan=True)
    joints = pd.read_csv(folder / "joints.csv")
    assert "measured_boom_rad" in joints.columns and len(joints) == len(run.channels["/joints"]
                                                                      .period)


@pytest.mark.parametrize(("topic", "expected"), [
    ("/jionts", "--csv-channels /jionts: "),
    ("/tf", "only numeric channels can be written as CSV"),
    ("/period", "the period records are JSON"),
])
def test_a_bad_channel_is_one_line_and_nothing_is_written(sim_run, tmp_path, topic, expected):
    done = CliRunner().invoke(app, ["review", str(sim_run), "--csv", str(tmp_path / "p.csv"),
                                    "--csv-channels", f"/joints,{topic}", "--csv-dir",
                                    str(tmp_path / "d")])
    assert done.exit_code == 2 and done.stdout == ""
    assert done.stderr.startswith("excosim: ") and done.stderr.count("\n") == 1
    assert expected in done.stderr
    assert list(tmp_path.iterdir()) == []


def test_runs_are_named_by_what_tells_them_apart():
    from orchestrator.cli.review import labels

    assert labels([Path("seed1.mcap"), Path("seed2.mcap")]) == ["seed1", "seed2"]
    assert labels([Path("a.mcap"), Path("x/a/runs/run.mcap"), Path("x/b/runs/run.mcap")]) == [
        "a", "a/run", "b/run"]
