"""Scenario files: the four tasks load; bad input names file, key and problem."""

from __future__ import annotations

import dataclasses
import logging
import re
from pathlib import Path

import pytest
import yaml

from legbench import backends, scenario
from legbench.exceptions import LegbenchError, ScenarioError

SCENARIOS = Path(__file__).resolve().parent.parent / "scenarios"
TASKS = ("position", "ellipse", "effort", "combined", "combined_ros")


@pytest.mark.parametrize("task", TASKS)
def test_shipped_tasks_load(task: str) -> None:
    sc = scenario.load(SCENARIOS / f"{task}.yaml")
    assert sc.name == task
    assert sc.control_rate == 1000.0
    assert sc.gains.Kp == (10.0, 10.0, 10.0) and sc.gains.Kd == (1.0, 1.0, 1.0)
    assert len(sc.sha256) == 64


@pytest.mark.parametrize("task", ("position", "effort", "validation"))  # the others' events start later
def test_a_shipped_task_shortened_takes_the_whole_run_as_its_steady_window(task: str) -> None:
    """The shipped tasks leave comparison.steady_window to its default, the last 0.5 s or the whole of a shorter run,
    so ``run_scenario("effort", overrides={"duration": 0.2})`` runs (a README reader's check: each file gave 0.5
    explicitly, and a shorter run was refused as 'longer than the run')."""
    assert scenario.load(SCENARIOS / f"{task}.yaml").comparison.steady_window == 0.5
    assert scenario.load(SCENARIOS / f"{task}.yaml", {"duration": 0.2}).comparison.steady_window == pytest.approx(0.2)


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
        # a steady window of under one control period holds one tick; a skip past the last period leaves one tick
        ({"comparison": {"steady_window": 1e-6}}, "comparison.steady_window", "shorter than one control period"),
        ({"comparison": {"skip": 0.9995}}, "comparison.skip", "fewer than two control ticks"),
        # a sine at or above half the control rate is sampled into another one (at 1 kHz a 1 kHz sine is all zeros)
        ({"events": [{"t": 0.0, "torque": {"amplitude": [0.1] * 3, "frequency": [1, 500, 1]}}]},
         "events[0].torque.frequency[1]", "not below half the control rate (500 Hz)"),
        ({"events": [{"t": 0.0, "position": {"joint": [0, 0, 0]}}, {"t": 2.0, "effort": {"force": [0, 0, -1]}}]},
         "events[1].t", "past the end"),
        ({"events": [{"t": 0.0, "position": {"joint": [0, 0, 0]}},
                     {"t": 0.5, "effort": {"force": [0, 0, -1]}, "delay": -0.01}]}, "events[1].delay", ">= 0"),
        ({"events": [{"t": 0.0, "position": {"joint": [0, 0, 0]}},
                     {"t": 0.5, "position": {"joint": [0, 0, 0]}, "force_delay": 0.007}]},
         "events[1].force_delay", "only an effort event"),
        ({"events": [{"t": 0.0, "position": {"joint": [0, 0, 0]}, "delay": 0.01}]}, "events[0].delay",
         "first event cannot be delayed"),
        ({"events": [{"t": 0.0, "position": {"joint": [0, 0, 0]}},
                     {"t": 0.9, "effort": {"force": [0, 0, -1]}, "delay": 0.2}]}, "events[1].delay", "past the end"),
        ({"events": [{"t": 0.0, "position": {"joint": [0, 0, 0]}},
                     {"t": 0.5, "effort": {"force": [0, 0, -1]}, "delay": 0.2},
                     {"t": 0.6, "position": {"joint": [0, 0, 0]}}]}, "events[2].t", "before the previous one"),
        # a controller switches on the 1 kHz grid only: an event off it would silently move to the tick before
        ({"events": [{"t": 0.0, "position": {"joint": [0, 0, 0]}},
                     {"t": 0.1005, "effort": {"force": [0, 0, -1]}}]}, "events[1].t", "not a whole number"),
        ({"events": [{"t": 0.0, "position": {"joint": [0, 0, 0]}},
                     {"t": 0.1, "effort": {"force": [0, 0, -1]}, "delay": 0.0004}]}, "events[1].delay",
         "not a whole number"),
        ({"events": [{"t": 0.0, "position": {"joint": [0, 0, 0]}},
                     {"t": 0.1, "effort": {"force": [0, 0, -1]}, "force_delay": 0.0071}]}, "events[1].force_delay",
         "not a whole number"),
        # the boundaries a mutation audit found untested: each of these was accepted with its < in place of <=
        ({"events": [{"t": 0.0, "position": {"joint": [0, 0, 0]}}, {"t": 1.0, "effort": {"force": [0, 0, -1]}}]},
         "events[1].t", "past the end"),  # an event at exactly the end never acts
        ({"events": [{"t": 0.0, "trajectory": {"waypoints": [[0.1667, 0.05, 0.10], [0.1667, 0.10, 0.12]],
                                               "times": [0.4, 0.4]}}]}, "events[0].trajectory.times",
         "must increase strictly"),  # two waypoints at one instant: a zero time step between them
        ({"duration": 20.0, "events": [{"t": 0.0, "ellipse": {"a": 0.15, "b": 0.06, "DY": 0.11208, "DZ": 0.105,
                                                              "T": 5.0, "points": 1000, "repetitions": 101}}]},
         "events[0].ellipse.points", "points x repetitions = 101000 is more than 100000"),
        ({"events": [{"t": 0.0, "position": {"joint": [0, 0, 0]}}, {"t": 0.5, "effort": {"force": [0, 0, -1]}},
                     {"t": 0.3, "position": {"joint": [0, 0, 0]}, "delay": 0.3}]}, "events[2].t",
         "events out of order"),  # its delayed switch (0.6 s) after the previous one's does not put it in order
        ({"events": [{"t": 0.0, "position": {"joint": [0, 0, 0]}},
                     {"t": 0.2, "effort": {"force": [0, 0, -1]}, "force_delay": 0.1},
                     {"t": 0.3, "position": {"joint": [0, 0, 0]}}]}, "events[1].force_delay",
         "not before the next event switches"),  # the force would start as the next event takes over
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


