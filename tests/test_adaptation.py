"""Adaptation of the deepest point D (paper section 2.3, eq. 5 and Fig. 5), checked by hand.

The expected numbers below are worked out by hand from eq. 5 and the triangles of the default
partition for m* = 30 kg: centres -18, -9, -3, 0, 3, 9, 18 kg -> outputs
-0.4, -0.25, -0.1, 0, 0.1, 0.25, 0.4 m.
"""

import doctest
import math

import pytest
from hypothesis import event, given, settings
from hypothesis import strategies as st

import planner.adaptation
from planner.adaptation import (
    WORKSPACE_LIMIT,
    AdaptationDefaults,
    AdaptationState,
    initial_state,
    next_deepest_point,
)
from planner.fuzzy import FuzzyRule

TARGET_KG = 30.0  # the paper's m* (section 3.2)
RULE = FuzzyRule.paper(TARGET_KG)
DEFAULTS = AdaptationDefaults()  # D0 = (-9, -0.1) m, dz_0 = -0.075 m, dy_0 = 3.5 m
DETERMINISTIC = settings(derandomize=True, database=None, deadline=None, max_examples=200)


class StubWorkspace:
    """A toy reach rule: D reachable when z_D > z_min and y_D <= y_max; records every query."""

    def __init__(self, z_min_m=-1.5, y_max_m=-5.0):
        self.z_min_m = z_min_m
        self.y_max_m = y_max_m
        self.queries = []

    def __call__(self, y_D, z_D):
        self.queries.append((y_D, z_D))
        return z_D > self.z_min_m and y_D <= self.y_max_m


# One campaign, period by period: (dug mass kg, then by hand: dm kg, eps m, dz m, z_D m, y_D m,
# flag, reset). Each row gives the state of the NEXT period.
CAMPAIGN = [
    # too light: dm = 21.5 kg is beyond vpb's centre (18 kg), shoulder -> eps = r7 = 0.4;
    # dz = -0.075 + 0.4 = 0.325, z_D = -0.1 - 0.325 = -0.425 (deeper)
    (8.5, 21.5, 0.4, 0.325, -0.425, -9.0, False, False),
    # still light: dm = 6 kg, halfway between ps (3) and pb (9): eps = (0.1 + 0.25)/2 = 0.175;
    # dz = 0.5, z_D = -0.925 (deeper again, by more)
    (24.0, 6.0, 0.175, 0.5, -0.925, -9.0, False, False),
    # too heavy: dm = -18 kg at vnb's centre: eps = -0.4; dz = 0.1, z_D = -1.025 (step shrinks)
    (48.0, -18.0, -0.4, 0.1, -1.025, -9.0, False, False),
    # too heavy: dm = -12 kg, mu_vnb = 1/3, mu_nb = 2/3: eps = -0.4/3 - 0.25*2/3 = -0.3;
    # dz = -0.2, z_D = -1.025 + 0.2 = -0.825 (shallower)
    (42.0, -12.0, -0.3, -0.2, -0.825, -9.0, False, False),
    # on target: eps = 0, dz stays -0.2, z_D keeps rising: -0.625 (eq. 5 is an integrator)
    (30.0, 0.0, 0.0, -0.2, -0.625, -9.0, False, False),
    # empty bucket twice: eps = 0.4 each; dz = 0.2 then 0.6; z_D = -0.825 then -1.425
    (0.0, 30.0, 0.4, 0.2, -0.825, -9.0, False, False),
    (0.0, 30.0, 0.4, 0.6, -1.425, -9.0, False, False),
    # dm = 1.5 kg, halfway between zero and ps: eps = 0.05; dz = 0.65 would put z_D at -2.075,
    # below the stub's -1.5 m: reset z_D = -0.1, dz = -0.075, shift y_D = -9 + 3.5 = -5.5
    (28.5, 1.5, 0.05, -0.075, -0.1, -5.5, True, True),
    # fresh ground at the shifted y_D: dz = 0.325, z_D = -0.425; then dz = 0.725, z_D = -1.15
    (8.5, 21.5, 0.4, 0.325, -0.425, -5.5, True, False),
    (0.0, 30.0, 0.4, 0.725, -1.15, -5.5, True, False),
]


