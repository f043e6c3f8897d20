"""Native code built when the package is built (setup.py's build_native, fmus.prebuild,
fmus.packaged): after `pip install -e .` or from a wheel, our FMUs and libraries serve without
gcc (the CLI runs a campaign, --trust compares against them), FMI binaries sit where fmpy looks
for this CPU, an edited or damaged artifact is not used, and the package build is
byte-reproducible (the slow tests build everything and a wheel)."""

from __future__ import annotations

import json
import os
import platform
import shutil
import subprocess
import sys
import sysconfig
import zipfile
from pathlib import Path

import fmpy
import pytest

import fmus
from fmus import packaged
from fmus.builder import MODELS_DIR, source_key
from fmus.prebuild import prebuild, stale
from fmus.shared_library import LIBRARIES, build_library, library_sources
from fmus.toolchain import BuildError, platform_folder

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "scenarios" / "paper-2020.toml"


@pytest.fixture
def installed() -> None:
    """The package's build (fmus/_built) is of these sources: else say how to refresh it."""
    old = stale()
    assert old == [], (f"fmus/_built is not the build of these sources ({', '.join(old)}): "
                       "install again (make .venv/.run-installed, or pip install -e .)")


@pytest.fixture
def no_gcc(tmp_path, monkeypatch) -> Path:
    """PATH without gcc and an empty build cache; returns the cache folder (not made)."""
    (tmp_path / "bin").mkdir()
    monkeypatch.setenv("PATH", str(tmp_path / "bin"))
    monkeypatch.setenv("EXCOSIM_FMU_DIR", str(tmp_path / "cache"))
    return tmp_path / "cache"


def _nothing_built(cache: Path) -> bool:
    """No FMU and no library in the build cache `cache` (other caches may live there)."""
    return not list(cache.rglob("*.fmu")) and not list(cache.rglob("*.so"))


def test_our_fmus_and_libraries_come_with_the_package_without_gcc(installed, no_gcc):
    for version in (2, 3):
        for name in fmus.MODELS:
            path = fmus.build(name, fmi_version=version)
            assert path == packaged.fmu_target(packaged.BUILT_DIR, name, version)
        assert sorted(fmus.local_content_hashes(version).values()) == sorted(fmus.MODELS)
    for name in LIBRARIES:
        path = build_library(name, *library_sources(name))
        assert path == packaged.library_target(packaged.BUILT_DIR, name)
    assert _nothing_built(no_gcc)


def test_what_a_build_of_the_package_would_compile_again(installed, tmp_path):
    """fmus.prebuild.stale: nothing in a fresh build, what is missing or of other sources."""
    root = Path(shutil.copytree(packaged.BUILT_DIR, tmp_path / "_built"))
    assert stale(root) == []
    packaged.fmu_target(root, "Pile", 3).with_suffix(".json").unlink()
    slump = packaged.library_target(root, "slump")
    packaged.write_record(slump, {**packaged.read_record(slump), "source": "0" * 64})
    assert stale(root) == ["fmi3/Pile.fmu", "native/slump.so"]


def test_an_edit_of_the_sources_is_not_the_packaged_build(installed, tmp_path, no_gcc):
    """The packaged FMU serves the sources it was built from, wherever they are; an edited
    copy needs a build (and so gcc)."""
    copy = Path(shutil.copytree(MODELS_DIR / "Pile", tmp_path / "Pile"))
    record = packaged.read_record(packaged.fmu_target(packaged.BUILT_DIR, "Pile", 2))
    assert source_key(copy) == record["source"]
    assert packaged.packaged_fmu("Pile", 2, source_key(copy)) is not None
    with open(copy / "model.c", "a") as source:
        source.write("/* an edit */\n")
    assert source_key(copy) != record["source"]
    assert packaged.packaged_fmu("Pile", 2, source_key(copy)) is None
    with pytest.raises(BuildError, match="gcc not found"):
        fmus.build_model(copy)


