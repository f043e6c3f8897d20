"""Run logs as the real viewers and checkers read them.

- The /period JSON schema against the rules of the JSON-schema reader that Foxglove and
  Lichtblick share (Lichtblick's packages/mcap-support/src/parseJsonSchema.ts): a schema is an
  object with `properties`; a field is boolean, string, number, integer, an object (recursively)
  or an array whose `items` is a boolean, string, number, integer or object schema. Anything
  else (an array without items, nested arrays, an object without properties, a type list) makes
  the reader throw, and the viewer drops the whole channel.
- Chunks against `mcap doctor`'s rules: log time never goes back inside a chunk, the chunk's
  start and end times are its messages' extremes; the data section's CRC (checked by the
  `mcap` package's StreamReader, an independent parser).
- The pile is drawn from t = 0: the surface before period 1 is in the log.
"""

from __future__ import annotations

import json
from pathlib import Path

import jsonschema
import numpy as np
import pytest
from mcap.reader import make_reader
from mcap.records import Chunk, DataEnd, Message
from mcap.stream_reader import CRCValidationError, StreamReader, breakup_chunk
from mcap_protobuf.decoder import DecoderFactory

from orchestrator.campaign import run_campaign
from orchestrator.runlog import read_run
from orchestrator.runlog.plan_scene import PERIOD_START_SCHEMA
from orchestrator.runlog.schemas import PERIOD_SUMMARY_SCHEMA
from orchestrator.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[1]
SCALARS = {"boolean", "string", "number", "integer"}
HEAP = {"heap_height": 0.6, "heap_center_y": -8.0, "heap_half_width": 2.5}


def viewer_schema_errors(schema: dict, where: str = "$") -> list[str]:
    """What the viewers' JSON-schema reader would throw on, one line each."""
    if schema.get("type") != "object":
        return [f"{where}: expected type object, got {schema.get('type')!r}"]
    if not isinstance(schema.get("properties"), dict):
        return [f"{where}: an object needs properties"]
    errors = []
    for name, field in schema["properties"].items():
        path, kind = f"{where}.{name}", field.get("type")
        if isinstance(kind, str) and kind in SCALARS:
            continue
        if kind == "object":
            errors += viewer_schema_errors(field, path)
        elif kind == "array":
            items = field.get("items")
            if not isinstance(items, dict):
                errors.append(f"{path}: an array needs items")
            elif items.get("type") == "object":
                errors += viewer_schema_errors(items, f"{path}[]")
            elif not (isinstance(items.get("type"), str) and items["type"] in SCALARS):
                errors.append(f"{path}[]: unsupported item type {items.get('type')!r}")
        else:
            errors.append(f"{path}: unsupported type {kind!r}")
    return errors


def test_the_schema_walker_rejects_what_the_viewers_reject():
    old = {"type": "object", "properties": {
        "via_points_rad": {"type": "array"},
        "nested": {"type": "array", "items": {"type": "array", "items": {"type": "number"}}},
        "spline": {"type": "object"},
        "maybe": {"type": ["number", "null"]},
        "ok": {"type": "array",
               "items": {"type": "object", "properties": {"x": {"type": "number"}}}},
    }}
    assert viewer_schema_errors(old) == [
        "$.via_points_rad: an array needs items",
        "$.nested[]: unsupported item type 'array'",
        "$.spline: an object needs properties",
        "$.maybe: unsupported type ['number', 'null']",
    ]


def test_every_period_field_has_a_schema_the_viewers_read():
    assert viewer_schema_errors(PERIOD_SUMMARY_SCHEMA) == []
    assert viewer_schema_errors(PERIOD_START_SCHEMA) == []


@pytest.fixture(scope="module")
def heap_run(tmp_path_factory):
    """Two paper periods dug into a triangular heap, logged."""
    path = tmp_path_factory.mktemp("viewers") / "heap.mcap"
    overrides = ["periods=2"] + [f"plant.pile.parameters.{k}={v}" for k, v in HEAP.items()]
    scenario = load_scenario(ROOT / "scenarios" / "paper-2020.toml", overrides)
    result = run_campaign(scenario, log_path=path)
    assert result.termination == "periods", result.message
    return path, result, scenario


def test_every_record_key_is_in_the_schema_and_every_record_is_valid(heap_run):
    path, result, _ = heap_run
    with open(path, "rb") as stream:
        summary = make_reader(stream).get_summary()
    channel = next(c for c in summary.channels.values() if c.topic == "/period")
    stored = json.loads(summary.schemas[channel.schema_id].data)
    assert stored == PERIOD_SUMMARY_SCHEMA
    for record in read_run(path).periods:
        assert set(record) <= set(stored["properties"]), set(record) - set(stored["properties"])
        jsonschema.validate(record, stored)
    assert read_run(path).periods == result.records


def chunk_message_times(path: Path) -> list[tuple[Chunk, list[int]]]:
    out = []
    with open(path, "rb") as stream:
        for record in StreamReader(stream, emit_chunks=True).records:
            if isinstance(record, Chunk):
                out.append((record, [r.log_time for r in breakup_chunk(record)
                                     if isinstance(r, Message)]))
    return out


def test_log_time_never_goes_back_inside_a_chunk(heap_run):
    path, _, _ = heap_run
    chunks = chunk_message_times(path)
    assert len(chunks) == 3  # the surface at t = 0, then one chunk per period
    for chunk, times in chunks:
        assert times and all(b >= a for a, b in zip(times, times[1:], strict=False))
        assert (chunk.message_start_time, chunk.message_end_time) == (min(times), max(times))


