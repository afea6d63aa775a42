"""The parameter file, the mass-property estimate and the generated URDF."""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

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


def test_holed_sphere_inertia_matches_a_quadrature_over_the_napkin_ring() -> None:
    """The foot of models/leg.yaml, an al7075 sphere R = 22.5 mm with a 20.5 mm bore along x: its central inertia
    equals the integral over the solid by numerical quadrature (scipy dblquad, relative error estimate below
    1e-12) in cylindrical coordinates about the bore, s from the bore's radius r to sqrt(R^2 - x^2), |x| <= h =
    sqrt(R^2 - r^2), dm = rho 2 pi s ds dx: I_xx = int s^2 dm = 2.5116e-5 kg m^2 about the bore, I_yy = I_zz =
    int (s^2 / 2 + x^2) dm = 2.0147e-5 kg m^2 across it (a ring of radius s puts s^2 / 2 on each transverse axis),
    to 1e-9 relative. A Monte Carlo estimate gave 2.5125e-5 / 2.0146e-5. R^4 + r^4 for R^4 - r^4 in the closed
    form would read I_xx 15.5 % high."""
    from scipy import integrate

    raw = model.load_raw()
    part = raw["links"]["foot"]["parts"][0]
    assert part["shape"] == "sphere" and part["axis"] == "x"
    R, r, rho = part["r"], part["hole_r"], raw["materials"][part["material"]]
    assert (R, r, rho) == (0.0225, 0.01025, 2810.0)
    h = np.sqrt(R * R - r * r)

    def integral(f: Callable[[float, float], float]) -> float:
        value, _ = integrate.dblquad(lambda s, x: rho * 2 * np.pi * s * f(s, x), -h, h, r,
                                     lambda x: np.sqrt(R * R - x * x), epsabs=0.0, epsrel=1e-12)  # fmt: skip
        return float(value)

    i_axis = integral(lambda s, x: s * s)
    i_trans = integral(lambda s, x: s * s / 2 + x * x)
    assert i_axis == pytest.approx(2.5116e-5, rel=1e-4) and i_trans == pytest.approx(2.0147e-5, rel=1e-4)
    inr = model.part_inertial(part, rho)
    assert inr.mass == pytest.approx(integral(lambda s, x: 1.0), rel=1e-9)
    np.testing.assert_allclose(np.diag(inr.I), [i_axis, i_trans, i_trans], rtol=1e-9)
    np.testing.assert_allclose(inr.I - np.diag(np.diag(inr.I)), 0.0, atol=0.0)  # principal axes: the bore's


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
        (lambda raw: raw["collision"].pop("foot"), "collision.foot: missing (the foot's collision sphere"),
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


def _edited(tmp_path: Path, pattern: str, new: str, name: str = "bad.yaml") -> Path:
    """The bundled parameter file with the first match of the regex ``pattern`` replaced by ``new``."""
    import re

    from legbench import resources

    text, n = re.subn(pattern, new, resources.bundled_model().read_text(), count=1, flags=re.DOTALL)
    assert n == 1, pattern
    path = tmp_path / name
    path.write_text(text)
    return path


_BODIES_HAVE_PARTS = "missing (the leg's bodies link1, link2, link3 and foot each have their parts)"
_JOINT_ORDER = "the joints are q1_abad (revolute), q2_hip (continuous), q3_knee (revolute)"


