"""The arm and the pile in Foxglove's 3D terms: frame transforms of the arm links and scene
updates of the arm, the pile surface and the bucket-tip path.

Frames (Foxglove and ROS REP-103: x forward, y left, z up, right-handed):

- `world`: the machine frame turned so that x points forward. x = -y_machine (the machine digs
  at y < 0, so the dig zone is at x > 0), z = z_machine (up, ground at z = 0), y = lateral (the
  arm moves in the plane y = 0).
- `boom`: origin at the boom foot, x along the boom line (boom foot -> stick pin).
- `stick`: origin at the stick pin, x along the stick line (stick pin -> bucket pin).
- `bucket`: origin at the bucket pin, x along the bucket line (bucket pin -> bucket tip).
- `bucket_tip`: origin at the bucket tip, axes as `bucket`.

Each link frame is its parent turned about its y axis by minus the joint angle (a joint angle
turns its link up toward +z, which is a negative turn about +y), so a point (u, 0, v) of a link
frame is the point (u, v) of `plant_models.geometry`'s link frames.
"""

from __future__ import annotations

import math

import numpy as np
from foxglove.messages import (
    Color,
    CubePrimitive,
    Duration,
    Pose,
    Quaternion,
    SceneEntity,
    SceneUpdate,
    Timestamp,
    Vector3,
)

from orchestrator.runlog import native
from orchestrator.runlog.wire import doubles, field, rows, varint
from plant_models.geometry import ExcavatorGeometry

WORLD = "world"
LINK_FRAMES = ("boom", "stick", "bucket")
TIP_FRAME = "bucket_tip"
FRAMES = (WORLD, *LINK_FRAMES, TIP_FRAME)
FRAMES_DOC = (
    "world: x = -y_machine (forward), y = lateral (left), z = z_machine (up, ground z = 0); "
    "boom, stick, bucket: origin at the link's proximal pin, x along the link; "
    "bucket_tip: at the bucket tip; a link frame is its parent turned about y by -joint angle"
)

_ARM_COLOR = Color(r=0.95, g=0.7, b=0.1, a=1.0)
_PILE_COLOR = (0.55, 0.4, 0.25, 1.0)
_PATH_COLOR = (0.1, 0.5, 1.0, 1.0)
# Display sizes only, relative to the arm's reach: link thickness and the pile's shown width.
_LINK_THICKNESS = 0.03
_PILE_WIDTH = 0.15


def link_transforms(geometry: ExcavatorGeometry, joints_rad: np.ndarray):
    """Parent->child transforms of the arm for joints (n, 3) rad.

    Returns a list of (parent, child, translation (n, 3) m, rotation (n, 4) quaternion x, y, z, w),
    in the order world->boom, boom->stick, stick->bucket, bucket->bucket_tip.
    """
    q = np.asarray(joints_rad, dtype=float)
    n = len(q)
    foot_y, foot_z = geometry.boom_foot_m
    offsets = (
        (-foot_y, foot_z), (geometry.boom_length_m, 0.0), (geometry.stick_length_m, 0.0),
        (geometry.bucket_length_m, 0.0),
    )
    out = []
    for index, (parent, child) in enumerate(zip(FRAMES[:-1], FRAMES[1:], strict=True)):
        translation = np.zeros((n, 3))
        translation[:, 0], translation[:, 2] = offsets[index]
        rotation = np.zeros((n, 4))
        if index < 3:
            half = -0.5 * q[:, index]
            rotation[:, 1], rotation[:, 3] = np.sin(half), np.cos(half)
        else:
            rotation[:, 3] = 1.0
        out.append((parent, child, translation, rotation))
    return out


def tip_positions(geometry: ExcavatorGeometry, joints_rad: np.ndarray) -> np.ndarray:
    """Bucket tip (n, 3) m in `world` for joints (n, 3) rad."""
    q = np.asarray(joints_rad, dtype=float)
    angles = np.cumsum(q, axis=1)
    lengths = (geometry.boom_length_m, geometry.stick_length_m, geometry.bucket_length_m)
    xyz = np.zeros((len(q), 3))
    xyz[:, 0] = -geometry.boom_foot_m[0] + np.cos(angles) @ np.array(lengths)
    xyz[:, 2] = geometry.boom_foot_m[1] + np.sin(angles) @ np.array(lengths)
    return xyz


def _string_field(number: int, text: str) -> bytes:
    return field(number, text.encode())


