"""The run loop with a fake backend: clock, zero-order hold, events, logging, outputs."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest
from fakes import FakeBackend, install_crashing_engine

from legbench import backends, kinematics, resources, results, run, scenario, signals
from legbench.exceptions import LegbenchError
from legbench.model import load_params

LIMIT = np.array(load_params().effort)  # joint torque limits [N m]

DOC: dict[str, Any] = {
    "name": "fake",
    "duration": 0.5,
    "events": [
        {"t": 0.0, "position": {"joint": [0.1, 0.0, 0.0]}},
        {"t": 0.25, "effort": {"force": [0.0, 0.0, 0.0]}},
    ],
}


def _simulate(doc: dict[str, Any]) -> tuple[results.RunResult, FakeBackend]:
    sc = scenario.parse(doc)
    be = FakeBackend()
    phys = scenario.physics_of(sc)
    be.load(Path("unused"), phys, {})
    return run.simulate(sc, be, phys), be


def test_ticks_are_exactly_on_the_control_grid_and_logged_once_each() -> None:
    tr, be = _simulate(DOC)
    assert len(tr.t) == 501
    np.testing.assert_array_equal(tr.t, np.arange(501) * 1e-3)
    assert len(be.steps) == 500  # the last row is logged, not stepped


def test_the_tick_is_loaded_before_the_clock_on_scratch_copies(monkeypatch: pytest.MonkeyPatch) -> None:
    """The tick's compiled code loads on its first call (numba's cache, ~0.3 s once per process), which was charged
    to the wall time of the first backend a process ran (a provenance review: Pinocchio's RTF 1.26 run first, 24.3
    second). simulate makes that call before its clock, on a scratch log row and copies of the controller's arrays:
    the clock starts after it, and the log is each tick's once (the seven backends' effort logs stayed equal to
    the last bit with it, 28 Nov)."""
    from legbench import tick

    calls: list[tuple[int, tuple[int, ...], float]] = []
    real = tick.tick
    clock = [0.0]

    def counting(k: int, *args: Any) -> int:
        calls.append((k, args[-2].shape, clock[0]))
        return int(real(k, *args))

    def perf_counter() -> float:  # a clock that counts its reads: the tick calls made before each read
        clock[0] += 1.0
        return clock[0]

    monkeypatch.setattr(tick, "tick", counting)
    monkeypatch.setattr(run.time, "perf_counter", perf_counter)
    tr, _ = _simulate(DOC)
    assert calls[0][:2] == (0, (1, 12)) and calls[0][2] == 0.0  # the scratch call, before the clock's first read
    assert [c[:2] for c in calls[1:]] == [(k, (501, 12)) for k in range(501)]  # then each tick once, on the log
    assert len(tr.t) == 501


def test_a_controllers_imports_are_made_before_the_clock(monkeypatch: pytest.MonkeyPatch) -> None:
    """A trajectory's start() imported scipy.interpolate (0.5-0.9 s once per process) inside the timed loop, so the
    first backend a process ran the ellipse on was charged for it (Pinocchio 0.19 s run first, 0.03 s second; a
    harness review). simulate calls every controller's prepare() before its clock's first read, and the trajectory
    controller's imports scipy.interpolate there."""
    from legbench import controllers

    clock, prepared = [0.0], []
    real_clock = run.time.perf_counter

    def perf_counter() -> float:  # counts the run loop's own reads (numba's event timing reads it too)
        if sys._getframe(1).f_code.co_filename == run.__file__:
            clock[0] += 1.0
        return real_clock()

    real = controllers.TrajectoryController.prepare

    def recording(self: controllers.TrajectoryController) -> None:
        prepared.append(clock[0])
        real(self)

    doc = {"name": "fake", "duration": 0.1,
           "events": [{"t": 0.0, "ellipse": {"a": 0.15, "b": 0.06, "DY": 0.11208, "DZ": 0.105, "dth": 0.0, "T": 5.0,
                                             "points": 50, "repetitions": 1, "approach": 1.0}}]}  # fmt: skip
    sc = scenario.parse(doc)
    be = FakeBackend()
    phys = scenario.physics_of(sc)
    be.load(Path("unused"), phys, {})
    monkeypatch.setattr(controllers.TrajectoryController, "prepare", recording)
    monkeypatch.setattr(run.time, "perf_counter", perf_counter)  # counted from here: the run's own reads
    tr = run.simulate(sc, be, phys)
    assert prepared == [0.0] and len(tr.t) == 101  # once, before the clock's first read
    assert "scipy.interpolate" in sys.modules


