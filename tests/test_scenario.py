"""Scenario files: the four tasks load; bad input names file, key and problem."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from legbench import scenario
from legbench.exceptions import ScenarioError

SCENARIOS = Path(__file__).resolve().parent.parent / "scenarios"
TASKS = ("position", "ellipse", "effort", "combined")


@pytest.mark.parametrize("task", TASKS)
def test_shipped_tasks_load(task: str) -> None:
    sc = scenario.load(SCENARIOS / f"{task}.yaml")
    assert sc.name == task
    assert sc.control_rate == 1000.0
    assert sc.gains.Kp == (10.0, 10.0, 10.0) and sc.gains.Kd == (1.0, 1.0, 1.0)
    assert len(sc.sha256) == 64


def test_ellipse_task_runs_two_laps_after_a_one_second_approach() -> None:
    sc = scenario.load(SCENARIOS / "ellipse.yaml")
    (ev,) = sc.events
    assert ev.times[0] == 1.0 and ev.times[-1] == pytest.approx(11.0)
    assert sc.duration >= ev.times[-1]


def test_validation_scenario_is_gravity_free_sinusoidal_torque_from_rest() -> None:
    """The report's validation run: g = 0, u_i = 0.01 sin(6 pi t) N m on every joint, from q = 0."""
    sc = scenario.load(SCENARIOS / "validation.yaml")
    (ev,) = sc.events
    assert sc.gravity == 0.0 and sc.q0 == (0.0, 0.0, 0.0) and sc.qd0 == (0.0, 0.0, 0.0)
    assert ev.controller == "torque" and ev.t == 0.0
    assert ev.amplitude == (0.01,) * 3 and ev.frequency == (3.0,) * 3 and ev.phase == (0.0,) * 3


def _write(tmp_path: Path, doc: dict) -> Path:  # type: ignore[type-arg]
    p = tmp_path / "s.yaml"
    p.write_text(yaml.safe_dump(doc))
    return p


BASE = {"name": "t", "duration": 1.0, "events": [{"t": 0.0, "position": {"joint": [0, 0, 0]}}]}


@pytest.mark.parametrize(
    ("patch", "key", "words"),
    [
        ({"duraton": 1.0}, "duraton", "did you mean 'duration'"),
        ({"duration": -1.0}, "duration", "must be > 0"),
        ({"events": [{"t": 0.0, "position": {"cartesian": [2.0, 0.0, 0.4]}}]}, "events[0].position.cartesian",
         "unreachable"),
        ({"events": [{"t": 0.0, "position": {"joint": [0, 0, 3.0]}}]}, "events[0].position.joint[2]",
         "outside the joint limits"),
        ({"physics": {"contact": {"Kp": "stiff"}}}, "physics.contact.Kp", "expected a number"),
        ({"events": [{"t": 0.0, "effort": {"force": [0, 0]}}]}, "events[0].effort.force", "list of 3"),
        ({"events": [{"t": 0.0, "torque": {"amplitude": [0.1, 0.1, 0.1]}}]}, "events[0].torque", "frequency"),
        ({"events": [{"t": 0.0, "torque": {"amplitude": [0.1] * 3, "frequency": [1, -1, 1]}}]},
         "events[0].torque.frequency[1]", ">= 0"),
        ({"events": [{"t": 0.0, "position": {"joint": [0, 0, 0]}}, {"t": 2.0, "effort": {"force": [0, 0, -1]}}]},
         "events[1].t", "past the end"),
    ],
)  # fmt: skip
def test_bad_input_names_file_key_and_problem(tmp_path: Path, patch: dict, key: str, words: str) -> None:  # type: ignore[type-arg]
    path = _write(tmp_path, {**BASE, **patch})
    with pytest.raises(ScenarioError) as err:
        scenario.load(path)
    msg = str(err.value)
    assert str(path) in msg
    assert err.value.key == key
    assert words in msg


def test_unreachable_waypoint_is_named(tmp_path: Path) -> None:
    doc = {**BASE, "events": [{"t": 0.0, "trajectory": {"waypoints": [[0.1667, 0.05, 0.1], [0.1667, 0.0, 0.95]],
                                                         "times": [0.5, 1.0]}}]}  # fmt: skip
    with pytest.raises(ScenarioError) as err:
        scenario.load(_write(tmp_path, doc))
    assert err.value.key == "events[0].trajectory.waypoints[1]"


def test_malformed_yaml_gives_the_line(tmp_path: Path) -> None:
    p = tmp_path / "bad.yaml"
    p.write_text("name: t\nduration: 1.0\nevents: [\n  {t: 0.0\n")
    with pytest.raises(ScenarioError) as err:
        scenario.load(p)
    assert "malformed YAML" in str(err.value)
    assert err.value.line is not None


def test_error_line_points_at_the_bad_key(tmp_path: Path) -> None:
    p = tmp_path / "s.yaml"
    text = "name: t\nduration: 1.0\nevents:\n  - t: 0.0\n    position: {joint: [0, 0, 0]}\n"
    p.write_text(text + "physics:\n  gravty: 9.81\n")
    with pytest.raises(ScenarioError) as err:
        scenario.load(p)
    assert err.value.key == "physics.gravty" and err.value.line == 7


def test_unknown_backend_setting_is_an_error(tmp_path: Path) -> None:
    with pytest.raises(ScenarioError) as err:
        scenario.load(_write(tmp_path, {**BASE, "backends": {"pinocchio": {"intgrator": "rk4"}}}))
    assert err.value.key == "backends.pinocchio.intgrator"
    with pytest.raises(ScenarioError) as err:
        scenario.load(_write(tmp_path, {**BASE, "backends": {"pinocchio": {"integrator": "leapfrog"}}}))
    assert "expected one of" in str(err.value)


def test_overrides_are_validated_too(tmp_path: Path) -> None:
    with pytest.raises(ScenarioError):
        scenario.load(_write(tmp_path, BASE), {"backends.pinocchio.dt": -1.0})
    sc = scenario.load(_write(tmp_path, BASE), {"backends.pinocchio.dt": 1e-4})
    assert sc.backends["pinocchio"]["dt"] == 1e-4


def test_profile_defaults_to_matched_and_is_recorded() -> None:
    sc = scenario.parse(dict(BASE))
    assert sc.profile == "matched" and sc.to_dict()["profile"] == "matched"
    assert scenario.parse({**BASE, "profile": "engine-defaults"}).profile == "engine-defaults"


@pytest.mark.parametrize(
    ("doc", "where"),
    [
        ({**BASE, "profile": "fastest"}, "profile"),
        ({**BASE, "backends": {"pinocchio": {"profile": "nope"}}}, "backends.pinocchio.profile"),
    ],
)
def test_unknown_profile_is_refused_naming_the_key(doc: dict, where: str) -> None:  # type: ignore[type-arg]
    with pytest.raises(ScenarioError, match=where.replace(".", r"\.")):
        scenario.parse(doc)
