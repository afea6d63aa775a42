"""Bad input gets one clear line (file, key path, problem) and exit status 2; nothing is written."""

from __future__ import annotations

import copy
import json
import os
import re
import shutil
import subprocess
import sys
import tracemalloc
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from fakes import FakeBackend
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from legbench import backends as registry
from legbench import cli, model, resources, results, scenario, yamlfile
from legbench.exceptions import LegbenchError, ModelError, ScenarioError

GOOD: dict[str, Any] = {
    "name": "t",
    "duration": 2.0,
    "events": [
        {"t": 0.0, "position": {"joint": [0.0, -1.0, -1.0]}},
        {"t": 1.0, "trajectory": {"waypoints": [[0.1667, 0.05, 0.10], [0.1667, 0.10, 0.12]], "times": [0.4, 0.8]}},
    ],
}


def _set(doc: dict[str, Any], path: str, value: Any) -> dict[str, Any]:
    doc = copy.deepcopy(doc)
    keys: list[Any] = [int(k) if k.isdigit() else k for k in path.split(".")]
    d = doc
    for k in keys[:-1]:
        d = d[k]
    if value is _DELETE:
        del d[keys[-1]]
    else:
        d[keys[-1]] = value
    return doc


_DELETE = object()

# (change to the good document, expected key path in the message, words expected)
CASES: list[tuple[str, Any, str, str]] = [
    ("duraton", 2.0, "duraton", "did you mean 'duration'"),
    ("duration", -1.0, "duration", "> 0"),
    ("duration", 0, "duration", "> 0"),
    ("duration", "long", "duration", "expected a number"),
    ("duration", float("nan"), "duration", "finite"),
    ("duration", float("inf"), "duration", "finite"),
    ("duration", 1e9, "duration", "control ticks"),
    ("duration", 2.0005, "duration", "whole number of control periods"),
    ("control_rate", 0, "control_rate", "> 0"),
    ("control_rate", -1000, "control_rate", "> 0"),
    ("name", "../escape", "name", "plain name"),
    ("name", "a/b", "name", "plain name"),
    ("name", "..", "name", "plain name"),
    ("name", 42, "name", "a name is text: quote it"),
    ("name", _DELETE, "", "missing required key 'name'"),
    ("events", [], "events", "non-empty list"),
    ("events", "go", "events", "non-empty list"),
    ("events.0.t", 0.5, "events[0].t", "first event must start at t = 0"),
    ("events.1.t", -0.5, "events[1].t", ">= 0"),
    ("events.1.t", 5.0, "events[1].t", "past the end"),
    ("events.0.position.joint", [0, 0], "events[0].position.joint", "list of 3"),
    ("events.0.position.joint", [0, 0, 2.5], "events[0].position.joint[2]", "outside the joint limits"),
    ("events.0.position.joint", [2.0, 0, 0], "events[0].position.joint[0]", "outside the joint limits"),
    ("events.0.position", {"cartesian": [0.1667, 0.0, 0.95]}, "events[0].position.cartesian", "unreachable"),
    ("events.0.position", {"joint": [0, 0, 0], "cartesian": [0.1, 0, 0]}, "events[0].position", "exactly one"),
    ("events.0.position", None, "events[0].position", "expected a mapping"),
    ("events.0.positon", {"joint": [0, 0, 0]}, "events[0].positon", "did you mean 'position'"),
    ("events.1.trajectory.times", [0.4], "events[1].trajectory.times", "one per waypoint"),
    ("events.1.trajectory.times", [0.8, 0.4], "events[1].trajectory.times", "increase strictly"),
    ("events.1.trajectory.times", [0.4, 0.401], "events[1].trajectory.times", "rad/s limit"),
    ("events.1.trajectory.waypoints.1", [0.1667, 0.0, 0.95], "events[1].trajectory.waypoints[1]", "unreachable"),
    ("events.1.trajectory.waypoints.1", [0.1, "y", 0.1], "events[1].trajectory.waypoints[1][1]", "a number"),
    ("initial", {"q": [0, 0, 3.0]}, "initial.q[2]", "outside the joint limits"),
    ("initial", {"qd": [0, 0, float("nan")]}, "initial.qd[2]", "finite"),
    ("initial", {"q0": [0, 0, 0]}, "initial.q0", "unknown key"),
    ("gains", {"Kp": [1, 2]}, "gains.Kp", "list of 3"),
    ("gains", {"KP": 10}, "gains.KP", "did you mean 'Kp'"),
    ("physics", {"gravity": -9.81}, "physics.gravity", ">= 0"),
    ("physics", {"contact_mode": "magic"}, "physics.contact_mode", "expected one of"),
    ("physics", {"contact": {"Kp": 0}}, "physics.contact.Kp", "> 0"),
    ("physics", {"contact": {"mu": 0.7}}, "physics.contact.mu", "did you mean"),
    ("physics", {"contact": {"poc": "side"}}, "physics.contact.poc", "centre"),
    ("backends", {"pinocchio": {"dt": -1e-4}}, "backends.pinocchio.dt", "> 0"),
    ("backends", {"pinocchio": {"dt": "small"}}, "backends.pinocchio.dt", "a number"),
    ("backends", {"pinocchio": {"integrator": "verlet"}}, "backends.pinocchio.integrator", "expected one of"),
    ("backends", {"gazebo": {}}, "backends.gazebo", "unknown backend"),
    ("comparison", {"skip": 5.0}, "comparison.skip", "skips the whole run"),
    ("comparison", {"steady_window": 0}, "comparison.steady_window", "> 0"),
    ("comparison", {"tolerances": [1, 2]}, "comparison.tolerances", "mapping"),
]


def test_the_malformed_scenario_cases_are_many_and_distinct() -> None:
    """The table the test below runs over (and the random values' key paths): 49 cases, each its own change to
    the good document. It guards the test data, once, rather than in each case."""
    assert len(CASES) >= 30, len(CASES)
    changes = [(path, repr(value)) for path, value, _, _ in CASES]
    assert len(set(changes)) == len(changes), "a case is listed twice"


@pytest.mark.parametrize(
    ("path", "value", "key", "words"),
    CASES,
    ids=[f"{c[0]}={c[1]!r}" if type(c[1]) is not object else f"{c[0]} deleted" for c in CASES],
)
def test_malformed_scenario_exits_2_naming_the_key(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], path: str, value: Any, key: str, words: str
) -> None:
    f = tmp_path / "bad.yaml"
    f.write_text(yaml.safe_dump(_set(GOOD, path, value)))
    assert cli.main(["validate", str(f)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0, "one line"
    assert str(f) in err and words in err
    if key:
        assert f": {key}: " in err
    with pytest.raises(ScenarioError) as exc:
        scenario.load(f)
    assert exc.value.key == key


@pytest.mark.parametrize(
    ("text", "words"),
    [
        ("name: t\nduration: [1\n", "malformed YAML"),
        ("name: t\n  duration: 1\n", "malformed YAML"),
        ("", "empty file"),
        ("- 1\n- 2\n", "expected a mapping"),
        ("name: !!python/object/apply:os.system ['echo hacked']\nduration: 1\n", "malformed YAML"),
    ],
)
def test_malformed_yaml_is_one_line_with_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture[str], text: str,
                                                words: str) -> None:  # fmt: skip
    f = tmp_path / "bad.yaml"
    f.write_text(text)
    assert cli.main(["validate", str(f)]) == 2
    err = capsys.readouterr().err.strip()
    assert words in err and str(f) in err and "\n" not in err


def test_missing_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert cli.main(["validate", str(tmp_path / "nope.yaml")]) == 2
    assert "no such file" in capsys.readouterr().err


def test_bad_scenario_writes_nothing(tmp_path: Path) -> None:
    f = tmp_path / "bad.yaml"
    f.write_text(yaml.safe_dump(_set(GOOD, "duration", -1.0)))
    out = tmp_path / "out"
    assert cli.main(["run", str(f), "--backends", "pinocchio", "--out", str(out), "-q"]) == 2
    assert not out.exists()
    assert list(tmp_path.iterdir()) == [f]


_scalars = st.one_of(
    st.none(), st.booleans(), st.integers(-(10**6), 10**6), st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=8),
)  # fmt: skip
_keys = st.sampled_from([*scenario.TOP_KEYS, "t", "position", "joint", "cartesian", "effort", "force", "trajectory",
                         "waypoints", "times", "ellipse", "a", "b", "T", "Kp", "q", "qd", "contact", "dt", "pinocchio",
                         "bogus"])  # fmt: skip
_values = st.recursive(_scalars, lambda inner: st.lists(inner, max_size=4) | st.dictionaries(_keys, inner, max_size=4),
                       max_leaves=12)  # fmt: skip


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(doc=st.dictionaries(_keys, _values, max_size=8))
def test_random_documents_never_raise_anything_but_scenario_error(doc: dict[str, Any]) -> None:
    try:
        scenario.parse(doc, "random.yaml")
    except ScenarioError as exc:
        assert str(exc).startswith("random.yaml")


@settings(max_examples=200, deadline=None)
@given(path=st.sampled_from([c[0] for c in CASES]), value=_values)
def test_random_values_in_a_good_document_never_raise_anything_but_scenario_error(path: str, value: Any) -> None:
    try:
        doc = _set(GOOD, path, value)
    except (KeyError, IndexError, TypeError):
        return
    try:
        scenario.parse(doc, "random.yaml")
    except ScenarioError:
        pass


