"""Sweeps (orchestrator.sweep, `excosim sweep`): a small sweep of 2-period runs gives the same
summary on 2 local workers and on a Dask LocalCluster (2 worker processes); the summary's figures
are those `excosim compare` prints for the same logs; resume skips complete runs and re-runs a
killed (truncated) one; a run that fails, or whose worker dies, does not stop the others; a bad
sweep file stops with one line and exit 2 before any run."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from faulty_fmus import CRASH, FAIL, patched_cylinder

from orchestrator.sweep import SchedulerUnreachable, SweepError, load_sweep, prepare, run_sweep
from orchestrator.sweep.executors import connect
from orchestrator.sweep.worker import FIGURES

ROOT = Path(__file__).resolve().parent.parent
PAPER = ROOT / "scenarios" / "paper-2020.toml"
MAIN = "from orchestrator.cli.app import main; main()"
SMALL = f"""
name = "small"
scenario = "{PAPER}"
set = ["periods=2", "plant.load_cell_noise_kg=0.5"]

[[axis]]
key = "adaptation.strategy"
values = ["fuzzy", "proportional"]

[[axis]]
key = "seed"
values = [3, 4]
group = "pile"

[[axis]]
key = "plant.pile.parameters.density"
sample = {{ distribution = "uniform", low = 1280.0, high = 1920.0, count = 2, seed = 11 }}
group = "pile"
"""
SAME = [c for c in ("run", "adaptation.strategy", "seed", "plant.pile.parameters.density",
                    "status", "termination", *FIGURES, "message", "log", "fmus")]


def _write(folder: Path, text: str, name: str = "sweep.toml") -> Path:
    path = folder / name
    path.write_text(text)
    return path


@pytest.fixture(scope="module")
def local(tmp_path_factory):
    folder = tmp_path_factory.mktemp("sweep")
    sweep = _write(folder, SMALL)
    return sweep, run_sweep(sweep, folder / "local", workers=2)


def test_the_runs_are_the_product_of_the_groups_zipped_inside(local):
    _, result = local
    frame = result.frame
    assert list(frame["run"]) == ["run-0001", "run-0002", "run-0003", "run-0004"]
    assert list(frame["adaptation.strategy"]) == ["fuzzy", "fuzzy", "proportional",
                                                  "proportional"]
    assert list(frame["seed"]) == [3, 4, 3, 4]
    densities = np.random.default_rng(11).uniform(1280.0, 1920.0, 2)
    assert list(frame["plant.pile.parameters.density"]) == list(densities) * 2
    assert set(frame["status"]) == {"done"} and list(frame["periods"]) == [2] * 4
    assert result.failed == [] and len(result.ran) == 4
    assert result.overview.stat().st_size > 10_000  # overview.png, one panel per axis


def test_the_per_axis_statistics_are_those_of_the_rows(local):
    from orchestrator.sweep.table import axis_statistics

    frame = local[1].frame
    for stats in axis_statistics(frame, "adaptation.strategy"):
        rows = frame[frame["adaptation.strategy"] == stats["value"]]
        assert stats["runs"] == len(rows) == 2
        assert stats["mean_abs_error_kg"] == pytest.approx(rows["mean_abs_error_kg"].mean())
        assert stats["worst_abs_error_kg"] == rows["max_abs_error_kg"].max()
        assert stats["within_share"] == rows["within_band"].sum() / rows["counted"].sum()


def test_each_run_log_holds_its_own_values(local):
    from orchestrator.runlog import read_run

    _, result = local
    for row in result.frame.itertuples(index=False):
        run = read_run(result.out_dir / row.log)
        assert run.scenario["seed"] == row.seed
        assert run.scenario["adaptation"]["strategy"] == row[1]
        assert run.scenario["plant"]["pile"]["parameters"]["density"] == row[3]
        assert run.scenario["plant"]["load_cell_noise_kg"] == 0.5


def test_the_summary_figures_are_what_compare_prints(local):
    _, result = local
    logs = [str(result.out_dir / log) for log in result.frame["log"]]
    done = subprocess.run([sys.executable, "-c", MAIN, "compare", "--json", *logs],
                          capture_output=True, text=True, timeout=120,
                          env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert done.returncode == 0, done.stderr
    compared = json.loads(done.stdout)["runs"]
    table = pd.read_parquet(result.parquet)
    pd.testing.assert_frame_equal(pd.read_csv(result.csv)[list(FIGURES)],
                                  table[list(FIGURES)], check_dtype=False)
    for row, other in zip(table.to_dict("records"), compared, strict=True):
        for name in FIGURES:
            assert row[name] == other["figures"][name], name
        assert row["termination"] == other["termination"]


def test_a_dask_local_cluster_gives_the_same_summary(local, tmp_path):
    from distributed import LocalCluster

    sweep, result = local
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                      dashboard_address=None) as cluster:
        on_dask = run_sweep(sweep, tmp_path / "dask", scheduler=cluster.scheduler_address)
    assert on_dask.failed == []
    pd.testing.assert_frame_equal(on_dask.frame[SAME], result.frame[SAME])
    assert (tmp_path / "dask" / "runs" / "run-0004.mcap").is_file()


def test_resume_skips_complete_runs_and_reruns_a_killed_one(local, tmp_path):
    sweep, result = local
    again = tmp_path / "again"
    shutil.copytree(result.out_dir, again)
    killed = again / "runs" / "run-0002.mcap"
    killed.write_bytes(killed.read_bytes()[: killed.stat().st_size // 2])  # cut mid-run
    (again / "runs" / "run-0003.mcap").unlink()
    resumed = run_sweep(sweep, again, workers=2)
    assert sorted(resumed.ran) == ["run-0002", "run-0003"]
    assert resumed.skipped == ["run-0001", "run-0004"]
    pd.testing.assert_frame_equal(resumed.frame[SAME], result.frame[SAME])
    skipped = resumed.frame.set_index("run").loc["run-0001"]
    assert skipped["wall_s"] == result.frame.set_index("run").loc["run-0001"]["wall_s"]


def test_a_failing_run_and_a_dying_worker_do_not_stop_the_others(tmp_path):
    failing = patched_cylinder(tmp_path / "f", FAIL, 1.0, "Failing")
    crashing = patched_cylinder(tmp_path / "c", CRASH, 1.0, "Crashing")
    sweep = _write(tmp_path, f"""
