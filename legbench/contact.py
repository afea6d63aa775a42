"""The report's analytic contact law (LEG_SPEC.md section 4), on plain floats.

Used natively by the Pinocchio backend and, in ``reference`` contact mode, by
every backend as an external force at each of its sub-steps, so that the one
law is the same code everywhere.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

POC_MODES = ("true", "centre")
CONTACT_MODES = ("native", "reference")


@dataclass(frozen=True)
class ContactParams:
    """Ground contact parameters.

    Attributes:
        Kp: normal stiffness [N/m].
        Kd: normal damping, acting only while pressing in [N s/m].
        mu_s: static friction coefficient.
        mu_k: kinetic friction coefficient.
        v_th: stick-slip threshold speed [m/s].
        poc: ``"true"`` (the sphere's lowest point, default) or ``"centre"``
            (the report's simplification: the sphere centre's velocity).
    """

    Kp: float = 1.0e4
    Kd: float = 1.0e2
    mu_s: float = 0.7
    mu_k: float = 0.6
    v_th: float = 0.01
    poc: str = "true"


def friction_coefficient(v: float, p: ContactParams) -> float:
    """Continuous stick-slip friction coefficient mu(v) for a sliding speed v >= 0 [m/s]."""
    if v < p.v_th:
        return v * p.mu_s / p.v_th
    if v < 1.5 * p.v_th:
        return p.mu_s - (v - p.v_th) * (p.mu_s - p.mu_k) / (0.5 * p.v_th)
    return p.mu_k


def ground_force(y: float, ydot: float, vx: float, vy: float, p: ContactParams) -> tuple[float, float, float]:
    """Force of the ground on the foot in W [N].

    Args:
        y: penetration R_foot - z_E [m] (> 0 in contact).
        ydot: penetration rate [m/s] (> 0 pressing in), i.e. -vz of the poc.
        vx, vy: horizontal velocity of the point of contact in W [m/s].
        p: contact parameters.
    """
    if y <= 0.0:
        return 0.0, 0.0, 0.0
    fn = p.Kp * y + (p.Kd * ydot if ydot > 0.0 else 0.0)
    v = math.hypot(vx, vy)
    if v == 0.0:
        return 0.0, 0.0, fn
    ff = friction_coefficient(v, p) * fn / v
    return -ff * vx, -ff * vy, fn


class ReferenceContact:
    """The analytic law as a generalized force, from joint state through the closed-form kinematics.

    ``generalized(q, qd)`` returns tau_c = J_poc^T F [N m] and keeps F in W in
    :attr:`force`. Written on floats: it runs at every engine sub-step.
    """

    def __init__(self, params: ContactParams, L_B0: float, H: float, L_01: float, L_12: float,
                 L_23: float, L_3E: float, R_foot: float) -> None:  # fmt: skip
        self.p = params
        self.L_B0, self.H, self.L_01, self.L_12 = L_B0, H, L_01, L_12
        self.L_23, self.L_3E, self.R = L_23, L_3E, R_foot
        self.true_poc = params.poc == "true"
        self.force = np.zeros(3)
        self._tau = np.zeros(3)

    @classmethod
    def from_leg(cls, params: ContactParams) -> ReferenceContact:
        from legbench.model import load_params

        g = load_params().geometry
        return cls(params, g.L_B0, g.H, g.L_01, g.L_12, g.L_23, g.L_3E, g.R_foot)

    def generalized(self, q1: float, q2: float, q3: float, qd1: float, qd2: float, qd3: float) -> np.ndarray:
        """J_poc^T F [N m] for the joint state (q [rad], qd [rad/s])."""
        s1, c1 = math.sin(q1), math.cos(q1)
        s2, c2 = math.sin(q2), math.cos(q2)
        s23, c23 = math.sin(q2 + q3), math.cos(q2 + q3)
        reach = self.L_23 * s2 + self.L_3E * s23
        # foot centre height in W: z_W = x0 + H
        z = self.L_12 * s1 + c1 * reach + self.H
        y = self.R - z
        tau = self._tau
        if y <= 0.0:
            self.force[:] = 0.0
            tau[:] = 0.0
            return tau
        dr2 = self.L_23 * c2 + self.L_3E * c23
        dr3 = self.L_3E * c23
        # Jacobian of E in frame 0 (rows x0, y0, z0); W = (-y0, -z0, x0)
        jx = (self.L_12 * c1 - s1 * reach, c1 * dr2, c1 * dr3)
        jy = (self.L_12 * s1 + c1 * reach, s1 * dr2, s1 * dr3)
        jz = (0.0, reach, self.L_3E * s23)
        # rows of J in W
        Jx = (-jy[0], -jy[1], -jy[2])
        Jy = (-jz[0], -jz[1], -jz[2])
        Jz = jx
        if self.true_poc:
            # v_poc = v_E + omega x r with r = (0, 0, -R): adds (-R w_y, R w_x, 0).
            # Joint axes in W: joint 1 (0, -1, 0); joints 2, 3 (c1, 0, s1); so
            # w_x = c1 (qd2 + qd3), w_y = -qd1.
            R = self.R
            Jx = (Jx[0] + R, Jx[1], Jx[2])
            Jy = (Jy[0], Jy[1] + R * c1, Jy[2] + R * c1)
        vx = Jx[0] * qd1 + Jx[1] * qd2 + Jx[2] * qd3
        vy = Jy[0] * qd1 + Jy[1] * qd2 + Jy[2] * qd3
        vz = Jz[0] * qd1 + Jz[1] * qd2 + Jz[2] * qd3
        fx, fy, fz = ground_force(y, -vz, vx, vy, self.p)
        f = self.force
        f[0], f[1], f[2] = fx, fy, fz
        tau[0] = Jx[0] * fx + Jy[0] * fy + Jz[0] * fz
        tau[1] = Jx[1] * fx + Jy[1] * fy + Jz[1] * fz
        tau[2] = Jx[2] * fx + Jy[2] * fy + Jz[2] * fz
        return tau
