"""The MCAP run log (orchestrator.runlog: writer and reader), checked with independent readers.

Files are read back with the `mcap` package's own readers and decoded with
mcap-protobuf-support from the schemas stored in the file (not with the writer's code); the arm
frames are composed with scipy's rotations and compared with plant_models' forward kinematics;
hashes with hashlib; a killed run is a real SIGKILL of a writing process.
"""

import hashlib
import json
import os
import signal
import struct
import subprocess
import sys
import textwrap
from importlib import metadata as importlib_metadata
from pathlib import Path

import numpy as np
import pytest
import zstandard
from hypothesis import given
from hypothesis import strategies as st
from mcap.exceptions import EndOfFile
from mcap.reader import NonSeekingReader, make_reader
from mcap.records import Chunk, MessageIndex
from mcap.stream_reader import StreamReader
from mcap.writer import Writer
from mcap_protobuf.decoder import DecoderFactory
from run_log_files import chunks, cut_inside_chunk
from run_log_reference import varint_digits
from scipy.spatial.transform import Rotation

from orchestrator.runlog import LogSettings, RunDescription, RunLog, RunLogError, read_run
from orchestrator.runlog.scene import FRAMES
from orchestrator.runlog.wire import varint
from plant_models import presets
from plant_models.geometry import forward_kinematics
from plant_models.plant import JOINTS, PeriodMeasurement

GEOMETRY = presets.get("paper")
CYLINDER_ROLES = ("x", "v", "p_A", "p_B", "F")
PILE_OUTPUTS = ("bucket_mass", "F_y", "F_z", "surface_z_at_tip")
SAMPLES = 400
STEP_S = 0.01  # 100 Hz samples: /tf at 25 Hz takes every 4th
PERIOD_S = 5.0  # campaign time between period starts


def measurement(seed: int, samples: int = SAMPLES) -> PeriodMeasurement:
    """A period of arm motion inside the joint limits, random signals, a pile profile."""
    rng = np.random.default_rng(seed)
    t = np.arange(samples) * STEP_S
    limits = np.array(GEOMETRY.joint_limits_rad)
    middle, half = limits.mean(axis=1), 0.4 * np.diff(limits, axis=1)[:, 0]
    phase = rng.uniform(0, 2 * np.pi, 3)
    joints = middle + half * np.sin(2 * np.pi * t[:, None] / 4.0 + phase)
    signals = {f"{joint}.{role}": rng.normal(size=samples) * 1e5
               for joint in JOINTS for role in CYLINDER_ROLES}
    signals["boom.u"] = rng.uniform(-1, 1, samples)  # only the boom reports its spool command
    signals.update({f"pile.{name}": rng.normal(size=samples) for name in PILE_OUTPUTS})
    tip_y, tip_z, angle = forward_kinematics(GEOMETRY, joints)
    signals.update({"tip.y": tip_y, "tip.z": tip_z, "tip.bucket_angle": angle})
    signals["valve.spool"] = rng.normal(size=samples)  # a component no fixed channel knows
    grid = np.linspace(-13.0, -2.0, 45)
    profile = -0.3 * np.exp(-((grid + 9.0) ** 2)) * (seed + 1)
    return PeriodMeasurement(t, joints, joints + rng.normal(size=(samples, 3)) * 1e-3,
                             float(8 + seed), signals, profile, grid)


def record(k: int) -> dict:
    return {"k": k, "deepest_point_m": [-9.0, -0.1 * k], "mass_kg": 8.0 + k,
            "error_kg": 0.5 - k, "reset": k == 2, "duration_s": SAMPLES * STEP_S,
            "tracking_rms_deg": [0.1, 0.2, 0.3 * k], "planner_ms": 5.5,
            "spline": {"knots": [0.0, 0.0, 1.5, 3.0], "coefficients": [[1.0, 2.0], [3.0, k]]}}