def test_event_delays_are_read_and_recorded(tmp_path: Path) -> None:
    """``delay`` moves the switch to t + delay; ``force_delay`` rides on the effort event; both go to run.json."""
    effort = {"t": 0.5, "effort": {"force": [0, 0, -1]}, "delay": 0.013, "force_delay": 0.007}
    doc = {**BASE, "events": [{"t": 0.0, "position": {"joint": [0, 0, 0]}}, effort]}
    sc = scenario.load(_write(tmp_path, doc))
    ev = sc.events[1]
    assert (ev.t, ev.delay, ev.force_delay) == (0.5, 0.013, 0.007)
    assert ev.t_switch == pytest.approx(0.513, abs=1e-15)
    assert sc.events[0].delay == 0.0 and sc.events[0].force_delay == 0.0
    assert sc.to_dict()["events"][1] == {"t": 0.5, "controller": "effort", "effort": {"force": [0, 0, -1]},
                                         "delay": 0.013, "force_delay": 0.007}  # fmt: skip


def test_combined_ros_is_the_combined_task_with_the_reports_ros_delays() -> None:
    """scenarios/combined_ros.yaml: combined.yaml's events, the effort switch 13 ms late and its force 7 ms later."""
    plain = scenario.load(SCENARIOS / "combined.yaml")
    ros = scenario.load(SCENARIOS / "combined_ros.yaml")
    assert [(e.t, e.controller, e.cartesian, e.force) for e in ros.events] == [
        (e.t, e.controller, e.cartesian, e.force) for e in plain.events
    ]
    assert [(e.delay, e.force_delay) for e in ros.events] == [(0.0, 0.0), (0.0, 0.0), (0.013, 0.007)]
    assert (ros.duration, ros.gains, ros.q0, ros.contact) == (plain.duration, plain.gains, plain.q0, plain.contact)


def test_an_overridden_value_is_blamed_on_the_override_not_the_files_line(tmp_path: Path) -> None:
    """--set replaces a value: its error names the override, and no line (the file's line holds the old value)."""
    path = _write(tmp_path, BASE)
    with pytest.raises(ScenarioError) as err:
        scenario.load(path, {"duration": 0})
    assert err.value.key == "duration" and err.value.line is None
    assert "(from --set duration)" in str(err.value)
    with pytest.raises(ScenarioError) as err:
        scenario.load(path, {"gains.Kp": [1.0, -2.0, 3.0]})
    assert err.value.key == "gains.Kp[1]" and "(from --set gains.Kp)" in str(err.value)


def test_an_overrides_origin_is_named_in_the_callers_words(tmp_path: Path) -> None:
    """``origin`` names what set the keys (the Python API passes "overrides"), in both kinds of error: a key that
    cannot be set (set_key: the error's file) and a value that does not validate (``(from ORIGIN KEY)``)."""
    path = _write(tmp_path, BASE)
    with pytest.raises(ScenarioError) as err:
        scenario.load(path, {"events[0].t": 0.1}, "overrides")
    assert str(err.value) == "overrides: events[0].t: a list item is written with a dot: events.0.t"
    with pytest.raises(ScenarioError) as err:
        scenario.load(path, {"duration": 0}, "overrides")
    assert str(err.value).endswith(" (from overrides duration)") and "--set" not in str(err.value)
    with pytest.raises(ScenarioError, match=r"^--set: events\[0\]\.t: a list item"):  # the default: the command line's
        scenario.load(path, {"events[0].t": 0.1})


