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
from legbench.model import ROOT, load_params

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
    """Data made by the law: penetration, friction ratio, angle and creep all match it to rounding (penetration
    below 1e-15 m, a few ulp of the 0.2 m links; measured 0.0 m)."""
    # joint 1 alone: the poc slips along x (v_t = 0.404 m/rad qd1, vy = 0) and rises (vz = 0.111 m/rad qd1), so
    # ydot < 0 and the law adds no damping here (pressing in: test_pressing_in_damping_is_not_the_springs)
    qd_dir = np.array([1.0, 0.0, 0.0])
    speeds = np.concatenate([np.linspace(1e-5, 0.9 * P.v_th, 20), np.linspace(2 * P.v_th, 0.1, 20)]) / 0.4
    t, q, qd, f = _synthetic(qd_dir, speeds)
    r = residuals(t, q, qd, f, P)
    assert r.n_contact == 40
    assert r.penetration_max < 1e-15  # Fn = Kp y exactly: y - Fn / Kp is round-off only
    assert r.n_sliding == 20 and r.friction_ratio == pytest.approx(1.0, abs=1e-12)
    assert r.angle_max < 1e-6
    # creep samples: those with mu(v) < 0.9 mu_k, i.e. v < 0.77 v_th: 17 of the 20 below v_th
    assert r.n_creep == 17 and r.creep_speed == pytest.approx(r.creep_law, rel=1e-9)


def test_pressing_in_damping_is_not_the_springs() -> None:
    """A foot pressing in (ydot > 0) carries Fn = Kp y + Kd ydot: the spring's share is Fn - Kd ydot, so the
    penetration residual is round-off only (below 1e-15 m, measured 0.0 m; penetration_rel below 1e-12), where
    counting the damping as spring would read Kd ydot / Kp, up to 2.8e-4 m here (ydot up to 0.028 m/s, Kd / Kp =
    0.01 s). Friction ratio 1 (1e-12) and the same sliding and creep samples as the rising foot."""
    qd_dir = np.array([-1.0, 0.0, 0.0])  # joint 1 backwards: the poc slips along -x and sinks (ydot = 0.275 v_t)
    speeds = np.concatenate([np.linspace(1e-5, 0.9 * P.v_th, 20), np.linspace(2 * P.v_th, 0.1, 20)]) / 0.4
    t, q, qd, f = _synthetic(qd_dir, speeds)
    ydot = -(kinematics.jacobian_poc(q) @ qd[..., None])[:, 2, 0]
    assert ydot.min() > 0 and P.Kd * ydot.max() / P.Kp > 2.7e-4  # [m]: every sample presses in, visibly
    y = load_params().geometry.R_foot - kinematics.fk(q)[:, 2]
    np.testing.assert_allclose(f[:, 2], P.Kp * y + P.Kd * ydot, rtol=1e-12)  # the law's force includes Kd ydot
    r = residuals(t, q, qd, f, P)
    assert r.n_contact == 40
    assert r.penetration_max < 1e-15 and r.penetration_rms < 1e-15 and r.penetration_rel < 1e-12
    assert r.n_sliding == 20 and r.friction_ratio == pytest.approx(1.0, abs=1e-12)
    assert r.n_creep == 17


def _slip_gain(qd_dir: np.ndarray) -> float:
    """Slip speed [m/s] of the poc per unit joint speed along ``qd_dir`` at :func:`_synthetic`'s pose."""
    q0 = _synthetic(qd_dir, np.zeros(1))[1][0]
    return float(np.hypot(*(kinematics.jacobian_poc(q0) @ qd_dir)[:2]))


