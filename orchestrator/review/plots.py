"""PNG figures of a run log, in the spirit of the paper's Figures 7-11, drawn from the file alone.

`write_plots(run, folder, period)` writes every figure the file has data for and returns what it
wrote; each `plot_*` function draws one figure and returns the matplotlib Figure (a caller may
save or show it). Angles in degrees, pressures in bar, lengths in m, masses in kg.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from orchestrator.campaign.record import reference_spline
from orchestrator.review.summary import band_kg, target_mass_kg
from orchestrator.runlog import RunFile
from plant_models.plant import JOINTS

# Topics the figures read (`orchestrator.review.summary.load(path, topics=PLOT_TOPICS)`).
PLOT_TOPICS = ("/joints", *(f"/cylinder/{joint}" for joint in JOINTS), "/pile/bucket",
               "/pile/profile")
PAPER_TIP_PATH_PERIODS = (1, 3, 5, 7, 11, 13, 15, 17)  # the periods of the paper's Figure 10
_COLOURS = {"boom": "tab:blue", "stick": "tab:orange", "bucket": "tab:green"}
_PA_PER_BAR = 1e5


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")  # files only; never needs a display
    import matplotlib.pyplot as plt

    return plt


def _record(run: RunFile, k: int) -> dict[str, Any]:
    return run.periods[k - 1]


def plot_joints(run: RunFile, k: int):
    """Period k: planned (dashed) and measured joint angles, and the planned velocity,
    acceleration and jerk with the scenario's limits (paper Figs. 7-8)."""
    plt = _pyplot()
    record = _record(run, k)
    reference = reference_spline(record)
    t = np.linspace(0.0, record["duration_s"], 1000)
    limits = run.scenario.get("limits", {})
    rows = (("angle (deg)", None), ("velocity (deg/s)", "velocity_deg_s"),
            ("acceleration (deg/s²)", "acceleration_deg_s2"), ("jerk (deg/s³)", "jerk_deg_s3"))
    fig, axes = plt.subplots(len(rows), 1, figsize=(8, 10), sharex=True, layout="constrained")
    measured = run.channels.get("/joints")
    samples = measured.of_period(k) if measured is not None else {}
    via_times = np.concatenate([[0.0], np.cumsum(record["segment_durations_s"])])
    for order, (ax, (label, limit_key)) in enumerate(zip(axes, rows, strict=True)):
        values = np.degrees(reference(t, nu=order))
        for j, joint in enumerate(JOINTS):
            ax.plot(t, values[:, j], color=_COLOURS[joint], ls="--" if order == 0 else "-",
                    lw=1.2, label=f"{joint} planned" if order == 0 else joint)
            if order == 0 and f"measured_{joint}_rad" in samples:
                ax.plot(samples["t_s"] - record["t0_s"],
                        np.degrees(samples[f"measured_{joint}_rad"]), color=_COLOURS[joint],
                        lw=0.8, alpha=0.8, label=f"{joint} measured")
            if limit_key and limit_key in limits:
                bound = limits[limit_key][j]
                ax.axhline(bound, color=_COLOURS[joint], ls=":", lw=0.8)
                ax.axhline(-bound, color=_COLOURS[joint], ls=":", lw=0.8)
        for via in via_times:
            ax.axvline(via, color="0.7", lw=0.5)
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    axes[0].legend(ncol=2, fontsize="small")
    axes[-1].set_xlabel("time from the period's start (s); grey lines: via-points; "
                        "dotted: limits")
    fig.suptitle(f"Period {k}: joint trajectory, duration {record['duration_s']:.2f} s, "
                 f"peak jerk {max(record['max_abs_jerk_deg_s3']):.1f} deg/s³")
    return fig


