"""The productivity figure: per period, the payload and the bucket's fill factor, the
productivity (t per hour of digging) and the hydraulic energy per tonne dug, from the /period
records (formulas: orchestrator.campaign.productivity)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from orchestrator.review.plots_common import pyplot
from orchestrator.review.plots_weight import RESET_COLOUR, integer_periods
from orchestrator.review.productivity import run_productivity
from orchestrator.runlog import RunFile

if TYPE_CHECKING:
    from matplotlib.figure import Figure


def has_productivity(run: RunFile) -> bool:
    """The run's records carry the productivity figures (logs before them do not)."""
    return bool(run.periods) and all("cycle_time_s" in r for r in run.periods)


def _column(run: RunFile, key: str) -> np.ndarray:
    """(n,) the key's value per period, NaN where a record lacks it (drawn as a gap)."""
    return np.array([r.get(key, np.nan) for r in run.periods], dtype=float)


def plot_productivity(run: RunFile) -> Figure:
    """Three panels over the digging period k: payload (kg) with the fill factor on a second
    scale, productivity (t/h) with the run's as a dashed line, and hydraulic energy per tonne
    (kJ/t, log scale: a period that digs little costs orders of magnitude more per tonne) with
    the run's; resets marked. Panels whose figures the log lacks say so."""
    plt = pyplot()
    k = np.array([r["k"] for r in run.periods])
    totals = run_productivity(run.periods)
    fig, (mass, rate, energy) = plt.subplots(3, 1, figsize=(8, 8.5), sharex=True,
                                              layout="constrained")
    mass.bar(k, _column(run, "mass_kg"), color="tab:blue", alpha=0.7, label="payload")
    mass.set_ylabel("payload (kg)")
    rated = [r["rated_payload_kg"] for r in run.periods if "rated_payload_kg" in r]
    if rated:
        fill = mass.twinx()
        fill.plot(k, _column(run, "fill_factor"), "o-", color="tab:orange", label="fill factor")
        fill.set_ylabel(f"fill factor (of {rated[0]:.3g} kg rated)", color="tab:orange")
        fill.set_ylim(0.0, max(1.05, float(np.nanmax(_column(run, "fill_factor"))) * 1.05))
    mass.set_title("Payload and fill factor per period")
    rate.plot(k, _column(run, "productivity_t_h"), "o-", color="tab:purple", label="period")
    if totals["productivity_t_h"] is not None:
        rate.axhline(totals["productivity_t_h"], color="tab:purple", ls="--", lw=0.9,
                     label=f"run: {totals['productivity_t_h']:.2f} t/h")
    rate.set_ylabel("productivity (t/h of digging)")
    per_tonne = _column(run, "energy_per_tonne_kj_t")
    if np.isfinite(per_tonne).any():
        energy.semilogy(k, per_tonne, "o-", color="tab:brown", label="period")
        if totals["energy_per_tonne_kj_t"] is not None:
            energy.axhline(totals["energy_per_tonne_kj_t"], color="tab:brown", ls="--", lw=0.9,
                           label=f"run: {totals['energy_per_tonne_kj_t']:.0f} kJ/t")
        energy.legend(loc="best")
    else:
        energy.text(0.5, 0.5, "no hydraulic energy in this log (a cylinder books no E_supply)",
                    ha="center", va="center", transform=energy.transAxes, color="0.4")
    energy.set_ylabel("hydraulic energy per tonne (kJ/t)")
    energy.set_xlabel("digging period k")
    for i, reset in enumerate(r["k"] for r in run.periods if r.get("reset")):
        for ax in (mass, rate, energy):
            ax.axvline(reset, color=RESET_COLOUR, ls="--", lw=0.8,
                       label="reset (D moved)" if i == 0 and ax is rate else None)
    for ax in (mass, rate, energy):
        ax.grid(alpha=0.3)
    rate.legend(loc="best")
    integer_periods(energy, int(k.max(initial=1)))
    fig.suptitle(f"Productivity of {run.metadata['excosim.run'].get('scenario_name', 'the run')}")
    return fig