@pytest.mark.parametrize(
    ("initial", "key"),
    [({"qd": [0, 0, 5000]}, "initial.qd[2]"), ({"qd": [-1000.5, 0, 0]}, "initial.qd[0]"), ({"qd": 2000}, "initial.qd")],
)
def test_an_initial_joint_speed_above_the_divergence_bound_is_refused(tmp_path: Path, initial: dict, key: str) -> None:  # type: ignore[type-arg]
    """An initial joint speed above MAX_JOINT_SPEED (the run loop's divergence bound: every engine stopped at
    t = 0 with exit 3) is a ScenarioError naming the file and initial.qd; the bound itself is accepted."""
    with pytest.raises(ScenarioError) as err:
        scenario.load(_write(tmp_path, {**BASE, "initial": initial}))
    assert err.value.key == key and str(tmp_path) in str(err.value)
    assert f"faster than {scenario.MAX_JOINT_SPEED:g} rad/s" in err.value.problem
    bound = scenario.parse({**BASE, "initial": {"qd": [0, 0, -scenario.MAX_JOINT_SPEED]}})
    assert bound.qd0 == (0.0, 0.0, -scenario.MAX_JOINT_SPEED)


def test_an_initial_pose_with_the_foot_deeper_than_the_divergence_bound_is_refused(tmp_path: Path) -> None:
    """initial.q within the joint limits but with the foot 9.8 cm into the ground (beyond MAX_PENETRATION, where
    the run loop stops every engine at t = 0) is a ScenarioError naming initial.q; a foot resting on it is not."""
    with pytest.raises(ScenarioError) as err:
        scenario.load(_write(tmp_path, {**BASE, "initial": {"q": [0.0, -1.6, 0.0]}}))
    assert err.value.key == "initial.q" and "0.0984 m into the ground, deeper than 0.05 m" in err.value.problem
    assert scenario.parse({**BASE, "initial": {"q": [-0.0025, -1.1899, -1.2599]}}).q0 == (-0.0025, -1.1899, -1.2599)


@pytest.mark.parametrize(
    ("tolerances", "key", "words"),
    [
        ({"foo": 1}, "comparison.tolerances.foo", "unknown tolerance; valid: ['max_sim_error_pct', 'rms'"),
        ({"max_sim_error_pct": -5}, "comparison.tolerances.max_sim_error_pct", "must be a mapping"),
        ({"max_sim_error_pct": {"q1": -5}}, "comparison.tolerances.max_sim_error_pct.q1", "must be a number >= 0"),
        ({"rms": {"abs": -1}}, "comparison.tolerances.rms.abs", "must be a number >= 0, not -1"),
        ({"rms": {"abs": {"tau": "x"}}}, "comparison.tolerances.rms.abs.tau", "must be a number >= 0, not 'x'"),
        ({"steady_mean": {"absolute": 1}}, "comparison.tolerances.steady_mean.absolute", "unknown key"),
    ],
)
def test_malformed_comparison_tolerances_are_refused_when_the_scenario_loads(
    tmp_path: Path,
    tolerances: dict,  # type: ignore[type-arg]
    key: str,
    words: str,
) -> None:
    """A scenario's comparison.tolerances with an unknown metric or a negative value is refused by load (validate
    and run), by the rules legbench check applies, naming the file, the key and its line; it passed both and
    failed only a later check."""
    path = _write(tmp_path, {**BASE, "comparison": {"tolerances": tolerances}})
    with pytest.raises(ScenarioError) as err:
        scenario.load(path)
    assert err.value.key == key and words in err.value.problem
    assert str(path) in str(err.value) and err.value.line is not None
    good = {"sim_error_pct": {"abs": 0.1}, "rms": {"abs": {"q": 1e-4}, "rel": 0}, "max_sim_error_pct": {"q1": 5}}
    assert scenario.parse({**BASE, "comparison": {"tolerances": good}}).comparison.tolerances == good


def test_a_control_rate_the_engines_default_sub_step_does_not_divide_is_refused_naming_file_and_key(
    tmp_path: Path,
) -> None:
    """control_rate: 333 validated, then run and doctor refused it with no file named (the engines' default dt,
    5e-5 s, does not divide 1/333 s): validate (scenario.errors) now refuses it naming the file, control_rate
    and its line, and the engines; with a dt that divides the period given to every installed engine, it is
    valid. Loading it for a run does not import every engine: a run checks the engines it loads (the pre-flight
    names the file: tests/test_cli.py)."""
    path = _write(tmp_path, {**BASE, "duration": 3.0, "control_rate": 333})
    (err,) = scenario.errors(path)
    assert err.key == "control_rate" and err.line is not None and str(path) in str(err)
    assert "backends.pinocchio.dt: 5e-05 s does not divide the control period 0.003003 s" in err.problem
    assert scenario.load(path).control_rate == 333
    step = 1.0 / 333 / 60
    fixed = {name: {"dt": step} for name in backends.available() if "dt" in backends.get(name).defaults}
    doc = {**BASE, "duration": 3.0, "control_rate": 333, "backends": fixed}
    assert scenario.parse(doc, every_engine=True).control_rate == 333


