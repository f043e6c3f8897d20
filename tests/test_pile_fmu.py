"""Physics of the Pile FMU, run through the built FMU with fmpy.

References: conservation of mass; exact geometry of straight cuts; the angle of repose;
Rankine's passive earth pressure (closed form) and an independent Python implementation of the
McKyes (1985) wedge model with scipy's bounded minimiser; the analytic area of a triangular heap.
"""

from __future__ import annotations

import math
from contextlib import contextmanager

import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Slave
from scipy.optimize import minimize_scalar

import fmus

DEG = math.pi / 180
OUTPUTS = ("bucket_mass", "F_y", "F_z", "removed_volume", "dumped_mass", "pile_mass",
           "surface_z_at_tip", "cut_depth", "spilled_mass")

RELAX_TOLERANCE_M = 1e-5  # PROFILE_RELAX_TOLERANCE of fmus/shared/pile/profile.h


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    path = fmus.build("Pile")
    description = read_model_description(str(path))
    unzip = extract(str(path), unzipdir=str(tmp_path_factory.mktemp("pile")))
    return description, unzip


class Pile:
    """One Pile instance whose bucket tip is driven along straight moves."""

    def __init__(self, description, unzip: str, tip: tuple[float, float], **parameters):
        self.vr = {v.name: v.valueReference for v in description.modelVariables}
        self.p = {v.name: float(v.start) for v in description.modelVariables
                  if v.causality == "parameter"}
        self.p.update(parameters)
        self.n_cells = int(next(v.start for v in description.modelVariables
                                if v.name == "n_cells"))
        self.fmu = FMU2Slave(guid=description.guid, unzipDirectory=unzip,
                             modelIdentifier="Pile", instanceName="pile")
        self.fmu.instantiate()
        self.fmu.setupExperiment(startTime=0.0)
        self.fmu.enterInitializationMode()
        integers = {v.name for v in description.modelVariables if v.type == "Integer"}
        for name, value in {**parameters, "tip_y": tip[0], "tip_z": tip[1]}.items():
            if name in integers:
                self.fmu.setInteger([self.vr[name]], [int(value)])
            else:
                self.fmu.setReal([self.vr[name]], [value])
        self.fmu.exitInitializationMode()
        self.time, self.tip = 0.0, tip
        self.dy = (self.p["y_max"] - self.p["y_min"]) / self.n_cells

    def move(self, y: float, z: float, steps: int, dt: float = 0.01, angle: float = 90 * DEG,
             dump: float = 0.0) -> list[dict[str, float]]:
        """Moves the tip linearly to (y, z) m in `steps` steps of dt s; outputs after each."""
        (y0, z0), history = self.tip, []
        inputs = [self.vr[n] for n in ("tip_y", "tip_z", "bucket_angle", "dump")]
        for k in range(1, steps + 1):
            f = k / steps
            self.fmu.setReal(inputs, [y0 + f * (y - y0), z0 + f * (z - z0), angle, dump])
            self.fmu.doStep(self.time, dt)
            self.time += dt
            history.append(self.outputs())
        self.tip = (y, z)
        return history

    def outputs(self) -> dict[str, float]:
        return dict(zip(OUTPUTS, self.fmu.getReal([self.vr[n] for n in OUTPUTS]), strict=True))

    def profile(self) -> np.ndarray:
        """Cell heights h[1..n] (m)."""
        return np.array(self.fmu.getReal([self.vr[f"h[{i}]"] for i in range(1, self.n_cells + 1)]))

    def max_slope(self) -> float:
        """Steepest slope between neighbouring cells (rad)."""
        return math.atan(np.max(np.abs(np.diff(self.profile()))) / self.dy)

    def free(self) -> None:
        self.fmu.terminate()
        self.fmu.freeInstance()


@pytest.fixture
def make_pile(built):
    made: list[Pile] = []

    def make(tip=(-10.0, 0.5), **parameters) -> Pile:
        made.append(Pile(*built, tip, **parameters))
        return made[-1]

    yield make
    for pile in made:
        pile.free()


