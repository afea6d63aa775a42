"""``legbench bench`` in quick mode: structure of the results, never timings (those belong in the benchmark).

One quick benchmark (all four tasks, shortened, one repeat) runs once per
session into a temporary directory; the tests read what it wrote.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from legbench import backends, scenario
from legbench.exceptions import LegbenchError
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
    args = _parser().parse_args(["bench", "--quick", "--quiet", "--out", str(out), "--backends", ",".join(BENCHED)])
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


def test_timings_and_ratios_are_finite_and_positive(quick: tuple[int, dict[str, Any], str]) -> None:
    _, doc, _ = quick
    for r in doc["results"]:
        for key in ("full_wall", "engine_wall", "full_us_per_tick", "engine_us_per_tick", "overhead_ratio"):
            s = r[key]
            assert s["n"] == 1
            for stat in ("median", "min", "max", "q1", "q3"):
                assert math.isfinite(s[stat]) and s[stat] > 0, (r["task"], r["backend"], key, stat)
        assert math.isfinite(r["rtf_full"]) and r["rtf_full"] > 0
        assert math.isfinite(r["harness_us_per_tick"])
        assert r["steps"] == int(round(r["duration"] * 1000)) and r["sub_steps"] >= 1


def test_engine_only_replay_reproduces_the_full_run_bit_for_bit(quick: tuple[int, dict[str, Any], str]) -> None:
    """Same torques through the same engine steps after reset: the final state must be identical, not close."""
    _, doc, _ = quick
    for r in doc["results"]:
        assert r["replay_identical"] is True, (r["task"], r["backend"], r["replay_max_diff"])
        assert r["replay_max_diff"] == 0.0


def test_memory_figures_are_present_and_cover_the_time_series(quick: tuple[int, dict[str, Any], str]) -> None:
    _, doc, _ = quick
    for r in doc["results"]:
        ticks = r["steps"] + 1
        # t, q, qd, tau, f as float64 and the controller column as object pointers: 8 (1 + 4 * 3 + 1) bytes per tick
        assert r["series_bytes"] == 8 * 14 * ticks
        assert r["mem_peak_bytes"] >= r["series_bytes"]  # the log itself is allocated during the run
        assert r["mem_excess_bytes"] == r["mem_peak_bytes"] - r["series_bytes"]
        assert r["max_rss_bytes"] > 0


def test_pinocchio_rows_compare_a_sub_step_with_its_own_calls(quick: tuple[int, dict[str, Any], str]) -> None:
    _, doc, _ = quick
    if "pinocchio" not in backends.available():
        pytest.skip("pinocchio backend not installed")
    for task in TASK_NAMES:
        k = _rows(doc)[(task, "pinocchio")]["kernels"]
        for key in ("substep_us", "aba_us", "law_us", "kernels_us", "ratio"):
            assert math.isfinite(k[key]) and k[key] > 0, (task, key)
        assert k["kernels_us"] == pytest.approx(k["aba_us"] + k["law_us"])
        assert k["ratio"] == pytest.approx(k["substep_us"] / k["kernels_us"])
    assert all(r["kernels"] is None for r in doc["results"] if r["backend"] != "pinocchio")


def test_versions_machine_and_targets_are_recorded(quick: tuple[int, dict[str, Any], str]) -> None:
    _, doc, _ = quick
    assert {"python", "numpy"} <= set(doc["versions"])
    assert doc["machine"]["cpus"] >= 1 and doc["machine"]["cpu_model"]
    assert doc["targets"] == dict(bench.TARGETS)
    assert set(doc["targets_met"]) <= set(bench.TARGETS)


def test_markdown_has_one_row_per_backend_and_task(quick: tuple[int, dict[str, Any], str]) -> None:
    _, doc, md = quick
    for r in doc["results"]:
        row = f"| {r['task']} | {r['backend']} |"
        assert sum(line.startswith(row) for line in md.splitlines()) == 2  # timing table, memory table
    assert "## Cost per sub-step against the engine's own calls" in md or "pinocchio" not in backends.available()


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


def test_a_backend_that_cannot_load_is_reported_failed_and_exits_3(tmp_path: Path) -> None:
    """The other backends are still benchmarked and written."""
    bad = tmp_path / "bad.yaml"
    sc = scenario.load(bench.TASKS[0])
    doc = {**bench.shorten(sc, 0.01).raw, "backends": {"pinocchio": {"dt": 3e-4}}}  # does not divide 1 ms
    bad.write_text(yaml.safe_dump(doc))
    out = tmp_path / "out"
    args = _parser().parse_args(["bench", str(bad), "--backends", "pinocchio", "--repeats", "1", "--quiet",
                                 "--out", str(out)])  # fmt: skip
    assert args.func(args) == 3
    (row,) = json.loads((out / "bench.json").read_text())["results"]
    assert row["status"] == "failed" and "does not divide" in row["reason"]
    assert "FAILED" in (out / "bench.md").read_text()


def test_set_overrides_a_scenario_key_and_a_malformed_one_is_a_user_error(tmp_path: Path) -> None:
    args = _parser().parse_args(["bench", str(bench.TASKS[0]), "--backends", "pinocchio", "--duration", "0.02",
                                 "--set", "backends.pinocchio.dt=1e-4", "--repeats", "1", "--warmup", "0",
                                 "--no-memory", "--quiet", "--out", str(tmp_path)])  # fmt: skip
    assert args.func(args) == 0
    doc = json.loads((tmp_path / "bench.json").read_text())
    assert doc["settings"]["overrides"] == {"backends.pinocchio.dt": 1e-4}
    (row,) = doc["results"]
    assert row["sub_steps"] == 10 and row["mem_peak_bytes"] == 0
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
