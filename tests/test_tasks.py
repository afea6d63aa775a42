"""The four tasks through the run loop on every installed backend, compared as the report does.

Simulation error % = max_t |x_b - x_ref| / max_t |x_ref| x 100 (docs/spec.md section 8), with the
Pinocchio backend as the reference. Defaults: semi-implicit Euler at 50 us in the fixed-step backends,
compared with Pinocchio at the same scheme and step; an adaptive backend (lagrange: RK45 per control
period) is compared with Pinocchio's same adaptive method and tolerances (:data:`ADAPTIVE_KEYS`).
"""

from __future__ import annotations

from functools import cache
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from legbench import backends, results, run, scenario
from legbench import kinematics as K
from legbench.backends.base import Physics, contact_point

SCENARIOS = Path(__file__).resolve().parent.parent / "scenarios"
ENGINES = [b for b in backends.available() if b != "pinocchio"]
pytestmark = pytest.mark.skipif(not ENGINES, reason="no engine backend installed")


#: Pinocchio settings of the reference for a backend of each integrator family: the defaults (semi-implicit
#: Euler at 50 us) for the fixed-step engines, so the step error cancels; for an adaptive backend classic
#: An adaptive backend is compared with Pinocchio running the same adaptive method with the same
#: tolerances (the engine's ``integrator``, ``rtol``, ``atol``, ``max_step`` from its info): the same
#: scheme on an independent implementation of the dynamics, as the fixed-step engines are compared with
#: Pinocchio at their own scheme and step.
ADAPTIVE_KEYS = ("integrator", "rtol", "atol", "max_step")


@cache
def _run(
    task: str, name: str, mode: str | None = None, settings: tuple[tuple[str, Any], ...] = ()
) -> results.RunResult:
    """``task`` on backend ``name`` (its defaults, overridden by ``settings``)."""
    sc = scenario.load(SCENARIOS / f"{task}.yaml", {f"backends.{name}.{k}": v for k, v in settings} or None)
    (tr,) = run.run(sc, [name], None, contact_mode=mode, progress=False)
    assert tr.status == "ok", tr.reason
    return tr


@cache
def _reference(task: str, engine: str, mode: str | None = None) -> results.RunResult:
    """The Pinocchio run an engine is compared with, by the engine's declared integrator family: a fixed-step
    semi-implicit Euler engine against Pinocchio's Euler at the engine's own sub-step (same scheme, same step,
    e.g. Drake's 0.1 ms), an adaptive one against Pinocchio's same adaptive method (:data:`ADAPTIVE_KEYS`)."""
    backend = backends.load(engine, run.physics_of(scenario.load(SCENARIOS / f"{task}.yaml"), mode), {})
    try:
        family, dt, info = backend.integrator_family(), Physics().control_dt / backend.sub_steps(), backend.info()
    finally:
        backend.close()
    if family == "euler":
        return _run(task, "pinocchio", mode, (("dt", dt),))
    if family == "adaptive":
        return _run(task, "pinocchio", mode, tuple((k, info[k]) for k in ADAPTIVE_KEYS))
    return _run(task, "pinocchio", mode)


