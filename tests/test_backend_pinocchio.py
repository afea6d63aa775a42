"""The Pinocchio ABA backend: dynamics against an independent integration, energy, contact statics."""

from __future__ import annotations

import dataclasses
import os
import re
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
import pytest
from scipy.integrate import solve_ivp

from legbench import kinematics as K
from legbench import model, run, scenario
from legbench.backends import joint_limits, pinocchio_kernel
from legbench.backends import load as registry_load
from legbench.backends.base import Physics
from legbench.backends.pinocchio_ import PinocchioBackend
from legbench.contact import ContactParams
from legbench.exceptions import LegbenchError
from legbench.results import RunResult

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
    """Gravity off, sinusoidal torques, 1 s, against DOP853 at rtol 1e-12 on crba/rnea. RK4 at 0.1 ms: measured
    5.6e-15 rad (DOP853 through the backend 2.0e-15), held to 1e-11 rad, the reference's own tolerance over
    its 1000 periods; semi-implicit Euler at the default 50 us is first order: 0.0065 % of amplitude, held
    to 0.1 %."""
    n = 1000
    ref = _reference(Q0, n)
    rk4 = _drive(_backend({"integrator": "rk4", "dt": 1e-4}), Q0, n)
    np.testing.assert_allclose(rk4, ref, rtol=0, atol=1e-11)
    eul = _drive(_backend({}), Q0, n)
    amp = np.abs(ref - Q0).max(axis=0)
    assert np.all(np.abs(eul - ref).max(axis=0) / amp * 100 < 0.1)
    dop = _drive(_backend({"integrator": "dop853", "rtol": 1e-11, "atol": 1e-13}), Q0, 200)
    np.testing.assert_allclose(dop, ref[:201], rtol=0, atol=1e-11)


def test_energy_is_conserved_without_torque_contact_or_damping() -> None:
    """Gravity on, zero torque, no contact, limits not reached: |E(t) - E(0)| / E_scale over 2 s (RK4, 0.1 ms),
    E_scale the largest kinetic energy reached (the potential's zero is arbitrary): measured 3.1e-14, held to
    1e-11 (RK4's energy error is O(h^4); a leak of one part in 1e11 per run fails)."""
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
    assert max(abs(E - E0) for E in Es) / scale < 1e-11


def test_knee_limit_holds_like_an_engine_limit() -> None:
    """10 N m pushing the knee into its 2.229 rad limit rests where the limit's spring holds it:
    2.229 + 10 / k_limit (k_limit = 1e4 N m/rad: 1 mrad past), within 1e-4 rad (the damper has settled;
    lagrange, with the same limit law, is held to the same; MuJoCo rests at 2.2292, PyBullet at 2.2293)."""
    be = _backend({}, gravity=0.0)
    be.reset(np.array([0.0, -0.5, 2.0]), np.zeros(3))
    for _ in range(1000):
        be.step(np.array([0.0, 0.0, 10.0]))
    q3 = be.state()[0][2]
    assert q3 == pytest.approx(2.229 + 10.0 / be.limit_law.k, abs=1e-4)


def _knee_pushed_into_its_limit(settings: dict, control_dt: float, duration: float) -> tuple[np.ndarray, list[str]]:  # type: ignore[type-arg]
    """Zero gravity, 10 N m pushing the knee into its 2.229 rad limit from 2.2 rad for ``duration`` [s] at
    control period ``control_dt`` [s]: the knee angle [rad] of each period and the backend's warnings."""
    be = PinocchioBackend()
    be.load(model.URDF_FILE, Physics(gravity=0.0, contact=NO_CONTACT, control_dt=control_dt), settings)
    be.reset(np.array([0.0, 0.0, 2.2]), np.zeros(3))
    q3 = []
    with np.errstate(all="ignore"):  # the diverging runs overflow
        for _ in range(round(duration / control_dt)):
            be.step(np.array([0.0, 0.0, 10.0]))
            q3.append(be.state()[0][2])
    return np.array(q3), be.warnings()


def _knee_limit_bound() -> float:
    """The limit spring-damper's semi-implicit Euler bound [s] at the knee resting on its limit, from Pinocchio's
    M^-1 (I = 1/(M^-1)_33 = 0.00651 kg m^2: 570 us)."""
    m = _pin_model()
    Mi = pin.computeMinverse(m, m.createData(), _pin_q(np.array([0.0, 0.0, 2.23])))
    return joint_limits.step_bound(joint_limits.STIFFNESS, joint_limits.DAMPING, 1.0 / Mi[2, 2], "euler")


