"""`excosim scenario show`: the resolved scenario with every default, without running it.

What a person checks before a run (and what a sweep's base looks like): every value the run
will use, the FMU file and sha256 that fills each plant role, and each cylinder servo as it is
designed for that FMU (python-control margins), so a substitution's effect on the servo is
seen before anything digs.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any

from orchestrator.cli import tables
from orchestrator.cli.conventions import status_on_terminal
from orchestrator.scenario import PLANT_ROLES, Scenario, ScenarioError, load_scenario


def flat_lines(data: Any, prefix: str = "") -> list[str]:
    """`dotted.key = value` lines of nested plain data, values as JSON (TOML-like)."""
    if isinstance(data, dict) and data:
        return [line for key, value in data.items()
                for line in flat_lines(value, f"{prefix}.{key}" if prefix else str(key))]
    return [f"{prefix} = {json.dumps(data)}"]


def plant_roles(scenario: Scenario) -> dict[str, dict[str, Any]]:
    """role -> {"fmu", "file", "sha256", "parameters", "derived", and for a cylinder of a
    simulated plant "arm_coupling", "arm_inertia", "supply"} of the resolved scenario
    ("derived": output -> how the master computes it for an FMU that lacks it; "arm_coupling":
    how the step loop couples the arm's cross inertia into it,
    orchestrator.plants.native.arm_coupling_notes; the others orchestrator.plants.role_notes)."""
    from orchestrator.campaign.loop import arm_coupling_of
    from orchestrator.plants.master import derivation_notes, fmu_path
    from orchestrator.plants.role_notes import cylinder_notes
    from plant_models.model_spec import ROLE_OF

    out = {}
    coupling = arm_coupling_of(scenario)
    notes = cylinder_notes(scenario)
    for role, spec in scenario.fmu_specs().items():
        path = fmu_path(spec, role)
        out[role] = {"fmu": spec.fmu, "file": str(path),
                     "sha256": hashlib.sha256(Path(path).read_bytes()).hexdigest(),
                     "parameters": dict(spec.parameters),
                     "derived": derivation_notes(role, ROLE_OF[role], spec)}
        if role in coupling:
            out[role]["arm_coupling"] = coupling[role]
        out[role].update(notes.get(role, {}))
    return out


_DESIGN_FIELDS = ("natural_frequency_rad_s", "damping", "position_gain_1_s", "gain_margin_db",
                  "phase_margin_deg", "bandwidth_rad_s")


def servo_designs(scenario: Scenario) -> dict[str, dict[str, Any]]:
    """cylinder role -> its servo as designed for its FMU (gains and margins; for a servo on a
    given or identified linear model, that model too), for a simulated plant; empty for
    another plant kind."""
    if scenario.plant.kind != "sim":
        return {}
    from orchestrator.campaign.loop import build_plant

    plant = build_plant(scenario)
    try:
        models = getattr(plant, "linear_models", None) or [None] * len(plant.servo_designs)
        found = getattr(plant, "identifications", None) or [None] * len(plant.servo_designs)
        out = {}
        for role, design, model, identified in zip(PLANT_ROLES, plant.servo_designs, models,
                                                  found, strict=False):
            entry: dict[str, Any] = {name: getattr(design, name) for name in _DESIGN_FIELDS
                                     if hasattr(design, name)}
            if model is not None:
                entry["linear_model"] = model.describe()
            if identified is not None:
                entry["identified"] = identified.describe()
            out[role] = entry
        return out
    finally:
        plant.close()


def _servo_line(role: str, design: dict[str, Any]) -> str:
    parts = [f"K_p {design['position_gain_1_s']:.3g} 1/s",
             f"gain margin {design['gain_margin_db']:.1f} dB",
             f"phase margin {design['phase_margin_deg']:.1f} deg"]
    if "natural_frequency_rad_s" in design:
        parts.insert(0, f"w_h {design['natural_frequency_rad_s']:.1f} rad/s, damping "
                        f"{design['damping']:.2f}")
    line = f"{role}: " + ", ".join(parts)
    if "identified" in design:
        line += f"; {design['identified']}"
    elif "linear_model" in design:
        line += f"; given model {design['linear_model']}"
    return line


def show(path: Path, overrides: list[str], as_json: bool,
         trust: bool = False) -> tuple[str, int] | None:
    """Print the resolved scenario at `path` with `overrides`; None, or (one line, status 2)
    for a scenario mistake or an FMU file that is not ours without `trust` (designing the
    servos instantiates the FMUs: orchestrator.cli.trust), 1 for a failure to build an FMU or
    design a servo."""
    import fmus
    from orchestrator.cli.trust import trust_problem

    try:
        status_on_terminal(as_json)
        scenario = load_scenario(path, overrides)
    except ScenarioError as error:
        return str(error), 2
    except fmus.BuildError as error:
        return str(error), 1
    refused = trust_problem(scenario, trust, quiet=as_json)
    if refused is not None:
        return refused
    try:
        roles = plant_roles(scenario)
        servos = servo_designs(scenario)
    except (ValueError, fmus.BuildError) as error:
        return f"{scenario.name}: {str(error).splitlines()[0]}", 1
    data = {"scenario": scenario.to_dict(), "overrides": list(scenario.overrides),
            "roles": roles, "servos": servos}
    if as_json:
        print(json.dumps(data))
        return None
    out = tables.console()
    out.print(f"# {scenario.name}: every value the run uses (file, preset defaults, --set)",
              markup=False, soft_wrap=True)
    for line in flat_lines(data["scenario"]):
        out.print(line, markup=False, soft_wrap=True)
    out.print("# the FMU of each plant role", markup=False)
    for role, table in roles.items():
        out.print(f"{role}: {table['file']} (sha256 {table['sha256'][:12]})", markup=False,
                  soft_wrap=True)
        for note in table["derived"].values():
            out.print(f"  derived by the master: {note}", markup=False, soft_wrap=True)
        for key in ("arm_coupling", "arm_inertia", "supply"):
            if key in table:
                out.print(f"  {key.replace('_', ' ')}: {table[key]}", markup=False,
                          soft_wrap=True)
    if servos:
        out.print("# the servo of each cylinder (design stroke; python-control margins)",
                  markup=False)
        for role, design in servos.items():
            out.print(_servo_line(role, design), markup=False, soft_wrap=True)
    return None