@pytest.mark.parametrize(
    ("pattern", "new", "message"),
    [
        (r"  link3:   # shank.*?\n(?=  foot:)", "", f"links.link3: {_BODIES_HAVE_PARTS}"),
        (r"  link1:   # ab/ad.*?\n(?=  link2:)", "", f"links.link1: {_BODIES_HAVE_PARTS}"),
        (r"  foot:    # fixed.*?\n(?=\n# Calibration)", "", f"links.foot: {_BODIES_HAVE_PARTS}"),
        ("name: q2_hip", "name: q1_abad",
         f"joints[1].name: 'q1_abad' is not unique (joints[0].name too): {_JOINT_ORDER}"),
        ("shape: sphere, r: 0.0225, hole_r", "shape: cone, r: 0.0225, hole_r",
         "links.foot.parts[0].shape: unknown shape 'cone' (known: box, tube, cylinder, sphere)"),
        (r"(  link2:[^\n]*\n    parts:)\n.*?\n(?=  link3:)", r"\1 []\n",
         "links.link2.parts: expected a non-empty list of parts, got []"),
        (r"(  link2:[^\n]*\n    parts:)\n.*?\n(?=  link3:)", r"\1 5\n",
         "links.link2.parts: expected a non-empty list of parts, got 5"),
        ("length: 0.105, axis: x", "length: 0.105, axis: w",
         "links.link2.parts[1].axis: expected one of x, y, z, got 'w'"),
        ("material: cfrp, shape: tube, r_out: 0.019, r_in: 0.017, length: 0.105",
         "material: unobtainium, shape: tube, r_out: 0.019, r_in: 0.017, length: 0.105",
         "links.link2.parts[1].material: unknown material 'unobtainium' (known: al7075, cfrp)"),
        ("link3: 1.27669764}", "link3: 1.27669764, linkX: 1.0}",
         "calibration.scale.linkX: unknown key (known: link1, link2, link3; the foot is scaled with link3)"),
    ],
    ids=["no-link3", "no-link1", "no-foot", "same-joint-name", "cone", "parts-empty", "parts-5", "axis-w",
         "unobtainium", "scale-linkX"],
)  # fmt: skip
def test_a_malformed_parameter_file_is_one_line_naming_it_and_the_key(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], pattern: str, new: str,
    message: str,
) -> None:  # fmt: skip
    """The error audit's leg files: a body deleted from `links` (a KeyError traceback out of the URDF writer, exit 1,
    and in `legbench run` the parity check's "pinocchio failed to load: KeyError: 'link3'"), two joints of one name
    (urdfdom's "not unique" and a ValueError traceback), a part of an unknown shape (the error named the bundled
    leg.yaml, not the file read), `parts: []` (numpy's RuntimeWarning, then "'float' object is not iterable"),
    `parts: 5`, `axis: w` ("substring not found"), an unknown material ("missing or malformed entry:
    'unobtainium'") and an unknown link's scale factor (accepted silently). Each is now one line naming the file
    given, the key path and what was expected, exit 2, with no warning, before any URDF is written."""
    import warnings

    from legbench import cli, resources

    cache = tmp_path / "cache"
    monkeypatch.setenv(resources.CACHE_ENV, str(cache))
    monkeypatch.delenv(resources.MODEL_ENV, raising=False)
    bad = _edited(tmp_path, pattern, new)
    out = tmp_path / "x.urdf"
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # a RuntimeWarning fails the command
            for argv in (["model", "check"], ["model", "urdf", "--out", str(out)]):
                assert cli.main(["--model", str(bad), *argv]) == 2
                assert capsys.readouterr().err == f"legbench: error: {bad}: {message}\n"
            assert cli.main(["model", "calibrate", "--params", str(bad)]) == 2  # named "leg parameters" before
            assert capsys.readouterr().err == f"legbench: error: {bad}: {message}\n"
    finally:
        resources.select_model(None)
    assert not out.exists()
    assert not cache.exists() or not any(cache.rglob("*")), sorted(cache.rglob("*"))


