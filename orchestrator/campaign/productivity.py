"""Productivity figures of one digging period, from what the plant measured: what earthmoving
papers and machine makers report, in the /period record (orchestrator.campaign.record).

With t the period's sample times (s, shape (m,)), m_k its weighed payload (kg), E_s,j and
E_t,j the cumulative `<joint>.E_supply` and `<joint>.E_throttling` signals of the cylinders
j = boom, stick, bucket (J since the FMU started, (m,) each) and dE = E[-1] - E[0]:

    cycle_time_s           T = t[-1] - t[0]: the samples' time span, the settle that holds a
                           lagging arm at the last pose included (the one step after the
                           last sample, between two periods' samples, counts in neither
                           period: the campaign's clock advances by T too)
    rated_payload_kg       m_r (`rated_payload_kg`): the bucket's rated heaped load
    fill_factor            m_k / m_r (absent when the plant states no rating)
    productivity_t_h       (m_k / 1000) / (T / 3600), t per hour of digging
    energy_kj              E = sum_j dE_s,j / 1000, the hydraulic energy the supply gave
    throttled_energy_kj    sum_j dE_t,j / 1000, what metering edges and checks made heat of it
    throttled_share        throttled_energy_kj / energy_kj (absent when E <= 0)
    energy_per_tonne_kj_t  E / (m_k / 1000) (absent when m_k < MIN_PAYLOAD_KG)
    peak_power_kw          max_i P_i / 1000, P_i = sum_j (E_s,j[i+1] - E_s,j[i]) / h_i, the
                           supply's power over each step h_i = t[i+1] - t[i]
    mean_power_kw          E / T

The energy figures are absent (not 0, not null) when a cylinder books no energies: an FMU
without the outputs (the IdealActuator: no oil) leaves its signals out of the measurement, and
a lab machine measures none.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from plant_models.plant import JOINTS

# Below 1 g a weighing is zero within any load cell's resolution (and a noisy empty bucket may
# read below 0): kJ per such a "tonne" would be a division by noise, so it is left out.
MIN_PAYLOAD_KG = 1e-3
KJ_PER_J = 1e-3
S_PER_H = 3600.0
KG_PER_T = 1000.0
PERIOD_KEYS = ("cycle_time_s", "rated_payload_kg", "fill_factor", "productivity_t_h",
               "energy_kj", "throttled_energy_kj", "throttled_share", "energy_per_tonne_kj_t",
               "peak_power_kw", "mean_power_kw")


def rated_payload_kg(scenario) -> float | None:
    """The rated payload m_r (kg) of the scenario's plant, None when it states none.

    kind "lab": the lab excavator's published 10 kg maximum load (plant_models.presets);
    kind "sim": the Pile FMU's heaped bucket capacity (m^3) x material density (kg/m^3), each
    from the scenario's [plant.pile.parameters], else the FMU's declared start value (read
    from its model description, as the simulated excavator reads it); None for a pile FMU
    without both parameters."""
    from plant_models import presets

    if scenario.plant.kind == "lab":
        return presets.LAB_MAX_LOAD_KG
    from orchestrator.plants.servo_setup import fmu_description, start_values

    spec = scenario.plant.pile.spec()
    try:
        values = {**start_values(fmu_description("pile", spec)), **spec.parameters}
    except (OSError, ValueError):  # no description: no rating (the plant reports the FMU)
        return None
    if "capacity" not in values or "density" not in values:
        return None
    return float(values["capacity"]) * float(values["density"])


def period_productivity(t_s: np.ndarray, signals: Mapping[str, np.ndarray], payload_kg: float,
                        rated_payload_kg: float | None = None) -> dict[str, float]:
    """The figures of the module docstring that the period's data allow, by key.

    t_s: (m,) s sample times; signals: name -> (m,) as PeriodMeasurement.signals;
    payload_kg: the weighed mass; rated_payload_kg: m_r (kg) or None."""
    t = np.asarray(t_s, dtype=float)
    cycle_s = float(t[-1] - t[0])
    payload_kg = float(payload_kg)
    out: dict[str, float] = {"cycle_time_s": cycle_s}
    if rated_payload_kg is not None and rated_payload_kg > 0.0:
        out["rated_payload_kg"] = float(rated_payload_kg)
        out["fill_factor"] = payload_kg / float(rated_payload_kg)
    if cycle_s > 0.0:
        out["productivity_t_h"] = (payload_kg / KG_PER_T) / (cycle_s / S_PER_H)
    supplied = _joint_energies(signals, "E_supply")
    if supplied is None:
        return out
    energy_j = float(np.sum(supplied[-1] - supplied[0]))
    out["energy_kj"] = energy_j * KJ_PER_J
    throttled = _joint_energies(signals, "E_throttling")
    if throttled is not None:
        throttled_j = float(np.sum(throttled[-1] - throttled[0]))
        out["throttled_energy_kj"] = throttled_j * KJ_PER_J
        if energy_j > 0.0:
            out["throttled_share"] = throttled_j / energy_j
    if payload_kg >= MIN_PAYLOAD_KG:
        out["energy_per_tonne_kj_t"] = out["energy_kj"] / (payload_kg / KG_PER_T)
    power_w = supply_power_w(t, supplied)
    if len(power_w):
        out["peak_power_kw"] = float(power_w.max()) * KJ_PER_J
    if cycle_s > 0.0:
        out["mean_power_kw"] = out["energy_kj"] / cycle_s
    return out


def supply_power_w(t_s: np.ndarray, supplied_j: np.ndarray) -> np.ndarray:
    """(m - 1,) W: the supply's mean power over each step, sum_j dE_s,j / h.

    t_s: (m,) s; supplied_j: (m, 3) J, the cumulative E_supply of boom, stick, bucket.
    Steps of zero length (none on a plant's grid) are left out rather than divided by."""
    h = np.diff(np.asarray(t_s, dtype=float))
    step_j = np.diff(np.asarray(supplied_j, dtype=float), axis=0).sum(axis=1)
    kept = h > 0.0
    return step_j[kept] / h[kept]


def _joint_energies(signals: Mapping[str, Any], name: str) -> np.ndarray | None:
    """(m, 3) J: `<joint>.<name>` of boom, stick, bucket; None when a cylinder has no such
    signal or it is not finite (a value the FMU did not book)."""
    columns = [signals.get(f"{joint}.{name}") for joint in JOINTS]
    if any(column is None or len(column) < 2 for column in columns):
        return None
    stacked = np.column_stack([np.asarray(c, dtype=float) for c in columns])
    return stacked if np.all(np.isfinite(stacked)) else None
