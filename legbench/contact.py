"""The report's analytic contact law (docs/spec.md section 4), on plain floats.

Used natively by the backends that integrate the law themselves and, in ``reference`` contact mode, by
every backend as an external force at each of its sub-steps, so that the one
law is the same code everywhere.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from legbench import kinematics
from legbench.model import Dynamics, load_params, pinocchio_model

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
    v_th: float = 1.0e-3  # [m/s], docs/contact_law.md
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
    v = math.sqrt(vx * vx + vy * vy)  # not hypot: CPython's and the C library's differ in the last bit
    if v == 0.0:
        return 0.0, 0.0, fn
    ff = friction_coefficient(v, p) * fn / v
    return -ff * vx, -ff * vy, fn


def implicit_velocity_step(h: float, m: tuple[float, ...], K: tuple[float, ...], a1: float, a2: float,
                           a3: float) -> tuple[float, float, float]:  # fmt: skip
    """dqd [rad/s] of the linearly implicit friction step: (I + h M^-1 K) dqd = h a.

    Args:
        h: sub-step [s].
        m: M^-1 as (m11, m12, m13, m22, m23, m33) [1/(kg m^2)] (symmetric).
        K: the friction's joint-space slope as (K11, K12, K13, K22, K23, K33) [N m s/rad]
            (:meth:`ReferenceContact.wrench_slope`).
        a1, a2, a3: the explicit acceleration [rad/s^2].

    Plain floats, Cramer's rule (the 3x3 system is well conditioned: I plus a positive semi-definite
    product).
    """
    m11, m12, m13, m22, m23, m33 = m
    K11, K12, K13, K22, K23, K33 = K
    x1, x2, x3 = h * a1, h * a2, h * a3
    c11 = 1.0 + h * (m11 * K11 + m12 * K12 + m13 * K13)
    c12 = h * (m11 * K12 + m12 * K22 + m13 * K23)
    c13 = h * (m11 * K13 + m12 * K23 + m13 * K33)
    c21 = h * (m12 * K11 + m22 * K12 + m23 * K13)
    c22 = 1.0 + h * (m12 * K12 + m22 * K22 + m23 * K23)
    c23 = h * (m12 * K13 + m22 * K23 + m23 * K33)
    c31 = h * (m13 * K11 + m23 * K12 + m33 * K13)
    c32 = h * (m13 * K12 + m23 * K22 + m33 * K23)
    c33 = 1.0 + h * (m13 * K13 + m23 * K23 + m33 * K33)
    d1 = c22 * c33 - c23 * c32
    d2 = c21 * c33 - c23 * c31
    d3 = c21 * c32 - c22 * c31
    det = c11 * d1 - c12 * d2 + c13 * d3
    y1 = (x1 * d1 - c12 * (x2 * c33 - c23 * x3) + c13 * (x2 * c32 - c22 * x3)) / det
    y2 = (c11 * (x2 * c33 - c23 * x3) - x1 * d2 + c13 * (c21 * x3 - x2 * c31)) / det
    y3 = (c11 * (c22 * x3 - x2 * c32) - c12 * (c21 * x3 - x2 * c31) + x1 * d3) / det
    return y1, y2, y3


# The law on plain floats, one implementation: ReferenceContact calls these functions in Python, and the
# Pinocchio backend's compiled period compiles these same functions with numba (nothing but floats, tuples
# and math: both run the same IEEE operations in the same order, so they agree bit for bit).
#: The order of the law's constants ``c`` (:attr:`ReferenceContact.constants`).
LAW_CONSTANTS = ("L_12", "L_23", "L_3E", "H", "R_foot", "Kp", "Kd", "mu_s", "mu_k", "v_th", "v_slip", "mu_s - mu_k",
                 "v_th / 2", "true_poc")  # fmt: skip


def law_wrench(
    c: Sequence[float], q1: float, q2: float, q3: float, qd1: float, qd2: float, qd3: float
) -> tuple[float, ...]:
    """(tau_c1, tau_c2, tau_c3, fx, fy, fz): J_poc^T F [N m] and F in W [N] for q [rad], qd [rad/s].

    Plain floats in and out; out of contact, six zeros.
    """
    L_12, L_23, L_3E, H, R = c[0], c[1], c[2], c[3], c[4]
    s1, c1 = math.sin(q1), math.cos(q1)
    s2, c2 = math.sin(q2), math.cos(q2)
    s23, c23 = math.sin(q2 + q3), math.cos(q2 + q3)
    reach = L_23 * s2 + L_3E * s23
    # foot centre height in W: z_W = x0 + H
    y = R - (L_12 * s1 + c1 * reach + H)
    if y <= 0.0:
        return (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    dr2 = L_23 * c2 + L_3E * c23
    dr3 = L_3E * c23
    # Jacobian of E in frame 0 (rows x0, y0, z0); W = (-y0, -z0, x0). Rows of J in W:
    # Jx = -jy0 = -(L_12 s1 + c1 reach, s1 dr2, s1 dr3), Jy = -jz0 = -(0, reach, L_3E s23),
    # Jz = jx0 = (L_12 c1 - s1 reach, c1 dr2, c1 dr3)
    Jx1, Jx2, Jx3 = -(L_12 * s1 + c1 * reach), -(s1 * dr2), -(s1 * dr3)
    Jy1, Jy2, Jy3 = -0.0, -reach, -(L_3E * s23)
    Jz1, Jz2, Jz3 = L_12 * c1 - s1 * reach, c1 * dr2, c1 * dr3
    if c[13] != 0.0:
        # v_poc = v_E + omega x r with r = (0, 0, -R): adds (-R w_y, R w_x, 0).
        # Joint axes in W: joint 1 (0, -1, 0); joints 2, 3 (c1, 0, s1); so
        # w_x = c1 (qd2 + qd3), w_y = -qd1.
        Jx1 = Jx1 + R
        Jy2 = Jy2 + R * c1
        Jy3 = Jy3 + R * c1
    vx = Jx1 * qd1 + Jx2 * qd2 + Jx3 * qd3
    vy = Jy1 * qd1 + Jy2 * qd2 + Jy3 * qd3
    vz = Jz1 * qd1 + Jz2 * qd2 + Jz3 * qd3
    # ground_force(y, -vz, vx, vy, p), inlined
    Kp, Kd, mu_s, mu_k, v_th, v_slip, dmu, half_v_th = c[5], c[6], c[7], c[8], c[9], c[10], c[11], c[12]
    ydot = -vz
    fz = Kp * y + (Kd * ydot if ydot > 0.0 else 0.0)
    v = math.sqrt(vx * vx + vy * vy)  # not hypot: CPython's and the C library's differ in the last bit
    if v == 0.0:
        fx = fy = 0.0
    else:
        if v < v_th:
            mu = v * mu_s / v_th
        elif v < v_slip:
            mu = mu_s - (v - v_th) * dmu / half_v_th
        else:
            mu = mu_k
        ff = mu * fz / v
        fx, fy = -ff * vx, -ff * vy
    return (Jx1 * fx + Jy1 * fy + Jz1 * fz, Jx2 * fx + Jy2 * fy + Jz2 * fz, Jx3 * fx + Jy3 * fy + Jz3 * fz,
            fx, fy, fz)  # fmt: skip


def law_wrench_slope(
    c: Sequence[float], q1: float, q2: float, q3: float, qd1: float, qd2: float, qd3: float
) -> tuple[float, ...]:
    """:meth:`wrench` and the friction's damping in joint space, for a linearly implicit step.

    Returns (tau_c1, tau_c2, tau_c3, fx, fy, fz, K11, K12, K13, K22, K23, K33): the first six as
    :meth:`wrench`; K = -J_t^T (dF_t/dv_t) J_t [N m s/rad] (symmetric, positive semi-definite),
    the slope of the friction force F_t in W [N] with respect to the poc's horizontal velocity
    v_t [m/s], with Fn held, mapped through the poc's horizontal Jacobian rows J_t. With
    c_perp = Fn mu(v)/v across the slip and c_par = Fn max(mu'(v), 0) along it,
    -dF_t/dv_t = c_perp I + (c_par - c_perp) v v^T / v^2; below v_th both are Fn mu_s / v_th
    (the law is viscous there). The falling branch of mu (v_th..1.5 v_th) is left out of K
    (c_par >= 0): K only moves the implicit step's damping, never its fixed points.
    """
    L_12, L_23, L_3E, H, R = c[0], c[1], c[2], c[3], c[4]
    s1, c1 = math.sin(q1), math.cos(q1)
    s2, c2 = math.sin(q2), math.cos(q2)
    s23, c23 = math.sin(q2 + q3), math.cos(q2 + q3)
    reach = L_23 * s2 + L_3E * s23
    y = R - (L_12 * s1 + c1 * reach + H)
    if y <= 0.0:
        return (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    dr2 = L_23 * c2 + L_3E * c23
    dr3 = L_3E * c23
    Jx1, Jx2, Jx3 = -(L_12 * s1 + c1 * reach), -(s1 * dr2), -(s1 * dr3)
    Jy1, Jy2, Jy3 = -0.0, -reach, -(L_3E * s23)
    Jz1, Jz2, Jz3 = L_12 * c1 - s1 * reach, c1 * dr2, c1 * dr3
    if c[13] != 0.0:
        Jx1 = Jx1 + R
        Jy2 = Jy2 + R * c1
        Jy3 = Jy3 + R * c1
    vx = Jx1 * qd1 + Jx2 * qd2 + Jx3 * qd3
    vy = Jy1 * qd1 + Jy2 * qd2 + Jy3 * qd3
    vz = Jz1 * qd1 + Jz2 * qd2 + Jz3 * qd3
    Kp, Kd, mu_s, mu_k, v_th, v_slip, dmu, half_v_th = c[5], c[6], c[7], c[8], c[9], c[10], c[11], c[12]
    ydot = -vz
    fz = Kp * y + (Kd * ydot if ydot > 0.0 else 0.0)
    v = math.sqrt(vx * vx + vy * vy)  # not hypot: CPython's and the C library's differ in the last bit
    if v < v_th:
        c_perp = c_par = fz * mu_s / v_th
        ff = c_perp  # mu(v) fz / v
        dxx = dyy = c_perp
        dxy = 0.0
    else:
        if v < v_slip:
            mu = mu_s - (v - v_th) * dmu / half_v_th
        else:
            mu = mu_k
        ff = mu * fz / v
        c_perp, c_par = ff, 0.0
        ux, uy = vx / v, vy / v
        dc = c_par - c_perp
        dxx, dxy, dyy = c_perp + dc * ux * ux, dc * ux * uy, c_perp + dc * uy * uy
    fx, fy = -ff * vx, -ff * vy
    # K = J_t^T D J_t with D = [[dxx, dxy], [dxy, dyy]]
    ax1, ax2, ax3 = dxx * Jx1 + dxy * Jy1, dxx * Jx2 + dxy * Jy2, dxx * Jx3 + dxy * Jy3
    ay1, ay2, ay3 = dxy * Jx1 + dyy * Jy1, dxy * Jx2 + dyy * Jy2, dxy * Jx3 + dyy * Jy3
    return (Jx1 * fx + Jy1 * fy + Jz1 * fz, Jx2 * fx + Jy2 * fy + Jz2 * fz, Jx3 * fx + Jy3 * fy + Jz3 * fz,
            fx, fy, fz,
            Jx1 * ax1 + Jy1 * ay1, Jx1 * ax2 + Jy1 * ay2, Jx1 * ax3 + Jy1 * ay3,
            Jx2 * ax2 + Jy2 * ay2, Jx2 * ax3 + Jy2 * ay3, Jx3 * ax3 + Jy3 * ay3)  # fmt: skip


class ReferenceContact:
    """The analytic law as a generalized force, from joint state through the closed-form kinematics.

    :meth:`wrench` is the law on plain floats: tau_c = J_poc^T F [N m] and F in
    W [N], nothing allocated, every constant bound at construction (it runs at
    every engine sub-step). :meth:`generalized` is the same numbers in arrays:
    it returns tau_c and keeps F in :attr:`force`. Both give exactly the
    values of :func:`ground_force` applied through the kinematics below.
    """

    def __init__(self, params: ContactParams, L_B0: float, H: float, L_01: float, L_12: float,
                 L_23: float, L_3E: float, R_foot: float) -> None:  # fmt: skip
        self.p = params
        self.L_B0, self.H, self.L_01, self.L_12 = L_B0, H, L_01, L_12
        self.L_23, self.L_3E, self.R = L_23, L_3E, R_foot
        self.true_poc = params.poc == "true"
        self.force = np.zeros(3)
        self._tau = np.zeros(3)
        # the geometry, the law's constants and the terms friction_coefficient() and ground_force() compute
        # from p at each call, as one tuple of floats: LAW_CONSTANTS, what law_wrench() and law_wrench_slope() take
        v_th = float(params.v_th)
        self.constants = (float(L_12), float(L_23), float(L_3E), float(H), float(R_foot),
                          float(params.Kp), float(params.Kd), float(params.mu_s), float(params.mu_k), v_th,
                          1.5 * v_th, float(params.mu_s) - float(params.mu_k), 0.5 * v_th,
                          1.0 if self.true_poc else 0.0)  # fmt: skip

    @classmethod
    def from_leg(cls, params: ContactParams, implicit_friction_gravity: float | None = None) -> ReferenceContact:
        """The law on the leg of ``models/leg.yaml``; with ``implicit_friction_gravity`` [m/s^2] also
        prepared for :meth:`implicit_generalized` (:meth:`use_implicit_friction`)."""
        g = load_params().geometry
        law = cls(params, g.L_B0, g.H, g.L_01, g.L_12, g.L_23, g.L_3E, g.R_foot)
        if implicit_friction_gravity is not None:
            law.use_implicit_friction(implicit_friction_gravity)
        return law

    def wrench(self, q1: float, q2: float, q3: float, qd1: float, qd2: float, qd3: float) -> tuple[float, ...]:
        """(tau_c1, tau_c2, tau_c3, fx, fy, fz): J_poc^T F [N m] and F in W [N] for q [rad], qd [rad/s]
        (:func:`law_wrench` on this law's :attr:`constants`); out of contact, six zeros."""
        return law_wrench(self.constants, q1, q2, q3, qd1, qd2, qd3)

    def wrench_slope(self, q1: float, q2: float, q3: float, qd1: float, qd2: float, qd3: float) -> tuple[float, ...]:
        """:meth:`wrench` and the friction's slope K in joint space (:func:`law_wrench_slope`)."""
        return law_wrench_slope(self.constants, q1, q2, q3, qd1, qd2, qd3)

    def use_implicit_friction(self, gravity: float) -> None:
        """Prepare :meth:`implicit_generalized`: the leg's Pinocchio model under gravity [m/s^2] along -z_W."""
        self._pin = pin
        self._model = pinocchio_model(gravity=gravity)
        self._data = self._model.createData()
        self._qp = np.zeros(self._model.nq)
        self._v = np.zeros(3)
        self._u = np.zeros(3)

    def implicit_generalized(self, q1: float, q2: float, q3: float, qd1: float, qd2: float, qd3: float,
                             u1: float, u2: float, u3: float, h: float) -> np.ndarray:  # fmt: skip
        """The law's generalized force for a step of ``h`` [s] with the friction slope treated implicitly.

        For an engine that applies the law as an external torque in reference mode: with u the
        other applied joint torques [N m], a = M^-1 (u + J_poc^T F - nle) the explicit acceleration
        (the leg's model, the engine's own constraint forces left out) and dqd from
        :func:`implicit_velocity_step`, the torque J_poc^T F - K dqd makes the engine's explicit
        step take the linearly implicit friction step documented in docs/pinocchio.md, with M^-1 at
        this sub-step's state (the Pinocchio backend holds its period's first M^-1 in contact; on the
        effort task the two differ by 4.6e-8 rad at most).
        Out of contact or with no friction slope it is :meth:`generalized`. F in W [N] (the law at
        the state) goes to :attr:`force`; the returned array is reused by the next call. Call
        :meth:`use_implicit_friction` first.
        """
        # Python floats from here on: an engine's numpy scalars would make every operation of the law and
        # the step below a numpy one (the same IEEE result, several times the cost)
        q1, q2, q3, qd1, qd2, qd3 = float(q1), float(q2), float(q3), float(qd1), float(qd2), float(qd3)
        u1, u2, u3, h = float(u1), float(u2), float(u3), float(h)
        r = law_wrench_slope(self.constants, q1, q2, q3, qd1, qd2, qd3)
        tc1, tc2, tc3, fx, fy, fz, K11, K12, K13, K22, K23, K33 = r
        f, tau = self.force, self._tau
        f[0], f[1], f[2] = fx, fy, fz
        if K11 != 0.0 or K22 != 0.0 or K33 != 0.0:
            pin, model, data, qp, v, u = self._pin, self._model, self._data, self._qp, self._v, self._u
            qp[0], qp[1], qp[2], qp[3] = q1, math.cos(q2), math.sin(q2), q3
            v[0], v[1], v[2] = qd1, qd2, qd3
            u[0], u[1], u[2] = u1 + tc1, u2 + tc2, u3 + tc3
            a1, a2, a3 = pin.aba(model, data, qp, v, u).tolist()
            (m11, m12, m13), (_, m22, m23), (_, _, m33) = pin.computeMinverse(model, data, qp).tolist()
            m = (m11, m12, m13, m22, m23, m33)
            x1, x2, x3 = implicit_velocity_step(h, m, (K11, K12, K13, K22, K23, K33), a1, a2, a3)
            tc1 -= K11 * x1 + K12 * x2 + K13 * x3
            tc2 -= K12 * x1 + K22 * x2 + K23 * x3
            tc3 -= K13 * x1 + K23 * x2 + K33 * x3
        tau[0], tau[1], tau[2] = tc1, tc2, tc3
        return tau

    def generalized(self, q1: float, q2: float, q3: float, qd1: float, qd2: float, qd3: float) -> np.ndarray:
        """J_poc^T F [N m] for the joint state (q [rad], qd [rad/s]); F in W [N] goes to :attr:`force`.

        The returned array is reused by the next call.
        """
        t1, t2, t3, fx, fy, fz = self.wrench(q1, q2, q3, qd1, qd2, qd3)
        f, tau = self.force, self._tau
        f[0], f[1], f[2] = fx, fy, fz
        tau[0], tau[1], tau[2] = t1, t2, t3
        return tau


def tangential_mass(q: tuple[float, float, float] | list[float] | np.ndarray, true_poc: bool = True) -> float:
    """Smallest apparent mass of the leg at its point of contact along the ground [kg].

    1 / lambda_max(J_t M(q)^-1 J_t^T), J_t the two horizontal rows of J_poc(q), M the leg's mass
    matrix (Pinocchio on the generated URDF), at joint angles q [rad].
    """
    qv = np.array([float(x) for x in q])
    M = Dynamics().mass_matrix(qv)
    J_t = kinematics.jacobian_poc(qv, true_poc=true_poc)[:2]
    return float(1.0 / np.linalg.eigvalsh(J_t @ np.linalg.solve(M, J_t.T)).max())


#: Stability factors x of explicit steps for the viscous friction below v_th (h c / m <= x, c = mu_s Fn / v_th,
#: m the apparent mass): semi-implicit Euler's non-oscillating bound h < m / c (it is stable to 2 m / c, but
#: its step factor 1 - h c / m turns negative past m / c: the friction then flips sign every step), and
#: classical RK4's stability interval on the negative real axis, |1 - x + x^2/2 - x^3/6 + x^4/24| <= 1 for
#: x <= 2.7853 (its step factor is positive for every real x, so there it never flips sign before it is unstable).
EULER_FRICTION_STABILITY = 1.0
RK4_FRICTION_STABILITY = 2.785293563405282


def friction_step_bound(fn: float, q: tuple[float, float, float] | list[float] | np.ndarray, p: ContactParams,
                        stability: float = EULER_FRICTION_STABILITY) -> float:  # fmt: skip
    """Largest explicit sub-step [s] that resolves the stick-slip law's slope: ``stability`` m v_th / (mu_s Fn).

    Below v_th the law is a viscous friction of coefficient c = mu_s Fn / v_th [N s/m] on the apparent mass m
    [kg] (:func:`tangential_mass` at q [rad]; Fn [N] the normal force): an explicit step h resolves it for
    h c / m <= ``stability``. The default, :data:`EULER_FRICTION_STABILITY` = 1, is semi-implicit Euler's
    non-oscillating bound h < m / c (stable to 2 m / c); :data:`RK4_FRICTION_STABILITY` = 2.785 is RK4's
    stability interval (2.785 / 2 of Euler's stable bound 2 m / c).
    """
    if fn <= 0.0:
        return math.inf
    return stability * tangential_mass(q, p.poc == "true") * p.v_th / (p.mu_s * fn)


def law_step_warnings(backend: str, h: float, fn_peak: float, q_peak: list[float], p: ContactParams,
                      stability: float = EULER_FRICTION_STABILITY) -> list[str]:  # fmt: skip
    """The warning a backend that applies the law explicitly every sub-step ``h`` [s] gives, or none.

    Args:
        backend: backend name, for the message.
        h: sub-step [s].
        fn_peak: largest normal force of the run [N]; q_peak: joint angles there [rad].
        p: contact parameters.
        stability: the integrator's stability factor (:func:`friction_step_bound`): the default is
            semi-implicit Euler's bound m v_th / (mu_s Fn), :data:`RK4_FRICTION_STABILITY` RK4's.
    """
    bound = friction_step_bound(fn_peak, q_peak, p, stability)
    if h <= bound:
        return []
    m = tangential_mass(q_peak, p.poc == "true")
    factor = "" if stability == EULER_FRICTION_STABILITY else f"{stability:.4g} "
    factor_x = "" if stability == EULER_FRICTION_STABILITY else f"{stability:.4g} x "
    return [
        f"{backend}: sub-step {h:.3g} s is too coarse for the stick-slip law: h > {factor}m v_th / (mu_s Fn) = "
        f"{factor_x}{m:.3g} kg x {p.v_th:.3g} m/s / ({p.mu_s:g} x {fn_peak:.3g} N) = {bound:.3g} s; the friction "
        f"chatters (use a sub-step <= {bound:.2g} s, or the implicit friction step where the backend has one)"
    ]


#: A friction force that reverses between consecutive control ticks (turning by more than 120 deg, both ticks'
#: |F_t| above half of mu_k Fn) and reverses again within two ticks, on at least this many ticks and this share of
#: the ticks in contact, is chatter (:func:`friction_chatter`): a slide rubbed back and forth reverses once per half
#: period (every 5 ticks even at 100 Hz), and the 84 task runs of `make compare` reverse at most once (the combined
#: task's swing); the law stepped too coarsely for its slope did so at 308 of 3000 ticks.
CHATTER_TICKS = 10
CHATTER_SHARE = 0.01


def friction_chatter(backend: str, t: np.ndarray, force: np.ndarray, p: ContactParams) -> list[str]:
    """The warning of a run whose friction chatters, read from its log at the control ticks, or none.

    Any contact's friction (the law's or an engine's) that is resolved turns smoothly from tick to tick, and a
    slide that changes direction reverses it once; one that flips sign every step of a too coarse integrator
    reverses and reverses back within a tick or two, over and over, each tick near the friction bound, so the
    run's forces and creep are the step's, not the physics' (the law stepped at 50 us with v_th = 1e-5 m/s, whose
    implicit step no bound covers: Fx, Fy spread by 22 N where they hold to 1e-4 N).

    Args:
        backend: backend name, for the message.
        t: tick times [s] (n,).
        force: ground force on the foot in W [N] (n, 3).
        p: contact parameters (mu_k: the bound the test takes half of).
    """
    if p.mu_k <= 0.0 or len(t) < 3:
        return []
    ft, fn = force[:, :2], force[:, 2]
    mag = np.hypot(ft[:, 0], ft[:, 1])
    touching = fn > 0.5
    engaged = touching & (mag > 0.5 * p.mu_k * fn)  # in contact, the friction well within reach of its bound
    both = engaged[:-1] & engaged[1:]
    turned = (ft[:-1] * ft[1:]).sum(axis=1) < -0.5 * mag[:-1] * mag[1:]  # cos < -1/2: by more than 120 deg
    flips = np.flatnonzero(both & turned)
    back = flips[:-1][np.diff(flips) <= 2]  # reversals reversed again within two ticks
    in_contact = int(np.count_nonzero(touching))
    if len(back) < CHATTER_TICKS or len(back) < CHATTER_SHARE * in_contact:
        return []
    return [
        f"{backend}: the friction chatters: it reverses and reverses back within two control ticks at {len(back)} "
        f"of {in_contact} ticks in contact, from t = {t[back[0] + 1]:.3f} s, each near its bound; the forces and the "
        "creep there are the step's, not the contact's (a step too coarse for the friction: for the law, a finer "
        "sub-step or a larger v_th)"
    ]
