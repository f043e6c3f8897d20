"""The valve-controlled cylinder as the servo sees it: data, linear model and steady valve law.

Linearised model (states stroke x, piston velocity v, hydraulic force F = p_A A_A - p_B A_B;
input the commanded piston velocity w, m/s)::

    dx/dt = v
    m dv/dt = F - b v - F_load
    dF/dt = k_h (w - v),   k_h = beta (A_A^2 / V_A + A_B^2 / V_B)     (hydraulic stiffness)
    V_A = V_dead_A + A_A x,  V_B = V_dead_B + A_B (stroke - x)

so x/w = w_h^2 / (s (s^2 + 2 zeta_h w_h s + w_h^2)), w_h = sqrt(k_h / m), 2 zeta_h w_h = b / m
(Merritt, Hydraulic Control Systems, 1967, ch. 5; Jelali & Kroll, Hydraulic Servo-systems,
2003, ch. 4). In the brief's form x/u = K_v / (s (s^2/w_h^2 + 2 zeta_h s/w_h + 1)) the input
here is w = K_v u: the valve law `CylinderModel.opening` turns w into the spool command u with
the measured force, so K_v = 1 at every load (load-pressure compensation). The valve's
flow-pressure coefficient is left out (zero for a closed critical-centre valve), so only the
viscous friction damps the model: zeta_h is about 0.001 for the excavator's cylinders.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, fields
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import control

MIN_FORCE_RESERVE = 0.05  # valve law: at least 5 % of the stall force is left to drive flow

# Parameter names of our HydraulicCylinder FMU (fmus/HydraulicCylinder/variables.toml).
FMU_PARAMETER_NAMES: Mapping[str, str] = {
    "bore_m": "bore", "rod_m": "rod", "stroke_m": "stroke", "dead_volume_a_m3": "V_dead_A",
    "dead_volume_b_m3": "V_dead_B", "bulk_modulus_pa": "beta",
    "supply_pressure_pa": "p_supply", "tank_pressure_pa": "p_tank",
    "rated_flow_m3_s": "q_rated", "rated_pressure_drop_pa": "dp_rated", "mass_kg": "mass",
    "viscous_friction_n_s_m": "b_viscous",
}
# Parameters a cylinder may leave out: the value a valve has without them (symmetric edges).
OPTIONAL_FMU_PARAMETERS: Mapping[str, tuple[str, float]] = {
    "meter_out_ratio": ("meter_out_ratio", 1.0),
}


@dataclass(frozen=True)
class CylinderModel:
    """What the servo design and the valve law need to know about one cylinder (SI units).

    bore_m, rod_m, stroke_m (m); dead volumes (m^3); bulk modulus and pressures (Pa, gauge);
    rated_flow_m3_s through one metering edge at rated_pressure_drop_pa (Pa); mass_kg the moving
    mass the FMU simulates (link inertia reflected onto the rod included); viscous friction
    (N s/m). meter_out_ratio: the meter-out edges' size over the meter-in edge's (1:
    symmetric). compensated_drop_pa: the drop (Pa) a load-sensing supply holds across the
    meter-in edge (plant_models.supply: its margin); 0: no compensator, the edge takes what the
    constant supply pressure leaves.
    """

    bore_m: float
    rod_m: float
    stroke_m: float
    dead_volume_a_m3: float
    dead_volume_b_m3: float
    bulk_modulus_pa: float
    supply_pressure_pa: float
    tank_pressure_pa: float
    rated_flow_m3_s: float
    rated_pressure_drop_pa: float
    mass_kg: float
    viscous_friction_n_s_m: float
    meter_out_ratio: float = 1.0
    compensated_drop_pa: float = 0.0

    def __post_init__(self) -> None:
        for item in fields(self):
            value = getattr(self, item.name)
            if isinstance(value, bool) or not isinstance(value, int | float) \
                    or not math.isfinite(value):
                raise ValueError(f"CylinderModel.{item.name} must be a finite number, "
                                 f"got {value!r}")
            may_be_zero = item.name in ("tank_pressure_pa", "viscous_friction_n_s_m",
                                        "compensated_drop_pa")
            if value < 0.0 or (value == 0.0 and not may_be_zero):
                raise ValueError(f"CylinderModel.{item.name} must be > 0, got {value!r}")
        if not self.rod_m < self.bore_m:
            raise ValueError("CylinderModel.rod_m must be smaller than bore_m")
        if not self.tank_pressure_pa < self.supply_pressure_pa:
            raise ValueError("CylinderModel.tank_pressure_pa must be below supply_pressure_pa")

    @classmethod
    def from_fmu_parameters(cls, values: Mapping[str, float]) -> CylinderModel:
        """The model from values named as our HydraulicCylinder FMU's parameters (bore, rod,
        stroke, V_dead_A, V_dead_B, beta, p_supply, p_tank, q_rated, dp_rated, mass, b_viscous;
        meter_out_ratio if given); ValueError naming the first one missing."""
        missing = [name for name in FMU_PARAMETER_NAMES.values() if name not in values]
        if missing:
            raise ValueError(f"cylinder parameter {missing[0]!r} is missing (the servo needs "
                             f"{', '.join(FMU_PARAMETER_NAMES.values())})")
        optional = {key: float(values.get(name, default))
                    for key, (name, default) in OPTIONAL_FMU_PARAMETERS.items()}
        return cls(**{key: float(values[name]) for key, name in FMU_PARAMETER_NAMES.items()},
                   **optional)

    def fmu_parameters(self) -> dict[str, float]:
        """This model as parameter values of our HydraulicCylinder FMU."""
        names = {**FMU_PARAMETER_NAMES,
                 **{key: name for key, (name, _) in OPTIONAL_FMU_PARAMETERS.items()}}
        return {name: getattr(self, key) for key, name in names.items()}

    @property
    def area_a_m2(self) -> float:
        """Piston area (m^2)."""
        return math.pi / 4.0 * self.bore_m**2

    @property
    def area_b_m2(self) -> float:
        """Annulus area (m^2)."""
        return math.pi / 4.0 * (self.bore_m**2 - self.rod_m**2)

    def hydraulic_stiffness(self, stroke_m: float) -> float:
        """k_h (N/m) of the two oil columns at stroke stroke_m (m)."""
        if not 0.0 <= stroke_m <= self.stroke_m:
            raise ValueError(f"stroke {stroke_m} m outside [0, {self.stroke_m}] m")
        a, b = self.area_a_m2, self.area_b_m2
        volume_a = self.dead_volume_a_m3 + a * stroke_m
        volume_b = self.dead_volume_b_m3 + b * (self.stroke_m - stroke_m)
        return self.bulk_modulus_pa * (a * a / volume_a + b * b / volume_b)

    def natural_frequency(self, stroke_m: float) -> float:
        """Hydraulic natural frequency w_h (rad/s) at stroke stroke_m (m)."""
        return math.sqrt(self.hydraulic_stiffness(stroke_m) / self.mass_kg)

    def state_space(self, stroke_m: float) -> control.StateSpace:
        """Continuous model at stroke stroke_m (m): states [x, v, F], input w (m/s), outputs
        [x (m), F (N)]."""
        import control  # python-control takes seconds to import: only when a servo is designed

        k_h, m, b = self.hydraulic_stiffness(stroke_m), self.mass_kg, self.viscous_friction_n_s_m
        a = [[0.0, 1.0, 0.0], [0.0, -b / m, 1.0 / m], [0.0, -k_h, 0.0]]
        return control.ss(a, [[0.0], [0.0], [k_h]], [[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]],
                          [[0.0], [0.0]])

    def force_state_space(self, stroke_m: float) -> control.StateSpace:
        """The force part alone (x does not act on F): states [v, F], input w (m/s), output
        F (N)."""
        import control

        k_h, m, b = self.hydraulic_stiffness(stroke_m), self.mass_kg, self.viscous_friction_n_s_m
        return control.ss([[-b / m, 1.0 / m], [-k_h, 0.0]], [[0.0], [k_h]], [[0.0, 1.0]], [[0.0]])

    def opening(self, velocity_m_s: float, force_n: float) -> float:
        """Spool opening u in [-1, 1] that drives the piston at velocity_m_s (m/s) in steady
        state with the hydraulic force force_n (N): velocity_m_s / gain(direction, force_n)
        (`velocity_gain`)."""
        return min(1.0, max(-1.0, velocity_m_s / self.velocity_gain(velocity_m_s, force_n)))

    def velocity_gain(self, velocity_m_s: float, force_n: float) -> float:
        """m/s of steady piston velocity per unit of spool opening, in the direction of
        velocity_m_s, with the hydraulic force force_n (N).

        Constant supply: both metering edges pass the piston's flow (Q_A = A_A v, Q_B = A_B v,
        orifice law Q = q u sqrt(dp / dp_rated), q = q_rated in, r q_rated out, r the
        meter_out_ratio); with F = p_A A_A - p_B A_B that gives
        (v / (q_rated u))^2 dp_rated (A_A^3 + A_B^3 / r^2) = p_S A_A - p_T A_B - F extending and
        (v / (q_rated u))^2 dp_rated (A_A^3 / r^2 + A_B^3) = F - p_T A_A + p_S A_B retracting
        (the right-hand side at least MIN_FORCE_RESERVE of p_S A_A).
        Compensated meter-in (compensated_drop_pa = dp_c > 0): the meter-in edge passes
        q_rated u sqrt(dp_c / dp_rated) whatever the load, v = that / A_in; a load that pulls
        the piston (overrunning) drives it faster through the meter-out edge alone, the inlet
        chamber near 0: v = r q_rated u sqrt((-F / A_B - p_T) / dp_rated) / A_B extending,
        r q_rated u sqrt((F / A_A - p_T) / dp_rated) / A_A retracting. The larger one holds.
        """
        a, b, r = self.area_a_m2, self.area_b_m2, self.meter_out_ratio
        p_s, p_t = self.supply_pressure_pa, self.tank_pressure_pa
        q, dp = self.rated_flow_m3_s, self.rated_pressure_drop_pa
        if self.compensated_drop_pa > 0.0:
            metered = q * math.sqrt(self.compensated_drop_pa / dp)
            if velocity_m_s >= 0.0:
                pulled = -force_n / b - p_t
                return max(metered / a, r * q * math.sqrt(max(pulled, 0.0) / dp) / b)
            pulled = force_n / a - p_t
            return max(metered / b, r * q * math.sqrt(max(pulled, 0.0) / dp) / a)
        if velocity_m_s >= 0.0:
            reserve = p_s * a - p_t * b - force_n
            areas = a**3 + b**3 / (r * r)
        else:
            reserve = force_n - p_t * a + p_s * b
            areas = a**3 / (r * r) + b**3
        reserve = max(reserve, MIN_FORCE_RESERVE * p_s * a)
        return q * math.sqrt(reserve / (dp * areas))
