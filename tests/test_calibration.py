"""bench/calibrate_paper.py: the committed paper scenario scores what the script's docstring says,
the score function counts and penalises as documented, and bad arguments exit 2 in one line.

The optimiser itself is not run here (minutes of campaigns); one campaign (a few seconds) checks
the committed scenario.
"""

import importlib.util
import math
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
SCRIPT = ROOT / "bench" / "calibrate_paper.py"


def _load_script():
    spec = importlib.util.spec_from_file_location("calibrate_paper", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up there
    spec.loader.exec_module(module)
    return module


cal = _load_script()


def _records(masses, resets=(), target=30.0):
    """Hand-made period records, k = 1.. in order; `resets` lists the reset periods."""
    return [{"k": k, "mass_kg": m, "error_kg": target - m, "reset": k in resets}
            for k, m in enumerate(masses, start=1)]


def _near(error_kg):
    """The documented per-period +-3 kg term."""
    excess = abs(error_kg) - 3.0
    return 0.025 + 0.025 * (1.0 - math.exp(-((excess / 3.0) ** 2))) if excess > 0 else 0.0


# Period 1 at 8.5 kg, the reset period at 9 digging 6.7 kg, all other periods on target.
IDEAL = [8.5] + [30.0] * 7 + [6.7] + [30.0] * 11


def test_committed_scenario_scores_as_the_docstring_says():
    score, records = cal.score_scenario(cal.load_scenario(cal.SCENARIO))
    assert score.termination == "periods" and len(records) == 20
    assert score.first_mass_kg == pytest.approx(8.81, abs=0.005)
    assert score.misses == 3 and records[1]["mass_kg"] == pytest.approx(10.97, abs=0.05)
    assert score.reset_periods == [12]
    assert (score.within_3, score.counted) == (14, 18)
    assert (score.reset, score.full, score.undug) == (0, 0, 0)
    assert score.total == pytest.approx(3.1625, abs=5e-4)
    doc = cal.__doc__
    assert "period 1 8.81 kg, 3 misses (periods 2, 5, 16), reset period 12" in doc
    assert "14 of 18 counted periods within +-3 kg" in doc
    assert f"score {score.total:.2f}" in doc and f"near {score.near:.2f}" in doc


def test_committed_values_are_the_start_point_inside_the_bounds():
    x0 = cal.start_point(cal.SCENARIO, [])
    assert x0.tolist() == [0.1119, 0.6143, 0.9025, -0.1277, 3.0546, 0.016595, 0.8154619, 0.047562]
    assert all(p.low <= v <= p.high for p, v in zip(cal.PARAMETERS, x0, strict=True))
    assert cal.rounded(x0).tolist() == x0.tolist()  # the search evaluates them unchanged


def test_printed_set_lines_reproduce_the_point():
    x = [0.15234, 0.5, 1.1, -0.12, 2.75, 0.0161, 1.0, 0.04]
    items = cal.point_overrides(x)
    assert items[0] == "adaptation.centre_fractions=[0.1523, 0.5000, 1.1000]"
    assert cal.start_point(cal.SCENARIO, items).tolist() == cal.rounded(x).tolist()
    assert cal.set_lines(x)[0] == "--set 'adaptation.centre_fractions=[0.1523, 0.5000, 1.1000]'"


def test_on_target_campaign_scores_zero():
    score = cal.score_records(_records(IDEAL, resets={9}))
    assert score.total == 0.0
    assert (score.misses, score.within_3, score.counted, score.reset_periods) == (0, 18, 18, [9])


def test_misses_count_errors_beyond_5_kg_after_period_1_without_the_reset():
    masses = list(IDEAL)
    masses[1], masses[2], masses[3], masses[4] = 24.0, 35.5, 25.0, 34.0  # e = 6, -5.5, 5, -4
    masses[0] = 9.0  # period 1 is never a miss (only the first-period term judges it)
    score = cal.score_records(_records(masses, resets={9}))
    assert score.misses == 2  # exactly 5 kg is not beyond 5 kg
    assert score.within_3 == 14
    assert score.near == pytest.approx(sum(_near(e) for e in (6.0, -5.5, 5.0, -4.0)))
    assert score.first == pytest.approx(0.05 * 0.5**2)
    assert score.total == pytest.approx(2 + score.near + score.first)


def test_near_terms_together_stay_below_one_miss():
    masses = [8.5] + [34.99] * 7 + [6.7] + [25.01] * 11  # every counted error just under 5 kg
    score = cal.score_records(_records(masses, resets={9}))
    assert score.misses == 0 and score.within_3 == 0
    assert 0.45 < score.total < 0.9


def test_reset_term_is_the_distance_from_periods_8_to_14():
    def reset(resets):
        return cal.score_records(_records(IDEAL, resets=set(resets))).reset

    assert [reset([8]), reset([14]), reset([6]), reset([17])] == [0, 0, 2, 3]
    assert reset([]) == 7  # no reset in 20 periods: as if in period 21
    assert reset([9, 15]) == 1  # one further reset


def test_first_period_term_penalises_beyond_1_kg():
    masses = list(IDEAL)
    masses[0] = 10.0
    score = cal.score_records(_records(masses, resets={9}))
    assert score.first == pytest.approx(10.0 * 0.5 + 0.05 * 1.5**2)
    assert score.total == pytest.approx(score.first)


def test_full_buckets_undug_periods_and_failures():
    masses = list(IDEAL)
    masses[5] = 40.0  # fills a 40 kg bucket: a miss and a full bucket
    score = cal.score_records(_records(masses, resets={9}), full_mass_kg=40.0)
    assert (score.full, score.misses) == (1, 1)
    short = cal.score_records(_records(IDEAL[:12], resets={9}), termination="workspace_limit")
    assert short.undug == 8 and short.total == pytest.approx(8.0)
    failed = cal.score_records(_records(IDEAL[:3]), termination="error", message="boom")
    assert failed.total == cal.FAIL_SCORE and "boom" in failed.summary()


def test_bad_argument_exits_2_in_one_line():
    done = subprocess.run([sys.executable, str(SCRIPT), "--popsize", "0"], capture_output=True,
                          text=True, timeout=60, cwd=ROOT)
    assert done.returncode == 2 and done.stdout == ""
    assert done.stderr.count("\n") == 1 and "--popsize" in done.stderr


def test_bad_set_exits_2_in_one_line(capsys):
    assert cal.main(["--score", "--set", "adaptation.no_such_key=1"]) == 2
    out, err = capsys.readouterr()
    assert out == "" and err.count("\n") == 1 and "no_such_key" in err


def test_the_general_score_scales_its_bands_to_the_target():
    """--general: the paper's +-5 and +-3 kg bands at 30 kg become 5/30 and 3/30 of m*, and
    Figure 9's first-period and reset terms drop out (a real pile resets where it must)."""
    target = 1600.0
    errors = [0.0, 0.9 * target / 6, 1.1 * target / 6, 0.09 * target, 0.11 * target] + [0.0] * 15
    records = [{"k": k, "mass_kg": target - e, "error_kg": e, "reset": k == 3}
               for k, e in enumerate(errors, start=1)]
    score = cal.score_records(records, target_kg=target)
    # periods 2-20 count but the reset (3): period 2 (0.15 m*) and 5 (0.11 m*) lie beyond 3/30
    # but within 5/30, period 4 (0.09 m*) within 3/30
    assert score.misses == 0 and (score.within_3, score.counted) == (16, 18)
    assert score.first == 0.0 and score.reset == 0.0
    assert score.near_kg == pytest.approx(160.0)
    paper = cal.score_records(records)  # the same records scored as Figure 9: kg bands
    assert paper.misses == 3 and paper.first > 0.0
