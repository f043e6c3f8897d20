"""A cylinder written for another tool: a pythonfmu (PyPI `pythonfmu`, in the test extra) model
with names and units of its own, exported as an FMI 2.0 co-simulation FMU by

    .venv/bin/python -m pythonfmu build -f examples/pythonfmu_cylinder.py -d build

(build/PyCylinder.fmu); docs/guide/substitution.md runs it in the bucket role, and
tests/test_pythonfmu_cylinder.py builds it at test time.

A first-order velocity servo with a valve that slows under load and end stops at 0 and the
stroke; percent, kN, mm, mm/s, cm2 and bar at its ports:

    w = max_speed * spool_cmd / 100 * sqrt(max(0, 1 - load_force * sign(spool_cmd) / stall_force))
    rod_speed' = (w - rod_speed) / time_constant,   rod_position' = rod_speed

(exact within a step, the command and load held). The rod holds its load, rod_force =
load_force; the chambers carry it: the rod side at back_pressure, the cap side at what balances
the load (at least tank_pressure, the rod side rising instead when the load pulls), so that
cap_pressure * bore_area - rod_pressure * annulus_area = rod_force exactly.

WITH_FORCE = False leaves rod_force out (a model that reports its pressures only).
"""

import math

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real

WITH_FORCE = True
_BAR_CM2_PER_KN = 1e5 * 1e-4 / 1e3  # 1 bar on 1 cm2 is 10 N = 0.01 kN


class PyCylinder(Fmi2Slave):
    author = "excosim tests"
    description = "First-order velocity servo cylinder in percent, kN, mm, mm/s, cm2, bar"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.spool_cmd = 0.0  # %, -100..100, + extends
        self.load_force = 0.0  # kN along the rod, + resists extension
        self.stroke_length = 1000.0  # mm
        self.rod_position_start = 500.0  # mm
        self.max_speed = 300.0  # mm/s at 100 %
        self.time_constant = 0.04  # s
        self.stall_force = 500.0  # kN: the load at which the valve's flow stops
        self.bore_area = 103.87  # cm2, cap side
        self.annulus_area = 53.61  # cm2, rod side
        self.back_pressure = 15.0  # bar
        self.tank_pressure = 1.0  # bar
        self.rod_position = 500.0  # mm
        self.rod_speed = 0.0  # mm/s
        self.rod_force = 0.0  # kN
        self.cap_pressure = 0.0  # bar
        self.rod_pressure = 0.0  # bar
        for name in ("spool_cmd", "load_force"):
            self.register_variable(Real(name, causality=Fmi2Causality.input))
        for name in ("stroke_length", "rod_position_start", "max_speed", "time_constant",
                     "stall_force", "bore_area", "annulus_area", "back_pressure",
                     "tank_pressure"):
            self.register_variable(Real(name, causality=Fmi2Causality.parameter,
                                        variability=Fmi2Variability.fixed))
        outputs = ["rod_position", "rod_speed", "cap_pressure", "rod_pressure"]
        for name in outputs + (["rod_force"] if WITH_FORCE else []):
            self.register_variable(Real(name, causality=Fmi2Causality.output))

    def exit_initialization_mode(self):
        self.rod_position = min(max(self.rod_position_start, 0.0), self.stroke_length)
        self.rod_speed = 0.0
        self._hold()

    def _hold(self):
        """rod_force and the chamber pressures that carry it."""
        self.rod_force = self.load_force
        rod_side = self.back_pressure
        cap_side = (self.load_force / _BAR_CM2_PER_KN + rod_side * self.annulus_area) \
            / self.bore_area
        if cap_side < self.tank_pressure:  # the load pulls: the rod side carries it
            cap_side = self.tank_pressure
            rod_side = (cap_side * self.bore_area - self.load_force / _BAR_CM2_PER_KN) \
                / self.annulus_area
        self.cap_pressure, self.rod_pressure = cap_side, rod_side

    def do_step(self, current_time, step_size):
        command = max(-100.0, min(100.0, self.spool_cmd)) / 100.0
        sign = 1.0 if command >= 0.0 else -1.0
        flow = math.sqrt(max(0.0, 1.0 - self.load_force * sign / self.stall_force))
        target = self.max_speed * command * flow
        decay = -math.expm1(-step_size / self.time_constant)
        position = self.rod_position + target * step_size \
            + (self.rod_speed - target) * self.time_constant * decay
        speed = self.rod_speed - (self.rod_speed - target) * decay
        if position <= 0.0 or position >= self.stroke_length:  # inelastic end stop
            position, speed = min(max(position, 0.0), self.stroke_length), 0.0
        self.rod_position, self.rod_speed = position, speed
        self._hold()
        return True
