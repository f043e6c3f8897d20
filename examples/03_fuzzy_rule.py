"""03 - The Sugeno fuzzy rule: weight error (kg) -> change of the depth step (m).

Seven triangular membership functions over dm = m* - m, crisp outputs r = -0.4 .. 0.4 m,
weighted-average defuzzification (paper section 2.3, eq. 6).
"""

from planner.fuzzy import TERMS, FuzzyRule

rule = FuzzyRule.paper(target_mass_kg=30.0)
print("membership centres (kg):", dict(zip(TERMS, rule.centres_kg, strict=True)))
print("rule outputs (m):       ", dict(zip(TERMS, rule.outputs_m, strict=True)))
for dm_kg in (-25.0, -9.0, -4.5, 0.0, 1.5, 6.0, 21.5):
    print(f"dm = {dm_kg:6.1f} kg -> eps = {rule(dm_kg):+.4f} m")
