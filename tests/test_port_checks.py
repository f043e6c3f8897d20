"""A cylinder FMU that would fill its role wrongly without a word is refused in one line, before
any log: a load that acts the wrong way (orchestrator.plants.port_checks loads it with the spool
closed and watches where the piston goes) and a stroke short of the linkage's (it drives the
piston out and watches where it stops). The references: our HydraulicCylinder and IdealActuator
pass; a copy of HydraulicCylinder that counts +F_ext as pushing out fails, and passes again
with the port mapped reversed; our cylinder with a 1.0 m stroke fails where the bucket
linkage needs 1.038 m."""

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import fmus
from orchestrator.campaign import PlantRefused, run_campaign
from orchestrator.plants.port_checks import check_cylinder
from orchestrator.scenario import load_scenario
from plant_models.hydraulics import cylinder_parameters
from plant_models.port_units import PortMap

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "scenarios" / "paper-2020.toml"
BUCKET_STROKE = 1.038  # m, the paper bucket linkage's
LOAD = 3.0e4  # N


@pytest.fixture(scope="module")
def pushing_out(tmp_path_factory):
    """HydraulicCylinder whose F_ext pushes the piston out (the sign of another tool)."""
    root = tmp_path_factory.mktemp("sign")
    folder = root / "HydraulicCylinder"
    shutil.copytree(Path(fmus.__file__).parent / "HydraulicCylinder", folder)
    model = folder / "model.c"
    code = model.read_text()
    flipped = code.replace("p->F_ext = clamp(v[VR_F_ext], -s->F_limit, s->F_limit);",
                           "p->F_ext = -clamp(v[VR_F_ext], -s->F_limit, s->F_limit);")
    flipped = flipped.replace("F0 = clamp(v[VR_F_ext], -s->F_limit, s->F_limit);",
                              "F0 = -clamp(v[VR_F_ext], -s->F_limit, s->F_limit);")
    assert flipped.count("-clamp(v[VR_F_ext]") == 2  # the law and the start's equilibrium
    model.write_text(flipped)
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("EXCOSIM_FMU_DIR", str(root / "fmu"))
        return fmus.build_model(folder)


def bucket() -> dict:
    return {k: v for k, v in cylinder_parameters("paper")["bucket"].items() if k != "x0"}


def test_ours_pass():
    check_cylinder("bucket", fmus.build("HydraulicCylinder"), {}, bucket(), BUCKET_STROKE, LOAD,
                   0.01)
    check_cylinder("bucket", fmus.build("IdealActuator"), {}, {"stroke": BUCKET_STROKE},
                   BUCKET_STROKE, LOAD, 0.01)


def test_a_load_of_the_wrong_sign_is_refused_and_a_reversed_port_fixes_it(pushing_out):
    with pytest.raises(ValueError, match=r"^bucket: its load acts the wrong way: with the spool "
                       r"closed, F_ext = \+30 kN moved the piston out by .* ports\.F_ext = "
                       r"\{ variable = \"F_ext\", scale = -1 \}$"):
        check_cylinder("bucket", pushing_out, {}, bucket(), BUCKET_STROKE, LOAD, 0.01)
    reversed_port = {"F_ext": PortMap("F_ext", scale=-1.0)}
    check_cylinder("bucket", pushing_out, {}, bucket(), BUCKET_STROKE, LOAD, 0.01,
                   reversed_port)


@pytest.mark.parametrize("stroke, message", [
    (1.0, r"^bucket: its stroke ends at 1(\.0+)? m where the linkage needs 1\.038 m"),
    (0.9, r"^bucket: it cannot start at x = 0\.9861 m, 5 % short of the linkage's stroke "
          r"1\.038 m .*is its stroke shorter\?"),
])
def test_a_stroke_short_of_the_linkages_is_refused(stroke, message):
    with pytest.raises(ValueError, match=message):
        check_cylinder("bucket", fmus.build("HydraulicCylinder"), {},
                       {**bucket(), "stroke": stroke}, BUCKET_STROKE, LOAD, 0.01)


def test_the_campaign_refuses_before_its_log_and_the_command_exits_2(pushing_out, tmp_path):
    scenario = load_scenario(PAPER, ["periods=1", f'plant.bucket.fmu="{pushing_out}"'])
    log = tmp_path / "refused.mcap"
    with pytest.raises(PlantRefused, match=r"^plant\.bucket: its load acts the wrong way"):
        run_campaign(scenario, log_path=log)
    assert not log.exists()
    done = subprocess.run([sys.executable, "-m", "orchestrator.cli.app", "run", str(PAPER),
                           "--periods", "1", "--trust", "-o", str(log), "--set",
                           f'plant.bucket.fmu="{pushing_out}"'],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 2, done.stderr
    lines = [line for line in done.stderr.strip().splitlines()
             if not line.startswith("excosim: --trust:")]  # the notice of what it trusts
    assert len(lines) == 1 and "plant.bucket: its load acts the wrong way" in lines[0], lines
    assert "Traceback" not in done.stderr and not log.exists()
    # Mapped reversed, the same FMU digs what ours digs.
    fixed = load_scenario(PAPER, ["periods=1", f'plant.bucket.fmu="{pushing_out}"',
                                  'plant.bucket.ports.F_ext={variable="F_ext", scale=-1}'])
    ours = run_campaign(load_scenario(PAPER, ["periods=1"]))
    theirs = run_campaign(fixed)
    assert theirs.termination == "periods", theirs.message
    assert theirs.records[0]["mass_kg"] == pytest.approx(ours.records[0]["mass_kg"], rel=1e-9)