@pytest.mark.parametrize("kernel", ["compiled", "python"])
def test_knee_limit_at_too_coarse_a_step_diverges_and_warns(kernel: str) -> None:
    """The limit spring-damper is explicit in semi-implicit Euler: 10 N m into the knee limit rests at 2.230 rad
    (within 1e-6 rad over the last 0.1 s of 1 s) at 50 us and at 0.95 of the bound 4 / (c + sqrt(c^2 + 4 k/I))
    (570 us), with no warning; at 1.25 of it (712 us) and at 1 ms it diverges (NaN or more than 0.1 rad off), and
    warnings() names the knee, the limit and the bound."""
    if kernel == "compiled" and not pinocchio_kernel.available():
        pytest.skip("needs numba")
    bound = _knee_limit_bound()
    assert bound == pytest.approx(5.70e-4, rel=0.01)
    for h, control_dt, stable in ((5e-5, 1e-3, True), (0.95 * bound, 0.95 * bound, True),
                                  (1.25 * bound, 1.25 * bound, False), (1e-3, 1e-3, False)):  # fmt: skip
        q3, notes = _knee_pushed_into_its_limit({"dt": h, "kernel": kernel}, control_dt, 1.0)
        last = q3[-round(0.1 / control_dt) :]
        if stable:
            assert np.abs(last - (2.229 + 10.0 / joint_limits.STIFFNESS)).max() < 1e-6, h
            assert notes == [], (h, notes)
        else:
            assert not np.all(np.abs(last - 2.230) < 0.1), h
            (note,) = notes
            assert "joint-limit spring-damper" in note and "q3_knee" in note, note
            # the smallest bound over the poses past the limit: the resting pose's, or a diverging pose's below it
            stated = float(re.search(r"c = b / I: ([0-9.e+-]+) s;", note).group(1))  # type: ignore[union-attr]
            assert stated <= bound * 1.001, note


def test_no_limit_warning_for_a_run_inside_the_limits() -> None:
    """The warning needs a limit reached: the free swing at 1 ms (far above the knee's 570 us bound) without
    touching a limit gets none."""
    be = _backend({"dt": 1e-3})
    q = _drive(be, Q0, 300)
    assert np.all(np.abs(q[:, 2]) < 2.229) and np.all(np.abs(q[:, 0]) < np.pi / 2)
    assert be.warnings() == []


#: The knee-limit record runs: integrator settings and sub-step h [s], Euler's below the limit's bound (563 us at
#: the record's I = 0.00643 kg m^2), RK4's above its 1.12 ms
LIMIT_RUNS: dict[str, tuple[dict[str, str], float]] = {
    "euler-implicit": ({"integrator": "euler", "friction": "implicit"}, 2.5e-4),
    "euler-explicit": ({"integrator": "euler", "friction": "explicit"}, 2.5e-4),
    "rk4": ({"integrator": "rk4"}, 1.5e-3),
}


def _limit_record(be: PinocchioBackend) -> list[float]:
    """The backend's joint-limit record, where its warnings() reads it: per joint the largest (M^-1)_jj
    [1/(kg m^2)] at which the joint was past its limit, 0 if never."""
    return be._limit_view.tolist() if be._compiled is not None else list(be._limit_minv)


def _knee_on_its_limit_while_the_hip_swings(settings: dict, h: float) -> tuple[PinocchioBackend, list[float], float]:  # type: ignore[type-arg]
    """Zero gravity, no contact, two sub-steps of ``h`` [s] per control period, 0.6 s from q = (0, 1, 2.2) rad:
    10 N m pushes the knee onto its 2.229 rad limit while a PD (4 N m/rad, 0.2 N m s/rad) holds the hip at
    1 rad for 0.15 s, then swings it towards -0.5 rad (it swings through -0.95 rad and back, the abad drifting
    to 1.03 rad inside its limits), so (M^-1)_33 at the knee's limit goes over its peak 155.57 1/(kg m^2)
    (hip ~0.2 rad) and ends at 139.6-139.9 (hip -0.38 rad).

    Every sub-step's state comes from a twin backend stepping one sub-step per period under the same held
    torque (asserted bit-equal to the run's state at each period start). Returns the run's backend, per period
    pin.computeMinverse(...)[2, 2] at its first sub-step with the knee past its limit (the state the backend
    records: the Python sub-steps and the compiled period both record a joint once per period, at its first
    sub-step past the limit; RK4 at a step's start state), and the largest (M^-1)_33 over every sub-step past
    the limit (the discrimination check: a record of every sub-step would be this)."""
    physics = Physics(gravity=0.0, contact=NO_CONTACT, control_dt=2 * h)
    be, twin = PinocchioBackend(), PinocchioBackend()
    be.load(model.URDF_FILE, physics, {**settings, "dt": h})
    twin.load(model.URDF_FILE, dataclasses.replace(physics, control_dt=h), {**settings, "dt": h})
    assert be.sub_steps() == 2 and twin.sub_steps() == 1
    m = _pin_model()
    d = m.createData()
    q0 = np.array([0.0, 1.0, 2.2])
    be.reset(q0, np.zeros(3))
    twin.reset(q0, np.zeros(3))
    knee_limit = be.upper[2]
    recorded, every = [], 0.0
    for k in range(round(0.6 / (2 * h))):
        q, qd = be.state()
        assert np.array_equal(twin.state()[0], q) and np.array_equal(twin.state()[1], qd), k
        target = 1.0 if k * 2 * h < 0.15 else -0.5
        tau = np.array([0.0, 4.0 * (target - q[1]) - 0.2 * qd[1], 10.0])
        first = True
        for _ in range(2):
            qs = twin.state()[0]
            assert -np.pi / 2 < qs[0] < np.pi / 2 and qs[2] > -knee_limit  # no other limit reached
            if qs[2] > knee_limit:
                minv = float(pin.computeMinverse(m, d, _pin_q(qs))[2, 2])
                every = max(every, minv)
                if first:
                    recorded.append(minv)
                    first = False
            twin.step(tau)
        be.step(tau)
    return be, recorded, every


