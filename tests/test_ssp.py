"""SSP 1.0: the plant exported for other masters and read back (orchestrator.ssp). The exported
archive passes the SSP schema (FMPy's validator); libcosim and ecos, two peer masters, load
it, apply its parameter set and step a cylinder driven by a fixed spool command to the stroke
fmpy gives the same FMU under the same parameters; read back as the scenario's plant it digs
the same masses; its port maps' linear transformations read back as the same port maps; a bad
archive is one line naming what is wrong."""

import ctypes
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest
from fmpy.ssp.ssd import read_ssd

import fmus
from fmus.ecos_runs import load_ecospy
from fmus.runs import run_fmpy
from orchestrator.campaign import run_campaign
from orchestrator.scenario import ScenarioError, load_scenario
from orchestrator.ssp.export import PARAMETER_SET, export_ssp
from orchestrator.ssp.read import read_component

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "scenarios" / "paper-2020.toml"
STEPS, H, SPOOL = 100, 0.01, 0.3


@pytest.fixture(scope="module")
def archive(tmp_path_factory):
    return export_ssp(load_scenario(PAPER), tmp_path_factory.mktemp("ssp") / "paper.ssp")


@pytest.fixture(scope="module")
def reference():
    """The bucket under fmpy: the scenario's parameters, u = SPOOL held, x after each step."""
    spec = load_scenario(PAPER).fmu_specs()["bucket"]
    out = run_fmpy(fmus.build("HydraulicCylinder"), {"u": np.full(STEPS, SPOOL)}, ["x"], H,
                   dict(spec.parameters))
    return out["x"][1:]


def test_the_archive_is_valid_ssp_and_byte_reproducible(archive, tmp_path):
    ssd = read_ssd(str(archive), validate=True)
    assert [c.name for c in ssd.system.elements] == ["boom", "stick", "bucket", "pile"]
    with zipfile.ZipFile(archive) as files:
        names = files.namelist()
        assert {"resources/HydraulicCylinder.fmu", "resources/Pile.fmu"} <= set(names)
        assert all(f'name="{PARAMETER_SET}"' in files.read(f"resources/{r}.ssv").decode()
                   for r in ("boom", "stick", "bucket", "pile"))
    again = export_ssp(load_scenario(PAPER), tmp_path / "again.ssp")
    assert again.read_bytes() == archive.read_bytes()


def test_libcosim_loads_it_and_steps_the_bucket_as_fmpy_does(archive, reference):
    import sys as _sys

    for library in sorted(Path(_sys.prefix, "lib").glob("libtbb.so.*"))[:1]:
        ctypes.CDLL(str(library), mode=ctypes.RTLD_GLOBAL)
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimManipulator import CosimManipulator
    from libcosimpy.CosimObserver import CosimObserver

    log_output_level(CosimLogLevel.ERROR)
    execution = CosimExecution.from_ssp_file(str(archive), step_size=int(H * 1e9))
    bucket = execution.slave_index_from_instance_name("bucket")
    refs = {(v.name.decode() if isinstance(v.name, bytes) else v.name): v.reference
            for v in execution.slave_variables(bucket)}
    manipulator, observer = CosimManipulator.create_override(), CosimObserver.create_last_value()
    execution.add_manipulator(manipulator)
    execution.add_observer(observer)
    strokes = []
    for _ in range(STEPS):
        manipulator.slave_real_values(bucket, [refs["u"]], [SPOOL])
        execution.step(1)
        stroke, q_rated = observer.last_real_values(bucket, [refs["x"], refs["q_rated"]])
        strokes.append(stroke)
    assert q_rated == pytest.approx(3.6666666666666666e-3, rel=1e-15)  # the scenario's, applied
    assert np.ptp(strokes) > 0.1  # it moved
    np.testing.assert_allclose(strokes, reference, rtol=0.0, atol=1e-9)


