"""Each controller on its own, against hand-computed values."""

from __future__ import annotations

import numpy as np
import pytest

from legbench import kinematics as K
from legbench.controllers import (
    PID,
    EffortController,
    TrajectoryController,
    joint_waypoints,
    saturate,
    waypoint_velocities,
)
from legbench.model import load_params
from legbench.scenario import Event, Gains, ellipse_waypoints

TS = 1e-3


def test_pid_discrete_form_by_hand() -> None:
    """u = Kp e + Kd (e - e_prev)/Ts + Ki sum(e Ts); first tick has no derivative kick."""
    pid = PID(Gains(Kp=(10.0,) * 3, Kd=(1.0,) * 3, Ki=(2.0,) * 3), TS)
    q_des = np.array([0.1, 0.2, -0.3])
    u0 = pid(np.zeros(3), q_des)
    np.testing.assert_allclose(u0, 10 * q_des + 2 * q_des * TS, atol=1e-15)
    q1 = np.array([0.05, 0.1, -0.1])
    e1 = q_des - q1
    u1 = pid(q1, q_des)
    np.testing.assert_allclose(u1, 10 * e1 + (e1 - q_des) / TS + 2 * (q_des + e1) * TS, atol=1e-12)


def test_pid_takes_the_short_way_round_on_the_continuous_hip() -> None:
    """Hip at 3.1 rad, target -3.1 rad: the error is +0.083 rad (through pi), not -6.2 rad."""
    pid = PID(Gains(Kp=(10.0,) * 3, Kd=(0.0,) * 3, Ki=(0.0,) * 3), TS)
    u = pid(np.array([0.0, 3.1, 0.0]), np.array([0.0, -3.1, 0.0]))
    assert u[1] == pytest.approx(10 * (2 * np.pi - 6.2), abs=1e-12)


def test_saturation_clips_at_the_joint_torque_limits() -> None:
    lim = load_params().effort
    tau = saturate(np.array([100.0, -100.0, 1.0]), lim)
    np.testing.assert_allclose(tau, [lim[0], -lim[1], 1.0])


def test_velocity_rule_for_waypoints() -> None:
    """Mean segment velocities w = (2, 1) -> interior knot (2+1)/2; sign change (2, -1) -> 0; last 0."""
    Q = np.array([[0.0, 0.0, 0.0], [2.0, 2.0, 1.0], [3.0, 1.0, 1.0]])
    times = np.array([0.0, 1.0, 2.0])
    V = waypoint_velocities(Q, times, np.array([0.5, 0.0, 0.0]))
    np.testing.assert_allclose(V[0], [0.5, 0.0, 0.0])
    np.testing.assert_allclose(V[1], [1.5, 0.0, 0.0])  # joint 3: w = (1, 0): 0 has no sign -> 0
    np.testing.assert_allclose(V[2], 0.0)


def test_trajectory_passes_through_its_waypoints_with_the_rule_velocities() -> None:
    """At each waypoint time the desired state equals the IK solution and the rule's velocity (1e-9)."""
    pts = [[0.1667, 0.05, 0.10], [0.1667, 0.10, 0.12], [0.1667, 0.15, 0.10]]
    times = (0.5, 1.0, 1.5)
    ev = Event(0.2, "trajectory", waypoints=tuple(map(tuple, pts)), times=times)
    ctrl = TrajectoryController(ev, Gains(), TS, n_ticks=3000)
    q0 = np.array([0.0, -0.6, -1.2])
    ctrl.start(0.2, q0, np.zeros(3))
    Qw = joint_waypoints(np.array(pts), q0)
    V = waypoint_velocities(np.vstack([q0, Qw]), np.array([0.0, *times]), np.zeros(3))
    k0 = 200
    for i, tw in enumerate(times):
        qd_, vd_ = ctrl.desired(k0 + int(round(tw / TS)))
        np.testing.assert_allclose(qd_, Qw[i], atol=1e-9)
        if i < len(times) - 1:
            np.testing.assert_allclose(vd_, V[i + 1], atol=1e-9)
        np.testing.assert_allclose(K.fk(qd_), pts[i], atol=1e-9)
    q_start, _ = ctrl.desired(k0)
    np.testing.assert_allclose(q_start, q0, atol=1e-12)  # starts from the measured state
    q_end, v_end = ctrl.desired(2999)
    np.testing.assert_allclose(q_end, Qw[-1], atol=1e-12)  # holds the last point
    np.testing.assert_allclose(v_end, 0.0)


def test_ellipse_waypoints_lie_on_the_ellipse() -> None:
    """(y - DY)^2/a^2 + (z - DZ)^2/b^2 = 1 for dth = 0, x = L_B0 + L12, N points per period (1e-12)."""
    a, b, DY, DZ = 0.15, 0.06, 0.11208, 0.105
    P, t = ellipse_waypoints(a, b, DY, DZ, 0.0, 5.0, 50, 2, 1.0)
    g = load_params().geometry
    assert P.shape == (101, 3)
    np.testing.assert_allclose(P[:, 0], g.L_B0 + g.L_12)
    np.testing.assert_allclose(((P[:, 1] - DY) / a) ** 2 + ((P[:, 2] - DZ) / b) ** 2, 1.0, atol=1e-12)
    np.testing.assert_allclose(np.diff(t), 0.1)
    assert t[0] == 1.0 and t[-1] == pytest.approx(11.0)


def test_effort_controller_is_jt_h_plus_gravity() -> None:
    q = np.array([-0.0025, -1.1899, -1.2599])
    ctrl = EffortController(Event(0.0, "effort", force=(0.0, 0.0, -100.0)))
    tau = ctrl(0, q, np.zeros(3))
    np.testing.assert_allclose(tau, K.jacobian(q).T @ [0, 0, -100.0] + K.gravity(q), atol=1e-12)
