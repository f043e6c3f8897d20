"""05 - The HydraulicCylinder FMU on its own, simulated with fmpy in one call.

Full spool command extends the cylinder against a constant load; the valve then closes and the
trapped oil holds the load: the piston-side pressure settles where p_A * A_A - p_B * A_B equals
the load.
"""

import numpy as np
from fmpy import simulate_fmu

import fmus

fmu = fmus.build("HydraulicCylinder")  # compiled once, cached by content hash
load_N = 50e3
inputs = np.array(
    [(0.0, 1.0, load_N), (0.8, 1.0, load_N), (0.8, 0.0, load_N), (2.0, 0.0, load_N)],
    dtype=[("time", float), ("u", float), ("F_ext", float)],
)
result = simulate_fmu(
    fmu, start_time=0.0, stop_time=2.0, output_interval=0.01, input=inputs,
    start_values={"x0": 0.2, "F_ext": load_N}, output=["x", "v", "p_A", "p_B", "F"],
)
for t in (0.0, 0.4, 0.8, 1.2, 2.0):
    row = result[np.searchsorted(result["time"], t - 1e-9)]
    print(f"t = {row['time']:4.2f} s: x = {row['x']:.4f} m, v = {row['v']:+.4f} m/s, "
          f"p_A = {row['p_A'] / 1e6:6.2f} MPa, p_B = {row['p_B'] / 1e6:6.2f} MPa, "
          f"F = {row['F'] / 1e3:7.2f} kN")
