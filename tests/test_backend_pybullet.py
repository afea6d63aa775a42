"""The PyBullet backend: Bullet's own sub-stepping against n x (command + step), its force read-out, no banner.

Native contact takes one torque command and one ``stepSimulation`` of ``numSubSteps = n_sub``
per control period (``sub_stepping: bullet``, the default); ``sub_stepping: python`` makes the
``n_sub`` calls itself. The two must give the same log.
"""

from __future__ import annotations

import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("pybullet")

from test_backends_engines import R_FOOT, check_delassus, run_press  # noqa: E402

from legbench import backends as registry  # noqa: E402
from legbench import kinematics, model, scenario  # noqa: E402
from legbench.backends.base import Physics  # noqa: E402
from legbench.backends.pybullet_ import CONTACT_ROWS  # noqa: E402
from legbench.backends.pybullet_ import p as bullet  # noqa: E402
from legbench.run import simulate  # noqa: E402
from legbench.scenario import physics_of, shorten  # noqa: E402
from legbench.studies.contact_study import steady_contact  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def _run(task: str, settings: dict[str, object], duration: float | None = None, mode: str | None = None):  # type: ignore[no-untyped-def]
    sc = scenario.load(ROOT / "scenarios" / f"{task}.yaml")
    if duration is not None:
        sc = shorten(sc, duration)
    physics = physics_of(sc, mode)
    backend = registry.load("pybullet", physics, {**sc.backends.get("pybullet", {}), **settings})
    try:
        return simulate(sc, backend, physics), backend.info(), backend.limits()
    finally:
        backend.close()


@pytest.mark.parametrize(("task", "duration"), [("effort", None), ("combined", 2.5)])
def test_own_sub_stepping_gives_the_log_of_n_commands_and_steps(task: str, duration: float | None) -> None:
    """q and qd bit-identical; the force to 1e-12 N.

    Bullet holds the commanded torque over its internal steps and clears it after the last, so the
    states cannot differ by a single bit. The force is the same impulse divided by the whole period
    and multiplied by n_sub instead of divided by the sub-step: one rounding apart (measured 1.4e-14 N
    at 68 N); 1e-12 N allows a few of them and nothing physical. The combined task covers the
    touch-down at 1 s and the push from 2 s; the effort task the sustained press.
    """
    own, info, limits = _run(task, {"sub_stepping": "bullet"}, duration)
    ref, info_ref, _ = _run(task, {"sub_stepping": "python"}, duration)
    assert own.status == ref.status == "ok"
    assert np.max(own.f[:, 2]) > 30.0  # [N]: the run does press on the ground
    assert np.array_equal(own.q, ref.q) and np.array_equal(own.qd, ref.qd)
    assert np.array_equal(own.tau, ref.tau)
    assert np.max(np.abs(own.f - ref.f)) < 1e-12
    assert info["engine_sub_steps"] == info["sub_steps"] == 20 and info["step_calls_per_period"] == 1
    assert info_ref["engine_sub_steps"] == 1 and info_ref["step_calls_per_period"] == 20
    assert info["timestep"] == info_ref["timestep"] == limits.timestep == pytest.approx(5e-5, rel=1e-12)


def test_rescaled_force_matches_the_statics_with_own_sub_stepping() -> None:
    """Effort task, last 0.5 s: the mean force equals the statics h = -(J_poc^T)^-1 (tau - G) within 1e-5 of Fn.

    getContactPoints divides the last internal step's impulse by the whole period (numSubSteps x
    the sub-step); the backend multiplies by numSubSteps. Measured 2e-7 of Fn (the foot sticks, so
    the statics hold to the solver's convergence); the unscaled read-out would be off by
    1 - 1/20 = 95 %, and a scale off by one sub-step (19/20) by 5 %: 1e-5 catches both with room.
    """
    tr, info, _ = _run("effort", {})
    assert info["engine_sub_steps"] == 20
    s = steady_contact(tr)
    assert s.force[2] > 30.0  # [N]
    assert s.readout_error < 1e-5, (s.force, s.statics)


def test_reference_mode_keeps_one_bullet_step_per_sub_step() -> None:
    """Reference contact needs the law at every sub-step's start state, so Bullet's own sub-stepping is not used."""
    tr, info, limits = _run("effort", {}, 0.2, "reference")
    assert tr.status == "ok"
    assert info["engine_sub_steps"] == 1 and info["step_calls_per_period"] == 20
    assert limits.timestep == pytest.approx(5e-5, rel=1e-12)


