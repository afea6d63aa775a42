"""``legbench bench --parallel N``: the study's structure, its refusal, the order of its measurements and the
arithmetic of its figures, never a timing.

The order, the warnings and the figures are checked with the measurements replaced by recorders that return
given numbers; one small real study (two 0.2 s tasks on pinocchio, two workers, two repeats, a 0.2 s probe)
checks what a real one records. Whether ``--jobs 2`` is fast is the benchmark's business
(docs/performance.md), not the suite's.
"""

from __future__ import annotations

import json
import logging
import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from legbench import backends, cli, resources, scenario
from legbench.exceptions import LegbenchError
from legbench.studies import scaling

POSITION = resources.scenarios_dir() / "position.yaml"
EFFORT = resources.scenarios_dir() / "effort.yaml"
needs_pin = pytest.mark.skipif("pinocchio" not in backends.available(), reason="needs pin")


def given(**kw: Any) -> scaling.ScalingResult:
    """A result of two repeats with N = 2, from given numbers (any of them overridden by ``kw``)."""
    base: dict[str, Any] = dict(
        jobs=2, runs=["a/x", "b/x", "a/y", "b/y"], probe="every run", wall_warmup=20.0,
        order=[["o"], ["o"]], workers=[2, 2],
        wall_serial=[20.0, 24.0], wall_parallel=[12.0, 10.0], pool_ready=[0.05, 0.05], pool_startup=[0.5, 1.0],
        probe_cpu_alone=[2.0, 2.0], probe_wall_alone=[2.0, 2.5],
        probe_cpu_together=[[2.0, 2.2], [2.0, 2.0]], probe_wall_together=[[3.0, 5.0], [2.5, 2.5]],
    )  # fmt: skip
    base.update(kw)
    return scaling.ScalingResult(**base)


# --------------------------------------------------------------------------- #
# The figures, on given numbers


def test_figures_are_the_stated_ratios() -> None:
    """speed-up = wall(1) / wall(N), with start-up wall(1) / (start-up + wall(N)); ceiling = N wall(alone) / mean
    wall(together), by CPU the same in CPU time; efficiency = speed-up / the wall-time ceiling, per repeat."""
    r = given()
    assert r.speedup().values == pytest.approx((20 / 12, 24 / 10))
    assert r.speedup_with_startup().values == pytest.approx((20 / 12.5, 24 / 11))
    assert r.ceiling_wall().values == pytest.approx((2 * 2.0 / 4.0, 2 * 2.5 / 2.5))
    assert r.ceiling_cpu().values == pytest.approx((2 * 2.0 / 2.1, 2.0))
    assert r.efficiency().values == pytest.approx((20 / 12 / 1.0, 24 / 10 / 2.0))
    assert r.efficiency_with_startup().values == pytest.approx((20 / 12.5 / 1.0, 24 / 11 / 2.0))
    assert r.speedup().median == pytest.approx(0.5 * (20 / 12 + 24 / 10))


def test_other_tenants_load_is_in_the_ceiling_not_the_efficiency() -> None:
    """The review's case: another tenant holds one of two CPUs. Each process's CPU time stays (CPU ceiling 2),
    its wall time doubles when two run (wall ceiling 1), and the batch gains nothing either (speed-up 1):
    the efficiency, on the wall ceiling, is 1, not the 0.5 the CPU ceiling would charge to legbench."""
    r = given(wall_serial=[10.0], wall_parallel=[10.0], pool_ready=[0.0], pool_startup=[0.0], workers=[2],
              order=[["o"]], probe_cpu_alone=[2.0], probe_wall_alone=[2.0], probe_cpu_together=[[2.0, 2.0]],
              probe_wall_together=[[4.0, 4.0]])  # fmt: skip
    assert r.ceiling_cpu().median == pytest.approx(2.0)
    assert r.ceiling_wall().median == pytest.approx(1.0)
    assert r.efficiency().median == pytest.approx(1.0)


def test_written_tables(tmp_path: Path) -> None:
    r = given()
    js, md = scaling.write_scaling(r, tmp_path, {"command": "legbench bench --parallel 2", "machine": {}})
    doc = json.loads(js.read_text())
    for key in ("speedup", "speedup_with_startup", "ceiling_wall", "ceiling_cpu", "efficiency",
                "efficiency_with_startup"):  # fmt: skip
        assert doc["figures"][key]["values"] == pytest.approx(getattr(r, key)().values)
    assert doc["samples"]["pool_startup"] == [0.5, 1.0] and doc["samples"]["workers"] == [2, 2]
    text = md.read_text()
    for row in ("**speed-up**", "with the pool's start-up", "pool start-up", "**ceiling** N x wall",
                "ceiling by CPU time", "**efficiency** speed-up / ceiling", "jobs 1 [s]", "jobs 2, pool"):  # fmt: skip
        assert row in text
    assert "**Warning:**" not in text


# --------------------------------------------------------------------------- #
# Warnings, on given numbers


def test_no_warning_for_a_long_batch() -> None:
    assert scaling._warnings(given()) == []


