"""Test helper: the two runs of scenarios/lab.toml that the lab tests share (tests/conftest.py's
session fixtures lab_simulated_run and lab_hil_run), so the real-time emulated run happens once
per test session."""

from pathlib import Path

LAB_SCENARIO = Path(__file__).resolve().parent.parent / "scenarios" / "lab.toml"
LAB_PERIODS = 3
# The emulated run's link, widened within the protocol's rules (test_lab_hil.py says why).
LAB_LINK = ("plant.lab.time_scale=1", "plant.lab.stream_rate_hz=25",
            "plant.lab.command_timeout_s=0.4", "plant.lab.feedback_timeout_s=0.48",
            "plant.lab.heartbeat_timeout_s=1.0")


def simulated_lab_run(path: Path):
    """(CampaignResult, path): the scenario's first LAB_PERIODS periods on the simulated plant,
    logged to `path`."""
    from orchestrator.campaign import run_campaign
    from orchestrator.scenario import load_scenario

    scenario = load_scenario(LAB_SCENARIO, [f"periods={LAB_PERIODS}"])
    return run_campaign(scenario, log_path=path), path


def emulated_lab_run(path: Path):
    """(CliRunner result, path): `excosim run scenarios/lab.toml --plant lab --emulate --periods
    LAB_PERIODS -o path --json` in real time."""
    from typer.testing import CliRunner

    from orchestrator.cli.app import app

    done = CliRunner().invoke(app, ["run", str(LAB_SCENARIO), "--plant", "lab", "--emulate",
                                    "--periods", str(LAB_PERIODS), "-o", str(path), "--json",
                                    *(f"--set={item}" for item in LAB_LINK)])
    return done, path
