"""A period's measurement as run-log content: checked arrays, the high-rate channels with their
protobuf field layout, and the pile profile message (`orchestrator.runlog.schemas`)."""

from __future__ import annotations

import functools
import json
import math
from dataclasses import dataclass, replace

import numpy as np

from orchestrator.runlog.schemas import (
    CYLINDER_STATE,
    DISPLAY_SAMPLE,
    DISPLAY_SCALE,
    JOINT_STATE,
    PILE_BUCKET_STATE,
    PILE_PROFILE,
    SIGNAL_SAMPLE,
    DoubleMessage,
    cylinder_signals,
)
from orchestrator.runlog.units import signal_unit
from orchestrator.runlog.wire import varint
from plant_models.plant import JOINTS, PeriodMeasurement


@dataclass(frozen=True)
class CheckedPeriod:
    """A PeriodMeasurement as float64 arrays: t_s (m,), joints_rad and reference_rad (m, 3),
    signals name -> (m,), pile_grid_m and pile_profile_m (n_cells,) or None."""

    t_s: np.ndarray
    joints_rad: np.ndarray
    reference_rad: np.ndarray
    signals: dict[str, np.ndarray]
    pile_grid_m: np.ndarray | None
    pile_profile_m: np.ndarray | None


@dataclass(frozen=True)
class SampleChannel:
    """One high-rate channel of a period: one message per sample whose payload is, for each
    column j, `prefixes[j]` (protobuf tag bytes) then the double `columns[j][i]`."""

    topic: str
    message: DoubleMessage
    metadata: dict[str, str]
    prefixes: tuple[bytes, ...]
    columns: tuple[np.ndarray, ...]  # len(prefixes) arrays (m,)


def double_tag(number: int) -> bytes:
    """Protobuf tag of double field `number` (wire type fixed64; two bytes from field 16 on)."""
    return varint(number << 3 | 1)


def _packed_tag(number: int, count: int) -> bytes:
    """Tag and length of a packed repeated double field of `count` values."""
    return varint(number << 3 | 2) + varint(8 * count)


_JOINT_PREFIXES = tuple(double_tag(n + 1) for n in range(len(JOINT_STATE.fields)))


def checked(measurement: PeriodMeasurement) -> CheckedPeriod:
    """The measurement as float64 arrays; ValueError naming what is malformed."""
    t = np.asarray(measurement.t_s, dtype=float)
    m = t.shape[0] if t.ndim == 1 else 0
    if m < 1 or t.ndim != 1 or not np.all(np.isfinite(t)) or np.any(np.diff(t) < 0.0):
        raise ValueError("measurement.t_s must be a non-empty (m,) array of finite, "
                         "non-decreasing times in s")
    arrays = []
    for name in ("joints_rad", "reference_rad"):
        value = np.asarray(getattr(measurement, name), dtype=float)
        if value.shape != (m, len(JOINTS)):
            raise ValueError(f"measurement.{name} has shape {value.shape}, expected ({m}, 3)")
        arrays.append(value)
    signals = {}
    for name, value in measurement.signals.items():
        value = np.asarray(value, dtype=float)
        if value.shape != (m,):
            raise ValueError(f"signal {name!r} has shape {value.shape}, expected ({m},)")
        signals[name] = value
    profile, grid = measurement.pile_profile_m, None
    if profile is not None:
        profile = np.asarray(profile, dtype=float)
        if profile.ndim != 1:
            raise ValueError(f"pile_profile_m has shape {profile.shape}, expected (n_cells,)")
        if measurement.pile_grid_m is not None:
            grid = np.asarray(measurement.pile_grid_m, dtype=float)
            if grid.shape != profile.shape:
                raise ValueError(f"pile_grid_m has shape {grid.shape} but pile_profile_m has "
                                 f"shape {profile.shape}")
    return CheckedPeriod(t, arrays[0], arrays[1], signals, grid, profile)


def decimated(period: CheckedPeriod, rate_hz: float | None) -> CheckedPeriod:
    """The period's samples at about rate_hz (every n-th sample from the first, and the last,
    which holds the period's end state); all of them for rate_hz None."""
    if rate_hz is None or len(period.t_s) < 2:
        return period
    step = float(np.median(np.diff(period.t_s)))
    stride = max(1, int(math.floor(1.0 / (rate_hz * step) + 0.5))) if step > 0.0 else 1
    if stride == 1:
        return period
    keep = np.arange(0, len(period.t_s), stride)
    if keep[-1] != len(period.t_s) - 1:
        keep = np.append(keep, len(period.t_s) - 1)
    return replace(period, t_s=period.t_s[keep], joints_rad=period.joints_rad[keep],
                   reference_rad=period.reference_rad[keep],
                   signals={name: values[keep] for name, values in period.signals.items()})