def test_short_batch_warned() -> None:
    """The review's case: 0.02 s of runs, under the minimum, and under ten times the pool's start-up."""
    r = given(wall_serial=[0.02, 0.02], wall_parallel=[0.02, 0.02], pool_startup=[0.3, 0.3])
    w = scaling._warnings(r)
    assert len(w) == 2
    assert "0.02 s with jobs 1, under 1 s" in w[0]
    assert "under 10 times the pool's start-up (0.30 s)" in w[1]
    r.warnings = w
    assert scaling.markdown(r, {}).count("**Warning:**") == 2


def test_batch_not_much_longer_than_the_startup_warned() -> None:
    r = given(wall_serial=[9.0, 9.0], wall_parallel=[5.0, 5.0], pool_startup=[0.6, 0.6])
    (w,) = scaling._warnings(r)
    assert "5.00 s with jobs 2, under 10 times the pool's start-up (0.60 s)" in w


def test_fewer_workers_warned() -> None:
    (w,) = scaling._warnings(given(workers=[2, 1]))
    assert "1 worker processes, not 2" in w


# --------------------------------------------------------------------------- #
# The probe: the batch's own mix


def test_probe_cuts_every_run_by_one_share() -> None:
    """A batch of 10 s for a 2 s probe: every run of it, each cut to 20 % of its duration (whole control
    periods, at least PROBE_MIN_S), once."""
    scs = [scenario.load(POSITION), scenario.shorten(scenario.load(EFFORT), 0.1)]
    runs, passes, share = scaling.probe_runs(scs, ["x", "y"], 10.0, 2.0)
    assert passes == 1 and share == pytest.approx(0.2)
    assert [(sc.name, b) for sc, b in runs] == [("position", "x"), ("position", "y"), ("effort", "x"), ("effort", "y")]
    assert [sc.duration for sc, _ in runs] == pytest.approx([0.2 * 3.0] * 2 + [scaling.PROBE_MIN_S] * 2)


def test_probe_repeats_a_short_batch_whole() -> None:
    sc = scenario.shorten(scenario.load(POSITION), 0.2)
    runs, passes, share = scaling.probe_runs([sc], ["x", "y"], 0.3, 2.0)
    assert share == 1.0 and passes == 7
    assert [s.duration for s, _ in runs] == [0.2, 0.2]


# --------------------------------------------------------------------------- #
# The study's course, with recorders in place of the measurements


@pytest.fixture
def recorded(monkeypatch: pytest.MonkeyPatch) -> Iterator[list[str]]:
    """Every measurement replaced by a recorder returning fixed numbers; the list of calls, in order."""
    calls: list[str] = []

    def warm_up(batch: Any, names: Any, jobs: int, barriers: Any, probe_s: float = 0.0) -> float:
        calls.append("warm-up")
        return 20.0

    def ceiling_sample(runs: Any, n: int, passes: int = 1) -> list[tuple[float, float]]:
        calls.append("alone" if n == 1 else "together")
        return [(2.0, 2.0)] * n

    def time_serial(batch: Any, names: Any) -> float:
        calls.append("serial")
        return 20.0

    def time_pool(batch: Any, names: Any, jobs: int, warm: Any, barriers: Any) -> scaling.PoolTiming:
        calls.append("pool")
        return scaling.PoolTiming(0.05, 0.5, 11.0, jobs)

    for name, fn in (("warm_up", warm_up), ("ceiling_sample", ceiling_sample), ("time_serial", time_serial),
                     ("time_pool", time_pool)):  # fmt: skip
        monkeypatch.setattr(scaling, name, fn)
    yield calls


def test_order_reversed_every_other_repeat(recorded: list[str]) -> None:
    """The probe alone, N together, the batch with 1, with N; then the reverse: neither side always first."""
    sc = scenario.load(POSITION)
    res = scaling.run_scaling([sc], ["x", "y", "z"], jobs=2, repeats=4)
    forward = ["alone", "together", "serial", "pool"]
    assert recorded == ["warm-up", *forward, *forward[::-1], *forward, *forward[::-1]]
    labels = ["probe alone", "probe 2 together", "batch jobs 1", "batch jobs 2"]
    assert res.order == [labels, labels[::-1], labels, labels[::-1]]
    assert res.workers == [2] * 4 and res.pool_startup == [0.5] * 4 and res.wall_parallel == [11.0] * 4
    assert res.wall_warmup == 20.0 and "cut to 10 %" in res.probe
    assert res.efficiency().values == pytest.approx([20 / 11 / 2] * 4)
    assert res.warnings == []


def test_warnings_logged(recorded: list[str], monkeypatch: pytest.MonkeyPatch, caplog: Any) -> None:
    monkeypatch.setattr(scaling, "time_serial", lambda batch, names: 0.02)
    with caplog.at_level(logging.WARNING, logger="legbench.scaling"):
        res = scaling.run_scaling([scenario.load(POSITION)], ["x", "y"], jobs=2, repeats=1)
    assert res.warnings and all(w in caplog.text for w in res.warnings)


