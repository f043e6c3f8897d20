"""The Pile's seeded density field, run through the built FMU with fmpy.

References: conservation of mass (to round-off, with every cell of its own density); an
independent Python implementation of the field (splitmix64 knots, linear between them) for the
initial mass; a uniform pile (density_variation = 0) unchanged bit for bit.
"""

from __future__ import annotations

import numpy as np
import pytest
from test_pile_fmu import Pile, built, make_pile  # noqa: F401  (the fixtures)

TIP = (-9.0, 0.5)  # where the tip starts: above the ground at the paper's D0

MASK64 = (1 << 64) - 1


def splitmix64(x: int) -> int:
    x = (x + 0x9E3779B97F4A7C15) & MASK64
    x = ((x ^ (x >> 30)) * 0xBF58476D1CE4E5B9) & MASK64
    x = ((x ^ (x >> 27)) * 0x94D049BB133111EB) & MASK64
    return x ^ (x >> 31)


def deviation(y: np.ndarray, y_min: float, length: float, seed: int) -> np.ndarray:
    """u(y) in [-1, 1]: knots `length` apart from y_min, linear between them."""
    def knot(j: int) -> float:
        bits = splitmix64(((seed * 0x100000001B3) & MASK64) ^ (j & MASK64))
        return 2.0 * (bits >> 11) * 2.0**-53 - 1.0

    x = (np.asarray(y) - y_min) / length
    j = np.floor(x).astype(int)
    f = x - j
    return np.array([(1 - fi) * knot(int(ji)) + fi * knot(int(ji) + 1)
                     for ji, fi in zip(j, f, strict=True)])


def random_dig(pile: Pile, seed: int, moves: int = 150):
    """A walk of the tip in and out of the ground, dumping now and then: outputs after each step."""
    rng = np.random.default_rng(seed)
    y, z = pile.tip
    for _ in range(moves):
        y = float(np.clip(y + rng.uniform(-0.6, 0.6), -13.5, -1.5))
        z = float(np.clip(z + rng.uniform(-0.4, 0.35), -1.8, 0.6))
        dump = 1.0 if rng.random() < 0.1 else 0.0
        yield from pile.move(y, z, steps=int(rng.integers(1, 6)), dump=dump)


@pytest.mark.parametrize(("variation", "length"), [(0.2, 0.5), (0.5, 0.05), (0.3, 7.0)])
def test_the_initial_mass_is_the_integral_of_an_independent_field(make_pile, variation, length):  # noqa: F811
    pile = make_pile(TIP, density_variation=variation, density_correlation_length=length,
                     density_seed=11)
    p = pile.p
    edges = np.linspace(p["y_min"], p["y_max"], pile.n_cells + 1)
    centres = 0.5 * (edges[1:] + edges[:-1])
    rho = p["density"] * (1 + variation * deviation(centres, p["y_min"], length, 11))
    assert rho.min() >= p["density"] * (1 - variation)
    assert rho.max() <= p["density"] * (1 + variation)
    columns = (pile.profile() - p["z_floor"]) * pile.dy * p["slice_width"]
    assert pile.outputs()["pile_mass"] == pytest.approx(float(rho @ columns), rel=1e-12)


@pytest.mark.parametrize("variation", [0.2, 0.5])
def test_mass_is_conserved_with_a_density_field(make_pile, variation):  # noqa: F811
    pile = make_pile(TIP, density_variation=variation, density_correlation_length=0.3,
                     density_seed=4)
    m0 = pile.outputs()["pile_mass"]
    worst, lightest, heaviest = 0.0, np.inf, 0.0
    density, capacity = pile.p["density"], pile.p["capacity"]
    for o in random_dig(pile, 20201):
        total = o["pile_mass"] + o["bucket_mass"] + o["dumped_mass"]
        worst = max(worst, abs(total - m0) / m0)
        assert o["bucket_mass"] >= -1e-9
        if o["bucket_mass"] > 0.2 * density * capacity:  # the bucket's mean density
            share = o["bucket_mass"] / (density * capacity)
            lightest, heaviest = min(lightest, share), max(heaviest, share)
    assert worst <= 1e-9
    assert o["dumped_mass"] > 2 * density * capacity * (1 - variation)  # it dug and dumped
    # Loads of the same volume weigh differently, within the field's bounds (capacity holds).
    assert heaviest <= 1 + variation + 1e-9


def test_a_uniform_pile_is_unchanged_by_the_field_parameters(make_pile):  # noqa: F811
    """density_variation = 0 ignores the seed and length: the uniform pile's numbers exactly."""
    plain = make_pile(TIP)
    seeded = make_pile(TIP, density_seed=99, density_correlation_length=3.0)
    for a, b in zip(random_dig(plain, 7, 60), random_dig(seeded, 7, 60), strict=True):
        assert a == b


def test_the_field_is_reproducible_and_differs_between_seeds(make_pile):  # noqa: F811
    runs = {}
    for name, seed in (("a", 5), ("b", 5), ("c", 6)):
        pile = make_pile(TIP, density_variation=0.2, density_seed=seed)
        runs[name] = [o["dumped_mass"] + o["bucket_mass"] for o in random_dig(pile, 3, 80)]
    assert runs["a"] == runs["b"]
    assert max(abs(x - y) for x, y in zip(runs["a"], runs["c"], strict=True)) > 1.0


@pytest.mark.parametrize(("name", "value"), [
    ("density_variation", -0.01), ("density_variation", 0.51),
    ("density_correlation_length", 0.0), ("density_correlation_length", float("inf")),
])
def test_bad_field_parameters_fail_initialization_naming_the_parameter(built, capsys,  # noqa: F811
                                                                        name, value):
    from fmpy.fmi1 import FMICallException

    with pytest.raises(FMICallException):
        Pile(*built, TIP, **{name: value})
    assert name in capsys.readouterr().out