def test_a_run_with_a_malformed_model_stops_before_any_backend_loads(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """LEGBENCH_MODEL naming a file without link3: `legbench run` reported it as the parity check's "pinocchio
    failed to load: KeyError: 'link3'". It is the reader's one line, exit 2, and no run directory."""
    from legbench import cli, resources

    monkeypatch.setenv(resources.CACHE_ENV, str(tmp_path / "cache"))
    bad = _edited(tmp_path, r"  link3:   # shank.*?\n(?=  foot:)", "")
    monkeypatch.setenv(resources.MODEL_ENV, str(bad))
    out = tmp_path / "out"
    argv = ["run", str(resources.scenario("effort")), "--backends", "pinocchio", "--out", str(out)]
    assert cli.main(argv) == 2
    assert capsys.readouterr().err == f"legbench: error: {bad}: links.link3: {_BODIES_HAVE_PARTS}\n"
    assert not out.exists()


_SECTIONS = "a leg parameter file has geometry, joints, materials, links, calibration, collision, contact"
_TUBE = "material, shape, pos, r_out, r_in, length, axis"


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda raw: raw.update(bogus=1), f"bogus: unknown section ({_SECTIONS})"),
        (lambda raw: raw["contact"].update(restitution=-3.0), "contact.restitution: -3.0 must be >= 0 (a negative "
         "restitution)"),  # it read "(negative damping, stiffness or friction)"
        (lambda raw: raw["contact"].update(Kd=-1.0), "contact.Kd: -1.0 must be >= 0 (a negative damping)"),
        (lambda raw: raw.pop("contact"), f"contact: missing ({_SECTIONS})"),
        (lambda raw: raw.update(joints={"q1_abad": 1}),
         "joints: {'q1_abad': 1} is not a list of the leg's three joints: q1_abad (revolute), q2_hip (continuous), "
         "q3_knee (revolute)"),
        (lambda raw: raw["joints"].__setitem__(0, "q1_abad"),
         "joints[0]: 'q1_abad' is not a joint (a mapping: name, type, reduction, effort, velocity, and lower, upper if "
         "revolute)"),
        (lambda raw: raw["joints"][2].pop("type"), "joints[2].type: missing (the knee joint is revolute)"),
        (lambda raw: raw["joints"][1].update(type="revolute", lower=-3.0, upper=3.0),
         f"joints[1].type: 'revolute' is not the hip joint's type: {_JOINT_ORDER}"),
        (lambda raw: raw["joints"][2].update(type="continuous"),
         f"joints[2].type: 'continuous' is not the knee joint's type: {_JOINT_ORDER}"),
        (lambda raw: raw["joints"][2].update(name="knee"),
         f"joints[2].name: 'knee' is not the knee joint's name: {_JOINT_ORDER}"),
        (lambda raw: raw["joints"][0].pop("effort"),
         "joints[0].effort: missing (required: name, type, lower, upper, reduction, effort, velocity)"),
        (lambda raw: raw["joints"][0].update(damping=0.1),
         "joints[0].damping: unknown key (known: name, type, lower, upper, reduction, effort, velocity)"),
        (lambda raw: raw["joints"][1].update(lower=-1.0),
         "joints[1].lower: a continuous joint has no position limits (lower, upper: revolute only)"),
        (lambda raw: raw["joints"][0].update(effort="7"), "joints[0].effort: '7' is not a finite number"),
        (lambda raw: raw["joints"][2].update(velocity=0), "joints[2].velocity: 0 must be > 0"),
        (lambda raw: raw["geometry"].update(H=10**400),
         f"geometry.H: 1{'0' * 56}... is not a finite number (too large for a float)"),  # cut to 60 characters
        (lambda raw: raw.update(materials=["al7075"]),
         "materials: ['al7075'] is not a mapping of material names to densities [kg/m^3]"),
        (lambda raw: raw.update(links=[{"parts": []}] * 9),
         f"links: {str([{'parts': []}] * 9)[:57]}... is not a mapping of the leg's bodies (link1, link2, link3, foot) "
         "to their parts"),
        (lambda raw: raw["links"].update(link4=raw["links"]["link3"]),
         "links.link4: not a body of the leg (the leg's bodies link1, link2, link3 and foot each have their parts)"),
        (lambda raw: raw["links"].update(link1=[]), "links.link1: [] is not a body (a mapping with its list of parts)"),
        (lambda raw: raw["links"]["link1"].update(mass=1.0), "links.link1.mass: unknown key (known: parts)"),
        (lambda raw: raw["links"]["link2"]["parts"].__setitem__(0, "hip_flange"),
         "links.link2.parts[0]: 'hip_flange' is not a part (a mapping: name, material, shape, pos and the shape's "
         "sizes)"),
        (lambda raw: raw["links"]["link2"]["parts"][0].pop("shape"),
         "links.link2.parts[0].shape: missing (one of box, tube, cylinder, sphere)"),
        (lambda raw: raw["links"]["link2"]["parts"][0].update(shape=["box"]),
         "links.link2.parts[0].shape: unknown shape ['box'] (known: box, tube, cylinder, sphere)"),
        (lambda raw: raw["links"]["link2"]["parts"][1].pop("r_in"),
         f"links.link2.parts[1].r_in: missing (required: {_TUBE})"),
        (lambda raw: raw["links"]["link1"]["parts"][0].update(r=0.1),
         "links.link1.parts[0].r: unknown key of a box (known: name, material, shape, pos, size)"),
        (lambda raw: raw["links"]["link1"]["parts"][0].update(size=0.06),
         "links.link1.parts[0].size: 0.06 is not a size (a list of three lengths [m])"),
        (lambda raw: raw["links"]["link1"]["parts"][0]["size"].__setitem__(1, 0),
         "links.link1.parts[0].size[1]: 0 must be > 0"),
        (lambda raw: raw["links"]["link2"]["parts"][2].update(name="hip_flange"),
         "links.link2.parts[2].name: 'hip_flange' is not unique (links.link2.parts[0].name too)"),
        (lambda raw: raw["links"]["link2"]["parts"][2].update(name=3),
         "links.link2.parts[2].name: 3 is not a name (a string)"),
        (lambda raw: raw["links"]["link2"]["parts"][0].update(material=["al7075"]),
         "links.link2.parts[0].material: unknown material ['al7075'] (known: al7075, cfrp)"),
        (lambda raw: raw.update(materials={}),
         "links.link1.parts[0].material: unknown material 'al7075' (known: none)"),
        (lambda raw: raw.update(calibration=[1.0]),
         "calibration: [1.0] is not a mapping: q_star, G_star, gravity, scale"),
        (lambda raw: raw["calibration"].update(bogus=1),
         "calibration.bogus: unknown key (known: q_star, G_star, gravity, scale)"),
        (lambda raw: raw["calibration"]["scale"].pop("link2"),
         "calibration.scale.link2: missing (known: link1, link2, link3; the foot is scaled with link3)"),
        (lambda raw: raw["calibration"].update(scale=2.0),
         "calibration.scale: 2.0 is not a mapping of mass scale factors (link1, link2, link3)"),
        (lambda raw: raw["collision"].update(base={"shape": "sphere", "r": 0.01}),
         "collision.base: not a body of the leg (known: link1, link2, link3, foot)"),
        (lambda raw: raw["collision"].update(foot={"shape": "cylinder", "r": 0.0225, "length": 0.01, "axis": "x"}),
         "collision.foot.shape: expected sphere (the foot touches the ground as a sphere), got 'cylinder'"),
        (lambda raw: raw["collision"]["link3"].update(shape="box"),
         "collision.link3.shape: unknown shape 'box' (known: sphere, cylinder)"),
        (lambda raw: raw["collision"]["link2"].update(axis="w"),
         "collision.link2.axis: expected one of x, y, z, got 'w'"),
        (lambda raw: raw["collision"]["foot"].update(length=0.01),
         "collision.foot.length: unknown key of a sphere (known: shape, pos, r)"),
        (lambda raw: raw.update(contact=None), "contact: None is not a mapping of the contact law's constants"),
        (lambda raw: raw["contact"].update(mu=0.5),
         "contact.mu: unknown key (known: Kp, Kd, mu_s, mu_k, v_th, restitution, torsional_friction)"),
        (lambda raw: raw["contact"].pop("Kp"), "contact.Kp: missing (required: Kp, Kd, mu_s, mu_k, v_th)"),
        (lambda raw: raw["contact"].update({"a\nb": 1}),
         "contact.a\\nb: unknown key (known: Kp, Kd, mu_s, mu_k, v_th, restitution, torsional_friction)"),
    ],
    ids=["unknown-section", "restitution-negative", "Kd-negative",
         "no-contact", "joints-mapping", "joint-string", "no-type", "hip-revolute",
         "knee-continuous", "joint-renamed", "no-effort", "joint-unknown-key", "continuous-limits", "effort-string",
         "velocity-0", "huge-integer", "materials-list", "links-list", "link4", "link-list", "link-unknown-key",
         "part-string", "no-shape", "shape-list", "tube-no-r_in", "box-r", "size-number", "size-0", "part-name-twice",
         "part-name-int", "material-list", "no-materials", "calibration-list", "calibration-unknown",
         "scale-no-link2", "scale-number", "collision-base", "foot-cylinder", "collision-box", "collision-axis-w",
         "sphere-length", "contact-none", "contact-unknown", "no-Kp", "newline-key"],
)  # fmt: skip
def test_every_malformed_entry_is_named_by_its_key_path(edit: Any, message: str) -> None:
    """Wrong types, missing and unknown keys in every section: each was a KeyError, TypeError, AttributeError or
    ValueError (a traceback, or "missing or malformed entry: <the exception's text>"), or was accepted and then
    failed in the URDF, Pinocchio or a backend (a renamed joint: KeyError; the hip revolute or the knee continuous:
    Pinocchio's "wrong argument size"; a foot cylinder: no contact sphere), or was ignored (an unknown key). Now one
    line: the file, the key path, what was expected."""
    import copy

    from legbench.exceptions import ModelError

    raw = copy.deepcopy(model.load_raw())
    edit(raw)
    with pytest.raises(ModelError) as exc:
        model.params_from_raw(raw, "p.yaml")
    assert str(exc.value) == f"p.yaml: {message}"