def test_logged_torque_is_what_the_backend_received_and_state_follows_zoh() -> None:
    """Row k: q_{k+1} = q_k + qd_k T + tau_k T^2/(2I) exactly (fake double integrator)."""
    tr, be = _simulate(DOC)
    np.testing.assert_array_equal(np.array(be.steps), tr.tau[:-1])
    T, I = 1e-3, 0.01
    pred = tr.q[:-1] + tr.qd[:-1] * T + tr.tau[:-1] * T**2 / (2 * I)
    np.testing.assert_allclose(tr.q[1:], pred, atol=1e-14)


def test_events_switch_controllers_at_their_tick() -> None:
    tr, _ = _simulate(DOC)
    assert set(tr.controller[:250]) == {"position"}
    assert set(tr.controller[250:]) == {"effort"}


def test_torque_is_saturated_at_the_joint_limits() -> None:
    """A 1.5 rad step at Kp 1000 asks joint 1 for 1500 N m: the logged torque is the model's effort limit exactly
    (7.051408 N m, the spec's), and no logged torque of any joint exceeds its limit."""
    doc = {**DOC, "gains": {"Kp": 1000.0}, "events": [{"t": 0.0, "position": {"joint": [1.5, 0.0, 0.0]}}]}
    tr, _ = _simulate(doc)
    assert LIMIT[0] == 7.051408 and tr.tau[0, 0] == LIMIT[0]
    assert np.all(np.abs(tr.tau) <= LIMIT)


