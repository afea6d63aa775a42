"""The contact profiles on the effort and combined tasks: agreement, creep, read-out, chatter, convergence.

Each task runs once per backend and profile (native contact) and is cached for
the module. Engines that are not installed are skipped.
"""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest

from legbench import backends as registry
from legbench.contact import ContactParams
from legbench.model import ROOT
from legbench.studies.contact_study import SteadyContact, run_case

BACKENDS = ("pinocchio", "mujoco", "pybullet")
PROFILES = ("matched", "engine-defaults")
SCENARIOS = {"effort": ROOT / "scenarios" / "effort.yaml", "combined": ROOT / "scenarios" / "combined.yaml"}
#: The report's table 10, Simscape row (stick-slip law, true poc): steady |qd| of the effort task [rad/s].
TABLE10_SIMSCAPE = (4.0e-4, 8.7e-4, 6.4e-4)


def _need(name: str) -> None:
    if name not in registry.available():
        pytest.skip(f"{name} is not installed")


@functools.cache
def _run(task: str, backend: str, profile: str = "matched", **settings: object) -> SteadyContact:
    return run_case(SCENARIOS[task], backend, profile, settings)


@pytest.mark.parametrize("task", ["effort", "combined"])
def test_matched_steady_normal_force_agrees_within_1_5_percent(task: str) -> None:
    """The lab's three frameworks agreed on the steady Fn to about 1.5 %; so must ours in the matched profile."""
    for b in BACKENDS:
        _need(b)
    fn = {b: float(_run(task, b).force[2]) for b in BACKENDS}
    spread = (max(fn.values()) - min(fn.values())) / float(np.mean(list(fn.values())))
    assert spread <= 0.015, fn


def test_stick_slip_creep_matches_table_10() -> None:
    """v_th derived from table 10 (docs/contact_law.md) reproduces its Simscape row's qd, signs (-, +, -) included.

    Measured (mean over the last 0.5 s, deterministic): qd = (-3.782e-4, 8.629e-4, -6.177e-4) rad/s, |qd| -2.2 %
    from the row's 1.152e-3, per joint -5.4 %, -0.8 %, -3.5 %. Held to 5 % on |qd| and 8 %, 2.5 %, 7 % per joint,
    so a few % change of the creep either way fails (v_th x 0.97: |qd| -5.1 %, qd1 -8.3 %; x 1.05: qd2 +4.1 %),
    where 15 % let a 10 % one pass (v_th x 1.1: |qd| +7.5 %).

    The residual is no error of the law, which creeps along -F_t to 0.02 deg; it is the derivation's inputs: the
    speed is 1.4 % below the row's (the derivation took |F_t| / Fn = 0.2045 from PyBullet, the Pinocchio run's
    is 0.2023, and v_th 1.003e-3 rounded to 1.0e-3), and the row's creep points 1.55 deg off the law's direction
    (123.54 deg against 121.99 deg in the ground plane), which takes 5.4 % off qd1 (mostly the foot's x-speed)."""
    _need("pinocchio")
    s = _run("effort", "pinocchio")
    ref = math.sqrt(sum(x * x for x in TABLE10_SIMSCAPE))
    assert abs(s.qd_norm / ref - 1.0) <= 0.05, (s.qd, ref)
    signed = np.array(TABLE10_SIMSCAPE) * (-1.0, 1.0, -1.0)  # the creep along the ground runs (-, +, -)
    assert np.all(np.abs(s.qd / signed - 1.0) <= (0.08, 0.025, 0.07)), (s.qd, s.qd / signed - 1.0)