def fake_fmus(folder: Path) -> dict[str, Path]:
    """FMU name -> a file of random bytes in `folder` (the log attaches and hashes them)."""
    paths = {}
    for name, size in (("HydraulicCylinder", 3000), ("Pile", 5000)):
        path = folder / f"{name}.fmu"
        path.write_bytes(np.random.default_rng(size).bytes(size))
        paths[name] = path
    return paths


@pytest.fixture
def fmus(tmp_path):
    return fake_fmus(tmp_path)


def open_log(path, fmus, overwrite=False, **settings):
    """A log of a 3-period test run; settings: LogSettings' fields."""
    return RunLog(path, RunDescription(
        scenario={"name": "test", "periods": 3, "target_mass_kg": 8.5},
        scenario_text="name = 'test'\nperiods = 3\n", scenario_name="test", fmus=fmus,
        plant_kind="sim", target_mass_kg=8.5, geometry=GEOMETRY), LogSettings(**settings),
        overwrite=overwrite)


def write_run(path, fmus, periods=3, termination="periods"):
    measurements = [measurement(k) for k in range(periods)]
    with open_log(path, fmus) as log:
        for k, period in enumerate(measurements, start=1):
            log.log_period(record(k), period, (k - 1) * PERIOD_S)
        log.close(termination, "done")
    return measurements


def decoded(path, topics=None):
    """(channel, message, decoded protobuf) from the mcap package's indexed reader."""
    with open(path, "rb") as stream:
        reader = make_reader(stream, validate_crcs=True, decoder_factories=[DecoderFactory()])
        return [(channel, message, proto) for _, channel, message, proto
                in reader.iter_decoded_messages(topics=topics)]


def test_records_metadata_and_attachments_round_trip(tmp_path, fmus):
    path = tmp_path / "run.mcap"
    write_run(path, fmus)
    run = read_run(path, tolerant=False)
    assert run.periods == [record(k) for k in (1, 2, 3)]
    assert run.finished and not run.truncated
    assert (run.termination, run.termination_message) == ("periods", "done")
    assert run.scenario == {"name": "test", "periods": 3, "target_mass_kg": 8.5}
    versions = run.metadata["excosim.versions"]
    assert versions["numpy"] == np.__version__
    assert versions["mcap"] == importlib_metadata.version("mcap")
    assert {"excosim", "fmpy", "scipy", "control", "foxglove", "python"} <= set(versions)
    for name, fmu in fmus.items():
        digest = hashlib.sha256(fmu.read_bytes()).hexdigest()
        assert run.metadata["excosim.fmus"][name] == digest
        assert run.attachments[run.metadata["excosim.fmu_attachments"][name]] == fmu.read_bytes()
    assert run.attachments["scenario.toml"] == b"name = 'test'\nperiods = 3\n"
    assert run.scenario_text == "name = 'test'\nperiods = 3\n"
    assert set(run.attachments) == {"scenario.toml", "fmus/HydraulicCylinder.fmu", "fmus/Pile.fmu"}
    assert run.metadata["excosim.end"]["periods"] == "3"
    # The same through the mcap package's reader.
    with open(path, "rb") as stream:
        reader = make_reader(stream)
        assert {m.name for m in reader.iter_metadata()} >= {"excosim.run", "excosim.end"}
        assert {a.name for a in reader.iter_attachments()} == set(run.attachments)


def test_an_fmu_used_by_several_roles_is_attached_once(tmp_path, fmus):
    path = tmp_path / "run.mcap"
    cylinder = fmus["HydraulicCylinder"]
    other = tmp_path / "other"
    other.mkdir()
    (other / cylinder.name).write_bytes(b"a different FMU with the same file name")
    roles = {"boom": cylinder, "stick": cylinder, "bucket": other / cylinder.name}
    open_log(path, roles).close("periods")
    run = read_run(path)
    assert run.metadata["excosim.fmu_attachments"] == {
        "boom": "fmus/HydraulicCylinder.fmu", "stick": "fmus/HydraulicCylinder.fmu",
        "bucket": "fmus/bucket/HydraulicCylinder.fmu"}
    assert run.attachments["fmus/bucket/HydraulicCylinder.fmu"] == (
        other / cylinder.name).read_bytes()
    assert len(run.attachments) == 3


