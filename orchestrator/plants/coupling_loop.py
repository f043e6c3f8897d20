"""The simulated excavator's step loop in Python: the coupling of one communication step between
the FMU steps (orchestrator.plants.simulated_excavator's module docstring: strokes -> pose ->
Pile step -> loads, inertia, servo commands, supply -> cylinder steps).

`PythonCoupling` and orchestrator.plants.native.NativeCoupling (the same arithmetic in C) have
one interface: built once per plant from its FMUs, arm coupling, arm inertia, servos and supply,
`track(strokes, rates, accelerations, n_columns, steps, pile_time)` runs the steps of one
stroke reference and returns the signal rows, the joint angles, and the step count and Pile
time after them; `clock` holds those where the last track ended, an FMU error included. This
one serves every servo (the linear servo too) and stays the reference the C one is tested on.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from orchestrator.plants.arm_coupling import ArmCoupling
from orchestrator.plants.arm_dynamics import ArmInertia
from orchestrator.plants.master import Master
from plant_models.supply import SupplyLaw


class PythonCoupling:
    """The step loop in Python (see the module docstring). master: an
    orchestrator.plants.master.Master with components boom, stick, bucket, pile; coupling,
    inertia: the plant's ArmCoupling and ArmInertia; servos: three objects with
    command(x_ref, v_ref, a_ref, x, force) -> u; supply_law: the pump's law (None: each valve
    on its own supply); step_s: the communication step (s)."""

    def __init__(self, master: Master, coupling: ArmCoupling, inertia: ArmInertia,
                 servos: Sequence[object], supply_law: SupplyLaw | None,
                 step_s: float) -> None:
        self._master, self._coupling, self._inertia = master, coupling, inertia
        self._servos, self._supply, self._step_s = tuple(servos), supply_law, float(step_s)
        self.clock: tuple[int, float] = (0, 0.0)
        """(steps, Pile time s) where the last track() ended, an FMU error included."""

    def track(self, strokes: np.ndarray, rates: np.ndarray, accelerations: np.ndarray,
              n_columns: int, steps: int, pile_time: float) -> tuple[np.ndarray, np.ndarray,
                                                                     int, float]:
        """The steps of one stroke reference (each (n, 3): m, m/s, m/s^2) from the plant's
        step count and Pile time (s): rows (n, n_columns), joint angles (n, 3) rad, and the
        step count and Pile time after them."""
        master, h = self._master, self._step_s
        boom, stick, bucket, pile = (master[n] for n in ("boom", "stick", "bucket", "pile"))
        boom_out, stick_out, bucket_out, pile_out = (
            c.outputs for c in (boom, stick, bucket, pile))
        boom_in, stick_in, bucket_in, pile_in = (c.inputs for c in (boom, stick, bucket, pile))
        boom_step, stick_step, bucket_step, pile_step = (
            c.step for c in (boom, stick, bucket, pile))
        kinematics, loads = self._coupling.kinematics, self._coupling.loads
        inertia = self._inertia.at_pose
        command0, command1, command2 = (s.command for s in self._servos)
        supply = self._supply
        x0r, x1r, x2r = (strokes[:, j].tolist() for j in range(3))
        v0r, v1r, v2r = (rates[:, j].tolist() for j in range(3))
        a0r, a1r, a2r = (accelerations[:, j].tolist() for j in range(3))
        rows, joints = [], []
        append_row, append_joints = rows.append, joints.append
        try:
            for k in range(len(x0r)):
                x0, v0, pa0, pb0, f0 = boom_out.tolist()
                x1, v1, pa1, pb1, f1 = stick_out.tolist()
                x2, v2, pa2, pb2, f2 = bucket_out.tolist()
                pose = kinematics(x0, x1, x2)
                q0, q1, q2, tip_y, tip_z, angle = pose[:6]
                pile_in[0] = tip_y
                pile_in[1] = tip_z
                pile_in[2] = -angle  # the Pile's bucket_angle: tip-to-pin line (geometry)
                pile_step(pile_time, h)
                pile_time += h
                mass, force_y, force_z, removed, dumped, in_pile, surface = pile_out.tolist()
                e0, e1, e2 = loads(pose, force_y, force_z, mass)
                # The arm's inertia (orchestrator.plants.arm_dynamics): the diagonal reflected
                # into each FMU's mass_load, the rest into F_ext: velocity products from this
                # step's rates, the cross terms from the planned joint accelerations.
                r0, r1, r2 = pose[6:9]
                w0, w1, w2 = v0 / r0, v1 / r1, v2 / r2
                m00, m11, m22, m01, m02, m12, h0, h1, h2 = inertia(pose, w0, w1, w2, mass)
                d0, d1, d2 = pose[21:24]
                a0 = (a0r[k] - d0 * (v0r[k] / r0) ** 2) / r0
                a1 = (a1r[k] - d1 * (v1r[k] / r1) ** 2) / r1
                a2 = (a2r[k] - d2 * (v2r[k] / r2) ** 2) / r2
                e0 += (m01 * a1 + m02 * a2 + h0) / r0 - m00 * d0 * w0 * w0 / (r0 * r0)
                e1 += (m01 * a0 + m12 * a2 + h1) / r1 - m11 * d1 * w1 * w1 / (r1 * r1)
                e2 += (m02 * a0 + m12 * a1 + h2) / r2 - m22 * d2 * w2 * w2 / (r2 * r2)
                u0 = command0(x0r[k], v0r[k], a0r[k], x0, f0)
                u1 = command1(x1r[k], v1r[k], a1r[k], x1, f1)
                u2 = command2(x2r[k], v2r[k], a2r[k], x2, f2)
                append_joints((q0, q1, q2))
                l0, l1, l2 = m00 / (r0 * r0), m11 / (r1 * r1), m22 / (r2 * r2)
                row = (x0, v0, pa0, pb0, f0, u0, e0, l0, x1, v1, pa1, pb1, f1, u1, e1, l1,
                       x2, v2, pa2, pb2, f2, u2, e2, l2, mass, force_y, force_z, removed,
                       dumped, in_pile, surface, tip_y, tip_z, angle)
                if supply is not None:
                    p_pump, p_ls, sharing = supply(u0, u1, u2, pa0, pb0, pa1, pb1, pa2, pb2)
                    boom_in[3] = stick_in[3] = bucket_in[3] = p_pump
                    boom_in[4] = stick_in[4] = bucket_in[4] = p_ls
                    row += (p_pump, p_ls, sharing)
                append_row(row)
                boom_in[0], boom_in[1], boom_in[2] = u0, e0, l0
                stick_in[0], stick_in[1], stick_in[2] = u1, e1, l1
                bucket_in[0], bucket_in[1], bucket_in[2] = u2, e2, l2
                t = steps * h
                boom_step(t, h)
                stick_step(t, h)
                bucket_step(t, h)
                steps += 1
        finally:
            self.clock = steps, pile_time
        table = np.array(rows, dtype=float).reshape(len(rows), n_columns)
        return table, np.array(joints, dtype=float).reshape(len(joints), 3), steps, pile_time