def test_sliding_starts_at_the_end_of_the_falling_ramp() -> None:
    """Only a slip at or above 1.5 v_th counts as sliding (the law's mu_k): on the ramp v_th..1.5 v_th mu falls
    from mu_s to mu_k, and those samples (1.05-1.49 v_th, |F_t| / (mu_k Fn) = 1.15-1.0033) are not scored, so the
    friction ratio of the law's own data is 1 (1e-12) over the four samples at 1.51-50 v_th."""
    qd_dir = np.array([1.0, 0.0, 0.0])
    ramp, beyond = np.array([1.05, 1.2, 1.35, 1.49]), np.array([1.51, 2.0, 5.0, 50.0])
    t, q, qd, f = _synthetic(qd_dir, np.concatenate([ramp, beyond]) * P.v_th / _slip_gain(qd_dir))
    r = residuals(t, q, qd, f, P)
    assert r.n_contact == 8
    assert r.n_sliding == 4 and r.friction_ratio == pytest.approx(1.0, abs=1e-12)
    ramp_ratio = np.hypot(f[:4, 0], f[:4, 1]) / (P.mu_k * f[:4, 2])
    assert ramp_ratio.min() > 1.003  # what counting the ramp would have scored: friction above mu_k


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
    # the poc rises (ydot < 0): no damping, Fn = 0.8 Kp y, so y Kp / Fn - 1 = 1/0.8 - 1 = 0.25 up to round-off (a few
    # ulp of 1.25, 2.2e-16 each; measured 0.0): 1e-14
    assert r.penetration_rel == pytest.approx(0.25, rel=0, abs=1e-14)
    # the same force from a Coulomb engine that declares it slides with mu_s is what it should be: ratio 1 (the
    # report showed MuJoCo's, Bullet's and Drake's 1.167 = mu_s / mu_k as if their friction were 17 % high)
    assert residuals(t, q, qd, f, P, sliding="mu_s").friction_ratio == pytest.approx(1.0, rel=1e-9)


def test_frictionless_ground_has_no_friction_ratio_and_no_warning() -> None:
    """mu_s = mu_k = 0 (a frictionless ground, valid input): sliding samples are counted, their friction ratio
    |F_t| / (mu Fn) is n/a (NaN), and nothing is divided by zero (numpy's RuntimeWarning reached the terminal of
    `legbench run` with its source line); the penetration is scored as before."""
    import dataclasses
    import warnings

    frictionless = dataclasses.replace(P, mu_s=0.0, mu_k=0.0)
    speeds = np.linspace(2 * P.v_th, 0.1, 10) / 0.4
    t, q, qd, f = _synthetic(np.array([1.0, 0.0, 0.0]), speeds)
    f = f.copy()
    f[:, :2] = 0.0  # no friction
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        r = residuals(t, q, qd, f, frictionless)
    assert r.n_sliding == 10 and math.isnan(r.friction_ratio)
    assert r.penetration_max < 1e-15


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
    """Friction turned 10 deg from opposite the slip at every sliding sample reads angle_max 10 deg (1e-6 deg)."""
    qd_dir = np.array([1.0, 0.0, 0.0])
    t, q, qd, f = _synthetic(qd_dir, np.linspace(2 * P.v_th, 0.1, 5) / 0.4)
    c, s = math.cos(math.radians(10)), math.sin(math.radians(10))
    f = f.copy()
    f[:, 0], f[:, 1] = c * f[:, 0] - s * f[:, 1], s * f[:, 0] + c * f[:, 1]
    r = residuals(t, q, qd, f, P)
    assert r.angle_max == pytest.approx(10.0, abs=1e-6)


