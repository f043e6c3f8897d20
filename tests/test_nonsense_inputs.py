"""Inputs that described no machine, or crashed with a traceback, are refused in one line naming
what is wrong (orchestrator.scenario.physics_bounds, the scenario and --set readers, the log
repair). Each case is a value the generated-input audit found accepted or crashing."""

import random
import subprocess
import sys
from pathlib import Path

import pytest

from orchestrator.campaign import run_campaign
from orchestrator.runlog.repair import repair
from orchestrator.scenario import ScenarioError, load_scenario

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "scenarios" / "paper-2020.toml"


@pytest.mark.parametrize("item, field, words", [
    ("plant.pile.parameters.y_max=-10", "adaptation.y_D0_m", "lies outside the pile's grid"),
    ("plant.pile.parameters.y_max=9.2e18", "plant.pile.parameters", "coarser than a quarter"),
    ("target_mass_kg=1e-9", "target_mass_kg", "less than 1 % of what the bucket holds"),
    ("adaptation.dz_0_m=-10", "adaptation.dz_0_m", "more than half the bucket's length"),
    ("adaptation.dz_0_m=1", "adaptation.dz_0_m", "more than half the bucket's length"),
    ("adaptation.dy_0_m=9.2e18", "adaptation.dy_0_m", "more than the pile's grid is wide"),
    ("adaptation.dy_0_m=-25", "adaptation.dy_0_m", "and the arm reaches"),
    ("plant.bucket.parameters.V_dead_A=1", "plant.bucket.parameters.V_dead_A",
     "more than ten times the cylinder's swept volume"),
    ("plant.pile.parameters.gravity=1e4", "plant.pile.parameters.gravity", "outside 1-25"),
    ("plant.pile.parameters.heap_height=100", "plant.pile.parameters.heap_height",
     "higher than the arm reaches"),
    ("plant.pile.parameters.cohesion=1e12", "plant.pile.parameters.cohesion", "that is rock"),
    ("log.sample_rate_hz=1e6", "log.sample_rate_hz", "more than one sample per communication"),
    ("seed=99999999999999999999999", "seed", "less than or equal to 9223372036854775807"),
])
def test_physical_nonsense_is_refused_at_load(item, field, words):
    with pytest.raises(ScenarioError) as error:
        load_scenario(PAPER, [item])
    assert error.value.field == field and words in error.value.reason


def test_the_bounds_leave_every_shipped_scenario_alone():
    for path in sorted((ROOT / "scenarios").glob("*.toml")):
        load_scenario(path)


def test_deep_nesting_and_long_paths_are_one_line(tmp_path):
    nested = tmp_path / "nested.toml"
    nested.write_text(PAPER.read_text().replace(
        "[machine]", "zz = " + "[" * 1000 + "]" * 1000 + "\n\n[machine]", 1))
    with pytest.raises(ScenarioError, match="not valid TOML: nested too deeply"):
        load_scenario(nested)
    with pytest.raises(ValueError, match=r"--set periods: the value is nested too deeply"):
        load_scenario(PAPER, ["periods=" + "[" * 1000 + "]" * 1000])
    with pytest.raises(ScenarioError, match=r"plant\.boom\.fmu: cannot look at the file"):
        load_scenario(PAPER, ["plant.boom.fmu=" + "a" * 300 + ".fmu"])
    done = subprocess.run([sys.executable, "-m", "orchestrator.cli.app", "run", str(nested)],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 2 and "Traceback" not in done.stderr
    assert len(done.stderr.strip().splitlines()) == 1


def test_a_log_with_bytes_overwritten_mid_file_is_repaired_up_to_the_damage(tmp_path):
    log = tmp_path / "run.mcap"
    assert run_campaign(load_scenario(PAPER, ["periods=3"]), log_path=log).termination == \
        "periods"
    data = bytearray(log.read_bytes())
    for seed in range(3):  # 4 kB of noise where lengths and offsets live: no traceback
        damaged = bytearray(data)
        start = len(data) // 2 + 5000 * seed
        noise = random.Random(seed)
        damaged[start:start + 4096] = bytes(noise.randrange(256) for _ in range(4096))
        source = tmp_path / f"damaged{seed}.mcap"
        source.write_bytes(bytes(damaged))
        report = repair(source, tmp_path / f"repaired{seed}.mcap")
        assert report.truncated and 1 <= report.periods < 3


def test_review_and_compare_options_that_would_be_ignored_or_create_folders(tmp_path):
    log = tmp_path / "run.mcap"
    run_campaign(load_scenario(PAPER, ["periods=1"]), log_path=log)

    def cli(*args):
        return subprocess.run([sys.executable, "-m", "orchestrator.cli.app", *map(str, args)],
                              capture_output=True, text=True, timeout=120)

    for period in (0, 99):  # without --plots it picked nothing: now said
        done = cli("review", log, "--period", period)
        assert done.returncode == 2 and "add --plots DIR" in done.stderr
    done = cli("review", log, "--csv", tmp_path / "missing" / "dir" / "x.csv")
    assert done.returncode == 2 and "does not exist" in done.stderr
    assert not (tmp_path / "missing").exists()
    done = cli("compare", log, log)
    assert done.returncode == 0 and "the same file is given more than once" in done.stdout


def test_a_worker_that_cannot_see_the_sweeps_fmu_gets_the_one_sent(tmp_path, monkeypatch):
    """The FMU files sent with a sweep's run: written under the worker's TMPDIR (a file
    planted there with other content is replaced, not run), and only the FMU roles point at
    them (plant.supply used to get an `fmu = None` key and every run failed)."""
    import hashlib
    import shutil
    import tempfile

    import fmus
    from orchestrator.sweep.plan import RunTask
    from orchestrator.sweep.worker import _scenario

    sent = tmp_path / "sweep" / "Ideal.fmu"
    sent.parent.mkdir()
    shutil.copy(fmus.build("IdealActuator"), sent)
    scenario = load_scenario(PAPER, [f'plant.bucket.fmu="{sent}"'])
    content = sent.read_bytes()
    task = RunTask("run-0001", {}, scenario.to_dict(), "paper-2020.toml", "", (),
                   str(tmp_path / "run-0001.mcap"), {str(sent): content})
    sent.unlink()  # the worker's file system does not see the sweep's folder
    worker_tmp = tmp_path / "worker-tmp"
    worker_tmp.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(worker_tmp))
    digest = hashlib.sha256(content).hexdigest()
    planted = worker_tmp / "excosim-sweep-fmus" / digest / "Ideal.fmu"
    planted.parent.mkdir(parents=True)
    planted.write_bytes(b"not the FMU that was sent")
    resolved = _scenario(task)
    assert resolved.plant.bucket.fmu == str(planted)
    assert planted.read_bytes() == content
    assert "fmu" not in resolved.to_dict()["plant"]["supply"]