def test_scripted_campaign_increase_decrease_reset_and_terminate():
    reachable = StubWorkspace()
    start = initial_state(DEFAULTS, reachable)
    assert not start.terminated and not start.reset and start.eps_m is None
    state = start.next_state
    assert (state.y_D, state.z_D, state.dz, state.flag, state.k) == (-9.0, -0.1, -0.075, False, 1)

    for mass, dm, eps, dz, z_D, y_D, flag, reset in CAMPAIGN:
        decision = next_deepest_point(state, mass, TARGET_KG, RULE, DEFAULTS, reachable)
        assert not decision.terminated and decision.reason is None
        assert decision.dm_kg == pytest.approx(dm, abs=1e-12)
        assert decision.eps_m == pytest.approx(eps, abs=1e-12)
        assert decision.reset is reset
        new = decision.next_state
        assert new.k == state.k + 1
        assert new.dz == pytest.approx(dz, abs=1e-12)
        assert new.z_D == pytest.approx(z_D, abs=1e-12)
        assert (new.y_D, new.flag) == (y_D, flag)
        state = new

    # The reset period asked about the deepened D first, then about the shifted default.
    assert (-9.0, pytest.approx(-2.075, abs=1e-12)) in reachable.queries
    assert (-5.5, -0.1) in reachable.queries

    # Empty again: dz = 0.725 + 0.4 = 1.125 -> z_D = -2.275, out of reach. y_D was already
    # shifted (flag), so the campaign ends without trying a second shift.
    queries_before = len(reachable.queries)
    end = next_deepest_point(state, 0.0, TARGET_KG, RULE, DEFAULTS, reachable)
    assert end.terminated and end.next_state is None and not end.reset
    assert end.reason == WORKSPACE_LIMIT == "workspace limit"
    assert end.eps_m == 0.4 and end.dm_kg == 30.0
    assert reachable.queries[queries_before:] == [(-5.5, pytest.approx(-2.275, abs=1e-12))]


def test_terminates_when_shifted_default_is_out_of_reach_too():
    reachable = StubWorkspace(y_max_m=-6.0)  # -9 + 3.5 = -5.5 m is beyond the inner limit
    state = AdaptationState(y_D=-9.0, z_D=-1.4, dz=0.3, flag=False, k=4)
    decision = next_deepest_point(state, 20.0, TARGET_KG, RULE, DEFAULTS, reachable)
    # dm = 10 kg: mu_pb = (18 - 10)/9, mu_vpb = 1/9 -> eps = (8*0.25 + 0.4)/9 = 0.2666...
    assert decision.eps_m == pytest.approx(2.4 / 9, abs=1e-12)
    assert decision.terminated and decision.reason == WORKSPACE_LIMIT
    assert decision.next_state is None
    assert reachable.queries == [(-9.0, pytest.approx(-1.4 - 0.3 - 2.4 / 9, abs=1e-12)),
                                 (-5.5, -0.1)]


def test_initial_state_is_checked_like_any_period():
    shifted = initial_state(DEFAULTS, lambda y_D, z_D: y_D > -6.0)
    assert shifted.reset and not shifted.terminated
    assert (shifted.next_state.y_D, shifted.next_state.z_D, shifted.next_state.flag) == (
        -5.5, -0.1, True)
    assert shifted.next_state.k == 1 and shifted.next_state.dz == -0.075

    unreachable = initial_state(DEFAULTS, lambda y_D, z_D: False)
    assert unreachable.terminated and unreachable.reason == WORKSPACE_LIMIT
    assert unreachable.next_state is None


@DETERMINISTIC
@given(
    z_D0=st.floats(-2.0, 0.0),
    dz_0=st.floats(-0.5, 0.5),
    periods=st.integers(1, 40),
)
def test_on_target_every_period_dz_holds_and_z_D_moves_by_dz(z_D0, dz_0, periods):
    defaults = AdaptationDefaults(z_D0=z_D0, dz_0=dz_0)
    state = initial_state(defaults, lambda y_D, z_D: True).next_state
    for _ in range(periods):
        decision = next_deepest_point(state, TARGET_KG, TARGET_KG, RULE, defaults,
                                      lambda y_D, z_D: True)
        new = decision.next_state
        assert decision.dm_kg == 0.0 and decision.eps_m == 0.0
        assert new.dz == state.dz == dz_0
        assert new.z_D == state.z_D - dz_0
        assert (new.y_D, new.flag, new.k) == (state.y_D, False, state.k + 1)
        state = new
    assert state.z_D == pytest.approx(z_D0 - periods * dz_0, abs=1e-9)


