"""Generated edits of a real run log's records: every command that reads a log gives exit status 0,
or one line and exit status 2, never a traceback (orchestrator.runlog.records, reader, resume).

The log is a killed run's (a 2-period paper campaign cut inside period 2's chunk: period 1 whole,
with its /resume state). Hypothesis draws one edit per case, from a fixed seed (the same cases
whatever the test's body): the /period record, the /resume record or the scenario record (a value
anywhere in the JSON set to null, a boolean, a string, a list, an object, NaN, 1e400, 2^70, a
nesting 900 or 5000 deep, scaled, removed; the whole record replaced; its text cut or a byte
changed), a metadata record (left out, repeated, a value set or removed) or a channel record
(left out, repeated, its topic, schema, encoding, metadata or id changed). Each edited log goes
through `review`, `review --json`, `compare` (with the whole log), `replay --json` and `run
--resume -o`, in this process (typer's test runner: an exception that would be a traceback is
one here). A replay of an edited log may differ from it (exit status 1, one line "replay
differs"), and a resumed run whose edited state still loads may fail as a run fails (exit 1,
one line "run failed"); those are counted apart. The counts are printed with -s.
"""

from __future__ import annotations

import time
from collections import Counter
from pathlib import Path

import pytest
from hypothesis import HealthCheck, Phase, given, seed, settings
from hypothesis import strategies as st
from mcap.records import Channel, Metadata
from run_log_files import cut_inside_chunk
from run_log_mutations import LogParts, edited, paths, record_bytes
from typer.testing import CliRunner

from orchestrator.campaign import run_campaign
from orchestrator.cli.app import app
from orchestrator.scenario import load_scenario

ROOT = Path(__file__).resolve().parent.parent
CASES = 300
VALUES = [None, True, 0, -1, 0.5, 1e308, "x", "", [], {}, [1.0, 2.0, 3.0], {"a": 1}, "nan",
          "inf", "1e400", "deep", "900 deep", "big int"]
STRINGS = ["", "x", "NaN", "1e400", "-1", "0", "{}", "[]", "null", "9" * 400, "é\u0000"]

json_edit = st.one_of(
    st.tuples(st.just("set"), st.integers(0, 10 ** 6), st.sampled_from(VALUES)),
    st.tuples(st.just("scale"), st.integers(0, 10 ** 6),
              st.sampled_from([0.0, -1.0, 1e-9, 1.001, 1e6])),
    st.tuples(st.just("delete"), st.integers(0, 10 ** 6), st.none()),
    st.tuples(st.just("bytes"), st.integers(0, 10 ** 6), st.sampled_from(["cut", "flip"])),
)
FAMILIES = {
    "period": json_edit, "resume": json_edit, "scenario": json_edit,
    "metadata": st.tuples(st.integers(0, 100),
                          st.sampled_from(["drop", "twice", "set", "delete", "add"]),
                          st.integers(0, 100), st.sampled_from(STRINGS)),
    "channel": st.tuples(st.integers(0, 100),
                         st.sampled_from(["drop", "twice", "topic", "schema", "encoding",
                                          "metadata", "id"]),
                         st.integers(0, 100)),
}
edit = st.sampled_from(sorted(FAMILIES)).flatmap(
    lambda family: st.tuples(st.just(family), FAMILIES[family]))


@pytest.fixture(scope="module")
def logs(tmp_path_factory) -> tuple[Path, Path]:
    """(the whole 2-period log, the killed one)."""
    folder = tmp_path_factory.mktemp("mutations")
    full = folder / "full.mcap"
    run_campaign(load_scenario(ROOT / "scenarios" / "paper-2020.toml", ["periods=2"]),
                 log_path=full)
    return full, cut_inside_chunk(full, folder / "killed.mcap")


def _json_edit(text: bytes, how: tuple) -> bytes:
    kind, at, value = how
    if kind == "bytes":
        at %= max(len(text), 1)
        return text[:at] if value == "cut" else text[:at] + bytes([text[at] ^ 0x5A]) + \
            text[at + 1:]
    import json
    where = paths(json.loads(text))
    path = where[at % len(where)] if kind != "delete" or len(where) == 1 else \
        where[1 + at % (len(where) - 1)]
    return edited(text.decode(), path, kind, value)


