"""``legbench bench``: what a legbench run costs against the engine alone, in CPU time, per backend and task.

For every task, all backends are loaded side by side and these *variants* are timed, interleaved
repeat by repeat (each repeat goes once through every backend and variant, the backend order
rotated from one repeat to the next, and within a backend the variants' order rotated too, so
neither a load drift on this shared machine nor a cold start after another backend's variants
always lands on the same variant):

* **full**: :func:`legbench.run.simulate`, the real run (state read, checks, events, controller,
  saturation, log);
* **replay**: the engine-only loop called from Python, ``backend.reset(q0, qd0)`` then
  ``backend.step(tau_k)`` for the torques the full run logged: no controller, no log, no checks.
  Its final state must equal the full run's last logged state bit for bit (same torques through
  the same engine steps); if not, the backend is not deterministic or its ``reset`` is incomplete;
* **floors**: whatever the backend declares in :meth:`~legbench.backends.base.Backend.kernels`,
  each a tight loop of the engine's own calls over the run's logged rows (e.g. ``mj_step(m, d, n)``
  per control period, Bullet's own sub-stepping, the backend's compiled period over all rows in one
  compiled call, or ``pin.aba`` and the law called from Python once per sub-step). A kernel is per
  sub-step unless its callable has ``per_tick = True`` or its name ends in ``_tick`` (one call = one
  control period); the per-sub-step kernels of a backend add up to one floor (their cost x sub-steps
  per period). A kernel whose callable has an ``end_state`` attribute (a function returning the
  pass's final (q, qd)) steps the run from its initial state: its end state is checked against the
  run's last logged state bit for bit, as the replay's is.

Every variant is timed in CPU time (:func:`time.process_time`, what the engines' single thread
uses; less sensitive to other processes' load than wall time, not insensitive: on this 2-core VM
the same floor has ranged 107-174 us/tick under other tenants) and wall time, per control period
[us/tick], with min / median / max over the repeats. Ratios are formed per repeat from the same
interleaved samples (full / replay, full / each floor, replay / each floor) and summarised the same
way. With two or more repeats, an overhead is a ratio >= 1 over all repeats (reported with its
spread, and its cost per tick); a ratio below 1 in every repeat is "faster"; where the repeats
straddle 1 it is "within noise": never a negative overhead. A single repeat is one sample, said so.

Memory (``--no-memory`` skips it): the peak RSS of one full run, measured in a fresh worker
process per (task, backend). A :data:`MEMORY_WARMUP` run of the task comes first, and where it stays
in the air one as long from the effort task's start on the ground (:data:`CONTACT_WARMUP`), so the
engine's contact code and buffers are in the base; the heap's free pages are then handed back to the
system (glibc ``malloc_trim(0)``, where there is one: freed memory still resident would otherwise be
reused by the run and not counted), and the RSS is the base (interpreter, imports, engine). The
kernel's peak-RSS mark is reset (``/proc/self/clear_refs``) and the run's peak read back
(``VmHWM``); beside it the growth of ``RssAnon`` (heap and other anonymous memory, at the run's end,
its log still held) and of ``RssFile`` (file-backed pages: code and data of libraries paged in), from
``/proc/self/status`` where it has them; both compared with the time series the run returns. Beside
it, the peak of Python allocations during a run (tracemalloc, in this process).

A backend may state targets as ``bench_targets`` (a class attribute, ``{"full/floor": 1.15}`` where
``floor`` is its tightest floor, or a property where they depend on its settings), checked per repeat on
the CPU-time ratios: *met* when every repeat's ratio is within the limit (max <= limit), *missed* when
every one is over it (min > limit),
*inconclusive* when the repeats straddle the limit; ``--check`` fails on a missed one (and on a target
not measured, or an end state that differs), never on an inconclusive one. Results go to
``<out>/bench.json`` (every sample and figure, versions, machine) and ``<out>/bench.md`` (the
tables the docs quote). ``--quick`` (short durations, one repeat) is what the test suite runs;
timings belong in the benchmark, not in tests.
"""

from __future__ import annotations

import argparse
import concurrent.futures
import gc
import math
import multiprocessing
import os
import platform
import resource
import shlex
import sys
import time
import tracemalloc
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from legbench import backends as registry
from legbench import resources, scenario, yamlfile
from legbench.backends.base import Backend, Physics
from legbench.exceptions import BackendNotFound, LegbenchError
from legbench.results import RunResult, check_study_out, platform_info, versions, write_json
from legbench.run import simulate
from legbench.scenario import Scenario, physics_of, shorten

__all__ = [
    "DEFAULT_REPEATS",
    "QUICK_DURATIONS",
    "TASKS",
    "BenchResult",
    "Ratio",
    "Spread",
    "Timing",
    "add_cli",
    "kernel_variants",
    "memory_of_run",
    "ratio",
    "run_bench",
    "shorten",
    "write_results",
]

ROOT = resources.scenarios_dir().parent  # the package data: ROOT / "scenarios" is the bundled scenarios
#: The four tasks of docs/spec.md section 7, benchmarked by default.
TASKS = tuple(ROOT / "scenarios" / f"{name}.yaml" for name in ("position", "ellipse", "effort", "combined"))
DEFAULT_REPEATS = 5
DEFAULT_WARMUP = 1
#: A sample is the fastest of k back-to-back executions of its variant, k (<= :data:`MAX_INNER`) chosen from
#: the warm-up so that the full run's sample lasts about this long [s CPU], the same k for every variant of
#: a backend on a task (so no ratio compares a fastest-of-3 with a fastest-of-1): a short run (50 ms) is
#: otherwise one burst of the shared machine's noise; load only ever adds time, so the fastest of k is the
#: least disturbed.
MIN_SAMPLE = 0.5
MAX_INNER = 5
DEFAULT_OUT = Path("results") / "bench"
#: What ``legbench bench`` writes into its --out: the bench's pages, and with ``--parallel`` the scaling study's.
OUTPUTS = ("bench.json", "bench.md", "scaling.json", "scaling.md")
#: ``--quick`` durations per task [s]: each still reaches every controller of its task
#: (combined: the touch-down at 1 s and the push from 2 s) but none lasts long.
QUICK_DURATIONS: Mapping[str, float] = {"position": 0.5, "ellipse": 1.5, "effort": 0.5, "combined": 2.5}
QUICK_DEFAULT_DURATION = 0.5
#: Length of the warm-up run before the memory base is read [s] (and of the contact warm-up, where needed).
MEMORY_WARMUP = 0.01
#: The task whose start presses the foot on the ground: where a task's own :data:`MEMORY_WARMUP` stays in the air,
#: the memory warm-up also runs as long from this task's initial state and controller (in the task's physics), so
#: that what an engine loads or allocates at its first contact is in the base, not in the run.
CONTACT_WARMUP = ROOT / "scenarios" / "effort.yaml"