def test_a_damaged_packaged_artifact_is_not_used(installed, tmp_path, monkeypatch):
    built = Path(shutil.copytree(packaged.BUILT_DIR, tmp_path / "_built"))
    monkeypatch.setattr(packaged, "BUILT_DIR", built)
    pile = packaged.fmu_target(built, "Pile", 3)
    source = packaged.read_record(pile)["source"]
    assert packaged.packaged_fmu("Pile", 3, source) == pile
    with zipfile.ZipFile(pile, "a") as archive:  # a second binary: another content hash
        archive.writestr("binaries/x86_64-linux/extra.so", b"\x7fELF")
    assert packaged.packaged_fmu("Pile", 3, source) is None
    rows = packaged.library_target(built, "runlog_rows")
    source = packaged.read_record(rows)["source"]
    assert packaged.packaged_library("runlog_rows", source) == rows
    rows.write_bytes(rows.read_bytes()[:-1])  # cut
    assert packaged.packaged_library("runlog_rows", source) is None
    slump = packaged.library_target(built, "slump")
    record = packaged.read_record(slump)
    packaged.write_record(slump, {**record, "source": "0" * 64})  # other sources
    assert packaged.packaged_library("slump", record["source"]) is None


def test_binaries_go_where_fmpy_looks_for_this_cpu():
    assert {m: platform_folder(3, m) for m in ("x86_64", "AMD64", "aarch64", "arm64")} == {
        "x86_64": "x86_64-linux", "AMD64": "x86_64-linux", "aarch64": "aarch64-linux",
        "arm64": "aarch64-linux"}
    assert platform_folder(2, "aarch64") == "linux64"
    with pytest.raises(BuildError, match="riscv64"):
        platform_folder(3, "riscv64")
    for version, folder in ((2, fmpy.platform), (3, fmpy.platform_tuple)):
        with zipfile.ZipFile(fmus.build("HydraulicCylinder", fmi_version=version)) as archive:
            assert f"binaries/{folder}/HydraulicCylinder.so" in archive.namelist()


def test_trust_compares_against_the_packaged_fmus_without_gcc(installed, tmp_path, no_gcc):
    from orchestrator.cli.trust import trust_problem
    from orchestrator.scenario import load_scenario

    copy = tmp_path / "MyCylinder.fmu"
    shutil.copyfile(fmus.build("HydraulicCylinder", fmi_version=3), copy)
    assert trust_problem(load_scenario(PAPER, [f"plant.boom.fmu={copy}"]), False) is None
    foreign = tmp_path / "Vendor.fmu"
    with zipfile.ZipFile(copy) as ours, zipfile.ZipFile(foreign, "w") as theirs:
        for info in ours.infolist():
            data = ours.read(info)
            theirs.writestr(info, data + b"/* theirs */\n" if info.filename == "sources/model.c"
                            else data)
    message, status = trust_problem(load_scenario(PAPER, [f"plant.boom.fmu={foreign}"]), False)
    assert status == 2 and "is not an FMU built from this version's sources" in message
    assert _nothing_built(no_gcc)


def _run_without_gcc(excosim: Path, where: Path) -> subprocess.CompletedProcess:
    """A 1-period paper campaign through `excosim` in an empty environment whose PATH has no
    gcc, with an empty build cache."""
    (where / "bin").mkdir()
    (where / "cache").mkdir()
    env = {"PATH": str(where / "bin"), "EXCOSIM_FMU_DIR": str(where / "cache"),
           "HOME": str(where), "OPENBLAS_NUM_THREADS": "1"}
    return subprocess.run([str(excosim), "run", str(PAPER), "--periods", "1", "-q",
                           "-o", str(where / "run.mcap")], env=env, cwd=where,
                          capture_output=True, text=True, timeout=600)