def plot_weight_error(run: RunFile):
    """Weight error m* - m per period with the on-target band (+-3 kg at m* = 30 kg) and
    resets marked (paper Fig. 9)."""
    plt = _pyplot()
    k = np.array([r["k"] for r in run.periods])
    error = np.array([r["error_kg"] for r in run.periods])
    fig, ax = plt.subplots(figsize=(8, 4.5), layout="constrained")
    band = band_kg(target_mass_kg(run))
    ax.axhspan(-band, band, color="tab:green", alpha=0.12, label=f"±{band:g} kg")
    ax.axhline(0.0, color="0.4", lw=0.8)
    ax.plot(k, error, "o-", color="tab:blue", label="m* − m")
    for r in run.periods:
        if r.get("reset"):
            ax.axvline(r["k"], color="tab:red", ls="--", lw=0.8)
            ax.annotate("reset", (r["k"], ax.get_ylim()[1]), color="tab:red", ha="center",
                        va="top", fontsize="small")
    ax.set_xlabel("digging period k")
    ax.set_ylabel("dug weight error (kg)")
    ax.set_xticks(k if len(k) <= 30 else np.linspace(k[0], k[-1], 10).round())
    ax.grid(alpha=0.3)
    ax.legend()
    ax.set_title(f"Dug weight error per period (target m* = {target_mass_kg(run):g} kg)")
    return fig


def tip_path_periods(n_periods: int) -> list[int]:
    """The periods the tip-path figure shows: the paper's Figure-10 periods the run has (at
    least two of them), else up to 8 periods spread over the run."""
    paper = [k for k in PAPER_TIP_PATH_PERIODS if k <= n_periods]
    if len(paper) >= 2:
        return paper
    return sorted({int(k) for k in np.linspace(1, n_periods, min(8, n_periods)).round()})


