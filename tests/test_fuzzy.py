"""The Sugeno rule eps(dm) of paper section 2.3 against simpful's Sugeno engine and its own laws."""

import contextlib
import doctest
import io

import numpy as np
import pytest
import simpful as sf

import planner.fuzzy
from planner.fuzzy import TERMS, FuzzyRule

TARGET_KG = 30.0  # the paper's m* (section 3.2)


def simpful_rule(centres_kg, outputs_m):
    """The same rule built in simpful: eq. 6 triangles, shoulder sets, crisp Sugeno outputs."""
    with contextlib.redirect_stdout(io.StringIO()):  # simpful prints its model type
        system = sf.FuzzySystem(show_banner=False, verbose=False)
        c = list(centres_kg)
        # Point-based sets keep their end values outside their points: shoulders that saturate
        # at any input, however far outside the universe of discourse.
        sets = [sf.FuzzySet(points=[[c[0], 1.0], [c[1], 0.0]], term=TERMS[0])]
        sets += [sf.TriangleFuzzySet(c[i - 1], c[i], c[i + 1], term=TERMS[i]) for i in range(1, 6)]
        sets.append(sf.FuzzySet(points=[[c[5], 0.0], [c[6], 1.0]], term=TERMS[6]))
        # The universe only serves simpful's plots; inputs beyond it are still evaluated.
        span = c[-1] - c[0]
        system.add_linguistic_variable(
            "dm", sf.LinguisticVariable(sets, universe_of_discourse=[c[0] - span, c[-1] + span])
        )
        for i, r in enumerate(outputs_m):
            system.set_crisp_output_value(f"r{i + 1}", r)
        system.add_rules([f"IF (dm IS {t}) THEN (eps IS r{i + 1})" for i, t in enumerate(TERMS)])

    def evaluate(dm_kg):
        system.set_variable("dm", dm_kg)
        return system.Sugeno_inference(["eps"])["eps"]

    return evaluate


def wide_inputs(rule, n, seed):
    """n inputs (kg) from well below the lowest to well above the highest centre."""
    lo, hi = rule.centres_kg[0], rule.centres_kg[-1]
    span = hi - lo
    return np.random.default_rng(seed).uniform(lo - span, hi + span, n)


def test_paper_rule_equals_simpful_sugeno_at_1000_inputs():
    rule = FuzzyRule.paper(TARGET_KG)
    reference = simpful_rule(rule.centres_kg, rule.outputs_m)
    dm = np.concatenate([wide_inputs(rule, 994, seed=1), [-1e6, -40.0, -18.0, 18.0, 40.0, 1e6]])
    expected = np.array([reference(x) for x in dm])
    np.testing.assert_allclose(rule(dm), expected, rtol=0, atol=1e-12)
    # Both sides of each shoulder are exercised, and the shoulders hold the outer outputs.
    assert np.sum(dm < -18.0) > 100 and np.sum(dm > 18.0) > 100
    assert expected[994] == -0.4 and expected[-1] == 0.4


def test_asymmetric_rule_equals_simpful_sugeno():
    rng = np.random.default_rng(7)
    centres = np.cumsum(rng.uniform(0.5, 8.0, 7)) - 20.0
    outputs = rng.uniform(-1.0, 1.0, 7)  # not monotone: the engine must not rely on order
    rule = FuzzyRule(centres_kg=centres, outputs_m=outputs)
    reference = simpful_rule(rule.centres_kg, rule.outputs_m)
    dm = wide_inputs(rule, 300, seed=2)
    np.testing.assert_allclose(rule(dm), [reference(x) for x in dm], rtol=0, atol=1e-12)


def test_paper_partition_scales_with_target_mass():
    rule = FuzzyRule.paper(TARGET_KG)
    assert rule.centres_kg == (-18.0, -9.0, -3.0, 0.0, 3.0, 9.0, 18.0)
    assert rule.outputs_m == (-0.4, -0.25, -0.1, 0.0, 0.1, 0.25, 0.4)
    # The same relative error gives the same correction for any target.
    light = FuzzyRule.paper(10.0)
    np.testing.assert_allclose(light(np.array([-5.0, 1.7, 6.5])),
                               rule(np.array([-15.0, 5.1, 19.5])), rtol=0, atol=1e-15)


def test_rule_gives_exact_output_at_each_centre():
    for rule in (FuzzyRule.paper(TARGET_KG), FuzzyRule((-7, -4, -2, 0.5, 1, 3, 11), range(7))):
        got = [rule(c) for c in rule.centres_kg]
        assert got == list(rule.outputs_m)


