"""`excosim review` and `excosim compare`: read run logs and print what a person or a script needs.

Each command returns None on success or (one-line message, exit status): 2 for a file that is not
a readable excosim run log or an option that does not fit it (e.g. --period beyond the run).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

from rich import box
from rich.console import Console
from rich.table import Table

from orchestrator.cli.run import period_table
from orchestrator.review import summary as review
from orchestrator.runlog import RunLogError


def _console() -> Console:
    # Piped output has no terminal width; rich would assume 80 columns and cut the table.
    return Console(highlight=False, width=None if sys.stdout.isatty() else 120)


def review_run(path: Path, as_json: bool, plots: Path | None,
               period: int) -> tuple[str, int] | None:
    """Print the summary and period table of the run log at `path` (or one JSON object);
    with `plots`, write the figures there for period `period`."""
    from orchestrator.review.plots import PLOT_TOPICS, write_plots

    try:
        run = review.load(path, PLOT_TOPICS if plots is not None else ())
    except RunLogError as error:
        return str(error), 2
    if plots is not None and not 1 <= period <= len(run.periods):
        held = f"periods 1-{len(run.periods)}" if run.periods else "no complete period"
        return f"--period {period}: {path} holds {held}", 2
    data = review.summary(run)
    if as_json:
        print(json.dumps(data))
    else:
        out = _console()
        out.print(f"{data['scenario']} ({data['plant']} plant): {data['description']}",
                  markup=False, soft_wrap=True)
        out.print(f"target {data['target_mass_kg']:g} kg; {review.ending(data)}",
                  markup=False, soft_wrap=True)
        out.print(period_table(run.periods, data["target_mass_kg"]))
        out.print(_figures_line(data["figures"]), markup=False, soft_wrap=True)
    if plots is not None:
        try:
            written = write_plots(run, plots, period)
        except OSError as error:
            return f"--plots {plots}: cannot write the figures: {error.strerror or error}", 2
        print("\n".join(str(p) for p in written), file=sys.stderr if as_json else sys.stdout)
    return None


def _figures_line(figures: dict[str, Any]) -> str:
    if not figures["counted"]:
        return "no period after the first: no error figures"
    return (f"after period 1: mean |error| {figures['mean_abs_error_kg']:.2f} kg, max "
            f"{figures['max_abs_error_kg']:.2f} kg, within ±{figures['band_kg']:g} kg "
            f"{figures['within_band']}/{figures['counted']}; resets {figures['resets']}")


def _label(paths: list[Path]) -> list[str]:
    """Short, distinct names for the runs: file stems, or whole paths when stems repeat."""
    stems = [p.stem for p in paths]
    return stems if len(set(stems)) == len(stems) else [str(p) for p in paths]


def compare_runs(paths: list[Path], as_json: bool,
                 plots: Path | None) -> tuple[str, int] | None:
    """Print the per-run figures of several run logs side by side (or one JSON object:
    {"runs": [review summary without the period records, plus "label"]}); with `plots`, write
    the weight-error overlay there."""
    runs = []
    for path in paths:
        try:
            runs.append(review.load(path))
        except RunLogError as error:
            return str(error), 2
    labels = _label(paths)
    summaries = [review.summary(run) for run in runs]
    if as_json:
        rows = []
        for label, data in zip(labels, summaries, strict=True):
            row = {"label": label, **data}
            row["errors_kg"] = [r["error_kg"] for r in data["periods"]]
            del row["periods"]
            rows.append(row)
        print(json.dumps({"runs": rows}))
    else:
        _console().print(_compare_table(labels, summaries))
    if plots is not None:
        from orchestrator.review.plots import plot_error_overlay, save_figure

        try:
            Path(plots).mkdir(parents=True, exist_ok=True)
            written = save_figure(plot_error_overlay(runs, labels),
                            Path(plots) / "weight_error_compare.png")
        except OSError as error:
            return f"--plots {plots}: cannot write the figure: {error.strerror or error}", 2
        print(written, file=sys.stderr if as_json else sys.stdout)
    return None


def _number(value: float | None, digits: int = 2) -> str:
    return "–" if value is None else f"{value:.{digits}f}"


def _compare_table(labels: list[str], summaries: list[dict[str, Any]]) -> Table:
    table = Table(title="Runs side by side", box=box.SIMPLE_HEAD,
                  caption="errors after period 1; in band: periods 2.. within ±10 % of m* "
                  "(the paper's ±3 kg at 30 kg); duration: planned trajectory per period; peak "
                  "jerk: largest |jerk| of any joint in any period")
    for header in ("run", "scenario", "plant", "m* kg", "periods", "mean |err| kg",
                   "max |err| kg", "in band", "mean duration s", "peak jerk °/s³",
                   "resets", "ended"):
        left = header in ("run", "scenario", "ended")
        table.add_column(header, justify="left" if left else "right",
                         no_wrap=left or header == "in band")
    for label, data in zip(labels, summaries, strict=True):
        f = data["figures"]
        within = f"{f['within_band']}/{f['counted']} (±{f['band_kg']:g})" if f["counted"] else "–"
        ending = data["termination"] or ("killed" if data["truncated"] else "unfinished")
        table.add_row(label, data["scenario"], data["plant"], f"{data['target_mass_kg']:g}",
                      str(f["periods"]), _number(f["mean_abs_error_kg"]),
                      _number(f["max_abs_error_kg"]), within, _number(f["mean_duration_s"]),
                      _number(f["peak_jerk_deg_s3"], 1), str(f["resets"]), ending)
    return table