def test_the_data_section_crc_is_written_and_checks(heap_run, tmp_path):
    path, _, _ = heap_run
    with open(path, "rb") as stream:
        records = list(StreamReader(stream, validate_crcs=True).records)
    data_end = next(r for r in records if isinstance(r, DataEnd))
    assert data_end.data_section_crc != 0
    # A flipped byte in the header's library string: the CRC catches it.
    data = bytearray(path.read_bytes())
    data[data.index(b"excosim")] ^= 0x20
    damaged = tmp_path / "damaged.mcap"
    damaged.write_bytes(bytes(data))
    with open(damaged, "rb") as stream, pytest.raises(CRCValidationError):
        list(StreamReader(stream, validate_crcs=True).records)


def heap_cell_means(centres: np.ndarray, cell: float) -> np.ndarray:
    """Mean height of the triangular heap over each cell, by fine quadrature."""
    s = (np.arange(2000) + 0.5) / 2000 - 0.5
    y = centres[:, None] + cell * s[None, :]
    height = HEAP["heap_height"] * np.clip(
        1.0 - np.abs(y - HEAP["heap_center_y"]) / HEAP["heap_half_width"], 0.0, None)
    return height.mean(axis=1)


def test_the_pile_is_in_the_log_from_t_0(heap_run):
    path, _, _ = heap_run
    with open(path, "rb") as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        profiles = [(m.log_time, d) for _, _, m, d in
                    reader.iter_decoded_messages(topics=["/pile/profile"], log_time_order=False)]
        stream.seek(0)
        scenes = [(m.log_time, d) for _, _, m, d in
                  reader.iter_decoded_messages(topics=["/scene/pile"], log_time_order=False)]
    assert profiles[0][0] == 0 and scenes[0][0] == 0
    assert len(profiles) == len(scenes) == 3  # t = 0, after period 1, after period 2
    first = profiles[0][1]
    y, z = np.array(first.y_m), np.array(first.z_m)
    np.testing.assert_allclose(z, heap_cell_means(y, y[1] - y[0]), rtol=0, atol=1e-9)
    assert [e.id for e in scenes[0][1].entities] == ["pile/surface"]  # no tip path yet
    np.testing.assert_allclose(max(p.z for p in scenes[0][1].entities[0].triangles[0].points),
                               z.max(), rtol=0, atol=1e-12)


def decoded_by_time(path: Path, topic: str) -> dict[int, object]:
    with open(path, "rb") as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        return {m.log_time: d for _, _, m, d in reader.iter_decoded_messages(topics=[topic])}


def test_the_display_channel_holds_the_si_samples_in_the_units_a_person_reads(heap_run):
    path, _, _ = heap_run
    display = decoded_by_time(path, "/display")
    joints, pile = decoded_by_time(path, "/joints"), decoded_by_time(path, "/pile/bucket")
    cylinders = {j: decoded_by_time(path, f"/cylinder/{j}") for j in ("boom", "stick", "bucket")}
    tf_times = set(decoded_by_time(path, "/tf"))
    assert set(display) == tf_times and len(display) > 100  # at the /tf rate
    for time, d in display.items():
        for joint in ("boom", "stick", "bucket"):
            reference = np.degrees(getattr(joints[time], f"reference_{joint}_rad"))
            measured = np.degrees(getattr(joints[time], f"measured_{joint}_rad"))
            assert getattr(d, f"reference_{joint}_deg") == pytest.approx(reference, abs=1e-9)
            assert getattr(d, f"measured_{joint}_deg") == pytest.approx(measured, abs=1e-9)
            assert getattr(d, f"tracking_error_{joint}_deg") == pytest.approx(
                measured - reference, abs=1e-9)
            for chamber in ("A", "B"):
                pa = getattr(cylinders[joint][time], f"p_{chamber}_Pa")
                assert getattr(d, f"p_{chamber}_{joint}_bar") == pytest.approx(pa / 1e5, rel=1e-12)
        assert d.soil_F_y_kN == pytest.approx(pile[time].F_y_N / 1e3, rel=1e-12, abs=1e-15)
        assert d.bucket_mass_kg == pile[time].bucket_mass_kg


def test_a_lower_sample_rate_decimates_the_samples_and_keeps_each_period_end(tmp_path):
    scenario = load_scenario(ROOT / "scenarios" / "paper-2020.toml",
                             ["periods=2", "log.sample_rate_hz=20"])
    full, thin = tmp_path / "full.mcap", tmp_path / "thin.mcap"
    for path, overrides in ((full, []), (thin, ["log.sample_rate_hz=20"])):
        result = run_campaign(load_scenario(ROOT / "scenarios" / "paper-2020.toml",
                                            ["periods=2", *overrides]), log_path=path)
        assert result.termination == "periods"
    every, some = (read_run(p, topics=("/joints",)).channels["/joints"] for p in (full, thin))
    def results(path):  # the planner's wall time is not a result
        return [{k: v for k, v in r.items() if k != "planner_ms"} for r in read_run(path).periods]

    assert results(full) == results(thin)  # logging changes no result
    step = scenario.plant.communication_step_s
    assert np.median(np.diff(some.log_time_ns)) == pytest.approx(0.05e9 / step * step, rel=1e-6)
    for k in (1, 2):
        a, b = every.of_period(k), some.of_period(k)
        assert b["t_s"][-1] == a["t_s"][-1]  # the period's end state is kept
        assert np.isin(b["t_s"], a["t_s"]).all()
        assert len(b["t_s"]) == pytest.approx(len(a["t_s"]) / 5, abs=2)
    assert thin.stat().st_size < 0.4 * full.stat().st_size
