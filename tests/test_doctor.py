"""Parity pre-flight: every engine holds the spec's leg; a planted mismatch is caught and named."""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import pytest
import yaml

from legbench import backends
from legbench.backends.base import Backend, Physics
from legbench.backends.pinocchio_ import PinocchioBackend
from legbench.exceptions import LegbenchError
from legbench.studies import doctor

EFFORT = Path(__file__).resolve().parents[1] / "scenarios" / "effort.yaml"


def test_every_backend_holds_the_spec_leg_limits_and_gravity() -> None:
    t = doctor.doctor(EFFORT)
    parity = t[t["status"] != "info"]
    assert (parity["status"] == "ok").all(), parity[parity["status"] != "ok"]
    names = backends.available()
    assert set(names) <= set(t.columns)
    rows = set(parity["row"])
    assert {"link2.mass", "link3.inertia.xy", "gravity", "q3_knee.upper", "q1_abad.torque_limit"} <= rows
    # settings each engine reports are shown beside each other
    assert "dt" in set(t["row"]) and "sub_steps" in set(t["row"])


def _heavier_link2_pinocchio(b: Any) -> None:
    Y = b.model.inertias[2]
    Y.mass = Y.mass * (1 + 1e-4)
    b.model.inertias[2] = Y


def _heavier_link2_mujoco(b: Any) -> None:
    b.model.body_mass[b.model.body("link2").id] *= 1 + 1e-4


def _heavier_link2_pybullet(b: Any) -> None:
    import pybullet as p

    link = b.links["link2"]
    mass = p.getDynamicsInfo(b.body, link, physicsClientId=b.cid)[0]
    p.changeDynamics(b.body, link, mass=mass * (1 + 1e-4), physicsClientId=b.cid)


def _heavier_link2_drake(b: Any) -> None:
    body = b.plant.GetBodyByName("link2")
    body.SetMass(b.ctx, body.get_mass(b.ctx) * (1 + 1e-4))


def _heavier_link2_dart(b: Any) -> None:
    body = b.skel.getBodyNode("link2")
    body.setMass(body.getMass() * (1 + 1e-4))


def _heavier_link2_lagrange(b: Any) -> None:
    """The equations re-derived (and cached) for a link 2 1e-4 heavier: dynamics and read-back change together."""
    import dataclasses

    from legbench.backends.lagrange_eom import leg_chain, load_eom
    from legbench.model import load_params

    chain = leg_chain(load_params())
    link2 = dataclasses.replace(chain.links[1], mass=chain.links[1].mass * (1 + 1e-4))
    b.eom = load_eom(dataclasses.replace(chain, links=(chain.links[0], link2, chain.links[2])))
    b._qdd = b.eom.module.qdd


def _heavier_link2_ode(b: Any) -> None:
    import ctypes

    import odepy as ode

    body = b.bodies[1]
    mass = ode.dMass()
    ode.dBodyGetMass(body, ctypes.byref(mass))
    ode.dMassAdjust(ctypes.byref(mass), mass.mass * (1 + 1e-4))
    ode.dBodySetMass(body, ctypes.byref(mass))


PLANT: dict[str, Callable[[Any], None]] = {
    "pinocchio": _heavier_link2_pinocchio,
    "mujoco": _heavier_link2_mujoco,
    "pybullet": _heavier_link2_pybullet,
    "drake": _heavier_link2_drake,
    "dart": _heavier_link2_dart,
    "lagrange": _heavier_link2_lagrange,
    "ode": _heavier_link2_ode,
}