def test_mass_is_conserved_on_a_random_dig(make_pile):
    pile = make_pile(tip=(-9.0, 0.5))
    m0 = pile.outputs()["pile_mass"]
    density, capacity = pile.p["density"], pile.p["capacity"]
    rng = np.random.default_rng(20201)
    y, z, worst = -9.0, 0.5, 0.0
    for _ in range(150):  # moves of up to 0.6 m, in and out of the ground and off the grid
        y = float(np.clip(y + rng.uniform(-0.6, 0.6), -13.5, -1.5))
        z = float(np.clip(z + rng.uniform(-0.4, 0.35), -1.8, 0.6))
        dump = 1.0 if rng.random() < 0.1 else 0.0
        for o in pile.move(y, z, steps=int(rng.integers(1, 6)), dump=dump):
            total = o["pile_mass"] + o["bucket_mass"] + o["dumped_mass"]
            worst = max(worst, abs(total - m0) / m0)
            assert o["bucket_mass"] <= density * capacity * (1 + 1e-12)
            # What was cut is in the bucket, dumped, or spilled back onto the pile.
            assert o["removed_volume"] * density == pytest.approx(
                o["bucket_mass"] + o["dumped_mass"] + o["spilled_mass"], rel=1e-9, abs=1e-9)
    assert worst <= 1e-9
    assert pile.outputs()["dumped_mass"] > 2 * density * capacity  # the walk dug and dumped


@pytest.mark.parametrize(("y_start", "length", "depth"), [
    (-10.013, 1.537, 0.2),  # starts and ends inside cells
    (-9.0, 0.4, 0.05),  # starts on a cell edge
    (-5.02, -2.211, 0.3),  # digging towards -y
])
def test_horizontal_cut_removes_depth_times_length(make_pile, y_start, length, depth):
    pile = make_pile(tip=(y_start, 0.5), capacity=1.0)
    pile.move(y_start, -depth, steps=20)  # a vertical plunge sweeps no area
    assert pile.outputs()["bucket_mass"] == 0.0
    pile.move(y_start + length, -depth, steps=300)
    pile.move(y_start + length, 0.5, steps=20)
    o = pile.outputs()
    area = depth * abs(length)
    # The specification asks for 1 %; the sub-cell bookkeeping makes it exact to round-off.
    assert o["removed_volume"] == pytest.approx(pile.p["slice_width"] * area, rel=1e-9)
    assert o["bucket_mass"] == pytest.approx(pile.p["density"] * pile.p["slice_width"] * area,
                                             rel=1e-9)
    bucket = o["bucket_mass"]
    o = pile.move(*pile.tip, steps=1, dump=1.0)[-1]
    assert (o["bucket_mass"], o["dumped_mass"]) == (0.0, bucket)


def test_sloped_cut_removes_the_triangle_above_its_path(make_pile):
    pile = make_pile(tip=(-10.0, 0.0), capacity=1.0)
    pile.move(-8.77, -0.43, steps=200)  # entry from the surface down to 0.43 m at 1.23 m
    expected = pile.p["density"] * pile.p["slice_width"] * 0.5 * 1.23 * 0.43
    assert pile.outputs()["bucket_mass"] == pytest.approx(expected, rel=1e-9)


def test_the_buried_bucket_holds_the_face_and_slopes_relax_when_it_leaves(make_pile):
    repose = 35 * DEG
    pile = make_pile(tip=(-8.0, 0.5), capacity=1.0, repose_angle=repose)
    m0 = pile.outputs()["pile_mass"]
    pile.move(-8.0, -1.5, steps=40)  # deep vertical plunge
    pile.move(-7.7, -1.5, steps=60)  # short drag: a pit 0.3 m wide, 1.5 m deep
    assert pile.max_slope() > 80 * DEG  # the face in front of the buried bucket stands
    pile.move(-7.7, 1.0, steps=10)
    assert pile.max_slope() <= repose + 1 * DEG
    h = pile.profile()
    assert h.min() > -1.0  # the walls slumped into the pit, 6 cells wide,
    assert np.count_nonzero(h < -1e-6) > 30  # and the crater spread out around it
    o = pile.outputs()
    assert o["pile_mass"] + o["bucket_mass"] == pytest.approx(m0, rel=1e-12)


