"""The adaptation strategy a scenario names (adaptation.strategy): an object with `initial()`
(period 1's Decision), `learn(weighed_mass_kg, joints_rad)` (take in a period),
`decide(state, weighed_mass_kg)` (the next period's Decision), and `snapshot()` / `restore()`
(what it learnt, for a resume; None for a strategy that learns nothing).

"fuzzy", "proportional" and "fixed" are the paper's eq. 5 with a rule
(planner.adaptation.RuleAdaptation); "terrain" predicts each period's mass from the planner's
own surface estimate and a recursive estimate of the mass per swept area
(planner.terrain.TerrainAdaptation).
"""

from __future__ import annotations

import math

from orchestrator.campaign.native_slump import native_relax
from orchestrator.scenario.model import Scenario
from planner.adaptation import RuleAdaptation
from planner.period_plan import PeriodPlanner
from planner.terrain import TerrainAdaptation, TerrainSettings


def adaptation_strategy(scenario: Scenario,
                        planner: PeriodPlanner) -> RuleAdaptation | TerrainAdaptation:
    """The strategy of the scenario's adaptation section, planning through `planner`."""
    a = scenario.adaptation
    if a.strategy == "terrain":
        settings = TerrainSettings(repose_angle_rad=math.radians(a.assumed_repose_angle_deg),
                                   weighing_sigma_kg=scenario.plant.load_cell_noise_kg)
        return TerrainAdaptation(planner, scenario.adaptation_defaults(),
                                 scenario.target_mass_kg, settings, relax=native_relax())
    return RuleAdaptation(scenario.adaptation_rule(), scenario.adaptation_defaults(),
                          scenario.target_mass_kg, planner.reachable)