@pytest.mark.parametrize("run_name", list(LIMIT_RUNS))
@pytest.mark.parametrize("kernel", ["python", "compiled"])
def test_limit_record_is_the_largest_minverse_at_each_periods_first_sub_step_past_the_limit(
    kernel: str, run_name: str
) -> None:
    """The knee held on its limit while the hip swings (:func:`_knee_on_its_limit_while_the_hip_swings`): the
    backend's record of the knee equals the largest pin.computeMinverse(q)[2, 2] over the states it records
    (each period's first sub-step past the limit) to rel 1e-12 (measured 155.5726 1/(kg m^2), Euler, and
    155.5616, RK4, i.e. I = 0.00643 kg m^2; compiled vs pin.computeMinverse 2e-15), not the last recorded
    value (139.6-139.9) nor the largest over every sub-step (larger by 3e-6 rel, Euler, 7e-5, RK4); abad and hip
    record 0; the Python and the compiled records agree to rel 1e-12 (measured 7e-16). RK4 at h = 1.5 ms
    above its bound 1.12 ms at that I: warnings() names q3_knee, I and the bound; Euler at 250 us below its
    563 us: no warning. After reset() the record is 0 and a free swing inside the limits gets no warning."""
    if kernel == "compiled" and not pinocchio_kernel.available():
        pytest.skip("needs numba")
    settings, h = LIMIT_RUNS[run_name]
    be, recorded, every = _knee_on_its_limit_while_the_hip_swings({**settings, "kernel": kernel}, h)
    assert (be._compiled is not None) == (kernel == "compiled")
    expected = max(recorded)
    assert recorded[-1] < 0.95 * expected and every > expected * (1 + 1e-7)  # the run tells them apart
    rec = _limit_record(be)
    assert rec[0] == 0.0 and rec[1] == 0.0
    assert rec[2] == pytest.approx(expected, rel=1e-12)
    if kernel == "compiled":
        py, _, _ = _knee_on_its_limit_while_the_hip_swings({**settings, "kernel": "python"}, h)
        assert rec[2] == pytest.approx(_limit_record(py)[2], rel=1e-12)
    integ = settings["integrator"]
    inertia = 1.0 / expected
    bound = joint_limits.step_bound(joint_limits.STIFFNESS, joint_limits.DAMPING, inertia, integ)
    if integ == "rk4":
        assert h > bound
        (note,) = be.warnings()
        assert "joint-limit spring-damper" in note and "q3_knee" in note, note
        assert f"I = 1/(M^-1)_jj = {inertia:.3g} kg m^2" in note and f"{bound:.3g} s;" in note, note
    else:
        assert h < bound
        assert be.warnings() == []
    be.reset(np.array([0.0, 0.5, 1.0]), np.zeros(3))
    assert _limit_record(be) == [0.0, 0.0, 0.0]
    for _ in range(100):
        be.step(np.array([0.05, 0.2, -0.1]))
        q = be.state()[0]
        assert abs(q[0]) < np.pi / 2 and abs(q[2]) < be.upper[2], q
    assert _limit_record(be) == [0.0, 0.0, 0.0]
    assert be.warnings() == []


@pytest.mark.parametrize("integrator", ["rk45", "dop853"])
def test_adaptive_integrators_declare_one_sub_step(integrator: str) -> None:
    """An adaptive solve per control period is one step for the harness (as the lagrange backend declares):
    sub_steps() and info() say 1, not control period / dt (20 at the default dt); the fixed-step ones n_sub."""
    be = _backend({"integrator": integrator})
    assert be.sub_steps() == 1 and be.info()["sub_steps"] == 1
    assert run.backend_info(be)["sub_steps"] == 1
    assert _backend({}).sub_steps() == 20 and _backend({"integrator": "rk4", "dt": 2.5e-5}).sub_steps() == 40


def test_rk4_friction_warning_uses_rk4s_stability_interval() -> None:
    """RK4 takes the friction explicitly, stable for h c / m <= 2.785 (c = mu_s Fn / v_th), 2.785 times semi-implicit
    Euler's m v_th / (mu_s Fn) (5.2 us at the effort task's 59 N peak): at 12.5 us it resolves the stick-slip
    ramp (the steady force within 0.01 N of the default implicit Euler's, std of Fx, Fy < 0.01 N) and gets no
    warning; at 25 us (above 2.785 x 5.2 = 14.4 us) it chatters (Fy more than 5 N off) and gets the warning."""
    sc = scenario.load(SCENARIOS / "effort.yaml")
    physics = scenario.physics_of(sc)

    def steady(settings: dict) -> tuple[np.ndarray, np.ndarray, list[str]]:  # type: ignore[type-arg]
        be = registry_load("pinocchio", physics, settings)
        tr = run.simulate(sc, be, physics)
        w = tr.t >= tr.t[-1] - 0.5
        return tr.f[w].mean(0), tr.f[w].std(0), be.warnings()

    f_ref, _, _ = steady({})
    f, std, notes = steady({"integrator": "rk4", "dt": 1.25e-5})
    assert notes == [] and np.abs(f - f_ref).max() < 0.01 and std[:2].max() < 0.01, (notes, f, f_ref, std)
    f, std, notes = steady({"integrator": "rk4", "dt": 2.5e-5})
    assert abs(f[1] - f_ref[1]) > 5.0, (f, f_ref)
    (note,) = notes
    assert "stick-slip law" in note and "h > 2.785 m v_th / (mu_s Fn)" in note, note


def _effort_steady(poc: str = "true") -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    sc = scenario.load(SCENARIOS / "effort.yaml", {"physics.contact.poc": poc})
    (tr,) = run.run(sc, ["pinocchio"], None, progress=False)
    w = tr.t >= tr.t[-1] - sc.comparison.steady_window
    return tr.q[w].mean(0), tr.tau[w].mean(0), tr.f[w].mean(0)


