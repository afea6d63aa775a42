"""``legbench bench``: what the harness costs on top of each engine, per backend and task.

For every backend and task, in one process and on one loaded backend, two
loops run side by side, interleaved repeat by repeat:

* **full**: :func:`legbench.run.simulate`, the real run (state read, checks,
  events, controller, saturation, log);
* **engine-only**: ``backend.reset(q0, qd0)`` and ``backend.step(tau_k)`` for
  the torques the full run logged, in a tight loop: no controller, no log, no
  checks. Its final state must equal the full run's last logged state bit for
  bit (same torques through the same engine steps); if it does not, the
  backend is not deterministic or its ``reset`` is incomplete.

Reported per (task, backend): wall time [s], microseconds per control period,
real-time factor, the harness overhead ratio full / engine-only (median of the
per-repeat ratios, with min/max), the harness's own cost per tick, and the
peak Python memory of one full run (tracemalloc) against the size of the time
series it returns. For a backend that offers its own per-sub-step calls
(:meth:`~legbench.backends.base.Backend.kernels`, e.g. forward dynamics and
the contact law) also the cost per sub-step against those calls in isolation,
each timed in a tight loop over the run's logged states (:func:`kernel_floors`).

Results go to ``<out>/bench.json`` (every figure, versions, machine) and
``<out>/bench.md`` (the tables the docs quote). ``--quick`` (short durations,
one repeat) is what the test suite runs; timings belong in the benchmark, not
in tests.
"""

from __future__ import annotations

import argparse
import gc
import math
import os
import platform
import resource
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
from legbench.backends.base import Backend
from legbench.exceptions import BackendNotFound, LegbenchError
from legbench.results import RunResult, platform_info, versions, write_json
from legbench.run import simulate
from legbench.scenario import Scenario, physics_of, shorten

__all__ = [
    "DEFAULT_REPEATS",
    "QUICK_DURATIONS",
    "TARGETS",
    "TASKS",
    "BenchResult",
    "Spread",
    "add_cli",
    "bench_backend",
    "kernel_floors",
    "run_bench",
    "shorten",
    "write_results",
]

