"""Position servo of one cylinder: design with python-control, and the runtime control law.

Plant: the linearised valve-cylinder model of `plant_models.cylinder_model` (input: commanded
piston velocity w; the valve law turns w into the spool command with the measured force).

Control law, evaluated once per communication step T (the spool command is held over the step,
so the zero-order-hold discretisation of the model is exact for it)::

    w = v_ref + K_p (x_ref - x) - k_f HP[F - m a_ref],   HP(s) = s / (s + w_f)  (Tustin)
    u = CylinderModel.opening(w, F)

- v_ref: velocity feed-forward (the reference's stroke rate), K_p: stroke error gain (1/s).
- Dynamic pressure feedback (DPF; Jelali & Kroll, Hydraulic Servo-systems, 2003, sec. 8.3):
  high-passed hydraulic force, which acts like valve leakage at the hydraulic resonance and
  damps it to `damping` at the design stroke, k_f = (2 damping w_h - b/m) / k_h, without costing
  static stiffness (w_f = FILTER_RATIO w_h). The inertial force m a_ref that the reference asks
  for is taken out first, so the damping does not resist the planned acceleration.
- K_p: the largest gain with the position loop's gain and phase margins at least the targets,
  at the design stroke and at 5 % and 95 % of the stroke (w_h changes with the oil volumes).
  If the pressure-feedback loop is not stable with a stability margin of 0.5 at all three
  strokes (a long step), the damping target is lowered until it is.

Loops, both discrete (sample time T): the position loop K_p x/w with the pressure feedback
closed, whose gain and phase margins are python-control's `stability_margins`; and the pressure
loop k_f HP F/w, whose crossovers lie on both sides of the real axis (it is a damping loop with
its peak at the resonance), so its robustness is given as python-control's stability margin
(least distance of the Nyquist curve from -1; 0.5 guarantees 6 dB and 29 deg both ways).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from functools import lru_cache
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # python-control takes about a second to import: only when designing
    import control

from plant_models.cylinder_model import MIN_FORCE_RESERVE, CylinderModel
from plant_models.sim_config import (
    DEFAULT_DAMPING,
    DEFAULT_GAIN_MARGIN_DB,
    DEFAULT_PHASE_MARGIN_DEG,
)

MIN_PRESSURE_STABILITY_MARGIN = 0.5
MIN_DAMPING = 0.1  # below this the DPF is not worth its name: the step is too long
FILTER_RATIO = 0.2  # DPF high-pass corner w_f / w_h: passes the resonance, blocks static load
_STROKE_CHECKS = (0.05, 0.95)  # fractions of the stroke where the margins are also held


@dataclass(frozen=True)
class ServoDesign:
    """One cylinder's servo (plain data; SI units).

    Gains: position_gain_1_s K_p (1/s: m/s of commanded velocity per m of stroke error),
    pressure_gain_m_s_per_n k_f, pressure_filter_rad_s w_f; step_s T (s).
    At the design stroke (m): natural_frequency_rad_s w_h; damping (the DPF's target);
    gain_margin_db, phase_margin_deg and crossover_rad_s of the position loop;
    pressure_stability_margin of the pressure loop; bandwidth_rad_s, the -3 dB frequency of
    stroke / stroke reference without feed-forward; max_pole_radius of the discrete closed loop
    (< 1: stable). position_loop_num/den, pressure_loop_num/den: the discrete loops' transfer
    functions in z (descending powers); `position_loop()` and `pressure_loop()` build them.
    """

    model: CylinderModel
    step_s: float
    design_stroke_m: float
    natural_frequency_rad_s: float
    damping: float
    position_gain_1_s: float
    pressure_gain_m_s_per_n: float
    pressure_filter_rad_s: float
    gain_margin_db: float
    phase_margin_deg: float
    crossover_rad_s: float
    pressure_stability_margin: float
    bandwidth_rad_s: float
    max_pole_radius: float
    position_loop_num: tuple[float, ...]
    position_loop_den: tuple[float, ...]
    pressure_loop_num: tuple[float, ...]
    pressure_loop_den: tuple[float, ...]

    def position_loop(self) -> control.TransferFunction:
        """Discrete position loop K_p x/w (pressure feedback closed), sample time step_s."""
        import control
        return control.tf(self.position_loop_num, self.position_loop_den, self.step_s)

    def pressure_loop(self) -> control.TransferFunction:
        """Discrete pressure-feedback loop k_f HP F/w, sample time step_s."""
        import control
        return control.tf(self.pressure_loop_num, self.pressure_loop_den, self.step_s)


def discrete_loops(model: CylinderModel, stroke_m: float, step_s: float, position_gain: float,
                   pressure_gain: float, filter_rad_s: float):
    """(position loop, pressure loop, closed loop x/x_ref) of the servo at stroke_m (m) as
    discrete python-control state-space systems with sample time step_s (s).

    The plant is discretised with a zero-order hold, the high-pass filter with Tustin's method,
    as `JointServo` evaluates it.
    """
    return _loops(_discretise(model, stroke_m, step_s, filter_rad_s), position_gain,
                  pressure_gain)


def _discretise(model: CylinderModel, stroke_m: float, step_s: float, filter_rad_s: float):
    """(plant [x, F] / w, plant F / w, high-pass filter), discrete, at stroke_m (m)."""
    import control
    return (control.c2d(model.state_space(stroke_m), step_s, "zoh"),
            control.c2d(model.force_state_space(stroke_m), step_s, "zoh"),
            control.ss(control.c2d(control.tf([1.0, 0.0], [1.0, filter_rad_s]), step_s,
                                   "tustin")))


def _loops(discretised, position_gain: float, pressure_gain: float):
    import control
    plant, force_plant, high_pass = discretised
    dpf = pressure_gain * high_pass
    force_only = control.ss([], [], [], [[0.0, 1.0]], dt=plant.dt)  # picks F from [x, F]
    position_loop = position_gain * control.feedback(plant, dpf * force_only)[0, 0]
    return position_loop, dpf * force_plant, control.feedback(position_loop, 1)


def _quiet_margins(loop):
    import control
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # "falling back to frd" notes for discrete systems
        return control.stability_margins(loop)


def _response(system, omega: np.ndarray) -> np.ndarray:
    """Complex frequency response of a discrete SISO system on omega (rad/s), through its
    transfer function (python-control evaluates a state space with one solve per frequency)."""
    import control
    return np.squeeze(control.ss2tf(system)(np.exp(1j * omega * system.dt)))


def _frequency_grid(step_s: float) -> np.ndarray:
    return np.logspace(-3.0, math.log10(math.pi / step_s * 0.999), 4000)


def _largest_gain(inner, step_s: float, gain_margin_db: float, phase_margin_deg: float) -> float:
    """Largest K_p with the margins met by K_p * inner on a dense frequency grid: the gain that
    puts the crossover where the phase reaches -180 + phase margin, or the gain margin at the
    first -180 deg crossing, whichever is smaller."""
    response = _response(inner, _frequency_grid(step_s))
    magnitude = np.abs(response)
    phase = np.unwrap(np.angle(response))
    phase_deg = np.degrees(phase - 2.0 * math.pi * np.round(phase[0] / (2.0 * math.pi)))
    late = np.nonzero(phase_deg < -180.0 + phase_margin_deg)[0]
    by_phase = 1.0 / magnitude[late[0]] if late.size else math.inf
    crossing = np.nonzero(phase_deg < -180.0)[0]
    by_gain = 10.0 ** (-gain_margin_db / 20.0) / magnitude[crossing[0]] if crossing.size \
        else math.inf
    return float(min(by_phase, by_gain))


def _pressure_loop_ok(discretised_strokes, pressure_gain: float) -> bool:
    """The pressure loop is stable with the least distance of its Nyquist curve from -1 at
    least MIN_PRESSURE_STABILITY_MARGIN, at every stroke (dense frequency grid)."""
    import control
    for discretised in discretised_strokes:
        _, pressure_loop, _ = _loops(discretised, 1.0, pressure_gain)
        closed = control.feedback(pressure_loop, 1)
        if np.max(np.abs(control.poles(closed))) >= 1.0:
            return False
        response = _response(pressure_loop, _frequency_grid(pressure_loop.dt))
        if np.min(np.abs(1.0 + response)) < MIN_PRESSURE_STABILITY_MARGIN:
            return False
    return True


@lru_cache(maxsize=64)
def design_servo(model: CylinderModel, step_s: float, design_stroke_m: float | None = None,
                 damping: float = DEFAULT_DAMPING,
                 gain_margin_db: float = DEFAULT_GAIN_MARGIN_DB,
                 phase_margin_deg: float = DEFAULT_PHASE_MARGIN_DEG) -> ServoDesign:
    """Design the servo of one cylinder for the communication step step_s (s).

    design_stroke_m (m, default mid-stroke) sets the oil volumes of the linearisation. Raises
    ValueError if no positive gain meets the margins (a step too long for the hydraulics).
    """
    import control
    if not (math.isfinite(step_s) and step_s > 0.0):
        raise ValueError(f"step_s must be > 0 s, got {step_s!r}")
    stroke = 0.5 * model.stroke_m if design_stroke_m is None else float(design_stroke_m)
    if not 0.0 <= stroke <= model.stroke_m:
        raise ValueError(f"design stroke {stroke} m outside [0, {model.stroke_m}] m")
    if not 0.0 < damping < 2.0:
        raise ValueError(f"damping must be in (0, 2), got {damping!r}")
    strokes = (stroke, *(f * model.stroke_m for f in _STROKE_CHECKS))
    w_h = model.natural_frequency(stroke)
    filter_rad_s = FILTER_RATIO * w_h
    discretised = [_discretise(model, at, step_s, filter_rad_s) for at in strokes]
    friction_damping = model.viscous_friction_n_s_m / model.mass_kg
    target = damping
    while True:
        pressure_gain = max(0.0, (2.0 * target * w_h - friction_damping)
                            / model.hydraulic_stiffness(stroke))
        if pressure_gain == 0.0 or _pressure_loop_ok(discretised, pressure_gain):
            break
        target *= 0.8
        if target < MIN_DAMPING:
            raise ValueError(
                f"the pressure feedback cannot damp the hydraulic mode ({w_h:.1f} rad/s) to "
                f"{MIN_DAMPING} with a {step_s} s step: shorten the communication step")
    gains = []
    for at in discretised:
        position_loop, _, _ = _loops(at, 1.0, pressure_gain)
        gains.append(_largest_gain(position_loop, step_s, gain_margin_db, phase_margin_deg))
    # 2 % below the grid's value, so python-control's exact margins land on the safe side.
    position_gain = 0.98 * min(gains)
    if not (math.isfinite(position_gain) and position_gain > 0.0):
        raise ValueError(f"no servo gain meets the margins with a {step_s} s step "
                         f"(hydraulic frequency {w_h:.1f} rad/s): shorten the step")
    position_loop, pressure_loop, closed = _loops(discretised[0], position_gain, pressure_gain)
    gm, pm, _, _, wgc, _ = _quiet_margins(position_loop)
    position_tf, pressure_tf = control.ss2tf(position_loop), control.ss2tf(pressure_loop)
    return ServoDesign(
        model=model, step_s=step_s, design_stroke_m=stroke, natural_frequency_rad_s=w_h,
        damping=target, position_gain_1_s=position_gain, pressure_gain_m_s_per_n=pressure_gain,
        pressure_filter_rad_s=filter_rad_s,
        gain_margin_db=math.inf if not np.isfinite(gm) else 20.0 * math.log10(gm),
        phase_margin_deg=float(pm), crossover_rad_s=float(wgc),
        pressure_stability_margin=float(_quiet_margins(pressure_loop)[2]) if pressure_gain
        else math.inf,
        bandwidth_rad_s=_bandwidth(closed, step_s),
        max_pole_radius=float(np.max(np.abs(control.poles(closed)))),
        position_loop_num=_coefficients(position_tf.num),
        position_loop_den=_coefficients(position_tf.den),
        pressure_loop_num=_coefficients(pressure_tf.num),
        pressure_loop_den=_coefficients(pressure_tf.den),
    )


def _coefficients(polynomial) -> tuple[float, ...]:
    return tuple(float(c) for c in np.ravel(polynomial[0][0]))


def _bandwidth(closed, step_s: float) -> float:
    """-3 dB frequency (rad/s) of a closed loop with unit static gain."""
    omega = _frequency_grid(step_s)
    below = np.nonzero(np.abs(_response(closed, omega)) < 1.0 / math.sqrt(2.0))[0]
    return float(omega[below[0]]) if below.size else math.pi / step_s


class JointServo:
    """The runtime control law of one cylinder (scalar math, one call per step).

    `command(x_ref, v_ref, a_ref, x, force, load_kg)`: stroke reference x_ref (m), its rate
    v_ref (m/s) and acceleration a_ref (m/s^2), measured stroke x (m), hydraulic force (N) and
    the arm's inertia reflected onto the rod now (kg, optional) -> spool command u in [-1, 1]
    to hold over the next step. `velocity_command` is the same law up to the commanded piston
    velocity w (m/s), before the valve law (CylinderModel.opening, which `command` evaluates
    inline with its constants precomputed).

    Gain scheduling on the load (design_load_kg > 0, the reflected inertia the design's mass
    holds): where the arm reflects more than that onto the rod (a bucket curled in reflects up
    to 18 times its mid-stroke inertia, a full bucket 3.4 times more again), the hydraulic mode
    falls as 1 / sqrt(moving mass), and gains designed at the lighter load would put the
    position loop's crossover on it. The law then uses the moving mass m = design mass -
    design_load_kg + load_kg for m a_ref and scales K_p, k_f and the high-pass corner w_f by
    sqrt(design mass / m): the loop keeps its shape relative to the mode (k_f ~ w_h, w_f =
    FILTER_RATIO w_h, and K_p's margins are set by w_h; tests/test_servo.py checks the margins
    up to 18 times the design's load). Lighter loads keep the design's gains. The step loop
    (orchestrator.plants.native) feeds each step's reflected inertia, the one it gives the FMU
    as mass_load.
    """

    __slots__ = ("_kp", "_kf", "_keep", "_gain", "_mass", "_filtered", "_last", "_extend",
                 "_retract", "_least", "_per_reserve_extend", "_per_reserve_retract",
                 "_compensated", "_metered", "_pull", "_p_tank", "_areas", "_held",
                 "_design_load")

    def __init__(self, design: ServoDesign, design_load_kg: float = 0.0) -> None:
        two_over_t = 2.0 / design.step_s
        w_f = design.pressure_filter_rad_s
        self._kp = design.position_gain_1_s
        self._kf = design.pressure_gain_m_s_per_n
        # Tustin high-pass: y_k (2/T + w_f) = (2/T - w_f) y_{k-1} + (2/T) (e_k - e_{k-1}).
        self._keep = (two_over_t - w_f) / (two_over_t + w_f)
        self._gain = two_over_t / (two_over_t + w_f)
        model = design.model
        self._mass = model.mass_kg
        a, b = model.area_a_m2, model.area_b_m2
        p_s, p_t = model.supply_pressure_pa, model.tank_pressure_pa
        self._extend = p_s * a - p_t * b  # reserve = extend - F, or F + retract
        self._retract = p_s * b - p_t * a
        self._least = MIN_FORCE_RESERVE * p_s * a
        # gain = q_rated sqrt(reserve / (dp_rated (A_A^3 + A_B^3 / r^2))) extending, with
        # A_A^3 / r^2 + A_B^3 retracting (CylinderModel.velocity_gain)
        r2 = model.meter_out_ratio * model.meter_out_ratio
        q2, dp = model.rated_flow_m3_s**2, model.rated_pressure_drop_pa
        self._per_reserve_extend = q2 / (dp * (a**3 + b**3 / r2))
        self._per_reserve_retract = q2 / (dp * (a**3 / r2 + b**3))
        # A compensated meter-in edge (CylinderModel.velocity_gain): metered q sqrt(dp_c / dp)
        # per area in, or pulled r q sqrt(pull / dp) per area out, pull = load pressure - p_T.
        self._compensated = model.compensated_drop_pa > 0.0
        metered = model.rated_flow_m3_s * math.sqrt(model.compensated_drop_pa
                                                     / model.rated_pressure_drop_pa)
        self._metered = (metered / a, metered / b)  # extending, retracting
        pull = model.meter_out_ratio * model.rated_flow_m3_s \
            / math.sqrt(model.rated_pressure_drop_pa)
        self._pull = (pull / b, pull / a)
        self._p_tank, self._areas = p_t, (a, b)
        self._filtered = 0.0
        self._last: float | None = None
        self._held = 0.0
        self._design_load = float(design_load_kg)
        if not 0.0 <= self._design_load < self._mass:
            raise ValueError(f"design_load_kg must lie in [0, the design's mass {self._mass} "
                             f"kg), got {design_load_kg!r}")

    def _scheduled(self, load_kg: float | None) -> tuple[float, float]:
        """(moving mass kg, gain scale) at the reflected load load_kg (class docstring)."""
        if load_kg is None or self._design_load <= 0.0 or load_kg <= self._design_load:
            return self._mass, 1.0
        moving = self._mass - self._design_load + load_kg
        return moving, math.sqrt(self._mass / moving)

    def state(self) -> tuple[float, float | None, float]:
        """What the servo carries from one sample to the next: the high-passed force (N), the
        last force sample it filtered (N; None before the first sample) and the spool command
        it holds until its next sample (the step loop, orchestrator.plants.native, samples
        every design.step_s)."""
        return self._filtered, self._last, self._held

    def set_state(self, filtered_n: float, last_n: float | None, held: float = 0.0) -> None:
        """Continue from a `state()` (a resumed run)."""
        self._filtered = float(filtered_n)
        self._last = None if last_n is None else float(last_n)
        self._held = float(held)

    def _high_pass(self, scale: float) -> tuple[float, float]:
        """The Tustin high-pass's (keep, gain) with its corner scaled by `scale` <= 1: the
        corner's w_f T / 2 = (1 - keep) / (1 + keep) scaled (coupling.c does the same)."""
        if scale >= 1.0:
            return self._keep, self._gain
        corner = (1.0 - self._keep) / (1.0 + self._keep) * scale
        return (1.0 - corner) / (1.0 + corner), 1.0 / (1.0 + corner)

    def velocity_command(self, x_ref: float, v_ref: float, a_ref: float, x: float,
                         force: float, load_kg: float | None = None) -> float:
        """Commanded piston velocity w (m/s); advances the filter by one step."""
        mass, scale = self._scheduled(load_kg)
        keep, gain = self._high_pass(scale)
        excess = force - mass * a_ref
        last = excess if self._last is None else self._last
        self._filtered = keep * self._filtered + gain * (excess - last)
        self._last = excess
        return v_ref + scale * (self._kp * (x_ref - x) - self._kf * self._filtered)

    def command(self, x_ref: float, v_ref: float, a_ref: float, x: float, force: float,
                load_kg: float | None = None) -> float:
        """Spool command u in [-1, 1] (see the class docstring)."""
        mass, scale = self._scheduled(load_kg)
        keep, gain = self._high_pass(scale)
        excess = force - mass * a_ref
        last = excess if self._last is None else self._last
        filtered = keep * self._filtered + gain * (excess - last)
        self._filtered = filtered
        self._last = excess
        velocity = v_ref + scale * (self._kp * (x_ref - x) - self._kf * filtered)
        if self._compensated:
            if velocity >= 0.0:
                pulled = -force / self._areas[1] - self._p_tank
                gain = self._metered[0]
                if pulled > 0.0:
                    gain = max(gain, self._pull[0] * math.sqrt(pulled))
            else:
                pulled = force / self._areas[0] - self._p_tank
                gain = self._metered[1]
                if pulled > 0.0:
                    gain = max(gain, self._pull[1] * math.sqrt(pulled))
            u = velocity / gain
        elif velocity >= 0.0:
            reserve = self._extend - force
            if reserve < self._least:
                reserve = self._least
            u = velocity / math.sqrt(reserve * self._per_reserve_extend)
        else:
            reserve = force + self._retract
            if reserve < self._least:
                reserve = self._least
            u = velocity / math.sqrt(reserve * self._per_reserve_retract)
        return 1.0 if u > 1.0 else (-1.0 if u < -1.0 else u)
