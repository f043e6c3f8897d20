"""The weight-error figures: one run's error per period (paper Fig. 9) and several runs'
errors on one axis (`excosim compare`), with their run labels."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from orchestrator.review.plots_common import pyplot
from orchestrator.review.summary import band_kg, target_mass_kg
from orchestrator.runlog import RunFile

if TYPE_CHECKING:
    from matplotlib.figure import Figure

RESET_COLOUR = "tab:red"
# Run colours: the tab10 cycle without its red (resets) and green (the on-target band).
_RUN_COLOURS = ("tab:blue", "tab:orange", "tab:purple", "tab:brown", "tab:pink", "tab:gray",
                "tab:olive", "tab:cyan")
_MAX_LABEL_KEYS = 3  # differing scenario keys named in a label; more are counted, not named
# Free text: it differs between scenarios without telling what the runs do differently.
_UNLABELLED_KEYS = ("name", "description")


def integer_periods(ax, last_k: int) -> None:
    """Ticks at whole periods only: every period up to 30, else a whole-number spacing."""
    from matplotlib.ticker import MaxNLocator, MultipleLocator

    ax.xaxis.set_major_locator(MultipleLocator(1) if last_k <= 30
                               else MaxNLocator(integer=True))


def plot_weight_error(run: RunFile) -> Figure:
    """Weight error m* - m per period with the on-target band (+-3 kg at m* = 30 kg) and
    resets marked (paper Fig. 9)."""
    plt = pyplot()
    k = np.array([r["k"] for r in run.periods])
    error = np.array([r["error_kg"] for r in run.periods])
    fig, ax = plt.subplots(figsize=(8, 4.5), layout="constrained")
    band = band_kg(target_mass_kg(run))
    ax.axhspan(-band, band, color="tab:green", alpha=0.12, label=f"±{band:g} kg")
    ax.axhline(0.0, color="0.4", lw=0.8)
    ax.plot(k, error, "o-", color="tab:blue", label="m* − m")
    resets = [r["k"] for r in run.periods if r.get("reset")]
    for i, reset in enumerate(resets):
        ax.axvline(reset, color=RESET_COLOUR, ls="--", lw=0.8,
                   label="reset (D moved)" if i == 0 else None)
    ax.set_xlabel("digging period k")
    ax.set_ylabel("dug weight error (kg)")
    integer_periods(ax, int(k.max(initial=1)))
    ax.grid(alpha=0.3)
    ax.legend()
    ax.set_title(f"Dug weight error per period (target m* = {target_mass_kg(run):g} kg)")
    return fig


def _flatten(tree: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    """{"plant": {"load_cell_noise_kg": 0.5}} -> {"plant.load_cell_noise_kg": 0.5}."""
    flat: dict[str, Any] = {}
    for key, value in tree.items():
        if isinstance(value, dict):
            flat.update(_flatten(value, f"{prefix}{key}."))
        else:
            flat[f"{prefix}{key}"] = value
    return flat


def _value(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:g}"
    if isinstance(value, list):
        return "[" + ", ".join(_value(v) for v in value) + "]"
    return str(value)


def run_labels(runs: list[RunFile], names: list[str] | None = None) -> list[str]:
    """Legend labels that tell the runs apart: each run's scenario name and the resolved
    scenario keys whose values differ between the runs (e.g. "paper-2020,
    plant.load_cell_noise_kg=0.5"), at most _MAX_LABEL_KEYS of them named. Runs whose labels
    still coincide (one scenario run twice) get their log's file name appended, and, if that
    coincides too, their entry of `names` (the caller's names of the runs, e.g. `excosim
    compare`'s a/run, b/run) or else their number."""
    scenarios = [_flatten(run.scenario) for run in runs]
    keys = sorted({key for scenario in scenarios for key in scenario} - set(_UNLABELLED_KEYS))
    missing = object()  # a key one scenario lacks differs from any value another one has
    differing = [key for key in keys
                 if len({repr(s.get(key, missing)) for s in scenarios}) > 1]
    labels = []
    for run, scenario in zip(runs, scenarios, strict=True):
        parts = [str(scenario.get("name", run.path.stem))]
        parts += [f"{key}={_value(scenario[key])}" for key in differing[:_MAX_LABEL_KEYS]
                  if key in scenario]
        if len(differing) > _MAX_LABEL_KEYS:
            parts.append(f"+{len(differing) - _MAX_LABEL_KEYS} more keys")
        labels.append(", ".join(parts))
    labels = _disambiguate(labels, [f" ({run.path.name})" for run in runs])
    last = names if names is not None else [f"#{i}" for i in range(1, len(runs) + 1)]
    return _disambiguate(labels, [f" {name}" for name in last])


def _disambiguate(labels: list[str], suffixes: list[str]) -> list[str]:
    """labels with its suffix appended to every label that occurs more than once."""
    return [label + suffix if labels.count(label) > 1 else label
            for label, suffix in zip(labels, suffixes, strict=True)]


def plot_error_overlay(runs: list[RunFile], names: list[str] | None = None) -> Figure:
    """Weight error per period of several runs on one axis (`excosim compare`), resets ringed,
    m* in the title, runs labelled by `run_labels(runs, names)`: by what differs between their
    scenarios, not by file paths (names only tell apart runs that nothing else does)."""
    from matplotlib.lines import Line2D

    plt = pyplot()
    labels = run_labels(runs, names)
    fig, ax = plt.subplots(figsize=(9, 5), layout="constrained")
    targets = [target_mass_kg(run) for run in runs]
    if len(set(targets)) == 1:  # runs with different targets have different bands: draw none
        band = band_kg(targets[0])
        ax.axhspan(-band, band, color="tab:green", alpha=0.12, label=f"±{band:g} kg (10 % of m*)")
        title = f"Dug weight error per period, target m* = {targets[0]:g} kg"
    else:
        labels = [f"{label}, m* = {m:g} kg" for label, m in zip(labels, targets, strict=True)]
        title = "Dug weight error per period (targets m* differ: see the legend)"
    ax.axhline(0.0, color="0.4", lw=0.8)
    any_reset = False
    for i, (run, label) in enumerate(zip(runs, labels, strict=True)):
        k = [r["k"] for r in run.periods]
        error = [r["error_kg"] for r in run.periods]
        (line,) = ax.plot(k, error, "o-", ms=4, lw=1.0, label=label,
                          color=_RUN_COLOURS[i % len(_RUN_COLOURS)])
        resets = [(r["k"], r["error_kg"]) for r in run.periods if r.get("reset")]
        if resets:
            any_reset = True
            # Rings around the run's own points: runs can reset in different periods.
            ax.plot(*zip(*resets, strict=True), "o", ms=11, mfc="none", color=RESET_COLOUR,
                    mew=1.5, zorder=3)
            for reset_k, _ in resets:
                ax.axvline(reset_k, color=line.get_color(), ls="--", lw=0.7, alpha=0.7)
    handles, _ = ax.get_legend_handles_labels()
    if any_reset:
        handles.append(Line2D([], [], ls="--", marker="o", ms=11, mfc="none", mec=RESET_COLOUR,
                              mew=1.5, color="0.4", lw=0.7, label="reset (D moved)"))
    ax.set_xlabel("digging period k")
    ax.set_ylabel("dug weight error m* − m (kg)")
    integer_periods(ax, max((r["k"] for run in runs for r in run.periods), default=1))
    ax.grid(alpha=0.3)
    fig.legend(handles=handles, loc="outside lower center", ncol=2, fontsize="small")
    ax.set_title(title)
    return fig
