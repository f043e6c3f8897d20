"""The figures the documentation (the site's pages under docs/, once the README's sections)
quotes of a run, computed from fresh logs.

Each test reads its figures from the page's own sentence (a regular expression on the page's
text, its line breaks taken as spaces) and compares them with a log made here, so the pages and
the runs cannot drift apart: a change that moves a figure fails here until the sentence is
updated; a sentence moved to another page fails until its test names that page.
The logs: one 20-period run of scenarios/paper-2020.toml (a few seconds, shared by the tests of
this module) and the 3-period simulated lab run the lab tests share (conftest's
lab_simulated_run).

Tolerances are the pages' rounding: a figure written with d decimals must lie within half a
unit of its last decimal (plus 1e-9 for the float's own rounding), e.g. 0.85 MB within
0.005 MB; a band written in round tens of kN within 5 kN. The runs are deterministic (same
scenario, seed and FMUs, same numbers: `excosim replay`), so the only error of the reference is
that rounding. Counts (periods, samples) are exact: the accelerations counted beyond 1.5 times
Table 1's limit lie at least 1e-4 (relative) from it, far beyond a CPU's rounding differences.
MB is 10^6 bytes.

Not here: the figures that need other runs (the lab scenario up to its workspace limit and at
100 Hz, the full-scale table, the sweeps, the step-size study, the hydraulics table's "before"
column) or that measure time (the benchmarks).
"""

from __future__ import annotations

import importlib.util
import math
import re
import sys
from pathlib import Path

import numpy as np
import pytest

from orchestrator.campaign import run_campaign
from orchestrator.review.summary import band_kg, run_figures
from orchestrator.runlog import read_run
from orchestrator.scenario import load_scenario
from plant_models.plant import JOINTS

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "scenarios" / "paper-2020.toml"
DOCS = ROOT / "docs"
FOXGLOVE, CAMPAIGNS, SWEEPS, LAB = "guide/foxglove.md", "guide/campaigns.md", "guide/sweeps.md", \
    "guide/lab.md"
SUPPLY, PAPER_RESULTS, FULL_SCALE = "models/supply.md", "results/paper.md", "results/full-scale.md"
SUBSTITUTION, BENCHMARKS = "results/substitution.md", "results/benchmarks.md"
G = 9.81  # m/s^2, for the payload's weight in kN
TOPICS = ("/joints", "/pile/bucket", "/signals/coupling", *(f"/cylinder/{j}" for j in JOINTS))


