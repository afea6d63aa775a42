"""The one controller stack (docs/spec.md section 6), run by the harness for every backend.

Every controller is discrete at the control rate and returns joint torques
[N m] before saturation; the run loop saturates them at the joint limits
(:func:`saturate`). A controller is started with the measured state when its
event fires (:meth:`Controller.start`), then called once per tick.

The run loop calls :meth:`Controller.torque`, which works on plain floats:
one control tick costs a few microseconds instead of the tens a chain of
small numpy operations costs, and the loop's overhead must stay well below
an engine's step. The array form ``controller(k, q, qd)`` gives the same
numbers bit for bit (every operation is the same IEEE operation in the same
order; :mod:`legbench.kinematics` documents its scalar paths).
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from bisect import bisect_right
from collections.abc import Sequence

import numpy as np
from scipy.interpolate import CubicHermiteSpline

from legbench import kinematics
from legbench.kinematics import angdist_scalar
from legbench.model import LegParams, load_params
from legbench.scenario import Event, Gains


def saturate(tau: np.ndarray, limit: np.ndarray) -> np.ndarray:
    """Clip joint torques to +-limit [N m] (in place, returned)."""
    np.clip(tau, -limit, limit, out=tau)
    return tau


def _floats(x: np.ndarray | Sequence[float]) -> tuple[float, float, float]:
    a, b, c = np.asarray(x, dtype=float).tolist()
    return a, b, c


class Controller(ABC):
    """A torque controller for the leg."""

    name: str = ""

    @abstractmethod
    def start(self, t: float, q: np.ndarray, qd: np.ndarray) -> None:
        """Activate at time t [s] from the measured q [rad], qd [rad/s]."""

    @abstractmethod
    def torque(self, k: int, q1: float, q2: float, q3: float, qd1: float, qd2: float, qd3: float) -> tuple[float, ...]:
        """Torque (tau1, tau2, tau3) [N m] at control tick k (t = k Ts) for the measured q [rad], qd [rad/s]."""

    def __call__(self, k: int, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        """:meth:`torque` on arrays: torque [N m] at tick k for the measured q [rad], qd [rad/s]."""
        return np.array(self.torque(k, *_floats(q), *_floats(qd)))


def _error_integral(
    c: PID | TrajectoryController, q1: float, q2: float, q3: float, r1: float, r2: float, r3: float
) -> tuple[float, float, float, float, float, float]:
    """Joint errors r - q [rad] (angular distance on continuous joints) and the updated forward-Euler
    integral sum(e Ts) [rad s] of a controller with ``_wrap``, ``Ts`` and ``_i``, on floats."""
    w1, w2, w3 = c._wrap
    e1 = angdist_scalar(q1, r1) if w1 else r1 - q1
    e2 = angdist_scalar(q2, r2) if w2 else r2 - q2
    e3 = angdist_scalar(q3, r3) if w3 else r3 - q3
    Ts = c.Ts
    i1, i2, i3 = c._i
    i1 += e1 * Ts
    i2 += e2 * Ts
    i3 += e3 * Ts
    c._i = (i1, i2, i3)
    return e1, e2, e3, i1, i2, i3


class PID:
    """Discrete PID per joint (ros_control / Simulink form), unfiltered derivative.

    e = d(q, q_des) (angular distance on the continuous hip), edot = (e - e_prev) / Ts,
    I += e Ts (forward Euler), u = Kp e + Kd edot + Ki I. On activation e_prev is set
    to the first error, so a new target does not give a one-tick derivative kick.
    """

    def __init__(self, gains: Gains, Ts: float, params: LegParams | None = None) -> None:
        self.Kp = np.array(gains.Kp)
        self.Kd = np.array(gains.Kd)
        self.Ki = np.array(gains.Ki)
        self.Ts = Ts
        self.params = params or load_params()
        self._gains = (*gains.Kp, *gains.Kd, *gains.Ki)
        self._wrap = tuple(bool(c) for c in self.params.continuous)
        self.e_prev: tuple[float, float, float] | None = None
        self._i = (0.0, 0.0, 0.0)

    @property
    def integral(self) -> np.ndarray:
        """Integral of the error, sum(e Ts) [rad s]."""
        return np.array(self._i)

    def reset(self) -> None:
        self.e_prev = None
        self._i = (0.0, 0.0, 0.0)

    def update(self, q1: float, q2: float, q3: float, r1: float, r2: float, r3: float) -> tuple[float, float, float]:
        """Torque [N m] for the joint angles q [rad] and the target r [rad], on floats."""
        e1, e2, e3, i1, i2, i3 = _error_integral(self, q1, q2, q3, r1, r2, r3)
        p1, p2, p3 = self.e_prev if self.e_prev is not None else (e1, e2, e3)
        Ts = self.Ts
        self.e_prev = (e1, e2, e3)
        kp1, kp2, kp3, kd1, kd2, kd3, ki1, ki2, ki3 = self._gains
        return (
            kp1 * e1 + kd1 * ((e1 - p1) / Ts) + ki1 * i1,
            kp2 * e2 + kd2 * ((e2 - p2) / Ts) + ki2 * i2,
            kp3 * e3 + kd3 * ((e3 - p3) / Ts) + ki3 * i3,
        )

    def __call__(self, q: np.ndarray, q_des: np.ndarray) -> np.ndarray:
        """Torque [N m] for the joint angles q [rad] and the target q_des [rad]."""
        return np.array(self.update(*_floats(q), *_floats(q_des)))


class PositionController(Controller):
    """PID to a joint target, or to a Cartesian foot target via the IK solution nearest the state."""

    name = "position"

    def __init__(self, event: Event, gains: Gains, Ts: float) -> None:
        self.event = event
        self.pid = PID(gains, Ts)
        self.q_des = np.zeros(3)
        self._r = (0.0, 0.0, 0.0)

    def start(self, t: float, q: np.ndarray, qd: np.ndarray) -> None:
        if self.event.joint is not None:
            self.q_des = np.array(self.event.joint)
        else:
            self.q_des = kinematics.ik_nearest(np.array(self.event.cartesian), q)
        self._r = _floats(self.q_des)
        self.pid.reset()

    def torque(self, k: int, q1: float, q2: float, q3: float, qd1: float, qd2: float, qd3: float) -> tuple[float, ...]:
        r1, r2, r3 = self._r
        return self.pid.update(q1, q2, q3, r1, r2, r3)


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

    u = Kp d(q, q_d(t)) + Kd (qd_d(t) - qd) + Ki integral(d). The trajectory starts
    from the measured state at activation; segments are cubic in position and
    velocity at both ends (as ros_control's joint_trajectory_controller). The
    desired state is the spline at the control instants after activation,
    held at the last waypoint (velocity 0) after the last waypoint time.

    Only the spline's coefficients are kept (memory per waypoint, not per
    tick); :meth:`desired_scalar` evaluates them at each tick with the same
    floating-point operations, in the same order, as scipy's ``PPoly`` (power
    sum from the constant term up, ``s = t - t_i`` in the interval
    ``t_i <= t < t_i+1``, closed at the last knot), so the values equal
    ``spline(t)`` and ``spline(t, 1)`` on the control grid bit for bit.
    """

    name = "trajectory"

    def __init__(self, event: Event, gains: Gains, Ts: float, n_ticks: int) -> None:
        self.event = event
        self.Kp = np.array(gains.Kp)
        self.Kd = np.array(gains.Kd)
        self.Ki = np.array(gains.Ki)
        self.Ts = Ts
        self.n_ticks = n_ticks
        self.params = load_params()
        self._gains = (*gains.Kp, *gains.Kd, *gains.Ki)
        self._wrap = tuple(bool(c) for c in self.params.continuous)
        self.k0 = 0
        self._last = 0  # last tick offset from k0 with its own desired state
        self._x: list[float] = [0.0, 1.0]  # knot times after activation [s]
        self._coef = np.zeros((1, 12))  # per interval: (c3, c2, c1, c0) of joints 1, 2, 3 (highest power first)
        self._seg: tuple[float, ...] = (0.0, 0.0, *([0.0] * 12))  # the current interval (see _interval)
        self._i = (0.0, 0.0, 0.0)
        self.knots_q = np.zeros((1, 3))
        self.knots_t = np.zeros(1)

    @property
    def integral(self) -> np.ndarray:
        """Integral of the tracking error [rad s]."""
        return np.array(self._i)

    def start(self, t: float, q: np.ndarray, qd: np.ndarray) -> None:
        Qw = joint_waypoints(np.array(self.event.waypoints), q, self.params)
        Q = np.vstack([q, Qw])
        times = np.concatenate([[0.0], self.event.times])
        V = waypoint_velocities(Q, times, np.asarray(qd, float))
        spline = CubicHermiteSpline(times, Q, V, axis=0)
        self.k0 = int(round(t / self.Ts))
        self._last = max(self.n_ticks - self.k0, 1) - 1
        self._x = times.tolist()
        c = spline.c  # (4, intervals, 3), highest power first
        self._coef = np.ascontiguousarray(c.transpose(1, 2, 0).reshape(c.shape[1], 12))
        self._seg = self._interval(0.0)
        self.knots_q, self.knots_t = Q, times
        self._i = (0.0, 0.0, 0.0)

    def _interval(self, xt: float) -> tuple[float, ...]:
        """(t_j, t_j+1, the interval's 12 coefficients) of the interval holding xt, as ``PPoly`` picks it: the
        last knot's interval extends to +inf (``t_end`` belongs to it)."""
        knots = self._x
        j = bisect_right(knots, xt) - 1
        if j > len(knots) - 2:
            j = len(knots) - 2
        hi = knots[j + 1] if j < len(knots) - 2 else math.inf
        return (knots[j], hi, *self._coef[j].tolist())

    def desired_scalar(self, k: int) -> tuple[float, float, float, float, float, float]:
        """Desired (q_d [rad], qd_d [rad/s]) at tick k, as six floats."""
        i = k - self.k0
        x = (i if i < self._last else self._last) * self.Ts  # time since activation [s]
        t_end = self._x[-1]
        xt = t_end if x > t_end else x
        lo, hi, a0, a1, a2, a3, b0, b1, b2, b3, c0, c1, c2, c3 = self._seg
        if not lo <= xt < hi:  # another interval (ticks move forward: once per knot)
            lo, hi, a0, a1, a2, a3, b0, b1, b2, b3, c0, c1, c2, c3 = self._seg = self._interval(xt)
        s = xt - lo
        s2 = s * s
        s3 = s2 * s
        r1 = 0.0 + a3 + a2 * s + a1 * s2 + a0 * s3
        r2 = 0.0 + b3 + b2 * s + b1 * s2 + b0 * s3
        r3 = 0.0 + c3 + c2 * s + c1 * s2 + c0 * s3
        if x < t_end:
            return (r1, r2, r3, 0.0 + a2 + a1 * s * 2.0 + a0 * s2 * 3.0, 0.0 + b2 + b1 * s * 2.0 + b0 * s2 * 3.0,
                    0.0 + c2 + c1 * s * 2.0 + c0 * s2 * 3.0)  # fmt: skip
        return r1, r2, r3, 0.0, 0.0, 0.0

    def desired(self, k: int) -> tuple[np.ndarray, np.ndarray]:
        """Desired q_d [rad] and qd_d [rad/s] at tick k."""
        d = self.desired_scalar(k)
        return np.array(d[:3]), np.array(d[3:])

    def torque(self, k: int, q1: float, q2: float, q3: float, qd1: float, qd2: float, qd3: float) -> tuple[float, ...]:
        r1, r2, r3, v1, v2, v3 = self.desired_scalar(k)
        e1, e2, e3, i1, i2, i3 = _error_integral(self, q1, q2, q3, r1, r2, r3)
        kp1, kp2, kp3, kd1, kd2, kd3, ki1, ki2, ki3 = self._gains
        return (
            kp1 * e1 + kd1 * (v1 - qd1) + ki1 * i1,
            kp2 * e2 + kd2 * (v2 - qd2) + ki2 * i2,
            kp3 * e3 + kd3 * (v3 - qd3) + ki3 * i3,
        )


