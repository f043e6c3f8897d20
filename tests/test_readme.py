"""Every code block of the README, and of every page of the documentation site (docs/), runs as
written, in order, in a fresh folder (one per page): the set-up block through make's dry run,
shell blocks with bash, Python blocks with this interpreter. On the site's pages a `text` block
(a diagram) is the one kind that is not run."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
DOCS = ROOT / "docs"
FENCE = re.compile(r"^```([^\n`]*)\n(.*?)^```\s*$", re.M | re.S)
INDENTED = re.compile(r"(?:^|\n\n)((?: {4}[^\n]*\n)+)")  # a Markdown indented code block
LANGUAGES = {"sh": "shell", "bash": "shell", "python": "python"}
SETUP = ["make run", "make test-all"]
# What a block may use of the project, linked into the fresh folder (the README's commands are
# written for a shell in the project's folder).
PROJECT_ITEMS = ("scenarios", "foxglove", "examples", "bench", "sweeps")


def blocks(text: str, page: bool = False) -> list[tuple[str, str]]:
    """(kind, code) of each fenced block in order; an unknown language is an error (a site page
    may also hold `text` blocks, left out)."""
    found = []
    for match in FENCE.finditer(text):
        language = match.group(1).strip().split()[0] if match.group(1).strip() else ""
        if page and language == "text":
            continue
        if language not in LANGUAGES:
            raise AssertionError(f"block of language {language!r} is not run by the "
                                 f"suite: use one of {sorted(LANGUAGES)}")
        found.append((LANGUAGES[language], match.group(2)))
    return found


def commands(code: str) -> list[str]:
    return [line.split("#")[0].strip() for line in code.splitlines()
            if line.split("#")[0].strip()]


BLOCKS = blocks(README.read_text())
PAGES = sorted(path.relative_to(DOCS).as_posix() for path in DOCS.rglob("*.md"))
# (page, index, kind, code) of every block of the site's pages but a copy of the set-up block
# (which the dry runs below check).
PAGE_BLOCKS = [(page, index, kind, code) for page in PAGES
               for index, (kind, code) in enumerate(blocks((DOCS / page).read_text(), True))
               if commands(code) != SETUP]


def test_the_readme_opens_with_the_two_setup_commands_and_has_no_unrun_block():
    assert BLOCKS[0] == ("shell", BLOCKS[0][1]) and commands(BLOCKS[0][1]) == SETUP
    for text in (README.read_text(), *((DOCS / page).read_text() for page in PAGES)):
        outside_fences = FENCE.sub("", text)
        assert INDENTED.findall(outside_fences) == []  # an indented block would escape the suite
    assert len(BLOCKS) >= 3 and len(PAGE_BLOCKS) >= 20


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


def run_block(kind: str, code: str, folder: Path, where: str) -> None:
    env = dict(os.environ)  # as a user has it: the project is installed in the venv
    command = (["bash", "-euo", "pipefail", "-c", code] if kind == "shell"
               else [sys.executable, "-c", code])
    done = subprocess.run(command, cwd=folder, env=env, capture_output=True, text=True,
                          timeout=600, stdin=subprocess.DEVNULL)
    assert done.returncode == 0, f"{where} ({kind}) failed:\n{code}\n{done.stderr[-3000:]}"
    assert "Traceback" not in done.stderr


@pytest.mark.parametrize("index", range(1, len(BLOCKS)),
                         ids=[f"block{i}-{BLOCKS[i][0]}" for i in range(1, len(BLOCKS))])
def test_readme_block_runs(index, folder):
    kind, code = BLOCKS[index]
    run_block(kind, code, folder, f"block {index}")


@pytest.fixture(scope="module")
def page_folders() -> dict[str, Path]:
    """page -> its own fresh folder, made as the page's first block runs."""
    return {}


@pytest.mark.parametrize("page, index, kind, code", PAGE_BLOCKS,
                         ids=[f"{page}-block{i}-{kind}" for page, i, kind, _ in PAGE_BLOCKS])
def test_page_block_runs(page, index, kind, code, page_folders, tmp_path_factory):
    if page not in page_folders:
        path = tmp_path_factory.mktemp(page.replace("/", "-").removesuffix(".md"))
        for item in PROJECT_ITEMS:
            (path / item).symlink_to(ROOT / item)
        (path / ".venv").symlink_to(Path(sys.prefix))
        page_folders[page] = path
    run_block(kind, code, page_folders[page], f"docs/{page} block {index}")
