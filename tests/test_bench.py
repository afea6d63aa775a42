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
from typing import Any, ClassVar

import numpy as np
import pytest
from fakes import FakeBackend

from legbench import backends, scenario
from legbench.backends.base import Physics
from legbench.exceptions import LegbenchError, ScenarioError
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


def _ratio_table(md: str) -> list[dict[str, str]]:
    """The rows of bench.md's Ratios table (the first table under "## Ratios"), each cell by its column's header."""
    section = md.split("## Ratios [CPU time]\n", 1)[1]
    table = next(p for p in section.split("\n\n") if p.startswith("| task |"))
    header, _, *rows = ([c.strip() for c in line.split("|")[1:-1]] for line in table.splitlines())
    return [dict(zip(header, r, strict=True)) for r in rows]


def test_ratios_come_from_the_same_samples_and_never_show_a_negative_overhead(
    quick: tuple[int, dict[str, Any], str],
) -> None:
    """Each ratio is the per-repeat quotient of its two variants' samples; with one repeat (--quick) each ratio is
    one sample, neither an overhead nor within noise, and no cost is given."""
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
            assert x["verdict"] == "one sample" and x["overhead_us"] is None
        assert r["harness_us_per_tick"] == "one sample"
        assert r["floor"] == (min(floors, key=lambda f: t[f]["cpu"]["median"]) if floors else "replay")
    table = _ratio_table(md)
    assert [(x["task"], x["backend"]) for x in table] == [(r["task"], r["backend"]) for r in doc["results"]]
    assert {x["harness [us/tick]"] for x in table} == {"one sample"}  # no cost from one sample, so no negative one
    assert "(one sample)" in md and "**" not in md.split("## Ratios")[1].split("\n## ")[0]  # nothing bold


def test_engine_only_replay_reproduces_the_full_run_bit_for_bit(quick: tuple[int, dict[str, Any], str]) -> None:
    """Same torques through the same engine steps after reset: the final state must be identical, not close; so
    must each floor's that retraces the run from its start (Pinocchio's compiled period, MuJoCo's mj_step, Bullet's
    sub-stepping and its 20 commands and steps, the tasks being in native contact)."""
    _, doc, md = quick
    floors = {"pinocchio": {"period_loop"}, "mujoco": {"mj_step_tick"},
              "pybullet": {"bullet_substeps_tick", "python_substeps_tick"}}  # fmt: skip
    for r in doc["results"]:
        assert r["replay_identical"] is True, (r["task"], r["backend"], r["replay_max_diff"])
        assert r["replay_max_diff"] == 0.0
        assert set(r["end_state"]) == {"replay", *floors[r["backend"]]}
        assert all(c == {"identical": True, "max_diff": 0.0} for c in r["end_state"].values()), r["end_state"]
    if "pinocchio" in BENCHED:
        assert "| replay yes; period_loop yes |" in md


def test_declared_floors_and_targets(quick: tuple[int, dict[str, Any], str]) -> None:
    """MuJoCo and PyBullet declare their tightest engine loops per tick and a full/floor target of 1.15;
    Pinocchio its compiled period over the run (``period_loop``) beside the Python aba + law per sub-step, and
    targets on replay / period_loop (1.3) and full / replay (1.2). One repeat: each target is met or missed by
    that one sample (which floor is the cheaper is a timing, the bench's to report, not this test's)."""
    _, doc, _ = quick
    expected = {"mujoco": {"mj_step_tick"}, "pybullet": {"bullet_substeps_tick", "python_substeps_tick"},
                "pinocchio": {"period_loop", "aba+law"}}  # fmt: skip
    for r in doc["results"]:
        floors = {k for k, v in r["timings"].items() if v["kind"] == "floor"}
        assert floors == expected[r["backend"]]
        if r["backend"] != "pinocchio":
            tg = r["targets"]["full/floor"]
            assert tg["limit"] == 1.15 and tg["ratio"] == f"full / {r['floor']}"
            assert tg["verdict"] == ("met" if tg["value"] <= 1.15 else "missed") and tg["n"] == 1
            assert tg["met"] == (tg["verdict"] == "met")
            assert tg["value"] == tg["min"] == tg["max"] == _ratios(r)[tg["ratio"]]["cpu"]["median"]
        else:  # the targets name period_loop, whichever floor measured cheapest in this one sample
            for key, limit in (("replay/period_loop", 1.3), ("full/replay", 1.2)):
                tg = r["targets"][key]
                assert tg["limit"] == limit and tg["ratio"] == key.replace("/", " / ") and tg["n"] == 1
                assert tg["verdict"] == ("met" if tg["value"] <= limit else "missed")
                assert tg["value"] == tg["min"] == tg["max"] == _ratios(r)[tg["ratio"]]["cpu"]["median"]
    met = doc["targets_met"]
    for name in ("mujoco", "pybullet"):
        if name in BENCHED:
            rows = [r for r in doc["results"] if r["backend"] == name]
            assert met[name] == all(r["targets"]["full/floor"]["met"] for r in rows)
    counts = doc["targets"]
    assert sum(counts[v] for v in bench.VERDICTS) == sum(len(r["targets"]) for r in doc["results"])
    assert counts["line"] == bench.count_line(counts)