_NO_FORCE = (0.0, 0.0, 0.0)


class EffortController(Controller):
    """tau = Jv(q)^T h_d + G(q): the foot pushes on the environment with h_d in W [N].

    With the event's ``force_delay`` [s], h_d is zero for that many control periods
    after the switch (tau = G(q): gravity compensation only), then the event's force.
    """

    name = "effort"

    def __init__(self, event: Event, Ts: float = 1e-3) -> None:
        self.h_d = np.array(event.force, dtype=float)
        self._h = _floats(self.h_d)
        self._geometry = g = load_params().geometry
        self._lengths = (g.L_12, g.L_23, g.L_3E)
        self._gravity = kinematics.GravityTorque()
        self.n_force_delay = int(round(event.force_delay / Ts))  # control periods with h_d = 0
        self.Ts = Ts
        self.k_force = 0  # first tick with the event's force

    def start(self, t: float, q: np.ndarray, qd: np.ndarray) -> None:
        self.k_force = int(round(t / self.Ts)) + self.n_force_delay

    def torque(self, k: int, q1: float, q2: float, q3: float, qd1: float, qd2: float, qd3: float) -> tuple[float, ...]:
        hx, hy, hz = self._h if k >= self.k_force else _NO_FORCE
        # kinematics.jacobian_scalar inlined on the lengths bound at construction (the same operations)
        L_12, L_23, L_3E = self._lengths
        sin, cos = math.sin, math.cos
        s1, c1 = sin(q1), cos(q1)
        s23 = sin(q2 + q3)
        c23 = cos(q2 + q3)
        reach = L_23 * sin(q2) + L_3E * s23
        dreach2 = L_23 * cos(q2) + L_3E * c23
        dreach3 = L_3E * c23
        j11, j12, j13 = -(L_12 * s1 + c1 * reach), -(s1 * dreach2), -(s1 * dreach3)
        j21, j22, j23 = 0.0, -reach, -(L_3E * s23)
        j31, j32, j33 = L_12 * c1 - s1 * reach, c1 * dreach2, c1 * dreach3
        g1, g2, g3 = self._gravity(q1, q2, q3)
        return (
            j11 * hx + j21 * hy + j31 * hz + g1,
            j12 * hx + j22 * hy + j32 * hz + g2,
            j13 * hx + j23 * hy + j33 * hz + g3,
        )


