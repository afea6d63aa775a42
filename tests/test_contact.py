"""The analytic contact law: the float path (``wrench``) against the law's parts and the vectorised kinematics."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pinocchio as pin
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
    implicit_velocity_step,
    law_step_warnings,
    tangential_mass,
)
from legbench.model import load_params, pinocchio_model

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


# --------------------------------------------------------------------------- #
# The friction's slope K and the linearly implicit step (docs/pinocchio.md)


def _tangential_branches(law: ReferenceContact, x: np.ndarray) -> tuple[str, float, float] | None:
    """("stick" | "ramp" | "slide", v [m/s], fz [N]) of a state in contact whose poc rises (ydot < 0: Fn = Kp y,
    independent of qd) and whose slip speed is 1e-6 m/s or more from the branch ends; None otherwise."""
    p = law.p
    out = law.wrench(*x.tolist())
    J = K.jacobian_poc(x[:3], true_poc=p.poc == "true")
    vx, vy, vz = J @ x[3:]
    v = float(np.hypot(vx, vy))
    if out[5] <= 0.0 or vz < 1e-6 or min(abs(v - p.v_th), abs(v - 1.5 * p.v_th)) < 1e-6:
        return None
    return ("stick" if v < p.v_th else "ramp" if v < 1.5 * p.v_th else "slide"), v, out[5]


def _sym(k: tuple[float, ...]) -> np.ndarray:
    """(K11, K12, K13, K22, K23, K33) as the symmetric 3x3 matrix."""
    k11, k12, k13, k22, k23, k33 = k
    return np.array([[k11, k12, k13], [k12, k22, k23], [k13, k23, k33]])


@pytest.mark.parametrize("poc", ["true", "centre"])
def test_friction_slope_is_minus_the_law_torques_derivative_in_qd(poc: str) -> None:
    """K = -d(J_t^T F_t)/d(qd) at fixed Fn, against a central difference (1e-7 rad/s) of the law's torque
    (``wrench``, itself checked against ground_force through the kinematics above): on the viscous branch
    (v < v_th, F_t linear in v) and the sliding one (v >= 1.5 v_th, mu_k) to 1e-6 of |K|'s largest entry. On the
    falling ramp K leaves out the law's negative slope along the slip, by design: K - K_fd is exactly
    Fn (mu_s - mu_k) / (v_th / 2) w w^T with w = J_t^T v/|v| (1e-6). K is symmetric positive semi-definite
    (eigenvalues >= -1e-12 |K|). v_th = 0.01, 0.15 and 1 m/s put the samples' slip speeds (up to about 0.3 m/s)
    on every branch. A K scaled by 3, or with its off-diagonal sign flipped, fails by orders of magnitude."""
    eps = 1e-7
    seen = {"stick": 0, "ramp": 0, "slide": 0}
    for v_th in (0.01, 0.15, 1.0):
        p = ContactParams(poc=poc, v_th=v_th)
        law = ReferenceContact.from_leg(p)
        for x in _states(3000):
            branch = _tangential_branches(law, x)
            if branch is None:
                continue
            which, v, fz = branch
            seen[which] += 1
            Kmat = _sym(law.wrench_slope(*x.tolist())[6:])
            Kfd = np.empty((3, 3))
            for j in range(3):
                xp, xm = x.copy(), x.copy()
                xp[3 + j] += eps
                xm[3 + j] -= eps
                dtau = np.array(law.wrench(*xp.tolist())[:3]) - np.array(law.wrench(*xm.tolist())[:3])
                Kfd[:, j] = -dtau / (2 * eps)
            scale = float(np.abs(Kmat).max())
            if which == "ramp":
                J = K.jacobian_poc(x[:3], true_poc=poc == "true")
                w = J[:2].T @ (J[:2] @ x[3:]) / v
                Kfd = Kfd + fz * (p.mu_s - p.mu_k) / (0.5 * p.v_th) * np.outer(w, w)
            np.testing.assert_allclose(Kmat, Kfd, rtol=0, atol=1e-6 * scale, err_msg=f"{which} at {x}, v_th {v_th}")
            assert np.linalg.eigvalsh(Kmat).min() >= -1e-12 * scale
    assert min(seen.values()) >= 20, seen


def test_implicit_velocity_step_solves_the_linearly_implicit_system() -> None:
    """dqd = (I + h M^-1 K)^-1 h a, Cramer's rule on floats against numpy's LU solve, to 1e-12 relative, with the
    leg's own M^-1 and the law's K at states in contact (h = 50 us and 1 ms: the default sub-step and a stiff one)."""
    law = ReferenceContact.from_leg(ContactParams())
    model = pinocchio_model()
    data = model.createData()
    rng = np.random.default_rng(RNG_SEED)
    checked = 0
    for x in _states(600):
        k = law.wrench_slope(*x.tolist())[6:]
        if k[0] == 0.0:
            continue
        q1, q2, q3 = x[:3]
        Minv = pin.computeMinverse(model, data, np.array([q1, np.cos(q2), np.sin(q2), q3]))
        Minv = np.triu(Minv) + np.triu(Minv, 1).T
        a = rng.normal(0.0, 50.0, 3)
        for h in (5e-5, 1e-3):
            m = (Minv[0, 0], Minv[0, 1], Minv[0, 2], Minv[1, 1], Minv[1, 2], Minv[2, 2])
            got = implicit_velocity_step(h, m, k, *a.tolist())
            want = np.linalg.solve(np.eye(3) + h * Minv @ _sym(k), h * a)
            np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12 * float(np.abs(want).max()))
        checked += 1
    assert checked >= 100


def test_implicit_generalized_makes_an_explicit_step_the_implicit_one() -> None:
    """The torque J^T F - K dqd that implicit_generalized returns makes an engine's explicit velocity step
    h M^-1 (u + tau - nle) equal the linearly implicit step dqd = (I + h M^-1 K)^-1 h a, a the explicit
    acceleration with J^T F: to 1e-10 relative, at states in contact; out of contact it is the law's torque."""
    g = load_params().gravity
    law = ReferenceContact.from_leg(ContactParams(), implicit_friction_gravity=g)
    model = pinocchio_model(gravity=g)
    data = model.createData()
    u = np.array([0.3, -1.2, 2.0])
    h = 5e-5
    checked = 0
    for x in _states(400):
        q, qd = x[:3], x[3:]
        qp = np.array([q[0], np.cos(q[1]), np.sin(q[1]), q[2]])
        r = law.wrench_slope(*x.tolist())
        q1, q2, q3, qd1, qd2, qd3 = x.tolist()
        tau = law.implicit_generalized(q1, q2, q3, qd1, qd2, qd3, u[0], u[1], u[2], h).copy()
        if r[5] <= 0.0:
            np.testing.assert_array_equal(tau, 0.0)
            continue
        a = pin.aba(model, data, qp, qd, u + np.array(r[:3]))
        Minv = pin.computeMinverse(model, data, qp)
        Minv = np.triu(Minv) + np.triu(Minv, 1).T
        want = np.linalg.solve(np.eye(3) + h * Minv @ _sym(r[6:]), h * a)
        got = h * pin.aba(model, data, qp, qd, u + tau)
        np.testing.assert_allclose(got, want, rtol=1e-10, atol=1e-12)
        checked += 1
    assert checked >= 50