def test_effort_task_ground_force_satisfies_static_balance() -> None:
    """Steady state: ground force F on the foot = -(J_poc^T)^-1 (tau - G) within 1e-4 of |F| (the law acts at
    the true poc and the creep's inertia is negligible: measured 1.2e-6); friction inside mu_s Fn."""
    q, tau, F = _effort_steady()
    h = np.linalg.solve(K.jacobian_poc(q).T, tau - K.gravity(q))
    assert np.linalg.norm(F + h) / np.linalg.norm(F) < 1e-4
    assert F[2] > 20.0  # pushing, but joints 1 and 3 saturate so well below 100 N
    assert np.hypot(F[0], F[1]) < 0.7 * F[2]
    limits = np.array(model.load_params().effort)  # 7.051408 and 10.07344 N m for joints 1 and 3 (the spec's)
    np.testing.assert_allclose(np.abs(tau[[0, 2]]), limits[[0, 2]], rtol=1e-6)  # saturated


def test_effort_rest_penetration_is_fn_over_kp() -> None:
    """At rest, Fn = Kp y (the damping Kd ydot of a 0.3 mm/s creep is 1e-5 of Fn): the foot centre sits Fn/Kp
    below R_foot within 1e-4 (measured 7.6e-6)."""
    q, _, F = _effort_steady()
    y = model.load_params().geometry.R_foot - K.fk(q)[2]
    assert y == pytest.approx(F[2] / 1e4, rel=1e-4)


def test_combined_task_touches_down_and_settles() -> None:
    """The combined task: no ground force over 0.5-1 s (hanging at the first target), more than 5 N at 1.9 s
    (standing after the 1 s touch-down), and over the last 0.5 s at rest (max |qd| below 5e-3 rad/s; measured
    9.3e-4, the law's creep) pushing with Fn within 45-55 N (measured 50.58-50.60 N: the saturated push)."""
    sc = scenario.load(SCENARIOS / "combined.yaml")
    (tr,) = run.run(sc, ["pinocchio"], None, progress=False)
    assert tr.status == "ok"
    # the weak gains let the foot brush the ground while the leg swings down (~0.14 s), then it
    # hangs in the air at the first target until the touch-down target at 1 s
    assert np.all(tr.f[500:1000, 2] == 0.0)
    assert tr.f[1900, 2] > 5.0  # standing at touch-down before the push
    last = tr.t >= tr.t[-1] - 0.5
    assert np.abs(tr.qd[last]).max() < 5e-3  # settled [rad/s]
    assert 45.0 < tr.f[last, 2].min() and tr.f[last, 2].max() < 55.0  # [N]


