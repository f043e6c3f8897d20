"""Values that each validate on their own but describe no machine that digs: refused when the
scenario loads, naming the quantity, before anything runs (after the FMUs' own checks and the
first period's reach, orchestrator.scenario.model.scenario_from_dict, with the resolved FMU
parameter values of orchestrator.scenario.sanity.resolved_values). Each bound says why:

- the first deepest point y_D0_m inside the pile's grid [y_min, y_max] (outside it every period
  digs nothing, which would be reported as a run);
- the pile's cells at most a quarter of the bucket's length (the bucket's cut must span several
  cells to be resolved; the paper's are 0.05 m under a 1.5 m bucket);
- the target at least 1 % of what the bucket holds (density x capacity): below that the load
  cell's resolution and the spill, not the adaptation, decide;
- the first depth step dz_0_m within half the bucket's length either way, and the shift dy_0_m
  within the pile's grid width plus the arm's reach (a larger shift is a number, not a place:
  a shift off the pile still ends a campaign at its workspace limit, as a test does);
- a cylinder's dead volumes at most ten times its swept volume (more is hundreds of metres of
  hose: no excavator's valve sits that far from its cylinder);
- the pile's gravity 1-25 m/s^2 (the Moon's 1.6 to two and a half g), its heap no higher than
  the arm reaches (boom + stick + bucket), its cohesion and adhesion at most 1 MPa (stronger is
  rock, which the McKyes wedge does not model);
- the log's sample rate at most one sample per communication step.
"""

from __future__ import annotations

import math
from typing import Any

from orchestrator.scenario.errors import ScenarioError

MIN_TARGET_FRACTION = 0.01  # of what the bucket holds
MAX_CELL_FRACTION = 0.25  # of the bucket's length
MAX_DEAD_VOLUME_RATIO = 10.0  # dead volume per swept volume
GRAVITY_M_S2 = (1.0, 25.0)
MAX_SOIL_STRENGTH_PA = 1.0e6


def check_physics(scenario: Any, source: str, pile: dict[str, Any],
                  cylinders: dict[str, dict[str, Any]]) -> None:
    """The module docstring's bounds; ScenarioError on the first one passed. pile, cylinders:
    the resolved parameter values of the pile and of each cylinder role (FMU defaults under
    the scenario's; a bound whose values are missing, as for another tool's FMU, is skipped)."""
    geometry = scenario.geometry()
    adaptation = scenario.adaptation
    y_min, y_max = pile.get("y_min"), pile.get("y_max")
    if _numbers(y_min, y_max):
        if not y_min <= adaptation.y_D0_m <= y_max:
            raise ScenarioError(source, "adaptation.y_D0_m",
                                f"{adaptation.y_D0_m:g} m lies outside the pile's grid "
                                f"[{y_min:g}, {y_max:g}] m (plant.pile.parameters y_min, "
                                "y_max): every period would dig nothing")
        cells = pile.get("n_cells")
        if _numbers(cells) and cells >= 1:
            width = (y_max - y_min) / cells
            if width > MAX_CELL_FRACTION * geometry.bucket_length_m:
                raise ScenarioError(source, "plant.pile.parameters",
                                    f"the pile's cells are {width:.4g} m wide ((y_max - y_min) / "
                                    f"n_cells), coarser than a quarter of the "
                                    f"{geometry.bucket_length_m:g} m bucket: its cut would not "
                                    "be resolved")
        reach = geometry.boom_length_m + geometry.stick_length_m + geometry.bucket_length_m
        if abs(adaptation.dy_0_m) > y_max - y_min + reach:
            raise ScenarioError(source, "adaptation.dy_0_m",
                                f"{adaptation.dy_0_m:g} m is more than the pile's grid is wide "
                                f"({y_max - y_min:g} m) and the arm reaches "
                                f"({reach:.3g} m) together")
    if abs(adaptation.dz_0_m) > 0.5 * geometry.bucket_length_m:
        raise ScenarioError(source, "adaptation.dz_0_m",
                            f"{adaptation.dz_0_m:g} m is more than half the bucket's length "
                            f"({geometry.bucket_length_m:g} m) in one period")
    density, capacity = pile.get("density"), pile.get("capacity")
    if _numbers(density, capacity) and \
            scenario.target_mass_kg < MIN_TARGET_FRACTION * density * capacity:
        raise ScenarioError(source, "target_mass_kg",
                            f"{scenario.target_mass_kg:g} kg is less than 1 % of what the "
                            f"bucket holds ({density * capacity:.4g} kg): the load cell and "
                            "the spill would decide, not the adaptation")
    for role, values in cylinders.items():
        _dead_volumes(role, values, source)
    gravity = pile.get("gravity")
    if _numbers(gravity) and not GRAVITY_M_S2[0] <= gravity <= GRAVITY_M_S2[1]:
        raise ScenarioError(source, "plant.pile.parameters.gravity",
                            f"{gravity:g} m/s^2 is outside {GRAVITY_M_S2[0]:g}-"
                            f"{GRAVITY_M_S2[1]:g} m/s^2 (the Moon's to two and a half g)")
    reach = geometry.boom_length_m + geometry.stick_length_m + geometry.bucket_length_m
    heap = pile.get("heap_height")
    if _numbers(heap) and heap > reach:
        raise ScenarioError(source, "plant.pile.parameters.heap_height",
                            f"{heap:g} m is higher than the arm reaches ({reach:.3g} m)")
    for name in ("cohesion", "adhesion"):
        value = pile.get(name)
        if _numbers(value) and value > MAX_SOIL_STRENGTH_PA:
            raise ScenarioError(source, f"plant.pile.parameters.{name}",
                                f"{value:g} Pa is stronger than 1 MPa: that is rock, which the "
                                "McKyes wedge does not model")
    rate = scenario.log.sample_rate_hz
    if rate is not None and rate * scenario.plant.communication_step_s > 1.0 + 1e-9:
        raise ScenarioError(source, "log.sample_rate_hz",
                            f"{rate:g} Hz is more than one sample per communication step of "
                            f"{scenario.plant.communication_step_s:g} s")


def _dead_volumes(role: str, values: dict[str, Any], source: str) -> None:
    bore, rod, stroke = values.get("bore"), values.get("rod"), values.get("stroke")
    if not _numbers(bore, rod, stroke):
        return
    swept = {"V_dead_A": math.pi / 4 * bore**2 * stroke,
             "V_dead_B": math.pi / 4 * (bore**2 - rod**2) * stroke}
    for name, volume in swept.items():
        dead = values.get(name)
        if _numbers(dead) and volume > 0.0 and dead > MAX_DEAD_VOLUME_RATIO * volume:
            raise ScenarioError(source, f"plant.{role}.parameters.{name}",
                                f"{dead:g} m^3 is more than ten times the cylinder's swept "
                                f"volume on that side ({volume:.3g} m^3): hundreds of metres of "
                                "hose")


def _numbers(*values) -> bool:
    return all(isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)
               for v in values)
