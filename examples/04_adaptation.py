"""04 - Period-to-period adaptation of the deepest point D (paper eq. 5 and Fig. 5).

A scripted sequence of weighed masses drives D: too light digs deeper, too heavy shallower; when
the next path leaves the workspace, D resets to its default depth and shifts toward the machine,
and when that fails too the campaign ends with "workspace limit" (a value, not an exception).
"""

from planner.adaptation import AdaptationDefaults, initial_state, next_deepest_point
from planner.digging_path import PathShape, is_reachable
from planner.fuzzy import FuzzyRule
from plant_models import presets

target_mass_kg = 30.0
rule = FuzzyRule.paper(target_mass_kg)
defaults = AdaptationDefaults()  # D0 = (-9, -0.1) m, dz_0 = -0.075 m, dy_0 = 3.5 m
reachable = is_reachable(presets.get("paper"), PathShape.preset("paper"))

decision = initial_state(defaults, reachable)
masses_kg = [8.5, 20.0, 27.0, 29.5, 8.6, 21.0, 28.5, 33.5, 29.8, 30.1]
for mass_kg in masses_kg:
    state = decision.next_state
    print(f"period {state.k:2d}: D = ({state.y_D:6.2f}, {state.z_D:6.3f}) m, "
          f"dz = {state.dz:+.3f} m, weighed {mass_kg:5.1f} kg")
    decision = next_deepest_point(state, mass_kg, target_mass_kg, rule, defaults, reachable)
    if decision.reset:
        print("           workspace limit: reset z_D and dz, shift y_D")
    if decision.terminated:
        print(f"           campaign ends: {decision.reason}")
        break