def test_ode45_profile_is_the_reports_simscape_solver() -> None:
    """Profile ``ode45``: adaptive RK45 at rtol 1e-6, atol 1e-8, max step 2e-4 s; it runs the effort task.

    Over the effort task's first 0.4 s (shortened: the adaptive solve as Python costs ~3 ms per tick in
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
        assert not {"dt", "friction"} & set(info)  # one solve per period: no sub-step, no Euler options
        assert info["kernel"] == "compiled" and "kernel" not in _backend({"integrator": "dop853"}).info()
        assert not {"rtol", "atol", "max_step"} & set(_backend({}).info())  # and Euler reads no tolerances
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


# --------------------------------------------------------------------------- #
# The compiled control period (legbench/backends/pinocchio_kernel.py) against the Python path

numba_needed = pytest.mark.skipif(not pinocchio_kernel.available(), reason="needs numba")


def _pin_model() -> pin.Model:
    m = pin.buildModelFromUrdf(str(model.URDF_FILE))
    m.gravity.linear = np.array([0.0, 0.0, -9.81])
    return m


def _pin_q(q: np.ndarray) -> np.ndarray:
    return np.array([q[0], np.cos(q[1]), np.sin(q[1]), q[2]])


@numba_needed
def test_compiled_aba_and_minverse_match_pinocchio() -> None:
    """The kernel's ABA is Pinocchio's algorithm on the same numbers: qdd equal to pin.aba and M^-1 to
    pin.computeMinverse within 1e-13 relative (round-off of a few hundred operations: measured qdd 1.2e-15,
    M^-1 1.3e-14, median 9.7e-16) over 300 random states, torques up to 20 N m and speeds up to 10 rad/s."""
    m = _pin_model()
    d = m.createData()
    R, p, inertia, a0 = pinocchio_kernel.model_arrays(m)
    work, tmp, buf = np.zeros((3, 6, 16)), np.zeros((6, 16)), np.zeros(64)
    qdd, minv = np.zeros(3), np.zeros((3, 3))
    rng = np.random.default_rng(7)
    for _ in range(300):
        q, qd, tau = rng.uniform(-2.5, 2.5, 3), rng.uniform(-10, 10, 3), rng.uniform(-20, 20, 3)
        ref = pin.aba(m, d, _pin_q(q), qd, tau)
        pinocchio_kernel.aba(R, p, inertia, a0, q, qd, tau, qdd, work, tmp)
        np.testing.assert_allclose(qdd, ref, rtol=1e-13, atol=1e-13 * np.abs(ref).max())
        Mi = pin.computeMinverse(m, d, _pin_q(q))
        Mi = np.triu(Mi) + np.triu(Mi, 1).T
        pinocchio_kernel.minverse(R, p, inertia, q, minv, work, tmp, buf)
        np.testing.assert_allclose(minv, Mi, rtol=1e-13, atol=1e-13 * np.abs(Mi).max())


@numba_needed
def test_compiled_law_and_limits_are_the_python_law_bit_for_bit() -> None:
    """The contact law, its friction slope and the joint-limit torques are the same IEEE operations in the
    same order as legbench.contact and joint_limits: equal to the last bit, in and out of contact, sticking
    and sliding (4000 states around the effort pose with speeds from 1e-5 to 1 rad/s: math.hypot, whose CPython
    and C-library versions differ in the last bit for 0.6 % of arguments, failed this on 8 of 12 seeds)."""
    be = _backend({}, gravity=9.81, contact=ContactParams())
    c = be.contact
    lc = np.array(c.constants)
    lim = np.array([*be.lower, *be.upper, be.limit_law.k, be.limit_law.b])
    sc = scenario.shorten(scenario.load(SCENARIOS / "effort.yaml"), 1.0)
    q_star = run.simulate(sc, be, scenario.physics_of(sc)).q[-1]  # the foot pressed into the ground
    rng = np.random.default_rng(3)
    contacts = 0
    for _ in range(4000):
        q = q_star + rng.normal(0.0, 0.003, 3)
        if rng.uniform() < 0.2:
            q[2] = rng.uniform(2.2, 2.3)  # about the knee's 2.229 rad limit
        qd = rng.normal(0.0, 1.0, 3) * 10.0 ** rng.uniform(-5, 0)
        args = (*q.tolist(), *qd.tolist())
        assert pinocchio_kernel.wrench(lc, *args) == c.wrench(*args)
        assert pinocchio_kernel.wrench_slope(lc, *args) == c.wrench_slope(*args)
        assert pinocchio_kernel.limit_torques(lim, *args) == be.limit_law(*args)
        contacts += c.wrench(*args)[5] > 0.0
    assert 500 < contacts < 3500  # both branches were exercised


def _python_and_compiled(
    sc: scenario.Scenario, settings: dict[str, Any], profile: str | None = None
) -> tuple[RunResult, RunResult]:
    """The scenario run with ``kernel: python`` and ``kernel: compiled`` (in ``profile``, default the scenario's)."""
    physics = scenario.physics_of(sc)
    runs = []
    for kernel in ("python", "compiled"):
        be = registry_load("pinocchio", physics, {**sc.backends.get("pinocchio", {}), **settings, "kernel": kernel},
                           profile or sc.profile)  # fmt: skip
        assert be.info()["kernel_used"].startswith(kernel)
        runs.append(run.simulate(sc, be, physics))
    a, b = runs
    assert a.status == b.status == "ok" and len(a.t) == len(b.t) == sc.n_ticks
    return a, b


@numba_needed
@pytest.mark.parametrize("task", ["position", "ellipse", "effort", "combined"])
def test_compiled_period_agrees_with_the_python_path_over_each_task(task: str) -> None:
    """The same task through the compiled period and the Python sub-steps: joint angles within 1e-12 rad at
    every tick (measured: 1.8e-15 rad at most, combined; the ABA's round-off does not grow), speeds within
    1e-9 rad/s, the ground force within 1e-9 N."""
    a, b = _python_and_compiled(scenario.load(SCENARIOS / f"{task}.yaml"), {})
    assert np.abs(a.q - b.q).max() <= 1e-12
    assert np.abs(a.qd - b.qd).max() <= 1e-9
    assert np.abs(a.f - b.f).max() <= 1e-9


@numba_needed
@pytest.mark.parametrize(("task", "duration", "dt"), [("position", None, 5e-5), ("ellipse", None, 5e-5),
                                                      ("effort", 0.3, 5e-6)])  # fmt: skip
def test_compiled_rk4_agrees_with_the_python_rk4(task: str, duration: float | None, dt: float) -> None:
    """RK4 through the compiled period and the Python stages, the same tolerances as Euler's (measured: 4e-19
    rad over the effort task's touch-down and slide, 1e-15 in free space). In contact RK4 treats the
    friction explicitly, so the sub-step is kept within the law's bound m v_th / (mu_s Fn) (no warning): above
    it the friction chatters and amplifies any round-off difference (at 50 us the two paths part by 1e-3 rad
    within 0.01 s, each as valid as the other)."""
    sc = scenario.load(SCENARIOS / f"{task}.yaml")
    a, b = _python_and_compiled(sc if duration is None else scenario.shorten(sc, duration),
                                {"integrator": "rk4", "dt": dt})  # fmt: skip
    assert a.info["warnings"] == b.info["warnings"] == []
    assert a.info["integrator"] == "rk4"
    assert np.abs(a.q - b.q).max() <= 1e-12
    assert np.abs(a.qd - b.qd).max() <= 1e-9
    assert np.abs(a.f - b.f).max() <= 1e-9
    if task == "effort":
        assert a.f[:, 2].max() > 50.0  # the touch-down and push were in it


@numba_needed
def test_compiled_rk45_takes_solve_ivps_steps_in_stick_slip_contact() -> None:
    """The ``rk45`` period compiled (legbench/backends/dopri.py over the compiled law, limits and ABA) from 100
    states of the foot pressed 1 mm into the ground, random speeds and torques, the ode45 profile's
    tolerances: the same right-hand-side evaluations as scipy's solve_ivp(RK45) on the Python ABA (same initial
    step, same accepted and rejected steps) and the end state within 1e-12 (round-off of the two ABAs), or, where
    the state is ill-conditioned, within what solve_ivp itself moves when its start state is perturbed by round-off
    (1e-16 relative, five draws): one of the 100 states (the foot near the stick-slip ramp) turns such a
    perturbation into up to 6.5e-11 of the end state, and the two ABAs differ there by 1.5e-12."""
    be = _backend({"integrator": "rk45", "rtol": 1e-6, "atol": 1e-8, "max_step": 2e-4}, 9.81, ContactParams())
    assert be.info()["kernel_used"] == "compiled (numba)"
    assert be._dopri is not None
    period, x, u, lc, lim, k, data = be._dopri
    rng = np.random.default_rng(5)
    start = K.ik_nearest(np.array([0.1667, 0.0, model.load_params().geometry.R_foot - 0.001]),
                         np.array(model.load_params().q_star))  # fmt: skip
    nfev = []
    ill = 0  # states where the two differ by more than 1e-12
    for _ in range(100):
        x0 = np.concatenate([start + rng.normal(0.0, 0.01, 3), rng.normal(0.0, 0.3, 3)])
        tau = rng.normal(0.0, 2.0, 3)

        def f(_t: float, y: np.ndarray, tau: np.ndarray = tau) -> np.ndarray:
            return np.concatenate([y[3:], be._qdd(y[:3].tolist(), y[3:].tolist(), tau.tolist())])

        ref = solve_ivp(f, (0.0, T_CTRL), x0, method="RK45", rtol=1e-6, atol=1e-8, max_step=2e-4)
        x[:] = x0
        u[:] = tau
        n = period(x, u, 0.0, lc, lim, T_CTRL, 1e-6, 1e-8, 2e-4, k, data)
        assert n == ref.nfev
        err = float(np.abs(x - ref.y[:, -1]).max())
        if err > 1e-12:  # the ill-conditioned state: the reference's own spread under round-off
            ill += 1
            spread = max(
                float(np.abs(solve_ivp(f, (0.0, T_CTRL), x0 * (1.0 + np.random.default_rng(s).normal(0.0, 1e-16, 6)),
                                       method="RK45", rtol=1e-6, atol=1e-8, max_step=2e-4).y[:, -1]
                             - ref.y[:, -1]).max())
                for s in range(5)
            )  # fmt: skip
            assert err <= spread, (err, spread)
        nfev.append(n)
    assert max(nfev) > min(nfev)  # the error control chose different steps for different states
    assert ill <= 3  # measured 1 of 100: the 1e-12 bound holds for the rest


@numba_needed
@pytest.mark.parametrize(("task", "duration"), [("position", None), ("effort", 1.0)])
def test_compiled_rk45_agrees_with_solve_ivp_over_a_task(task: str, duration: float | None) -> None:
    """The ode45 profile (the lab's Simscape solver) through the compiled period and through solve_ivp: joint
    angles within 1e-10 rad, speeds within 1e-7 rad/s, the ground force within 1e-3 N at every tick (measured
    over the whole tasks: 1.2e-13 rad, 1.4e-9 rad/s, 1.6e-5 N; the two ABAs differ at round-off, which moves
    an adaptive step now and then, by far less than the solver's atol of 1e-8)."""
    sc = scenario.load(SCENARIOS / f"{task}.yaml")
    a, b = _python_and_compiled(sc if duration is None else scenario.shorten(sc, duration), {}, "ode45")
    assert a.info["integrator"] == b.info["integrator"] == "rk45"
    assert np.abs(a.q - b.q).max() <= 1e-10
    assert np.abs(a.qd - b.qd).max() <= 1e-7
    assert np.abs(a.f - b.f).max() <= 1e-3
    if task == "effort":
        assert a.f[:, 2].max() > 50.0  # the touch-down and push were in it


def test_the_compiled_floor_s_target_applies_only_where_the_compiled_period_runs() -> None:
    """``replay/period_loop`` (bench) needs the compiled fixed-step period, the floor it names: euler and rk4
    compiled state it; the Python path, rk45 and dop853 state only full/replay (they read "not measured", and
    ``bench --check`` failed on a target that cannot apply). Each configuration's floors agree with its targets."""
    both = {"replay/period_loop": 1.3, "full/replay": 1.2}
    q, qd, tau = np.zeros((2, 3)), np.zeros((2, 3)), np.zeros((2, 3))
    for settings, targets in (({}, both), ({"integrator": "rk4"}, both), ({"kernel": "python"}, {"full/replay": 1.2}),
                              ({"integrator": "rk45"}, {"full/replay": 1.2}),
                              ({"integrator": "dop853"}, {"full/replay": 1.2})):  # fmt: skip
        be = _backend(settings)
        assert dict(be.bench_targets) == targets, settings
        assert ("period_loop" in be.kernels(q, qd, tau)) == ("replay/period_loop" in targets), settings


def test_kernel_falls_back_to_python_and_says_why(monkeypatch: pytest.MonkeyPatch) -> None:
    """``kernel: python`` runs the Python path silently; a missing numba runs it with a warning naming the
    fix; dop853 never uses the kernel (solve_ivp), rk45 only unless ``kernel: python``."""
    assert _backend({"kernel": "python"}).info()["kernel_used"] == "python"
    assert _backend({"kernel": "python"}).warnings() == []
    assert _backend({"integrator": "dop853"}).info()["kernel_used"] == "python"
    assert _backend({"integrator": "rk45", "kernel": "python"}).info()["kernel_used"] == "python"
    monkeypatch.setattr(pinocchio_kernel, "available", lambda: False)
    be = _backend({})
    assert be.info()["kernel_used"] == "python"
    assert any("numba is not installed" in w and "pip install numba" in w for w in be.warnings())
    be = _backend({"integrator": "rk45"})
    assert be.info()["kernel_used"] == "python"
    assert any("numba is not installed" in w and "solve_ivp" in w for w in be.warnings())


def test_kernel_refuses_joints_it_does_not_integrate() -> None:
    """A model with a prismatic joint is refused (the Python path runs it), naming the joint and its type."""
    m = pin.Model()
    m.addJoint(0, pin.JointModelRZ(), pin.SE3.Identity(), "hinge")
    m.addJoint(1, pin.JointModelPX(), pin.SE3.Identity(), "slider")
    with pytest.raises(pinocchio_kernel.KernelUnavailable, match="slider .JointModelPX."):
        pinocchio_kernel.model_arrays(m)


def test_kernel_refuses_a_model_with_rotor_inertia() -> None:
    """pin.aba adds model.armature to each joint's articulated inertia; the compiled ABA read only placements,
    inertias and gravity, so with armature (0.0049, 0.01, 0.01) kg m^2 it gave qdd (-14.8, -29.0, 86.3) where
    pin.aba gives (-17.9, -11.4, 25.6), silently. It is refused now (the Python path, on pin.aba, runs it)."""
    m = model.pinocchio_model().copy()
    pinocchio_kernel.model_arrays(m)  # no armature in the leg's model: accepted
    m.armature = np.array([0.0049, 0.01, 0.01])
    with pytest.raises(pinocchio_kernel.KernelUnavailable, match="rotor inertia"):
        pinocchio_kernel.model_arrays(m)


@numba_needed
def test_the_compiled_rk45_period_is_loaded_from_numbas_cache_in_a_later_process(tmp_path: Path) -> None:
    """The compiled rk45 period (a named copy of the shared stepper) is compiled once: a second process finds
    it in numba's disk cache (a hit, no compile)."""
    script = (
        "import numpy as np\n"
        "from legbench import model\n"
        "from legbench.backends.base import Physics\n"
        "from legbench.backends.pinocchio_ import PinocchioBackend as P\n"
        "be = P(); be.load(model.URDF_FILE, Physics(), P.resolve_settings({'integrator': 'rk45'}, 'matched'))\n"
        "be.reset(np.zeros(3), np.zeros(3)); be.step(np.zeros(3))\n"
        "s = be._dopri[0].stats\n"
        "print(sum(s.cache_hits.values()), sum(s.cache_misses.values()))\n"
    )
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "numba")}
    counts = []
    for _ in range(2):
        out = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True, check=True)
        counts.append(tuple(int(v) for v in out.stdout.split()))
    assert counts == [(0, 1), (1, 0)]  # (cache hits, misses): compiled in the first process, loaded in the second


