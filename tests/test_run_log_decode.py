"""The run log's numeric decoder against protobuf's own parser, for messages protobuf wrote with
any mix of present and absent fields (the slow path) and with one shared layout (the fast path)."""

import numpy as np
import pytest
from google.protobuf import descriptor_pb2, descriptor_pool, message_factory
from hypothesis import given, settings
from hypothesis import strategies as st

from orchestrator.runlog.decode import DecodeError, decode, numeric_schema
from orchestrator.runlog.schemas import DoubleMessage, file_descriptor_set

SAMPLE = DoubleMessage("TestSample", ("t_s", "a", "b"), repeated=("values",))
SCHEMA_DATA = file_descriptor_set(SAMPLE)


def _message_class():
    pool = descriptor_pool.DescriptorPool()
    for file in descriptor_pb2.FileDescriptorSet.FromString(SCHEMA_DATA).file:
        pool.Add(file)
    return message_factory.GetMessageClass(pool.FindMessageTypeByName("excosim.TestSample"))


Sample = _message_class()
finite = st.floats(allow_nan=False, allow_infinity=True, width=64)
message = st.fixed_dictionaries({}, optional={
    "t_s": finite, "a": finite, "b": finite, "values": st.lists(finite, max_size=4)})


def _expected(messages: list[dict], name: str):
    if name == "values":
        return [np.array(m.get("values", []), dtype=float) for m in messages]
    return np.array([m.get(name, np.nan) for m in messages], dtype=float)


@settings(max_examples=150, deadline=None)
@given(st.lists(message, min_size=1, max_size=12))
def test_decoding_equals_protobufs_parse(messages):
    payloads = [Sample(**m).SerializeToString() for m in messages]
    parsed = [Sample.FromString(p) for p in payloads]
    decoded = decode(numeric_schema("excosim.TestSample", SCHEMA_DATA), payloads)
    for name in ("t_s", "a", "b"):
        if not any(m.HasField(name) for m in parsed):
            assert name not in decoded
            continue
        expected = np.array([getattr(m, name) if m.HasField(name) else np.nan for m in parsed])
        assert np.array_equal(decoded[name], expected, equal_nan=True)
    if any(m.get("values") for m in messages):
        got = list(decoded["values"])
        for row, want in zip(got, _expected(messages, "values"), strict=True):
            assert np.array_equal(np.asarray(row, dtype=float), want)


def test_messages_of_one_layout_decode_as_columns():
    rng = np.random.default_rng(4)
    values = rng.normal(size=(50, 3))
    payloads = [Sample(t_s=t, a=a, values=[a, b]).SerializeToString() for t, a, b in values]
    decoded = decode(numeric_schema("excosim.TestSample", SCHEMA_DATA), payloads)
    assert set(decoded) == {"t_s", "a", "values"}
    assert np.array_equal(decoded["t_s"], values[:, 0])
    assert decoded["values"].shape == (50, 2)
    assert np.array_equal(decoded["values"], values[:, 1:])


def test_a_field_added_by_a_newer_writer_is_skipped():
    newer = DoubleMessage("TestSample", ("t_s", "a", "b", "d", "c"))  # c: field 5
    payload = (b"\x09" + np.float64(1.5).tobytes() + b"\x29" + np.float64(7.0).tobytes())
    decoded = decode(numeric_schema("excosim.TestSample", file_descriptor_set(newer)), [payload])
    assert decoded["t_s"][0] == 1.5 and decoded["c"][0] == 7.0
    decoded = decode(numeric_schema("excosim.TestSample", SCHEMA_DATA), [payload])
    assert set(decoded) == {"t_s"}  # field 5 is unknown to this schema: skipped, no error


def test_malformed_input_is_refused_with_a_reason():
    schema = numeric_schema("excosim.TestSample", SCHEMA_DATA)
    with pytest.raises(DecodeError, match="wire type 0"):
        decode(schema, [b"\x08\x01"])  # a varint field: not a double
    with pytest.raises(DecodeError, match="ends inside"):
        decode(schema, [b"\x09\x00\x00"])
    with pytest.raises(DecodeError, match="does not define message excosim.Other"):
        numeric_schema("excosim.Other", SCHEMA_DATA)
