"""Study designs of a sweep: the axes of one group sampled together over their ranges.

    [[axis]]
    key = "plant.pile.parameters.density"
    sample = { design = "lhs", distribution = "uniform", low = 1280.0, high = 1920.0,
               count = 16, seed = 1 }
    group = "soil"

A `design` other than "random" (the default: independent draws per axis, orchestrator.sweep.spec)
draws one point set for all the design axes of a group, in the file's order, in the unit cube
[0, 1)^d, then scales each column to its axis's range: linearly for `distribution = "uniform"`,
linearly in log(value) for "loguniform". The axes of such a group give the same design, count
and seed; `values` axes may be zipped with them as in any group.

- "lhs": scipy.stats.qmc.LatinHypercube(d, rng=seed).random(count): count runs.
- "sobol": scipy.stats.qmc.Sobol(d, scramble=True, rng=seed).random(count), count a power of 2
  (the sequence's balance needs it): count runs.
- "saltelli": SALib.sample.sobol.sample (Saltelli's scheme over a scrambled Sobol sequence,
  first-order and total indices only, calc_second_order=False), count a power of 2: count x
  (d + 2) runs, the design `excosim sweep --sensitivity` needs.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

DESIGNS = ("random", "lhs", "sobol", "saltelli")
POWER_OF_TWO = ("sobol", "saltelli")  # designs whose count must be 2^m


@dataclass(frozen=True)
class Design:
    """How one axis is sampled by a group design: design ("lhs", "sobol", "saltelli"), its
    range low < high (the axis's unit; log: sampled uniformly in log(value), low > 0), count
    (base points; a saltelli design runs count x (d + 2)), seed."""

    design: str
    low: float
    high: float
    log: bool
    count: int
    seed: int

    def scale(self, unit: np.ndarray) -> np.ndarray:
        """Values of the axis for unit coordinates in [0, 1] (shape (n,) -> (n,))."""
        if self.log:
            a, b = math.log(self.low), math.log(self.high)
            return np.exp(a + unit * (b - a))
        return self.low + unit * (self.high - self.low)

    def centre(self) -> float:
        """The middle of the range (geometric for a log range)."""
        return float(self.scale(np.array([0.5]))[0])


def runs_of(design: str, count: int, dimensions: int) -> int:
    """How many runs a design of `count` base points in `dimensions` axes makes."""
    return count * (dimensions + 2) if design == "saltelli" else count


def unit_points(design: str, dimensions: int, count: int, seed: int) -> np.ndarray:
    """The design's points in the unit cube, shape (runs_of(...), dimensions)."""
    from scipy.stats import qmc

    if design == "lhs":
        return qmc.LatinHypercube(dimensions, rng=seed).random(count)
    if design == "sobol":
        return qmc.Sobol(dimensions, scramble=True, rng=seed).random(count)
    if design == "saltelli":
        return saltelli_sample(unit_problem(dimensions), count, seed)
    raise ValueError(f"unknown design {design!r}")


def unit_problem(dimensions: int, names: list[str] | None = None) -> dict:
    """A SALib problem over the unit cube (the design is scaled per axis afterwards)."""
    names = names or [f"x{i}" for i in range(dimensions)]
    return {"num_vars": dimensions, "names": names, "bounds": [[0.0, 1.0]] * dimensions}


def saltelli_sample(problem: dict, count: int, seed: int) -> np.ndarray:
    """SALib's Saltelli sample for first-order and total indices: (count x (d + 2), d)."""
    from SALib.sample import sobol

    return sobol.sample(problem, count, calc_second_order=False, seed=seed)


def design_values(designs: list[Design]) -> list[tuple[float, ...]]:
    """The values of each axis of one group design (same design, count, seed), in order."""
    first = designs[0]
    unit = unit_points(first.design, len(designs), first.count, first.seed)
    return [tuple(float(v) for v in d.scale(unit[:, i])) for i, d in enumerate(designs)]


def discrepancy(values: np.ndarray, designs: list[Design]) -> float:
    """The centred L2 discrepancy (scipy.stats.qmc.discrepancy) of a design's points (n, d),
    mapped back to the unit cube: how evenly they fill it (lower is more even)."""
    from scipy.stats import qmc

    unit = np.column_stack([
        (np.log(values[:, i]) - math.log(d.low)) / (math.log(d.high) - math.log(d.low))
        if d.log else (values[:, i] - d.low) / (d.high - d.low)
        for i, d in enumerate(designs)])
    return float(qmc.discrepancy(np.clip(unit, 0.0, 1.0)))