@dataclass(frozen=True)
class Spread:
    """Median and spread of repeated measurements (same unit as the samples)."""

    median: float
    min: float
    max: float
    q1: float  # 25th percentile
    q3: float  # 75th percentile
    n: int

    @classmethod
    def of(cls, samples: Sequence[float]) -> Spread:
        """Summary of one or more samples."""
        x = np.asarray(samples, float)
        q1, q3 = np.percentile(x, [25.0, 75.0])
        return cls(float(np.median(x)), float(x.min()), float(x.max()), float(q1), float(q3), len(x))

    def scaled(self, factor: float) -> Spread:
        """The same summary with every figure multiplied by ``factor`` (> 0)."""
        return Spread(self.median * factor, self.min * factor, self.max * factor, self.q1 * factor,
                      self.q3 * factor, self.n)  # fmt: skip

    def text(self, fmt: str = ".1f") -> str:
        """``median [min-max]``."""
        return f"{self.median:{fmt}} [{self.min:{fmt}}-{self.max:{fmt}}]"


@dataclass
class Timing:
    """One variant's cost per control period over the repeats.

    Attributes:
        kind: ``full``, ``replay`` or ``floor``.
        what: what it times, in words.
        cpu_samples: CPU time per control period, one per repeat [us/tick].
        wall_samples: wall time per control period, one per repeat [us/tick] (of the same execution).
        inner: executions per sample, the fastest kept (:data:`MIN_SAMPLE`).
    """

    kind: str
    what: str
    cpu_samples: list[float] = field(default_factory=list)
    wall_samples: list[float] = field(default_factory=list)
    inner: int = 1

    @property
    def cpu(self) -> Spread:
        return Spread.of(self.cpu_samples)

    @property
    def wall(self) -> Spread:
        return Spread.of(self.wall_samples)

    def to_dict(self) -> dict[str, Any]:
        return {**asdict(self), "cpu": asdict(self.cpu), "wall": asdict(self.wall)}


@dataclass
class Ratio:
    """``num / den`` of two variants, per repeat (interleaved samples of the same repeat).

    Attributes:
        num, den: variant names.
        cpu, wall: the per-repeat ratios summarised [1].
        verdict: with two or more repeats ``overhead`` (every repeat's CPU ratio >= 1), ``faster``
            (every one below 1: ``num`` is the cheaper of the two) or ``within noise`` (the repeats
            straddle 1): never a negative overhead; with a single repeat ``one sample``, whichever
            side of 1 it fell (one sample cannot tell an overhead from the noise).
        overhead_us: median of the per-repeat CPU differences num - den [us/tick] for an
            ``overhead`` (>= 0 then), None otherwise.
        best: min(num) / min(den) in CPU time, the two variants' fastest repeats (load on a shared
            machine only ever adds time, so the minima are each variant's least disturbed figure).
    """

    num: str
    den: str
    cpu: Spread
    wall: Spread
    verdict: str
    overhead_us: float | None
    best: float = math.nan

    @property
    def label(self) -> str:
        return f"{self.num} / {self.den}"


def ratio(num: str, den: str, a: Timing, b: Timing) -> Ratio:
    """The ratio ``a / b`` of two timings with the same repeats (sample i of both from repeat i)."""
    cpu = [x / y for x, y in zip(a.cpu_samples, b.cpu_samples, strict=True)]
    wall = [x / y for x, y in zip(a.wall_samples, b.wall_samples, strict=True)]
    best = min(a.cpu_samples) / min(b.cpu_samples)
    if len(cpu) == 1:
        return Ratio(num, den, Spread.of(cpu), Spread.of(wall), "one sample", None, best)
    if min(cpu) >= 1.0:
        diff = [x - y for x, y in zip(a.cpu_samples, b.cpu_samples, strict=True)]
        return Ratio(num, den, Spread.of(cpu), Spread.of(wall), "overhead", max(float(np.median(diff)), 0.0), best)
    if max(cpu) < 1.0:
        return Ratio(num, den, Spread.of(cpu), Spread.of(wall), "faster", None, best)
    return Ratio(num, den, Spread.of(cpu), Spread.of(wall), "within noise", None, best)


