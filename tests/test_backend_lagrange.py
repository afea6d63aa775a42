"""The symbolic Euler-Lagrange backend: derivation vs Pinocchio and textbook closed forms, the solve, the cache."""

from __future__ import annotations

import dataclasses
import math
import os
import shutil
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy.integrate import solve_ivp

sp = pytest.importorskip("sympy")

from legbench import backends as registry  # noqa: E402
from legbench import kinematics, model, run, scenario  # noqa: E402
from legbench.backends import dopri, lagrange_kernel  # noqa: E402
from legbench.backends import lagrange_eom as E  # noqa: E402
from legbench.backends.base import Physics  # noqa: E402
from legbench.backends.lagrange_ import LagrangeBackend  # noqa: E402
from legbench.exceptions import LegbenchError, ScenarioError  # noqa: E402

PARAMS = model.load_params()
CONTROL_DT = 1e-3  # [s]
SCENARIOS = Path(__file__).resolve().parents[1] / "scenarios"
G_EARTH = 9.81  # [m/s^2]


@pytest.fixture
def make() -> Iterator[Any]:
    """Factory: ``make(physics=Physics(), profile="matched", **settings)`` -> loaded lagrange backend."""
    made: list[LagrangeBackend] = []

    def _make(physics: Physics | None = None, profile: str = "matched", **settings: Any) -> LagrangeBackend:
        backend = LagrangeBackend()
        backend.load(model.URDF_FILE, physics or Physics(), LagrangeBackend.resolve_settings(settings, profile))
        made.append(backend)
        return backend

    yield _make
    for backend in made:
        backend.close()


@pytest.fixture(scope="module")
def eom() -> Any:
    """The leg's generated equations of motion (from the user cache, derived there once)."""
    return E.load_eom(E.leg_chain(PARAMS)).module


# --------------------------------------------------------------------------- #
# The derivation against Pinocchio's rigid-body algorithms


def test_B_Cqd_G_equal_pinocchio_crba_rnea_to_1e13_at_200_poses(eom: Any) -> None:
    """B(q) = crba, C(q, qd) qd = rnea(q, qd, 0) - rnea(q, 0, 0), G(q) = rnea(q, 0, 0) to 1e-13 (SI units).

    Two independent algorithms on the same leg: the derivation reads the parameter file, Pinocchio the
    URDF, which carries the same numbers exactly (written with repr); they differ by round-off (measured
    3.5e-17 kg m^2 for B, 7.2e-16 N m for C qd, 8.9e-16 N m for G at |qd| <= 5 rad/s; 5e-13 and 1.2e-11
    while the URDF stored 12 significant digits). A sign flip of a product of inertia moves them by ~1e-4.
    """
    import pinocchio as pin

    pm = model.pinocchio_model(gravity=G_EARTH)
    pd = pm.createData()
    rng = np.random.default_rng(13)
    zero = np.zeros(3)
    for _ in range(200):
        q, qd = rng.uniform(-np.pi, np.pi, 3), rng.uniform(-5.0, 5.0, 3)
        qp = model.q_to_pin(q)
        M = pin.crba(pm, pd, qp)
        M = np.triu(M) + np.triu(M, 1).T  # CRBA fills the upper triangle
        g = pin.rnea(pm, pd, qp, zero, zero)
        cqd = pin.rnea(pm, pd, qp, qd, zero) - g
        np.testing.assert_allclose(np.reshape(eom.mass_matrix(*q), (3, 3)), M, rtol=0, atol=1e-13)
        np.testing.assert_allclose(eom.bias(*q, *qd), cqd, rtol=0, atol=1e-13)
        np.testing.assert_allclose(np.array(eom.gravity(*q)) * G_EARTH, g, rtol=0, atol=1e-13)
        C = np.reshape(eom.coriolis(*q, *qd), (3, 3))
        np.testing.assert_allclose(C @ qd, eom.bias(*q, *qd), rtol=0, atol=1e-12)


def test_gravity_torque_at_q_star_is_the_report_calibration_figure(eom: Any) -> None:
    """G(q*) = [1.0426, 0.1631, -0.2984] N m, the figure the model's masses are calibrated to (1e-9 N m:
    the calibration solves exactly; the residual is the URDF's rounding in the calibration's own G)."""
    np.testing.assert_allclose(np.array(eom.gravity(*PARAMS.q_star)) * PARAMS.gravity, PARAMS.G_star, atol=1e-9)


def test_euler_lagrange_equations_from_the_energies_equal_B_qdd_plus_C_qd_plus_G() -> None:
    """d/dt(dT/dqd) - dT/dq + dV/dq, differentiated from the energies, equals the collected form (1e-12).

    Checks the collection (B as the Hessian of T, C from the Christoffel symbols) against the
    Euler-Lagrange derivatives themselves, at 20 random states; only rounding separates the two.
    """
    d = E.derive(E.leg_chain(PARAMS))
    f = E.lambdified(d)
    rng = np.random.default_rng(5)
    for _ in range(20):
        q, qd, qdd = rng.uniform(-3, 3, 3), rng.uniform(-5, 5, 3), rng.uniform(-50, 50, 3)
        lhs = np.ravel(f["el"](q, qd, qdd))
        rhs = np.asarray(f["B"](q)) @ qdd + np.asarray(f["C"](q, qd)) @ qd + np.ravel(f["G"](q))
        np.testing.assert_allclose(lhs, rhs, rtol=0, atol=1e-12)


