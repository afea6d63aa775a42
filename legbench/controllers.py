"""The one controller stack (LEG_SPEC.md section 6), run by the harness for every backend.

Every controller is discrete at the control rate and returns joint torques
[N m] before saturation; the run loop saturates them at the joint limits
(:func:`saturate`). A controller is started with the measured state when its
event fires (:meth:`Controller.start`), then called once per tick.
"""

from __future__ import annotations

from abc import ABC, abstractmethod

import numpy as np
from scipy.interpolate import CubicHermiteSpline

from legbench import kinematics
from legbench.model import LegParams, load_params
from legbench.scenario import Event, Gains


def saturate(tau: np.ndarray, limit: np.ndarray) -> np.ndarray:
    """Clip joint torques to +-limit [N m] (in place, returned)."""
    np.clip(tau, -limit, limit, out=tau)
    return tau


class Controller(ABC):
    """A torque controller for the leg."""

    name: str = ""

    @abstractmethod
    def start(self, t: float, q: np.ndarray, qd: np.ndarray) -> None:
        """Activate at time t [s] from the measured q [rad], qd [rad/s]."""

    @abstractmethod
    def __call__(self, k: int, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        """Torque [N m] at control tick k (t = k Ts) for the measured state."""


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
        self.e_prev: np.ndarray | None = None
        self.integral = np.zeros(3)

    def reset(self) -> None:
        self.e_prev = None
        self.integral[:] = 0.0

    def __call__(self, q: np.ndarray, q_des: np.ndarray) -> np.ndarray:
        e = kinematics.joint_error(q, q_des, self.params)
        if self.e_prev is None:
            self.e_prev = e
        edot = (e - self.e_prev) / self.Ts
        self.integral += e * self.Ts
        self.e_prev = e
        return self.Kp * e + self.Kd * edot + self.Ki * self.integral


class PositionController(Controller):
    """PID to a joint target, or to a Cartesian foot target via the IK solution nearest the state."""

    name = "position"

    def __init__(self, event: Event, gains: Gains, Ts: float) -> None:
        self.event = event
        self.pid = PID(gains, Ts)
        self.q_des = np.zeros(3)

    def start(self, t: float, q: np.ndarray, qd: np.ndarray) -> None:
        if self.event.joint is not None:
            self.q_des = np.array(self.event.joint)
        else:
            self.q_des = kinematics.ik_nearest(np.array(self.event.cartesian), q)
        self.pid.reset()

    def __call__(self, k: int, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        return self.pid(q, self.q_des)


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
    desired state is sampled on the control grid once, at activation.
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
        self.k0 = 0
        self.q_d = np.zeros((1, 3))
        self.qd_d = np.zeros((1, 3))
        self.integral = np.zeros(3)
        self.knots_q = np.zeros((1, 3))
        self.knots_t = np.zeros(1)

    def start(self, t: float, q: np.ndarray, qd: np.ndarray) -> None:
        Qw = joint_waypoints(np.array(self.event.waypoints), q, self.params)
        Q = np.vstack([q, Qw])
        times = np.concatenate([[0.0], self.event.times])
        V = waypoint_velocities(Q, times, np.asarray(qd, float))
        spline = CubicHermiteSpline(times, Q, V, axis=0)
        self.k0 = int(round(t / self.Ts))
        n = max(self.n_ticks - self.k0, 1)
        tt = np.minimum(np.arange(n) * self.Ts, times[-1])
        self.q_d = spline(tt)
        self.qd_d = np.where((np.arange(n) * self.Ts < times[-1])[:, None], spline(tt, 1), 0.0)
        self.knots_q, self.knots_t = Q, times
        self.integral[:] = 0.0

    def desired(self, k: int) -> tuple[np.ndarray, np.ndarray]:
        """Desired q_d [rad] and qd_d [rad/s] at tick k."""
        i = min(k - self.k0, len(self.q_d) - 1)
        return self.q_d[i], self.qd_d[i]

    def __call__(self, k: int, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        q_d, qd_d = self.desired(k)
        e = kinematics.joint_error(q, q_d, self.params)
        self.integral += e * self.Ts
        return self.Kp * e + self.Kd * (qd_d - qd) + self.Ki * self.integral


class EffortController(Controller):
    """tau = Jv(q)^T h_d + G(q): the foot pushes on the environment with h_d in W [N]."""

    name = "effort"

    def __init__(self, event: Event) -> None:
        self.h_d = np.array(event.force, dtype=float)

    def start(self, t: float, q: np.ndarray, qd: np.ndarray) -> None:
        pass

    def __call__(self, k: int, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        return kinematics.jacobian(q).T @ self.h_d + kinematics.gravity(q)


def make_controller(event: Event, gains: Gains, Ts: float, n_ticks: int) -> Controller:
    """The controller an event asks for."""
    if event.controller == "position":
        return PositionController(event, gains, Ts)
    if event.controller == "trajectory":
        return TrajectoryController(event, gains, Ts, n_ticks)
    if event.controller == "effort":
        return EffortController(event)
    raise ValueError(f"unknown controller {event.controller!r}")