@dataclass
class BenchResult:
    """One (task, backend) of the benchmark.

    Attributes:
        task: scenario name.
        backend: backend name.
        status: ``ok``, or ``failed`` with ``reason`` (nothing timed).
        duration: simulated time of each run [s].
        steps: control periods simulated per run (ticks - 1).
        sub_steps: engine steps per control period.
        timings: variant name -> :class:`Timing` (``full``, ``replay``, then the floors).
        ratios: full / replay, full / each floor, replay / each floor.
        floor: the tightest floor (lowest median CPU time; ``replay`` if the backend declares none).
        replay_identical: the replay's final (q, qd) equalled the full run's last logged state, bit
            for bit, after every replay.
        replay_max_diff: largest absolute difference between them [rad, rad/s] (0 when identical).
        end_state: per variant whose end state is checked (the replay, and each floor that declares
            ``end_state``): ``{"identical": bool, "max_diff": float}`` over every execution, as above.
        series_bytes: size of the time series the run returns (t, q, qd, tau, f, controller) [bytes].
        mem_peak_bytes: peak Python allocations (tracemalloc) during one full run [bytes].
        rss: the fresh-process RSS figures of :func:`memory_of_run` [bytes], or None.
        targets: the backend's ``bench_targets`` checked: key -> {ratio, limit, value (median), min, max,
            best, n, verdict (``met``, ``inconclusive`` or ``missed``: :func:`target_verdict`), met}.
        info: the backend's ``info()``.
    """

    task: str
    backend: str
    status: str = "ok"
    reason: str | None = None
    duration: float = 0.0
    steps: int = 0
    sub_steps: int | None = None
    timings: dict[str, Timing] = field(default_factory=dict)
    ratios: list[Ratio] = field(default_factory=list)
    floor: str | None = None
    replay_identical: bool = False
    replay_max_diff: float = math.nan
    end_state: dict[str, dict[str, Any]] = field(default_factory=dict)
    series_bytes: int = 0
    mem_peak_bytes: int = 0
    rss: dict[str, Any] | None = None
    targets: dict[str, dict[str, Any]] = field(default_factory=dict)
    info: dict[str, Any] = field(default_factory=dict)

    def find(self, label: str) -> Ratio | None:
        """The ratio ``num / den`` by label, or None."""
        return next((r for r in self.ratios if r.label == label), None)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict."""
        out = {k: v for k, v in asdict(self).items() if k not in ("timings", "ratios")}
        out["timings"] = {k: t.to_dict() for k, t in self.timings.items()}
        out["ratios"] = [{**asdict(r), "label": r.label} for r in self.ratios]
        out["mem_ratio"] = (
            self.mem_peak_bytes / self.series_bytes if self.series_bytes and self.mem_peak_bytes else None
        )
        full, replay, h = self.timings.get("full"), self.timings.get("replay"), self.find("full / replay")
        if full is not None and replay is not None and full.cpu_samples and h is not None:
            # the summary the report's Performance table reads: CPU-time medians of full and replay
            out["full_us_per_tick"] = asdict(full.cpu)
            out["engine_us_per_tick"] = asdict(replay.cpu)
            out["harness_us_per_tick"] = harness_cost(h)
            out["overhead_ratio"] = asdict(h.cpu)
            out["rtf_full"] = self.duration / (full.wall.median * max(self.steps, 1) / 1e6)
        return out


# --------------------------------------------------------------------------- #
# Scenarios


def load_tasks(
    paths: Sequence[str | Path],
    quick: bool = False,
    duration: float | None = None,
    overrides: Mapping[str, Any] | None = None,
) -> list[Scenario]:
    """Load and validate the scenarios.

    Args:
        paths: scenario files.
        quick: shorten each to its :data:`QUICK_DURATIONS` entry (see :func:`shorten`), unless
            ``overrides`` sets ``duration``: a duration asked for by name is kept.
        duration: shorten each to this [s] instead.
        overrides: dotted scenario keys set before validation, as ``legbench run --set``.
    """
    out = [scenario.load(path, overrides) for path in paths]
    if duration is not None:
        return scenario.shorten_each(out, duration)
    if quick and "duration" not in (overrides or {}):
        return [shorten(sc, QUICK_DURATIONS.get(sc.name, QUICK_DEFAULT_DURATION)) for sc in out]
    return out


# --------------------------------------------------------------------------- #
# Measurement


def _series_bytes(tr: RunResult) -> int:
    return int(sum(a.nbytes for a in (tr.t, tr.q, tr.qd, tr.tau, tr.f, tr.controller)))


def _timed(fn: Callable[[], Any]) -> tuple[float, float, Any]:
    """CPU and wall time of one call [s], and its result."""
    gc.collect()
    c0, w0 = time.process_time(), time.perf_counter()
    out = fn()
    return time.process_time() - c0, time.perf_counter() - w0, out


def _per_tick(name: str, fn: Callable[[], None]) -> bool:
    return bool(getattr(fn, "per_tick", False)) or name.endswith("_tick")


def kernel_variants(backend: Backend, tr: RunResult) -> dict[str, tuple[Callable[[], None], float, str]]:
    """The backend's floors: variant name -> (one pass over the run's rows, ticks per pass, description).

    :meth:`Backend.kernels` gets the run's consecutive rows (q, qd, tau of every control period
    but the last); a per-tick kernel's pass covers ``steps`` control periods, the per-sub-step
    kernels (one call per row each) add up to one floor whose pass covers ``steps / (sub_steps x calls)``, calls
    the kernels' ``calls_per_sub_step`` (default 1: RK4's 4, an adaptive solve's right-hand sides per period).
    Empty if the backend declares no kernels.
    """
    try:
        loops = backend.kernels(tr.q[:-1], tr.qd[:-1], tr.tau[:-1])
    except NotImplementedError:
        return {}
    steps = max(len(tr.t) - 1, 1)
    n_sub = backend.sub_steps()
    out: dict[str, tuple[Callable[[], None], float, str]] = {}
    per_sub = {k: f for k, f in loops.items() if not _per_tick(k, f)}
    for name, fn in loops.items():
        if name not in per_sub:
            out[name] = (fn, float(steps), getattr(fn, "__doc__", None) or f"{name}, one call per control period")
    if per_sub:
        calls = list(per_sub.values())
        # as many calls per sub-step as the run makes (RK4's stages, an adaptive solve's right-hand sides): the
        # kernels of one floor share that count, the first one's
        per = float(getattr(calls[0], "calls_per_sub_step", 1.0))

        def one_pass() -> None:
            for f in calls:
                f()

        name = "+".join(per_sub)
        what = f"{name}: one call each per sub-step, x {n_sub} sub-steps"
        if per != 1.0:
            what = f"{name}: {per:.4g} calls each per sub-step (as the run evaluates them), x {n_sub} sub-steps"
        out[name] = (one_pass, steps / (n_sub * per), what)
    return out


def _max_rss() -> int:
    """Peak resident set size of this process [bytes] (Linux reports kB, macOS bytes)."""
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return int(rss if sys.platform == "darwin" else rss * 1024)


def _status_kb(key: str) -> int | None:
    return _status(key)[key]


def _status(*keys: str) -> dict[str, int | None]:
    """The given ``/proc/self/status`` figures [bytes] (reported in kB), None for each one it lacks (or no /proc)."""
    out: dict[str, int | None] = dict.fromkeys(keys)
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            key = line.split(":", 1)[0]
            if key in out:
                out[key] = int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return out


def trim_heap() -> bool:
    """Hand the C heap's free pages back to the system: glibc's ``malloc_trim(0)`` (through ctypes), where the
    C library has it. Returns whether it was called (False elsewhere: macOS, musl, Windows)."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        import ctypes

        fn = ctypes.CDLL(None).malloc_trim
    except (OSError, AttributeError, TypeError):
        return False
    fn.argtypes, fn.restype = [ctypes.c_size_t], ctypes.c_int
    fn(0)
    return True


def _touched(tr: RunResult) -> bool:
    """The run felt a ground force at some tick."""
    return bool(len(tr.f) and np.any(np.asarray(tr.f) != 0.0))


def _warm_up(sc: Scenario, backend: Backend, physics: Physics) -> tuple[str, bool]:
    """The memory base's warm-up on the loaded backend: :data:`MEMORY_WARMUP` of the task; where that stays in
    the air, as long again from :data:`CONTACT_WARMUP`'s start on the ground (its initial state and events, the
    task's physics and settings). Returns what ran, in words, and whether the foot touched the ground in it."""
    ms = f"{MEMORY_WARMUP * 1e3:g} ms"
    short = shorten(sc, MEMORY_WARMUP)
    if _touched(simulate(short, backend, physics)):
        return f"{ms} of the task (in contact)", True
    ground = scenario.load(CONTACT_WARMUP)
    doc = dict(short.raw)
    doc["initial"], doc["events"] = dict(ground.raw["initial"]), list(ground.raw["events"])
    touched = _touched(simulate(scenario.parse(doc, sc.file), backend, physics))
    what = f"{ms} of the task (in the air), then {ms} from the {CONTACT_WARMUP.stem} task's start on the ground"
    return what + ("" if touched else " (no contact in it either)"), touched