def _sim_error(x: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """Per column, in %."""
    return np.abs(x - ref).max(axis=0) / np.abs(ref).max(axis=0) * 100


#: Free space, simulation error % of q and tau against Pinocchio at the engine's own sub-step. Engines in joint
#: coordinates run the same semi-implicit Euler (or lagrange the same RK45): round-off, measured <= 5e-10 %.
#: ODE's joints are constraints between free bodies, held by its solver: measured 1.0e-3 % (ellipse's tau).
FREE_SPACE_PCT = {"ode": 5e-3}
FREE_SPACE_PCT_DEFAULT = 1e-8


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("task", ["position", "ellipse"])
def test_free_space_tasks_agree_to_round_off(task: str, engine: str) -> None:
    """No contact: rigid-body dynamics are the same physics and the same integrator at the same step, so the
    joint trajectories and torques agree to round-off (:data:`FREE_SPACE_PCT`); the 0.1 % this test allowed
    before let a 2e-6 kg m^2 rotor inertia added to one engine pass."""
    ref, tr = _reference(task, engine), _run(task, engine)
    limit = FREE_SPACE_PCT.get(engine, FREE_SPACE_PCT_DEFAULT)
    assert np.all(_sim_error(tr.q, ref.q) < limit), _sim_error(tr.q, ref.q)
    assert np.all(_sim_error(tr.tau, ref.tau) < limit), _sim_error(tr.tau, ref.tau)


@pytest.mark.parametrize("engine", ENGINES)
def test_validation_run_agrees_within_0p01_percent(engine: str) -> None:
    """The report's validation run (g = 0, u_i = 0.01 sin(6 pi t) N m on every joint from q = 0, 2 s):
    every backend traces Pinocchio's joint motion within 0.01 % (measured 3e-13 % MuJoCo, 2e-9 %
    PyBullet, 0.0026 % lagrange: its RK45 against semi-implicit Euler at 50 us, the Euler step's own
    error); the leg turns by more than 0.1 rad per joint and never nears the ground."""
    ref, tr = _run("validation", "pinocchio"), _run("validation", engine)
    assert np.ptp(ref.q, axis=0).min() > 0.1  # [rad]
    assert K.fk(ref.q)[:, 2].min() > 0.3  # [m] foot-centre height
    assert np.all(_sim_error(tr.q, ref.q) < 0.01)
    np.testing.assert_array_equal(tr.tau, ref.tau)  # open loop: the same torques, bit for bit


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("task", ["effort", "combined"])
def test_reference_contact_mode_agrees_within_1e_3_percent(task: str, engine: str) -> None:
    """Reference mode (the one analytic law inside every backend), same family (semi-implicit
    Euler) and step (50 us), or an adaptive backend against Pinocchio's same adaptive method (lagrange:
    RK45, rtol 1e-8, atol 1e-6): joint positions within 1e-3 % (measured <= 2.1e-4 %; ODE, whose joints are
    solver-held constraints, 0.05 %: measured 0.011 %), ground force within 0.2 % (measured <= 0.098 %,
    lagrange's adaptive steps across the touchdown)."""
    ref, tr = _reference(task, engine, "reference"), _run(task, engine, "reference")
    assert np.all(_sim_error(tr.q, ref.q) < (0.05 if engine == "ode" else 1e-3)), _sim_error(tr.q, ref.q)
    assert np.all(_sim_error(tr.f, ref.f) < 0.2), _sim_error(tr.f, ref.f)


@pytest.mark.parametrize("name", backends.available())
@pytest.mark.parametrize("mode", ["native", "reference"])
def test_effort_task_force_satisfies_each_backends_own_static_balance(name: str, mode: str) -> None:
    """Mean over the last 0.5 s: F = -(J^T)^-1 (tau - G) from the backend's own state, J the Jacobian of the point
    its info declares its force acts at (``contact_point``: MuJoCo's y/2 above the true poc), within 5e-4 of |F|
    (measured 27 Nov: <= 1.6e-4, the symbolic model's adaptive steps; 1.2e-6 for the law's creep in reference
    contact; 1e-14 to 5e-7 for the engines' own contact; MuJoCo at the true poc 2.1e-3, its lever)."""
    tr = _run("effort", name, mode)
    w = tr.t >= tr.t[-1] - 0.5
    q, tau, F = tr.q[w].mean(0), tr.tau[w].mean(0), tr.f[w].mean(0)
    h = np.linalg.solve(K.jacobian_at(q, *contact_point(tr.info, "true")).T, tau - K.gravity(q))
    assert np.linalg.norm(F + h) / np.linalg.norm(F) < 5e-4
    assert np.hypot(F[0], F[1]) <= 0.7 * F[2] * (1 + 1e-6)  # inside the friction cone


@pytest.mark.parametrize("name", backends.available())
def test_combined_task_settles_standing_on_the_ground(name: str) -> None:
    """Over the last 0.5 s of the combined task the foot pushes with the saturated torques' force, Fn within 45-55 N
    (measured 27 Nov: 49.47 N DART's rigid contact to 50.98 N Drake), and the leg is at rest, max |qd| below 5e-3
    rad/s (measured: at most 9.3e-4, the stick-slip law's creep; the Coulomb engines 1e-13 to 6e-6)."""
    tr = _run("combined", name)
    w = tr.t >= tr.t[-1] - 0.5
    assert 45.0 < tr.f[w, 2].min() and tr.f[w, 2].max() < 55.0  # [N]
    assert np.abs(tr.qd[w]).max() < 5e-3  # [rad/s]


@pytest.mark.parametrize("name", backends.available())
def test_foot_lowered_onto_the_ground_carries_the_supported_weight(name: str) -> None:
    """The position controller holds a pose 3 mm above the ground; with Kp = 10 N m/rad gravity sags the
    leg onto the ground, which then carries what the controller does not: after 1.5 s the ground force has
    settled (varies < 1 % over the last 0.3 s) and equals the static balance -(J_poc^T)^-1 (tau - G)
    from the backend's own state within 2 %."""
    q0 = K.ik_nearest(np.array([0.1667, 0.0, 0.0255]), np.array([0.0, -1.19, -1.26]))
    doc = {"name": "lower", "duration": 1.5, "initial": {"q": q0.tolist()},
           "events": [{"t": 0.0, "position": {"joint": q0.tolist()}}]}  # fmt: skip
    (tr,) = run.run(scenario.parse(doc), [name], None, progress=False)
    assert tr.status == "ok", tr.reason
    w = tr.t >= tr.t[-1] - 0.3
    fz = tr.f[w, 2]
    assert fz.mean() > 1.0 and np.ptp(fz) < 0.01 * fz.mean()
    q, tau, F = tr.q[w].mean(0), tr.tau[w].mean(0), tr.f[w].mean(0)
    h = np.linalg.solve(K.jacobian_poc(q).T, tau - K.gravity(q))
    assert np.linalg.norm(F + h) / np.linalg.norm(F) < 5e-3
