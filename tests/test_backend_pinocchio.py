"""The Pinocchio ABA backend: dynamics against an independent integration, energy, contact statics."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from scipy.integrate import solve_ivp

from legbench import kinematics as K
from legbench import model, run, scenario
from legbench.backends import load as registry_load
from legbench.backends.base import Physics
from legbench.backends.pinocchio_ import PinocchioBackend
from legbench.contact import ContactParams

SCENARIOS = Path(__file__).resolve().parent.parent / "scenarios"
NO_CONTACT = ContactParams(Kp=0.0, Kd=0.0)  # Fn = 0 whatever the pose
T_CTRL = 1e-3


def _backend(settings: dict, gravity: float = 0.0, contact: ContactParams = NO_CONTACT) -> PinocchioBackend:  # type: ignore[type-arg]
    be = PinocchioBackend()
    be.load(model.URDF_FILE, Physics(gravity=gravity, contact=contact, control_dt=T_CTRL), settings)
    return be


def _torque(k: int) -> np.ndarray:
    """Small sinusoidal torque [N m] held over control period k."""
    t = k * T_CTRL
    return np.array(
        [0.1 * np.sin(2 * np.pi * 1.0 * t), 0.05 * np.sin(2 * np.pi * 1.5 * t + 0.3), 0.01 * np.cos(3.0 * t)]
    )


def _reference(q0: np.ndarray, n: int, gravity: float = 0.0) -> np.ndarray:
    """Independent solution of M(q) qdd + C(q, qd) qd + G(q) = tau with crba/rnea and DOP853 at rtol 1e-12."""
    m = pin.buildModelFromUrdf(str(model.URDF_FILE))
    m.gravity.linear = np.array([0.0, 0.0, -gravity])
    d = m.createData()

    def f(_t: float, x: np.ndarray, tau: np.ndarray) -> np.ndarray:
        qp = model.q_to_pin(x[:3])
        M = pin.crba(m, d, qp)
        M = np.triu(M) + np.triu(M, 1).T
        h = pin.rnea(m, d, qp, x[3:], np.zeros(3))  # C qd + G
        return np.concatenate([x[3:], np.linalg.solve(M, tau - h)])

    x = np.concatenate([q0, np.zeros(3)])
    out = [x[:3]]
    for k in range(n):
        sol = solve_ivp(f, (0, T_CTRL), x, args=(_torque(k),), method="DOP853", rtol=1e-12, atol=1e-14)
        x = sol.y[:, -1]
        out.append(x[:3])
    return np.array(out)


def _drive(be: PinocchioBackend, q0: np.ndarray, n: int) -> np.ndarray:
    be.reset(q0, np.zeros(3))
    out = [be.state()[0]]
    for k in range(n):
        be.step(_torque(k))
        out.append(be.state()[0])
    return np.array(out)


Q0 = np.array([0.2, -0.8, -1.0])


def test_free_dynamics_match_an_independent_crba_rnea_integration() -> None:
    """Gravity off, sinusoidal torques, 1 s. RK4 at 0.1 ms: local error O(h^5) -> 1e-9 rad;
    semi-implicit Euler at the default 50 us is first order: within 0.1 % of amplitude."""
    n = 1000
    ref = _reference(Q0, n)
    rk4 = _drive(_backend({"integrator": "rk4", "dt": 1e-4}), Q0, n)
    np.testing.assert_allclose(rk4, ref, atol=1e-9)
    eul = _drive(_backend({}), Q0, n)
    amp = np.abs(ref - Q0).max(axis=0)
    assert np.all(np.abs(eul - ref).max(axis=0) / amp * 100 < 0.1)
    dop = _drive(_backend({"integrator": "dop853", "rtol": 1e-11, "atol": 1e-13}), Q0, 200)
    np.testing.assert_allclose(dop, ref[:201], atol=1e-9)


def test_energy_is_conserved_without_torque_contact_or_damping() -> None:
    """Gravity on, zero torque, no contact, limits not reached: |E(t) - E(0)| / E_scale < 1e-6 over 2 s (RK4, 0.1 ms).
    E_scale is the kinetic energy range swept (the potential's zero is arbitrary)."""
    be = _backend({"integrator": "rk4", "dt": 1e-4}, gravity=9.81)
    m = be.model
    d = m.createData()
    q0, qd0 = np.array([0.3, -1.2, -1.0]), np.array([1.0, 2.0, -1.0])
    be.reset(q0, qd0)

    def energy() -> tuple[float, float]:
        q, qd = be.state()
        ke = pin.computeKineticEnergy(m, d, model.q_to_pin(q), qd)
        pe = pin.computePotentialEnergy(m, d, model.q_to_pin(q))
        return ke + pe, ke

    E0, _ = energy()
    Es, kes = [], []
    for _ in range(2000):
        be.step(np.zeros(3))
        E, ke = energy()
        Es.append(E)
        kes.append(ke)
        q = be.state()[0]
        assert abs(q[2]) < 2.229 and abs(q[0]) < np.pi / 2  # no limit spring involved
    scale = max(kes)
    assert max(abs(E - E0) for E in Es) / scale < 1e-6


def test_knee_limit_holds_like_an_engine_limit() -> None:
    """10 N m pushing the knee into its 2.229 rad limit rests within 0.005 rad of it
    (MuJoCo rests at 2.2292, PyBullet at 2.2293)."""
    be = _backend({}, gravity=0.0)
    be.reset(np.array([0.0, -0.5, 2.0]), np.zeros(3))
    for _ in range(1000):
        be.step(np.array([0.0, 0.0, 10.0]))
    q3 = be.state()[0][2]
    assert 2.229 < q3 < 2.234


def _effort_steady(poc: str = "true") -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    sc = scenario.load(SCENARIOS / "effort.yaml", {"physics.contact.poc": poc})
    (tr,) = run.run(sc, ["pinocchio"], None, progress=False)
    w = tr.t >= tr.t[-1] - sc.comparison.steady_window
    return tr.q[w].mean(0), tr.tau[w].mean(0), tr.f[w].mean(0)


def test_effort_task_ground_force_satisfies_static_balance() -> None:
    """Steady state: ground force F on the foot = -(J_poc^T)^-1 (tau - G) within 1 %; friction inside mu_s Fn."""
    q, tau, F = _effort_steady()
    h = np.linalg.solve(K.jacobian_poc(q).T, tau - K.gravity(q))
    assert np.linalg.norm(F + h) / np.linalg.norm(F) < 0.01
    assert F[2] > 20.0  # pushing, but joints 1 and 3 saturate so well below 100 N
    assert np.hypot(F[0], F[1]) < 0.7 * F[2]
    np.testing.assert_allclose(np.abs(tau[[0, 2]]), [7.051408, 10.07344], rtol=1e-6)  # saturated


def test_effort_rest_penetration_is_fn_over_kp() -> None:
    """At rest, Fn = Kp y (no damping while still): the foot centre sits Fn/Kp below R_foot (1 %)."""
    q, _, F = _effort_steady()
    y = model.load_params().geometry.R_foot - K.fk(q)[2]
    assert y == pytest.approx(F[2] / 1e4, rel=0.01)


def test_combined_task_touches_down_and_settles() -> None:
    sc = scenario.load(SCENARIOS / "combined.yaml")
    (tr,) = run.run(sc, ["pinocchio"], None, progress=False)
    assert tr.status == "ok"
    # the weak gains let the foot brush the ground while the leg swings down (~0.14 s), then it
    # hangs in the air at the first target until the touch-down target at 1 s
    assert np.all(tr.f[500:1000, 2] == 0.0)
    assert tr.f[1900, 2] > 5.0  # standing at touch-down before the push
    last = tr.t >= tr.t[-1] - 0.5
    assert np.abs(tr.qd[last]).max() < 0.05  # settled [rad/s]
    assert 20.0 < tr.f[last, 2].mean() < 100.0


def test_ode45_profile_is_the_reports_simscape_solver() -> None:
    """Profile ``ode45``: adaptive RK45 at rtol 1e-6, atol 1e-8, max step 2e-4 s; it runs the effort task.

    Over the effort task's first 0.4 s (shortened: the adaptive solve costs ~15 ms per tick in
    contact) the leg settles onto the ground; its ground force agrees with the default fixed-step
    run's to 1 % (two convergent integrators of the same law: the default's step error is 0.002 %
    of Fn in docs/pinocchio.md, the transient's remaining motion dominates) and satisfies the
    statics h = (J_poc^T)^-1 (tau - G) to 2 % (the leg is still moving slightly at 0.4 s).
    """
    physics = scenario.physics_of(scenario.load(SCENARIOS / "effort.yaml"))
    be = registry_load("pinocchio", physics, {}, "ode45")
    try:
        assert be.profile == "ode45"
        assert be.integrator_family() == "adaptive"
        info = be.info()
        assert (info["integrator"], info["rtol"], info["atol"], info["max_step"]) == ("rk45", 1e-6, 1e-8, 2e-4)
        assert info["contact"]["poc"] == "true"
        assert be.limits().timestep is None  # adaptive: no fixed step to report
    finally:
        be.close()
    sc = scenario.load(SCENARIOS / "effort.yaml", {"duration": 0.4, "comparison.steady_window": 0.1})
    sc45 = scenario.load(
        SCENARIOS / "effort.yaml",
        {"duration": 0.4, "comparison.steady_window": 0.1, "backends.pinocchio.profile": "ode45"},
    )
    (tr45,) = run.run(sc45, ["pinocchio"], None, progress=False)
    (tr,) = run.run(sc, ["pinocchio"], None, progress=False)
    assert tr45.status == "ok" and tr45.info["profile"] == "ode45" and tr45.info["integrator_family"] == "adaptive"
    assert tr45.f[-1, 2] > 20.0
    np.testing.assert_allclose(tr45.f[-1], tr.f[-1], rtol=0.01, atol=0.01 * tr.f[-1, 2])
    q, tau, F = tr45.q[-1], tr45.tau[-1], tr45.f[-1]
    h = np.linalg.solve(K.jacobian_poc(q).T, tau - K.gravity(q))
    assert np.linalg.norm(F + h) / np.linalg.norm(F) < 0.02