@pytest.mark.parametrize("repose_deg", [25.0, 35.0])
def test_trench_walls_relax_to_the_repose_angle(make_pile, repose_deg):
    repose = repose_deg * DEG
    pile = make_pile(tip=(-11.0, 0.5), repose_angle=repose)
    pile.move(-11.0, -1.0, steps=20)
    pile.move(-7.0, -1.0, steps=200, dump=1.0)  # 4 m trench, bucket emptied every step
    pile.move(-7.0, 1.0, steps=10)
    assert pile.max_slope() <= repose + 1 * DEG
    h = pile.profile()
    y = pile.p["y_min"] + (np.arange(pile.n_cells) + 0.5) * pile.dy
    # Far from the trench the ground is untouched; the trench floor is still cut.
    assert np.all(h[(y < pile.p["y_min"] + 0.3) | (y > -3.0)] == 0.0)
    assert h.min() == pytest.approx(-1.0)


def test_capacity_caps_the_bucket_and_the_rest_stays(make_pile):
    pile = make_pile(tip=(-12.0, 0.5))
    density, width, capacity = pile.p["density"], pile.p["slice_width"], pile.p["capacity"]
    depth = 0.5
    pile.move(-12.0, -depth, steps=20)
    history = pile.move(-7.0, -depth, steps=250)  # 2.5 m^2 of cut, far beyond capacity
    assert max(o["bucket_mass"] for o in history) <= density * capacity * (1 + 1e-12)
    o = history[-1]
    assert o["bucket_mass"] == pytest.approx(density * capacity, rel=1e-9)
    assert o["removed_volume"] == pytest.approx(capacity, rel=1e-9)
    # Where the bucket was already full it passed through the ground without cutting.
    filled_at = -12.0 + capacity / (width * depth)
    y = pile.p["y_min"] + (np.arange(pile.n_cells) + 0.5) * pile.dy
    beyond = (y > filled_at + depth / math.tan(pile.p["repose_angle"]) + 0.1) & (y < -7.0)
    assert beyond.sum() > 40 and np.all(pile.profile()[beyond] == 0.0)


def mckyes_force(beta, depth, gamma, c, ca, q, phi, delta):
    """Independent McKyes (1985) wedge model, rho minimised with scipy: (draft, normal force)
    per unit width (N/m); the normal force is positive away from the soil."""
    def blade(rho):
        denominator = math.cos(beta + delta) + math.sin(beta + delta) / math.tan(rho + phi)
        n_gamma = (1 / math.tan(beta) + 1 / math.tan(rho)) / (2 * denominator)
        n_c = (1 + 1 / (math.tan(rho) * math.tan(rho + phi))) / denominator
        n_ca = (1 - 1 / (math.tan(beta) * math.tan(rho + phi))) / denominator
        n_q = (1 / math.tan(beta) + 1 / math.tan(rho)) / denominator
        return gamma * depth**2 * n_gamma + depth * (c * n_c + ca * n_ca + q * n_q)

    upper = math.pi - beta - delta - phi
    best = minimize_scalar(blade, bounds=(1e-6, upper - 1e-6), method="bounded",
                           options={"xatol": 1e-12})
    p = blade(best.x)
    # Vector sum on the blade: P at delta from the face normal, adhesion c_a d / sin(beta)
    # along the face (up from the tip).
    face, normal = np.array([-math.cos(beta), math.sin(beta)]), np.array([math.sin(beta),
                                                                          math.cos(beta)])
    force = p * (-normal * math.cos(delta) + face * math.sin(delta)) + ca * depth / math.sin(
        beta) * face
    return -force[0], force[1]


def bearing_factors(phi):
    """Prandtl-Reissner N_q, N_c and Vesic's N_gamma."""
    n_q = math.exp(math.pi * math.tan(phi)) * math.tan(math.pi / 4 + phi / 2) ** 2
    n_c = (n_q - 1) / math.tan(phi) if phi > 0 else math.pi + 2
    return n_q, n_c, 2 * (n_q + 1) * math.tan(phi)


def test_bearing_factors_match_the_textbook_table():
    # Das, Principles of Foundation Engineering, Table 3.3 (phi = 0, 20, 30, 40 deg).
    table = {0: (1.00, 5.14, 0.00), 20: (6.40, 14.83, 5.39), 30: (18.40, 30.14, 22.40),
             40: (64.20, 75.31, 109.41)}
    for phi, expected in table.items():
        assert bearing_factors(phi * DEG) == pytest.approx(expected, abs=0.01)


def drag(pile, y_to, z, steps, angle):
    """The last outputs of a straight move (the resistance fully mobilised by then)."""
    return pile.move(y_to, z, steps=steps, angle=angle)[-1]


