"""The productivity figures (orchestrator.campaign.productivity per period, the run's totals in
orchestrator.review.productivity): each against a hand computation from the raw logged
/signals/<joint> samples and the scenario of a 2-period paper run; review (table, --json,
--csv), compare and the sweep summary show them; an FMU without energy outputs (IdealActuator)
leaves the energy figures absent, and a payload of ~0 leaves kJ/t absent, without a crash and
without a NaN or inf in the JSON.

Tolerances are round-off only: the logged energies are the measurement's doubles, so the
energies and their ratios agree to a few ulp of a sum of three terms (rel 1e-12). The logged
times are campaign times t0 + t (each rounded to half an ulp of ~30 s, 3.6e-15 s), so a time
span read from them is off by at most ~1e-14 s: 1e-12 s on the cycle time, and on one
communication step of 0.01 s a relative 1e-12, 1e-10 on the powers per step.
"""

from __future__ import annotations

import json
import math
import tomllib
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from orchestrator.campaign import run_campaign
from orchestrator.campaign.productivity import MIN_PAYLOAD_KG, period_productivity
from orchestrator.cli.app import app
from orchestrator.review import productivity as run_level
from orchestrator.review.plots import write_plots
from orchestrator.runlog import read_run
from orchestrator.scenario import load_scenario
from orchestrator.sweep.table import productivity as sweep_productivity
from plant_models.plant import JOINTS

ROOT = Path(__file__).resolve().parent.parent
PAPER = ROOT / "scenarios" / "paper-2020.toml"
IDEAL = ROOT / "scenarios" / "paper-2020-ideal-actuators.toml"
SIGNALS = tuple(f"/signals/{joint}" for joint in JOINTS)
REL = 1e-12  # energies and their ratios: a few ulp of three-term sums
TIME_ABS_S = 1e-12  # a span of logged campaign times
POWER_REL = 1e-10  # one step's energy over one step's logged time


def _campaign(path: Path, scenario: Path, periods: int) -> Path:
    result = run_campaign(load_scenario(scenario, [f"periods={periods}"]), log_path=path)
    assert result.termination == "periods", result.message
    return path


@pytest.fixture(scope="module")
def paper_log(tmp_path_factory) -> Path:
    return _campaign(tmp_path_factory.mktemp("productivity") / "paper.mcap", PAPER, 2)


@pytest.fixture(scope="module")
def ideal_log(tmp_path_factory) -> Path:
    return _campaign(tmp_path_factory.mktemp("productivity") / "ideal.mcap", IDEAL, 1)


def _rated_payload_kg(scenario_path: Path) -> float:
    """capacity x density of the Pile: the scenario file's value, else variables.toml's."""
    defaults = {v["name"]: v.get("start") for v in tomllib.loads(
        (ROOT / "fmus" / "Pile" / "variables.toml").read_text())["variable"]}
    given = tomllib.loads(scenario_path.read_text())["plant"]["pile"]["parameters"]
    values = {**defaults, **given}
    return values["capacity"] * values["density"]


def _by_hand(run, k: int, rated_kg: float) -> dict[str, float]:
    """Period k's figures from its logged /signals/<joint> samples (J, campaign s)."""
    energies = {}
    for joint in JOINTS:
        channel = run.channels[f"/signals/{joint}"]
        names = json.loads(channel.metadata["names"])
        samples = channel.of_period(k)
        for name in ("E_supply", "E_throttling"):
            energies[joint, name] = samples["values"][:, names.index(f"{joint}.{name}")]
        t = samples["t_s"]
    mass = run.periods[k - 1]["mass_kg"]
    cycle = t[-1] - t[0]
    supplied = sum(energies[j, "E_supply"][-1] - energies[j, "E_supply"][0] for j in JOINTS)
    throttled = sum(energies[j, "E_throttling"][-1] - energies[j, "E_throttling"][0]
                    for j in JOINTS)
    steps = [sum(energies[j, "E_supply"][i + 1] - energies[j, "E_supply"][i] for j in JOINTS)
             / (t[i + 1] - t[i]) for i in range(len(t) - 1)]
    return {"cycle_time_s": cycle, "rated_payload_kg": rated_kg, "fill_factor": mass / rated_kg,
            "productivity_t_h": mass / 1000 / (cycle / 3600), "energy_kj": supplied / 1000,
            "throttled_energy_kj": throttled / 1000, "throttled_share": throttled / supplied,
            "energy_per_tonne_kj_t": (supplied / 1000) / (mass / 1000),
            "peak_power_kw": max(steps) / 1000, "mean_power_kw": supplied / 1000 / cycle,
            "steps_j": sum(s * (t[i + 1] - t[i]) for i, s in enumerate(steps))}