def test_every_declared_target_names_a_ratio_the_bench_measures(quick: tuple[int, dict[str, Any], str]) -> None:
    """A target naming a variant the backend does not declare is never silently unmeasured."""
    _, doc, _ = quick
    for r in doc["results"]:
        for key, tg in r["targets"].items():
            assert tg["verdict"] != "not measured", (r["task"], r["backend"], key, tg.get("note"))


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


def test_a_floor_counts_as_many_evaluations_per_tick_as_the_run_makes(fake_registry: None) -> None:
    """A per-evaluation kernel that the run calls more than once a sub-step (RK4's four stages, an adaptive solve's
    right-hand sides: lagrange made 62-440 a period) is counted that many times: a reviewer's bench printed
    'full / qdd+law 19.9', one evaluation per tick against a run of hundreds. The fake's 2.5 calls per sub-step
    over 4 sub-steps: a pass covers 50 / 10 periods; the lagrange backend's floor covers the run's periods over
    the right-hand sides its own solves made per period (measured: > 50 on the effort task's push), and
    Pinocchio's aba+law under rk4 a quarter of euler's."""
    sc = _fake_scenario()
    physics = scenario.physics_of(sc)
    b = backends.load("fake", physics, {})
    tr = simulate(sc, b, physics)
    loops = b.kernels(tr.q[:-1], tr.qd[:-1], tr.tau[:-1])
    orig = b.kernels
    for f in loops.values():
        f.calls_per_sub_step = 2.5  # type: ignore[attr-defined]
    b.kernels = lambda q, qd, tau: loops  # type: ignore[method-assign]
    assert bench.kernel_variants(b, tr)["aba+law"][1] == 50.0 / (4 * 2.5)
    assert "2.5 calls each per sub-step" in bench.kernel_variants(b, tr)["aba+law"][2]
    b.kernels = orig  # type: ignore[method-assign]
    effort = bench.load_tasks(bench.TASKS[2:3], duration=0.3)[0]
    physics = scenario.physics_of(effort)
    for name, settings, low, high in (("lagrange", {}, 50.0, 500.0), ("pinocchio", {"integrator": "rk4"}, 80, 80)):
        if name not in backends.available():
            continue
        eng = backends.load(name, physics, settings)
        try:
            tr = simulate(effort, eng, physics)
            (floor,) = [v for k, v in bench.kernel_variants(eng, tr).items() if "+" in k]
            per_tick = (len(tr.t) - 1) / floor[1]  # evaluations per period the floor stands for
            assert low <= per_tick <= high, (name, per_tick)
        finally:
            eng.close()


@pytest.mark.parametrize("name", ["mujoco", "pybullet"])
def test_a_floor_that_skips_the_law_sets_no_target_in_reference_contact(name: str) -> None:
    """MuJoCo's and PyBullet's floors step the engine alone; in reference contact the run also applies the law every
    sub-step, so their 1.15x full/floor target read 4.8x and 3.9x 'missed' there (and bench --check failed) on work
    the floor does not do: no target in reference contact, the 1.15x in native."""
    if name not in backends.available():
        pytest.skip(f"{name} not installed")
    from legbench.backends.base import Physics

    for mode, targets in (("reference", {}), ("native", {"full/floor": 1.15})):
        eng = backends.load(name, Physics(contact_mode=mode), {})
        try:
            assert dict(getattr(eng, "bench_targets")) == targets, mode  # noqa: B009
        finally:
            eng.close()