@DETERMINISTIC
@given(masses=st.lists(st.floats(allow_nan=False, allow_infinity=False), min_size=1,
                       max_size=30))
def test_any_finite_masses_give_a_valid_decision(masses):
    reachable = StubWorkspace(z_min_m=-1.8)
    state = initial_state(DEFAULTS, reachable).next_state
    for mass in masses:
        decision = next_deepest_point(state, mass, TARGET_KG, RULE, DEFAULTS, reachable)
        assert -0.4 <= decision.eps_m <= 0.4
        # dm > 0 (too light) enlarges the depth step, dm < 0 (too heavy) shrinks it.
        assert (decision.eps_m > 0.0) == (decision.dm_kg > 0.0)
        assert (decision.eps_m < 0.0) == (decision.dm_kg < 0.0)
        event(f"reset={decision.reset} terminated={decision.terminated}")
        if decision.terminated:
            assert decision.next_state is None and decision.reason == WORKSPACE_LIMIT
            # The stub always reaches the shifted default, so only a second limit ends it.
            assert state.flag
            return
        new = decision.next_state
        assert decision.reason is None and new.k == state.k + 1
        assert reachable(new.y_D, new.z_D)
        if decision.reset:
            assert (new.y_D, new.z_D, new.dz, new.flag) == (state.y_D + 3.5, -0.1, -0.075, True)
        else:
            assert new.dz == state.dz + decision.eps_m
            assert new.z_D == state.z_D - new.dz
            assert (new.y_D, new.flag) == (state.y_D, state.flag)
        state = new


def test_any_rule_callable_is_used_as_eps():
    linear = lambda dm_kg: 0.01 * dm_kg  # noqa: E731 - a stand-in for any eps(dm) rule
    state = AdaptationState(y_D=-9.0, z_D=-0.5, dz=0.1, flag=False, k=3)
    decision = next_deepest_point(state, 10.0, TARGET_KG, linear, DEFAULTS, lambda y, z: True)
    # eps = 0.01 * 20 = 0.2; dz = 0.3; z_D = -0.8
    assert decision.next_state.dz == pytest.approx(0.3, abs=1e-15)
    assert decision.next_state.z_D == pytest.approx(-0.8, abs=1e-15)


@pytest.mark.parametrize(
    ("mass", "target", "message"),
    [
        (math.nan, TARGET_KG, "dug_mass_kg"),
        (math.inf, TARGET_KG, "dug_mass_kg"),
        ("8.5", TARGET_KG, "dug_mass_kg"),
        (8.5, 0.0, "target_mass_kg"),
        (8.5, -30.0, "target_mass_kg"),
        (8.5, math.nan, "target_mass_kg"),
    ],
)
def test_bad_masses_raise_value_error(mass, target, message):
    state = AdaptationState(y_D=-9.0, z_D=-0.1, dz=-0.075, flag=False, k=1)
    with pytest.raises(ValueError, match=message):
        next_deepest_point(state, mass, target, RULE, DEFAULTS, lambda y, z: True)


def test_rule_returning_nan_raises_value_error():
    state = AdaptationState(y_D=-9.0, z_D=-0.1, dz=-0.075, flag=False, k=1)
    with pytest.raises(ValueError, match="non-finite correction"):
        next_deepest_point(state, 8.5, TARGET_KG, lambda dm: math.nan, DEFAULTS,
                           lambda y, z: True)


@pytest.mark.parametrize(
    ("fields", "message"),
    [
        ({"z_D": math.nan}, "z_D must be a finite"),
        ({"dz": math.inf}, "dz must be a finite"),
        ({"k": 0}, "k \\(period index\\)"),
        ({"k": 1.0}, "k \\(period index\\)"),
        ({"flag": 1}, "flag must be a bool"),
    ],
)
def test_bad_state_raises_value_error(fields, message):
    base = {"y_D": -9.0, "z_D": -0.1, "dz": -0.075, "flag": False, "k": 1}
    with pytest.raises(ValueError, match=message):
        AdaptationState(**{**base, **fields})


def test_bad_defaults_raise_value_error():
    with pytest.raises(ValueError, match="dy_0 must be a finite"):
        AdaptationDefaults(dy_0=math.nan)


def test_module_docstring_example_runs():
    result = doctest.testmod(planner.adaptation)
    assert result.attempted > 0 and result.failed == 0


def test_proportional_module_examples_run():
    import planner.proportional

    result = doctest.testmod(planner.proportional)
    assert result.attempted >= 2 and result.failed == 0