@pytest.fixture(scope="module")
def by_hand(paper_log):
    run = read_run(paper_log, topics=(*SIGNALS, "/pile/bucket"))
    rated = _rated_payload_kg(PAPER)
    return run, [_by_hand(run, k, rated) for k in (1, 2)]


def test_each_period_figure_is_its_hand_computation(by_hand):
    run, hand = by_hand
    for record, expected in zip(run.periods, hand, strict=True):
        # payload: the load cell's reading, the bucket's content at the last sample (no noise)
        assert record["mass_kg"] == run.channels["/pile/bucket"].of_period(
            record["k"])["bucket_mass_kg"][-1]
        assert record["cycle_time_s"] == pytest.approx(expected["cycle_time_s"], abs=TIME_ABS_S,
                                                       rel=0)
        # the samples' span: the planned trajectory rounded up to the step, plus any settle
        assert record["cycle_time_s"] >= record["duration_s"] - 1e-9
        assert record["rated_payload_kg"] == pytest.approx(expected["rated_payload_kg"],
                                                           rel=1e-15)
        for key in ("fill_factor", "productivity_t_h", "energy_kj", "throttled_energy_kj",
                    "throttled_share", "energy_per_tonne_kj_t", "mean_power_kw"):
            assert record[key] == pytest.approx(expected[key], rel=REL), key
        assert record["peak_power_kw"] == pytest.approx(expected["peak_power_kw"],
                                                        rel=POWER_REL)
        # the step powers integrate to the period's energy; the peak is above the mean
        assert expected["steps_j"] == pytest.approx(1000 * record["energy_kj"], rel=1e-10)
        assert 0 < record["throttled_share"] < 1
        assert record["peak_power_kw"] > record["mean_power_kw"] > 0


def test_the_run_totals_are_sums_of_the_hand_computations(by_hand, paper_log):
    run, hand = by_hand
    done = CliRunner().invoke(app, ["review", str(paper_log), "--json"])
    assert done.exit_code == 0, done.output
    figures = json.loads(done.stdout)["figures"]
    payload = math.fsum(r["mass_kg"] for r in run.periods)
    time_s = math.fsum(h["cycle_time_s"] for h in hand)
    energy = math.fsum(h["energy_kj"] for h in hand)
    throttled = math.fsum(h["throttled_energy_kj"] for h in hand)
    assert figures["total_payload_kg"] == pytest.approx(payload, rel=REL)
    assert figures["digging_time_s"] == pytest.approx(time_s, abs=2 * TIME_ABS_S, rel=0)
    # the campaign's clock: the last period's start plus its cycle
    last = run.periods[-1]
    assert figures["digging_time_s"] == pytest.approx(last["t0_s"] + last["cycle_time_s"],
                                                      abs=TIME_ABS_S, rel=0)
    expected = {"productivity_t_h": payload / 1000 / (time_s / 3600),
                "mean_fill_factor": payload / (2 * _rated_payload_kg(PAPER)),
                "energy_kj": energy, "throttled_energy_kj": throttled,
                "energy_per_tonne_kj_t": energy / (payload / 1000),
                "throttled_share": throttled / energy, "mean_power_kw": energy / time_s}
    for key, value in expected.items():
        assert figures[key] == pytest.approx(value, rel=REL), key
    assert figures["peak_power_kw"] == pytest.approx(max(h["peak_power_kw"] for h in hand),
                                                     rel=POWER_REL)