def test_planted_divergence_stops_only_that_backend(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Contact stiffness 1e7 N/m is stable at the engines' 50 us sub-step (omega dt ~ 0.35) but not for
    Pinocchio forced to one 1 ms step (omega dt ~ 7): Pinocchio is stopped and marked failed with time and
    reason, the others finish, the report says so, and the exit status is 3."""
    import json

    from legbench import backends

    out = tmp_path / "effort"
    names = ",".join(backends.available())
    scen = str(Path(__file__).resolve().parent.parent / "scenarios" / "effort.yaml")
    argv = ["run", scen, "--backends", names, "--out", str(out), "-q",
            "--set", "physics.contact.Kp=1e7", "--set", "backends.pinocchio.dt=1e-3",
            # the explicit friction step: the implicit default damps the tangential modes and delays the blow-up
            "--set", "backends.pinocchio.friction=explicit"]  # fmt: skip
    assert cli.main(argv) == 3
    meta = json.loads((out / "run.json").read_text())
    pin_entry = meta["backends"]["pinocchio"]
    assert pin_entry["status"] == "failed" and "diverged" in pin_entry["reason"]
    assert 0.0 < pin_entry["failed_at"] < 0.1
    for name, entry in meta["backends"].items():
        if name != "pinocchio":
            assert entry["status"] == "ok"
    assert "pinocchio' failed" in (out / "report.md").read_text()
    assert "FAILED" in capsys.readouterr().out


# --------------------------------------------------------------------------- #
# Issue classes: limits, guarded readers, atomic writes, validation, no silent overwrite


ROOT = Path(__file__).resolve().parent.parent
EFFORT = ROOT / "scenarios" / "effort.yaml"


def _bomb(levels: int) -> str:
    """A billion-laughs document: 10**levels strings once its aliases are expanded (~0.1 KB a level)."""
    text = 'name: t\nduration: 1.0\nl0: &l0 ["x","x","x","x","x","x","x","x","x","x"]\n'
    for i in range(1, levels):
        text += f"l{i}: &l{i} [" + ",".join([f"*l{i - 1}"] * 10) + "]\n"
    return text


def test_alias_bomb_is_refused_before_expansion(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """10**9 values once expanded: refused from the composed tree (memoised sizes), so the refusal allocates
    next to nothing: peak traced memory below 10 MB (measured 0.04 MB), where expanding even 1e6 of the 1e9
    values would take more than 8 MB (one pointer each) and the whole expansion tens of GB. Memory, not time:
    the bound holds whatever else the machine is doing."""
    f = tmp_path / "bomb.yaml"
    f.write_text(_bomb(9))
    assert cli.main(["validate", str(EFFORT)]) == 0  # the validate path imported before measuring
    capsys.readouterr()
    tracemalloc.start()
    try:
        assert cli.main(["validate", str(f)]) == 2
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 10e6, f"{peak / 1e6:.1f} MB"
    err = capsys.readouterr().err
    assert "limit yaml_nodes" in err and err.count("\n") == 1


@pytest.mark.parametrize(
    ("text", "words"),
    [
        ("name: t\nname: u\nduration: 1\n", "name: duplicate key (first at line 1)"),
        ("a: " + "[" * 50_000 + "]" * 50_000 + "\n", "limit yaml_depth"),
        ("name: t\x00\n", "NUL byte"),
        ("x: &a [*a]\n", "recursive alias"),
        ("a: {b: 1}\nc: *nope\n", "malformed YAML"),
        ("".join(f"k{i}: &a{i} 1\nv{i}: *a{i}\n" for i in range(1001)), "limit yaml_aliases"),
        ("name: t\nduration: " + "1" * 5000 + "\n", "cannot convert: Exceeds the limit (4300 digits)"),
        ("name: t\nwhen: 2001-13-01\n", "cannot convert: month must be in 1..12"),
        # validated ok, then every run ended in a traceback (UnicodeEncodeError) writing run.json
        ('name: t\ndescription: "a \\ud800"\n', "x.yaml:2: 'a \\ud800': a lone surrogate"),
    ],
    ids=[
        "duplicate",
        "deep",
        "nul",
        "recursive",
        "undefined-alias",
        "many-aliases",
        "huge-int",
        "bad-date",
        "surrogate",
    ],
)
def test_hostile_yaml_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str], text: str, words: str) -> None:
    f = tmp_path / "x.yaml"
    f.write_text(text)
    assert cli.main(["validate", str(f)]) == 2
    err = capsys.readouterr().err
    assert words in err and str(f) in err and err.count("\n") == 1


def test_non_utf8_and_oversized_files(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                      monkeypatch: pytest.MonkeyPatch) -> None:  # fmt: skip
    f = tmp_path / "latin.yaml"
    f.write_bytes(b"name: caf\xe9\nduration: 1\n")
    assert cli.main(["validate", str(f)]) == 2
    assert "not UTF-8" in capsys.readouterr().err
    big = tmp_path / "big.yaml"
    big.write_text(EFFORT.read_text() + "#" * 2_000_000 + "\n")
    assert cli.main(["validate", str(big)]) == 2
    assert "limit file_bytes" in capsys.readouterr().err
    monkeypatch.setenv("LEGBENCH_LIMITS", "file_bytes=1e7")  # the documented way to raise a limit
    assert cli.main(["validate", str(big)]) == 0


def test_tick_limit_can_be_raised(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    doc = _set(GOOD, "duration", 20_000.0)  # 2e7 ticks at 1 kHz
    with pytest.raises(ScenarioError, match="limit ticks"):
        scenario.parse(doc, "x.yaml")
    monkeypatch.setenv("LEGBENCH_LIMITS", "ticks=3e7")
    assert scenario.parse(doc, "x.yaml").n_ticks > 10_000_000
    monkeypatch.setenv("LEGBENCH_LIMITS", "tick=3e7")  # a typo would silently leave the limit as it was
    with pytest.raises(ScenarioError, match="LEGBENCH_LIMITS: tick=3e7: unknown limit; known: file_bytes"):
        scenario.parse(doc, "x.yaml")
    monkeypatch.delenv("LEGBENCH_LIMITS")
    # the rate alone set on the command line: the error blamed the file's duration line, which did not change
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump(GOOD))
    with pytest.raises(ScenarioError) as exc:
        scenario.load(path, {"control_rate": 1e9})
    assert exc.value.key == "control_rate" and str(exc.value).endswith("(from --set control_rate)"), exc.value
    monkeypatch.setenv("LEGBENCH_LIMITS", "ticks")  # a known limit without its value was called unknown
    with pytest.raises(ScenarioError, match="LEGBENCH_LIMITS: ticks: no value: write ticks=N$"):
        scenario.parse(doc, "x.yaml")


@pytest.mark.parametrize(
    ("value", "words"),
    [
        ("ticks=1.5", "ticks: must be a whole number >= 1, got '1.5'"),  # was taken for 1
        ("ticks=3e7,ticks=4e7", "ticks: given twice"),  # the last one won
        ("integer=1e12", "integer: at most 2147483647, the engines' C int (it may only be lowered), got '1e12'"),
    ],
)
def test_a_limit_that_cannot_be_is_refused(monkeypatch: pytest.MonkeyPatch, value: str, words: str) -> None:
    """LEGBENCH_LIMITS: a fraction was truncated, a name given twice took the last value, and ``integer`` raised
    past a C int let an ODE iteration count of 3e9 wrap to -1294967296 in run.json: each one ScenarioError."""
    monkeypatch.setenv("LEGBENCH_LIMITS", value)
    with pytest.raises(ScenarioError) as exc:
        yamlfile.limit("ticks")
    assert str(exc.value) == f"LEGBENCH_LIMITS: {words}"
    monkeypatch.setenv("LEGBENCH_LIMITS", "integer=1000")  # lowering it is fine
    assert yamlfile.limit("integer") == 1000


@pytest.mark.parametrize(
    ("setting", "words"),
    [
        ("duration=[0.3", "malformed YAML"),
        ("duration.x=1", "'duration' is 3.0, not a mapping"),
        ("events.7.t=1", "not an index"),
        ("events[0].t=1", "events[0].t: a list item is written with a dot: events.0.t"),
        ("name=!!python/object/apply:os.system ['echo hacked']", "malformed YAML"),
        ("=1", "expected KEY=VALUE"),
        ("backends.pinocchio.dt=1e-9", "limit sub_steps"),
        ("backends.pinocchio.dt=3e-4", "does not divide the control period"),
        ("backends.pinocchio.max_step=1e-20", "limit sub_steps"),  # an adaptive solve: 1e17 steps a tick, a hang
        ("backends.pybullet.solver_iterations=1e20", "expected an integer"),
        ("backends.pybullet.solver_iterations=100000000000000000000", "largest integer"),
        ("comparison.reference=pinochio", "unknown backend 'pinochio'"),
    ],
)
def test_malformed_set_values_are_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str], setting: str,
                                           words: str) -> None:  # fmt: skip
    out = tmp_path / "out"
    assert cli.main(["run", str(EFFORT), "--backends", "pinocchio", "--out", str(out), "-q", "--set", setting]) == 2
    err = capsys.readouterr().err
    assert words in err and err.count("\n") == 1
    assert not out.exists()


@pytest.mark.parametrize(
    ("path", "value", "key", "words"),
    [
        ("gains", {"Kd": -1.0}, "gains.Kd", "negative gain"),
        ("gains", {"Kp": [1.0, -2.0, 3.0]}, "gains.Kp[1]", "negative gain"),
        ("events.1.t", 0.0, "events[1].t", "same instant"),
        ("physics", {"contact": {"mu_k": 0.9, "mu_s": 0.5}}, "physics.contact.mu_k", "above static"),
        ("comparison", {"reference": "pinochio"}, "comparison.reference", "unknown backend"),
    ],
)
def test_physically_meaningless_scenarios_are_refused(path: str, value: Any, key: str, words: str) -> None:
    with pytest.raises(ScenarioError) as exc:
        scenario.parse(_set(GOOD, path, value), "x.yaml")
    assert exc.value.key == key and words in exc.value.problem


@pytest.mark.parametrize(
    ("section", "key", "value", "words"),
    [
        ("geometry", "L_23", -0.2, "geometry.L_23: -0.2 must be > 0"),
        ("materials", "cfrp", -2000.0, "materials.cfrp: -2000.0 must be > 0"),
        ("contact", "Kd", -1.0, "contact.Kd: -1.0 must be >= 0"),
        ("contact", "mu_k", 0.9, "above the static coefficient"),
    ],
)
def test_meaningless_leg_parameters_are_refused(section: str, key: str, value: float, words: str) -> None:
    raw = copy.deepcopy(model.load_raw())
    raw[section][key] = value
    with pytest.raises(ModelError, match=words.replace("(", r"\(")):
        model.params_from_raw(raw, "p.yaml")


@pytest.mark.parametrize(
    ("edit", "words"),
    [
        (lambda raw: raw["joints"].pop(), "joints: 2 joints: the leg has three"),
        (lambda raw: raw["joints"][0].update(type="prismatic"), "joints[0].type: 'prismatic' is not a rotary joint"),
        (lambda raw: raw["geometry"].update(bogus=0.1), "geometry.bogus: 0.1 is not a length of the leg (H, "),
    ],
    ids=["two-joints", "prismatic", "unknown-length"],
)
def test_a_leg_that_is_not_the_3_dof_leg_is_refused(edit: Any, words: str) -> None:
    """The model, URDF and every backend assume three rotary joints: anything else is one line naming the key
    (a leg file with two joints ended in zip()'s ValueError, a prismatic joint ran)."""
    raw = copy.deepcopy(model.load_raw())
    edit(raw)
    with pytest.raises(ModelError, match=words.replace("(", r"\(").replace("[", r"\[")):
        model.params_from_raw(raw, "p.yaml")


def test_validate_reports_every_error_of_a_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    f = tmp_path / "bad.yaml"
    f.write_text(
        "name: t\nduration: 2.0\ngains: {Kd: -1}\nevents:\n"
        "  - {t: 0.0, position: {joint: [0.0, -1.0, -1.0]}}\n  - {t: 0.0, position: {joint: [0.0, -1.0, -1.0]}}\n"
        "physics: {contact: {mu_k: 0.9}}\nbackends: {pinocchio: {dt: 3e-4}, mujoco: {dt: -1}}\n"
        "comparison: {reference: pinochio}\n"
    )
    good = tmp_path / "good.yaml"
    good.write_text(yaml.safe_dump(GOOD))
    assert cli.main(["validate", str(f), str(good)]) == 2
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert [ln.split(": ")[3] for ln in lines] == ["gains.Kd", "events[1].t", "physics.contact.mu_k",
                                                   "backends.pinocchio.dt", "backends.mujoco.dt",
                                                   "comparison.reference"]  # fmt: skip
    assert [ln.split(": ")[2].rsplit(":", 1)[1] for ln in lines] == ["3", "6", "7", "8", "8", "9"]  # lines
    assert f"{good}: ok" in captured.out


def test_validate_tolerance_and_sweep_files_fully(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    tol = tmp_path / "tol.yaml"
    tol.write_text("rms: {abs: -1}\nbogus: {abs: 1}\nscenarios: {effort: {rms: {rel: abc}}}\n")
    assert cli.main(["validate", str(tol)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 3 and "bogus: unknown tolerance" in err and "scenarios.effort.rms.rel" in err
    sw = tmp_path / "sw.yaml"
    sw.write_text(f"name: s\nscenario: {EFFORT}\nstudies:\n  - backends: [pinocchio]\n"
                  "    grid: {backends.*.dt: [1e-4, abc]}\n    reference: {backend: pinocchio}\n")  # fmt: skip
    assert cli.main(["validate", str(sw)]) == 2
    err = capsys.readouterr().err
    assert "studies[0].grid.backends.*.dt" in err and "'abc'" in err
    sw.write_text(sw.read_text().replace("[1e-4, abc]", str([1e-4] * 200) + ", physics.contact.Kp: " +
                                         str(list(range(1, 101)))))  # fmt: skip
    assert cli.main(["validate", str(sw)]) == 2
    assert "limit sweep_points" in capsys.readouterr().err


def test_validate_looks_past_an_invalid_duration_and_control_rate(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """An invalid duration or control_rate no longer ends validate's search: each is replaced by a stand-in and
    the rest is still checked (it reported only the unknown key and the duration of this file), and nothing is
    blamed on a stand-in (an event after it, off its tick grid, a window longer than it)."""
    f = tmp_path / "bad.yaml"
    f.write_text("name: t\nbogus: 1\nduration: -1\ncontrol_rate: 0\ngains: {Kp: -1}\nevents:\n"
                 "  - {t: 0.0, effort: {force: [0, 0]}}\n")  # fmt: skip
    assert cli.main(["validate", str(f)]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert [ln.split(": ")[3] for ln in lines] == ["bogus", "duration", "control_rate", "gains.Kp",
                                                   "events[0].effort.force"]  # fmt: skip
    hold = "{joint: [0, 0, 0]}"
    f.write_text(f"name: t\nduration: -1\ncontrol_rate: 0\nevents:\n  - {{t: 0.0, position: {hold}}}\n"
                 f"  - {{t: 5.0005, position: {hold}}}\ncomparison: {{skip: 3, steady_window: 4}}\n")  # fmt: skip
    assert cli.main(["validate", str(f)]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert [ln.split(": ")[3] for ln in lines] == ["duration", "control_rate"]


def test_validate_refuses_what_would_fail_every_run_at_t_0(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """What validated ok and then failed every engine (an initial speed past the divergence bound: exit 3) or
    every load with no file named (a control_rate the engines' default step does not divide) is one line of
    validate naming the file and the key, exit 2."""
    for text, key in (("initial: {qd: [0, 0, 5000]}\n", "initial.qd[2]"), ("control_rate: 333\n", "control_rate")):
        f = tmp_path / "s.yaml"
        f.write_text(yaml.safe_dump({**GOOD, "duration": 3.0}) + text)
        assert cli.main(["validate", str(f)]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and f"{f}:" in err and f": {key}: " in err


def test_a_path_that_is_not_a_regular_file_is_refused_without_reading_it(tmp_path: Path) -> None:
    """A character device (/dev/zero: no end, read until the process was killed) and a FIFO (open blocked for
    ever) are refused in one line naming what they are, exit 2, at once (each in a fresh process, bounded)."""
    fifo = tmp_path / "fifo.yaml"
    os.mkfifo(fifo)
    for path, kind in (("/dev/zero", "a character device"), (str(fifo), "a FIFO")):
        if not Path(path).exists():
            continue
        done = subprocess.run([sys.executable, "-m", "legbench", "validate", path], capture_output=True, text=True,
                              timeout=120)  # fmt: skip
        assert done.returncode == 2, done.stderr[-500:]
        assert done.stderr == f"legbench: error: {path}: is {kind}, not a regular file (a file is read only from one)\n"


def test_at_most_the_file_size_limit_is_read_whatever_stat_says(monkeypatch: pytest.MonkeyPatch) -> None:
    """A regular file whose stat size is 0 (a /proc file) is read only up to file_bytes + 1 bytes: beyond the
    limit it is refused (the size limit was a stat check only)."""
    proc = Path("/proc/self/status")
    if not proc.is_file() or proc.stat().st_size != 0:
        pytest.skip("needs Linux /proc")
    monkeypatch.setenv("LEGBENCH_LIMITS", "file_bytes=64")
    with pytest.raises(ScenarioError, match="/proc/self/status: more than 64 bytes \\(limit file_bytes\\)"):
        yamlfile.read_text(proc)


@pytest.mark.parametrize("value", ["-1", "0", "0.5", "-1e9"])
def test_a_limit_below_1_is_refused(monkeypatch: pytest.MonkeyPatch, value: str) -> None:
    """LEGBENCH_LIMITS=ticks=-1 was taken ("more than -1e+00 control ticks"): a limit must be a whole number >= 1,
    refused whichever limit is read first."""
    monkeypatch.setenv("LEGBENCH_LIMITS", f"file_bytes=2e6,ticks={value}")  # the bad one after a good one
    for name in ("ticks", "file_bytes"):
        with pytest.raises(ScenarioError) as err:
            yamlfile.limit(name)
        assert str(err.value) == f"LEGBENCH_LIMITS: ticks: must be a whole number >= 1, got {value!r}"
    monkeypatch.setenv("LEGBENCH_LIMITS", "ticks=1")
    assert yamlfile.limit("ticks") == 1


# --------------------------------------------------------------------------- #
# Output paths checked before any work; readers guarded


@pytest.mark.parametrize(
    "argv",
    [
        ["run", str(EFFORT), "--backends", "pinocchio"],
        ["sweep", str(ROOT / "scenarios" / "sweeps" / "gains.yaml")],
        ["bench", "--quick"],
        ["verify"],
        ["calibrate-contact"],
        ["reproduce"],
    ],
    ids=lambda a: a[0],
)
def test_out_that_is_a_regular_file_is_refused_before_any_work(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                               argv: list[str]) -> None:  # fmt: skip
    f = tmp_path / "file"
    f.write_text("keep me")
    assert cli.main([*argv, "--out", str(f)]) == 2
    err = capsys.readouterr().err
    assert "is a regular file" in err and err.count("\n") == 1
    assert f.read_text() == "keep me"


@pytest.mark.parametrize(
    ("argv", "words"),
    [
        (["run", str(EFFORT), "--backends", "", "--out", "X"], "names no backend"),
        (["run", str(EFFORT), "--backends", "pinocchio", "--jobs", "0", "--out", "X"], "--jobs 0"),
        (["run", str(EFFORT), "--backends", "pinocchio", "--jobs", "-3", "--out", "X"], "--jobs -3"),
        (["model", "urdf", "--params", "DIR"], "is a directory"),
        (["model", "urdf", "--out", "DIR/missing/leg.urdf"], "no such folder"),
        (["check", "DIR", "--baseline", "DIR", "--summary", "DIR/missing/s.md"], "no such folder"),
    ],
)
def test_bad_options_are_one_line_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture[str], argv: list[str],
                                         words: str) -> None:  # fmt: skip
    argv = [a.replace("DIR", str(tmp_path)).replace("X", str(tmp_path / "x")) for a in argv]
    assert cli.main(argv) == 2
    err = capsys.readouterr().err
    assert words in err and err.count("\n") == 1
    assert not (tmp_path / "x").exists()


def _fake_run(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, name: str = "t") -> Path:
    """A finished run directory of the fake backend (0.01 s)."""
    reg = registry._registry
    monkeypatch.setattr(registry, "_registry", lambda: {**reg(), "fake": FakeBackend})
    f = tmp_path / f"{name}.yaml"
    f.write_text(yaml.safe_dump({**_set(GOOD, "duration", 2.0), "name": name}))
    return f


def test_corrupt_results_are_one_line(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                      capsys: pytest.CaptureFixture[str]) -> None:  # fmt: skip
    f = _fake_run(tmp_path, monkeypatch)
    out = tmp_path / "r"
    argv = ["run", str(f), "--backends", "fake", "--out", str(out), "-q", "--no-compare", "--no-preflight"]
    assert cli.main(argv) == 0
    (out / "run.json").write_bytes(b"\xff\xfe garbage")
    assert cli.main(["compare", str(out)]) == 2
    assert "not UTF-8" in capsys.readouterr().err
    # a rerun into it names the corruption instead of "scenario None"
    assert cli.main(argv) == 2
    err = capsys.readouterr().err
    assert "unreadable or corrupt" in err and "None" not in err
    (out / "run.json").write_text('{"scenario": {"name": "t"}, "backends": {"fake": {"status": "ok"}}}')
    (out / "fake.parquet").write_bytes(b"PAR1 truncated")
    assert cli.main(["compare", str(out)]) == 2
    assert "not a readable parquet file" in capsys.readouterr().err


def test_a_rerun_after_an_interrupt_before_the_comparison_compares_only(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """A Ctrl-C after every backend finished and before the comparison leaves a complete run.json, the logs and no
    metrics.json (written here by deleting the comparison, not by timing a signal). The interrupt says "rerun the
    same command to finish", but the rerun was refused: "holds a finished run; ... or --force". Now the same
    command compares it, runs no backend and says so in one line; with other settings, another leg (--model) or
    CSV logs it does not hold (--csv) it is still refused."""
    from legbench import run

    f = _fake_run(tmp_path, monkeypatch)
    out = tmp_path / "r"
    argv = ["run", str(f), "--backends", "fake", "--out", str(out), "-q", "--no-preflight"]
    assert cli.main(argv) == 0
    for p in out.iterdir():
        if p.name not in ("run.json", "fake.parquet"):
            shutil.rmtree(p) if p.is_dir() else p.unlink()
    kept = {p.name: p.read_bytes() for p in out.iterdir()}
    capsys.readouterr()

    def no_runs(*args: Any, **kwargs: Any) -> None:
        raise AssertionError("a backend was run again")

    monkeypatch.setattr(run, "run_many", no_runs)
    assert cli.main([*argv, "--set", "duration=1.9"]) == 2  # other settings: still refused
    err = capsys.readouterr().err
    assert f"{out} holds a finished run; choose another --out" in err and err.count("\n") == 1
    assert not (out / "metrics.json").exists()
    assert cli.main([*argv, "--csv"]) == 2  # the CSV logs it asks for are not there: a run, refused as before
    assert "holds a finished run" in capsys.readouterr().err
    other = tmp_path / "leg2.yaml"  # another leg: the logs are of the bundled one
    other.write_text(resources.bundled_model().read_text().replace("gravity: 9.81", "gravity: 9.0", 1))
    try:
        assert cli.main(["--model", str(other), *argv]) == 2
    finally:
        resources.select_model(None)
    assert "holds a finished run" in capsys.readouterr().err
    assert cli.main(argv) == 0
    said = capsys.readouterr().out.splitlines()
    assert said[0] == (f"t: {out}: every backend finished in an earlier run of the same scenario, settings and leg, "
                       f"which has no comparison yet: kept as it is and compared only, as legbench compare {out} "
                       "would (--force runs it again)")  # fmt: skip
    assert said[1] == f"report: {out / 'report.html'}"
    assert (out / "metrics.json").is_file() and (out / "report.html").is_file()
    assert {n: (out / n).read_bytes() for n in kept} == kept  # the run itself untouched
    assert cli.main(argv) == 2  # now finished with its comparison: refused as before
    assert "holds a finished run" in capsys.readouterr().err


def test_check_against_another_scenarios_baseline_names_the_mismatch(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    dirs = []
    for name in ("a", "b"):
        f = _fake_run(tmp_path, monkeypatch, name)
        out = tmp_path / f"r_{name}"
        assert cli.main(["run", str(f), "--backends", "fake", "--out", str(out), "-q", "--no-preflight"]) in (0, 3)
        dirs.append(out)
    assert cli.main(["check", str(dirs[0]), "--baseline", str(dirs[1])]) == 2
    err = capsys.readouterr().err
    assert "holds scenario 'a' but the baseline" in err and "'b'" in err


def test_run_without_out_never_replaces_a_finished_run(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                       capsys: pytest.CaptureFixture[str]) -> None:  # fmt: skip
    f = _fake_run(tmp_path, monkeypatch)
    monkeypatch.chdir(tmp_path)
    argv = ["run", str(f), "--backends", "fake", "-q", "--no-compare", "--no-preflight"]
    assert cli.main(argv) == 0
    meta = tmp_path / "results" / "latest" / "t" / "run.json"
    before = meta.read_bytes()
    assert cli.main(argv) == 2
    err = capsys.readouterr().err
    assert "holds a finished run; pass --out DIR for a new one, or --force" in err and err.count("\n") == 1
    assert meta.read_bytes() == before
    assert cli.main([*argv, "--force"]) == 0


def test_run_with_out_never_replaces_a_finished_run_without_force(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """A run into an --out that holds a finished run of the same scenario is refused in one line naming --force
    (exit 2, the run untouched; it was silently replaced), replaced with --force, but not while it holds a file of
    the user's (refused even with --force, naming it: the replacement would delete it). An interrupted run there
    (``"complete": false``, no backend finished) is resumed without --force; one of other settings (another
    --set) is not, and needs --force as well."""
    import json

    f = _fake_run(tmp_path, monkeypatch)
    out = tmp_path / "r"
    argv = ["run", str(f), "--backends", "fake", "--out", str(out), "-q", "--no-compare", "--no-preflight"]
    assert cli.main(argv) == 0
    before = (out / "run.json").read_bytes()
    capsys.readouterr()
    assert cli.main(argv) == 2
    err = capsys.readouterr().err
    assert f"{out} holds a finished run; choose another --out for a new one, or --force" in err  # --out given
    assert err.count("\n") == 1
    assert (out / "run.json").read_bytes() == before
    (out / "mine.txt").write_text("kept")  # what a replacement would lose
    assert cli.main([*argv, "--force"]) == 2  # a file of the user's in it: not replaced even with --force
    err = capsys.readouterr().err
    assert "holds mine.txt" in err and err.count("\n") == 1 and (out / "mine.txt").read_text() == "kept"
    (out / "mine.txt").unlink()
    assert cli.main([*argv, "--force"]) == 0
    meta = json.loads((out / "run.json").read_text())
    meta["backends"]["fake"] |= {"status": "interrupted", "reason": "interrupted at t = 0.0000 s"}
    interrupted = json.dumps({**meta, "complete": False})  # as Ctrl-C before the backend finished leaves it
    (out / "run.json").write_text(interrupted)
    assert cli.main([*argv, "--set", "duration=1.9"]) == 2  # still past the trajectory's last waypoint (1.8 s)
    err = capsys.readouterr().err
    assert "holds an interrupted run of other settings" in err and "--force" in err and err.count("\n") == 1
    assert (out / "run.json").read_text() == interrupted
    assert cli.main(argv) == 0
    meta = json.loads((out / "run.json").read_text())
    assert meta["complete"] is True and meta["backends"]["fake"]["status"] == "ok"


def test_an_interrupted_run_of_another_leg_is_not_resumed(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """An interrupted run (fake finished, fake2 interrupted) of the bundled leg, rerun with ``--model`` of another
    leg (gravity 9.0 instead of 9.81; the same scenario, hash and backends): resuming it would put two legs' logs in
    one run, so it is an interrupted run of other settings, refused in one line naming --force (exit 2), the
    directory as it was; run.json's ``urdf`` names the leg it is of. The bundled leg resumes it. A mutation audit
    found no test of the resume with another leg (only of a finished run's comparison)."""
    f = _fake_run(tmp_path, monkeypatch)
    reg = registry._registry
    monkeypatch.setattr(
        registry, "_registry", lambda: {**reg(), "fake2": type("fake2", (FakeBackend,), {"name": "fake2"})}
    )
    out = tmp_path / "r"
    argv = ["run", str(f), "--backends", "fake,fake2", "--out", str(out), "-q", "--no-compare", "--no-preflight"]
    assert cli.main(argv) == 0
    meta = json.loads((out / "run.json").read_text())
    assert meta["urdf"] == resources.urdf_name()  # the bundled leg's
    meta["complete"] = False
    meta["backends"]["fake2"] |= {"status": "interrupted", "reason": "interrupted at t = 1.0000 s"}
    (out / "run.json").write_text(json.dumps(meta))
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    other = tmp_path / "leg2.yaml"
    other.write_text(resources.bundled_model().read_text().replace("gravity: 9.81", "gravity: 9.0", 1))
    capsys.readouterr()
    try:
        assert cli.main(["--model", str(other), *argv]) == 2
    finally:
        resources.select_model(None)
    err = capsys.readouterr().err
    assert err == (f"legbench: error: {out} holds an interrupted run of other settings (it resumes only with the same "
                   "scenario and options); choose another --out for a new one, or --force to replace it\n")  # fmt: skip
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    assert cli.main(argv) == 0  # the leg it is of: resumed, fake's log kept
    assert (out / "fake.parquet").read_bytes() == before["fake.parquet"]
    assert json.loads((out / "run.json").read_text())["complete"] is True


def test_check_replaces_an_existing_summary_or_junit_file_only_with_force(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """``legbench check --summary FILE`` / ``--junit FILE`` naming an existing file: one line naming --force,
    exit 2, the file untouched (it was overwritten); with --force it is replaced. The defaults in the results
    directory (check.md, check-junit.xml) are rewritten on every check."""
    f = _fake_run(tmp_path, monkeypatch)
    dirs = []
    for name in ("new", "base"):
        dirs.append(tmp_path / name)
        assert cli.main(["run", str(f), "--backends", "fake", "--out", str(dirs[-1]), "-q", "--no-preflight"]) == 0
    check = ["check", str(dirs[0]), "--baseline", str(dirs[1])]
    assert cli.main(check) == 0 and cli.main(check) == 0
    assert (dirs[0] / "check.md").is_file() and (dirs[0] / "check-junit.xml").is_file()
    for opt in ("--summary", "--junit"):
        mine = tmp_path / f"mine{opt}"
        mine.write_text("my notes")
        capsys.readouterr()
        assert cli.main([*check, opt, str(mine)]) == 2
        err = capsys.readouterr().err
        assert f"{opt} {mine}: exists" in err and "--force" in err and err.count("\n") == 1
        assert mine.read_text() == "my notes"
        assert cli.main([*check, opt, str(mine), "--force"]) == 0
        assert mine.read_text() != "my notes"


def test_an_out_that_is_not_writable_is_refused_before_any_work_exit_2(
    readonly_dir: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """--out in a place that is not writable is bad input found before any work (README: exit 2, one line,
    nothing written); exit 4 is a write that fails while writing (test_full_disk_...)."""
    before = sorted(p.name for p in readonly_dir.iterdir())
    assert cli.main(["run", str(EFFORT), "--backends", "pinocchio", "--out", str(readonly_dir / "run"), "-q"]) == 2
    err = capsys.readouterr().err
    assert "is not writable" in err and err.count("\n") == 1
    assert sorted(p.name for p in readonly_dir.iterdir()) == before


def test_two_scenarios_with_one_name_are_refused(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                 capsys: pytest.CaptureFixture[str]) -> None:  # fmt: skip
    f = _fake_run(tmp_path, monkeypatch)
    g = tmp_path / "copy.yaml"
    g.write_text(f.read_text())
    out = tmp_path / "tree"
    assert cli.main(["run", str(f), str(g), "--backends", "fake", "--out", str(out), "-q", "--no-preflight"]) == 2
    assert "collide" in capsys.readouterr().err
    assert not out.exists()


# --------------------------------------------------------------------------- #
# Atomic writes


def test_atomic_dir_keeps_the_previous_result_on_failure(tmp_path: Path) -> None:
    d = tmp_path / "run"
    with results.atomic_dir(d) as tmp:
        (tmp / "a.txt").write_text("one")
    with pytest.raises(RuntimeError), results.atomic_dir(d) as tmp:
        (tmp / "a.txt").write_text("two, half")
        raise RuntimeError("killed while writing")
    assert (d / "a.txt").read_text() == "one"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]


def _dead_pid() -> int:
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


def test_temporaries_of_killed_runs_are_cleaned(tmp_path: Path) -> None:
    dead = _dead_pid()
    (tmp_path / f".effort.tmp-{dead}").mkdir()
    (tmp_path / f".effort.tmp-{dead}" / "pinocchio.parquet").write_bytes(b"x" * 100)
    (tmp_path / f".sweep.out.tmp-{dead}").mkdir()
    (tmp_path / f".metrics.json.tmp-{dead}").write_text("{")
    (tmp_path / f".position.old-{dead}").mkdir()  # a kill between the two renames of a swap
    (tmp_path / f".position.old-{dead}" / "run.json").write_text("{}")
    (tmp_path / f".live.tmp-{os.getpid()}").mkdir()  # ours, alive: kept
    results.clean_stale(tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == [f".live.tmp-{os.getpid()}", "position"]
    assert (tmp_path / "position" / "run.json").is_file()


def test_a_stale_displaced_copy_never_replaces_the_current_result(tmp_path: Path) -> None:
    """A ``.<name>.old-<dead pid>`` is put back only where ``<name>`` is missing (a kill between the two renames of
    a swap): beside an existing ``<name>`` (the swap's new result went in, the kill came before the old one was
    removed) it is removed, and the current result stays byte for byte: a run directory whose run.json reads
    "new" and a file reading "new", each beside an "old" copy. A mutation audit found only the missing-target case
    tested (renaming the stale copy back over the file passed)."""
    dead = _dead_pid()
    (tmp_path / "position").mkdir()
    (tmp_path / "position" / "run.json").write_bytes(b"new")
    (tmp_path / f".position.old-{dead}").mkdir()
    (tmp_path / f".position.old-{dead}" / "run.json").write_bytes(b"old")
    (tmp_path / "report.md").write_bytes(b"new")
    (tmp_path / f".report.md.old-{dead}").write_bytes(b"old")
    removed = results.clean_stale(tmp_path)
    assert (tmp_path / "report.md").read_bytes() == b"new"
    assert (tmp_path / "position" / "run.json").read_bytes() == b"new"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["position", "report.md"]
    assert sorted(p.name for p in removed) == [f".position.old-{dead}", f".report.md.old-{dead}"]


def test_temporaries_of_another_users_live_process_are_kept(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """``os.kill(pid, 0)`` raising PermissionError means the process exists and belongs to another user (a shared
    results folder): its temporaries are that live run's, kept. PID 4194303 (Linux's largest), with os.kill
    patched to answer EPERM: a ``.effort.tmp-`` directory holding a log, a ``.metrics.json.tmp-`` file and a
    ``.position.old-`` directory stay as they were, and nothing is reported removed. A mutation audit found no test
    holding it (taking EPERM for a dead process passed)."""
    import errno

    pid = 4194303
    asked: list[tuple[int, int]] = []

    def not_yours(p: int, sig: int) -> None:
        asked.append((p, sig))
        raise PermissionError(errno.EPERM, os.strerror(errno.EPERM))

    (tmp_path / f".effort.tmp-{pid}").mkdir()
    (tmp_path / f".effort.tmp-{pid}" / "pinocchio.parquet").write_bytes(b"x" * 100)
    (tmp_path / f".metrics.json.tmp-{pid}").write_text("{")
    (tmp_path / f".position.old-{pid}").mkdir()
    before = sorted(p.name for p in tmp_path.iterdir())
    monkeypatch.setattr(os, "kill", not_yours)
    assert results.clean_stale(tmp_path) == []
    assert asked == [(pid, 0)] * 3
    assert sorted(p.name for p in tmp_path.iterdir()) == before
    assert (tmp_path / f".effort.tmp-{pid}" / "pinocchio.parquet").read_bytes() == b"x" * 100


_FULL_DISK = """
import resource, sys
from pathlib import Path
from legbench import cli
resource.setrlimit(resource.RLIMIT_FSIZE, (2000, 2000))
sys.exit(cli.main(["model", "urdf", "--out", sys.argv[1], "--force"]))  # "previous" is not a generated URDF
"""


def test_full_disk_is_one_line_exit_4_and_the_previous_file_intact(tmp_path: Path) -> None:
    """RLIMIT_FSIZE (2 KB, the URDF is ~10 KB) stands for a full disk: the write fails with EFBIG
    (SIGXFSZ ignored so the process sees the error)."""
    target = tmp_path / "leg.urdf"
    target.write_text("previous")
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    code = "import signal; signal.signal(signal.SIGXFSZ, signal.SIG_IGN)\n" + _FULL_DISK
    proc = subprocess.run([sys.executable, "-c", code, str(target)], capture_output=True, text=True, env=env,
                          timeout=300)  # fmt: skip
    assert proc.returncode == 4, proc.stderr
    err = [ln for ln in proc.stderr.splitlines() if ln.startswith("legbench")]
    assert len(err) == 1 and "I/O error" in err[0] and "Traceback" not in proc.stderr
    assert target.read_text() == "previous"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["leg.urdf"]


@pytest.fixture
def readonly_dir(tmp_path: Path) -> Iterator[Path]:
    """A read-only tmpfs (root ignores chmod); skipped where mounting is not allowed."""
    d = tmp_path / "ro"
    d.mkdir()
    if os.geteuid() != 0:
        (d / "metrics.json").write_text("previous")
        d.chmod(0o555)
        yield d
        d.chmod(0o755)
        return
    ok = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=1m", "tmpfs", str(d)], capture_output=True)
    if ok.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs as root here: {ok.stderr.decode().strip()}")
    (d / "metrics.json").write_text("previous")
    subprocess.run(["mount", "-o", "remount,ro", str(d)], check=True)
    yield d
    subprocess.run(["umount", str(d)], check=False)


def test_read_only_output_keeps_the_previous_file(readonly_dir: Path) -> None:
    target = readonly_dir / "metrics.json"
    with pytest.raises(OSError):
        results.atomic_write_text(target, "new")
    assert target.read_text() == "previous"
    with pytest.raises(LegbenchError, match="not writable"):
        results.check_out_path(readonly_dir / "run")


_cli_docs = st.fixed_dictionaries(
    {"name": st.one_of(st.just("t"), st.text(max_size=6)), "duration": st.one_of(st.just(0.01), _scalars)},
    optional={k: _values for k in scenario.TOP_KEYS if k not in ("name", "duration")},
)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow,
                                                                  HealthCheck.function_scoped_fixture])  # fmt: skip
@given(doc=_cli_docs, good_events=st.booleans())
def test_generated_documents_through_the_cli_exit_0_or_2_never_a_traceback(
    tmp_path_factory: pytest.TempPathFactory,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
    doc: dict[str, Any],
    good_events: bool,
) -> None:
    """``legbench validate`` and ``legbench run`` (the fake backend, 10 ms) on generated documents: every
    outcome is exit 0 or exit 2 with one line per problem on stderr, each 'legbench: error: ' and no traceback;
    anything else fails the test."""
    reg = registry._registry
    monkeypatch.setattr(registry, "_registry", lambda: {**reg(), "fake": FakeBackend})
    if good_events:
        doc = {**doc, "events": [{"t": 0.0, "position": {"joint": [0.0, -1.0, -1.0]}}]}
    d = tmp_path_factory.mktemp("gen")
    f = d / "gen.yaml"
    f.write_text(yaml.safe_dump(doc))
    for argv in (["validate", str(f)],
                 ["run", str(f), "--backends", "fake", "--out", str(d / "out"), "-q", "--no-compare",
                  "--no-preflight"]):  # fmt: skip
        capsys.readouterr()
        status = cli.main(argv)
        err = capsys.readouterr().err
        assert status in (0, 2), argv
        if status == 2:
            lines = err.splitlines()
            assert lines and all(line.startswith("legbench: error: ") for line in lines), (argv, err)
            assert "Traceback" not in err, (argv, err)
            assert argv[0] == "validate" or len(lines) == 1, (argv, err)  # run: the first problem, one line


def test_schema_accepts_every_bundled_scenario_and_refuses_bad_ones(capsys: pytest.CaptureFixture[str]) -> None:
    """``legbench schema`` is a valid JSON Schema (draft 2020-12) that every bundled scenario satisfies and that
    refuses what the validator refuses by shape (unknown key, negative duration, two controllers in one event)."""
    import json

    jsonschema = pytest.importorskip("jsonschema")
    assert cli.main(["schema"]) == 0
    schema = json.loads(capsys.readouterr().out)
    jsonschema.Draft202012Validator.check_schema(schema)
    v = jsonschema.Draft202012Validator(schema)
    files = [p for p in sorted((ROOT / "scenarios").rglob("*.yaml")) if "sweeps" not in p.parts
             and p.name != "reproduce.yaml"]  # fmt: skip
    assert len(files) >= 10
    for f in files:
        assert [e.message for e in v.iter_errors(yamlfile.read_yaml(f)[0])] == [], f
    assert not v.is_valid(GOOD | {"duraton": 1.0})
    assert not v.is_valid(GOOD | {"duration": -1.0})
    assert not v.is_valid(_set(GOOD, "events.0.effort", {"force": [0, 0, 1]}))
    assert v.is_valid(GOOD)


def test_external_logs_with_implausible_values_or_units(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    """1e308 or NaN-only angles are refused; ms and degrees are accepted with a warning giving the evidence
    (a 1 kHz log in ms has 1 s steps; 57 'rad' is one radian in degrees)."""
    import numpy as np
    import pandas as pd

    from legbench import logs
    from legbench.exceptions import ResultsError

    t = np.arange(21) * 1e-3

    def csv(name: str, tt: np.ndarray, q: float) -> Path:
        f = tmp_path / name
        pd.DataFrame({"t": tt, **{f"q{i}": np.full(len(tt), q) for i in (1, 2, 3)}}).to_csv(f, index=False)
        return f

    with pytest.raises(ResultsError, match="reaches 1e\\+308"):
        logs.load_log(csv("big.csv", t, 1e308))
    with pytest.raises(ResultsError, match="NaN only"):
        logs.load_log(csv("nan.csv", t, float("nan")))
    with pytest.raises(LegbenchError, match="--log-time-scale"):
        logs.load_log(csv("ok.csv", t, 0.0), time_scale=0.0)
    caplog.clear()
    assert len(logs.load_log(csv("ms.csv", t * 1000, 0.0))) == 21
    assert "median time step 1 s" in caplog.text
    caplog.clear()
    assert len(logs.load_log(csv("deg.csv", t, -57.0))) == 21
    assert "degrees" in caplog.text and "57" in caplog.text
    caplog.clear()
    logs.load_log(csv("fine.csv", t, -1.0))
    assert caplog.text == ""


def test_a_log_value_beyond_1e9_is_refused_and_1e9_is_read(tmp_path: Path) -> None:
    """The plausibility limit of an external log is 1e9 (SI units) in every column: a ground force fz of exactly
    1e9 N is read, 1.5e9 N is refused naming the column, its row and time and the limit. A mutation audit found
    only 1e308 tested (a limit of 1e10 passed)."""
    import pandas as pd

    from legbench import logs
    from legbench.exceptions import ResultsError

    f = tmp_path / "log.csv"
    for fz in (1e9, 1.5e9):
        pd.DataFrame({"t": [0.0, 1e-3, 2e-3], "q1": 0.1, "q2": -1.0, "q3": -1.2, "fz": [20.0, fz, 20.0]}).to_csv(
            f, index=False
        )
        if fz == 1e9:
            assert logs.load_log(f)["fz"].tolist() == [20.0, 1e9, 20.0]
            continue
        with pytest.raises(ResultsError) as exc:
            logs.load_log(f)
        assert str(exc.value) == (f"{f}: column 'fz' reaches 1.5e+09 at data row 2 (t = 0.001 s): not a physical "
                                  "value (limit 1e+09)")  # fmt: skip


def test_the_degrees_warning_starts_just_above_2_pi_plus_0_1_rad(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """A log's joint angles beyond 2 pi + 0.1 rad (6.3832) are likely degrees, said in a warning; a knee at 6.38
    rad gives none, one at 6.39 rad the warning with that value. A mutation audit found only 57 rad tested (a
    threshold of 4 pi passed)."""
    import pandas as pd

    from legbench import logs

    f = tmp_path / "log.csv"
    for q3, warned in ((6.38, False), (6.39, True)):
        pd.DataFrame({"t": [0.0, 1e-3, 2e-3], "q1": 0.1, "q2": -1.0, "q3": [0.0, q3, 0.0]}).to_csv(f, index=False)
        caplog.clear()
        with caplog.at_level("WARNING", logger="legbench.logs"):
            logs.load_log(f)
        said = f"{f}: joint angles reach {q3:.4g}: above 2 pi rad, are they in degrees?"
        assert (said in caplog.text) is warned and ("degrees" in caplog.text) is warned, caplog.text


@pytest.mark.parametrize(
    ("key", "value", "problem"),
    [
        ("gains.Kp", "[1.0e+308, 1, 1]", "beyond +-1e+12"),  # a product with an error overflows to inf
        ("gains.Kd", "1.0e+13", "beyond +-1e+12"),
        ("backends.pinocchio.rtol", "1.0e-320", "below 1e-30"),  # a subnormal
        ("backends.mujoco.dt", "5.0e-310", "below 1e-30"),
        ("physics.gravity", "1.0e+200", "beyond +-1e+12"),
    ],
)
def test_absurd_magnitudes_are_refused_before_any_engine_loads(
    key: str, value: str, problem: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A finite number no engine can use (beyond +-1e12, or a non-zero below 1e-30: it overflows or underflows
    in the first product) is one line naming the key, exit 2, nothing written."""
    out = tmp_path / "out"
    code = cli.main(["run", str(EFFORT), "--backends", "pinocchio", "--set", f"{key}={value}", "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2
    assert key in err and problem in err and len(err.strip().splitlines()) == 1
    assert not out.exists()


def test_absurd_leg_parameters_are_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A leg parameter file with a density of 1e300 kg/m^3 (its inertias overflow) is refused, naming the key."""
    text = (ROOT / "models" / "leg.yaml").read_text()
    raw = yaml.safe_load(text)
    first = next(iter(raw["materials"]))
    raw["materials"][first] = 1.0e300
    bad = tmp_path / "leg.yaml"
    bad.write_text(yaml.safe_dump(raw))
    assert cli.main(["--model", str(bad), "model", "check"]) == 2
    err = capsys.readouterr().err
    assert f"materials.{first}" in err and "beyond +-1e+12" in err


@pytest.mark.parametrize(
    ("argv", "words"),
    [
        (["run", "scenarios/sweeps/timestep.yaml"], "is a sweep file (it has 'studies'), not a scenario: run it "
                                                     "with legbench sweep"),
        (["run", "scenarios/reproduce.yaml"], "is a framework file (it has 'frameworks'), not a scenario: run it "
                                               "with legbench reproduce"),
        (["sweep", "scenarios/effort.yaml"], "is a scenario (it has 'events'), not a sweep: run it with legbench run"),
    ],
)  # fmt: skip
def test_a_file_of_another_kind_is_named_as_such(
    argv: list[str], words: str, tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """A sweep given to run, a framework file to run, a scenario to sweep: one line saying which kind of file it
    is and the command it belongs to (it said 'scenario: unknown key' or 'duration: unknown key'), exit 2,
    nothing written."""
    monkeypatch.chdir(ROOT)
    out = tmp_path / "o"
    assert cli.main([*argv, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and words in err[0], err
    assert not out.exists()


def test_a_tolerance_file_given_as_a_scenario_is_named_as_such(tmp_path: Path) -> None:
    """A tolerance file where a scenario goes: named as a tolerance file, with where it belongs."""
    f = tmp_path / "tol.yaml"
    f.write_text("sim_error_pct: {abs: 1.0}\nscenarios: {effort: {rms: {rel: 0.1}}}\n")
    with pytest.raises(ScenarioError, match="is a tolerance file, not a scenario: give it to legbench check"):
        scenario.load(f)


@pytest.mark.parametrize("text", ["sim_error_pc:\n  abs: 1\n", "rmse: {abs: 1}\n", "my_metric: {rel: 0.1}\n"])
def test_a_misspelt_tolerance_file_given_as_a_scenario_is_named_as_one(
    text: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """validate and run told a tolerance file from a scenario by two rules: validate's took a file whose every key
    was misspelt (``sim_error_pc``), run's only exact keys, so run said "unknown key 'sim_error_pc'; valid keys:
    name, ..." and "missing required key 'name'". One rule now (``scenario.is_tolerance_file``): both name it a
    tolerance file in one line, exit 2."""
    f = tmp_path / "tol.yaml"
    f.write_text(text)
    with pytest.raises(ScenarioError, match="is a tolerance file, not a scenario: give it to legbench check") as err:
        scenario.load(f)
    assert "\n" not in str(err.value)
    out = tmp_path / "o"
    assert cli.main(["run", str(f), "--backends", "pinocchio", "--out", str(out)]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and "is a tolerance file" in lines[0], lines
    assert not out.exists()
    assert scenario.is_tolerance_file({"name": "x", "rms": {"abs": 1}}) is False  # a scenario key: a scenario


def test_a_leg_parameter_file_given_as_a_scenario_is_named_as_such() -> None:
    """`legbench run models/leg.yaml` printed "unknown key" for each of its sections, then "missing required key
    'name'": now one error naming it a leg parameter file and the option that takes it."""
    with pytest.raises(ScenarioError, match=r"leg\.yaml: is a leg parameter file, not a scenario: give it to legbench "
                                            r"--model") as err:  # fmt: skip
        scenario.load(ROOT / "models" / "leg.yaml")
    assert "\n" not in str(err.value)


# --------------------------------------------------------------------------- #
# Found by fuzzing the command line (each test failed before its fix)


@pytest.mark.parametrize(
    ("setting", "key"),
    [
        ("backends.*.dt=1e-4", "backends.*"),  # '*' is a sweep's; the override made the unknown backend '*'
        ("gains.Kq.x=1", "gains.Kq"),  # blamed on the file's line of gains:, which holds nothing wrong
        ("bogus.x=1", "bogus"),
    ],
)
def test_an_error_above_an_overridden_key_names_the_override(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], setting: str, key: str
) -> None:
    """An override that creates or changes the keys above its own (``--set backends.*.dt``: the backend ``*``)
    is refused at such a key: the message said nothing of ``--set`` and named the file's line of the nearest
    key the file has (``gains:``), which holds nothing wrong."""
    out = tmp_path / "out"
    assert cli.main(["run", str(EFFORT), "--backends", "pinocchio", "--out", str(out), "-q", "--set", setting]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"{EFFORT}: {key}: " in err, err
    assert f"(from --set {setting.split('=')[0]})" in err
    assert not out.exists()


def test_user_text_with_a_line_break_stays_on_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A file name or a value with a newline, quoted in a message, broke it into two lines (a sweep's
    ``scenario: "a\\nb"``, a missing file named so): it is escaped, the message one line."""
    sw = tmp_path / "sw.yaml"
    sw.write_text('name: s\nscenario: "no\\nsuch.yaml"\nstudies:\n  - {backends: [pinocchio], reference: '
                  "{backend: pinocchio}}\n")  # fmt: skip
    missing = tmp_path / "two\nlines.yaml"
    for argv in (["validate", str(sw)], ["validate", str(missing)], ["sweep", str(sw), "--out", str(tmp_path / "o")],
                 ["run", str(missing), "--out", str(tmp_path / "o")]):  # fmt: skip
        assert cli.main(argv) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "\\n" in err, (argv, err)
    assert not (tmp_path / "o").exists()


def test_a_path_too_long_for_the_file_system_is_bad_input_not_an_io_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A name longer than the file system allows (ENAMETOOLONG) in --out, a sweep's scenario or a framework
    file's task was an 'I/O error', exit 4 (after the runs, for --out), naming neither the option nor the key:
    it is bad input, one line naming them, exit 2, nothing written."""
    long = "x" * 300
    out = tmp_path / long
    assert cli.main(["run", str(EFFORT), "--backends", "pinocchio", "--out", str(out), "-q"]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"legbench: error: --out {out}: ") and "too long" in err and err.count("\n") == 1
    sw = tmp_path / "sw.yaml"
    sw.write_text(f"name: s\nscenario: {long}.yaml\nstudies:\n  - {{backends: [pinocchio], reference: "
                  "{backend: pinocchio}}\n")  # fmt: skip
    fw = tmp_path / "fw.yaml"
    fw.write_text(f"frameworks:\n  - {{name: S, backend: pinocchio, profile: ode45}}\ntasks:\n"
                  f"  - {{file: {long}.yaml, tables: [force]}}\n")  # fmt: skip
    for f, key in ((sw, "scenario"), (fw, "tasks[0].file")):
        assert cli.main(["validate", str(f)]) == 2
        err = capsys.readouterr().err
        assert f"{f}:" in err and f": {key}: " in err and "too long" in err and err.count("\n") == 1, err
    assert cli.main(["compare", str(out)]) == 2
    assert "too long" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fw.yaml", "sw.yaml"]


def test_an_out_inside_a_run_directory_is_refused(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """``--out RUN/sub`` (RUN a run directory, alone or in a tree) wrote a second run inside the first, where it
    is taken for part of it or lost with it: refused in one line before any work, exit 2, the run untouched."""
    f = _fake_run(tmp_path, monkeypatch)
    run_dir = tmp_path / "r"
    common = ["--backends", "fake", "-q", "--no-preflight", "--no-compare"]
    assert cli.main(["run", str(f), *common, "--out", str(run_dir)]) == 0
    before = sorted(p.name for p in run_dir.iterdir())
    for cmd in (["run", str(f), *common], ["sweep", str(ROOT / "scenarios/sweeps/gains.yaml")]):
        capsys.readouterr()
        assert cli.main([*cmd, "--out", str(run_dir / "sub" / "deeper")]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and f"inside the run directory {run_dir}," in err, err
    assert sorted(p.name for p in run_dir.iterdir()) == before


def test_a_tree_into_a_folder_of_someone_elses_is_refused_and_legbench_s_own_is_not(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """``legbench run a.yaml b.yaml --out DIR`` writes a tree: a run directory per run and the index pages
    report.html, report.md and assets/ in DIR itself, where a user's own report.html was replaced without a
    word. A DIR holding anything legbench did not write is refused in one line before any work, exit 2, DIR as
    it was; a tree holding legbench's own outputs (run directories, a study's directory, the pages) is run into."""
    a, b = _fake_run(tmp_path, monkeypatch, "a"), _fake_run(tmp_path, monkeypatch, "b")
    common = ["--backends", "fake", "-q", "--no-preflight", "--no-compare"]
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "report.html").write_text("my page")
    (mine / "notes.txt").write_text("mine")
    assert cli.main(["run", str(a), str(b), *common, "--out", str(mine)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "not a legbench results tree directory (it holds notes.txt)" in err, err
    assert sorted(p.name for p in mine.iterdir()) == ["notes.txt", "report.html"]
    tree = tmp_path / "tree"
    (tree / "verification").mkdir(parents=True)
    (tree / "verification" / "verification.json").write_text("{}")
    (tree / "assets").mkdir()
    (tree / "report.html").write_text("<title>legbench: comparison summary</title>")  # an index legbench wrote
    (tree / "check.md").write_text("# legbench check")  # a regression check's default summary
    assert cli.main(["run", str(a), str(b), *common, "--out", str(tree)]) == 0
    assert {"a", "b", "verification", "check.md"} <= {p.name for p in tree.iterdir()}
    # a report.md of the user's is refused before the runs (the index replaced it only after them)
    (tree / "report.md").write_text("# my notes\n")
    capsys.readouterr()
    assert cli.main(["run", str(a), str(b), *common, "--out", str(tree), "--force"]) == 2
    assert capsys.readouterr().err == (f"legbench: error: {tree / 'report.md'}: not an index legbench wrote, and this "
                                       "results tree's index goes there; move it away first\n")  # fmt: skip
    assert (tree / "report.md").read_text() == "# my notes\n"


def test_an_out_that_is_a_dangling_link_is_refused_before_any_work(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """``--out LINK`` (a symbolic link to nothing) ran every backend and then failed to move the result into
    place: 'I/O error ... Not a directory', exit 4. It is refused before the run, exit 2, the link as it was."""
    f = _fake_run(tmp_path, monkeypatch)
    link = tmp_path / "link"
    link.symlink_to(tmp_path / "nowhere")
    ran: list[object] = []
    from legbench import run

    monkeypatch.setattr(run, "run_many", lambda *a, **k: ran.append(a))
    assert cli.main(["run", str(f), "--backends", "fake", "-q", "--no-preflight", "--out", str(link)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"--out {link}: a symbolic link to" in err and "does not exist" in err
    assert ran == [] and link.is_symlink() and sorted(p.name for p in tmp_path.iterdir()) == ["link", "t.yaml"]


def test_jobs_beyond_the_runs_start_no_more_workers_than_runs(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """``--jobs 64`` for two runs started 64 worker processes (each importing every engine; --jobs 10000 would
    start 10000): the pool is as large as the runs, at most."""
    from legbench import run

    f = _fake_run(tmp_path, monkeypatch)
    asked: list[int] = []

    def start(jobs: int, tasks: int | None = None, backend_names: Any = None) -> None:
        asked.append(run.LocalExecutor(jobs, tasks=tasks).jobs)  # the pool it would start (no process yet)
        raise LegbenchError("stopped before the runs")

    monkeypatch.setattr(run, "start_pool", start)
    argv = ["run", str(f), "--backends", "fake,pinocchio", "-q", "--no-preflight", "--jobs", "64", "--out",
            str(tmp_path / "o")]  # fmt: skip
    assert cli.main(argv) == 2
    assert asked == [2]


@pytest.mark.parametrize(
    ("text", "key", "words"),
    [
        ("[]\n", "", "top level must be a mapping"),  # a list (or 0, false) was taken for 'no tolerances'
        ("false\n", "", "top level must be a mapping"),
        ("scenarios: []\n", "scenarios", "must be a mapping"),
        ("max_sim_error_pct: {7: 1, q: 5}\n", "max_sim_error_pct.7", "unknown component"),
        ("rms: {abs: {qq: 1.0e-3}}\n", "rms.abs.qq", "unknown component"),  # a typo left the default in force
        ("rms: {abs: .inf}\n", "rms.abs", "finite"),
    ],
)
def test_malformed_tolerance_files_are_refused_by_check(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], text: str, key: str, words: str
) -> None:
    """``legbench check --tolerances FILE``: one line naming the file and the key, exit 2, no check.md written."""
    from fakerun import scale, write_run

    new = write_run(tmp_path / "new", {"ref": None, "a": scale(1.01)})
    base = write_run(tmp_path / "base", {"ref": None, "a": scale(1.01)})
    tol = tmp_path / "tol.yaml"
    tol.write_text(text)
    assert cli.main(["check", str(new), "--baseline", str(base), "--tolerances", str(tol)]) == 2
    err = capsys.readouterr().err
    where = re.escape(str(tol)) + r"(:1)?: " + (re.escape(key) + ": " if key else "")  # the line where it is known
    assert err.count("\n") == 1 and re.search(where, err) and words in err, err
    assert not (new / "check.md").exists()


def test_an_external_log_with_an_absurd_foot_position_is_refused(tmp_path: Path) -> None:
    """The foot centre of a CSV log (ee_x..ee_z) was taken unchecked: 1e300 m passed, and the report's float32
    figures overflowed (a RuntimeWarning on stderr). It is refused as the signals are, naming the column."""
    import numpy as np
    import pandas as pd

    from legbench import logs
    from legbench.exceptions import ResultsError

    t = np.arange(21) * 1e-3
    f = tmp_path / "foot.csv"
    cols = {"t": t, **{f"q{i}": np.zeros(21) for i in (1, 2, 3)}, "ee_x": np.full(21, 1e300)}
    pd.DataFrame(cols).to_csv(f, index=False)
    with pytest.raises(ResultsError, match=r"column 'ee_x' reaches 1e\+300 at data row 1 \(t = 0 s\): not a physical "):
        logs.load_log(f)


# --------------------------------------------------------------------------- #
# A plug-in's own bugs fail that backend alone


class _StepTypeError(FakeBackend):
    """A plug-in whose step raises an error of its own after 5 ticks (not one of legbench's)."""

    name = "steptypeerror"

    def step(self, tau: Any) -> None:
        if len(self.steps) >= 5:
            raise TypeError("plug-in bug")
        super().step(tau)


class _InfoRaises(FakeBackend):
    name = "inforaises"

    def info(self) -> dict[str, Any]:
        raise KeyError("engine")


class _InfoContactText(FakeBackend):
    """info()['contact'] as text: verification and calibration read it as a mapping (poc, Kp)."""

    name = "infocontacttext"

    def info(self) -> dict[str, Any]:
        return {**super().info(), "contact": "the spec's law"}


def test_any_error_of_a_backend_fails_it_alone(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A plug-in raising TypeError in step() took the whole run down (the loop caught legbench's errors and three
    numeric ones only); an info() that raises or breaks the keys legbench reads did the same after the run. Now
    each fails alone with the reason, its log kept up to the error, and the fake beside them runs to the end."""
    from legbench import run

    reg = registry._registry
    extra = {c.name: c for c in (_StepTypeError, _InfoRaises, _InfoContactText, FakeBackend)}
    monkeypatch.setattr(registry, "_registry", lambda: {**reg(), **extra})
    doc = {"name": "t", "duration": 0.02, "events": GOOD["events"][:1], "comparison": {"steady_window": 0.01}}
    sc = scenario.parse(doc, "t.yaml")
    (res,) = run.run_many([(sc, None, tmp_path / "t")], list(extra), jobs=1, progress=False)
    got = {tr.backend: tr for tr in res}
    assert got["steptypeerror"].status == "failed"
    assert got["steptypeerror"].reason == "TypeError at t = 0.0050 s: plug-in bug"
    assert len(got["steptypeerror"].t) == 6  # the ticks up to the error kept, its own row read before the step
    assert got["inforaises"].status == "failed" and got["inforaises"].reason == "info() failed: KeyError: 'engine'"
    assert got["infocontacttext"].status == "failed"
    assert (got["infocontacttext"].reason or "").startswith("infocontacttext: info() contact: expected a mapping")
    assert got["fake"].status == "ok" and len(got["fake"].t) == sc.n_ticks
    meta = results.read_meta(tmp_path / "t")
    assert {n: b["status"] for n, b in meta["backends"].items()} == {
        "steptypeerror": "failed", "inforaises": "failed", "infocontacttext": "failed", "fake": "ok"
    }  # fmt: skip


@pytest.mark.parametrize(
    ("info", "words"),
    [
        ([("engine", "x")], "expected a mapping of setting -> value, got list"),
        ({1: "x"}, "key 1: expected text keys"),
        ({"contact": "law"}, "contact: expected a mapping"),
        ({"contact": {"poc": "centre-ish"}}, "contact.poc: expected 'true' or 'centre', got 'centre-ish'"),
        ({"contact": {"Kp": "stiff"}}, "contact.Kp: expected a stiffness [N/m] or null (rigid contact), got 'stiff'"),
        ({"contact": {"Kp": True}}, "contact.Kp: expected a stiffness"),
        ({"max_step": "1e-4"}, "max_step: expected a number, got '1e-4'"),
        ({"rtol": None}, "rtol: expected a number, got None"),
    ],
)
def test_info_problem_names_the_key(info: Any, words: str) -> None:
    from legbench.backends.base import info_problem

    assert (info_problem(info) or "").startswith(words)


def test_info_problem_accepts_the_documented_shapes() -> None:
    from legbench.backends.base import info_problem

    assert info_problem({}) is None
    assert info_problem({"engine": "e", "contact": {"poc": "true", "Kp": None}, "max_step": 1e-4, "rtol": 1}) is None
    assert info_problem({"contact": {"poc": "centre", "Kp": 1.0e4}, "atol": np.float64(1e-9)}) is None


def _short_run(cls: type[FakeBackend]) -> Any:
    """A 20 ms hold run on a fresh ``cls`` (a fake plug-in), through run.simulate: its RunResult."""
    from legbench import run

    doc = {"name": "t", "duration": 0.02, "events": GOOD["events"][:1], "comparison": {"steady_window": 0.01}}
    sc = scenario.parse(doc, "t.yaml")
    physics = scenario.physics_of(sc)
    backend = cls()
    backend.load(Path("unused.urdf"), physics, {})
    return run.simulate(sc, backend, physics)


class _ResetRaises(FakeBackend):
    name = "resetraises"

    def reset(self, q: Any, qd: Any) -> None:
        raise TypeError("plug-in bug in reset")


def test_an_engines_error_in_reset_fails_it_alone_and_a_harness_bug_is_not_an_engine_failure(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Only the engine's own calls (reset, read, step) are caught as a failed engine whatever they raise: a
    plug-in's TypeError in reset fails it alone; a TypeError in legbench's own tick is a bug and propagates (it
    would otherwise show as every backend 'failed', exit 3, with no traceback)."""
    from legbench import tick

    tr = _short_run(_ResetRaises)
    assert tr.status == "failed" and tr.reason == "TypeError at t = 0.0000 s: plug-in bug in reset"

    def broken_tick(*args: Any) -> int:
        raise TypeError("a bug in the harness")

    monkeypatch.setattr(tick, "tick", broken_tick)
    with pytest.raises(TypeError, match="a bug in the harness"):
        _short_run(FakeBackend)


class _ColumnState(FakeBackend):
    """A plug-in whose state() gives (3, 1) columns: read() then returns lists, which the compiled tick refuses."""

    name = "columnstate"

    def state(self) -> tuple[Any, Any]:
        q, qd = super().state()
        return q.reshape(3, 1), qd.reshape(3, 1)


class _DivergesInStep(FakeBackend):
    """A plug-in that checks its own state, as the built-ins do (check_finite), and raises SimulationDiverged."""

    name = "divergesinstep"

    def step(self, tau: Any) -> None:
        from legbench.exceptions import SimulationDiverged

        if len(self.steps) >= 3:
            raise SimulationDiverged(self.name, 0.003, "non-finite joint state")
        super().step(tau)


def test_an_engine_read_of_the_wrong_types_or_its_own_divergence_fails_it_alone_with_its_reason() -> None:
    """Two cases the narrowed catch first got wrong (a review): a read() of arrays fails only inside the tick, so
    it propagated as the harness's error; and an engine's own SimulationDiverged, raised in step, was reported as
    'SimulationDiverged at t = ...: div diverged at ...'. Now the first fails that backend naming what read()
    returned, and the second keeps the engine's own sentence."""
    tr = _short_run(_ColumnState)
    assert tr.status == "failed"
    assert tr.reason == "TypeError at t = 0.0000 s: read() returned float, list, not nine floats"
    tr = _short_run(_DivergesInStep)
    assert tr.status == "failed" and tr.reason == "divergesinstep diverged at t = 0.0030 s: non-finite joint state"


@pytest.mark.parametrize(
    ("cmd", "doc", "kind"),
    [
        (["verify", "--backends", "pinocchio", "--cases", "energy"], "verification.json", "verification"),
        (["calibrate-contact", "--backends", "pinocchio"], "calibration.json", "calibration"),
        (["bench", "--quick", "--backends", "pinocchio", "--no-memory"], "bench.json", "bench"),
        (["bench", "--quick", "--backends", "pinocchio", "--parallel", "2"], "scaling.json", "bench"),
    ],
)
def test_a_study_never_replaces_a_finished_one_nor_writes_into_a_foreign_folder(
    cmd: list[str], doc: str, kind: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``verify``, ``calibrate-contact`` and ``bench`` replaced an earlier study in --out (a verify of other cases
    lost the first one's checks) and wrote into a folder of the user's: as run, sweep and reproduce, a finished
    study (its JSON document) is refused without --force and a folder holding anything but the study's own files
    always, before any work: one line, exit 2, the folder as it was."""
    done = tmp_path / "done"
    done.mkdir()
    (done / doc).write_text("{}")
    assert cli.main([*cmd, "--out", str(done), "-q"] if kind == "bench" else [*cmd, "--out", str(done)]) == 2
    assert capsys.readouterr().err == (f"legbench: error: {done} holds a finished {kind} ({doc}); choose another "
                                       "--out for a new one, or --force to replace it\n")  # fmt: skip
    assert [p.name for p in done.iterdir()] == [doc] and (done / doc).read_text() == "{}"
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("mine")
    for extra in ([], ["--force"]):
        assert cli.main([*cmd, "--out", str(mine), *extra]) == 2
        assert capsys.readouterr().err == (f"legbench: error: {mine}: not empty and not a legbench {kind} directory "
                                           "(it holds notes.txt); choose another --out\n")  # fmt: skip
    assert [p.name for p in mine.iterdir()] == ["notes.txt"]


def test_verify_with_force_replaces_its_own_finished_verification(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """--force replaces a finished verification: the second run's cases are what verification.json holds."""
    out = tmp_path / "v"
    cmd = ["verify", "--backends", "pinocchio", "--out", str(out)]
    assert cli.main([*cmd, "--cases", "energy"]) in (0, 1)
    assert cli.main([*cmd, "--cases", "rest_penetration"]) == 2
    assert cli.main([*cmd, "--cases", "rest_penetration", "--force"]) in (0, 1)
    capsys.readouterr()
    cases = {c["case"] for c in json.loads((out / "verification.json").read_text())["checks"]}
    assert cases == {"rest_penetration"}


def test_an_interrupted_run_is_not_resumed_by_a_run_that_drops_one_of_its_backends(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """A run of fake,fake2 interrupted in fake2 (fake finished), then a run of fake,fake3 into the same --out: it
    was taken for a resume and dropped fake2's log without --force. Now refused, one line naming fake2, exit 2,
    the directory as it was; the same backends (or more) resume it, --force replaces it."""
    f = _fake_run(tmp_path, monkeypatch)
    reg = registry._registry
    more = {n: type(n, (FakeBackend,), {"name": n}) for n in ("fake2", "fake3")}
    monkeypatch.setattr(registry, "_registry", lambda: {**reg(), **more})
    out = tmp_path / "r"
    common = [str(f), "--out", str(out), "-q", "--no-compare", "--no-preflight"]
    assert cli.main(["run", *common, "--backends", "fake,fake2"]) == 0
    meta = json.loads((out / "run.json").read_text())
    meta["complete"] = False
    meta["backends"]["fake2"]["status"] = "interrupted"
    (out / "run.json").write_text(json.dumps(meta))
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    capsys.readouterr()
    assert cli.main(["run", *common, "--backends", "fake,fake3"]) == 2
    assert capsys.readouterr().err == (f"legbench: error: {out} holds an interrupted run of other backends too "
                                       "(fake2: it resumes only with them among the backends); choose another --out "
                                       "for a new one, or --force to replace it\n")  # fmt: skip
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    assert cli.main(["run", *common, "--backends", "fake2,fake,fake3"]) == 0  # a resume: fake kept, fake2 run again
    done = json.loads((out / "run.json").read_text())
    assert done.get("complete", True) and {k: v["status"] for k, v in done["backends"].items()} == dict.fromkeys(
        ("fake", "fake2", "fake3"), "ok")  # fmt: skip


def test_an_interrupted_run_resumes_without_a_backend_that_had_not_started(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """fake2 interrupted before it ran (no log): a run of fake alone resumes the directory (nothing is lost: it was
    refused as "of other backends too"), fake's log as it was, fake2 gone from run.json."""
    f = _fake_run(tmp_path, monkeypatch)
    reg = registry._registry
    monkeypatch.setattr(
        registry, "_registry", lambda: {**reg(), "fake2": type("fake2", (FakeBackend,), {"name": "fake2"})}
    )
    out = tmp_path / "r"
    common = [str(f), "--out", str(out), "-q", "--no-compare", "--no-preflight"]
    assert cli.main(["run", *common, "--backends", "fake,fake2"]) == 0
    meta = json.loads((out / "run.json").read_text())
    meta["complete"] = False
    meta["backends"]["fake2"].update(status="interrupted", reason="not run")
    (out / "run.json").write_text(json.dumps(meta))
    (out / "fake2.parquet").unlink()
    log = (out / "fake.parquet").read_bytes()
    assert cli.main(["run", *common, "--backends", "fake"]) == 0
    assert (out / "fake.parquet").read_bytes() == log and list(
        json.loads((out / "run.json").read_text())["backends"]
    ) == ["fake"]
