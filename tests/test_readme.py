"""Every code block of the README runs as written, in order, in a fresh folder: the set-up block
through make's dry run, shell blocks with bash, Python blocks with this interpreter."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
FENCE = re.compile(r"^```([^\n`]*)\n(.*?)^```\s*$", re.M | re.S)
INDENTED = re.compile(r"(?:^|\n\n)((?: {4}[^\n]*\n)+)")  # a Markdown indented code block
LANGUAGES = {"sh": "shell", "bash": "shell", "python": "python"}
SETUP = ["make run", "make test-all"]
# What a block may use of the project, linked into the fresh folder (the README's commands are
# written for a shell in the project's folder).
PROJECT_ITEMS = ("scenarios", "foxglove", "examples", "bench", "sweeps")


def blocks(text: str) -> list[tuple[str, str]]:
    """(kind, code) of each fenced block in order; an unknown language is an error."""
    found = []
    for match in FENCE.finditer(text):
        language = match.group(1).strip().split()[0] if match.group(1).strip() else ""
        if language not in LANGUAGES:
            raise AssertionError(f"README block of language {language!r} is not run by the "
                                 f"suite: use one of {sorted(LANGUAGES)}")
        found.append((LANGUAGES[language], match.group(2)))
    return found


def commands(code: str) -> list[str]:
    return [line.split("#")[0].strip() for line in code.splitlines()
            if line.split("#")[0].strip()]


BLOCKS = blocks(README.read_text())


def test_the_readme_opens_with_the_two_setup_commands_and_has_no_unrun_block():
    assert BLOCKS[0] == ("shell", BLOCKS[0][1]) and commands(BLOCKS[0][1]) == SETUP
    outside_fences = FENCE.sub("", README.read_text())
    assert INDENTED.findall(outside_fences) == []  # an indented block would escape the suite
    assert len(BLOCKS) >= 6


def dry_run(target: str) -> str:
    """The commands `make TARGET` runs on a machine with nothing installed (-B: all stale)."""
    done = subprocess.run(["make", "-n", "-B", target, "VENV=/nonexistent/venv"], cwd=ROOT,
                          capture_output=True, text=True, timeout=60, check=True)
    return done.stdout


def test_make_run_installs_the_runtime_lock_only_and_make_test_adds_the_test_lock():
    run, test, everything = dry_run("run"), dry_run("test"), dry_run("test-all")
    assert '-m pytest -q -m "not slow"' in test and "-m pytest -q\n" in everything
    assert "make test-all" in (ROOT / ".ci" / "run").read_text()
    for plan in (run, test, everything):
        assert "--require-hashes -r requirements/run.txt" in plan
        assert "--no-build-isolation -e ." in plan
        assert "[test]" not in plan  # nothing resolved from pyproject's ranges
    assert "requirements/test.txt" not in run and "pytest" not in run
    assert "excosim run scenarios/paper-2020.toml" in run
    assert "--require-hashes -r requirements/test.txt" in test and "-m pytest" in test


def test_every_locked_package_is_pinned_with_hashes():
    for name in ("run.txt", "test.txt"):
        lines = (ROOT / "requirements" / name).read_text().splitlines()
        pins = [line for line in lines if line and not line.startswith((" ", "#"))]
        assert pins and all(re.fullmatch(r"[a-z0-9._-]+==[^ ]+ \\", pin) for pin in pins), name
        assert sum("--hash=sha256:" in line for line in lines) >= len(pins)
    run_pins = {p.split(" ")[0] for p in (ROOT / "requirements/run.txt").read_text().splitlines()
                if "==" in p and not p.startswith((" ", "#"))}
    test_pins = {p.split(" ")[0] for p in (ROOT / "requirements/test.txt").read_text().splitlines()
                 if "==" in p and not p.startswith((" ", "#"))}
    assert run_pins < test_pins  # the same versions, test adds its extra


@pytest.fixture(scope="module")
def folder(tmp_path_factory) -> Path:
    """A fresh working folder that looks like the project's to the README's commands."""
    path = tmp_path_factory.mktemp("readme")
    for item in PROJECT_ITEMS:
        (path / item).symlink_to(ROOT / item)
    (path / ".venv").symlink_to(Path(sys.prefix))
    return path


@pytest.mark.parametrize("index", range(1, len(BLOCKS)),
                         ids=[f"block{i}-{BLOCKS[i][0]}" for i in range(1, len(BLOCKS))])
def test_readme_block_runs(index, folder):
    kind, code = BLOCKS[index]
    env = dict(os.environ)  # as a user has it: the project is installed in the venv
    command = (["bash", "-euo", "pipefail", "-c", code] if kind == "shell"
               else [sys.executable, "-c", code])
    done = subprocess.run(command, cwd=folder, env=env, capture_output=True, text=True,
                          timeout=600, stdin=subprocess.DEVNULL)
    assert done.returncode == 0, f"block {index} ({kind}) failed:\n{code}\n{done.stderr[-3000:]}"
    assert "Traceback" not in done.stderr
