"""``legbench bench``: structure of the results and the invariants of its ratios, never timings.

One quick benchmark (all four tasks, shortened, one repeat, no memory runs) runs once per
session into a temporary directory; the tests read what it wrote. The mechanism (interleaving,
floors, ratios, memory) is also checked on the fake backend, without an engine.
"""

from __future__ import annotations

import argparse
import json
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from fakes import FakeBackend

from legbench import backends, scenario
from legbench.backends.base import Physics
from legbench.exceptions import LegbenchError
from legbench.run import simulate
from legbench.studies import bench

TASK_NAMES = ["position", "ellipse", "effort", "combined"]
#: The bench's mechanism (timing, replay, memory, floors) is the same for every backend: the suite benches
#: the fast ones (a quick bench of the symbolic model alone costs ~3 CPU-minutes); `make bench` runs all.
BENCHED = [b for b in ("pinocchio", "mujoco", "pybullet") if b in backends.available()]


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="legbench")
    bench.add_cli(parser.add_subparsers(dest="cmd", required=True))
    return parser


@pytest.fixture(scope="module")
def quick(tmp_path_factory: pytest.TempPathFactory) -> tuple[int, dict[str, Any], str]:
    """Exit status, bench.json and bench.md of ``legbench bench --quick``."""
    out = tmp_path_factory.mktemp("bench")
    args = _parser().parse_args(
        ["bench", "--quick", "--quiet", "--no-memory", "--out", str(out), "--backends", ",".join(BENCHED)]
    )
    status = args.func(args)
    return status, json.loads((out / "bench.json").read_text()), (out / "bench.md").read_text()


def _rows(doc: dict[str, Any]) -> dict[tuple[str, str], dict[str, Any]]:
    return {(r["task"], r["backend"]): r for r in doc["results"]}


def test_quick_bench_succeeds_and_covers_every_backend_and_task(quick: tuple[int, dict[str, Any], str]) -> None:
    status, doc, _ = quick
    assert status == 0
    assert set(_rows(doc)) == {(t, b) for t in TASK_NAMES for b in BENCHED}
    assert all(r["status"] == "ok" for r in doc["results"])
    assert doc["settings"]["quick"] is True and doc["settings"]["repeats"] == 1


def _ratios(r: dict[str, Any]) -> dict[str, dict[str, Any]]:
    return {x["label"]: x for x in r["ratios"]}


def test_every_variant_is_timed_in_cpu_and_wall_time(quick: tuple[int, dict[str, Any], str]) -> None:
    _, doc, _ = quick
    for r in doc["results"]:
        assert {"full", "replay"} <= set(r["timings"])
        for name, t in r["timings"].items():
            assert len(t["cpu_samples"]) == len(t["wall_samples"]) == 1, (r["task"], r["backend"], name)
            for clock in ("cpu", "wall"):
                s = t[clock]
                assert s["n"] == 1
                for stat in ("median", "min", "max", "q1", "q3"):
                    assert math.isfinite(s[stat]) and s[stat] > 0, (r["task"], r["backend"], name, clock, stat)
        assert r["steps"] == int(round(r["duration"] * 1000)) and r["sub_steps"] >= 1


def test_ratios_come_from_the_same_samples_and_never_show_a_negative_overhead(
    quick: tuple[int, dict[str, Any], str],
) -> None:
    """Each ratio is the per-repeat quotient of its two variants' samples; an overhead is >= 1 in every repeat
    and costs >= 0 us/tick, anything else is 'within noise' with no cost given."""
    _, doc, md = quick
    for r in doc["results"]:
        t = r["timings"]
        floors = [k for k, v in t.items() if v["kind"] == "floor"]
        labels = {"full / replay"} | {f"full / {f}" for f in floors} | {f"replay / {f}" for f in floors}
        assert set(_ratios(r)) == labels
        for x in r["ratios"]:
            num, den = t[x["num"]], t[x["den"]]
            per_repeat = [a / b for a, b in zip(num["cpu_samples"], den["cpu_samples"], strict=True)]
            assert x["cpu"]["median"] == pytest.approx(float(np.median(per_repeat)), rel=1e-12)
            assert x["best"] == pytest.approx(min(num["cpu_samples"]) / min(den["cpu_samples"]), rel=1e-12)
            if x["verdict"] == "overhead":
                assert x["cpu"]["min"] >= 1.0 and x["overhead_us"] >= 0.0
            elif x["verdict"] == "faster":
                assert x["cpu"]["max"] < 1.0 and x["overhead_us"] is None and len(num["cpu_samples"]) >= 2
            else:
                assert x["verdict"] == "within noise" and x["overhead_us"] is None and x["cpu"]["min"] < 1.0
        assert r["floor"] == (min(floors, key=lambda f: t[f]["cpu"]["median"]) if floors else "replay")
    harness = [line.split("|")[4].strip() for line in md.split("## Ratios")[1].splitlines() if line.startswith("| ")]
    assert all(not h.startswith("-") for h in harness[2:])  # header and rule skipped: no negative cost


