"""Contact-law residuals on synthetic data (built from the law itself) and on real backend runs; the sliding
case on every backend; the backends' step warnings."""

from __future__ import annotations

import math

import numpy as np
import pytest

from legbench import backends as registry
from legbench import kinematics
from legbench.contact import ContactParams, ReferenceContact
from legbench.contact_residuals import residuals
from legbench.model import ROOT

P = ContactParams()
Q_STAR = np.array([-0.0025, -1.1899, -1.2599])
BACKENDS = ("pinocchio", "mujoco", "pybullet")


def _need(name: str) -> None:
    if name not in registry.available():
        pytest.skip(f"{name} is not installed")


def _synthetic(qd_dir: np.ndarray, speeds: np.ndarray, depth: float = 0.004) -> tuple[np.ndarray, ...]:
    """Samples at a pose ``depth`` [m] into the ground, moving along ``qd_dir`` at each speed, with the law's force."""
    q0 = kinematics.ik_nearest(kinematics.fk(Q_STAR) - np.array([0.0, 0.0, depth + kinematics.fk(Q_STAR)[2] - 0.0225]),
                               Q_STAR)  # fmt: skip
    law = ReferenceContact.from_leg(P)
    n = len(speeds)
    q = np.tile(q0, (n, 1))
    qd = speeds[:, None] * qd_dir[None, :]
    f = np.array([law.wrench(*q[k], *qd[k])[3:] for k in range(n)])
    return np.arange(n) * 1e-3, q, qd, f


def test_law_data_has_zero_residuals() -> None:
    """Data made by the law: penetration, friction ratio, angle and creep all match it to rounding."""
    # a slip along the ground only (no vertical poc velocity): joint 1 moves the foot almost purely along x
    qd_dir = np.array([1.0, 0.0, 0.0])
    speeds = np.concatenate([np.linspace(1e-5, 0.9 * P.v_th, 20), np.linspace(2 * P.v_th, 0.1, 20)]) / 0.4
    t, q, qd, f = _synthetic(qd_dir, speeds)
    r = residuals(t, q, qd, f, P)
    assert r.n_contact == 40
    assert r.penetration_max < 1e-4 * 0.004 + 1e-12  # pressing-in damping removed exactly; rounding only
    assert r.n_sliding == 20 and r.friction_ratio == pytest.approx(1.0, abs=1e-12)
    assert r.angle_max < 1e-6
    # creep samples: those with mu(v) < 0.9 mu_k, i.e. v < 0.77 v_th: 17 of the 20 below v_th
    assert r.n_creep == 17 and r.creep_speed == pytest.approx(r.creep_law, rel=1e-9)


def test_residuals_see_a_wrong_law() -> None:
    """A Coulomb-like force (mu_s at any slip) and a too-shallow spring show up as residuals of known size."""
    qd_dir = np.array([1.0, 0.0, 0.0])
    speeds = np.linspace(2 * P.v_th, 0.1, 10) / 0.4
    t, q, qd, f = _synthetic(qd_dir, speeds)
    f = f.copy()
    f[:, :2] *= P.mu_s / P.mu_k  # slides with mu_s instead of mu_k
    f[:, 2] *= 0.8  # 20 % less normal force than Kp y (+ damping)
    f[:, :2] *= 0.8
    r = residuals(t, q, qd, f, P)
    assert r.friction_ratio == pytest.approx(P.mu_s / P.mu_k, rel=1e-9)
    assert r.penetration_rel == pytest.approx(0.25, rel=0.05)  # y Kp / Fn - 1 = 1/0.8 - 1 (damping is small here)
    # the same force from a Coulomb engine that declares it slides with mu_s is what it should be: ratio 1 (the
    # report showed MuJoCo's, Bullet's and Drake's 1.167 = mu_s / mu_k as if their friction were 17 % high)
    assert residuals(t, q, qd, f, P, sliding="mu_s").friction_ratio == pytest.approx(1.0, rel=1e-9)


