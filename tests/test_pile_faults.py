"""Faults of the Pile FMU are the pile's: a NaN among its outputs is reported as the pile's (not
as the boom's "F_ext is not finite", which is where the NaN would go next), and an error from
its fmi2Terminate ends a run that otherwise succeeded (exit status 1, the log closed with the
reason and readable). The faulty Piles are ours with their FMI layer patched
(tests/faulty_fmus.py), as a foreign FMU without our layer's checks would behave."""

import subprocess
import sys
from pathlib import Path

import pytest
from faulty_fmus import PILE_NAN, PILE_TERMINATE_ERROR, patched_pile

from orchestrator.campaign import run_campaign
from orchestrator.runlog import read_run
from orchestrator.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "scenarios" / "paper-2020.toml"


@pytest.fixture(scope="module")
def piles(tmp_path_factory) -> dict[str, Path]:
    folder, built = tmp_path_factory.mktemp("piles"), {}
    for fault in (PILE_NAN, PILE_TERMINATE_ERROR):
        (folder / fault).mkdir()
        built[fault] = patched_pile(folder / fault, fault, "Pile")
    return built


def run(pile: Path, log: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "orchestrator.cli.app", "run", str(PAPER),
                           "--set", "periods=2", "--set", f"plant.pile.fmu={pile}", "--trust",
                           "-q", "-o", str(log)], capture_output=True, text=True, timeout=300)


def test_a_nan_output_of_the_pile_is_the_piles(piles, tmp_path):
    log = tmp_path / "nan.mcap"
    done = run(piles[PILE_NAN], log)
    assert done.returncode == 1, done.stderr[-500:]
    line = done.stderr.strip().splitlines()[-1]
    assert line.startswith("excosim: run failed: period 1: RuntimeError: pile (Pile): its "
                           "output is not finite after its step from t = 3.01 s "
                           "(bucket_mass 0.0, F_y nan, F_z "), line
    assert "boom" not in line and "F_ext" not in line
    assert "Traceback" not in done.stderr
    logged = read_run(log, tolerant=False)
    assert logged.termination == "error" and "pile (Pile): its output is not finite" in \
        logged.termination_message


def test_an_error_from_fmi2terminate_fails_the_run(piles, tmp_path):
    log = tmp_path / "terminate.mcap"
    done = run(piles[PILE_TERMINATE_ERROR], log)
    assert done.returncode == 1, done.stderr[-500:]
    line = done.stderr.strip().splitlines()[-1]
    said = ("closing the plant: RuntimeError: pile (Pile): fmi2Terminate failed: "
            "fmi2Terminate: a stuck valve (test fault)")
    assert line == f"excosim: run failed: {said} (log {log} is readable up to period 2)"
    logged = read_run(log, tolerant=False)  # closed, indexed, whole
    assert len(logged.periods) == 2 and logged.finished
    assert (logged.termination, logged.termination_message) == ("error", said)
    # The API gives the same result; a run whose steps failed keeps its own reason (FMI lets
    # terminate fail after an error, and nothing then reports it).
    result = run_campaign(load_scenario(PAPER, ["periods=1",
                                                f"plant.pile.fmu={piles[PILE_TERMINATE_ERROR]}"]))
    assert (result.termination, result.message) == ("error", said)
