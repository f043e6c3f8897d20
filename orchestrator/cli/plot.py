"""`excosim plot RUN.mcap TOPIC:FIELD...`: a quick figure of logged numbers against campaign time,
without a viewer.

A FIELD is a column of the channel's table (orchestrator.cli.export: `p_A_Pa`, `u_1`,
`z_m[3]`, `boom.E_supply_J`) or the name it is logged under (`u`, a /signals element such as
`boom.E_supply`); a repeated field (`/pile/profile:z_m`) is refused with the columns to pick
from. `/period:FIELD` plots a column of the period table (`error_kg`, `mass_kg`,
`tracking_rms_deg_boom`), one point per period at the period's end. The y axes are labelled
with the units the names carry (orchestrator.runlog.units), one axis per distinct unit;
`--period K` keeps period K's samples. `plot_fields` is the same as a function: it returns the
matplotlib Figure and the series drawn.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from orchestrator.cli.conventions import fail

if TYPE_CHECKING:
    import numpy as np
    from matplotlib.figure import Figure

    from orchestrator.runlog import RunFile

SUFFIXES = (".png", ".pdf", ".svg")
_LISTED = 12  # a channel with more columns than this names its fields, not every column


class PlotError(ValueError):
    """A request that does not fit the run log; the message is one line."""


@dataclass(frozen=True)
class Series:
    """One curve: `topic`:`column`, its unit as the name says (None: the name carries none),
    t_s (n,) campaign time in s and values (n,) in that unit."""

    topic: str
    column: str
    unit: str | None
    t_s: np.ndarray
    values: np.ndarray

    @property
    def label(self) -> str:
        return f"{self.topic}:{self.column}"


def plot(
    run_log: Annotated[Path, typer.Argument(metavar="RUN.mcap", help="Run log written by "
                                            "`excosim run`.")],
    fields: Annotated[list[str], typer.Argument(
        metavar="TOPIC:FIELD", help="What to plot, e.g. /cylinder/boom:p_A_Pa, "
        "/joints:measured_boom_rad, /display:p_A_boom_bar, /signals/supply:supply.p_pump, "
        "/period:error_kg (several: one figure).")],
    period: Annotated[int | None, typer.Option(
        "--period", metavar="K", help="Only period K's samples.")] = None,
    output: Annotated[Path | None, typer.Option(
        "-o", "--output", metavar="FILE.png", help="Figure to write (.png, .pdf or .svg; "
        "default: <run stem>-<topic>_<field>.png in the current folder).")] = None,
) -> None:
    """Plot logged numbers of a run log against campaign time, one y axis per unit.

    Time is t_s (s); /period fields are one point per period, at its end. Prints the file
    written.
    """
    try:
        target = output_path(run_log, fields, period, output)
        run = _read(run_log, fields)
        figure, _ = plot_fields(run, fields, period)
    except PlotError as error:
        fail(str(error))
        raise typer.Exit(2) from None
    from orchestrator.review.plots import save_figure

    try:
        save_figure(figure, target)
    except OSError as error:
        fail(f"{target}: cannot write the figure: {error.strerror or error}")
        raise typer.Exit(2) from None
    print(target)


def split(spec: str) -> tuple[str, str]:
    """"TOPIC:FIELD" -> (topic, field); PlotError for anything else."""
    topic, colon, field = spec.partition(":")
    if not colon or not topic.startswith("/") or not field:
        raise PlotError(f"{spec!r}: expected TOPIC:FIELD, e.g. /joints:measured_boom_rad")
    return topic, field


def output_path(run_log: Path, fields: list[str], period: int | None,
                output: Path | None) -> Path:
    """The figure's file: `output`, or <run stem>-<topic>_<field>[+...][-period<K>].png in the
    current folder; PlotError for a bad spec, a suffix matplotlib is not asked to write or a
    folder that does not exist."""
    names = []
    for spec in fields:
        topic, field = split(spec)
        names.append(re.sub(r"[^A-Za-z0-9_.-]+", "_", f"{topic.strip('/')}_{field}").strip("_"))
    if output is None:
        joined = "+".join(names) if len("+".join(names)) <= 160 else \
            f"{names[0]}+{len(names) - 1}_more"
        tail = f"-period{period}" if period is not None else ""
        return Path(f"{run_log.stem}-{joined}{tail}.png")
    if output.suffix.lower() not in SUFFIXES:
        raise PlotError(f"-o {output}: expected a file name ending in {', '.join(SUFFIXES)}")
    if output.is_dir():
        raise PlotError(f"-o {output}: is a folder; give a file name")
    if not output.absolute().parent.is_dir():
        raise PlotError(f"-o {output}: the folder {output.parent} does not exist")
    return output


def _read(path: Path, fields: list[str]) -> RunFile:
    """The run log with the numeric channels that `fields` name decoded; PlotError (one line)
    for a file that is not a readable run log or a topic it has not or that is not numeric."""
    from orchestrator.cli.export import PERIOD_TOPIC
    from orchestrator.review import summary
    from orchestrator.runlog import RunLogError

    try:
        run = summary.load(path)
        numeric = [t for t in run.numeric_topics if t in run.message_counts]
        wanted = list(dict.fromkeys(split(spec)[0] for spec in fields))
        for topic in wanted:
            if topic == PERIOD_TOPIC or topic in numeric:
                continue
            known = ", ".join([*numeric, PERIOD_TOPIC])
            if topic in run.message_counts:
                raise PlotError(f"{topic}: not a numeric channel (numeric: {known})")
            raise PlotError(f"{path} has no channel {topic} (numeric channels: {known})")
        return summary.load(path, tuple(t for t in wanted if t != PERIOD_TOPIC))
    except RunLogError as error:
        raise PlotError(str(error)) from None


def _known(columns: list[str], sources: dict[str, list[str]]) -> str:
    """The fields of a table, for a message: its columns, or, for a wide one, each repeated
    field once with its index range."""
    if len(columns) <= _LISTED:
        return ", ".join(columns)
    return ", ".join(f"{name}[0..{len(cols) - 1}]" if len(cols) > 1 else cols[0]
                     for name, cols in sources.items() if set(cols) <= set(columns))


def _table(run: RunFile, topic: str) -> tuple[dict[str, np.ndarray], np.ndarray, np.ndarray,
                                               dict[str, list[str]]]:
    """(column -> values, t_s, period, logged name -> its columns) of a channel or of the
    period table (times: each period's end; values of its numeric columns only)."""
    import numpy as np

    from orchestrator.cli.export import PERIOD_TOPIC, channel_columns, period_frame

    if topic == PERIOD_TOPIC:
        frame = period_frame(run)
        columns = {}
        for name in frame.columns:
            if frame[name].dtype != bool:
                try:
                    columns[name] = frame[name].to_numpy(dtype=float, na_value=np.nan)
                except (TypeError, ValueError):
                    continue
        times = np.asarray(run.period_end_ns, dtype=np.int64) / 1e9
        periods = np.asarray(frame.index, dtype=np.int64)
        return columns, times, periods, {name: [name] for name in frame.columns}
    channel = run.channels[topic]
    sources: dict[str, list[str]] = {}
    columns = {}
    for name, source, values in channel_columns(channel):
        columns[name] = values
        sources.setdefault(source, []).append(name)
    times = channel.fields.get("t_s", channel.log_time_ns / 1e9)
    return columns, times, channel.period, sources


def _column(topic: str, field: str, columns: dict[str, np.ndarray],
            sources: dict[str, list[str]]) -> str:
    """The table column that `field` names (module doc); PlotError naming what exists."""
    if field in columns:
        return field
    found = sources.get(field, [])
    if len(found) == 1 and found[0] in columns:
        return found[0]
    if len(found) > 1:
        raise PlotError(f"{topic}:{field} holds {len(found)} values per message; pick one, "
                        f"e.g. {found[0]} ({found[0]}..{found[-1]})")
    if field in sources or field in ("t_s", "period"):
        what = "the time axis" if field in ("t_s", "period") else "not a number"
        raise PlotError(f"{topic}:{field} is {what}; fields: {_known(list(columns), sources)}")
    raise PlotError(f"{topic} has no field {field}; fields: {_known(list(columns), sources)}")


def plot_fields(run: RunFile, fields: list[str], period: int | None = None
                ) -> tuple[Figure, list[Series]]:
    """The figure of `fields` (TOPIC:FIELD) of `run` (read with their channels decoded) against
    campaign time (s), only period `period`'s samples if given, one axis per distinct unit;
    and the series drawn. PlotError (one line) for a field the log lacks or an empty period."""
    import numpy as np

    from orchestrator.cli.export import PERIOD_TOPIC
    from orchestrator.review.plots_common import pyplot
    from orchestrator.runlog.units import unit_of

    n = len(run.periods)
    if period is not None and not 1 <= period <= n:
        held = {0: "no complete period", 1: "period 1 only"}.get(n, f"periods 1-{n}")
        raise PlotError(f"--period {period}: {run.path} holds {held}")
    drawn: list[Series] = []
    for spec in fields:
        topic, field = split(spec)
        if topic not in run.channels and topic != PERIOD_TOPIC:
            raise PlotError(f"{topic}: {run.path} holds no sample of it")
        columns, times, periods, sources = _table(run, topic)
        column = _column(topic, field, columns, sources)
        keep = np.ones(len(times), dtype=bool) if period is None else periods == period
        if not keep.any():
            raise PlotError(f"{spec}: no sample in " + (f"period {period}" if period
                                                        else str(run.path)))
        drawn.append(Series(topic, column, unit_of(column), times[keep], columns[column][keep]))
    units = list(dict.fromkeys(series.unit for series in drawn))
    plt = pyplot()
    figure, axes = plt.subplots(len(units), 1, sharex=True, squeeze=False,
                                figsize=(9.0, 2.0 + 2.2 * len(units)))
    for unit, axis in zip(units, axes[:, 0], strict=True):
        for series in (s for s in drawn if s.unit == unit):
            few = len(series.t_s) <= 60 or series.topic == PERIOD_TOPIC
            axis.plot(series.t_s, series.values, marker="o" if few else None,
                      markersize=3.5, linewidth=1.0, label=series.label)
        axis.set_ylabel(unit if unit is not None else "(no unit in the name)")
        axis.grid(True, alpha=0.3)
        axis.legend(loc="best", fontsize="small")
    axes[-1, 0].set_xlabel("campaign time t (s)")
    where = f", period {period}" if period is not None else ""
    axes[0, 0].set_title(f"{Path(run.path).name}{where}")
    figure.tight_layout()
    return figure, drawn