def plot_tip_paths(run: RunFile):
    """Bucket-tip paths of several periods over the pile surface after the last of them, with
    each period's deepest point D (paper Fig. 10)."""
    plt = _pyplot()
    tips = run.channels["/pile/bucket"]
    periods = tip_path_periods(len(run.periods))
    fig, ax = plt.subplots(figsize=(9, 5), layout="constrained")
    profile = run.channels.get("/pile/profile")
    if profile is not None:
        surface = profile.of_period(periods[-1])
        if len(surface["z_m"]):
            ax.fill_between(surface["y_m"][-1], surface["z_m"][-1], surface["z_m"][-1].min()
                            - 0.5, color="tan", alpha=0.5,
                            label=f"pile after period {periods[-1]}")
    colours = plt.get_cmap("viridis")(np.linspace(0.0, 0.9, len(periods)))
    for colour, k in zip(colours, periods, strict=True):
        path = tips.of_period(k)
        ax.plot(path["tip_y_m"], path["tip_z_m"], color=colour, lw=1.2, label=f"period {k}")
        y_d, z_d = _record(run, k)["deepest_point_m"]
        ax.plot([y_d], [z_d], "x", color=colour, ms=7)
    ax.set_xlabel("y (m, horizontal; the machine is at y = 0)")
    ax.set_ylabel("z (m, up; ground at 0)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(alpha=0.3)
    ax.legend(fontsize="small", ncol=2)
    ax.set_title("Bucket-tip paths (x: the period's deepest point D)")
    return fig


def pile_profile_periods(n_periods: int) -> list[int]:
    """Period 10 (when the run reached it) and the last period (paper Fig. 11)."""
    return sorted({k for k in (10, n_periods) if k <= n_periods})


def plot_pile_profiles(run: RunFile):
    """Pile surface after period 10 and after the last period (paper Fig. 11)."""
    plt = _pyplot()
    profile = run.channels["/pile/profile"]
    fig, ax = plt.subplots(figsize=(9, 4.5), layout="constrained")
    for k, style in zip(pile_profile_periods(len(run.periods)), ("--", "-"), strict=False):
        surface = profile.of_period(k)
        ax.plot(surface["y_m"][-1], surface["z_m"][-1], style, lw=1.4,
                label=f"after period {k}")
    ax.set_xlabel("y (m, horizontal)")
    ax.set_ylabel("surface height z (m)")
    ax.grid(alpha=0.3)
    ax.legend()
    ax.set_title("Shape of the pile")
    return fig


def plot_cylinder_pressures(run: RunFile, k: int):
    """Period k: both chamber pressures of each cylinder (bar), with its relief pressure when
    the scenario sets one."""
    plt = _pyplot()
    record = _record(run, k)
    fig, axes = plt.subplots(len(JOINTS), 1, figsize=(8, 8), sharex=True, layout="constrained")
    plant = run.scenario.get("plant", {})
    for ax, joint in zip(axes, JOINTS, strict=True):
        samples = run.channels[f"/cylinder/{joint}"].of_period(k)
        t = samples["t_s"] - record["t0_s"]
        for name, label in (("p_A_Pa", "p_A (cap side)"), ("p_B_Pa", "p_B (rod side)")):
            if name in samples:
                ax.plot(t, samples[name] / _PA_PER_BAR, lw=1.0, label=label)
        relief = plant.get(joint, {}).get("parameters", {}).get("p_relief")
        if isinstance(relief, int | float):
            ax.axhline(relief / _PA_PER_BAR, color="tab:red", ls=":", lw=0.8, label="relief")
        ax.set_ylabel(f"{joint} (bar)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize="small", loc="upper right")
    axes[-1].set_xlabel("time from the period's start (s)")
    fig.suptitle(f"Period {k}: cylinder chamber pressures")
    return fig


def plot_error_overlay(runs: list[RunFile], labels: list[str]):
    """Weight error per period of several runs on one axis (`excosim compare`)."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(8, 4.5), layout="constrained")
    bands = {band_kg(target_mass_kg(run)) for run in runs}
    if len(bands) == 1:  # runs with different targets have different bands: draw none
        band = bands.pop()
        ax.axhspan(-band, band, color="tab:green", alpha=0.12, label=f"±{band:g} kg")
    ax.axhline(0.0, color="0.4", lw=0.8)
    for run, label in zip(runs, labels, strict=True):
        ax.plot([r["k"] for r in run.periods], [r["error_kg"] for r in run.periods], "o-",
                ms=4, lw=1.0, label=label)
    ax.set_xlabel("digging period k")
    ax.set_ylabel("dug weight error m* − m (kg)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize="small")
    ax.set_title("Dug weight error per period")
    return fig


def save_figure(fig, path: Path) -> Path:
    fig.savefig(path, dpi=110)
    _pyplot().close(fig)
    return path


def write_plots(run: RunFile, folder: str | Path, period: int = 1) -> list[Path]:
    """Write every figure the run log has data for into `folder` (created) and return the
    files: period_<k>_joints.png and period_<k>_cylinder_pressures.png for period `period`,
    weight_error.png, tip_paths.png and pile_profiles.png. `run` must have been read with
    topics=PLOT_TOPICS; ValueError if it holds no period or not `period`."""
    n = len(run.periods)
    if not 1 <= period <= n:
        held = f"periods 1-{n}" if n else "no complete period"
        raise ValueError(f"period {period}: the run log holds {held}")
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    tag = f"period_{period:02d}"
    written = [save_figure(plot_joints(run, period), folder / f"{tag}_joints.png"),
               save_figure(plot_weight_error(run), folder / "weight_error.png")]
    if "/pile/bucket" in run.channels:
        written.append(save_figure(plot_tip_paths(run), folder / "tip_paths.png"))
    if "/pile/profile" in run.channels:
        written.append(save_figure(plot_pile_profiles(run), folder / "pile_profiles.png"))
    if all(f"/cylinder/{joint}" in run.channels for joint in JOINTS):
        written.append(save_figure(plot_cylinder_pressures(run, period),
                             folder / f"{tag}_cylinder_pressures.png"))
    return written

