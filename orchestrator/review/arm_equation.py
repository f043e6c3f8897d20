"""The arm's equation of motion checked on a run's logged signals alone.

For boom, stick and bucket (joint angles q, rad) the rigid arm obeys

    M(q) qdd + h(q, qd) + G(q, payload) - J(q)^T f = R(q) (F - F_friction(v) - m_p xdd)

with M the mass matrix and h the velocity products of the links and the payload
(plant_models.arm_inertia; h from finite differences of M: Mdot qd - d(qd^T M qd / 2)/dq), G the
gravity holding torques (plant_models.geometry.gravity_joint_torques), f = (F_y, F_z) the soil
force at the tip and J its Jacobian (from plant_models.geometry.arm_points), R = diag(r) the
cylinders' moment arms d(stroke)/dq (plant_models.joint_strokes, from the linkage geometry),
F the hydraulic force p_A A_A - p_B A_B, F_friction = F_coulomb tanh(v / v_coulomb) + b_viscous v
and m_p xdd the piston's own inertia, with the cylinder FMU's parameters.

Nothing here comes from the coupling that produced the run: the motion is the logged joint
angles and piston velocities, the forces the logged cylinder forces, soil force and payload.
The equation is evaluated over each logged interval [t_k, t_k+1] of a period, as the
co-simulation makes it hold: accelerations as (qd_k+1 - qd_k) / dt (qd = v / r), every other
term at the interval's middle (the mean of its two ends). The residual (left minus right side)
is reported per joint in cylinder-force units (N, divided by r) against the RMS cylinder force.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from plant_models.arm_inertia import mass_matrix
from plant_models.geometry import ExcavatorGeometry, arm_points, gravity_joint_torques
from plant_models.joint_strokes import moment_arm_m
from plant_models.linkage import JOINT_NAMES

_PINS = ("boom_foot", "stick_pin", "bucket_pin")
_EPSILON_RAD = 1e-6  # finite-difference step of dM/dq: M is smooth in q (cos, sin of links)
_FRICTION = ("F_coulomb", "v_coulomb", "b_viscous", "mass")


@dataclass(frozen=True)
class ArmResidual:
    """The equation's residual over one run's intervals (see the module docstring).

    residual_n: (n, 3) per interval and joint, N at the rod (torque residual / r).
    cylinder_force_rms_n: (3,) RMS of the hydraulic force F per joint over the same intervals.
    rms_ratio, peak_ratio: (3,) RMS and largest |residual| over that RMS force.
    """

    residual_n: np.ndarray
    cylinder_force_rms_n: np.ndarray

    @property
    def rms_ratio(self) -> np.ndarray:
        return np.sqrt(np.mean(self.residual_n**2, axis=0)) / self.cylinder_force_rms_n

    @property
    def peak_ratio(self) -> np.ndarray:
        return np.max(np.abs(self.residual_n), axis=0) / self.cylinder_force_rms_n


def arm_terms(geometry: ExcavatorGeometry, q: np.ndarray, qd: np.ndarray, payload_kg: float,
              soil_n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(M (3, 3) kg m^2, h + G - J^T f (3,) N m) at joints q (3,) rad turning at qd (3,)
    rad/s with payload_kg in the bucket and the soil force soil_n (F_y, F_z) N at the tip."""
    matrix = mass_matrix(geometry, q, payload_kg)
    derivatives = []
    for j in range(3):
        step = np.zeros(3)
        step[j] = _EPSILON_RAD
        derivatives.append((mass_matrix(geometry, q + step, payload_kg)
                            - mass_matrix(geometry, q - step, payload_kg)) / (2 * _EPSILON_RAD))
        # central differences: truncation ~ eps^2 |M'''|, far below round-off's eps_mach / eps
    m_dot = sum(d * rate for d, rate in zip(derivatives, qd, strict=True))
    products = m_dot @ qd - 0.5 * np.array([qd @ d @ qd for d in derivatives])
    points = arm_points(geometry, q)
    tip = points["bucket_tip"]
    soil = np.array([soil_n[0] * (tip[1] - points[pin][1]) - soil_n[1] * (tip[0] - points[pin][0])
                     for pin in _PINS])
    return matrix, products + gravity_joint_torques(geometry, q, payload_kg) - soil


