"""Kinematics of the leg against the spec's numbers, Pinocchio and finite differences."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pinocchio as pin
import pytest

from legbench import kinematics as K
from legbench import model

Q_STAR = np.array([-0.0025, -1.1899, -1.2599])
RNG_SEED = 20261121


def random_q(n: int, seed: int = RNG_SEED) -> np.ndarray:
    p = model.load_params()
    rng = np.random.default_rng(seed)
    lo = np.where(np.isfinite(p.lower), p.lower, -np.pi)
    hi = np.where(np.isfinite(p.upper), p.upper, np.pi)
    return rng.uniform(lo, hi, size=(n, 3))


def test_fk_of_q_star_puts_the_foot_centre_one_radius_above_ground() -> None:
    """Spec section 1/3: FK(q*) = W (0.16669, -0.00001, 0.02250) within 1e-5 m."""
    np.testing.assert_allclose(K.fk(Q_STAR), [0.16669, -0.00001, 0.02250], atol=1e-5)


def test_fk_of_zero_is_the_horizontal_leg() -> None:
    """q = 0 is the leg fully extended: W (0.16763, 0.55373, 0.400), exact to rounding."""
    np.testing.assert_allclose(K.fk(np.zeros(3)), [0.16763, 0.55373, 0.400], atol=1e-12)


def test_fk_matches_pinocchio_on_the_generated_urdf() -> None:
    """Hand-written FK and the URDF cannot drift apart: 1e-9 m at 500 random poses."""
    m = model.pinocchio_model()
    d = m.createData()
    fid = m.getFrameId(model.FOOT_FRAME)
    qs = random_q(500)
    ours = K.fk(qs)
    for q, p in zip(qs, ours, strict=True):
        pin.framesForwardKinematics(m, d, model.q_to_pin(q))
        np.testing.assert_allclose(d.oMf[fid].translation, p, atol=1e-9)


def test_batch_fk_equals_single_fk() -> None:
    qs = random_q(20)
    np.testing.assert_allclose(K.fk(qs), np.array([K.fk(q) for q in qs]), atol=0)


def test_ik_round_trip_on_thousands_of_reachable_points() -> None:
    """Every returned solution maps back within 1e-9 m, respects the limits, and the
    configuration that generated the point is among the solutions (1e-7 rad)."""
    p = model.load_params()
    qs = random_q(3000)
    pts = K.fk(qs)
    for q, pt in zip(qs, pts, strict=True):
        res = K.ik(pt)
        assert res, res.reason
        np.testing.assert_allclose(K.fk(res.solutions), np.broadcast_to(pt, res.solutions.shape), atol=1e-9)
        assert np.all(res.solutions >= np.where(np.isfinite(p.lower), p.lower, -np.inf))
        assert np.all(res.solutions <= np.where(np.isfinite(p.upper), p.upper, np.inf))
        assert np.all(np.abs(res.solutions[:, 1]) <= np.pi)
        err = np.abs(K.joint_error(q[None, :], res.solutions)).max(axis=1)
        assert err.min() < 1e-7


def test_ik_of_the_standing_point_lists_q_star() -> None:
    res = K.ik([0.1667, 0.0, 0.0225])
    assert np.abs(res.solutions - Q_STAR).max(axis=1).min() < 2e-3


@pytest.mark.parametrize(
    ("point", "why"),
    [
        ([2.0, 0.0, 0.4], "workspace"),  # far beyond full extension
        ([0.1667, 0.0, 0.50], "workspace"),  # too close to the hip axis for the knee limit
        ([0.0555, 0.0, 0.40], "ab/ad axis"),  # on the ab/ad axis, closer than L_12
    ],
)
def test_unreachable_points_return_no_solution_and_a_reason(point: list[float], why: str) -> None:
    res = K.ik(point)
    assert not res
    assert len(res.solutions) == 0
    assert why in res.reason


def test_random_points_outside_the_workspace_have_no_solution() -> None:
    """Points beyond L23 + L3E + |offsets| from the hip are unreachable; IK must say so."""
    rng = np.random.default_rng(RNG_SEED)
    g = model.load_params().geometry
    centre = np.array([g.L_B0, 0.0, g.H])
    reach = np.hypot(g.L_01, g.L_12) + g.L_23 + g.L_3E
    for _ in range(500):
        d = rng.normal(size=3)
        pt = centre + d / np.linalg.norm(d) * reach * rng.uniform(1.01, 3.0)
        assert not K.ik(pt)


def test_ik_nearest_unwraps_the_hip_across_the_pi_seam() -> None:
    """A foot at fk(0, 3.2, -1) seen from (0, 3.1, -1): IK lists the hip wrapped into [-pi, pi) (hip -3.0832 rad,
    knee -1) and the knee-flipped (hip 2.2690, knee +1). By angular distance on the hip the first is 0.1 rad from
    the reference, the flipped one 2.17 rad (0.83 hip, 2 knee); by the plain difference the first would be 6.18 rad
    away and lose. ik_nearest returns the first, unwrapped to be continuous with the reference: (0, 3.2, -1) to
    1e-9 rad (measured 4.4e-16)."""
    q = np.array([0.0, 3.2, -1.0])
    sols = K.ik(K.fk(q)).solutions
    assert sorted(np.round(sols[:, 1], 4).tolist()) == [-3.0832, 2.269]  # wrapped: no solution at 3.2 itself
    np.testing.assert_allclose(K.ik_nearest(K.fk(q), np.array([0.0, 3.1, -1.0])), q, rtol=0, atol=1e-9)


def test_jacobian_is_the_derivative_of_fk() -> None:
    """Central differences, h = 1e-6 rad: truncation error ~ h^2 * 0.5 m = 5e-13, tolerance 1e-8."""
    h = 1e-6
    for q in random_q(200):
        J = K.jacobian(q)
        fd = np.stack([(K.fk(q + h * e) - K.fk(q - h * e)) / (2 * h) for e in np.eye(3)], axis=1)
        np.testing.assert_allclose(J, fd, atol=1e-8)


def test_poc_jacobian_matches_pinocchio_point_velocity() -> None:
    """The true poc is a material point at -R_foot z_W from E; its Jacobian equals
    Pinocchio's frame Jacobian of that point (1e-10; the URDF carries the model's numbers exactly, so
    only round-off is left: FK agrees to 2e-16 m)."""
    m = model.pinocchio_model()
    d = m.createData()
    fid = m.getFrameId(model.FOOT_FRAME)
    R = model.load_params().geometry.R_foot
    for q in random_q(50):
        qp = model.q_to_pin(q)
        pin.computeJointJacobians(m, d, qp)
        pin.updateFramePlacements(m, d)
        J6 = pin.getFrameJacobian(m, d, fid, pin.LOCAL_WORLD_ALIGNED)
        r = np.array([0.0, 0.0, -R])
        J_point = J6[:3] - pin.skew(r) @ J6[3:]
        np.testing.assert_allclose(K.jacobian_poc(q), J_point, atol=1e-10)
        np.testing.assert_allclose(K.jacobian_poc(q, true_poc=False), J6[:3], atol=1e-10)


def test_singularities() -> None:
    assert K.is_singular(np.array([0.3, -1.0, 0.0]))  # straight knee
    # foot on the ab/ad axis: L23 s2 + L3E s23 = 0
    g = model.load_params().geometry
    q3 = -1.0
    q2 = np.arctan2(-g.L_3E * np.sin(q3), g.L_23 + g.L_3E * np.cos(q3))
    assert K.is_singular(np.array([0.0, q2, q3]))
    assert np.linalg.matrix_rank(K.jacobian(np.array([0.0, q2, q3])), tol=1e-9) < 3
    assert not K.is_singular(Q_STAR)


def test_angular_distance_wraps_the_short_way() -> None:
    assert K.angdist(3.0, -3.0) == pytest.approx(2 * np.pi - 6.0)
    assert K.angdist(-3.0, 3.0) == pytest.approx(6.0 - 2 * np.pi)
    assert K.angdist(0.1, 0.3) == pytest.approx(0.2)
    # only the continuous hip wraps; the knee (range 4.46 rad) must not
    err = K.joint_error(np.array([0.0, 3.0, -2.0]), np.array([0.0, -3.0, 2.0]))
    np.testing.assert_allclose(err, [0.0, 2 * np.pi - 6.0, 4.0])


def test_gravity_at_q_star_reproduces_the_calibration_figure() -> None:
    """The report's G(q*), to 1e-6 N m (the leg's mass properties are calibrated to it)."""
    G_ref = np.array([1.0426, 0.1631, -0.2984])
    np.testing.assert_allclose(K.gravity(Q_STAR), G_ref, atol=1e-6)


def test_gravity_equals_minus_derivative_of_potential_energy() -> None:
    """G = dV/dq with V = g sum m_i z_com_i (central differences, 1e-7 N m)."""
    m = model.pinocchio_model()
    d = m.createData()
    h = 1e-6
    for q in random_q(20):

        def V(qq: np.ndarray) -> float:
            return float(pin.computePotentialEnergy(m, d, model.q_to_pin(qq)))

        fd = np.array([(V(q + h * e) - V(q - h * e)) / (2 * h) for e in np.eye(3)])
        np.testing.assert_allclose(K.gravity(q), fd, atol=1e-7)


def _bits(x: np.ndarray | Sequence[float]) -> np.ndarray:
    return np.asarray(x, dtype=float).view(np.int64)


def test_scalar_jacobian_equals_the_vectorised_one_bit_for_bit() -> None:
    """The controllers' float path must not change a single bit of the torque (sign of zero included)."""
    g = model.load_params().geometry
    for q in random_q(2000):
        q1, q2, q3 = q.tolist()
        np.testing.assert_array_equal(
            _bits(K.jacobian_scalar(q1, q2, q3, g.L_12, g.L_23, g.L_3E)), _bits(K.jacobian(q).ravel())
        )