# --------------------------------------------------------------------------- #
# The report's validation of the derivation code: textbook closed forms

#: W_T_0 turning the chain's x0-y0 plane into the vertical x_W-z_W plane (y0 up), joints along -y_W.
VERTICAL_PLANE = ((1, 0, 0, 0), (0, 0, -1, 0), (0, 1, 0, 0), (0, 0, 0, 1))


def _planar_link(a: Any, m: Any, lc: Any, izz: Any) -> E.Link:
    """A link of a planar arm: joint axis z, COM on the link's x axis, inertia izz about the COM."""
    zero = sp.Integer(0)
    return E.Link(0, a, 0, 0, m, (lc, zero, zero), ((izz, 0, 0), (0, izz, 0), (0, 0, izz)))


def _assert_zero(expr: Any) -> None:
    assert sp.simplify(sp.expand_trig(expr)) == 0, expr


def test_pendulum_matches_the_textbook_closed_form() -> None:
    """1-DOF pendulum, angle q from the horizontal: B = I + m lc^2, C = 0, G = m g lc cos q (exact, symbolic)."""
    m, lc, izz, g = sp.symbols("m l_c I g", positive=True)
    d = E.derive(E.Chain(VERTICAL_PLANE, (_planar_link(0, m, lc, izz),)))
    (q,) = d.q
    _assert_zero(d.B[0, 0] - (izz + m * lc**2))
    _assert_zero(d.C[0, 0])
    _assert_zero(g * d.G[0] - m * g * lc * sp.cos(q))
    _assert_zero(g * d.V - m * g * lc * sp.sin(q))


def test_planar_two_link_arm_matches_the_textbook_closed_form() -> None:
    """Planar 2-DOF arm (Spong, Hutchinson and Vidyasagar, Robot Modeling and Control, the two-link
    planar elbow manipulator): B, C (Christoffel) and G equal the closed forms exactly (symbolic)."""
    m1, m2, l1, lc1, lc2, i1, i2, g = sp.symbols("m1 m2 l1 lc1 lc2 I1 I2 g", positive=True)
    chain = E.Chain(VERTICAL_PLANE, (_planar_link(0, m1, lc1, i1), _planar_link(l1, m2, lc2, i2)))
    d = E.derive(chain)
    q1, q2 = d.q
    qd1, qd2 = d.qd
    c2 = sp.cos(q2)
    B = sp.Matrix(
        [
            [m1 * lc1**2 + m2 * (l1**2 + lc2**2 + 2 * l1 * lc2 * c2) + i1 + i2, m2 * (lc2**2 + l1 * lc2 * c2) + i2],
            [m2 * (lc2**2 + l1 * lc2 * c2) + i2, m2 * lc2**2 + i2],
        ]
    )
    h = -m2 * l1 * lc2 * sp.sin(q2)
    C = sp.Matrix([[h * qd2, h * qd2 + h * qd1], [-h * qd1, 0]])
    G = sp.Matrix(
        [(m1 * lc1 + m2 * l1) * g * sp.cos(q1) + m2 * lc2 * g * sp.cos(q1 + q2), m2 * lc2 * g * sp.cos(q1 + q2)]
    )
    for i in range(2):
        _assert_zero(g * d.G[i] - G[i])
        for j in range(2):
            _assert_zero(d.B[i, j] - B[i, j])
            _assert_zero(d.C[i, j] - C[i, j])


# --------------------------------------------------------------------------- #
# The solve: free swing, gravity, limits, contact

Q_SWING = np.array([0.2, 3.0, 0.8])  # foot high above the hip; swings 1.6-2.5 rad per joint in 0.5 s
N_SWING = 500


def _swing(backend: Any) -> np.ndarray:
    backend.reset(Q_SWING, np.zeros(3))
    out = [backend.state()[0]]
    for _ in range(N_SWING):
        backend.step(np.zeros(3))
        out.append(backend.state()[0])
    return np.array(out)


def test_free_swing_matches_dop853_of_the_same_equations_to_1e9_rad(make: Any, eom: Any) -> None:
    """Zero torque under gravity, 0.5 s: RK45 (rtol 1e-8, atol 1e-6, max step 0.1 ms) vs DOP853 (rtol 1e-12)
    of the same generated qdd, per control period. The 0.1 ms step cap keeps RK45's local error far below
    its tolerances (measured 4e-14 rad); 1e-9 rad would catch any slip in the hold or the state handling."""

    def f(_t: float, x: np.ndarray) -> np.ndarray:
        return np.array([*x[3:], *eom.qdd(*x.tolist(), 0.0, 0.0, 0.0, G_EARTH)])

    x = np.concatenate([Q_SWING, np.zeros(3)])
    ref = [x[:3].copy()]
    for _ in range(N_SWING):
        x = solve_ivp(f, (0.0, CONTROL_DT), x, method="DOP853", rtol=1e-12, atol=1e-14).y[:, -1]
        ref.append(x[:3].copy())
    q = _swing(make())
    assert np.ptp(q, axis=0).min() > 1.5  # [rad] every joint swings far
    np.testing.assert_allclose(q, np.array(ref), rtol=0, atol=1e-9)


