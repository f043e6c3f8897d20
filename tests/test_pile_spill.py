"""Spill by tilt in the Pile FMU: out of the ground a bucket holds what its tilt leaves in it,
against the bucket's cross-section worked out numerically here (a half-disc shell under the
strike plane and a heap on it whose flanks stand at the angle of repose), and the spilled
material goes back onto the pile."""

import math

import numpy as np
import pytest
from test_pile_fmu import Pile, built  # noqa: F401  (the fixture)

DENSITY = 1600.0
CAPACITY = 0.004  # m^3 of the 0.038 m slice: filled by a 0.3 m x 1 m cut
REPOSE = math.radians(35.0)  # the FMU's default
HEAP_SHARE = 0.2  # the FMU's default


def _inside(points, lines):
    """Mask of points (n, 2) below every line (point, angle rad of its rise)."""
    mask = np.ones(len(points), dtype=bool)
    for (px, py), angle in lines:
        mask &= points[:, 1] <= py + math.tan(angle) * (points[:, 0] - px)
    return mask


def held_share_by_geometry(tilt: float, n: int = 1200) -> float:
    """Share of a full bucket that stays in it, tilted by `tilt` from opening up, by counting
    grid points of its cross-section: a unit half-disc below the strike plane (x in [-1, 1],
    y = 0), then the bucket turned clockwise by tilt, so the lip at (1, 0) is the lower one.
    Struck part: the half-disc below the free surface, a line through the lower lip rising into
    the bucket at the repose angle. Heap: what stands on the strike plane between two flanks at
    the repose angle to the horizontal from both lips (none when the plane is steeper)."""
    g = np.linspace(-1.5, 1.5, n)
    x, y = (a.ravel() for a in np.meshgrid(g, g))
    cell = (g[1] - g[0]) ** 2
    # Bucket frame -> world: turn clockwise by tilt.
    c, s = math.cos(tilt), math.sin(tilt)
    world = np.column_stack([c * x + s * y, -s * x + c * y])
    low_lip = np.array([c, -s])  # (1, 0) turned
    high_lip = -low_lip
    shell = (x * x + y * y <= 1.0) & (y <= 0.0)
    # Rising leftward (toward the bucket's inside) from the lower lip at the repose angle.
    struck = shell & _inside(world, [(low_lip, -REPOSE)])
    struck_share = struck.sum() * cell / (math.pi / 2)
    heap_share = 0.0
    if tilt < REPOSE:
        # Flanks from each lip rising at the repose angle toward the other; above the plane.
        heap = (y >= 0.0) & _inside(world, [(low_lip, -REPOSE), (high_lip, REPOSE)])
        heap_share = heap.sum() * cell / math.tan(REPOSE)  # level heap: L^2 tan(rho) / 4, L = 2
    return (1.0 - HEAP_SHARE) * struck_share + HEAP_SHARE * heap_share


@pytest.fixture
def full_pile(built):  # noqa: F811
    """A Pile whose bucket was filled to capacity at the carry orientation and lifted out."""
    made = []

    def make():
        pile = Pile(*built, (-10.0, 0.5), capacity=CAPACITY, density=DENSITY)
        made.append(pile)
        pile.move(-10.0, -0.3, steps=20, angle=math.pi)
        pile.move(-9.0, -0.3, steps=200, angle=math.pi)
        assert pile.outputs()["bucket_mass"] == pytest.approx(DENSITY * CAPACITY, rel=1e-9)
        return pile

    yield make
    for pile in made:
        pile.free()


@pytest.mark.parametrize("tilt_deg", [0.0, 15.0, 30.0, 34.0, 50.0, 80.0, 110.0, 124.0, 150.0])
def test_a_bucket_out_of_the_ground_holds_what_its_tilt_leaves(full_pile, tilt_deg):
    pile = full_pile()
    tilt = math.radians(tilt_deg)
    start = pile.outputs()
    # The tip-to-pin line at pi points back at the machine: opening up. pi - tilt turns it.
    pile.move(-9.0, 0.5, steps=20, angle=math.pi)
    assert pile.outputs()["spilled_mass"] == 0.0  # carried level: nothing spills
    o = pile.move(-9.0, 0.5, steps=1, angle=math.pi - tilt)[-1]
    expected = DENSITY * CAPACITY * held_share_by_geometry(tilt)
    # The grid's error is about 0.3 % of a full bucket.
    assert o["bucket_mass"] == pytest.approx(expected, abs=0.005 * DENSITY * CAPACITY)
    assert o["spilled_mass"] == pytest.approx(start["bucket_mass"] - o["bucket_mass"], rel=1e-12)
    # Spilled material is pile material again: the total is conserved.
    total = o["pile_mass"] + o["bucket_mass"] + o["dumped_mass"]
    assert total == pytest.approx(start["pile_mass"] + start["bucket_mass"], rel=1e-12)
    # Tilting back does not fill the bucket again.
    assert pile.move(-9.0, 0.5, steps=1, angle=math.pi)[-1]["bucket_mass"] == o["bucket_mass"]


def test_a_buried_bucket_spills_nothing_and_its_spill_lands_below_its_tip(full_pile):
    pile = full_pile()
    # Turned upside down in the ground: the soil around it holds the content.
    o = pile.move(-9.0, -0.3, steps=5, angle=math.pi - math.radians(150.0))[-1]
    assert o["bucket_mass"] == pytest.approx(DENSITY * CAPACITY, rel=1e-9)
    assert o["spilled_mass"] == 0.0
    before = pile.profile()
    o = pile.move(-9.0, 0.8, steps=40, angle=math.pi - math.radians(150.0))[-1]
    assert o["bucket_mass"] == 0.0 and o["spilled_mass"] == pytest.approx(DENSITY * CAPACITY)
    # The material is back in the trench under the tip (y = -9 m), within slumping's reach.
    centres = pile.p["y_min"] + (np.arange(pile.n_cells) + 0.5) * pile.dy
    gained = (pile.profile() - before) * pile.dy * pile.p["slice_width"] * DENSITY
    near = np.abs(centres + 9.0) < 1.0
    assert gained.sum() == pytest.approx(DENSITY * CAPACITY, rel=1e-9)
    assert gained[near].sum() == pytest.approx(DENSITY * CAPACITY, rel=1e-9)
