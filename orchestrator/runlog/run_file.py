"""What a run log holds, as the reader (orchestrator.runlog.reader) gives it: RunFile, the
decoded numeric channels (ChannelSamples), and RunLogError, a file that is not a readable run
log."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np


class RunLogError(ValueError):
    """A file that is not a readable excosim run log; the message is one line."""


@dataclass
class ChannelSamples:
    """The messages of one numeric channel, decoded with the schema stored in the file.

    log_time_ns: (n,) campaign time of each message (ns since the start of period 1).
    period: (n,) the period (1-based) each message belongs to: the one whose /period record
    follows it in the file (a period's last sample and the next one's first share a time).
    fields: field name -> (n,) values (NaN where a message lacks the field) or (n, k) for a
    repeated field. schema: its name (e.g. "excosim.JointState"). metadata: the channel's
    metadata (e.g. "names" of a /signals channel as a JSON list).
    """

    topic: str
    schema: str
    log_time_ns: np.ndarray
    period: np.ndarray
    fields: dict[str, np.ndarray]
    metadata: dict[str, str]

    def of_period(self, k: int) -> dict[str, np.ndarray]:
        """The fields of the messages of period k (1-based)."""
        lo, hi = np.searchsorted(self.period, [k, k + 1])
        return {name: values[lo:hi] for name, values in self.fields.items()}


@dataclass
class RunFile:
    """What a run log holds.

    periods: the /period records in order (dicts as the campaign wrote them).
    metadata: record name -> key -> value (e.g. metadata["excosim.versions"]["numpy"]).
    attachments: name -> bytes ("scenario.toml", "fmus/<file name>").
    message_counts: topic -> number of messages read.
    period_end_ns: log time (ns) of each /period message, i.e. of each period's end.
    channels: topic -> ChannelSamples of the numeric channels asked for (`read_run(topics=)`).
    finished: the run closed its log (an end record is present); termination and
    termination_message come from it (None if not finished).
    truncated: the file ends inside a record, lacks its footer or has a damaged chunk (a
    killed run); everything before that point was read.
    damage: how the file is damaged, "damaged at byte N (chunk CRC)" (module docstring),
    None if it is not; the periods before the damage were read.
    resume_states: period k -> the JSON bytes of its /resume message (what a resumed run
    continues from: orchestrator.campaign.resume), for the periods that have one.
    period_chunks: per period, the file offsets [start, end) of the chunk record that holds its
    /period record.
    numeric_topics: the topics whose schema is a protobuf message of doubles (what `topics=`
    decodes), in the order of their channel records.
    """

    path: Path
    periods: list[dict] = field(default_factory=list)
    metadata: dict[str, dict[str, str]] = field(default_factory=dict)
    attachments: dict[str, bytes] = field(default_factory=dict)
    message_counts: dict[str, int] = field(default_factory=dict)
    period_end_ns: list[int] = field(default_factory=list)
    channels: dict[str, ChannelSamples] = field(default_factory=dict)
    finished: bool = False
    termination: str | None = None
    termination_message: str | None = None
    truncated: bool = False
    damage: str | None = None
    resume_states: dict[int, bytes] = field(default_factory=dict)
    period_chunks: list[tuple[int, int]] = field(default_factory=list)
    numeric_topics: list[str] = field(default_factory=list)

    @property
    def scenario(self) -> dict:
        """The resolved scenario the run used."""
        return json.loads(self.metadata["excosim.scenario"]["json"])

    @property
    def scenario_text(self) -> str:
        """The text of the scenario file the run was started with."""
        return self.attachments[self.metadata["excosim.run"]["scenario_attachment"]].decode()

    def not_simulated(self, cannot: str) -> str | None:
        """Why a run that must be simulated again ("be re-simulated", "be resumed": `cannot`)
        cannot be (one line: a lab run, another plant kind); None for a simulated run."""
        kind = self.metadata.get("excosim.run", {}).get("plant_kind")
        if kind == "lab":
            return (f"{self.path} is a lab run: it was measured on the real machine, so it "
                    f"cannot {cannot}")
        if kind != "sim":
            return f"{self.path}: plant kind {kind!r} cannot {cannot} (only 'sim')"
        return None
