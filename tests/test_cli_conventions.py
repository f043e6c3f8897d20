"""The `excosim` command line follows the field's conventions (fmpy, cosim-cli, git): --version,
-h/--help everywhere, help that names values by what they are, shell completion, one-line
mistakes with exit status 2, Ctrl-C in one line with 130 (SIGTERM: 143), --json/--quiet/--force
on `run`, log names that never collide, and plain English with correct plurals."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
from datetime import UTC, datetime
from importlib.metadata import version
from pathlib import Path

import pytest
from kinematic_plant import KinematicPlant
from typer.main import get_command
from typer.testing import CliRunner

from orchestrator.campaign import loop as campaign
from orchestrator.cli import results
from orchestrator.cli.app import app
from orchestrator.review.summary import ending
from orchestrator.runlog import read_run
from orchestrator.scenario import load_scenario

ROOT = Path(__file__).resolve().parent.parent
PAPER = ROOT / "scenarios" / "paper-2020.toml"
MAIN = "from orchestrator.cli.app import main; main()"
ENV = {**os.environ, "PYTHONPATH": str(ROOT), "COLUMNS": "100"}


def _excosim(*args: str, cwd: Path, timeout: float = 120) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", MAIN, *args], capture_output=True, text=True,
                          cwd=cwd, env=ENV, timeout=timeout)


def _commands(command=None, path=()):
    """(path, command) of every command and group of the command line."""
    command = command or get_command(app)
    yield path, command
    for name, sub in getattr(command, "commands", {}).items():
        yield from _commands(sub, (*path, name))


COMMANDS = [path for path, _ in _commands()]


@pytest.fixture
def double_plant(monkeypatch):
    """Make `excosim run` dig with the fast test double."""
    monkeypatch.setattr(campaign, "build_plant", lambda scenario: KinematicPlant(
        scenario.geometry()))


def test_version_prints_the_package_version(tmp_path):
    for flag in ("--version", "-V"):
        done = _excosim(flag, cwd=tmp_path)
        assert done.returncode == 0 and done.stderr == ""
        assert done.stdout == f"excosim {version('excosim')}\n"


@pytest.mark.parametrize("path", COMMANDS, ids=lambda p: " ".join(p) or "excosim")
def test_every_command_and_group_takes_h_and_help(path):
    for flag in ("-h", "--help"):
        done = CliRunner().invoke(app, [*path, flag])
        assert done.exit_code == 0, done.output
        assert f"Usage: {' '.join(('excosim', *path))}" in done.stdout


NOISE = ("<bool>", "<path>", "<int", "<str>", "<list[", "<float>", "{", "TEXT", "INTEGER",
         "PATH", "[x>=", "BOOLEAN")


@pytest.mark.parametrize("columns", ["80", "200"])
def test_help_names_values_by_what_they_are_not_by_type(columns):
    seen = ""
    for path in COMMANDS:
        done = CliRunner().invoke(app, [*path, "-h"], env={"COLUMNS": columns})
        for noise in NOISE:
            assert noise not in done.stdout, (path, noise, done.stdout)
        seen += done.stdout
    for metavar in ("SCENARIO.toml", "KEY=VALUE", "RUN.mcap", "FILE.csv", "TOPIC[,TOPIC]",
                    "DIR", "SHELL", "MODEL", "--version", "--quiet", "--force", "--json"):
        assert metavar in seen


def test_the_completion_script_completes_commands_and_options(tmp_path):
    for shell in ("bash", "zsh", "fish"):
        done = _excosim("completion", shell, cwd=tmp_path)
        assert done.returncode == 0 and "_EXCOSIM_COMPLETE" in done.stdout
    bash = shutil.which("bash")
    assert bash is not None  # the machines this runs on have bash (the README's blocks need it)
    script = tmp_path / "bin" / "excosim"
    script.parent.mkdir()
    script.write_text(f'#!/bin/sh\nexec "{sys.executable}" -c "{MAIN}" "$@"\n')
    script.chmod(0o755)
    words = ('eval "$(excosim completion bash)"; '
             'COMP_WORDS=(excosim re); COMP_CWORD=1; _excosim_completion excosim; '
             'echo "${COMPREPLY[*]}"; '
             'COMP_WORDS=(excosim run --q); COMP_CWORD=2; _excosim_completion excosim; '
             'echo "${COMPREPLY[*]}"')
    env = {**ENV, "PATH": f"{script.parent}{os.pathsep}{os.environ['PATH']}"}
    done = subprocess.run([bash, "-c", words], capture_output=True, text=True, env=env,
                          timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.splitlines() == ["review replay", "--quiet"]


@pytest.mark.parametrize(("args", "expected"), [
    (["run", "--bogus", str(PAPER)], "no such option: --bogus (see 'excosim run -h')"),
    (["run"], "missing argument 'SCENARIO.toml' (see 'excosim run -h')"),
    (["nosuch"], "no such command 'nosuch' (see 'excosim -h')"),
    (["run", "missing.toml"], "missing.toml: no such scenario file"),
    (["run", str(PAPER), "--periods", "many"], "invalid value for '--periods'"),
    (["run", str(PAPER), "--periods", "0"], "periods: must be greater than or equal to 1"),
    (["run", str(PAPER), "--json", "--quiet"], "--json and --quiet exclude each other"),
    (["review", "missing.mcap"], "cannot read missing.mcap"),
    (["compare"], "missing argument 'RUN.mcap'"),
    (["review", "missing.mcap", "--csv-dir", "out"], "--csv-dir: give the channels"),
    (["completion", "tcsh"], "completion: unknown shell 'tcsh'; known: bash, zsh, fish"),
    (["fmus", "build", "Nope"], "unknown model 'Nope'"),
])
def test_every_mistake_is_one_line_exit_2_and_writes_nothing(tmp_path, args, expected):
    done = _excosim(*args, cwd=tmp_path)
    assert done.returncode == 2
    assert done.stderr.startswith("excosim: ") and done.stderr.count("\n") == 1
    assert expected in done.stderr and "Traceback" not in done.stderr
    assert done.stdout == "" and list(tmp_path.iterdir()) == []


# `excosim` with each finished period said on stderr, then held for up to a minute: a signal
# sent when the line arrives reaches the campaign inside period 2, however loaded the machine
# (no race with a run that finishes first, no polling of the log).
# A child started from a non-interactive shell's background job inherits SIGINT ignored, and
# Python then keeps it ignored: the child restores the default, as an interactive terminal has.
PAUSED_MAIN = """
import signal, sys, time
signal.signal(signal.SIGINT, signal.default_int_handler)
import orchestrator.campaign as campaign
real = campaign.run_campaign
def run_campaign(scenario, *, progress=None, **kwargs):
    def report(record):
        progress(record)
        print(f"test: period {record['k']} done", file=sys.stderr, flush=True)
        time.sleep(60)
    return real(scenario, progress=report, **kwargs)