def test_numpy_values_in_a_record_are_stored_as_lists(tmp_path, fmus):
    path = tmp_path / "run.mcap"
    coefficients = np.arange(6.0).reshape(3, 2)
    with open_log(path, fmus) as log:
        log.log_period({"k": np.int64(1), "spline": {"coefficients": coefficients}},
                       measurement(0), 0.0)
    assert read_run(path).periods == [{"k": 1, "spline": {"coefficients": coefficients.tolist()}}]


def test_samples_decode_to_the_measured_arrays(tmp_path, fmus):
    path = tmp_path / "run.mcap"
    measurements = write_run(path, fmus)
    messages = decoded(path, ["/joints", "/cylinder/boom", "/cylinder/stick", "/pile/bucket",
                              "/signals/valve", "/pile/profile"])
    by_topic = {}
    for channel, message, proto in messages:
        by_topic.setdefault(channel.topic, []).append((message, proto))
    for topic in ("/joints", "/cylinder/boom", "/cylinder/stick", "/pile/bucket",
                  "/signals/valve"):
        assert len(by_topic[topic]) == 3 * SAMPLES, topic
    for k, period in enumerate(measurements):
        rows = slice(k * SAMPLES, (k + 1) * SAMPLES)
        t = k * PERIOD_S + period.t_s
        joints = by_topic["/joints"][rows]
        assert [m.log_time for m, _ in joints] == list(np.rint(t * 1e9).astype(np.int64))
        np.testing.assert_array_equal([p.t_s for _, p in joints], t)
        for j, joint in enumerate(JOINTS):
            measured = [getattr(p, f"measured_{joint}_rad") for _, p in joints]
            reference = [getattr(p, f"reference_{joint}_rad") for _, p in joints]
            np.testing.assert_array_equal(measured, period.joints_rad[:, j])
            np.testing.assert_array_equal(reference, period.reference_rad[:, j])
        boom = [p for _, p in by_topic["/cylinder/boom"][rows]]
        np.testing.assert_array_equal([p.p_A_Pa for p in boom], period.signals["boom.p_A"])
        np.testing.assert_array_equal([p.u for p in boom], period.signals["boom.u"])
        stick = [p for _, p in by_topic["/cylinder/stick"][rows]]
        np.testing.assert_array_equal([p.F_N for p in stick], period.signals["stick.F"])
        assert not stick[0].HasField("u")  # not measured: absent, not zero
        pile = [p for _, p in by_topic["/pile/bucket"][rows]]
        np.testing.assert_array_equal([p.tip_z_m for p in pile], period.signals["tip.z"])
        np.testing.assert_array_equal([p.bucket_mass_kg for p in pile],
                                      period.signals["pile.bucket_mass"])
        assert not pile[0].HasField("pile_mass_kg")
        valve = [p for _, p in by_topic["/signals/valve"][rows]]
        np.testing.assert_array_equal([p.values[0] for p in valve], period.signals["valve.spool"])
        _, profile = by_topic["/pile/profile"][k]
        np.testing.assert_array_equal(profile.y_m, period.pile_grid_m)
        np.testing.assert_array_equal(profile.z_m, period.pile_profile_m)
    channels = {channel.topic: channel for channel, _, _ in messages}
    assert json.loads(channels["/signals/valve"].metadata["names"]) == ["valve.spool"]
    assert json.loads(channels["/cylinder/boom"].metadata["signals"])["p_A_Pa"] == "boom.p_A"