def test_engine_only_replay_reproduces_the_full_run_bit_for_bit(quick: tuple[int, dict[str, Any], str]) -> None:
    """Same torques through the same engine steps after reset: the final state must be identical, not close."""
    _, doc, _ = quick
    for r in doc["results"]:
        assert r["replay_identical"] is True, (r["task"], r["backend"], r["replay_max_diff"])
        assert r["replay_max_diff"] == 0.0


def test_declared_floors_and_targets(quick: tuple[int, dict[str, Any], str]) -> None:
    """MuJoCo and PyBullet declare their tightest engine loops per tick and a full/floor target of 1.15;
    Pinocchio's Python aba + law per sub-step is kept as a floor."""
    _, doc, _ = quick
    expected = {"mujoco": {"mj_step_tick"}, "pybullet": {"bullet_substeps_tick", "python_substeps_tick"}}
    for r in doc["results"]:
        floors = {k for k, v in r["timings"].items() if v["kind"] == "floor"}
        if r["backend"] in expected:
            assert floors == expected[r["backend"]]
            tg = r["targets"]["full/floor"]
            assert tg["limit"] == 1.15 and tg["ratio"] == f"full / {r['floor']}"
            assert tg["met"] == (tg["value"] <= 1.15)
            assert tg["value"] == _ratios(r)[tg["ratio"]]["cpu"]["median"]
        if r["backend"] == "pinocchio":
            assert "aba+law" in floors
    met = doc["targets_met"]
    for name in expected:
        if name in BENCHED:
            rows = [r for r in doc["results"] if r["backend"] == name]
            assert met[name] == all(r["targets"]["full/floor"]["met"] for r in rows)


def test_versions_machine_and_settings_are_recorded(quick: tuple[int, dict[str, Any], str]) -> None:
    _, doc, _ = quick
    assert {"python", "numpy"} <= set(doc["versions"])
    assert doc["machine"]["cpus"] >= 1 and doc["machine"]["cpu_model"]
    assert "process_time" in doc["settings"]["clock"]


def test_json_keeps_the_summary_the_report_reads(quick: tuple[int, dict[str, Any], str], tmp_path: Path) -> None:
    """The report's Performance table reads full and engine-only medians, harness, ratio, RTF from bench.json."""
    from legbench import report

    _, doc, _ = quick
    for r in doc["results"]:
        assert r["full_us_per_tick"] == r["timings"]["full"]["cpu"]
        assert r["engine_us_per_tick"] == r["timings"]["replay"]["cpu"]
        assert r["overhead_ratio"] == _ratios(r)["full / replay"]["cpu"]
        assert r["rtf_full"] > 0
    (tmp_path / "bench").mkdir()
    (tmp_path / "bench" / "bench.json").write_text(json.dumps(doc))
    blocks = report._bench_blocks(tmp_path)
    assert len(blocks) == 2  # heading and table, no malformed-output error


def test_markdown_has_a_row_per_backend_and_task_in_each_table(quick: tuple[int, dict[str, Any], str]) -> None:
    _, doc, md = quick
    for r in doc["results"]:
        row = f"| {r['task']} | {r['backend']} |"
        assert sum(line.startswith(row) for line in md.splitlines()) >= 2  # cost table, ratio table


# --------------------------------------------------------------------------- #
# The mechanism on the fake backend (no engine, no timing asserted)

CALLS: list[tuple[int, str]] = []