campaign.run_campaign = run_campaign
from orchestrator.cli.app import main
main()
"""


def _signal_after_period_1(tmp_path: Path, named: bool, signum: int):
    """Run 20 paper periods, send `signum` once period 1 is logged; (process, stderr after
    the marker line, log path, temporary folder of the child)."""
    temporary = tmp_path / "tmp"
    temporary.mkdir()
    args = ["run", str(PAPER), "--periods", "20", *(["-o", "run.mcap"] if named else [])]
    process = subprocess.Popen([sys.executable, "-c", PAUSED_MAIN, *args], cwd=tmp_path,
                               env={**ENV, "TMPDIR": str(temporary)}, stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True)
    try:
        line = process.stderr.readline()  # blocks until period 1 is done (or the run failed)
        assert line == "test: period 1 done\n", line + process.communicate(timeout=60)[1]
        process.send_signal(signum)
        out, err = process.communicate(timeout=60)
    finally:
        if process.poll() is None:
            process.kill()
            process.communicate()
    log = tmp_path / "run.mcap" if named else next(tmp_path.glob("runs/*.mcap"))
    assert out == ""
    return process, err, log, temporary


@pytest.mark.parametrize("named", [True, False], ids=["-o", "default name"])
def test_ctrl_c_during_run_says_how_far_it_got_and_leaves_a_readable_log(tmp_path, named):
    process, err, log, temporary = _signal_after_period_1(tmp_path, named, signal.SIGINT)
    run = read_run(log)
    shown = log.relative_to(tmp_path)
    assert process.returncode == 130 and len(run.periods) == 1
    assert err == (f"excosim: interrupted after 1 of 20 periods; log {shown} is readable "
                   "up to period 1\n")
    assert run.finished and run.termination == "error"
    assert run.termination_message == campaign.INTERRUPTED
    assert list(temporary.iterdir()) == []  # the extracted FMUs are gone
    review = CliRunner().invoke(app, ["review", str(log)])
    assert "interrupted after 1 period" in review.stdout


def test_sigterm_during_run_is_handled_like_ctrl_c_with_exit_143(tmp_path):
    process, err, log, temporary = _signal_after_period_1(tmp_path, True, signal.SIGTERM)
    run = read_run(log)
    assert process.returncode == 143 and len(run.periods) == 1
    assert err == ("excosim: terminated (SIGTERM) after 1 of 20 periods; log run.mcap is "
                   "readable up to period 1\n")
    assert run.finished and run.termination_message == campaign.INTERRUPTED  # flushed, closed
    assert list(temporary.iterdir()) == []


def test_run_json_is_one_object_with_the_records_and_the_ending(tmp_path, double_plant):
    log = tmp_path / "run.mcap"
    done = CliRunner().invoke(app, ["run", str(PAPER), "--periods", "3", "--json", "-o",
                                    str(log)])
    assert done.exit_code == 0, done.output
    data = json.loads(done.stdout)  # nothing else on stdout
    assert data["termination"] == "periods" and data["path"] == str(log)
    assert data["periods"] == json.loads(json.dumps(read_run(log).periods))
    assert data["scenario"] == "paper-2020" and data["figures"]["periods"] == 3


def test_run_json_of_a_failed_run_says_so_and_exits_1(tmp_path, monkeypatch):
    monkeypatch.setattr(campaign, "build_plant", lambda scenario: KinematicPlant(
        scenario.geometry(), fail_in_period=2))
    done = CliRunner().invoke(app, ["run", str(PAPER), "--json", "-o", str(tmp_path / "f.mcap")])
    assert done.exit_code == 1 and done.stderr.startswith("excosim: run failed: period 2")
    data = json.loads(done.stdout)
    assert data["termination"] == "error" and len(data["periods"]) == 1


def test_run_quiet_prints_nothing(tmp_path, double_plant):
    log = tmp_path / "run.mcap"
    done = CliRunner().invoke(app, ["run", str(PAPER), "--periods", "2", "-q", "-o", str(log)])
    assert done.exit_code == 0 and done.stdout == "" and done.stderr == ""
    assert len(read_run(log).periods) == 2


def test_force_overwrites_an_existing_output(tmp_path, double_plant):
    log = tmp_path / "old.mcap"
    log.write_bytes(b"old")
    refused = CliRunner().invoke(app, ["run", str(PAPER), "--periods", "1", "-o", str(log)])
    assert refused.exit_code == 2 and "--force" in refused.stderr
    assert log.read_bytes() == b"old"
    done = CliRunner().invoke(app, ["run", str(PAPER), "--periods", "1", "-o", str(log), "-f"])
    assert done.exit_code == 0, done.output
    assert read_run(log).finished


def test_runs_started_in_the_same_millisecond_get_their_own_logs(tmp_path, double_plant,
                                                                  monkeypatch):
    class Frozen(datetime):
        @classmethod
        def now(cls, tz=None):
            return datetime(2026, 1, 2, 3, 4, 5, 678_000, tzinfo=UTC)

    monkeypatch.setattr(results, "datetime", Frozen)
    monkeypatch.chdir(tmp_path)
    outputs = [CliRunner().invoke(app, ["run", str(PAPER), "--periods", "1", *extra])
               for extra in ([], [], ["--set", "seed=7"])]
    assert all(done.exit_code == 0 for done in outputs), [d.output for d in outputs]
    same, other = (results.default_name(load_scenario(PAPER, items), Frozen.now())
                   for items in (["periods=1"], ["seed=7", "periods=1"]))
    assert same.startswith("paper-2020-20260102T030405.678Z-") and same != other
    names = [f"{same}.mcap", f"{same}-2.mcap", f"{other}.mcap"]
    assert sorted(p.name for p in (tmp_path / "runs").iterdir()) == sorted(names)
    for done, name in zip(outputs, names, strict=True):  # each run says where its log went
        assert f"log: {Path('runs') / name}\n" in done.stdout
        assert read_run(tmp_path / "runs" / name).finished


def test_two_runs_started_together_both_succeed(tmp_path):
    processes = [subprocess.Popen([sys.executable, "-c", MAIN, "run", str(PAPER), "--periods",
                                   "1", "-q"], cwd=tmp_path, env=ENV, stdout=subprocess.PIPE,
                                  stderr=subprocess.PIPE, text=True) for _ in range(2)]
    results = [p.communicate(timeout=180) for p in processes]
    assert [p.returncode for p in processes] == [0, 0], results
    logs = list((tmp_path / "runs").glob("paper-2020-*.mcap"))
    assert len(logs) == 2 and all(read_run(log).finished for log in logs)


def _review(n: int, termination: str | None, message: str = "", truncated: bool = False):
    return {"periods": [{}] * n, "finished": termination is not None, "truncated": truncated,
            "termination": termination, "message": message}


@pytest.mark.parametrize(("review", "line"), [
    (_review(20, "periods"), "dug all 20 planned periods"),
    (_review(1, "periods"), "dug the 1 planned period"),
    (_review(1, None, truncated=True),
     "did not finish: the log holds 1 complete period (the file ends early); a killed run?"),
    (_review(2, None), "did not finish: the log holds 2 complete periods; a killed run?"),
    (_review(1, "workspace_limit", "workspace limit after 1 period(s)"),
     "stopped at the workspace limit after 1 period (the next D was out of reach after a "
     "reset)"),
    (_review(3, "error", campaign.INTERRUPTED), "interrupted after 3 periods"),
    (_review(1, "error", "period 2: RuntimeError: burst"),
     "failed after 1 period: period 2: RuntimeError: burst"),
])
def test_endings_are_plain_english_with_correct_plurals(review, line):
    assert ending(review) == line


def test_no_output_says_1_periods(tmp_path, double_plant):
    log = tmp_path / "one.mcap"
    done = CliRunner().invoke(app, ["run", str(PAPER), "--periods", "1", "-o", str(log)])
    assert "dug the 1 planned period;" in done.stdout
    for command in (["review", str(log)], ["compare", str(log)]):
        out = CliRunner().invoke(app, command, env={"COLUMNS": "200"}).stdout
        assert "1 periods" not in out and "1 complete periods" not in out
    refused = CliRunner().invoke(app, ["review", str(log), "--plots", str(tmp_path / "f"),
                                       "--period", "2"])
    assert refused.stderr == f"excosim: --period 2: {log} holds period 1 only\n"


def test_a_one_line_error_prints_its_text_as_it_is(capsys):
    """rich would turn emoji codes such as ":100:" (a range 0:100:...) into pictures."""
    from orchestrator.cli.conventions import fail

    fail("--param x=0:100:5 [bold]not markup[/bold]")
    assert capsys.readouterr().err == "excosim: --param x=0:100:5 [bold]not markup[/bold]\n"
