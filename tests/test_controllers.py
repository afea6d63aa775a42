"""Each controller on its own, against hand-computed values."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from scipy.interpolate import CubicHermiteSpline

from legbench import kinematics as K
from legbench import model, resources, scenario
from legbench.controllers import (
    PID,
    EffortController,
    TorqueController,
    TrajectoryController,
    joint_waypoints,
    make_controller,
    saturate,
    waypoint_velocities,
)
from legbench.model import load_params
from legbench.scenario import Event, Gains
from legbench.trajectories import ellipse_waypoints

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


def test_ellipse_waypoints_of_a_tilted_ellipse_lie_on_it_with_a_along_dth() -> None:
    """With dth = 0.4 rad the ellipse is turned by dth in the y-z plane: in axes turned by dth about the centre,
    (u/a)^2 + (v/b)^2 = 1 (1e-12); the farthest of 4000 points per lap lies in the direction dth or dth + pi
    (within the points' spacing, d = 2 pi / 4000 rad) at a from the centre, the nearest at b (within a d^2,
    3.7e-7 m: off the axis by at most d, r falls short of a by about a d^2 / 2 (1 - b^2/a^2))."""
    a, b, DY, DZ, dth = 0.15, 0.06, 0.11208, 0.105, 0.4
    P, _ = ellipse_waypoints(a, b, DY, DZ, dth, 5.0, 4000, 1, 1.0)
    y, z = P[:, 1] - DY, P[:, 2] - DZ
    u, v = y * np.cos(dth) + z * np.sin(dth), -y * np.sin(dth) + z * np.cos(dth)
    np.testing.assert_allclose((u / a) ** 2 + (v / b) ** 2, 1.0, atol=1e-12)
    r = np.hypot(y, z)
    far = int(np.argmax(r))
    d = 2 * np.pi / 4000
    assert r[far] == pytest.approx(a, abs=a * d**2) and r.min() == pytest.approx(b, abs=a * d**2)
    off = np.mod(np.arctan2(z[far], y[far]) - dth + np.pi / 2, np.pi) - np.pi / 2  # dth and dth + pi alike
    assert abs(off) <= d


def test_effort_controller_is_jt_h_plus_gravity() -> None:
    q = np.array([-0.0025, -1.1899, -1.2599])
    ctrl = EffortController(Event(0.0, "effort", force=(0.0, 0.0, -100.0)))
    tau = ctrl(0, q, np.zeros(3))
    np.testing.assert_allclose(tau, K.jacobian(q).T @ [0, 0, -100.0] + K.gravity(q), atol=1e-12)


def test_effort_controller_compensates_the_scenarios_gravity() -> None:
    """G(q) of tau = Jv^T h_d + G(q) is for the scenario's physics.gravity, the gravity the backends simulate.

    A scenario (the effort task) with physics.gravity = 3.71 m/s^2: the torque at q* equals
    Jv^T h_d + G(q) of a Pinocchio model at 3.71 m/s^2 to 1e-12 N m (G(q) from the leg file's 9.81 is off
    by up to 0.65 N m there). The default scenario (9.81) and no gravity given keep the leg file's G(q),
    bit for bit.
    """
    q = np.array([-0.0025, -1.1899, -1.2599])
    h_d = np.array([0.0, 0.0, -100.0])
    sc = scenario.load(resources.scenario("effort"), {"physics.gravity": 3.71})
    gravity = scenario.physics_of(sc).gravity
    assert gravity == 3.71
    ctrl = make_controller(sc.events[0], sc.gains, sc.control_dt, sc.n_ticks, gravity)
    ctrl.start(0.0, q, np.zeros(3))
    mars = model.pinocchio_model(gravity=3.71)
    G = pin.computeGeneralizedGravity(mars, mars.createData(), model.q_to_pin(q))
    np.testing.assert_allclose(ctrl(0, q, np.zeros(3)), K.jacobian(q).T @ h_d + G, rtol=0, atol=1e-12)
    default = scenario.load(resources.scenario("effort"))
    earth = make_controller(default.events[0], default.gains, default.control_dt, default.n_ticks,
                            scenario.physics_of(default).gravity)  # fmt: skip
    unset = EffortController(Event(0.0, "effort", force=(0.0, 0.0, -100.0)))
    np.testing.assert_array_equal(earth.params, unset.params)
    np.testing.assert_allclose(unset(0, q, np.zeros(3)), K.jacobian(q).T @ h_d + K.gravity(q), rtol=0, atol=1e-12)


def test_torque_controller_is_open_loop_sinusoids_from_its_activation() -> None:
    """tau_i = A_i sin(2 pi f_i (k Ts - t_event) + phi_i) whatever the state: by hand at a few ticks (1e-15 N m)."""
    ev = Event(0.5, "torque", amplitude=(0.01, 0.02, -0.03), frequency=(3.0, 1.0, 0.0), phase=(0.0, 0.5, 1.0))
    ctrl = TorqueController(ev, TS)
    ctrl.start(0.5, np.zeros(3), np.zeros(3))
    for k in (500, 583, 1234):
        t = (k - 500) * TS
        want = [0.01 * np.sin(6 * np.pi * t), 0.02 * np.sin(2 * np.pi * t + 0.5), -0.03 * np.sin(1.0)]
        np.testing.assert_allclose(ctrl(k, np.array([1.0, -2.0, 0.3]), np.array([5.0, 0, 0])), want, atol=1e-15)
        np.testing.assert_array_equal(ctrl(k, np.zeros(3), np.zeros(3)), ctrl(k, np.ones(3), -np.ones(3)))


def _bits(x: np.ndarray | tuple[float, ...]) -> np.ndarray:
    return np.asarray(x, dtype=float).view(np.int64)


def test_trajectory_desired_state_is_the_scipy_spline_on_the_control_grid_bit_for_bit() -> None:
    """Evaluated per tick on floats, q_d and qd_d equal scipy's spline(t) and spline(t, 1) exactly (activation
    mid-run, hold after the last waypoint), so the float path changes no logged bit."""
    pts = [[0.1667, 0.05, 0.10], [0.1667, 0.10, 0.12], [0.1667, 0.15, 0.10], [0.1667, 0.12, 0.06]]
    times = (0.5, 1.0, 1.5, 1.7)
    ev = Event(0.2, "trajectory", waypoints=tuple(map(tuple, pts)), times=times)
    n_ticks = 2500
    ctrl = TrajectoryController(ev, Gains(), TS, n_ticks=n_ticks)
    q0, qd0 = np.array([0.0, -0.6, -1.2]), np.array([0.1, -0.2, 0.3])
    ctrl.start(0.2, q0, qd0)
    Q = np.vstack([q0, joint_waypoints(np.array(pts), q0)])
    knots = np.array([0.0, *times])
    spline = CubicHermiteSpline(knots, Q, waypoint_velocities(Q, knots, qd0), axis=0)
    i = np.arange(n_ticks - 200)
    tt = np.minimum(i * TS, knots[-1])
    P = spline(tt)
    V = np.where((i * TS < knots[-1])[:, None], spline(tt, 1), 0.0)
    for k in range(200, n_ticks):
        d = ctrl.desired_scalar(k)
        np.testing.assert_array_equal(_bits(d), _bits(np.concatenate([P[k - 200], V[k - 200]])), err_msg=f"tick {k}")


def test_trajectory_feedback_law_by_hand() -> None:
    """u = Kp d(q, q_d) + Kd (qd_d - qd) + Ki sum(d Ts) with the measured state off the desired one (position
    by 0.02-0.3 rad, the hip a full turn plus 0.03 rad away: the short way round; velocity by 0.1-0.8 rad/s) at
    six ticks, on the spline, at a knot and after the hold, q_d and qd_d from scipy's spline: 1e-12 N m (|u| up to
    ~4 N m)."""
    pts = [[0.1667, 0.05, 0.10], [0.1667, 0.10, 0.12], [0.1667, 0.15, 0.10]]
    times = (0.5, 1.0, 1.5)
    ev = Event(0.2, "trajectory", waypoints=tuple(map(tuple, pts)), times=times)
    gains = Gains(Kp=(10.0, 12.0, 9.0), Kd=(1.0, 0.7, 1.3), Ki=(50.0, 40.0, 30.0))
    ctrl = TrajectoryController(ev, gains, TS, n_ticks=2500)
    q0, qd0 = np.array([0.0, -0.6, -1.2]), np.array([0.1, -0.2, 0.3])
    ctrl.start(0.2, q0, qd0)
    Q = np.vstack([q0, joint_waypoints(np.array(pts), q0)])
    knots = np.array([0.0, *times])
    spline = CubicHermiteSpline(knots, Q, waypoint_velocities(Q, knots, qd0), axis=0)
    Kp, Kd, Ki = np.array(gains.Kp), np.array(gains.Kd), np.array(gains.Ki)
    dq = np.array([[0.02, -0.05, 0.1], [-0.3, 0.03 + 2 * np.pi, -0.02], [0.1, -0.1, 0.25]])
    dqd = np.array([[0.5, -0.3, 0.1], [-0.8, 0.2, 0.4], [0.3, 0.6, -0.5]])
    integral = np.zeros(3)
    for n, k in enumerate((200, 201, 202, 650, 1200, 2400)):  # 1200: the knot at 1.0 s; 2400: held since 1700
        t = min((k - 200) * TS, knots[-1])
        q_d, qd_d = spline(t), (spline(t, 1) if (k - 200) * TS < knots[-1] else np.zeros(3))
        q, qd = q_d + dq[n % 3], qd_d + dqd[n % 3]
        e = K.joint_error(q, q_d)  # hip: +-0.03 rad the short way, not 6.3 rad
        assert np.abs(e).max() < 0.31
        integral += e * TS
        want = Kp * e + Kd * (qd_d - qd) + Ki * integral
        np.testing.assert_allclose(ctrl(k, q, qd), want, rtol=0, atol=1e-12, err_msg=f"tick {k}")
        np.testing.assert_allclose(ctrl.integral, integral, rtol=0, atol=1e-15)


def test_pid_float_path_equals_the_numpy_formula_bit_for_bit() -> None:
    """u = Kp e + Kd (e - e_prev)/Ts + Ki I in numpy arrays, tick by tick, against the controller's floats."""
    gains = Gains(Kp=(10.0, 12.0, 9.0), Kd=(1.0, 0.7, 1.3), Ki=(2.0, 0.5, 1.0))
    pid = PID(gains, TS)
    rng = np.random.default_rng(3)
    q_des = np.array([0.3, 3.0, -1.0])
    e_prev, integral = None, np.zeros(3)
    for q in rng.uniform(-3.5, 3.5, size=(500, 3)):
        e = K.joint_error(q, q_des)
        e_prev = e if e_prev is None else e_prev
        integral += e * TS
        ref = np.array(gains.Kp) * e + np.array(gains.Kd) * ((e - e_prev) / TS) + np.array(gains.Ki) * integral
        e_prev = e
        np.testing.assert_array_equal(_bits(pid(q, q_des)), _bits(ref))


def test_effort_float_path_equals_the_numpy_formula_bit_for_bit() -> None:
    """J^T h_d + G(q) with h_d along one axis (the tasks' (0, 0, -100) N): one rounding per product, so
    matrix product and scalar sums agree exactly (G(q) on floats, which test_kinematics checks against
    Pinocchio's)."""
    ctrl = EffortController(Event(0.0, "effort", force=(0.0, 0.0, -100.0)))
    rng = np.random.default_rng(4)
    a = K.gravity_arrays()
    for q in rng.uniform(-2.0, 2.0, size=(300, 3)):
        q1, q2, q3 = q.tolist()
        ref = K.jacobian(q).T @ np.array([0.0, 0.0, -100.0]) + np.array(K.gravity_scalar(q1, q2, q3, a))
        np.testing.assert_array_equal(_bits(ctrl(0, q, np.zeros(3))), _bits(ref))