def test_free_swing_matches_the_pinocchio_backend_in_reference_mode_to_1e9_rad(make: Any) -> None:
    """Same swing on Pinocchio's ABA (DOP853, rtol 1e-11): two dynamics implementations agree to 1e-9 rad.

    Measured 8e-11 rad, the solvers' own tolerance; an error in any inertia
    term (e.g. a product-of-inertia sign, ~1e-4 relative) moves the swing by 1e-5 rad or more.
    """
    pytest.importorskip("pinocchio")
    from legbench.backends.pinocchio_ import PinocchioBackend

    physics = Physics(contact_mode="reference")
    pin_backend = PinocchioBackend()
    pin_backend.load(model.URDF_FILE, physics, {"integrator": "dop853", "rtol": 1e-11, "atol": 1e-13})
    np.testing.assert_allclose(_swing(make(physics)), _swing(pin_backend), rtol=0, atol=1e-9)


def test_gravity_compensation_holds_the_leg_still(make: Any, eom: Any) -> None:
    """tau = G(q0) at a pose in the air: the leg stays within 1e-9 rad of q0 for 0.3 s (it starts at rest,
    the torque balances gravity exactly up to the integrator's rounding)."""
    q0 = np.array([0.3, -0.6, -1.1])
    backend = make()
    backend.reset(q0, np.zeros(3))
    tau = np.array(eom.gravity(*q0)) * G_EARTH
    for _ in range(300):
        backend.step(tau)
    np.testing.assert_allclose(backend.state()[0], q0, rtol=0, atol=1e-9)
    assert kinematics.fk(q0)[2] > PARAMS.geometry.R_foot + 0.05  # [m] clear of the ground


def test_knee_limit_holds_like_the_other_custom_integrator(make: Any) -> None:
    """10 N m pushing the knee into its 2.229 rad limit rests at 2.229 + 10/1e4 rad (the shared limit law)
    to 1e-4 rad (the spring's static deflection; gravity off)."""
    backend = make(Physics(gravity=0.0))
    backend.reset(np.array([0.0, -0.5, 2.0]), np.zeros(3))
    for _ in range(1000):
        backend.step(np.array([0.0, 0.0, 10.0]))
    assert backend.state()[0][2] == pytest.approx(PARAMS.upper[2] + 10.0 / 1e4, abs=1e-4)


def test_foot_lowered_onto_the_ground_carries_the_supported_weight(make: Any, eom: Any) -> None:
    """Foot lowered from 3 mm onto the ground, then pressing with the leg's weight W = m g (tau = G + J_poc^T h,
    h = -W z_W, a little joint damping): the steady normal force equals W (12.4 N) to 1e-6, and Kp y.

    A purely normal push leaves no tangential load, so the foot comes to rest (no creep) and
    M qdd + C qd and Kd ydot vanish: measured 3e-14 relative. 1e-6 leaves room for rounding and
    still catches a wrong Kp, a missing J_poc^T term or gravity off by a link (percent level)."""
    weight = sum(PARAMS.body_inertial(link).mass for link in model.LINK_NAMES) * G_EARTH  # [N]
    start = kinematics.ik_nearest(np.array([0.1667, 0.0, PARAMS.geometry.R_foot + 0.003]), np.array(PARAMS.q_star))
    backend = make()
    backend.reset(start, np.zeros(3))
    push = np.array([0.0, 0.0, -weight])
    fz = []
    for _ in range(1500):
        q, qd = backend.state()
        tau = np.array(eom.gravity(*q)) * G_EARTH + kinematics.jacobian_poc(q).T @ push - 0.05 * qd
        backend.step(tau)
        fz.append(backend.ground_force()[2])
    assert fz[-1] == pytest.approx(weight, rel=1e-6)
    assert abs(fz[-1] - fz[-500]) < 1e-6 * weight  # settled over the last 0.5 s
    y = PARAMS.geometry.R_foot - kinematics.fk(backend.state()[0])[2]
    assert fz[-1] == pytest.approx(PARAMS.contact.Kp * y, rel=1e-6)


def test_profiles_put_the_poc_where_the_report_did(make: Any) -> None:
    """``matched``: the true poc (the sphere's lowest point); ``engine-defaults``: the sphere centre, as the
    report's custom simulation. Rolling the foot in contact (hip and knee turning) moves the lowest point
    by R (qd2 + qd3) more than the centre; slow enough that both speeds sit on the law's stick-slip ramp
    (below v_th), the friction force differs with the speed (measured 0.915 vs 0.678 N along y_W)."""
    q = kinematics.ik_nearest(np.array([0.1667, 0.0, PARAMS.geometry.R_foot - 0.001]), np.array(PARAMS.q_star))
    qd = np.array([0.0, 0.0005, -0.002])
    forces = {}
    for profile in ("matched", "engine-defaults"):
        backend = make(profile=profile)
        backend.reset(q, qd)
        forces[profile] = backend.ground_force()
        assert backend.info()["contact"]["poc"] == {"matched": "true", "engine-defaults": "centre"}[profile]
    assert forces["matched"][2] > 5.0  # [N] in contact
    assert abs(forces["matched"][1] - forces["engine-defaults"][1]) > 0.1  # [N]


