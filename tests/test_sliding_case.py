"""The sliding verification case scores each backend against the contact it declares: the friction shape
(``friction_cone``: the diamond here), the coefficient it slides with (``sliding_coefficient``) and the point its
force acts at (``contact.poc``), and its engine-defaults rows say which misses are the engine's."""

from __future__ import annotations

import math

import numpy as np
import pytest
from fakes import FakeBackend

from legbench import backends, kinematics, model
from legbench.backends.base import Physics
from legbench.studies import sliding_case as S

P = Physics().contact


def _need(name: str) -> None:
    if name not in backends.available():
        pytest.skip(f"{name} is not installed")


def test_the_diamond_slides_on_the_vertex_against_the_slips_larger_component() -> None:
    """|F_x| + |F_y| <= mu Fn: of all its points the vertex on the slip's larger axis dissipates most (to
    round-off, against 2000 points of its boundary), so a slip (-40, 280) mm/s gets F_t = (0, -mu Fn): |F_t| =
    mu Fn, atan(40 / 280) = 8.13 deg off -slip; a slip along the diagonal gets the face's middle, mu Fn / 2 on each
    axis, opposite the slip."""
    mu, fn = 0.7, np.array([15.0, 15.0, 10.0, 10.0])
    v = np.array([[-0.04, 0.28], [0.3, -0.01], [0.2, 0.2], [-0.1, 0.1]])
    f = S.diamond_friction(v, fn, mu)
    np.testing.assert_allclose(f, [[0.0, -10.5], [-10.5, 0.0], [-3.5, -3.5], [3.5, -3.5]], rtol=0, atol=1e-12)
    np.testing.assert_allclose(np.abs(f).sum(axis=1), mu * fn, rtol=1e-12)
    off = math.degrees(math.acos(-(f[0] @ v[0]) / (np.linalg.norm(f[0]) * np.linalg.norm(v[0]))))
    assert off == pytest.approx(math.degrees(math.atan(0.04 / 0.28)), abs=1e-9) and off == pytest.approx(8.13, abs=0.01)
    th = np.linspace(0.0, 2.0 * np.pi, 2000)
    boundary = np.column_stack([np.cos(th), np.sin(th)]) / (np.abs(np.cos(th)) + np.abs(np.sin(th)))[:, None]
    for s in range(len(v)):
        assert -(f[s] @ v[s]) >= (-(mu * fn[s] * boundary) @ v[s]).max() - 1e-12


def test_the_declared_sliding_coefficient_is_the_runs_not_the_classs() -> None:
    """The coefficient is what the loaded backend declared (``slides_with()``, run info ``sliding_coefficient``);
    a run that recorded none falls back to the class's."""
    assert FakeBackend.sliding_coefficient == "mu_k"
    assert S.sliding_coefficient({"sliding_coefficient": "mu_s"}, FakeBackend) == "mu_s"
    assert S.sliding_coefficient({}, FakeBackend) == "mu_k"
    assert S.sliding_coefficient({"sliding_coefficient": "bogus"}, FakeBackend) == "mu_k"


def test_the_closed_form_applies_the_force_at_the_declared_point() -> None:
    """poc 'centre': the force acts at E and the acceleration is E's, J_E qdd + Jdot_E qd (qdd under J_E^T F);
    a 6 N horizontal force's lever R_foot (22.5 mm) shorter moves the poc's acceleration by more than 5 %."""
    rng = np.random.default_rng(3)
    p = model.load_params()
    q0 = kinematics.ik_nearest(np.array([0.1667, 0.0, p.geometry.R_foot - 0.001]), np.array(p.q_star))
    q = q0 + 0.01 * rng.standard_normal((3, 3))
    qd, tau = 0.3 * rng.standard_normal((3, 3)), 3.0 * rng.standard_normal((3, 3))
    force = np.tile([0.0, -6.0, 15.0], (3, 1))
    centre = S.predicted_acceleration(q, qd, tau, force, 0.5, "centre")  # lift does not apply at the centre
    dyn, eps = model.Dynamics(), 1e-7
    for k in range(3):
        J = kinematics.jacobian(q[k])
        qdd = np.linalg.solve(
            dyn.mass_matrix(q[k]), tau[k] - dyn.inverse_dynamics(q[k], qd[k], np.zeros(3)) + J.T @ force[k]
        )
        a = J @ qdd + (kinematics.jacobian(q[k] + eps * qd[k]) - J) / eps @ qd[k]
        np.testing.assert_allclose(centre[k], a[:2], rtol=1e-6, atol=1e-6)
    lowest = S.predicted_acceleration(q, qd, tau, force)
    assert (np.abs(centre[:, 1] - lowest[:, 1]) > 0.05 * np.abs(lowest[:, 1])).all()