@numba_needed
def test_compiled_rk45_drives_a_joint_past_its_limit_as_solve_ivp_does() -> None:
    """The limit law inside the compiled rk45 period: the foot in the air, the knee 0.02 rad past its upper
    limit moving out at 0.5 rad/s (tau_lim = -k 0.02 - b 0.5 = -210 N m; k and b swapped would give ~-5000 N m):
    solve_ivp(RK45)'s evaluations on the Python ABA and limit law, and its end state within 1e-12."""
    be = _backend({"integrator": "rk45", "rtol": 1e-6, "atol": 1e-8, "max_step": 2e-4}, 9.81, ContactParams())
    assert be._dopri is not None
    period, x, u, lc, lim, k, data = be._dopri
    x0 = np.array([0.0, -0.3, be.upper[2] + 0.02, 0.0, 0.0, 0.5])
    assert be.law(*x0)[5] == 0.0  # off the ground

    def f(_t: float, y: np.ndarray) -> np.ndarray:
        return np.concatenate([y[3:], be._qdd(y[:3].tolist(), y[3:].tolist(), [0.0, 0.0, 0.0])])

    ref = solve_ivp(f, (0.0, T_CTRL), x0, method="RK45", rtol=1e-6, atol=1e-8, max_step=2e-4)
    x[:] = x0
    u[:] = 0.0
    assert period(x, u, 0.0, lc, lim, T_CTRL, 1e-6, 1e-8, 2e-4, k, data) == ref.nfev
    np.testing.assert_allclose(x, ref.y[:, -1], rtol=0, atol=1e-12)
    assert x[5] < 0.0  # turned back within the period


