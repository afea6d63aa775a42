"""``legbench bench --parallel N``: how close ``--jobs N`` comes to N-fold, against this machine's own ceiling.

Four measurements per repeat, side by side: the ceiling's probe alone, the probe N at once, the batch
with ``jobs = 1`` and the batch with ``jobs = N``, in that order on even repeats and in the reverse
order on odd ones (:attr:`ScalingResult.order` records it), so a load drift hits each pair alike
and neither side of a pair is always first.

* **throughput**: the batch (every scenario x backend asked for, logs kept in memory, nothing written)
  through :func:`legbench.run.run_many`, in wall time. ``jobs = 1`` runs it in this process;
  ``jobs = N`` in a pool started afresh for each repeat (:func:`legbench.run.start_pool`, as
  ``legbench run --jobs N`` starts it). Both sides are timed warm: this process ran the whole batch
  untimed before the repeats (twice if it is short); the pool's workers run every run of the batch
  cut to :data:`WARM_S` (their first uses: imports, compiled code) before the batch is timed. The
  pool's **start-up** (from starting the pool until every worker has imported and run its warm-up;
  the worker processes that answered are counted) is timed apart, so there are two speed-ups:
  ``wall(1) / wall(N)`` (the batch alone) and ``wall(1) / (start-up + wall(N))``. The second charges
  the pool its start-up while the ``jobs = 1`` side pays none of its own (a ``legbench run --jobs
  1`` pays its imports and first uses too): a lower bound. The fork server the workers come from
  (:mod:`legbench.studies.executors`) is started by an untimed pool before the repeats, so every
  repeat's start-up is the same: forking, the workers' initialisation and their warm-up, not the
  server's imports (about 1.5 s once per command, which a command overlaps with its pre-flight).
  Fewer runs than N is refused: a pool never has more workers than runs, and such a "speed-up"
  compares the same work with itself.
* **ceiling**: what N processes get out of this machine at this moment. The *probe* is the batch's
  own mix: every run of the batch, each cut to the same share of its duration (later events dropped),
  so the probe costs about ``probe_s`` of one process's time, as the untimed serial batch measured
  it, and each engine's share of the probe is its share of the batch (a batch shorter than
  ``probe_s`` is run whole, several times). Each probe process loads, runs and closes each run as a
  pool worker does (:func:`legbench.run.run_backend`), after a warm-up like the workers'. One fresh
  process runs the probe alone; N fresh processes run it together, started at a barrier (an event,
  not a sleep), each from a different run of the list, as the pool's workers run different runs at a
  time. ``ceiling = N x wall(alone) / mean wall(together)``: the throughput N processes reach,
  in units of one process's. It is lowered both by hardware the "cores" share (SMT siblings, a VM's
  vCPUs on one host core: each process's own CPU time grows) and by other tenants' load (a process
  waits for a CPU: wall time grows, CPU time does not), and the batch's speed-up is lowered by
  both alike. ``N x CPU(alone) / mean CPU(together)`` is given beside it: the shared hardware alone.

``efficiency = speed-up / ceiling`` (the wall-time ceiling of the same repeat) is legbench's share of
what the machine allowed: the serial parts (pre-flight, result transfer), the tail of the longest
run and first uses the workers' warm-up did not reach (events after :data:`WARM_S`); with start-up,
the pool's start too. A batch under :data:`MIN_BATCH_S` with ``jobs = 1``, or under
:data:`STARTUP_FACTOR` times the pool's start-up with ``jobs = N``, is warned about (logged, and in
the tables). A ceiling and a
batch measured at different moments see different loads, so a repeat's efficiency can still stray
above 1 on a busy machine: the spread of the repeats says by how much.
"""

from __future__ import annotations

import logging
import math
import multiprocessing
import os
import signal
import threading
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import asdict, dataclass, field
from multiprocessing import connection
from multiprocessing.connection import Connection
from multiprocessing.managers import SyncManager
from pathlib import Path
from typing import Any, cast

from legbench.exceptions import LegbenchError
from legbench.results import atomic_write_text, write_json
from legbench.run import run_backend, run_many, start_pool
from legbench.scenario import Scenario, shorten
from legbench.studies.executors import capped
from legbench.yamlfile import one_line