def test_both_contact_modes_apply_the_same_law(make: Any) -> None:
    """No engine contact: ``native`` and ``reference`` give identical runs, and the backend says so."""
    runs = []
    for mode in ("native", "reference"):
        backend = make(Physics(contact_mode=mode))
        assert not backend.engine_contact()
        q = kinematics.ik_nearest(np.array([0.1667, 0.0, PARAMS.geometry.R_foot - 0.001]), np.array(PARAMS.q_star))
        backend.reset(q, np.zeros(3))
        for _ in range(50):
            backend.step(np.array([0.5, 0.0, 0.0]))
        runs.append((*backend.state(), backend.ground_force()))
    for a, b in zip(*runs, strict=True):
        np.testing.assert_array_equal(a, b)


def test_mass_properties_are_the_parameter_file_to_the_last_bit(make: Any) -> None:
    """The generated code holds the model's inertials exactly (floats printed round-trip), link 3 with the foot."""
    props = make().mass_properties()
    for link in model.LINK_NAMES:
        want = PARAMS.body_inertial(link)
        assert props[link]["mass"] == want.mass
        assert tuple(props[link]["com"]) == tuple(want.com)
        np.testing.assert_array_equal(props[link]["inertia"], want.I)


def test_declared_abilities(make: Any) -> None:
    backend = make()
    lim = backend.limits()
    assert backend.integrator_family() == "adaptive" and backend.sub_steps() == 1 and lim.timestep is None
    assert lim.gravity == G_EARTH and lim.upper[2] == PARAMS.upper[2] and math.isinf(lim.upper[1])
    assert lim.effort == Physics().torque_limit
    assert set(backend.kernels(np.zeros((2, 3)), np.zeros((2, 3)), np.zeros((2, 3)))) == {"qdd", "law"}


# --------------------------------------------------------------------------- #
# The cache


def test_second_load_reads_the_cache_and_does_not_derive(make: Any, tmp_path: Path) -> None:
    """First load derives and writes eom_<hash>.py; a second load imports it: the derivation counter
    and the file's mtime do not change. A changed model (link 2 1 % heavier) has another hash and derives."""
    before = E.derivations
    first = make(cache_dir=str(tmp_path))
    assert first.eom.derived and E.derivations == before + 1
    files = list(tmp_path.glob("eom_*.py"))
    assert files == [first.eom.path]
    mtime = first.eom.path.stat().st_mtime_ns
    second = make(cache_dir=str(tmp_path))
    assert not second.eom.derived and E.derivations == before + 1
    assert second.eom.path.stat().st_mtime_ns == mtime
    np.testing.assert_array_equal(
        first.eom.module.mass_matrix(0.1, 0.2, 0.3), second.eom.module.mass_matrix(0.1, 0.2, 0.3)
    )
    chain = E.leg_chain(PARAMS)
    heavier = dataclasses.replace(chain.links[1], mass=chain.links[1].mass * 1.01)
    other = E.load_eom(dataclasses.replace(chain, links=(chain.links[0], heavier, chain.links[2])), tmp_path)
    assert other.derived and other.path != first.eom.path and E.derivations == before + 2


