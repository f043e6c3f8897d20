"""What a viewer shows of a period while it plays: its plan beside the dig.

- `/period/start` (JSON, `excosim.PeriodStart`) at the period's start: the part of the period
  record that is known before the arm moves (k, D, dz, eps, the reset, the planned duration,
  the via-points, the planner's time). One message per period: an event that marks each
  period's start on the shared time axis, and the record of the period being played (the
  full `/period` record comes at the period's end, with the weighed mass).
- `/scene/plan` (foxglove.SceneUpdate) at the period's start: the planned bucket-tip path,
  its via-points and D; again at the period's end, with the lowest point the tip reached.
  Each message holds the whole picture of its period (a viewer that seeks shows the last
  message of a topic, so nothing may depend on an earlier one) and first deletes the entities
  of the period before.
- `/scene/tip_trail` (foxglove.SceneUpdate) every `TRAIL_PERIOD_S` during the period: the
  measured tip path from the period's start to that time.

All in the `world` frame of `orchestrator.runlog.scene`.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from foxglove.messages import (
    Color,
    LinePrimitive,
    LinePrimitiveLineType,
    Point3,
    Pose,
    Quaternion,
    SceneEntity,
    SceneEntityDeletion,
    SceneEntityDeletionType,
    SceneUpdate,
    SpherePrimitive,
    TextPrimitive,
    Timestamp,
    Vector3,
)

from orchestrator.runlog.scene import WORLD, tip_positions
from orchestrator.runlog.schemas import PERIOD_SUMMARY_SCHEMA
from plant_models.geometry import ExcavatorGeometry

# The keys of a period record that are known at the period's start (the fuzzy rule's decision
# and the plan); the rest (masses, peaks, tracking, energy) come from the dig.
START_KEYS = ("k", "t0_s", "deepest_point_m", "dz_m", "eps_m", "flag", "reset", "duration_s",
              "planner_ms", "via_points_rad", "segment_durations_s")
PERIOD_START_SCHEMA: dict = {
    "title": "excosim.PeriodStart",
    "description": "A digging period as planned, at its start: the fuzzy rule's D and the "
                   "time-jerk optimal path (the weighed result follows on /period).",
    "type": "object",
    "properties": {key: PERIOD_SUMMARY_SCHEMA["properties"][key] for key in START_KEYS},
    "additionalProperties": True,
}

TRAIL_PERIOD_S = 0.25  # a trail message 4 times a second: smooth enough to watch
TRAIL_POINT_S = 0.1  # trail points 10 per second: 3 mm apart at the paper's tip speeds
_PLAN = Color(r=0.75, g=0.75, b=0.75, a=1.0)
_VIA = Color(r=0.3, g=0.3, b=0.3, a=1.0)
_DEEPEST = Color(r=0.85, g=0.1, b=0.1, a=1.0)
_LOWEST = Color(r=0.1, g=0.65, b=0.2, a=1.0)
_TRAIL = Color(r=0.1, g=0.5, b=1.0, a=1.0)
_UPRIGHT = Quaternion(x=0.0, y=0.0, z=0.0, w=1.0)
_IDENTITY = Pose(position=Vector3(x=0.0, y=0.0, z=0.0), orientation=_UPRIGHT)


def period_start(record: Mapping, k: int) -> dict:
    """The /period/start message of period k from its record: the START_KEYS it has."""
    start = {key: record[key] for key in START_KEYS if key in record}
    start["k"] = k
    return start


def _stamp(time_ns: int) -> Timestamp:
    seconds, nanos = divmod(int(time_ns), 1_000_000_000)
    return Timestamp(sec=seconds, nsec=nanos)


def _world(y_m: float, z_m: float) -> tuple[float, float, float]:
    """A point (y, z) of the machine frame in `world` (x = -y), m."""
    return -float(y_m), 0.0, float(z_m)


def _marker(time_ns: int, entity_id: str, at: tuple[float, float, float], size_m: float,
            color: Color, label: str) -> SceneEntity:
    x, y, z = at
    pose = Pose(position=Vector3(x=x, y=y, z=z), orientation=_UPRIGHT)
    text_pose = Pose(position=Vector3(x=x, y=y, z=z + 1.5 * size_m), orientation=_UPRIGHT)
    return SceneEntity(
        timestamp=_stamp(time_ns), frame_id=WORLD, id=entity_id, frame_locked=False,
        spheres=[SpherePrimitive(pose=pose, size=Vector3(x=size_m, y=size_m, z=size_m),
                                 color=color)],
        texts=[TextPrimitive(pose=text_pose, billboard=True, font_size=14.0,
                             scale_invariant=True, color=color, text=label)],
    )


def _line(xyz: np.ndarray, color: Color, thickness_px: float) -> LinePrimitive:
    return LinePrimitive(type=LinePrimitiveLineType.LineStrip, pose=_IDENTITY,
                         thickness=thickness_px, scale_invariant=True,
                         points=[Point3(x=float(x), y=float(y), z=float(z)) for x, y, z in xyz],
                         color=color)


def plan_scene(time_ns: int, k: int, record: Mapping, reference_rad: np.ndarray,
               geometry: ExcavatorGeometry, lowest_tip_m=None) -> bytes:
    """foxglove.SceneUpdate of period k's plan: the tip path of the reference joints (n, 3) rad
    (grey), the via-points of `record["via_points_rad"]` (dark dots), D (red) and, at the
    period's end, the lowest tip point [y, z] m (green); after deleting the entities of the
    topic's earlier messages."""
    size = 0.012 * (geometry.boom_length_m + geometry.stick_length_m + geometry.bucket_length_m)
    entities = []
    path = tip_positions(geometry, reference_rad)
    if len(path) >= 2:
        entities.append(SceneEntity(timestamp=_stamp(time_ns), frame_id=WORLD, id="plan/path",
                                    lines=[_line(path, _PLAN, 4.0)]))
    via = record.get("via_points_rad")
    if isinstance(via, Mapping) and all(joint in via for joint in ("boom", "stick", "bucket")):
        joints = np.column_stack([np.asarray(via[j], dtype=float)
                                  for j in ("boom", "stick", "bucket")])
        spheres = [SpherePrimitive(pose=Pose(position=Vector3(x=float(x), y=float(y),
                                                              z=float(z)),
                                             orientation=_UPRIGHT),
                                   size=Vector3(x=size, y=size, z=size), color=_VIA)
                   for x, y, z in tip_positions(geometry, joints)]
        entities.append(SceneEntity(timestamp=_stamp(time_ns), frame_id=WORLD,
                                    id="plan/via_points", spheres=spheres))
    deepest = record.get("deepest_point_m")
    if deepest is not None and len(deepest) == 2:
        entities.append(_marker(time_ns, "plan/deepest_point", _world(*deepest), 1.6 * size,
                                _DEEPEST, f"D{k}"))
    if lowest_tip_m is not None and len(lowest_tip_m) == 2:
        entities.append(_marker(time_ns, "dig/lowest_point", _world(*lowest_tip_m), 1.6 * size,
                                _LOWEST, f"lowest {k}"))
    clear = SceneEntityDeletion(timestamp=_stamp(time_ns), type=SceneEntityDeletionType.All,
                                id="")
    return SceneUpdate(deletions=[clear], entities=entities).encode()