@numba_needed
def test_a_step_size_underflow_in_the_compiled_rk45_is_a_clear_error() -> None:
    """The compiled period's -1 (step size below 10 ulp of t) becomes the backend's one-line error."""
    be = _backend({"integrator": "rk45"})
    be.reset(np.zeros(3), np.zeros(3))
    assert be._dopri is not None
    be._dopri = (lambda *_: -1, *be._dopri[1:])
    with pytest.raises(LegbenchError, match="rk45 failed: Required step size"):
        be.step(np.zeros(3))


# --------------------------------------------------------------------------- #
# The bench floor (`legbench bench`: PinocchioBackend.kernels)


def _floor_run(task: str, duration: float, settings: dict[str, Any]) -> tuple[PinocchioBackend, RunResult]:
    sc = scenario.shorten(scenario.load(SCENARIOS / f"{task}.yaml"), duration)
    physics = scenario.physics_of(sc)
    be = registry_load("pinocchio", physics, settings)
    assert isinstance(be, PinocchioBackend)
    tr = run.simulate(sc, be, physics)
    assert tr.status == "ok"
    return be, tr


@numba_needed
@pytest.mark.parametrize(
    ("task", "duration", "settings"),
    [("combined", 1.5, {}), ("effort", 0.3, {"friction": "explicit", "dt": 5e-6}),
     ("effort", 0.3, {"integrator": "rk4", "dt": 5e-6}), ("position", 0.3, {})],
)  # fmt: skip
def test_the_compiled_floor_is_the_backends_own_period_and_ends_where_the_run_ended(
    task: str, duration: float, settings: dict[str, Any]
) -> None:
    """``period_loop`` is the backend's compiled period over the run's logged torques from the run's initial
    state, so its end state is the run's last logged state bit for bit (over a touch-down, in contact with
    either friction, RK4, in the air); it is per control period, declares its end-state reader, and leaves the
    backend's own state alone. The former floor ``aba_law_tick`` (law, limits and ABA at each logged state,
    without the integration) cost 1-2 % more than the whole period and is gone."""
    be, tr = _floor_run(task, duration, settings)
    before = be.read()
    k = be.kernels(tr.q[:-1], tr.qd[:-1], tr.tau[:-1])
    assert set(k) == {"aba", "law", "period_loop"}
    loop = k["period_loop"]
    assert loop.per_tick is True  # type: ignore[attr-defined]
    for _ in range(2):  # a second pass starts again from the run's initial state
        loop()
        q, qd = loop.end_state()  # type: ignore[attr-defined]
        assert np.array_equal(q, tr.q[-1]) and np.array_equal(qd, tr.qd[-1])
    assert be.read() == before
    if task == "combined":
        assert tr.f[:, 2].max() > 0.0  # the touch-down was in it


