"""The cylinder-pressure figure of one period: both chamber pressures of each cylinder, with
the via-point times and the spans in which the bucket is in the soil."""

from __future__ import annotations

from typing import TYPE_CHECKING

from orchestrator.review.plots_common import (
    JOINTS,
    LIMIT_COLOUR,
    PA_PER_BAR,
    SOIL_COLOUR,
    VIA_COLOUR,
    pyplot,
    record,
    soil_spans,
    via_times,
)
from orchestrator.runlog import RunFile

if TYPE_CHECKING:
    from matplotlib.figure import Figure

_CHAMBERS = (("p_A_Pa", "p_A (cap side)", "tab:blue"), ("p_B_Pa", "p_B (rod side)", "tab:purple"))


def plot_cylinder_pressures(run: RunFile, k: int) -> Figure:
    """Period k: both chamber pressures of each cylinder (bar), the relief pressure when the
    scenario sets one, grey lines at the via-point times and shading where the bucket is in the
    soil (`soil_spans`). One legend for the figure, beside the axes."""
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    plt = pyplot()
    period = record(run, k)
    fig, axes = plt.subplots(len(JOINTS), 1, figsize=(9.5, 8.5), sharex=True,
                             layout="constrained")
    plant = run.scenario.get("plant", {})
    spans = soil_spans(run, k)
    vias = via_times(period)
    handles: dict[str, object] = {}
    for ax, joint in zip(axes, JOINTS, strict=True):
        samples = run.channels[f"/cylinder/{joint}"].of_period(k)
        t = samples["t_s"] - period["t0_s"]
        for start, end in spans:
            ax.axvspan(start, end, color=SOIL_COLOUR, alpha=0.35, lw=0, zorder=0)
        for via in vias:
            ax.axvline(via, color=VIA_COLOUR, lw=0.8, zorder=1)
        for name, label, colour in _CHAMBERS:
            if name in samples:
                (handles[label],) = ax.plot(t, samples[name] / PA_PER_BAR, color=colour,
                                            lw=1.0, label=label)
        relief = plant.get(joint, {}).get("parameters", {}).get("p_relief")
        if isinstance(relief, int | float):
            handles["relief pressure"] = ax.axhline(relief / PA_PER_BAR, color=LIMIT_COLOUR,
                                                    ls=":", lw=1.0, label="relief pressure")
        ax.set_ylabel(f"{joint} (bar)")
        ax.grid(alpha=0.3)
    handles["via-point"] = Line2D([], [], color=VIA_COLOUR, lw=0.8, label="via-point")
    if spans:
        handles["bucket in the soil"] = Patch(color=SOIL_COLOUR, alpha=0.35,
                                              label="bucket in the soil\n(tip below the surface)")
    axes[-1].set_xlabel("time from the period's start (s)")
    # Beside the axes: above them it would collide with the suptitle in constrained layout.
    fig.legend(handles=list(handles.values()), loc="outside right upper", fontsize="small")
    fig.suptitle(f"Period {k}: cylinder chamber pressures")
    return fig