def test_angle_scores_are_the_largest_and_the_median_angle() -> None:
    """Friction turned by a different angle at each sample (3, 25, 10, 7 and 15 deg from opposite the slip):
    angle_max is the largest, 25 deg, and angle_median the middle one, 10 deg (1e-9 deg: arccos of a rotation
    by cos and sin, round-off ~1e-14 deg)."""
    qd_dir = np.array([1.0, 0.0, 0.0])
    t, q, qd, f = _synthetic(qd_dir, np.linspace(2 * P.v_th, 0.1, 5) / 0.4)
    a = np.radians([3.0, 25.0, 10.0, 7.0, 15.0])
    f = f.copy()
    f[:, 0], f[:, 1] = np.cos(a) * f[:, 0] - np.sin(a) * f[:, 1], np.sin(a) * f[:, 0] + np.cos(a) * f[:, 1]
    r = residuals(t, q, qd, f, P)
    assert r.n_direction == 5
    assert r.angle_max == pytest.approx(25.0, abs=1e-9)
    assert r.angle_median == pytest.approx(10.0, abs=1e-9)


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
    from legbench.studies.sliding_case import COUNT_KEYS, ROW_KEYS, sliding_case

    rows = sliding_case(backend)
    assert len(rows) == 3 and all(tuple(r) == ROW_KEYS + COUNT_KEYS for r in rows)
    # the foot stays on the ground through the window: every sample in contact, every difference scored
    assert all(r["out_of_contact"] == 0 and r["acceleration_samples"] == r["window_samples"] == 51 for r in rows), rows
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
    cone, a diamond, slides on its vertex (|F_y| = mu_s Fn, F_x = 0, up to 10 deg off the slip) as the
    diamond's closed form says, and its 1 ms step with the default impedance lets the foot hop, so the slip
    acceleration misses, saying why (tests/test_sliding_case.py)."""
    _need(backend)
    from legbench.studies.sliding_case import sliding_case

    rows = {r["quantity"].split()[0]: r for r in sliding_case(backend, "engine-defaults")}
    assert rows["friction"]["passed"] and rows["angle"]["passed"], rows
    if backend == "mujoco":
        assert not rows["slip"]["passed"] and rows["slip"]["note"].startswith("known: "), rows["slip"]
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


def test_penetration_max_and_rms_of_an_uneven_spring_error() -> None:
    """At the pose 4 mm in the ground (y = 4 mm, rising: ydot < 0, no damping, so Fn_spring = Fn), normal forces
    of 0.75, 1.125, 0.9375, 1 and 0.5 Kp y leave y - Fn / Kp = 1, -0.5, 0.25, 0 and 2 mm: penetration_max is the
    largest |.|, 2 mm, and penetration_rms sqrt((1 + 0.25 + 0.0625 + 0 + 4) / 5) mm = sqrt(1.0625) mm =
    1.0308 mm, not the largest (1e-15 m: y from the forward kinematics is 4 mm to a few ulp of the 0.2 m links,
    ~1e-16 m)."""
    qd_dir = np.array([1.0, 0.0, 0.0])
    t, q, qd, f = _synthetic(qd_dir, np.linspace(2 * P.v_th, 0.1, 5) / 0.4)
    ydot = -(kinematics.jacobian_poc(q) @ qd[..., None])[:, 2, 0]
    assert ydot.max() < 0  # rising: the law adds no damping, the whole normal force is the spring's
    y = 0.004  # [m]: _synthetic's depth
    f = f.copy()
    f[:, 2] = np.array([0.75, 1.125, 0.9375, 1.0, 0.5]) * P.Kp * y  # [N]: 30, 45, 37.5, 40, 20
    r = residuals(t, q, qd, f, P)
    assert r.n_contact == 5
    assert r.penetration_max == pytest.approx(2e-3, rel=0, abs=1e-15)
    assert r.penetration_rms == pytest.approx(1e-3 * math.sqrt(1.0625), rel=0, abs=1e-15)
    # the same from the definition, with y from the forward kinematics: sqrt(mean((y - Fn / Kp)^2))
    y_fk = load_params().geometry.R_foot - kinematics.fk(q)[:, 2]
    assert r.penetration_rms == pytest.approx(math.sqrt(np.mean((y_fk - f[:, 2] / P.Kp) ** 2)), rel=1e-12)


def test_penetration_rel_is_the_median_over_contact_samples() -> None:
    """A spring error that differs over thirds of 9 samples at y = 4 mm (rising, no damping): Fn = 0.8 Kp y on
    the first three (|y Kp / Fn - 1| = 0.25), 1.25 Kp y on the middle three (0.2), 0.5 Kp y on the last three
    (1.0). penetration_rel is their median, 0.25, not the mean 0.4833, the largest 1.0, nor the middle sample's
    0.2 (1e-12: y from the forward kinematics is 4 mm to a few ulp of the 0.2 m links, ~1e-16 m, 2.5e-14 of y;
    measured 2.3e-14)."""
    qd_dir = np.array([1.0, 0.0, 0.0])
    t, q, qd, f = _synthetic(qd_dir, np.linspace(2 * P.v_th, 0.1, 9) / 0.4)
    f = f.copy()
    f[:, 2] = np.repeat([0.8, 1.25, 0.5], 3) * P.Kp * 0.004  # [N]: 32, 50, 20
    r = residuals(t, q, qd, f, P)
    assert r.n_contact == 9
    assert r.penetration_rel == pytest.approx(0.25, rel=0, abs=1e-12)


def test_penetration_max_is_the_largest_residual_also_where_it_is_negative() -> None:
    """A spring that pushes too hard at one sample: at y = 4 mm, rising (ydot < 0, no damping, Fn_spring = Fn),
    normal forces of 0.75, 1.5, 0.9375 and 1 Kp y leave y - Fn / Kp = +1, -2, +0.25 and 0 mm. penetration_max is
    the largest |.|, 2 mm, not the largest signed residual, 1 mm (1e-15 m: y from the forward kinematics is 4 mm to
    a few ulp of the 0.2 m links). A mutation audit found no test with a negative largest residual."""
    qd_dir = np.array([1.0, 0.0, 0.0])
    t, q, qd, f = _synthetic(qd_dir, np.linspace(2 * P.v_th, 0.1, 4) / 0.4)
    ydot = -(kinematics.jacobian_poc(q) @ qd[..., None])[:, 2, 0]
    assert ydot.max() < 0  # rising: the whole normal force is the spring's
    y = 0.004  # [m]: _synthetic's depth
    f = f.copy()
    f[:, 2] = np.array([0.75, 1.5, 0.9375, 1.0]) * P.Kp * y  # [N]: 30, 60, 37.5, 40
    r = residuals(t, q, qd, f, P)
    assert r.n_contact == 4
    assert r.penetration_max == pytest.approx(2e-3, rel=0, abs=1e-15)


def test_a_spring_too_stiff_everywhere_has_a_positive_relative_penetration_error() -> None:
    """Fn = 1.25 Kp y on every sample at y = 4 mm (rising, no damping): |y Kp / Fn - 1| = |0.8 - 1| = 0.2, so
    penetration_rel reads 0.2 (1e-12: y from the forward kinematics is 4 mm to ~1e-16 m, 2.5e-14 of y), a 20 %
    spring error, not -0.2, which a one-sided check such as test_residuals_on_the_effort_task's < 0.01 would pass.
    A mutation audit found that the signed error passed every test."""
    qd_dir = np.array([1.0, 0.0, 0.0])
    t, q, qd, f = _synthetic(qd_dir, np.linspace(2 * P.v_th, 0.1, 5) / 0.4)
    ydot = -(kinematics.jacobian_poc(q) @ qd[..., None])[:, 2, 0]
    assert ydot.max() < 0  # rising: Fn_spring = Fn
    f = f.copy()
    f[:, 2] = 1.25 * P.Kp * 0.004  # [N]: 50
    r = residuals(t, q, qd, f, P)
    assert r.n_contact == 5
    assert r.penetration_rel == pytest.approx(0.2, rel=0, abs=1e-12)


def test_friction_direction_is_scored_from_a_slip_of_1e4_m_per_s() -> None:
    """V_DIRECTION = 1e-4 m/s: below it a sticking foot's direction is numerical noise. Of the law's own samples
    slipping at 0.5 and 0.9 x 1e-4 m/s and at 1.1 and 2 x 1e-4 m/s (slip speeds to ~1e-16 m/s from the
    Jacobian), only the last two are scored for direction (n_direction 2), each with the law's angle, 0 deg
    (1e-6 deg); all four are in contact. A mutation audit found that a threshold of 1e-3 m/s passed every test."""
    qd_dir = np.array([1.0, 0.0, 0.0])
    slip = np.array([0.5, 0.9, 1.1, 2.0]) * 1e-4  # [m/s]
    t, q, qd, f = _synthetic(qd_dir, slip / _slip_gain(qd_dir))
    v = (kinematics.jacobian_poc(q) @ qd[..., None])[:, :2, 0]
    np.testing.assert_allclose(np.hypot(v[:, 0], v[:, 1]), slip, rtol=1e-9)
    assert (np.hypot(f[:, 0], f[:, 1]) > 1.0).all()  # [N]: every sample carries friction (the law's creep, 1.4-5.6 N)
    r = residuals(t, q, qd, f, P)
    assert r.n_contact == 4
    assert r.n_direction == 2
    assert r.angle_max == pytest.approx(0.0, abs=1e-6)


def test_an_airborne_foot_does_not_count_towards_the_penetration() -> None:
    """Six samples made by the law 4 mm in the ground and six with the foot 10 mm up (y = -10 mm, no force, the
    law's zero): only the first six are in contact, and penetration_max is the contact samples' round-off, below
    1e-15 m (measured 0.0 m); the airborne foot's y - Fn_spring / Kp = -10 mm must not count. A mutation audit
    found that scoring every finite sample passed every test."""
    qd_dir = np.array([1.0, 0.0, 0.0])
    speeds = np.linspace(1e-5, 0.1, 6) / 0.4
    _, q_in, qd_in, f_in = _synthetic(qd_dir, speeds)
    _, q_up, qd_up, f_up = _synthetic(qd_dir, speeds, depth=-0.01)
    y_up = load_params().geometry.R_foot - kinematics.fk(q_up)[:, 2]
    np.testing.assert_allclose(y_up, -0.01, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(f_up, 0.0)  # [N]: out of the ground, the law gives nothing
    q, qd, f = np.vstack([q_in, q_up]), np.vstack([qd_in, qd_up]), np.vstack([f_in, f_up])
    r = residuals(np.arange(len(q)) * 1e-3, q, qd, f, P)
    assert r.n_contact == 6
    assert r.penetration_max < 1e-15 and r.penetration_rms < 1e-15


def test_friction_ratio_is_the_median_over_sliding_samples() -> None:
    """Ten sliding samples made by the law (2 v_th to 0.1 m/s), one of them carrying three times the law's
    friction (an impact spike): friction_ratio is the median, 1 (1e-12), not the mean 1.2. A mutation audit found
    that the mean passed every test."""
    t, q, qd, f = _synthetic(np.array([1.0, 0.0, 0.0]), np.linspace(2 * P.v_th, 0.1, 10) / 0.4)
    f = f.copy()
    f[4, :2] *= 3.0  # the spike
    r = residuals(t, q, qd, f, P)
    assert r.n_sliding == 10
    assert r.friction_ratio == pytest.approx(1.0, abs=1e-12)


def test_creep_speed_and_creep_law_are_medians_over_creep_samples() -> None:
    """Nine creep samples made by the law, eight slipping at 2.5e-5 m/s and one at 0.7 v_th = 7e-4 m/s (still a
    sub-limit load: 0.7 mu_s Fn = 0.49 Fn < 0.9 mu_k Fn = 0.54 Fn): creep_speed and creep_law (the law's
    v_th |F_t| / (mu_s Fn), the slip itself for the law's data) are both the median, 2.5e-5 m/s (1e-9 relative:
    the slip from the Jacobian to ~1e-16), not the mean 1e-4 m/s, four times larger. A mutation audit found that
    the mean passed every test for either."""
    qd_dir = np.array([1.0, 0.0, 0.0])
    slip = np.array([2.5e-5] * 8 + [0.7 * P.v_th])  # [m/s]
    t, q, qd, f = _synthetic(qd_dir, slip / _slip_gain(qd_dir))
    r = residuals(t, q, qd, f, P)
    assert r.n_creep == 9
    assert r.creep_speed == pytest.approx(2.5e-5, rel=1e-9)
    assert r.creep_law == pytest.approx(2.5e-5, rel=1e-9)


def test_the_sub_limit_load_is_a_fraction_of_the_total_normal_force() -> None:
    """The sub-limit load is |F_t| < 0.9 min(mu_s, mu_k) Fn with Fn the TOTAL normal force, damping included. A
    foot 4 mm in the ground pressing in at ydot = 0.05 m/s carries Fn = Kp y + Kd ydot = 40 + 5 = 45 N; slipping at
    0.5 v_th with |F_t| = 0.95 x 0.9 mu_k x 45 N = 23.085 N (below 24.3 N, above the spring part's 0.9 mu_k x 40 N =
    21.6 N), every sample is a creep sample and creep_speed is the slip, 0.5 v_th (1e-9 relative: the slip from the
    Jacobian to ~1e-16). A mutation audit found that the spring part alone passed every test."""
    q0 = _synthetic(np.array([1.0, 0.0, 0.0]), np.zeros(1))[1][0]
    slip, ydot = 0.5 * P.v_th, 0.05  # [m/s]
    qd0 = np.linalg.solve(kinematics.jacobian_poc(q0), [slip, 0.0, -ydot])  # the poc slips along x and sinks
    y = load_params().geometry.R_foot - kinematics.fk(q0)[2]
    fn = P.Kp * y + P.Kd * ydot
    assert fn == pytest.approx(45.0, rel=1e-9)
    ft = 0.95 * 0.9 * P.mu_k * fn  # [N], opposite the slip
    n = 5
    q, qd, f = np.tile(q0, (n, 1)), np.tile(qd0, (n, 1)), np.tile([-ft, 0.0, fn], (n, 1))
    r = residuals(np.arange(n) * 1e-3, q, qd, f, P)
    assert r.n_contact == n
    assert r.n_creep == n
    assert r.creep_speed == pytest.approx(slip, rel=1e-9)


def test_the_slip_is_taken_at_the_law_s_poc_by_default() -> None:
    """Data made by the law with its poc at the sphere centre (the report's simplification), the joints moving
    along (0.3, 1, -0.5): residuals called without ``point`` read the slip at the law's poc, the centre, so the
    friction is opposite the slip (angle_max below 1e-5 deg: arccos near 1 of round-off, ~sqrt(2 eps) rad =
    1.2e-6 deg) and the creep speed equals the law's (1e-9 relative). Read at the true poc the same data showed
    0.40 deg and a creep 4 % fast (measured)."""
    import dataclasses

    centre = dataclasses.replace(P, poc="centre")
    law = ReferenceContact.from_leg(centre)
    speeds = np.concatenate([np.linspace(1e-5, 0.9 * P.v_th, 20), np.linspace(2 * P.v_th, 0.1, 20)]) / 0.4
    t, q, qd, _ = _synthetic(np.array([0.3, 1.0, -0.5]), speeds)
    f = np.array([law.wrench(*q[k], *qd[k])[3:] for k in range(len(t))])
    r = residuals(t, q, qd, f, centre)
    assert r.n_contact == 40 and r.n_creep > 0 and r.n_direction > 0
    assert r.angle_max < 1e-5
    assert r.creep_speed == pytest.approx(r.creep_law, rel=1e-9)