ROOT = resources.scenarios_dir().parent  # the package data: ROOT / "scenarios" is the bundled scenarios
#: The four tasks of docs/spec.md section 7, benchmarked by default.
TASKS = tuple(ROOT / "scenarios" / f"{name}.yaml" for name in ("position", "ellipse", "effort", "combined"))
DEFAULT_REPEATS = 5
DEFAULT_WARMUP = 1
DEFAULT_OUT = Path("results") / "bench"
#: ``--quick`` durations per task [s]: each still reaches every controller of its task
#: (combined: the touch-down at 1 s and the push from 2 s) but none lasts long.
QUICK_DURATIONS: Mapping[str, float] = {"position": 0.5, "ellipse": 1.5, "effort": 0.5, "combined": 2.5}
QUICK_DEFAULT_DURATION = 0.5
#: Targets: ``overhead``, the harness overhead ratio (full / engine-only) of every backend
#: without kernel floors; ``substep``, the cost per sub-step over the cost of the engine's own
#: calls (:meth:`~legbench.backends.base.Backend.kernels`) of every backend that offers them.
TARGETS: Mapping[str, float] = {"overhead": 1.25, "substep": 3.0}
#: Minimum wall time of each isolated-kernel timing loop [s].
KERNEL_MIN_TIME = 0.05


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
        full_wall: wall time of the full run [s].
        engine_wall: wall time of the engine-only replay [s].
        full_us_per_tick: full run per control period [us].
        engine_us_per_tick: engine-only replay per control period [us].
        harness_us_per_tick: median full minus median engine-only per control period [us].
        overhead_ratio: full / engine-only wall time, per repeat (interleaved pairs).
        rtf_full: real-time factor of the full run (simulated / wall time, median).
        rtf_engine: real-time factor of the engine-only replay (median).
        replay_identical: the replay's final (q, qd) equalled the full run's last logged state, bit
            for bit, after every replay.
        replay_max_diff: largest absolute difference between them [rad, rad/s] (0 when identical).
        mem_peak_bytes: peak Python memory (tracemalloc) during one full run [bytes].
        series_bytes: size of the time series the run returns (t, q, qd, tau, f, controller) [bytes].
        max_rss_bytes: the process's peak resident set size so far (getrusage) [bytes].
        kernels: backends offering :meth:`~legbench.backends.base.Backend.kernels` only: sub-step cost
            against the engine's own calls (see :func:`kernel_floors`); None otherwise.
        info: the backend's ``info()``.
    """

    task: str
    backend: str
    status: str = "ok"
    reason: str | None = None
    duration: float = 0.0
    steps: int = 0
    sub_steps: int | None = None
    full_wall: Spread | None = None
    engine_wall: Spread | None = None
    full_us_per_tick: Spread | None = None
    engine_us_per_tick: Spread | None = None
    harness_us_per_tick: float = math.nan
    overhead_ratio: Spread | None = None
    rtf_full: float = math.nan
    rtf_engine: float = math.nan
    replay_identical: bool = False
    replay_max_diff: float = math.nan
    mem_peak_bytes: int = 0
    series_bytes: int = 0
    max_rss_bytes: int = 0
    kernels: dict[str, float] | None = None
    info: dict[str, Any] = field(default_factory=dict)

    @property
    def mem_ratio(self) -> float:
        """Peak Python memory of a full run over the size of its time series [1]."""
        return self.mem_peak_bytes / self.series_bytes if self.series_bytes else math.nan

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict (spreads as nested dicts), plus ``mem_ratio`` and ``mem_excess_bytes`` (peak - series)."""
        out = asdict(self)
        out["mem_ratio"] = self.mem_ratio
        out["mem_excess_bytes"] = self.mem_peak_bytes - self.series_bytes if self.mem_peak_bytes else None
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
        quick: shorten each to its :data:`QUICK_DURATIONS` entry (see :func:`shorten`).
        duration: shorten each to this [s] instead.
        overrides: dotted scenario keys set before validation, as ``legbench run --set``.
    """
    out = []
    for path in paths:
        sc = scenario.load(path, overrides)
        if duration is not None:
            sc = shorten(sc, duration)
        elif quick:
            sc = shorten(sc, QUICK_DURATIONS.get(sc.name, QUICK_DEFAULT_DURATION))
        out.append(sc)
    return out


# --------------------------------------------------------------------------- #
# Measurement


def _series_bytes(tr: RunResult) -> int:
    return int(sum(a.nbytes for a in (tr.t, tr.q, tr.qd, tr.tau, tr.f, tr.controller)))


def _replay(backend: Backend, q0: np.ndarray, qd0: np.ndarray, taus: Sequence[np.ndarray]) -> float:
    """Engine-only loop: reset, then one step per logged torque. Wall time [s]."""
    reset, step = backend.reset, backend.step
    start = time.perf_counter()
    reset(q0, qd0)
    for tau in taus:
        step(tau)
    return time.perf_counter() - start


def _memory_peak(fn: Callable[[], Any]) -> int:
    """Peak Python memory allocated while ``fn`` runs [bytes] (tracemalloc, everything still alive counts)."""
    gc.collect()
    tracemalloc.start()
    try:
        tracemalloc.reset_peak()
        base = tracemalloc.get_traced_memory()[0]
        fn()
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    return int(peak - base)


def _max_rss() -> int:
    """Peak resident set size of this process [bytes] (Linux reports kB, macOS bytes)."""
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return int(rss if sys.platform == "darwin" else rss * 1024)


def _time_loop(body: Callable[[], None], calls_per_body: int) -> float:
    """Best time per call of a loop body [s]: the body repeated until KERNEL_MIN_TIME, best of 3."""
    reps = 1
    while True:
        start = time.perf_counter()
        for _ in range(reps):
            body()
        took = time.perf_counter() - start
        if took >= KERNEL_MIN_TIME:
            break
        reps *= 2
    best = took
    for _ in range(2):
        start = time.perf_counter()
        for _ in range(reps):
            body()
        best = min(best, time.perf_counter() - start)
    return best / (reps * calls_per_body)


def kernel_floors(backend: Backend, tr: RunResult, samples: int = 200) -> dict[str, float] | None:
    """Cost of the engine's own calls per sub-step, each in isolation [us]; None if the backend offers none.

    Every callable of :meth:`Backend.kernels` is timed in a tight loop over up
    to ``samples`` states evenly spaced through the run's log (in or out of
    contact as the run was), with inputs prepared beforehand by the backend.

    Returns:
        ``<kernel>_us`` per call of each kernel (e.g. ``aba_us``, ``law_us``) and
        ``kernels_us``, their sum [us].
    """
    rows = np.unique(np.linspace(0, len(tr.t) - 1, min(samples, len(tr.t))).astype(int))
    try:
        loops = backend.kernels(tr.q[rows], tr.qd[rows], tr.tau[rows])
    except NotImplementedError:
        return None
    out = {f"{name}_us": 1e6 * _time_loop(loop, len(rows)) for name, loop in loops.items()}
    out["kernels_us"] = sum(out.values())
    return out


def bench_backend(
    sc: Scenario,
    name: str,
    repeats: int = DEFAULT_REPEATS,
    warmup: int = DEFAULT_WARMUP,
    contact_mode: str | None = None,
    memory: bool = True,
) -> BenchResult:
    """Benchmark one backend on one scenario: warm-up, then ``repeats`` interleaved (full, engine-only) pairs.

    Args:
        sc: the scenario (a task, possibly shortened).
        name: backend name.
        repeats: timed (full, engine-only) pairs (>= 1).
        warmup: untimed pairs before them (>= 0); a first full run always gives the torque log.
        contact_mode: ``native`` or ``reference``; default the scenario's.
        memory: also measure the peak memory of one full run (an extra, untimed run under tracemalloc).

    Returns:
        The figures; a backend that cannot load or whose run fails gives ``status="failed"``.
    """
    res = BenchResult(task=sc.name, backend=name, duration=sc.duration, steps=sc.n_ticks - 1)
    physics = physics_of(sc, contact_mode)
    try:
        backend = registry.load(name, physics, sc.backends.get(name, {}))
    except BackendNotFound:
        raise
    except Exception as exc:  # an engine that cannot load must not stop the others
        res.status, res.reason = "failed", f"load failed: {type(exc).__name__}: {exc}"
        return res
    try:
        q0, qd0 = np.array(sc.q0), np.array(sc.qd0)
        tr = simulate(sc, backend, physics)
        if tr.status != "ok":
            res.status, res.reason = "failed", tr.reason
            return res
        res.info = tr.info
        res.sub_steps = backend.sub_steps()
        taus = list(tr.tau[:-1])  # row views, the same kind of array the run loop hands the backend
        q_end, qd_end = tr.q[-1].copy(), tr.qd[-1].copy()
        for _ in range(warmup):
            simulate(sc, backend, physics)
            _replay(backend, q0, qd0, taus)
        full: list[float] = []
        engine: list[float] = []
        identical, max_diff = True, 0.0
        for _ in range(repeats):
            gc.collect()
            start = time.perf_counter()
            tr_r = simulate(sc, backend, physics)
            full.append(time.perf_counter() - start)
            if tr_r.status != "ok":
                res.status, res.reason = "failed", tr_r.reason
                return res
            gc.collect()
            engine.append(_replay(backend, q0, qd0, taus))
            q, qd = backend.state()
            same = np.array_equal(q, q_end) and np.array_equal(qd, qd_end)
            identical &= same and np.array_equal(tr_r.q[-1], q_end) and np.array_equal(tr_r.qd[-1], qd_end)
            with np.errstate(invalid="ignore"):
                max_diff = max(max_diff, float(np.max(np.abs(np.concatenate([q - q_end, qd - qd_end])))))
        steps = max(res.steps, 1)
        res.full_wall, res.engine_wall = Spread.of(full), Spread.of(engine)
        res.full_us_per_tick = res.full_wall.scaled(1e6 / steps)
        res.engine_us_per_tick = res.engine_wall.scaled(1e6 / steps)
        res.harness_us_per_tick = res.full_us_per_tick.median - res.engine_us_per_tick.median
        res.overhead_ratio = Spread.of([f / e for f, e in zip(full, engine, strict=True)])
        res.rtf_full = sc.duration / res.full_wall.median
        res.rtf_engine = sc.duration / res.engine_wall.median
        res.replay_identical, res.replay_max_diff = identical, max_diff
        if memory:
            holder: list[RunResult] = []
            res.mem_peak_bytes = _memory_peak(lambda: holder.append(simulate(sc, backend, physics)))
            res.series_bytes = _series_bytes(holder[0])
            del holder
        res.max_rss_bytes = _max_rss()
        k = kernel_floors(backend, tr) if res.sub_steps else None
        if k is not None and res.sub_steps:
            k["substep_us"] = res.engine_us_per_tick.median / res.sub_steps
            k["ratio"] = k["substep_us"] / k["kernels_us"]
            res.kernels = k
        return res
    finally:
        backend.close()


def run_bench(
    scenarios: Sequence[Scenario],
    backend_names: Sequence[str],
    repeats: int = DEFAULT_REPEATS,
    warmup: int = DEFAULT_WARMUP,
    contact_mode: str | None = None,
    memory: bool = True,
    progress: Callable[[BenchResult], None] | None = None,
) -> list[BenchResult]:
    """Benchmark every backend on every scenario (task-major order), one after the other in this process."""
    if repeats < 1:
        raise LegbenchError(f"bench: --repeats must be at least 1, got {repeats}")
    if warmup < 0:
        raise LegbenchError(f"bench: --warmup must be at least 0, got {warmup}")
    out = []
    for sc in scenarios:
        for name in backend_names:
            res = bench_backend(sc, name, repeats, warmup, contact_mode, memory)
            if progress is not None:
                progress(res)
            out.append(res)
    return out


# --------------------------------------------------------------------------- #
# Output


def machine() -> dict[str, Any]:
    """The machine: platform, CPU model and count, Python build."""
    cpu = platform.processor()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    aff = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    return {
        **platform_info(),
        "cpu_model": cpu,
        "cpus_usable": aff,
        "python_build": " ".join(platform.python_build()),
        "python_implementation": platform.python_implementation(),
    }


def targets_met(results: Sequence[BenchResult]) -> dict[str, bool]:
    """Each target of :data:`TARGETS` against the medians (True where met; a failed run misses)."""
    met: dict[str, bool] = {}
    for r in results:
        if r.kernels is None and r.status == "ok":
            ok = r.overhead_ratio is not None and r.overhead_ratio.median <= TARGETS["overhead"]
            met["overhead"] = met.get("overhead", True) and ok
        elif r.kernels is not None:
            ok = r.status == "ok" and r.kernels["ratio"] <= TARGETS["substep"]
            met["substep"] = met.get("substep", True) and ok
        else:  # a failed run misses the target it was under
            met["overhead"] = False
    return met


def _f(x: float | None, fmt: str) -> str:
    return "-" if x is None or not math.isfinite(x) else format(x, fmt)


def markdown(results: Sequence[BenchResult], meta: Mapping[str, Any]) -> str:
    """The benchmark as Markdown: settings, one table per measure, targets."""
    s = meta["settings"]
    m = meta["machine"]
    v = meta["versions"]
    engines = ", ".join(f"{k} {v[k]}" for k in registry.engine_packages() if k in v)
    lines = [
        "# legbench bench",
        "",
        f"Command: `{meta['command']}`  ",
        f"Machine: {m['cpu_model']}, {m['cpus_usable']} usable CPUs, {m['system']} {m['machine']}; "
        f"Python {v['python']}, numpy {v.get('numpy', '?')}, {engines}.  ",
        f"Settings: {s['repeats']} timed repeats after {s['warmup']} warm-up, contact mode "
        f"{s['contact_mode'] or 'from each scenario'}{', quick' if s['quick'] else ''}"
        f"{''.join(f', {k} = {val}' for k, val in (s.get('overrides') or {}).items())}. "
        "Figures are medians; brackets give min-max over the repeats.",
        "",
        "## Full run against engine-only replay",
        "",
        "| task | backend | sim [s] | sub-steps | full [us/tick] | engine-only [us/tick] | harness [us/tick] "
        "| overhead ratio | RTF full | replay identical |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in results:
        if r.status != "ok":
            lines.append(f"| {r.task} | {r.backend} | {r.duration:g} | - | FAILED: {r.reason} | | | | | |")
            continue
        assert r.full_us_per_tick and r.engine_us_per_tick and r.overhead_ratio
        o = r.overhead_ratio
        lines.append(
            f"| {r.task} | {r.backend} | {r.duration:g} | {r.sub_steps} "
            f"| {r.full_us_per_tick.median:.1f} [{r.full_us_per_tick.min:.1f}-{r.full_us_per_tick.max:.1f}] "
            f"| {r.engine_us_per_tick.median:.1f} [{r.engine_us_per_tick.min:.1f}-{r.engine_us_per_tick.max:.1f}] "
            f"| {r.harness_us_per_tick:.1f} | **{o.median:.3f}** [{o.min:.3f}-{o.max:.3f}] "
            f"| {r.rtf_full:.1f} | {'yes' if r.replay_identical else f'NO (max diff {r.replay_max_diff:.3g})'} |"
        )
    if any(r.mem_peak_bytes for r in results):
        lines += [
            "",
            "## Memory of one full run",
            "",
            "Peak Python memory (tracemalloc) during `simulate`, against the time series it returns "
            "(t, q, qd, tau, f, controller).",
            "",
            "| task | backend | ticks | peak [MB] | time series [MB] | peak / series | peak - series [kB] |",
            "|---|---|---|---|---|---|---|",
        ]
        for r in results:
            if r.status == "ok" and r.mem_peak_bytes:
                lines.append(
                    f"| {r.task} | {r.backend} | {r.steps + 1} | {r.mem_peak_bytes / 1e6:.3f} "
                    f"| {r.series_bytes / 1e6:.3f} | {r.mem_ratio:.3f} "
                    f"| {(r.mem_peak_bytes - r.series_bytes) / 1e3:.1f} |"
                )
    kernel_rows = [r for r in results if r.kernels]
    if kernel_rows:
        lines += [
            "",
            "## Cost per sub-step against the engine's own calls",
            "",
            "Engine-only cost per sub-step against the calls the backend makes at every sub-step "
            "(`Backend.kernels`), each timed alone in a tight loop over the run's logged states.",
            "",
            "| backend | task | per sub-step [us] | own calls [us] | ratio |",
            "|---|---|---|---|---|",
        ]
        for r in kernel_rows:
            k = r.kernels or {}
            calls = ", ".join(f"{n.removesuffix('_us')} {v:.2f}" for n, v in k.items()
                              if n.endswith("_us") and n not in ("kernels_us", "substep_us"))  # fmt: skip
            lines.append(f"| {r.backend} | {r.task} | {k['substep_us']:.2f} | {calls} | **{k['ratio']:.2f}** |")
    met = meta["targets_met"]
    if met:
        lines += ["", "## Targets", ""]
        names = {
            "overhead": "overhead ratio of each backend without kernel floors",
            "substep": "sub-step / own calls of each backend with kernel floors",
        }
        for key, ok in met.items():
            lines.append(f"- {names[key]} <= {TARGETS[key]:g} on every task: {'met' if ok else 'MISSED'}")
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
        help="time the full run against an engine-only replay per backend and task",
        description="Time the full legbench run against an engine-only replay of its torques, per backend "
        "and task; write bench.json and bench.md.",
    )
    p.add_argument("scenarios", nargs="*", metavar="SCENARIO",
                   help="scenario YAML files (default: the four tasks in scenarios/)")  # fmt: skip
    p.add_argument("--backends", default="all", help="comma-separated backend names, or 'all' (default)")
    p.add_argument("--repeats", type=int, default=None,
                   help=f"timed repeats per backend and task (default {DEFAULT_REPEATS}; 1 with --quick)")  # fmt: skip
    p.add_argument("--warmup", type=int, default=DEFAULT_WARMUP,
                   help=f"untimed warm-up runs before them (default {DEFAULT_WARMUP})")  # fmt: skip
    p.add_argument("--quick", action="store_true",
                   help="short durations (later events dropped), one repeat: a smoke test, not figures")  # fmt: skip
    p.add_argument("--duration", type=float, default=None, help="cut every scenario to this many seconds")
    p.add_argument("--contact-mode", choices=("native", "reference"), default=None,
                   help="override the scenarios' contact mode")  # fmt: skip
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="override a scenario key, e.g. --set backends.<name>.dt=1e-4 (10 sub-steps)")  # fmt: skip
    p.add_argument("--no-memory", action="store_true", help="skip the (untimed, tracemalloc) memory run")
    p.add_argument("--out", default=str(DEFAULT_OUT), help=f"output directory (default {DEFAULT_OUT})")
    p.add_argument("--check", action="store_true", help="exit 1 if a performance target is missed")
    p.add_argument("-q", "--quiet", action="store_true", help="no per-row progress lines")
    p.set_defaults(func=_cli)


def _cli(args: argparse.Namespace) -> int:
    """Handler of ``legbench bench``.

    Returns:
        0; 3 if a backend failed to load or run (the others are still written);
        1 with ``--check`` if a target is missed or a replay was not bit-identical.
    """
    paths = args.scenarios or [str(p) for p in TASKS]
    overrides = yamlfile.parse_overrides(args.set)
    scenarios = load_tasks(paths, quick=args.quick, duration=args.duration, overrides=overrides)
    names = registry.resolve(args.backends)
    repeats = args.repeats if args.repeats is not None else (1 if args.quick else DEFAULT_REPEATS)

    def show(r: BenchResult) -> None:
        if args.quiet:
            return
        if r.status != "ok" or r.overhead_ratio is None or r.full_us_per_tick is None:
            print(f"{r.task:<10} {r.backend:<10} FAILED: {r.reason}", flush=True)
            return
        extra = f"  sub-step/own calls {r.kernels['ratio']:.2f}" if r.kernels else ""
        print(
            f"{r.task:<10} {r.backend:<10} full {r.full_us_per_tick.median:7.1f} us/tick  harness "
            f"{r.harness_us_per_tick:6.1f} us/tick  ratio {r.overhead_ratio.median:.3f}  RTF {r.rtf_full:6.1f}"
            f"  replay {'identical' if r.replay_identical else 'DIFFERS'}{extra}",
            flush=True,
        )

    results = run_bench(scenarios, names, repeats, args.warmup, args.contact_mode, not args.no_memory, show)
    settings = {
        "repeats": repeats,
        "warmup": args.warmup,
        "quick": args.quick,
        "duration": args.duration,
        "contact_mode": args.contact_mode,
        "overrides": overrides,
        "scenarios": [str(p) for p in paths],
        "backends": names,
    }
    met = targets_met(results)
    meta = {
        "command": " ".join(["legbench", "bench", *sys.argv[2:]]) if sys.argv[1:2] == ["bench"] else "legbench bench",
        "created": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        "settings": settings,
        "targets": dict(TARGETS),
        "targets_met": met,
        "versions": versions(),
        "machine": machine(),
    }
    js, md = write_results(results, Path(args.out), meta)
    if not args.quiet:
        print(f"wrote {js} and {md}")
    if any(r.status != "ok" for r in results):
        return 3
    if args.check and not (all(met.values()) and all(r.replay_identical for r in results)):
        return 1
    return 0
