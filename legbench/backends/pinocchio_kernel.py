"""The Pinocchio backend's control period in one compiled call (numba): ABA, the contact law, the joint limits.

Part of the Pinocchio backend (:mod:`legbench.backends.pinocchio_`), which keeps its Python path as the
reference. The model crosses as plain numbers read from the ``pin.Model`` at load (:func:`model_arrays`):
per joint its placement in the parent joint's frame (R, p) and its body's spatial inertia, and gravity.
The kernel knows one kind of joint, a revolute joint about its own z axis (Pinocchio's ``JointModelRZ``
and ``JointModelRUBZ``, the continuous hip: the same motion, only the configuration is stored as
cos/sin), and refuses a model with any other (:class:`KernelUnavailable`).

* :func:`aba` is Featherstone's articulated-body algorithm in the joint frames, the algorithm of
  ``pinocchio::aba`` (motion vectors linear part first, as Pinocchio): forward pass for the velocities
  and bias terms, backward pass for the articulated inertias, forward pass for the accelerations.
  It agrees with ``pin.aba`` to round-off (tests/test_backend_pinocchio.py), not bit for bit: the
  operations are the same algorithm, not the same order.
* :func:`wrench`, :func:`wrench_slope`, :func:`implicit_velocity_step` and :func:`limit_torques` are
  :func:`legbench.contact.law_wrench`, :func:`~legbench.contact.law_wrench_slope`,
  :func:`~legbench.contact.implicit_velocity_step` and :func:`legbench.backends.joint_limits.limit_torques`
  themselves, compiled: one implementation, so the same IEEE operations in the same order (numba without
  ``fastmath``; ``math.sin``/``cos``/``sqrt`` are the C library's, as in Python; the law takes a slip speed
  as ``sqrt(vx * vx + vy * vy)``, not ``math.hypot``, whose CPython and C library versions differ in the
  last bit for about 0.6 % of arguments).
* :func:`dopri_period` is the adaptive ``rk45`` solve of a control period: the Dormand-Prince stepper of
  :mod:`legbench.backends.dopri` (scipy's RK45 step for step) over :func:`_dopri_rhs` (the law, the limits and
  ABA: :meth:`PinocchioBackend._qdd` compiled), where the Python path calls ``scipy.integrate.solve_ivp``.
* :func:`period` is :meth:`PinocchioBackend._euler_implicit` (:data:`EULER_IMPLICIT`: the friction's slope
  linearly implicit, M^-1 frozen over the period at its first sub-step in contact), ``_euler``
  (:data:`EULER`) or ``_rk4`` (:data:`RK4`). It also keeps the joint-limit record the backend's step-bound
  warning reads (:func:`_record_limits`, :func:`limit_record`): per joint the largest (M^-1)_jj at which it
  was past its limit, one M^-1 per period and joint past its limit, three comparisons per sub-step inside.
* :func:`period_loop` is :func:`period` over a whole run's logged torques in one compiled call, from the run's
  initial state: ``legbench bench``'s compiled floor for this backend (its end state is the run's, bit for bit).

Units: q [rad], qd [rad/s], tau [N m], F in W [N], h [s].
"""

from __future__ import annotations

import functools
import math
from typing import Any

import numpy as np

from legbench import contact, jit
from legbench.backends import dopri, joint_limits

try:
    import numba
except ImportError:  # the backend runs its Python path and says so
    numba = None  # type: ignore[assignment]

__all__ = [
    "EULER",
    "EULER_IMPLICIT",
    "RK4",
    "KernelUnavailable",
    "aba",
    "available",
    "dopri_data",
    "dopri_period",
    "limit_record",
    "minverse",
    "model_arrays",
    "period",
    "period_loop",
    "wrench",
    "wrench_slope",
]

#: :func:`period`'s integrators: semi-implicit Euler (friction explicit), the same with the friction slope
#: linearly implicit, classical Runge-Kutta 4.
EULER, EULER_IMPLICIT, RK4 = 0, 1, 2
#: The joint types the kernel integrates (all: revolute about the joint frame's z axis).
JOINT_TYPES = ("JointModelRZ", "JointModelRUBZ")