class TorqueController(Controller):
    """Open loop: tau_i = A_i sin(2 pi f_i (t - t_event) + phi_i) [N m], whatever the state.

    The torque of tick k is the value at t = k Ts (held over the period by the backend).
    """

    name = "torque"

    def __init__(self, event: Event, Ts: float) -> None:
        if event.amplitude is None or event.frequency is None:
            raise ValueError("a torque event needs amplitude and frequency")
        self.Ts = Ts
        self._a = _floats(event.amplitude)
        self._w = _floats(2.0 * math.pi * np.asarray(event.frequency, dtype=float) * Ts)  # [rad per tick]
        self._phi = _floats(event.phase if event.phase is not None else (0.0, 0.0, 0.0))
        self.k0 = int(round(event.t / Ts))

    def start(self, t: float, q: np.ndarray, qd: np.ndarray) -> None:
        self.k0 = int(round(t / self.Ts))

    def torque(self, k: int, q1: float, q2: float, q3: float, qd1: float, qd2: float, qd3: float) -> tuple[float, ...]:
        a1, a2, a3 = self._a
        w1, w2, w3 = self._w
        p1, p2, p3 = self._phi
        n = k - self.k0
        sin = math.sin
        return a1 * sin(w1 * n + p1), a2 * sin(w2 * n + p2), a3 * sin(w3 * n + p3)


def make_controller(event: Event, gains: Gains, Ts: float, n_ticks: int) -> Controller:
    """The controller an event asks for."""
    if event.controller == "position":
        return PositionController(event, gains, Ts)
    if event.controller == "trajectory":
        return TrajectoryController(event, gains, Ts, n_ticks)
    if event.controller == "effort":
        return EffortController(event, Ts)
    if event.controller == "torque":
        return TorqueController(event, Ts)
    raise ValueError(f"unknown controller {event.controller!r}")
