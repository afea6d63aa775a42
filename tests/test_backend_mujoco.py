"""The MuJoCo backend's hot path: the end-state ``mj_forward`` reused by the next period, bit-identical.

``force_readout: end`` needs one ``mj_forward`` at the end of each control period; the next
period's first sub-step then runs only the acceleration stage (``mj_forwardSkip``) and the
integrator. The log must be the one of plain ``mj_step`` calls, bit for bit. Also: what the
``last`` and ``mean`` read-outs hold with ``rk4`` (the 4th stage's solve).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

mujoco = pytest.importorskip("mujoco")

from legbench import backends as registry  # noqa: E402
from legbench import scenario  # noqa: E402
from legbench.backends.mujoco_ import MujocoBackend  # noqa: E402
from legbench.results import write_run  # noqa: E402
from legbench.run import simulate  # noqa: E402
from legbench.scenario import physics_of, shorten  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def _logs(task: str, duration: float, settings: dict[str, object]):  # type: ignore[no-untyped-def]
    sc = shorten(scenario.load(ROOT / "scenarios" / f"{task}.yaml"), duration)
    physics = physics_of(sc, None)
    out = []
    for plain in (False, True):
        backend = registry.load("mujoco", physics, {**sc.backends.get("mujoco", {}), **settings})
        try:
            if plain:
                backend._step = backend._step_native_plain  # type: ignore[attr-defined]
            out.append(simulate(sc, backend, physics))
        finally:
            backend.close()
    return out


@pytest.mark.parametrize(
    ("task", "duration", "settings"),
    [
        ("combined", 2.5, {}),  # touch-down at 1 s, push from 2 s: contacts appear and persist
        ("effort", 1.0, {"integrator": "implicitfast"}),
        ("effort", 0.3, {"integrator": "rk4"}),
    ],
)
def test_reused_stages_give_the_plain_mj_step_log_bit_for_bit(task: str, duration: float, settings: dict) -> None:  # type: ignore[type-arg]
    """q, qd and the ground force identical, not close: the skipped stages depend only on qpos and qvel,
    which the end-state ``mj_forward`` computed at the very same state."""
    fast, plain = _logs(task, duration, settings)
    assert fast.status == plain.status == "ok"
    assert np.max(fast.f[:, 2]) > 30.0  # [N]: in contact, so the constraint solve is exercised
    for a, b in ((fast.q, plain.q), (fast.qd, plain.qd), (fast.f, plain.f), (fast.tau, plain.tau)):
        assert np.array_equal(a, b)


@pytest.mark.parametrize(("profile", "readout"), [("matched", "end"), ("engine-defaults", "end"), ("matched", "mean")])
def test_cached_contact_frame_reads_the_force_of_the_general_read_out(profile: str, readout: str) -> None:
    """The force read with the ground contact's frame kept from the first contact equals the read-out that takes
    frame and geoms from MjData at every contact, over the combined task (touch-down, press, push).

    Same numbers in the same order of operations: measured bit-identical; 1e-12 N (at ~70 N) would allow a
    rounding, not a wrong frame or sign (those are off by the force itself). The engine-defaults profile has
    MuJoCo's pyramidal cone, where mj_contactForce converts the pyramid's rows.
    """
    sc = shorten(scenario.load(ROOT / "scenarios" / "combined.yaml"), 2.5)
    physics = physics_of(sc, None)
    logs = []
    for general in (False, True):
        backend = registry.load("mujoco", physics, {"force_readout": readout}, profile)
        try:
            if general:
                backend._contact_force = backend._contact_force_general  # type: ignore[attr-defined, method-assign]
            logs.append(simulate(sc, backend, physics))
        finally:
            backend.close()
    fast, general_log = logs
    assert np.max(fast.f[:, 2]) > 30.0  # [N]
    assert np.max(np.abs(fast.f - general_log.f)) <= 1e-12
    assert np.array_equal(fast.q, general_log.q)


@pytest.mark.parametrize("readout", ["last", "mean"])
def test_rk4_last_and_mean_read_the_last_stage_solve(readout: str) -> None:
    """With ``rk4`` the force ``mj_step`` leaves is its 4th stage's solve, not its start state's.

    ``mj_RungeKutta`` runs stages 2-4 with ``mj_forwardSkip`` and restores only qpos, qvel and act, so
    ``efc_force`` is that of the state x0 + h k3. Rebuilt here stage by stage on a second MjData: the
    backend's read equals the 4th stage's force (measured bit-identical, 7.706 N; 1e-9 allows a rounding)
    and differs from the start state's (8.947 N), so the test tells the two apart. One 1 ms sub-step.
    """
    physics = physics_of(scenario.load(ROOT / "scenarios" / "effort.yaml"), None)
    backend = registry.load("mujoco", physics, {"integrator": "rk4", "force_readout": readout, "dt": 1.0e-3})
    try:
        m = backend.model  # type: ignore[attr-defined]
        q0, qd0 = np.array([-0.0025, -1.1799, -1.2599]), np.array([0.0, -0.5, 0.3])
        tau = np.zeros(3)
        backend.reset(q0, qd0)
        fn_start = float(backend.ground_force()[2])
        backend.step(tau)
        fn_read = float(backend.ground_force()[2])

        d = mujoco.MjData(m)
        d.ctrl[:] = tau
        h = m.opt.timestep
        qvel: list[np.ndarray] = []
        qacc: list[np.ndarray] = []
        for i, a in enumerate((0.0, 0.5, 0.5, 1.0)):  # classical RK4: stage i at x0 + a h k_{i-1}
            d.qpos[:] = q0
            d.qvel[:] = qd0
            if i:
                mujoco.mj_integratePos(m, d.qpos, qvel[-1], a * h)
                d.qvel[:] = qd0 + a * h * qacc[-1]
            mujoco.mj_forward(m, d)
            qvel.append(d.qvel.copy())
            qacc.append(d.qacc.copy())
        f6, fn_stage4 = np.zeros(6), 0.0  # the 4th stage's normal force (contact frame: normal first)
        for c in range(d.ncon):
            mujoco.mj_contactForce(m, d, c, f6)
            fn_stage4 += f6[0]
    finally:
        backend.close()
    assert fn_start > 5.0  # [N]: in contact
    assert abs(fn_start - fn_stage4) > 0.5  # [N]: the stages differ enough to be told apart
    assert abs(fn_read - fn_stage4) <= 1e-9 * fn_stage4


def test_the_force_acts_halfway_through_the_penetration_as_info_declares(tmp_path: Path) -> None:
    """MuJoCo places a contact between the two surfaces (mjContact.pos), so its force acts, and its slip is
    taken, y/2 above the sphere's lowest point; info() declares that (contact.lift 0.5; 0 in reference contact,
    where legbench applies the law at its poc). Effort task, last 0.5 s: the statics at that point hold to round-off
    (measured 5e-13 N of 52.5), where at the true poc they are 0.2 % of Fn off (measured 0.10 N); the compare's
    force check and its metrics.json take the declared point."""
    from legbench import compare, metrics, run

    sc = scenario.load(ROOT / "scenarios" / "effort.yaml")
    tr = run.run_backend(sc, "mujoco")
    assert tr.status == "ok" and tr.info["contact"]["poc"] == "true" and tr.info["contact"]["lift"] == 0.5
    at_own = metrics.steady_state(tr, 0.5, "true", lift=0.5)
    at_poc = metrics.steady_state(tr, 0.5, "true")
    fn = float(at_own.force[2])
    assert fn > 50.0  # [N]: pressing
    assert np.abs(at_own.residual).max() < 1e-9 * fn
    assert np.abs(at_poc.residual).max() > 1e-3 * fn
    # the spec's check at the lowest point stays beside it, with the lever between the two
    assert at_own.analytic_lowest is not None and at_poc.analytic_lowest is None
    np.testing.assert_array_equal(at_own.analytic_lowest, at_poc.analytic_poc)
    ref = registry.load("mujoco", physics_of(sc, "reference"), {})
    try:
        assert ref.info()["contact"]["lift"] == 0.0
    finally:
        ref.close()
    write_run(sc, [tr], tmp_path)
    res = compare.compare(tmp_path)
    assert res.to_json()["backends"]["mujoco"]["contact_lift"] == 0.5
    (steady,) = res.steady
    np.testing.assert_array_equal(steady.residual, at_own.residual)
    shown = set(res.frame()["metric"])
    assert {"analytic_lowest", "lift_compensation"} <= shown
    assert res.residuals["mujoco"].angle_max < 1.0  # [deg]: at its own point the friction opposes the slip


def test_the_matched_solref_rests_on_kp_exactly() -> None:
    """At rest the contact row's force is aref / R, R = A (1 - d) / d with the impedance pinned at d = 1e-4: the
    solref -(Kp, Kd) A alone gave Kp / (1 - d), k eff 10001 N/m (a maintainer's review); with (1 - d) in the
    solref the calibration's rests give Kp to 1e-8 (measured 9999.99999999 N/m) and the pressing-in fit Kd to
    1e-5 (measured 99.99989 N s/m; the row's own acceleration takes about d of the moving force)."""
    from legbench.studies import calibrate_contact as cc

    row = cc.calibrate(None, ["mujoco"]).iloc[0]
    assert row.k_eff == pytest.approx(row.Kp, rel=1e-8), row.k_eff
    assert row.c_eff == pytest.approx(row.Kd, rel=1e-5), row.c_eff


@pytest.mark.parametrize(("impratio", "c_rel"), [(1.0, 1e-3), (10.0, 1e-2)])
def test_the_scaled_solref_gives_kp_and_kd_on_the_pyramidal_cone_too(
    tmp_path: Path, impratio: float, c_rel: float
) -> None:
    """The pyramid's rows share 2 (mu^2 / impratio) (1 + mu^2) times the elliptic normal row's regulariser, so the
    same solref made the foot 2.74 times stiffer on it at impratio 1 (measured 27,402 N/m for Kp 10,000), 27.4
    times at impratio 10; scaled back by that factor, the calibration push measures the elliptic cone's stiffness
    on the pyramid within 0.1 % (measured 10,001.06 and 10,001.2 against 10,001.0 N/m) and its damping within
    0.1 % at impratio 1, 1 % at 10 (94.22 and 95.08 against 94.27 N s/m)."""
    import yaml

    from legbench.studies import calibrate_contact as cc

    base = yaml.safe_load(Path(cc.SCENARIO).read_text())
    est = {}
    for cone, friction in (("elliptic", "deadbeat"), ("pyramidal", "contact")):
        path = tmp_path / f"{cone}.yaml"
        settings = {"cone": cone, "friction_solref": friction, "force_readout": "mean", "impratio": impratio}
        path.write_text(yaml.safe_dump({**base, "backends": {"mujoco": settings}}))
        log, saturated = cc.push("mujoco", cc.Program(), path)
        est[cone] = cc.estimate(log, cc.Program(), scenario.load(path).contact, saturated)
    assert est["elliptic"].k_eff == pytest.approx(scenario.load(path).contact.Kp, rel=1e-3)
    assert est["pyramidal"].k_eff == pytest.approx(est["elliptic"].k_eff, rel=1e-3)
    assert est["pyramidal"].c_eff == pytest.approx(est["elliptic"].c_eff, rel=c_rel)


def test_deadbeat_friction_on_the_pyramidal_cone_is_refused() -> None:
    """MuJoCo applies solreffriction to an elliptic cone's friction rows only: on the pyramid the deadbeat
    reference was dropped without a word (bit-identical to friction_solref: contact). The scenario loader and
    the backend's load refuse the pair in native contact, naming the key the scenario gave (the cone, or the
    friction reference where the profile gave the cone); reference contact (no engine contact) and the pyramid
    with the contact's own friction reference load."""
    from legbench.exceptions import LegbenchError, ScenarioError

    sc = ROOT / "scenarios" / "effort.yaml"
    with pytest.raises(ScenarioError, match=r"backends\.mujoco\.cone: cone 'pyramidal' ignores friction_solref"):
        scenario.load(sc, {"backends.mujoco.cone": "pyramidal"})
    with pytest.raises(ScenarioError, match=r"backends\.mujoco\.friction_solref: cone 'pyramidal' ignores"):
        scenario.load(sc, {"profile": "engine-defaults", "backends.mujoco.friction_solref": "deadbeat"})
    physics = physics_of(scenario.load(sc), None)
    with pytest.raises(LegbenchError, match=r"^backends\.mujoco\.cone: cone 'pyramidal' ignores"):
        registry.load("mujoco", physics, {"cone": "pyramidal"})
    for mode, settings in (("reference", {"cone": "pyramidal"}), (None, {"cone": "pyramidal", "friction_solref":
                                                                              "contact"})):  # fmt: skip
        registry.load("mujoco", physics_of(scenario.load(sc), mode), settings).close()


def test_info_lists_only_settings_that_acted_and_the_compiler_options() -> None:
    """engine-defaults runs without noslip (opt.noslip_iterations 0): the settings table showed
    ``noslip_iterations 10`` beside ``noslip false``, read as noslip on. info() leaves out what the load does not
    read (as Drake's does) and records the URDF compiler options it loaded: fusestatic="false", where MuJoCo's URDF
    default is "true", sets the foot body's inverse weight (2.2101 1/kg; fused into link 3, 0.8431) that the
    engine-defaults raw solref is per unit of; and opt.disableflags by name (mjDSBL_AUTORESET, where MuJoCo's
    default is none), which engine-defaults did not list among what departs from MuJoCo's defaults."""
    sc = scenario.load(ROOT / "scenarios" / "effort.yaml")
    for profile in ("matched", "engine-defaults"):
        backend = registry.load("mujoco", physics_of(sc, "native"), {}, profile)
        try:
            assert isinstance(backend, MujocoBackend)
            info, m = backend.info(), backend.model
            assert info.get("noslip_iterations", 0) == m.opt.noslip_iterations
            assert "reference_friction" not in info  # native contact: the law is not applied
            assert info["compiler"]["fusestatic"] == "false" and info["compiler"]["urdf_default_fusestatic"] == "true"
            assert m.body("foot").id != m.body("link3").id  # the foot not fused, as the info says
            # opt.disableflags by name: mjDSBL_AUTORESET, not MuJoCo's default (none), in both profiles
            assert info["disableflags"] == ["mjDSBL_AUTORESET"]
            assert m.opt.disableflags == int(mujoco.mjtDisableBit.mjDSBL_AUTORESET)
        finally:
            backend.close()


def test_the_pyramidal_cone_is_recorded_as_the_diamond_it_is() -> None:
    """MuJoCo's pyramidal cone has the edges n +- mu t_i (engine_core_constraint.c), so it bounds |F_t1| + |F_t2| by
    mu Fn: a diamond, not the axis-by-axis pyramid of ODE's and DART's Dantzig (whose bounds the report held it to,
    when it held it to any). Dragged along W y with 0.8 Fn (mu 0.7), it slides with |F_x| + |F_y| = 0.700 Fn and
    |F_t| = 0.608 Fn (a cone: 0.700 Fn); info() records 'diamond', and 'cone' for the elliptic cone. The slip
    across the drag chatters about zero (+-0.4 mm/s under 0.5-0.7 m/s along it): a sample whose |v_x| falls inside
    the soft rows' band (measured: the window's off-vertex samples at 0.008 and 0.000 mm/s, every sample at 0.07 mm/s
    or more on the vertex) has its F_x between the two vertices, so the vertex is held where |v_x| > 0.01 mm/s,
    to 1e-3 (measured: exact to round-off), at all but 10 % of the window's samples."""
    from legbench import kinematics
    from legbench.backends.base import contact_point
    from legbench.studies import sliding_case as S

    for cone, shape in (("pyramidal", "diamond"), ("elliptic", "cone")):
        tr, _ = S.drag("mujoco", settings={"cone": cone, "friction_solref": "contact"})
        assert tr.info["friction_cone"] == shape
        k = (tr.t >= S.WINDOW[0]) & (tr.t <= S.WINDOW[1]) & (tr.f[:, 2] > S.FN_MIN)
        f = tr.f[k]
        l1, l2 = (np.abs(f[:, 0]) + np.abs(f[:, 1])) / f[:, 2], np.hypot(f[:, 0], f[:, 1]) / f[:, 2]
        if shape == "diamond":
            J = kinematics.jacobian_at(tr.q[k], *contact_point(tr.info, "true"))  # where its force acts
            vx = np.einsum("nj,nj->n", J[:, 0, :], tr.qd[k])
            band = np.abs(vx) <= 1e-5  # [m/s]
            assert band.mean() <= 0.1, band.sum()
            assert np.abs(l1[~band] - 0.7).max() < 1e-3 and l2.mean() < 0.65, (l1, l2.mean())
        else:
            assert abs(l2.mean() - 0.7) < 2e-3, l2.mean()


@pytest.mark.parametrize(("cone", "impratio"), [("pyramidal", 1.0), ("pyramidal", 10.0), ("elliptic", 10.0)])
def test_the_usual_solref_closed_forms_meet_mujocos_own_rows(cone: str, impratio: float) -> None:
    """``usual_rest_depth`` and ``usual_creep`` against MuJoCo's own constraint rows, engine-defaults (raw solref,
    default impedance) at impratio 1 and 10.

    At rest (qvel 0, so J qacc = 0 in the steady state) each row's force is efc_aref / efc_R; the rows' normal
    forces add up to Fn (the pyramid's four n +- mu t_i rows each carry 1 of the normal; the elliptic cone's normal
    row alone). With the foot 0.42 mm deep (the effort task's rest), the closed form's depth for that Fn is the
    pose's: measured <= 4e-16 relative at every impratio, held to 1e-9. It fails with the pyramid's R taken without
    impratio (MuJoCo: R[1] = R[0] / impratio, R_py = 2 mu^2 / impratio R[0]): 10 times too soft at impratio 10, y
    2.38 mm instead of 0.42. The creep: with the contact slipping along t1 at 20 mm/s, usual_creep of the rows'
    Fn and Ft = mu (f_+ - f_-) is the rows' own slip (efc_vel_+ - efc_vel_-) / (2 mu): measured 2e-16, held to
    1e-9 (at impratio 10 it was 5.9 times the slip, through the wrong y)."""
    from legbench import kinematics
    from legbench.backends.mujoco_ import usual_creep, usual_rest_depth
    from legbench.model import load_params

    sc = scenario.load(ROOT / "scenarios" / "effort.yaml")
    p = load_params()
    q_star = np.asarray(p.q_star, float)
    e, y0 = kinematics.fk(q_star), 4.2e-4  # [m], [m]
    q = kinematics.ik_nearest(np.array([e[0], e[1], p.geometry.R_foot - y0]), q_star)
    backend = registry.load("mujoco", physics_of(sc, "native"), {"cone": cone, "impratio": impratio},
                            "engine-defaults")  # fmt: skip
    try:
        assert isinstance(backend, MujocoBackend)
        m, d, contact = backend.model, backend.data, backend.info()["contact"]
        assert contact["impratio"] == impratio and contact["cone"] == f"mjCONE_{cone.upper()}"
        d.qpos[:], d.qvel[:] = q, 0.0
        mujoco.mj_forward(m, d)
        assert d.ncon == 1
        n = d.nefc
        f = d.efc_aref[:n] / d.efc_R[:n]  # [N]: each row's steady force
        fn = float(f.sum()) if cone == "pyramidal" else float(f[0])
        y = -float(d.efc_pos[0])  # [m]
        assert y == pytest.approx(y0, rel=1e-9)
        y_closed, k_closed = usual_rest_depth(contact, fn)
        assert y_closed == pytest.approx(y, rel=1e-9)
        assert k_closed == pytest.approx(fn / y, rel=1e-9)  # [N/m]
        if cone == "pyramidal":
            mu = float(contact["friction"][0])
            site = m.site("E").id
            jac = np.zeros((3, m.nv))
            mujoco.mj_jacSite(m, d, jac, None, site)
            t1 = np.asarray(backend._axes[0], float)  # type: ignore[index]
            d.qvel[:] = np.linalg.lstsq(jac, 0.02 * t1, rcond=None)[0]  # the foot centre at 20 mm/s along t1
            mujoco.mj_forward(m, d)
            f = d.efc_aref[:n] / d.efc_R[:n]
            slip = float(d.efc_vel[0] - d.efc_vel[1]) / (2.0 * mu)  # [m/s]: the contact point along t1
            assert slip > 0.01
            ft = mu * float(f[0] - f[1])  # [N]: against the slip
            assert ft < 0.0
            assert usual_creep(contact, float(f.sum()), -ft) == pytest.approx(slip, rel=1e-9)
    finally:
        backend.close()


@pytest.mark.parametrize(
    ("settings", "k40"),
    [({}, 1.264e5), ({"impratio": 10.0, "dt": 5.0e-5, "force_readout": "mean"}, 1.114e6)],
)
def test_the_raw_solref_note_gives_the_stiffness_measured_at_rest(
    tmp_path: Path, settings: dict[str, float], k40: float
) -> None:
    """engine-defaults gives Kp, Kd to solref as (-Kp, -Kd), which are not N/m and N s/m in MuJoCo; info() said
    contact.Kp 10000 (the report's settings table: [N/m]) with nothing beside it. Its contact.Kp_Kd_note says so
    and gives the stiffness at rest MuJoCo has, computed from the loaded model, here held to the calibration's two
    rests (20 and 40 N under the effort controller, means over 0.2 s): the model's closed form at the measured Fn
    within 1e-6 of the measured Fn / y (measured 1e-8 and 1.6e-9 at impratio 1: 115,448.59 and 126,389.75 N/m;
    3.3e-9 at impratio 10, 1.114e6 N/m at 40 N, where the formula without impratio said 1.114e5), and the note's
    4-digit numbers are the measured ones rounded. Impratio 10 at 50 us: at the profile's 1 ms step its tenfold
    stiffer pyramid chatters (std of Fn 6.7 N), no rest. The matched profile's scaled solref gives Kp in N/m: no
    note."""
    import yaml

    from legbench import kinematics
    from legbench.backends.mujoco_ import usual_rest_depth
    from legbench.model import load_params
    from legbench.studies import calibrate_contact as cc

    path = tmp_path / "push.yaml"
    base = yaml.safe_load(Path(cc.SCENARIO).read_text())
    path.write_text(yaml.safe_dump({**base, "backends": {"mujoco": {"cone": "pyramidal", "friction_solref":
                                                                    "contact", **settings}}}))  # fmt: skip
    program = cc.Program()
    log, saturated = cc.push("mujoco", program, path, profile="engine-defaults")
    assert saturated == 0
    contact = log.info["contact"]
    assert contact["impratio"] == settings.get("impratio", 1.0)
    note = contact["Kp_Kd_note"]
    assert "not its stiffness" in note
    y = load_params().geometry.R_foot - kinematics.fk(log.q)[:, 2]
    for end, load in ((program.phase, program.F1), (2 * program.phase, program.F2)):
        w = (log.t > end - 1e-3 - program.window - 1e-9) & (log.t <= end - 1e-3 + 1e-9)
        fn, depth = float(log.f[w, 2].mean()), float(y[w].mean())
        assert fn == pytest.approx(load, rel=1e-6)  # [N]: at rest under h_d
        k = fn / depth  # [N/m]
        assert k > 10.0 * contact["Kp"]  # not Kp: 11-13 times it at impratio 1
        assert usual_rest_depth(contact, fn)[1] == pytest.approx(k, rel=1e-6)
        assert f"{k:.4g} N/m at {load:g} N" in note
    assert f"{k40:.4g} N/m at 40 N" in note
    matched = registry.load("mujoco", physics_of(scenario.load(cc.SCENARIO), "native"), {}, "matched")
    try:
        assert "Kp_Kd_note" not in matched.info()["contact"]
    finally:
        matched.close()


def test_the_hop_explains_the_sliding_row_only_where_its_closed_form_meets_it(monkeypatch: pytest.MonkeyPatch) -> None:
    """base.py's contract: an explanation holds the row's own measured value to a closed form. The engine-defaults
    drag's note was a fixed text ('Fn 0 at 4 of 51 samples', 'mean +20 m/s^2') returned for any failing value
    (0.13 or -40 alike). The sliding case now scores only central differences whose stencil is in contact and counts
    the samples out of contact (4 of 51 here); the row still misses the closed form at k (measured -3.978 against
    -3.609 m/s^2), and MuJoCo's step applying the force read at its start gives the central difference's closed form
    as the mean over its two steps (-3.966, 0.31 %): said there, with the counts the run measured, and nowhere
    else."""
    from legbench.studies import sliding_case as S

    asked: dict[str, object] = {}
    real = S.explained_note

    def spy(cls: type, case: str, quantity: str, info: object, *rest: object) -> str:
        asked[quantity] = info
        return real(cls, case, quantity, info, *rest)  # type: ignore[arg-type]

    monkeypatch.setattr(S, "explained_note", spy)
    tr, physics = S.drag("mujoco", "engine-defaults")
    *_, row = S.score(tr, physics)
    info = asked[row["quantity"]]
    assert isinstance(info, dict)
    drag = info["drag"]
    assert row["out_of_contact"] == drag["out_of_contact"] >= 2 and row["window_samples"] == 51
    on = tr.f[:, 2] > S.FN_MIN
    k = np.flatnonzero((tr.t >= S.WINDOW[0] - 1e-9) & (tr.t <= S.WINDOW[1] + 1e-9))
    assert row["out_of_contact"] == int((~on[k]).sum())
    assert row["acceleration_samples"] == int((on[k - 1] & on[k] & on[k + 1]).sum()) < 51 - row["out_of_contact"]
    assert not row["passed"] and abs(row["measured"] - drag["over_steps"]) <= row["tolerance"], (row, drag)
    assert row["note"].startswith("known: ") and "hops" in row["note"] and "met to" in row["note"], row["note"]
    assert f"out of contact at {row['out_of_contact']} of the window's 51 samples" in row["note"]
    ask, q = MujocoBackend.known_deviation, row["quantity"]
    args = (row["expected"], row["tolerance"])
    assert ask("sliding", q, info, row["measured"], *args) is not None
    for far in (0.13, -40.0, row["expected"]):
        assert ask("sliding", q, info, far, *args) is None, far
    # nothing measured (the old fixed text's case): nothing said
    bare = {k: v for k, v in info.items() if k != "drag"}
    assert ask("sliding", q, bare, row["measured"], *args) is None
