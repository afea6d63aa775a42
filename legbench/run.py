"""The run loop: owns the clock, the controllers and the log; drives any backend.

At each control tick k (t = k Ts) the loop reads the backend's state, fires the
events due (an event with a ``delay`` at its tick round((t + delay) / Ts), the
previous controller running until then), computes the active controller's torque, saturates it at the joint
limits, logs the tick into preallocated arrays, and steps the backend one
control period under that torque (zero-order hold). Row k of the log holds the
state and ground force at t_k and the torque applied over [t_k, t_k + Ts).
"""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from legbench import backends as registry
from legbench.backends.base import Backend, Physics
from legbench.controllers import Controller, make_controller
from legbench.exceptions import BackendNotFound, LegbenchError, SimulationDiverged
from legbench.model import load_params
from legbench.results import RunResult, check_out_dir, resumable, write_run
from legbench.scenario import Scenario, physics_of
from legbench.studies.executors import LocalExecutor

#: Divergence bounds no physical run of this leg reaches: joint speed [rad/s] (20x the hip's
#: speed limit) and foot penetration [m] (5 cm is 500 N at Kp = 1e4 N/m; the leg pushes <= 100 N).
MAX_JOINT_SPEED = 1.0e3
MAX_PENETRATION = 0.05


def simulate(
    scenario: Scenario,
    backend: Backend,
    physics: Physics,
    progress: Callable[[float], None] | None = None,
) -> RunResult:
    """Run one scenario on one loaded-and-ready backend; a divergence ends the log early, marked failed.

    The loop is the benchmark's "full run" (``legbench bench``); per tick it
    does only what a tick needs, on plain floats: read the state, check it,
    fire due events, compute and saturate the torque, write one row of each
    preallocated log array, step. The torque handed to :meth:`Backend.step` is
    a read-only view of the logged row, so what is logged is what the backend
    received. Nothing is allocated per tick beyond the backend's own state
    arrays and the controller's three floats; memory is the log itself.

    Args:
        scenario: the task (duration, control rate, events, gains, initial state).
        backend: a backend already :meth:`~Backend.load`-ed with ``physics``.
        physics: the physics the backend was loaded with (torque limits [N m]).
        progress: called with the fraction done (0..1) about 50 times per run.

    Returns:
        The log; ``status`` ``failed`` (divergence or an engine error) or
        ``interrupted`` (Ctrl-C) with the rows up to that tick.
    """
    n = scenario.n_ticks
    Ts = scenario.control_dt
    lim1, lim2, lim3 = (float(x) for x in physics.torque_limit)
    g = load_params().geometry
    L_12, L_23, L_3E, H = g.L_12, g.L_23, g.L_3E, g.H
    z_min = g.R_foot - MAX_PENETRATION  # lowest foot-centre height before we call it diverged [m]
    v_max = MAX_JOINT_SPEED
    t = np.arange(n) * Ts
    q_log = np.full((n, 3), np.nan)
    qd_log = np.full((n, 3), np.nan)
    tau_log = np.full((n, 3), np.nan)
    f_log = np.full((n, 3), np.nan)
    tau_out = tau_log.view()
    tau_out.flags.writeable = False  # the backend gets read-only rows of the log
    ticks = [int(round(e.t_switch / Ts)) for e in scenario.events]  # a delayed event switches late
    names = [e.controller for e in scenario.events]
    controllers: list[Controller] = [make_controller(e, scenario.gains, Ts, n) for e in scenario.events]
    backend.reset(np.array(scenario.q0), np.array(scenario.qd0))
    state, ground_force, step = backend.state, backend.ground_force, backend.step
    sin, cos, isfinite = math.sin, math.cos, math.isfinite
    torque = controllers[0].torque
    next_event, n_events = 0, len(ticks)
    next_tick = ticks[0]
    status, reason, k = "ok", None, 0
    every = max(n // 50, 1)
    last = n - 1
    start = time.perf_counter()
    try:
        for k in range(n):
            q, qd = state()
            f = ground_force()
            q1, q2, q3 = q.tolist()
            qd1, qd2, qd3 = qd.tolist()
            f1, f2, f3 = f.tolist()
            if not isfinite(q1 + q2 + q3 + qd1 + qd2 + qd3 + f1 + f2 + f3):
                raise SimulationDiverged(backend.name, k * Ts, "state is not finite")
            if abs(qd1) > v_max or abs(qd2) > v_max or abs(qd3) > v_max:
                raise SimulationDiverged(backend.name, k * Ts, f"joint speed above {MAX_JOINT_SPEED} rad/s")
            if L_12 * sin(q1) + cos(q1) * (L_23 * sin(q2) + L_3E * sin(q2 + q3)) + H < z_min:  # foot-centre height z_W
                raise SimulationDiverged(backend.name, k * Ts, f"foot more than {MAX_PENETRATION} m into the ground")
            if k >= next_tick:
                while next_event < n_events and ticks[next_event] <= k:
                    active = controllers[next_event]
                    active.start(k * Ts, q, qd)
                    torque = active.torque
                    next_event += 1
                next_tick = ticks[next_event] if next_event < n_events else n
            u1, u2, u3 = torque(k, q1, q2, q3, qd1, qd2, qd3)
            # saturate at +-limit (as np.clip: NaN passes through)
            u1 = -lim1 if u1 < -lim1 else (lim1 if u1 > lim1 else u1)
            u2 = -lim2 if u2 < -lim2 else (lim2 if u2 > lim2 else u2)
            u3 = -lim3 if u3 < -lim3 else (lim3 if u3 > lim3 else u3)
            q_log[k] = q
            qd_log[k] = qd
            f_log[k] = f
            tau_log[k] = (u1, u2, u3)
            if k < last:
                step(tau_out[k])
            if progress is not None and k % every == 0:
                progress(k / n)
    except SimulationDiverged as exc:
        status, reason = "failed", str(exc)
        n = k
    except (LegbenchError, FloatingPointError, RuntimeError, ValueError) as exc:
        status, reason = "failed", f"{type(exc).__name__} at t = {k * Ts:.4f} s: {exc}"
        n = k
    except KeyboardInterrupt:
        status, reason = "interrupted", f"interrupted at t = {k * Ts:.4f} s"
        n = k
    wall = time.perf_counter() - start
    # active controller per logged tick: each event's from its tick on (ticks are sorted), filled
    # slice by slice so no per-tick index array is allocated next to the log
    controller = np.empty(n, dtype=object)
    for tick, name in zip(ticks, names, strict=True):
        controller[min(tick, n) :] = name
    return RunResult(
        backend=backend.name,
        t=t[:n] if status != "ok" else t,
        q=q_log[:n] if status != "ok" else q_log,
        qd=qd_log[:n] if status != "ok" else qd_log,
        tau=tau_log[:n] if status != "ok" else tau_log,
        f=f_log[:n] if status != "ok" else f_log,
        controller=controller,
        status=status,
        reason=reason,
        info=backend_info(backend),
        wall_time=wall,
    )


def backend_info(backend: Backend) -> dict[str, Any]:
    """What run.json records of a backend: its :meth:`~Backend.info`, the ``profile`` it was loaded with,
    its declared ``integrator_family`` and ``sub_steps`` (what verification predicts by), and its
    :meth:`~Backend.warnings` after the run (e.g. a sub-step too coarse for the contact law)."""
    return {**backend.info(), "profile": backend.profile, "integrator_family": backend.integrator_family(),
            "sub_steps": backend.sub_steps(), "warnings": backend.warnings()}  # fmt: skip


def run_backend(scenario: Scenario, name: str, contact_mode: str | None = None, progress: bool = False) -> RunResult:
    """Load ``name``, run the scenario, close; any failure is returned as a failed result."""
    physics = physics_of(scenario, contact_mode)
    try:
        backend = registry.load(name, physics, scenario.backends.get(name, {}), scenario.profile)
    except BackendNotFound as exc:
        return RunResult.empty(name, "missing", str(exc))
    except Exception as exc:  # an engine that cannot load must not stop the others
        return RunResult.empty(name, "failed", f"load failed: {type(exc).__name__}: {exc}")
    bar = _ProgressBar(f"{scenario.name}/{name}") if progress else None
    try:
        return simulate(scenario, backend, physics, bar)
    finally:
        if bar is not None:
            bar.done()
        backend.close()


class _ProgressBar:
    """A one-line progress bar on stderr, only on a terminal."""

    def __init__(self, label: str) -> None:
        self.label = label
        self.tty = sys.stderr.isatty()

    def __call__(self, frac: float) -> None:
        if self.tty:
            filled = int(30 * frac)
            sys.stderr.write(f"\r{self.label:<28} [{'#' * filled}{'.' * (30 - filled)}] {100 * frac:5.1f} %")
            sys.stderr.flush()

    def done(self) -> None:
        if self.tty:
            sys.stderr.write("\r" + " " * 75 + "\r")
            sys.stderr.flush()


def _task(args: tuple[Scenario, str, str | None, bool]) -> RunResult:
    scenario, name, mode, progress = args
    return run_backend(scenario, name, mode, progress)


def run_many(
    jobs_list: Sequence[tuple[Scenario, str | None, Path | None]],
    backend_names: Sequence[str],
    jobs: int = 1,
    csv: bool = False,
    progress: bool = True,
) -> list[list[RunResult]]:
    """Run several (scenario, contact mode, output dir) on every backend, in ``jobs`` processes.

    Each (scenario, mode, backend) is one task; results are collected in input
    order, so the output is the same (bit-identical logs) for any ``jobs``. A
    failing backend is logged up to its failure and the others still run. On
    Ctrl-C (or SIGTERM turned into KeyboardInterrupt by the CLI) what was
    simulated is written, marked incomplete, and the interrupt re-raised; a
    rerun into the same directories runs only the backends that did not finish.
    """
    plan: list[tuple[int, Scenario, str, str | None]] = []
    kept: list[dict[str, Any]] = []
    for i, (sc, mode, out) in enumerate(jobs_list):
        done: dict[str, Any] = {}
        if out is not None:
            check_out_dir(sc, out)
            done = {k: v for k, v in resumable(sc, out, mode).items() if k in backend_names}
        kept.append(done)
        plan += [(i, sc, name, mode) for name in backend_names if name not in done]
    results: list[list[RunResult]] = [[] for _ in jobs_list]
    interrupted = False
    # longest runs first, so the pool does not wait on one long run at the end; results are
    # still collected in plan order, so the output does not depend on ``jobs``
    first = sorted(range(len(plan)), key=lambda j: -plan[j][1].duration)
    tasks = [(sc, name, mode, progress and jobs <= 1) for _, sc, name, mode in plan]
    with LocalExecutor(max(jobs, 1)) as pool:
        try:
            for (i, *_), tr in zip(plan, pool.imap(_task, tasks, first), strict=False):
                results[i].append(tr)
                if tr.status == "interrupted":
                    interrupted = True
                    break
        except KeyboardInterrupt:
            interrupted = True
    for (sc, mode, out), res, done in zip(jobs_list, results, kept, strict=True):
        if out is not None and (res or done):
            if interrupted and len(res) + len(done) < len(backend_names):
                res = [*res, *_not_run(sc, backend_names, res, done)]
            write_run(sc, res, out, csv, mode, done)
    if interrupted:
        raise KeyboardInterrupt
    return results


def _not_run(sc: Scenario, names: Sequence[str], res: Sequence[RunResult], done: Mapping[str, Any]) -> list[RunResult]:
    """Placeholders for backends an interrupt stopped before they started."""
    have = {tr.backend for tr in res} | set(done)
    return [RunResult.empty(n, "interrupted", "interrupted before it started") for n in names if n not in have]


def run(scenario: Scenario, backend_names: Sequence[str], out_dir: Path | None, csv: bool = False,
        contact_mode: str | None = None, progress: bool = True, jobs: int = 1) -> list[RunResult]:  # fmt: skip
    """Run one scenario on every named backend and write the results into ``out_dir`` (see :func:`run_many`)."""
    return run_many([(scenario, contact_mode, out_dir)], backend_names, jobs, csv, progress)[0]