def trail_messages(geometry: ExcavatorGeometry, t_s: np.ndarray, joints_rad: np.ndarray,
                   log_ns: np.ndarray) -> list[tuple[int, bytes]]:
    """/scene/tip_trail of a period: [(log time ns, SceneUpdate bytes)], one about every
    TRAIL_PERIOD_S after the start and one at the last sample, each with the measured tip path
    up to its sample (points about TRAIL_POINT_S apart, then the tip at that sample).
    t_s (m,) s, joints_rad (m, 3) rad, log_ns (m,) ns: the period's samples."""
    t = np.asarray(t_s, dtype=float)
    if len(t) < 2:
        return []
    points = _every(t, TRAIL_POINT_S)
    tip = tip_positions(geometry, np.asarray(joints_rad)[points])
    out = []
    for index in _every(t, TRAIL_PERIOD_S)[1:]:
        upto = int(np.searchsorted(points, index, side="right"))
        path = tip[:upto] if points[upto - 1] == index else np.vstack(
            [tip[:upto], tip_positions(geometry, np.asarray(joints_rad)[[index]])])
        out.append((int(log_ns[index]), trail_scene(int(log_ns[index]), path)))
    return out


def _every(t: np.ndarray, spacing_s: float) -> np.ndarray:
    ticks = np.floor((t - t[0]) / spacing_s + 1e-9)
    picked = np.flatnonzero(np.diff(ticks, prepend=-1.0) > 0)
    return np.union1d(picked, [len(t) - 1])


def trail_scene(time_ns: int, tip_world_m: np.ndarray) -> bytes:
    """foxglove.SceneUpdate of the tip's trail: the points (n, 3) m in `world` so far."""
    entity = SceneEntity(timestamp=_stamp(time_ns), frame_id=WORLD, id="dig/tip_trail",
                         lines=[_line(tip_world_m, _TRAIL, 3.0)] if len(tip_world_m) >= 2
                         else [])
    return SceneUpdate(entities=[entity]).encode()
