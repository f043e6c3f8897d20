"""PileZelenin (fmus/PileZelenin): the Pile's mechanics with Zelenin's cutting resistance
H = g0 C (100 d)^1.35 (1 + 2.6 B)(1 + 0.0075 alpha_deg) z on the whole bucket edge B, its
normal force normal_ratio * H, and the DorNII penetration pressure 0.981 C MPa on the edge.
Tested against hand-computed values, its trends (depth exponent, width, cutting angle), its
valid range, and mass conservation / identical mechanics with the Pile."""

import math

import numpy as np
import pytest
from fmpy import simulate_fmu
from fmpy.fmi1 import FMICallException
from fmpy.validation import validate_fmu

import fmus
from fmus.runs import run_fmpy
from plant_models.model_spec import PILE_INPUTS, PILE_OUTPUTS

SPEED = 0.5  # m/s, horizontal drag towards the machine (+y)
OUTPUTS = ["F_y", "F_z", "cut_depth", "bucket_mass", "pile_mass", "dumped_mass"]


@pytest.fixture(scope="module")
def fmu():
    return fmus.build("PileZelenin")


def drag(fmu, depth, rake_deg=90.0, **parameters):
    """Drag the tip horizontally at `depth` (m) for 0.4 s; return the draft H (N) and the depth
    the model reports at the end. Rake = pi - bucket_angle for a move along +y."""
    n, step = 400, 1e-3
    y = -10.5 + SPEED * step * np.arange(1, n + 1)
    angle = math.pi - math.radians(rake_deg)
    inputs = {"tip_y": y, "tip_z": np.full(n, -depth), "bucket_angle": np.full(n, angle),
              "dump": np.zeros(n)}
    start = {"tip_y": -10.5, "tip_z": -depth, "bucket_angle": angle, **parameters}
    r = run_fmpy(fmu, inputs, OUTPUTS, step, start)
    draft = -r["F_y"][-1]  # fully mobilised after 0.2 m
    # Horizontal motion: the normal force is the law's ratio of the draft, upwards.
    ratio = parameters.get("normal_ratio", 0.2)
    assert r["F_z"][-1] == pytest.approx(ratio * draft, rel=1e-12, abs=1e-9)
    return draft, r["cut_depth"][-1]


def test_valid_fmu_with_the_pile_ports(fmu):
    assert validate_fmu(str(fmu)) == []
    from fmpy import read_model_description
    names = {v.name for v in read_model_description(str(fmu)).modelVariables}
    assert set(PILE_INPUTS) | set(PILE_OUTPUTS) <= names


def test_draft_equals_the_hand_computed_zelenin_value(fmu):
    # C = 2, d = 20 cm, B = 1.2 m, alpha = 90 deg, z = 1:
    # P = 2 * 20^1.35 * (1 + 2.6*1.2) * (1 + 0.0075*90) = 2 * 57.0677 * 4.12 * 1.675
    #   = 787.649 kgf = 7724.19 N on the whole edge (the force acts on the bucket, not on the
    #   material slice).
    draft, depth = drag(fmu, 0.2)
    assert depth == pytest.approx(0.2, abs=1e-12)
    assert draft == pytest.approx(7724.19, rel=1e-6)
    assert drag(fmu, 0.2, normal_ratio=-0.3)[0] == pytest.approx(draft, rel=1e-12)


def test_penetration_meets_the_dornii_pressure_on_the_edge(fmu):
    # C blows of 2.5 kg falling 0.4 m drive a 1 cm^2 rod 10 cm: 0.980665 C MPa; on the
    # default 4 cm x 1.2 m edge with C = 2: 94.14 kN, fully mobilised 0.2 m down.
    n, step = 300, 1e-3
    z = 0.1 - 0.5 * np.arange(1, n + 1) / n
    inputs = {"tip_y": np.full(n, -9.0), "tip_z": z, "bucket_angle": np.full(n, 1.2),
              "dump": np.zeros(n)}
    r = run_fmpy(fmu, inputs, OUTPUTS, step, {"tip_y": -9.0, "tip_z": 0.1})
    assert r["bucket_mass"][-1] == 0.0  # a vertical push cuts nothing
    assert r["F_y"][-1] == pytest.approx(0.0, abs=1e-9)
    assert r["F_z"][-1] == pytest.approx(0.980665e6 * 2 * 0.04 * 1.2, rel=1e-12)