def test_fewer_runs_than_workers_refused(recorded: list[str]) -> None:
    """Three runs for four workers: a pool has no more workers than runs, so nothing is measured."""
    sc = scenario.load(POSITION)
    with pytest.raises(LegbenchError, match=r"--parallel 4: the batch has 3 runs, fewer than 4 workers.*--parallel 3$"):
        scaling.run_scaling([sc], ["x", "y", "z"], jobs=4)
    with pytest.raises(LegbenchError, match=r"the batch has 1 run, fewer than 2 workers"):
        scaling.run_scaling([sc], ["x"], jobs=2)
    assert recorded == []


@needs_pin
def test_fewer_runs_than_workers_exit_2(recorded: list[str], tmp_path: Path, capsys: Any) -> None:
    """Through the command: one line on stderr, exit status 2, nothing run or written."""
    out = tmp_path / "scale"
    argv = ["bench", "--parallel", "2", "--backends", "pinocchio", str(POSITION), "--out", str(out)]
    assert cli.main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "the batch has 1 run, fewer than 2 workers" in err
    assert recorded == [] and not out.exists()


def test_bad_counts_refused() -> None:
    sc = scenario.load(POSITION)
    with pytest.raises(LegbenchError, match="--parallel must be at least 2"):
        scaling.run_scaling([sc], ["pinocchio"], jobs=1)
    with pytest.raises(LegbenchError, match="--repeats must be at least 1"):
        scaling.run_scaling([sc], ["pinocchio"], jobs=2, repeats=0)


# --------------------------------------------------------------------------- #
# One small real study


@pytest.fixture(scope="module")
def study() -> scaling.ScalingResult:
    scs = [scenario.shorten(scenario.load(p), 0.2) for p in (POSITION, EFFORT)]
    return scaling.run_scaling(scs, ["pinocchio"], jobs=2, repeats=2, probe_s=0.2)


@needs_pin
def test_every_sample_recorded(study: scaling.ScalingResult) -> None:
    """Two repeats: per repeat one serial and one pool batch, the pool's start-up, both workers answering,
    one probe alone and two together, in the order stated."""
    assert study.jobs == 2 and study.runs == ["position/pinocchio", "effort/pinocchio"]
    assert study.workers == [2, 2]
    labels = ["probe alone", "probe 2 together", "batch jobs 1", "batch jobs 2"]
    assert study.order == [labels, labels[::-1]]
    for series in (study.wall_serial, study.wall_parallel, study.pool_ready, study.pool_startup,
                   study.probe_cpu_alone, study.probe_wall_alone):  # fmt: skip
        assert len(series) == 2 and all(math.isfinite(v) and v > 0 for v in series)
    assert [len(t) for t in study.probe_cpu_together] == [2, 2] == [len(t) for t in study.probe_wall_together]
    assert all(r <= s for r, s in zip(study.pool_ready, study.pool_startup, strict=True))
    # a process's CPU time never exceeds its wall time (one thread), up to the clocks' resolution
    for cpus, walls in zip(study.probe_cpu_together, study.probe_wall_together, strict=True):
        for cpu, wall in zip(cpus, walls, strict=True):
            assert cpu <= wall + 1e-3
    assert study.efficiency().values == pytest.approx(
        tuple(s / c for s, c in zip(study.speedup().values, study.ceiling_wall().values, strict=True))
    )


def test_a_probe_process_that_crashes_is_one_error_not_a_hang(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A probe process whose engine kills it (SIGSEGV) put nothing on the queue: the parent waited the whole
    timeout (600 s) and then raised a bare queue.Empty, and the other probe waited at the barrier. The parent now
    waits on each probe's pipe, which the dying process closes: one LegbenchError at once, naming the exit code."""
    from fakes import install_crashing_engine

    monkeypatch.syspath_prepend(str(tmp_path))
    crashy = install_crashing_engine(tmp_path)
    sc = scenario.load(resources.scenario("position"), {"duration": 0.05, "comparison.steady_window": 0.02})
    with pytest.raises(LegbenchError, match=r"a probe process ended \(exit code -11\) without its result"):
        scaling.ceiling_sample([(sc, crashy), (sc, crashy)], 2, timeout=300.0)


def test_a_failed_run_of_the_batch_is_refused_naming_it_and_why() -> None:
    """A backend whose runs fail made ``bench --parallel`` end with "runs failed on pybullet", no reason: the
    message names each failed backend with its status and first reason, and what to do, on one line."""
    from legbench.results import RunResult

    ok = RunResult.empty("pinocchio", "ok", "")
    bad = RunResult.empty("pybullet", "failed", "load failed: RuntimeError: engine broken\nsecond line")
    with pytest.raises(LegbenchError) as exc:
        scaling._check([[ok, bad], [ok, bad]])
    why = "failed: load failed: RuntimeError: engine broken\\nsecond line"
    assert str(exc.value) == (f"bench --parallel: runs failed on pybullet ({why}); a batch is timed whole: leave "
                              "them out of --backends")  # fmt: skip
    scaling._check([[ok], [ok]])