def test_hand_computed_values_between_centres():
    rule = FuzzyRule.paper(TARGET_KG)
    # dm = 6 kg: halfway between ps (3 kg) and pb (9 kg) -> (0.1 + 0.25) / 2.
    assert rule(6.0) == pytest.approx(0.175, abs=1e-15)
    # dm = -12 kg: mu_vnb = (-9 + 12)/9 = 1/3, mu_nb = (-12 + 18)/9 = 2/3.
    assert rule(-12.0) == pytest.approx(-0.4 / 3 - 0.25 * 2 / 3, abs=1e-15)
    # Beyond the outer centres the shoulders hold r_1 and r_7.
    assert rule(21.5) == 0.4 and rule(-1e9) == -0.4


def test_odd_symmetry_for_symmetric_partition():
    rule = FuzzyRule.paper(TARGET_KG)
    dm = wide_inputs(rule, 1000, seed=3)
    np.testing.assert_allclose(rule(-dm), -rule(dm), rtol=0, atol=1e-15)


def test_monotone_non_decreasing():
    rule = FuzzyRule.paper(TARGET_KG)
    dm = np.sort(np.concatenate([wide_inputs(rule, 2000, seed=4), rule.centres_kg]))
    assert np.all(np.diff(rule(dm)) >= 0.0)


def test_memberships_are_a_partition_of_unity():
    rule = FuzzyRule.paper(TARGET_KG)
    dm = np.concatenate([wide_inputs(rule, 1000, seed=5), rule.centres_kg, [-1e300, 1e300]])
    mu = rule.memberships(dm)
    assert mu.shape == (dm.size, 7)
    assert np.all((mu >= 0.0) & (mu <= 1.0))
    np.testing.assert_allclose(mu.sum(axis=1), 1.0, rtol=0, atol=1e-15)
    # At most two adjacent terms fire.
    firing = mu > 0.0
    assert np.all(firing.sum(axis=1) <= 2)
    first = np.argmax(firing, axis=1)
    last = 6 - np.argmax(firing[:, ::-1], axis=1)
    assert np.all(last - first <= 1)


def test_breakpoints_follow_the_centres():
    rule = FuzzyRule.paper(TARGET_KG)
    bp = rule.breakpoints_kg
    assert bp[0] == (-np.inf, -18.0, -9.0)
    assert bp[3] == (-3.0, 0.0, 3.0)
    assert bp[6] == (9.0, 18.0, np.inf)


def test_scalar_in_float_out_array_in_array_out():
    rule = FuzzyRule.paper(TARGET_KG)
    assert type(rule(3.0)) is float and type(rule(3)) is float
    assert type(rule(np.float64(3.0))) is float
    out = rule(np.array([[1.0, 2.0], [3.0, 4.0]]))
    assert isinstance(out, np.ndarray) and out.shape == (2, 2)
    assert isinstance(rule([1.0, 2.0]), np.ndarray)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"centres_kg": (0, 1, 2, 3, 4, 5)}, "centres_kg must have 7 values"),
        ({"centres_kg": (0, 1, 2, 2, 4, 5, 6)}, "strictly increasing"),
        ({"centres_kg": (6, 5, 4, 3, 2, 1, 0)}, "strictly increasing"),
        ({"centres_kg": (0, 1, 2, np.nan, 4, 5, 6)}, "centres_kg must be finite"),
        ({"centres_kg": range(7), "outputs_m": (0, 1)}, "outputs_m must have 7 values"),
        ({"centres_kg": range(7), "outputs_m": (0, 1, 2, 3, 4, 5, np.inf)}, "outputs_m must be"),
        ({"centres_kg": "abcdefg"}, "centres_kg must be 7 numbers"),
    ],
)
def test_bad_rule_parameters_raise_value_error(kwargs, message):
    with pytest.raises(ValueError, match=message):
        FuzzyRule(**kwargs)


@pytest.mark.parametrize("target", [0.0, -30.0, np.nan, np.inf])
def test_paper_rule_needs_positive_finite_target(target):
    with pytest.raises(ValueError, match="target_mass_kg"):
        FuzzyRule.paper(target)


@pytest.mark.parametrize("dm", [np.nan, np.inf, [0.0, np.nan], "heavy"])
def test_non_finite_weight_error_raises_value_error(dm):
    with pytest.raises(ValueError, match="dm_kg"):
        FuzzyRule.paper(TARGET_KG)(dm)


def test_module_docstring_example_runs():
    result = doctest.testmod(planner.fuzzy)
    assert result.attempted > 0 and result.failed == 0
