"""A run's productivity figures, totalled from its /period records (the per-period figures and
their formulas: orchestrator.campaign.productivity), and the pump's power limit they are
judged against. From the file alone: the records and the logged scenario.

Over the periods k of the run, with T_k the cycle time, m_k the payload, E_k the hydraulic
energy and H_k its throttled part:

    total_payload_kg       sum m_k
    digging_time_s         sum T_k
    productivity_t_h       (sum m_k / 1000) / (sum T_k / 3600)
    mean_fill_factor       mean of the periods' fill factors (sum m_k / (n m_r))
    energy_kj              sum E_k;  throttled_energy_kj: sum H_k
    energy_per_tonne_kj_t  sum E_k / (sum m_k / 1000) (None below MIN_PAYLOAD_KG in all)
    throttled_share        sum H_k / sum E_k
    peak_power_kw          max over the periods of their peak supply power
    mean_power_kw          sum E_k / sum T_k

A figure is None when a period lacks what it needs (a log written before the figures, a plant
that measures no energies): a total over some of the periods would read as the run's.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

# As orchestrator.campaign.productivity.MIN_PAYLOAD_KG (not imported: reading a log must not
# load the planner and the plant): below 1 g dug, kJ per tonne is a division by noise.
MIN_PAYLOAD_KG = 1e-3
RUN_KEYS = ("total_payload_kg", "digging_time_s", "productivity_t_h", "mean_fill_factor",
            "energy_kj", "throttled_energy_kj", "energy_per_tonne_kj_t", "throttled_share",
            "peak_power_kw", "mean_power_kw")


def run_productivity(records: list[dict[str, Any]]) -> dict[str, float | None]:
    """The run's figures of the module docstring, by key (RUN_KEYS), None where not known."""
    out: dict[str, float | None] = dict.fromkeys(RUN_KEYS)
    times = _every(records, "cycle_time_s")
    if not records or times is None:
        return out
    payload_kg = math.fsum(r["mass_kg"] for r in records)
    time_s = math.fsum(times)
    out.update(total_payload_kg=payload_kg, digging_time_s=time_s)
    if time_s > 0.0:
        out["productivity_t_h"] = (payload_kg / 1000.0) / (time_s / 3600.0)
    fills = _every(records, "fill_factor")
    if fills is not None:
        out["mean_fill_factor"] = math.fsum(fills) / len(fills)
    energies = _every(records, "energy_kj")
    if energies is None:
        return out
    energy_kj = math.fsum(energies)
    out["energy_kj"] = energy_kj
    if payload_kg >= MIN_PAYLOAD_KG:
        out["energy_per_tonne_kj_t"] = energy_kj / (payload_kg / 1000.0)
    throttled = _every(records, "throttled_energy_kj")
    if throttled is not None:
        out["throttled_energy_kj"] = math.fsum(throttled)
        if energy_kj > 0.0:
            out["throttled_share"] = out["throttled_energy_kj"] / energy_kj
    peaks = _every(records, "peak_power_kw")
    if peaks is not None:
        out["peak_power_kw"] = max(peaks)
    if time_s > 0.0:
        out["mean_power_kw"] = energy_kj / time_s
    return out


def power_limit_kw(scenario: Mapping[str, Any]) -> float | None:
    """The pump's hydraulic power limit (kW): [plant.supply] engine_power_w (W) x
    pump_efficiency, None when the scenario sets no engine power (a scenario from before the
    power limiter, or without one)."""
    supply = scenario.get("plant", {}).get("supply", {})
    supply = supply if isinstance(supply, Mapping) else {}
    engine_w, efficiency = supply.get("engine_power_w"), supply.get("pump_efficiency")
    if not isinstance(engine_w, int | float) or not isinstance(efficiency, int | float):
        return None
    return float(engine_w) * float(efficiency) / 1000.0


def _every(records: list[dict[str, Any]], key: str) -> list[float] | None:
    """The key's value of every record, None when a record lacks it."""
    values = [r.get(key) for r in records]
    return None if any(v is None for v in values) else [float(v) for v in values]