def test_stick_slip_creep_in_the_combined_task_is_the_laws_from_the_statics() -> None:
    """The combined task ends pushing like the effort task but from the pose its position phase reached, where
    |F_t|/Fn is 0.26 against 0.20: table 10 (the effort task's) does not apply, the law does. Over the last
    second the poc slips at v_th |F_t| / (mu_s Fn) (the stick-slip ramp) with F the ground force the leg's
    statics give, -(J_poc^T)^-1 (tau - G(q)), not the reported one: the creep is quasi-static, so its speed
    follows from the torques and pose alone, to the inertia of a 0.37 mm/s creep (measured 7.4e-6
    relative; 1e-4 here)."""
    _need("pinocchio")
    from legbench import kinematics, model
    from legbench import scenario as scenario_mod
    from legbench.run import physics_of, simulate

    sc = scenario_mod.load(SCENARIOS["combined"])
    physics = physics_of(sc)
    b = registry.load("pinocchio", physics, {})
    try:
        tr = simulate(sc, b, physics)
    finally:
        b.close()
    late = tr.t >= tr.t[-1] - 1.0
    q, qd, tau = tr.q[late], tr.qd[late], tr.tau[late]
    J = kinematics.jacobian_poc(q)
    v = np.einsum("nij,nj->ni", J, qd)
    F = -np.array([np.linalg.solve(Ji.T, ti - model.gravity_torque(qi)) for Ji, ti, qi in zip(J, tau, q, strict=True)])
    c = physics.contact
    predicted = c.v_th * np.hypot(F[:, 0], F[:, 1]) / (c.mu_s * F[:, 2])
    assert np.all(F[:, 2] > 40.0) and np.all(predicted < c.v_th)  # pressing, on the ramp
    np.testing.assert_allclose(np.hypot(v[:, 0], v[:, 1]), predicted, rtol=1e-4)


def test_mujoco_matched_holds_the_foot() -> None:
    """MuJoCo's matched friction (noslip, deadbeat friction rows) sticks: < 1 mm of foot motion after 50 ms."""
    _need("mujoco")
    s = _run("effort", "mujoco")
    assert s.foot_travel < 1e-3, s.foot_travel


@pytest.mark.parametrize("profile", PROFILES)
@pytest.mark.parametrize("backend", BACKENDS)
def test_readout_matches_the_legs_statics(backend: str, profile: str) -> None:
    """|F_reported - h| <= 0.02 % of Fn over the effort task's final 0.5 s, h = -(J^T)^-1 (tau - G) with J at the
    point where the backend's force acts (its info's contact.lift: MuJoCo's y/2 above the lowest point). Measured
    27 Nov: 4e-16 (MuJoCo matched) to 9.7e-5 (MuJoCo's engine defaults, whose regularised cone lets the foot walk);
    at the true poc MuJoCo was 0.2 % off, which the former 0.5 % let pass."""
    _need(backend)
    s = _run("effort", backend, profile)
    assert s.readout_error <= 2e-4, (s.force, s.statics)


@pytest.mark.parametrize("backend", BACKENDS)
def test_no_chatter_at_default_settings(backend: str) -> None:
    """Standard deviation of Fx, Fy over the effort task's final 0.5 s < 0.5 N (it was ~22 N for the explicit law)."""
    _need(backend)
    s = _run("effort", backend)
    assert s.force_std[0] < 0.5 and s.force_std[1] < 0.5, s.force_std


def test_pinocchio_explicit_friction_chatters_and_warns() -> None:
    """The explicit law at the default sub-step is what the implicit default removes: it chatters (> 5 N)."""
    _need("pinocchio")
    s = _run("effort", "pinocchio", friction="explicit")
    assert s.force_std[0] > 5.0 and s.force_std[1] > 5.0, s.force_std


def test_pinocchio_default_within_half_a_percent_of_the_dt_to_zero_limit() -> None:
    """Steady ground force of the default (implicit friction, 50 us) against runs at 10 and 5 us.

    The limit is taken from the 5 us run; that the sequence has converged is checked by the 10 us
    run and by the explicit law at 5 us (below its chatter bound of ~5.6 us), an independent scheme.
    """
    _need("pinocchio")
    default = _run("effort", "pinocchio")
    fine = _run("effort", "pinocchio", dt=1e-5)
    finest = _run("effort", "pinocchio", dt=5e-6)
    explicit = _run("effort", "pinocchio", dt=5e-6, friction="explicit")
    fn = float(finest.force[2])
    # converged sequence: 10 us and 5 us, and the two schemes at 5 us, agree far inside the 0.5 % budget
    assert np.max(np.abs(fine.force - finest.force)) <= 1e-3 * fn
    assert np.max(np.abs(explicit.force - finest.force)) <= 1e-3 * fn
    assert np.max(np.abs(default.force - finest.force)) <= 5e-3 * fn, (default.force, finest.force)


