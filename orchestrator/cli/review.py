"""`excosim review` and `excosim compare`: read run logs and print what a person or a script needs.

Each command returns None on success or (one-line message, exit status): 2 for a file that is not
a readable excosim run log or an option that does not fit it (e.g. --period beyond the run, a
--csv-channels topic the file lacks). Every check comes before anything is written.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rich.text import Text

from orchestrator.cli import export, tables
from orchestrator.cli.conventions import count, json_text
from orchestrator.cli.run_output import period_grid
from orchestrator.review import summary as review
from orchestrator.runlog import RunLogError


@dataclass
class CsvRequest:
    """What `review` writes as CSV: the period table to `periods` (None: not), the channels
    `topics` (TOPIC[,TOPIC] items) into `folder` (None: the current folder)."""

    periods: Path | None = None
    topics: list[str] = field(default_factory=list)
    folder: Path | None = None


def review_run(path: Path, as_json: bool, plots: Path | None, period: int | str | None,
               csv: CsvRequest | None = None) -> tuple[str, int] | None:
    """Print the summary and period table of the run log at `path` (or one JSON object);
    with `plots`, write the figures there for period `period` (a number, "all": every period;
    None: 1); with `csv`, write CSV files. The paths written go to stdout (to stderr with
    --json, which keeps stdout one object)."""
    from orchestrator.review.plots import PLOT_TOPICS, write_plots

    csv = csv or CsvRequest()
    if csv.folder is not None and not csv.topics:
        return "--csv-dir: give the channels to write with --csv-channels TOPIC[,TOPIC]", 2
    wanted = export.topics(csv.topics)
    try:
        run = review.load(path, PLOT_TOPICS if plots is not None else ())
        export.check_topics(run, wanted)
        channels = export.read_channels(path, wanted) if wanted else None
    except (RunLogError, export.ExportError) as error:
        return str(error), 2
    if period is not None and plots is None:
        return f"--period {period}: it picks the period of the --plots figures; add --plots DIR", 2
    if csv.periods is not None and not Path(csv.periods).parent.is_dir():
        return f"--csv {csv.periods}: the folder {Path(csv.periods).parent} does not exist", 2
    periods = figure_periods(period, len(run.periods), path) if plots is not None else []
    if isinstance(periods, str):
        return periods, 2
    data = review.summary(run)
    if as_json:
        print(json_text(data))
    else:
        out = tables.console()
        out.print(f"{data['scenario']} ({data['plant']} plant): {data['description']}",
                  markup=False, soft_wrap=True)
        resumed = data["resumed_after_period"]
        resumed = f" (resumed after period {resumed})" if resumed is not None else ""
        out.print(f"target {data['target_mass_kg']:g} kg; {review.ending(data)}{resumed}",
                  markup=False, soft_wrap=True)
        for line in role_lines(data):
            out.print(line, markup=False, soft_wrap=True)
        tables.show(out, period_grid(run.periods, data["target_mass_kg"]))
        out.print(_figures_line(data["figures"]), markup=False, soft_wrap=True)
        out.print(productivity_line(data["figures"], data["power_limit_kw"]), markup=False,
                  soft_wrap=True)
    written: list[Path] = []
    try:
        written += export.write(run, csv.periods, channels, wanted, Path(csv.folder or "."))
    except OSError as error:
        return f"--csv: cannot write: {error.strerror or error}", 2
    if plots is not None:
        try:
            written += write_plots(run, plots, periods)
        except OSError as error:
            return f"--plots {plots}: cannot write the figures: {error.strerror or error}", 2
    if written:
        print("\n".join(str(p) for p in written), file=sys.stderr if as_json else sys.stdout)
    return None


def figure_periods(period: int | str | None, n: int, path: Path) -> list[int] | str:
    """The periods of the per-period figures that `--period` picks (None: 1; "all": every
    one) in the log at `path` of `n` complete periods, or the one-line mistake."""
    if period is None or period == "all":
        wanted = list(range(1, n + 1)) if period == "all" else [1]
    else:
        try:
            wanted = [int(period)]
        except ValueError:
            return f"--period {period}: expected a period number K or all"
    if n and all(1 <= k <= n for k in wanted):
        return wanted
    held = {0: "no complete period", 1: "period 1 only"}.get(n, f"periods 1-{n}")
    return f"--period {period if period is not None else 1}: {path} holds {held}"


def role_lines(data: dict[str, Any]) -> list[str]:
    """One line per plant role (its FMU, short hash, parameter count) and the --set items."""
    lines = []
    for role, table in data["roles"].items():
        fmu = Path(str(table.get("fmu", ""))).name or table.get("file", "")
        digest = str(table.get("sha256", ""))[:12]
        derived = table.get("derived") or {}
        lines.append(f"  {role}: {fmu} (sha256 {digest}), "
                     f"{count(len(table.get('parameters', {})), 'parameter')} set"
                     + "".join(f"; {out} derived by the master" for out in derived)
                     + ("; arm coupling explicit" if str(table.get("arm_coupling", "")
                                                        ).startswith("explicit") else "")
                     + ("; arm inertia not fed" if str(table.get("arm_inertia", "")
                                                      ).startswith("not fed") else "")
                     + ("; off the shared pump" if str(table.get("supply", "")
                                                      ).startswith("its own supply") else ""))
    if data["overrides"]:
        lines.append("  --set " + " --set ".join(data["overrides"]))
    return lines


def _figures_line(figures: dict[str, Any]) -> str:
    if not figures["counted"]:
        return "no period after the first: no error figures"
    return (f"after period 1: mean |error| {figures['mean_abs_error_kg']:.2f} kg, max "
            f"{figures['max_abs_error_kg']:.2f} kg, within ±{figures['band_kg']:g} kg "
            f"{figures['within_band']}/{figures['counted']}; "
            f"{count(figures['resets'], 'reset')}")


def productivity_line(figures: dict[str, Any], limit_kw: float | None = None) -> str:
    """The run's productivity totals in one line (orchestrator.review.productivity); the peak
    supply power against the pump's limit `limit_kw` (kW) when the scenario sets one."""
    if figures["productivity_t_h"] is None:
        return "productivity: not in this log (its records have no cycle times)"
    f = figures
    line = (f"productivity {f['productivity_t_h']:.2f} t/h: {f['total_payload_kg']:.1f} kg in "
            f"{f['digging_time_s']:.1f} s of digging")
    if f["mean_fill_factor"] is not None:
        line += f", mean fill factor {f['mean_fill_factor']:.2f}"
    if f["energy_kj"] is None:
        return line + "; hydraulic energy not measured (a cylinder books no E_supply)"
    line += f"; hydraulic energy {f['energy_kj']:.0f} kJ"
    if f["energy_per_tonne_kj_t"] is not None:
        line += f", {f['energy_per_tonne_kj_t']:.0f} kJ/t"
    if f["throttled_share"] is not None:
        line += f", {100 * f['throttled_share']:.1f} % throttled"
    if f["peak_power_kw"] is not None:
        line += f"; supply power peak {f['peak_power_kw']:.1f} kW"
        if limit_kw is not None:
            line += f" ({100 * f['peak_power_kw'] / limit_kw:.0f} % of the pump's {limit_kw:g} kW)"
    if f["mean_power_kw"] is not None:
        line += f", mean {f['mean_power_kw']:.1f} kW"
    return line