def test_a_missing_sample_leaves_out_only_that_sample() -> None:
    """An imported log's NaN (one joint speed, one friction component) leaves that sample out of the scores that
    need it, as the deviation metrics do; before, one NaN made penetration_max, penetration_rms and creep_speed
    null for the whole run. Each score equals the one over the other samples (1e-12 relative)."""
    qd_dir = np.array([1.0, 0.0, 0.0])
    speeds = np.concatenate([np.linspace(1e-5, 0.9 * P.v_th, 20), np.linspace(2 * P.v_th, 0.1, 20)]) / 0.4
    t, q, qd, f = _synthetic(qd_dir, speeds)
    f = f.copy()
    f[:, 2] *= 1.01  # a 1 % stiffer spring, so that the penetration residual is not round-off
    qd_gap, f_gap = qd.copy(), f.copy()
    qd_gap[3, 1] = np.nan  # a creep sample
    f_gap[30, 0] = np.nan  # a sliding sample
    keep = np.ones(len(t), dtype=bool)
    keep[[3, 30]] = False
    r = residuals(t, q, qd_gap, f_gap, P)
    ref = residuals(t[keep], q[keep], qd[keep], f[keep], P)
    for key, value in ref.to_dict().items():
        got = r.to_dict()[key]
        assert math.isfinite(got), key
        if key == "n_contact":
            assert got == value + 2  # both samples have a normal force: in contact
        elif key.startswith("n_"):
            assert got == value, key
        else:
            assert got == pytest.approx(value, rel=1e-12), key


def test_rotated_friction_gives_its_angle() -> None:
    qd_dir = np.array([1.0, 0.0, 0.0])
    t, q, qd, f = _synthetic(qd_dir, np.linspace(2 * P.v_th, 0.1, 5) / 0.4)
    c, s = math.cos(math.radians(10)), math.sin(math.radians(10))
    f = f.copy()
    f[:, 0], f[:, 1] = c * f[:, 0] - s * f[:, 1], s * f[:, 0] + c * f[:, 1]
    r = residuals(t, q, qd, f, P)
    assert r.angle_max == pytest.approx(10.0, abs=1e-6)


@pytest.mark.parametrize("backend", BACKENDS)
def test_residuals_on_the_effort_task(backend: str) -> None:
    """Real runs: the law creeps as the law says (pinocchio); Coulomb engines creep far below it; every
    backend's penetration is Fn/Kp in steady contact (1 % of it: the soft contacts of the engines)."""
    _need(backend)
    from legbench import scenario as scenario_mod
    from legbench.run import physics_of, simulate

    sc = scenario_mod.load(ROOT / "scenarios" / "effort.yaml")
    physics = physics_of(sc)
    b = registry.load(backend, physics, {})
    try:
        tr = simulate(sc, b, physics)
    finally:
        b.close()
    late = tr.t >= 1.0
    r = residuals(tr.t[late], tr.q[late], tr.qd[late], tr.f[late], physics.contact)
    assert r.n_contact == int(late.sum())
    assert r.penetration_rel < 0.01, r
    assert r.n_sliding == 0
    if backend == "pinocchio":
        assert r.creep_speed == pytest.approx(r.creep_law, rel=0.02), r  # steady: v = v_th F_t / (mu_s Fn)
    else:
        assert r.creep_speed < 0.01 * r.creep_law, r  # Coulomb cone: sticks


@pytest.mark.parametrize("backend", BACKENDS)
def test_sliding_case_passes(backend: str) -> None:
    _need(backend)
    from legbench.studies.sliding_case import ROW_KEYS, sliding_case

    rows = sliding_case(backend)
    assert len(rows) == 3 and all(tuple(r) == ROW_KEYS for r in rows)
    assert all(r["passed"] for r in rows), rows
    mu = rows[0]["expected"]
    assert mu == (P.mu_k if backend == "pinocchio" else P.mu_s)


def test_sliding_case_unknown_backend_is_a_failed_row() -> None:
    from legbench.studies.sliding_case import sliding_case

    rows = sliding_case("no-such-engine")
    assert len(rows) == 1 and rows[0]["passed"] is False and "no-such-engine" in rows[0]["note"]