def test_force_matches_rankine_passive_pressure_and_grows_with_depth(make_pile):
    # Smooth vertical blade, no adhesion: McKyes reduces to Rankine's passive earth pressure.
    soil = {"cohesion": 2000.0, "adhesion": 0.0, "surcharge": 500.0,
            "friction_angle": 30 * DEG, "tool_friction_angle": 0.0}
    magnitudes = []
    for depth in (0.05, 0.2, 0.5, 1.0):
        pile = make_pile(tip=(-10.0, 0.5), capacity=1.0, **soil)
        pile.move(-10.0, -depth, steps=10)
        o = drag(pile, -10.0 + 1.0, -depth, 100, 90 * DEG)
        kp = (1 + math.sin(30 * DEG)) / (1 - math.sin(30 * DEG))
        gamma = pile.p["density"] * pile.p["gravity"]
        rankine = pile.p["bucket_width"] * (0.5 * gamma * depth**2 * kp
                                            + 2 * 2000.0 * depth * math.sqrt(kp)
                                            + 500.0 * depth * kp)
        assert o["cut_depth"] == pytest.approx(depth, rel=1e-12)
        # The penetration of the descent has unloaded over 1 m of travel (e^-25).
        assert o["F_z"] == pytest.approx(0.0, abs=1e-6 * rankine)
        assert -o["F_y"] == pytest.approx(rankine, rel=1e-7)
        magnitudes.append(-o["F_y"])
    assert all(np.diff(magnitudes) > 0)


@pytest.mark.parametrize(("direction", "angle_deg", "rake_deg"), [
    (+1, 120.0, 60.0), (+1, 150.0, 30.0), (-1, 60.0, 60.0), (-1, 90.0, 90.0),
    (+1, 45.0, 90.0),  # a face leaning forward (135 deg) cuts as one normal to the surface
    (-1, 150.0, 90.0),  # the bucket's back leading (150 deg): the same dead-wedge face
])
def test_force_matches_an_independent_mckyes_implementation(make_pile, direction, angle_deg,
                                                            rake_deg):
    soil = {"cohesion": 3000.0, "adhesion": 1500.0, "surcharge": 800.0,
            "friction_angle": 32 * DEG, "tool_friction_angle": 15 * DEG}
    depth = 0.35
    pile = make_pile(tip=(-9.0, 0.5), capacity=1.0, **soil)
    pile.move(-9.0, -depth, steps=10, angle=angle_deg * DEG)
    o = drag(pile, -9.0 + direction * 1.0, -depth, 100, angle_deg * DEG)
    draft, normal = mckyes_force(rake_deg * DEG, depth, pile.p["density"] * pile.p["gravity"],
                                 3000.0, 1500.0, 800.0, 32 * DEG, 15 * DEG)
    width = pile.p["bucket_width"]
    assert o["F_y"] == pytest.approx(-direction * width * draft, rel=1e-7)
    assert o["F_z"] == pytest.approx(width * normal, rel=1e-6)


def test_force_is_evaluated_in_the_frame_of_an_inclined_surface(make_pile):
    # Drag parallel to a heap's 20 deg flank, 0.3 m below it vertically: the earthmoving
    # equation sees the depth normal to the flank and the rake to it, and the force lies along
    # the flank (draft) and normal to it.
    soil = {"cohesion": 3000.0, "adhesion": 1500.0, "surcharge": 0.0,
            "friction_angle": 32 * DEG, "tool_friction_angle": 15 * DEG}
    slope, vertical, rake = 20 * DEG, 0.3, 70 * DEG
    height, half_width, crest = 2.0, 2.0 / math.tan(slope), -6.0
    pile = make_pile(tip=(-11.0, 3.0), capacity=1.0, heap_height=height, heap_center_y=crest,
                     heap_half_width=half_width, repose_angle=35 * DEG, **soil)
    def flank(y):
        return height * (1 - (crest - y) / half_width)
    angle = math.pi - rake + slope  # tip-to-pin line at `rake` to the flank behind the edge
    y0, y1 = crest - 0.8 * half_width, crest - 0.3 * half_width
    pile.move(y0, flank(y0) - vertical, steps=20, angle=angle)
    o = drag(pile, y1, flank(y1) - vertical, 200, angle)
    depth = vertical * math.cos(slope)
    assert o["cut_depth"] == pytest.approx(depth, rel=1e-9)
    draft, normal = mckyes_force(rake, depth, pile.p["density"] * pile.p["gravity"], 3000.0,
                                 1500.0, 0.0, 32 * DEG, 15 * DEG)
    t, n = np.array([math.cos(slope), math.sin(slope)]), np.array([-math.sin(slope),
                                                                   math.cos(slope)])
    force = np.array([o["F_y"], o["F_z"]])
    width = pile.p["bucket_width"]
    assert force @ t == pytest.approx(-width * draft, rel=1e-6)
    assert force @ n == pytest.approx(width * normal, rel=1e-6)