def memory_of_run(sc: Scenario, name: str, contact_mode: str | None = None) -> dict[str, Any]:
    """Peak RSS of one full run of ``name`` on ``sc`` in this process [bytes] (run it in a fresh one).

    ``base``: RSS after loading the backend, a warm-up through contact (:func:`_warm_up`: interpreter,
    imports, engine, and what the engine loads and allocates as it first steps and first touches the
    ground), a garbage collection and :func:`trim_heap` (free heap pages still resident would otherwise be
    reused by the run and not counted: a run would seem to hold less than its own log). The peak-RSS mark
    is then reset (Linux ``/proc/self/clear_refs``; elsewhere the mark since start is used, ``method`` says
    which), the full run made, and ``peak`` read. ``run = peak - base`` is what the run added; ``ratio`` is
    that over the run's time series (``series``). ``anon_run`` and ``file_run``: the growth of ``RssAnon``
    (heap and other anonymous memory) and of ``RssFile`` (file-backed pages, e.g. a library's code paged in)
    from the base to the run's end, its log still held (None where ``/proc/self/status`` has no such line,
    ``anon_note`` says so); ``anon_ratio`` = ``anon_run / series``.
    """
    physics = physics_of(sc, contact_mode)
    backend = registry.load(name, physics, sc.backends.get(name, {}), sc.profile)
    try:
        warmup, touched = _warm_up(sc, backend, physics)
        gc.collect()
        trimmed = trim_heap()
        before = _status("VmRSS", "RssAnon", "RssFile")
        base = before["VmRSS"]
        try:
            Path("/proc/self/clear_refs").write_text("5")
            method = "clear_refs"
        except OSError:
            method = "maxrss since start"
        if base is None:
            base, method = _max_rss(), "maxrss since start"
        tr = simulate(sc, backend, physics)
        peak = _status_kb("VmHWM") if method == "clear_refs" else None
        peak = peak if peak is not None else _max_rss()
        after = _status("RssAnon", "RssFile")
        series = _series_bytes(tr)
        out: dict[str, Any] = {"base": base, "peak": peak, "run": max(peak - base, 0), "series": series,
                               "ratio": max(peak - base, 0) / series, "method": method, "status": tr.status,
                               "warmup": warmup, "warmup_contact": touched, "malloc_trim": trimmed}  # fmt: skip
        for key, tag in (("RssAnon", "anon"), ("RssFile", "file")):
            b, a = before[key], after[key]
            out[f"{tag}_run"] = a - b if a is not None and b is not None else None
        out["anon_ratio"] = out["anon_run"] / series if out["anon_run"] is not None else None
        if out["anon_run"] is None:
            out["anon_note"] = "RssAnon unavailable (no /proc/self/status line for it on this system)"
        return out
    finally:
        backend.close()


def _memory_in_fresh_process(sc: Scenario, name: str, contact_mode: str | None) -> dict[str, Any] | None:
    ctx = multiprocessing.get_context("spawn")
    try:
        with concurrent.futures.ProcessPoolExecutor(1, mp_context=ctx) as pool:
            return pool.submit(memory_of_run, sc, name, contact_mode).result()
    except Exception as exc:  # a worker that cannot start or fails: no memory figure, not a failed bench
        return {"error": f"{type(exc).__name__}: {exc}"}


def _tracemalloc_peak(fn: Callable[[], Any]) -> tuple[int, Any]:
    """Peak Python allocations while ``fn`` runs [bytes] (tracemalloc), and its result."""
    gc.collect()
    tracemalloc.start()
    try:
        tracemalloc.reset_peak()
        base = tracemalloc.get_traced_memory()[0]
        out = fn()
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    return int(peak - base), out


@dataclass
class _Loaded:
    """One backend under benchmark on one task: its variants and what they record."""

    res: BenchResult
    backend: Backend
    physics: Physics
    variants: dict[str, tuple[Callable[[], Any], float]]
    q_end: np.ndarray
    qd_end: np.ndarray
    #: variant -> its end-state reader (q, qd), for the variants that step the run from its start
    end_states: dict[str, Callable[[], tuple[np.ndarray, np.ndarray]]] = field(default_factory=dict)


def _load(sc: Scenario, name: str, contact_mode: str | None) -> _Loaded | BenchResult:
    """Load, run once for the torque log, set up the variants; a failure gives a failed result."""
    res = BenchResult(task=sc.name, backend=name, duration=sc.duration, steps=sc.n_ticks - 1)
    physics = physics_of(sc, contact_mode)
    try:
        backend = registry.load(name, physics, sc.backends.get(name, {}), sc.profile)
    except BackendNotFound:
        raise
    except Exception as exc:  # an engine that cannot load must not stop the others
        res.status, res.reason = "failed", f"load failed: {type(exc).__name__}: {exc}"
        return res
    tr = simulate(sc, backend, physics)
    if tr.status != "ok":
        backend.close()
        res.status, res.reason = "failed", tr.reason
        return res
    res.info, res.sub_steps = tr.info, backend.sub_steps()
    steps = float(max(res.steps, 1))
    q0, qd0 = np.array(sc.q0), np.array(sc.qd0)
    taus = list(tr.tau[:-1])  # row views, the same kind of array the run loop hands the backend
    reset, step = backend.reset, backend.step

    def replay() -> None:
        reset(q0, qd0)
        for tau in taus:
            step(tau)

    variants: dict[str, tuple[Callable[[], Any], float]] = {
        "full": (lambda: simulate(sc, backend, physics), steps),
        "replay": (replay, steps),
    }
    res.timings["full"] = Timing("full", "legbench run loop: reads, checks, controller, saturation, log")
    res.timings["replay"] = Timing("replay", "backend.step() per logged torque, called from Python")
    end_states: dict[str, Callable[[], tuple[np.ndarray, np.ndarray]]] = {"replay": backend.state}
    for kname, (fn, ticks, what) in kernel_variants(backend, tr).items():
        variants[kname] = (fn, ticks)
        res.timings[kname] = Timing("floor", what)
        reader = getattr(fn, "end_state", None)
        if callable(reader):
            end_states[kname] = reader
    res.series_bytes = _series_bytes(tr)
    res.end_state = {k: {"identical": True, "max_diff": 0.0} for k in end_states}
    return _Loaded(res, backend, physics, variants, tr.q[-1].copy(), tr.qd[-1].copy(), end_states)


def variant_order(names: Sequence[str], rep: int) -> list[str]:
    """The variants' order in pass ``rep`` (warm-up passes counted): rotated by one per pass, so that the first
    variant after another backend's (cold caches, a frequency step) is each variant in turn."""
    k = rep % len(names) if names else 0
    return [*names[k:], *names[:k]]


def _one_repeat(b: _Loaded, rep: int = 0) -> None:
    """Time every variant of one backend once (the fastest of its ``inner`` executions), in pass ``rep``'s
    order (:func:`variant_order`); check the end state of each variant that steps the run from its start."""
    res = b.res
    for vname in variant_order(list(b.variants), rep):
        fn, ticks = b.variants[vname]
        cpu, wall = math.inf, math.inf
        for _ in range(res.timings[vname].inner):
            c, w, out = _timed(fn)
            if vname == "full" and isinstance(out, RunResult) and out.status != "ok":
                raise LegbenchError(out.reason or "run failed")
            if c < cpu:
                cpu, wall = c, w
        res.timings[vname].cpu_samples.append(1e6 * cpu / ticks)
        res.timings[vname].wall_samples.append(1e6 * wall / ticks)
        if vname in b.end_states:
            q, qd = b.end_states[vname]()
            same = np.array_equal(q, b.q_end) and np.array_equal(qd, b.qd_end)
            with np.errstate(invalid="ignore"):
                diff = float(np.max(np.abs(np.concatenate([q - b.q_end, qd - b.qd_end]))))
            check = res.end_state[vname]
            check["identical"] = check["identical"] and same
            check["max_diff"] = max(check["max_diff"], diff) if math.isfinite(check["max_diff"]) else diff
            if vname == "replay":
                res.replay_identical, res.replay_max_diff = check["identical"], check["max_diff"]