def test_ecos_loads_it_and_steps_the_bucket_as_fmpy_does(archive, reference):
    ecospy = load_ecospy()
    ecospy.EcosLib.set_log_level("warn")
    simulation = ecospy.EcosSimulation(step_size=H, ssp_path=str(archive))
    try:
        assert simulation.init(parameter_set=PARAMETER_SET)
        strokes = []
        for _ in range(STEPS):
            simulation.set_real("bucket::u", SPOOL)
            simulation.step()
            strokes.append(simulation.get_real("bucket::x"))
        assert simulation.get_real("bucket::q_rated") == pytest.approx(3.6666666666666666e-3,
                                                                       rel=1e-15)
        simulation.terminate()
    finally:
        simulation.free()
    np.testing.assert_allclose(strokes, reference, rtol=0.0, atol=1e-9)


def test_read_back_as_the_plant_it_digs_the_same_masses(archive):
    ours = run_campaign(load_scenario(PAPER, ["periods=2"]))
    scenario = load_scenario(PAPER, ["periods=2", f'plant.ssp="{archive}"'])
    assert Path(scenario.fmu_specs()["bucket"].fmu).parent.parent.name == "ssp"
    theirs = run_campaign(scenario)
    assert [r["mass_kg"] for r in theirs.records] == [r["mass_kg"] for r in ours.records]


def test_port_maps_travel_as_linear_transformations(tmp_path):
    scenario = load_scenario(PAPER, ['plant.boom.ports.u={variable = "u", scale = 0.01}',
                                     'plant.boom.ports.x={variable = "x", scale = 1e-3, '
                                     'offset = 0.5}'], check_fmus=False)  # not run: read back
    path = export_ssp(scenario, tmp_path / "mapped.ssp")
    read_ssd(str(path), validate=True)
    _, parameters, ports = read_component(path, "boom")
    assert ports["u"] == {"variable": "u", "scale": pytest.approx(0.01), "offset": 0.0}
    assert ports["x"] == {"variable": "x", "scale": pytest.approx(1e-3),
                          "offset": pytest.approx(0.5)}
    assert parameters == dict(scenario.fmu_specs()["boom"].parameters)


def _edited(archive: Path, target: Path, old: str, new: str) -> Path:
    with zipfile.ZipFile(archive) as source, zipfile.ZipFile(target, "w") as out:
        for name in source.namelist():
            data = source.read(name)
            if name == "SystemStructure.ssd":
                text = data.decode()
                assert old in text
                data = text.replace(old, new, 1).encode()
            out.writestr(name, data)
    return target


@pytest.mark.parametrize("make, message", [
    (lambda a, t: t.write_bytes(b"not a zip") and t, "not an SSP archive"),
    (lambda a, t: _edited(a, t, "<ssd:Elements>", "<ssd:Elementz>"),
     "not a valid SSP 1.0 system structure"),
    (lambda a, t: _edited(a, t, '<ssd:ParameterBinding source="resources/bucket.ssv"/>',
                          '<ssd:ParameterBinding source="resources/bucket.ssv"><ssd:Parameter'
                          'Mapping source="m.ssm"/></ssd:ParameterBinding>'),
     "component 'bucket' has a parameter mapping, which excosim cannot map"),
])
def test_a_bad_archive_is_one_line(archive, tmp_path, make, message):
    bad = make(archive, tmp_path / "bad.ssp")
    with pytest.raises(ScenarioError) as error:
        load_scenario(PAPER, [f'plant.bucket.ssp="{bad}"'])
    assert message in str(error.value) and "\n" not in str(error.value)
    assert str(error.value).startswith("paper-2020.toml: plant.bucket.ssp: ")
    done = subprocess.run([sys.executable, "-m", "orchestrator.cli.app", "run", str(PAPER),
                           "--set", f'plant.bucket.ssp="{bad}"'], capture_output=True,
                          text=True, timeout=120)
    assert done.returncode == 2 and len(done.stderr.strip().splitlines()) == 1



def test_a_role_names_a_component_the_archive_lacks(archive):
    with pytest.raises(ScenarioError, match=r"plant\.bucket\.ssp: paper\.ssp has no component "
                       r"'scoop'"):
        load_scenario(PAPER, [f'plant.bucket.ssp="{archive}"', 'plant.bucket.component="scoop"'])