def test_no_wrong_value_anywhere_in_the_file_escapes_as_a_python_error() -> None:
    """Every entry of the bundled file replaced by each of a few values of the wrong kind, every key deleted and an
    unknown key added to every mapping: the outcome is the parameters (a value that is valid there, such as a part
    named "w", an optional key deleted) or a ModelError of one line naming a key at or under the edited entry's
    parent, never a Python exception or the catch-all "missing or malformed entry"."""
    import copy

    from legbench.exceptions import ModelError
    from legbench.yamlfile import keypath

    base = model.load_raw()

    def entries(node: Any, at: tuple[Any, ...] = ()) -> Any:
        items = node.items() if isinstance(node, dict) else enumerate(node) if isinstance(node, list) else ()
        for k, v in items:
            yield (*at, k)
            yield from entries(v, (*at, k))

    def parent(raw: Any, at: tuple[Any, ...]) -> Any:
        for k in at[:-1]:
            raw = raw[k]
        return raw

    def outcome(raw: Any) -> str | None:
        try:
            model.params_from_raw(raw, "p.yaml")
        except ModelError as exc:
            msg = str(exc)
            assert msg.startswith("p.yaml: ") and "\n" not in msg and "malformed" not in msg, msg
            return msg.removeprefix("p.yaml: ")
        return None

    accepted = set()
    for at in entries(base):
        above = keypath(list(at[:-1]))
        values: tuple[Any, ...] = (None, True, "w", [], {}, ["x"], 10**400)
        for value in values:
            raw = copy.deepcopy(base)
            parent(raw, at)[at[-1]] = value
            msg = outcome(raw)
            if msg is None:
                accepted.add((keypath(list(at)), repr(value)))
            else:
                assert msg.startswith(above), (at, value, msg)
        raw = copy.deepcopy(base)
        del parent(raw, at)[at[-1]]
        if outcome(raw) is None:
            accepted.add((keypath(list(at)), "deleted"))
        if isinstance(parent(base, at), dict) and at[-1] == next(iter(parent(base, at))) and above != "materials":
            raw = copy.deepcopy(base)
            parent(raw, at)["zz"] = 1.0
            assert (outcome(raw) or "").startswith(f"{above}.zz: " if above else "zz: "), at  # a new material is not
    deletable = {  # optional entries, and a part of a body with more than one
        *(f"links.{link}.parts[{i}]" for link, n in (("link1", 4), ("link2", 3), ("link3", 2)) for i in range(n)),
        *(f"links.{link}.parts[{i}].name" for link, n in (("link1", 4), ("link2", 3), ("link3", 2)) for i in range(n)),
        "links.foot.parts[0].name", "links.foot.parts[0].hole_r", "links.foot.parts[0].axis", "collision.link2",
        "collision.link3", "collision.link2.pos", "collision.link3.pos", "contact.restitution",
        "contact.torsional_friction",
    }  # fmt: skip
    assert {k for k, v in accepted if v == "deleted"} == deletable
    names = {k for k in deletable if k.endswith(".name")}
    assert {(k, v) for k, v in accepted if v != "deleted"} == {(k, "'w'") for k in names}  # any string names a part


