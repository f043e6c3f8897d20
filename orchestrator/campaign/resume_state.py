"""A period's resume record: what a resumed run (orchestrator.campaign.resume) needs to continue
after the period, logged on /resume in the period's chunk (orchestrator.runlog.schemas:
RESUME_STATE_SCHEMA).

Besides the plant's own state (orchestrator.plants.plant_state), the campaign carries three
things from one period to the next (orchestrator.campaign.loop): the adaptation state the
period dug with and the mass weighed after it, from which the next period's D is decided (a pure
function: the resumed run decides it again, exactly), and the campaign time at which the next
period starts. The rule strategies hold nothing else across periods (the planner only a cache of
its plans); the terrain strategy (planner.terrain) also its surface estimate and its mass per
area, kept as "strategy" (its `snapshot()`, taken once it has learnt from the period).
"""

from __future__ import annotations

import dataclasses
import json
import math
from typing import Any

from planner.adaptation import AdaptationState
from plant_models.plant import resume_state as plant_resume_state

RESUME_FORMAT = 1


def resume_record(plant: Any, state: AdaptationState, weighed_mass_kg: float,
                  t0_next_s: float, strategy: dict[str, Any] | None = None
                  ) -> dict[str, Any] | None:
    """The resume record after the period `state.k` (weighed_mass_kg: its weighing, kg;
    t0_next_s: the next period's start, s; strategy: what the adaptation strategy learnt, JSON
    data, or None); None for a plant that cannot save its state (the lab excavator, an FMU
    without state serialization)."""
    try:
        saved = plant_resume_state(plant)
    except Exception:  # noqa: BLE001 - a run is not failed for what only a resume would need
        saved = None
    if saved is None:
        return None
    record = {"format": RESUME_FORMAT, "k": state.k, "t0_next_s": float(t0_next_s),
              "adaptation": dataclasses.asdict(state),
              "weighed_mass_kg": float(weighed_mass_kg), "plant": saved}
    if strategy is not None:
        record["strategy"] = strategy
    return record


def parse_resume_record(data: bytes, k: int) -> dict[str, Any]:
    """The resume record of period k from its /resume message, checked: "adaptation" as an
    AdaptationState. ValueError (one line) naming what is wrong."""
    try:
        record = json.loads(data)
    except ValueError:
        raise ValueError("it is not JSON") from None
    if not isinstance(record, dict):
        raise ValueError("it is not a JSON object")
    if record.get("format") != RESUME_FORMAT:
        raise ValueError(f"its format is {record.get('format')!r}; this version reads "
                         f"{RESUME_FORMAT}")
    if record.get("k") != k:
        raise ValueError(f"it is the state after period {record.get('k')!r}, not {k}")
    for name in ("t0_next_s", "weighed_mass_kg"):
        value = record.get(name)
        if not (isinstance(value, float) and math.isfinite(value)):
            raise ValueError(f"field {name!r} is not a finite number")
    if record["t0_next_s"] < 0.0:
        raise ValueError("field 't0_next_s' is negative")
    adaptation = record.get("adaptation")
    try:
        record["adaptation"] = AdaptationState(**adaptation)
    except (TypeError, ValueError) as error:
        raise ValueError(f"field 'adaptation' is not an adaptation state ({error})") from None
    if record["adaptation"].k != k:
        raise ValueError(f"its adaptation state is period {record['adaptation'].k}'s, not {k}'s")
    if not isinstance(record.get("plant"), dict):
        raise ValueError("field 'plant' is not an object")
    if not isinstance(record.setdefault("strategy", None), (dict, type(None))):
        raise ValueError("field 'strategy' is not an object")
    return record
