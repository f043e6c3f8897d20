"""`excosim run`: exit status 0 / 2 / 1, one line and no traceback for mistakes and failures, the
period table, and an MCAP log that reads back (also after a failure)."""

import os
import subprocess
import sys
from pathlib import Path

import pytest
from kinematic_plant import KinematicPlant
from typer.testing import CliRunner

from orchestrator.campaign import loop as campaign
from orchestrator.cli.app import app
from orchestrator.runlog import read_run

ROOT = Path(__file__).resolve().parent.parent
PAPER = ROOT / "scenarios" / "paper-2020.toml"


def _excosim(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    command = [sys.executable, "-c", "from orchestrator.cli.app import main; main()", *args]
    env = {**os.environ, "PYTHONPATH": str(ROOT), "COLUMNS": "100"}
    return subprocess.run(command, capture_output=True, text=True, cwd=cwd, env=env, timeout=120)


@pytest.mark.parametrize(("args", "expected"), [
    (["missing.toml"], "excosim: missing.toml: no such scenario file"),
    ([str(PAPER), "--set", "periods=0"],
     "excosim: paper-2020.toml: periods: must be greater than or equal to 1, got 0"),
    ([str(PAPER), "--set", "plant.pile.parameters.densty=1800"],
     "excosim: paper-2020.toml: plant.pile.parameters.densty: Pile has no parameter 'densty' "
     "(closest: density, density_seed, density_variation)"),
    ([str(PAPER), "--set", "limits.jerk_deg_s3=[60, 60]"],
     "excosim: paper-2020.toml: limits.jerk_deg_s3: expected 3 numbers, got 2"),
    ([str(PAPER), "--set", "periods"],
     "excosim: paper-2020.toml: --set 'periods': expected KEY=VALUE, e.g. periods=5"),
    ([str(PAPER), "-o", "run.txt"],
     "excosim: output 'run.txt': expected a file name ending in .mcap"),
])
def test_a_users_mistake_exits_2_with_one_line(tmp_path, args, expected):
    done = _excosim("run", *args, cwd=tmp_path)
    assert done.returncode == 2
    assert done.stderr == expected + "\n"
    assert not (tmp_path / "runs").exists()


def test_an_existing_output_is_not_overwritten(tmp_path):
    (tmp_path / "old.mcap").write_bytes(b"precious")
    done = _excosim("run", str(PAPER), "-o", "old.mcap", cwd=tmp_path)
    assert done.returncode == 2
    assert "already exists" in done.stderr and "Traceback" not in done.stderr
    assert (tmp_path / "old.mcap").read_bytes() == b"precious"


def test_a_bad_option_value_exits_2_without_traceback(tmp_path):
    done = _excosim("run", str(PAPER), "--periods", "many", cwd=tmp_path)
    assert done.returncode == 2
    assert "--periods" in done.stderr and "Traceback" not in done.stderr


@pytest.fixture
def double_plant(monkeypatch):
    """Make `excosim run` dig with the test double; returns the list of plants it made."""
    made = []

    def build(scenario, fail_in_period=None):
        made.append(KinematicPlant(scenario.geometry(), fail_in_period=fail_in_period))
        return made[-1]

    monkeypatch.setattr(campaign, "build_plant", build)
    return made


def test_a_campaign_exits_0_prints_its_table_and_logs_every_period(tmp_path, double_plant,
                                                                    monkeypatch):
    monkeypatch.chdir(tmp_path)
    result = CliRunner().invoke(app, ["run", str(PAPER), "--periods", "3",
                                      "--set", "target_mass_kg=25"])
    assert result.exit_code == 0, result.output
    out = result.stdout
    assert "Digging periods (target 25 kg)" in out
    for k in (1, 2, 3):
        assert f"\n  {k}   (-9.00, " in out
    # the on-target band is 10 % of m*: the paper's +-3 kg at 30 kg, +-2.5 kg at 25 kg
    assert "dug all 3 planned periods; within +/-2.5 kg after period 1:" in out
    logs = list((tmp_path / "runs").glob("paper-2020-*.mcap"))
    assert len(logs) == 1 and f"log: {Path('runs') / logs[0].name}" in out
    run = read_run(logs[0])
    assert run.finished and run.termination == "periods"
    assert [p["k"] for p in run.periods] == [1, 2, 3]
    assert run.scenario["periods"] == 3 and run.scenario["target_mass_kg"] == 25.0
    assert b"D0 = (-9, -0.1) m" in run.attachments["scenario.toml"]  # the file, comments too


def test_a_runtime_failure_exits_1_and_leaves_a_readable_log(tmp_path, monkeypatch):
    def failing(scenario):
        return KinematicPlant(scenario.geometry(), fail_in_period=2)

    monkeypatch.setattr(campaign, "build_plant", failing)
    log = tmp_path / "failed.mcap"
    result = CliRunner().invoke(app, ["run", str(PAPER), "-o", str(log)])
    assert result.exit_code == 1
    assert result.stderr == (f"excosim: run failed: period 2: RuntimeError: hydraulic hose burst "
                             f"(test double) (log {log} is readable up to period 1)\n")
    assert "Traceback" not in result.output
    run = read_run(log)
    assert run.finished and run.termination == "error"
    assert [p["k"] for p in run.periods] == [1]
    assert "hydraulic hose burst" in run.termination_message


def test_the_simulated_excavator_digs_one_period_from_the_command_line(tmp_path):
    done = _excosim("run", str(PAPER), "--periods", "1", "-o", "one.mcap", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert "Traceback" not in done.stderr
    assert "dug the 1 planned period;" in done.stdout
    run = read_run(tmp_path / "one.mcap")
    assert run.finished and run.termination == "periods" and len(run.periods) == 1
    # The paper's first period (section 3.2: 8.5 kg), as calibrated in the scenario.
    assert run.periods[0]["mass_kg"] == pytest.approx(8.5, abs=1.0)
