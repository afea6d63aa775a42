"""The analytic contact law: the float path (``wrench``) against the law's parts and the vectorised kinematics."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from legbench import kinematics as K
from legbench.contact import (
    EULER_FRICTION_STABILITY,
    RK4_FRICTION_STABILITY,
    ContactParams,
    ReferenceContact,
    friction_coefficient,
    friction_step_bound,
    ground_force,
    law_step_warnings,
    tangential_mass,
)
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


Q_SS = (-0.00270, -1.20408, -1.22272)  # the effort task's settled pose [rad] (docs/contact_law.md)


def _decay_after(step: Callable[[float], float], n: int = 200) -> float:
    """|v_n / v_0| after n steps of a one-step map v -> step(v) from v = 1."""
    v = 1.0
    for _ in range(n):
        v = step(v)
    return abs(v)


def test_friction_step_bound_is_each_integrators_on_the_viscous_ramp() -> None:
    """Below v_th the law is a viscous friction c = mu_s Fn / v_th on the apparent mass m: m v' = -c v. Semi-implicit
    Euler's bound (the default, today's m v_th / (mu_s Fn)) is where its step factor 1 - h c / m turns negative (the
    friction flips sign every step: chatter); RK4's (2.785 m v_th / (mu_s Fn)) where its step factor
    1 - x + x^2/2 - x^3/6 + x^4/24 (x = h c / m, positive for every real x) passes 1: 200 RK4 steps 1 % below
    it shrink v below 0.2, 1 % above grow it past 5 (the step factor is 0.959 and 1.043 there). Fn = 59.1 N
    (the effort task's peak) at q_ss: 5.14 us and 14.3 us."""
    p = ContactParams()
    fn = 59.1
    euler = friction_step_bound(fn, Q_SS, p)
    rk4 = friction_step_bound(fn, Q_SS, p, RK4_FRICTION_STABILITY)
    assert euler == pytest.approx(5.14e-6, rel=2e-3)
    assert rk4 == pytest.approx(2.785293563405282 * euler, rel=1e-12)
    m, c = tangential_mass(Q_SS), p.mu_s * fn / p.v_th
    assert euler == pytest.approx(m / c, rel=1e-12)
    assert 1.0 - 0.99 * euler * c / m > 0.0 > 1.0 - 1.01 * euler * c / m  # Euler: the sign flip

    def rk4_step(h: float) -> Callable[[float], float]:
        def step(v: float) -> float:
            k1 = -c / m * v
            k2 = -c / m * (v + 0.5 * h * k1)
            k3 = -c / m * (v + 0.5 * h * k2)
            k4 = -c / m * (v + h * k3)
            return v + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)

        return step

    assert _decay_after(rk4_step(0.99 * rk4)) < 0.2
    assert _decay_after(rk4_step(1.01 * rk4)) > 5.0


def test_law_step_warnings_default_is_eulers_and_rk4s_factor_widens_it() -> None:
    """Between the two bounds (2x Euler's) the default (Euler: MuJoCo, PyBullet, Pinocchio's explicit friction)
    warns with today's sentence and RK4's factor does not; above RK4's (3x Euler's) RK4 warns naming its factor."""
    p = ContactParams()
    fn = 59.1
    euler = friction_step_bound(fn, Q_SS, p)
    (note,) = law_step_warnings("x", 2.0 * euler, fn, list(Q_SS), p)
    assert "h > m v_th / (mu_s Fn) = 0.213 kg x 0.001 m/s / (0.7 x 59.1 N) = 5.14e-06 s" in note, note
    assert law_step_warnings("x", 2.0 * euler, fn, list(Q_SS), p, EULER_FRICTION_STABILITY) == [note]
    assert law_step_warnings("x", 2.0 * euler, fn, list(Q_SS), p, RK4_FRICTION_STABILITY) == []
    (note,) = law_step_warnings("x", 3.0 * euler, fn, list(Q_SS), p, RK4_FRICTION_STABILITY)
    assert "h > 2.785 m v_th / (mu_s Fn) = 2.785 x 0.213 kg x 0.001 m/s / (0.7 x 59.1 N) = 1.43e-05 s" in note, note
    assert law_step_warnings("x", 0.99 * euler, fn, list(Q_SS), p) == []
