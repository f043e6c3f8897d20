"""Units of a run log's numbers: of the measurement signals behind /signals/<component> channels
(which a channel's metadata records since "units" came in; derived from the names for older
logs) and of any field or column name that carries its unit as a suffix (`p_A_Pa`, `v_m_s`,
`measured_boom_deg`, `energy_kj`).

Units are written as in `plant_models.port_units` ("m/s", "m3", "1" for a dimensionless
quantity); a column name carries one as `_<unit>` with "/" as "_" (`supply.p_pump_Pa`,
`v_m_s`, `coupling.iterations_1`).
"""

from __future__ import annotations

import json
import re
from collections.abc import Mapping, Sequence

from plant_models.port_units import ROLE_UNITS

# Signals that no FMU role names (orchestrator.plants.simulated_excavator and
# orchestrator.plants.lab.measurement document them), by their whole name.
SIGNAL_UNITS: Mapping[str, str] = {
    "tip.y": "m", "tip.z": "m", "tip.bucket_angle": "rad", "coupling.iterations": "1",
    "supply.p_pump": "Pa", "supply.p_LS": "Pa", "supply.sharing": "1",
    "bus.frames_sent": "1", "bus.frames_received": "1", "bus.feedback_lost": "1",
    "bus.setpoints_lost": "1", "bus.bad_checksums": "1", "bus.send_jitter_s": "s",
    "bus.feedback_latency_s": "s",
}
# Variables of a component ("<component>.<variable>") beyond plant_models.port_units.ROLE_UNITS:
# the cylinders' energy outputs and the supply inputs (plant_models.model_spec).
VARIABLE_UNITS: Mapping[str, str] = {**ROLE_UNITS, "E_supply": "J", "E_throttling": "J",
                                     "p_pump": "Pa", "p_LS": "Pa"}

# Name suffix (tokens after the last "_", one or two of them) -> unit as a person reads it.
SUFFIX_UNITS: Mapping[str, str] = {
    "m_s": "m/s", "m_s2": "m/s²", "deg_s": "deg/s", "deg_s2": "deg/s²", "deg_s3": "deg/s³",
    "rad_s": "rad/s", "rad_s2": "rad/s²", "kg_m2": "kg/m²", "kj_t": "kJ/t", "t_h": "t/h",
    "m": "m", "m2": "m²", "m3": "m³", "s": "s", "ms": "ms", "Pa": "Pa", "bar": "bar",
    "N": "N", "kN": "kN", "kg": "kg", "rad": "rad", "deg": "deg", "J": "J", "kj": "kJ",
    "W": "W", "kw": "kW", "1": "1",
}
_JOINT_TAIL = re.compile(r"_(boom|stick|bucket)$")  # per-joint columns of the period table
_INDEX = re.compile(r"\[\d+\]$")


def signal_unit(name: str) -> str:
    """The unit of measurement signal `name` ("boom.E_supply" -> "J"), "" if unknown."""
    if name in SIGNAL_UNITS:
        return SIGNAL_UNITS[name]
    return VARIABLE_UNITS.get(name.rpartition(".")[2], "") if "." in name else ""


def signal_units(metadata: Mapping[str, str], names: Sequence[str]) -> list[str]:
    """The units of a /signals channel's elements `names`: its metadata "units" (JSON list,
    written since this module came in) where it has one per name, else derived from the names
    (`signal_unit`); "" where neither knows."""
    try:
        recorded = json.loads(metadata.get("units", "null"))
    except ValueError:
        recorded = None
    if isinstance(recorded, list) and len(recorded) == len(names) \
            and all(isinstance(unit, str) for unit in recorded):
        return [unit or signal_unit(name) for unit, name in zip(recorded, names, strict=True)]
    return [signal_unit(name) for name in names]


def with_unit(name: str, unit: str) -> str:
    """`name` as a column name that carries `unit` ("supply.p_pump", "Pa" -> "supply.p_pump_Pa");
    `name` itself when the unit is unknown ("") or already its suffix ("bus.send_jitter_s")."""
    suffix = "_" + unit.replace("/", "_")
    return name if not unit or name.endswith(suffix) else name + suffix


def unit_of(name: str) -> str | None:
    """The unit a field or column name carries as its suffix, as a person reads it ("p_A_Pa" ->
    "Pa", "v_m_s" -> "m/s", "z_m[3]" -> "m", "tracking_rms_deg_boom" -> "deg"); None if its
    name carries none ("fill_factor")."""
    name = _JOINT_TAIL.sub("", _INDEX.sub("", name))
    tokens = name.split("_")
    for size in (2, 1):
        if len(tokens) > size and "_".join(tokens[-size:]) in SUFFIX_UNITS:
            return SUFFIX_UNITS["_".join(tokens[-size:])]
    return None