def test_outputs_parquet_csv_and_run_json(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    sc = scenario.parse(DOC)
    tr, _ = _simulate(DOC)
    out = results.write_run(sc, [tr], tmp_path / "fake", csv=True)
    df = pd.read_parquet(out / "fake.parquet")
    assert list(df.columns) == list(signals.RUN_COLUMNS)
    np.testing.assert_array_equal(df["q1"].to_numpy(), tr.q[:, 0])
    assert (out / "fake.csv").exists()
    meta = json.loads((out / "run.json").read_text())
    assert meta["scenario"]["name"] == "fake"
    assert meta["backends"]["fake"]["status"] == "ok"
    assert "numpy" in meta["versions"]
    # provenance (a review): when it was written, in UTC; the leg file and its digest; the CPU model where Linux
    # says it (/proc/cpuinfo's model name: platform.processor() is empty there)
    import datetime

    assert datetime.datetime.fromisoformat(meta["written"]).utcoffset() == datetime.timedelta(0)
    assert meta["leg"]["digest"] == resources.param_digest(resources.model_file())
    cpuinfo = Path("/proc/cpuinfo")
    if cpuinfo.is_file():
        model = next(x.split(":", 1)[1].strip() for x in cpuinfo.read_text().splitlines() if x.startswith("model name"))
        assert meta["platform"]["cpu_model"] == model
    assert not list(tmp_path.glob(".*tmp*"))  # no half-written temp dir left behind


def test_refuses_to_overwrite_another_scenarios_results(tmp_path: Path) -> None:
    sc = scenario.parse(DOC)
    tr, _ = _simulate(DOC)
    results.write_run(sc, [tr], tmp_path / "x")
    other = scenario.parse({**DOC, "name": "other"})
    with pytest.raises(LegbenchError, match="holds results of scenario 'fake'"):
        results.write_run(other, [tr], tmp_path / "x")
    results.write_run(sc, [tr], tmp_path / "x")  # same scenario: replaced


def test_diverging_backend_is_stopped_and_marked_failed() -> None:
    class Exploding(FakeBackend):
        def step(self, tau: np.ndarray) -> None:
            super().step(tau)
            if len(self.steps) == 100:
                self.qd[:] = np.nan

    sc = scenario.parse(DOC)
    be = Exploding()
    phys = scenario.physics_of(sc)
    be.load(Path("unused"), phys, {})
    tr = run.simulate(sc, be, phys)
    assert tr.status == "failed"
    assert "not finite" in (tr.reason or "")
    assert len(tr.t) == 100 and np.isfinite(tr.q).all()


@pytest.mark.parametrize(
    ("method", "value", "words"),
    [
        ("integrator_family", "semi-implicit", "integrator_family() returned 'semi-implicit', not one of euler, "),
        ("sub_steps", 0, "sub_steps() returned 0, not a whole number >= 1"),
        ("slides_with", "mu", "slides_with() returned 'mu', not 'mu_s' or 'mu_k'"),
    ],
)
def test_a_backend_declaring_what_legbench_cannot_read_fails_its_run_naming_it(
    method: str, value: object, words: str
) -> None:
    """A plug-in's integrator_family() of 'semi-implicit' (FAMILY_TEXT's words for euler) ran with exit 0 and
    verification then marked every check of it not applicable, silently; sub_steps() 0 was a ZeroDivisionError
    row in verify. Each fails the backend's run with a reason naming the method and the value."""
    sc = scenario.parse(DOC)
    be = FakeBackend()
    setattr(be, method, lambda: value)
    phys = scenario.physics_of(sc)
    be.load(Path("unused"), phys, {})
    tr = run.simulate(sc, be, phys)
    assert tr.status == "failed" and words in (tr.reason or ""), tr.reason


def test_a_step_that_raises_keeps_the_row_read_before_it() -> None:
    """A plug-in's step() raising at t = 0.05 s: the reason said t = 0.0500 s while the log ended at 0.049 s (the
    row of the state read at 0.05 s, written before the step, was dropped). It is kept: the log ends at the time
    the reason names; a read() that raises keeps nothing of its tick."""

    class Breaking(FakeBackend):
        def step(self, tau: np.ndarray) -> None:
            if len(self.steps) == 50:
                raise RuntimeError("solver gave up")
            super().step(tau)

    sc = scenario.parse(DOC)
    be = Breaking()
    phys = scenario.physics_of(sc)
    be.load(Path("unused"), phys, {})
    tr = run.simulate(sc, be, phys)
    assert tr.status == "failed" and "RuntimeError at t = 0.0500 s: solver gave up" in (tr.reason or "")
    assert len(tr.t) == 51 and tr.t[-1] == pytest.approx(0.05) and np.isfinite(tr.q).all()

    class Unreadable(FakeBackend):
        def read(self) -> tuple[float, ...]:
            if len(self.steps) == 50:
                raise RuntimeError("lost the state")
            return super().read()

    be2 = Unreadable()
    be2.load(Path("unused"), phys, {})
    tr = run.simulate(sc, be2, phys)
    assert tr.status == "failed" and len(tr.t) == 50 and tr.t[-1] == pytest.approx(0.049)


def test_results_are_bit_identical_for_any_number_of_jobs(tmp_path: Path) -> None:
    """Tasks run in separate processes with --jobs 2 give exactly the logs of --jobs 1, in input order."""
    from legbench import backends

    root = Path(__file__).resolve().parent.parent / "scenarios"
    scs = [scenario.load(root / f"{t}.yaml", {"duration": 0.5}) for t in ("position", "effort")]
    names = [n for n in ("pinocchio", "mujoco", "pybullet") if n in backends.available()]
    one = run.run_many([(s, None, tmp_path / f"{s.name}-1") for s in scs], names, jobs=1, progress=False)
    two = run.run_many([(s, None, tmp_path / f"{s.name}-2") for s in scs], names, jobs=2, progress=False)
    for res1, res2 in zip(one, two, strict=True):
        assert [tr.backend for tr in res1] == [tr.backend for tr in res2] == names
        for a, b in zip(res1, res2, strict=True):
            for field in ("t", "q", "qd", "tau", "f"):
                np.testing.assert_array_equal(getattr(a, field), getattr(b, field))
    for s in scs:
        for n in names:
            assert (tmp_path / f"{s.name}-1" / f"{n}.parquet").read_bytes() == (
                tmp_path / f"{s.name}-2" / f"{n}.parquet"
            ).read_bytes()


def test_an_engine_that_crashes_its_worker_is_marked_failed_and_the_others_finish(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """--jobs 2, Pinocchio, a plug-in engine whose first step kills its process with SIGSEGV (as a crash in
    an engine's C code would), and MuJoCo: the crash is that backend's failure (run.json: failed, the signal
    named), the other two finish whole (501 ticks of 0.5 s) and nothing is reported as interrupted."""
    from legbench import backends

    site = tmp_path / "site"
    install_crashing_engine(site)
    monkeypatch.syspath_prepend(str(site))
    names = [n for n in ("pinocchio", "crashy", "mujoco") if n == "crashy" or n in backends.available()]
    sc = scenario.load(Path(__file__).resolve().parent.parent / "scenarios" / "effort.yaml", {"duration": 0.5})
    (res,) = run.run_many([(sc, None, tmp_path / "out")], names, jobs=2, progress=False)
    by = {tr.backend: tr for tr in res}
    assert by["crashy"].status == "failed" and "killed by SIGSEGV" in str(by["crashy"].reason)
    assert all(by[n].status == "ok" and len(by[n].t) == 501 for n in names if n != "crashy")
    meta = json.loads((tmp_path / "out" / "run.json").read_text())
    assert meta["backends"]["crashy"]["status"] == "failed" and meta["complete"] is True


def test_profile_selects_settings_and_names_the_run_directory(tmp_path: Path) -> None:
    """A scenario's profile reaches the backend (recorded in run.json) and its directory is <name>__<profile>;
    a per-backend profile wins over the scenario's."""
    doc = {
        "name": "t",
        "duration": 0.01,
        "profile": "engine-defaults",
        "events": [{"t": 0.0, "position": {"joint": [0, 0, 0]}}],
        "comparison": {"steady_window": 0.005},
    }
    sc = scenario.parse(doc)
    assert results.out_dir_for(tmp_path, sc, None).name == "t__engine-defaults"
    assert results.out_dir_for(tmp_path, sc, "reference").name == "t__engine-defaults__reference"
    (tr,) = run.run(sc, ["pinocchio"], tmp_path / "a", progress=False)
    assert tr.info["profile"] == "engine-defaults"
    meta = results.read_meta(tmp_path / "a")
    assert meta["scenario"]["profile"] == "engine-defaults"
    assert backends.load("pinocchio", scenario.physics_of(sc), {"profile": "matched"}, "engine-defaults").profile == (
        "matched"
    )


def test_delayed_switch_and_force_delay_tau_is_gravity_compensation() -> None:
    """delay 13 ms: the position controller runs to tick 262, effort from 263 (0.25 s + 0.013 s at 1 kHz);
    force_delay 7 ms: ticks 263..269 send h_d = 0, so tau = G(q) exactly (to 1e-12 N m, float rounding
    of J^T 0 + G), and from tick 270 tau = J^T h_d + G(q) with the event's force."""
    h_d = [0.0, 0.0, -5.0]
    doc = {**DOC, "events": [DOC["events"][0], {"t": 0.25, "effort": {"force": h_d}, "delay": 0.013,
                                                  "force_delay": 0.007}]}  # fmt: skip
    tr, _ = _simulate(doc)
    plain, _ = _simulate({**DOC, "events": DOC["events"][:1]})  # the position controller alone
    assert set(tr.controller[:263]) == {"position"} and set(tr.controller[263:]) == {"effort"}
    np.testing.assert_array_equal(tr.tau[:263], plain.tau[:263])  # the previous controller kept running
    for k in range(263, 270):
        np.testing.assert_allclose(tr.tau[k], kinematics.gravity(tr.q[k]), rtol=0, atol=1e-12)
    for k in (270, 300, 499):
        expect = kinematics.jacobian(tr.q[k]).T @ np.array(h_d) + kinematics.gravity(tr.q[k])
        np.testing.assert_allclose(tr.tau[k], np.clip(expect, -LIMIT, LIMIT), rtol=0, atol=1e-12)
    assert np.abs(tr.tau[270] - kinematics.gravity(tr.q[270])).max() > 0.1  # the force is on


def test_the_effort_controller_compensates_the_scenarios_gravity() -> None:
    """physics.gravity 3.71 m/s^2 (Mars): the run loop gives the effort controller the scenario's gravity, so
    from its first tick tau = J^T h_d + G(q) with G for 3.71, not the leg file's 9.81 (to 1e-12 N m; the
    two differ by about 0.6 N m at this pose)."""
    h_d = [0.0, 0.0, -5.0]
    doc = {**DOC, "physics": {"gravity": 3.71}, "events": [DOC["events"][0], {"t": 0.25, "effort": {"force": h_d}}]}
    tr, _ = _simulate(doc)
    scale = 3.71 / load_params().gravity
    for k in (250, 275, 300):
        expect = kinematics.jacobian(tr.q[k]).T @ np.array(h_d) + scale * kinematics.gravity(tr.q[k])
        np.testing.assert_allclose(tr.tau[k], np.clip(expect, -LIMIT, LIMIT), rtol=0, atol=1e-12)
    assert np.abs((1 - scale) * kinematics.gravity(tr.q[250])).max() > 0.1


def test_backend_warnings_reach_run_json_and_residuals_reach_metrics(tmp_path: Path) -> None:
    """Explicit stick-slip friction at 50 us is coarser than m v_th / (mu_s Fn) on the effort task: the backend
    says so and run.json keeps it; the implicit default gives no warning. The law's own backend follows the
    law: its penetration residual |y - Fn_spring/Kp| is round-off (< 1e-9 m against ~5 mm of penetration)."""
    from legbench.compare import compare

    root = Path(__file__).resolve().parent.parent / "scenarios"
    sc = scenario.load(root / "effort.yaml", {"duration": 0.6, "backends.pinocchio.friction": "explicit"})
    (tr,) = run.run(sc, ["pinocchio"], tmp_path / "explicit", progress=False)
    assert tr.info["warnings"] and "v_th" in " ".join(tr.info["warnings"])
    assert results.read_meta(tmp_path / "explicit")["backends"]["pinocchio"]["info"]["warnings"] == tr.info["warnings"]
    sc = scenario.load(root / "effort.yaml", {"duration": 0.6})
    (tr,) = run.run(sc, ["pinocchio"], tmp_path / "implicit", progress=False)
    assert tr.info["warnings"] == []
    df = compare(tmp_path / "implicit").frame()
    pen = df[(df.backend == "pinocchio") & (df.metric == "residual_penetration_max")]["value"]
    assert len(pen) == 1 and float(pen.iloc[0]) < 1e-9
    n = df[(df.backend == "pinocchio") & (df.metric == "residual_n_contact")]["value"]
    assert float(n.iloc[0]) == 600  # every tick but t = 0, where q* holds the foot 4 um above the ground


def test_a_run_whose_friction_chatters_says_so_in_run_json(tmp_path: Path) -> None:
    """The law's implicit friction step at 50 us holds the effort task's foot for v_th down to 2e-5 m/s (Fx, Fy
    spread 1e-4 N) and chatters below, 1e-5 (22 N, the friction flipping near its bound), where no step bound
    of the backend's says so: the run loop reads the chatter from the log (the friction reversing and reversing
    back within two ticks) and warns, once, in run.json; at 1e-4 it gives no warning (nor at the leg's own v_th:
    test_backend_warnings_reach_run_json_and_residuals_reach_metrics; at 2e-5 and 3e-5 the end holds but the
    first 0.6 s chatter, Fx, Fy spread 17-22 N, and the warning says so). (A review found the chattering run
    exiting 0 without a word, 27 Nov.)"""
    root = Path(__file__).resolve().parent.parent / "scenarios"
    sc = scenario.load(root / "effort.yaml", {"duration": 0.6, "physics.contact.v_th": 1e-5})
    (tr,) = run.run(sc, ["pinocchio"], tmp_path / "chatter", progress=False)
    said = [w for w in tr.info["warnings"] if "the friction chatters" in w]
    assert len(said) == 1 and " of 600 ticks in contact, from t = 0.0" in said[0], tr.info["warnings"]
    assert results.read_meta(tmp_path / "chatter")["backends"]["pinocchio"]["info"]["warnings"] == tr.info["warnings"]
    sel = tr.t >= 0.3
    assert tr.f[sel, :2].std(axis=0).max() > 5.0  # [N]: what the warning is about
    sc = scenario.load(root / "effort.yaml", {"duration": 0.6, "physics.contact.v_th": 1e-4})
    (tr,) = run.run(sc, ["pinocchio"], tmp_path / "holds", progress=False)
    assert tr.info["warnings"] == [] and tr.f[sel, :2].std(axis=0).max() < 0.01


def _run_json(d: Path, name: str, duration: float, walls: dict[str, float]) -> None:
    d.mkdir(parents=True)
    doc = {"scenario": {"name": name, "duration": duration},
           "backends": {b: {"status": "ok", "wall_time": w} for b, w in walls.items()}}  # fmt: skip
    (d / "run.json").write_text(json.dumps(doc))


def test_runs_are_ordered_longest_first_by_earlier_measured_wall_times(tmp_path: Path) -> None:
    """Cost hints: wall time per simulated second from the run.json already in an output directory, else from
    the same directory under the baseline root, else the backend's median elsewhere, else 1 s/s."""
    out = tmp_path / "latest"
    base = tmp_path / "baseline"
    _run_json(out / "fake", "fake", 2.0, {"slow": 8.0, "fast": 0.5})  # 4 s/s and 0.25 s/s
    _run_json(base / "other", "other", 4.0, {"slow": 4.0, "mid": 4.0})  # 1 s/s each
    _run_json(base / "fake", "fake", 2.0, {"slow": 100.0})  # the output directory's own measurement wins
    hints = run.cost_hints([out / "fake", out / "other", None], roots=[base])
    assert hints == {("fake", "slow"): 4.0, ("fake", "fast"): 0.25, ("other", "slow"): 1.0, ("other", "mid"): 1.0}
    sc = scenario.parse(DOC)  # 0.5 s
    plan = [(0, sc, "fast", None), (0, sc, "slow", None), (0, sc, "mid", None), (0, sc, "unknown", None)]
    est = run._estimates(plan, [out / "fake"], hints)
    # fast 0.25 s/s; slow 4 s/s (own); mid: median elsewhere 1 s/s; unknown: 1 s/s
    assert est == pytest.approx([0.125, 2.0, 0.5, 0.5])
    assert run.cost_hints([tmp_path / "missing"], roots=[]) == {}  # nothing there: no hint, no error


class _OrderPool:
    """A stand-in for the process pool that records the order run_many hands its tasks out in, and returns a
    finished result per task without running anything."""

    jobs = 2

    def __init__(self) -> None:
        self.order: list[tuple[str, str]] = []

    def imap_unordered(self, fn: Any, tasks: list[Any], order: list[int], on_crash: Any) -> Any:
        for j in order:
            sc, name, *_ = tasks[j]
            self.order.append((sc.name, name))
            yield j, type("Done", (), {"status": "ok", "backend": name})()

    def close(self) -> None:
        pass

    def terminate(self) -> None:
        pass


def test_run_many_hands_the_runs_out_longest_first(monkeypatch: pytest.MonkeyPatch) -> None:
    """The pool gets the runs in decreasing estimated cost (duration x measured s/s; runs not written anywhere
    take their backend's median rate), ties in plan order, and the results come back in plan order whatever the
    order they finished in."""
    short, long_ = scenario.parse(DOC), scenario.parse({**DOC, "name": "long", "duration": 2.0})  # 0.5 s, 2 s
    # medians: slow 2 s/s, fast 0.5 s/s, mid 0.5 s/s
    hints = {("a", "slow"): 1.0, ("b", "slow"): 3.0, ("a", "fast"): 0.5, ("a", "mid"): 0.5}
    monkeypatch.setattr(run, "cost_hints", lambda outs: hints)
    pool = _OrderPool()
    got = run.run_many([(short, None, None), (long_, None, None)], ["fast", "slow", "mid"], jobs=2, progress=False,
                       pool=pool)  # type: ignore[arg-type]  # fmt: skip
    # costs [s]: fake/fast 0.25, fake/slow 1, fake/mid 0.25, long/fast 1, long/slow 4, long/mid 1
    assert pool.order == [("long", "slow"), ("fake", "slow"), ("long", "fast"), ("long", "mid"), ("fake", "fast"),
                          ("fake", "mid")]  # fmt: skip
    assert [[r.backend for r in rs] for rs in got] == [["fast", "slow", "mid"], ["fast", "slow", "mid"]]


def test_backend_rates_are_each_backends_median_cost_over_a_results_tree(tmp_path: Path) -> None:
    """run.backend_rates: the median wall time per simulated second of each backend over every run directory
    under a root (the baseline), for studies that start their slowest runs first; nothing readable: empty."""
    base = tmp_path / "baseline"
    _run_json(base / "a", "a", 2.0, {"slow": 8.0, "fast": 0.5})  # 4 and 0.25 s/s
    _run_json(base / "b", "b", 1.0, {"slow": 2.0, "fast": 0.25})  # 2 and 0.25 s/s
    _run_json(base / "c", "c", 4.0, {"slow": 12.0})  # 3 s/s
    assert run.backend_rates(base) == {"slow": pytest.approx(3.0), "fast": pytest.approx(0.25)}
    assert run.backend_rates(tmp_path / "missing") == {}


def test_signals_are_held_while_results_are_written() -> None:
    """A SIGINT inside deferred_interrupts() lets the block finish, then raises KeyboardInterrupt once."""
    import os
    import signal

    finished = []
    with pytest.raises(KeyboardInterrupt):
        with run.deferred_interrupts() as got:
            os.kill(os.getpid(), signal.SIGINT)
            for _ in range(1000):  # bytecode boundaries at which the handler runs
                pass
            finished.append(got[:])
    assert finished == [[signal.SIGINT]]
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler  # restored


def test_backend_read_is_state_and_ground_force_as_floats() -> None:
    """``Backend.read()`` (the run loop's one read per tick, overridden by backends for speed) returns exactly
    the numbers of ``state()`` and ``ground_force()``, bit for bit, after steps in and out of contact."""
    from legbench import resources
    from legbench.scenario import physics_of

    sc = scenario.shorten(scenario.load(resources.scenarios_dir() / "combined.yaml"), 2.5)
    for name in [b for b in ("pinocchio", "mujoco", "pybullet") if b in backends.available()]:
        for mode in ("native", "reference"):
            physics = physics_of(sc, mode)
            be = backends.load(name, physics, sc.backends.get(name, {}), sc.profile)
            try:
                tr = run.simulate(sc, be, physics)  # ends in contact (the push starts at 2 s)
                q, qd = be.state()
                f = be.ground_force()
                assert be.read() == (*q.tolist(), *qd.tolist(), *f.tolist())
                assert f[2] > 0.0 and tr.f[-1][2] == f[2]
            finally:
                be.close()


_WRITER_MEMORY = """
import sys, tracemalloc, numpy as np
from pathlib import Path
from typing import Any
import pyarrow as pa
from legbench import results
n = 64001  # a 64 s run at 1 kHz
rng = np.random.default_rng(0)
log = rng.normal(size=(n, 12))
tr = results.RunResult("fake", np.arange(n) * 1e-3, log[:, 0:3], log[:, 3:6], log[:, 9:12], log[:, 6:9],
                       np.full(n, "effort", dtype=object), foot=rng.normal(size=(n, 3)))
series = sum(a.nbytes for a in (tr.t, log, tr.controller))
pool0 = pa.default_memory_pool().max_memory()
tracemalloc.start()
results.write_log(tr, Path(sys.argv[1]))
numpy_peak = tracemalloc.get_traced_memory()[1]
arrow_peak = pa.default_memory_pool().max_memory() - pool0
print((numpy_peak + arrow_peak) / series)
"""


def test_writing_a_log_holds_a_row_group_not_copies_of_the_log(tmp_path: Path) -> None:
    """Writing a 64 s log (7.2 MB) allocates at most 0.8x the log on top of it (numpy's allocations traced by
    tracemalloc plus Arrow's memory pool peak; measured 0.30 + 0.31: one 16,384-row group of the 64,001 rows
    is 0.26x, Arrow's copy and encoding of it about as much): the writer builds and encodes one row group at a
    time. The old way (stack the columns, a DataFrame, Arrow's conversion of it) measures 2.7 + 1.0 the same
    way. In a fresh process so that Arrow's pool peak is this write's. The file reads back whole."""
    import subprocess
    import sys

    out = tmp_path / "log.parquet"
    r = subprocess.run([sys.executable, "-c", _WRITER_MEMORY, str(out)], capture_output=True, text=True, check=True)
    assert float(r.stdout) <= 0.8
    back = results.read_log(out)
    assert len(back) == 64001 and list(back.columns) == list(signals.RUN_COLUMNS)


def _alive(pool: Any) -> list[Any]:
    """The live worker processes of a LocalExecutor (none once it is closed or terminated)."""
    procs = (getattr(pool._pool, "_processes", None) or {}).values() if pool._pool is not None else ()
    return [p for p in procs if p.is_alive()]


def _made_pools(monkeypatch: pytest.MonkeyPatch) -> list[Any]:
    """Every pool ``run`` makes from now on, in order (the real executors, recorded)."""
    made: list[Any] = []
    real = run.LocalExecutor

    def count(*args: Any, **kw: Any) -> Any:
        made.append(real(*args, **kw))
        return made[-1]

    monkeypatch.setattr(run, "LocalExecutor", count)
    return made


def test_a_given_pool_is_the_one_used_and_closed_afterwards(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """``run_many(pool=start_pool(2))`` runs on that pool (no second pool is made) and closes it when the runs
    end; ``start_pool(1)`` makes none (the runs go in this process)."""
    assert run.start_pool(1) is None
    made = _made_pools(monkeypatch)
    root = Path(__file__).resolve().parent.parent / "scenarios"
    sc = scenario.load(root / "position.yaml", {"duration": 0.05, "comparison.steady_window": 0.01})
    pool = run.start_pool(2)
    assert pool is not None and len(made) == 1
    names = [n for n in ("pinocchio", "mujoco") if n in backends.available()]
    out = run.run_many([(sc, None, tmp_path / "r")], names, jobs=2, progress=False, pool=pool)
    assert [tr.status for tr in out[0]] == ["ok"] * len(names)
    assert len(made) == 1 and pool._pool is None and not _alive(pool)


def test_a_given_pool_is_stopped_when_the_plan_is_refused(tmp_path: Path) -> None:
    """An output directory holding another scenario's run is refused before anything runs, and the pool handed
    in (already starting its workers) is stopped, not left running."""
    sc = scenario.parse(DOC)
    tr, _ = _simulate(DOC)
    results.write_run(scenario.parse({**DOC, "name": "other"}), [tr], tmp_path / "x")
    pool = run.start_pool(2)
    assert pool is not None
    with pytest.raises(LegbenchError, match="holds results of scenario 'other'"):
        run.run_many([(sc, None, tmp_path / "x")], ["pinocchio", "mujoco"], jobs=2, progress=False, pool=pool)
    assert pool._pool is None and not _alive(pool)


def test_run_many_starts_no_more_workers_than_runs_left(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """``run_many(jobs=8)`` of one scenario on two backends makes a pool of 2 (each worker a process importing
    every engine: the Python API's ``run_scenario(jobs=1000)`` started 1000), and a resume counts only the
    runs left: after one of the two backends finished, jobs=8 runs the other in this process (a pool of 1)."""
    made = _made_pools(monkeypatch)
    root = Path(__file__).resolve().parent.parent / "scenarios"
    sc = scenario.load(root / "position.yaml", {"duration": 0.05, "comparison.steady_window": 0.01})
    names = [n for n in ("pinocchio", "mujoco") if n in backends.available()]
    if len(names) < 2:
        pytest.skip("needs pinocchio and mujoco")
    out = tmp_path / "r"
    run.run_many([(sc, None, out)], names, jobs=8, progress=False)
    assert [p.jobs for p in made] == [2]
    meta = json.loads((out / "run.json").read_text())  # as an interrupt leaves it: mujoco not finished
    meta["complete"] = False
    meta["backends"]["mujoco"]["status"] = "interrupted"
    (out / "run.json").write_text(json.dumps(meta))
    (out / "mujoco.parquet").unlink()
    (res,) = run.run_many([(sc, None, out)], names, jobs=8, progress=False)
    assert [p.jobs for p in made] == [2, 1] and [tr.backend for tr in res] == ["mujoco"]


def test_a_pool_for_named_backends_preloads_only_their_engines(tmp_path: Path) -> None:
    """`legbench run --backends pinocchio,mujoco --jobs 2` started workers that imported every installed engine
    (Drake's import alone is about a second on the path to the first run; a two-task run took 2.20-2.29 s, now
    1.97-2.06 s): the pool of named backends preloads the run loop, the tasks and those engines' modules only,
    and its workers (in a fresh process: a fork server keeps the preload of the first pool it served) hold no
    other engine. Without names, every installed engine, as before."""
    from legbench.studies.executors import DEFAULT_PRELOAD

    assert run.run_preload(None) == DEFAULT_PRELOAD
    engines = ("legbench.backends.pinocchio_", "legbench.backends.mujoco_")
    assert run.run_preload(["pinocchio", "mujoco", "pinocchio", "no-such"]) == (*DEFAULT_PRELOAD[:2], *engines)
    script = tmp_path / "pool.py"
    script.write_text(
        "import sys\n\n\ndef engines(_):\n"
        "    return sorted(m for m in ('pinocchio', 'mujoco', 'pybullet', 'pydrake', 'dartpy', 'odepy', 'sympy')\n"
        "                  if m in sys.modules)\n\n\n"
        "if __name__ == '__main__':\n"
        "    from legbench import run\n\n"
        "    pool = run.start_pool(2, tasks=2, backend_names=['pinocchio'])\n"
        "    with pool:\n"
        "        print(pool.map(engines, [0, 1]))\n"
    )
    out = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=300, check=True)
    assert out.stdout.strip() == "[['pinocchio'], ['pinocchio']]", out.stdout + out.stderr


def test_a_warning_is_named_for_its_backend_once(tmp_path: Path) -> None:
    """A backend's warning carries its name once, whether its sentence begins with it (the built-ins' do) or not (a
    plug-in's need not): run.json, and so the report's paragraph, which read 'drake: drake: SAP's point contact ...'
    when the report added the name again."""
    from legbench import report

    class Warns(FakeBackend):
        def warnings(self) -> list[str]:
            return ["fake: the step is coarse", "the contact is soft"]

    sc = scenario.parse(DOC)
    be = Warns()
    be.load(Path("unused"), scenario.physics_of(sc), {})
    assert run.backend_info(be)["warnings"] == ["fake: the step is coarse", "fake: the contact is soft"]
    tr = run.simulate(sc, be, scenario.physics_of(sc))
    results.write_run(sc, [tr], tmp_path / "r")
    md = report.write_report(tmp_path / "r").markdown.read_text()
    assert md.count("fake: the step is coarse") == 1 and "fake: fake:" not in md, md
    assert "fake: the contact is soft" in md
