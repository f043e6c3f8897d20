"""The pile figures: bucket-tip paths with the planned and the reached deepest points (paper
Fig. 10) and the pile's shape (paper Fig. 11)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from orchestrator.review.plots_common import SOIL_COLOUR, pyplot, record
from orchestrator.runlog import RunFile

if TYPE_CHECKING:
    from matplotlib.figure import Figure

PAPER_TIP_PATH_PERIODS = (1, 3, 5, 7, 11, 13, 15, 17)  # the periods of the paper's Figure 10
# The pile figure's axes are about this much taller than wide; a vertical stretch beyond this
# factor (times 1.5) is worth the distortion, below it the true shape (equal scales) is drawn.
_PROFILE_BOX_RATIO = 0.42


def tip_path_periods(n_periods: int) -> list[int]:
    """The periods the tip-path figure shows: the paper's Figure-10 periods the run has (at
    least two of them), else up to 8 periods spread over the run."""
    paper = [k for k in PAPER_TIP_PATH_PERIODS if k <= n_periods]
    if len(paper) >= 2:
        return paper
    return sorted({int(k) for k in np.linspace(1, n_periods, min(8, n_periods)).round()})


def lowest_tip_point(run: RunFile, k: int) -> tuple[float, float] | None:
    """(y, z) of the lowest bucket-tip sample of period k (/pile/bucket tip_y_m, tip_z_m): the
    deepest point the bucket really reached, to set beside the planned D. None without samples."""
    samples = run.channels["/pile/bucket"].of_period(k)
    if not len(samples["tip_z_m"]):
        return None
    i = int(np.argmin(samples["tip_z_m"]))
    return float(samples["tip_y_m"][i]), float(samples["tip_z_m"][i])


def plot_tip_paths(run: RunFile) -> Figure:
    """Bucket-tip paths of several periods over the pile surface after the last of them, with
    each period's planned deepest point D (x) and the lowest point its tip reached (triangle)
    (paper Fig. 10). Equal scales: the paths are shapes in the vertical plane."""
    from matplotlib.lines import Line2D

    plt = pyplot()
    tips = run.channels["/pile/bucket"]
    periods = tip_path_periods(len(run.periods))
    fig, ax = plt.subplots(figsize=(10, 5), layout="constrained")
    profile = run.channels.get("/pile/profile")
    handles = []
    if profile is not None:
        surface = profile.of_period(periods[-1])
        if len(surface["z_m"]):
            handles.append(ax.fill_between(
                surface["y_m"][-1], surface["z_m"][-1], surface["z_m"][-1].min() - 0.5,
                color=SOIL_COLOUR, alpha=0.5, label=f"pile after period {periods[-1]}"))
    colours = plt.get_cmap("viridis")(np.linspace(0.0, 0.9, len(periods)))
    for colour, k in zip(colours, periods, strict=True):
        path = tips.of_period(k)
        handles += ax.plot(path["tip_y_m"], path["tip_z_m"], color=colour, lw=1.2,
                           label=f"period {k}")
        y_d, z_d = record(run, k)["deepest_point_m"]
        ax.plot([y_d], [z_d], "x", color=colour, ms=8, mew=2.0, label=f"D, period {k}")
        lowest = lowest_tip_point(run, k)
        if lowest is not None:
            ax.plot([lowest[0]], [lowest[1]], "v", color=colour, mec="black", mew=0.6, ms=7,
                    label=f"lowest tip, period {k}")
    # One legend entry per marker kind (black stand-ins), not one per period and marker.
    handles += [Line2D([], [], ls="", marker="x", color="black", ms=8, mew=2.0,
                       label="D: planned deepest point"),
                Line2D([], [], ls="", marker="v", color="0.6", mec="black", mew=0.6, ms=7,
                       label="lowest tip point reached")]
    ax.set_xlabel("y (m, horizontal; the machine is at y = 0)")
    ax.set_ylabel("z (m, up; ground at 0)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(alpha=0.3)
    fig.legend(handles=handles, loc="outside right upper", fontsize="small")
    ax.set_title("Bucket-tip paths: planned deepest point D and lowest tip point per period")
    return fig


def pile_profile_periods(n_periods: int) -> list[int]:
    """Period 10 (when the run reached it) and the last period (paper Fig. 11)."""
    return sorted({k for k in (10, n_periods) if k <= n_periods})


def vertical_stretch(y: np.ndarray, z: np.ndarray) -> int:
    """Integer vertical scale for a surface over y with heights z: 1 (equal scales) unless the
    surface is so flat that equal scales would leave its shape unreadable, then the whole
    factor that fills an axes box about _PROFILE_BOX_RATIO as tall as wide."""
    y_span = float(np.ptp(y)) if len(y) else 1.0
    z_span = max(float(np.ptp(z)) if len(z) else 0.0, 1e-3)  # a flat surface: still finite
    fill = _PROFILE_BOX_RATIO * y_span / (1.2 * z_span)  # 1.2: room above and below the data
    return 1 if fill < 1.5 else int(fill)


def plot_pile_profiles(run: RunFile) -> Figure:
    """Pile surface after period 10 and after the last period (paper Fig. 11), at equal scales
    or, for a shallow pile, at an integer vertical stretch named in the axis label."""
    plt = pyplot()
    profile = run.channels["/pile/profile"]
    fig, ax = plt.subplots(figsize=(9, 4.5), layout="constrained")
    ys, zs = [], []
    periods = pile_profile_periods(len(run.periods))
    for k in periods:
        style = "-" if k == periods[-1] else "--"  # the last surface solid, an earlier dashed
        surface = profile.of_period(k)
        if not len(surface["z_m"]):
            continue
        ys.append(surface["y_m"][-1])
        zs.append(surface["z_m"][-1])
        ax.plot(ys[-1], zs[-1], style, lw=1.4, label=f"after period {k}")
    stretch = vertical_stretch(np.concatenate(ys or [np.empty(0)]),
                               np.concatenate(zs or [np.empty(0)]))
    # A fixed ratio of data units makes the stretch what the label says, whatever the size.
    ax.set_aspect(stretch, adjustable="datalim")
    ax.set_xlabel("y (m, horizontal)")
    scale = "equal scales" if stretch == 1 else f"vertical scale × {stretch}"
    ax.set_ylabel(f"surface height z (m)\n{scale}")
    ax.grid(alpha=0.3)
    ax.legend(loc="best")  # the lines are all it could cover; "best" avoids them
    ax.set_title("Shape of the pile" + ("" if stretch == 1 else f" (vertical scale × {stretch})"))
    return fig