def labels(paths: list[Path]) -> list[str]:
    """Short, distinct names for the runs: file stems; runs whose stems clash get the folders
    that tell them apart (x/a/runs/run and x/b/runs/run: a/run, b/run), not their whole paths.
    The JSON of `compare` has each run's path."""
    resolved = [Path(p).resolve() for p in paths]
    names = [p.stem for p in resolved]
    for stem in {n for n in names if names.count(n) > 1}:
        group = [i for i, n in enumerate(names) if n == stem]
        parents = [resolved[i].parent.parts for i in group]
        # Folders the whole group shares, outermost and innermost, say nothing: drop them.
        lead = 0
        while all(len(p) > lead for p in parents) and len({p[lead] for p in parents}) == 1:
            lead += 1
        rests = [p[lead:] for p in parents]
        tail = 0
        while all(len(r) > tail for r in rests) and len({r[-1 - tail] for r in rests}) == 1:
            tail += 1
        for i, rest in zip(group, rests, strict=True):
            names[i] = "/".join([*rest[:len(rest) - tail], stem])
    return names if len(set(names)) == len(names) else [str(p) for p in paths]


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
    names = labels(paths)
    summaries = [review.summary(run) for run in runs]
    if as_json:
        rows = []
        for label, data in zip(names, summaries, strict=True):
            row = {"label": label, **data}
            row["errors_kg"] = [r["error_kg"] for r in data["periods"]]
            del row["periods"]
            rows.append(row)
        print(json_text({"runs": rows, "differing_roles": review.differing_roles(summaries),
                         "differing_numerics": review.differing_numerics(summaries)}))
    else:
        out = tables.console()
        tables.show(out, compare_grid(names, summaries))
        out.print(differing_line(summaries), markup=False, soft_wrap=True)
        twice = sorted({str(p) for p in paths if sum(q.resolve() == p.resolve() for q in paths)
                        > 1})
        if twice:
            out.print(f"note: the same file is given more than once: {', '.join(twice)}",
                      markup=False, soft_wrap=True)
        for label, data in zip(names, summaries, strict=True):
            if data["damage"] is not None:
                out.print(f"note: {label}: {review.ending(data)}", markup=False,
                          soft_wrap=True)
    if plots is not None:
        from orchestrator.review.plots import plot_error_overlay, save_figure

        try:
            Path(plots).mkdir(parents=True, exist_ok=True)
            written = save_figure(plot_error_overlay(runs, names),
                                  Path(plots) / "weight_error_compare.png")
        except OSError as error:
            return f"--plots {plots}: cannot write the figure: {error.strerror or error}", 2
        print(written, file=sys.stderr if as_json else sys.stdout)
    return None


