"""The lab protocol's DBC and frame helpers against independent references: the CRC catalogue's
check value, cantools decoding straight from the DBC, docs/can-protocol.md's frame table."""

import re
from pathlib import Path

import cantools
import pytest
from lab_bus import DBC, crc8_bitwise, read_frame

from orchestrator.plants.lab import protocol

DOC = Path(__file__).resolve().parent.parent / "docs" / "can-protocol.md"


def test_the_crc_is_crc8_sae_j1850():
    assert protocol.crc8_sae_j1850(b"123456789") == 0x4B  # the catalogue's check value
    for data in (b"", b"\x00" * 9, bytes(range(9)), b"\xff\x10\x02excav"):
        assert protocol.crc8_sae_j1850(data) == crc8_bitwise(data)


def test_every_frame_is_classic_can_with_counter_and_checksum_in_the_same_place():
    db = cantools.database.load_file(str(DBC))
    ids = [m.frame_id for m in db.messages]
    assert len(set(ids)) == len(ids) and all(i < 0x800 for i in ids)
    for message in db.messages:
        assert message.length == 8 and not message.is_extended_frame, message.name
        counter, checksum = (message.get_signal_by_name(n) for n in ("Counter", "Checksum"))
        assert (counter.start, counter.length) == (48, 4), message.name
        assert (checksum.start, checksum.length) == (56, 8), message.name
        assert all(s.byte_order == "little_endian" for s in message.signals)


def test_the_all_stop_outranks_every_other_frame_on_the_bus():
    db = cantools.database.load_file(str(DBC))
    assert min(db.messages, key=lambda m: m.frame_id).name == "AllStop"


@pytest.mark.parametrize("name, signals", [
    ("RefPosition", {"Boom": 12.34, "Stick": -76.21, "Bucket": -124.99, "Counter": 7}),
    ("FbPressureA", {"Boom": 19.5, "Stick": 0.123, "Bucket": 65.535, "Counter": 15}),
    ("LoadCell", {"Mass": -0.021, "Valid": 1, "Sample": 200, "Period": 3, "Counter": 2}),
    ("Command", {"Cmd": int(protocol.Cmd.PERIOD_START), "Seq": 9, "Period": 2,
                 "Argument": 1295, "Counter": 1}),
])
def test_an_encoded_frame_decodes_by_cantools_with_a_valid_checksum(name, signals):
    frame = protocol.encode(name, **signals)
    decoded = read_frame(frame)  # cantools from the DBC file, bitwise CRC
    assert decoded.name == name and decoded.checksum_ok
    for key, value in signals.items():
        assert decoded.signals[key] == pytest.approx(value, abs=1e-9)
    assert protocol.decode(frame).checksum_ok


def test_a_corrupted_frame_fails_its_checksum_and_a_frame_under_another_id_too():
    bad = protocol.encode("FbPosition", corrupt=True, Boom=1.0)
    assert not read_frame(bad).checksum_ok and not protocol.decode(bad).checksum_ok
    good = protocol.encode("RefVelocity", Boom=1.0)
    moved = good.__class__(arbitration_id=protocol.frame_id("RefAcceleration"), data=good.data,
                           is_extended_id=False)
    assert not protocol.decode(moved).checksum_ok  # the identifier is part of the CRC


def test_a_value_outside_the_dbc_range_is_refused_by_cantools():
    with pytest.raises(cantools.database.EncodeError):
        protocol.encode("RefPosition", Boom=400.0)


def test_the_protocol_document_lists_every_frame_with_its_id_and_rate():
    db = cantools.database.load_file(str(DBC))
    text = DOC.read_text(encoding="utf-8")
    rows = dict(re.findall(r"^\| (0x[0-9A-F]{3}) \| (\w+)", text, re.MULTILINE))
    assert {int(k, 16): v for k, v in rows.items()} == {m.frame_id: m.name for m in db.messages}
    assert db.get_message_by_name("RefPosition").cycle_time == 10  # "stream (100 Hz)"
    assert db.get_message_by_name("HeartbeatMaster").cycle_time == 100  # "10 Hz"
