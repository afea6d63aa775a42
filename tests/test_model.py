"""The parameter file, the mass-property estimate and the generated URDF."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pybullet
import pytest

from legbench import model


def test_committed_urdf_is_the_generated_one() -> None:
    """models/leg.urdf must equal what `legbench model urdf` writes from models/leg.yaml."""
    assert model.URDF_FILE.read_text() == model.urdf_text(model.load_params())


def test_urdf_marks_the_hip_continuous_and_carries_the_foot_sphere() -> None:
    import yourdfpy

    robot = yourdfpy.URDF.load(str(model.URDF_FILE), load_meshes=False, build_scene_graph=False)
    assert robot.joint_map["q2_hip"].type == "continuous"
    assert robot.joint_map["q1_abad"].type == "revolute"
    assert robot.joint_map["q3_knee"].limit.upper == pytest.approx(2.229)
    foot = robot.link_map["foot"]
    (col,) = foot.collisions
    assert col.geometry.sphere.radius == pytest.approx(0.0225)
    np.testing.assert_allclose(col.origin[:3, 3], 0.0)  # sphere centre is the E frame


def test_urdf_is_plain_urdf_and_loads_in_mujoco_and_pybullet() -> None:
    """The generated URDF names no engine (MuJoCo's compiler options are its backend's business) and loads
    in MuJoCo as is (fusing the fixed foot into link 3) and with the backend's options (foot kept a body)."""
    import mujoco

    from legbench.backends.mujoco_ import urdf_with_compiler

    text = model.URDF_FILE.read_text()
    assert "<mujoco" not in text and "<gazebo" not in text and "<drake" not in text
    plain = mujoco.MjSpec.from_file(str(model.URDF_FILE)).compile()
    m = mujoco.MjSpec.from_string(urdf_with_compiler(model.URDF_FILE)).compile()
    assert plain.njnt == m.njnt == 3
    names = {mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, i) for i in range(m.nbody)}
    plain_names = {mujoco.mj_id2name(plain, mujoco.mjtObj.mjOBJ_BODY, i) for i in range(plain.nbody)}
    assert "foot" in names and "foot" not in plain_names  # a body of its own only with fusestatic="false"
    cid = pybullet.connect(pybullet.DIRECT)
    try:
        body = pybullet.loadURDF(
            str(model.URDF_FILE), useFixedBase=True, flags=pybullet.URDF_USE_INERTIA_FROM_FILE, physicsClientId=cid
        )
        assert pybullet.getNumJoints(body, physicsClientId=cid) == 4
    finally:
        pybullet.disconnect(cid)


def test_holed_sphere_mass_matches_the_napkin_ring_formula() -> None:
    """Volume of a sphere R with a through hole r: 4/3 pi (R^2 - r^2)^(3/2)."""
    R, r, rho = 0.0225, 0.01025, 2810.0
    inr = model.part_inertial({"shape": "sphere", "r": R, "hole_r": r, "axis": "x", "pos": [0, 0, 0]}, rho)
    assert inr.mass == pytest.approx(rho * 4 / 3 * np.pi * (R * R - r * r) ** 1.5, rel=1e-10)
    solid = model.part_inertial({"shape": "sphere", "r": R, "hole_r": 0.0, "pos": [0, 0, 0]}, rho)
    np.testing.assert_allclose(np.diag(solid.I), 0.4 * solid.mass * R * R, rtol=1e-10)


def test_parallel_axis_composition() -> None:
    a = model.Inertial(1.0, (0.1, 0.0, 0.0), ((0.0, 0, 0), (0, 0.0, 0), (0, 0, 0.0)))
    b = model.Inertial(1.0, (-0.1, 0.0, 0.0), ((0.0, 0, 0), (0, 0.0, 0), (0, 0, 0.0)))
    c = model.combine([a, b])
    assert c.mass == 2.0
    np.testing.assert_allclose(c.com, 0.0, atol=1e-15)
    np.testing.assert_allclose(np.diag(c.I), [0.0, 0.02, 0.02], atol=1e-15)


def test_products_of_inertia_keep_the_urdf_sign() -> None:
    """Point masses at (+x, +y) give I_xy = -sum m x y < 0 in the URDF convention."""
    pts = [model.Inertial(1.0, (0.1, 0.1, 0.0), ((0.0, 0, 0), (0, 0.0, 0), (0, 0, 0.0)))]
    pts.append(model.Inertial(1.0, (-0.1, -0.1, 0.0), pts[0].inertia))
    c = model.combine(pts)
    assert c.I[0, 1] == pytest.approx(-2 * 0.01)


