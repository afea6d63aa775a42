"""``legbench bench --parallel N``: how close ``--jobs N`` comes to N-fold, against this machine's own ceiling.

Two things are measured side by side, interleaved repeat by repeat (each repeat does both, in an
order rotated from one repeat to the next, so a load drift hits both alike):

* **throughput**: the same batch of runs (every scenario x backend asked for, logs kept in memory,
  nothing written) through :func:`legbench.run.run_many` with ``jobs = 1`` (in this process) and with
  ``jobs = N`` (the process pool, started afresh as a ``legbench run --jobs N`` starts it: its
  start-up is part of the figure). ``speed-up = wall(1) / wall(N)``.
* **ceiling**: what N processes can get out of this machine at all. One run of the first scenario
  on the first backend (the *probe*), loaded in N fresh processes that then start it together (they
  wait at a barrier: an event, not a sleep), against the same probe in one process alone.
  ``ceiling = N x cpu(alone) / mean cpu(together)``: on N independent idle cores it is N; where
  the "cores" share an execution unit or a memory path (SMT siblings, a VM's vCPUs on one host
  core) each process's own CPU time grows and the ceiling drops below N. CPU time, not wall time,
  because other processes' load only delays a process (wall) while shared hardware slows it
  (CPU); the wall-time ceiling is given beside it.

``efficiency = speed-up / ceiling`` is legbench's share of what the machine allows: the pool's
start-up, the serial parts (pre-flight, result transfer) and the tail of the longest run.
"""

from __future__ import annotations

import multiprocessing
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from legbench import backends as registry
from legbench.exceptions import LegbenchError
from legbench.results import atomic_write_text, write_json
from legbench.run import run_many, simulate
from legbench.scenario import Scenario, physics_of, shorten

__all__ = ["ScalingResult", "ceiling_sample", "run_scaling", "markdown", "write_scaling"]


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


@dataclass
class ScalingResult:
    """Every sample of one ``--parallel N`` study [s, or 1 for ratios]."""

    jobs: int
    runs: list[str]
    probe: str
    wall_serial: list[float] = field(default_factory=list)  # the batch with jobs = 1 [s]
    wall_parallel: list[float] = field(default_factory=list)  # the batch with jobs = N [s]
    probe_cpu_alone: list[float] = field(default_factory=list)  # [s]
    probe_wall_alone: list[float] = field(default_factory=list)
    probe_cpu_together: list[list[float]] = field(default_factory=list)  # per repeat, per process [s]
    probe_wall_together: list[list[float]] = field(default_factory=list)

    def speedup(self) -> Sample:
        return Sample(tuple(a / b for a, b in zip(self.wall_serial, self.wall_parallel, strict=True)))

    def ceiling_cpu(self) -> Sample:
        n = self.jobs
        return Sample(tuple(n * a / (sum(t) / len(t)) for a, t in
                            zip(self.probe_cpu_alone, self.probe_cpu_together, strict=True)))  # fmt: skip

    def ceiling_wall(self) -> Sample:
        n = self.jobs
        pairs = zip(self.probe_wall_alone, self.probe_wall_together, strict=True)
        return Sample(tuple(n * a / max(t) for a, t in pairs))

    def efficiency(self) -> Sample:
        """speed-up / CPU-time ceiling, per repeat."""
        s, c = self.speedup().values, self.ceiling_cpu().values
        return Sample(tuple(a / b for a, b in zip(s, c, strict=True)))


# --------------------------------------------------------------------------- #
# The ceiling: the probe alone, then N copies at once


#: The probe repeats its run until it has used this much CPU time [s], so a short run still gives a steady figure.
PROBE_CPU = 2.0


def _probe(sc: Scenario, name: str, barrier: Any, out: Any, probe_cpu: float) -> None:
    """In a fresh process: load the backend, run 10 ms (first-step allocations), wait for the others, then
    repeat the run until ``probe_cpu`` [s] of CPU time is used; put (CPU, wall) per run [s] and the status."""
    physics = physics_of(sc)
    backend = registry.load(name, physics, sc.backends.get(name, {}), sc.profile)
    try:
        simulate(shorten(sc, 0.01), backend, physics)
        barrier.wait()
        c0, w0 = time.process_time(), time.perf_counter()
        n, status = 0, "ok"
        while status == "ok" and (n == 0 or time.process_time() - c0 < probe_cpu):
            status = simulate(sc, backend, physics).status
            n += 1
        out.put(((time.process_time() - c0) / n, (time.perf_counter() - w0) / n, status))
    finally:
        backend.close()


def ceiling_sample(
    sc: Scenario, name: str, n: int, probe_cpu: float = PROBE_CPU, timeout: float = 600.0
) -> list[tuple[float, float]]:
    """(CPU, wall) time per probe run [s] in each of ``n`` fresh processes started together at a barrier."""
    ctx = multiprocessing.get_context("spawn")
    barrier, out = ctx.Barrier(n), ctx.Queue()
    procs = [ctx.Process(target=_probe, args=(sc, name, barrier, out, probe_cpu), daemon=True) for _ in range(n)]
    for p in procs:
        p.start()
    got = []
    try:
        for _ in range(n):
            cpu, wall, status = out.get(timeout=timeout)
            if status != "ok":
                raise LegbenchError(f"bench --parallel: the probe run on {name} ended {status}")
            got.append((cpu, wall))
    finally:
        for p in procs:
            p.join(5.0)
            if p.is_alive():
                p.kill()
    return got