def test_an_edited_derivation_or_another_sympy_derives_again(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The cache key held the chain's numbers and a hand-bumped GENERATOR_VERSION only: an edit of the derivation
    without a bump (a reviewer flipped G's sign in derive()) reused the old equations. The key now holds the
    module's source and sympy's version (DERIVATION): another value is another file, derived again."""
    chain = E.Chain(VERTICAL_PLANE, (_planar_link(0.0, 0.5, 0.2, 1e-3),))
    first = E.load_eom(chain, tmp_path)
    assert not E.load_eom(chain, tmp_path).derived  # the same derivation: loaded
    monkeypatch.setattr(E, "DERIVATION", "0" * 64)  # as an edited lagrange_eom.py or another sympy would give
    again = E.load_eom(chain, tmp_path)
    assert again.derived and again.path != first.path
    assert again.module.KEY == chain.key() != first.module.KEY
    assert oct(again.path.stat().st_mode & 0o777) == "0o644"  # readable by others sharing the cache (mkstemp: 600)


@pytest.mark.parametrize("mass", [math.pi, math.pi / 2])
def test_a_number_equal_to_a_multiple_of_pi_over_2_is_a_number(tmp_path: Path, mass: float) -> None:
    """Only DH twists and offsets are taken as exact multiples of pi/2: a mass of exactly pi [kg] became sympy's
    pi, printed as ``pi`` into a module that imports only cos, sin and sqrt, and its first call raised NameError
    (and the cache kept the file, as it imports). Now it is the number: G = m lc cos q per unit g."""
    chain = E.Chain(VERTICAL_PLANE, (_planar_link(0.0, mass, 0.2, 1e-3),))
    eom = E.load_eom(chain, tmp_path).module
    assert eom.gravity(0.3)[0] == pytest.approx(mass * 0.2 * math.cos(0.3), rel=1e-15)
    assert eom.mass_matrix(0.3)[0] == pytest.approx(1e-3 + mass * 0.2**2, rel=1e-15)


def test_a_corrupt_cache_file_is_derived_again(tmp_path: Path) -> None:
    """A cache file that does not import is replaced by a fresh derivation (a numeric pendulum: fast)."""
    chain = E.Chain(VERTICAL_PLANE, (_planar_link(0.0, 0.5, 0.2, 1e-3),))
    path = E.load_eom(chain, tmp_path).path
    path.write_text("this is not python(")
    again = E.load_eom(chain, tmp_path)
    assert again.derived and again.module.N == 1
    # B = I + m lc^2 and G = m lc cos q per unit g, from the regenerated file
    assert again.module.mass_matrix(0.3)[0] == pytest.approx(1e-3 + 0.5 * 0.2**2, rel=1e-15)
    assert again.module.gravity(0.3)[0] == pytest.approx(0.5 * 0.2 * math.cos(0.3), rel=1e-15)


# --------------------------------------------------------------------------- #
# The Dormand-Prince period (legbench/backends/lagrange_kernel.py): scipy's RK45, run as Python and compiled

numba_needed = pytest.mark.skipif(not lagrange_kernel.available(), reason="needs numba")


def _pressed_states(n: int) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """``n`` states of the foot pressed 1 mm into the ground with random joint speeds, and random torques [N m]:
    stick, slip and the stiff stick-slip ramp all occur."""
    rng = np.random.default_rng(7)
    start = kinematics.ik_nearest(np.array([0.1667, 0.0, PARAMS.geometry.R_foot - 0.001]), np.array(PARAMS.q_star))
    for _ in range(n):
        yield np.concatenate([start + rng.normal(0.0, 0.01, 3), rng.normal(0.0, 0.3, 3)]), rng.normal(0.0, 2.0, 3)


def _one_period(backend: LagrangeBackend, compiled: bool, x: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, int]:
    """The backend's period, compiled or as Python, from x under u: (end state, right-hand-side evaluations)."""
    fn = lagrange_kernel.period(backend.eom.module.KEY, backend._qdd, compiled)
    y = x.copy()
    rtol, atol, max_step = backend._tols
    n = fn(y, u, backend.g, backend._lc, backend._lim, CONTROL_DT, rtol, atol, max_step, backend._k, ())
    return y, n


def test_the_period_takes_scipy_rk45s_steps_in_stick_slip_contact(make: Any) -> None:
    """One control period from 200 pressed-foot states, with the backend's tolerances: the period (as Python)
    makes exactly solve_ivp(RK45)'s right-hand-side evaluations (same initial step, same accepted and rejected
    steps) and ends within 1e-12 of it (measured 5e-14: the two differ only in the rounding of the stage sums;
    a wrong tableau entry or step control moves the end state by 1e-8 or the evaluation count)."""
    backend = make(kernel="python")
    s = backend._solve
    nfev = []
    for x, u in _pressed_states(200):
        backend._u[:] = u.tolist()
        ref = solve_ivp(backend.rhs, (0.0, CONTROL_DT), x, method="RK45", rtol=s["rtol"], atol=s["atol"],
                        max_step=s["max_step"])  # fmt: skip
        y, n = _one_period(backend, False, x, u)
        assert n == ref.nfev
        np.testing.assert_allclose(y, ref.y[:, -1], rtol=0, atol=1e-12)
        nfev.append(n)
    assert max(nfev) > 62  # some periods needed more than the ten 0.1 ms steps (error control at work)


def test_the_stepper_rejects_steps_like_scipy_on_a_stiff_problem() -> None:
    """The same stepper on Van der Pol with mu = 1000 over 1 ms from its fast transient, no step cap: the error
    control rejects and shrinks steps (1-2 rejections from each start); evaluation count equal to
    solve_ivp(RK45)'s and the end state within 1e-12 relative (rounding of the stage sums)."""
    mu = 1000.0

    def rhs(_lc: Any, _lim: Any, _u: Any, _g: float, y: Any, out: Any, _data: Any) -> None:
        out[0], out[1] = y[1], mu * (1.0 - y[0] ** 2) * y[1] - y[0]

    period = dopri.stepper(rhs)
    for y0 in ([2.0, 0.0], [0.5, 3.0], [1.9, -50.0]):
        ref = solve_ivp(lambda _t, y: np.array([y[1], mu * (1.0 - y[0] ** 2) * y[1] - y[0]]), (0.0, 1e-3), y0,
                        method="RK45", rtol=1e-6, atol=1e-9)  # fmt: skip
        y = np.array(y0)
        n = period(y, None, 0.0, None, None, 1e-3, 1e-6, 1e-9, math.inf, np.zeros((9, 2)), ())
        assert n == ref.nfev and (n - 2) // 6 > len(ref.t) - 1  # 6 per attempt: some attempts were rejected
        np.testing.assert_allclose(y, ref.y[:, -1], rtol=1e-12, atol=1e-15)


@numba_needed
def test_the_compiled_equations_are_the_python_equations_to_the_last_bit(eom: Any) -> None:
    """The generated qdd compiled by numba and run by CPython give the same bits at 20,000 random states and
    torques. Squares are written x*x: CPython's x**2 is the C library's pow, which differs from numba's x*x in
    the last bit for some x (8 of these states differed, and the combined task's two paths parted at 2.191 s)."""
    from legbench import jit

    compiled = jit.njit(eom.qdd)
    rng = np.random.default_rng(0)
    for a in rng.uniform(-3.0, 3.0, (20000, 9)).tolist():
        assert compiled(*a, G_EARTH) == eom.qdd(*a, G_EARTH), a


@numba_needed
def test_the_compiled_period_is_the_python_period(make: Any) -> None:
    """From the 200 pressed-foot states: the compiled period makes the same right-hand-side evaluations as the
    same code run as Python and ends within 1e-12 of it (measured: equal to the last bit)."""
    backend = make()
    assert backend.info()["kernel_used"] == "compiled (numba)"
    for x, u in _pressed_states(200):
        (yp, n_py), (yc, n_c) = _one_period(backend, False, x, u), _one_period(backend, True, x, u)
        assert n_c == n_py
        np.testing.assert_allclose(yc, yp, rtol=0, atol=1e-12)


@numba_needed
@pytest.mark.parametrize(("task", "duration"), [("position", None), ("effort", 1.0), ("combined", None)])
def test_compiled_period_agrees_with_the_python_path_over_each_task(task: str, duration: float | None) -> None:
    """The same task through the compiled period and the Python solve: joint angles within 1e-12 rad at every
    tick, speeds within 1e-9 rad/s, the ground force within 1e-9 N (measured: equal to the last bit; the
    effort task's touch-down and push, the combined task's step, swing and touch-down)."""
    sc = scenario.load(SCENARIOS / f"{task}.yaml")
    sc = sc if duration is None else scenario.shorten(sc, duration)
    physics = scenario.physics_of(sc)
    runs = []
    for kernel in ("python", "compiled"):
        be = registry.load("lagrange", physics, {**sc.backends.get("lagrange", {}), "kernel": kernel}, sc.profile)
        assert be.info()["kernel_used"].startswith(kernel)
        runs.append(run.simulate(sc, be, physics))
    a, b = runs
    assert a.status == b.status == "ok" and len(a.t) == len(b.t) == sc.n_ticks
    assert np.abs(a.q - b.q).max() <= 1e-12
    assert np.abs(a.qd - b.qd).max() <= 1e-9
    assert np.abs(a.f - b.f).max() <= 1e-9
    if task != "position":
        assert a.f[:, 2].max() > 5.0  # the contact was in it (combined: the touch-down at 1.139 s)


def test_kernel_falls_back_to_python_and_says_why(make: Any, monkeypatch: pytest.MonkeyPatch) -> None:
    """``kernel: python`` runs the Python solve silently; a missing numba runs it with a warning naming the fix;
    dop853 (solve_ivp) never uses the kernel, and its run.json does not list the setting."""
    assert make(kernel="python").info()["kernel_used"] == "python"
    assert make(kernel="python").warnings() == []
    dop = make(integrator="dop853")
    assert dop.info()["kernel_used"] == "python" and "kernel" not in dop.info()
    monkeypatch.setattr(lagrange_kernel, "available", lambda: False)
    be = make()
    assert be.info()["kernel_used"] == "python"
    assert any("numba is not installed" in w and "pip install numba" in w for w in be.warnings())


@numba_needed
def test_each_model_has_its_own_compiled_period(make: Any, tmp_path: Path) -> None:
    """The period is compiled per model (its key): a leg with link 2 1 % heavier gets another period, whose
    end state is its own Python period's (within 1e-12), not the first model's (which differs by far more)."""
    backend = make()
    chain = E.leg_chain(PARAMS)
    heavier = dataclasses.replace(chain.links[1], mass=chain.links[1].mass * 1.01)
    other = E.load_eom(dataclasses.replace(chain, links=(chain.links[0], heavier, chain.links[2])), tmp_path).module
    assert other.KEY != backend.eom.module.KEY
    first, second = (
        lagrange_kernel.period(backend.eom.module.KEY, backend._qdd),
        lagrange_kernel.period(other.KEY, other.qdd),
    )
    assert first is not second and first is lagrange_kernel.period(backend.eom.module.KEY, backend._qdd)
    x0 = np.array([0.1, -0.6, 1.2, 0.5, -0.3, 0.8])  # free swing: the masses alone set the motion
    u, g = np.zeros(3), backend.g
    rtol, atol, max_step = backend._tols
    ends = []
    for key, qdd, period in ((backend.eom.module.KEY, backend._qdd, first), (other.KEY, other.qdd, second)):
        x, y = x0.copy(), x0.copy()
        period(x, u, g, backend._lc, backend._lim, CONTROL_DT, rtol, atol, max_step, backend._k, ())
        python = lagrange_kernel.period(key, qdd, compiled=False)
        python(y, u, g, backend._lc, backend._lim, CONTROL_DT, rtol, atol, max_step, backend._k, ())
        np.testing.assert_allclose(x, y, rtol=0, atol=1e-12)
        ends.append(x)
    assert np.abs(ends[0] - ends[1]).max() > 1e-6


#: A process that loads the lagrange backend, runs one period and prints numba's (cache hits, misses) for it.
_CACHE_PROBE = """
import numpy as np
from legbench import model
from legbench.backends.base import Physics
from legbench.backends.lagrange_ import LagrangeBackend as L
be = L(); be.load(model.URDF_FILE, Physics(), L.resolve_settings({}, 'matched'))
be.reset(np.zeros(3), np.zeros(3)); be.step(np.zeros(3))
s = be._period.stats
print(sum(s.cache_hits.values()), sum(s.cache_misses.values()))
"""


@numba_needed
def test_the_compiled_period_is_loaded_from_numbas_cache_in_a_later_process(tmp_path: Path) -> None:
    """The period is compiled once per model and machine: a second process finds it in numba's disk cache (a
    hit, no compile), where a closure or a cache key that changed per process would compile it every time."""
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "numba"), "LEGBENCH_CACHE_DIR": str(tmp_path / "eom")}
    counts = []
    for _ in range(2):
        out = subprocess.run([sys.executable, "-c", _CACHE_PROBE], env=env, capture_output=True, text=True, check=True)
        counts.append(tuple(int(v) for v in out.stdout.split()))
    assert counts == [(0, 1), (1, 0)]  # (cache hits, misses): compiled in the first process, loaded in the second


