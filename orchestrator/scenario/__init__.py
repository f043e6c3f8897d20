"""Scenarios: TOML -> typed, validated objects; `--set KEY=VALUE` overrides; FMU resolution.

    from orchestrator.scenario import load_scenario
    scenario = load_scenario("scenarios/paper-2020.toml", ["periods=5"])
"""

from orchestrator.scenario.errors import ScenarioError
from orchestrator.scenario.model import PLANT_ROLES, Scenario, load_scenario, scenario_from_dict

__all__ = ["PLANT_ROLES", "Scenario", "ScenarioError", "load_scenario", "scenario_from_dict"]
