"""Every numbered example runs in seconds and prints what its docstring promises."""

import re
import subprocess
import sys
from pathlib import Path

import pytest

EXAMPLES = sorted((Path(__file__).parent.parent / "examples").glob("[0-9][0-9]_*.py"))


def _run(path: Path) -> str:
    done = subprocess.run(
        [sys.executable, str(path)], capture_output=True, text=True, timeout=120,
        cwd=path.parent.parent,
    )
    assert done.returncode == 0, done.stderr
    assert "Traceback" not in done.stderr
    return done.stdout


def test_examples_are_numbered_and_present():
    numbers = [int(p.name[:2]) for p in EXAMPLES]
    assert numbers[:6] == [1, 2, 3, 4, 5, 6]


@pytest.mark.parametrize("path", EXAMPLES, ids=[p.stem for p in EXAMPLES])
def test_example_runs(path):
    assert _run(path).strip()


def test_pile_example_weighs_the_swept_area():
    out = _run(next(p for p in EXAMPLES if p.stem == "06_pile"))
    # Vertical plunge and lift sweep no area; the 1.5 m drag at 0.2 m depth sweeps 0.3 m^2 of
    # section, times the FMU's default density * width (1600 kg/m^3 * 0.038 m).
    mass = float(re.search(r"bucket mass ([\d.]+) kg", out).group(1))
    assert mass == pytest.approx(1600.0 * 0.038 * 0.3, rel=1e-3)
    total, initial = map(float, re.search(r"= ([\d.]+) kg \(initial ([\d.]+) kg\)", out).groups())
    assert total == pytest.approx(initial, rel=1e-12)


def test_adaptation_example_resets_once_and_shifts_toward_the_machine():
    out = _run(next(p for p in EXAMPLES if p.stem == "04_adaptation"))
    assert out.count("workspace limit: reset") == 1
    assert "D = ( -5.50, -0.100)" in out