def test_the_installed_cli_runs_a_campaign_without_gcc(installed, tmp_path):
    """The editable install (make .venv/.run-installed: pip install -e .) compiled everything:
    `env -i PATH=<no gcc> excosim run ...` digs and logs."""
    excosim = Path(sys.executable).parent / "excosim"
    assert excosim.is_file(), f"no {excosim}: install the project (pip install -e .)"
    done = _run_without_gcc(excosim, tmp_path)
    assert done.returncode == 0, done.stderr
    assert (tmp_path / "run.mcap").stat().st_size > 0
    assert _nothing_built(tmp_path / "cache")


@pytest.mark.slow
def test_the_package_build_keeps_what_is_current_and_is_reproducible(installed, tmp_path):
    root = tmp_path / "_built"
    (root / "fmi2").mkdir(parents=True)
    (root / "fmi2" / "Gone.fmu").write_bytes(b"a model that no longer exists")
    said: list[str] = []
    written = prebuild(root, said.append)
    assert len(said) == 2 * len(fmus.MODELS) + len(LIBRARIES)
    assert not (root / "fmi2" / "Gone.fmu").exists()
    for path in written:  # the same bytes as the installed package's build
        assert path.read_bytes() == (packaged.BUILT_DIR / path.relative_to(root)).read_bytes()
    said.clear()
    assert prebuild(root, said.append) == written and said == []


@pytest.mark.slow
def test_a_wheel_installed_in_a_fresh_venv_runs_a_campaign_without_gcc(tmp_path):
    """pip wheel of the tracked sources (a copy: nothing of this tree's fmus/_built), installed
    in a new venv whose dependencies are this venv's packages, runs with gcc off the PATH."""
    tree = tmp_path / "tree"
    tree.mkdir()
    for name in ("pyproject.toml", "setup.py", "README.md"):
        shutil.copyfile(ROOT / name, tree / name)
    for package in ("fmus", "plant_models", "planner", "orchestrator"):
        shutil.copytree(ROOT / package, tree / package,
                        ignore=shutil.ignore_patterns("_built", "__pycache__"))
    wheels = tmp_path / "wheels"
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--quiet", "--no-deps",
                    "--no-build-isolation", "-w", str(wheels), str(tree)], check=True,
                   cwd=tmp_path, timeout=900)
    (wheel,) = wheels.iterdir()
    assert wheel.name == f"excosim-0.1.0-py3-none-linux_{platform.machine().lower()}.whl"
    with zipfile.ZipFile(wheel) as archive:
        names = set(archive.namelist())
    assert {str(Path("fmus/_built/fmi3") / f"{m}.fmu") for m in fmus.MODELS} <= names
    assert {f"fmus/_built/native/{n}.so" for n in LIBRARIES} <= names

    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True)
    python = venv / "bin" / "python"
    subprocess.run([sys.executable, "-m", "pip", "--python", str(python), "install", "--quiet",
                    "--no-deps", str(wheel)], check=True, timeout=600)
    # Only then the dependencies: this venv's site-packages at the end of the new one's path
    # (its .pth files, among them the editable install's, are not run).
    site = subprocess.run([str(python), "-c", "import sysconfig; print(sysconfig.get_paths()"
                           "['purelib'])"], capture_output=True, text=True, check=True)
    Path(site.stdout.strip(), "dependencies.pth").write_text(
        sysconfig.get_paths()["purelib"] + "\n")
    where = subprocess.run([str(python), "-c", "import fmus, orchestrator, planner, json; "
                            "print(json.dumps([m.__file__ for m in (fmus, orchestrator, "
                            "planner)]))"], capture_output=True, text=True, check=True,
                           cwd=tmp_path, env={**os.environ, "PYTHONPATH": ""})
    for path in json.loads(where.stdout):
        assert Path(path).is_relative_to(venv), path
    run = tmp_path / "run"
    run.mkdir()
    done = _run_without_gcc(venv / "bin" / "excosim", run)
    assert done.returncode == 0, done.stderr
    assert (run / "run.mcap").stat().st_size > 0
    assert _nothing_built(run / "cache")