def test_friction_chatter_is_read_from_reversals_reversed_again_within_two_ticks() -> None:
    """A friction force near its bound that reverses and reverses back within two ticks, over and over, is chatter
    (one warning, naming the count and the first tick); a slide rubbed back and forth reverses once per half
    period (at 10 Hz and even at 100 Hz, every 5 ticks: a reviewer's synthetic log from the law warned at 7 Hz
    under the first rule, reversals alone), and a force turning slowly, reversing once (the combined task's swing)
    or too small to be near its bound (|F_t| < mu_k Fn / 2) is not; nor is a frictionless contact. The share rule
    (1 % of the ticks in contact): a burst of 13 flips in a 3001-tick contact (13 reversals reversed back, 0.4 %)
    is not said, one of 41 (41, 1.4 %) is."""
    import dataclasses

    from legbench.contact import ContactParams, friction_chatter

    p = ContactParams()
    n = 1000
    t = np.arange(n) * 1e-3
    fn = np.full(n, 50.0)
    sign = np.where(np.arange(n) % 2 == 0, 1.0, -1.0)
    flipping = np.column_stack([0.7 * fn * sign, np.zeros(n), fn])
    (w,) = friction_chatter("b", t, flipping, p)
    assert "reverses back within two control ticks at 998 of 1000 ticks in contact, from t = 0.001 s" in w
    for hz in (10.0, 100.0):  # a real back-and-forth slide at the friction bound
        rubbed = np.column_stack([-0.6 * fn * np.sign(np.sin(2 * np.pi * hz * t + 0.1)), np.zeros(n), fn])
        assert friction_chatter("b", t, rubbed, p) == [], hz
    angle = np.linspace(0.0, np.pi, n)  # turns by 180 deg over the run: 0.18 deg a tick
    turning = np.column_stack([0.7 * fn * np.cos(angle), 0.7 * fn * np.sin(angle), fn])
    assert friction_chatter("b", t, turning, p) == []
    once = np.column_stack([0.7 * fn * np.where(t < 0.5, 1.0, -1.0), np.zeros(n), fn])
    assert friction_chatter("b", t, once, p) == []
    small = np.column_stack([0.2 * p.mu_k * fn * sign, np.zeros(n), fn])
    assert friction_chatter("b", t, small, p) == []
    assert friction_chatter("b", t, flipping, dataclasses.replace(p, mu_s=0.0, mu_k=0.0)) == []
    m = 3001
    tm, fm = np.arange(m) * 1e-3, np.full(m, 50.0)
    for burst, said in ((13, False), (41, True)):  # ticks flipped in a row; the share threshold is 30 ticks
        s = np.ones(m)
        s[1000 : 1000 + burst] = np.where(np.arange(burst) % 2 == 0, -1.0, 1.0)
        f = np.column_stack([0.7 * fm * s, np.zeros(m), fm])
        assert bool(friction_chatter("b", tm, f, p)) is said, burst


