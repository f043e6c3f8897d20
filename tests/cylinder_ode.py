"""The HydraulicCylinder FMU's law in Python, integrated by scipy's stiff solvers: a second
implementation to check the C model and its integrators against.

Written from the law as fmus/HydraulicCylinder/model.c documents it (its header comment), not
translated from its code: states x (stroke, m), v (m/s), psi_A, psi_B (chamber pressures, Pa, or
cavitation voids when negative); inputs u, F_ext (N), mass_load (kg), p_pump, p_LS (Pa) held
over each communication step; a critical-centre 4/3 valve with square-root edges and their
laminar cubic, a load-holding check and post-compensator on the meter-in edge, a regeneration
passage from the rod to the piston side while extending, port relief and make-up, chamber
compressibility with cavitation voids, Coulomb (tanh) and viscous friction.

`reference_run` integrates each step with `scipy.integrate.solve_ivp` (Radau by default, its own
finite-difference Jacobian: nothing of the C model's analytic one) at tight tolerances. The end
stops are an integrator's act in the FMU (a clamp after each substep), so this reference stops
with a ValueError when the stroke leaves (0, stroke): compare away from the stops. Left out too:
the FMU's clamp of |F_ext| at 1000 times its largest port force, which no real load comes near.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np
from scipy.integrate import solve_ivp

INPUTS = ("u", "F_ext", "mass_load", "p_pump", "p_LS")


def _orifice(dp: float, dp_rated: float, dp_laminar: float) -> float:
    """Flow of an edge per unit rated flow: sign(dp) sqrt(|dp| / dp_rated), below dp_laminar
    the odd cubic c1 dp + c3 dp^3 of equal value and slope at |dp| = dp_laminar."""
    if abs(dp) >= dp_laminar:
        return math.copysign(math.sqrt(abs(dp) / dp_rated), dp)
    s = math.sqrt(dp_rated * dp_laminar)
    return 1.25 / s * dp - 0.25 / (s * dp_laminar ** 2) * dp ** 3


class CylinderLaw:
    """dy/dt of the cylinder for parameters `parameters` (the FMU's names, SI) and one step's
    held inputs (`hold`)."""

    def __init__(self, parameters: Mapping[str, float]) -> None:
        p = dict(parameters)
        self.p = p
        self.A_A = math.pi / 4.0 * p["bore"] ** 2
        self.A_B = math.pi / 4.0 * (p["bore"] ** 2 - p["rod"] ** 2)
        self.inputs = dict.fromkeys(INPUTS, 0.0)

    def hold(self, inputs: Mapping[str, float]) -> None:
        """The inputs (INPUTS, SI) of the next communication step."""
        self.inputs.update(inputs)

    def start(self, x0: float, F_ext: float) -> np.ndarray:
        """(4,) state at rest at stroke x0 (m) in equilibrium with the load F_ext (N): the lower
        chamber at tank pressure, the other carrying the load."""
        p_T = self.p["p_tank"]
        if F_ext >= p_T * (self.A_A - self.A_B):
            return np.array([x0, 0.0, (F_ext + p_T * self.A_B) / self.A_A, p_T])
        return np.array([x0, 0.0, p_T, (p_T * self.A_A - F_ext) / self.A_B])

    def __call__(self, _t: float, y: np.ndarray) -> np.ndarray:
        p, i = self.p, self.inputs
        x, v, psi_A, psi_B = (float(value) for value in y)
        if not 0.0 < x < p["stroke"]:
            raise ValueError(f"stroke {x} m reached an end stop: outside this reference's range")
        p_A, p_B = max(psi_A, 0.0), max(psi_B, 0.0)
        p_S, p_T, p_LS = min(i["p_pump"], p["p_supply"]), p["p_tank"], i["p_LS"]
        a = min(max(i["u"], -1.0), 1.0)
        q = p["q_rated"] * abs(a)
        q_out = p["meter_out_ratio"] * q

        def edge(dp: float) -> float:
            return _orifice(dp, p["dp_rated"], p["dp_laminar"])

        Q_A = Q_B = 0.0
        if a > 0.0:  # P -> A through check and compensator, B -> T; B -> A regeneration
            regeneration = p.get("regeneration_ratio", 0.0) * q * edge(max(p_B - p_A, 0.0))
            Q_A = q * edge(max(p_S - max(p_LS, p_A), 0.0)) + regeneration
            Q_B = -q_out * edge(p_B - p_T) - regeneration
        elif a < 0.0:  # P -> B, A -> T
            Q_B = q * edge(max(p_S - max(p_LS, p_B), 0.0))
            Q_A = -q_out * edge(p_A - p_T)
        p_makeup = p_T - p["dp_makeup"]
        for name, pressure in (("A", p_A), ("B", p_B)):
            port = -p["k_relief"] * max(pressure - p["p_relief"], 0.0) \
                + p["k_makeup"] * max(p_makeup - pressure, 0.0)
            if name == "A":
                Q_A += port
            else:
                Q_B += port
        mass = p["mass"] + i["mass_load"]
        force = p_A * self.A_A - p_B * self.A_B - i["F_ext"] \
            - p["F_coulomb"] * math.tanh(v / p["v_coulomb"]) - p["b_viscous"] * v
        V_A = p["V_dead_A"] + self.A_A * x
        V_B = p["V_dead_B"] + self.A_B * (p["stroke"] - x)
        dV_A, dV_B = self.A_A * v, -self.A_B * v
        beta = p["beta"]
        # In a void (psi < 0) the pressure is 0 and the void's volume -psi V / beta fills.
        rate_A = beta / V_A * (Q_A - dV_A) - (psi_A / V_A * dV_A if psi_A < 0.0 else 0.0)
        rate_B = beta / V_B * (Q_B - dV_B) - (psi_B / V_B * dV_B if psi_B < 0.0 else 0.0)
        return np.array([v, force / mass, rate_A, rate_B])


def reference_run(parameters: Mapping[str, float], x0: float, inputs: Mapping[str, np.ndarray],
                  step_s: float, method: str = "Radau", rtol: float = 1e-10) -> np.ndarray:
    """States after each communication step, (n, 4): x (m), v (m/s), p_A, p_B (Pa, voids shown as
    0), integrating CylinderLaw with solve_ivp(method, rtol) step by step with inputs[name][k]
    (each (n,), SI; missing ones: u, F_ext, mass_load, p_LS 0 and p_pump 1 GPa, the FMU's
    starts) held over step k. The absolute tolerances are rtol times 1 m, 1 m/s and 1 MPa."""
    law = CylinderLaw(parameters)
    n = len(next(iter(inputs.values())))
    held = {"p_pump": np.full(n, 1.0e9), **{name: np.asarray(inputs[name], dtype=float)
                                           for name in inputs}}
    for name in INPUTS:
        held.setdefault(name, np.zeros(n))
    y = law.start(x0, float(held["F_ext"][0]))
    atol = rtol * np.array([1.0, 1.0, 1.0e6, 1.0e6])
    out = np.empty((n, 4))
    for k in range(n):
        law.hold({name: float(held[name][k]) for name in INPUTS})
        solution = solve_ivp(law, (k * step_s, (k + 1) * step_s), y, method=method, rtol=rtol,
                             atol=atol)
        if not solution.success:
            raise RuntimeError(f"{method} failed in step {k}: {solution.message}")
        y = solution.y[:, -1]
        out[k] = y[0], y[1], max(y[2], 0.0), max(y[3], 0.0)
    return out