def test_v_th_is_the_legs_default() -> None:
    """The leg's default threshold is the one derived from table 10 (docs/contact_law.md)."""
    from legbench.model import load_params

    assert load_params().contact.v_th == pytest.approx(1.0e-3)
    assert ContactParams().v_th == pytest.approx(1.0e-3)


def test_pinocchio_implicit_friction_is_plain_euler_out_of_contact() -> None:
    """Out of contact K = 0: the implicit-friction step is the explicit one, bit for bit (free swing, 0.3 s)."""
    _need("pinocchio")
    from legbench.backends.base import Physics

    out = []
    for friction in ("implicit", "explicit"):
        b = registry.load("pinocchio", Physics(), {"friction": friction})
        b.reset(np.array([0.3, 0.5, -0.4]), np.zeros(3))
        for _ in range(300):
            b.step(np.array([0.5, -1.0, 0.3]))
        out.append(np.concatenate(b.state()))
        b.close()
    assert np.array_equal(out[0], out[1])


def test_mujoco_mean_readout_is_right_where_the_friction_alternates() -> None:
    """impratio 100 with the contact's own friction solref: the friction alternates between sub-steps at the
    cone's edge. The end-state read is off by > 20 % of Fn (the old read-out's failure) and warned; the
    period's mean impulse matches the statics to 0.5 % of Fn."""
    _need("mujoco")
    stiff = {"impratio": 100.0, "friction_solref": "contact", "noslip": False}
    end = _run("effort", "mujoco", **stiff)
    mean = _run("effort", "mujoco", force_readout="mean", **stiff)
    assert end.readout_error > 0.2, end.force
    assert mean.readout_error <= 0.005, (mean.force, mean.statics)
    from legbench.backends.base import Physics

    b = registry.load("mujoco", Physics(), stiff)
    try:
        assert any("force_readout: mean" in w for w in b.warnings())
    finally:
        b.close()


def test_reference_mode_engines_match_pinocchio_with_implicit_friction() -> None:
    """Reference mode at default settings: MuJoCo and Bullet apply the law with the same implicit friction
    correction as the Pinocchio backend, so the effort task neither chatters nor departs from it. What is left
    is the engines' M^-1 per sub-step against Pinocchio's per period: measured 3.8e-7 of max|q1| (1.5e-9 rad; the
    largest absolute error 4.6e-8 rad, q3's), 2.1e-5 of the largest force component; tolerances 10x those.
    Explicit friction: 2e-4 rad, 68 N."""
    from legbench import scenario as scenario_mod
    from legbench.run import physics_of, simulate

    for name in BACKENDS:
        _need(name)
    sc = scenario_mod.load(SCENARIOS["effort"])
    physics = physics_of(sc, "reference")
    runs = {}
    for name in BACKENDS:
        b = registry.load(name, physics, {})
        try:
            runs[name] = simulate(sc, b, physics)
            assert b.warnings() == []
        finally:
            b.close()
    ref = runs["pinocchio"]
    for name in ("mujoco", "pybullet"):
        tr = runs[name]
        assert np.all(np.abs(tr.q - ref.q).max(axis=0) / np.abs(ref.q).max(axis=0) < 4e-6), name
        assert np.all(np.abs(tr.f - ref.f).max(axis=0) / np.abs(ref.f).max(axis=0) < 2e-4), name
        w = tr.t >= tr.t[-1] - 0.5
        assert tr.f[w, 0].std() < 0.5 and tr.f[w, 1].std() < 0.5, name
