"""Position servo of a cylinder known only by its linear model (plant_models.linear_cylinder).

Control law, evaluated once per communication step T and held over the step (so the
zero-order-hold discretisation of the plant is exact for it)::

    u = clip((v_ref + K_p (x_ref - x)) / K_v, -1, 1)

v_ref (m/s): the reference's stroke rate (feed-forward through the model's velocity gain K_v);
K_p (1/s): the stroke error gain. Without pressure feedback (the FMU's pressures need not mean
what ours do) the only damping of the hydraulic mode is the plant's own, so K_p is bounded by
about 2 zeta w_h times the gain margin: a lightly damped plant gets a slow servo, an undamped
one none (refused).

Position loop at operating point i (its identified plant P_i, or the given model)::

    L_i(z) = (K_p / K_v) ZOH{P_i(s)},   P_i(s) = K_v,i w_i^2 / (s (s^2 + 2 zeta_i w_i s + w_i^2))

K_p is the largest gain whose gain and phase margins (python-control `stability_margins`) are
at least the targets at every operating point, found on a dense frequency grid and then
checked (and trimmed) against python-control's exact margins.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # python-control takes about a second to import: only when designing
    import control

from plant_models.linear_cylinder import LinearCylinderModel
from plant_models.sim_config import (
    DEFAULT_GAIN_MARGIN_DB,
    DEFAULT_PHASE_MARGIN_DEG,
    REQUIRED_GAIN_MARGIN_DB,
    REQUIRED_PHASE_MARGIN_DEG,
)

# Below this the stroke error decays slower than 10 s, longer than a digging period: a servo
# that weak only rides on its feed-forward, so it is refused rather than run.
MIN_POSITION_GAIN_1_S = 0.1
_GRID_POINTS = 6000


@dataclass(frozen=True)
class LinearServoDesign:
    """The linear servo of one cylinder role (plain data, SI units).

    role: who it is for (boom, stick, bucket). model: the role's linear model (the law divides
    by its K_v). operating_points: the plants the margins hold for (the identified fits, or
    the model alone). step_s: T (s). position_gain_1_s: K_p (1/s). gain_margin_db,
    phase_margin_deg, crossover_rad_s: of the worst operating point (python-control);
    max_pole_radius: of the discrete closed loops (< 1: stable); *_target: the design targets.
    """

    role: str
    model: LinearCylinderModel
    operating_points: tuple[LinearCylinderModel, ...]
    step_s: float
    position_gain_1_s: float
    gain_margin_db: float
    phase_margin_deg: float
    crossover_rad_s: float
    max_pole_radius: float
    gain_margin_target_db: float
    phase_margin_target_deg: float

    def position_loop(self, index: int = 0) -> control.TransferFunction:
        """Discrete position loop L_i(z) of operating point `index`, sample time step_s."""
        return position_loop(self.model, self.operating_points[index], self.step_s,
                             self.position_gain_1_s)

    def describe(self) -> str:
        """One line for a person: gain and worst margins."""
        return (f"{self.role}: linear servo K_p {self.position_gain_1_s:.3g} 1/s, margins "
                f"{self.gain_margin_db:.1f} dB / {self.phase_margin_deg:.1f} deg (worst of "
                f"{len(self.operating_points)} operating points, targets "
                f"{self.gain_margin_target_db:g} dB / {self.phase_margin_target_deg:g} deg)")


def position_loop(model: LinearCylinderModel, plant: LinearCylinderModel, step_s: float,
                  position_gain_1_s: float) -> control.TransferFunction:
    """(K_p / K_v) ZOH{plant x/u}: the discrete position loop (sample time step_s, s) of the
    law designed on `model` acting on `plant`."""
    import control
    discrete = control.c2d(plant.transfer_function(), step_s, "zoh")
    return (position_gain_1_s / model.velocity_gain_m_s) * discrete


def _margins(loop) -> tuple[float, float, float]:
    """(gain margin dB, phase margin deg, crossover rad/s) by python-control."""
    import control
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # "falling back to frd" notes for discrete systems
        gm, pm, _, _, wgc, _ = control.stability_margins(loop)
    gm_db = math.inf if not np.isfinite(gm) or gm <= 0.0 else 20.0 * math.log10(gm)
    return gm_db, float(pm), float(wgc)


def _grid_gain(loop, step_s: float, gain_margin_db: float, phase_margin_deg: float) -> float:
    """Largest k with k * loop inside the margins on a dense grid: |k L| < 1 wherever the
    phase is within the phase margin of -180 deg, and |k L| <= the gain margin's inverse
    where it crosses -180 deg."""
    omega = np.logspace(-3.0, math.log10(math.pi / step_s * 0.999), _GRID_POINTS)
    num, den = (np.ravel(c[0][0]) for c in (loop.num, loop.den))
    z = np.exp(1j * omega * step_s)
    response = np.polyval(num, z) / np.polyval(den, z)
    magnitude = np.abs(response)
    phase = np.degrees(np.unwrap(np.angle(response)))
    phase -= 360.0 * np.round((phase[0] + 90.0) / 360.0)  # the integrator's -90 deg at w -> 0
    from_minus_180 = np.abs((phase + 180.0 + 180.0) % 360.0 - 180.0)
    near = from_minus_180 < phase_margin_deg
    by_phase = 1.0 / magnitude[near].max() if near.any() else math.inf
    wrapped = (phase + 180.0 + 180.0) % 360.0 - 180.0  # phase relative to -180, in (-180, 180]
    crossing = np.nonzero((np.sign(wrapped[:-1]) != np.sign(wrapped[1:]))
                          & (from_minus_180[:-1] < 90.0))[0]
    by_gain = math.inf
    if crossing.size:
        peak = np.maximum(magnitude[crossing], magnitude[crossing + 1])
        by_gain = 10.0 ** (-gain_margin_db / 20.0) / peak.max()
    return float(min(by_phase, by_gain))


def design_linear_servo(model: LinearCylinderModel, step_s: float, role: str = "cylinder",
                        operating_points: Sequence[LinearCylinderModel] = (),
                        gain_margin_db: float = DEFAULT_GAIN_MARGIN_DB,
                        phase_margin_deg: float = DEFAULT_PHASE_MARGIN_DEG) -> LinearServoDesign:
    """Design the linear servo of `role` for the communication step step_s (s).

    operating_points: the plants the margins must hold for (default: the model itself). Raises
    ValueError (one line, naming the role and what to change) if targets are below 6 dB /
    45 deg or no gain of at least MIN_POSITION_GAIN_1_S meets them.
    """
    import control
    if not (math.isfinite(step_s) and step_s > 0.0):
        raise ValueError(f"{role}: step_s must be > 0 s, got {step_s!r}")
    if not (gain_margin_db >= REQUIRED_GAIN_MARGIN_DB
            and REQUIRED_PHASE_MARGIN_DEG <= phase_margin_deg < 90.0):
        raise ValueError(f"{role}: servo margins {gain_margin_db} dB / {phase_margin_deg} deg "
                         f"are below the required {REQUIRED_GAIN_MARGIN_DB:g} dB / "
                         f"{REQUIRED_PHASE_MARGIN_DEG:g} deg: raise the design targets")
    plants = tuple(operating_points) or (model,)
    loops = [position_loop(model, plant, step_s, 1.0) for plant in plants]
    gain = min(_grid_gain(loop, step_s, gain_margin_db, phase_margin_deg) for loop in loops)
    # The grid misses the exact extremes by a little: trim until python-control's exact
    # margins (and closed-loop poles) agree at every operating point.
    for _ in range(40):
        if not (math.isfinite(gain) and gain >= MIN_POSITION_GAIN_1_S):
            break
        checks = [_margins(gain * loop) for loop in loops]
        radius = max(float(np.max(np.abs(control.poles(control.feedback(gain * loop, 1)))))
                     for loop in loops)
        if radius < 1.0 and all(gm >= gain_margin_db and pm >= phase_margin_deg
                                for gm, pm, _ in checks):
            worst_gm = min(checks, key=lambda c: c[0])
            worst_pm = min(checks, key=lambda c: c[1])
            return LinearServoDesign(
                role=role, model=model, operating_points=plants, step_s=step_s,
                position_gain_1_s=float(gain), gain_margin_db=worst_gm[0],
                phase_margin_deg=worst_pm[1], crossover_rad_s=worst_pm[2],
                max_pole_radius=radius, gain_margin_target_db=gain_margin_db,
                phase_margin_target_deg=phase_margin_deg)
        gain *= 0.98
    weakest = min(plants, key=lambda p: p.damping * p.natural_frequency_rad_s)
    raise ValueError(
        f"{role}: no servo gain of at least {MIN_POSITION_GAIN_1_S} 1/s keeps "
        f"{gain_margin_db:g} dB / {phase_margin_deg:g} deg with a {step_s} s step (hydraulic "
        f"mode {weakest.natural_frequency_rad_s:.3g} rad/s, damping {weakest.damping:.3g}): "
        "shorten the communication step or give the linear model more damping")


class LinearJointServo:
    """The runtime law of a LinearServoDesign, with JointServo's interface.

    `command(x_ref, v_ref, a_ref, x, force)`: stroke reference x_ref (m) and its rate v_ref
    (m/s), measured stroke x (m) -> spool command u in [-1, 1] to hold over the next step.
    a_ref (m/s^2) and force (N) are accepted and unused (no pressure feedback).
    """

    __slots__ = ("_kp", "_per_velocity", "_held")

    def __init__(self, design: LinearServoDesign) -> None:
        self._kp = design.position_gain_1_s
        self._per_velocity = 1.0 / design.model.velocity_gain_m_s
        self._held = 0.0

    def state(self) -> tuple[float]:
        """The spool command held until the next sample (JointServo's interface)."""
        return (self._held,)

    def set_state(self, held: float = 0.0) -> None:
        """Continue from a `state()` (a resumed run)."""
        self._held = float(held)

    def velocity_command(self, x_ref: float, v_ref: float, a_ref: float, x: float,
                         force: float) -> float:
        """Commanded piston velocity v_ref + K_p (x_ref - x) (m/s)."""
        return v_ref + self._kp * (x_ref - x)

    def command(self, x_ref: float, v_ref: float, a_ref: float, x: float, force: float) -> float:
        """Spool command u in [-1, 1] (see the class docstring)."""
        u = (v_ref + self._kp * (x_ref - x)) * self._per_velocity
        return 1.0 if u > 1.0 else (-1.0 if u < -1.0 else u)
