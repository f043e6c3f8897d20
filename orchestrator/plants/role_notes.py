"""What each cylinder role's FMU takes of the plant, said in words where a person looks
(`scenario show`, the run log's excosim.roles, `review`): whether the arm's inertia reaches it,
and which oil supply it is on. A substitute FMU that lacks an optional input is run without
it, so these say what that costs rather than leaving it silent.

- arm inertia: an FMU with the input `mass_load` integrates the inertia the arm reflects onto
  its rod (M_ii / r_i^2, from the design pose's range over the stroke, in kg). Without it, that
  inertia reaches the FMU only as far as its own model carries one (an actuator that ignores
  its load needs none), and its servo is designed (or identified) on the FMU alone.
- supply: with a load-sensing supply, an FMU with the inputs `p_pump` and `p_LS` is on the
  shared pump; one without them runs on whatever supply it models, off the pump, whose signals
  in the log are then the other roles' pump.
"""

from __future__ import annotations

from typing import Any

CYLINDERS = ("boom", "stick", "bucket")
STROKE_RANGE = (0.05, 0.95)  # of each stroke, the others at their design strokes


def cylinder_notes(scenario: Any) -> dict[str, dict[str, str]]:
    """cylinder role -> {"arm_inertia": ..., "supply": ...} (module docstring) for a simulated
    plant; {} for another plant kind."""
    if scenario.plant.kind != "sim":
        return {}
    from fmus.descriptions import model_description
    from orchestrator.plants.master import check_component, fmu_path

    specs = scenario.fmu_specs()
    pump = scenario.plant.supply.pump()
    reflected = reflected_range_kg(scenario)
    out = {}
    for role in CYLINDERS:
        spec = specs[role]
        ports = check_component(role, "cylinder", spec, model_description(fmu_path(spec, role)))
        low, high = reflected[role]
        arm = f"the arm's {low:,.0f}-{high:,.0f} kg reflected onto the rod"
        inertia = f"fed as mass_load ({arm})" if "mass_load" in ports else (
            f"not fed: the FMU has no mass_load input, so {arm} reaches it only as far as its "
            "own model carries one, and its servo is designed on the FMU alone")
        if pump is None:
            supply = "its own (the scenario's supply is constant: each valve on its own)"
        elif "p_pump" in ports and "p_LS" in ports:
            supply = "the shared load-sensing pump"
        else:
            supply = ("its own supply: the FMU has no p_pump/p_LS inputs, so it is off the "
                      "shared pump (the log's /signals/supply is the other roles' pump)")
        out[role] = {"arm_inertia": inertia, "supply": supply}
    return out


def reflected_range_kg(scenario: Any) -> dict[str, tuple[float, float]]:
    """cylinder role -> (least, most) inertia the empty arm reflects onto its rod (kg), its own
    stroke over STROKE_RANGE and the others at their design strokes (mid-stroke)."""
    from orchestrator.plants.simulated_excavator import shared_coupling
    from plant_models.hydraulics import reflected_mass_kg

    geometry = scenario.geometry()
    coupling = shared_coupling(geometry)
    design = [0.5 * table.stroke_m for table in coupling.tables]
    out = {}
    for index, role in enumerate(CYLINDERS):
        masses = []
        for fraction in STROKE_RANGE:
            strokes = list(design)
            strokes[index] = fraction * coupling.tables[index].stroke_m
            joints = [coupling.joint_state(i, s)[0] for i, s in enumerate(strokes)]
            masses.append(reflected_mass_kg(geometry, role, joints))
        out[role] = (min(masses), max(masses))
    return out