#: A target's verdicts (:func:`target_verdict`), in the order the count line gives them.
VERDICTS = ("met", "inconclusive", "missed", "not measured")


def target_verdict(ratios: Sequence[float], limit: float) -> str:
    """``met`` when every repeat's ratio is within ``limit`` (max <= limit), ``missed`` when every one is over
    it (min > limit), else ``inconclusive`` (the repeats straddle the limit: more repeats, or a quieter
    machine, may tell); ``not measured`` when there is no ratio (the target names a variant the run lacks)."""
    x = np.asarray(ratios, float)
    if x.size == 0:
        return "not measured"
    if float(x.max()) <= limit:
        return "met"
    if float(x.min()) > limit:
        return "missed"
    return "inconclusive"


def _summarise(res: BenchResult, backend: Backend) -> None:
    """Ratios, the tightest floor and the backend's targets from the samples."""
    floors = [k for k, t in res.timings.items() if t.kind == "floor"]
    t = res.timings
    res.ratios = [ratio("full", "replay", t["full"], t["replay"])]
    res.ratios += [ratio("full", f, t["full"], t[f]) for f in floors]
    res.ratios += [ratio("replay", f, t["replay"], t[f]) for f in floors]
    res.floor = min(floors, key=lambda f: t[f].cpu.median) if floors else "replay"
    for key, limit in dict(getattr(backend, "bench_targets", {}) or {}).items():
        num, den = key.split("/")
        den = res.floor if den == "floor" else den
        if num == den and num in t:
            per_repeat = [1.0] * len(t[num].cpu_samples)
        elif num in t and den in t:
            per_repeat = [a / b for a, b in zip(t[num].cpu_samples, t[den].cpu_samples, strict=True)]
        else:
            per_repeat = []
        verdict = target_verdict(per_repeat, float(limit))
        r = res.find(f"{num} / {den}")
        nan = math.nan
        res.targets[key] = {
            "ratio": f"{num} / {den}",
            "limit": float(limit),
            "value": float(np.median(per_repeat)) if per_repeat else nan,
            "min": min(per_repeat, default=nan),
            "max": max(per_repeat, default=nan),
            "best": r.best if r is not None else (1.0 if per_repeat else nan),
            "n": len(per_repeat),
            "verdict": verdict,
            "met": verdict == "met",
        }
        if not per_repeat:
            res.targets[key]["note"] = f"no variant {', '.join(v for v in (num, den) if v not in t)} in this run"


def target_counts(results: Sequence[BenchResult]) -> dict[str, int]:
    """How many target cells (a backend's target on a task) got each verdict (:data:`VERDICTS`); ``failed``:
    the runs that failed (their targets were not measured)."""
    counts = dict.fromkeys(VERDICTS, 0)
    for r in results:
        for tg in r.targets.values():
            counts[tg["verdict"]] += 1
    counts["failed"] = sum(r.status != "ok" for r in results)
    return counts


def count_line(counts: Mapping[str, int]) -> str:
    """``N met, M inconclusive, K missed (of T targets)``, with the unmeasured and the failed runs if any."""
    total = sum(counts.get(v, 0) for v in VERDICTS)
    line = f"{counts.get('met', 0)} met, {counts.get('inconclusive', 0)} inconclusive, {counts.get('missed', 0)} missed"
    extra = [f"{counts['not measured']} not measured"] if counts.get("not measured") else []
    extra += [f"{counts['failed']} failed run(s), targets not measured"] if counts.get("failed") else []
    return f"{line}{''.join(f', {e}' for e in extra)} (of {total} targets)"


def run_bench(
    scenarios: Sequence[Scenario],
    backend_names: Sequence[str],
    repeats: int = DEFAULT_REPEATS,
    warmup: int = DEFAULT_WARMUP,
    contact_mode: str | None = None,
    memory: bool = True,
    progress: Callable[[BenchResult], None] | None = None,
    min_sample: float = MIN_SAMPLE,
) -> list[BenchResult]:
    """Benchmark every backend on every scenario (task-major order; backends interleaved within a task).

    Args:
        scenarios: the tasks (possibly shortened).
        backend_names: backends to load.
        repeats: timed passes through every backend and variant (>= 1).
        warmup: untimed passes before them (>= 0).
        contact_mode: ``native`` or ``reference``; default each scenario's.
        memory: also measure the peak memory of a run (fresh worker process; tracemalloc here).
        progress: called with each finished result.
        min_sample: each sample the fastest of as many back-to-back executions (at most :data:`MAX_INNER`)
            as make the full run's sample last this long [s CPU], counted from the warm-up, the same number
            for every variant of a backend on a task; 0 (or no warm-up): one execution.
    """
    if repeats < 1:
        raise LegbenchError(f"bench: --repeats must be at least 1, got {repeats}")
    if warmup < 0:
        raise LegbenchError(f"bench: --warmup must be at least 0, got {warmup}")
    out = []
    for sc in scenarios:
        loaded = [_load(sc, name, contact_mode) for name in backend_names]
        live = [b for b in loaded if isinstance(b, _Loaded)]
        try:
            for b in live:
                b.res.replay_identical, b.res.replay_max_diff = True, 0.0
            for rep in range(warmup + repeats):
                order = live[rep % len(live) :] + live[: rep % len(live)] if live else []
                for b in order:
                    if b.res.status != "ok":
                        continue
                    try:
                        _one_repeat(b, rep)
                    except Exception as exc:  # a run that fails on a repeat fails that backend alone
                        b.res.status, b.res.reason = "failed", f"{type(exc).__name__}: {exc}"
                if rep == warmup - 1:  # warm-up samples are dropped, after sizing the samples from them
                    for b in live:
                        full = b.res.timings["full"]
                        if min_sample > 0 and full.cpu_samples:
                            seconds = 1e-6 * full.cpu_samples[-1] * b.variants["full"][1]  # one full run [s CPU]
                            k = max(1, min(MAX_INNER, math.ceil(min_sample / max(seconds, 1e-9))))
                            for tm in b.res.timings.values():
                                tm.inner = k
                        for tm in b.res.timings.values():
                            tm.cpu_samples.clear()
                            tm.wall_samples.clear()
            for b in live:
                if b.res.status == "ok":
                    _summarise(b.res, b.backend)
                    if memory:
                        b.res.mem_peak_bytes, _ = _tracemalloc_peak(b.variants["full"][0])
        finally:
            for b in live:
                b.backend.close()
        for item in loaded:
            res = item.res if isinstance(item, _Loaded) else item
            if memory and res.status == "ok":
                res.rss = _memory_in_fresh_process(sc, res.backend, contact_mode)
            if progress is not None:
                progress(res)
            out.append(res)
    return out