class KernelUnavailable(Exception):
    """The compiled kernel cannot run this model (or numba is missing): the Python path runs instead."""


def available() -> bool:
    """numba is installed."""
    return numba is not None


def model_arrays(model: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The numbers the kernel needs from a ``pin.Model`` of a serial chain of z-revolute joints.

    Returns:
        R (n, 3, 3) and p (n, 3): joint i's placement in its parent joint's frame at q = 0 [1, m];
        inertia (n, 6, 6): body i's spatial inertia in its joint frame, motion ordered (v, w)
        [kg, kg m, kg m^2]; a0 (6,): the root's spatial acceleration standing for gravity, -g [m/s^2].
    """
    n = model.njoints - 1
    names = [model.joints[i].shortname() for i in range(1, n + 1)]
    bad = [f"{model.names[i + 1]} ({t})" for i, t in enumerate(names) if t not in JOINT_TYPES]
    if bad:
        raise KernelUnavailable(f"joints the compiled kernel does not integrate: {', '.join(bad)}")
    if list(model.parents)[1:] != list(range(n)):
        raise KernelUnavailable("the model is not a serial chain")
    if np.any(np.asarray(model.armature, dtype=float) != 0.0):  # pin.aba adds it to each joint's D; the kernel does not
        raise KernelUnavailable(f"the model has rotor inertia (armature {np.asarray(model.armature).tolist()})")
    R = np.empty((n, 3, 3))
    p = np.empty((n, 3))
    inertia = np.empty((n, 6, 6))
    for i in range(n):
        placement = model.jointPlacements[i + 1]
        R[i] = placement.rotation
        p[i] = placement.translation
        inertia[i] = model.inertias[i + 1].matrix()
    a0 = np.zeros(6)
    a0[:3] = -np.asarray(model.gravity.linear, dtype=float)
    return R, p, inertia, a0


def _njit(fn: Any) -> Any:
    """Compiled, its cache stamped with the law modules compiled in (:func:`legbench.jit.njit`)."""
    return jit.njit(fn, depends_on=(contact, joint_limits))


# --------------------------------------------------------------------------- #
# Spatial algebra on (6,) motion / force vectors, linear part first


@_njit
def aba(
    R: np.ndarray,
    p: np.ndarray,
    inertia: np.ndarray,
    a0: np.ndarray,
    q: np.ndarray,
    qd: np.ndarray,
    tau: np.ndarray,
    qdd: np.ndarray,
    work: np.ndarray,
    tmp: np.ndarray,
) -> None:
    """qdd = ABA(q, qd, tau) [rad/s^2] for a chain of z-revolute joints (:func:`model_arrays`).

    Scratch space, nothing allocated: ``work`` (n, 6, 16), per joint the rows of X_i (columns 0-5,
    motion vectors parent -> joint frame), the articulated inertia IA_i (6-11), v_i (12), c_i (13),
    pA_i (14), U_i (15); ``tmp`` (6, 16). Indexed directly (no array views in the loops).
    """
    n = q.shape[0]
    for i in range(n):  # forward: transforms, velocities, bias accelerations and forces
        cq, sq = math.cos(q[i]), math.sin(q[i])
        # E = (R Rz(q))^T: rows Rz^T R^T; X = [[E, -E [p]x], [0, E]]
        for k in range(3):
            e0 = cq * R[i, k, 0] + sq * R[i, k, 1]
            e1 = -sq * R[i, k, 0] + cq * R[i, k, 1]
            e2 = R[i, k, 2]
            work[i, 0, k] = e0
            work[i, 1, k] = e1
            work[i, 2, k] = e2
            work[i, 3, k + 3] = e0
            work[i, 4, k + 3] = e1
            work[i, 5, k + 3] = e2
            work[i, 3, k] = 0.0
            work[i, 4, k] = 0.0
            work[i, 5, k] = 0.0
        p0, p1, p2 = p[i, 0], p[i, 1], p[i, 2]
        for r in range(3):
            e0, e1, e2 = work[i, r, 0], work[i, r, 1], work[i, r, 2]
            work[i, r, 3] = -(e1 * p2 - e2 * p1)
            work[i, r, 4] = -(-e0 * p2 + e2 * p0)
            work[i, r, 5] = -(e0 * p1 - e1 * p0)
        if i == 0:
            for r in range(6):
                work[i, r, 12] = 0.0
        else:
            for r in range(6):
                acc = 0.0
                for k in range(6):
                    acc += work[i, r, k] * work[i - 1, k, 12]
                work[i, r, 12] = acc
        w = qd[i]
        work[i, 5, 12] += w
        vx, vy, vz = work[i, 0, 12], work[i, 1, 12], work[i, 2, 12]
        wx, wy, wz = work[i, 3, 12], work[i, 4, 12], work[i, 5, 12]
        # c = v x (S qd), S qd = (0, 0, 0, 0, 0, qd)
        work[i, 0, 13] = vy * w
        work[i, 1, 13] = -vx * w
        work[i, 2, 13] = 0.0
        work[i, 3, 13] = wy * w
        work[i, 4, 13] = -wx * w
        work[i, 5, 13] = 0.0
        for r in range(6):
            acc = 0.0
            for k in range(6):
                ib = inertia[i, r, k]
                work[i, r, 6 + k] = ib
                acc += ib * work[i, k, 12]
            tmp[r, 0] = acc  # f = I v
        f0, f1, f2, f3, f4, f5 = tmp[0, 0], tmp[1, 0], tmp[2, 0], tmp[3, 0], tmp[4, 0], tmp[5, 0]
        # pA = v x* f = [w x f_lin ; v_lin x f_lin + w x f_ang]
        work[i, 0, 14] = wy * f2 - wz * f1
        work[i, 1, 14] = wz * f0 - wx * f2
        work[i, 2, 14] = wx * f1 - wy * f0
        work[i, 3, 14] = vy * f2 - vz * f1 + wy * f5 - wz * f4
        work[i, 4, 14] = vz * f0 - vx * f2 + wz * f3 - wx * f5
        work[i, 5, 14] = vx * f1 - vy * f0 + wx * f4 - wy * f3
    for i in range(n - 1, -1, -1):  # backward: articulated inertias and bias forces
        for r in range(6):
            work[i, r, 15] = work[i, r, 11]  # U = IA S, S = e_5
        D = work[i, 5, 15]
        u = tau[i] - work[i, 5, 14]
        qdd[i] = u  # kept for the last pass
        if i == 0:
            continue
        # Ia = IA - U U^T / D (tmp cols 4-9); pa = pA + Ia c + U u / D (tmp col 1)
        for r in range(6):
            ur = work[i, r, 15]
            for k in range(6):
                tmp[r, 4 + k] = work[i, r, 6 + k] - ur * work[i, k, 15] / D
        for r in range(6):
            acc = 0.0
            for k in range(6):
                acc += tmp[r, 4 + k] * work[i, k, 13]
            tmp[r, 1] = work[i, r, 14] + acc + work[i, r, 15] * u / D
        # T = Ia X (tmp cols 10-15); IAp += X^T T; pAp += X^T pa
        for r in range(6):
            for k in range(6):
                acc = 0.0
                for m in range(6):
                    acc += tmp[r, 4 + m] * work[i, m, k]
                tmp[r, 10 + k] = acc
        for r in range(6):
            for k in range(6):
                acc = 0.0
                for m in range(6):
                    acc += work[i, m, r] * tmp[m, 10 + k]
                work[i - 1, r, 6 + k] += acc
            acc = 0.0
            for m in range(6):
                acc += work[i, m, r] * tmp[m, 1]
            work[i - 1, r, 14] += acc
    for r in range(6):  # forward: accelerations (a_parent in tmp col 3, a in col 2)
        tmp[r, 3] = a0[r]
    for i in range(n):
        for r in range(6):
            acc = 0.0
            for k in range(6):
                acc += work[i, r, k] * tmp[k, 3]
            tmp[r, 2] = acc + work[i, r, 13]
        ua = 0.0
        for r in range(6):
            ua += work[i, r, 15] * tmp[r, 2]
        qdd_i = (qdd[i] - ua) / work[i, 5, 15]
        qdd[i] = qdd_i
        tmp[5, 2] += qdd_i
        for r in range(6):
            tmp[r, 3] = tmp[r, 2]


# --------------------------------------------------------------------------- #
# The contact law, its slope, the implicit friction step and the joint limits: the Python functions of
# legbench.contact and joint_limits themselves, compiled (one implementation, run two ways)

wrench = _njit(contact.law_wrench)
wrench_slope = _njit(contact.law_wrench_slope)
implicit_velocity_step = _njit(contact.implicit_velocity_step)
limit_torques = _njit(joint_limits.limit_torques)


# --------------------------------------------------------------------------- #
# One control period


@_njit
def minverse_factored(work: np.ndarray, tmp: np.ndarray, out: np.ndarray) -> None:
    """M(q)^-1 [1/(kg m^2)] into ``out`` (n, n) from the factorization the last :func:`aba` call left in
    ``work`` (its transforms X_i, articulated inertias and U_i = IA_i S depend on q only): column j is ABA's
    second and third pass for the torque e_j with no velocity and no gravity, which is what a whole ABA
    call would compute, without the first pass and the articulated inertias again (as Pinocchio's
    ``computeMinverse(model, data)`` reuses them after an ``aba`` in the WORLD convention). ``tmp`` rows 0-5
    and columns 0-3 are scratch."""
    n = work.shape[0]
    for j in range(n):
        # backward: the bias forces of the children, per joint in work column 14 (pA is not needed again)
        for i in range(n):
            for r in range(6):
                work[i, r, 14] = 0.0
        for i in range(n - 1, -1, -1):
            D = work[i, 5, 15]
            u = (1.0 if i == j else 0.0) - work[i, 5, 14]
            out[i, j] = u  # kept for the forward pass
            if i == 0:
                continue
            for r in range(6):
                tmp[r, 1] = work[i, r, 14] + work[i, r, 15] * u / D
            for r in range(6):
                acc = 0.0
                for m in range(6):
                    acc += work[i, m, r] * tmp[m, 1]
                work[i - 1, r, 14] += acc
        for r in range(6):  # forward: accelerations from rest, no gravity
            tmp[r, 3] = 0.0
        for i in range(n):
            for r in range(6):
                acc = 0.0
                for k in range(6):
                    acc += work[i, r, k] * tmp[k, 3]
                tmp[r, 2] = acc
            ua = 0.0
            for r in range(6):
                ua += work[i, r, 15] * tmp[r, 2]
            qdd_i = (out[i, j] - ua) / work[i, 5, 15]
            out[i, j] = qdd_i
            tmp[5, 2] += qdd_i
            for r in range(6):
                tmp[r, 3] = tmp[r, 2]


@_njit
def minverse(R: np.ndarray, p: np.ndarray, inertia: np.ndarray, q: np.ndarray, out: np.ndarray,
             work: np.ndarray, tmp: np.ndarray, buf: np.ndarray) -> None:  # fmt: skip
    """M(q)^-1 [1/(kg m^2)] at q into ``out`` (n, n): one :func:`aba` at q (for its factorization), then
    :func:`minverse_factored`."""
    n = q.shape[0]
    zero6 = buf[0:6]
    zeros = buf[6 : 6 + n]
    col = buf[6 + n : 6 + 2 * n]
    for r in range(6):
        zero6[r] = 0.0
    for j in range(n):
        zeros[j] = 0.0
    aba(R, p, inertia, zero6, q, zeros, zeros, col, work, tmp)
    minverse_factored(work, tmp, out)


@_njit
def _record_limits(rec: np.ndarray, mi: np.ndarray, tl1: float, tl2: float, tl3: float, seen1: bool, seen2: bool,
                   seen3: bool) -> tuple[bool, bool, bool]:  # fmt: skip
    """Record in ``rec`` (3,) the largest (M^-1)_jj [1/(kg m^2)] at which joint j was past its limit (its limit
    torque tl_j [N m] non-zero); ``mi``: M^-1 at that state. 0 in ``rec`` = the joint never reached its limit.
    The backend's :meth:`~legbench.backends.pinocchio_.PinocchioBackend.warnings` turns it into the limit
    spring-damper's step bound (:func:`legbench.backends.joint_limits.step_bound`, I = 1 / (M^-1)_jj). Called
    at most once per joint and period (``seen``: recorded already), so a joint resting at its limit costs one
    M^-1 per period, and a period inside the limits only the three comparisons before the call."""
    if tl1 != 0.0:
        rec[0] = max(rec[0], mi[0, 0])
        seen1 = True
    if tl2 != 0.0:
        rec[1] = max(rec[1], mi[1, 1])
        seen2 = True
    if tl3 != 0.0:
        rec[2] = max(rec[2], mi[2, 2])
        seen3 = True
    return seen1, seen2, seen3


@_njit
def _period_arrays(R: np.ndarray, p: np.ndarray, inertia: np.ndarray, a0: np.ndarray, lc: np.ndarray, lim: np.ndarray,
           h: float, n_sub: int, implicit: bool, u: np.ndarray, x: np.ndarray, work: np.ndarray,
           tmp: np.ndarray, buf: np.ndarray, rec: np.ndarray) -> None:  # fmt: skip
    """``n_sub`` semi-implicit Euler sub-steps of ``h`` [s] under the held torque u [N m].

    ``u``: the torque row as the run loop hands it (read, never written). ``x`` = (q1, q2, q3, qd1, qd2, qd3,
    fx, fy, fz) in and out: the state, then the law's F in W [N] at the
    end state (the backend's force read-out). ``implicit``: the friction slope linearly implicit with M^-1
    at the period's first sub-step in contact (:meth:`PinocchioBackend._euler_implicit`), else explicit
    (``_euler``). ``buf``: scratch of 64 floats. ``rec``: the joint-limit record, kept across periods
    (:func:`_record_limits`).
    """
    q = buf[16:19]
    qd = buf[19:22]
    t = buf[22:25]
    a = buf[25:28]
    mi = buf[28:37].reshape((3, 3))
    u1, u2, u3 = u[0], u[1], u[2]
    q1, q2, q3, qd1, qd2, qd3 = x[0], x[1], x[2], x[3], x[4], x[5]
    have_minv = False
    m11 = m12 = m13 = m22 = m23 = m33 = 0.0
    seen1 = seen2 = seen3 = False  # joints whose limit this period has recorded
    for _ in range(n_sub):
        if implicit:
            tc1, tc2, tc3, _f1, _f2, _f3, K11, K12, K13, K22, K23, K33 = wrench_slope(lc, q1, q2, q3, qd1, qd2, qd3)
        else:
            tc1, tc2, tc3, _f1, _f2, _f3 = wrench(lc, q1, q2, q3, qd1, qd2, qd3)
            K11 = K12 = K13 = K22 = K23 = K33 = 0.0
        tl1, tl2, tl3 = limit_torques(lim, q1, q2, q3, qd1, qd2, qd3)
        t[0], t[1], t[2] = u1 + tc1 + tl1, u2 + tc2 + tl2, u3 + tc3 + tl3
        q[0], q[1], q[2] = q1, q2, q3
        qd[0], qd[1], qd[2] = qd1, qd2, qd3
        aba(R, p, inertia, a0, q, qd, t, a, work, tmp)
        if (tl1 != 0.0 and not seen1) or (tl2 != 0.0 and not seen2) or (tl3 != 0.0 and not seen3):
            minverse_factored(work, tmp, mi)  # the aba just above was at this q
            seen1, seen2, seen3 = _record_limits(rec, mi, tl1, tl2, tl3, seen1, seen2, seen3)
        a1, a2, a3 = a[0], a[1], a[2]
        if K11 == 0.0 and K22 == 0.0 and K33 == 0.0:
            x1, x2, x3 = h * a1, h * a2, h * a3
        else:
            if not have_minv:  # first sub-step in contact of this period
                minverse_factored(work, tmp, mi)  # the aba just above was at this q
                m11, m12, m13, m22, m23, m33 = mi[0, 0], mi[0, 1], mi[0, 2], mi[1, 1], mi[1, 2], mi[2, 2]
                have_minv = True
            x1, x2, x3 = implicit_velocity_step(h, (m11, m12, m13, m22, m23, m33), (K11, K12, K13, K22, K23, K33),
                                                a1, a2, a3)  # fmt: skip
        qd1 = qd1 + x1
        qd2 = qd2 + x2
        qd3 = qd3 + x3
        q1 = q1 + h * qd1
        q2 = q2 + h * qd2
        q3 = q3 + h * qd3
    _t1, _t2, _t3, fx, fy, fz = wrench(lc, q1, q2, q3, qd1, qd2, qd3)
    x[0], x[1], x[2], x[3], x[4], x[5], x[6], x[7], x[8] = q1, q2, q3, qd1, qd2, qd3, fx, fy, fz


@_njit
def _accel(R: np.ndarray, p: np.ndarray, inertia: np.ndarray, a0: np.ndarray, lc: np.ndarray, lim: np.ndarray,
           u1: float, u2: float, u3: float, q1: float, q2: float, q3: float, qd1: float, qd2: float, qd3: float,
           work: np.ndarray, tmp: np.ndarray, buf: np.ndarray) -> tuple[float, float, float]:  # fmt: skip
    """Joint accelerations [rad/s^2] at (q, qd) under the held torque u [N m] plus the law's J_poc^T F and the
    limits' torque: :meth:`PinocchioBackend._qdd`, compiled (the same sums in the same order)."""
    q = buf[16:19]
    qd = buf[19:22]
    t = buf[22:25]
    a = buf[25:28]
    tc1, tc2, tc3, _f1, _f2, _f3 = wrench(lc, q1, q2, q3, qd1, qd2, qd3)
    tl1, tl2, tl3 = limit_torques(lim, q1, q2, q3, qd1, qd2, qd3)
    t[0], t[1], t[2] = u1 + tc1 + tl1, u2 + tc2 + tl2, u3 + tc3 + tl3
    q[0], q[1], q[2] = q1, q2, q3
    qd[0], qd[1], qd[2] = qd1, qd2, qd3
    aba(R, p, inertia, a0, q, qd, t, a, work, tmp)
    return a[0], a[1], a[2]


@_njit
def _rk4_arrays(R: np.ndarray, p: np.ndarray, inertia: np.ndarray, a0: np.ndarray, lc: np.ndarray, lim: np.ndarray,
                h: float, n_sub: int, u: np.ndarray, x: np.ndarray, work: np.ndarray, tmp: np.ndarray,
                buf: np.ndarray, rec: np.ndarray) -> None:  # fmt: skip
    """``n_sub`` classical Runge-Kutta 4 steps of ``h`` [s] under the held torque u [N m]:
    :meth:`PinocchioBackend._rk4`, compiled (the same stages in the same order). ``x`` as in
    :func:`_period_arrays`: the state in, the state and the law's F in W [N] at the end state out. ``rec``: the
    joint-limit record (:func:`_record_limits`) at each step's start state."""
    u1, u2, u3 = u[0], u[1], u[2]
    q1, q2, q3, qd1, qd2, qd3 = x[0], x[1], x[2], x[3], x[4], x[5]
    hh = 0.5 * h
    h6 = h / 6.0
    mi = buf[28:37].reshape((3, 3))
    qm = buf[37:40]
    seen1 = seen2 = seen3 = False
    for _ in range(n_sub):
        tl1, tl2, tl3 = limit_torques(lim, q1, q2, q3, 0.0, 0.0, 0.0)  # the spring alone: non-zero past a limit
        if (tl1 != 0.0 and not seen1) or (tl2 != 0.0 and not seen2) or (tl3 != 0.0 and not seen3):
            qm[0], qm[1], qm[2] = q1, q2, q3
            minverse(R, p, inertia, qm, mi, work, tmp, buf)
            seen1, seen2, seen3 = _record_limits(rec, mi, tl1, tl2, tl3, seen1, seen2, seen3)
        # stage 1 at (q, qd); v1 = qd
        a11, a12, a13 = _accel(R, p, inertia, a0, lc, lim, u1, u2, u3, q1, q2, q3, qd1, qd2, qd3, work, tmp, buf)
        # stage 2 at (q + h/2 v1, qd + h/2 a1)
        v21, v22, v23 = qd1 + hh * a11, qd2 + hh * a12, qd3 + hh * a13
        a21, a22, a23 = _accel(R, p, inertia, a0, lc, lim, u1, u2, u3, q1 + hh * qd1, q2 + hh * qd2, q3 + hh * qd3,
                               v21, v22, v23, work, tmp, buf)  # fmt: skip
        # stage 3 at (q + h/2 v2, qd + h/2 a2)
        v31, v32, v33 = qd1 + hh * a21, qd2 + hh * a22, qd3 + hh * a23
        a31, a32, a33 = _accel(R, p, inertia, a0, lc, lim, u1, u2, u3, q1 + hh * v21, q2 + hh * v22, q3 + hh * v23,
                               v31, v32, v33, work, tmp, buf)  # fmt: skip
        # stage 4 at (q + h v3, qd + h a3)
        v41, v42, v43 = qd1 + h * a31, qd2 + h * a32, qd3 + h * a33
        a41, a42, a43 = _accel(R, p, inertia, a0, lc, lim, u1, u2, u3, q1 + h * v31, q2 + h * v32, q3 + h * v33,
                               v41, v42, v43, work, tmp, buf)  # fmt: skip
        q1 = q1 + h6 * (qd1 + 2 * v21 + 2 * v31 + v41)
        q2 = q2 + h6 * (qd2 + 2 * v22 + 2 * v32 + v42)
        q3 = q3 + h6 * (qd3 + 2 * v23 + 2 * v33 + v43)
        qd1 = qd1 + h6 * (a11 + 2 * a21 + 2 * a31 + a41)
        qd2 = qd2 + h6 * (a12 + 2 * a22 + 2 * a32 + a42)
        qd3 = qd3 + h6 * (a13 + 2 * a23 + 2 * a33 + a43)
    _t1, _t2, _t3, fx, fy, fz = wrench(lc, q1, q2, q3, qd1, qd2, qd3)
    x[0], x[1], x[2], x[3], x[4], x[5], x[6], x[7], x[8] = q1, q2, q3, qd1, qd2, qd3, fx, fy, fz


def _record_at(n: int) -> int:
    """Where the joint-limit record starts in :func:`pack`'s ``scratch`` of an ``n``-body model: after work (n*96),
    tmp (96) and buf (64)."""
    return 96 * n + 160


jit.jitable(_record_at)


def pack(R: np.ndarray, p: np.ndarray, inertia: np.ndarray, a0: np.ndarray, lc: np.ndarray,
         lim: np.ndarray) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """The model and law constants in one array, and the scratch space in another, for :func:`period`: a call
    from Python then passes four arrays, not fourteen arguments (numba's dispatch costs per argument).

    model = (n, R (n*9), p (n*3), inertia (n*36), a0 (6), lc (14), lim (8)); scratch = work (n*96), tmp (96),
    buf (64), the joint-limit record (n: :func:`_record_limits`, kept across periods; :func:`limit_record`).
    """
    n = R.shape[0]
    model = np.concatenate([[float(n)], R.ravel(), p.ravel(), inertia.ravel(), a0, lc, lim]).astype(float)
    scratch = np.zeros(_record_at(n) + n)
    return model, scratch


def limit_record(scratch: np.ndarray) -> np.ndarray:
    """The joint-limit record in :func:`pack`'s ``scratch`` (a view, length n): per joint the largest (M^-1)_jj
    [1/(kg m^2)] at which the joint was past its limit since the record was last zeroed, 0 if never."""
    n = (scratch.shape[0] - _record_at(0)) // 97  # per body 96 before the record and 1 in it
    return scratch[_record_at(n) :]


@_njit
def period(model: np.ndarray, scratch: np.ndarray, u: np.ndarray, x: np.ndarray, h: float, n_sub: int,
           method: int) -> None:  # fmt: skip
    """One control period on :func:`pack`'s arrays: what the backend calls. ``method``: :data:`EULER`,
    :data:`EULER_IMPLICIT` (:func:`_period_arrays`) or :data:`RK4` (:func:`_rk4_arrays`); both update the
    joint-limit record at the end of ``scratch`` (:func:`limit_record`)."""
    n = int(model[0])
    o = 1
    R = model[o : o + 9 * n].reshape((n, 3, 3))
    o += 9 * n
    p = model[o : o + 3 * n].reshape((n, 3))
    o += 3 * n
    inertia = model[o : o + 36 * n].reshape((n, 6, 6))
    o += 36 * n
    a0 = model[o : o + 6]
    lc = model[o + 6 : o + 20]
    lim = model[o + 20 : o + 28]
    work = scratch[: 96 * n].reshape((n, 6, 16))
    tmp = scratch[96 * n : 96 * n + 96].reshape((6, 16))
    buf = scratch[96 * n + 96 : _record_at(n)]
    rec = scratch[_record_at(n) :]
    if method == RK4:
        _rk4_arrays(R, p, inertia, a0, lc, lim, h, n_sub, u, x, work, tmp, buf, rec)
    else:
        _period_arrays(R, p, inertia, a0, lc, lim, h, n_sub, method == EULER_IMPLICIT, u, x, work, tmp, buf, rec)


@_njit
def period_loop(model: np.ndarray, scratch: np.ndarray, x0: np.ndarray, TAU: np.ndarray, x: np.ndarray, h: float,
                n_sub: int, method: int) -> None:  # fmt: skip
    """A whole run's control periods in one compiled call: ``x`` (9,) set to ``x0`` (the run's initial state;
    its force entries are not read), the joint-limit record zeroed (as the backend's ``reset``), then
    :func:`period` once per row of ``TAU`` (N, 3) [N m], the torques the run logged, in order. Nothing but
    the backend's own period, so the end state in ``x`` is the run's last state bit for bit: the bench's
    compiled floor (:meth:`PinocchioBackend.kernels`), what a replay costs without its Python loop, its
    numba dispatch per period and its read-out."""
    for i in range(x.shape[0]):
        x[i] = x0[i]
    n = int(model[0])
    for j in range(_record_at(n), scratch.shape[0]):
        scratch[j] = 0.0
    for row in range(TAU.shape[0]):
        period(model, scratch, TAU[row], x, h, n_sub, method)


def _dopri_rhs(lc: np.ndarray, lim: np.ndarray, u: np.ndarray, g: float, y: np.ndarray, out: np.ndarray,
               data: Any) -> None:  # fmt: skip
    """d/dt (q, qd) = (qd, qdd) into ``out``: :func:`_accel` (the held torque u [N m] plus the law's J_poc^T F and
    the limits' torque, then ABA) on the model and scratch arrays of :func:`dopri_data` (``g``: unused, gravity
    is in the model's a0)."""
    R, p, inertia, a0, work, tmp, buf = data
    q1, q2, q3, qd1, qd2, qd3 = y[0], y[1], y[2], y[3], y[4], y[5]
    a1, a2, a3 = _accel(R, p, inertia, a0, lc, lim, u[0], u[1], u[2], q1, q2, q3, qd1, qd2, qd3, work, tmp, buf)
    out[0], out[1], out[2], out[3], out[4], out[5] = qd1, qd2, qd3, a1, a2, a3


def dopri_data(R: np.ndarray, p: np.ndarray, inertia: np.ndarray, a0: np.ndarray) -> tuple[np.ndarray, ...]:
    """The model arrays (:func:`model_arrays`) and the scratch :func:`_accel` takes, as one tuple."""
    return (R, p, inertia, a0, np.zeros((R.shape[0], 6, 16)), np.zeros((6, 16)), np.zeros(64))


@functools.cache
def dopri_period() -> Any:
    """The ``rk45`` control period, compiled (disk-cached) on first use: ``dopri_period()(x, u, g, lc, lim, t_bound,
    rtol, atol, max_step, k, dopri_data(...))`` integrates x = (q [rad], qd [rad/s]) in place over ``t_bound`` [s]
    and returns the number of right-hand-side evaluations, or -1 (:func:`legbench.backends.dopri.bind`)."""
    return dopri.bind(_njit(_dopri_rhs), "_period_pinocchio", True, (contact, joint_limits, dopri, _dopri_rhs))
