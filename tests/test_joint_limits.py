"""The joint-limit spring-damper (:class:`legbench.backends.joint_limits.JointLimitLaw`) by hand on each side of
each limit, and its step bound (:func:`legbench.backends.joint_limits.step_bound`) against the linear dynamics it
bounds, integrated step by step."""

from __future__ import annotations

import math

import pytest

from legbench.backends.joint_limits import DAMPING, STIFFNESS, JointLimitLaw, step_bound
from legbench.model import load_params

#: The knee's effective inertia 1/(M^-1)_33 with the knee at its limit [kg m^2] (0.0064-0.0075 over the hip angle).
I_KNEE = 0.0065
N_STEPS = 200


def _euler_amplitude(h: float, c: float, w2: float) -> float:
    """|(x, h v)| after N_STEPS semi-implicit Euler steps of x'' = -c x' - w2 x from x = 1 rad, v = 0."""
    x, v = 1.0, 0.0
    for _ in range(N_STEPS):
        v = v + h * (-c * v - w2 * x)
        x = x + h * v
    return math.hypot(x, h * v)


def _rk4_amplitude(h: float, c: float, w2: float) -> float:
    """The same for classical RK4's four stages."""

    def f(x: float, v: float) -> tuple[float, float]:
        return v, -c * v - w2 * x

    x, v = 1.0, 0.0
    for _ in range(N_STEPS):
        k1 = f(x, v)
        k2 = f(x + 0.5 * h * k1[0], v + 0.5 * h * k1[1])
        k3 = f(x + 0.5 * h * k2[0], v + 0.5 * h * k2[1])
        k4 = f(x + h * k3[0], v + h * k3[1])
        x += h / 6.0 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
        v += h / 6.0 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
    return math.hypot(x, h * v)


@pytest.mark.parametrize("integrator", ["euler", "rk4"])
@pytest.mark.parametrize("inertia", [0.002, I_KNEE, 0.05])  # over-damped, over-damped, under-damped
def test_step_bound_is_where_the_damped_limit_spring_turns_unstable(integrator: str, inertia: float) -> None:
    """k = 1e4 N m/rad, b = 20 N m s/rad on I: 200 steps of 3 % below the bound shrink the excursion below
    1e-2 (spectral radius 0.88-0.92 at the knee), 3 % above grow it past 1e2 (1.08-1.13)."""
    c, w2 = DAMPING / inertia, STIFFNESS / inertia
    h = step_bound(STIFFNESS, DAMPING, inertia, integrator)
    amplitude = _euler_amplitude if integrator == "euler" else _rk4_amplitude
    assert amplitude(0.97 * h, c, w2) < 1e-2
    assert amplitude(1.03 * h, c, w2) > 1e2


def test_step_bound_numbers_and_limits() -> None:
    """The knee's bounds (Euler 4 / (c + sqrt(c^2 + 4 w2)) = 570 us at I = 0.00651 kg m^2, where the backend
    diverges at 1 ms; RK4 1.14 ms), and the closed forms at the ends: a spring alone (Euler 2/w, RK4 2 sqrt 2 / w,
    the imaginary axis), a damper alone (Euler 2/c, RK4 2.7853/c, the real axis)."""
    assert step_bound(STIFFNESS, DAMPING, 0.0065110, "euler") == pytest.approx(5.699e-4, rel=1e-3)
    assert step_bound(STIFFNESS, DAMPING, 0.0065110, "rk4") == pytest.approx(1.1401e-3, rel=1e-3)
    w, c = math.sqrt(STIFFNESS / I_KNEE), DAMPING / I_KNEE
    assert step_bound(STIFFNESS, 0.0, I_KNEE, "euler") == pytest.approx(2.0 / w, rel=1e-12)
    assert step_bound(STIFFNESS, 0.0, I_KNEE, "rk4") == pytest.approx(2.0 * math.sqrt(2.0) / w, rel=1e-9)
    assert step_bound(0.0, DAMPING, I_KNEE, "euler") == pytest.approx(2.0 / c, rel=1e-12)
    assert step_bound(0.0, DAMPING, I_KNEE, "rk4") == pytest.approx(2.785293563405282 / c, rel=1e-9)
    assert step_bound(0.0, 0.0, I_KNEE, "euler") == math.inf
    with pytest.raises(ValueError, match="rk45"):
        step_bound(STIFFNESS, DAMPING, I_KNEE, "rk45")


