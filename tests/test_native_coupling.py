"""The per-step coupling in C (orchestrator.plants.native) against the Python loop it replaces
(orchestrator.plants.coupling_loop): the same campaign through either gives the same bits, in
every signal, joint angle, weighing and resume state, on the load-sensing pump and on the
constant supply, with the arm held after a lagging period; the loop in C that steps the FMUs
itself gives the bits of the FMUs stepped from Python, an FMU's failure there reads as it
does from Python, and its board names the FMU in a step; a plant the C coupling cannot serve
(a linear servo) runs the Python loop and says why; the library builds byte-reproducibly."""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np
import pytest

from orchestrator.campaign import run_campaign
from orchestrator.plants import simulated_excavator
from orchestrator.plants.coupling_loop import PythonCoupling
from orchestrator.plants.native import NativeCoupling
from orchestrator.plants.native.board import Board, stepping_after_death
from orchestrator.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "scenarios" / "paper-2020.toml"


def campaign(monkeypatch, native: bool, scenario: Path, overrides: list[str]) -> dict:
    """One campaign through one loop: its measurements, the plant's resume state after each
    period, the loops it used and why, and the chunks the arm was held for."""
    cls = simulated_excavator.SimulatedExcavator
    monkeypatch.setattr(cls, "native_coupling", native)
    out = {"measurements": [], "states": [], "loops": set(), "notes": set(), "held": 0}
    run_period, settle = cls.run_period, cls._settle

    def keep(self, reference):
        out["measurements"].append(run_period(self, reference))
        out["states"].append(self.resume_state())
        out["loops"].add(type(self._loop))
        out["notes"].add(self.step_loop_note)
        return out["measurements"][-1]

    def count(self, *args):
        chunks = settle(self, *args)
        out["held"] += len(chunks)
        return chunks

    monkeypatch.setattr(cls, "run_period", keep)
    monkeypatch.setattr(cls, "_settle", count)
    result = run_campaign(load_scenario(scenario, overrides))
    monkeypatch.setattr(cls, "run_period", run_period)
    monkeypatch.setattr(cls, "_settle", settle)
    assert result.termination == "periods", result.message
    return out


def assert_same_bits(a, b) -> None:
    assert len(a) == len(b)
    for first, second in zip(a, b, strict=True):
        assert first.weighed_mass_kg == second.weighed_mass_kg
        assert np.array_equal(first.joints_rad, second.joints_rad)
        assert np.array_equal(first.t_s, second.t_s)
        assert first.signals.keys() == second.signals.keys()
        for name in first.signals:
            assert np.array_equal(first.signals[name], second.signals[name]), name


@pytest.mark.parametrize("overrides", [
    ["periods=20"],  # the paper scenario on its load-sensing pump
    ["periods=4", "plant.supply.kind=constant"],
    # a pump too small for the path: periods that end off the path are held on its last pose
    ["periods=3", "plant.supply.max_flow_l_min=100", "plant.max_tracking_error_deg=60"],
], ids=["pump", "constant-supply", "held"])
def test_the_c_coupling_gives_the_python_loops_bits(monkeypatch, overrides):
    native = campaign(monkeypatch, True, PAPER, overrides)
    python = campaign(monkeypatch, False, PAPER, overrides)
    assert native["loops"] == {NativeCoupling} and native["notes"] == {None}
    assert python["loops"] == {PythonCoupling}
    assert_same_bits(native["measurements"], python["measurements"])
    assert native["states"] == python["states"]  # servo filters, FMU states, step counters
    assert native["held"] == python["held"]
    assert (native["held"] > 0) == ("plant.max_tracking_error_deg=60" in overrides)


def test_a_linear_servo_runs_the_python_loop_and_says_why(monkeypatch):
    ideal = campaign(monkeypatch, True, ROOT / "scenarios" / "paper-2020-ideal-actuators.toml",
                     ["periods=1"])
    assert ideal["loops"] == {PythonCoupling}
    assert any("linear servo" in note for note in ideal["notes"])


def test_the_library_builds_byte_reproducibly(tmp_path, monkeypatch):
    from fmus.shared_library import build_library

    source = ROOT / "orchestrator" / "plants" / "native"
    digests = []
    for folder in ("a", "b"):
        monkeypatch.setenv("EXCOSIM_FMU_DIR", str(tmp_path / folder))
        path = build_library("coupling", source, ("coupling.c",))
        assert path.is_relative_to(tmp_path / folder)
        digests.append(hashlib.sha256(path.read_bytes()).hexdigest())
    assert digests[0] == digests[1]


