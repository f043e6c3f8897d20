"""The emulated device's physics: the simulated excavator (our FMUs) stepped one stream cycle at
a time instead of one whole period.

The device receives one setpoint per stream cycle T (position, velocity and acceleration of each
joint) and runs the simulated excavator's own step loop over the cycle's communication steps h
(T / h of them), with the reference between setpoints from the setpoint's second-order Taylor
expansion, q(t_c + s) = q + v s + a s^2 / 2: exact for the planner's quintic spline up to its
jerk term (jerk T^3 / 6 = 1e-5 deg for 60 deg/s^3 at T = 10 ms), and causal (a device cannot
wait for the next setpoint). Weighing and dumping are separate steps, as on the machine. Between
periods nothing is stepped: the valves are closed and the hydraulic arm holds.

This subclass reuses SimulatedExcavator's step loop (`_track`), dump and profile methods, so
the emulated device and the simulated plant step the same physics.
"""

from __future__ import annotations

import math

import numpy as np

from orchestrator.plants.simulated_excavator import SimulatedExcavator
from plant_models.linkage import JOINT_NAMES
from plant_models.sim_config import SimulatedExcavatorConfig


class SteppedExcavator(SimulatedExcavator):
    """A SimulatedExcavator that runs cycle by cycle (module docstring). `config.start_pose_rad`
    must be set: a device has an arm from power-on."""

    def __init__(self, config: SimulatedExcavatorConfig, cycle_s: float) -> None:
        if config.start_pose_rad is None:
            raise ValueError("the emulated device needs SimulatedExcavatorConfig.start_pose_rad")
        super().__init__(config)
        h = config.communication_step_s
        substeps = cycle_s / h
        if abs(substeps - round(substeps)) > 1e-6 or round(substeps) < 1:
            raise ValueError(f"the stream period {cycle_s} s must be a whole number of "
                             f"communication steps of {h} s")
        self.cycle_s = float(cycle_s)
        self.substeps = int(round(substeps))
        self._offsets = np.arange(self.substeps) * h

    def pressures_pa(self) -> tuple[np.ndarray, np.ndarray]:
        """(p_A (3,), p_B (3,)) Pa: the cylinders' chamber pressures now."""
        outputs = [self._master[j].outputs for j in JOINT_NAMES]
        return (np.array([o[2] for o in outputs]), np.array([o[3] for o in outputs]))

    def bucket_mass_kg(self) -> float:
        """Material in the bucket now (kg, the pile's output)."""
        return float(self._master["pile"].outputs[0])

    def cycle(self, position_rad, velocity_rad_s, acceleration_rad_s2) -> None:
        """Track one stream cycle from the setpoint (each (3,), rad, rad/s, rad/s^2) at its
        start: T / h communication steps."""
        p, v, a = (np.asarray(x, dtype=float) for x in (position_rad, velocity_rad_s,
                                                         acceleration_rad_s2))
        s = self._offsets[:, None]
        position = p + v * s + 0.5 * a * s * s
        velocity = v + a * s
        acceleration = np.broadcast_to(a, position.shape)
        self._track(*self.coupling.stroke_reference(position, velocity, acceleration))

    def weigh(self) -> float:
        """The load cell's reading (kg): the bucket's content plus the configured Gaussian noise,
        from the same seeded generator, one draw per weighing, as the simulated plant."""
        noise = self.config.load_cell_noise_kg * float(self._rng.standard_normal())
        return self.bucket_mass_kg() + noise

    def dump(self) -> None:
        """Empty the bucket (one pile step with `dump` high, as the simulated plant)."""
        self._dump()

    def start_pose_error_rad(self, position_rad) -> float:
        """Largest |setpoint - arm| over the joints (rad)."""
        return float(np.max(np.abs(np.asarray(position_rad, dtype=float) - self.joints_rad())))


def within_limits(position_rad, limits_rad, tolerance_rad: float = math.radians(0.5)) -> bool:
    """Whether every joint angle (3,) rad is inside its (low, high) rad range, with a tolerance
    (rad) for the setpoint's quantization and the planner's own limit tolerance."""
    return all(low - tolerance_rad <= q <= high + tolerance_rad
               for q, (low, high) in zip(position_rad, limits_rad, strict=True))