_BLOW_UP = """
import numpy as np
from scipy.integrate import solve_ivp
from legbench.backends import dopri

def rhs(_lc, _lim, _u, _g, y, out, _data):
    out[0] = y[0] * y[0]

ref = solve_ivp(lambda _t, y: y * y, (0.0, 2.0), [1.0], method="RK45", rtol=1e-6, atol=1e-9)
y = np.array([1.0])
n = dopri.stepper(rhs)(y, None, 0.0, None, None, 2.0, 1e-6, 1e-9, np.inf, np.zeros((9, 1)), ())
print(ref.status, n, repr(float(ref.y[0, -1])), repr(float(y[0])), ref.t[-1])
"""


def test_the_stepper_gives_up_where_scipy_does_when_the_step_underflows() -> None:
    """y' = y^2, y(0) = 1 blows up at t = 1: scipy's RK45 stops there ("Required step size is less than spacing
    between numbers", status -1, at t just above 1); the stepper returns -1 at the same step: its y within 5 % of
    scipy's last y. Near the pole y grows 14-17 % per step, so a stop one step early or late misses by that much;
    scipy's own last y moves by up to 0.5 % with the BLAS kernel its RK stages are summed with (OpenBLAS's
    Haswell, SkylakeX and Prescott kernels: 6.8278e13, 6.8361e13, 6.7940e13; the stepper's sums, in plain
    Python, give 6.8278e13 under each of them), so bit-equality holds on some machines only. (In a subprocess
    with a generous time-out: a stepper that kept creeping by one ulp would not come back.)"""
    out = subprocess.run([sys.executable, "-c", _BLOW_UP], capture_output=True, text=True, check=True, timeout=120)
    status, n, y_ref, y, t_end = out.stdout.split()
    assert (status, n) == ("-1", "-1") and 1.0 < float(t_end) < 1.0 + 1e-3
    assert abs(float(y) / float(y_ref) - 1.0) < 0.05