def test_calibration_solve_reproduces_the_committed_factors() -> None:
    """The committed scale factors are what the 3x3 solve gives (1e-6)."""
    k = model.calibrate()
    p = model.load_params()
    for link in model.LINK_NAMES:
        assert k[link] == pytest.approx(p.scale[link], rel=1e-6)


def _cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "legbench.cli", *args], capture_output=True, text=True, check=False)


def test_cli_ik_json_lists_q_star() -> None:
    out = _cli("model", "ik", "0.1667", "0", "0.0225", "--json")
    assert out.returncode == 0, out.stderr
    sols = np.array(json.loads(out.stdout)["solutions"])
    assert np.abs(sols - [-0.0025, -1.1899, -1.2599]).max(axis=1).min() < 2e-3


def test_cli_fk_and_gravity_json() -> None:
    out = json.loads(_cli("model", "fk", "0", "0", "0", "--json").stdout)
    np.testing.assert_allclose(out["ee"], [0.16763, 0.55373, 0.4], atol=1e-12)
    tau = json.loads(_cli("model", "gravity", "-0.0025", "-1.1899", "-1.2599", "--json").stdout)["tau"]
    np.testing.assert_allclose(tau, [1.0426, 0.1631, -0.2984], atol=1e-6)


def test_cli_ik_unreachable_says_why() -> None:
    out = _cli("model", "ik", "2", "0", "0.4")
    assert out.returncode == 1
    assert "unreachable" in out.stdout


def test_cli_urdf_regenerates_identically(tmp_path) -> None:  # type: ignore[no-untyped-def]
    dest = tmp_path / "leg.urdf"
    out = _cli("model", "urdf", "--out", str(dest))
    assert out.returncode == 0, out.stderr
    assert dest.read_text() == model.URDF_FILE.read_text()


def test_cli_urdf_of_another_parameter_file_never_replaces_the_bundled_urdf(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """`legbench model urdf --params other.yaml` without --out writes the URDF where legbench reads that file's
    (the cache, urdf/other-<hash>.urdf), not the bundled model's models/leg.urdf (it did: the default was the
    active model's URDF whatever --params named). The source tree is moved to tmp_path, so nothing real is
    written either way."""
    from legbench import cli, resources

    tree = tmp_path / "tree"
    monkeypatch.setattr(resources, "source_tree", lambda: tree)
    monkeypatch.setenv(resources.CACHE_ENV, str(tmp_path / "cache"))
    monkeypatch.delenv(resources.MODEL_ENV, raising=False)
    other = tmp_path / "other.yaml"
    other.write_text(resources.bundled_model().read_text())
    assert cli.main(["model", "urdf", "--params", str(other)]) == 0
    assert not (tree / "models" / "leg.urdf").exists()
    (written,) = (tmp_path / "cache" / "urdf").glob("other-*.urdf")
    assert written == resources.urdf_target(other)
    assert written.read_text() == model.urdf_text(model.load_params(other))


def _leg_with(tmp_path: Path, key: str, value: str) -> Path:
    """The bundled parameter file with one ``geometry`` entry's value replaced by the YAML text ``value``."""
    import re

    from legbench import resources

    text, n = re.subn(rf"(\n  {key}:\s*)\S+", rf"\g<1>{value}", resources.bundled_model().read_text(), count=1)
    assert n == 1, key
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    return path


@pytest.mark.parametrize(
    ("key", "value", "words"),
    [
        ("H", ".nan", ": nan is not a finite number"),
        ("H", "-.inf", "-inf is not a finite number"),
        ("H", "-0.4", "-0.4 must be > 0 (the height of frame 0, the hip, above the ground"),
        ("H", "0", "0 must be > 0"),
        ("H", "1.0e300", "1e+300 is beyond +-1e+12"),
        ("L_B0", ".nan", "nan is not a finite number"),
        ("L_B0", ".inf", "inf is not a finite number"),
        ("L_B0", "1.0e300", "1e+300 is beyond"),
        ("L_01", ".nan", "nan is not a finite number"),
        ("L_01", "-.inf", "-inf is not a finite number"),
        ("L_01", "-1.0e300", "-1e+300 is beyond"),
        ("L_12", ".nan", "nan is not a finite number"),
        ("L_12", "0", "0 must be > 0 (a length"),
        ("L_23", ".inf", "inf is not a finite number"),
        ("L_3E", "-0.223", "-0.223 must be > 0 (a length"),
        ("R_foot", ".nan", "nan is not a finite number"),
    ],
)
def test_a_bad_geometry_entry_is_one_line_exit_2_and_no_urdf(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], key: str, value: str,
    words: str,
) -> None:  # fmt: skip
    """H, L_B0 and L_01 were not checked: NaN or inf went into the URDF (written to the cache, then Pinocchio's
    "does not contain a valid URDF model" traceback, exit 1), and a negative or zero H, or 1e300, was accepted (a
    negative H then blamed the scenario's initial.q). Every geometry entry is refused in one line naming the file
    and the key, exit 2, before any URDF is written."""
    from legbench import cli, resources

    cache = tmp_path / "cache"
    monkeypatch.setenv(resources.CACHE_ENV, str(cache))
    monkeypatch.delenv(resources.MODEL_ENV, raising=False)
    bad = _leg_with(tmp_path, key, value)
    try:
        for argv in (["model", "check"], ["validate", str(resources.scenario("effort"))]):
            assert cli.main(["--model", str(bad), *argv]) == 2
            err = capsys.readouterr().err
            assert err.startswith(f"legbench: error: {bad}: geometry.{key}: ") and err.count("\n") == 1, err
            assert words in err and "initial.q" not in err, err
    finally:
        resources.select_model(None)
    assert not cache.exists() or not any(cache.rglob("*")), sorted(cache.rglob("*"))


