"""Port maps across units: an FMU that declares mm, mm/s, bar or deg fills a role through the
conversion of its declared unit (or an explicit scale and offset), and digs like its SI twin."""

import math
import re
import shutil
from pathlib import Path
from types import SimpleNamespace

import pytest

import fmus
from orchestrator.campaign import run_campaign
from orchestrator.scenario import ScenarioError, load_scenario
from plant_models.port_units import PortMap, si_to_declared, unit_conversion

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "scenarios" / "paper-2020.toml"
MM = {"x": "mm", "v": "mm/s", "v_max": "mm/s", "stroke": "mm", "x0": "mm"}


def variable(name, unit):
    return SimpleNamespace(name=name, unit=unit, declaredType=None)


def test_declared_units_convert_to_the_roles_si_units():
    assert unit_conversion("p_A", variable("pA", "bar"), {}) == PortMap("pA", 1e5, 0.0)
    assert unit_conversion("x", variable("s", "mm"), {}) == PortMap("s", 1e-3, 0.0)
    assert unit_conversion("bucket_angle", variable("a", "deg"), {}).scale == \
        pytest.approx(math.pi / 180)
    assert unit_conversion("x", variable("s", "m"), {}) is None  # already the role's
    assert unit_conversion("x", variable("s", None), {}) is None  # nothing declared
    # The FMU's own <BaseUnit> definition wins over the table (a made-up "hm" = 100 m).
    hm = SimpleNamespace(baseUnit=SimpleNamespace(kg=0, m=1, s=0, rad=0, A=0, K=0, mol=0, cd=0,
                                                  factor=100.0, offset=0.0))
    assert unit_conversion("x", variable("s", "hm"), {"hm": hm}) == PortMap("s", 100.0, 0.0)
    assert si_to_declared(1.289, variable("stroke", "mm"), {}) == pytest.approx(1289.0)


@pytest.mark.parametrize("role, unit, message", [
    ("x", "N", "role 'x' is in m, but variable 'q' is in 'N', another quantity"),
    ("p_A", "psi_g", "variable 'q' is in 'psi_g', which the FMU does not define"),
])
def test_a_unit_that_does_not_convert_is_refused(role, unit, message):
    with pytest.raises(ValueError, match=re.escape(message)):
        unit_conversion(role, variable("q", unit), {})


def test_a_unit_the_fmu_defines_in_ampere_is_another_quantity_not_an_unknown_one():
    """A spool command in mA, defined by the FMU (<BaseUnit A="1" factor="0.001"/>): the
    refusal names what it is and what to give, not "a unit the FMU does not define"."""
    milliampere = SimpleNamespace(baseUnit=SimpleNamespace(kg=0, m=0, s=0, rad=0, A=1, K=0,
                                                           mol=0, cd=0, factor=1e-3,
                                                           offset=0.0))
    with pytest.raises(ValueError) as error:
        unit_conversion("u", variable("spool", "mA"), {"mA": milliampere})
    assert str(error.value) == (
        "role 'u' is in 1, but variable 'spool' is in 'mA', another quantity (the FMU defines "
        "it in ampere, kelvin, mole or candela); map it with an explicit scale and offset to 1")
    assert si_to_declared(0.5, variable("spool", "mA"), {"mA": milliampere}) is None


@pytest.fixture(scope="module")
def mm_actuator(tmp_path_factory) -> Path:
    """IdealActuator declared in mm: its physics is linear, so in mm it is the same model."""
    folder = tmp_path_factory.mktemp("mm") / "IdealActuatorMM"
    shutil.copytree(ROOT / "fmus" / "IdealActuator", folder)
    text = (folder / "variables.toml").read_text().replace(
        'identifier = "IdealActuator"', 'identifier = "IdealActuatorMM"')
    blocks = text.split("[[variable]]")
    for i, block in enumerate(blocks):
        name = re.search(r'^name = "(\w+)"', block, re.M)
        if name and name.group(1) in MM:
            block = re.sub(r'^unit = ".*"$', f'unit = "{MM[name.group(1)]}"', block, flags=re.M)
            block = re.sub(r"^(start|min|max) = (.*)$",
                           lambda m: f"{m.group(1)} = {float(m.group(2)) * 1000!r}",
                           block, flags=re.M)
            blocks[i] = block
    (folder / "variables.toml").write_text("[[variable]]".join(blocks))
    return fmus.build_model(folder)


def masses(scenario):
    return [r["mass_kg"] for r in run_campaign(scenario).records]


def test_an_fmu_in_mm_digs_like_its_si_twin(mm_actuator):
    base = ["periods=2", "plant.boom.fmu=IdealActuator"]
    si = load_scenario(PAPER, base)
    mm = load_scenario(PAPER, ["periods=2", f"plant.boom.fmu={mm_actuator}"])
    # The preset's stroke (SI) is kept, in the FMU's mm.
    assert mm.plant.boom.parameters["stroke"] == pytest.approx(
        1000 * si.plant.boom.parameters["stroke"])
    assert masses(mm) == pytest.approx(masses(si), rel=1e-6)


def test_an_explicit_scale_replaces_the_declared_unit(mm_actuator, tmp_path):
    same = load_scenario(PAPER, ["periods=1", f"plant.boom.fmu={mm_actuator}",
                                 'plant.boom.ports.x={variable = "x", scale = 1e-3}'])
    assert masses(same) == pytest.approx(masses(load_scenario(PAPER, [
        "periods=1", f"plant.boom.fmu={mm_actuator}"])), rel=1e-9)
    with pytest.raises(ScenarioError, match=r"plant\.boom\.ports: x\.scale: must not be 0"):
        load_scenario(PAPER, [f"plant.boom.fmu={mm_actuator}",
                              'plant.boom.ports.x={variable = "x", scale = 0}'])