def arm_residual(geometry: ExcavatorGeometry, periods: list[Mapping[str, np.ndarray]],
                 cylinder_parameters: Mapping[str, Mapping[str, float]]) -> ArmResidual:
    """The residual over `periods`, each a mapping of logged signals (n,) of one period:
    "joints" (n, 3) rad, "<joint>.v" m/s, "<joint>.F" N, "pile.bucket_mass" kg, "pile.F_y",
    "pile.F_z" N; cylinder_parameters: joint -> the cylinder FMU's F_coulomb (N), v_coulomb
    (m/s), b_viscous (N s/m) and mass (kg)."""
    residuals, forces = [], []
    friction = {joint: tuple(float(cylinder_parameters[joint][k]) for k in _FRICTION)
                for joint in JOINT_NAMES}
    for signals in periods:
        q = np.asarray(signals["joints"], dtype=float)
        v = np.column_stack([signals[f"{j}.v"] for j in JOINT_NAMES])
        hydraulic = np.column_stack([signals[f"{j}.F"] for j in JOINT_NAMES])
        payload, soil_y, soil_z = (np.asarray(signals[k]) for k in (
            "pile.bucket_mass", "pile.F_y", "pile.F_z"))
        dt = np.diff(np.asarray(signals["t_s"], dtype=float))
        arms = np.array([[moment_arm_m(geometry, joint, angle) for joint, angle in
                          zip(JOINT_NAMES, pose, strict=True)] for pose in q])
        qd = v / arms
        for k in range(len(dt)):
            q_mid, qd_mid = 0.5 * (q[k] + q[k + 1]), 0.5 * (qd[k] + qd[k + 1])
            qdd = (qd[k + 1] - qd[k]) / dt[k]
            xdd = (v[k + 1] - v[k]) / dt[k]
            # The Pile's outputs at t_k hold over the interval (its sample of the tip's path)
            matrix, rest = arm_terms(geometry, q_mid, qd_mid, payload[k],
                                     np.array([soil_y[k], soil_z[k]]))
            arm = np.array([moment_arm_m(geometry, joint, angle)
                            for joint, angle in zip(JOINT_NAMES, q_mid, strict=True)])
            v_mid, force = 0.5 * (v[k] + v[k + 1]), 0.5 * (hydraulic[k] + hydraulic[k + 1])
            rod = np.array([force[i] - c * np.tanh(v_mid[i] / v_c) - b * v_mid[i] - m * xdd[i]
                            for i, (c, v_c, b, m) in enumerate(friction.values())])
            residuals.append((matrix @ qdd + rest - arm * rod) / arm)
            forces.append(force)
    forces_array = np.array(forces)
    return ArmResidual(np.array(residuals), np.sqrt(np.mean(forces_array**2, axis=0)))


def logged_periods(run) -> list[dict[str, np.ndarray]]:
    """The signals arm_residual reads, per period, from a run log read with
    orchestrator.runlog.read_run(path, topics=LOGGED_TOPICS)."""
    channels = run.channels
    out = []
    for k in range(1, len(run.periods) + 1):
        joints = channels["/joints"].of_period(k)
        lo, hi = np.searchsorted(channels["/joints"].period, [k, k + 1])
        signals: dict[str, np.ndarray] = {
            "t_s": channels["/joints"].log_time_ns[lo:hi] * 1e-9,
            "joints": np.column_stack([joints[f"measured_{j}_rad"] for j in JOINT_NAMES])}
        for joint in JOINT_NAMES:
            cylinder = channels[f"/cylinder/{joint}"].of_period(k)
            signals[f"{joint}.v"], signals[f"{joint}.F"] = cylinder["v_m_s"], cylinder["F_N"]
        bucket = channels["/pile/bucket"].of_period(k)
        signals["pile.bucket_mass"] = bucket["bucket_mass_kg"]
        signals["pile.F_y"], signals["pile.F_z"] = bucket["F_y_N"], bucket["F_z_N"]
        out.append(signals)
    return out


LOGGED_TOPICS = ("/joints", "/pile/bucket", *(f"/cylinder/{joint}" for joint in JOINT_NAMES))


def cylinder_parameters(scenario) -> dict[str, dict[str, float]]:
    """joint -> the cylinder FMU's parameters (its start values, then the scenario's) of a
    simulated scenario (orchestrator.scenario.Scenario)."""
    from orchestrator.plants.servo_setup import fmu_description, start_values

    specs = scenario.fmu_specs()
    return {joint: {**start_values(fmu_description(joint, specs[joint])),
                    **specs[joint].parameters} for joint in JOINT_NAMES}
