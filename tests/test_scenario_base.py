"""`base = "other.toml"`: a scenario that starts from another one."""

from pathlib import Path

import pytest

from orchestrator.scenario import ScenarioError, load_scenario

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "scenarios" / "paper-2020.toml"


def test_a_based_scenario_is_its_base_with_its_own_values_on_top(tmp_path):
    (tmp_path / "paper.toml").write_text(PAPER.read_text())
    child = tmp_path / "child.toml"
    child.write_text('base = "paper.toml"\nperiods = 3\n[plant.pile.parameters]\ndensity = 1800\n')
    based = load_scenario(child).to_dict()
    expected = load_scenario(PAPER, ["periods=3", "plant.pile.parameters.density=1800"]).to_dict()
    assert based["name"] == "child"  # never inherited
    assert {**based, "name": "paper-2020"} == expected


def test_the_shipped_substitution_scenarios_differ_from_the_paper_only_in_their_fmus():
    for name, roles, fmu in (("paper-2020-ideal-actuators", ("boom", "stick", "bucket"),
                              "IdealActuator"), ("paper-2020-zelenin", ("pile",), "PileZelenin")):
        data = load_scenario(ROOT / "scenarios" / f"{name}.toml").to_dict()
        paper = load_scenario(PAPER).to_dict()
        for role in roles:
            assert data["plant"][role]["fmu"] == fmu
            data["plant"][role] = paper["plant"][role] = None
        if fmu == "IdealActuator":  # and their supply: velocity servos share no pump
            assert data["plant"]["supply"] == {"kind": "constant"}
            assert paper["plant"]["supply"]["kind"] == "load_sensing"
            data["plant"]["supply"] = paper["plant"]["supply"] = None
        assert {**data, "name": "", "description": ""} == \
            {**paper, "name": "", "description": ""}


@pytest.mark.parametrize("text, message", [
    ('base = 5\n', "base: expected a scenario file name, got 5"),
    ('base = "missing.toml"\n', "no such scenario file"),
    ('base = "loop.toml"\n', "base: 'loop.toml' is this scenario or one it is based on"),
])
def test_a_wrong_base_is_one_line(tmp_path, text, message):
    path = tmp_path / "loop.toml"
    path.write_text(text)
    with pytest.raises(ScenarioError, match=message) as error:
        load_scenario(path)
    assert "\n" not in str(error.value)


def test_a_circle_of_bases_is_refused(tmp_path):
    (tmp_path / "a.toml").write_text('base = "b.toml"\n')
    (tmp_path / "b.toml").write_text('base = "a.toml"\n')
    with pytest.raises(ScenarioError, match=r"a\.toml \(base b\.toml\): base: 'a\.toml' is"):
        load_scenario(tmp_path / "a.toml")


def _misspelt_boom_parameter(tmp_path):
    (tmp_path / "own.toml").write_text(
        f'base = "{PAPER}"\n[plant.boom.parameters]\nq_ratd = 1e-3\n')
    (tmp_path / "top.toml").write_text(
        'base = "own.toml"\n[plant.boom]\nfmu = "HydraulicCylinder"\n')


@pytest.mark.parametrize("file, overrides", [
    ("own.toml", []),
    ("own.toml", ['plant.boom.fmu="HydraulicCylinder"']),  # naming the FMU it already has
    ("top.toml", []),
    (PAPER, ["plant.boom.parameters.q_ratd=1e-3"]),
    (PAPER, ["plant.boom.parameters={q_ratd=1e-3}"]),  # a --set table names it too
    (PAPER, ["plant.boom={parameters={q_ratd=1e-3}}"]),
])
def test_a_misspelt_parameter_is_refused_however_it_is_given(tmp_path, file, overrides):
    _misspelt_boom_parameter(tmp_path)
    with pytest.raises(ScenarioError, match="plant.boom.parameters.q_ratd: HydraulicCylinder has "
                                            "no parameter 'q_ratd' \\(closest: q_rated"):
        load_scenario(tmp_path / file if isinstance(file, str) else file, overrides)


def test_a_swapped_fmu_drops_the_base_files_parameters_it_lacks():
    # The paper file rates the boom's valve (q_rated, dp_rated, meter_out_ratio); IdealActuator
    # declares none of them, so swapping it in by --set keeps only what it declares.
    scenario = load_scenario(PAPER, ['plant.boom.fmu="IdealActuator"',
                                     'plant.supply.kind="constant"'])
    assert scenario.plant.boom.parameters == {"stroke": 1.289}
    with pytest.raises(ScenarioError, match="IdealActuator has no parameter 'q_rated'"):
        load_scenario(PAPER, ['plant.boom.fmu="IdealActuator"', "plant.boom.parameters.q_rated=1"])


@pytest.mark.parametrize("overrides, message", [
    (['plant.supply.kind="pump"'], "unknown supply kind 'pump'"),
    (["plant.supply.margin_pa=40e6"], "margin_pa must be below cutoff_pa"),
    (["plant.supply.cutoff_pa=38e6"], "plant.boom: the pump's cut-off 38 MPa is above the "
                                      "valve's p_supply 35 MPa"),
    (['plant.kind="lab"'], "supply kind 'load_sensing' applies to plant kind \"sim\" only"),
])
def test_a_wrong_supply_is_one_line(overrides, message):
    with pytest.raises(ScenarioError, match=message) as error:
        load_scenario(PAPER, overrides)
    assert "\n" not in str(error.value)


def test_a_constant_supply_clears_the_pumps_settings():
    data = load_scenario(PAPER, ['plant.supply.kind="constant"']).to_dict()
    assert data["plant"]["supply"] == {"kind": "constant"}
