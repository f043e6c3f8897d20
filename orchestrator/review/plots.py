"""PNG figures of a run log, in the spirit of the paper's Figures 7-11, drawn from the file alone.

`write_plots(run, folder, period)` writes every figure the file has data for (the per-period
ones for one period or several) and returns what it wrote; each `plot_*` function draws one
figure and returns the matplotlib Figure (a caller may save or show it). Angles in degrees,
pressures in bar, lengths in m, masses in kg. The figures live in one module each (plots_joints,
plots_pile, plots_pressures, plots_productivity, plots_weight; shared parts in plots_common);
this module is the entry point and re-exports them.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from orchestrator.review.plots_common import JOINTS, pyplot, soil_spans, via_times
from orchestrator.review.plots_joints import plot_joints, tracking_error_deg
from orchestrator.review.plots_pile import (
    PAPER_TIP_PATH_PERIODS,
    lowest_tip_point,
    pile_profile_periods,
    plot_pile_profiles,
    plot_tip_paths,
    tip_path_periods,
    vertical_stretch,
)
from orchestrator.review.plots_pressures import plot_cylinder_pressures
from orchestrator.review.plots_productivity import has_productivity, plot_productivity
from orchestrator.review.plots_weight import plot_error_overlay, plot_weight_error, run_labels
from orchestrator.runlog import RunFile

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["PAPER_TIP_PATH_PERIODS", "PLOT_TOPICS", "has_productivity", "lowest_tip_point",
           "pile_profile_periods", "plot_cylinder_pressures", "plot_error_overlay",
           "plot_joints", "plot_pile_profiles", "plot_productivity", "plot_tip_paths",
           "plot_weight_error", "run_labels", "save_figure", "soil_spans", "tip_path_periods",
           "tracking_error_deg", "vertical_stretch", "via_times", "write_plots"]

# Topics the figures read (`orchestrator.review.summary.load(path, topics=PLOT_TOPICS)`).
PLOT_TOPICS = ("/joints", *(f"/cylinder/{joint}" for joint in JOINTS), "/pile/bucket",
               "/pile/profile")


def save_figure(fig: Figure, path: Path) -> Path:
    """Write `fig` to `path` as PNG, close it (pyplot keeps open figures alive) and return path."""
    fig.savefig(path, dpi=110)
    pyplot().close(fig)
    return path


def write_plots(run: RunFile, folder: str | Path, period: int | Sequence[int] = 1) -> list[Path]:
    """Write every figure the run log has data for into `folder` (created) and return the
    files: period_<k>_joints.png and period_<k>_cylinder_pressures.png for period `period`
    (or for each of several periods, e.g. range(1, len(run.periods) + 1)), weight_error.png,
    tip_paths.png, pile_profiles.png and productivity.png (payload, fill factor, t/h, kJ/t per
    period; logs with the figures). `run` must have been read with topics=PLOT_TOPICS;
    ValueError if it holds no period or not `period`."""
    n = len(run.periods)
    periods = [period] if isinstance(period, int) else list(period)
    for k in periods:
        if not 1 <= k <= n:
            held = f"periods 1-{n}" if n else "no complete period"
            raise ValueError(f"period {k}: the run log holds {held}")
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    written = []
    for k in periods:
        written.append(save_figure(plot_joints(run, k), folder / f"period_{k:02d}_joints.png"))
        if all(f"/cylinder/{joint}" in run.channels for joint in JOINTS):
            written.append(save_figure(plot_cylinder_pressures(run, k),
                                       folder / f"period_{k:02d}_cylinder_pressures.png"))
    written.append(save_figure(plot_weight_error(run), folder / "weight_error.png"))
    if "/pile/bucket" in run.channels:
        written.append(save_figure(plot_tip_paths(run), folder / "tip_paths.png"))
    if "/pile/profile" in run.channels:
        written.append(save_figure(plot_pile_profiles(run), folder / "pile_profiles.png"))
    if has_productivity(run):
        written.append(save_figure(plot_productivity(run), folder / "productivity.png"))
    return written
