"""The master's check of a period's reference before any frame of it is sent.

A period goes to the machine only if every setpoint of its stream is inside the arm's joint
ranges and the scenario's velocity and acceleration limits, judged both on the reference's own
velocity and acceleration (the feed-forward the device receives) and on the setpoints' finite
differences (what the device's position loop sees: a divided difference of a smooth trajectory
equals its derivative somewhere in the interval, so a planned spline that keeps its limits keeps
them here too), and inside the protocol's encodable ranges. Otherwise the period is refused with
ReferenceRefused, a ValueError naming the joint, the sample and the bound.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from orchestrator.plants.lab.protocol import signal_range
from plant_models.plant import JOINTS, JointReference

RELATIVE_TOLERANCE = 1e-6  # the planner keeps its limits to 1e-9; this is round-off only
LIMIT_TOLERANCE_RAD = 1e-6  # as plant_models.geometry's joint-range tolerance


class ReferenceRefused(ValueError):
    """A period's reference breaks a limit; nothing of the period was sent."""


@dataclass(frozen=True)
class Stream:
    """A period's setpoints on the stream grid t = 0, T, 2T, ...: t_s (n,) s, position_rad,
    velocity_rad_s, acceleration_rad_s2 (n, 3)."""

    t_s: np.ndarray
    position_rad: np.ndarray
    velocity_rad_s: np.ndarray
    acceleration_rad_s2: np.ndarray


def on_stream_grid(reference: JointReference, frame_period_s: float) -> Stream:
    """The reference on the grid k T (linear interpolation, held after its end, as the simulated
    plant samples it); ReferenceRefused for non-finite values or a bad time axis."""
    t_ref = np.asarray(reference.t_s, dtype=float)
    arrays = [np.asarray(a, dtype=float) for a in (
        reference.position_rad, reference.velocity_rad_s, reference.acceleration_rad_s2)]
    if not (np.all(np.isfinite(t_ref)) and all(np.all(np.isfinite(a)) for a in arrays)):
        raise ReferenceRefused("period refused before any frame was sent: the reference "
                               "contains NaN or infinite values")
    if t_ref[0] != 0.0 or np.any(np.diff(t_ref) <= 0.0):
        raise ReferenceRefused("period refused before any frame was sent: the reference's "
                               "t_s must start at 0 s and increase")
    count = int(math.ceil(t_ref[-1] / frame_period_s - 1e-9)) + 1
    t = np.arange(count) * frame_period_s
    grid = [np.column_stack([np.interp(t, t_ref, a[:, j]) for j in range(3)]) for a in arrays]
    return Stream(t, *grid)


def check_stream(stream: Stream, joint_limits_rad, limits_rad) -> None:
    """ReferenceRefused unless every setpoint keeps the joint ranges ((3, 2) rad), the limits
    (rows velocity rad/s, acceleration rad/s^2; a third jerk row is not checked: the device
    sees no jerk) and the protocol's ranges."""
    position, velocity, acceleration = (stream.position_rad, stream.velocity_rad_s,
                                        stream.acceleration_rad_s2)
    limits = np.asarray(limits_rad, dtype=float)
    for j, joint in enumerate(JOINTS):
        low, high = joint_limits_rad[j]
        _bound(stream.t_s, position[:, j], low - LIMIT_TOLERANCE_RAD, high + LIMIT_TOLERANCE_RAD,
               f"{joint} setpoint", "deg", "the joint range")
        v_max, a_max = limits[0, j] * (1 + RELATIVE_TOLERANCE), limits[1, j] * (
            1 + RELATIVE_TOLERANCE)
        _bound(stream.t_s, velocity[:, j], -v_max, v_max, f"{joint} velocity", "deg/s",
               "the velocity limit")
        _bound(stream.t_s, acceleration[:, j], -a_max, a_max, f"{joint} acceleration",
               "deg/s^2", "the acceleration limit")
        if len(stream.t_s) > 1:
            h = stream.t_s[1] - stream.t_s[0]
            rate = np.diff(position[:, j]) / h
            _bound(stream.t_s[1:], rate, -v_max, v_max, f"{joint} setpoint step / T", "deg/s",
                   "the velocity limit")
        if len(stream.t_s) > 2:
            second = np.diff(position[:, j], 2) / (h * h)
            _bound(stream.t_s[1:-1], second, -a_max, a_max, f"{joint} setpoint second "
                   "difference / T^2", "deg/s^2", "the acceleration limit")
    for name, values, unit in (("RefPosition", position, "deg"),
                               ("RefVelocity", velocity, "deg/s"),
                               ("RefAcceleration", acceleration, "deg/s^2")):
        for j, signal in enumerate(("Boom", "Stick", "Bucket")):
            low, high = (math.radians(v) for v in signal_range(name, signal))
            _bound(stream.t_s, values[:, j], low, high, f"{JOINTS[j]} {name}", unit,
                   "the protocol's range")


def _bound(t_s: np.ndarray, values: np.ndarray, low: float, high: float, what: str, unit: str,
           bound: str) -> None:
    bad = np.flatnonzero((values < low) | (values > high))
    if bad.size:
        i = int(bad[0])
        raise ReferenceRefused(
            f"period refused before any frame was sent: {what} {math.degrees(values[i]):.3f} "
            f"{unit} at t = {t_s[i]:.3f} s is beyond {bound} [{math.degrees(low):.3f}, "
            f"{math.degrees(high):.3f}] {unit} ({bad.size} sample(s))")