def test_review_shows_the_totals_and_writes_the_per_period_figures(paper_log, tmp_path):
    target = tmp_path / "periods.csv"
    done = CliRunner().invoke(app, ["review", str(paper_log), "--csv", str(target), "--plots",
                                    str(tmp_path / "figures")], env={"COLUMNS": "200"})
    assert done.exit_code == 0, done.output
    figures = run_level.run_productivity(read_run(paper_log).periods)
    assert (f"productivity {figures['productivity_t_h']:.2f} t/h: "
            f"{figures['total_payload_kg']:.1f} kg in {figures['digging_time_s']:.1f} s") \
        in done.stdout
    assert f"{figures['energy_per_tonne_kj_t']:.0f} kJ/t" in done.stdout
    assert f"supply power peak {figures['peak_power_kw']:.1f} kW" in done.stdout
    assert (tmp_path / "figures" / "productivity.png").stat().st_size > 10_000
    table = pd.read_csv(target, index_col="k")
    for record in read_run(paper_log).periods:
        for key in ("cycle_time_s", "fill_factor", "productivity_t_h", "energy_kj",
                    "energy_per_tonne_kj_t", "throttled_share", "peak_power_kw",
                    "mean_power_kw"):
            assert table.loc[record["k"], key] == record[key], key  # all digits, read back


def test_compare_sets_the_totals_side_by_side(paper_log, ideal_log):
    done = CliRunner().invoke(app, ["compare", str(paper_log), str(ideal_log), "--json"])
    assert done.exit_code == 0, done.output
    paper, ideal = (run["figures"] for run in json.loads(done.stdout)["runs"])
    assert paper == {**paper, **run_level.run_productivity(read_run(paper_log).periods)}
    assert ideal["productivity_t_h"] > 0 and ideal["energy_kj"] is None
    table = CliRunner().invoke(app, ["compare", str(paper_log), str(ideal_log)],
                               env={"COLUMNS": "200"})
    assert table.exit_code == 0, table.output
    for text in (f"{paper['productivity_t_h']:.2f}", f"{paper['energy_per_tonne_kj_t']:.0f}",
                 f"{100 * paper['throttled_share']:.1f}", f"{paper['peak_power_kw']:.1f}",
                 "t/h", "kJ/t", "peak power"):
        assert text in table.stdout, text


def test_an_fmu_without_energy_outputs_leaves_the_energy_figures_absent(ideal_log, tmp_path):
    run = read_run(ideal_log, topics=SIGNALS)
    names = json.loads(run.channels["/signals/boom"].metadata["names"])
    assert not any("E_supply" in name for name in names)  # IdealActuator books no oil
    (record,) = run.periods
    assert {"cycle_time_s", "fill_factor", "productivity_t_h"} <= set(record)
    assert not {"energy_kj", "throttled_energy_kj", "throttled_share", "energy_per_tonne_kj_t",
                "peak_power_kw", "mean_power_kw"} & set(record)
    done = CliRunner().invoke(app, ["review", str(ideal_log), "--json"])
    assert done.exit_code == 0, done.output
    figures = json.loads(done.stdout)["figures"]
    assert figures["energy_kj"] is None and figures["peak_power_kw"] is None
    assert figures["productivity_t_h"] == pytest.approx(
        record["mass_kg"] / 1000 / (record["cycle_time_s"] / 3600), rel=REL)
    text = CliRunner().invoke(app, ["review", str(ideal_log)]).stdout
    assert "hydraulic energy not measured" in text
    assert (tmp_path / "productivity.png") in write_plots(read_run(ideal_log), tmp_path)