def differing_line(summaries: list[dict[str, Any]]) -> str:
    """Which plant roles differ between the runs, and in what (e.g. "boom: FMU; pile: density")."""
    differ = review.differing_roles(summaries)
    steps = review.differing_numerics(summaries)
    numeric = "" if not steps else "; numerics that differ: " + ", ".join(
        f"{key} {' | '.join('–' if v is None else f'{v:g}' for v in values)}"
        for key, values in steps.items())
    if not differ:
        return "plant: the same FMUs, ports and parameters in every run" + numeric
    return "plant roles that differ: " + "; ".join(
        f"{role}: {', '.join(what)}" for role, what in differ.items()) + numeric


def _number(value: float | None, digits: int = 2) -> str:
    return "–" if value is None else f"{value:.{digits}f}"


def ended(data: dict[str, Any]) -> str:
    """How a run ended, in a word or two (the compare table's `ended` column)."""
    if data.get("damage") is not None:
        return "damaged"
    if data["termination"] is None:
        return "killed" if data["truncated"] else "unfinished"
    if data["termination"] == "error" and data["message"] == "interrupted":
        return "interrupted"
    return {"periods": "all periods dug", "workspace_limit": "workspace limit",
            "error": "failed"}.get(data["termination"], data["termination"])


def compare_grid(names: list[str], summaries: list[dict[str, Any]]) -> tables.Grid:
    """One row per run: the figures of `orchestrator.review.summary.run_figures`."""
    c = tables.Column
    columns = [c("run", left=True), c("scenario", left=True), c("plant", left=True),
               c("m*", "kg"), c("periods"), c("mean |err|", "kg"), c("max |err|", "kg"),
               c("in band"), c("mean duration", "s"), c("peak jerk", "°/s³"), c("resets"),
               c("productivity", "t/h"), c("fill"), c("energy", "kJ/t"), c("throttled", "%"),
               c("peak power", "kW"), c("mean power", "kW"), c("ended", left=True)]
    rows: list[list[str | Text]] = []
    for label, data in zip(names, summaries, strict=True):
        f = data["figures"]
        within = f"{f['within_band']}/{f['counted']} (±{f['band_kg']:g})" if f["counted"] else "–"
        rows.append([label, data["scenario"], data["plant"], f"{data['target_mass_kg']:g}",
                     str(f["periods"]), _number(f["mean_abs_error_kg"]),
                     _number(f["max_abs_error_kg"]), within, _number(f["mean_duration_s"]),
                     _number(f["peak_jerk_deg_s3"], 1), str(f["resets"]),
                     _number(f["productivity_t_h"]), _number(f["mean_fill_factor"]),
                     _number(f["energy_per_tonne_kj_t"], 0),
                     _number(None if f["throttled_share"] is None
                             else 100 * f["throttled_share"], 1),
                     _number(f["peak_power_kw"], 1), _number(f["mean_power_kw"], 1),
                     ended(data)])
    return tables.Grid("Runs side by side", columns, rows,
                       caption="errors after period 1; in band: periods 2.. within ±10 % of m* "
                       "(the paper's ±3 kg at 30 kg); duration: planned trajectory per period; "
                       "peak jerk: largest |jerk| of any joint in any period; productivity: t "
                       "per hour of digging; fill: mean fill factor; energy, throttled, power: "
                       "the cylinders' hydraulic supply (– where not measured; "
                       "docs/guide/review.md, Productivity figures)")