@pytest.mark.parametrize("name", backends.available())
def test_planted_mass_mismatch_is_caught_and_named(name: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """Link 2 made 1e-4 heavier inside one engine after it loaded (100 x the 1e-6 tolerance)."""
    if name not in PLANT:
        pytest.skip(f"no way to plant a mismatch in {name}")
    cls = backends.get(name)
    original = cls.load

    def load(self: Any, *args: Any, **kwargs: Any) -> None:
        original(self, *args, **kwargs)
        PLANT[name](self)

    monkeypatch.setattr(cls, "load", load)
    with pytest.raises(doctor.ParityError) as err:
        doctor.preflight(EFFORT, backends.available())
    assert err.value.backend == name and err.value.row == "link2.mass"
    assert f"{name} holds link2.mass" in str(err.value)


def test_cli_prints_the_table_and_reports_a_mismatch(monkeypatch: pytest.MonkeyPatch,
                                                     capsys: pytest.CaptureFixture[str]) -> None:  # fmt: skip
    parser = argparse.ArgumentParser()
    doctor.add_cli(parser.add_subparsers())
    args = parser.parse_args(["doctor", str(EFFORT), "--backends", "pinocchio"])
    assert args.func(args) == 0
    assert "parity: every backend holds" in capsys.readouterr().out
    original = backends.get("pinocchio").load

    def load(self: Any, *a: Any, **k: Any) -> None:
        original(self, *a, **k)
        self.lower = [x - 0.1 for x in self.lower]  # a wider joint limit than the spec

    monkeypatch.setattr(backends.get("pinocchio"), "load", load)
    assert args.func(args) == 1
    got = capsys.readouterr()  # the table on stdout, the error on stderr (it was printed into the table's stream)
    assert "pinocchio holds q1_abad.lower" in got.err and "holds q1_abad.lower" not in got.out


def test_a_backend_that_reads_nothing_back_is_not_called_in_parity(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """A backend without mass_properties leaves 30 parity rows unread; doctor said "every backend holds the spec's
    leg" (exit 0) all the same. It still exits 0 (nothing read back differs) but names the backend and the count."""
    cls = backends.get("pinocchio")
    monkeypatch.setattr(cls, "mass_properties", Backend.mass_properties)  # the contract's default: none
    t = doctor.table(EFFORT, ["pinocchio"])
    doctor.check(t)  # nothing read back differs
    unread = int(t.loc[t["status"] != "info", "pinocchio"].isna().sum())
    assert unread == 30  # 3 links x (mass, 3 com, 6 inertia)
    parser = argparse.ArgumentParser()
    doctor.add_cli(parser.add_subparsers())
    args = parser.parse_args(["doctor", str(EFFORT), "--backends", "pinocchio"])
    assert args.func(args) == 0
    out = capsys.readouterr().out
    assert "every backend holds" not in out
    assert f"not read back, so not checked: pinocchio ({unread} of {int((t['status'] != 'info').sum())} rows)" in out


def test_a_mismatch_message_shows_plain_numbers() -> None:
    """numpy's repr leaked into the message: 'says np.float64(7.051408) N m'."""
    import numpy as np

    err = doctor.ParityError("euler", "q1_abad.torque_limit", float("inf"), np.float64(7.051408), "N m")
    assert "holds q1_abad.torque_limit = inf N m, the spec" in str(err)
    assert "says 7.051408 N m" in str(err) and "np.float64" not in str(err)


class _ReferenceOnly(PinocchioBackend):
    """A plug-in (the Pinocchio backend, so it holds the spec's leg) that refuses native contact mode when it loads
    (its own rule)."""

    name = "refonly"

    @classmethod
    def settings_problem(cls, settings: Mapping[str, Any], contact_mode: str) -> tuple[str, str] | None:
        return ("contact", "refonly has no contact of its own: run it in reference contact") if contact_mode == (
            "native") else None  # fmt: skip

    def load(self, urdf: Path, physics: Physics, settings: Mapping[str, Any]) -> None:
        bad = self.settings_problem(settings, physics.contact_mode)
        if bad is not None:
            raise LegbenchError(f"backends.refonly.{bad[0]}: {bad[1]}")
        super().load(urdf, physics, settings)


def test_the_preflight_loads_each_backend_in_the_runs_contact_mode(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """The pre-flight loaded every backend in the scenario file's contact mode, whatever --contact-mode said: a
    backend that runs only in reference contact was refused for `--contact-mode reference` (exit 2, "has no
    contact of its own"), and one that cannot run in reference mode was not refused up front for it (it failed
    later, exit 3). Now it is loaded in each mode the command runs: reference runs, native is refused, both is
    refused before anything is written."""
    from legbench import cli

    reg = backends._registry
    monkeypatch.setattr(backends, "_registry", lambda: {**reg(), "refonly": _ReferenceOnly})
    doc = {"name": "t", "duration": 0.02, "events": [{"t": 0.0, "position": {"joint": [0.0, -1.0, -1.0]}}],
           "comparison": {"steady_window": 0.01}}  # fmt: skip
    f = tmp_path / "t.yaml"
    f.write_text(yaml.safe_dump(doc))  # native contact mode (the default)
    run = ["run", str(f), "--backends", "refonly", "-q", "--no-compare"]
    assert cli.main([*run, "--out", str(tmp_path / "ref"), "--contact-mode", "reference"]) == 0
    assert (tmp_path / "ref" / "run.json").is_file()
    capsys.readouterr()
    for mode, out in (("native", "nat"), ("both", "both")):
        assert cli.main([*run, "--out", str(tmp_path / out), "--contact-mode", mode]) == 2
        err = capsys.readouterr().err.strip()
        assert err.count("\n") == 0 and "backends.refonly.contact: refonly has no contact of its own" in err
        assert not (tmp_path / out).exists()


def _plant_failing_load(monkeypatch: pytest.MonkeyPatch, name: str, error: Exception) -> None:
    """Register a plug-in backend ``name`` (Pinocchio's) whose load raises ``error``."""

    class FailingLoad(PinocchioBackend):
        def load(self, urdf: Path, physics: Physics, settings: Mapping[str, Any]) -> None:
            raise error

    FailingLoad.name = name
    reg = backends._registry
    monkeypatch.setattr(backends, "_registry", lambda: {**reg(), name: FailingLoad})


def test_a_plug_in_that_raises_in_the_pre_flight_fails_alone(
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
    caplog: pytest.LogCaptureFixture,
) -> None:
    """A plug-in raising AttributeError in its load: the pre-flight escaped as a traceback, then refused the whole
    run (exit 2, pinocchio not run either). It is one warning line naming the backend, the others are checked and
    run, and the failing backend's run fails alone (exit 3, run.json naming its error). ``legbench doctor`` prints
    the table of the others and the failure (exit 3)."""
    from legbench import cli

    _plant_failing_load(monkeypatch, "loadraises", AttributeError("'str' object has no attribute 'get'"))
    out = tmp_path / "run"
    argv = ["run", str(EFFORT), "--backends", "pinocchio,loadraises", "--out", str(out), "-q", "--no-compare"]
    with caplog.at_level("WARNING", logger="legbench.studies.doctor"):
        assert cli.main([*argv, "--set", "duration=0.02", "--set", "comparison.steady_window=0.01"]) == 3
    warning = (
        "legbench: warning: parity check: loadraises failed to load: AttributeError: 'str' object has no "
        "attribute 'get'; not checked, its run fails alone"
    )
    assert [r.getMessage() for r in caplog.records] == [warning]
    meta = json.loads((out / "run.json").read_text())
    assert meta["backends"]["pinocchio"]["status"] == "ok" and meta["backends"]["loadraises"]["status"] == "failed"
    assert "AttributeError" in meta["backends"]["loadraises"]["reason"]
    # the status's one line on stderr, where a script looks for errors (the reason is on stdout's table)
    assert capsys.readouterr().err.splitlines()[-1] == (
        "legbench: 1 run(s) did not finish ok (run/loadraises); the others' results are written"
    )
    assert cli.main(["doctor", str(EFFORT), "--backends", "pinocchio,loadraises"]) == 3
    got = capsys.readouterr()
    assert "legbench: error: parity check: loadraises failed to load: AttributeError" in got.err
    shown = got.out
    assert "pinocchio" in shown.splitlines()[0] and "loadraises" not in shown


def test_a_cache_every_engine_needs_is_named_as_it_is(monkeypatch: pytest.MonkeyPatch) -> None:
    """An engine's load that meets the unusable cache directory (lagrange's generated equations) raised a
    ModelError the pre-flight prefixed with the scenario's file, as if the scenario were wrong: it is passed on
    as it is, naming the variable."""
    from legbench.exceptions import ModelError

    _plant_failing_load(monkeypatch, "cachebound", ModelError("LEGBENCH_CACHE_DIR=/tmp/f: not a directory"))
    with pytest.raises(ModelError) as exc:
        doctor.preflight(EFFORT, ["pinocchio", "cachebound"])
    assert str(exc.value) == "LEGBENCH_CACHE_DIR=/tmp/f: not a directory"


def test_a_mismatch_names_the_active_parameter_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """With `--model copy.yaml` the parity error said "the spec (models/leg.yaml and the scenario)", the bundled
    file, which was not in use. It names the active parameter file (as outputs show a path); the bundled file by
    its checkout path."""
    from legbench import cli, resources

    monkeypatch.setenv(resources.CACHE_ENV, str(tmp_path / "cache"))
    monkeypatch.delenv(resources.MODEL_ENV, raising=False)
    monkeypatch.chdir(tmp_path)
    copy = tmp_path / "copy.yaml"
    copy.write_text(resources.bundled_model().read_text())
    original = backends.get("pinocchio").load

    def load(self: Any, *a: Any, **k: Any) -> None:
        original(self, *a, **k)
        self.lower = [x - 0.1 for x in self.lower]  # a wider joint limit than the spec

    monkeypatch.setattr(backends.get("pinocchio"), "load", load)
    try:
        resources.select_model(copy)
        with pytest.raises(doctor.ParityError) as err:
            doctor.preflight(EFFORT, ["pinocchio"])
        assert "the spec (copy.yaml and the scenario) says" in str(err.value)
        assert "models/leg.yaml" not in str(err.value)
        assert cli.main(["--model", str(copy), "doctor", str(EFFORT), "--backends", "pinocchio"]) == 1
        assert "the spec (copy.yaml and the scenario) says" in capsys.readouterr().err
    finally:
        resources.select_model(None)
    err_bundled = doctor.ParityError("pinocchio", "q1_abad.lower", 0.0, 1.0, "rad")
    assert f"the spec ({resources.shown(resources.bundled_model())} and the scenario)" in str(err_bundled)


def test_doctor_reads_back_the_scenario_as_set_overrides_it(capsys: pytest.CaptureFixture[str]) -> None:
    """`legbench doctor --set` checks what `legbench run --set` would run (a review: doctor had no --set, so a
    run's overridden step or profile could not be pre-flighted): MuJoCo's dt 1e-4 is read back as 0.0001 s with
    10 sub-steps per 1 ms period; a misspelt key, or a control rate the sub-step does not divide, is one line naming
    it as `run` does, exit 2."""
    from legbench import cli

    assert cli.main(["doctor", str(EFFORT), "--backends", "mujoco", "--all", "--set", "backends.mujoco.dt=1e-4"]) == 0
    rows = {tuple(line.split()[:2]): line.split() for line in capsys.readouterr().out.splitlines() if line}
    assert rows[("settings", "dt")][-2] == "0.0001" and rows[("settings", "sub_steps")][-2] == "10"
    assert cli.main(["doctor", str(EFFORT), "--backends", "mujoco", "--set", "gravty=1"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "gravty: unknown key" in err and "(from --set gravty)" in err
    # a control rate the default sub-step does not divide: named as `run` names it (it blamed backends.mujoco.dt)
    assert cli.main(["doctor", str(EFFORT), "--backends", "mujoco", "--set", "control_rate=700"]) == 2
    err = capsys.readouterr().err
    assert "control_rate: 700 Hz does not suit the default (or profile) sub-step of mujoco" in err
    assert err.rstrip().endswith("(from --set control_rate)")