def test_a_shape_refused_past_the_reader_names_the_file_it_came_from() -> None:
    """part_inertial and the URDF writer named the active parameter file (the bundled leg.yaml unless --model) in
    their unknown-shape errors, whatever file the part came from: they name the place they are given, the file
    and the key path (the reader refuses such a file first; these are for parameters built by hand)."""
    from dataclasses import replace

    from legbench.exceptions import ModelError

    cone = {"shape": "cone", "r": 0.01, "pos": [0.0, 0.0, 0.0]}
    with pytest.raises(ModelError) as exc:
        model.part_inertial(cone, 1000.0, "mine.yaml: links.foot.parts[0]")
    known = "box, tube, cylinder, sphere"
    assert str(exc.value) == f"mine.yaml: links.foot.parts[0].shape: unknown shape 'cone' (known: {known})"
    params = replace(model.load_params(), collision={"foot": cone}, source=Path("mine.yaml"), digest="0" * 16)
    with pytest.raises(ModelError) as exc:
        model.urdf_text(params)
    assert str(exc.value) == "mine.yaml: collision.foot.shape: unknown shape 'cone' (known: sphere, cylinder)"


_FOOT_R = "is not the foot's radius geometry.R_foot"
_FOOT_POS = "is not E, the foot sphere's centre"