def test_the_engines_floors_end_where_the_run_ends() -> None:
    """MuJoCo's mj_step_tick and PyBullet's sub-step floors (Bullet's own, and 20 commands and steps) retrace the
    run from its first state in native contact: each declares its end state, which is the run's last state bit
    for bit, so the floor is known to do the run's work (only Pinocchio's period_loop was checked); in reference
    contact they step without the law, declare none, and the replay alone is checked."""
    names = [n for n in ("mujoco", "pybullet") if n in backends.available()]
    if not names:
        pytest.skip("neither mujoco nor pybullet is installed")
    sc = bench.load_tasks(bench.TASKS[2:3], duration=0.2)[0]  # effort: in contact from the start
    for mode, floors in (("native", True), ("reference", False)):
        for r in bench.run_bench([sc], names, repeats=1, warmup=0, memory=False, min_sample=0.0, contact_mode=mode):
            assert r.status == "ok" and all(c["identical"] for c in r.end_state.values()), (r.backend, r.end_state)
            checked = set(r.end_state) - {"replay"}
            assert checked == ({k for k, t in r.timings.items() if t.kind == "floor"} if floors else set()), (
                r.backend, mode, checked)  # fmt: skip


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
        for i, name in enumerate(bench.variant_order(names, 1 + rep)):  # pass 0 was the warm-up
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
    for one in ([0.9], [1.3]):  # one repeat: one sample, whichever side of 1 (it cannot tell)
        single = bench.ratio("a", "b", timing(one), timing([1.0]))
        assert single.verdict == "one sample" and single.overhead_us is None
        assert bench._ratio_cell(single) == f"{one[0]:.3f} (one sample)"
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
    assert m["warmup"] == "10 ms of the task (in contact)" and m["warmup_contact"] is True  # the fake's constant force
    assert m["malloc_trim"] is bench.trim_heap()
    if bench._status("RssAnon")["RssAnon"] is not None:
        assert isinstance(m["anon_run"], int) and isinstance(m["file_run"], int)
        assert m["anon_ratio"] == pytest.approx(m["anon_run"] / m["series"])
    else:
        assert m["anon_run"] is None and "RssAnon unavailable" in m["anon_note"]


class AirFake(KernelFake):
    """The kernel fake with no ground force until a run starts from the effort task's pose on the ground."""

    def reset(self, q: np.ndarray, qd: np.ndarray) -> None:
        super().reset(q, qd)
        self.on_ground = bool(np.allclose(q, scenario.load(bench.CONTACT_WARMUP).q0))
        CALLS.append((id(self), "ground" if self.on_ground else "air"))

    def ground_force(self) -> np.ndarray:
        return np.array([0.0, 0.0, 50.0 if self.on_ground else 0.0])


def test_the_memory_warm_up_goes_through_contact_where_the_task_starts_in_the_air(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The task's own 10 ms stays in the air: 10 ms from the effort task's start on the ground follow, so what an
    engine sets up at its first contact is in the base, not counted as the run's (MuJoCo's combined task showed
    5x its log that way); then the run itself, from the task's start."""
    monkeypatch.setattr(backends, "get", lambda name: AirFake)
    CALLS.clear()
    m = bench.memory_of_run(_fake_scenario(), "fake")
    assert [c[1] for c in CALLS if c[1] in ("air", "ground")] == ["air", "ground", "air"]
    assert m["warmup_contact"] is True and "then 10 ms from the effort task's start on the ground" in m["warmup"]


@pytest.mark.skipif(not bench.trim_heap(), reason="needs glibc's malloc_trim")
def test_a_run_holds_at_least_its_log_in_a_fresh_process() -> None:
    """The base is taken after malloc_trim(0): freed heap still resident would otherwise be reused by the run
    uncounted (measured before: 0.84-0.87x the log, impossible for a run that holds its log). Pinocchio on the
    position task (3001 ticks; the log in the C heap, under the mmap threshold after the warm-up's frees)."""
    sc = bench.load_tasks(bench.TASKS[0:1])[0]
    m = bench._memory_in_fresh_process(sc, "pinocchio", None)
    assert m is not None and m["status"] == "ok", m
    assert m["malloc_trim"] is True and m["warmup_contact"] is True
    assert m["run"] >= 0.98 * m["series"], m  # a few pages of slack at the allocations' edges
    assert m["anon_run"] >= 0.98 * m["series"], m