def sample_channels(period: CheckedPeriod, times_s: np.ndarray) -> list[SampleChannel]:
    """The high-rate channels of a period with campaign times times_s (m,) s: /joints always;
    /cylinder/<joint> and /pile/bucket with the fields whose signals were measured; every other
    signal on /signals/<component> (the part of its name before the first dot), whose metadata
    "names" orders the values and "units" gives their units (orchestrator.runlog.units; "" where
    unknown)."""
    signals = period.signals
    out = [SampleChannel("/joints", JOINT_STATE, {}, _JOINT_PREFIXES,
                         (times_s, *period.reference_rad.T, *period.joints_rad.T))]
    for topic, message, metadata, prefixes, names in _signal_layout(tuple(signals)):
        out.append(SampleChannel(topic, message, dict(metadata), prefixes,
                                 (times_s, *(signals[name] for name in names))))
    return out


@functools.lru_cache(maxsize=16)  # a run measures the same signals every period
def _signal_layout(signal_names: tuple[str, ...]) -> tuple[tuple, ...]:
    """(topic, message, metadata, prefixes, signal names of the columns after t_s) of each
    channel of `sample_channels` after /joints, for the measured signals `signal_names`."""
    groups = [(f"/cylinder/{joint}", CYLINDER_STATE, cylinder_signals(joint))
              for joint in JOINTS]
    groups.append(("/pile/bucket", PILE_BUCKET_STATE, PILE_BUCKET_STATE.signals))
    measured, used, out = set(signal_names), set(), []
    for topic, message, sources in groups:
        mapping = {f: s for f, s in zip(message.fields, sources, strict=True) if s}
        fields = [f for f, s in mapping.items() if s in measured]
        if not fields:
            continue
        used.update(mapping[f] for f in fields)
        out.append((topic, message, {"signals": json.dumps(mapping)},
                    tuple(double_tag(message.number(f)) for f in ("t_s", *fields)),
                    tuple(mapping[f] for f in fields)))
    components: dict[str, list[str]] = {}
    for name in signal_names:
        if name not in used:
            components.setdefault(name.split(".", 1)[0] if "." in name else "plant",
                                  []).append(name)
    for component, names in components.items():
        packed = _packed_tag(SIGNAL_SAMPLE.number("values"), len(names))
        metadata = {"names": json.dumps(names),
                    "units": json.dumps([signal_unit(name) for name in names])}
        out.append((f"/signals/{component}", SIGNAL_SAMPLE, metadata,
                    (double_tag(1), packed) + (b"",) * (len(names) - 1), tuple(names)))
    return tuple(out)


def profile_message(time_s: float, grid_m: np.ndarray | None, profile_m: np.ndarray) -> bytes:
    """Serialized excosim.PileProfile: t_s (s), y_m (cell centres, m; empty if unknown), z_m."""
    data = double_tag(1) + np.float64(time_s).astype("<f8").tobytes()
    for name, values in (("y_m", grid_m), ("z_m", profile_m)):
        if values is not None and values.size:
            data += _packed_tag(PILE_PROFILE.number(name), values.size)
            data += values.astype("<f8").tobytes()
    return data


def display_channel(period: CheckedPeriod, times_s: np.ndarray, picked: np.ndarray
                    ) -> SampleChannel:
    """/display at the samples `picked` (indices into the period): the fields of
    schemas.DISPLAY_SAMPLE whose source was measured, in deg, bar, kN and kg."""
    angles = {"reference": period.reference_rad[picked], "measured": period.joints_rad[picked]}
    angles["error"] = angles["measured"] - angles["reference"]
    columns, fields = [times_s[picked]], []
    for name, source in zip(DISPLAY_SAMPLE.fields[1:], DISPLAY_SAMPLE.signals[1:], strict=True):
        kind, _, what = source.partition(".")
        if kind in angles:
            values = angles[kind][:, JOINTS.index(what)]
        elif source in period.signals:
            values = period.signals[source][picked]
        else:
            continue
        unit = "_" + name.rsplit("_", 1)[1]
        columns.append(values * DISPLAY_SCALE[unit])
        fields.append(name)
    return SampleChannel("/display", DISPLAY_SAMPLE, {},
                         tuple(double_tag(DISPLAY_SAMPLE.number(f)) for f in ("t_s", *fields)),
                         tuple(columns))