@pytest.mark.parametrize("integrator", ["euler", "rk4"])
def test_step_bound_is_inf_for_a_joint_without_inertia(integrator: str) -> None:
    """I = 0 kg m^2 (no recorded inertia) bounds nothing: inf, with a spring and damper, either alone (not a
    division by I = 0: c = b / I, w2 = k / I)."""
    assert step_bound(STIFFNESS, DAMPING, 0.0, integrator) == math.inf
    assert step_bound(STIFFNESS, 0.0, 0.0, integrator) == math.inf
    assert step_bound(0.0, DAMPING, 0.0, integrator) == math.inf


def test_rk4_bound_of_a_lightly_damped_limit_is_the_undamped_phases() -> None:
    """k = 1e4 N m/rad, b = 1 N m s/rad, I = 0.05 kg m^2 (c = 20 1/s, w = sqrt(k/I) = 447 rad/s, damping ratio
    0.022): while the joint moves back in, the damper is off and the eigenvalues +-i w sit on the imaginary
    axis, where RK4 is stable up to h w = 2 sqrt 2: 6.3246e-3 s. The damped phase's eigenvalues -10 +- 447i
    lie left of it, where RK4's region reaches farther (6.419e-3 s), so the undamped phase sets the bound:
    2 sqrt(2) / w to rel 1e-9 (measured 1.6e-14); 200 undamped RK4 steps 3 % below it shrink an excursion
    below 1e-2, 3 % above grow it past 1e2."""
    inertia, damping = 0.05, 1.0
    w = math.sqrt(STIFFNESS / inertia)
    h = step_bound(STIFFNESS, damping, inertia, "rk4")
    assert h == pytest.approx(2.0 * math.sqrt(2.0) / w, rel=1e-9)
    assert _rk4_amplitude(0.97 * h, 0.0, w * w) < 1e-2
    assert _rk4_amplitude(1.03 * h, 0.0, w * w) > 1e2


@pytest.mark.parametrize(
    ("joint", "side", "qd", "want"),
    [
        # 0.01 rad past the limit: the spring's k 0.01 rad = 100 N m back in; moving out at 0.5 rad/s adds the
        # damper's b 0.5 rad/s = 10 N m; moving back in, the damper is off
        (0, "upper", 0.5, -110.0),
        (0, "upper", -0.5, -100.0),
        (0, "upper", 0.0, -100.0),
        (0, "lower", -0.5, 110.0),
        (0, "lower", 0.5, 100.0),
        (0, "lower", 0.0, 100.0),
        (2, "upper", 0.5, -110.0),
        (2, "upper", -0.5, -100.0),
        (2, "upper", 0.0, -100.0),
        (2, "lower", -0.5, 110.0),
        (2, "lower", 0.5, 100.0),
        (2, "lower", 0.0, 100.0),
    ],
)
def test_limit_torque_is_a_one_sided_spring_damper(joint: int, side: str, qd: float, want: float) -> None:
    """0.01 rad past the ab/ad's or the knee's limit (+-pi/2, +-2.229 rad), k = 1e4 N m/rad, b = 20 N m s/rad:
    tau = -k (q - q_lim) - b qd while moving further out, -k (q - q_lim) while at rest or moving back in, on that
    joint only (the others 0 exactly); 1e-9 N m (q - q_lim is 0.01 rad to a few ulp of 2.229 rad: 1e-12 N m)."""
    leg = load_params()
    law = JointLimitLaw(leg.lower.tolist(), leg.upper.tolist(), STIFFNESS, DAMPING)
    q = [0.0, 0.3, -1.2]
    v = [0.0, 0.0, 0.0]
    q[joint] = leg.upper[joint] + 0.01 if side == "upper" else leg.lower[joint] - 0.01
    v[joint] = qd
    tau = law(*q, *v)
    assert tau[joint] == pytest.approx(want, rel=0, abs=1e-9)
    assert all(t == 0.0 for i, t in enumerate(tau) if i != joint)


def test_limit_torque_is_zero_inside_the_limits_and_on_the_continuous_hip() -> None:
    """Inside the limits (1e-3 rad in from each side of the ab/ad and the knee, at +-5 rad/s either way) and on the
    continuous hip at any angle (here +-100 rad, moving at 5 rad/s) the limit torque is 0 N m exactly."""
    leg = load_params()
    law = JointLimitLaw(leg.lower.tolist(), leg.upper.tolist(), STIFFNESS, DAMPING)
    assert math.isinf(leg.lower[1]) and math.isinf(leg.upper[1])  # the hip has no position limit
    for q1 in (leg.lower[0] + 1e-3, leg.upper[0] - 1e-3):
        for q3 in (leg.lower[2] + 1e-3, leg.upper[2] - 1e-3):
            for q2 in (-100.0, 0.0, 100.0):
                for v in (-5.0, 5.0):
                    assert law(q1, q2, q3, v, v, -v) == (0.0, 0.0, 0.0)
