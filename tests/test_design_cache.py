"""Servo designs remembered on disk (orchestrator.plants.design_cache): the value read back is
the one computed, a damaged file is computed anew, a failure is not remembered; and what that
buys at start-up, checked by what a process imports (not by wall time): `excosim --help`
imports neither numpy nor python-control, and a run whose designs are remembered never imports
python-control."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from orchestrator.plants import design_cache
from plant_models.hydraulics import cylinder_model
from plant_models.servo import design_servo

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "scenarios" / "paper-2020.toml"


@pytest.fixture
def cache(tmp_path, monkeypatch) -> Path:
    monkeypatch.setenv("EXCOSIM_FMU_DIR", str(tmp_path / "fmus"))
    return tmp_path / "fmus" / "designs"


def test_a_value_is_computed_once_and_read_back(cache):
    calls = []

    def compute():
        calls.append(1)
        return {"gain": 0.1 + 0.2}

    assert design_cache.remembered("test", (1.5, "boom"), compute) == {"gain": 0.1 + 0.2}
    assert design_cache.remembered("test", (1.5, "boom"), compute) == {"gain": 0.1 + 0.2}
    assert len(calls) == 1 and len(list(cache.iterdir())) == 1
    design_cache.remembered("test", (1.5, "stick"), compute)  # other inputs: computed
    assert len(calls) == 2


def test_a_damaged_file_is_computed_anew_and_a_failure_is_not_remembered(cache):
    design_cache.remembered("test", (2,), lambda: 42)
    (stored,) = cache.iterdir()
    stored.write_bytes(stored.read_bytes()[:10])  # cut
    assert design_cache.remembered("test", (2,), lambda: 43) == 43
    stored.write_bytes(b"not a pickle at all")
    assert design_cache.remembered("test", (2,), lambda: 44) == 44

    def fails():
        raise ValueError("no servo with these margins")

    with pytest.raises(ValueError, match="no servo"):
        design_cache.remembered("test", (3,), fails)
    assert design_cache.remembered("test", (3,), lambda: 5) == 5


def test_a_remembered_servo_design_is_the_computed_one(cache):
    from orchestrator.plants import servo_setup

    model = cylinder_model("paper", "stick")
    settings = (0.01,)
    fresh = design_servo(model, *settings)
    servo_setup.design_servo_cached.cache_clear()
    first = servo_setup.design_servo_cached(model, *settings)
    servo_setup.design_servo_cached.cache_clear()  # the next one comes from the disk
    assert any(cache.iterdir())
    assert servo_setup.design_servo_cached(model, *settings) == first == fresh


def _imports_after(args: list[str], cwd: Path) -> set[str]:
    """The top-level packages `excosim ARGS` imports, as python -X importtime reports them."""
    code = f"import sys; sys.argv = ['excosim', *{args!r}]\n" \
        "from orchestrator.cli.app import main\nmain()\n"
    done = subprocess.run([sys.executable, "-X", "importtime", "-c", code], cwd=cwd,
                          capture_output=True, text=True, env={**os.environ}, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    return {line.rsplit("|", 1)[1].strip().split(".")[0]
            for line in done.stderr.splitlines() if line.startswith("import time:")}


def test_help_imports_neither_numpy_nor_control(tmp_path):
    modules = _imports_after(["--help"], tmp_path)
    assert "typer" in modules and not {"numpy", "control", "scipy"} & modules


def test_a_run_with_remembered_designs_never_imports_control(tmp_path):
    args = ["run", str(PAPER), "--periods", "1", "-q", "-o", "run.mcap", "--force",
            "--in-process"]
    _imports_after(args, tmp_path)  # remembers the designs (if not remembered already)
    modules = _imports_after(args, tmp_path)
    assert "scipy" in modules and "control" not in modules