def test_a_payload_of_about_zero_has_no_energy_per_tonne_and_no_inf():
    t = np.arange(5) * 0.01
    signals = {f"{j}.{name}": np.linspace(0.0, 40.0, 5) for j in JOINTS
               for name in ("E_supply", "E_throttling")}
    for payload in (0.0, 0.4 * MIN_PAYLOAD_KG, -0.2):  # a noisy empty bucket may weigh < 0
        figures = period_productivity(t, signals, payload, 74.0)
        assert "energy_per_tonne_kj_t" not in figures
        assert figures["energy_kj"] == pytest.approx(0.12, rel=REL)
        json.dumps(figures, allow_nan=False)
    records = [{"mass_kg": 0.0, **period_productivity(t, signals, 0.0, 74.0)}]
    totals = run_level.run_productivity(records)
    assert totals["energy_per_tonne_kj_t"] is None and totals["productivity_t_h"] == 0.0
    json.dumps(totals, allow_nan=False)
    # an energy the FMU did not book (NaN) is no energy figure either
    signals["stick.E_supply"][2] = math.nan
    assert "energy_kj" not in period_productivity(t, signals, 30.0, 74.0)
    assert run_level.MIN_PAYLOAD_KG == MIN_PAYLOAD_KG  # one threshold, run and period


def test_the_pumps_power_limit_comes_from_the_scenario_when_it_sets_one():
    supply = {"kind": "load_sensing", "engine_power_w": 121000.0, "pump_efficiency": 0.85}
    assert run_level.power_limit_kw({"plant": {"supply": supply}}) == pytest.approx(102.85)
    assert run_level.power_limit_kw({"plant": {"supply": {"kind": "constant"}}}) is None
    assert run_level.power_limit_kw({}) is None


def test_the_sweep_summary_has_them_per_run_and_per_axis_value(tmp_path):
    sweep = tmp_path / "sweep.toml"
    sweep.write_text(f"""
scenario = "{PAPER}"
set = ["periods=1"]
[[axis]]
scenario = ["{PAPER}", "{IDEAL}"]
[[axis]]
key = "plant.pile.parameters.slice_width"
values = [0.017072, 0.02]
""")
    done = CliRunner().invoke(app, ["sweep", str(sweep), "-o", str(tmp_path / "out"),
                                    "--workers", "2"], env={"COLUMNS": "200"})
    assert done.exit_code == 0, done.output
    assert "t/h" in done.stdout and "kJ/t" in done.stdout
    frame = pd.read_parquet(tmp_path / "out" / "summary.parquet")
    for row in frame.to_dict("records"):
        totals = run_level.run_productivity(read_run(tmp_path / "out" / row["log"]).periods)
        for key, value in totals.items():
            assert (value is None and math.isnan(row[key])) or row[key] == value, key
    paper = frame[frame["scenario"].str.endswith("paper-2020.toml")]
    assert len(paper) == 2 and paper["energy_kj"].notna().all()
    stats = sweep_productivity(paper)
    payload, time_s = paper["total_payload_kg"].sum(), paper["digging_time_s"].sum()
    energy = paper["energy_kj"].sum()
    assert stats["productivity_t_h"] == pytest.approx(payload / 1000 / (time_s / 3600), rel=REL)
    assert stats["energy_per_tonne_kj_t"] == pytest.approx(energy / (payload / 1000), rel=REL)
    assert stats["throttled_share"] == pytest.approx(
        paper["throttled_energy_kj"].sum() / energy, rel=REL)
    assert stats["peak_power_kw"] == paper["peak_power_kw"].max()
    ideal = sweep_productivity(frame[frame["scenario"].str.endswith("actuators.toml")])
    assert ideal["productivity_t_h"] > 0 and ideal["energy_per_tonne_kj_t"] is None
    report = CliRunner().invoke(app, ["sweep", str(sweep), "-o", str(tmp_path / "out"),
                                      "--json"])
    assert report.exit_code == 0, report.output
    by_value = json.loads(report.stdout)["axes"]["scenario"]
    assert [s["productivity_t_h"] is not None for s in by_value] == [True, True]