@numba_needed
def test_the_compiled_floor_is_one_call_per_pass_with_no_python_per_tick() -> None:
    """One pass over 50 or over 500 logged periods makes the same (small) number of Python-level calls: the
    periods run inside one compiled call."""
    be, tr = _floor_run("effort", 0.5, {})

    def calls(rows: int) -> int:
        loop = be.kernels(tr.q[:rows], tr.qd[:rows], tr.tau[:rows])["period_loop"]
        loop()  # compiled and loaded before counting
        count = 0

        def profile(frame: Any, event: str, arg: Any) -> None:
            nonlocal count
            count += event in ("call", "c_call")

        sys.setprofile(profile)
        try:
            loop()
        finally:
            sys.setprofile(None)
        return count

    assert calls(50) == calls(500) <= 5


def test_the_python_kernel_declares_no_compiled_floor() -> None:
    """``kernel: python``: only ``pin.aba`` and the law called from Python (no compiled period to loop)."""
    be, tr = _floor_run("position", 0.05, {"kernel": "python"})
    assert set(be.kernels(tr.q[:-1], tr.qd[:-1], tr.tau[:-1])) == {"aba", "law"}


@pytest.mark.parametrize(
    ("kernel", "start"), [("compiled", "legbench's ABA compiled with numba"), ("python", "pin.aba")]
)
def test_info_says_what_computes_the_dynamics(kernel: str, start: str) -> None:
    """The backend named "pinocchio" runs legbench's own ABA, compiled with numba, on Pinocchio's model (pin.aba is
    the Python path): info()'s ``dynamics``, which the report's backend table shows beside the engine, says which,
    so a timing or a deviation is not credited to Pinocchio's code where it is legbench's."""
    if kernel == "compiled" and not pinocchio_kernel.available():
        pytest.skip("numba not installed")
    be = registry_load("pinocchio", Physics(), {"kernel": kernel})
    try:
        assert be.info()["dynamics"].startswith(start)
    finally:
        be.close()


@pytest.mark.parametrize(
    ("old", "new", "words"),
    [
        ('damping="0"', 'damping="0.05"', "joint damping [0.05, 0.05, 0.05]: pin.aba does not apply it"),
        ('friction="0"', 'friction="0.2"', "joint friction [0.2, 0.2, 0.2]: pin.aba does not apply it"),
        (
            'lower="-2.229" upper="2.229"',
            'lower="-2.0" upper="2.229"',
            "joint q3_knee limits (-2.0, 2.229) rad, the leg",
        ),
    ],
)
def test_a_urdf_the_backend_would_simulate_otherwise_is_refused(tmp_path: Path, old: str, new: str, words: str) -> None:
    """pin.aba (and the compiled ABA) ignores a URDF's joint damping and dry friction, and the limit law takes the
    leg's limits, not the URDF's: a URDF given to load() by hand with either is refused, naming the file and what
    would be dropped, instead of a run that silently leaves it out. The leg's own URDF loads (every other test)."""
    from legbench import resources
    from legbench.exceptions import ModelError

    text = resources.urdf_file().read_text(encoding="utf-8")
    assert old in text
    urdf = tmp_path / "leg.urdf"
    urdf.write_text(text.replace(old, new), encoding="utf-8")
    with pytest.raises(ModelError) as err:
        PinocchioBackend().load(urdf, Physics(), {})
    assert str(err.value).startswith(f"{urdf}: {words}"), str(err.value)
