"""`excosim scenario show`: the resolved scenario, the FMU of each role and its servo, run as a
user would, compared with the library's own answers."""

import hashlib
import json
import subprocess
import sys
from pathlib import Path

import fmus
from orchestrator.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "scenarios" / "paper-2020.toml"


def excosim(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "orchestrator.cli.app", *args],
                          capture_output=True, text=True, timeout=120)


def test_show_prints_the_resolved_scenario_roles_and_servos():
    done = excosim("scenario", "show", str(PAPER), "--set", "periods=3", "--json")
    assert done.returncode == 0, done.stderr
    shown = json.loads(done.stdout)
    assert shown["scenario"] == load_scenario(PAPER, ["periods=3"]).to_dict()
    assert shown["overrides"] == ["periods=3"]
    for role, model in (("boom", "HydraulicCylinder"), ("pile", "Pile")):
        data = Path(fmus.build(model)).read_bytes()
        assert shown["roles"][role]["sha256"] == hashlib.sha256(data).hexdigest()
    assert set(shown["servos"]) == {"boom", "stick", "bucket"}
    for design in shown["servos"].values():  # the design targets: 6 dB, 45 deg
        assert design["gain_margin_db"] >= 6.0 and design["phase_margin_deg"] >= 45.0
    text = excosim("scenario", "show", str(PAPER))
    assert "periods = 20" in text.stdout and "boom: w_h" in text.stdout


def test_a_mistake_is_one_line_and_exit_2():
    done = excosim("scenario", "show", str(PAPER), "--set", "perods=3")
    assert done.returncode == 2 and done.stderr.count("\n") == 1
    assert "perods: unknown key" in done.stderr and done.stdout == ""