# --------------------------------------------------------------------------- #
# The study


def run_scaling(
    scenarios: Sequence[Scenario],
    backend_names: Sequence[str],
    jobs: int = 2,
    repeats: int = 3,
    progress: Callable[[str], None] | None = None,
    probe_cpu: float = PROBE_CPU,
) -> ScalingResult:
    """Throughput of the batch (every scenario x backend) with 1 and ``jobs`` workers, and the machine's ceiling.

    Args:
        scenarios: the runs' scenarios (the first one, on the first backend, is the ceiling's probe).
        backend_names: backends, each run on every scenario.
        jobs: N, the worker count compared with 1 (>= 2).
        repeats: interleaved repeats (>= 1).
        progress: called with one line per measurement.
        probe_cpu: CPU time [s] each probe process spends repeating its run (:data:`PROBE_CPU`).
    """
    if jobs < 2:
        raise LegbenchError(f"bench: --parallel must be at least 2, got {jobs}")
    if repeats < 1:
        raise LegbenchError(f"bench: --repeats must be at least 1, got {repeats}")
    if not scenarios or not backend_names:
        raise LegbenchError("bench --parallel: no scenario or no backend to run")
    batch = [(sc, None, None) for sc in scenarios]
    res = ScalingResult(
        jobs=jobs,
        runs=[f"{sc.name}/{b}" for sc in scenarios for b in backend_names],
        probe=f"{scenarios[0].name}/{backend_names[0]}",
    )
    say = progress or (lambda _line: None)

    def batch_wall(n: int) -> float:
        w0 = time.perf_counter()
        results = run_many(batch, backend_names, jobs=n, progress=False)
        wall = time.perf_counter() - w0
        bad = [tr.backend for rs in results for tr in rs if tr.status != "ok"]
        if bad:
            raise LegbenchError(f"bench --parallel: runs failed on {', '.join(sorted(set(bad)))}")
        return wall

    def ceiling(n: int) -> None:
        alone = ceiling_sample(scenarios[0], backend_names[0], 1, probe_cpu)[0]
        together = ceiling_sample(scenarios[0], backend_names[0], n, probe_cpu)
        res.probe_cpu_alone.append(alone[0])
        res.probe_wall_alone.append(alone[1])
        res.probe_cpu_together.append([c for c, _ in together])
        res.probe_wall_together.append([w for _, w in together])
        say(f"probe {res.probe}: alone {alone[0]:.2f} s CPU; {n} together "
            + ", ".join(f"{c:.2f}" for c, _ in together) + " s CPU")  # fmt: skip

    def throughput() -> None:
        w1 = batch_wall(1)
        wn = batch_wall(jobs)
        res.wall_serial.append(w1)
        res.wall_parallel.append(wn)
        say(f"batch of {len(res.runs)} runs: jobs 1 {w1:.2f} s, jobs {jobs} {wn:.2f} s wall ({w1 / wn:.2f}x)")

    batch_wall(1)  # warm-up: imports, caches (e.g. generated code) in this process; not timed
    for rep in range(repeats):
        steps = [ceiling, throughput] if rep % 2 == 0 else [throughput, ceiling]
        for step in steps:
            step(jobs) if step is ceiling else step()  # type: ignore[operator]
    return res


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
        f"Batch: {len(res.runs)} runs ({', '.join(res.runs)}), logs in memory; {len(res.wall_serial)} interleaved "
        f"repeats, median [min-max].",
        "",
        "| figure | value |",
        "|---|---|",
        f"| batch wall, jobs 1 [s] | {Sample(tuple(res.wall_serial)).cell()} |",
        f"| batch wall, jobs {n} [s] | {Sample(tuple(res.wall_parallel)).cell()} |",
        f"| **speed-up** jobs 1 / jobs {n} | **{res.speedup().cell()}** |",
        f"| probe {res.probe} alone, CPU [s] | {Sample(tuple(res.probe_cpu_alone)).cell()} |",
        f"| probe, {n} at once, CPU per process [s] | "
        f"{Sample(tuple(sum(t) / len(t) for t in res.probe_cpu_together)).cell()} |",
        f"| **ceiling** N x CPU alone / CPU together | **{res.ceiling_cpu().cell()}** |",
        f"| ceiling by wall time | {res.ceiling_wall().cell()} |",
        f"| **efficiency** speed-up / ceiling | **{res.efficiency().cell()}** |",
        "",
    ]
    return "\n".join(lines)


def write_scaling(res: ScalingResult, out_dir: Path, meta: Mapping[str, Any]) -> tuple[Path, Path]:
    """``scaling.json`` (every sample, the figures, the machine) and ``scaling.md`` into ``out_dir``."""
    out_dir.mkdir(parents=True, exist_ok=True)
    figures = {k: {"median": s.median, "min": min(s.values), "max": max(s.values), "values": list(s.values)}
               for k, s in (("speedup", res.speedup()), ("ceiling_cpu", res.ceiling_cpu()),
                            ("ceiling_wall", res.ceiling_wall()), ("efficiency", res.efficiency()))}  # fmt: skip
    js = out_dir / "scaling.json"
    write_json({**meta, "samples": asdict(res), "figures": figures}, js)
    md = out_dir / "scaling.md"
    atomic_write_text(md, markdown(res, meta))
    return js, md
