"""The run loop's compiled tick against the same function run as Python, and its checks one by one."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from legbench import backends as registry
from legbench import jit, resources, scenario
from legbench import tick as T
from legbench.controllers import PositionController
from legbench.model import load_params
from legbench.run import MAX_JOINT_SPEED, MAX_PENETRATION, simulate
from legbench.scenario import Event, Gains, physics_of

pytestmark = pytest.mark.skipif(not jit.available(), reason="numba is not installed: the tick runs as Python")

TICK: Any = T.tick  # called with star-unpacked readings
TASKS = ("position", "ellipse", "effort", "combined")
LIMITS = (3.0, 4.0, 5.0)


def _log(task: str, tick_fn: object, monkeypatch: pytest.MonkeyPatch) -> np.ndarray:
    sc = scenario.load(resources.scenario(task))
    physics = physics_of(sc, "reference")
    backend = registry.load("pinocchio", physics, sc.backends.get("pinocchio", {}), sc.profile)
    with monkeypatch.context() as m:
        m.setattr(T, "tick", tick_fn)
        tr = simulate(sc, backend, physics)
    assert tr.status == "ok"
    return np.hstack([tr.q, tr.qd, tr.f, tr.tau])


@pytest.mark.parametrize("task", TASKS)
def test_compiled_tick_gives_the_python_ticks_log_bit_for_bit(task: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """Each task's whole log (q, qd, f, tau) with the compiled tick equals the log with the same function run
    as Python, bit for bit: one implementation of every controller law, the same IEEE operations."""
    compiled_tick = T.tick
    assert compiled_tick is not T.control_tick  # numba compiled it
    compiled = _log(task, compiled_tick, monkeypatch)
    python = _log(task, T.control_tick, monkeypatch)
    np.testing.assert_array_equal(compiled.view(np.int64), python.view(np.int64))


def _arrays() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    g = load_params().geometry
    c = T.constants(LIMITS, g, g.R_foot - MAX_PENETRATION, MAX_JOINT_SPEED)
    ctrl = PositionController(Event(0.0, "position", joint=(0.0, -1.0, -1.2)), Gains(Kp=(1e3,) * 3), 1e-3)
    ctrl.start(0.0, np.zeros(3), np.zeros(3))
    return ctrl.params, ctrl.state, c, np.full((3, 12), np.nan), np.full(3, np.nan)


HOLD = (0.0, -0.5, -0.5)  # foot centre 9 cm above the ground


@pytest.mark.parametrize(
    ("state", "code"),
    [
        ((math.nan, -0.5, -0.5, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0), T.NOT_FINITE),
        ((*HOLD, 0.0, 0.0, 0.0, 0.0, 0.0, math.inf), T.NOT_FINITE),
        ((*HOLD, 0.0, -1.001 * MAX_JOINT_SPEED, 0.0, 0.0, 0.0, 0.0), T.TOO_FAST),
        # each joint's speed, either sign, and each force component (a mutation audit: only qd2 and fz were tried)
        ((*HOLD, -1.001 * MAX_JOINT_SPEED, 0.0, 0.0, 0.0, 0.0, 0.0), T.TOO_FAST),
        ((*HOLD, 0.0, 0.0, 1.001 * MAX_JOINT_SPEED, 0.0, 0.0, 0.0), T.TOO_FAST),
        ((*HOLD, 0.0, 0.0, 0.0, math.nan, 0.0, 0.0), T.NOT_FINITE),
        ((*HOLD, 0.0, 0.0, 0.0, 0.0, -math.inf, 0.0), T.NOT_FINITE),
        ((0.0, -math.pi / 2, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0), T.TOO_DEEP),  # leg straight down: z_W = -7.6 cm
    ],
)
def test_a_diverged_state_returns_its_code_and_writes_nothing(state: tuple[float, ...], code: int) -> None:
    p, s, c, log, u = _arrays()
    assert TICK(1, *state, p, s, c, log, u) == code
    assert np.isnan(log).all() and np.isnan(u).all()
    assert not s.any()  # the controller did not run: its integral is untouched


def test_a_good_state_logs_the_reading_and_the_saturated_law_torque() -> None:
    """Row k = (q, qd, f, clip(u, +-limit)); the law's torque from the same state through the Python path."""
    p, s, c, log, u = _arrays()
    q = (0.2, -0.9, -1.0)
    state = (*q, 0.1, -0.2, 0.3, 4.0, 5.0, 6.0)
    assert TICK(1, *state, p, s, c, log, u) == T.OK
    ref = PositionController(Event(0.0, "position", joint=(0.0, -1.0, -1.2)), Gains(Kp=(1e3,) * 3), 1e-3)
    ref.start(0.0, np.zeros(3), np.zeros(3))
    law = np.array(ref.torque(1, *state[:6]))
    assert np.abs(law).max() > max(LIMITS)  # so the clip is exercised
    np.testing.assert_array_equal(log[1, :9], state)
    np.testing.assert_array_equal(log[1, 9:], np.clip(law, -np.array(LIMITS), LIMITS))
    np.testing.assert_array_equal(u, log[1, 9:])  # the buffer the backend is stepped with
    assert np.isnan(log[[0, 2]]).all()
    np.testing.assert_array_equal(s, ref.state)  # the same controller state after the tick


def test_a_nan_torque_passes_the_saturation_as_nan() -> None:
    """As np.clip: a NaN torque (a NaN gain) is logged as NaN, not clipped to a limit."""
    p, s, c, log, u = _arrays()
    p[2] = math.nan  # Kp of joint 1
    assert TICK(0, 0.2, -0.9, -1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, p, s, c, log, u) == T.OK
    assert math.isnan(log[0, 9]) and np.isfinite(log[0, 10:]).all()


def test_too_deep_is_the_foot_centre_below_the_bound_at_any_abduction() -> None:
    """The depth check against the forward kinematics on 400 poses drawn around the bound, abduction up to 0.8 rad
    (a mutation audit: the check's cos(q1) could be dropped with q1 = 0 and 0.2 rad the only ones tried)."""
    from legbench import kinematics

    g = load_params().geometry
    bound = g.R_foot - MAX_PENETRATION
    rng = np.random.default_rng(7)
    seen = set()
    for _ in range(400):
        q = np.array([rng.uniform(-0.8, 0.8), rng.uniform(-1.6, -0.6), rng.uniform(-2.2, -0.2)])
        z = float(kinematics.fk(q)[2])
        if abs(z - bound) > 0.03:
            continue
        p, s, c, log, u = _arrays()
        code = TICK(0, *q, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, p, s, c, log, u)
        assert code == (T.TOO_DEEP if z < bound else T.OK), (q, z, bound, code)
        seen.add((z < bound, abs(q[0]) > 0.4))
    assert seen == {(True, True), (True, False), (False, True), (False, False)}, seen  # every case was drawn


def test_each_joints_torque_is_clipped_at_its_own_limit_both_ways() -> None:
    """A law torque beyond every limit, positive then negative, is clipped to (3, 4, 5) and (-3, -4, -5) N m:
    each joint at its own limit (a mutation audit: joint 3's upper clip at joint 2's limit went unseen)."""
    for q in ((-0.4, -1.6, -2.0), (0.4, -0.4, -0.3)):
        p, s, c, log, u = _arrays()
        assert TICK(0, *q, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, p, s, c, log, u) == T.OK
        sign = np.sign(log[0, 9:])
        assert (sign == sign[0]).all() and sign[0] != 0.0, log[0, 9:]
        np.testing.assert_array_equal(log[0, 9:], sign * np.array(LIMITS))