class KernelFake(FakeBackend):
    """The fake with two sub-step kernels and one per-tick kernel, recording every call's order."""

    def load(self, urdf: Path, physics: Physics, settings: Mapping[str, Any]) -> None:
        super().load(urdf, physics, settings)
        self.n_sub = 4

    def sub_steps(self) -> int:
        return self.n_sub

    def reset(self, q: np.ndarray, qd: np.ndarray) -> None:
        CALLS.append((id(self), "reset"))
        super().reset(q, qd)

    def kernels(self, q: np.ndarray, qd: np.ndarray, tau: np.ndarray) -> dict[str, Any]:
        rows = len(tau)

        def aba() -> None:
            CALLS.append((id(self), "aba"))
            for _ in range(rows):
                pass

        def law() -> None:
            for _ in range(rows):
                pass

        def engine() -> None:
            CALLS.append((id(self), "engine"))

        engine.per_tick = True  # type: ignore[attr-defined]
        return {"aba": aba, "law": law, "engine": engine}


@pytest.fixture
def fake_registry(monkeypatch: pytest.MonkeyPatch) -> None:
    real = backends.get
    monkeypatch.setattr(backends, "get", lambda name: KernelFake if name.startswith("fake") else real(name))
    CALLS.clear()


def _fake_scenario() -> scenario.Scenario:
    return bench.load_tasks(bench.TASKS[0:1], duration=0.05)[0]  # position, 50 periods


def test_kernels_per_sub_step_add_up_to_one_floor_and_per_tick_ones_stand_alone(fake_registry: None) -> None:
    sc = _fake_scenario()
    physics = scenario.physics_of(sc)
    b = backends.load("fake", physics, {})
    tr = simulate(sc, b, physics)
    v = bench.kernel_variants(b, tr)
    assert set(v) == {"aba+law", "engine"}
    assert v["engine"][1] == 50.0  # one call per control period: a pass covers the 50 periods
    assert v["aba+law"][1] == 50.0 / 4  # one call per sub-step: a pass covers 50 sub-steps = 12.5 periods


def test_repeats_are_interleaved_across_backends_with_the_order_rotated(fake_registry: None) -> None:
    """Three repeats after one warm-up through two backends: each pass times full, replay and the floors of one
    backend, then the other; the first backend alternates from pass to pass. Warm-up samples are dropped."""
    res = bench.run_bench([_fake_scenario()], ["fake", "fake2"], repeats=3, warmup=1, memory=False, min_sample=0.0)
    assert [r.backend for r in res] == ["fake", "fake2"]
    for r in res:
        assert r.status == "ok" and r.replay_identical
        assert set(r.timings) == {"full", "replay", "aba+law", "engine"}
        assert all(len(t.cpu_samples) == 3 for t in r.timings.values())
    firsts = [CALLS[i][0] for i, c in enumerate(CALLS) if c[1] == "engine"]  # once per backend per pass
    assert len(firsts) == 2 * 4 and len(set(firsts)) == 2
    pass_first = firsts[0::2]
    assert pass_first[0] != pass_first[1] and pass_first[0] == pass_first[2] and pass_first[1] == pass_first[3]