__all__ = [
    "PoolTiming",
    "ScalingResult",
    "ceiling_sample",
    "markdown",
    "probe_runs",
    "run_scaling",
    "time_pool",
    "time_serial",
    "warm_up",
    "write_scaling",
]

logger = logging.getLogger("legbench.scaling")

#: The ceiling's probe costs about this much of one process's wall time [s] (the serial batch's share).
PROBE_S = 2.0
#: Each warm-up run (a pool worker's, a probe process's) is its run cut to this many seconds [s].
WARM_S = 0.01
#: No run of the probe is cut shorter than this [s] (a shorter run would be mostly its load and reset).
PROBE_MIN_S = 0.05
#: Below this wall time with ``jobs = 1`` [s] a batch's timings are mostly scheduling and timer noise: warned.
MIN_BATCH_S = 1.0
#: The batch with ``jobs = N`` should last this many times the pool's start-up, or a warning says it does not.
STARTUP_FACTOR = 10.0
#: How long a worker or probe process waits at a barrier for the others [s] before the study gives up.
BARRIER_TIMEOUT = 600.0


@dataclass(frozen=True)
class Sample:
    """min / median / max of one figure over the repeats."""

    values: tuple[float, ...]

    @property
    def median(self) -> float:
        v = sorted(self.values)
        n = len(v)
        return v[n // 2] if n % 2 else 0.5 * (v[n // 2 - 1] + v[n // 2])

    def cell(self, fmt: str = ".2f") -> str:
        return f"{self.median:{fmt}} [{min(self.values):{fmt}}-{max(self.values):{fmt}}]"


def _mean(x: Sequence[float]) -> float:
    return sum(x) / len(x)


@dataclass
class ScalingResult:
    """Every sample of one ``--parallel N`` study [s, or 1 for ratios], per repeat."""

    jobs: int
    runs: list[str]
    probe: str  # what the probe runs (the batch's mix: the share of each run's duration, the passes)
    wall_warmup: float = math.nan  # the untimed serial batch before the repeats [s]
    order: list[list[str]] = field(default_factory=list)  # per repeat, the measurements in the order taken
    workers: list[int] = field(default_factory=list)  # the pool's worker processes that answered, per repeat
    wall_serial: list[float] = field(default_factory=list)  # the batch with jobs = 1 [s]
    wall_parallel: list[float] = field(default_factory=list)  # the batch with jobs = N, pool started and warm [s]
    pool_ready: list[float] = field(default_factory=list)  # pool started -> every worker imported [s]
    pool_startup: list[float] = field(default_factory=list)  # pool started -> every worker warmed up [s]
    probe_cpu_alone: list[float] = field(default_factory=list)  # [s]
    probe_wall_alone: list[float] = field(default_factory=list)
    probe_cpu_together: list[list[float]] = field(default_factory=list)  # per repeat, per process [s]
    probe_wall_together: list[list[float]] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)

    def _ratio(self, num: Sequence[float], den: Sequence[float]) -> Sample:
        return Sample(tuple(a / b for a, b in zip(num, den, strict=True)))

    def speedup(self) -> Sample:
        """wall(jobs 1) / wall(jobs N), the batch alone (both sides warm)."""
        return self._ratio(self.wall_serial, self.wall_parallel)

    def speedup_with_startup(self) -> Sample:
        """wall(jobs 1) / (pool start-up + wall(jobs N))."""
        total = [s + w for s, w in zip(self.pool_startup, self.wall_parallel, strict=True)]
        return self._ratio(self.wall_serial, total)

    def ceiling_wall(self) -> Sample:
        """N x wall(probe alone) / mean wall(probe, N together): the ceiling the efficiency is based on."""
        n = self.jobs
        return self._ratio([n * a for a in self.probe_wall_alone], [_mean(t) for t in self.probe_wall_together])

    def ceiling_cpu(self) -> Sample:
        """N x CPU(probe alone) / mean CPU(probe, N together): the shared hardware alone, without others' load."""
        n = self.jobs
        return self._ratio([n * a for a in self.probe_cpu_alone], [_mean(t) for t in self.probe_cpu_together])

    def efficiency(self) -> Sample:
        """speed-up / wall-time ceiling, per repeat."""
        return self._ratio(self.speedup().values, self.ceiling_wall().values)

    def efficiency_with_startup(self) -> Sample:
        """speed-up with the pool's start-up / wall-time ceiling, per repeat."""
        return self._ratio(self.speedup_with_startup().values, self.ceiling_wall().values)


