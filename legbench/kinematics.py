"""Closed-form kinematics of the leg (docs/spec.md sections 1 and 5).

Every function takes joint angles ``q = (q1, q2, q3)`` [rad] and works on a
single configuration of shape (3,) or a batch of shape (N, 3). Positions are
of the foot centre E, in W [m], unless stated otherwise. The equations are the
spec's; tests check them against Pinocchio on the generated URDF.

The run loop's controllers use the scalar paths (:func:`angdist_scalar`,
:func:`jacobian_scalar`: the same arithmetic on plain floats, in the same
order, so the same numbers bit for bit; :func:`gravity_scalar`: Pinocchio's
Newton-Euler recursion at rest on the model's numbers, equal to
:func:`gravity` to round-off). They allocate nothing, and the compiled tick
(:mod:`legbench.tick`) calls them (:data:`SCALAR`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from legbench.exceptions import ModelError, Unreachable
from legbench.model import LegParams, gravity_torque, load_params, pinocchio_model

#: Rotation W_R_0 of the base frame (frame 0 x is up, y0 = -x_W, z0 = -y_W).
W_R_0 = np.array([[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]])


def _params(params: LegParams | None) -> LegParams:
    return params if params is not None else load_params()


def angdist(q_from: np.ndarray | float, q_to: np.ndarray | float) -> np.ndarray:
    """Shortest signed angle from ``q_from`` to ``q_to`` in [-pi, pi) [rad]."""
    return np.mod(np.asarray(q_to) - np.asarray(q_from) + np.pi, 2.0 * np.pi) - np.pi


def angdist_scalar(q_from: float, q_to: float) -> float:
    """:func:`angdist` of two floats [rad] (Python's float ``%`` is ``np.mod``: same result bit for bit)."""
    return (q_to - q_from + math.pi) % (2.0 * math.pi) - math.pi


def joint_error(q: np.ndarray, q_des: np.ndarray, params: LegParams | None = None) -> np.ndarray:
    """Joint error q_des - q [rad]: angular distance on continuous joints, plain difference elsewhere.

    A revolute joint's range may exceed pi (the knee spans 4.46 rad), so wrapping
    it would drive it the wrong way round, through its limit.
    """
    p = _params(params)
    diff = np.asarray(q_des, float) - np.asarray(q, float)
    return np.where(p.continuous, angdist(q, q_des), diff)


def fk0(q: np.ndarray, params: LegParams | None = None) -> np.ndarray:
    """Foot centre in frame 0 [m]."""
    g = _params(params).geometry
    q = np.asarray(q, float)
    q1, q2, q3 = q[..., 0], q[..., 1], q[..., 2]
    s1, c1 = np.sin(q1), np.cos(q1)
    reach = g.L_23 * np.sin(q2) + g.L_3E * np.sin(q2 + q3)
    x0 = g.L_12 * s1 + c1 * reach
    y0 = -g.L_12 * c1 + s1 * reach
    z0 = -g.L_01 - g.L_23 * np.cos(q2) - g.L_3E * np.cos(q2 + q3)
    return np.stack([x0, y0, z0], axis=-1)


def chain0(q: np.ndarray, params: LegParams | None = None) -> np.ndarray:
    """Points of the leg in frame 0 [m], shape (..., 5, 3): frame 0's origin, the ab/ad joint, the hip
    joint, the knee joint and the foot centre E (the last equals :func:`fk0`), for drawing the leg."""
    g = _params(params).geometry
    q = np.asarray(q, float)
    q1, q2 = q[..., 0], q[..., 1]
    s1, c1 = np.sin(q1), np.cos(q1)
    zero = np.zeros_like(q1)
    p1 = np.stack([zero, zero, zero - g.L_01], axis=-1)
    p2 = np.stack([g.L_12 * s1, -g.L_12 * c1, zero - g.L_01], axis=-1)
    thigh = g.L_23 * np.sin(q2)
    p3 = p2 + np.stack([c1 * thigh, s1 * thigh, -g.L_23 * np.cos(q2)], axis=-1)
    pts = np.stack([np.zeros_like(p1), p1, p2, p3, fk0(q, params)], axis=-2)
    return pts


def chain(q: np.ndarray, params: LegParams | None = None) -> np.ndarray:
    """:func:`chain0` in W [m], shape (..., 5, 3); the last point is :func:`fk`."""
    return frame0_to_world(chain0(q, params), params)


def frame0_to_world(p0: np.ndarray, params: LegParams | None = None) -> np.ndarray:
    """A point in frame 0 -> W [m]."""
    g = _params(params).geometry
    p0 = np.asarray(p0, float)
    return np.stack([g.L_B0 - p0[..., 1], -p0[..., 2], p0[..., 0] + g.H], axis=-1)


def world_to_frame0(pw: np.ndarray, params: LegParams | None = None) -> np.ndarray:
    """A point in W -> frame 0: 0P = [z_W - H, L_B0 - x_W, -y_W] [m]."""
    g = _params(params).geometry
    pw = np.asarray(pw, float)
    return np.stack([pw[..., 2] - g.H, g.L_B0 - pw[..., 0], -pw[..., 1]], axis=-1)


def fk(q: np.ndarray, params: LegParams | None = None) -> np.ndarray:
    """Foot centre E in W [m], shape (..., 3)."""
    return frame0_to_world(fk0(q, params), params)


def jacobian0(q: np.ndarray, params: LegParams | None = None) -> np.ndarray:
    """Linear Jacobian of E in frame 0, shape (..., 3, 3) [m/rad]."""
    g = _params(params).geometry
    q = np.asarray(q, float)
    q1, q2, q3 = q[..., 0], q[..., 1], q[..., 2]
    s1, c1 = np.sin(q1), np.cos(q1)
    reach = g.L_23 * np.sin(q2) + g.L_3E * np.sin(q2 + q3)
    dreach2 = g.L_23 * np.cos(q2) + g.L_3E * np.cos(q2 + q3)
    dreach3 = g.L_3E * np.cos(q2 + q3)
    zero = np.zeros_like(q1)
    J = np.stack(
        [
            np.stack([g.L_12 * c1 - s1 * reach, c1 * dreach2, c1 * dreach3], axis=-1),
            np.stack([g.L_12 * s1 + c1 * reach, s1 * dreach2, s1 * dreach3], axis=-1),
            np.stack([zero, g.L_23 * np.sin(q2) + g.L_3E * np.sin(q2 + q3), g.L_3E * np.sin(q2 + q3)], axis=-1),
        ],
        axis=-2,
    )
    return J


def jacobian(q: np.ndarray, params: LegParams | None = None) -> np.ndarray:
    """Linear geometric Jacobian of the foot centre E in W, Jv(q): v_E = Jv qd [m/rad]."""
    return W_R_0 @ jacobian0(q, params)


def jacobian_scalar(
    q1: float, q2: float, q3: float, L_12: float, L_23: float, L_3E: float
) -> tuple[float, float, float, float, float, float, float, float, float]:
    """:func:`jacobian` for one configuration, on floats: Jv(q) in W, row-major (9 floats) [m/rad].

    W_R_0 only permutes and negates rows (W x = -y0, W y = -z0, W z = x0), which
    is exact, so the values equal :func:`jacobian`'s bit for bit.

    Args:
        q1, q2, q3: joint angles [rad].
        L_12, L_23, L_3E: the leg's lengths (``load_params().geometry``) [m].
    """
    s1, c1 = math.sin(q1), math.cos(q1)
    s23 = math.sin(q2 + q3)
    c23 = math.cos(q2 + q3)
    reach = L_23 * math.sin(q2) + L_3E * s23
    dreach2 = L_23 * math.cos(q2) + L_3E * c23
    dreach3 = L_3E * c23
    return (
        -(L_12 * s1 + c1 * reach), -(s1 * dreach2), -(s1 * dreach3),
        0.0, -reach, -(L_3E * s23),
        L_12 * c1 - s1 * reach, c1 * dreach2, c1 * dreach3,
    )  # fmt: skip


def angular_jacobian(q: np.ndarray) -> np.ndarray:
    """Angular Jacobian of the shank (link 3) in W: omega = Jw qd [1]."""
    q = np.asarray(q, float)
    s1, c1 = np.sin(q[..., 0]), np.cos(q[..., 0])
    one, zero = np.ones_like(s1), np.zeros_like(s1)
    z1 = np.stack([zero, zero, one], axis=-1)
    z2 = np.stack([s1, -c1, zero], axis=-1)
    J0 = np.stack([z1, z2, z2], axis=-1)  # columns are the joint axes in frame 0
    return W_R_0 @ J0


def jacobian_poc(q: np.ndarray, params: LegParams | None = None, true_poc: bool = True) -> np.ndarray:
    """Linear Jacobian of the point of contact in W [m/rad].

    With ``true_poc`` the poc is the foot sphere's lowest point, a material
    point of the shank at r = -R_foot z_W from E, so v_poc = v_E + omega x r.
    Without it, the poc is the sphere centre (the report's simplification).
    """
    if not true_poc:
        return jacobian(q, params)
    return jacobian_below(q, _params(params).geometry.R_foot, params)


def jacobian_below(q: np.ndarray, depth: float | np.ndarray, params: LegParams | None = None) -> np.ndarray:
    """Linear Jacobian in W [m/rad] of the shank's material point ``depth`` [m] below E along -z_W (a number, or
    one per configuration of ``q``): r = -d z_W, v = v_E + omega x r = v_E + (-d w_y, d w_x, 0)."""
    d = np.asarray(depth, float)[..., None]
    Jw = angular_jacobian(q)
    J = jacobian(q, params).copy()
    J[..., 0, :] -= d * Jw[..., 1, :]
    J[..., 1, :] += d * Jw[..., 0, :]
    return J


def contact_depth(q: np.ndarray, lift: float = 0.0, params: LegParams | None = None) -> np.ndarray:
    """Depth [m] below E, along -z_W, of the point where an engine's contact force acts: ``lift`` [1] of the
    penetration y = R_foot - z_E above the sphere's lowest point (0: the true poc; 0.5: halfway between the two
    surfaces; 1: on the ground plane), per configuration of ``q`` [rad] (shape () for one, (N,) for a batch); out
    of the ground (y <= 0), the lowest point."""
    R = _params(params).geometry.R_foot
    q = np.asarray(q, float)
    if lift == 0.0:
        return np.full(q.shape[:-1], R)
    y = R - fk(q, params)[..., 2]
    return R - lift * np.maximum(y, 0.0)


def jacobian_at(q: np.ndarray, poc: str = "true", lift: float = 0.0, params: LegParams | None = None) -> np.ndarray:
    """Linear Jacobian in W [m/rad] of the shank's material point where the contact force acts: the law's poc
    (``poc``: ``"true"``, the sphere's lowest point, or ``"centre"``, E), raised by ``lift`` of the penetration
    where an engine's own contact acts above the lowest point (:func:`contact_depth`; only with ``"true"``):
    r = -d z_W from E, v = v_E + omega x r. With ``lift`` 0 the numbers of :func:`jacobian_poc`."""
    if poc == "centre":
        return jacobian(q, params)
    return jacobian_below(q, contact_depth(q, lift, params), params)


def is_singular(q: np.ndarray, params: LegParams | None = None, tol: float = 1e-6) -> np.ndarray:
    """True where the Jacobian loses rank: straight knee (s3 = 0), or E in the plane of the ab/ad and hip axes.

    The second condition is zero reach, L23 s2 + L3E s23 = 0: there the ab/ad and hip columns of J are
    parallel. (E itself never reaches the ab/ad axis: its distance from it is at least L_12.)
    """
    g = _params(params).geometry
    q = np.asarray(q, float)
    s3 = np.sin(q[..., 2])
    reach = g.L_23 * np.sin(q[..., 1]) + g.L_3E * np.sin(q[..., 1] + q[..., 2])
    return (np.abs(s3) < tol) | (np.abs(reach) < tol * (g.L_23 + g.L_3E))


@dataclass(frozen=True)
class IKResult:
    """All joint solutions for one point, with the reason when there are none."""

    solutions: np.ndarray  # (k, 3) [rad], k in 0..4
    reason: str = ""

    def __bool__(self) -> bool:
        return len(self.solutions) > 0


def ik(p_w: np.ndarray | Sequence[float], params: LegParams | None = None, tol: float = 1e-9) -> IKResult:
    """Closed-form inverse kinematics of the foot centre E at ``p_w`` in W [m].

    Returns every solution inside the joint limits (up to four: two ab/ad roots
    times knee up/down), hip angle wrapped to [-pi, pi). ``reason`` says why a
    point has none.
    """
    p = _params(params)
    g = p.geometry
    xw, yw, zw = np.asarray(p_w, float).tolist()
    x, y, z = zw - g.H, g.L_B0 - xw, -yw  # world_to_frame0 on floats
    rxy = math.hypot(x, y)
    if rxy < g.L_12 - tol:
        return IKResult(np.empty((0, 3)), f"point is {rxy:.4f} m from the ab/ad axis, closer than L_12 = {g.L_12} m")
    phi = math.atan2(y, x)
    a = math.asin(min(1.0, g.L_12 / rxy)) if rxy > 0 else math.pi / 2
    q1_candidates = {_wrap(phi + a), _wrap(phi + math.pi - a)}
    lo, hi = p.lower, p.upper
    r2_min = g.L_23**2 + g.L_3E**2 + 2 * g.L_23 * g.L_3E * math.cos(hi[2])
    r2_max = (g.L_23 + g.L_3E) ** 2
    sols: list[list[float]] = []
    reasons: list[tuple[str, float]] = []  # (kind, value), put into words only when there is no solution
    for q1 in sorted(q1_candidates):
        if not lo[0] - tol <= q1 <= hi[0] + tol:
            reasons.append(("abad", q1))
            continue
        s1, c1 = math.sin(q1), math.cos(q1)
        K1 = x * c1 + y * s1
        K2 = -z - g.L_01
        r2 = K1 * K1 + K2 * K2
        if r2 > r2_max * (1 + tol) or r2 < r2_min * (1 - tol):
            reasons.append(("distance", r2))
            continue
        c3 = min(1.0, max(-1.0, (r2 - g.L_23**2 - g.L_3E**2) / (2 * g.L_23 * g.L_3E)))
        s3_abs = math.sqrt(max(0.0, 1.0 - c3 * c3))
        for s3 in {s3_abs, -s3_abs}:
            q3 = math.atan2(s3, c3)
            if not lo[2] - tol <= q3 <= hi[2] + tol:
                reasons.append(("knee", q3))
                continue
            # [[a, b], [b, -a]] (cos q2, sin q2) = (K1, K2), a = L_3E sin q3, b = L_23 + L_3E cos q3: the
            # solution is (a K1 + b K2, b K1 - a K2) / (a^2 + b^2), and atan2 needs no division
            a_, b_ = g.L_3E * s3, g.L_3E * c3 + g.L_23
            q2 = math.atan2(b_ * K1 - a_ * K2, a_ * K1 + b_ * K2)
            sols.append([min(max(q1, lo[0]), hi[0]), q2, min(max(q3, lo[2]), hi[2])])
    if not sols:
        words = {
            "abad": lambda v: f"ab/ad angle {v:.4f} rad outside [{lo[0]:.4f}, {hi[0]:.4f}]",
            "distance": lambda v: (
                f"distance {math.sqrt(v):.4f} m from the hip axis outside the workspace "
                f"[{math.sqrt(max(r2_min, 0)):.4f}, {math.sqrt(r2_max):.4f}] m"
            ),
            "knee": lambda v: f"knee angle {v:.4f} rad outside [{lo[2]:.4f}, {hi[2]:.4f}]",
        }
        text = [words[kind](v) for kind, v in reasons]
        return IKResult(np.empty((0, 3)), "; ".join(dict.fromkeys(text)) or "no solution")
    return IKResult(np.array(sols))


def _wrap(a: float) -> float:
    return (a + math.pi) % (2 * math.pi) - math.pi


def nearest(solutions: np.ndarray, q_ref: np.ndarray, params: LegParams | None = None) -> np.ndarray:
    """The solution nearest ``q_ref`` by joint error norm, unwrapped so it is continuous with ``q_ref``."""
    if len(solutions) == 0:
        raise Unreachable("no inverse-kinematics solution to choose from")
    wrap = _params(params).continuous
    r1, r2, r3 = np.asarray(q_ref, float).tolist()
    best, best_e = math.inf, (0.0, 0.0, 0.0)
    for s1, s2, s3 in solutions.tolist():  # at most four: floats, not a chain of small array operations
        e = (
            angdist_scalar(r1, s1) if wrap[0] else s1 - r1,
            angdist_scalar(r2, s2) if wrap[1] else s2 - r2,
            angdist_scalar(r3, s3) if wrap[2] else s3 - r3,
        )
        d = e[0] * e[0] + e[1] * e[1] + e[2] * e[2]
        if d < best:
            best, best_e = d, e
    return np.array([r1 + best_e[0], r2 + best_e[1], r3 + best_e[2]])


def ik_nearest(p_w: np.ndarray, q_ref: np.ndarray, params: LegParams | None = None) -> np.ndarray:
    """IK solution nearest ``q_ref`` [rad]; raises :class:`Unreachable` with the reason."""
    res = ik(p_w, params)
    if not res:
        raise Unreachable(f"W point {np.round(np.asarray(p_w, float), 5).tolist()} is unreachable: {res.reason}")
    return nearest(res.solutions, q_ref, params)


def gravity(q: np.ndarray) -> np.ndarray:
    """Gravity torque G(q) [N m] through Pinocchio on the generated URDF."""
    return gravity_torque(np.asarray(q, float))


#: Offsets in :func:`gravity_arrays`: per joint (16 numbers) its placement R (row-major) and p, its body's
#: mass and first moment m c, then -g in the root frame.
_G_JOINT, _G_R, _G_P, _G_M, _G_MC, _G_A0, GRAVITY_SIZE = 16, 0, 9, 12, 13, 48, 51


def gravity_arrays(urdf: str | None = None) -> np.ndarray:
    """The numbers :func:`gravity_scalar` needs, read from the Pinocchio model of the leg (51 floats).

    Per joint i = 1..3: its placement in the parent joint's frame at q = 0 (R row-major [1], p [m]), its
    body's mass m [kg] and first moment m c [kg m] (c: the centre of mass in the joint frame); then the
    root's acceleration standing for gravity, -g in W [m/s^2] (the model's gravity, as :func:`gravity`).

    Raises:
        ModelError: the model is not a chain of three joints turning about their own z axis.
    """
    model = pinocchio_model(urdf)
    kinds = [model.joints[i].shortname() for i in range(1, model.njoints)]
    if kinds not in (["JointModelRZ", "JointModelRUBZ", "JointModelRZ"],) or list(model.parents)[1:] != [0, 1, 2]:
        raise ModelError(f"G(q) on floats needs a chain of three z-revolute joints, not {kinds}")
    out = np.empty(GRAVITY_SIZE)
    for i in range(3):
        placement, inertia, o = model.jointPlacements[i + 1], model.inertias[i + 1], _G_JOINT * i
        out[o + _G_R : o + _G_R + 9] = np.asarray(placement.rotation).reshape(9)
        out[o + _G_P : o + _G_P + 3] = placement.translation
        out[o + _G_M] = inertia.mass
        out[o + _G_MC : o + _G_MC + 3] = inertia.mass * np.asarray(inertia.lever)
    out[_G_A0 : _G_A0 + 3] = -np.asarray(model.gravity.linear)
    return out


def _to_child(a: np.ndarray, o: int, q: float, x: float, y: float, z: float) -> tuple[float, float, float]:
    """A vector in joint i's parent frame -> joint i's frame (``o``: joint i's block): (R Rz(q))^T v."""
    u0 = a[o] * x + a[o + 3] * y + a[o + 6] * z
    u1 = a[o + 1] * x + a[o + 4] * y + a[o + 7] * z
    u2 = a[o + 2] * x + a[o + 5] * y + a[o + 8] * z
    c, s = math.cos(q), math.sin(q)
    return c * u0 + s * u1, c * u1 - s * u0, u2


def _to_parent(a: np.ndarray, o: int, q: float, x: float, y: float, z: float) -> tuple[float, float, float]:
    """A vector in joint i's frame -> its parent's frame: R Rz(q) v."""
    c, s = math.cos(q), math.sin(q)
    w0, w1 = c * x - s * y, s * x + c * y
    return (
        a[o] * w0 + a[o + 1] * w1 + a[o + 2] * z,
        a[o + 3] * w0 + a[o + 4] * w1 + a[o + 5] * z,
        a[o + 6] * w0 + a[o + 7] * w1 + a[o + 8] * z,
    )


def _body_wrench(a: np.ndarray, o: int, ax: float, ay: float, az: float) -> tuple[float, ...]:
    """Body i's wrench at its joint origin for the acceleration (ax, ay, az) [m/s^2], no rotation:
    (m a [N], m c x a [N m])."""
    m, cx, cy, cz = a[o + _G_M], a[o + _G_MC], a[o + _G_MC + 1], a[o + _G_MC + 2]
    return m * ax, m * ay, m * az, cy * az - cz * ay, cz * ax - cx * az, cx * ay - cy * ax


def _wrench_to_parent(a: np.ndarray, o: int, q: float, w: tuple[float, ...]) -> tuple[float, ...]:
    """A wrench at joint i's origin in its frame -> at the parent's joint origin in the parent's frame."""
    fx, fy, fz = _to_parent(a, o, q, w[0], w[1], w[2])
    nx, ny, nz = _to_parent(a, o, q, w[3], w[4], w[5])
    px, py, pz = a[o + _G_P], a[o + _G_P + 1], a[o + _G_P + 2]
    return fx, fy, fz, nx + py * fz - pz * fy, ny + pz * fx - px * fz, nz + px * fy - py * fx


def gravity_scalar(q1: float, q2: float, q3: float, a: np.ndarray) -> tuple[float, float, float]:
    """G(q) [N m] on floats: the recursive Newton-Euler algorithm at rest (qd = qdd = 0) on
    :func:`gravity_arrays`' numbers, the algorithm of Pinocchio's ``computeGeneralizedGravity``.

    Forward, gravity as the root's upward acceleration -g carried into each joint frame; backward, each
    body's wrench m (-g), m c x (-g) plus its child's, moved to the joint origin; G_i is the z moment.
    Plain arithmetic, so the run loop's compiled tick can call it (the effort controller's G(q));
    it agrees with :func:`gravity` (Pinocchio) to round-off, not bit for bit.
    """
    o1, o2, o3 = 0, _G_JOINT, 2 * _G_JOINT
    a1x, a1y, a1z = _to_child(a, o1, q1, a[_G_A0], a[_G_A0 + 1], a[_G_A0 + 2])
    a2x, a2y, a2z = _to_child(a, o2, q2, a1x, a1y, a1z)
    a3x, a3y, a3z = _to_child(a, o3, q3, a2x, a2y, a2z)
    w3 = _body_wrench(a, o3, a3x, a3y, a3z)
    b2 = _body_wrench(a, o2, a2x, a2y, a2z)
    c2 = _wrench_to_parent(a, o3, q3, w3)
    w2 = (b2[0] + c2[0], b2[1] + c2[1], b2[2] + c2[2], b2[3] + c2[3], b2[4] + c2[4], b2[5] + c2[5])
    b1 = _body_wrench(a, o1, a1x, a1y, a1z)
    c1 = _wrench_to_parent(a, o2, q2, w2)
    return b1[5] + c1[5], w2[5], w3[5]


#: The plain functions of this module that compiled code calls (:mod:`legbench.tick` registers them).
SCALAR = (angdist_scalar, jacobian_scalar, gravity_scalar, _to_child, _to_parent, _body_wrench, _wrench_to_parent)