def _short_effort() -> tuple[object, object]:
    from legbench import scenario as scenario_mod
    from legbench.run import physics_of

    sc = scenario_mod.load(ROOT / "scenarios" / "effort.yaml", {"duration": 0.3, "comparison.steady_window": 0.1})
    return sc, physics_of


@pytest.mark.parametrize(
    ("backend", "mode", "settings", "warns"),
    [
        ("pinocchio", "native", {}, False),
        ("pinocchio", "native", {"friction": "explicit"}, True),
        ("pinocchio", "native", {"friction": "explicit", "dt": 5e-6}, False),
        ("mujoco", "native", {}, False),
        ("mujoco", "native", {"noslip": False}, True),
        ("mujoco", "reference", {}, False),
        ("mujoco", "reference", {"reference_friction": "explicit"}, True),
        ("pybullet", "native", {}, False),
        ("pybullet", "reference", {}, False),
        ("pybullet", "reference", {"reference_friction": "explicit"}, True),
    ],
)
def test_step_warnings(backend: str, mode: str, settings: dict[str, object], warns: bool) -> None:
    """A sub-step above m v_th / (mu_s Fn) (~5.6 us at the effort task's ~59 N peak) is said, with its numbers."""
    _need(backend)
    from legbench.run import simulate

    sc, physics_of = _short_effort()
    physics = physics_of(sc, mode)  # type: ignore[operator]
    b = registry.load(backend, physics, settings)
    try:
        simulate(sc, b, physics)  # type: ignore[arg-type]
        w = b.warnings()
    finally:
        b.close()
    assert bool(w) == warns, w
    if warns and "sub-step" in w[0]:
        assert "m v_th / (mu_s Fn)" in w[0] and "kg" in w[0]


@pytest.mark.parametrize("backend", BACKENDS)
def test_sliding_case_engine_defaults(backend: str) -> None:
    """Engine defaults: the law and Bullet's cone pass as in the matched profile; MuJoCo's default pyramidal
    cone slides with |F_t| = mu_s Fn but not opposite the slip (measured 10 deg: friction along the pyramid's
    edges), and its 1 ms step with the default impedance lets the foot hop, so the closed form misses."""
    _need(backend)
    from legbench.studies.sliding_case import sliding_case

    rows = {r["quantity"].split()[0]: r for r in sliding_case(backend, "engine-defaults")}
    assert rows["friction"]["passed"], rows["friction"]
    if backend == "mujoco":
        assert rows["angle"]["measured"] > 5.0 and not rows["angle"]["passed"], rows["angle"]
    else:
        assert all(r["passed"] for r in rows.values()), rows


def test_the_slip_is_taken_where_the_backend_says_its_force_acts() -> None:
    """A foot 4 mm in the ground rolling about the point halfway through its penetration (where MuJoCo's
    contact acts, lift 0.5): that point does not slip, the sphere's lowest point does (omega x 2 mm). Read at the
    declared point every sample is a creep sample at 0 m/s (to round-off); read at the true poc, as every
    engine was before, the same samples slip at 0.11-1.1 mm/s, and a sticking Coulomb engine would seem to
    violate the law."""
    t, q, _, _ = _synthetic(np.array([1.0, 0.0, 0.0]), np.zeros(20))
    J_mid = kinematics.jacobian_at(q[0], "true", 0.5)
    direction = np.linalg.svd(J_mid[:2])[2][-1]  # joint motion that leaves the mid point's horizontal velocity 0
    qd = np.linspace(0.1, 1.0, 20)[:, None] * direction[None, :]  # [rad/s]
    f = np.tile([1.0, 0.0, 40.0], (20, 1))  # [N]: a sub-limit tangential load, 40 N down
    at_mid = residuals(t, q, qd, f, P, ("true", 0.5))
    at_poc = residuals(t, q, qd, f, P)
    assert at_mid.n_creep == 20 and at_mid.creep_speed < 1e-15
    v_poc = np.hypot(*(kinematics.jacobian_poc(q) @ qd[..., None])[:, :2, 0].T)
    assert at_poc.creep_speed == pytest.approx(float(np.median(v_poc)), rel=1e-12) and at_poc.creep_speed > 1e-4