def test_indexes_and_statistics_match_the_messages(tmp_path, fmus):
    path = tmp_path / "run.mcap"
    write_run(path, fmus)
    chunk, found = None, 0
    with open(path, "rb") as stream:
        for item in StreamReader(stream, emit_chunks=True, validate_crcs=True).records:
            if isinstance(item, Chunk):
                chunk = zstandard.ZstdDecompressor().decompress(
                    item.data, max_output_size=item.uncompressed_size)
            elif isinstance(item, MessageIndex):
                for log_time, offset in item.records:
                    opcode, _, channel_id, _, stamp = struct.unpack_from("<BQHIQ", chunk, offset)
                    assert (opcode, channel_id, stamp) == (0x05, item.channel_id, log_time)
                    found += 1
    with open(path, "rb") as stream:
        summary = make_reader(stream).get_summary()
    counts = {summary.channels[i].topic: n
              for i, n in summary.statistics.channel_message_counts.items()}
    assert found == summary.statistics.message_count == sum(counts.values())
    assert counts == read_run(path).message_counts
    assert summary.statistics.chunk_count == 3


def test_bucket_tip_frame_follows_forward_kinematics(tmp_path, fmus):
    path = tmp_path / "run.mcap"
    measurements = write_run(path, fmus, periods=1)
    transforms = [proto for _, _, proto in decoded(path, ["/tf"])]
    assert len(transforms) == SAMPLES // 4  # 25 Hz from 100 Hz samples
    for i, message in enumerate(transforms):
        chain = [(tf.parent_frame_id, tf.child_frame_id) for tf in message.transforms]
        assert chain == list(zip(FRAMES[:-1], FRAMES[1:], strict=True))
        position, rotation = np.zeros(3), Rotation.identity()
        for tf in message.transforms:
            position = position + rotation.apply([tf.translation.x, tf.translation.y,
                                                  tf.translation.z])
            q = tf.rotation
            rotation = rotation * Rotation.from_quat([q.x, q.y, q.z, q.w])
        stamp = message.transforms[0].timestamp
        assert stamp.seconds * 10**9 + stamp.nanos == round(measurements[0].t_s[4 * i] * 1e9)
        tip_y, tip_z, _ = forward_kinematics(GEOMETRY, measurements[0].joints_rad[4 * i])
        np.testing.assert_allclose(position, [-tip_y, 0.0, tip_z], atol=1e-6)


def test_scene_updates_show_the_arm_pile_and_tip_path(tmp_path, fmus):
    path = tmp_path / "run.mcap"
    period = write_run(path, fmus, periods=1)[0]
    arm = decoded(path, ["/scene/arm"])[0][2]
    assert sorted(e.frame_id for e in arm.entities) == ["boom", "bucket", "stick"]
    assert all(e.frame_locked and len(e.cubes) == 1 for e in arm.entities)
    _, message, pile = decoded(path, ["/scene/pile"])[0]
    assert message.log_time == round(period.t_s[-1] * 1e9)
    entities = {e.id: e for e in pile.entities}
    assert all(e.frame_id == "world" for e in entities.values())
    surface = entities["pile/surface"].triangles[0]
    corners = np.array([[p.x, p.y, p.z] for p in surface.points])
    np.testing.assert_array_equal(corners[::2, 0], -period.pile_grid_m)
    np.testing.assert_array_equal(corners[1::2, 2], period.pile_profile_m)
    assert len(surface.indices) == 6 * (len(period.pile_grid_m) - 1)
    assert max(surface.indices) == len(corners) - 1
    path_points = np.array([[p.x, p.y, p.z] for p in entities["pile/bucket_tip_path"].lines[0]
                            .points])
    tip_y, tip_z, _ = forward_kinematics(GEOMETRY, period.joints_rad[::4])
    np.testing.assert_allclose(path_points[:, [0, 2]], np.column_stack([-tip_y, tip_z]),
                               atol=1e-9)