def test_a_short_variant_is_sampled_as_the_fastest_of_back_to_back_executions(
    fake_registry: None, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A 50-period fake run lasts microseconds: with min_sample 1 s every variant is executed MAX_INNER times
    per sample (sized from the warm-up's single execution) and the sample is the fastest of them; without
    a warm-up, or with min_sample 0, one execution per sample."""
    rng = np.random.default_rng(5)
    seen: list[float] = []
    real = bench._timed

    def timed(fn: Any) -> tuple[float, float, Any]:
        _, _, out = real(fn)
        cpu = float(rng.uniform(1e-4, 1e-3))  # a made-up CPU time [s], so the kept one is known
        seen.append(cpu)
        return cpu, 2 * cpu, out

    monkeypatch.setattr(bench, "_timed", timed)
    (r,) = bench.run_bench([_fake_scenario()], ["fake"], repeats=2, warmup=1, memory=False, min_sample=1.0)
    names = list(r.timings)
    k = bench.MAX_INNER
    assert all(t.inner == k for t in r.timings.values())
    assert len(seen) == len(names) * (1 + 2 * k)
    timed_calls = seen[len(names) :]  # after the warm-up pass: per repeat, k calls of each variant in turn
    ticks = {"full": 50.0, "replay": 50.0, "aba+law": 12.5, "engine": 50.0}  # periods a pass covers
    for rep in range(2):
        for i, name in enumerate(names):
            chunk = timed_calls[(rep * len(names) + i) * k : (rep * len(names) + i + 1) * k]
            assert r.timings[name].cpu_samples[rep] == pytest.approx(1e6 * min(chunk) / ticks[name], rel=1e-12)
            assert r.timings[name].wall_samples[rep] == pytest.approx(2e6 * min(chunk) / ticks[name], rel=1e-12)
    for kwargs in ({"warmup": 0, "min_sample": 1.0}, {"warmup": 1, "min_sample": 0.0}):
        seen.clear()
        (r,) = bench.run_bench([_fake_scenario()], ["fake"], repeats=2, memory=False, **kwargs)  # type: ignore[arg-type]
        assert all(t.inner == 1 for t in r.timings.values())
        assert len(seen) == len(names) * (kwargs["warmup"] + 2)


def test_ratio_is_an_overhead_only_when_every_repeat_is_at_least_one_and_faster_only_when_all_below() -> None:
    def timing(xs: list[float]) -> bench.Timing:
        return bench.Timing("full", "x", list(xs), list(xs))

    over = bench.ratio("a", "b", timing([2.0, 3.0, 2.2]), timing([1.0, 1.5, 1.0]))
    assert over.verdict == "overhead" and over.cpu.median == 2.0 and over.overhead_us == pytest.approx(1.2)
    assert over.best == 2.0  # fastest repeats: 2.0 / 1.0
    noise = bench.ratio("a", "b", timing([1.0, 1.2]), timing([1.1, 1.0]))
    assert noise.verdict == "within noise" and noise.overhead_us is None
    below = bench.ratio("a", "b", timing([0.9]), timing([1.0]))
    assert below.verdict == "within noise" and below.overhead_us is None  # one repeat: cannot tell
    faster = bench.ratio("a", "b", timing([0.9, 0.8, 0.95]), timing([1.0, 1.0, 1.0]))
    assert faster.verdict == "faster" and faster.overhead_us is None and faster.cpu.median == 0.9
    assert "(faster)" in bench._ratio_cell(faster) and "noise" not in bench._ratio_cell(faster)


def test_memory_of_a_run_against_its_log(fake_registry: None) -> None:
    """In-process (the bench runs it in a fresh worker): base, peak and growth in bytes, the series it returns."""
    sc = _fake_scenario()
    m = bench.memory_of_run(sc, "fake")
    assert m["status"] == "ok" and m["base"] > 0 and m["peak"] > 0 and m["run"] >= 0
    assert m["series"] == 8 * 14 * 51  # t, q, qd, tau, f as float64 and the controller column: 14 words per tick
    assert m["ratio"] == pytest.approx(m["run"] / m["series"])
    assert m["method"] in ("clear_refs", "maxrss since start")


@pytest.mark.skipif("mujoco" not in backends.available(), reason="mujoco backend not installed")
def test_memory_is_measured_in_a_fresh_process_and_written(tmp_path: Path) -> None:
    args = _parser().parse_args(["bench", str(bench.TASKS[2]), "--backends", "mujoco", "--duration", "0.2",
                                 "--repeats", "1", "--warmup", "0", "--quiet", "--out", str(tmp_path)])  # fmt: skip
    assert args.func(args) == 0
    (row,) = json.loads((tmp_path / "bench.json").read_text())["results"]
    rss = row["rss"]
    assert rss["status"] == "ok" and rss["series"] == row["series_bytes"] == 8 * 14 * 201
    assert rss["peak"] >= rss["base"] > 50e6  # [bytes]: a fresh interpreter with numpy and MuJoCo loaded
    assert row["mem_peak_bytes"] >= row["series_bytes"]  # the log itself is allocated during the run
    assert "## Memory of one full run" in (tmp_path / "bench.md").read_text()


def test_shorten_drops_events_at_or_after_the_new_end_and_validates() -> None:
    sc = scenario.load(bench.TASKS[3])  # combined: events at 0, 1 and 2 s
    short = bench.shorten(sc, 2.0)
    assert short.duration == 2.0 and [e.t for e in short.events] == [0.0, 1.0]
    assert bench.shorten(sc, 10.0) is sc
    ellipse = bench.shorten(scenario.load(bench.TASKS[1]), 0.5)  # comparison.skip 1.0 s no longer fits
    assert ellipse.comparison.skip == 0.0 and ellipse.n_ticks == 501


def test_quick_durations_reach_every_controller_of_each_task() -> None:
    for sc in bench.load_tasks(bench.TASKS, quick=True):
        full = scenario.load(next(p for p in bench.TASKS if p.stem == sc.name))
        assert [e.controller for e in sc.events] == [e.controller for e in full.events], sc.name
        assert sc.duration == bench.QUICK_DURATIONS[sc.name]


def test_bad_repeats_or_warmup_is_a_user_error() -> None:
    sc = bench.load_tasks(bench.TASKS[:1], duration=0.01)
    with pytest.raises(LegbenchError, match="--repeats must be at least 1"):
        bench.run_bench(sc, ["pinocchio"], repeats=0)
    with pytest.raises(LegbenchError, match="--warmup must be at least 0"):
        bench.run_bench(sc, ["pinocchio"], warmup=-1)


def test_a_backend_that_cannot_load_is_reported_failed_and_exits_3(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A backend whose load fails (the scenario itself is valid) is reported failed; the other backends are
    still benchmarked and written."""
    from legbench.backends.pinocchio_ import PinocchioBackend

    def broken(self: PinocchioBackend, *args: object, **kwargs: object) -> None:
        raise LegbenchError("pinocchio: planted load failure")

    monkeypatch.setattr(PinocchioBackend, "load", broken)
    out = tmp_path / "out"
    args = _parser().parse_args(["bench", str(bench.TASKS[0]), "--duration", "0.01", "--backends",
                                 "pinocchio,mujoco", "--repeats", "1", "--warmup", "0", "--no-memory", "--quiet",
                                 "--out", str(out)])  # fmt: skip
    assert args.func(args) == 3
    rows = {r["backend"]: r for r in json.loads((out / "bench.json").read_text())["results"]}
    assert rows["pinocchio"]["status"] == "failed" and "planted load failure" in rows["pinocchio"]["reason"]
    assert rows["mujoco"]["status"] == "ok"
    assert "FAILED" in (out / "bench.md").read_text()


def test_set_overrides_a_scenario_key_and_a_malformed_one_is_a_user_error(tmp_path: Path) -> None:
    args = _parser().parse_args(["bench", str(bench.TASKS[0]), "--backends", "pinocchio", "--duration", "0.02",
                                 "--set", "backends.pinocchio.dt=1e-4", "--repeats", "1", "--warmup", "0",
                                 "--no-memory", "--quiet", "--out", str(tmp_path)])  # fmt: skip
    assert args.func(args) == 0
    doc = json.loads((tmp_path / "bench.json").read_text())
    assert doc["settings"]["overrides"] == {"backends.pinocchio.dt": 1e-4}
    (row,) = doc["results"]
    assert row["sub_steps"] == 10 and row["mem_peak_bytes"] == 0 and row["rss"] is None
    assert "backends.pinocchio.dt = 0.0001" in (tmp_path / "bench.md").read_text()
    bad = _parser().parse_args(["bench", "--set", "duration", "--out", str(tmp_path)])
    with pytest.raises(LegbenchError, match="expected KEY=VALUE"):
        bad.func(bad)


def test_spread_summarises_samples() -> None:
    s = bench.Spread.of([3.0, 1.0, 2.0, 4.0])
    assert (s.median, s.min, s.max, s.n) == (2.5, 1.0, 4.0, 4)
    assert s.q1 == pytest.approx(1.75) and s.q3 == pytest.approx(3.25)
    assert s.scaled(2.0).median == 5.0
    assert np.isfinite(bench.Spread.of([1.0]).q1)


def test_quick_keeps_a_duration_set_by_name() -> None:
    """``--quick --set duration=64`` runs 64 s once (the memory target's run), not the quick 0.5 s."""
    effort = bench.TASKS[2:3]
    (long,) = bench.load_tasks(effort, quick=True, overrides={"duration": 64.0})
    (short,) = bench.load_tasks(effort, quick=True)
    assert long.duration == 64.0 and long.n_ticks == 64001
    assert short.duration == bench.QUICK_DURATIONS["effort"]
