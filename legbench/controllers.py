"""The one controller stack (docs/spec.md section 6), run by the harness for every backend.

Every controller is discrete at the control rate and returns joint torques
[N m] before saturation; the run loop saturates them at the joint limits
(:func:`saturate`). A controller is started with the measured state when its
event fires (:meth:`Controller.start`), then called once per tick.

Each control law is a plain function on floats and two float arrays
(:func:`control_law` and the laws it dispatches to): the controller's
parameters (``params``, filled by :meth:`Controller.start`: gains, target,
spline coefficients, force) and its state (``state``: the error integral, the
previous error, the spline interval). The classes only set those arrays up.
The run loop calls the laws compiled inside its tick (:mod:`legbench.tick`:
numba, the same IEEE operations in the same order, so the same bits);
:meth:`Controller.torque` and the array form ``controller(k, q, qd)`` call the
very same functions as Python, the reference. One implementation of each law.

The effort controller's gravity torque G(q) is Pinocchio's algorithm on the
model's numbers, on floats (:func:`legbench.kinematics.gravity_scalar`), so
that law too is plain arithmetic. Its gravity is the one given to
:func:`make_controller`, which the caller takes from the scenario
(``physics.gravity``, the value the backends simulate); without one, the leg
parameter file's 9.81 m/s^2.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Sequence

import numpy as np

from legbench import kinematics
from legbench.kinematics import GRAVITY_SIZE, angdist_scalar, gravity_arrays, gravity_scalar, jacobian_scalar
from legbench.model import LegParams, load_params
from legbench.scenario import Event, Gains

# Controller kinds (params[P_KIND]).
POSITION, TRAJECTORY, EFFORT, TORQUE = 0, 1, 2, 3

# params: a header every kind shares, then the kind's own numbers from P_BODY on.
P_KIND, P_TS, P_KP, P_KD, P_KI, P_WRAP, P_BODY = 0, 1, 2, 5, 8, 11, 14
# state: the error integral sum(e Ts) [rad s], the previous error [rad], whether there is one, the
# spline interval in use.
S_I, S_E, S_HAS_PREV, S_SEG, S_SIZE = 0, 3, 6, 7, 8


def saturate(tau: np.ndarray, limit: np.ndarray) -> np.ndarray:
    """Clip joint torques to +-limit [N m] (in place, returned)."""
    np.clip(tau, -limit, limit, out=tau)
    return tau


def _floats(x: np.ndarray | Sequence[float]) -> tuple[float, float, float]:
    a, b, c = np.asarray(x, dtype=float).tolist()
    return a, b, c


def _header(kind: int, Ts: float, gains: Gains | None, params: LegParams, body: int) -> np.ndarray:
    """A params array: kind, Ts [s], Kp, Kd, Ki (3 each), the continuous-joint flags, ``body`` more zeros."""
    p = np.zeros(P_BODY + body)
    p[P_KIND], p[P_TS] = kind, Ts
    if gains is not None:
        p[P_KP : P_KP + 3], p[P_KD : P_KD + 3], p[P_KI : P_KI + 3] = gains.Kp, gains.Kd, gains.Ki
    p[P_WRAP : P_WRAP + 3] = [1.0 if c else 0.0 for c in params.continuous]
    return p


# ----------------------------------------------------------------------------- the laws (plain functions)


def error_integral(
    q1: float, q2: float, q3: float, r1: float, r2: float, r3: float, p: np.ndarray, s: np.ndarray
) -> tuple[float, float, float, float, float, float]:
    """Joint errors r - q [rad] (angular distance on continuous joints) and the integral sum(e Ts) [rad s] with the
    current error added before use (what Simulink's discrete PID calls backward Euler; docs/spec.md section 6),
    updated in ``s``."""
    e1 = angdist_scalar(q1, r1) if p[P_WRAP] != 0.0 else r1 - q1
    e2 = angdist_scalar(q2, r2) if p[P_WRAP + 1] != 0.0 else r2 - q2
    e3 = angdist_scalar(q3, r3) if p[P_WRAP + 2] != 0.0 else r3 - q3
    Ts = p[P_TS]
    i1 = s[S_I] + e1 * Ts
    i2 = s[S_I + 1] + e2 * Ts
    i3 = s[S_I + 2] + e3 * Ts
    s[S_I], s[S_I + 1], s[S_I + 2] = i1, i2, i3
    return e1, e2, e3, i1, i2, i3


def pid_law(
    q1: float, q2: float, q3: float, r1: float, r2: float, r3: float, p: np.ndarray, s: np.ndarray
) -> tuple[float, float, float]:
    """u = Kp e + Kd (e - e_prev) / Ts + Ki I [N m] for the angles q [rad] and the target r [rad]."""
    e1, e2, e3, i1, i2, i3 = error_integral(q1, q2, q3, r1, r2, r3, p, s)
    if s[S_HAS_PREV] != 0.0:
        p1, p2, p3 = s[S_E], s[S_E + 1], s[S_E + 2]
    else:
        p1, p2, p3 = e1, e2, e3
    s[S_E], s[S_E + 1], s[S_E + 2], s[S_HAS_PREV] = e1, e2, e3, 1.0
    Ts = p[P_TS]
    return (
        p[P_KP] * e1 + p[P_KD] * ((e1 - p1) / Ts) + p[P_KI] * i1,
        p[P_KP + 1] * e2 + p[P_KD + 1] * ((e2 - p2) / Ts) + p[P_KI + 1] * i2,
        p[P_KP + 2] * e3 + p[P_KD + 2] * ((e3 - p3) / Ts) + p[P_KI + 2] * i3,
    )


def position_law(q1: float, q2: float, q3: float, p: np.ndarray, s: np.ndarray) -> tuple[float, float, float]:
    """:func:`pid_law` to the joint target held in ``p[P_BODY:P_BODY+3]`` [rad]."""
    return pid_law(q1, q2, q3, p[P_BODY], p[P_BODY + 1], p[P_BODY + 2], p, s)


# trajectory params after the header: k0, last tick offset, m knots, the m knot times [s], then per interval
# the 12 coefficients (c3, c2, c1, c0) of joints 1, 2, 3, highest power first
T_K0, T_LAST, T_M, T_KNOTS = P_BODY, P_BODY + 1, P_BODY + 2, P_BODY + 3


def trajectory_desired(k: int, p: np.ndarray, s: np.ndarray) -> tuple[float, float, float, float, float, float]:
    """Desired (q_d [rad], qd_d [rad/s]) at tick k, as ``PPoly`` evaluates the spline: the interval
    ``t_j <= t < t_j+1`` (the last one closed at the last knot and beyond), power sum from the constant
    term up in ``s = t - t_j``; held at the last knot (velocity 0) after it."""
    Ts = p[P_TS]
    m = int(p[T_M])
    last = int(p[T_LAST])
    i = k - int(p[T_K0])
    x = (i if i < last else last) * Ts  # time since activation [s]
    t_end = p[T_KNOTS + m - 1]
    xt = t_end if x > t_end else x
    j = int(s[S_SEG])
    lo = p[T_KNOTS + j]
    hi = p[T_KNOTS + j + 1] if j < m - 2 else math.inf
    if not lo <= xt < hi:  # another interval (ticks move forward: once per knot)
        j = 0
        while j < m - 2 and p[T_KNOTS + j + 1] <= xt:
            j += 1
        s[S_SEG] = j
        lo = p[T_KNOTS + j]
    o = T_KNOTS + m + 12 * j
    a0, a1, a2, a3 = p[o], p[o + 1], p[o + 2], p[o + 3]
    b0, b1, b2, b3 = p[o + 4], p[o + 5], p[o + 6], p[o + 7]
    c0, c1, c2, c3 = p[o + 8], p[o + 9], p[o + 10], p[o + 11]
    u = xt - lo
    u2 = u * u
    u3 = u2 * u
    r1 = 0.0 + a3 + a2 * u + a1 * u2 + a0 * u3
    r2 = 0.0 + b3 + b2 * u + b1 * u2 + b0 * u3
    r3 = 0.0 + c3 + c2 * u + c1 * u2 + c0 * u3
    if x < t_end:
        return (r1, r2, r3, 0.0 + a2 + a1 * u * 2.0 + a0 * u2 * 3.0, 0.0 + b2 + b1 * u * 2.0 + b0 * u2 * 3.0,
                0.0 + c2 + c1 * u * 2.0 + c0 * u2 * 3.0)  # fmt: skip
    return r1, r2, r3, 0.0, 0.0, 0.0


def trajectory_law(
    k: int, q1: float, q2: float, q3: float, qd1: float, qd2: float, qd3: float, p: np.ndarray, s: np.ndarray
) -> tuple[float, float, float]:
    """u = Kp d(q, q_d(t)) + Kd (qd_d(t) - qd) + Ki integral(d) [N m]."""
    r1, r2, r3, v1, v2, v3 = trajectory_desired(k, p, s)
    e1, e2, e3, i1, i2, i3 = error_integral(q1, q2, q3, r1, r2, r3, p, s)
    return (
        p[P_KP] * e1 + p[P_KD] * (v1 - qd1) + p[P_KI] * i1,
        p[P_KP + 1] * e2 + p[P_KD + 1] * (v2 - qd2) + p[P_KI + 1] * i2,
        p[P_KP + 2] * e3 + p[P_KD + 2] * (v3 - qd3) + p[P_KI + 2] * i3,
    )


# effort params after the header: h_d in W [N], the first tick with it, L_12, L_23, L_3E [m], then the
# model's numbers for G(q) (kinematics.gravity_arrays), whose last three are -g in W [m/s^2]
E_H, E_K_FORCE, E_L, E_G = P_BODY, P_BODY + 3, P_BODY + 4, P_BODY + 7
E_G_ACC = E_G + GRAVITY_SIZE - 3


def effort_law(k: int, q1: float, q2: float, q3: float, p: np.ndarray) -> tuple[float, float, float]:
    """tau = Jv(q)^T h_d + G(q) [N m]: Jv by :func:`legbench.kinematics.jacobian_scalar`, G(q) by
    :func:`legbench.kinematics.gravity_scalar`."""
    g1, g2, g3 = gravity_scalar(q1, q2, q3, p[E_G : E_G + GRAVITY_SIZE])
    if k >= p[E_K_FORCE]:
        hx, hy, hz = p[E_H], p[E_H + 1], p[E_H + 2]
    else:
        hx, hy, hz = 0.0, 0.0, 0.0
    j11, j12, j13, j21, j22, j23, j31, j32, j33 = jacobian_scalar(q1, q2, q3, p[E_L], p[E_L + 1], p[E_L + 2])
    return (
        j11 * hx + j21 * hy + j31 * hz + g1,
        j12 * hx + j22 * hy + j32 * hz + g2,
        j13 * hx + j23 * hy + j33 * hz + g3,
    )


# torque params after the header: amplitude A [N m], frequency [rad per tick], phase [rad], the first tick
O_A, O_W, O_PHI, O_K0 = P_BODY, P_BODY + 3, P_BODY + 6, P_BODY + 9


def torque_law(k: int, p: np.ndarray) -> tuple[float, float, float]:
    """tau_i = A_i sin(w_i (k - k0) + phi_i) [N m], w_i in rad per tick."""
    n = k - int(p[O_K0])
    return (
        p[O_A] * math.sin(p[O_W] * n + p[O_PHI]),
        p[O_A + 1] * math.sin(p[O_W + 1] * n + p[O_PHI + 1]),
        p[O_A + 2] * math.sin(p[O_W + 2] * n + p[O_PHI + 2]),
    )


def control_law(
    k: int, q1: float, q2: float, q3: float, qd1: float, qd2: float, qd3: float, p: np.ndarray, s: np.ndarray
) -> tuple[float, float, float]:
    """The torque [N m] of the controller whose arrays ``p``, ``s`` are given, at tick k, for the measured
    q [rad], qd [rad/s]."""
    kind = p[P_KIND]
    if kind == POSITION:
        return position_law(q1, q2, q3, p, s)
    if kind == TRAJECTORY:
        return trajectory_law(k, q1, q2, q3, qd1, qd2, qd3, p, s)
    if kind == EFFORT:
        return effort_law(k, q1, q2, q3, p)
    return torque_law(k, p)


#: Every plain function the compiled tick calls (:mod:`legbench.tick` registers them with numba).
LAWS = (error_integral, pid_law, position_law, trajectory_desired, trajectory_law, effort_law, torque_law,
        control_law)  # fmt: skip

# ----------------------------------------------------------------------------- the controllers


class Controller(ABC):
    """A torque controller for the leg: sets up its law's ``params`` and ``state`` arrays."""

    name: str = ""
    #: the law's parameters (kind, Ts, gains, ...; see the ``P_*`` layout) and its state (``S_*``)
    params: np.ndarray
    state: np.ndarray

    @abstractmethod
    def start(self, t: float, q: np.ndarray, qd: np.ndarray) -> None:
        """Activate at time t [s] from the measured q [rad], qd [rad/s]."""

    def prepare(self) -> None:  # noqa: B027 (a hook: most controllers' start() needs no import)
        """Import what :meth:`start` needs, so the run loop can do it before its clock starts (nothing here)."""

    def torque(self, k: int, q1: float, q2: float, q3: float, qd1: float, qd2: float, qd3: float) -> tuple[float, ...]:
        """Torque (tau1, tau2, tau3) [N m] at control tick k (t = k Ts) for the measured q [rad], qd [rad/s]."""
        return control_law(k, q1, q2, q3, qd1, qd2, qd3, self.params, self.state)

    def __call__(self, k: int, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        """:meth:`torque` on arrays: torque [N m] at tick k for the measured q [rad], qd [rad/s]."""
        return np.array(self.torque(k, *_floats(q), *_floats(qd)))


class PID:
    """Discrete PID per joint (ros_control / Simulink form), unfiltered derivative (:func:`pid_law`).

    e = d(q, q_des) (angular distance on the continuous hip), edot = (e - e_prev) / Ts,
    I += e Ts (the current error added before use: Simulink's backward Euler), u = Kp e + Kd edot + Ki I.
    On activation e_prev is set to the first error, so a new target does not give a one-tick derivative kick (one
    ros_control PID carried across the target change would; docs/spec.md section 6 gives
    the decision and its measured effect).
    """

    def __init__(self, gains: Gains, Ts: float, params: LegParams | None = None) -> None:
        self.params = _header(POSITION, Ts, gains, params or load_params(), 3)  # gains and Ts live here
        self.state = np.zeros(S_SIZE)

    @property
    def integral(self) -> np.ndarray:
        """Integral of the error, sum(e Ts) [rad s]."""
        return self.state[S_I : S_I + 3].copy()

    def reset(self) -> None:
        self.state[:] = 0.0

    def update(self, q1: float, q2: float, q3: float, r1: float, r2: float, r3: float) -> tuple[float, float, float]:
        """Torque [N m] for the joint angles q [rad] and the target r [rad], on floats."""
        return pid_law(q1, q2, q3, r1, r2, r3, self.params, self.state)

    def __call__(self, q: np.ndarray, q_des: np.ndarray) -> np.ndarray:
        """Torque [N m] for the joint angles q [rad] and the target q_des [rad]."""
        return np.array(self.update(*_floats(q), *_floats(q_des)))


class PositionController(Controller):
    """PID to a joint target, or to a Cartesian foot target via the IK solution nearest the state."""

    name = "position"

    def __init__(self, event: Event, gains: Gains, Ts: float) -> None:
        self.event = event
        self.q_des = np.zeros(3)
        self.params = _header(POSITION, Ts, gains, load_params(), 3)
        self.state = np.zeros(S_SIZE)

    def start(self, t: float, q: np.ndarray, qd: np.ndarray) -> None:
        if self.event.joint is not None:
            self.q_des = np.array(self.event.joint, dtype=float)
        else:
            self.q_des = kinematics.ik_nearest(np.array(self.event.cartesian), q)
        self.params[P_BODY : P_BODY + 3] = self.q_des
        self.state[:] = 0.0  # a fresh PID per event: no derivative kick at the new target (docs/spec.md section 6)


def waypoint_velocities(Q: np.ndarray, times: np.ndarray, v_start: np.ndarray) -> np.ndarray:
    """Knot velocities by the spec's rule [rad/s].

    w_i = (q_i - q_{i-1}) / dt_i; an interior knot gets (w_i + w_{i+1}) / 2 where
    both have the same sign, else 0; the first knot keeps the measured velocity,
    the last one 0.
    """
    w = np.diff(Q, axis=0) / np.diff(times)[:, None]
    V = np.zeros_like(Q)
    V[0] = v_start
    same = np.sign(w[:-1]) * np.sign(w[1:]) > 0
    V[1:-1] = np.where(same, 0.5 * (w[:-1] + w[1:]), 0.0)
    return V


def joint_waypoints(waypoints: np.ndarray, q_start: np.ndarray, params: LegParams | None = None) -> np.ndarray:
    """IK of each Cartesian waypoint, each solution nearest the previous one (the first: q_start) [rad]."""
    out = np.empty((len(waypoints), 3))
    prev = np.asarray(q_start, float)
    for i, p in enumerate(waypoints):
        prev = kinematics.ik_nearest(p, prev, params)
        out[i] = prev
    return out


class TrajectoryController(Controller):
    """Cubic joint trajectory through Cartesian waypoints, tracked with PD(+I) and velocity feed-forward.

    u = Kp d(q, q_d(t)) + Kd (qd_d(t) - qd) + Ki integral(d) (:func:`trajectory_law`). The trajectory
    starts from the measured state at activation; segments are cubic in position and velocity at both
    ends (as ros_control's joint_trajectory_controller). The desired state is the spline at the control
    instants after activation, held at the last waypoint (velocity 0) after the last waypoint time.

    Only the spline's knots and coefficients are kept (memory per waypoint, not per tick);
    :func:`trajectory_desired` evaluates them at each tick with the same floating-point operations, in
    the same order, as scipy's ``PPoly``, so the values equal ``spline(t)`` and ``spline(t, 1)`` on the
    control grid bit for bit.
    """

    name = "trajectory"

    def __init__(self, event: Event, gains: Gains, Ts: float, n_ticks: int) -> None:
        self.event = event
        self.gains = gains
        self.Ts = Ts
        self.n_ticks = n_ticks
        self.leg = load_params()
        self.k0 = 0
        self.params = _header(TRAJECTORY, Ts, gains, self.leg, T_KNOTS - P_BODY + 2 + 12)
        self.params[T_M], self.params[T_KNOTS + 1] = 2.0, 1.0
        self.state = np.zeros(S_SIZE)
        self.knots_q = np.zeros((1, 3))
        self.knots_t = np.zeros(1)

    @property
    def integral(self) -> np.ndarray:
        """Integral of the tracking error [rad s]."""
        return self.state[S_I : S_I + 3].copy()

    def prepare(self) -> None:
        """scipy.interpolate (0.5-0.9 s to import once per process), before the run loop's clock: in start() it was
        charged to the wall time of the first backend a process ran a trajectory on (a harness review)."""
        import scipy.interpolate  # noqa: F401

    def start(self, t: float, q: np.ndarray, qd: np.ndarray) -> None:
        from scipy.interpolate import CubicHermiteSpline  # imported by prepare(): only where a trajectory starts

        Qw = joint_waypoints(np.array(self.event.waypoints), q, self.leg)
        Q = np.vstack([q, Qw])
        times = np.concatenate([[0.0], self.event.times])
        V = waypoint_velocities(Q, times, np.asarray(qd, float))
        spline = CubicHermiteSpline(times, Q, V, axis=0)
        self.k0 = int(round(t / self.Ts))
        c = spline.c  # (4, intervals, 3), highest power first
        m = len(times)
        p = _header(TRAJECTORY, self.Ts, self.gains, self.leg, T_KNOTS - P_BODY + m + 12 * (m - 1))
        p[T_K0], p[T_LAST], p[T_M] = self.k0, max(self.n_ticks - self.k0, 1) - 1, m
        p[T_KNOTS : T_KNOTS + m] = times
        p[T_KNOTS + m :] = c.transpose(1, 2, 0).reshape(-1)
        self.params = p
        self.state = np.zeros(S_SIZE)
        self.knots_q, self.knots_t = Q, times

    def desired_scalar(self, k: int) -> tuple[float, float, float, float, float, float]:
        """Desired (q_d [rad], qd_d [rad/s]) at tick k, as six floats."""
        return trajectory_desired(k, self.params, self.state)

    def desired(self, k: int) -> tuple[np.ndarray, np.ndarray]:
        """Desired q_d [rad] and qd_d [rad/s] at tick k."""
        d = self.desired_scalar(k)
        return np.array(d[:3]), np.array(d[3:])


class EffortController(Controller):
    """tau = Jv(q)^T h_d + G(q): the foot pushes on the environment with h_d in W [N] (:func:`effort_law`).

    With the event's ``force_delay`` [s], h_d is zero for that many control periods
    after the switch (tau = G(q): gravity compensation only), then the event's force.
    G(q) is Pinocchio's algorithm on floats (:func:`legbench.kinematics.gravity_scalar`) for the
    gravity ``gravity`` [m/s^2] along -z_W: the scenario's ``physics.gravity``, the one the backend
    simulates (None: the leg parameter file's, 9.81).
    """

    name = "effort"

    def __init__(self, event: Event, Ts: float = 1e-3, gravity: float | None = None) -> None:
        self.h_d = np.array(event.force, dtype=float)
        leg = load_params()
        g = leg.geometry
        self.n_force_delay = int(round(event.force_delay / Ts))  # control periods with h_d = 0
        self.Ts = Ts
        self.k_force = 0  # first tick with the event's force
        self.params = _header(EFFORT, Ts, None, leg, 7 + GRAVITY_SIZE)
        self.params[E_G : E_G + GRAVITY_SIZE] = gravity_arrays()
        if gravity is not None:  # G(q) is linear in g: the root's upward acceleration -g in W is (0, 0, g)
            self.params[E_G_ACC : E_G_ACC + 3] = 0.0, 0.0, float(gravity)
        self.params[E_H : E_H + 3] = self.h_d
        self.params[E_L : E_L + 3] = g.L_12, g.L_23, g.L_3E
        self.state = np.zeros(S_SIZE)

    def start(self, t: float, q: np.ndarray, qd: np.ndarray) -> None:
        self.k_force = int(round(t / self.Ts)) + self.n_force_delay
        self.params[E_K_FORCE] = self.k_force


class TorqueController(Controller):
    """Open loop: tau_i = A_i sin(2 pi f_i (t - t_s) + phi_i) [N m], whatever the state (:func:`torque_law`), t_s
    the tick the event switches at (its ``t`` plus any delay: :meth:`start`).

    The torque of tick k is the value at t = k Ts (held over the period by the backend).
    """

    name = "torque"

    def __init__(self, event: Event, Ts: float) -> None:
        if event.amplitude is None or event.frequency is None:
            raise ValueError("a torque event needs amplitude and frequency")
        self.Ts = Ts
        p = self.params = _header(TORQUE, Ts, None, load_params(), 10)
        p[O_A : O_A + 3] = event.amplitude
        p[O_W : O_W + 3] = _floats(2.0 * math.pi * np.asarray(event.frequency, dtype=float) * Ts)  # [rad per tick]
        p[O_PHI : O_PHI + 3] = event.phase if event.phase is not None else (0.0, 0.0, 0.0)
        p[O_K0] = int(round(event.t / Ts))
        self.state = np.zeros(S_SIZE)

    def start(self, t: float, q: np.ndarray, qd: np.ndarray) -> None:
        self.params[O_K0] = int(round(t / self.Ts))


def make_controller(event: Event, gains: Gains, Ts: float, n_ticks: int, gravity: float | None = None) -> Controller:
    """The controller an event asks for; ``gravity`` [m/s^2] is the scenario's ``physics.gravity`` (the effort
    controller's G(q); None: the leg parameter file's)."""
    if event.controller == "position":
        return PositionController(event, gains, Ts)
    if event.controller == "trajectory":
        return TrajectoryController(event, gains, Ts, n_ticks)
    if event.controller == "effort":
        return EffortController(event, Ts, gravity)
    if event.controller == "torque":
        return TorqueController(event, Ts)
    raise ValueError(f"unknown controller {event.controller!r}")
