"""Every numbered example runs in seconds and prints what its docstring promises."""

import re
import subprocess
import sys
from pathlib import Path

import pytest

EXAMPLES = sorted((Path(__file__).parent.parent / "examples").glob("[0-9][0-9]_*.py"))


def _run(path: Path, cwd: Path, *args: str) -> str:
    # A temporary cwd: what an example writes to its current folder must not land in the repo.
    done = subprocess.run(
        [sys.executable, str(path), *args], capture_output=True, text=True, timeout=120,
        cwd=cwd,
    )
    assert done.returncode == 0, done.stderr
    assert "Traceback" not in done.stderr
    return done.stdout


def test_examples_are_numbered_and_present():
    numbers = [int(p.name[:2]) for p in EXAMPLES]
    assert numbers[:6] == [1, 2, 3, 4, 5, 6]


@pytest.mark.parametrize("path", EXAMPLES, ids=[p.stem for p in EXAMPLES])
def test_example_runs(path, tmp_path):
    assert _run(path, tmp_path).strip()


def test_pile_example_weighs_the_swept_area(tmp_path):
    out = _run(next(p for p in EXAMPLES if p.stem == "06_pile"), tmp_path)
    # Vertical plunge and lift sweep no area; the 1.5 m drag at 0.2 m depth sweeps 0.3 m^2 of
    # section, times the FMU's default density * width (1600 kg/m^3 * 0.038 m).
    mass = float(re.search(r"bucket mass ([\d.]+) kg", out).group(1))
    assert mass == pytest.approx(1600.0 * 0.038 * 0.3, rel=1e-3)
    total, initial = map(float, re.search(r"= ([\d.]+) kg \(initial ([\d.]+) kg\)", out).groups())
    assert total == pytest.approx(initial, rel=1e-12)


def test_adaptation_example_resets_once_and_shifts_toward_the_machine(tmp_path):
    out = _run(next(p for p in EXAMPLES if p.stem == "04_adaptation"), tmp_path)
    assert out.count("workspace limit: reset") == 1
    assert "D = ( -5.50, -0.100)" in out


def test_review_example_leaves_its_figures_where_it_says(tmp_path):
    """figures/ in the current folder by default, or the folder given; absolute paths printed."""
    example = next(p for p in EXAMPLES if p.stem == "08_review_run")
    for args, folder in (((), tmp_path / "figures"), (("given",), tmp_path / "given")):
        out = _run(example, tmp_path, *args)
        written = [Path(p) for p in re.findall(r"^wrote (\S+\.png) ", out, flags=re.M)]
        assert {p.name for p in written} >= {"tip_paths.png", "period_02_joints.png"}
        for path in written:
            assert path.is_absolute() and path.parent == folder.resolve()
            assert path.stat().st_size > 10_000