def test_import_prints_no_build_banner_but_keeps_other_stderr() -> None:
    """Importing the backend writes nothing to stdout or stderr (pybullet alone prints its build time to stderr)."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    code = "import sys, legbench.backends.pybullet_; sys.stderr.write('after\\n')"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True)
    assert out.stdout == ""
    assert out.stderr == "after\n"
    bare = subprocess.run([sys.executable, "-c", "import pybullet"], capture_output=True, text=True, env=env)
    assert "pybullet build time" in bare.stderr  # the banner this backend hides is really there


def _press(settings: dict[str, object]):  # type: ignore[no-untyped-def]
    """Foot pressed with 40 N and dragged with 3.6 N (tests/test_backends_engines.py's press), 0.8 s: backend, log."""
    backend = registry.load("pybullet", Physics(), settings)
    return backend, run_press(backend, np.array([3.0, 2.0, -40.0]), duration=0.8)


def test_bullet_keeps_the_foot_first_in_its_contact_manifold() -> None:
    """The raw contact (manifold body0, body1) is (foot, ground), so getContactPoints(foot, ground) swaps nothing.

    When it swaps, PyBullet negates the normal but not the friction directions
    (PhysicsServerCommandProcessor.cpp), so the backend's friction read-out
    relies on Bullet's own order: btConvexPlaneCollisionAlgorithm creates a
    sphere-plane manifold as (sphere, plane). Checked on the unfiltered
    getContactPoints, and with the drag: the read force balances the statics
    (F = -h) to 1e-5 of Fn in all three components (a flipped friction would be
    off by twice the 3.6 N drag, 9 % of Fn; measured 2e-7).
    """
    backend, log = _press({})
    try:
        raw = bullet.getContactPoints(physicsClientId=backend.cid)
        assert len(raw) >= 1
        assert {(cp[1], cp[3], cp[2]) for cp in raw} == {(backend.body, backend.foot, backend.ground)}
    finally:
        backend.close()
    q, tau, F = log["q"][-1], log["tau"][-1], log["F"][-1]
    h = np.linalg.solve(kinematics.jacobian_poc(q).T, tau - model.gravity_torque(q))
    assert F[2] > 30.0 and np.hypot(F[0], F[1]) > 2.0  # [N]: pressing and dragged
    assert np.linalg.norm(F + h) < 1e-5 * F[2], (F, -h)


def test_default_margins_record_and_apply_pybullets_1e5_m_slop() -> None:
    """contact_margins: default keeps PyBullet's contactSlop, 1e-5 m (not Bullet's 0): info() records the number,
    and the resting foot sinks that much deeper than with zero margins at the same force.

    Depth beyond Fn / Kp, y - Fn / Kp with y = R_foot - z_E: the slop adds 1e-5 m to it (measured 2.7e-7 m
    with zero margins, 1.027e-5 m with PyBullet's: the difference 1.000e-5 m); checked to 1e-7 m, 1 % of the
    slop.
    """
    extra = {}
    for margins in ("zero", "default"):
        backend, log = _press({"contact_margins": margins})
        try:
            info = backend.info()["contact"]
        finally:
            backend.close()
        y = R_FOOT - kinematics.fk(log["q"][-1])[2]
        extra[margins] = y - log["F"][-1][2] / 1e4  # [m], Kp = 1e4 N/m (the rigid plane in series)
        assert info["contact_slop"] == (0.0 if margins == "zero" else 1e-5)
    assert extra["default"] - extra["zero"] == pytest.approx(1e-5, abs=1e-7), extra


def test_own_sub_stepping_only_where_bullets_accumulator_takes_every_step() -> None:
    """Bullet takes int(held time / (T / n)) internal steps per stepSimulation, clamped to n, keeping the rest: at
    n = 61 (dt = 1/61 ms, which the one sub-step rule accepts) half the calls took 60 steps and the time was lost,
    a free body at 1 m/s covering 0.99180 m in 1000 periods instead of 1 m (and the force read-out scaled by 61
    where 60 steps ran). The backend now uses Bullet's own sub-stepping only where the accumulator comes back to
    exactly 0 (n = 1..60 at 1 kHz) and steps n times itself elsewhere: 61 steps of the 61st of a period each."""
    from legbench.backends.pybullet_ import bullet_substeps_exact

    assert all(bullet_substeps_exact(1e-3, n) for n in range(1, 61))
    assert not any(bullet_substeps_exact(1e-3, n) for n in (61, 105, 109, 115, 122, 123))
    # Bullet itself, at n = 61: a free body at 1 m/s and no gravity over 1000 periods
    cid = bullet.connect(bullet.DIRECT)
    try:
        bullet.setGravity(0.0, 0.0, 0.0, physicsClientId=cid)
        bullet.setPhysicsEngineParameter(fixedTimeStep=1e-3, numSubSteps=61, physicsClientId=cid)
        shape = bullet.createCollisionShape(bullet.GEOM_SPHERE, radius=0.1, physicsClientId=cid)
        body = bullet.createMultiBody(1.0, shape, basePosition=[0, 0, 10], physicsClientId=cid)
        bullet.changeDynamics(body, -1, linearDamping=0.0, angularDamping=0.0, physicsClientId=cid)
        bullet.resetBaseVelocity(body, [1.0, 0.0, 0.0], physicsClientId=cid)
        for _ in range(1000):
            bullet.stepSimulation(physicsClientId=cid)
        x = bullet.getBasePositionAndOrientation(body, physicsClientId=cid)[0][0]
    finally:
        bullet.disconnect(cid)
    assert x == pytest.approx(1.0 - 500 / 61000, abs=1e-9)  # 500 steps of 1/61 ms lost
    sc = shorten(scenario.load(ROOT / "scenarios" / "position.yaml"), 0.05)
    own, info, _ = _run("position", {"sub_stepping": "bullet", "dt": 1e-3 / 61}, 0.05)
    ref, info_ref, _ = _run("position", {"sub_stepping": "python", "dt": 1e-3 / 61}, 0.05)
    assert info["step_calls_per_period"] == info_ref["step_calls_per_period"] == 61 and info["engine_sub_steps"] == 1
    assert np.array_equal(own.q, ref.q) and len(own.t) == sc.n_ticks


@pytest.mark.parametrize(("plane", "damping"), [("rigid", 0.0), ("default", 0.1)])
def test_info_gives_the_plane_contact_bullet_combines_not_getdynamicsinfos_unset(
    plane: str, damping: float, tmp_path: Path
) -> None:
    """getDynamicsInfo reports -1 for a body whose contact stiffness and damping were never set (engine-defaults'
    plane); Bullet then combines its btCollisionObject defaults, 1e30 N/m and 0.1 N s/m. info() (and so the
    report's settings table) showed -1, -1; it gives the values combined and the pair's contact, which the
    calibration push measures: c_eff 100.102 (default plane) against 100.002 N s/m (rigid plane)."""
    import yaml

    from legbench.studies import calibrate_contact as cc

    base = yaml.safe_load(Path(cc.SCENARIO).read_text())
    sc = scenario.load(ROOT / "scenarios" / "effort.yaml")
    backend = registry.load("pybullet", physics_of(sc, "native"), {"plane_contact": plane})
    try:
        contact = backend.info()["contact"]
    finally:
        backend.close()
    assert contact["plane_damping"] == damping and contact["plane_stiffness"] >= 1e30
    assert contact["pair_damping"] == pytest.approx(sc.contact.Kd + damping, abs=1e-12)
    assert contact["pair_stiffness"] == pytest.approx(sc.contact.Kp, rel=1e-12)
    path = tmp_path / "push.yaml"
    path.write_text(yaml.safe_dump({**base, "backends": {"pybullet": {"plane_contact": plane}}}))
    log, saturated = cc.push("pybullet", cc.Program(), path)
    est = cc.estimate(log, cc.Program(), scenario.load(path).contact, saturated)
    assert est.c_eff == pytest.approx(contact["pair_damping"], abs=0.01)  # [N s/m]: measured 100.002, 100.102


def test_the_friction_anchor_holds_the_foot_where_the_velocity_level_friction_lets_it_drift() -> None:
    """``friction_anchor: on`` (Bullet's frictionAnchor, off in PyBullet and in both profiles) holds the contact
    point: over the effort task's last 2 s the foot centre moves 1.9 um sideways with the anchor off (the
    velocity-level Coulomb cone's drift under the tangential load) and not at all with it on (< 1 nm); info()
    records the setting."""
    drift = {}
    for anchor in ("off", "on"):
        tr, info, _ = _run("effort", {"friction_anchor": anchor})
        assert info["friction_anchor"] == anchor
        e = kinematics.fk(tr.q)
        i = np.flatnonzero(tr.t >= 1.0)
        drift[anchor] = float(np.hypot(*(e[i[-1], :2] - e[i[0], :2])))  # [m]
    assert drift["off"] == pytest.approx(1.9e-6, rel=0.1) and drift["on"] < 1e-9, drift


@pytest.mark.parametrize(("threshold", "passes"), [(1e-7, 2), (1e-9, 4), (0.0, None)])
def test_the_held_foots_creep_is_what_the_solvers_residual_threshold_leaves(
    monkeypatch: pytest.MonkeyPatch, threshold: float, passes: int | None
) -> None:
    """Under the calibration's hold (40 N, 13.2 N drag, below mu_s Fn) Bullet's foot creeps at what its solver's
    passes leave: it stops at the first pass whose squared row residual is below the threshold (PyBullet's 1e-7:
    2 passes, 12.56 um/s; 1e-9: 4 passes, 0.07 um/s), and the closed form of those passes (pgs_creep, from the run's
    own W = J M^-1 J^T) meets the measured creep within 0.1 %; with the threshold at 0 the passes run until the
    residual is round-off and the foot sticks (below the calibration's 1e-9 m/s)."""
    from legbench.backends import pybullet_
    from legbench.studies import calibrate_contact

    monkeypatch.setattr(pybullet_, "PYBULLET_RESIDUAL_THRESHOLD", threshold)
    log, _ = calibrate_contact.push("pybullet")
    sc = scenario.load(calibrate_contact.SCENARIO)
    row = calibrate_contact.estimate(log, calibrate_contact.Program(), sc.contact)
    contact = log.info["contact"]
    assert contact["solver_residual_threshold"] == threshold
    end = log.t > log.t[-1] - calibrate_contact.Program().window - 1e-9
    W = np.array(log.info["at_end"]["delassus"])
    v, n = pybullet_.pgs_creep(W, log.info["timestep"], contact["pair_stiffness"], contact["pair_damping"],
                               log.f[end].mean(axis=0), threshold, 50)  # fmt: skip
    if passes is not None:
        assert n == passes
        assert row.creep == pytest.approx(v, rel=1e-3), (row.creep, v)
        assert f"here after {passes} of 50 passes" in row.note, row.note
    else:
        assert row.creep < calibrate_contact.STICK_SPEED and v < calibrate_contact.STICK_SPEED


def test_info_gives_the_contact_rows_delassus_from_the_engines_own_mass_matrix() -> None:
    """info()'s at_end.delassus, W = J M^-1 J^T at the sphere's lowest point with the engine's own mass matrix
    (what the calibration's creep closed form is built on), equals the spec leg's (Pinocchio's M) to 1e-6 of its
    largest entry, symmetric positive definite; a state that is not finite (a diverged run) gives None, not NaN."""
    check_delassus("pybullet", np.array(CONTACT_ROWS), lambda b: setattr(b, "_reading", (math.nan,) * 9))


def test_pass_counts_that_cycle_give_no_steady_creep_and_the_rows_are_bullets_own() -> None:
    """Where no pass count leaves a steady state that stops at it (a drag of 0.6 mu_s Fn at the effort task's start,
    50 us: the counts map 1 -> 3, 2 -> 3, 3 -> 2), pgs_creep says NaN (no steady creep to explain), not one side of
    the cycle; and CONTACT_ROWS' friction directions are the ones Bullet reports for the foot's contact."""
    from legbench.backends import pybullet_

    sc = scenario.load(ROOT / "scenarios" / "effort.yaml")
    backend = registry.load("pybullet", physics_of(sc), {})
    try:
        backend.reset(np.array(sc.q0), np.zeros(3))
        info = backend.info()
        contact = info["contact"]
        W = np.array(info["at_end"]["delassus"])
        v, _ = pybullet_.pgs_creep(W, info["timestep"], contact["pair_stiffness"], contact["pair_damping"],
                                   np.array([23.86, 0.0, 40.0]), 1e-7, 50)  # fmt: skip
        assert math.isnan(v)
        for _ in range(50):  # onto the ground under the effort task's start torques: a contact to read
            backend.step(np.zeros(3))
        points = bullet.getContactPoints(bodyA=backend.body, physicsClientId=backend.cid)  # type: ignore[attr-defined]
        assert points, "no contact to read the friction directions from"
        for point in points:
            n, d1, d2 = np.array(point[7]), np.array(point[11]), np.array(point[13])
            assert np.allclose(np.abs([n, d1, d2]), np.abs(np.array(pybullet_.CONTACT_ROWS)), atol=1e-9), point
    finally:
        backend.close()
