"""`excosim run` digs in a supervised child process (orchestrator/campaign/isolation.py): an FMU
that segfaults, aborts or calls exit() ends the run with one line naming the FMU and the
cause, exit status 1, and a log closed with that reason (indexed, resumable), with the
extracted FMUs removed; `--in-process` shows what the same fault does without the supervisor.
An FMU whose initialization never returns is caught by the step watchdog. Real faults in real
native code (tests/faulty_fmus.py), in real processes."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from faulty_fmus import CRASH, EXIT, INIT_HANG, SEGFAULT, patched_cylinder
from mcap.reader import make_reader

from orchestrator.campaign.isolation import available
from orchestrator.campaign.resume import prepare_resume
from orchestrator.runlog import read_run

ROOT = Path(__file__).resolve().parent.parent
PAPER = ROOT / "scenarios" / "paper-2020.toml"
MAIN = "from orchestrator.cli.app import main; main()"
CRASH_T_S = 18.0  # inside period 2 (period 1 of the paper scenario lasts 12.7 s)

pytestmark = pytest.mark.skipif(not available(), reason="supervised runs need Linux")


@pytest.fixture(scope="module")
def faulty(tmp_path_factory) -> dict[str, Path]:
    folder = tmp_path_factory.mktemp("faulty")
    faults = {"segfault": SEGFAULT, "abort": CRASH, "exit": EXIT, "init": INIT_HANG}
    made = {}
    for name, fault in faults.items():
        (folder / name).mkdir()
        made[name] = patched_cylinder(folder / name, fault, CRASH_T_S, name.title())
    return made


def _run(tmp_path: Path, fmu: Path, *extra: str, periods: int = 3, quiet: bool = True):
    temporary = tmp_path / "tmp"
    temporary.mkdir(exist_ok=True)
    done = subprocess.run(
        [sys.executable, "-c", MAIN, "run", str(PAPER), "--periods", str(periods), "-o",
         "run.mcap", "--trust", *(["-q"] if quiet else []), "--set",
         f"plant.boom.fmu={fmu}", *extra],
        capture_output=True, text=True, cwd=tmp_path, timeout=300,
        env={**os.environ, "PYTHONPATH": str(ROOT), "TMPDIR": str(temporary)})
    return done, temporary


CAUSES = {
    "segfault": "the run's process died (signal 11, SIGSEGV) in the step of FMU boom "
                "(HydraulicCylinder)",
    "abort": "the run's process died (signal 6, SIGABRT) in the step of FMU boom "
             "(HydraulicCylinder)",
    "exit": "the run's process ended (exit status 3): FMU boom (HydraulicCylinder) called "
            "exit() in its step at t = 18",
}


@pytest.mark.parametrize("fault", list(CAUSES))
def test_a_crashing_fmu_ends_the_run_with_its_reason_in_the_log(tmp_path, faulty, fault):
    done, temporary = _run(tmp_path, faulty[fault])
    assert done.returncode == 1 and done.stdout == ""
    lines = done.stderr.splitlines()  # -q: the failure alone
    assert len(lines) == 1 and lines[0].startswith(f"excosim: run failed: period 2: "
                                                   f"{CAUSES[fault]}")
    assert lines[0].endswith("(log run.mcap is readable up to period 1)")
    log = tmp_path / "run.mcap"
    run = read_run(log, tolerant=False)  # whole, with its summary
    assert run.finished and run.termination == "error" and len(run.periods) == 1
    assert run.termination_message.startswith(f"period 2: {CAUSES[fault]}")
    with open(log, "rb") as stream:  # an indexed reader (Foxglove's and Lichtblick's kind)
        summary = make_reader(stream).get_summary()
    assert summary is not None and summary.statistics.message_count > 0
    assert list(temporary.iterdir()) == []  # the child's extracted FMUs are removed
    assert prepare_resume(log).k == 1  # and the run can be resumed after its last period


def test_run_json_of_a_crashed_run_is_the_object_of_its_closed_log(tmp_path, faulty):
    done, _ = _run(tmp_path, faulty["segfault"], "--json", quiet=False)
    assert done.returncode == 1
    data = json.loads(done.stdout)  # one object, nothing else
    assert data["termination"] == "error" and len(data["periods"]) == 1
    assert data["message"].startswith(f"period 2: {CAUSES['segfault']}")
    assert data["path"] == "run.mcap" and data["figures"]["periods"] == 1


def test_without_the_supervisor_the_same_crash_takes_the_log_s_end_record_along(tmp_path,
                                                                                  faulty):
    done, temporary = _run(tmp_path, faulty["segfault"], "--in-process")
    assert done.returncode == -signal.SIGSEGV
    run = read_run(tmp_path / "run.mcap")
    assert not run.finished and len(run.periods) == 1
    assert [p.name for p in temporary.iterdir()] != []  # an extracted FMU left behind


def test_an_fmu_whose_initialization_never_returns_is_named(tmp_path, faulty):
    started = time.monotonic()
    done, temporary = _run(tmp_path, faulty["init"], "--step-timeout", "2")
    assert done.returncode == 1 and done.stdout == ""
    line = done.stderr.splitlines()[-1]
    # The plant is built before the log is opened (a refused plant leaves no log behind).
    assert line == ("excosim: run stopped: FMU boom (HydraulicCylinder) did not return from "
                    "its instantiation and initialization within 2 s (no log was written)")
    assert not (tmp_path / "run.mcap").exists()
    assert time.monotonic() - started < 120
    assert list(temporary.iterdir()) == []


def _children(pid: int) -> list[int]:
    path = Path(f"/proc/{pid}/task/{pid}/children")
    return [int(c) for c in path.read_text().split()] if path.exists() else []


def test_sigkill_on_the_command_ends_its_supervised_child_too(tmp_path):
    log = tmp_path / "run.mcap"
    process = subprocess.Popen(
        [sys.executable, "-c", MAIN, "run", str(PAPER), "--periods", "20", "-o", str(log),
         "-q"], env={**os.environ, "PYTHONPATH": str(ROOT)}, stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and not (log.exists() and log.stat().st_size > 0):
            time.sleep(0.01)
        children = _children(process.pid)
        assert len(children) == 1  # the digging child
        process.send_signal(signal.SIGKILL)
    finally:
        process.wait(timeout=60)
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline and Path(f"/proc/{children[0]}").exists() \
            and "Z" not in _state(children[0]):
        time.sleep(0.05)
    assert not Path(f"/proc/{children[0]}").exists() or "Z" in _state(children[0])
    assert not read_run(log).finished


def _state(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (OSError, IndexError):
        return "Z"