def test_penetration_meets_the_bearing_capacity_of_the_edge(make_pile):
    soil = {"cohesion": 2000.0, "adhesion": 1000.0, "surcharge": 300.0,
            "friction_angle": 30 * DEG, "tool_friction_angle": 20 * DEG}
    pile = make_pile(tip=(-9.0, 0.5), capacity=1.0, **soil)
    o = pile.move(-9.0, -0.6, steps=110)[-1]  # straight down: nothing is cut
    assert o["bucket_mass"] == 0.0
    n_q, n_c, n_gamma = bearing_factors(30 * DEG)
    gamma, b = pile.p["density"] * pile.p["gravity"], pile.p["edge_thickness"]
    q_ult = 2000.0 * n_c + (gamma * 0.6 + 300.0) * n_q + 0.5 * gamma * b * n_gamma
    assert o["F_y"] == pytest.approx(0.0, abs=1e-9)
    assert o["F_z"] == pytest.approx(q_ult * b * pile.p["bucket_width"], rel=1e-9)


def test_a_vertical_lift_meets_only_the_wall_friction(make_pile):
    # The review's case: a pure vertical lift at 0.8 m depth with nothing cut. The material
    # above the edge rises in the bucket; the soil outside holds it back by the at-rest
    # pressure's friction and the adhesion on the face (Jaky: K0 = 1 - sin phi).
    pile = make_pile(tip=(-9.0, 0.5))
    pile.move(-9.0, -0.9, steps=140)
    o = pile.move(-9.0, -0.8, steps=20)[-1]  # 0.1 m up: the spring has gone through to lift
    p = pile.p
    gamma, k0 = p["density"] * p["gravity"], 1 - math.sin(p["friction_angle"])
    lift = p["bucket_width"] * (p["adhesion"] * 0.8 + 0.5 * k0 * gamma * 0.8**2
                                * math.tan(p["tool_friction_angle"]))
    assert o["bucket_mass"] == 0.0 and o["F_y"] == pytest.approx(0.0, abs=1e-9)
    assert o["F_z"] == pytest.approx(-lift, rel=1e-9)
    assert lift < 2e3  # N, on the 1.2 m edge (the old wedge at 120 deg rake: 830 kN there)


def test_resistance_is_mobilised_over_the_mobilisation_length_and_unloads_elastically(
        make_pile):
    pile = make_pile(tip=(-10.0, 0.5), capacity=1.0)
    pile.move(-10.0, -0.3, steps=10)
    full = -drag(pile, -9.0, -0.3, 100, 90 * DEG)["F_y"]  # fully mobilised
    delta = pile.p["mobilization_length"]
    pile.move(-9.0 - 0.25 * delta, -0.3, steps=1)  # back by delta/4: 3/4 left
    o = pile.outputs()
    assert -o["F_y"] == pytest.approx(0.75 * full, rel=1e-9)
    pile.move(-9.0 - 2 * delta, -0.3, steps=1)  # back beyond delta: unloaded, nothing ahead
    assert pile.outputs()["F_y"] == pytest.approx(0.0, abs=1e-9)


def test_the_soil_is_passive_under_any_back_and_forth(make_pile):
    # Work the soil does on the bucket, trapezoidal over each move (exact for the
    # elastic-plastic element at constant depth): never positive, to round-off.
    pile = make_pile(tip=(-10.0, 0.5), capacity=1.0)
    pile.move(-10.0, -0.3, steps=10)
    rng = np.random.default_rng(7)
    y, force, work, worst = -10.0, np.array([0.0, 0.0]), 0.0, 0.0
    for _ in range(400):
        step = rng.uniform(-0.6, 1.0) * pile.p["mobilization_length"]
        o = pile.move(y + step, -0.3, steps=1)[-1]
        new = np.array([o["F_y"], o["F_z"]])
        work += 0.5 * (force + new) @ np.array([step, 0.0])
        worst = max(worst, work)
        force, y = new, y + step
    assert worst <= 1e-9 * abs(work)
    assert work < 0.0