scenario = "{PAPER}"
set = ["periods=1"]
[[axis]]
roles = ["boom"]
fmu = ["HydraulicCylinder", "{failing}", "{crashing}", "HydraulicCylinder"]
""")
    result = run_sweep(sweep, tmp_path / "out", workers=2)
    status = result.frame.set_index("run")["status"].to_dict()
    assert status == {"run-0001": "done", "run-0002": "failed", "run-0003": "failed",
                      "run-0004": "done"}
    errors = result.frame.set_index("run")["error"]
    assert "burst hose" in errors["run-0002"] and "boom" in errors["run-0002"]
    assert "worker process died" in errors["run-0003"] and "signal 6" in errors["run-0003"]
    assert result.frame.set_index("run").loc["run-0002", "termination"] == "error"


@pytest.mark.parametrize(("text", "says"), [
    ('scenario = "{p}"\nsweeep = 1\n[[axis]]\nkey = "seed"\nvalues = [1]', "sweeep: unknown key"),
    ('scenario = "{p}"\n[[axis]]\nkey = "seed"\nvalues = []', "empty axis"),
    ('scenario = "{p}"\n[[axis]]\nkey = "seed"\nvalue = [1]', "value: unknown key"),
    ('scenario = "{p}"\n[[axis]]\nkey = "plant.pile.colour"\nvalues = [1]', "colour"),
    ('scenario = "{p}"\n[[axis]]\nkey = "periods"\nvalues = ["five"]', "periods"),
    ('scenario = "{p}"\n[[axis]]\nkey = "seed"\nvalues = [1, 2]\ngroup = "g"\n[[axis]]\n'
     'key = "periods"\nvalues = [1]\ngroup = "g"', "zipped axes need as many values"),
    ('scenario = "{p}"\n[[axis]]\nkey = "seed"\nsample = {{ distribution = "uniform", '
     'low = 0, high = 1, count = 3 }}', "seed must be an integer"),
    ('scenario = "{p}"\n[[axis]]\nroles = ["arm"]\nfmu = ["HydraulicCylinder"]', "plant roles"),
    ('scenario = "missing.toml"\n[[axis]]\nkey = "seed"\nvalues = [1]', "no such scenario file"),
])
def test_a_bad_sweep_file_stops_before_any_run_with_one_line(tmp_path, text, says):
    sweep = _write(tmp_path, text.format(p=PAPER))
    with pytest.raises(SweepError, match=says):
        prepare(sweep, tmp_path / "out")
    done = subprocess.run([sys.executable, "-c", MAIN, "sweep", str(sweep), "-o", "out"],
                          capture_output=True, text=True, cwd=tmp_path, timeout=120,
                          env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert done.returncode == 2 and done.stdout == ""
    assert len(done.stderr.strip().splitlines()) == 1 and "Traceback" not in done.stderr
    assert not (tmp_path / "out").exists()


def test_an_unreachable_scheduler_is_one_line_before_any_run(tmp_path):
    with pytest.raises(SchedulerUnreachable, match="tcp://127.0.0.1:9"):
        connect("tcp://127.0.0.1:9", timeout_s=2.0)
    sweep = _write(tmp_path, f'scenario = "{PAPER}"\n[[axis]]\nkey = "seed"\nvalues = [1]')
    done = subprocess.run([sys.executable, "-c", MAIN, "sweep", str(sweep), "-o", "out",
                           "--scheduler", "tcp://127.0.0.1:9"],
                          capture_output=True, text=True, cwd=tmp_path, timeout=120,
                          env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert done.returncode == 2 and "cannot reach the Dask scheduler" in done.stderr
    assert len(done.stderr.strip().splitlines()) == 1
    assert not list((tmp_path / "out").glob("runs/*.mcap"))


def test_samples_are_reproducible_and_inside_their_range(tmp_path):
    sweep = _write(tmp_path, f"""