def test_folders_of_killed_runs_are_removed_by_the_next(tmp_path, monkeypatch):
    """A SIGKILL leaves a run's temporary folder; the next run removes those whose owner no
    longer runs (and that are older than a minute), and leaves the rest alone."""
    import os
    import tempfile
    import time

    from orchestrator.campaign import stale_folders

    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True, check=True).stdout.strip()
    old = time.time() - 2 * stale_folders.MIN_AGE_S
    folders = {}
    for name, owner, age in (("killed", dead, old), ("running", str(os.getpid()), old),
                             ("young", dead, None), ("foreign", None, old)):
        folder = tmp_path / f"excosim-run-{name}"
        folder.mkdir()
        if owner is not None:
            (folder / stale_folders.OWNER_FILE).write_text(owner)
        if age is not None:
            os.utime(folder, (age, age))
        folders[name] = folder
    assert stale_folders.remove_stale("excosim-run-") == [folders["killed"]]
    assert [f.exists() for f in folders.values()] == [False, True, True, True]
    made = stale_folders.owned_folder("excosim-run-")
    assert (made / stale_folders.OWNER_FILE).read_text() == str(os.getpid())


def test_an_fmu_without_a_binary_for_this_platform_is_refused_at_load(tmp_path):
    """Our HydraulicCylinder repacked as if built for Windows only: refused when the scenario
    loads, naming what it carries (it used to stop the run after its log was written)."""
    import zipfile

    import fmus

    built = fmus.build("HydraulicCylinder")
    windows = tmp_path / "Windows.fmu"
    with zipfile.ZipFile(built) as source, zipfile.ZipFile(windows, "w") as out:
        for name in source.namelist():
            renamed = name.replace("binaries/linux64/", "binaries/win64/").replace(".so", ".dll")
            out.writestr(renamed, source.read(name))
    with pytest.raises(ScenarioError) as error:
        load_scenario(PAPER, [f'plant.bucket.fmu="{windows}"'])
    assert error.value.field == "plant.bucket.fmu"
    assert error.value.reason == ("Windows.fmu has no binary for this platform "
                                  "(binaries/linux64/HydraulicCylinder.so); it carries win64")


def test_an_fmu_folder_that_cannot_be_made_is_the_users_mistake(tmp_path):
    """$EXCOSIM_FMU_DIR naming a file, where a build is needed (a user's edit of the C sources,
    here in a copy of the fmus package): `fmus build` exits 2 as `run` does, one line."""
    import os
    import shutil

    tree = tmp_path / "tree"
    shutil.copytree(ROOT / "fmus", tree / "fmus",
                    ignore=shutil.ignore_patterns("_built", "__pycache__"))
    with open(tree / "fmus" / "IdealActuator" / "model.c", "a") as source:
        source.write("/* the user's edit */\n")
    blocker = tmp_path / "a-file"
    blocker.write_text("not a folder")
    env = {**os.environ, "EXCOSIM_FMU_DIR": str(blocker),
           "PYTHONPATH": os.pathsep.join([str(tree), str(ROOT)])}
    done = subprocess.run([sys.executable, "-m", "orchestrator.cli.app", "fmus", "build",
                           "IdealActuator"], capture_output=True, text=True, timeout=120, env=env,
                          cwd=tmp_path)
    assert done.returncode == 2 and done.stderr.startswith("excosim: cannot create the FMU "
                                                           "folder")
    assert len(done.stderr.strip().splitlines()) == 1