_WRITER = textwrap.dedent("""
    import json, sys, time
    import numpy as np
    from plant_models import presets
    from plant_models.plant import PeriodMeasurement
    from orchestrator.runlog import RunDescription, RunLog
    path, arrays, records, fmu = sys.argv[1:]
    data = np.load(arrays)
    log = RunLog(path, RunDescription(
        scenario={}, scenario_text="", scenario_name="killed", fmus={"f": fmu}, plant_kind="sim",
        target_mass_kg=8.5, geometry=presets.get("paper")))
    for k, record in enumerate(json.loads(records)):
        if k == 2:
            print("logged 2", flush=True)
            time.sleep(60)
        signals = {"pile.bucket_mass": data[f"mass{k}"]}
        log.log_period(record, PeriodMeasurement(data[f"t{k}"], data[f"q{k}"], data[f"q{k}"],
                       8.0, signals), 10.0 * k)
""")


def test_a_killed_run_keeps_its_finished_periods(tmp_path, fmus):
    path, arrays = tmp_path / "killed.mcap", tmp_path / "arrays.npz"
    periods = [measurement(k) for k in range(3)]
    np.savez(arrays, **{f"{name}{k}": value for k, p in enumerate(periods) for name, value in
                        (("t", p.t_s), ("q", p.joints_rad),
                         ("mass", p.signals["pile.bucket_mass"]))})
    writer = subprocess.Popen(
        [sys.executable, "-c", _WRITER, str(path), str(arrays),
         json.dumps([record(k) for k in (1, 2, 3)]), str(fmus["Pile"])],
        stdout=subprocess.PIPE, text=True, cwd=Path(__file__).parents[1],
    )
    try:
        assert writer.stdout.readline().strip() == "logged 2"
    finally:
        os.kill(writer.pid, signal.SIGKILL)
        writer.wait()
    run = read_run(path)
    assert run.periods == [record(1), record(2)]
    assert not run.finished and run.termination is None and run.truncated
    assert run.message_counts["/pile/bucket"] == 2 * SAMPLES
    with pytest.raises(RunLogError, match="truncated after 2 complete periods"):
        read_run(path, tolerant=False)
    # The mcap package reads the same messages from the unfinished file.
    masses = []
    with open(path, "rb") as stream:
        reader = NonSeekingReader(stream, decoder_factories=[DecoderFactory()])
        with pytest.raises(EndOfFile):
            for _, _, _, proto in reader.iter_decoded_messages(topics=["/pile/bucket"],
                                                               log_time_order=False):
                masses.append(proto.bucket_mass_kg)
    expected = np.concatenate([p.signals["pile.bucket_mass"] for p in periods[:2]])
    np.testing.assert_array_equal(masses, expected)


def test_a_file_cut_inside_a_chunk_gives_its_complete_periods(tmp_path, fmus):
    path = tmp_path / "run.mcap"
    write_run(path, fmus)
    cut = cut_inside_chunk(path, tmp_path / "cut.mcap")
    run = read_run(cut)
    assert run.periods == [record(1), record(2)]
    assert run.truncated and not run.finished
    with pytest.raises(RunLogError, match="truncated"):
        read_run(cut, tolerant=False)


def test_a_damaged_chunk_ends_the_readable_part(tmp_path, fmus):
    path = tmp_path / "run.mcap"
    write_run(path, fmus)
    second = chunks(path)[1]
    data = bytearray(path.read_bytes())
    data[second.chunk_start_offset + second.chunk_length - 100] ^= 0xFF
    path.write_bytes(bytes(data))
    run = read_run(path)
    assert run.periods == [record(1)] and run.truncated and not run.finished


def test_files_that_are_not_run_logs_are_refused_in_one_line(tmp_path):
    text = tmp_path / "notes.mcap"
    text.write_text("not an mcap file\n")
    with pytest.raises(RunLogError, match="is not an MCAP file") as error:
        read_run(text)
    assert "\n" not in str(error.value)
    foreign = tmp_path / "foreign.mcap"
    with open(foreign, "wb") as stream:
        writer = Writer(stream)
        writer.start()
        channel = writer.register_channel("/x", "json", writer.register_schema("", "", b""))
        writer.add_message(channel, 1, b"{}", 1)
        writer.finish()
    with pytest.raises(RunLogError, match="not an excosim run log"):
        read_run(foreign)
    with pytest.raises(RunLogError, match="cannot read"):
        read_run(tmp_path / "missing.mcap")


