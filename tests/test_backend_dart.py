"""The DART backend: contact force read from the collision result against the leg's statics, rigid contact.

The statics are the repo's analytic check (legbench.compare): h = (J_poc^T)^-1
(tau - G(q)) at the backend's own final state and last commanded torque; the
ground force on the foot must be -h.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
import pytest

dart = pytest.importorskip("dartpy")

from test_backends_engines import R_FOOT, check_delassus, dop853_reference, run_case, run_press  # noqa: E402

from legbench import kinematics, model, resources  # noqa: E402
from legbench.backends import load  # noqa: E402
from legbench.backends.base import Physics  # noqa: E402
from legbench.scenario import physics_of  # noqa: E402

#: A press with a tangential load inside the friction cone (|F_t| / Fn = 0.09 < mu_s) [N, W].
PUSH = np.array([3.0, 2.0, -40.0])


@pytest.mark.parametrize("profile", ["matched", "engine-defaults"])
def test_contact_force_equals_statics_within_0p5_percent_of_fn(profile: str) -> None:
    """Pressed with 40 N and dragged with 3.6 N: |F + h| < 0.5 % of Fn, and the rigid foot does not sink.

    DART's contact force is its LCP impulse over the last sub-step; at rest the
    foot sticks (Coulomb), so the statics hold to round-off (measured 7e-11
    relative at 0.05 ms, 7e-8 at 1 ms). 0.5 % of Fn is the accuracy
    required of a read-out in steady contact. Rigid contact: the foot stays within 0.1 mm of
    touching (measured 5e-10 m at 0.05 ms, 3e-7 m at 1 ms); a 1e4 N/m
    spring would sink 4 mm.
    """
    backend = load("dart", Physics(), {}, profile)
    try:
        log = run_press(backend, PUSH, duration=0.8)
    finally:
        backend.close()
    q, tau, F = log["q"][-1], log["tau"][-1], log["F"][-1]
    h = np.linalg.solve(kinematics.jacobian_poc(q).T, tau - model.gravity_torque(q))
    assert F[2] > 30.0  # [N], pressing
    assert np.linalg.norm(F + h) < 5e-3 * F[2], (F, -h)
    assert abs(R_FOOT - kinematics.fk(q)[2]) < 1e-4


def test_free_space_equals_pinocchio_euler_to_1e12_rad() -> None:
    """DART's World.step is semi-implicit Euler: at 0.05 ms it equals the Pinocchio backend's to 1e-12 rad.

    Both run the same scheme at the same sub-step on the same URDF; measured
    3e-16 rad over 0.5 s of free swing under gravity (rounding only). Any
    model or scheme difference (damping, inertia, order of updates) shows up
    at 1e-6 rad or more.
    """
    pytest.importorskip("pinocchio")
    physics = Physics(gravity=9.81)
    runs = []
    for name in ("dart", "pinocchio"):
        backend = load(name, physics, {"dt": 5e-5})
        try:
            runs.append(run_case(backend, "swing"))
        finally:
            backend.close()
    np.testing.assert_allclose(runs[0], runs[1], rtol=0, atol=1e-12)
    assert np.abs(runs[0] - dop853_reference("swing")).max() > 1e-6  # the test is not vacuous: Euler's own error


def _press_statics(settings: dict[str, str]) -> tuple[float, dict[str, Any]]:
    """The 40 N press with a 3.6 N drag on DART with ``settings``: |F + (J_poc^T)^-1 (tau - G)| / Fn at its end, and
    the contact as info() reports it."""
    backend = load("dart", Physics(), settings)
    try:
        log = run_press(backend, PUSH, duration=0.5)
        info = backend.info()["contact"]
    finally:
        backend.close()
    q, tau, F = log["q"][-1], log["tau"][-1], log["F"][-1]
    h = np.linalg.solve(kinematics.jacobian_poc(q).T, tau - model.gravity_torque(q))
    return float(np.linalg.norm(F + h) / F[2]), info


@pytest.mark.parametrize("settings", [{"lcp_solver": "pgs"}, {"collision_detector": "dart"}])
def test_solver_choices_load_and_hold_the_statics(settings: dict[str, str]) -> None:
    """The PGS solver and DART's own collision detector give the same statics (0.5 % of Fn) and report themselves."""
    residual, info = _press_statics(settings)
    assert residual < 5e-3, residual
    if "lcp_solver" in settings:
        assert info["lcp_solver"] == "PgsBoxedLcpSolver"
    else:
        assert info["collision_detector"] == "dart"


