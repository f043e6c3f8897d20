"""06 - The Pile FMU on its own: drag the bucket tip through the ground and weigh what it took.

The tip plunges at y = -10 m, drags 0.2 m deep to y = -8.5 m, curls the bucket shut and lifts
out; the swept material enters the bucket (mass = density * slice_width * area), the trench
walls slump to the angle of repose, and mass is conserved to round-off: pile + bucket + dumped
= initial. Lifted out still open (tilted 70 deg from up), the bucket would spill most of it
back into the trench: set `curled = pin_above` to see it.
"""

import numpy as np
from fmpy import simulate_fmu

import fmus

fmu = fmus.build("Pile")
# Columns: time (s), tip y, tip z (m), bucket angle (rad: tip-to-pin line from +y), dump.
pin_above = np.radians(110.0)
curled = np.radians(175.0)  # the opening faces up, 5 deg from level
inputs = np.array(
    [(0.0, -10.0, 0.3, pin_above, 0.0), (0.5, -10.0, -0.2, pin_above, 0.0),
     (3.5, -8.5, -0.2, pin_above, 0.0), (3.75, -8.5, -0.2, curled, 0.0),
     (4.25, -8.5, 0.5, curled, 0.0), (5.0, -8.5, 0.5, curled, 0.0)],
    dtype=[("time", float), ("tip_y", float), ("tip_z", float), ("bucket_angle", float),
           ("dump", float)],
)
result = simulate_fmu(
    fmu, stop_time=5.0, output_interval=0.01, input=inputs,
    start_values={"tip_y": -10.0, "tip_z": 0.3},
    output=["bucket_mass", "F_y", "F_z", "pile_mass", "dumped_mass", "removed_volume",
            "spilled_mass"],
)
end = result[-1]
print(f"bucket mass {end['bucket_mass']:.3f} kg, removed volume {end['removed_volume']:.5f} m^3, "
      f"spilled {end['spilled_mass']:.3f} kg")
print(f"peak soil force |F_y| {np.abs(result['F_y']).max():.0f} N")
total = end["pile_mass"] + end["bucket_mass"] + end["dumped_mass"]
print(f"pile + bucket + dumped = {total:.9f} kg (initial {result[0]['pile_mass']:.9f} kg)")
