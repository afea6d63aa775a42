"""The analytic contact law: the float path (``wrench``) against the law's parts and the vectorised kinematics."""

from __future__ import annotations

import numpy as np
import pytest

from legbench import kinematics as K
from legbench.contact import ContactParams, ReferenceContact, friction_coefficient, ground_force
from legbench.model import load_params

RNG_SEED = 20261121


def _states(n: int) -> np.ndarray:
    """Joint states (q [rad], qd [rad/s]) around the standing pose q*, about a third of them in contact."""
    rng = np.random.default_rng(RNG_SEED)
    centre = np.array([0.0, -1.19, -1.26, 0.0, 0.0, 0.0])
    spread = np.array([0.3, 0.4, 0.4, 0.5, 0.5, 0.5])
    return centre + spread * rng.uniform(-1.0, 1.0, size=(n, 6))


@pytest.mark.parametrize("poc", ["true", "centre"])
@pytest.mark.parametrize("v_th", [0.01, 1.0])  # 1 m/s puts most samples on the stick-slip ramp
def test_wrench_is_the_law_through_the_poc_jacobian(poc: str, v_th: float) -> None:
    """F = ground_force(penetration, rate, poc velocity) and tau_c = J_poc^T F, to 1e-12 relative.

    Only relative rounding separates the two (numpy matrix products against
    scalar sums of three terms).
    """
    p = ContactParams(poc=poc, v_th=v_th)
    law = ReferenceContact.from_leg(p)
    R = load_params().geometry.R_foot
    touching = 0
    for x in _states(3000):
        q, qd = x[:3], x[3:]
        out = law.wrench(*x.tolist())
        J = K.jacobian_poc(q, true_poc=poc == "true")
        v = J @ qd
        F = np.array(ground_force(R - K.fk(q)[2], -v[2], v[0], v[1], p))
        np.testing.assert_allclose(out[3:], F, rtol=1e-12, atol=1e-9)
        np.testing.assert_allclose(out[:3], J.T @ F, rtol=1e-12, atol=1e-9)
        touching += F[2] > 0
    assert 500 < touching < 2500


def test_generalized_returns_the_wrench_in_arrays_bit_for_bit() -> None:
    law = ReferenceContact.from_leg(ContactParams())
    for x in _states(500):
        out = law.wrench(*x.tolist())
        tau = law.generalized(*x.tolist())
        np.testing.assert_array_equal(tau, out[:3])
        np.testing.assert_array_equal(law.force, out[3:])


def test_out_of_contact_everything_is_zero() -> None:
    law = ReferenceContact.from_leg(ContactParams())
    assert law.wrench(0.0, 0.0, 0.0, 1.0, 1.0, 1.0) == (0.0,) * 6  # horizontal leg, far above the ground
    np.testing.assert_array_equal(law.generalized(0.0, 0.0, 0.0, 1.0, 1.0, 1.0), np.zeros(3))
    np.testing.assert_array_equal(law.force, np.zeros(3))


def test_friction_coefficient_is_the_spec_stick_slip_curve() -> None:
    """mu(v) with the defaults (mu_s 0.7, mu_k 0.6, v_th 1 mm/s), by hand from the spec's curve: linear from 0 to
    mu_s at v_th, falling linearly to mu_k at 1.5 v_th, then mu_k; continuous at both corners. 1e-12: a few
    float operations."""
    p = ContactParams()
    by_hand = {0.0: 0.0, 0.5e-3: 0.35, 1e-3: 0.7, 1.25e-3: 0.65, 1.5e-3: 0.6, 1e-2: 0.6, 1.0: 0.6}
    for v, mu in by_hand.items():
        assert friction_coefficient(v, p) == pytest.approx(mu, rel=1e-12, abs=1e-15), v
    for corner in (p.v_th, 1.5 * p.v_th):
        below, above = friction_coefficient(corner * (1 - 1e-12), p), friction_coefficient(corner * (1 + 1e-12), p)
        assert below == pytest.approx(above, abs=1e-9)


def test_ground_force_spring_damper_and_friction_against_the_motion() -> None:
    """At 1 mm penetration: Fn = Kp y + Kd ydot while pressing in (10 + 1 = 11 N), Kp y while releasing (no pull,
    10 N), 0 out of contact; friction mu(v) Fn exactly opposite the poc's horizontal velocity, here on the
    falling ramp (v = 1.25 mm/s: mu = 0.65)."""
    p = ContactParams()
    assert ground_force(1e-3, 0.01, 0.0, 0.0, p) == pytest.approx((0.0, 0.0, 11.0), rel=1e-12)
    assert ground_force(1e-3, -0.01, 0.0, 0.0, p) == pytest.approx((0.0, 0.0, 10.0), rel=1e-12)
    assert ground_force(-1e-3, 0.01, 1.0, 0.0, p) == (0.0, 0.0, 0.0)
    vx, vy = 0.6 * 1.25e-3, 0.8 * 1.25e-3
    fx, fy, fz = ground_force(1e-3, 0.0, vx, vy, p)
    assert fz == pytest.approx(10.0, rel=1e-12)
    assert (fx, fy) == pytest.approx((-0.65 * 10.0 * 0.6, -0.65 * 10.0 * 0.8), rel=1e-12)