def test_an_exception_inside_the_run_is_recorded(tmp_path, fmus):
    path = tmp_path / "run.mcap"
    with pytest.raises(RuntimeError, match="planner failed"), open_log(path, fmus) as log:
        log.log_period(record(1), measurement(0), 0.0)
        raise RuntimeError("planner failed")
    run = read_run(path, tolerant=False)
    assert run.finished and run.termination == "error"
    assert run.termination_message == "RuntimeError: planner failed"
    assert len(run.periods) == 1


def test_without_geometry_or_profile_only_the_samples_display_and_records_are_logged(tmp_path,
                                                                                    fmus):
    path = tmp_path / "run.mcap"
    bare = measurement(0)
    bare = PeriodMeasurement(bare.t_s, bare.joints_rad, bare.reference_rad, 1.0,
                             {"pile.bucket_mass": bare.signals["pile.bucket_mass"]})
    with RunLog(path, RunDescription(scenario={}, scenario_text='{"name": "lab"}',
                                     scenario_name="lab", fmus={}, plant_kind="lab",
                                     target_mass_kg=2.0), LogSettings(fsync=True)) as log:
        log.log_period(record(1), bare, 0.0)
    run = read_run(path, tolerant=False)
    assert run.message_counts == {"/joints": SAMPLES, "/pile/bucket": SAMPLES, "/period": 1,
                                  "/period/start": 1,
                                  "/display": SAMPLES // 4}  # at the /tf rate, 25 Hz
    assert run.termination == "periods" and "excosim.geometry" not in run.metadata
    assert run.attachments == {"scenario.json": b'{"name": "lab"}'}  # not TOML: named .json


def test_the_same_run_gives_the_same_bytes(tmp_path, fmus):
    write_run(tmp_path / "a.mcap", fmus)
    write_run(tmp_path / "b.mcap", fmus)
    assert (tmp_path / "a.mcap").read_bytes() == (tmp_path / "b.mcap").read_bytes()


def test_bad_input_is_refused_with_a_clear_message(tmp_path, fmus):
    with pytest.raises(ValueError, match="FMU 'Pile': no file"):
        open_log(tmp_path / "a.mcap", {"Pile": tmp_path / "missing.fmu"})
    log = open_log(tmp_path / "b.mcap", fmus)
    good = measurement(0)
    bad_joints = PeriodMeasurement(good.t_s, good.joints_rad[:, :2], good.reference_rad, 1.0)
    with pytest.raises(ValueError, match=r"joints_rad has shape \(400, 2\)"):
        log.log_period(record(1), bad_joints, 0.0)
    with pytest.raises(ValueError, match="period 1 record is not JSON"):
        log.log_period({"mass_kg": float("nan")}, good, 0.0)
    with pytest.raises(ValueError, match="termination must be one of"):
        log.close("done")
    log.close("workspace_limit", "z_D beyond reach")
    with pytest.raises(ValueError, match="is closed"):
        log.log_period(record(1), good, 0.0)
    with pytest.raises(FileExistsError, match="already exists"):
        open_log(tmp_path / "b.mcap", fmus)
    assert read_run(tmp_path / "b.mcap").termination == "workspace_limit"


@given(st.lists(st.integers(min_value=0, max_value=2**63), min_size=1, max_size=20))
def test_vectorised_varints_equal_the_scalar_encoding(values):
    digits, lengths = varint_digits(np.array(values, dtype=np.uint64))
    for value, row, length in zip(values, digits, lengths, strict=True):
        assert bytes(row[:length]) == varint(value)
    # and the scalar one against protobuf's own encoder (an uint64 field 1 holds a varint)
    from google.protobuf import descriptor_pb2
    encoded = descriptor_pb2.UninterpretedOption(positive_int_value=values[0])
    assert encoded.SerializeToString()[1:] == varint(values[0])

