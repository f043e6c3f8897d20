"""`excosim run --out-dir` (a results folder per run) and `excosim layout`, checked against
the run log they come from (read_run) and by running the written scenario again."""

from __future__ import annotations

import json
import tomllib
from pathlib import Path

import pandas as pd
import pytest
from typer.testing import CliRunner

from orchestrator.cli.app import app
from orchestrator.review.layout import LayoutFacts, layout_text
from orchestrator.runlog import read_run
from orchestrator.scenario import load_scenario
from orchestrator.scenario.toml_text import toml_text

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "scenarios" / "paper-2020.toml"
runner = CliRunner()


@pytest.fixture(scope="module")
def results(tmp_path_factory) -> Path:
    parent = tmp_path_factory.mktemp("results")
    done = runner.invoke(app, ["run", str(PAPER), "--periods", "2", "--out-dir", str(parent),
                               "--set", "plant.load_cell_noise_kg=0.5"])
    assert done.exit_code == 0, done.output
    (folder,) = parent.iterdir()
    return folder


def test_at_a_terminal_the_run_says_where_it_logs_before_it_digs(tmp_path):
    """stderr a terminal (a pseudo-terminal here): the log's path is the first line, written
    before a period is weighed (the progress bar then says "(last ... kg)")."""
    import os
    import pty
    import subprocess
    import sys

    controller, terminal = pty.openpty()
    process = subprocess.Popen(
        [str(Path(sys.executable).parent / "excosim"), "run", str(PAPER), "--periods", "2",
         "-o", "tty.mcap"], cwd=tmp_path, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
        stderr=terminal)
    os.close(terminal)
    seen = b""
    try:
        while True:
            try:
                chunk = os.read(controller, 4096)
            except OSError:  # the terminal closed: the run is over
                break
            if not chunk:
                break
            seen += chunk
    finally:
        process.wait(timeout=300)
        os.close(controller)
    text = seen.decode(errors="replace")
    said = text.find(f"logging to {Path('tty.mcap')}")
    assert 0 <= said < text.find("(last "), text[-2000:]  # before a period was weighed
    assert process.returncode == 0


def test_the_folder_holds_the_log_scenario_layout_table_and_figures(results):
    run = read_run(results / "run.mcap", topics=("/display",))
    assert run.finished and len(run.periods) == 2
    table = pd.read_csv(results / "periods.csv", index_col="k")
    assert table["mass_kg"].tolist() == [p["mass_kg"] for p in run.periods]
    assert json.loads((results / "foxglove-layout.json").read_text()) == json.loads(
        layout_text(LayoutFacts.of_run(run)))
    assert {p.name for p in (results / "figures").iterdir()} >= {"weight_error.png"}


def test_the_written_scenario_digs_the_same_run_from_anywhere(results, tmp_path):
    assert tomllib.loads((results / "scenario.toml").read_text()) == read_run(
        results / "run.mcap").scenario
    moved = tmp_path / "elsewhere.toml"
    moved.write_text((results / "scenario.toml").read_text())
    done = runner.invoke(app, ["run", str(moved), "-o", str(tmp_path / "again.mcap"), "-q"])
    assert done.exit_code == 0, done.output
    again, first = read_run(tmp_path / "again.mcap"), read_run(results / "run.mcap")
    strip = [{k: v for k, v in p.items() if k != "planner_ms"} for p in first.periods]
    assert [{k: v for k, v in p.items() if k != "planner_ms"} for p in again.periods] == strip


@pytest.mark.parametrize("value", [1e-300, 0.1, 1 / 3, float("inf"), -0.0, 7, True, "a\"b\\\n",
                                   [1.5, 2], []])
def test_toml_text_reads_back_as_the_same_values(value):
    data = {"top": value, "table": {"key with space": value, "sub": {"x": value}}}
    assert tomllib.loads(toml_text(data)) == data


def test_out_dir_and_o_exclude_each_other_and_resume_takes_no_out_dir(tmp_path):
    done = runner.invoke(app, ["run", str(PAPER), "--periods", "1", "-o",
                               str(tmp_path / "a.mcap"), "--out-dir", str(tmp_path)])
    assert done.exit_code == 2 and "exclude each other" in done.stderr
    done = runner.invoke(app, ["run", "--resume", str(tmp_path / "a.mcap"), "--out-dir",
                               str(tmp_path)])
    assert done.exit_code == 2 and "--out-dir" in done.stderr
    assert list(tmp_path.iterdir()) == []


def test_layout_command_writes_the_layout_of_a_log_or_a_scenario(results, tmp_path):
    out = tmp_path / "layout.json"
    done = runner.invoke(app, ["layout", str(results / "run.mcap"), "-o", str(out)])
    assert done.exit_code == 0, done.output
    assert out.read_text() == (results / "foxglove-layout.json").read_text()
    done = runner.invoke(app, ["layout", str(PAPER), "--set", "target_mass_kg=20"])
    assert done.exit_code == 0, done.output
    facts = LayoutFacts.of_scenario(load_scenario(PAPER, ["target_mass_kg=20"]))
    assert done.stdout == layout_text(facts)
    assert '"value": "2"' in done.stdout  # the band: 10 % of the 20 kg target


@pytest.mark.parametrize("args, expected", [
    (["nothere.mcap"], "cannot read nothere.mcap"),
    ([str(PAPER), "-o", "x.txt"], "a layout file ends in .json"),
    ([str(PAPER), "-o", "missing/x.json"], "its folder does not exist"),
    ([str(PAPER), "--set", "target_mass_kg=-1"], "target_mass_kg"),
])
def test_layout_command_refuses_bad_input_in_one_line(args, expected, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    done = runner.invoke(app, ["layout", *args])
    assert done.exit_code == 2 and expected in done.stderr, done.output
    assert done.stderr.count("\n") == 1 and list(tmp_path.iterdir()) == []
