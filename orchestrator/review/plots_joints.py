"""The joint figure of one period (paper Figs. 7-8): planned and measured angles, the tracking
error, and the planned velocity, acceleration and jerk against the scenario's limits."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from orchestrator.campaign.record import reference_spline
from orchestrator.review.plots_common import (
    COLOURS,
    JOINTS,
    LIMIT_COLOUR,
    VIA_COLOUR,
    pyplot,
    record,
    via_times,
)
from orchestrator.runlog import RunFile

if TYPE_CHECKING:
    from matplotlib.figure import Figure

# Rows below the angle and its tracking error: (y label, key of the limit in [limits], order of
# the derivative of the planned spline).
_DERIVATIVE_ROWS = (("planned velocity (deg/s)", "velocity_deg_s", 1),
                    ("planned acceleration (deg/s²)", "acceleration_deg_s2", 2),
                    ("planned jerk (deg/s³)", "jerk_deg_s3", 3))


def tracking_error_deg(run: RunFile, k: int) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Period k's sample times (s from the period's start) and, per joint, the tracking error
    measured minus reference (deg) of the /joints samples: the reference the servo was given
    at that sample, as logged. Empty arrays when the log has no /joints samples."""
    channel = run.channels.get("/joints")
    if channel is None:
        return np.empty(0), {}
    samples = channel.of_period(k)
    t = samples["t_s"] - record(run, k)["t0_s"]
    errors = {joint: np.degrees(samples[f"measured_{joint}_rad"]
                                - samples[f"reference_{joint}_rad"])
              for joint in JOINTS if f"measured_{joint}_rad" in samples}
    return t, errors


def _draw_limits(ax, bounds: list[float]) -> None:
    """+-limit lines in the limit colour; joints that share a bound share one pair of lines,
    and when the joints' bounds differ each pair is named by its joints."""
    groups: dict[float, list[str]] = {}
    for joint, bound in zip(JOINTS, bounds, strict=True):
        groups.setdefault(float(bound), []).append(joint)
    for bound, joints in groups.items():
        for sign in (1.0, -1.0):
            ax.axhline(sign * bound, color=LIMIT_COLOUR, ls="-.", lw=0.9)
        if len(groups) > 1:
            ax.annotate(f"{', '.join(joints)} ±{bound:g}", (0.995, bound),
                        xycoords=("axes fraction", "data"), ha="right", va="bottom",
                        color=LIMIT_COLOUR, fontsize="x-small")


def _legend_handles() -> list:
    from matplotlib.lines import Line2D

    handles = [Line2D([], [], color=COLOURS[joint], lw=2.0, label=joint) for joint in JOINTS]
    handles += [Line2D([], [], color="0.2", ls="--", lw=1.2, label="planned angle"),
                Line2D([], [], color="0.2", lw=2.2, alpha=0.45, label="measured angle"),
                Line2D([], [], color=LIMIT_COLOUR, ls="-.", lw=0.9, label="± limit"),
                Line2D([], [], color=VIA_COLOUR, lw=0.8, label="via-point")]
    return handles


def plot_joints(run: RunFile, k: int) -> Figure:
    """Period k: planned (dashed) and measured joint angles, the tracking error measured minus
    planned, and the planned velocity, acceleration and jerk with the scenario's limits (paper
    Figs. 7-8). The legend sits beside the axes, outside the data."""
    plt = pyplot()
    period = record(run, k)
    reference = reference_spline(period)
    t = np.linspace(0.0, period["duration_s"], 1000)
    limits = run.scenario.get("limits", {})
    fig, axes = plt.subplots(2 + len(_DERIVATIVE_ROWS), 1, figsize=(9.5, 12), sharex=True,
                             layout="constrained")
    angle_ax, error_ax, *derivative_axes = axes
    planned = np.degrees(reference(t))
    channel = run.channels.get("/joints")
    samples = channel.of_period(k) if channel is not None else {}
    t_error, errors = tracking_error_deg(run, k)
    for j, joint in enumerate(JOINTS):
        colour = COLOURS[joint]
        if f"measured_{joint}_rad" in samples:
            # Measured first, wide and translucent, so the dashed plan on top stays visible.
            angle_ax.plot(samples["t_s"] - period["t0_s"],
                          np.degrees(samples[f"measured_{joint}_rad"]), color=colour, lw=2.2,
                          alpha=0.45, label=f"{joint} measured")
        angle_ax.plot(t, planned[:, j], color=colour, ls="--", lw=1.0,
                      label=f"{joint} planned")
        if joint in errors:
            error_ax.plot(t_error, errors[joint], color=colour, lw=1.0,
                          label=f"{joint} tracking error")
    error_ax.axhline(0.0, color="0.4", lw=0.6)
    if not errors:
        error_ax.text(0.5, 0.5, "no measured joint samples in the log", ha="center",
                      va="center", transform=error_ax.transAxes, color="0.4")
    angle_ax.set_ylabel("angle (deg)")
    error_ax.set_ylabel("tracking error\nmeasured − planned (deg)")
    for ax, (label, limit_key, order) in zip(derivative_axes, _DERIVATIVE_ROWS, strict=True):
        values = np.degrees(reference(t, nu=order))
        for j, joint in enumerate(JOINTS):
            ax.plot(t, values[:, j], color=COLOURS[joint], lw=1.2, label=f"{joint} planned")
        if limit_key in limits:
            _draw_limits(ax, limits[limit_key])
        ax.set_ylabel(label)
    for ax in axes:
        for via in via_times(period):
            ax.axvline(via, color=VIA_COLOUR, lw=0.8, zorder=0)
        ax.grid(alpha=0.3)
    axes[-1].set_xlabel("time from the period's start (s)")
    # Beside the axes: above them it would collide with the suptitle in constrained layout.
    fig.legend(handles=_legend_handles(), loc="outside right upper", fontsize="small")
    fig.suptitle(f"Period {k}: joint trajectory, duration {period['duration_s']:.2f} s, "
                 f"peak planned jerk {max(period['max_abs_jerk_deg_s3']):.1f} deg/s³")
    return fig
