"""The JSON records of a run log checked once, where the reader decodes them, so that every
command that reads a log (review, compare, replay, resume, repair) meets a damaged or edited
record as the same one line naming the record and what is wrong, not as a traceback deep in a
figure.

A /period record (orchestrator.campaign.record) must be a JSON object with:

- k, a whole number >= 1, the period's place in the log;
- mass_kg, error_kg and duration_s, finite numbers (duration_s >= 0), and reset a boolean;
- deepest_point_m, two finite numbers;
- the per-joint peaks and tracking figures (PER_JOINT), three finite numbers each;
- where present (not null), the figures the commands compute with (OPTIONAL_FIGURES: planner
  wall time, productivity, estimates), a finite number each, and lowest_tip_m two.

The header (metadata excosim.run) must give the target (target_mass_kg) as a finite number.
The resolved scenario (metadata excosim.scenario) must be a JSON object. A JSON text nested
deeper than MAX_DEPTH (ours go 5 deep), or one holding numbers beyond a double (1e400 reads as
infinity), fails these checks too.
"""

from __future__ import annotations

import json
import math
from typing import Any

PER_JOINT = ("max_abs_velocity_deg_s", "max_abs_acceleration_deg_s2", "max_abs_jerk_deg_s3",
             "tracking_rms_deg")
FINITE = ("mass_kg", "error_kg", "duration_s")
OPTIONAL_FIGURES = ("planner_ms", "t0_s", "dz_m", "eps_m", "predicted_mass_kg",
                    "mass_per_area_kg_m2", "mass_per_area_sigma_kg_m2", "cycle_time_s",
                    "rated_payload_kg", "fill_factor", "productivity_t_h", "energy_kj",
                    "throttled_energy_kj", "throttled_share", "energy_per_tonne_kj_t",
                    "peak_power_kw", "mean_power_kw")
# Deeper nesting is refused where a record is read: ours go 5 deep (a spline's coefficients per
# joint), and what reads them (the JSON writer of --json, the figures) recurses per level.
MAX_DEPTH = 32


def loads(data: bytes | str, what: str) -> Any:
    """json.loads, ValueError "<what> is not JSON" or "... nested too deeply"."""
    try:
        value = json.loads(data)
    except RecursionError:
        raise ValueError(f"{what} is nested too deeply") from None
    except ValueError:
        raise ValueError(f"{what} is not JSON") from None
    if _deeper_than(value, MAX_DEPTH):
        raise ValueError(f"{what} is nested too deeply (more than {MAX_DEPTH} levels)")
    return value


def _deeper_than(value: Any, limit: int) -> bool:
    """Whether lists and objects nest in `value` more than `limit` deep (without recursion)."""
    level = [value]
    for _ in range(limit + 1):
        level = [item for v in level if isinstance(v, list | dict)
                 for item in (v.values() if isinstance(v, dict) else v)]
        if not level:
            return False
    return True


def period_problem(record: Any, k: int, complete: bool = False) -> str | None:
    """What is wrong with the /period record found as the k-th (module docstring), or None.
    complete: every key of the docstring must be there (what the review and the resume read);
    else only the keys present are checked (the reader: a log's writer may log any record)."""
    if not isinstance(record, dict):
        return f"/period record {k} is a JSON {_kind(record)}, not an object"
    number = record.get("k")
    if not (isinstance(number, int) and not isinstance(number, bool) and number >= 1):
        return f"/period record {k}: k is {number!r}, not a whole number >= 1"
    checks = [(key, _finite, "a finite number") for key in FINITE] + [
        (key, _optional_finite, "a finite number") for key in OPTIONAL_FIGURES if key in record
    ] + [("lowest_tip_m", lambda v: v is None or _numbers(v, 2), "two finite numbers")
         ] * ("lowest_tip_m" in record) + [
        ("reset", lambda v: isinstance(v, bool), "true or false"),
        ("deepest_point_m", lambda v: _numbers(v, 2), "two finite numbers")] + [
        (key, lambda v: _numbers(v, 3), "three finite numbers") for key in PER_JOINT]
    for key, good, wanted in checks:
        if key not in record and not complete:
            continue
        if key not in record:
            return f"/period record {k} has no {key}"
        if not good(record[key]):
            return f"/period record {k}: {key} is {_short(record[key])}, not {wanted}"
    if "duration_s" in record and record["duration_s"] < 0.0:
        return f"/period record {k}: duration_s is negative"
    return None


def runs_problem(periods: list[Any]) -> str | None:
    """The first problem of a run's records for the commands that compute with them (every
    key present, module docstring), or None."""
    for k, record in enumerate(periods, start=1):
        problem = period_problem(record, k, complete=True)
        if problem is not None:
            return problem
    return None


def _numbers(value: Any, n: int) -> bool:
    return isinstance(value, list) and len(value) == n and all(map(_finite, value))


def _short(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def header_problem(header: dict[str, str]) -> str | None:
    """What is wrong with the header record (excosim.run) for the commands, or None."""
    target = header.get("target_mass_kg")
    try:
        finite = math.isfinite(float(target))
    except (TypeError, ValueError):
        finite = False
    if not finite:
        return (f"the header (excosim.run): target_mass_kg is {_short(target)}, not a finite "
                "number")
    return None


def scenario_problem(record: Any) -> str | None:
    """What is wrong with the resolved scenario record, or None."""
    if not isinstance(record, dict):
        return f"the scenario record (excosim.scenario) is a JSON {_kind(record)}, not an object"
    return None


def _optional_finite(value: Any) -> bool:
    return value is None or _finite(value)


def _finite(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)


def _kind(value: Any) -> str:
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "boolean"
    if isinstance(value, int | float):
        return "number"
    return {str: "string", list: "array", dict: "object"}.get(type(value), type(value).__name__)
