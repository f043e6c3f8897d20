"""The oil supply the three valve sections share: a load-sensing pump with post-compensated flow
sharing (LUDV, as on most mid-size excavators), plain data and the per-step law.

Each section i has a meter-in edge of rated flow q_i at the drop dp_i (HydraulicCylinder's
q_rated, dp_rated), opened a_i = clamp(u_i, -1, 1). Its compensator, between that edge and the
chamber, holds the edge's outlet at the load-sensing pressure p_LS, the highest meter-in
chamber pressure of the open sections; the pump regulates its pressure to p_LS + margin. So
every open section sees the same drop across its meter-in edge and takes
q_i |a_i| sqrt(drop / dp_i), whatever its own load: the operator's (here the servo's) command
sets the flow. When the sections ask for more than the pump's flow,

    demand D = sum_i q_i |a_i| sqrt(margin / dp_i)        (m^3/s at the full margin)
    sharing s = min(1, Q_max / D),   drop = margin s^2,   p_pump = min(p_LS + drop, p_cutoff)

the drop falls until the flows add up to Q_max, and every section slows by the same factor s
(flow sharing: the arm keeps its path's direction, only slower). The pump's power (torque)
limiter does the same where the flow at the pump's pressure would take more than the engine
gives: with P = engine_power x pump_efficiency (the hydraulic power at the pump's outlet),

    s = the root of (p_LS + margin s^2) s D = P    when (p_LS + margin s^2) s D > P

(one real root, increasing in s; Newton's method from the flow-limited s converges from above),
so p_pump x Q = (p_LS + margin s^2) s D never exceeds P: the swashplate swivels back as p x Q
reaches the engine's power, at any pressure. An LS pressure limiter holds
p_LS at most p_cutoff - margin, so the pump never passes its cut-off p_cutoff: a section whose
load needs more (a stalled bucket, its port relief at 35 MPa) gets only what p_cutoff drives
into it, while the others keep their margin.

The demand comes from the commands, not from the flows of the step, so the law needs no
iteration with the cylinders: the master evaluates it once per communication step with the
chamber pressures at its start and feeds p_pump and p_LS to every cylinder FMU (its inputs of
the same names). A real pump's swashplate answers in 50-100 ms; holding its pressure over a
10 ms step is well inside that.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from plant_models.cylinder_model import CylinderModel

M3_S_PER_L_MIN = 1.0e-3 / 60.0
SupplyLaw = Callable[[float, float, float, float, float, float, float, float, float],
                     tuple[float, float, float]]


@dataclass(frozen=True)
class LoadSensingPump:
    """A flow- and pressure-limited load-sensing pump with flow sharing (SI units).

    max_flow_m3_s: the most the pump delivers (m^3/s; a CAT 320's 2 x 214.5 L/min).
    cutoff_pa: its pressure limit (Pa; the main relief of the class, 35 MPa on a CAT 320).
    margin_pa: the load-sensing margin p_pump - p_LS it regulates (Pa; 2-3 MPa is usual).
    engine_power_w: the engine's net power the pump may take (W; a CAT 320's 121 kW, SAE
    J1349 net).
    pump_efficiency: the pump's overall efficiency, hydraulic power out per shaft power in (-;
    axial piston pumps reach 0.85-0.9 at high pressure).
    """

    max_flow_m3_s: float = 429.0 * M3_S_PER_L_MIN
    cutoff_pa: float = 35.0e6
    margin_pa: float = 2.5e6
    engine_power_w: float = 121.0e3
    pump_efficiency: float = 0.85

    def __post_init__(self) -> None:
        for name in ("max_flow_m3_s", "cutoff_pa", "margin_pa", "engine_power_w",
                     "pump_efficiency"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | float) \
                    or not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"LoadSensingPump.{name} must be a finite number > 0, "
                                 f"got {value!r}")
        if not self.margin_pa < self.cutoff_pa:
            raise ValueError("LoadSensingPump.margin_pa must be below cutoff_pa")
        if not self.pump_efficiency <= 1.0:
            raise ValueError(f"LoadSensingPump.pump_efficiency must be at most 1, got "
                             f"{self.pump_efficiency!r}")

    @property
    def power_limit_w(self) -> float:
        """The hydraulic power p_pump x Q the power limiter allows (W): engine_power_w x
        pump_efficiency."""
        return self.engine_power_w * self.pump_efficiency

    def law_parameters(self, models: Sequence[CylinderModel | None]
                       ) -> tuple[tuple[float | None, ...], float, float, float, float]:
        """What `law` computes with, for a second implementation of it (the master's C
        coupling): per section its flow at the full margin q_i sqrt(margin / dp_i) (m^3/s;
        None off the pump), the pump's Q_max (m^3/s), its margin and the LS limiter's ceiling
        cutoff - margin (Pa), and the power limit P (W)."""
        fulls = tuple(None if m is None else m.rated_flow_m3_s
                      * math.sqrt(self.margin_pa / m.rated_pressure_drop_pa) for m in models)
        return (fulls, self.max_flow_m3_s, self.margin_pa, self.cutoff_pa - self.margin_pa,
                self.power_limit_w)

    def law(self, models: Sequence[CylinderModel | None]) -> SupplyLaw:
        """The per-step law of boom, stick and bucket (models: their rated flows and drops;
        None for a section not on this pump, whose command and pressures then never count):
        law(u0, u1, u2, p_A0, p_B0, p_A1, p_B1, p_A2, p_B2) -> (p_pump Pa, p_LS Pa, sharing s
        in (0, 1]), from the spool commands u_i (clamped to [-1, 1] as the valve does) and the
        chamber pressures (Pa) at the step's start: p_LS is the highest meter-in chamber
        pressure of the open sections (p_A extending, p_B retracting), at most cutoff - margin
        (the LS pressure limiter), and p_pump = p_LS + margin s^2 (see the module docstring).
        Scalar math: it runs once per communication step."""
        (full0, full1, full2), q_max, margin, ceiling, power = self.law_parameters(models)

        def law(u0, u1, u2, pa0, pb0, pa1, pb1, pa2, pb2):
            p_ls, demand = 0.0, 0.0
            for u, pa, pb, full in ((u0, pa0, pb0, full0), (u1, pa1, pb1, full1),
                                    (u2, pa2, pb2, full2)):
                if full is None:
                    continue
                if u > 0.0:
                    demand += full * (u if u < 1.0 else 1.0)
                    p_ls = pa if pa > p_ls else p_ls
                elif u < 0.0:
                    demand -= full * (u if u > -1.0 else -1.0)
                    p_ls = pb if pb > p_ls else p_ls
            p_ls = p_ls if p_ls < ceiling else ceiling
            sharing = power_limited(1.0 if demand <= q_max else q_max / demand, p_ls, margin,
                                    demand, power)
            return p_ls + margin * sharing * sharing, p_ls, sharing

        return law


def power_limited(sharing: float, p_ls_pa: float, margin_pa: float, demand_m3_s: float,
                  power_w: float) -> float:
    """The sharing factor s (-, in (0, sharing]) at which the pump's power (p_LS + margin s^2) s
    D stays within power_w (W), from the flow-limited `sharing`, the LS pressure (Pa), the
    margin (Pa) and the demand D at the full margin (m^3/s): `sharing` itself when that is
    within the power, else the root of (p_LS + margin s^2) s D = power_w by Newton's method
    from above (the power is convex and increasing in s > 0, so the iterates fall
    monotonically to the root). The master's C loop does the same operations."""
    s = sharing
    if demand_m3_s <= 0.0 or (p_ls_pa + margin_pa * s * s) * s * demand_m3_s <= power_w:
        return s
    for _ in range(60):
        excess = (p_ls_pa + margin_pa * s * s) * s * demand_m3_s - power_w
        step = excess / ((p_ls_pa + 3.0 * margin_pa * s * s) * demand_m3_s)
        s -= step
        if not step > 1e-15 * s:
            break
    return s