def test_period_mean_force_keeps_the_impact_that_the_end_sample_misses() -> None:
    """force_readout: mean reports the period's contact impulse / Ts. It changes no state (q, qd
    identical to the last bit), equals the end sample in sustained contact (the combined task's last 0.5 s:
    measured 3e-11 of Fn, bound 1e-9), and keeps an impact the end sample misses: started at rest at q = 0
    instead of its first target, the combined task's first swing grazes the ground at t = 0.136 s (every
    backend: docs/spec.md section 7), which the end sample reads as 0 N: with the matched profile's NSGS solver
    the graze is resolved inside one period, 0.624 N s in the period mean and nothing at all in the end samples
    (Dantzig: 0.52 N s against 0.026 N s; bounds: more than 0.3 N s, and more than 10x the end samples')."""
    from legbench import scenario
    from legbench.run import run_backend

    runs = {}
    for readout in ("last", "mean"):
        sc = scenario.load(resources.scenario("combined"), {"backends.dart.force_readout": readout,
                                                            "initial.q": [0.0, 0.0, 0.0]})  # fmt: skip
        runs[readout] = run_backend(sc, "dart")
    end, mean = runs["last"], runs["mean"]
    assert np.array_equal(end.q, mean.q) and np.array_equal(end.qd, mean.qd)
    k = int(np.argmax(mean.f[:500, 2] > 0))  # the first period with contact
    assert abs(mean.t[k] - 0.136) < 1e-9 and end.f[k, 2] == 0.0 and mean.f[k, 2] > 100.0
    graze = slice(k - 5, k + 25)
    impulse = mean.f[graze, 2].sum() * float(mean.t[1] - mean.t[0])  # [N s]
    assert impulse > 0.3 and mean.f[graze, 2].sum() > 10 * end.f[graze, 2].sum(), (impulse, end.f[graze, 2].sum())
    w = end.t >= end.t[-1] - 0.5
    assert np.abs(mean.f[w] - end.f[w]).max() < 1e-9 * end.f[w, 2].mean()
    assert mean.info["contact"]["force_readout"] == "contact impulse over the control period / the period"


def test_enforced_limits_leave_joint_speeds_free_as_every_other_backend() -> None:
    """The hip spun at 50 rad/s, above the URDF's 38.84 rad/s rating, keeps its speed with the limits enforced.

    setLimitEnforcement makes DART's joint constraint bound qd by the URDF's
    ``<limit velocity>`` too (38.84 and 55.49 rad/s): one 50 us step took the
    hip from 50 to 38.84 rad/s and pushed the other joints. No other backend
    bounds a speed, so matched sets the velocity limits to +-inf. Gravity off,
    no contact, zero torque, q inside the position limits: one control period
    (20 sub-steps) with the limits enforced must equal the same period with
    them off (no constraint acts either way) to 1e-9 rad/s and rad: the same
    semi-implicit Euler steps, measured identical to the last bit.
    """
    q0, qd0 = np.array([0.0, -1.0, -1.0]), np.array([0.0, 50.0, 0.0])
    physics = Physics(gravity=0.0, contact_mode="reference")
    states, infos = {}, {}
    for enforce in (True, False):
        backend = load("dart", physics, {"enforce_limits": enforce})
        try:
            backend.reset(q0, qd0)
            backend.step(np.zeros(3))
            states[enforce], infos[enforce] = backend.state(), backend.info()
        finally:
            backend.close()
    (q_on, qd_on), (q_off, qd_off) = states[True], states[False]
    assert qd_off[1] > 45.0  # [rad/s]: the free hip is still far above 38.84 rad/s
    np.testing.assert_allclose(qd_on, qd_off, rtol=0, atol=1e-9)
    np.testing.assert_allclose(q_on, q_off, rtol=0, atol=1e-9)
    for enforce, info in infos.items():
        assert info["joint_limits_enforced"] is enforce and not info["joint_velocity_limits_enforced"]


@pytest.mark.parametrize(("setting", "solver"), [("nsgs", "NsgsFrictionSolver"), ("fbf", "FbfFrictionSolver")])
def test_constructed_friction_solvers_slide_at_mu_fn_and_hold_the_statics(setting: str, solver: str) -> None:
    """dartpy 6.20 constructs ``NsgsFrictionSolver`` and ``FbfFrictionSolver`` (BoxedLcpSolver subclasses), so
    ``lcp_solver`` offers them. They bound friction by mu times the current normal impulse: the sliding
    verification's drag slides at 0.700 Fn (measured 0.6999 NSGS, 0.6995 FBF; DART's default Dantzig holds
    0.83 Fn and does not slide), with the slip acceleration within 1 % of the closed form (measured 0.06 %,
    0.7 %), and the press statics hold (7e-11, 8e-9 of Fn)."""
    from legbench.studies import sliding_case as S

    tr, physics = S.drag("dart", settings={"lcp_solver": setting})
    rows = S.score(tr, physics)
    assert len(rows) == 3 and all(r["passed"] for r in rows), rows
    assert rows[0]["measured"] == pytest.approx(0.7, abs=2e-3)
    assert rows[2]["error"] < 0.01 * rows[2]["expected"]
    residual, info = _press_statics({"lcp_solver": setting})
    assert residual < 5e-3, residual
    assert info["lcp_solver"] == solver and info["secondary_lcp_solver"] == "PgsBoxedLcpSolver"