@pytest.mark.parametrize(
    ("pattern", "new", "message"),
    [
        ("R_foot: 0.0225 ", "R_foot: 0.05 ", f"collision.foot.r: 0.0225 {_FOOT_R} = 0.05"),
        ("foot: {shape: sphere, r: 0.0225}", "foot: {shape: sphere, r: 0.03}", f"collision.foot.r: 0.03 {_FOOT_R}"),
        ("foot: {shape: sphere, r: 0.0225}", "foot: {shape: sphere, r: 0.0225, pos: [0.1, 0, 0]}",
         f"collision.foot.pos: [0.1, 0, 0] {_FOOT_POS}"),
    ],
    ids=["R_foot-0.05", "collision-r-0.03", "collision-pos"],
)  # fmt: skip
def test_a_foot_collision_sphere_that_is_not_the_spec_foot_is_refused(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], pattern: str, new: str,
    message: str,
) -> None:  # fmt: skip
    """geometry.R_foot (the contact law's radius, about E) and collision.foot (the sphere the engines collide, in
    the URDF) were independent: R_foot 0.05 beside r 0.0225, or the sphere moved off E, was accepted, and
    `legbench run --backends pinocchio,mujoco` exited 0 with the engines simulating different feet (doctor has no
    foot row). The collision sphere is the spec's foot; any other is one line naming the file and both keys,
    exit 2, before any URDF is written; pos [0, 0, 0] written out is the same sphere and accepted."""
    from legbench import cli, resources

    cache = tmp_path / "cache"
    monkeypatch.setenv(resources.CACHE_ENV, str(cache))
    monkeypatch.delenv(resources.MODEL_ENV, raising=False)
    bad = _edited(tmp_path, pattern, new)
    try:
        assert cli.main(["--model", str(bad), "model", "check"]) == 2
    finally:
        resources.select_model(None)
    err = capsys.readouterr().err
    assert err.startswith(f"legbench: error: {bad}: {message}") and err.count("\n") == 1, err
    assert ("geometry.R_foot" if ".r:" in message else "geometry.L_3E") in err  # the spec's key beside it
    assert not cache.exists() or not any(cache.rglob("*")), sorted(cache.rglob("*"))
    at_e = _edited(tmp_path, "foot: {shape: sphere, r: 0.0225}", "foot: {shape: sphere, r: 0.0225, pos: [0, 0, 0]}",
                   "at_e.yaml")  # fmt: skip
    assert model.read_params(at_e).collision["foot"]["pos"] == [0, 0, 0]