scenario = "{PAPER}"
[[axis]]
key = "plant.pile.parameters.density"
sample = {{ distribution = "loguniform", low = 1200.0, high = 2000.0, count = 50, seed = 5 }}
[[axis]]
key = "seed"
sample = {{ distribution = "integers", low = 0, high = 1000, count = 3, seed = 5 }}
""")
    first, second = load_sweep(sweep), load_sweep(sweep)
    assert first.axes == second.axes
    density = np.array(first.axes[0].values)
    assert density.min() >= 1200.0 and density.max() < 2000.0 and len(set(density)) == 50
    assert all(isinstance(s, int) and 0 <= s < 1000 for s in first.axes[1].values)
    assert len(first.points()) == 150  # two groups: a product


def test_local_workers_are_replaced_after_their_runs(tmp_path):
    """--recycle-after 1 on 1 worker: every run in a process of its own (the pids differ), and
    the sweep does not stall when a worker retires (ProcessPoolExecutor's would, gh-115634)."""
    sweep = _write(tmp_path, f'scenario = "{PAPER}"\nset = ["periods=1"]\n[[axis]]\n'
                   'key = "seed"\nvalues = [1, 2, 3]')
    result = run_sweep(sweep, tmp_path / "out", workers=1, recycle_after=1)
    assert list(result.frame["status"]) == ["done"] * 3
    assert result.frame["worker"].nunique() == 3


def test_sigterm_stops_the_sweep_in_one_line_and_the_same_command_goes_on(tmp_path):
    import signal
    import time

    sweep = _write(tmp_path, f'scenario = "{PAPER}"\nset = ["periods=3"]\n[[axis]]\n'
                   'key = "seed"\nvalues = [1, 2, 3]')
    command = [sys.executable, "-c", MAIN, "sweep", str(sweep), "-o", "out", "--workers", "1"]
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    process = subprocess.Popen(command, cwd=tmp_path, env=env, stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True,
                               preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        deadline = time.monotonic() + 120
        while not (tmp_path / "out" / "runs" / "run-0001.json").exists():
            assert process.poll() is None and time.monotonic() < deadline
            time.sleep(0.05)
        process.send_signal(signal.SIGTERM)
        out, err = process.communicate(timeout=60)
    finally:
        if process.poll() is None:
            process.kill()
            process.communicate()
    assert process.returncode == 143 and out == ""
    assert err.startswith("excosim: terminated (SIGTERM): 1 of 3 runs done, summary in out")
    assert len(err.strip().splitlines()) == 1
    assert len(pd.read_parquet(tmp_path / "out" / "summary.parquet")) == 1
    again = subprocess.run([*command, "--json"], cwd=tmp_path, env=env, capture_output=True,
                           text=True, timeout=300)
    assert again.returncode == 0, again.stderr
    report = json.loads(again.stdout)
    assert (report["runs"], report["skipped"], report["ran"]) == (3, 1, 2)


def test_another_sweeps_folder_is_refused_and_an_edited_sweep_goes_on(tmp_path):
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    base = f'scenario = "{PAPER}"\nset = ["periods=1"]\n[[axis]]\nkey = "seed"\n'
    first = _write(tmp_path, f'name = "a"\n{base}values = [1]', "a.toml")
    other = _write(tmp_path, f'name = "b"\n{base}values = [1]', "b.toml")
    grown = _write(tmp_path, f'name = "a"\n{base}values = [1, 2]', "a2.toml")

    def sweep(path):
        return subprocess.run([sys.executable, "-c", MAIN, "sweep", str(path), "-o", "out",
                               "--workers", "1", "--json"], cwd=tmp_path, env=env,
                              capture_output=True, text=True, timeout=300)

    assert sweep(first).returncode == 0
    refused = sweep(other)
    assert refused.returncode == 2 and "another sweep" in refused.stderr
    report = json.loads(sweep(grown).stdout)
    assert (report["runs"], report["skipped"], report["ran"]) == (2, 1, 1)



@pytest.mark.parametrize("path", sorted((ROOT / "sweeps").glob("*.toml")), ids=lambda p: p.name)
def test_every_shipped_sweep_plans_its_runs(path, tmp_path):
    """Each sweep file the README names loads, and every run's scenario passes its checks."""
    sweep, tasks = prepare(path, tmp_path / "out")
    assert len(tasks) == len(sweep.points()) >= 2
    assert len({json.dumps(task.scenario, sort_keys=True) for task in tasks}) == len(tasks)
    assert not (tmp_path / "out").exists()  # planning writes nothing