def test_kernel_python_runs_the_python_period(make: Any) -> None:
    """``kernel: python`` really runs the period as Python (not the compiled one under another label)."""
    be = make(kernel="python")
    assert be._period is lagrange_kernel.period(be.eom.module.KEY, be._qdd, compiled=False)
    assert not hasattr(be._period, "stats")  # a plain function, not a numba dispatcher


@pytest.mark.parametrize("kernel", ["compiled", "python"])
def test_the_period_drives_a_joint_past_its_limit_as_solve_ivp_does(make: Any, kernel: str) -> None:
    """The limit law inside the period: the foot in the air, the knee 0.02 rad past its upper limit and moving out
    at 0.5 rad/s (tau_lim = -k 0.02 - b 0.5 = -210 N m; with k and b swapped it would be ~-5000 N m): one period
    makes solve_ivp(RK45)'s evaluations over the backend's rhs (the limit law object) and ends within 1e-12."""
    be = make(kernel=kernel)
    x0 = np.array([0.0, -0.3, be.upper[2] + 0.02, 0.0, 0.0, 0.5])
    assert be.law(*x0)[5] == 0.0  # the foot is off the ground: only the limit acts besides gravity
    be._u[:] = [0.0, 0.0, 0.0]
    rtol, atol, max_step = be._tols
    ref = solve_ivp(be.rhs, (0.0, CONTROL_DT), x0, method="RK45", rtol=rtol, atol=atol, max_step=max_step)
    y, n = _one_period(be, kernel == "compiled", x0, np.zeros(3))
    assert n == ref.nfev
    np.testing.assert_allclose(y, ref.y[:, -1], rtol=0, atol=1e-12)
    assert y[5] < 0.0  # the limit turned the knee back within the period