def test_friction_chatter_boundaries_two_ticks_120_degrees_and_both_ticks_engaged() -> None:
    """The rule's three boundaries, each one side and the other (a mutation audit found them untried): a reversal
    undone two ticks later (+, +, -, -, ...) counts, three ticks later does not; a turn of 130 deg tick to tick
    counts, of 100 deg does not; a reversal between a tick near the bound and one at a tenth of mu_k Fn does not."""
    from legbench.contact import ContactParams, friction_chatter

    p = ContactParams()
    n = 1200
    t = np.arange(n) * 1e-3
    fn = np.full(n, 50.0)
    k = np.arange(n)

    def along(sign: np.ndarray, size: np.ndarray | float = 0.7) -> np.ndarray:
        return np.column_stack([size * fn * sign, np.zeros(n), fn])

    assert friction_chatter("b", t, along(np.where(k // 2 % 2 == 0, 1.0, -1.0)), p)  # period 4: back in 2
    assert friction_chatter("b", t, along(np.where(k // 3 % 2 == 0, 1.0, -1.0)), p) == []  # period 6: back in 3
    for deg, said in ((130.0, True), (100.0, False)):
        a = np.radians(deg) * k
        turning = np.column_stack([0.7 * fn * np.cos(a), 0.7 * fn * np.sin(a), fn])
        assert bool(friction_chatter("b", t, turning, p)) is said, deg
    alternate = np.where(k % 2 == 0, 1.0, -1.0)
    size = np.where(k % 2 == 0, 0.7, 0.1 * p.mu_k)  # every other tick far from the bound
    assert friction_chatter("b", t, along(alternate, size), p) == []
