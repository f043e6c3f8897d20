"""Tables of a run log for spreadsheets and other tools: the one implementation behind `excosim
review --csv` / `--csv-channels`, `excosim export` (CSV and Parquet) and `excosim plot`.

The period table has the columns of `orchestrator.campaign.record.records_dataframe` (index k).
A channel's table has `t_s` (campaign time, s), `period` (1-based), then one column per field,
named with its unit as in the log's schema (`measured_boom_rad`, `p_A_Pa`; the spool command
`u` as `u_1`); repeated fields get one column per element (`z_m[0]`, ...); a /signals channel's
elements are named by its metadata "names" with their units appended (`boom.E_supply_J`,
`supply.p_pump_Pa`: the metadata "units", or for logs written before it the units its names
imply, orchestrator.runlog.units; a name of unknown unit stays bare). Floats keep all their
digits, so a read-back equals the log.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from orchestrator.runlog import RunFile, RunLogError
from orchestrator.runlog.reader import ChannelSamples
from orchestrator.runlog.units import signal_units, with_unit

# Fields whose schema name carries no unit: named here with it (SI writes a dimensionless
# quantity's unit as 1; `u` is the spool command, -1..1).
_UNIT_NAMES = {"u": "u_1"}
PERIOD_TOPIC = "/period"  # JSON records: the period table instead of a channel table
_NOT_NUMERIC = (PERIOD_TOPIC,)
FORMATS = ("csv", "parquet")  # what `write_tables` writes: file suffixes


class ExportError(ValueError):
    """A request that does not fit the file; the message is one line."""


def topics(items: list[str]) -> list[str]:
    """TOPIC[,TOPIC] items (repeatable) -> topics in order, once each."""
    found: list[str] = []
    for item in items:
        for topic in item.split(","):
            topic = topic.strip()
            if topic and topic not in found:
                found.append(topic)
    return found


def check_topics(run: RunFile, wanted: list[str]) -> None:
    """ExportError unless every topic in `wanted` is a channel of the file that is not JSON."""
    for topic in wanted:
        if topic in _NOT_NUMERIC:
            raise ExportError(f"--csv-channels {topic}: the period records are JSON; write "
                              "them with --csv FILE.csv")
        if topic not in run.message_counts:
            known = ", ".join(t for t in run.message_counts if t not in _NOT_NUMERIC)
            raise ExportError(f"--csv-channels {topic}: {run.path} has no such channel "
                              f"(channels: {known})")


def read_channels(path: Path, wanted: list[str]) -> RunFile:
    """The run log with `wanted` decoded; ExportError for a channel that is not numeric."""
    from orchestrator.review import summary

    try:
        return summary.load(path, tuple(wanted))
    except RunLogError as error:
        raise ExportError(f"--csv-channels: {error} (only numeric channels can be written "
                          "as CSV)") from None


def numeric_channels(run: RunFile) -> list[str]:
    """The numeric channels of `run` that hold samples (RunFile.numeric_topics with messages)."""
    return [topic for topic in run.numeric_topics if run.message_counts.get(topic)]


def period_frame(run: RunFile) -> Any:
    """pandas DataFrame of the /period records (records_dataframe: index k)."""
    from orchestrator.campaign.record import records_dataframe

    return records_dataframe(run.periods)


def channel_columns(channel: ChannelSamples) -> list[tuple[str, str, np.ndarray]]:
    """(column name, what it comes from, values (n,)) of every column of a decoded channel's
    table after t_s and period (module doc). "What it comes from" is the logged field ("u",
    "z_m") or a /signals element's name ("boom.E_supply"): a repeated field's columns share it."""
    try:
        names = json.loads(channel.metadata.get("names", "null"))
    except ValueError:  # a damaged or foreign log: its elements get indices instead
        names = None
    if not (isinstance(names, list) and all(isinstance(name, str) for name in names)):
        names = None
    out = []
    for field, values in channel.fields.items():
        if field == "t_s":
            continue
        if values.ndim == 1:
            out.append((_UNIT_NAMES.get(field, field), field, values))
            continue
        if names and len(names) == values.shape[1]:
            units = signal_units(channel.metadata, names)
            out += [(with_unit(name, unit), name, column)
                    for name, unit, column in zip(names, units, values.T, strict=True)]
        else:
            out += [(f"{field}[{i}]", field, column) for i, column in enumerate(values.T)]
    return out


def channel_frame(run: RunFile, topic: str) -> Any:
    """pandas DataFrame of a decoded channel: t_s, period, one column per field (module doc)."""
    import pandas as pd

    channel = run.channels[topic]
    times = channel.fields.get("t_s", channel.log_time_ns / 1e9)
    columns: dict[str, Any] = {"t_s": times, "period": channel.period}
    for label, _, values in channel_columns(channel):
        columns[label] = values
    return pd.DataFrame(columns)


def channel_file(topic: str, suffix: str = ".csv") -> str:
    """/cylinder/boom -> cylinder_boom.csv (or another `suffix`, e.g. ".parquet")."""
    return topic.strip("/").replace("/", "_") + suffix


def write(run: RunFile, csv: Path | None, channels: RunFile | None, wanted: list[str],
          folder: Path) -> list[Path]:
    """Write the period CSV of `run` (to `csv`) and one CSV per topic in `wanted` from
    `channels` (`read_channels`; into `folder`); the paths written. OSError if a file cannot
    be written."""
    written = []
    if csv is not None:  # its folder must exist: a typo must not create folders
        period_frame(run).to_csv(csv)
        written.append(Path(csv))
    if channels is not None and wanted:
        folder.mkdir(parents=True, exist_ok=True)
        for topic in wanted:
            target = folder / channel_file(topic)
            channel_frame(channels, topic).to_csv(target, index=False)
            written.append(target)
    return written


def write_tables(run: RunFile, folder: Path, suffix: str) -> list[Path]:
    """Write every decoded channel of `run` (one file each, `channel_file`) and the period
    table (period.<suffix>) into `folder` (which must exist) as `suffix` ("csv" or "parquet");
    the paths written. OSError if a file cannot be written."""
    frames = [(channel_file(topic, f".{suffix}"), channel_frame(run, topic), False)
              for topic in run.channels]
    frames.append((f"period.{suffix}", period_frame(run), True))
    written = []
    for name, frame, index in frames:
        target = folder / name
        if suffix == "csv":
            frame.to_csv(target, index=index)
        else:
            frame.to_parquet(target, index=index)
        written.append(target)
    return written