def test_the_c_coupling_refuses_references_it_would_read_past():
    from orchestrator.campaign.loop import build_plant

    with build_plant(load_scenario(PAPER, ["periods=1"])) as plant:
        middle = [0.5 * table.stroke_m for table in plant.coupling.tables]
        plant._start(np.array(plant.coupling.kinematics(*middle)[:3]))  # at rest mid-stroke
        loop = plant._loop
        assert isinstance(loop, NativeCoupling)
        good = np.zeros((4, 3))
        with pytest.raises(ValueError, match=r"must be \(n, 3\)"):
            loop.track(np.zeros((4, 2)), good, good, 37, 0, 0.0)
        with pytest.raises(ValueError, match=r"must be \(n, 3\)"):
            loop.track(good, np.zeros((3, 3)), good, 37, 0, 0.0)
        with pytest.raises(ValueError, match="signal columns"):
            loop.track(good, good, good, 34, 0, 0.0)


def test_the_loop_in_c_gives_the_bits_of_the_fmus_stepped_from_python(monkeypatch):
    ran = []
    in_c, in_python = NativeCoupling._run_in_c, NativeCoupling._run_in_python

    def counted(name, run):
        def wrapper(self, *args):
            ran.append(name)
            return run(self, *args)
        return wrapper

    monkeypatch.setattr(NativeCoupling, "_run_in_c", counted("c", in_c))
    c = campaign(monkeypatch, True, PAPER, ["periods=3"])
    assert set(ran) == {"c"}
    ran.clear()
    monkeypatch.setattr(NativeCoupling, "_run_in_c", counted("python", in_python))
    python = campaign(monkeypatch, True, PAPER, ["periods=3"])
    assert set(ran) == {"python"}
    assert_same_bits(c["measurements"], python["measurements"])
    assert c["states"] == python["states"]


def test_an_fmu_failing_in_the_loop_in_c_reads_as_from_python(tmp_path, monkeypatch):
    from faulty_fmus import FAIL, patched_cylinder

    failing = patched_cylinder(tmp_path, FAIL, 2.0, "Failing")
    overrides = ["periods=1", f"plant.stick.fmu={failing}"]
    cls = simulated_excavator.SimulatedExcavator
    close = cls.close
    seen = []

    def closing(self):  # what the loop left when the FMU failed, before the plant closes
        seen.append((self._loop.clock, [servo.state() for servo in self._servos]))
        close(self)

    monkeypatch.setattr(cls, "close", closing)
    messages, ran = [], []
    for name, run in (("c", NativeCoupling._run_in_c), ("python", NativeCoupling._run_in_python)):
        def counted(self, *args, run=run, name=name):
            ran.append(name)
            return run(self, *args)

        monkeypatch.setattr(NativeCoupling, "_run_in_c", counted)
        messages.append(run_campaign(load_scenario(PAPER, overrides)).message)
    assert ran == ["c", "python"]  # one stroke reference each: the failure ends the period
    assert messages[0] == messages[1]
    assert "stick (HydraulicCylinder): fmi2DoStep failed at t = 2.0" in messages[0]
    assert "a burst hose" in messages[0]
    assert seen[0] == seen[1] and seen[0][0][0] == 200  # the clock: 200 steps done


def test_the_board_names_the_fmu_in_a_step_and_goes_with_the_plant(tmp_path, monkeypatch):
    from orchestrator.campaign.loop import build_plant

    labels = ["boom (A)", "stick (B)", "bucket (C)", "pile (D)"]
    monkeypatch.setattr("tempfile.tempdir", str(tmp_path))
    board = Board(labels)
    assert board.reading() is None and stepping_after_death(tmp_path) is None
    board.layout.which, board.layout.t = 2, 1.25  # as coupling.c writes it before a step
    assert board.reading() == (2, 1.25, "bucket (C)")
    assert stepping_after_death(tmp_path) == (1.25, "bucket (C)")  # from the file, as a parent
    board.close()
    board.close()
    assert stepping_after_death(tmp_path) is None and not any(tmp_path.iterdir())
    with build_plant(load_scenario(PAPER, ["periods=1"])) as plant:
        middle = [0.5 * table.stroke_m for table in plant.coupling.tables]
        plant._start(np.array(plant.coupling.kinematics(*middle)[:3]))
        folder = plant._loop.temporary_folders()[0]
        assert folder in plant.temporary_folders() and Path(folder, "board").is_file()
    assert not Path(folder).exists()


def test_a_closed_loop_or_plant_is_never_stepped_from_c():
    from orchestrator.campaign.loop import build_plant

    with build_plant(load_scenario(PAPER, ["periods=1"])) as plant:
        middle = [0.5 * table.stroke_m for table in plant.coupling.tables]
        plant._start(np.array(plant.coupling.kinematics(*middle)[:3]))
        loop, still = plant._loop, np.zeros((3, 3))
        strokes = np.repeat(np.array(middle)[None, :], 3, axis=0)
        loop.close()  # the board is gone: the FMUs, still open, step from Python
        rows, _, steps, _ = loop.track(strokes, still, still, 37, 0, 0.0)
        assert steps == 3 and np.isfinite(rows).all()
    with pytest.raises(RuntimeError, match="closed"):  # and a closed plant's FMUs refuse
        loop.track(strokes, still, still, 37, 3, 0.03)
