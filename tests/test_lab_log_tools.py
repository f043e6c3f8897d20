"""A lab run's log works unchanged in the tools made for simulated runs: `excosim review` (text,
--json, --plots), `excosim compare` against a simulated run of the same scenario, and the
Foxglove layout's topics, fields and frames; `excosim replay` refuses it in one line (a lab run
was measured on the machine, there is nothing to re-run).

The logs are tests/conftest.py's session fixtures (lab_runs.py): the emulated lab run in real
time that test_lab_hil.py checks too, and the simulated run of the same scenario, so this module
adds no real-time run.
"""

import json

import matplotlib.image
import pytest
from lab_runs import LAB_PERIODS, LAB_SCENARIO
from test_foxglove_layout import LAYOUT_PATH, run_log_facts, unresolved
from typer.testing import CliRunner

from orchestrator.cli.app import app
from orchestrator.runlog import read_run
from orchestrator.scenario import load_scenario

runner = CliRunner()


@pytest.fixture(scope="module")
def lab_log(lab_hil_run):
    done, path = lab_hil_run
    assert done.exit_code == 0, done.output
    return path


def test_review_prints_the_lab_run(lab_log):
    done = runner.invoke(app, ["review", str(lab_log)])
    assert done.exit_code == 0, done.output
    assert "lab (lab plant)" in done.stdout
    assert f"dug all {LAB_PERIODS} planned periods" in done.stdout
    for record in read_run(lab_log).periods:
        assert f"{record['mass_kg']:.2f}" in done.stdout


def test_review_json_gives_back_the_lab_runs_records(lab_log):
    done = runner.invoke(app, ["review", str(lab_log), "--json"])
    assert done.exit_code == 0, done.output
    data = json.loads(done.stdout)
    assert data["plant"] == "lab" and data["scenario"] == "lab"
    assert data["termination"] == "periods" and data["finished"] and not data["truncated"]
    assert data["target_mass_kg"] == load_scenario(LAB_SCENARIO).target_mass_kg
    assert data["periods"] == json.loads(json.dumps(read_run(lab_log).periods))
    assert data["figures"]["counted"] == LAB_PERIODS - 1


def test_review_plots_draws_every_figure_of_the_lab_run(lab_log, tmp_path):
    done = runner.invoke(app, ["review", str(lab_log), "--plots", str(tmp_path), "--period", "2"])
    assert done.exit_code == 0, done.output
    names = sorted(p.name for p in tmp_path.iterdir())
    # A lab log has no /pile/bucket or /pile/profile (the machine has no pile model to log),
    # so the tip paths and pile profiles, drawn from those, are left out.
    assert names == ["period_02_cylinder_pressures.png", "period_02_joints.png",
                     "productivity.png", "weight_error.png"]
    assert not {"/pile/bucket", "/pile/profile"} & set(read_run(lab_log).message_counts)
    assert sorted(done.stdout.split()[-len(names):]) == sorted(str(tmp_path / name)
                                                               for name in names)
    for name in names:
        image = matplotlib.image.imread(tmp_path / name)
        assert image.shape[0] > 300 and image.shape[1] > 500
        assert image[..., :3].std() > 0.05, name  # not a blank canvas


def test_compare_sets_the_lab_run_beside_the_simulated_one(lab_log, lab_simulated_run,
                                                           tmp_path):
    simulated, sim_log = lab_simulated_run
    done = runner.invoke(app, ["compare", str(lab_log), str(sim_log), "--json"])
    assert done.exit_code == 0, done.output
    runs = json.loads(done.stdout)["runs"]
    assert len(runs) == 2 and runs[0]["label"] != runs[1]["label"]
    assert runs[0]["errors_kg"] == [r["error_kg"] for r in read_run(lab_log).periods]
    assert runs[1]["errors_kg"] == [r["error_kg"] for r in simulated.records]
    # The emulated machine weighs what the simulated one does (test_lab_hil.py: within 2 %).
    assert runs[0]["errors_kg"] == pytest.approx(runs[1]["errors_kg"], abs=0.1)
    done = runner.invoke(app, ["compare", str(lab_log), str(sim_log), "--plots", str(tmp_path)])
    assert done.exit_code == 0, done.output
    assert runs[0]["label"] in done.stdout and runs[1]["label"] in done.stdout
    assert (tmp_path / "weight_error_compare.png").stat().st_size > 10_000


def test_every_topic_field_and_frame_of_the_foxglove_layout_is_in_the_lab_log(lab_log):
    layout = json.loads(LAYOUT_PATH.read_text(encoding="utf-8"))
    facts = run_log_facts(lab_log)
    assert unresolved(layout, facts) == []
    assert "/signals/bus" in facts.schemas  # a lab log, with the bus statistics


def test_replay_refuses_the_lab_run_in_one_line(lab_log):
    done = runner.invoke(app, ["replay", str(lab_log)])
    assert done.exit_code == 2
    assert done.stderr.count("\n") == 1 and "Traceback" not in done.stderr
    assert "lab run" in done.stderr