def test_scalar_angdist_equals_angdist_bit_for_bit() -> None:
    """Python's float % and np.mod round the same way, including near the +-pi seam and at exact multiples."""
    rng = np.random.default_rng(RNG_SEED)
    a = np.concatenate([rng.uniform(-20, 20, 5000), [np.pi, -np.pi, 3 * np.pi, 0.0, -0.0, 1e-300]])
    b = np.concatenate([rng.uniform(-20, 20, 5000), [0.0, 0.0, 0.0, 2 * np.pi, -2 * np.pi, 0.0]])
    scalar = [K.angdist_scalar(x, y) for x, y in zip(a.tolist(), b.tolist(), strict=True)]
    np.testing.assert_array_equal(_bits(scalar), _bits(K.angdist(a, b)))


def test_gravity_on_floats_is_pinocchios_generalized_gravity() -> None:
    """G(q) by the Newton-Euler recursion on floats (the effort controller's, compiled into the tick) against
    pin.computeGeneralizedGravity at 500 configurations over the whole circle: 1e-13 N m (|G| up to ~2 N m)."""
    a = K.gravity_arrays()
    worst = 0.0
    for q in np.random.default_rng(RNG_SEED).uniform(-np.pi, np.pi, size=(500, 3)):
        q1, q2, q3 = q.tolist()
        worst = max(worst, float(np.abs(np.array(K.gravity_scalar(q1, q2, q3, a)) - K.gravity(q)).max()))
    assert worst < 1e-13