# --------------------------------------------------------------------------- #
# The ceiling: the probe (the batch's mix) alone, then N copies at once


def probe_runs(
    scenarios: Sequence[Scenario], backend_names: Sequence[str], serial_wall: float, probe_s: float = PROBE_S
) -> tuple[list[tuple[Scenario, str]], int, float]:
    """The probe for a batch whose serial wall time is ``serial_wall`` [s]: every run of the batch cut to the
    same share of its duration (at least :data:`PROBE_MIN_S`), so it costs about ``probe_s``; a batch shorter
    than that is run whole, ``passes`` times. Returns (the runs, passes, the share)."""
    if serial_wall <= 0:
        share, passes = 1.0, 1
    elif serial_wall >= probe_s:
        share, passes = probe_s / serial_wall, 1
    else:
        share, passes = 1.0, math.ceil(probe_s / serial_wall)
    runs = [(_cut(sc, max(share * sc.duration, PROBE_MIN_S)), b) for sc in scenarios for b in backend_names]
    return runs, passes, share


def _cut(sc: Scenario, seconds: float) -> Scenario:
    """``sc`` cut to about ``seconds`` [s]: a whole number of its control periods, at least one."""
    return shorten(sc, max(1, round(seconds * sc.control_rate)) / sc.control_rate)


def _run_all(runs: Sequence[tuple[Scenario, str]]) -> tuple[str, str]:
    """Run each (scenario, backend) as a pool worker does (load, run, close); the first failure, if any."""
    for sc, name in runs:
        tr = run_backend(sc, name)
        if tr.status != "ok":
            return f"{sc.name}/{name}", f"{tr.status}: {tr.reason}"
    return "", ""


def _warm_runs(runs: Sequence[tuple[Scenario, str]]) -> list[tuple[Scenario, str]]:
    return [(_cut(sc, WARM_S), name) for sc, name in runs]


def _probe(runs: Sequence[tuple[Scenario, str]], offset: int, passes: int, barrier: Any, out: Any) -> None:
    """In a fresh process: the warm-up, wait for the others, then ``passes`` times every run of ``runs`` from
    ``runs[offset]`` on (wrapping round); send (CPU, wall) of it all [s] and the first failure down ``out``."""
    _run_all(_warm_runs(runs))  # first uses (imports, compiled code), as a worker's warm-up
    try:
        barrier.wait(BARRIER_TIMEOUT)
    except threading.BrokenBarrierError:  # another probe died and the parent gave up: end quietly
        return
    mine = [*runs[offset:], *runs[:offset]] * passes
    c0, w0 = time.process_time(), time.perf_counter()
    failed = _run_all(mine)
    out.send((time.process_time() - c0, time.perf_counter() - w0, *failed))


