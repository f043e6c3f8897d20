"""CSV export of a run log for spreadsheets and other tools (`excosim review --csv`,
`--csv-channels`): the per-period table and chosen numeric channels.

The period table has the columns of `orchestrator.campaign.record.records_dataframe` (index k).
A channel's CSV has `t_s` (campaign time, s), `period` (1-based), then one column per field,
named with its unit as in the log's schema (`measured_boom_rad`, `p_A_Pa`); repeated fields get
one column per element (`z_m[0]`, ...; a /signals channel's element names from its metadata).
Floats are written with all their digits, so a read-back equals the log.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from orchestrator.runlog import RunFile, RunLogError

# Fields whose schema name carries no unit: named here with it (SI writes a dimensionless
# quantity's unit as 1; `u` is the spool command, -1..1).
_UNIT_NAMES = {"u": "u_1"}
_NOT_NUMERIC = ("/period",)  # JSON records: in the period CSV instead


class ExportError(ValueError):
    """A --csv request that does not fit the file; the message is one line."""


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


def period_frame(run: RunFile) -> Any:
    """pandas DataFrame of the /period records (records_dataframe: index k)."""
    from orchestrator.campaign.record import records_dataframe

    return records_dataframe(run.periods)


def channel_frame(run: RunFile, topic: str) -> Any:
    """pandas DataFrame of a decoded channel: t_s, period, one column per field (module doc)."""
    import pandas as pd

    channel = run.channels[topic]
    times = channel.fields.get("t_s", channel.log_time_ns / 1e9)
    columns: dict[str, Any] = {"t_s": times, "period": channel.period}
    names = json.loads(channel.metadata.get("names", "null")) or None
    for field, values in channel.fields.items():
        if field == "t_s":
            continue
        if values.ndim == 1:
            columns[_UNIT_NAMES.get(field, field)] = values
            continue
        labels = names if names and len(names) == values.shape[1] else [
            f"{field}[{i}]" for i in range(values.shape[1])]
        for label, column in zip(labels, values.T, strict=True):
            columns[label] = column
    return pd.DataFrame(columns)


def channel_file(topic: str) -> str:
    """/cylinder/boom -> cylinder_boom.csv"""
    return topic.strip("/").replace("/", "_") + ".csv"


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