def mutate(data: bytes, family: str, how: tuple) -> tuple[bytes, str]:
    """The edited log and a short name of the edit (for the counts)."""
    parts = LogParts(data)
    if family in ("period", "resume"):
        topic = f"/{family}"
        parts.replace_message(topic, _json_edit(parts.message(topic), how))
        return parts.bytes(), f"{family} {how[0]}"
    metadata = parts.metadata()
    if family == "scenario":
        index, record = next((i, m) for i, m in metadata if m.name == "excosim.scenario")
        text = _json_edit(record.metadata["json"].encode(), how)
        values = {**record.metadata, "json": text.decode("utf-8", "replace")}
        parts.records[index][1] = record_bytes(Metadata(name=record.name, metadata=values))
        return parts.bytes(), f"scenario {how[0]}"
    if family == "metadata":
        which, op, key_at, value = how
        index, record = metadata[which % len(metadata)]
        values = dict(record.metadata)
        keys = sorted(values)
        if op == "drop":
            del parts.records[index]
        elif op == "twice":
            parts.records.insert(index + 1, list(parts.records[index]))
        else:
            if op == "set" and keys:
                values[keys[key_at % len(keys)]] = value
            elif op == "delete" and keys:
                del values[keys[key_at % len(keys)]]
            else:
                values["added"] = value
            parts.records[index][1] = record_bytes(Metadata(name=record.name, metadata=values))
        return parts.bytes(), f"metadata {op}"
    which, op, other = how
    channels = parts.channels()
    index, channel = channels[which % len(channels)]
    if op == "drop":
        del parts.records[index]
    elif op == "twice":
        parts.records.insert(index + 1, list(parts.records[index]))
    else:
        topic, schema, encoding = channel.topic, channel.schema_id, channel.message_encoding
        metadata_, ident = dict(channel.metadata), channel.id
        if op == "topic":
            topic = channels[other % len(channels)][1].topic if other % 3 else "/x"
        elif op == "schema":
            schema = (0, 999, other % 12 + 1)[other % 3]
        elif op == "encoding":
            encoding = ("cbor", "", "json")[other % 3]
        elif op == "metadata":
            metadata_ = {} if other % 2 else {**metadata_, "names": "not JSON ["}
        else:
            ident = (0, 65535, channels[other % len(channels)][1].id)[other % 3]
        parts.records[index][1] = record_bytes(Channel(
            id=ident, topic=topic, message_encoding=encoding, schema_id=schema,
            metadata=metadata_))
    return parts.bytes(), f"channel {op}"


COUNTS: Counter = Counter()
EDITS: Counter = Counter()


@pytest.fixture(scope="module", autouse=True)
def report():
    start = time.perf_counter()
    yield
    edits = ", ".join(f"{n} {k}" for k, n in sorted(EDITS.items()))
    outcomes = ", ".join(f"{k}: {n}" for k, n in sorted(COUNTS.items()))
    print(f"\n{sum(EDITS.values())} edited logs ({edits}); outcomes: {outcomes}; "
          f"{time.perf_counter() - start:.0f} s")


def check(case: tuple, command: list[str], allowed_failure: str | None = None) -> str:
    """Run `excosim command` here: exit 0, or one line and exit 2 (or 1 with `allowed_failure`
    starting its line); returns the outcome's name for the counts. case: the edit, named in
    a failure."""
    result = CliRunner().invoke(app, command)
    assert result.exception is None or isinstance(result.exception, SystemExit), \
        (case, command, repr(result.exception))
    lines = result.stderr.strip().splitlines()
    if result.exit_code == 0:
        return "0"
    assert len(lines) == 1 and lines[0].startswith("excosim: "), (case, command, result.stderr)
    if result.exit_code == 1 and allowed_failure is not None and \
            lines[0].startswith(f"excosim: {allowed_failure}"):
        return "1"
    assert result.exit_code == 2, (case, command, result.exit_code, result.stderr)
    return "2"


@seed(20_261_207)  # the same cases whatever the test's body (derandomize hashes the source)
@settings(max_examples=CASES, deadline=None, database=None,
          phases=[Phase.explicit, Phase.generate],  # one edit per case: nothing to shrink
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(edit)
def test_an_edited_record_is_read_or_refused_in_one_line(logs, tmp_path_factory, change):
    full, killed = logs
    data, name = mutate(killed.read_bytes(), *change)
    EDITS[name.split()[0]] += 1
    folder = tmp_path_factory.mktemp("case")
    path = folder / "run.mcap"
    path.write_bytes(data)
    outcomes = [check(change, ["review", str(path)]),
                check(change, ["review", str(path), "--json"]),
                check(change, ["compare", str(full), str(path)]),
                check(change, ["replay", str(path), "--json"], "replay differs from the log"),
                check(change, ["run", "--resume", str(path), "-o", str(folder / "resumed.mcap"),
                               "-q"], "run failed")]
    for command, outcome in zip(("review", "review --json", "compare", "replay", "resume"),
                                outcomes, strict=True):
        COUNTS[f"{command} {outcome}"] += 1
    assert path.read_bytes() == data  # no command changed the file it read