@pytest.mark.skipif("mujoco" not in backends.available(), reason="mujoco backend not installed")
def test_memory_is_measured_in_a_fresh_process_and_written(tmp_path: Path) -> None:
    args = _parser().parse_args(["bench", str(bench.TASKS[2]), "--backends", "mujoco", "--duration", "0.2",
                                 "--repeats", "1", "--warmup", "0", "--quiet", "--out", str(tmp_path)])  # fmt: skip
    assert args.func(args) == 0
    (row,) = json.loads((tmp_path / "bench.json").read_text())["results"]
    rss = row["rss"]
    assert rss["status"] == "ok" and rss["series"] == row["series_bytes"] == 8 * 14 * 201
    # [bytes]: the base is taken with the engine loaded: an interpreter with numpy and mujoco imported holds 49 MB
    # (27 Nov), the bench's worker with legbench's backend loaded and warmed up 314 MB (docs/performance.md)
    assert rss["peak"] >= rss["base"] > 49e6
    assert rss["warmup"] == "10 ms of the task (in contact)" and "anon_run" in rss and "file_run" in rss
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


def test_the_variants_order_rotates_from_pass_to_pass(fake_registry: None, monkeypatch: pytest.MonkeyPatch) -> None:
    """Within a backend the variants run in a rotated order each pass (warm-up included), so the first variant
    after another backend's, the one a cold start would hit, is each variant in turn, not always ``full``."""
    assert bench.variant_order(["a", "b", "c"], 0) == ["a", "b", "c"]
    assert bench.variant_order(["a", "b", "c"], 4) == ["b", "c", "a"]
    seen: list[str] = []
    real = bench._timed

    def timed(fn: Any) -> tuple[float, float, Any]:
        seen.append(getattr(fn, "__name__", "?"))
        return real(fn)

    monkeypatch.setattr(bench, "_timed", timed)
    bench.run_bench([_fake_scenario()], ["fake"], repeats=3, warmup=1, memory=False, min_sample=0.0)
    names = {"<lambda>": "full", "replay": "replay", "one_pass": "aba+law", "engine": "engine"}
    passes = [[names[n] for n in seen[i : i + 4]] for i in range(0, len(seen), 4)]
    assert passes == [["full", "replay", "engine", "aba+law"], ["replay", "engine", "aba+law", "full"],
                      ["engine", "aba+law", "full", "replay"], ["aba+law", "full", "replay", "engine"]]  # fmt: skip


def test_a_target_is_met_only_when_every_repeat_is_within_it_and_missed_only_when_every_one_is_over() -> None:
    assert bench.target_verdict([1.05, 1.10, 1.15], 1.15) == "met"
    assert bench.target_verdict([1.05, 1.16, 1.10], 1.15) == "inconclusive"  # the median 1.10 alone said met
    assert bench.target_verdict([1.16, 1.30], 1.15) == "missed"
    assert bench.target_verdict([1.10, 1.16, 1.20], 1.15) == "inconclusive"  # the median 1.16 alone said missed
    assert bench.target_verdict([], 1.15) == "not measured"
    counts = {"met": 13, "inconclusive": 2, "missed": 1, "not measured": 0, "failed": 0}
    assert bench.count_line(counts) == "13 met, 2 inconclusive, 1 missed (of 16 targets)"


class TargetFake(KernelFake):
    """The kernel fake with targets, one on a variant it does not declare."""

    bench_targets: ClassVar[Mapping[str, float]] = {"full/replay": 1e9, "replay/floor": 1e-9, "full/nothing": 2.0}