def test_force_vanishes_out_of_the_ground_and_a_tiny_step_does_not_crash(make_pile):
    pile = make_pile(tip=(-10.0, 0.3))
    for o in pile.move(-9.0, 0.3, steps=20):  # moving above the surface
        assert (o["F_y"], o["F_z"], o["cut_depth"]) == (0.0, 0.0, 0.0)
    pile.move(-9.0, -0.4, steps=10)
    # The review's crash: a 1e-310 s step while the tip moves (the force no longer divides by
    # the step).
    o = pile.move(-8.9, -0.45, steps=3, dt=1e-310)[-1]
    assert all(math.isfinite(value) for value in o.values())


def triangle_heap_cell_means(y_edges, crest_y, half_width, height):
    """Exact cell means of height * max(0, 1 - |y - crest_y| / half_width)."""
    def integral(y):  # of the heap from -inf to y
        x = np.clip((y - crest_y) / half_width, -1.0, 1.0)
        return half_width * height * np.where(x <= 0, 0.5 * (x + 1) ** 2, 1 - 0.5 * (1 - x) ** 2)
    return np.diff(integral(y_edges)) / np.diff(y_edges)


@pytest.mark.parametrize(("height", "half_width"), [(0.8, 1.5), (2.0, 1.0)])
def test_heap_mass_is_the_integral_of_its_profile(make_pile, height, half_width):
    pile = make_pile(heap_height=height, heap_center_y=-8.27, heap_half_width=half_width)
    p = pile.p
    base = (p["z_surface0"] - p["z_floor"]) * (p["y_max"] - p["y_min"])
    expected = p["density"] * p["slice_width"] * (base + height * half_width)
    assert pile.outputs()["pile_mass"] == pytest.approx(expected, rel=1e-12)
    # A steep heap settles at once: no step steeper than repose by more than the relaxation's
    # tolerance (fmus/shared/pile/profile.h: 1e-5 m per cell).
    steepest = math.atan(math.tan(p["repose_angle"]) + RELAX_TOLERANCE_M / pile.dy)
    assert pile.max_slope() <= steepest
    if math.atan(height / half_width) < p["repose_angle"]:
        edges = p["y_min"] + np.arange(pile.n_cells + 1) * pile.dy
        means = triangle_heap_cell_means(edges, -8.27, half_width, height)
        assert pile.profile() == pytest.approx(p["z_surface0"] + means, abs=1e-12)


@pytest.mark.parametrize("slope_deg", [-20.0, 12.0])
def test_inclined_ground_is_the_line_through_the_crest_and_its_mass_the_trapezoid(make_pile,
                                                                                  slope_deg):
    """An inclined initial ground (rising toward +y for a positive slope) through z_surface0 at
    heap_center_y, below the repose angle so nothing slumps: its cells are the line's values at
    their centres, its mass the trapezoid's area times density and slice width."""
    crest = -8.0
    pile = make_pile(ground_slope=slope_deg * DEG, heap_center_y=crest, heap_height=0.0)
    p = pile.p
    grade = math.tan(slope_deg * DEG)
    centres = p["y_min"] + (np.arange(pile.n_cells) + 0.5) * pile.dy
    assert pile.profile() == pytest.approx(p["z_surface0"] + grade * (centres - crest), abs=1e-12)
    mid = 0.5 * (p["y_min"] + p["y_max"])
    height = p["z_surface0"] + grade * (mid - crest) - p["z_floor"]  # trapezoid's mean height
    expected = p["density"] * p["slice_width"] * height * (p["y_max"] - p["y_min"])
    assert pile.outputs()["pile_mass"] == pytest.approx(expected, rel=1e-12)
    assert pile.max_slope() == pytest.approx(abs(slope_deg) * DEG, abs=1e-9)