def test_lagrange_engine_defaults_is_scored_at_the_sphere_centre() -> None:
    """The lagrange backend's engine-defaults apply the law at the sphere's centre (info ``contact.poc``
    'centre'); the closed form with F there meets its slip acceleration (measured 6.521 against 6.511 m/s^2,
    0.15 %); with F at the lowest point the closed form said 2.36 m/s^2."""
    _need("lagrange")
    rows = S.sliding_case("lagrange", "engine-defaults")
    assert all(r["passed"] for r in rows), rows
    acc = rows[2]
    assert "sphere's centre" in acc["note"] and acc["expected"] == pytest.approx(6.51, rel=5e-3)


def test_drake_engine_defaults_is_scored_with_its_dynamic_coefficient() -> None:
    """Drake's engine-defaults contact is CoulombFriction(mu_s, mu_k), and its discrete solvers slide with the
    dynamic one: the run declares mu_k, its pair's mu_dynamic, and meets the cone's closed form with it (friction
    0.5993 Fn against 0.6, acceleration 7.144 against 7.104 m/s^2); with mu_s the closed form said 0.7 and
    -0.012 m/s^2."""
    _need("drake")
    tr, physics = S.drag("drake", "engine-defaults")
    coef = tr.info["sliding_coefficient"]
    assert coef == "mu_k" and tr.info["contact"]["mu_dynamic"] == pytest.approx(getattr(physics.contact, coef))
    rows = S.score(tr, physics)
    assert all(r["passed"] for r in rows), rows
    assert rows[0]["expected"] == P.mu_k and rows[0]["note"].startswith("mu_k = 0.6")


def test_mujoco_engine_defaults_slides_on_the_diamonds_vertex_and_hops() -> None:
    """MuJoCo's default pyramidal cone (info ``friction_cone`` 'diamond') slides with F_t = (0, -mu_s Fn), the
    vertex, while the slip is up to 10 deg off W y: the diamond's rows pass. Its acceleration row misses (the
    foot hops for single 1 ms steps without contact) and says so; the contact steps themselves meet the closed
    form: forward differences under the force read at each step's start within 1 % (measured 0.3 %)."""
    _need("mujoco")
    tr, physics = S.drag("mujoco", "engine-defaults")
    assert tr.info["friction_cone"] == "diamond"
    ratio, angle, acc = S.score(tr, physics)
    assert ratio["passed"] and angle["passed"] and "(diamond)" in ratio["quantity"], (ratio, angle)
    assert "up to 10 deg off -slip" in ratio["note"]
    assert not acc["passed"] and acc["note"].startswith("known: ") and "hops" in acc["note"]
    poc, lift = tr.info["contact"]["poc"], tr.info["contact"]["lift"]
    v = np.einsum("nij,nj->ni", kinematics.jacobian_at(tr.q, poc, lift), tr.qd)[:, :2]
    k = np.flatnonzero((tr.t >= S.WINDOW[0] - 1e-9) & (tr.t <= S.WINDOW[1] + 1e-9) & (tr.f[:, 2] > S.FN_MIN))
    hop = (tr.t >= S.WINDOW[0] - 1e-9) & (tr.t <= S.WINDOW[1] + 1e-9) & (tr.f[:, 2] <= S.FN_MIN)
    assert hop.sum() >= 2  # the engine's hop, not a fluke
    u = v[k] / np.linalg.norm(v[k], axis=1)[:, None]
    f = np.column_stack([S.diamond_friction(v[k], tr.f[k, 2], P.mu_s), tr.f[k, 2]])
    pred = np.sum(S.predicted_acceleration(tr.q[k], tr.qd[k], tr.tau[k], f, lift) * u, axis=1).mean()
    forward = np.sum((v[k + 1] - v[k]) / physics.control_dt * u, axis=1).mean()
    assert forward == pytest.approx(pred, rel=0.01)


def test_dart_engine_defaults_says_why_its_dantzig_pyramid_does_not_slide() -> None:
    """DART's engine-defaults Dantzig LCP bounds friction by the frictionless normal impulse: the foot holds
    0.83 Fn and does not slide. The rows still fail, each with that explanation."""
    _need("dart")
    rows = S.sliding_case("dart", "engine-defaults")
    assert rows[0]["measured"] == pytest.approx(0.833, abs=0.005)
    assert all(not r["passed"] and r["note"].startswith("known: ") and "0.83 Fn" in r["note"] for r in rows)