def test_targets_are_judged_per_repeat_and_an_unknown_one_is_not_measured(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(backends, "get", lambda name: TargetFake)
    (r,) = bench.run_bench([_fake_scenario()], ["fake"], repeats=2, warmup=0, memory=False, min_sample=0.0)
    tg = r.targets
    assert tg["full/replay"]["verdict"] == "met" and tg["full/replay"]["n"] == 2
    assert tg["replay/floor"]["verdict"] == "missed" and tg["replay/floor"]["ratio"] == f"replay / {r.floor}"
    assert tg["full/nothing"]["verdict"] == "not measured" and "nothing" in tg["full/nothing"]["note"]
    for t in tg.values():
        assert t["met"] == (t["verdict"] == "met")
    assert bench.target_counts([r]) == {"met": 1, "inconclusive": 0, "missed": 1, "not measured": 1, "failed": 0}


def _planted(verdicts: list[str]) -> list[bench.BenchResult]:
    r = bench.BenchResult(task="position", backend="pinocchio", replay_identical=True,
                          end_state={"replay": {"identical": True, "max_diff": 0.0}})  # fmt: skip
    r.timings = {k: bench.Timing(k, k, [10.0, 11.0], [10.0, 11.0]) for k in ("full", "replay")}
    r.ratios = [bench.ratio("full", "replay", r.timings["full"], r.timings["replay"])]
    r.floor = "replay"
    for i, v in enumerate(verdicts):
        r.targets[f"t{i}"] = {"ratio": "full / replay", "limit": 1.1, "value": 1.1, "min": 1.0, "max": 1.2,
                              "best": 1.1, "n": 2, "verdict": v, "met": v == "met"}  # fmt: skip
    return [r]


@pytest.mark.parametrize(("verdicts", "status"), [(["met", "inconclusive"], 0), (["met", "missed"], 1),
                                                  (["inconclusive", "not measured"], 1)])  # fmt: skip
def test_check_fails_on_a_missed_target_only_and_the_count_line_is_honest(
    verdicts: list[str], status: int, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(bench, "run_bench", lambda *a, **k: _planted(verdicts))
    args = _parser().parse_args(["bench", str(bench.TASKS[0]), "--backends", "pinocchio", "--check", "--quiet",
                                 "--out", str(tmp_path)])  # fmt: skip
    assert args.func(args) == status
    doc = json.loads((tmp_path / "bench.json").read_text())
    line = bench.count_line(doc["targets"])
    assert line.startswith(f"{verdicts.count('met')} met, {verdicts.count('inconclusive')} inconclusive, "
                           f"{verdicts.count('missed')} missed")  # fmt: skip
    md = (tmp_path / "bench.md").read_text()
    assert f"**{line}**" in md and "of 2 targets" in line
    assert ("| MISSED |" in md) == ("missed" in verdicts)


def test_check_fails_when_a_floors_end_state_differs(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    results = _planted(["met"])
    results[0].end_state["period_loop"] = {"identical": False, "max_diff": 1e-3}
    monkeypatch.setattr(bench, "run_bench", lambda *a, **k: results)
    args = _parser().parse_args(["bench", str(bench.TASKS[0]), "--backends", "pinocchio", "--check", "--quiet",
                                 "--out", str(tmp_path)])  # fmt: skip
    assert args.func(args) == 1
    assert "period_loop NO (max diff 0.001)" in (tmp_path / "bench.md").read_text()


def test_the_bench_records_the_load_at_its_start_and_the_stolen_cpu_time() -> None:
    """An asv/pyperf review: the load average was taken only at the end and the hypervisor's steal time not at
    all, so a run on a busy host could not be told from one on an idle one. during() gives both: here 10 s in
    which other guests took 5 % of every CPU's time (in /proc/stat's jiffies), to one jiffy."""
    import os

    from legbench.studies import bench

    hz = os.sysconf("SC_CLK_TCK")
    before = {"load": [1.5, 1.0, 0.5], "time": 100.0, "steal": 1000}
    after = {"load": [1.0, 1.0, 0.5], "time": 110.0, "steal": 1000 + int(0.05 * hz * 10 * (os.cpu_count() or 1))}
    got = bench.during(before, after)
    assert got["load_average_start"] == [1.5, 1.0, 0.5]
    assert got["steal_fraction"] == pytest.approx(0.05, abs=1.0 / hz)
    assert bench.during({**before, "steal": None}, after)["steal_fraction"] is None
    now = bench.conditions()
    assert set(now) == {"load", "time", "steal"}


@pytest.mark.skipif("drake" not in backends.available(), reason="drake backend not installed")
def test_a_contact_mode_the_settings_cannot_run_is_refused_before_any_work(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``bench --contact-mode reference`` with Drake's continuous plant (which cannot take the law as an external
    force): Drake failed at load, exit 3, bench.json written; ``legbench run`` refuses the same before any work.
    Now the bench does too: one line naming the file, the setting and the option, exit 2, nothing written."""
    args = _parser().parse_args(["bench", str(bench.TASKS[0]), "--backends", "drake,pinocchio", "--quick",
                                 "--no-memory", "-q", "--set", "backends.drake.solver=continuous",
                                 "--contact-mode", "reference", "--out", str(tmp_path / "b")])  # fmt: skip
    with pytest.raises(ScenarioError) as exc:
        args.func(args)
    assert exc.value.key == "backends.drake.solver" and str(exc.value).endswith("(with --contact-mode reference)")
    assert "\n" not in str(exc.value) and not (tmp_path / "b").exists()


@pytest.mark.parametrize(
    ("full", "verdict", "cell"),
    [
        ([99.5, 99.8, 100.3], "within noise", "within noise (0.995-1.003)"),
        ([99.8, 100.2, 100.3], "within noise", "within noise (0.998-1.003)"),
        ([99.0, 99.5, 99.8], "faster", "0.995 [0.990-0.998] (faster)"),
        ([110.0, 111.0, 112.0], "overhead", "**1.110** [1.100-1.120]"),
    ],
)
def test_a_full_run_measured_faster_than_its_replay_never_shows_a_negative_overhead(
    full: list[float], verdict: str, cell: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Three repeats, the replay 100 us/tick CPU in each: a full run measured at 99.5, 99.8, 100.3 us/tick (cheaper
    than its replay in two repeats, by noise: the median difference is -0.2 us/tick) or at 99.8, 100.2, 100.3
    (ratios 0.998-1.003, median 1.002) is within noise: bench.json's harness_us_per_tick and bench.md's harness
    column say so, with no figure (neither -0.2 nor a clamped 0.0). Cheaper in every repeat (99.0-99.8) it is
    faster, and the harness column says none (faster), not within noise. Only at 110, 111, 112 (every ratio
    >= 1) is there a cost, the median difference: 11.0 us/tick."""
    r = bench.BenchResult(task="position", backend="pinocchio", replay_identical=True,
                          end_state={"replay": {"identical": True, "max_diff": 0.0}})  # fmt: skip
    r.timings = {"full": bench.Timing("full", "full", full, full),
                 "replay": bench.Timing("replay", "replay", [100.0] * 3, [100.0] * 3)}  # fmt: skip
    r.ratios = [bench.ratio("full", "replay", r.timings["full"], r.timings["replay"])]
    r.floor = "replay"
    monkeypatch.setattr(bench, "run_bench", lambda *a, **k: [r])
    args = _parser().parse_args(["bench", str(bench.TASKS[0]), "--backends", "pinocchio", "--repeats", "3",
                                 "--quiet", "--out", str(tmp_path)])  # fmt: skip
    assert args.func(args) == 0
    (row,) = json.loads((tmp_path / "bench.json").read_text())["results"]
    (line,) = _ratio_table((tmp_path / "bench.md").read_text())
    harness = line["harness [us/tick]"]
    if verdict == "overhead":
        assert row["harness_us_per_tick"] == 11.0 and harness == "11.0"
    else:  # no figure at all, so no negative one (nor a clamped 0.0)
        assert row["harness_us_per_tick"] == harness and not any(c.isdigit() for c in harness), harness
    if verdict in ("within noise", "faster"):  # faster: no harness cost at all, said so beside the ratio's (faster)
        assert harness == {"within noise": "within noise", "faster": "none (faster)"}[verdict]
    assert _ratios(row)["full / replay"]["verdict"] == verdict and line["full / replay"] == cell


def test_the_recorded_command_keeps_the_global_options_and_their_quoting(monkeypatch: pytest.MonkeyPatch) -> None:
    """bench.json's command is the command line as run (a provenance review: a global option before 'bench', such as
    --model, shrank it to "legbench bench"), quoted as a shell needs; from the API, "legbench bench"."""
    import sys

    from legbench.studies import bench

    monkeypatch.setattr(sys, "argv", ["legbench", "--model", "my leg.yaml", "bench", "--repeats", "1"])
    assert bench._command() == "legbench --model 'my leg.yaml' bench --repeats 1"
    monkeypatch.setattr(sys, "argv", ["script.py"])
    assert bench._command() == "legbench bench"


def test_a_contact_mode_given_by_set_and_by_its_option_is_refused(tmp_path: Path) -> None:
    """``--set physics.contact_mode=reference --contact-mode native`` benched native in silence: refused, naming
    both, before anything is timed or written."""
    args = _parser().parse_args(["bench", str(bench.TASKS[0]), "--backends", "pinocchio", "--set",
                                 "physics.contact_mode=reference", "--contact-mode", "native", "--quiet", "--out",
                                 str(tmp_path / "b")])  # fmt: skip
    with pytest.raises(ScenarioError, match="also given by --contact-mode native; give it in one place") as exc:
        args.func(args)
    assert exc.value.key == "physics.contact_mode" and not (tmp_path / "b").exists()