def test_a_step_size_underflow_is_a_clear_error(make: Any, monkeypatch: pytest.MonkeyPatch) -> None:
    """The period's -1 (step size below 10 ulp of t) becomes the backend's one-line error, as solve_ivp's failure."""
    be = make()
    be.reset(np.zeros(3), np.zeros(3))
    monkeypatch.setattr(be, "_period", lambda *_: -1)
    with pytest.raises(LegbenchError, match="rk45 failed: Required step size"):
        be.step(np.zeros(3))


@numba_needed
def test_an_edited_law_recompiles_the_cached_period(tmp_path: Path) -> None:
    """The cached period holds the contact law inlined: after an edit of legbench/contact.py (a comment appended,
    in a copy of the package) the next process misses numba's cache and compiles again (a hit would run the old
    law)."""
    pkg = tmp_path / "src"
    shutil.copytree(Path(lagrange_kernel.__file__).parents[1], pkg / "legbench",
                    ignore=shutil.ignore_patterns("__pycache__"))  # fmt: skip
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "numba"), "LEGBENCH_CACHE_DIR": str(tmp_path / "eom"),
           "PYTHONPATH": str(pkg)}  # fmt: skip
    counts = []
    for edit in (False, False, True):
        if edit:
            with (pkg / "legbench" / "contact.py").open("a") as f:
                f.write("\n# edited\n")
        out = subprocess.run([sys.executable, "-c", _CACHE_PROBE], env=env, capture_output=True, text=True, check=True,
                             cwd=tmp_path)  # fmt: skip
        counts.append(tuple(int(v) for v in out.stdout.split()))
    assert counts == [(0, 1), (1, 0), (0, 1)]  # compiled, loaded, compiled again after the edit


@pytest.mark.parametrize("where", ["int", "/dev/null", "file", "under-file", "run", "under-run"])
def test_a_cache_dir_that_cannot_hold_the_equations_is_refused_naming_the_key(tmp_path: Path, where: str,
                                                                               make: Any) -> None:  # fmt: skip
    """backends.lagrange.cache_dir was never checked: 5, /dev/null or an existing regular file passed validate and
    the run then failed (TypeError: expected str ... not int; exit 3). The loader refuses each naming the key
    (exit 2 before any work), and so does the backend's load (LegbenchError, not a TypeError); a directory not
    made yet passes. A run directory (or a folder in one) is refused too: the cache's file went among a finished
    run's, which `legbench run --force` then refused to replace as holding a file not legbench's (a review)."""
    file = tmp_path / "plain.txt"
    file.write_text("x")
    run = tmp_path / "finished"
    run.mkdir(exist_ok=True)
    (run / "run.json").write_text("{}")
    value: Any = {"int": 5, "/dev/null": "/dev/null", "file": str(file), "under-file": str(file / "sub"),
                  "run": str(run), "under-run": str(run / "eom")}[where]  # fmt: skip
    doc = {"name": "t", "duration": 1.0, "events": [{"t": 0.0, "position": {"joint": [0, 0, 0]}}]}
    with pytest.raises(ScenarioError) as err:
        scenario.parse({**doc, "backends": {"lagrange": {"cache_dir": value}}}, "s.yaml")
    assert err.value.key == "backends.lagrange.cache_dir" and "\n" not in str(err.value)
    with pytest.raises(LegbenchError, match=r"^backends\.lagrange\.cache_dir: "):
        make(cache_dir=value)
    assert scenario.parse({**doc, "backends": {"lagrange": {"cache_dir": str(tmp_path / "new" / "dir")}}})
    # beside a run, not in it (RUN/../x), is fine; a link into a run is in it
    assert scenario.parse({**doc, "backends": {"lagrange": {"cache_dir": str(run / ".." / "eom")}}})
    (tmp_path / "link").symlink_to(run)
    with pytest.raises(ScenarioError, match="is in the legbench run directory"):
        scenario.parse({**doc, "backends": {"lagrange": {"cache_dir": str(tmp_path / "link" / "eom")}}}, "s.yaml")


def test_a_cache_dir_with_a_tilde_is_under_the_home_directory(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, make: Any
) -> None:
    """cache_dir: ~/eom made a folder named '~' in the working directory; a leading ~ is now the home directory, as
    in the shell (the equations are loaded from HOME/eom), and a ~user naming no user is refused naming the key."""
    from legbench.backends import lagrange_

    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    monkeypatch.chdir(tmp_path)
    asked: list[Any] = []

    def load(chain: Any, cache_dir: Any = None) -> Any:
        asked.append(cache_dir)
        raise LegbenchError("stop after the cache directory is named")

    monkeypatch.setattr(lagrange_, "load_eom", load)
    with pytest.raises(LegbenchError, match="stop after"):
        make(cache_dir="~/eom")
    assert asked == [tmp_path / "home" / "eom"] and not (tmp_path / "~").exists()
    doc = {"name": "t", "duration": 1.0, "events": [{"t": 0.0, "position": {"joint": [0, 0, 0]}}]}
    with pytest.raises(ScenarioError) as err:
        scenario.parse({**doc, "backends": {"lagrange": {"cache_dir": "~no_such_user_0x4c/eom"}}}, "s.yaml")
    assert err.value.key == "backends.lagrange.cache_dir" and "\n" not in str(err.value)