def test_the_sub_step_rule_is_the_backends_own() -> None:
    """The loader's sub-step check and the engines' load ask one rule (backends.base.dt_problem): what one
    refuses, the other does, with the same words."""
    from legbench.backends.base import dt_problem, sub_step_count

    for dt, control_dt in ((5e-5, 1 / 333), (3e-4, 1e-3), (2e-3, 1e-3), (1e-4, 1e-3)):
        why = dt_problem(dt, control_dt)
        if why is None:
            assert sub_step_count("x", dt, control_dt) == round(control_dt / dt)
            continue
        with pytest.raises(LegbenchError, match=re.escape(f"backends.x.dt: {why}")):
            sub_step_count("x", dt, control_dt)
        with pytest.raises(ScenarioError) as err:
            scenario.parse(
                {**BASE, "control_rate": 1 / control_dt, "duration": 3.0, "backends": {"pinocchio": {"dt": dt}}}
            )
        assert err.value.key == "backends.pinocchio.dt" and err.value.problem == why


def test_the_sub_step_rule_refuses_a_near_fraction_and_a_zero_step() -> None:
    """dt_problem: 1 ms / 3.0001 is not a whole fraction of 1 ms (the ratio must be whole to 1e-9); a step of 0
    is refused (sub_step_count raises LegbenchError, not ZeroDivisionError); 1 ms / 20 fits."""
    from legbench.backends.base import dt_problem, sub_step_count

    assert dt_problem(1e-3 / 3.0001, 1e-3) is not None
    assert dt_problem(0.0, 1e-3) is not None
    with pytest.raises(LegbenchError, match="does not divide"):
        sub_step_count("x", 0.0, 1e-3)
    assert dt_problem(1e-3 / 20, 1e-3) is None and sub_step_count("x", 1e-3 / 20, 1e-3) == 20


def test_a_null_setting_is_refused_where_the_range_does_not_allow_it() -> None:
    """ODE's erp has a range without null: ``erp: null`` is a ScenarioError naming the key; its nullable
    settings (ground_kp) take null; the JSON schema gives an open lower bound as exclusiveMinimum."""
    if "ode" not in backends.available():
        pytest.skip("ODE not installed here")
    with pytest.raises(ScenarioError) as err:
        scenario.parse({**BASE, "backends": {"ode": {"erp": None}}}, "s.yaml")
    assert err.value.key == "backends.ode.erp"
    assert scenario.parse({**BASE, "backends": {"ode": {"ground_kp": None}}}).backends["ode"]["ground_kp"] is None
    if "drake" in backends.available():
        drake = scenario.json_schema()["properties"]["backends"]["properties"]["drake"]["properties"]
        assert drake["stiction_tolerance"] == {"type": ["number", "null"], "exclusiveMinimum": 0.0}


def test_a_backend_setting_that_cannot_run_the_contact_mode_is_refused_at_load(tmp_path: Path) -> None:
    """Drake's continuous plant cannot apply the reference law (it has no sub-steps): the loader asks the backend's
    own rule (Backend.settings_problem, which its load asks too) and names the setting, or the contact mode when
    the combination comes from a profile or default; the same settings in native contact load."""
    pytest.importorskip("pydrake")
    doc = {**BASE, "physics": {"contact_mode": "reference"}, "backends": {"drake": {"solver": "continuous"}}}
    with pytest.raises(ScenarioError, match=r"backends\.drake\.solver: 'continuous' cannot run reference contact"):
        scenario.load(_write(tmp_path, doc))
    doc["physics"] = {"contact_mode": "native"}
    assert scenario.load(_write(tmp_path, doc)).backends["drake"] == {"solver": "continuous"}