@pytest.mark.parametrize(("key", "value"), [("L_B0", "0"), ("L_B0", "-0.05555"), ("L_01", "0"), ("L_01", "-0.07763")])
def test_the_offsets_l_b0_and_l_01_may_be_zero_or_negative(tmp_path: Path, key: str, value: str) -> None:
    """L_B0 (x_W of frame 0) and L_01 (frame 1's offset along the ab/ad axis, which q1 turns about) place the leg,
    they do not shape it: 0 or a negative value is a leg moved along x_W or y_W, with the same G(q*)."""
    path = _leg_with(tmp_path, key, value)
    params = model.load_params(path)
    assert getattr(params.geometry, key) == float(value)
    urdf = model.write_urdf(params, tmp_path / "moved.urdf")
    q_star = np.array(params.q_star)
    np.testing.assert_allclose(model.gravity_torque(q_star, urdf=str(urdf)), model.gravity_torque(q_star), atol=1e-12)


@pytest.mark.parametrize(
    ("edit", "words"),
    [
        (lambda raw: raw["links"]["link1"]["parts"][0]["pos"].__setitem__(0, float("nan")),
         "links.link1.parts[0].pos[0]: nan is not a finite number"),
        (lambda raw: raw["links"]["link2"]["parts"][1].update(pos=[0.1, 0.0]),
         "links.link2.parts[1].pos: [0.1, 0.0] is not a position"),
        (lambda raw: raw["links"]["foot"]["parts"][0].update(hole_r=float("nan")),
         "links.foot.parts[0].hole_r: nan is not a finite number"),
        (lambda raw: raw["links"]["foot"]["parts"][0].update(hole_r=0.0225),
         "links.foot.parts[0].hole_r: 0.0225 must be in [0, r)"),
        (lambda raw: raw["collision"]["link2"].update(r=float("inf")), "collision.link2.r: inf is not a finite number"),
        (lambda raw: raw["collision"]["link3"].update(length=0.0), "collision.link3.length: 0.0 must be > 0"),
        (lambda raw: raw["collision"]["foot"].update(r=float("nan")), "collision.foot.r: nan is not a finite number"),
        (lambda raw: raw["collision"]["link2"]["pos"].__setitem__(2, float("-inf")),
         "collision.link2.pos[2]: -inf is not a finite number"),
        (lambda raw: raw["collision"].pop("foot"), "collision: "),
        (lambda raw: raw["calibration"]["q_star"].__setitem__(1, float("nan")),
         "calibration.q_star[1]: nan is not a finite number"),
        (lambda raw: raw["calibration"]["G_star"].__setitem__(0, float("inf")),
         "calibration.G_star[0]: inf is not a finite number"),
        (lambda raw: raw["calibration"].update(gravity=0.0), "calibration.gravity: 0.0 must be > 0"),
        (lambda raw: raw["geometry"].pop("H"), "geometry.H: missing"),
        (lambda raw: raw.update(geometry=[0.4]), "geometry: [0.4] is not a mapping"),
    ],
    ids=["part-pos-nan", "part-pos-short", "hole-nan", "hole-full", "coll-r-inf", "coll-length-0", "foot-r-nan",
         "coll-pos-inf", "no-foot", "q-star-nan", "g-star-inf", "gravity-0", "no-H", "geometry-list"],
)  # fmt: skip
def test_every_other_length_and_position_of_the_file_is_checked(edit: object, words: str) -> None:
    """The CAD parts' positions and the collision primitives' sizes and positions went into the URDF unchecked
    (NaN: a URDF no parser reads, or a NaN inertia), q* and G(q*) into `model check` as NaN, and gravity 0 made
    `model calibrate`'s solve singular (a LinAlgError traceback): each is one line naming the file and the key."""
    import copy
    import re

    from legbench.exceptions import ModelError

    raw = copy.deepcopy(model.load_raw())
    edit(raw)  # type: ignore[operator]
    with pytest.raises(ModelError, match=re.escape(f"p.yaml: {words}")):
        model.params_from_raw(raw, "p.yaml")


