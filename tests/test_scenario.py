"""TOML scenarios: every kind of mistake is one line naming the field; defaults, --set, round trip.

The expected values are the paper's (Vu & Tran 2020: section 3.2 for D0, m* and the 20 periods;
Table 1 for the limits; section 3.1 case 2 for k_T, k_J; section 2.3 for the rule's outputs).
"""

import json
import math
import shutil
from pathlib import Path

import numpy as np
import pytest

import fmus
from orchestrator.scenario import ScenarioError, load_scenario, scenario_from_dict
from orchestrator.scenario.overrides import parse_override
from planner.adaptation import AdaptationDefaults
from planner.digging_path import LAB_DEEPEST_POINT_M, PathShape
from planner.fuzzy import FuzzyRule

SCENARIOS = Path(__file__).resolve().parent.parent / "scenarios"
PAPER = SCENARIOS / "paper-2020.toml"


def _write(tmp_path: Path, text: str, name: str = "s.toml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


# (scenario text after `name = "s"`, --set items, the expected message after "s.toml: ")
MISTAKES = [
    ("[limits]\njerk_deg_s3 = [60, 60]", [], "limits.jerk_deg_s3: expected 3 numbers, got 2"),
    ("[limits]\njerk_deg_s3 = 60", [], "limits.jerk_deg_s3: expected 3 numbers, got 60"),
    ("[limits]\nvelocity_deg_s = [100, -1, 100]", [],
     "limits.velocity_deg_s: expected 3 numbers > 0, got [100.0, -1.0, 100.0]"),
    ("[limits]\njerk_deg_s3 = [60, 60, nan]", [],
     "limits.jerk_deg_s3: expected a finite number, got nan"),
    ("peroids = 5", [], "peroids: unknown key (known: name, description, seed, periods, "
     "target_mass_kg, machine, path, limits, trajectory, adaptation, plant, log)"),
    ("[trajectory]\nk_t = 0.1", [], "trajectory.k_t: unknown key (known: k_T, k_J)"),
    ('periods = "5"', [], "periods: expected an integer, got '5'"),
    ("periods = 5.0", [], "periods: expected an integer, got 5.0"),
    ("periods = 0", [], "periods: must be greater than or equal to 1, got 0"),
    ("seed = true", [], "seed: expected an integer, got True"),
    ('target_mass_kg = "30"', [], "target_mass_kg: expected a number, got '30'"),
    ("target_mass_kg = true", [], "target_mass_kg: expected a number, got True"),
    ("target_mass_kg = -30", [], "target_mass_kg: must be greater than 0, got -30.0"),
    ("target_mass_kg = inf", [], "target_mass_kg: expected a finite number, got inf"),
    ("limits = 5", [], "limits: expected a table, got 5"),
    ("[trajectory]\nk_T = 0", [], "trajectory.k_T: must be greater than 0, got 0.0"),
    ("[path]\nstart_tip_m = [1.0]", [], "path.start_tip_m: expected 2 numbers, got 1"),
    ("[path]\nentry_offset_m = -0.5", [],
     "path.entry_offset_m: must be greater than or equal to 0, got -0.5"),
    ('[machine]\npreset = "big"', [], "machine.preset: unknown preset 'big'; known: paper, lab"),
    ('[plant]\nkind = "lab"\n[plant.lab]\nstream_rate_hz = 0', [],
     "plant.lab.stream_rate_hz: must be greater than 0, got 0.0"),
    ('[plant]\nkind = "real"', [], "plant.kind: unknown plant kind 'real'; use \"sim\" or "
     "\"lab\""),
    ("[plant]\ncommunication_step_s = 0", [],
     "plant.communication_step_s: must be greater than 0, got 0.0"),
    ("[adaptation]\ncentres_kg = [-9, -6, -3, 0, 3, 6, 9]\ncentre_fractions = [0.1, 0.3, 0.6]",
     [],
     "adaptation: give either centre_fractions or centres_kg (exactly one)"),
    ("[adaptation]\ncentre_fractions = [0.3, 0.1, 0.6]", [],
     "adaptation.centre_fractions: expected 3 strictly increasing numbers, got [0.3, 0.1, 0.6]"),
    ("[adaptation]\ny_D0_m = -20.0", [],
     "adaptation: the path through D0 = (-20, -0.1) m is out of reach, also shifted by dy_0_m: "
     "entry via-point: bucket pin 19.304 m from the boom foot, beyond the arm's reach 8.880 m"),
    ("[plant.pile]\nfmu = \"Heap\"", [], "plant.pile.fmu: no such file 'Heap' and no model of "
     "that name (models: HydraulicCylinder, IdealActuator, Pile, PileZelenin)"),
    ("[plant.pile]\nfmu = \"missing/pile.fmu\"", [], "plant.pile.fmu: no such file "
     "'missing/pile.fmu' and no model of that name (models: HydraulicCylinder, IdealActuator, "
     "Pile, PileZelenin)"),
    ("[plant.pile.parameters]\ndensty = 1800", [],
     "plant.pile.parameters.densty: Pile has no parameter 'densty' "
     "(closest: density, density_seed, density_variation)"),
    ("[plant.pile.parameters]\ndensity = \"heavy\"", [],
     "plant.pile.parameters.density: expected a number or true/false, got 'heavy'"),
    ("[plant.pile.parameters]\ndensity = true", [],
     "plant.pile.parameters.density: Pile.density is a Real, got True"),
    ("[plant.boom.parameters]\nn_substeps = 2.5", [],
     "plant.boom.parameters.n_substeps: HydraulicCylinder.n_substeps is a Integer, got 2.5"),
    ("[plant.pile.parameters]\nbucket_mass = 3.0", [],
     "plant.pile.parameters.bucket_mass: parameter 'bucket_mass' has causality output in Pile; "
     "only parameters and inputs can be set"),
    ('[plant.pile.ports]\ntip_y = "tip_x"', [], "plant.pile.ports.tip_y: role 'tip_y' maps to "
     "variable 'tip_x', which Pile does not have"),
    ('[plant.stick.ports]\nx = "u"', [], "plant.stick.ports.x: role 'x' needs a Real output, but "
     "variable 'u' of HydraulicCylinder is a Real input"),
    ('[plant.bucket.ports]\nstroke = "x"', [], "plant.bucket.ports.stroke: port map names unknown "
     "role 'stroke'; cylinder roles: u, F_ext, mass_load, p_pump, p_LS, x, v, p_A, p_B, F, "
     "E_supply, E_throttling, x0, A_A, A_B"),
    ('[plant.boom.ports]\nx0 = "x"', [], "plant.boom.ports.x0: role 'x0' maps to variable 'x' "
     "has causality output in HydraulicCylinder; only parameters and inputs can be set"),
    ("", ["periods=five"], "periods: expected an integer, got 'five'"),
    ("", ["limits.jerk_deg_s3=[1, 2]"], "limits.jerk_deg_s3: expected 3 numbers, got 2"),
    ("", ["plant.pile.parameters.densty=1800"],
     "plant.pile.parameters.densty: Pile has no parameter 'densty' "
     "(closest: density, density_seed, density_variation)"),
    ("", ["periods"], "--set 'periods': expected KEY=VALUE, e.g. periods=5"),
    ("", ["=5"], "--set '=5': expected KEY=VALUE, e.g. periods=5"),
    ("", ["a..b=1"], "--set 'a..b=1': bad key 'a..b' (dotted names of letters, digits, _ and -)"),
    ("", ["name.first=x"],
     "name: is not a table, so --set 'name.first=x' cannot set a key inside it"),
]


@pytest.mark.parametrize(("text", "overrides", "expected"), MISTAKES,
                         ids=[m[2].split(":")[0] for m in MISTAKES])
def test_a_mistake_is_one_line_naming_the_field(tmp_path, text, overrides, expected):
    path = _write(tmp_path, f'name = "s"\n{text}\n')
    with pytest.raises(ScenarioError) as caught:
        load_scenario(path, overrides)
    assert str(caught.value) == f"s.toml: {expected}"
    assert "\n" not in str(caught.value)


def test_file_mistakes_name_the_file(tmp_path):
    with pytest.raises(ScenarioError, match=r"nothing\.toml: no such scenario file$"):
        load_scenario(tmp_path / "nothing.toml")
    broken = _write(tmp_path, "name = \n")
    with pytest.raises(ScenarioError, match=r"^s\.toml: not valid TOML: .*line 1"):
        load_scenario(broken)


def test_the_paper_scenario_says_what_the_paper_says():
    scenario = load_scenario(PAPER)
    assert scenario.name == "paper-2020"
    assert (scenario.periods, scenario.target_mass_kg) == (20, 30.0)  # section 3.2, Figure 9
    assert (scenario.adaptation.y_D0_m, scenario.adaptation.z_D0_m) == (-9.0, -0.1)
    np.testing.assert_allclose(np.degrees(scenario.limits_rad()),
                               [[100.0] * 3, [60.0] * 3, [60.0] * 3], rtol=1e-15)  # Table 1
    assert (scenario.trajectory.k_T, scenario.trajectory.k_J) == (0.1, 0.9)  # case 2
    assert scenario.fuzzy_rule().outputs_m == (-0.4, -0.25, -0.1, 0.0, 0.1, 0.25, 0.4)
    assert scenario.machine.preset == "paper"


def test_missing_values_take_the_presets_defaults(tmp_path):
    scenario = load_scenario(_write(tmp_path, ""))
    assert scenario.name == "s"  # the file's stem
    assert scenario.target_mass_kg == 30.0 and scenario.periods == 20
    assert scenario.adaptation_defaults() == AdaptationDefaults()
    assert scenario.fuzzy_rule() == FuzzyRule.paper(30.0)
    shape, preset = scenario.path_shape(), PathShape.preset("paper")
    for field in ("start_bucket_angle_rad", "entry_bucket_angle_rad", "closed_bucket_joint_rad"):
        assert getattr(shape, field) == pytest.approx(getattr(preset, field), abs=1e-12)
    assert shape.start_tip_m == preset.start_tip_m and shape.lift_tip_m == preset.lift_tip_m
    assert scenario.plant.pile.fmu == "Pile" and scenario.plant.boom.fmu == "HydraulicCylinder"


def test_the_lab_preset_scales_the_paper_defaults(tmp_path):
    scenario = load_scenario(_write(tmp_path, '[machine]\npreset = "lab"\n'))
    defaults = scenario.adaptation_defaults()
    assert (defaults.y_D0, defaults.z_D0) == pytest.approx(LAB_DEEPEST_POINT_M)
    assert scenario.path_shape().start_tip_m == pytest.approx(PathShape.preset("lab").start_tip_m)


def test_fuzzy_centres_in_kg_replace_the_fractions(tmp_path):
    text = "[adaptation]\ncentre_fractions = []\n"
    path = _write(tmp_path, text.replace("centre_fractions = []",
                                         "centres_kg = [-12, -6, -2, 0, 2, 6, 12]"))
    rule = load_scenario(path).fuzzy_rule()
    assert rule.centres_kg == (-12.0, -6.0, -2.0, 0.0, 2.0, 6.0, 12.0)
    assert rule(4.0) == pytest.approx((0.1 + 0.25) / 2)  # halfway between ps and pb


@pytest.mark.parametrize(("item", "key", "value"), [
    ("periods=5", ["periods"], 5),
    ("plant.load_cell_noise_kg=0.5", ["plant", "load_cell_noise_kg"], 0.5),
    ("plant.pile.parameters.density=1800", ["plant", "pile", "parameters", "density"], 1800),
    ("limits.jerk_deg_s3=[40, 50, 60]", ["limits", "jerk_deg_s3"], [40, 50, 60]),
    ("flag=true", ["flag"], True),
    ('name="my run"', ["name"], "my run"),
    ("machine.preset=lab", ["machine", "preset"], "lab"),  # not TOML: taken as a string
    ("description = two words ", ["description"], "two words"),
])
def test_set_values_are_read_as_toml(item, key, value):
    assert parse_override(item) == (key, value)


def test_set_is_applied_before_validation_in_order(tmp_path):
    path = _write(tmp_path, "periods = 20\n[limits]\njerk_deg_s3 = [60, 60]\n")
    scenario = load_scenario(path, ["limits.jerk_deg_s3=[60, 60, 60]", "periods=3",
                                    "periods=5", "plant.pile.parameters.density=1800"])
    assert scenario.periods == 5
    assert scenario.plant.pile.parameters["density"] == 1800
    assert scenario.plant.boom.parameters["bore"] > 0  # the preset's other values stay
    assert "periods = 20" in scenario.source_text  # the file as written


def test_the_resolved_scenario_round_trips_through_plain_data():
    scenario = load_scenario(PAPER, ["plant.load_cell_noise_kg=0.5", "seed=7"])
    data = json.loads(json.dumps(scenario.to_dict()))  # plain JSON-able data
    again = scenario_from_dict(data, source="metadata")
    assert again == scenario
    assert again.to_dict() == data
    assert set(data) == {"name", "description", "seed", "periods", "target_mass_kg", "machine",
                         "path", "limits", "trajectory", "adaptation", "plant", "log"}


def test_an_fmu_path_resolves_against_the_scenario_folder(tmp_path):
    shutil.copy(fmus.build("Pile"), tmp_path / "my_pile.fmu")
    (tmp_path / "sub").mkdir()
    path = _write(tmp_path / "sub", '[plant.pile]\nfmu = "../my_pile.fmu"\n'
                  "[plant.pile.parameters]\nslice_width = 0.02\n")
    scenario = load_scenario(path)
    pile = scenario.plant.pile
    assert Path(pile.fmu) == (tmp_path / "my_pile.fmu").resolve()
    # The preset gives the pile no parameters (the FMU's start values are its defaults).
    assert dict(pile.parameters) == {"slice_width": 0.02}
    assert scenario_from_dict(scenario.to_dict()) == scenario


def test_a_substitute_keeps_the_defaults_it_declares_and_refuses_given_ones_it_lacks(tmp_path):
    from orchestrator.scenario.fmu_paths import resolve_fmus

    shutil.copy(fmus.build("HydraulicCylinder"), tmp_path / "MyCylinder.fmu")
    plant = load_scenario(_write(tmp_path, "")).to_dict()["plant"]
    plant["boom"] = {"fmu": "MyCylinder.fmu", "ports": {},
                     "parameters": {**plant["boom"]["parameters"], "not_a_variable": 1.0,
                                    "mass": "heavy"}}
    kept = resolve_fmus(plant, "s.toml", tmp_path, {role: set() for role in plant
                                                     if role in ("boom", "stick", "bucket",
                                                                 "pile")})
    # Defaults the FMU does not declare, or of another type, are not its: dropped.
    assert "not_a_variable" not in kept["boom"]["parameters"]
    assert "mass" not in kept["boom"]["parameters"]
    assert kept["boom"]["parameters"]["bore"] == plant["boom"]["parameters"]["bore"]
    assert len(kept["boom"]["parameters"]) == len(plant["boom"]["parameters"]) - 2 > 10
    with pytest.raises(ScenarioError) as refused:
        resolve_fmus(plant, "s.toml", tmp_path, {"boom": {"not_a_variable"}, "stick": set(),
                                                  "bucket": set(), "pile": set()})
    assert str(refused.value).startswith("s.toml: plant.boom.parameters.not_a_variable: "
                                         "HydraulicCylinder has no parameter 'not_a_variable'")
    typo = _write(tmp_path, '[plant.boom]\nfmu = "MyCylinder.fmu"\n'
                  "[plant.boom.parameters]\nq_rate = 0.004\n", "typo.toml")
    with pytest.raises(ScenarioError, match=r"has no parameter 'q_rate' \(closest: q_rated"):
        load_scenario(typo)


def test_a_file_that_is_not_an_fmu_is_named(tmp_path):
    _write(tmp_path, "not a zip", "fake.fmu")
    path = _write(tmp_path, '[plant.boom]\nfmu = "fake.fmu"\n')
    with pytest.raises(ScenarioError, match=r"^s\.toml: plant\.boom\.fmu: not a readable FMU"):
        load_scenario(path)


def test_every_shipped_scenario_loads():
    for path in sorted(SCENARIOS.glob("*.toml")):
        scenario = load_scenario(path)
        assert scenario.name == path.stem
        assert math.isfinite(scenario.target_mass_kg)


def test_the_override_example_holds():
    import doctest

    import orchestrator.scenario.overrides

    assert doctest.testmod(orchestrator.scenario.overrides).failed == 0
