"""Study designs of sweeps (orchestrator.sweep.designs, .sensitivity, .optimize): Latin hypercube
and Sobol axes are scipy.stats.qmc's points for the same seed, scaled to their ranges, and fill
the cube more evenly than independent draws; a saltelli design is SALib's sample, and the
indices `--sensitivity` reports are SALib's own analysis of the summary's column (a figure that
depends on one axis only has no index on the other); `excosim optimize` finds the known better
side of a cheap objective (1-period campaigns) and resumes its study; list elements are axes;
bad designs, objectives and options stop in one line with exit 2 before any run."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy.stats import qmc

from orchestrator.sweep import SweepError, load_sweep, prepare
from orchestrator.sweep.designs import discrepancy
from orchestrator.sweep.sensitivity import sensitivity

ROOT = Path(__file__).resolve().parent.parent
PAPER = ROOT / "scenarios" / "paper-2020.toml"
MAIN = "from orchestrator.cli.app import main; main()"
ONE_PERIOD = f'scenario = "{PAPER}"\nset = ["periods=1", "log.sample_rate_hz=10"]\n'


def _axis(key: str, design: str, low: float, high: float, count: int, seed: int,
          group: str = "g", distribution: str = "uniform") -> str:
    return (f'[[axis]]\nkey = "{key}"\ngroup = "{group}"\nsample = {{ design = "{design}", '
            f'distribution = "{distribution}", low = {low}, high = {high}, count = {count}, '
            f"seed = {seed} }}\n")


def _write(folder: Path, text: str, name: str = "sweep.toml") -> Path:
    path = folder / name
    path.write_text(text)
    return path


def _cli(folder: Path, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", MAIN, *args], capture_output=True, text=True,
                          cwd=folder, timeout=300, env={**os.environ, "PYTHONPATH": str(ROOT)})


@pytest.mark.parametrize("design", ["lhs", "sobol"])
def test_lhs_and_sobol_axes_are_scipys_points_scaled_to_their_ranges(tmp_path, design):
    sweep = load_sweep(_write(tmp_path, ONE_PERIOD
                              + _axis("plant.pile.parameters.density", design, 1280, 1920, 16, 7)
                              + _axis("plant.load_cell_noise_kg", design, 0.01, 1.0, 16, 7,
                                      distribution="loguniform")))
    engine = (qmc.LatinHypercube(2, rng=7) if design == "lhs"
              else qmc.Sobol(2, scramble=True, rng=7))
    unit = engine.random(16)
    assert np.allclose(sweep.axes[0].values, 1280 + 640 * unit[:, 0], rtol=0, atol=1e-9)
    assert np.allclose(np.log(sweep.axes[1].values),
                       np.log(0.01) + unit[:, 1] * (np.log(1.0) - np.log(0.01)), atol=1e-12)
    assert len(sweep.points()) == 16  # one group: zipped, not a product
    values = np.column_stack([sweep.axes[0].values, sweep.axes[1].values])
    designs = [a.design for a in sweep.axes]
    assert discrepancy(values, designs) == pytest.approx(qmc.discrepancy(unit), rel=1e-9)
    # more even than independent uniform draws of the same size (20 seeds of them)
    random = [qmc.discrepancy(np.random.default_rng(s).uniform(size=(16, 2)))
              for s in range(20)]
    assert discrepancy(values, designs) < min(random)
    assert load_sweep(tmp_path / "sweep.toml").axes == sweep.axes  # reproducible


def test_a_saltelli_design_is_salibs_sample(tmp_path):
    from SALib.sample import sobol

    sweep = load_sweep(_write(tmp_path, ONE_PERIOD
                              + _axis("plant.pile.parameters.density", "saltelli", 1280, 1920,
                                      8, 3)
                              + _axis("plant.load_cell_noise_kg", "saltelli", 0.0, 1.0, 8, 3)))
    problem = {"num_vars": 2, "names": ["a", "b"], "bounds": [[1280, 1920], [0.0, 1.0]]}
    expected = sobol.sample(problem, 8, calc_second_order=False, seed=3)
    assert expected.shape == (32, 2) and len(sweep.points()) == 32
    assert np.allclose(np.column_stack([a.values for a in sweep.axes]), expected, atol=1e-9)


def _ishigami_frame(sweep, figure) -> pd.DataFrame:
    rows = []
    for index, point in enumerate(sweep.points(), 1):
        x = [point[a.name] for a in sweep.axes if a.design is not None]
        rows.append({"run": f"run-{index:04d}", **point, **figure(x)})
    return pd.DataFrame(rows)


def test_the_indices_are_salibs_analysis_of_the_column(tmp_path):
    from SALib.analyze import sobol

    text = ONE_PERIOD + "".join(_axis(k, "saltelli", -math.pi, math.pi, 64, 2) for k in
                                ("plant.pile.parameters.density", "plant.load_cell_noise_kg",
                                 "target_mass_kg"))
    text += '[[axis]]\nkey = "adaptation.strategy"\nvalues = ["fuzzy", "fixed"]\n'
    sweep = load_sweep(_write(tmp_path, text))

    def figure(x):  # Ishigami (SALib's test function); a figure of the first axis only
        return {"mean_abs_error_kg": math.sin(x[0]) + 7 * math.sin(x[1]) ** 2
                + 0.1 * x[2] ** 4 * math.sin(x[0]), "energy_kj": x[0] ** 2, "periods": 3}

    frame = _ishigami_frame(sweep, figure)
    records = sensitivity(frame, sweep, ["mean_abs_error_kg", "energy_kj", "periods"])
    assert {json.dumps(r["condition"]) for r in records} == {'{"adaptation.strategy": "fuzzy"}',
                                                           '{"adaptation.strategy": "fixed"}'}
    fuzzy = frame[frame["adaptation.strategy"] == "fuzzy"]
    problem = {"num_vars": 3, "names": [a.name for a in sweep.axes[:3]],
               "bounds": [[0.0, 1.0]] * 3}
    own = sobol.analyze(problem, fuzzy["mean_abs_error_kg"].to_numpy(), calc_second_order=False,
                        num_resamples=1000, conf_level=0.95, seed=2)
    chosen = [r for r in records if r["figure"] == "mean_abs_error_kg"
              and r["condition"] == {"adaptation.strategy": "fuzzy"}]
    for i, record in enumerate(chosen):
        for key in ("S1", "S1_conf", "ST", "ST_conf"):
            assert record[key] == pytest.approx(own[key][i], rel=1e-12)
    # Ishigami's analytic indices: S1 = 0.314, 0.442, 0; ST = 0.558, 0.442, 0.244
    assert [r["ST"] for r in chosen] == pytest.approx([0.558, 0.442, 0.244], abs=0.12)
    one = [r for r in records if r["figure"] == "energy_kj"]
    assert all(r["ST"] == pytest.approx(0.0, abs=1e-12) for r in one if r["axis"] != "plant.pile"
               ".parameters.density")
    assert all(r["ST"] > 0.9 for r in one if r["axis"] == "plant.pile.parameters.density")
    assert {r["note"] for r in records if r["figure"] == "periods"} == {"constant"}


@pytest.mark.slow
def test_sweep_sensitivity_of_one_period_campaigns(tmp_path):
    text = ONE_PERIOD + _axis("plant.pile.parameters.density", "saltelli", 1300, 1900, 4, 1) \
        + _axis("plant.load_cell_noise_kg", "saltelli", 0.0, 1.0, 4, 1)
    sweep = _write(tmp_path, text)
    done = _cli(tmp_path, "sweep", str(sweep), "-o", "out", "--workers", "2", "--sensitivity",
                "--json")
    assert done.returncode == 0, done.stderr
    report = json.loads(done.stdout)
    energy = {r["axis"]: r for r in report["sensitivity"] if r["figure"] == "energy_kj"}
    assert energy["plant.load_cell_noise_kg"]["ST"] == 0.0  # the cell weighs, it does not dig
    assert energy["plant.pile.parameters.density"]["ST"] > 0.5
    frame = pd.read_parquet(tmp_path / "out" / "summary.parquet")
    assert list(frame["plant.pile.parameters.density"]) == pytest.approx(
        load_sweep(sweep).axes[0].values)
    assert (tmp_path / "out" / "sensitivity.png").stat().st_size > 10_000
    assert len(pd.read_csv(tmp_path / "out" / "sensitivity.csv")) == len(report["sensitivity"])


def test_a_list_element_is_an_axis(tmp_path):
    sweep, tasks = prepare(_write(tmp_path, ONE_PERIOD + '[[axis]]\nkey = '
                                  '"adaptation.centre_fractions[1]"\nvalues = [0.5, 0.7]\n'),
                           tmp_path / "out")
    assert [t.scenario["adaptation"]["centre_fractions"] for t in tasks] == [
        [0.1119, 0.5, 0.9025], [0.1119, 0.7, 0.9025]]
    with pytest.raises(SweepError, match="has 3 elements"):
        prepare(_write(tmp_path, ONE_PERIOD + '[[axis]]\nkey = "adaptation.centre_fractions[5]"'
                       '\nvalues = [0.5]\n'), tmp_path / "out")


BAD = [
    (_axis("seed", "lhs", 2, 1, 4, 1), "low must be below high"),
    (_axis("seed", "lhs", '"a"', 1, 4, 1), "needs a finite number low"),
    (_axis("seed", "sobol", 0, 1, 12, 1), "power of 2"),
    (_axis("seed", "saltelli", 0, 1, 6, 1), "power of 2"),
    (_axis("seed", "grid", 0, 1, 4, 1), "design must be one of"),
    (_axis("seed", "lhs", 0, 1, 4, 1, distribution="normal"), "uniform or loguniform"),
    (_axis("seed", "lhs", 0, 1, 4, 1, distribution="loguniform"), "low > 0"),
    ('[[axis]]\nkey = "seed"\nsample = { design = "lhs", low = 0, high = 1, count = 4, '
     'seed = 1, spread = 2 }\n', "unknown key 'spread'"),
    (_axis("seed", "lhs", 0, 1, 4, 1) + _axis("periods", "lhs", 1, 3, 8, 1),
     "one design per group"),
]


@pytest.mark.parametrize("axes, says", BAD, ids=[s for _, s in BAD])
def test_a_bad_design_is_one_line(tmp_path, axes, says):
    with pytest.raises(SweepError, match=says) as error:
        load_sweep(_write(tmp_path, ONE_PERIOD + axes))
    assert "\n" not in str(error.value)


def test_bad_input_exits_2_in_one_line_before_any_run(tmp_path):
    sweep = _write(tmp_path, ONE_PERIOD + _axis("seed", "sobol", 0, 1, 12, 1))
    plain = _write(tmp_path, ONE_PERIOD + '[[axis]]\nkey = "seed"\nvalues = [1]\n', "plain.toml")
    ranged = _write(tmp_path, ONE_PERIOD + _axis("plant.load_cell_noise_kg", "lhs", 0, 1, 4, 1),
                    "ranged.toml")
    for args, says in [(("sweep", str(sweep), "-o", "out"), "power of 2"),
                       (("sweep", str(plain), "-o", "out", "--sensitivity"), "saltelli"),
                       (("optimize", str(ranged), "-o", "out", "--objective", "weight"),
                        "not a summary figure"),
                       (("optimize", str(plain), "-o", "out", "--objective", "resets"),
                        "no axis with a range")]:
        done = _cli(tmp_path, *args)
        assert done.returncode == 2 and done.stdout == "", (args, done.stderr)
        assert len(done.stderr.strip().splitlines()) == 1 and says in done.stderr
        assert not (tmp_path / "out" / "runs").exists()


@pytest.mark.slow
def test_optimize_finds_the_heavier_side_and_resumes(tmp_path):
    text = ONE_PERIOD + _axis("plant.pile.parameters.density", "lhs", 1300, 1900, 4, 1) \
        + '[[axis]]\nkey = "seed"\nvalues = [1, 2]\n'
    sweep = _write(tmp_path, text)
    done = _cli(tmp_path, "optimize", str(sweep), "-o", "out", "--objective",
                "total_payload_kg", "--maximize", "--trials", "6", "--workers", "2", "--json")
    assert done.returncode == 0, done.stderr
    report = json.loads(done.stdout)
    assert report["ran"] == 6 and len(report["trials"]) == 6
    best = report["best"]["params"]["plant.pile.parameters.density"]
    assert best > 1750.0  # more soil per slice: the heavier side
    frame = pd.read_parquet(tmp_path / "out" / "summary.parquet")
    assert len(frame) == 12 and set(frame["status"]) == {"done"}
    assert frame.groupby("trial")["total_payload_kg"].mean().max() == pytest.approx(
        report["best"]["value"])
    again = _cli(tmp_path, "optimize", str(sweep), "-o", "out", "--objective",
                 "total_payload_kg", "--maximize", "--trials", "7", "--workers", "2", "--json")
    assert again.returncode == 0, again.stderr
    assert json.loads(again.stdout)["ran"] == 1 and (tmp_path / "out" / "study.db").is_file()
    other = _cli(tmp_path, "optimize", str(sweep), "-o", "out", "--objective",
                 "total_payload_kg", "--minimize", "--trials", "7")
    assert other.returncode == 2 and "maximizes total_payload_kg" in other.stderr


@pytest.mark.slow
def test_optimize_runs_its_trials_on_a_dask_cluster(tmp_path):
    from distributed import LocalCluster

    from orchestrator.sweep.optimize import run_optimize

    text = ONE_PERIOD + _axis("plant.pile.parameters.density", "lhs", 1300, 1900, 4, 1) \
        + '[[axis]]\nkey = "seed"\nvalues = [1, 2]\n'
    sweep = _write(tmp_path, text)
    local = run_optimize(sweep, tmp_path / "local", "total_payload_kg", maximize=True,
                         trials=2, workers=2)
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                      dashboard_address=None) as cluster:
        on_dask = run_optimize(sweep, tmp_path / "dask", "total_payload_kg", maximize=True,
                               trials=2, scheduler=cluster.scheduler_address)
    assert [t["params"] for t in on_dask.trials] == [t["params"] for t in local.trials]
    assert [t["value"] for t in on_dask.trials] == pytest.approx(
        [t["value"] for t in local.trials])
    assert (tmp_path / "dask" / "runs" / "trial-0001-02.mcap").is_file()
    assert list(on_dask.frame["trial"]) == [0, 0, 1, 1]


def test_a_trial_interrupted_in_the_study_is_failed_and_run_again(tmp_path):
    from optuna.trial import TrialState

    from orchestrator.sweep.optimize import _finished, _study

    sweep = load_sweep(_write(tmp_path, ONE_PERIOD + _axis("plant.load_cell_noise_kg", "lhs", 0,
                                                           1, 4, 1)))
    study = _study(sweep, tmp_path, "resets", "minimize", 0, 4)
    study.tell(study.ask({"x": __import__("optuna").distributions.FloatDistribution(0, 1)}), 1.0)
    running = study.ask()
    running.suggest_float("x", 0.0, 1.0)  # a session stopped with this trial in flight
    again = _study(sweep, tmp_path, "resets", "minimize", 0, 4)
    states = [t.state for t in again.get_trials(deepcopy=False)]
    assert states == [TrialState.COMPLETE, TrialState.FAIL, TrialState.WAITING]
    assert again.user_attrs["interrupted"] == [1] and _finished(again) == 1
    first = again.ask()  # the enqueued values come first
    assert first.suggest_float("x", 0.0, 1.0) == running.params["x"]
    with pytest.raises(SweepError, match="minimizes resets; give another -o"):
        _study(sweep, tmp_path, "resets", "maximize", 0, 4)
