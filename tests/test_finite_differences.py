"""The finite-difference helper the derivative tests rely on: its bound covers its real error, on
smooth functions and on functions with round-off noise, and is tight enough to catch a wrong
derivative."""

import numpy as np
import pytest
from finite_differences import assert_derivative, central_difference


def smooth(x):
    return np.array([np.sin(3 * x[0]) * np.exp(x[1]), x[0] ** 5 - np.cos(x[1]) / (1 + x[0] ** 2)])


def smooth_jacobian(x):
    return np.array([
        [3 * np.cos(3 * x[0]) * np.exp(x[1]), np.sin(3 * x[0]) * np.exp(x[1])],
        [5 * x[0] ** 4 + 2 * x[0] * np.cos(x[1]) / (1 + x[0] ** 2) ** 2,
         np.sin(x[1]) / (1 + x[0] ** 2)],
    ])


def noisy(level):
    """smooth() plus deterministic noise of relative size `level` (a CPU that rounds worse)."""
    def function(x):
        value = smooth(x)
        phase = np.sin(1e7 * x.sum() + np.arange(value.size))
        return value + level * phase * (1.0 + np.abs(value))
    return function


@pytest.mark.parametrize("level", [0.0, 1e-15, 1e-13, 1e-11])
def test_the_bound_covers_the_true_error(level):
    rng = np.random.default_rng(7)
    for x in rng.uniform(-1.0, 1.0, (20, 2)):
        numeric = central_difference(noisy(level), x)
        true_error = np.abs(numeric.estimate - smooth_jacobian(x))
        assert np.all(true_error <= numeric.error)
        assert_derivative(smooth_jacobian(x), numeric)


def test_the_bound_grows_with_the_noise_it_sees():
    x = np.array([0.3, -0.2])
    quiet, loud = central_difference(noisy(0.0), x), central_difference(noisy(1e-11), x)
    assert loud.error.min() > 100 * quiet.error.max()


def test_a_wrong_derivative_is_caught():
    x = np.array([0.4, 0.1])
    numeric = central_difference(smooth, x)
    assert numeric.error.max() < 1e-9
    with pytest.raises(AssertionError, match="derivatives off"):
        assert_derivative(smooth_jacobian(x) * (1.0 + 1e-6), numeric)
    wrong = smooth_jacobian(x)
    wrong[1, 0] += 1e-7
    with pytest.raises(AssertionError, match=r"\(1, 0\)"):
        assert_derivative(wrong, numeric)
