"""The arm's inertia in the coupling: the pose-dependent mass matrix M(q) and the velocity-product
(centrifugal and Coriolis) torques, per communication step, in scalar math.

The same model as plant_models.arm_inertia (point masses at the centres of mass plus a uniform
rod's m L^2 / 12; payload at the bucket's centre of mass), written for speed in the absolute
angles phi_k = q_0 + ... + q_(k-1) of the links. With e_k = (-cos phi_k, sin phi_k) along link k
and n_k = de_k/dphi_k = (sin phi_k, cos phi_k), link k's centre of mass is
pin_k + u_k e_k + v_k n_k, so its velocity is a sum of terms phi_k_dot * (vector):

    c1' = W1 G1,  c2' = W1 A1 + W2 G2,  c3' = W1 A1 + W2 A2 + W3 G3
    G_k = u_k n_k - v_k e_k,  A_k = l_k n_k   (W_k: the rate of phi_k)

and its acceleration adds the velocity products W_k^2 dG_k/dphi_k (dG/dphi = -u e - v n,
dA_k/dphi_k = -l_k e_k). In the absolute angles the mass matrix N has
N_ab = sum_links m (dc/dphi_a . dc/dphi_b) + I_a [a = b]; joint angles turn every later link,
phi = T q with T lower triangular ones, so M = T^T N T and joint torques are T^T of absolute ones.

How the coupling uses it (orchestrator.plants.native, coupling.c, which evaluates the same
formulas per step): each cylinder FMU integrates its own diagonal term, M_ii / r_i^2 reflected
onto the rod (its `mass_load` input, implicit in the FMU's substeps, so the stiff part stays
stable); the rest goes into F_ext: the velocity-product torques / r_i and the terms
-M_ij (dr_j/dq_j) qd_j^2 / (r_i r_j) (the stroke's acceleration is r qdd + (dr/dq) qd^2) from the
step's start, and the cross terms sum_{j != i} M_ij xdd_j / (r_i r_j) from the strokes'
accelerations over the step, iterated with the FMUs' state rollback until they agree (stick and
bucket are coupled by M_12 / sqrt(M_11 M_22) up to 0.7: fed back lagged, without iterating,
they diverged within the first period, the added-mass instability of explicit co-simulation).
Without rollback the cross terms use the planned accelerations. `at` evaluates the same model
in Python (the plant's start: the diagonal reflected masses; tests/test_arm_inertia.py checks
it against plant_models.arm_inertia).
"""

from __future__ import annotations

import math

from plant_models.geometry import ExcavatorGeometry


class ArmInertia:
    """Mass matrix and velocity-product torques of one arm geometry (see the module doc)."""

    def __init__(self, geometry: ExcavatorGeometry) -> None:
        links = (geometry.boom_mass, geometry.stick_mass, geometry.bucket_mass)
        self._masses = tuple(link.mass_kg for link in links)
        self._coms = tuple((float(link.com_m[0]), float(link.com_m[1])) for link in links)
        self._lengths = (geometry.boom_length_m, geometry.stick_length_m,
                         geometry.bucket_length_m)

    def at(self, q0: float, q1: float, q2: float, w0: float, w1: float, w2: float,
           payload_kg: float) -> tuple[float, ...]:
        """At joints q (rad) turning at w (rad/s) with payload_kg in the bucket: the mass
        matrix entries M00, M11, M22, M01, M02, M12 (kg m^2) and the velocity-product joint
        torques h0, h1, h2 (N m; M qdd + h is the torque the arm's inertia takes)."""
        p2 = q0 + q1
        p3 = p2 + q2
        return self._at(math.cos(q0), math.sin(q0), math.cos(p2), math.sin(p2), math.cos(p3),
                        math.sin(p3), w0, w1, w2, payload_kg)

    def at_pose(self, kinematics: tuple[float, ...], w0: float, w1: float, w2: float,
                payload_kg: float) -> tuple[float, ...]:
        """`at` from ArmCoupling.kinematics(...) (its link angles' cos and sin)."""
        c1, s1, c2, s2, c3, s3 = kinematics[24:30]
        return self._at(c1, s1, c2, s2, c3, s3, w0, w1, w2, payload_kg)

    def _at(self, c1: float, s1: float, c2: float, s2: float, c3: float, s3: float,
            w0: float, w1: float, w2: float, payload_kg: float) -> tuple[float, ...]:
        (m1, m2, m3), (l1, l2, l3) = self._masses, self._lengths
        m3 += payload_kg
        (u1, v1), (u2, v2), (u3, v3) = self._coms
        # e_k = (-c, s), n_k = (s, c).
        g1y, g1z = u1 * s1 + v1 * c1, u1 * c1 - v1 * s1
        g2y, g2z = u2 * s2 + v2 * c2, u2 * c2 - v2 * s2
        g3y, g3z = u3 * s3 + v3 * c3, u3 * c3 - v3 * s3
        a1y, a1z, a2y, a2z = l1 * s1, l1 * c1, l2 * s2, l2 * c2
        i1, i2, i3 = m1 * l1 * l1 / 12.0, m2 * l2 * l2 / 12.0, m3 * l3 * l3 / 12.0
        n11 = m1 * (g1y * g1y + g1z * g1z) + (m2 + m3) * (a1y * a1y + a1z * a1z) + i1
        n22 = m2 * (g2y * g2y + g2z * g2z) + m3 * (a2y * a2y + a2z * a2z) + i2
        n33 = m3 * (g3y * g3y + g3z * g3z) + i3
        n12 = m2 * (a1y * g2y + a1z * g2z) + m3 * (a1y * a2y + a1z * a2z)
        n13 = m3 * (a1y * g3y + a1z * g3z)
        n23 = m3 * (a2y * g3y + a2z * g3z)
        # Velocity products of each centre's acceleration: W^2 dG/dphi, dG/dphi = -u e - v n.
        w_1, w_2 = w0, w0 + w1
        w_3 = w_2 + w2
        k1, k2, k3 = w_1 * w_1, w_2 * w_2, w_3 * w_3
        h1y, h1z = u1 * c1 - v1 * s1, -u1 * s1 - v1 * c1
        h2y, h2z = u2 * c2 - v2 * s2, -u2 * s2 - v2 * c2
        h3y, h3z = u3 * c3 - v3 * s3, -u3 * s3 - v3 * c3
        b1y, b1z, b2y, b2z = l1 * c1, -l1 * s1, l2 * c2, -l2 * s2
        vp1y, vp1z = k1 * h1y, k1 * h1z
        vp2y, vp2z = k1 * b1y + k2 * h2y, k1 * b1z + k2 * h2z
        vp3y, vp3z = k1 * b1y + k2 * b2y + k3 * h3y, k1 * b1z + k2 * b2z + k3 * h3z
        e1 = (m1 * (g1y * vp1y + g1z * vp1z) + m2 * (a1y * vp2y + a1z * vp2z)
              + m3 * (a1y * vp3y + a1z * vp3z))
        e2 = m2 * (g2y * vp2y + g2z * vp2z) + m3 * (a2y * vp3y + a2z * vp3z)
        e3 = m3 * (g3y * vp3y + g3z * vp3z)
        # M = T^T N T: M_ij sums N_ab over a >= i, b >= j.
        return (n11 + n22 + n33 + 2.0 * (n12 + n13 + n23),  # M00
                n22 + 2.0 * n23 + n33,  # M11
                n33,  # M22
                n12 + n13 + n22 + 2.0 * n23 + n33,  # M01
                n13 + n23 + n33,  # M02
                n23 + n33,  # M12
                e1 + e2 + e3, e2 + e3, e3)