def test_body_sleeping_is_off_in_matched_and_dartpys_own_in_engine_defaults() -> None:
    """dartpy 6.20's World() puts a body to sleep below 0.01 m/s and 0.05 rad/s after 0.5 s, and a sleeping island's
    contact forces read zero (DeactivationOptions); the backend neither set nor recorded it. matched turns it off,
    engine-defaults keeps DART's own, and info() reads it back from the world."""
    assert dart.simulation.World().getDeactivationOptions().mEnabled  # what engine-defaults keeps
    for profile, enabled in (("matched", False), ("engine-defaults", True)):
        backend = load("dart", Physics(), {}, profile)
        try:
            assert backend.info()["deactivation_enabled"] is enabled, profile
        finally:
            backend.close()


def test_info_gives_the_pairs_friction_as_dart_combines_it() -> None:
    """info()'s contact.friction read the foot's coefficient alone; DART slides with min(mu_foot, mu_ground): a
    ground made slipperier than the foot (0.3 against 0.7) reads 0.3."""
    backend = load("dart", Physics(), {}, "matched")
    try:
        assert backend.info()["contact"]["friction"] == pytest.approx(0.7)
        ground = backend.ground.getBodyNode(0)  # type: ignore[attr-defined]
        ground.getShapeNode(0).getDynamicsAspect().setFrictionCoeff(0.3)
        assert backend.info()["contact"]["friction"] == pytest.approx(0.3)
    finally:
        backend.close()


def test_info_lists_only_the_settings_that_acted() -> None:
    """The report's settings table lists what acted (as MuJoCo's, PyBullet's and Drake's do): in reference contact
    nothing collides, so the contact's own settings (its friction coefficient, the force read-out, the collision
    detector) are left out and the law's reference_friction is there; native contact the other way round."""
    contact_only = {"friction_coefficient", "force_readout", "collision_detector"}
    for mode, absent, present in (("reference", contact_only, {"reference_friction", "lcp_solver"}),
                                  ("native", {"reference_friction"}, contact_only | {"lcp_solver"})):  # fmt: skip
        backend = load("dart", dataclasses.replace(Physics(), contact_mode=mode), {}, "matched")
        try:
            info = backend.info()
            assert not absent & info.keys() and present <= info.keys(), mode
        finally:
            backend.close()


def test_info_gives_the_contact_rows_delassus_from_the_engines_own_mass_matrix() -> None:
    """info()'s at_end.delassus, W = J M^-1 J^T at the sphere's lowest point with the engine's own mass matrix
    (what the calibration's creep closed form is built on), equals the spec leg's (Pinocchio's M) to 1e-6 of its
    largest entry, symmetric positive definite; a state that is not finite (a diverged run) gives None, not NaN."""
    check_delassus("dart", np.eye(3), lambda b: b._q.fill(math.nan))  # type: ignore[attr-defined]