def test_depth_exponent_is_1_35(fmu):
    (h1, d1), (h2, d2) = drag(fmu, 0.1), drag(fmu, 0.3)
    assert math.log(h2 / h1) / math.log(d2 / d1) == pytest.approx(1.35, rel=1e-9)


def test_width_term_is_not_proportional(fmu):
    # 1 + 2.6 B, not B: half the width takes 62 % of the force (more per metre).
    wide, _ = drag(fmu, 0.2, bucket_width=1.2)
    narrow, _ = drag(fmu, 0.2, bucket_width=0.6)
    assert narrow / wide == pytest.approx((1 + 2.6 * 0.6) / (1 + 2.6 * 1.2), rel=1e-9)


def test_cutting_angle_term_and_its_clamp(fmu):
    at_90, _ = drag(fmu, 0.2, 90.0)
    at_45, _ = drag(fmu, 0.2, 45.0)
    assert at_45 / at_90 == pytest.approx((1 + 0.0075 * 45) / (1 + 0.0075 * 90), rel=1e-9)
    # Outside [20, 90] deg the fit was not measured: the nearest end is used (the shared
    # mechanics already take a face beyond 90 deg as 90 deg).
    assert drag(fmu, 0.2, 10.0)[0] == pytest.approx(drag(fmu, 0.2, 20.0)[0], rel=1e-12)
    assert drag(fmu, 0.2, 120.0)[0] == pytest.approx(at_90, rel=1e-12)


def test_strength_and_cutting_factor_scale_linearly(fmu):
    base, _ = drag(fmu, 0.2)
    assert drag(fmu, 0.2, blows=8.0)[0] == pytest.approx(4 * base, rel=1e-12)
    assert drag(fmu, 0.2, cutting_factor=1.5)[0] == pytest.approx(1.5 * base, rel=1e-12)


@pytest.mark.parametrize("parameters", [{"blows": 0.5}, {"blows": 40.0}, {"bucket_width": 0.0},
                                        {"normal_ratio": 1.5}, {"edge_thickness": 0.0},
                                        {"cutting_factor": 0.0}])
def test_outside_the_valid_range_initialization_fails(fmu, parameters):
    # Outside the table's min/max (blows) the set is refused already; else initialization fails.
    with pytest.raises(FMICallException, match="fmi2SetReal|fmi2ExitInitializationMode"):
        simulate_fmu(str(fmu), stop_time=0.01, start_values=parameters)


def paper_like_pass(n=2000):
    s = np.arange(1, n + 1) / n
    return {"tip_y": -10.0 + 2.5 * s, "tip_z": 0.5 - 1.3 * np.sin(np.pi * s),
            "bucket_angle": 2.3 + 0.8 * s, "dump": (s > 0.9).astype(float)}


def test_mass_is_conserved_and_the_mechanics_are_the_piles(fmu):
    inputs = paper_like_pass()
    start = {"tip_y": -10.0, "tip_z": 0.5, "bucket_angle": 2.3}
    names = OUTPUTS + ["removed_volume", "surface_z_at_tip", "spilled_mass"] + [
        f"h[{i}]" for i in (1, 80, 120)]
    ours = run_fmpy(fmu, inputs, names, 1e-3, start)
    pile = run_fmpy(fmus.build("Pile"), inputs, names, 1e-3, start)
    total = ours["pile_mass"] + ours["bucket_mass"] + ours["dumped_mass"]
    np.testing.assert_allclose(total, total[0], rtol=1e-12)
    assert ours["dumped_mass"][-1] > 1.0  # material was dug and dumped
    for name in names:  # the resistance law does not feed back into the shared mechanics
        if name not in ("F_y", "F_z"):
            assert np.array_equal(ours[name], pile[name]), name
    assert np.abs(ours["F_y"]).max() > 0 and not np.array_equal(ours["F_y"], pile["F_y"])