def ceiling_sample(
    runs: Sequence[tuple[Scenario, str]], n: int, passes: int = 1, timeout: float = 600.0
) -> list[tuple[float, float]]:
    """(CPU, wall) time [s] of ``passes`` times ``runs`` in each of ``n`` fresh processes started together at
    a barrier, process i from run ``i len(runs) / n`` on."""
    ctx = multiprocessing.get_context("spawn")
    barrier = ctx.Barrier(n)
    pipes = [ctx.Pipe(duplex=False) for _ in range(n)]
    procs = [ctx.Process(target=_probe, args=(list(runs), i * len(runs) // n, passes, barrier, pipes[i][1]),
                         daemon=True) for i in range(n)]  # fmt: skip
    for p in procs:
        p.start()
    for _, sender in pipes:
        sender.close()  # the child holds its own end: a child that dies closes the pipe (EOF), not a hang
    pending = {reader: p for (reader, _), p in zip(pipes, procs, strict=True)}
    got: list[tuple[float, float]] = []
    deadline = time.monotonic() + timeout
    try:
        while pending:
            # a result, or the end of a probe process (an engine that crashes its process sends nothing)
            ready = connection.wait(list(pending), max(0.0, deadline - time.monotonic()))
            if not ready:
                raise LegbenchError(f"bench --parallel: the probe gave no result within {timeout:g} s")
            for obj in ready:
                reader = cast(Connection, obj)
                proc = pending.pop(reader)
                try:
                    cpu, wall, which, why = reader.recv()
                except EOFError:
                    barrier.abort()  # the others would wait for it at the barrier
                    proc.join(5.0)
                    why = "the engine crashed it" if (proc.exitcode or 0) < 0 else "an error in it"
                    raise LegbenchError(f"bench --parallel: a probe process ended (exit code {proc.exitcode}) "
                                        f"without its result: {why}") from None  # fmt: skip
                if which:
                    raise LegbenchError(f"bench --parallel: the probe's run {which} ended {why}")
                got.append((cpu, wall))
    finally:
        if len(got) < n:  # leaving on an error: the probes still running are of no use, stop them at once
            for p in procs:
                if p.is_alive():
                    p.kill()
        for p in procs:
            p.join(5.0)
            if p.is_alive():
                p.kill()
                p.join()
        for reader, _ in pipes:
            reader.close()
    return got


# --------------------------------------------------------------------------- #
# The batch: jobs = 1 in this process, jobs = N in a fresh pool


def time_serial(batch: Sequence[tuple[Scenario, str | None, Path | None]], backend_names: Sequence[str]) -> float:
    """Wall time [s] of the batch with ``jobs = 1`` (in this process)."""
    w0 = time.perf_counter()
    results = run_many(batch, backend_names, jobs=1, progress=False)
    wall = time.perf_counter() - w0
    _check(results)
    return wall


def _check(results: Sequence[Sequence[Any]]) -> None:
    """Refuse a batch with a failed run: its timings would not be of the same work. One line naming each failed
    backend with its first reason (the batch's timing needs every run; leave that backend out)."""
    bad: dict[str, str] = {}
    for tr in (tr for rs in results for tr in rs if tr.status != "ok"):
        bad.setdefault(tr.backend, f"{tr.status}: {tr.reason or 'no reason given'}")
    if bad:
        which = "; ".join(f"{name} ({why})" for name, why in sorted(bad.items()))
        raise LegbenchError(one_line(f"bench --parallel: runs failed on {which}; a batch is timed whole: leave "
                                     "them out of --backends"))  # fmt: skip


@dataclass(frozen=True)
class PoolTiming:
    """One ``jobs = N`` batch [s]: the pool's start-up (until every worker imported; until every worker ran
    its warm-up), the batch on the warm pool, and how many worker processes answered."""

    ready: float
    startup: float
    wall: float
    workers: int


def _rendezvous(args: tuple[Any, Sequence[tuple[Scenario, str]]]) -> int:
    """A pool task: wait until every worker holds one (so each worker gets exactly one), run the warm-up
    runs; this worker's process id."""
    barrier, runs = args
    barrier.wait(BARRIER_TIMEOUT)
    _run_all(runs)
    return os.getpid()


def _no_sigint() -> None:
    """Start of the barriers' manager process: Ctrl-C is this process's business (it shuts the manager down)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


@contextmanager
def _barriers() -> Iterator[Callable[[int], Any]]:
    """Barriers a pool's tasks can be handed (a manager's proxies, picklable): the manager's ``Barrier``, from a
    manager process started now (spawned, about 0.3 s, untimed) and shut down on leaving."""
    manager = SyncManager(ctx=multiprocessing.get_context("spawn"))
    manager.start(_no_sigint)
    try:
        yield manager.Barrier
    finally:
        manager.shutdown()


def _ready_pool(
    jobs: int, tasks: int, warm: Sequence[tuple[Scenario, str]], barriers: Callable[[int], Any]
) -> tuple[Any, float, float, int]:
    """A pool started now (:func:`legbench.run.start_pool`), every worker imported, then warmed up on ``warm``:
    (the pool, seconds until ready, seconds until warm, distinct worker processes)."""
    n = capped(jobs, tasks)  # the workers start_pool starts
    b1, b2 = barriers(n), barriers(n)
    w0 = time.perf_counter()
    pool = start_pool(jobs, tasks)
    assert pool is not None  # jobs >= 2
    try:
        pool.map(_rendezvous, [(b1, ())] * pool.jobs)
        ready = time.perf_counter() - w0
        pids = pool.map(_rendezvous, [(b2, tuple(warm))] * pool.jobs)
        startup = time.perf_counter() - w0
    except BaseException as exc:
        pool.terminate()
        if isinstance(exc, Exception):
            raise LegbenchError(
                f"bench --parallel: the pool's workers did not start: {type(exc).__name__}: {exc}"
            ) from exc
        raise
    return pool, ready, startup, len(set(pids))


def time_pool(
    batch: Sequence[tuple[Scenario, str | None, Path | None]],
    backend_names: Sequence[str],
    jobs: int,
    warm: Sequence[tuple[Scenario, str]],
    barriers: Callable[[int], Any],
) -> PoolTiming:
    """The batch with ``jobs = N``: a pool started afresh and warmed up (timed apart), then the batch on it."""
    pool, ready, startup, workers = _ready_pool(jobs, len(batch) * len(backend_names), warm, barriers)
    w0 = time.perf_counter()
    results = run_many(batch, backend_names, jobs=jobs, progress=False, pool=pool)  # closes the pool
    wall = time.perf_counter() - w0
    _check(results)
    return PoolTiming(ready, startup, wall, workers)


def warm_up(
    batch: Sequence[tuple[Scenario, str | None, Path | None]],
    backend_names: Sequence[str],
    jobs: int,
    barriers: Callable[[int], Any],
    probe_s: float = PROBE_S,
) -> float:
    """Untimed, before the repeats: the whole batch in this process (imports, first uses, caches), again if it
    took under ``4 probe_s`` (first uses are then much of it), then a pool of ``jobs`` started and closed (it
    starts the fork server, which every later pool forks from). The last batch's wall time [s]: what the
    probe is cut by."""
    wall = time_serial(batch, backend_names)
    if wall < 4 * probe_s:
        wall = time_serial(batch, backend_names)
    pool, *_ = _ready_pool(jobs, len(batch) * len(backend_names), (), barriers)
    pool.close()
    return wall


# --------------------------------------------------------------------------- #
# The study


def run_scaling(
    scenarios: Sequence[Scenario],
    backend_names: Sequence[str],
    jobs: int = 2,
    repeats: int = 3,
    progress: Callable[[str], None] | None = None,
    probe_s: float = PROBE_S,
) -> ScalingResult:
    """Throughput of the batch (every scenario x backend) with 1 and ``jobs`` workers, and the machine's ceiling.

    Args:
        scenarios: the runs' scenarios.
        backend_names: backends, each run on every scenario.
        jobs: N, the worker count compared with 1 (>= 2, and no more than the batch's runs).
        repeats: interleaved repeats (>= 1).
        progress: called with one line per measurement.
        probe_s: about how long [s] the ceiling's probe takes one process (:data:`PROBE_S`).

    Raises:
        LegbenchError: a bad count, fewer runs than ``jobs``, or a run that failed.
    """
    if jobs < 2:
        raise LegbenchError(f"bench: --parallel must be at least 2, got {jobs}")
    if repeats < 1:
        raise LegbenchError(f"bench: --repeats must be at least 1, got {repeats}")
    if not scenarios or not backend_names:
        raise LegbenchError("bench --parallel: no scenario or no backend to run")
    runs = [(sc, b) for sc in scenarios for b in backend_names]
    if len(runs) < jobs:
        smaller = f", or --parallel {len(runs)}" if len(runs) >= 2 else ""
        raise LegbenchError(f"bench --parallel {jobs}: the batch has {len(runs)} run{'s' if len(runs) > 1 else ''}, "
                            f"fewer than {jobs} workers (a pool has no more workers than runs: nothing to compare); "
                            f"add scenarios or backends{smaller}")  # fmt: skip
    batch: list[tuple[Scenario, str | None, Path | None]] = [(sc, None, None) for sc in scenarios]
    say = progress or (lambda _line: None)
    with _barriers() as barriers:
        w_warm = warm_up(batch, backend_names, jobs, barriers, probe_s)
        probe, passes, share = probe_runs(scenarios, backend_names, w_warm, probe_s)
        res = ScalingResult(
            jobs=jobs,
            runs=[f"{sc.name}/{b}" for sc, b in runs],
            probe=(
                f"every run of the batch cut to {100 * share:.0f} % of its duration (at least {PROBE_MIN_S:g} s)"
                if share < 1
                else f"every run of the batch, whole, {passes} time{'s' if passes > 1 else ''}"
            ),
            wall_warmup=w_warm,
        )
        say(f"warm-up: the batch of {len(runs)} runs took {w_warm:.2f} s with jobs 1; probe: {res.probe}")
        warm = _warm_runs(runs)
        alone: tuple[float, float] = (math.nan, math.nan)
        together: list[tuple[float, float]] = []
        serial = math.nan
        pt = PoolTiming(math.nan, math.nan, math.nan, 0)
        for rep in range(repeats):
            steps = ["alone", "together", "serial", "pool"]
            if rep % 2:
                steps.reverse()
            done: list[str] = []
            for step in steps:
                if step == "alone":
                    alone = ceiling_sample(probe, 1, passes)[0]
                    done.append("probe alone")
                elif step == "together":
                    together = ceiling_sample(probe, jobs, passes)
                    done.append(f"probe {jobs} together")
                elif step == "serial":
                    serial = time_serial(batch, backend_names)
                    done.append("batch jobs 1")
                else:
                    pt = time_pool(batch, backend_names, jobs, warm, barriers)
                    done.append(f"batch jobs {jobs}")
            res.order.append(done)
            res.probe_cpu_alone.append(alone[0])
            res.probe_wall_alone.append(alone[1])
            res.probe_cpu_together.append([c for c, _ in together])
            res.probe_wall_together.append([w for _, w in together])
            res.wall_serial.append(serial)
            res.wall_parallel.append(pt.wall)
            res.pool_ready.append(pt.ready)
            res.pool_startup.append(pt.startup)
            res.workers.append(pt.workers)
            i = len(res.wall_serial) - 1
            say(f"repeat {rep + 1}/{repeats} ({', '.join(done)}): probe alone {alone[1]:.2f} s wall ({alone[0]:.2f} s "
                f"CPU), {jobs} together {', '.join(f'{w:.2f}' for _, w in together)} s wall: ceiling "
                f"{res.ceiling_wall().values[i]:.2f} (by CPU {res.ceiling_cpu().values[i]:.2f})")  # fmt: skip
            say(f"repeat {rep + 1}/{repeats}: batch jobs 1 {serial:.2f} s, jobs {jobs} {pt.wall:.2f} s + start-up "
                f"{pt.startup:.2f} s ({pt.workers} workers): {res.speedup().values[i]:.2f}x, "
                f"{res.speedup_with_startup().values[i]:.2f}x with start-up")  # fmt: skip
    res.warnings = _warnings(res)
    for w in res.warnings:
        logger.warning("legbench: warning: %s", w)
    return res


def _warnings(res: ScalingResult) -> list[str]:
    """What makes the figures of ``res`` weak: a short batch, a batch not much longer than the pool's
    start-up, fewer workers than asked for."""
    out = []
    serial, parallel = Sample(tuple(res.wall_serial)).median, Sample(tuple(res.wall_parallel)).median
    startup = Sample(tuple(res.pool_startup)).median
    if serial < MIN_BATCH_S:
        out.append(f"bench --parallel: the batch takes {serial:.2f} s with jobs 1, under {MIN_BATCH_S:g} s: fixed "
                   "costs and scheduling noise weigh on its ratios; lengthen it (--duration, more scenarios or "
                   "backends)")  # fmt: skip
    if parallel < STARTUP_FACTOR * startup:
        out.append(f"bench --parallel: the batch takes {parallel:.2f} s with jobs {res.jobs}, under "
                   f"{STARTUP_FACTOR:g} times the pool's start-up ({startup:.2f} s): the speed-up with start-up "
                   "measures mostly the start-up; lengthen the batch")  # fmt: skip
    fewer = sorted({w for w in res.workers if w < res.jobs})
    if fewer:
        out.append(f"bench --parallel: the pool ran with {', '.join(map(str, fewer))} worker processes, not "
                   f"{res.jobs}")  # fmt: skip
    return out


def markdown(res: ScalingResult, meta: Mapping[str, Any]) -> str:
    """The tables docs/performance.md quotes."""
    n = res.jobs
    m = meta.get("machine", {})
    lines = [
        f"### `--jobs {n}` against `--jobs 1`, and this machine's ceiling",
        "",
        f"Command: `{meta.get('command', 'legbench bench --parallel')}`  ",
        f"Machine: {m.get('cpu_model', '?')}, {m.get('cpus_usable', '?')} usable CPUs, load average "
        f"{', '.join(f'{x:.2f}' for x in (m.get('load_average') or []))} at the end.  ",
        f"Batch: {len(res.runs)} runs ({', '.join(res.runs)}), logs in memory; pool of {n} "
        f"({', '.join(map(str, sorted(set(res.workers))))} worker processes answered); {len(res.wall_serial)} "
        f"repeats, the order reversed every other one, median [min-max].  ",
        f"Probe: {res.probe}.",
        "",
        *[f"**Warning:** {w}.  " for w in res.warnings],
        *([""] if res.warnings else []),
        "| figure | value |",
        "|---|---|",
        f"| batch wall, jobs 1 [s] | {Sample(tuple(res.wall_serial)).cell()} |",
        f"| batch wall, jobs {n}, pool started and warm [s] | {Sample(tuple(res.wall_parallel)).cell()} |",
        f"| pool start-up: workers imported [s] | {Sample(tuple(res.pool_ready)).cell('.3f')} |",
        f"| pool start-up: workers warmed up [s] | {Sample(tuple(res.pool_startup)).cell('.3f')} |",
        f"| **speed-up** jobs 1 / jobs {n} | **{res.speedup().cell()}** |",
        f"| speed-up with the pool's start-up | {res.speedup_with_startup().cell()} |",
        f"| probe alone, wall [s] | {Sample(tuple(res.probe_wall_alone)).cell()} |",
        f"| probe, {n} at once, wall per process [s] | "
        f"{Sample(tuple(_mean(t) for t in res.probe_wall_together)).cell()} |",
        f"| **ceiling** N x wall alone / wall together | **{res.ceiling_wall().cell()}** |",
        f"| ceiling by CPU time (shared hardware only) | {res.ceiling_cpu().cell()} |",
        f"| **efficiency** speed-up / ceiling | **{res.efficiency().cell()}** |",
        f"| efficiency with the pool's start-up | {res.efficiency_with_startup().cell()} |",
        "",
    ]
    return "\n".join(lines)


def write_scaling(res: ScalingResult, out_dir: Path, meta: Mapping[str, Any]) -> tuple[Path, Path]:
    """``scaling.json`` (every sample, the figures, the machine) and ``scaling.md`` into ``out_dir``."""
    out_dir.mkdir(parents=True, exist_ok=True)
    named = (("speedup", res.speedup()), ("speedup_with_startup", res.speedup_with_startup()),
             ("ceiling_wall", res.ceiling_wall()), ("ceiling_cpu", res.ceiling_cpu()),
             ("efficiency", res.efficiency()), ("efficiency_with_startup", res.efficiency_with_startup()))  # fmt: skip
    figures = {k: {"median": s.median, "min": min(s.values), "max": max(s.values), "values": list(s.values)}
               for k, s in named}  # fmt: skip
    js = out_dir / "scaling.json"
    write_json({**meta, "samples": asdict(res), "figures": figures}, js)
    md = out_dir / "scaling.md"
    atomic_write_text(md, markdown(res, meta))
    return js, md
