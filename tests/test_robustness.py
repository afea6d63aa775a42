"""Bad input gets one clear line (file, key path, problem) and exit status 2; nothing is written."""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from legbench import cli, scenario
from legbench.exceptions import ScenarioError

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
    ("name", 42, "name", "plain name"),
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
    assert len(CASES) >= 30
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
