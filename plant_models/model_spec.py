"""Which FMU plays which part of the simulated excavator, with its parameters and port map.

A port map says which FMU variable plays each role the excavator needs, so any FMI 2.0 or 3.0
co-simulation FMU with equivalent ports can replace one of ours. Roles:

- cylinder (boom, stick, bucket): inputs `u` (spool command, -1..1, +1 extends), `F_ext` (N,
  load along the rod, positive resists extension), `mass_load` (kg, optional: the arm's inertia
  reflected onto the rod, which the FMU integrates with its piston), `p_pump` and `p_LS` (Pa,
  optional: a shared load-sensing pump's pressure and the load-sensing pressure, which a
  load-sensing supply needs, plant_models.supply); outputs `x` (stroke, m),
  `v` (m/s), `p_A`, `p_B` (Pa; optional: an FMU without chambers has none), `F` (N; derivable,
  see DERIVABLE_OUTPUTS), `E_supply`, `E_throttling` (J since the FMU started, optional: the
  hydraulic energy taken from the supply and the part its metering edges and checks turned into
  heat; the productivity figures read them, orchestrator.campaign.productivity).
- pile: inputs `tip_y`, `tip_z` (m), `bucket_angle` (rad, plant_models.geometry.pile_bucket_angle),
  `dump` (>0.5 empties the bucket); outputs `bucket_mass` (kg), `F_y`, `F_z` (N),
  `removed_volume` (m^3), `dumped_mass`, `pile_mass` (kg), `surface_z_at_tip` (m).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

from plant_models.linear_cylinder import LinearCylinderModel
from plant_models.port_units import PortMap

CYLINDER_INPUTS: tuple[str, ...] = ("u", "F_ext", "mass_load", "p_pump", "p_LS")
CYLINDER_OUTPUTS: tuple[str, ...] = ("x", "v", "p_A", "p_B", "F", "E_supply", "E_throttling")
PILE_INPUTS: tuple[str, ...] = ("tip_y", "tip_z", "bucket_angle", "dump")
PILE_OUTPUTS: tuple[str, ...] = (
    "bucket_mass", "F_y", "F_z", "removed_volume", "dumped_mass", "pile_mass", "surface_z_at_tip",
)
# Ports a role's FMU may lack: an actuator without oil chambers (IdealActuator) has no chamber
# pressures (the excavator then logs none: absent, not a made-up 0), and one that takes no load
# mass has no `mass_load` (the arm's reflected inertia is then not fed to it); one on its own
# supply has no `p_pump` / `p_LS` (it can only run with the constant supply); one that books no
# energies has no `E_supply` / `E_throttling` (its energy figures are then absent).
OPTIONAL_PORTS: Mapping[str, tuple[str, ...]] = MappingProxyType({
    "cylinder": ("p_A", "p_B", "mass_load", "p_pump", "p_LS", "E_supply", "E_throttling"),
    "pile": (),
})
SUPPLY_INPUTS: tuple[str, ...] = ("p_pump", "p_LS")
# Outputs the master computes when the FMU lacks them, from other outputs and parameters of the
# role (orchestrator.plants.derived). The rule for a cylinder's force:
#   F = p_A * A_A - p_B * A_B   (N; chamber pressures p_A, p_B in Pa; piston areas in m^2: A_A
#                                the cap side's, A_B the rod side's annulus)
# It applies when the FMU has no variable for F and the port map names none, the FMU has both
# p_A and p_B, and each area is known: from the role's `piston_areas` table (m^2), else from the
# FMU's parameter or calculated parameter that the port map names for it (default: a variable
# named A_A / A_B, as our HydraulicCylinder declares them; its declared unit or the port's scale
# converts it to m^2; read from the instance after initialization). An FMU with neither F nor
# what derives it cannot fill the role.
# output -> ((term output, its parameter, sign), ...): output = sum(sign * term * parameter).
DERIVABLE_OUTPUTS: Mapping[str, Mapping[str, tuple[tuple[str, str, float], ...]]] = \
    MappingProxyType({"cylinder": MappingProxyType({"F": (("p_A", "A_A", 1.0),
                                                          ("p_B", "A_B", -1.0))}),
                      "pile": MappingProxyType({})})
# The parameters of those rules, mappable in a port map like the parameter roles (read, not set).
DERIVATION_PARAMETERS: Mapping[str, tuple[str, ...]] = MappingProxyType({
    "cylinder": ("A_A", "A_B"), "pile": (),
})
# The plant's roles and the kind of FMU each takes.
ROLE_OF: Mapping[str, str] = MappingProxyType({"boom": "cylinder", "stick": "cylinder",
                                               "bucket": "cylinder", "pile": "pile"})
ROLES: Mapping[str, tuple[str, ...]] = MappingProxyType({
    "cylinder": CYLINDER_INPUTS + CYLINDER_OUTPUTS,
    "pile": PILE_INPUTS + PILE_OUTPUTS,
})


@dataclass(frozen=True)
class FmuSpec:
    """One FMU of the plant.

    fmu: the name of one of our models ("HydraulicCylinder", "Pile"; built on demand) or a path
        to any FMI 2.0 or 3.0 co-simulation .fmu.
    parameters: FMU variable name -> start value (SI units, as the FMU declares them).
    ports: role -> FMU variable name; a role left out maps to the variable of the same name.
    port_maps: role -> PortMap with an explicit si = scale * fmu_value + offset (else the FMU's
        declared unit is converted, plant_models.port_units).
    linear_model: a cylinder role's linear model for its servo (plant_models.linear_cylinder);
        None: the simulated excavator reads our HydraulicCylinder's parameters, else identifies
        it from the FMU (orchestrator.plants.identify).
    piston_areas: a cylinder role's piston areas {"A_A", "A_B"} (m^2) for a derived force
        (DERIVABLE_OUTPUTS); an area left out is read from the FMU's parameter, if it has one.
    """

    fmu: str
    parameters: Mapping[str, float | int | bool] = field(default_factory=dict)
    ports: Mapping[str, str] = field(default_factory=dict)
    linear_model: LinearCylinderModel | None = None
    port_maps: Mapping[str, PortMap] = field(default_factory=dict)
    piston_areas: Mapping[str, float] = field(default_factory=dict)

    @classmethod
    def from_table(cls, fmu: str, parameters: Mapping, ports: Mapping,
                   linear_model: LinearCylinderModel | None = None,
                   piston_areas: Mapping[str, float] | None = None) -> FmuSpec:
        """From a scenario's FMU table, whose port entries are a variable name or a table
        {variable, scale, offset}."""
        names, maps = {}, {}
        for role, entry in ports.items():
            if isinstance(entry, Mapping):
                maps[role] = PortMap(str(entry["variable"]), float(entry.get("scale", 1.0)),
                                     float(entry.get("offset", 0.0)))
                names[role] = maps[role].variable
            else:
                names[role] = entry
        return cls(fmu, dict(parameters), names, linear_model, maps,
                   {k: float(v) for k, v in (piston_areas or {}).items()})

    def variable(self, role: str) -> str:
        """The FMU variable that plays `role`."""
        return self.ports.get(role, role)