@pytest.mark.parametrize(
    ("factor", "body", "words"),
    [
        ("link3", "1e-25", "leaves link3 1.49e-26 kg, below 1e-15 kg, the least mass the engines hold"),
        ("link3", "1e-10", "leaves link3 a principal moment of inertia of 3.6e-15 kg m^2, below 1e-14 kg m^2"),
        ("link1", "1e-20", "leaves link1 2.8e-21 kg, below 1e-15 kg"),
    ],
    ids=["link3-mass", "link3-inertia", "link1-mass"],
)
def test_a_link_too_light_for_the_engines_is_refused_naming_its_scale_factor(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], factor: str, body: str,
    words: str,
) -> None:  # fmt: skip
    """calibration.scale.link3: 1e-25 was accepted; `legbench --model that.yaml run scenarios/position.yaml` then
    stopped at the parity check ("pinocchio holds link3.com.x = 1.04e-21 m, the spec (models/leg.yaml ...) says
    0.1268": Pinocchio merges the foot into link3 dividing by max(m, 2.2e-16)) after MuJoCo failed to load
    ("inertia must have positive eigenvalues", below 1e-14). The reader refuses a body of the URDF lighter than
    model.MIN_MASS or with a principal moment below model.MIN_INERTIA, naming the scale factor, exit 2. The
    bundled leg is far above both (its lightest body 0.12 kg, smallest moment 2.6e-5 kg m^2); 1e-9 on link3, which
    every engine holds, is accepted."""
    from legbench import cli, resources

    monkeypatch.setenv(resources.CACHE_ENV, str(tmp_path / "cache"))
    monkeypatch.delenv(resources.MODEL_ENV, raising=False)
    value = {"link1": "2.24287369", "link3": "1.27669764"}[factor]
    bad = _edited(tmp_path, f"{factor}: {value}", f"{factor}: {body}")
    try:
        assert cli.main(["--model", str(bad), "model", "check"]) == 2
    finally:
        resources.select_model(None)
    err = capsys.readouterr().err
    assert err.startswith(f"legbench: error: {bad}: calibration.scale.{factor}: {body} {words}"), err
    assert err.count("\n") == 1, err
    held = _edited(tmp_path, "link3: 1.27669764", "link3: 1e-9", "held.yaml")
    assert model.read_params(held).scale["link3"] == 1e-9


@pytest.mark.parametrize(
    ("name", "words"),
    [
        ("effort.yaml", "is a scenario (it has 'events'), not a leg parameter file: run it with legbench run"),
        ("sweeps/timestep.yaml", "is a sweep file (it has 'studies'), not a leg parameter file"),
        ("reproduce.yaml", "is a framework file (it has 'frameworks'), not a leg parameter file"),
    ],
)
def test_another_of_legbenchs_files_given_to_model_is_named(name: str, words: str) -> None:
    """A scenario given to --model read "name: unknown section (a leg parameter file has ...)": each of legbench's
    other files is named for what it is, with the command that takes it, as a leg file given as a scenario was."""
    from legbench.exceptions import ModelError

    path = Path(__file__).resolve().parent.parent / "scenarios" / name
    with pytest.raises(ModelError) as exc:
        model.load_params(path)
    assert f"{path}: {words}" in str(exc.value)


def test_model_check_ends_with_its_verdict_and_names_a_foreign_legs_references(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """`model check` printed the bundled leg's foot position as 'spec' beside any --model's FK(q*), the file's
    G_star as 'report', and exited 1 with no line saying it failed: the last line is PASS or FAIL (naming the
    joints off by more than 5 %), and another leg's references are its own."""
    import re

    from legbench import cli, resources

    monkeypatch.setenv(resources.CACHE_ENV, str(tmp_path / "cache"))
    monkeypatch.delenv(resources.MODEL_ENV, raising=False)
    assert cli.main(["model", "check"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert "the lab report's foot at q*" in out[0] and out[-1] == "PASS: G(q*) within 5 % of G_star in every joint"
    text, n = re.subn(r"G_star: \[1\.0426,", "G_star: [2.0,", resources.bundled_model().read_text())
    assert n == 1
    path = tmp_path / "heavy.yaml"
    path.write_text(text)
    try:
        assert cli.main(["--model", str(path), "model", "check"]) == 1
    finally:
        resources.select_model(None)
    out = capsys.readouterr().out.splitlines()
    assert "lab report" not in out[0] and "(calibration.G_star: [2.0," in out[1], out
    assert out[-1].startswith("FAIL: G(q*) more than 5 % off G_star in joint 1 ("), out


def test_model_calibrate_refuses_factors_no_leg_has(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A G_star of the wrong sign printed scale factors of -55.6 (which the parameter file then refuses) with
    exit 0, and a q_star where a link's weight moves no joint factors of 2e16: both are one line, exit 2."""
    import re

    from legbench import cli, resources

    text = resources.bundled_model().read_text()
    bad, n = re.subn(r"G_star: \[1\.0426,", "G_star: [-5.0,", text)
    assert n == 1
    path = tmp_path / "neg.yaml"
    path.write_text(bad)
    assert cli.main(["model", "calibrate", "--params", str(path)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"legbench: error: {path}: calibration.G_star at q_star needs a link") and "\n" not in err
    assert "not a physical one (> 0 and < 1000)" in err