def transform_records(transforms, log_time_ns: np.ndarray, channel_id: int,
                      first_sequence: int) -> list[tuple[np.ndarray, int, TransformRows]]:
    """foxglove.FrameTransforms message records of `channel_id`, one per sample, from
    `link_transforms` output and the samples' times (n,) ns (the transforms' timestamps;
    sequence numbers from `first_sequence`), written by rows.c when the chunk's records are made
    (ChunkBuilder.add_rows): [(sample indices, record size in bytes, their TransformRows)], one
    entry per record size (sizes differ only through the timestamp varints). Explicit zeros are
    written (valid protobuf) so that every other part has a fixed size. tests/run_log_reference.py
    encodes the same messages the plain way (the tests' oracle)."""
    ns = np.asarray(log_time_ns, dtype=np.uint64)
    billion = np.uint64(1_000_000_000)
    stamp = 2 + _varint_sizes(ns // billion) + _varint_sizes(ns % billion)  # Timestamp bytes
    names = [_string_field(2, parent) + _string_field(3, child)
             for parent, child, _, _ in transforms]
    name_at = np.cumsum([0, *(len(n) for n in names)], dtype=np.int64)
    poses = np.stack([np.concatenate([translation, rotation], axis=1)
                      for _, _, translation, rotation in transforms], axis=1)  # (n, T, 7)
    sequences = (first_sequence + np.arange(len(ns))).astype(np.uint32)
    out = []
    for size in np.unique(stamp).tolist():
        index = np.flatnonzero(stamp == size)
        width = _MESSAGE_HEADER_SIZE
        for name in names:
            transform = 1 + len(varint(size)) + size + len(name) + _POSE_FIELDS_SIZE
            width += 1 + len(varint(transform)) + transform
        out.append((index, width, TransformRows(
            channel_id, sequences[index], ns[index], b"".join(names), name_at, poses[index])))
    return out


class TransformRows:
    """foxglove.FrameTransforms records of one size, kept as their values until written by
    their rows.c job, which puts record i at byte at[i] (fill_transforms)."""

    def __init__(self, channel_id: int, sequences: np.ndarray, times_ns: np.ndarray,
                 names: bytes, name_at: np.ndarray, poses: np.ndarray) -> None:
        self.channel_id, self.sequences, self.times = channel_id, sequences, times_ns
        self.names = np.frombuffer(names, dtype=np.uint8)
        self.name_at = name_at
        self.poses = np.ascontiguousarray(poses, dtype=np.float64)  # (n, T, 7)
        if self.poses.shape != (len(times_ns), len(name_at) - 1, 7):
            raise ValueError(f"poses have shape {self.poses.shape}, expected "
                             f"({len(times_ns)}, {len(name_at) - 1}, 7)")

    def job(self, records: np.ndarray, at: np.ndarray, keep: list) -> list[int]:
        """The rows.c job that writes these records (`keep`: where arrays it points to are
        kept alive until it has run)."""
        at, p = np.ascontiguousarray(at, dtype=np.int64), native.pointer
        keep.append(at)
        return native.job(native.FILL_TRANSFORMS, p(records), p(at), len(at), self.channel_id,
                          p(self.sequences), p(self.times), len(self.name_at) - 1,
                          p(self.names), p(self.name_at), p(self.poses))


_VARINT_STEPS = np.array([1 << bits for bits in range(7, 64, 7)], dtype=np.uint64)


def _varint_sizes(values: np.ndarray) -> np.ndarray:
    """Bytes of the protobuf varint of each non-negative integer (n,) uint64."""
    return 1 + np.searchsorted(_VARINT_STEPS, values, side="right")


_MESSAGE_HEADER_SIZE = 31  # MCAP message record: opcode, length, channel, sequence, 2 times
_POSE_FIELDS_SIZE = 2 + 3 * 9 + 2 + 4 * 9  # translation (Vector3) and rotation (Quaternion)


def _reach(geometry: ExcavatorGeometry | None) -> float:
    if geometry is None:
        return 1.0
    return geometry.boom_length_m + geometry.stick_length_m + geometry.bucket_length_m


def _time(time_ns: int) -> Timestamp:
    seconds, nanos = divmod(int(time_ns), 1_000_000_000)
    return Timestamp(sec=seconds, nsec=nanos)


def arm_scene(geometry: ExcavatorGeometry, time_ns: int) -> bytes:
    """foxglove.SceneUpdate with one box per link, locked to the link frames."""
    thickness = _LINK_THICKNESS * _reach(geometry)
    lengths = (geometry.boom_length_m, geometry.stick_length_m, geometry.bucket_length_m)
    entities = []
    for frame, length in zip(LINK_FRAMES, lengths, strict=True):
        cube = CubePrimitive(
            pose=Pose(position=Vector3(x=length / 2.0, y=0.0, z=0.0),
                      orientation=Quaternion(x=0.0, y=0.0, z=0.0, w=1.0)),
            size=Vector3(x=length, y=thickness, z=thickness), color=_ARM_COLOR,
        )
        entities.append(SceneEntity(
            timestamp=_time(time_ns), frame_id=frame, id=f"arm/{frame}", frame_locked=True,
            lifetime=Duration(sec=0, nsec=0), cubes=[cube],
        ))
    return SceneUpdate(entities=entities).encode()


# Hand-encoded parts of the pile scene (its point lists are long; numpy encodes them at once).
# Field numbers: foxglove/SceneEntity.proto, TriangleListPrimitive.proto, LinePrimitive.proto.
_IDENTITY_POSE = field(1, doubles((1, 2, 3), np.zeros((1, 3))).tobytes()) + field(
    2, doubles((1, 2, 3, 4), np.array([[0.0, 0.0, 0.0, 1.0]])).tobytes())


def _color(rgba) -> bytes:
    return doubles((1, 2, 3, 4), np.array([rgba], dtype=float)).tobytes()


def _points(number: int, xyz: np.ndarray) -> bytes:
    """Repeated foxglove.Point3 field `number` for points (n, 3) m."""
    return rows(len(xyz), [bytes([number << 3 | 2, 27]), doubles((1, 2, 3), xyz)]).tobytes()


def _entity(time_ns: int, entity_id: str, primitive: bytes) -> bytes:
    seconds, nanos = divmod(int(time_ns), 1_000_000_000)
    stamp = b"\x08" + varint(seconds) + b"\x10" + varint(nanos)
    lifetime_forever = field(4, b"")
    return (field(1, stamp) + _string_field(2, WORLD) + _string_field(3, entity_id)
            + lifetime_forever + primitive)


EARLIER_PROFILES = 4  # the trench profiles of the last periods, drawn fading


def pile_scene(time_ns: int, grid_m, profile_m, tip_world_m, geometry: ExcavatorGeometry | None,
               earlier=()) -> bytes:
    """foxglove.SceneUpdate with the pile surface (the profile z(y) extruded across a display
    width), the bucket-tip path of the period (tip_world_m (n, 3) m in `world`, or None) and
    the surface profiles before it (`earlier`: [(grid (n,) m, profile (n,) m)], newest first,
    at most EARLIER_PROFILES), as lines in the arm's plane that fade with age."""
    entities = b""
    for age, (grid, profile) in enumerate(list(earlier)[:EARLIER_PROFILES]):
        y, z = np.asarray(grid, dtype=float), np.asarray(profile, dtype=float)
        if len(y) < 2:
            continue
        alpha = 0.7 * (1.0 - age / EARLIER_PROFILES)
        line = (b"\x08\x00" + field(2, _IDENTITY_POSE) + b"\x19" + np.float64(2.0).tobytes()
                + b"\x20\x01" + _points(5, np.column_stack([-y, np.zeros_like(y), z]))
                + field(6, _color((*_PILE_COLOR[:3], alpha))))
        entities += field(2, _entity(time_ns, f"pile/earlier/{age + 1}", field(11, line)))
    if grid_m is not None and profile_m is not None and len(grid_m) >= 2:
        y, z = np.asarray(grid_m, dtype=float), np.asarray(profile_m, dtype=float)
        half = 0.5 * _PILE_WIDTH * _reach(geometry)
        corners = np.zeros((len(y), 2, 3))
        corners[:, :, 0] = -y[:, None]
        corners[:, :, 1] = (-half, half)
        corners[:, :, 2] = z[:, None]
        a = 2 * np.arange(len(y) - 1, dtype=np.uint32)[:, None]
        indices = (a + np.array([0, 1, 2, 1, 3, 2], dtype=np.uint32)).astype("<u4")
        triangles = (field(1, _IDENTITY_POSE) + _points(2, corners.reshape(-1, 3))
                     + field(3, _color(_PILE_COLOR)) + field(5, indices.tobytes()))
        entities += field(2, _entity(time_ns, "pile/surface", field(12, triangles)))
    if tip_world_m is not None and len(tip_world_m) >= 2:
        line = (b"\x08\x00" + field(2, _IDENTITY_POSE)  # LINE_STRIP
                + b"\x19" + np.float64(3.0).tobytes() + b"\x20\x01"  # 3 px, scale-invariant
                + _points(5, np.asarray(tip_world_m, dtype=float)) + field(6, _color(_PATH_COLOR)))
        entities += field(2, _entity(time_ns, "pile/bucket_tip_path", field(11, line)))
    return entities


def decimation_stride(t_s: np.ndarray, rate_hz: float) -> int:
    """Sample stride giving about `rate_hz` from samples at times t_s (s)."""
    if len(t_s) < 2:
        return 1
    step = float(np.median(np.diff(t_s)))
    if not step > 0.0:
        return 1
    return max(1, int(math.floor(1.0 / (rate_hz * step) + 0.5)))