# --------------------------------------------------------------------------- #
# Output


def _command() -> str:
    """The command line that ran the bench, its global options (``--model``) included and quoted as a shell would
    need; "legbench bench" where it did not come from the command line (the API)."""
    return shlex.join(["legbench", *sys.argv[1:]]) if "bench" in sys.argv[1:] else "legbench bench"


def machine() -> dict[str, Any]:
    """The machine: platform with its CPU model (:func:`~legbench.results.platform_info`), usable CPUs, load, Python
    build."""
    aff = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    load = os.getloadavg() if hasattr(os, "getloadavg") else None
    return {
        **platform_info(),
        "cpus_usable": aff,
        "load_average": list(load) if load else None,
        "python_build": " ".join(platform.python_build()),
        "python_implementation": platform.python_implementation(),
    }


def conditions() -> dict[str, Any]:
    """The machine's state now, for :func:`during`: load average, the time [s] and the CPU time the
    hypervisor gave other guests (steal, /proc/stat, in USER_HZ jiffies; None where it is not reported)."""
    steal = None
    try:
        fields = Path("/proc/stat").read_text().split("\n", 1)[0].split()
        if fields[0] == "cpu" and len(fields) > 8:
            steal = int(fields[8])
    except (OSError, ValueError, IndexError):
        pass
    load = os.getloadavg() if hasattr(os, "getloadavg") else None
    return {"load": list(load) if load else None, "time": time.monotonic(), "steal": steal}


def during(before: Mapping[str, Any], after: Mapping[str, Any]) -> dict[str, Any]:
    """What the machine did over the bench: the load average at its start, and the share of the machine's CPU
    time stolen by other guests of the host (0 on bare metal or an idle host; a few per cent already moves
    CPU-time figures on a shared VM)."""
    out: dict[str, Any] = {"load_average_start": before.get("load")}
    hz = os.sysconf("SC_CLK_TCK") if hasattr(os, "sysconf") else 100
    cpus = os.cpu_count() or 1
    span = float(after["time"]) - float(before["time"])
    if before.get("steal") is not None and after.get("steal") is not None and span > 0:
        # a counter that went backwards (a VM migrated) is no measurement of stealing
        out["steal_fraction"] = max(0.0, (after["steal"] - before["steal"]) / hz / (span * cpus))
    else:
        out["steal_fraction"] = None
    return out


def targets_met(results: Sequence[BenchResult]) -> dict[str, bool]:
    """Per backend: every one of its targets met on every task, in every repeat (:func:`target_verdict`; a
    failed run or an inconclusive cell is not met)."""
    met: dict[str, bool] = {}
    for r in results:
        if r.status != "ok":
            met[r.backend] = False
        elif r.targets:
            met[r.backend] = met.get(r.backend, True) and all(t["met"] for t in r.targets.values())
    return met


def _end_state_text(r: BenchResult) -> str:
    """``replay, period_loop identical``, or the variants whose end state differed from the run's."""
    bad = [k for k, c in r.end_state.items() if not c["identical"]]
    if bad:
        return f"{', '.join(bad)} DIFFER{'S' if len(bad) == 1 else ''}"
    return f"{', '.join(r.end_state) or 'replay'} identical"


def harness_cost(full_replay: Ratio) -> float | str:
    """The harness's cost from the full run's ratio to its replay: [us/tick] where it is an overhead in every
    repeat, else what the repeats say instead (``one sample``, ``none (faster)``: the full run the cheaper in every
    repeat, ``within noise``): never a negative cost."""
    if full_replay.overhead_us is not None:
        return full_replay.overhead_us
    return {"one sample": "one sample", "faster": "none (faster)"}.get(full_replay.verdict, "within noise")


def _ratio_cell(r: Ratio | None, bold: bool = True) -> str:
    if r is None:
        return "-"
    if r.verdict == "overhead":
        star = "**" if bold else ""
        return f"{star}{r.cpu.median:.3f}{star} [{r.cpu.min:.3f}-{r.cpu.max:.3f}]"
    if r.verdict == "faster":
        return f"{r.cpu.median:.3f} [{r.cpu.min:.3f}-{r.cpu.max:.3f}] (faster)"
    if r.verdict == "one sample":
        return f"{r.cpu.median:.3f} (one sample)"
    return f"within noise ({r.cpu.min:.3f}-{r.cpu.max:.3f})"


