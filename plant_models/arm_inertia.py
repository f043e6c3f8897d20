"""The arm's mass matrix: kinetic energy T = q_dot^T M(q) q_dot / 2 of boom, stick and bucket.

Links are point masses at their centres of mass plus a uniform rod's m L^2 / 12 about it (L the
link's pin-to-pin length; plant_models.hydraulics.link_inertia_diagonal is the same model's
diagonal); the payload sits at the bucket's centre of mass. A joint turns every link after it,
so the centre of mass c of a link after joint j moves by rot(c - pin_j) dq_j, rot(y, z) = (z, -y)
(plant_models.geometry), and the link turns by the sum of the joint rates up to it:

    M(q) = sum_links m J_c^T J_c + I e e^T,  J_c (2, 3): column j = rot(c - pin_j) for joints
    j up to the link, else 0; e (3,): 1 for those joints, else 0.

This is the reference the coupling's per-step scalar version (orchestrator.plants.arm_coupling)
is tested against, and the tests check it against a finite difference of the kinetic energy.
"""

from __future__ import annotations

import numpy as np

from plant_models.geometry import ExcavatorGeometry, arm_points

_PINS = ("boom_foot", "stick_pin", "bucket_pin")


def _links(geometry: ExcavatorGeometry, payload_kg: float):
    return (("boom_com", geometry.boom_mass.mass_kg, geometry.boom_length_m),
            ("stick_com", geometry.stick_mass.mass_kg, geometry.stick_length_m),
            ("bucket_com", geometry.bucket_mass.mass_kg + payload_kg, geometry.bucket_length_m))


def mass_matrix(geometry: ExcavatorGeometry, joints, payload_kg: float = 0.0) -> np.ndarray:
    """M(q) (3, 3) kg m^2 at joints (3,) rad (boom, stick, bucket), payload_kg in the bucket."""
    points = arm_points(geometry, joints)
    matrix = np.zeros((3, 3))
    for index, (com, mass, length) in enumerate(_links(geometry, payload_kg)):
        jacobian = np.zeros((2, 3))
        for j in range(index + 1):
            offset = points[com] - points[_PINS[j]]
            jacobian[:, j] = (offset[1], -offset[0])
        turns = np.array([1.0 if j <= index else 0.0 for j in range(3)])
        matrix += mass * jacobian.T @ jacobian + mass * length * length / 12.0 * np.outer(
            turns, turns)
    return matrix


def kinetic_energy(geometry: ExcavatorGeometry, joints, rates, payload_kg: float = 0.0
                   ) -> float:
    """T (J) at joints (3,) rad turning at rates (3,) rad/s."""
    rates = np.asarray(rates, dtype=float)
    return 0.5 * float(rates @ mass_matrix(geometry, joints, payload_kg) @ rates)