def _bench(name: str):
    """A script of bench/ as a module (its figures are what the pages' tables print)."""
    spec = importlib.util.spec_from_file_location(f"bench_{name}", ROOT / "bench" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


def page_text(page: str) -> str:
    return " ".join((DOCS / page).read_text().split())  # a sentence may wrap anywhere


def quoted(pattern: str, page: str) -> tuple[str, ...]:
    """The groups of the one match of `pattern` on docs/`page`."""
    found = list(re.finditer(pattern, page_text(page)))
    assert len(found) == 1, f"docs/{page}: {len(found)} matches of {pattern!r}"
    return found[0].groups()


def rounded(value: float, text: str, unit: float | None = None) -> None:
    """`value` is what the page's `text` says, to its rounding (half a unit of its last digit,
    or `unit` / 2 for a figure written to round tens)."""
    digits = text.replace(",", "")
    decimals = len(digits.split(".")[1]) if "." in digits else 0
    half = 0.5 * (unit if unit is not None else 10.0 ** -decimals)
    assert abs(value - float(digits)) <= half + 1e-9, f"the page says {text}, the log {value!r}"


@pytest.fixture(scope="module")
def paper(tmp_path_factory):
    """(log path, RunFile with TOPICS): the paper scenario's 20 periods."""
    log = tmp_path_factory.mktemp("readme-figures") / "paper.mcap"
    result = run_campaign(load_scenario(PAPER), log_path=log)
    assert result.termination == "periods", result.message
    return log, read_run(log, topics=TOPICS)


@pytest.fixture(scope="module")
def paper_run(paper):
    return paper[1]


def _soil_kn(run) -> np.ndarray:
    fields = run.channels["/pile/bucket"].fields
    return np.hypot(fields["F_y_N"], fields["F_z_N"]) / 1e3


def _per_period_max(run, values: np.ndarray) -> dict[int, float]:
    period = run.channels["/pile/bucket"].period
    return {k: float(values[period == k].max()) for k in range(1, len(run.periods) + 1)}


def test_the_pressure_panel_s_boom_figures(paper_run):
    run = paper_run
    boom = run.channels["/cylinder/boom"]
    assert np.array_equal(boom.log_time_ns, run.channels["/pile/bucket"].log_time_ns)
    p_A, p_B = boom.fields["p_A_Pa"] / 1e5, boom.fields["p_B_Pa"] / 1e5
    force, load = boom.fields["F_N"] / 1e3, boom.fields["F_ext_N"] / 1e3
    cut = _soil_kn(run) > 0.0
    lowest, low, high = quoted(r"it never falls below (\d+) bar, and the boom cylinder force lies "
                               r"between (\d+) and (\d+) kN 90 % of the time", FOXGLOVE)
    rounded(p_A.min(), lowest)
    rounded(np.percentile(force, 5), low, unit=10.0)
    rounded(np.percentile(force, 95), high, unit=10.0)

    # The soil takes the arm's weight off the boom; where the force turns negative, the servo
    # lowers the boom (spool and velocity negative) in the cut on its rod side.
    least, first, second, rod, negative = quoted(
        r"the boom's load falls to (\d+) kN, and in periods (\d+) and (\d+), where the servo "
        r"lowers the boom into the cut, the rod side \(up to (\d+) bar\) drives it down and the "
        r"boom cylinder force reaches (-\d+) kN", FOXGLOVE)
    rounded(load.min(), least)
    assert cut[np.argmin(load)]
    pulled = force < 0.0
    assert sorted(set(boom.period[pulled].tolist())) == [int(first), int(second)]
    assert cut[pulled].all()
    assert (boom.fields["u"][pulled] < 0.0).all() and (boom.fields["v_m_s"][pulled] < 0.0).all()
    rounded(p_B[pulled].max(), rod)
    rounded(force.min(), negative)

    # The largest force: out of the ground, in the lift of the period whose tip went lowest,
    # where the cap side reaches both of its extremes.
    peak, k, swing_low, swing_high = quoted(
        r"Its largest force, (\d+) kN, comes out of the ground, in period (\d+)'s lift after the "
        r"run's deepest cut, where the boom's cap side swings between (\d+) and (\d+) bar, the "
        r"run's lowest and highest", FOXGLOVE)
    k = int(k)
    at = int(np.argmax(force))
    rounded(force[at], peak)
    assert not cut[at] and boom.period[at] == k
    record = run.periods[k - 1]
    lift_starts_s = record["t0_s"] + sum(record["segment_durations_s"][:3])
    assert boom.log_time_ns[at] / 1e9 > lift_starts_s  # the last segment: the lift
    assert record["lowest_tip_m"][1] == min(r["lowest_tip_m"][1] for r in run.periods)
    in_k = boom.period == k
    assert p_A[in_k].min() == p_A.min() and p_A[in_k].max() == p_A.max()
    rounded(p_A.min(), swing_low)
    rounded(p_A.max(), swing_high)


def test_the_pressure_panel_s_stick_and_bucket_figures(paper_run):
    cut = _soil_kn(paper_run) > 0.0
    outside, stick, bucket = quoted(r"at most (\d+) bar out of the ground, rise to (\d+) and (\d+) "
                                    r"bar as they pull the bucket through the soil", FOXGLOVE)
    for joint, peak in (("stick", stick), ("bucket", bucket)):
        p_A = paper_run.channels[f"/cylinder/{joint}"].fields["p_A_Pa"] / 1e5
        assert p_A[~cut].max() <= float(outside) + 0.5, joint
        assert p_A[cut].max() == p_A.max(), joint
        rounded(p_A.max(), peak)


def test_the_soil_force_panel_s_figures(paper_run):
    run = paper_run
    soil = _soil_kn(run)
    peaks = _per_period_max(run, soil)
    peak, at, value, passing, periods, first, second, below = quoted(
        r"the force peaks at (\d+) kN \(in period (\d+)\) and passes (\d+) kN in (\d+) of the "
        r"(\d+) periods; the shallow periods (\d+) and (\d+) and the reset period stay below "
        r"(\d+) kN", FOXGLOVE)
    rounded(soil.max(), peak)
    assert max(peaks, key=peaks.get) == int(at)
    assert len(run.periods) == int(periods)
    assert sum(p > float(value) for p in peaks.values()) == int(passing)
    resets = [r["k"] for r in run.periods if r["reset"]]
    assert len(resets) == 1
    assert sorted(k for k, p in peaks.items() if p < float(below)) == sorted(
        [int(first), int(second), resets[0]])


def test_the_slice_the_payload_and_the_soil_force_of_the_full_scale_section(paper_run):
    run = paper_run
    slice_cm = 100.0 * run.scenario["plant"]["pile"]["parameters"]["slice_width"]
    (panel,) = quoted(r"The pile is a ([\d.]+) cm slice of soil", FOXGLOVE)
    (section,) = quoted(r"30 kg a period from a ([\d.]+) cm slice of the pile", FULL_SCALE)
    rounded(slice_cm, panel)
    rounded(slice_cm, section)
    weight, soil, holds = quoted(r"payload then weighs ([\d.]+) kN against up to (\d+) kN of soil "
                                 r"force, and the bucket holds ([\d.]+) m\* of its slice",
                                 FULL_SCALE)
    target = run.scenario["target_mass_kg"]
    assert target == 30.0
    rounded(target * G / 1e3, weight)
    rounded(_soil_kn(run).max(), soil)
    rounded(run.periods[0]["rated_payload_kg"] / target, holds)


def test_the_run_log_sizes(paper):
    log, run = paper
    per_period, total, periods = quoted(r"each period adds ([\d.]+) MB for the paper scenario "
                                        r"\(100 Hz: ([\d.]+) MB for its (\d+) periods\)", CAMPAIGNS)
    assert len(run.periods) == int(periods)
    assert 1.0 / run.scenario["plant"]["communication_step_s"] == pytest.approx(100.0)
    assert np.median(np.diff(run.channels["/joints"].of_period(1)["t_s"])) == pytest.approx(0.01)
    starts = [start for start, _ in run.period_chunks]
    rounded((starts[-1] - starts[0]) / (len(starts) - 1) / 1e6, per_period)
    rounded(log.stat().st_size / 1e6, total)
    (about,) = quoted(r"A 20-period paper run logs about (\d+) MB at the default sample rate",
                      SWEEPS)
    rounded(log.stat().st_size / 1e6, about)
    (resume,) = quoted(r"\(`/resume`, (\d+) kB per period\)", CAMPAIGNS)
    sizes = [len(state) for state in run.resume_states.values()]
    assert len(sizes) == len(run.periods)
    rounded(float(np.mean(sizes)) / 1e3, resume)


def test_the_lab_run_s_log_size_and_errors(lab_simulated_run):
    from lab_runs import LAB_PERIODS

    result, log = lab_simulated_run
    assert result.termination == "periods", result.message
    run = read_run(log)
    per_period, total, periods = quoted(r"and ([\d.]+) MB for the lab scenario on the simulated "
                                        r"plant \(1 kHz: ([\d.]+) MB for (\d+) periods;", CAMPAIGNS)
    assert len(run.periods) == int(periods) == LAB_PERIODS
    assert 1.0 / run.scenario["plant"]["communication_step_s"] == pytest.approx(1000.0)
    starts = [start for start, _ in run.period_chunks]
    rounded((starts[-1] - starts[0]) / (len(starts) - 1) / 1e6, per_period)
    rounded(log.stat().st_size / 1e6, total)
    errors = quoted(r"errors ([\d.]+), ([\d.]+), ([\d.]+) kg in periods 1-3", LAB)
    for record, text in zip(run.periods, errors, strict=True):
        rounded(record["error_kg"], text)


def test_reproducing_the_paper_s_tables(paper_run):
    records = paper_run.periods
    (first,) = quoted(r"\| period 1 digs 8\.5 kg \| ([\d.]+) kg \|", PAPER_RESULTS)
    rounded(records[0]["mass_kg"], first)
    after, y_D, z_D = quoted(r"\| reset and shift after period 10 \| after period (\d+) "
                             r"\(D -> \((-[\d.]+), (-[\d.]+)\) m\) \|", PAPER_RESULTS)
    resets = [r for r in records if r["reset"]]
    assert [r["k"] for r in resets] == [int(after) + 1]
    rounded(resets[0]["deepest_point_m"][0], y_D)
    rounded(resets[0]["deepest_point_m"][1], z_D)
    *beyond, within, counted = quoted(r"\*\*not met\*\*: three periods beyond 5 kg \((\d+), (\d+), "
                                      r"(\d+)\); (\d+) of (\d+) periods within \+-3 kg \(the "
                                      r"reset period left out\)", PAPER_RESULTS)
    kept = [r for r in records if r["k"] >= 2 and not r["reset"]]
    assert [r["k"] for r in kept if abs(r["error_kg"]) > 5.0] == [int(k) for k in beyond]
    assert sum(abs(r["error_kg"]) <= 3.0 for r in kept) == int(within)
    assert len(kept) == int(counted)
    # Case 2 of the planner's table is period 1's trajectory: the paper's k_T, k_J and D0.
    duration, jerk = quoted(r"\| case 2 \(k_T = 0\.1, k_J = 0\.9\): 18\.38 s, peak jerk about 40 "
                            r"deg/s\^3 \| ([\d.]+) s, peak jerk ([\d.]+) deg/s\^3 \|",
                            PAPER_RESULTS)
    assert paper_run.scenario["trajectory"] == {"k_T": 0.1, "k_J": 0.9}
    assert records[0]["deepest_point_m"] == [-9.0, -0.1]
    rounded(records[0]["duration_s"], duration)
    rounded(max(records[0]["max_abs_jerk_deg_s3"]), jerk)


def test_the_substitution_table_s_paper_row(paper_run):
    figures = run_figures(paper_run.periods, band_kg(30.0))
    mean, worst, within, counted, resets = quoted(
        r"\| `paper-2020` \(HydraulicCylinder, Pile\) \| ([\d.]+) kg \| ([\d.]+) kg \(the reset "
        r"period\) \| (\d+)/(\d+) \| (\d+) \|", SUBSTITUTION)
    rounded(figures["mean_abs_error_kg"], mean)
    rounded(figures["max_abs_error_kg"], worst)
    reset = next(r for r in paper_run.periods if r["reset"])
    assert abs(reset["error_kg"]) == figures["max_abs_error_kg"]
    assert (figures["within_band"], figures["counted"]) == (int(within), int(counted))
    assert figures["resets"] == int(resets)


def test_the_hydraulics_table_s_after_column(paper):
    """bench/hydraulics.py's figures of the paper scenario as it is (its "after" column)."""
    log, run = paper
    figures = _bench("hydraulics").figures(log, run.scenario["target_mass_kg"])
    for joint in JOINTS:
        share, episodes, longest = quoted(
            rf"\| {joint}: samples with a chamber at 0 Pa \| [^|]+ \| ([\d.]+) % \((\d+) "
            rf"episodes, longest ([\d.]+) s\) \|", SUPPLY)
        void_share, void_episodes, void_longest = figures["voids"][joint]
        rounded(void_share, share)
        assert void_episodes == int(episodes)
        rounded(void_longest, longest)
    for key, label, unit in (("peak_kw", "peak hydraulic power", " kW"),
                             ("mean_kw", "mean hydraulic power", " kW"),
                             ("energy_kj", "supply energy per period", " kJ"),
                             ("throttled", "throttled share", "")):
        (text,) = quoted(rf"\| {label} \| [^|]+ \| ([\d.]+){unit} \|", SUPPLY)
        rounded(figures[key], text)
    rms = quoted(r"\| tracking RMS boom / stick / bucket \| [^|]+ \| ([\d.]+) / ([\d.]+) / "
                 r"([\d.]+) deg \|", SUPPLY)
    for value, text in zip(figures["tracking"], rms, strict=True):
        rounded(value, text)
    jumps = quoted(r"\| samples beyond 1\.5 x the acceleration limit, boom / stick / bucket \| "
                   r"[^|]+ \| (\d+) / (\d+) / (\d+) \|", SUPPLY)
    assert figures["jumps"] == [int(n) for n in jumps]
    within = quoted(r"\| periods within \+-3 kg \| [^|]+ \| (\d+) of (\d+) \|", SUPPLY)
    assert figures["within"] == tuple(int(n) for n in within)


def test_the_converged_co_simulation_s_figures(paper_run):
    """The tries per step of the arm coupling, and where the large joint accelerations lie
    (bench/convergence.py's classification: within its window of soil contact or not)."""
    run = paper_run
    convergence = _bench("convergence")
    tries = run.channels["/signals/coupling"].fields["values"].ravel()
    (table,) = quoted(r"\| 10 ms \| [^|]+ \| [^|]+ \| ([\d.]+) \([\d.]+\) \|", BENCHMARKS)
    (text,) = quoted(r"wall time [\d.]+ of its own pair by pair\), ([\d.]+) tries per step",
                     BENCHMARKS)
    rounded(float(np.mean(tries)), table)
    rounded(float(np.mean(tries)), text)

    step = run.scenario["plant"]["communication_step_s"]
    window = int(round(convergence.VOID_WINDOW_S / step))
    counts = np.zeros((len(JOINTS), 2), dtype=int)  # beyond the limit; of them near soil
    nearest = math.inf
    for k in range(1, len(run.periods) + 1):
        joints = run.channels["/joints"].of_period(k)
        q = np.column_stack([joints[f"measured_{j}_rad"] for j in JOINTS])
        ratio = np.abs(np.diff(q, 2, axis=0)) / step**2 / (1.5 * convergence.LIMIT_RAD_S2)
        nearest = min(nearest, float(np.min(np.abs(ratio - 1.0))))
        for joint in JOINTS:
            cylinder = run.channels[f"/cylinder/{joint}"].of_period(k)
            assert (cylinder["p_A_Pa"] > 0.0).all() and (cylinder["p_B_Pa"] > 0.0).all()
        soil = run.channels["/pile/bucket"].of_period(k)
        contact = np.hypot(soil["F_y_N"], soil["F_z_N"]) > 0.0
        near = np.convolve(contact, np.ones(2 * window + 1), "same") > 0
        for j in range(len(JOINTS)):
            high = np.nonzero(ratio[:, j] > 1.0)[0] + 1
            counts[j] += (len(high), int(near[high].sum()))
    assert nearest > 1e-6  # no count hangs on a CPU's rounding
    beyond = quoted(r"0 / ([\d,]+) / ([\d,]+) with the stick circuit, make-up checks and power "
                    r"limiter as they are", BENCHMARKS)
    near_soil = quoted(r"within 0\.3 s of soil contact \(stick (\d+) of ([\d,]+), bucket (\d+) "
                       r"of ([\d,]+)\)", BENCHMARKS)
    assert counts[0, 0] == 0
    assert counts[1:, 0].tolist() == [int(n.replace(",", "")) for n in beyond]
    assert [counts[1, 1], counts[1, 0], counts[2, 1], counts[2, 0]] == [
        int(n.replace(",", "")) for n in near_soil]
