"""The watchdog on FMU steps (orchestrator/campaign/watchdog.py): a step that never returns ends
`excosim run` with the FMU named, in one line, exit status 1, the log closed with the reason and
the extracted FMUs removed; the step loop itself carries no extra work."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from faulty_fmus import HANG, patched_cylinder

import fmus
from fmus.runs import FastSlave
from orchestrator.campaign.watchdog import SameCall, StepWatchdog, stuck_step
from orchestrator.runlog import read_run

ROOT = Path(__file__).resolve().parent.parent
PAPER = ROOT / "scenarios" / "paper-2020.toml"
MAIN = "from orchestrator.cli.app import main; main()"


@pytest.fixture(scope="module")
def hanging_cylinder(tmp_path_factory) -> Path:
    """Our cylinder, but its step spins forever from t = 0.5 s on."""
    return patched_cylinder(tmp_path_factory.mktemp("hang"), HANG, 0.5, "Hanging")


def test_a_step_that_never_returns_ends_the_run_with_the_fmu_named(tmp_path, hanging_cylinder):
    temporary = tmp_path / "tmp"
    temporary.mkdir()
    started = time.monotonic()
    done = subprocess.run(
        [sys.executable, "-c", MAIN, "run", str(PAPER), "--periods", "2", "-o", "run.mcap",
         "--trust", "--step-timeout", "2", "--set", f"plant.boom.fmu={hanging_cylinder}"],
        capture_output=True, text=True, cwd=tmp_path, timeout=180,
        env={**os.environ, "PYTHONPATH": str(ROOT), "TMPDIR": str(temporary)})
    assert done.returncode == 1 and done.stdout == ""
    lines = done.stderr.splitlines()
    assert len(lines) == 2 and lines[0].startswith("excosim: --trust: plant.boom.fmu runs")
    assert lines[1].startswith("excosim: run stopped: period 1: FMU boom (HydraulicCylinder) "
                               "did not return from its step at t = 0.5")
    assert lines[1].endswith("within 2 s (log run.mcap is readable up to period 0)")
    assert time.monotonic() - started < 120
    run = read_run(tmp_path / "run.mcap")
    assert run.finished and run.termination == "error" and run.periods == []
    assert "FMU boom (HydraulicCylinder) did not return" in run.termination_message
    assert list(temporary.iterdir()) == []  # the extracted FMUs are removed


def test_the_judgement_reports_one_call_seen_for_the_timeout_and_nothing_else():
    """SameCall on a fake clock: steps that keep returning (a new key at every poll) are never
    stuck, however long; one key seen for the timeout is; no FMU call (None) never is."""
    calls = SameCall(2.0)
    assert not any(calls.stuck(("boom", 0.01 * i), 10.0 * i) for i in range(100))
    assert not any(calls.stuck(None, 1000.0 + i) for i in range(10))
    assert [calls.stuck(("boom", 5.0), t) for t in (2000.0, 2001.0, 2001.99, 2002.0)] == \
        [False, False, False, True]


def test_steps_that_keep_returning_are_never_reported():
    """A busy step loop is sampled inside FastSlave.step again and again, at other times t:
    the watchdog stays quiet (and a frame that is no step is none). The timeout is far above
    the 10 ms poll and the 1 s loop, so a descheduled main thread cannot look stuck (the fake
    clock test above tries the judgement itself at its edge)."""
    reports: list[str] = []
    with FastSlave(fmus.build("HydraulicCylinder"), ["u"], ["x"], instance_name="stick") as ok:
        with StepWatchdog(5.0, reports.append, poll_s=0.01):
            deadline, t = time.monotonic() + 1.0, 0.0
            while time.monotonic() < deadline:
                ok.step(t, 1e-3, np.array([0.1]))
                t += 1e-3
    assert reports == [] and stuck_step(sys._getframe()) is None
    with pytest.raises(ValueError, match="step timeout must be > 0 s"):
        StepWatchdog(0.0, reports.append)


def test_every_instance_s_step_is_known_whatever_its_name_and_whoever_was_freed():
    """Code objects compare by value: two instances called "boom" (a sweep worker's second
    campaign) must not share one entry that goes when the first instance is freed."""
    import gc

    from fmus.runs import STEP_CODES

    built = fmus.build("HydraulicCylinder")
    first = FastSlave(built, ["u"], ["x"], instance_name="boom")
    second = FastSlave(built, ["u"], ["x"], instance_name="boom")
    try:
        assert first.step.__code__ != second.step.__code__
        first.close()
        del first
        gc.collect()
        assert second.step.__code__ in STEP_CODES
    finally:
        second.close()