def test_chain_points_are_pinocchio_joint_origins_and_end_at_fk() -> None:
    """The drawn leg (report's 3D view): ab/ad, hip and knee points at Pinocchio's joint origins of the
    generated URDF to 1e-9 m (the FK test's bound) at 200 random poses; the last point is fk(q) exactly."""
    m = model.pinocchio_model()
    d = m.createData()
    ids = [m.getJointId(n) for n in model.JOINT_NAMES]
    qs = random_q(200)
    pts = K.chain(qs)
    assert pts.shape == (200, 5, 3)
    np.testing.assert_array_equal(pts[:, -1], K.fk(qs))
    for q, p in zip(qs, pts, strict=True):
        pin.forwardKinematics(m, d, model.q_to_pin(q))
        for k, jid in enumerate(ids):
            np.testing.assert_allclose(d.oMi[jid].translation, p[k + 1], atol=1e-9)


def test_jacobian_at_a_lifted_point_is_the_shank_point_at_that_depth() -> None:
    """The material point d = R_foot - lift y below E (y = R_foot - z_E the penetration): J = J_E + (d / R_foot)
    (J_poc - J_E), since omega x (-d z_W) is linear in d; lift 0 is J_poc exactly, poc 'centre' is J_E, and a foot
    out of the ground (y < 0) has its point at the lowest point whatever the lift. Round-off only (1e-15)."""
    R = model.load_params().geometry.R_foot
    q_ground = K.ik(np.array([0.1667, 0.0, R - 0.005])).solutions  # E 5 mm into the ground
    q = np.vstack([q_ground, [[0.2, -0.7, 1.1]]])  # and one in the air
    y = R - K.fk(q)[:, 2]
    assert np.allclose(y[:-1], 0.005) and y[-1] < 0
    J_E, J_poc = K.jacobian(q), K.jacobian_poc(q)
    for lift in (0.0, 0.5, 1.0):
        d = R - lift * np.maximum(y, 0.0)
        want = J_E + (d / R)[:, None, None] * (J_poc - J_E)
        np.testing.assert_allclose(K.jacobian_at(q, "true", lift), want, rtol=0, atol=1e-15)
        np.testing.assert_allclose(K.contact_depth(q, lift), d, rtol=0, atol=1e-17)
    assert np.array_equal(K.jacobian_at(q, "true"), J_poc)
    assert np.array_equal(K.jacobian_at(q, "centre", 0.5), J_E)
    half = K.jacobian_at(q, "true", 0.5)
    assert np.abs(half[:-1] - J_poc[:-1]).max() > 1e-4  # [m/rad]: 2.5 mm of lever makes a difference
    np.testing.assert_array_equal(half[-1], J_poc[-1])  # out of the ground: the lowest point