@pytest.mark.parametrize(
    ("patch", "key", "words"),
    [
        # a label that is not text: run.json's sorted keys raised TypeError ('<' between int and str): a traceback
        ({"tolerances": {"max_sim_error_pct": {7: 1.0, "q": 5.0}}}, "comparison.tolerances.max_sim_error_pct.7",
         "unknown component"),
        # a label no lookup asks for was kept and silently never used: the tolerance stayed the default
        ({"tolerances": {"rms": {"abs": {"qq": 1.0}}}}, "comparison.tolerances.rms.abs.qq", "unknown component"),
        ({"tolerances": {"sim_error_pct": {"rel": {"Q1": 1.0}}}}, "comparison.tolerances.sim_error_pct.rel.Q1",
         "valid: default, q, qd, tau, force, q1"),
        # infinity was taken, and written to run.json as Infinity, which is not JSON
        ({"tolerances": {"rms": {"abs": float("inf")}}}, "comparison.tolerances.rms.abs", "finite"),
        ({"tolerances": {"max_sim_error_pct": {"q": float("inf")}}}, "comparison.tolerances.max_sim_error_pct.q",
         "finite"),
        # an empty list was taken for "no tolerances" (`[] or {}`), a list of items refused
        ({"tolerances": []}, "comparison.tolerances", "mapping"),
    ],
)  # fmt: skip
def test_tolerance_labels_must_be_components_and_numbers_finite(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], patch: dict[str, object], key: str, words: str
) -> None:
    from legbench import cli

    path = _write(tmp_path, {**BASE, "comparison": patch})
    assert cli.main(["validate", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"{path}:" in err and f": {key}: " in err and words in err, err
    with pytest.raises(ScenarioError) as exc:
        scenario.load(path)
    assert exc.value.key == key


def test_tolerance_component_keys_are_the_signals_names() -> None:
    """The validator's list of component keys is what :func:`legbench.signals.keyed` looks up."""
    from legbench.signals import LABELS, SIGNALS

    assert scenario.TOLERANCE_KEYS == ("default", *SIGNALS, *LABELS)


@pytest.mark.parametrize("settings", [[], 0, "", False])
def test_backend_settings_that_are_no_mapping_are_refused(tmp_path: Path, settings: object) -> None:
    """``backends: {pinocchio: []}`` (or 0, '', false) was read as no settings (``bset or {}``); only an empty
    entry (``pinocchio:``, null) means the defaults."""
    with pytest.raises(ScenarioError) as exc:
        scenario.load(_write(tmp_path, {**BASE, "backends": {"pinocchio": settings}}))
    assert exc.value.key == "backends.pinocchio" and "mapping" in exc.value.problem
    assert scenario.load(_write(tmp_path, {**BASE, "backends": {"pinocchio": None}})).backends["pinocchio"] == {}


@pytest.mark.parametrize(
    ("key", "text", "says"),
    [
        (
            "control_rate",
            "01750",
            "01750: YAML 1.1 reads a leading 0 as octal (1000); write 1750 for the decimal "
            "number, 1000 for the octal one, or quote it ('01750') for text",
        ),
        # 007 is 7 either way: the message offered '7, or 7'
        (
            "duration",
            "007",
            "007: YAML 1.1 reads a leading 0 as octal (7); write 7 for the decimal number, or "
            "quote it ('007') for text",
        ),
        ("duration", "1:30", "1:30: YAML 1.1 reads this as the base-60 number 90; write 90 if that is meant"),
        # a review: these ran as 3 s and 10 s without a word
        ("duration", "0b11", "0b11: YAML 1.1 reads this as the binary number 3; write 3 if that is meant"),
        ("duration", "1_0", "1_0: YAML 1.1 drops the '_' and reads 10; write 10 if that is meant"),
        ("duration", "1_0.5", "1_0.5: YAML 1.1 drops the '_' and reads 10.5; write 10.5 if that is meant"),
        ("duration", "0x1_0", "0x1_0: YAML 1.1 drops the '_' and reads 16; write 16 if that is meant"),
        # no digits at all: the generic conversion error named neither the line nor the key
        ("duration", "0b_", "0b_: not a number (YAML 1.1 reads it as one with no digits)"),
    ],
)
def test_yaml_11_numbers_that_read_as_something_else_are_refused(tmp_path: Path, key: str, text: str,
                                                                  says: str) -> None:  # fmt: skip
    """PyYAML reads YAML 1.1: ``control_rate: 01750`` loaded as 1000 Hz (octal) and ``duration: 1:30`` as 90 s
    (base 60), without a word. Both are refused with the file, the line, the key and what YAML 1.1 makes of
    them, in the file and in ``--set``; quoted, or written as what is meant, they load; 0, 00 and 0.5 stay
    numbers."""
    from legbench import resources, yamlfile

    lines = resources.scenario("effort").read_text().splitlines()
    at = next(i for i, line in enumerate(lines) if line.startswith(f"{key}:"))
    lines[at] = f"{key}: {text}"
    p = tmp_path / "s.yaml"
    p.write_text("\n".join(lines) + "\n")
    with pytest.raises(ScenarioError) as err:
        scenario.load(p)
    assert str(err.value).startswith(f"{p}:{at + 1}: {key}: {says}"), err.value
    with pytest.raises(ScenarioError, match=re.escape(says)):
        yamlfile.parse_overrides([f"{key}={text}"])
    assert yamlfile.parse_overrides([f"x='{text}'", "a=0", "b=00", "c=0.5"]) == {"x": text, "a": 0, "b": 0, "c": 0.5}


def test_the_yaml_readers_refusals_name_the_whole_key_path(tmp_path: Path) -> None:
    """A YAML 1.1 number form deep in the file, or a duplicate key, named only its last key (``Kp: 01750``), where
    every other scenario error names the path (a README reader's check): now ``physics.contact.Kp``,
    ``events[0].position.joint[1]`` and ``physics.gravity``, each with its line."""
    cases = (
        ("physics:\n  contact:\n    Kp: 01750\n", "physics.contact.Kp: 01750: YAML 1.1 reads a leading 0 as octal"),
        ("events:\n  - t: 0\n    position: {joint: [0, 0b11, 0]}\n",
         "events[0].position.joint[1]: 0b11: YAML 1.1 reads this as the binary number 3"),
        ("physics:\n  gravity: 9.8\n  gravity: 9.7\n", "physics.gravity: duplicate key (first at line 4)"),
    )  # fmt: skip
    for body, says in cases:
        f = tmp_path / "s.yaml"
        f.write_text("name: s\nduration: 1\n" + body)
        with pytest.raises(ScenarioError) as err:
            scenario.load(f)
        line = 3 + body.count("\n") - 1
        assert str(err.value).startswith(f"{f}:{line}: {says}"), err.value


def test_a_document_that_is_no_mapping_is_refused_as_such_with_set(tmp_path: Path) -> None:
    """With --set, a scenario file holding a list was refused as "--set: duration: '' is a list of 2", naming
    neither the file nor its problem; the overrides are applied only to a mapping, and parse names the file."""
    f = tmp_path / "list.yaml"
    f.write_text("- a\n- b\n")
    (problem,) = scenario.errors(f, {"duration": 1})
    assert str(problem).endswith("list.yaml: expected a mapping, got list")
    with pytest.raises(ScenarioError, match=r"list\.yaml: expected a mapping, got list"):
        scenario.load(f, {"duration": 1})


def test_a_problem_the_sections_defaults_share_is_said_once() -> None:
    """position.yaml with duration 0.2 s and a steady_window of 0.5 s: the window is longer than the run, and so
    was the default that replaced the dropped comparison section: the same line was printed twice; now once. (The
    shipped file leaves the window to its default since 28 Nov, which takes the whole of a shorter run: the window
    is given here.)"""
    (problem,) = scenario.errors(SCENARIOS / "position.yaml", {"duration": 0.2, "comparison.steady_window": 0.5})
    assert "comparison.steady_window: longer than the run (0.2 s): " in str(problem)


def test_a_gain_that_is_no_number_says_a_single_number_is_allowed() -> None:
    """gains.Kp: 'nan' (a --set value that is no number) said "expected a list of 3 numbers" though one number
    stands for all three joints: the message names both forms."""
    problems = scenario.errors(SCENARIOS / "position.yaml", {"gains.Kp": "nan"})
    assert [str(p).split(": ", 1)[1] for p in problems] == ["gains.Kp: expected a number or a list of 3 numbers, got "
                                                             "'nan' (from --set gains.Kp)"]  # fmt: skip


def test_a_duration_that_cuts_off_the_control_grid_names_the_option() -> None:
    """``reproduce --duration=1e-9`` (or bench's) was blamed on the scenario file's ``duration:`` key, which the user
    did not write: the error names the option that gave it, and the scenario."""
    sc = scenario.load(SCENARIOS / "position.yaml")
    with pytest.raises(ScenarioError) as exc:
        scenario.shorten(sc, 1e-9)
    assert str(exc.value) == (f"--duration: 1e-09 s is not a whole number of control periods at 1000.0 Hz (position, "
                              f"{sc.file})")  # fmt: skip
    assert scenario.shorten(sc, 0.5).duration == 0.5


def test_shorten_lets_go_of_a_skip_that_would_leave_fewer_than_two_ticks() -> None:
    """A skip valid in the whole run (0.9995 s of 3 s) would leave one tick when the run is cut to 1 s, which the
    loader refuses (a review, 27 Nov): the cut drops the skip, as it drops one past the new end, and keeps a skip
    that leaves two ticks."""
    sc = scenario.load(SCENARIOS / "effort.yaml", {"comparison.skip": 0.9995})
    assert scenario.shorten(sc, 1.0).comparison.skip == 0.0
    sc = scenario.load(SCENARIOS / "effort.yaml", {"comparison.skip": 0.999})
    assert scenario.shorten(sc, 1.0).comparison.skip == 0.999


def test_shorten_each_says_which_scenarios_a_longer_duration_leaves_whole(caplog: pytest.LogCaptureFixture) -> None:
    """``bench --duration 6`` over the position (3 s) and ellipse (11.5 s) tasks: position runs whole, which one
    note says (before, nothing did, and its 3 s could be read as the 6 asked for); the ellipse is cut to 6 s. A
    duration that cuts them all says nothing."""
    pos, comb = scenario.load(SCENARIOS / "position.yaml"), scenario.load(SCENARIOS / "ellipse.yaml")
    assert pos.duration < 6.0 < comb.duration
    with caplog.at_level(logging.WARNING, logger="legbench"):
        out = scenario.shorten_each([pos, comb], 6.0, "--duration")
    assert [sc.duration for sc in out] == [pos.duration, 6.0]
    assert out[0] is pos
    assert [r.getMessage() for r in caplog.records] == [
        f"legbench: note: --duration 6 s is not shorter than position ({pos.duration:g} s): it runs whole"
    ]
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="legbench"):
        assert [sc.duration for sc in scenario.shorten_each([pos, comb], 0.5)] == [0.5, 0.5]
    assert caplog.records == []


def test_a_published_row_takes_a_caveat_as_text() -> None:
    """``comparison.published[i].note``: text the report prints beside the row; anything else is one error naming
    the key."""
    row = {"source": "lab", "qd_abs": [1e-4, 2e-4, 3e-4]}
    sc = scenario.parse({**BASE, "comparison": {"published": [{**row, "note": "misreported"}]}}, "s.yaml")
    assert sc.comparison.published[0]["note"] == "misreported"
    for bad in ("", 3):
        with pytest.raises(ScenarioError) as err:
            scenario.parse({**BASE, "comparison": {"published": [{**row, "note": bad}]}}, "s.yaml")
        assert err.value.key == "comparison.published[0].note"


@pytest.mark.parametrize("backend", ["lagrange", "pinocchio"])
def test_an_rtol_below_scipy_s_floor_is_refused(backend: str) -> None:
    """scipy's RK45 raises an rtol below 100 eps (2.2e-14) to it, with a warning; the compiled Dormand-Prince took
    it as given, so at 1e-15 it made 20 right-hand-side calls where scipy made 14, no longer "scipy's RK45, step
    for step". Such an rtol is refused at load, naming the key; the floor itself passes."""
    if backend not in backends.available():
        pytest.skip(f"{backend} not installed")
    from legbench.backends.dopri import RTOL_MIN

    with pytest.raises(ScenarioError) as err:
        scenario.load(SCENARIOS / "effort.yaml", {f"backends.{backend}.rtol": 1e-15})
    assert err.value.key == f"backends.{backend}.rtol" and "must be >= 2.22045e-14" in err.value.problem
    assert scenario.load(SCENARIOS / "effort.yaml", {f"backends.{backend}.rtol": RTOL_MIN}).backends[backend]


@pytest.mark.parametrize(("backend", "extra"), [("pinocchio", {"integrator": "rk45"}), ("lagrange", {})])
def test_a_max_step_past_the_sub_step_limit_is_refused_naming_the_key(backend: str, extra: dict) -> None:  # type: ignore[type-arg]
    """max_step bounds an adaptive solve's step: 1e-20 s is 1e17 steps per 1 ms control tick. It passed validate
    (only dt was held to the limit on sub-steps per tick, 100,000) and the run then hung, deaf to SIGTERM (the
    compiled period checks no signal). It is refused now naming backends.<name>.max_step, by the limit the
    backend declares (Backend.step_bounds); a max_step need not divide the control period (3e-4 s passes)."""
    if backend not in backends.available():
        pytest.skip(f"{backend} not installed")
    assert "max_step" in backends.get(backend).step_bounds
    for bad in (1e-20, 1e-12):
        with pytest.raises(ScenarioError) as err:
            scenario.parse({**BASE, "backends": {backend: {**extra, "max_step": bad}}}, "s.yaml")
        assert err.value.key == f"backends.{backend}.max_step" and "limit sub_steps" in err.value.problem
    assert scenario.parse({**BASE, "backends": {backend: {**extra, "max_step": 3e-4}}}).backends[backend]
    assert scenario.parse({**BASE, "backends": {backend: {**extra, "max_step": 1e-3 / 100_000}}}).backends[backend]


def test_a_control_rate_the_default_max_step_cannot_reach_is_refused_naming_the_engine() -> None:
    """A 20 s control period with every engine's dt given (2e-4 s: 100,000 sub-steps, at the limit) still left the
    adaptive backends' default max_step (1e-4 s: 200,000 steps per tick) unchecked; validate (every_engine) now
    blames control_rate, naming backends.<name>.max_step."""
    adaptive = [n for n in ("pinocchio", "lagrange") if n in backends.available()]
    if not adaptive:
        pytest.skip("no adaptive backend installed")
    fixed = {name: {"dt": 2e-4} for name in backends.available() if "dt" in backends.get(name).defaults}
    doc = {**BASE, "duration": 20.0, "control_rate": 0.05, "backends": fixed}
    with pytest.raises(ScenarioError) as err:
        scenario.parse(doc, "s.yaml", every_engine=True)
    assert err.value.key == "control_rate" and f"backends.{adaptive[0]}.max_step" in err.value.problem
    for name in adaptive:
        fixed[name] = {**fixed.get(name, {}), "max_step": 2e-4}
    assert scenario.parse({**doc, "backends": fixed}, every_engine=True).control_rate == 0.05


@pytest.mark.parametrize(
    "name",
    [
        "foo__reference",
        "foo__engine-defaults",
        "foo__engine-defaults__reference",
        "report.html",
        "report.md",
        "Report.MD",
        "check.md",
        "check-junit.xml",
        "assets",
    ],
)
def test_a_scenario_name_that_clashes_with_legbench_s_own_names_is_refused(name: str) -> None:
    """A scenario named foo__reference (the folder of foo run in reference mode), report.html, report.md,
    check.md or assets (a results tree's index pages, check summary and plotly assets) passed validate and broke
    later (one run's folder shared with another's, a page or the assets overwritten). The loader refuses each,
    naming ``name``, one line; a name merely containing such words passes."""
    with pytest.raises(ScenarioError) as err:
        scenario.parse({**BASE, "name": name}, "s.yaml")
    assert err.value.key == "name" and "\n" not in str(err.value)
    assert scenario.parse({**BASE, "name": f"{name.replace('__', '_')}_x"}).name


def test_the_reserved_names_are_the_results_trees_own() -> None:
    """scenario.py may not import results or report_figures (docs/architecture.md), so it spells their names;
    these are the tree's pages, check outputs and assets folder, and every suffix out_dir_for gives a folder."""
    from legbench.backends.base import PROFILES
    from legbench.report_figures import ASSETS
    from legbench.results import CHECK_OUTPUTS, out_dir_for

    assert {"report.html", "report.md", *CHECK_OUTPUTS, ASSETS} <= set(scenario.RESERVED_NAMES)
    sc = scenario.parse(BASE)
    for profile in PROFILES:
        for mode in ("native", "reference"):
            folder = out_dir_for(Path("r"), dataclasses.replace(sc, profile=profile), mode).name
            assert folder == "t" or scenario.name_problem(folder) is not None


@pytest.mark.parametrize(
    ("events", "key", "words"),
    [
        ([{"t": 0.2, "effort": {"force": [0, 0, -1]}, "force_delay": 5}], "events[1].force_delay", "past the end"),
        ([{"t": 0.2, "effort": {"force": [0, 0, -1]}, "force_delay": 0.4}], "events[1].force_delay", "past the end"),
        ([{"t": 0.2, "effort": {"force": [0, 0, -1]}, "force_delay": 0.2}, {"t": 0.3, "position": {"joint": [0] * 3}}],
         "events[1].force_delay", "next event"),
    ],
)  # fmt: skip
def test_a_force_delay_that_starts_the_force_after_the_run_is_refused(events: list, key: str, words: str) -> None:  # type: ignore[type-arg]
    """force_delay: 5 on an effort event at 0.2 s of a 0.6 s run was accepted, so the force was never applied (the
    same overrun with delay was refused); so was one that starts the force after the next event took over. Each is
    refused naming the key; a force_delay that fits, the same scenario cut short by shorten (the start of the
    whole run), and a trajectory whose times outlast the run (a run cut short measures its start) pass."""
    hold = {"t": 0.0, "position": {"joint": [0, 0, 0]}}
    doc = {**BASE, "duration": 0.6, "events": [hold, *events]}
    with pytest.raises(ScenarioError) as err:
        scenario.parse(doc, "s.yaml")
    assert err.value.key == key and words in err.value.problem
    fits = {**doc, "events": [hold, {"t": 0.2, "effort": {"force": [0, 0, -1]}, "force_delay": 0.399}]}
    assert scenario.parse(fits).events[1].force_delay == 0.399
    whole = scenario.parse({**fits, "duration": 3.0})
    assert scenario.shorten(whole, 0.5).duration == 0.5
    path = {"t": 0.2, "trajectory": {"waypoints": [[0.2, 0.11, 0.05]], "times": [1.0]}}
    assert scenario.parse({**doc, "events": [hold, path]}).duration == 0.6


def test_the_default_steady_window_is_the_last_half_second_or_the_whole_of_a_shorter_run() -> None:
    """Without comparison.steady_window a 3 s run's window is its last 0.5 s and a 0.3 s run's the whole 0.3 s (it was
    refused as longer than the run, though the user gave no window); one given longer than the run is refused, and
    the message says how to give a shorter one."""
    assert scenario.parse({**BASE, "duration": 3.0}).comparison.steady_window == 0.5
    assert scenario.parse({**BASE, "duration": 0.3}).comparison.steady_window == 0.3
    with pytest.raises(ScenarioError) as err:
        scenario.parse({**BASE, "duration": 0.3, "comparison": {"steady_window": 0.5}})
    assert err.value.key == "comparison.steady_window" and "--set comparison.steady_window=" in err.value.problem


def test_a_numeric_name_is_told_to_be_quoted(tmp_path: Path) -> None:
    """`name: 123` said "expected a plain name (letters, digits, ...), got 123" though 123 is digits: YAML read a
    number; the line says to quote it, and the quoted name loads."""
    with pytest.raises(ScenarioError) as err:
        scenario.load(_write(tmp_path, {**BASE, "name": 123}))
    assert err.value.key == "name" and err.value.problem == (
        "a name is text: quote it ('123'), or YAML reads it as the number 123"
    )
    assert scenario.load(_write(tmp_path, {**BASE, "name": "123"})).name == "123"
