"""Compare the period records of a logged run with those of its replay (orchestrator.review.replay).

Each period is compared on what the campaign decides and measures: the weighed mass (kg), the
deepest point D = (y, z) (m) the period dug through and its trajectory's duration (s).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Any

__all__ = ["TOLERANCE", "PeriodComparison", "compare_periods"]

# Absolute, in kg, m and s alike: a deterministic replay repeats the numbers bit for bit, so
# this only separates "the same" from "different"; 1e-9 kg is far below any load cell.
TOLERANCE = 1e-9


@dataclass(frozen=True)
class PeriodComparison:
    """Period k of the log and of the replay; a side's values are None when it has no period
    k. Differences are absolute (inf for a non-finite value); the deepest point's is the
    larger of |dy| and |dz| (m)."""

    k: int
    mass_kg_logged: float | None
    mass_kg_replayed: float | None
    deepest_point_m_logged: tuple[float, float] | None
    deepest_point_m_replayed: tuple[float, float] | None
    duration_s_logged: float | None
    duration_s_replayed: float | None
    abs_diff_mass_kg: float | None = field(init=False)
    abs_diff_deepest_point_m: float | None = field(init=False)
    abs_diff_duration_s: float | None = field(init=False)
    tolerance: float = TOLERANCE

    def __post_init__(self) -> None:
        both = self.mass_kg_logged is not None and self.mass_kg_replayed is not None
        d_mass = _difference(self.mass_kg_logged, self.mass_kg_replayed) if both else None
        d_point = max(_difference(a, b) for a, b in zip(self.deepest_point_m_logged,
                                                         self.deepest_point_m_replayed,
                                                         strict=True)) if both else None
        d_time = _difference(self.duration_s_logged, self.duration_s_replayed) if both else None
        object.__setattr__(self, "abs_diff_mass_kg", d_mass)
        object.__setattr__(self, "abs_diff_deepest_point_m", d_point)
        object.__setattr__(self, "abs_diff_duration_s", d_time)

    @property
    def matches(self) -> bool:
        """Both sides have period k and every difference is within the tolerance."""
        return self.abs_diff_mass_kg is not None and max(
            self.abs_diff_mass_kg, self.abs_diff_deepest_point_m, self.abs_diff_duration_s,
        ) <= self.tolerance

    def difference(self) -> str:
        """One line: what differs in this period ("" if nothing does)."""
        if self.mass_kg_logged is None:
            return "replayed, not logged"
        if self.mass_kg_replayed is None:
            return "logged, not replayed"
        parts = []
        if self.abs_diff_mass_kg > self.tolerance:
            parts.append(f"mass {self.mass_kg_logged!r} kg logged, {self.mass_kg_replayed!r} "
                         "kg replayed")
        if self.abs_diff_deepest_point_m > self.tolerance:
            parts.append(f"D {list(self.deepest_point_m_logged)} m logged, "
                         f"{list(self.deepest_point_m_replayed)} m replayed")
        if self.abs_diff_duration_s > self.tolerance:
            parts.append(f"duration {self.duration_s_logged!r} s logged, "
                         f"{self.duration_s_replayed!r} s replayed")
        return "; ".join(parts)

    def as_dict(self) -> dict[str, Any]:
        """Plain JSON-able data (an infinite difference as None) with `matches`."""
        out = asdict(self)
        for key in ("deepest_point_m_logged", "deepest_point_m_replayed"):
            out[key] = list(out[key]) if out[key] is not None else None
        for key in ("abs_diff_mass_kg", "abs_diff_deepest_point_m", "abs_diff_duration_s"):
            out[key] = _finite(out[key])
        del out["tolerance"]
        out["matches"] = self.matches
        return out


def _difference(a: float, b: float) -> float:
    if a == b:
        return 0.0
    d = abs(a - b)
    return d if math.isfinite(d) else math.inf


def _number(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ValueError(f"{where} must be a number, got {value!r}")
    return float(value)


def _by_period(records: list[dict], side: str) -> dict[int, tuple]:
    """k -> (mass kg, (y, z) m, duration s) of each record; ValueError naming a bad one."""
    out: dict[int, tuple] = {}
    for index, record in enumerate(records, start=1):
        where = f"{side} period record {index}"
        k = record.get("k") if isinstance(record, dict) else None
        if isinstance(k, bool) or not isinstance(k, int):
            raise ValueError(f"{where}: k must be an integer, got {k!r}")
        if k in out:
            raise ValueError(f"{where}: period k = {k} appears twice")
        point = record.get("deepest_point_m")
        if not (isinstance(point, list | tuple) and len(point) == 2):
            raise ValueError(f"{where}: deepest_point_m must be [y, z], got {point!r}")
        y, z = (_number(v, f"{where}: deepest_point_m") for v in point)
        out[k] = (_number(record.get("mass_kg"), f"{where}: mass_kg"), (y, z),
                  _number(record.get("duration_s"), f"{where}: duration_s"))
    return out


def compare_periods(logged: list[dict], replayed: list[dict],
                    tolerance: float = TOLERANCE) -> list[PeriodComparison]:
    """Compare period records (dicts with k, mass_kg, deepest_point_m [y, z], duration_s)
    by k: one PeriodComparison per k in either list, in order of k. tolerance: the largest
    absolute difference taken as equal, in kg, m and s (>= 0)."""
    if not (isinstance(tolerance, int | float) and math.isfinite(tolerance) and tolerance >= 0):
        raise ValueError(f"tolerance must be a finite number >= 0, got {tolerance!r}")
    left, right = _by_period(logged, "logged"), _by_period(replayed, "replayed")
    out = []
    for k in sorted(left.keys() | right.keys()):
        a, b = left.get(k, (None,) * 3), right.get(k, (None,) * 3)
        out.append(PeriodComparison(k, a[0], b[0], a[1], b[1], a[2], b[2], tolerance))
    return out


def _finite(value: float | None) -> float | None:
    return value if value is not None and math.isfinite(value) else None
