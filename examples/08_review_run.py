"""Review a run from its MCAP log alone: period records, decoded sample channels, the figures.

Digs two periods of the paper scenario into a temporary log, then reads the log as a reviewer
would (no scenario file, no FMUs): the /period records, the measured joints and the boom
cylinder's pressures of period 2 as numpy arrays, and the review figures of period 2 (joints
with their tracking error, cylinder pressures, weight error, bucket-tip paths as the paper's
Fig. 10, pile shape). The figures go to figures/ in the current folder, or to the folder given
as the first argument, and stay there; their absolute paths are printed. The same from a shell:
`excosim review RUN.mcap --plots figures/ --period 2`.

    python examples/08_review_run.py [FOLDER]
"""

import sys
import tempfile
from pathlib import Path

import numpy as np

from orchestrator.campaign import run_campaign
from orchestrator.review.plots import PLOT_TOPICS, write_plots
from orchestrator.runlog import read_run
from orchestrator.scenario import load_scenario

ROOT = Path(__file__).resolve().parent.parent
FIGURES = Path(sys.argv[1] if len(sys.argv) > 1 else "figures").resolve()

# The log is only a means here: it goes with the temporary folder, the figures stay.
with tempfile.TemporaryDirectory() as folder:
    log_path = Path(folder) / "run.mcap"
    run_campaign(load_scenario(ROOT / "scenarios" / "paper-2020.toml", ["periods=2"]),
                 log_path=log_path)
    run = read_run(log_path, topics=PLOT_TOPICS)

for record in run.periods:
    y, z = record["deepest_point_m"]
    print(f"period {record['k']}: D = ({y:.2f}, {z:.3f}) m, dug {record['mass_kg']:.2f} kg")

joints = run.channels["/joints"].of_period(2)  # field name -> (n,) array
error = np.degrees(joints["measured_stick_rad"] - joints["reference_stick_rad"])
boom = run.channels["/cylinder/boom"].of_period(2)
print(f"period 2: {len(joints['t_s'])} samples; stick tracking error max "
      f"{np.abs(error).max():.3f} deg; boom cap-side pressure max "
      f"{boom['p_A_Pa'].max() / 1e5:.0f} bar")

for figure in write_plots(run, FIGURES, period=2):
    print(f"wrote {figure} ({figure.stat().st_size // 1000} kB)")
