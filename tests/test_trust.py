"""The trust rule of the commands that run a scenario's FMUs (orchestrator/cli/trust.py): an FMU
file whose content is none of our builds needs --trust, as in `excosim replay`; the refusal is
one line with the file's sha256 and exit status 2 before any log is written; with --trust the
command names the file and its full sha256. A copy of our own build runs as it is."""

from __future__ import annotations

import hashlib
import shutil
import zipfile
from pathlib import Path

import pytest
from typer.testing import CliRunner

import fmus
from orchestrator.cli.app import app
from orchestrator.runlog import read_run

ROOT = Path(__file__).resolve().parent.parent
PAPER = ROOT / "scenarios" / "paper-2020.toml"


@pytest.fixture(scope="module")
def files(tmp_path_factory) -> dict[str, Path]:
    folder = tmp_path_factory.mktemp("fmu-files")
    copy = folder / "MyCylinder.fmu"
    shutil.copyfile(fmus.build("HydraulicCylinder"), copy)
    foreign = folder / "Vendor.fmu"
    with zipfile.ZipFile(copy) as ours, zipfile.ZipFile(foreign, "w") as theirs:
        for info in ours.infolist():
            data = ours.read(info)
            theirs.writestr(info, data + b"/* theirs */\n" if info.filename == "sources/model.c"
                            else data)
    linked = folder / "Linked.fmu"
    shutil.copyfile(copy, linked)
    link = zipfile.ZipInfo("resources/link")
    link.create_system, link.external_attr = 3, 0o120777 << 16
    with zipfile.ZipFile(linked, "a") as archive:
        archive.writestr(link, "/etc/passwd")
    return {"copy": copy, "foreign": foreign, "linked": linked}


def _run(*args: str):
    return CliRunner().invoke(app, ["run", str(PAPER), "--periods", "1", "-q", *args])


def test_a_foreign_fmu_file_needs_trust_and_nothing_is_written(files, tmp_path):
    log = tmp_path / "run.mcap"
    done = _run("--set", f"plant.boom.fmu={files['foreign']}", "-o", str(log))
    digest = hashlib.sha256(files["foreign"].read_bytes()).hexdigest()
    assert done.exit_code == 2 and done.stderr.count("\n") == 1
    assert done.stderr.startswith(f"excosim: plant.boom.fmu: {files['foreign']} (sha256 "
                                  f"{digest[:12]}) is not an FMU built from this version's")
    assert "--trust" in done.stderr and "native code" in done.stderr
    assert not log.exists() and done.stdout == ""


def test_with_trust_it_runs_and_the_file_is_named_with_its_sha256(files, tmp_path):
    log = tmp_path / "run.mcap"
    done = CliRunner().invoke(app, ["run", str(PAPER), "--periods", "1", "--trust", "-o",
                                    str(log), "--set", f"plant.boom.fmu={files['foreign']}"])
    digest = hashlib.sha256(files["foreign"].read_bytes()).hexdigest()
    assert done.exit_code == 0, done.output
    assert f"excosim: --trust: plant.boom.fmu runs {files['foreign']} (sha256 {digest})\n" \
        in done.stderr
    run = read_run(log)
    assert run.finished and run.metadata["excosim.fmus"]["boom"] == digest


def test_a_copy_of_our_build_needs_no_trust(files, tmp_path):
    done = _run("--set", f"plant.boom.fmu={files['copy']}", "-o", str(tmp_path / "run.mcap"))
    assert done.exit_code == 0, done.output
    assert done.stderr == ""


def test_an_unsafe_fmu_file_is_refused_at_load_even_with_trust(files, tmp_path):
    log = tmp_path / "run.mcap"
    done = _run("--trust", "--set", f"plant.boom.fmu={files['linked']}", "-o", str(log))
    assert done.exit_code == 2 and done.stderr.count("\n") == 1
    assert "plant.boom.fmu: not a readable FMU" in done.stderr
    assert "'resources/link' is a link" in done.stderr and not log.exists()


def test_scenario_show_follows_the_same_rule(files):
    runner = CliRunner()
    args = ["scenario", "show", str(PAPER), "--set", f"plant.stick.fmu={files['foreign']}"]
    refused = runner.invoke(app, args)
    assert refused.exit_code == 2 and "plant.stick.fmu:" in refused.stderr
    assert "--trust" in refused.stderr and refused.stdout == ""
    shown = runner.invoke(app, [*args, "--trust", "--json"])
    assert shown.exit_code == 0, shown.output
    assert shown.stderr == ""  # --json: one object on stdout and nothing else