def test_model_check_with_a_zero_report_torque_says_inf_without_a_warning(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """A report G(q*) component of 0 (a valid file) printed numpy's divide-by-zero warning over two more lines of
    `model check`: the component's relative error is now inf (or 0 where the model's is 0 too), the check fails
    (exit 1: the model's 0.163 N m is not the report's 0), and stderr stays empty."""
    import re
    import warnings

    from legbench import cli, resources

    monkeypatch.setenv(resources.CACHE_ENV, str(tmp_path / "cache"))
    monkeypatch.delenv(resources.MODEL_ENV, raising=False)
    text, n = re.subn(r"G_star: \[1\.0426, 0\.1631,", "G_star: [1.0426, 0.0,", resources.bundled_model().read_text())
    assert n == 1
    path = tmp_path / "zero_g.yaml"
    path.write_text(text)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # a RuntimeWarning would fail the command
            assert cli.main(["--model", str(path), "model", "check"]) == 1
    finally:
        resources.select_model(None)
    out, err = capsys.readouterr()
    assert err == "" and "relative error per component: [" in out and "inf" in out, (out, err)


def test_an_edited_parameter_file_is_read_again_in_the_same_process(tmp_path: Path) -> None:
    """load_params was cached per path for the life of the process, while the URDF is read again on every call:
    a notebook that edited its leg file got engines on the new leg and the controllers and the lagrange model on
    the old one. It is now cached per path and the file's modification time, size and inode."""
    import os

    src = Path(model.PARAMS_FILE)
    mine = tmp_path / "leg.yaml"
    mine.write_bytes(src.read_bytes())
    before = model.load_params(mine)
    assert model.load_params(mine) is before  # unchanged: cached
    text = mine.read_text()
    assert "link2: 1.48493010," in text  # the mass scale of link 2 (models/leg.yaml)
    mine.write_text(text.replace("link2: 1.48493010,", "link2: 2.96986020,", 1))
    st = mine.stat()
    os.utime(mine, ns=(st.st_atime_ns, st.st_mtime_ns + 1_000_000))  # a later edit, whatever the clock's grain
    after = model.load_params(mine)
    assert after is not before
    assert after.scale["link2"] == pytest.approx(2.0 * before.scale["link2"], rel=1e-12)


def test_a_urdf_regenerated_in_place_is_a_new_reference_model(tmp_path: Path) -> None:
    """pinocchio_model was cached by path only: after `legbench model urdf` rewrote models/leg.urdf in place
    (what the out-of-date warning advises), Dynamics, kinematics and the verification's closed forms kept the
    old leg while the engines and load_params had the new one. The cache now holds the file's mtime, size and
    inode: the rewritten file (written atomically, a new inode) gives the new model."""
    urdf = tmp_path / "leg.urdf"
    urdf.write_text(model.urdf_text(model.load_params()))
    before = model.pinocchio_model(urdf)
    assert model.pinocchio_model(urdf) is before
    heavier = model.load_params()
    link2 = before.inertias[2].mass
    text = urdf.read_text()
    tmp = tmp_path / "new.urdf"
    tmp.write_text(text.replace(f'<mass value="{link2!r}"/>', f'<mass value="{2.0 * link2!r}"/>', 1))
    assert tmp.read_text() != text, "the link-2 mass element was not found"
    tmp.replace(urdf)
    after = model.pinocchio_model(urdf)
    assert after is not before and after.inertias[2].mass == pytest.approx(2.0 * link2, rel=1e-15)
    assert heavier is model.load_params()  # the parameter file itself did not change
