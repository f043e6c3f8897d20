"""A scripted campaign: load the paper's scenario, change it, dig, and look at the periods.

Loads scenarios/paper-2020.toml with two overrides (as `excosim run --set` would), digs three
periods on the simulated excavator (hydraulic cylinder FMUs under a servo, the Pile FMU),
writes the MCAP log to a temporary folder, and prints per period: the deepest point D, the
weighed mass and its error, the trajectory's duration and peak jerk, and how closely the
servos tracked the planned spline. Then it reads the log back.

    python examples/07_campaign.py
"""

import tempfile
from pathlib import Path

from orchestrator.campaign import run_campaign
from orchestrator.runlog import read_run
from orchestrator.scenario import load_scenario

ROOT = Path(__file__).resolve().parent.parent

scenario = load_scenario(ROOT / "scenarios" / "paper-2020.toml",
                         ["periods=3", "plant.load_cell_noise_kg=0.2"])
print(f"scenario {scenario.name}: {scenario.periods} periods, target "
      f"{scenario.target_mass_kg:g} kg, D0 = ({scenario.adaptation.y_D0_m:g}, "
      f"{scenario.adaptation.z_D0_m:g}) m")

with tempfile.TemporaryDirectory() as folder:
    log_path = Path(folder) / "campaign.mcap"
    result = run_campaign(scenario, log_path=log_path,
                          progress=lambda record: print(f"  period {record['k']} done"))
    print(f"termination: {result.termination} ({result.message})")
    frame = result.to_dataframe()
    columns = ["y_D_m", "z_D_m", "mass_kg", "error_kg", "reset", "duration_s",
               "max_abs_jerk_deg_s3_bucket", "tracking_rms_deg_boom", "tracking_rms_deg_stick",
               "tracking_rms_deg_bucket"]
    print(frame[columns].round(3).to_string())
    run = read_run(log_path)
    print(f"log: {len(run.periods)} periods, termination {run.termination}, "
          f"{sum(run.message_counts.values())} messages, "
          f"{log_path.stat().st_size / 1e6:.1f} MB")