def test_surface_at_tip_interpolates_between_cell_centres(make_pile):
    pile = make_pile(tip=(-9.0, 3.0), heap_height=0.8, heap_center_y=-9.0, heap_half_width=1.5)
    h = pile.profile()
    i = int((-9.3 - pile.p["y_min"]) // pile.dy)
    centre = pile.p["y_min"] + (i + 0.5) * pile.dy
    for f in (0.0, 0.3, 0.75):
        o = pile.move(centre + f * pile.dy, 3.0, steps=1)[-1]
        assert o["surface_z_at_tip"] == pytest.approx((1 - f) * h[i] + f * h[i + 1], abs=1e-12)
    o = pile.move(-20.0, 3.0, steps=1)[-1]  # clamped beyond the grid
    assert o["surface_z_at_tip"] == h[0]


@contextmanager
def _initializing(built):
    """A Pile instance in initialization mode and its value references by name; freed after."""
    description, unzip = built
    fmu = FMU2Slave(guid=description.guid, unzipDirectory=unzip, modelIdentifier="Pile",
                    instanceName="bad")
    fmu.instantiate()
    try:
        fmu.setupExperiment(startTime=0.0)
        fmu.enterInitializationMode()
        yield fmu, {v.name: v.valueReference for v in description.modelVariables}
    finally:
        fmu.freeInstance()


@pytest.mark.parametrize(("name", "value"), [
    ("y_max", -14.0), ("repose_angle", 0.0), ("tool_friction_angle", 40 * DEG),
    ("capacity", -0.1), ("heap_half_width", 0.0),
    ("ground_slope", 60 * DEG), ("ground_slope", -0.62)])
def test_bad_parameters_fail_initialization_naming_the_parameter(built, capsys, name, value):
    with _initializing(built) as (fmu, vr):
        fmu.setReal([vr[name]], [value])
        with pytest.raises(FMICallException):
            fmu.exitInitializationMode()
        assert name in capsys.readouterr().out


@pytest.mark.parametrize("value", [0.0, 99.0, 10001.0, 1.6e12, float("nan")])
def test_a_density_outside_what_soil_and_rock_weigh_is_refused_naming_it(built, capsys, value):
    """Bulk densities run from about 300 kg/m3 (peat) to 5000 kg/m3 (iron ore): the Pile takes
    [100, 10000] (its declared min and max, checked when set) and refuses the rest."""
    with _initializing(built) as (fmu, vr):
        with pytest.raises(FMICallException):
            fmu.setReal([vr["density"]], [value])
        assert "density" in capsys.readouterr().out


@pytest.mark.parametrize(("angle_deg", "share"), [
    (135.0, 1.0),  # rake 45 deg: the edge leads, everything enters
    (90.0, 1.0),  # rake 90 deg: a face normal to the drag still fills
    (45.0, math.sin(135 * DEG)),  # rake 135 deg: the face leans forward and pushes part aside
    (0.0, 0.0),  # rake 180 deg: dragged back-first, the bucket collects nothing
])
def test_filling_depends_on_the_buckets_orientation(make_pile, angle_deg, share):
    pile = make_pile(tip=(-10.0, 0.5), capacity=1.0)
    m0 = pile.outputs()["pile_mass"]
    pile.move(-10.0, -0.2, steps=10, angle=angle_deg * DEG)
    o = pile.move(-9.0, -0.2, steps=100, angle=angle_deg * DEG)[-1]
    assert o["pile_mass"] + o["bucket_mass"] == pytest.approx(m0, rel=1e-12)
    full_cut = pile.p["density"] * pile.p["slice_width"] * 0.2 * 1.0
    assert o["bucket_mass"] == pytest.approx(share * full_cut, rel=1e-6, abs=1e-9)


def test_a_full_bucket_pushes_a_surcharge_of_its_spoil(make_pile):
    soil = {"cohesion": 3000.0, "adhesion": 1500.0, "surcharge": 800.0,
            "friction_angle": 32 * DEG, "tool_friction_angle": 15 * DEG}
    depth = 0.3
    pile = make_pile(tip=(-10.0, 0.5), capacity=0.002, **soil)  # full after 0.42 m
    pile.move(-10.0, -depth, steps=10)
    o = drag(pile, -9.0, -depth, 100, 90 * DEG)
    assert o["bucket_mass"] == pytest.approx(pile.p["density"] * 0.002, rel=1e-9)
    gamma = pile.p["density"] * pile.p["gravity"]
    draft, _ = mckyes_force(90 * DEG, depth, gamma, 3000.0, 1500.0, 800.0 + gamma * depth,
                            32 * DEG, 15 * DEG)
    assert -o["F_y"] == pytest.approx(pile.p["bucket_width"] * draft, rel=1e-7)