def test_nearest_does_not_wrap_the_knee() -> None:
    """The knee is revolute (limits +-2.229 rad, a span of 4.46 rad > pi): its distance from the reference is the
    plain difference, never the short way round. The only solution (0, 0.5, 2.1) seen from (0, 0.5, -2.1) comes
    back as it is (knee 2.1, inside the limits), not as the knee 4.2 - 2 pi rad from the reference (-4.18 rad,
    beyond its lower limit); and of (0, 0.5, 2.1), 4.2 rad of knee away, and (0, 2.5, -1), 2 rad of hip and 1.1
    of knee away (2.28 rad), the second is nearer (by the wrapped knee the first would be, 2.08 rad). Exact: the
    answer is the reference plus float differences of numbers of the same magnitude (to 1e-15 rad). A mutation
    audit found that wrapping the knee here passed every test."""
    lo, hi = model.load_params().lower[2], model.load_params().upper[2]
    assert hi - lo > np.pi and not model.load_params().continuous[2]
    q_ref = np.array([0.0, 0.5, -2.1])
    one = K.nearest(np.array([[0.0, 0.5, 2.1]]), q_ref)
    np.testing.assert_allclose(one, [0.0, 0.5, 2.1], rtol=0, atol=1e-15)
    assert lo <= one[2] <= hi
    two = K.nearest(np.array([[0.0, 0.5, 2.1], [0.0, 2.5, -1.0]]), q_ref)
    np.testing.assert_allclose(two, [0.0, 2.5, -1.0], rtol=0, atol=1e-15)