def test_the_dantzig_sliding_miss_is_explained_by_its_predicted_bound_only() -> None:
    """The engine-defaults drag (Dantzig, 1 ms): the foot holds beyond the Coulomb bound and does not slide (its end
    state in info at_end: slip 5.3e-7 m/s, |F_y| = 0.833 Fn against mu 0.7). Each row is explained by the pyramid's
    closed form at the bound re-solved without friction (1.043 Fn: the axis holds) and only there: the row's value
    moved by twice its tolerance, a run without the prediction (its info's frictionless_fn gone), or another LCP
    solver, gets nothing (base.py's contract: the note held to the held foot's own end state, attached until 28 Nov,
    read the run back)."""
    from legbench.backends.dart_ import DartBackend
    from legbench.studies import sliding_case as S

    tr, physics = S.drag("dart", "engine-defaults")
    rows = S.score(tr, physics)
    assert len(rows) == 3 and not any(r["passed"] for r in rows), rows
    assert all(r["note"].startswith("known: DART's Dantzig boxed LCP") for r in rows), rows
    at_end = tr.info["at_end"]
    assert at_end["slip"] < 1e-6 and abs(at_end["force"][1]) / at_end["force"][2] == pytest.approx(0.833, abs=1e-3)
    bare = dataclasses.replace(tr, info={k: v for k, v in tr.info.items() if k != "frictionless_fn"})
    assert not any("known: " in r["note"] for r in S.score(bare, physics))
    asked: dict[str, Any] = {}
    real = S.explained_note

    def spy(cls: Any, case: str, quantity: str, info: Any, *rest: Any) -> str:
        asked[quantity] = info
        return real(cls, case, quantity, info, *rest)

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(S, "explained_note", spy)
        S.score(tr, physics)
    for r in rows:
        info, q, tol = asked[r["quantity"]], r["quantity"], r["tolerance"]
        assert DartBackend.known_deviation("sliding", q, info, r["measured"], r["expected"], tol) is not None
        far = r["measured"] + 2 * tol + 1e-6
        assert DartBackend.known_deviation("sliding", q, info, far, r["expected"], tol) is None
        nsgs = {**info, "lcp_solver": "nsgs"}
        assert DartBackend.known_deviation("sliding", q, nsgs, r["measured"], r["expected"], tol) is None


def test_the_frictionless_normal_leaves_the_friction_as_it_was_and_is_dantzigs_alone() -> None:
    """frictionless_normal steps once with both shapes' friction at 0 and puts the coefficient back (a reviewer's
    check: only ODE's restore was tested); its Fn is above the run's where friction pulls the foot up (1.490 Fn in
    the engine-defaults drag: the bound 1.043 Fn); NSGS (the matched solver) and reference contact give None."""
    from legbench.backends.dart_ import DartBackend
    from legbench.run import simulate
    from legbench.studies import sliding_case as S

    sc = S._scenario()
    physics = physics_of(sc, "native")
    b = load("dart", physics, {}, "engine-defaults")
    assert isinstance(b, DartBackend)
    try:
        tr = simulate(sc, b, physics)
        k = int(np.flatnonzero(tr.t >= 0.35)[0])
        before = [sn.getDynamicsAspect().getFrictionCoeff() for sn in b._contact_shapes()]
        fn0 = b.frictionless_normal(tr.q[k], tr.qd[k], tr.tau[k])
        assert [sn.getDynamicsAspect().getFrictionCoeff() for sn in b._contact_shapes()] == before == [0.7, 0.7]
        assert fn0 is not None and fn0 / tr.f[k, 2] == pytest.approx(1.490, abs=2e-3), (fn0, tr.f[k, 2])
    finally:
        b.close()
    for profile, mode in (("matched", "native"), ("engine-defaults", "reference")):
        other = load("dart", physics_of(sc, mode), {}, profile)
        try:
            assert other.frictionless_normal(tr.q[k], tr.qd[k], tr.tau[k]) is None
        finally:
            other.close()


def test_rest_sink_is_the_regularisations_closed_form_where_it_holds() -> None:
    """rest_sink(info, Fn) = cfm A_nn Fn h^2 / ERP from the run's info (contact.constraint_force_mixing 1e-5,
    at_end.delassus's normal entry, timestep; ERP 0.01): 4.769 1/kg, 51.31 N at 50 us give 6.117e-10 m, at 1 ms
    2.447e-7 m; None without those entries (reference contact, a diverged run's null Delassus) and where the bias
    ERP y / h would exceed DART's cap of 1e-3 m/s (no closed form of the rest: here above Fn = 2.1e4 N at 1 ms)."""
    from legbench.backends.dart_ import DartBackend

    W = [[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 4.769]]
    info = {"timestep": 5e-5, "contact": {"constraint_force_mixing": 1e-5}, "at_end": {"delassus": W}}
    assert DartBackend.rest_sink(info, 51.31) == pytest.approx(1e-5 * 4.769 * 51.31 * 5e-5**2 / 0.01, rel=1e-12)
    assert DartBackend.rest_sink(info, 51.31) == pytest.approx(6.117e-10, rel=1e-3)
    slow = {**info, "timestep": 1e-3}
    assert DartBackend.rest_sink(slow, 51.31) == pytest.approx(2.447e-7, rel=1e-3)
    assert DartBackend.rest_sink(slow, 2.0e4) is not None and DartBackend.rest_sink(slow, 2.2e4) is None
    assert DartBackend.rest_sink({**info, "at_end": {"delassus": None}}, 51.31) is None
    assert DartBackend.rest_sink({**info, "contact": {"enabled": False, "Kp": 1e4}}, 51.31) is None
    assert "= 6.117e-10 m" in DartBackend.rest_sink_text(info, 51.31)