def markdown(results: Sequence[BenchResult], meta: Mapping[str, Any]) -> str:
    """The benchmark as Markdown: settings, the timing table, ratios, memory, targets."""
    s = meta["settings"]
    m = meta["machine"]
    v = meta["versions"]
    engines = ", ".join(f"{k} {v[k]}" for k in registry.engine_packages() if k in v)
    load, start, steal = m.get("load_average"), m.get("load_average_start"), m.get("steal_fraction")
    lines = [
        "# legbench bench",
        "",
        f"Command: `{meta['command']}`  ",
        f"Machine: {m['cpu_model']}, {m['cpus_usable']} usable CPUs, {m['system']} {m['machine']}"
        f"{f', load average {start[0]:.2f} at the start' if start else ''}"
        f"{(', ' if start else ', load average ') + f'{load[0]:.2f} at the end' if load else ''}"
        f"{f', CPU time stolen by other guests {100 * steal:.2f} %' if steal is not None else ''}; "
        f"Python {v['python']}, numpy {v.get('numpy', '?')}, {engines}.  ",
        f"Settings: {s['repeats']} timed repeats after {s['warmup']} warm-up, interleaved across backends and "
        "variants (both orders rotated from repeat to repeat); "
        f"contact mode {s['contact_mode'] or 'from each scenario'}{', quick' if s['quick'] else ''}"
        f"{''.join(f', {k} = {val}' for k, val in (s.get('overrides') or {}).items())}. "
        "CPU time (process_time) per control period; figures are medians, brackets min-max over the repeats"
        + (
            f"; each sample the fastest of up to {MAX_INNER} back-to-back executions, as many as make the full "
            f"run's sample last {s['min_sample_s']:g} s (sized from the warm-up, the same for every variant of a "
            "backend on a task)."
            if s.get("min_sample_s") and s["warmup"]
            else "."
        ),
        "",
        "## Cost per control period [us/tick, CPU time]",
        "",
        "`full`: the legbench run; `replay`: backend.step() over the logged torques; the floors: the engine's own "
        "calls in a tight loop (`Backend.kernels`). Wall-time medians are in bench.json. End state identical: the "
        "replay's (and a floor's that steps the run from its start) final q, qd equal the run's last logged state "
        "bit for bit.",
        "",
        "| task | backend | sub-steps | full | replay | floors | end state identical |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in results:
        if r.status != "ok":
            lines.append(f"| {r.task} | {r.backend} | - | FAILED: {r.reason} | | | |")
            continue
        t = r.timings
        floors = "; ".join(f"{k} {tm.cpu.text()}" for k, tm in t.items() if tm.kind == "floor") or "-"
        same = "; ".join(f"{k} {'yes' if c['identical'] else 'NO (max diff ' + format(c['max_diff'], '.3g') + ')'}"
                         for k, c in r.end_state.items()) or ("yes" if r.replay_identical else "NO")  # fmt: skip
        lines.append(f"| {r.task} | {r.backend} | {r.sub_steps} | {t['full'].cpu.text()} | {t['replay'].cpu.text()} "
                     f"| {floors} | {same} |")  # fmt: skip
    lines += [
        "",
        "## Ratios [CPU time]",
        "",
        "Per repeat from the same interleaved samples, then median [min-max]; an overhead is a ratio >= 1 in "
        "every repeat, with its cost per tick; below 1 in every repeat it is marked faster; where the repeats "
        "straddle 1 it is within noise; a single repeat is one sample. `floor` is the "
        "backend's tightest floor; `best` is the ratio of the two variants' fastest repeats.",
        "",
        "| task | backend | full / replay | harness [us/tick] | tightest floor | full / floor | full / floor, best "
        "| replay / floor |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in results:
        if r.status != "ok":
            continue
        h = r.find("full / replay")
        fl = r.floor or "replay"
        full_fl = h if fl == "replay" else r.find(f"full / {fl}")
        rep_fl = None if fl == "replay" else r.find(f"replay / {fl}")
        cost = "-" if h is None else (f"{c:.1f}" if isinstance(c := harness_cost(h), float) else c)
        best = f"{full_fl.best:.3f}" if full_fl is not None else "-"
        lines.append(f"| {r.task} | {r.backend} | {_ratio_cell(h)} | {cost} | {fl} | {_ratio_cell(full_fl)} | {best} "
                     f"| {_ratio_cell(rep_fl) if rep_fl else '-'} |")  # fmt: skip
    other = [(r, x) for r in results if r.status == "ok" for x in r.ratios
             if x.den not in ("replay", r.floor)]  # fmt: skip
    if other:
        lines += [
            "",
            "Against the other floors:",
            "",
            "| task | backend | ratio | CPU | wall |",
            "|---|---|---|---|---|",
        ]
        lines += [f"| {r.task} | {r.backend} | {x.label} | {_ratio_cell(x)} | {x.wall.text('.3f')} |" for r, x in other]
    mem = [r for r in results if r.status == "ok" and (r.mem_peak_bytes or r.rss)]
    if mem:
        trimmed = any((r.rss or {}).get("malloc_trim") for r in mem)
        lines += [
            "",
            "## Memory of one full run",
            "",
            f"RSS in a fresh worker process: `base` after loading the engine, a {MEMORY_WARMUP * 1e3:g} ms warm-up "
            f"run of the task (`+ ground`: then {MEMORY_WARMUP * 1e3:g} ms from the {CONTACT_WARMUP.stem} task's "
            "start on the ground, where the task's own start is in the air, so the engine's first contact is in the "
            "base)"
            + (", a garbage collection and `malloc_trim(0)` (the heap's free pages handed back, so the run cannot "
               "reuse resident freed memory uncounted)" if trimmed else ", a garbage collection (no malloc_trim here)")
            + "; `run` the peak (VmHWM) during the full run above that base; `RssAnon` and `RssFile` growth: heap "
            "(anonymous) and file-backed pages from the base to the run's end, its log still held. Python "
            "allocations (tracemalloc) during a run beside it. `series`: the time series the run returns (t, q, "
            "qd, tau, f, controller).",
            "",
            "| task | backend | ticks | series [MB] | warm-up | base RSS [MB] | run peak RSS - base [MB] "
            "| (peak - base) / series | RssAnon growth [MB] | RssAnon / series | RssFile growth [MB] "
            "| tracemalloc peak [MB] |",
            "|---|---|---|---|---|---|---|---|---|---|---|---|",
        ]  # fmt: skip
        notes: set[str] = set()
        for r in mem:
            x = r.rss or {}
            if "run" in x:
                warm = ("task" if "then" not in str(x.get("warmup", "")) else "task + ground") + (
                    "" if x.get("warmup_contact", True) else " (no contact)")  # fmt: skip
                anon = x.get("anon_run")
                if anon is None:
                    notes.add(str(x.get("anon_note", "RssAnon unavailable")))
                    anon_cells = "n/a | n/a"
                else:
                    anon_cells = f"{anon / 1e6:.2f} | {anon / x['series']:.2f}"
                file = x.get("file_run")
                file_cell = f"{file / 1e6:.2f}" if file is not None else "n/a"
                rss = (f"{warm} | {x['base'] / 1e6:.1f} | {x['run'] / 1e6:.2f} | **{x['ratio']:.2f}** | {anon_cells} "
                       f"| {file_cell}")  # fmt: skip
            else:
                rss = f"- | - | {x.get('error', '-')} | - | - | - | -"
            lines.append(f"| {r.task} | {r.backend} | {r.steps + 1} | {r.series_bytes / 1e6:.3f} | {rss} "
                         f"| {r.mem_peak_bytes / 1e6:.3f} |")  # fmt: skip
        lines += [f"\n{n}." for n in sorted(notes)]
    with_targets = [r for r in results if r.targets]
    if with_targets:
        lines += ["", "## Targets (per repeat, CPU time)", "",
                  f"**{count_line(target_counts(results))}**. Met: every repeat's ratio within the limit (max <= "
                  "limit); missed: every repeat over it (min > limit); inconclusive: the repeats straddle the limit "
                  "(`--check` fails on a missed or unmeasured target, never on an inconclusive one). Median "
                  "[min-max] over the repeats; best: the ratio of the two variants' fastest repeats."
                  + (" One repeat: each verdict rests on one sample." if s["repeats"] == 1 else ""), "",
                  "| task | backend | ratio | limit | median [min-max] | best | verdict |",
                  "|---|---|---|---|---|---|---|"]  # fmt: skip
        for r in with_targets:
            for tg in r.targets.values():
                verdict = {"missed": "MISSED", "not measured": f"NOT MEASURED ({tg.get('note', '')})"}.get(
                    tg["verdict"], tg["verdict"])  # fmt: skip
                lines.append(f"| {r.task} | {r.backend} | {tg['ratio']} | {tg['limit']:g} | {tg['value']:.3f} "
                             f"[{tg['min']:.3f}-{tg['max']:.3f}] | {tg['best']:.3f} | {verdict} |")  # fmt: skip
    return "\n".join(lines) + "\n"


def write_results(results: Sequence[BenchResult], out_dir: Path, meta: Mapping[str, Any]) -> tuple[Path, Path]:
    """Write ``bench.json`` and ``bench.md`` into ``out_dir`` (each atomically). Returns their paths."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    doc = {**meta, "results": [r.to_dict() for r in results]}
    md = out_dir / "bench.md"
    tmp = md.with_name(f".{md.name}.tmp-{os.getpid()}")
    tmp.write_text(markdown(results, meta))
    tmp.replace(md)
    return write_json(doc, out_dir / "bench.json"), md


# --------------------------------------------------------------------------- #
# CLI


def add_cli(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Register ``legbench bench [SCENARIO ...] [--quick] [--backends all] [--out DIR] ...``."""
    p = subparsers.add_parser(
        "bench",
        help="time the full run against the engine alone (CPU time), per backend and task",
        description="Time the full legbench run against an engine-only replay of its torques and the engine's own "
        "tightest loops, in CPU and wall time, per backend and task; peak RSS of a run; write bench.json and "
        "bench.md.",
    )
    p.add_argument("scenarios", nargs="*", metavar="SCENARIO",
                   help="scenario YAML files (default: the four tasks in scenarios/)")  # fmt: skip
    p.add_argument("--backends", default="all", help="comma-separated backend names, or 'all' (default)")
    p.add_argument("--repeats", type=int, default=None,
                   help=f"timed repeats per backend and task (default {DEFAULT_REPEATS}; 1 with --quick)")  # fmt: skip
    p.add_argument("--warmup", type=int, default=DEFAULT_WARMUP,
                   help=f"untimed warm-up passes before them (default {DEFAULT_WARMUP})")  # fmt: skip
    p.add_argument("--quick", action="store_true",
                   help="short durations (later events dropped; a --set duration is kept), one repeat: "
                   "a smoke test, not figures")  # fmt: skip
    p.add_argument("--duration", type=yamlfile.positive_float, default=None,
                   help="cut every scenario to at most this many seconds (a shorter one runs whole)")  # fmt: skip
    p.add_argument("--contact-mode", choices=("native", "reference"), default=None,
                   help="override the scenarios' contact mode")  # fmt: skip
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="override a scenario key, e.g. --set backends.<name>.dt=1e-4 (10 sub-steps)")  # fmt: skip
    p.add_argument("--no-memory", action="store_true", help="skip the memory runs (fresh process, tracemalloc)")
    p.add_argument("--out", default=str(DEFAULT_OUT), help=f"output directory (default {DEFAULT_OUT})")
    p.add_argument("--force", action="store_true",
                   help="replace a finished bench (bench.json; with --parallel, scaling.json) in --out")  # fmt: skip
    p.add_argument("--check", action="store_true",
                   help="exit 1 if a backend's target is missed (every repeat over its limit) or not measured, or "
                   "an end state differs; an inconclusive target (the repeats straddle the limit: this run cannot "
                   "tell) does not fail")  # fmt: skip
    p.add_argument("-q", "--quiet", action="store_true", help="no per-row progress lines")
    p.add_argument("--parallel", type=int, default=None, metavar="N",
                   help="instead: the batch of runs with --jobs N against --jobs 1 (wall time), beside this "
                   "machine's own N-process ceiling; writes scaling.json and scaling.md")  # fmt: skip
    p.set_defaults(func=_cli)


def _meta(settings: Mapping[str, Any]) -> dict[str, Any]:
    return {
        "command": _command(),
        "created": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        "settings": dict(settings),
        "versions": versions(),
        "machine": machine(),
    }


def _parallel_cli(
    args: argparse.Namespace, scenarios: Sequence[Scenario], names: Sequence[str], repeats: int, paths: Sequence[str]
) -> int:
    """``legbench bench --parallel N`` (:mod:`legbench.studies.scaling`)."""
    from legbench.studies import scaling

    res = scaling.run_scaling(scenarios, names, args.parallel, repeats, None if args.quiet else print)
    settings = {"parallel": args.parallel, "repeats": repeats, "quick": args.quick, "duration": args.duration,
                "scenarios": [str(p) for p in paths], "backends": list(names)}  # fmt: skip
    js, md = scaling.write_scaling(res, Path(args.out), _meta(settings))
    if not args.quiet:
        print(scaling.markdown(res, _meta(settings)))
        print(f"wrote {js} and {md}")
    return 0


def _cli(args: argparse.Namespace) -> int:
    """Handler of ``legbench bench``.

    Returns:
        0; 3 if a backend failed to load or run (the others are still written);
        1 with ``--check`` if a target is missed or not measured (not if inconclusive), or a replay's or a
        floor's end state was not bit-identical to the run's.
    """
    paths = args.scenarios or [str(p) for p in TASKS]
    overrides = yamlfile.parse_overrides(args.set)
    contact_mode = f"--contact-mode {args.contact_mode}" if args.contact_mode else None
    yamlfile.check_one_place(overrides, {"physics.contact_mode": contact_mode})
    scenarios = load_tasks(paths, quick=args.quick, duration=args.duration, overrides=overrides)
    names = registry.resolve(args.backends)
    if args.contact_mode is not None:  # as the scenario would be refused with that mode in it, before any work
        for sc in scenarios:
            scenario.check_contact_mode(sc, names, args.contact_mode)
    repeats = args.repeats if args.repeats is not None else (1 if args.quick else DEFAULT_REPEATS)
    doc = "scaling.json" if args.parallel is not None else "bench.json"
    check_study_out(args.out, doc, OUTPUTS, "bench", args.force)
    if args.parallel is not None:
        return _parallel_cli(args, scenarios, names, repeats, paths)

    def show(r: BenchResult) -> None:
        if args.quiet:
            return
        if r.status != "ok":
            print(f"{r.task:<10} {r.backend:<10} FAILED: {r.reason}", flush=True)
            return
        h = r.find("full / replay")
        fl = r.find(f"full / {r.floor}") if r.floor != "replay" else None
        print(
            f"{r.task:<10} {r.backend:<10} full {r.timings['full'].cpu.median:7.1f} us/tick CPU  "
            f"full/replay {_ratio_cell(h, bold=False)}"
            f"{f'  full/{r.floor} {_ratio_cell(fl, bold=False)}' if fl else ''}"
            f"  end state: {_end_state_text(r)}",
            flush=True,
        )

    min_sample = 0.0 if args.quick else MIN_SAMPLE
    before = conditions()
    results = run_bench(scenarios, names, repeats, args.warmup, args.contact_mode, not args.no_memory, show, min_sample)
    after = conditions()
    settings = {
        "repeats": repeats,
        "warmup": args.warmup,
        "min_sample_s": min_sample,
        "quick": args.quick,
        "duration": args.duration,
        "contact_mode": args.contact_mode,
        "overrides": overrides,
        "scenarios": [str(p) for p in paths],
        "backends": names,
        "clock": "time.process_time (CPU) and time.perf_counter (wall)",
    }
    met = targets_met(results)
    counts = target_counts(results)
    meta = {
        "command": _command(),
        "created": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        "settings": settings,
        "targets_met": met,
        "targets": {**counts, "line": count_line(counts)},
        "versions": versions(),
        "machine": {**machine(), **during(before, after)},
    }
    js, md = write_results(results, Path(args.out), meta)
    if not args.quiet:
        print(f"targets: {count_line(counts)}")
        print(f"wrote {js} and {md}")
    if any(r.status != "ok" for r in results):
        return 3
    same = all(c["identical"] for r in results for c in r.end_state.values())
    if args.check and (counts["missed"] or counts["not measured"] or not same):
        return 1
    return 0
