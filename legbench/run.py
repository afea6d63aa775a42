"""The run loop: owns the clock, the controllers and the log; drives any backend.

At each control tick k (t = k Ts) the loop reads the backend's state, fires the
events due (an event with a ``delay`` at its tick round((t + delay) / Ts), the
previous controller running until then), computes the active controller's torque, saturates it at the joint
limits, logs the tick into preallocated arrays, and steps the backend one
control period under that torque (zero-order hold). Row k of the log holds the
state at t_k, the ground force as the backend reads it at t_k, and the torque applied over [t_k, t_k + Ts).

That force is each backend's own read-out (run.json info, ``contact.force_readout`` where a backend names it):
the law at the state (Pinocchio, the symbolic model, every backend in reference contact), an engine's constraint
force at that state (MuJoCo's default), the last sub-step's impulse over its length (ODE, PyBullet, Drake's discrete
plant, DART's default), or the period's mean (about half a period behind; MuJoCo and DART with ``force_readout:
mean``): the same in steady contact, up to a sub-step or half a period apart in an impact. Row 0's is the reset
state's: an engine whose force is a step's impulse reads 0 there even where the foot starts in contact (no
bundled task does), where the law's backends read the law.
"""

from __future__ import annotations

import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from concurrent.futures import BrokenExecutor
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

from legbench import backends as registry
from legbench import progress as progress_mod
from legbench.backends.base import Backend, Physics, declared_problem, info_problem
from legbench.contact import friction_chatter
from legbench.controllers import Controller, make_controller
from legbench.exceptions import BackendNotFound, LegbenchError, SimulationDiverged
from legbench.model import load_params
from legbench.results import (
    CHECK_OUTPUTS,
    RunResult,
    check_index_pages,
    check_out_dir,
    check_out_tree,
    read_meta,
    replaced_by_run,
    resumable,
    run_dirs,
    write_run,
)
from legbench.scenario import MAX_JOINT_SPEED, MAX_PENETRATION, Scenario, physics_of
from legbench.studies.executors import DEFAULT_PRELOAD, TASK_PRELOAD, LocalExecutor, capped
from legbench.yamlfile import one_line


def _diverged(code: int) -> str:
    """Why the run stopped, for a :func:`legbench.tick.control_tick` code."""
    from legbench import tick

    return {
        tick.NOT_FINITE: "state or ground force is not finite",
        tick.TOO_FAST: f"joint speed above {MAX_JOINT_SPEED} rad/s",
        tick.TOO_DEEP: f"foot more than {MAX_PENETRATION} m into the ground",
    }[code]


def simulate(
    scenario: Scenario,
    backend: Backend,
    physics: Physics,
    progress: Callable[[float], None] | None = None,
    keep_interrupted: bool = False,
) -> RunResult:
    """Run one scenario on one loaded-and-ready backend; a divergence ends the log early, marked failed.

    The loop is the benchmark's "full run" (``legbench bench``); per tick it
    reads the state and force (:meth:`Backend.read`, nine floats), fires due
    events, and makes one compiled call (:func:`legbench.tick.tick`) that checks
    the state, evaluates the active controller's law, saturates the torque and
    writes the tick's row of the preallocated (n, 12) log (q, qd, f, tau: the
    four logs are column views of it); then it steps. The torque handed to
    :meth:`Backend.step` is a read-only array the tick fills with the logged
    row's torque, so what is logged is what the backend received. Nothing is allocated per tick beyond
    the floats read; memory is the log itself.

    Args:
        scenario: the task (duration, control rate, events, gains, initial state).
        backend: a backend already :meth:`~Backend.load`-ed with ``physics``.
        physics: the physics the backend was loaded with (torque limits [N m]).
        progress: called with the fraction done (0..1) about 50 times per run.
        keep_interrupted: on Ctrl-C (SIGTERM: the CLI's handler raises the same), return the rows up to that
            tick marked ``interrupted`` (a run directory keeps them and resumes); False (the studies, which
            keep nothing of an interrupted study): the KeyboardInterrupt propagates, so an interrupt is never
            read as the engine's failure.

    Returns:
        The log; ``status`` ``failed`` (divergence or an engine error) or
        ``interrupted`` (Ctrl-C, with ``keep_interrupted``) with the rows up to that tick.

    Raises:
        KeyboardInterrupt: interrupted, without ``keep_interrupted``.
    """
    from legbench import tick  # numba: imported by the process that runs, not by every command

    n = scenario.n_ticks
    Ts = scenario.control_dt
    g = load_params().geometry
    # lowest foot-centre height before we call it diverged [m]
    consts = tick.constants(physics.torque_limit, g, g.R_foot - MAX_PENETRATION, MAX_JOINT_SPEED)
    t = np.arange(n) * Ts
    # one (n, 12) block, row k = (q, qd, f, tau) of tick k, written by the compiled tick; the four logs are
    # column views of it (no copy)
    log = np.full((n, 12), np.nan)
    q_log, qd_log, f_log, tau_log = log[:, 0:3], log[:, 3:6], log[:, 6:9], log[:, 9:12]
    # the tick writes each torque into the log row and into u; the backend gets a read-only view of u,
    # made once (a per-tick view of the log row would cost more than the tick's own arithmetic)
    u = np.zeros(3)
    tau_out = u.view()
    tau_out.flags.writeable = False
    ticks = [int(round(e.t_switch / Ts)) for e in scenario.events]  # a delayed event switches late
    names = [e.controller for e in scenario.events]
    controllers: list[Controller] = [
        make_controller(e, scenario.gains, Ts, n, scenario.gravity) for e in scenario.events
    ]
    read, step, control = backend.read, backend.step, tick.tick
    active = controllers[0]
    p, s = active.params, active.state
    next_event, n_events = 0, len(ticks)
    next_tick = ticks[0]
    status, reason, k = "ok", None, 0
    every = max(n // 50, 1)
    last = n - 1
    # the tick's compiled code loads (numba's cache, ~0.3 s once per process) on its first call: made here on
    # scratch copies, before the clock, so the first backend a process runs is not charged for it in wall_time
    (a1, a2, a3), (v1, v2, v3) = (float(x) for x in scenario.q0), (float(x) for x in scenario.qd0)
    control(0, a1, a2, a3, v1, v2, v3, 0.0, 0.0, 0.0, p.copy(), s.copy(), consts, np.full((1, 12), np.nan), np.zeros(3))
    for c in controllers:  # what their start() imports (a trajectory's scipy.interpolate), before the clock too
        c.prepare()
    start = time.perf_counter()
    try:
        try:
            backend.reset(np.array(scenario.q0), np.array(scenario.qd0))
        except Exception as exc:
            raise _EngineError(exc) from exc
        start = time.perf_counter()  # the loop's wall time: the reset is not part of it
        for k in range(n):
            try:  # the engine's calls: any error of theirs fails this backend alone (a try costs nothing here)
                q1, q2, q3, qd1, qd2, qd3, f1, f2, f3 = read()
            except Exception as exc:
                raise _EngineError(exc) from exc
            if k >= next_tick:
                q, qd = np.array((q1, q2, q3)), np.array((qd1, qd2, qd3))
                while next_event < n_events and ticks[next_event] <= k:
                    active = controllers[next_event]
                    active.start(k * Ts, q, qd)
                    next_event += 1
                p, s = active.params, active.state
                next_tick = ticks[next_event] if next_event < n_events else n
            try:
                code = control(k, q1, q2, q3, qd1, qd2, qd3, f1, f2, f3, p, s, consts, log, u)
            except Exception as exc:  # the engine's read gave what the tick cannot take (an array, a None)?
                read_values = (q1, q2, q3, qd1, qd2, qd3, f1, f2, f3)
                if any(type(x) is not float for x in read_values):
                    kinds = ", ".join(sorted({type(x).__name__ for x in read_values}))
                    raise _EngineError(TypeError(f"read() returned {kinds}, not nine floats")) from exc
                raise  # the harness's own error: a bug, not the engine's
            if code:
                raise SimulationDiverged(backend.name, k * Ts, _diverged(code))
            if k < last:
                try:
                    step(tau_out)
                except Exception as exc:
                    raise _EngineError(exc, logged=True) from exc
            if progress is not None and k % every == 0:
                progress(k / n)
    except SimulationDiverged as exc:
        status, reason = "failed", str(exc)
        n = k
    except (_EngineError, LegbenchError, FloatingPointError, RuntimeError, ValueError) as exc:
        # the engine's own errors, whatever their type (a plug-in's TypeError too), and the failures a run may
        # meet in the harness (an unreachable target, a non-finite state); any other error of legbench's own
        # code propagates, a bug, not a failed engine
        cause = exc.cause if isinstance(exc, _EngineError) else exc
        if isinstance(cause, SimulationDiverged):  # the engine's own divergence check: its message says it all
            status, reason = "failed", one_line(str(cause))
        else:
            status, reason = "failed", one_line(f"{type(cause).__name__} at t = {k * Ts:.4f} s: {cause}")
        n = k + 1 if isinstance(exc, _EngineError) and exc.logged else k  # the state read at t_k is the log's
    except KeyboardInterrupt:
        if not keep_interrupted:
            raise
        status, reason = "interrupted", f"interrupted at t = {k * Ts:.4f} s"
        n = k
    wall = time.perf_counter() - start
    # active controller per logged tick: each event's from its tick on (ticks are sorted), filled
    # slice by slice so no per-tick index array is allocated next to the log
    controller = np.empty(n, dtype=object)
    for first, name in zip(ticks, names, strict=True):
        controller[min(first, n) :] = name
    try:
        info = backend_info(backend)
    except Exception as exc:  # the run is kept up to here, but a backend that cannot say what it ran failed
        info = _declared(backend)
        if status == "ok":
            why = one_line(
                str(exc) if isinstance(exc, LegbenchError) else f"info() failed: {type(exc).__name__}: {exc}"
            )
            status, reason = "failed", why
    if status == "ok":  # the log read at the ticks: a friction that chatters, whatever the engine
        info["warnings"] = [*info["warnings"], *friction_chatter(backend.name, t, f_log, physics.contact)]
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
        info=info,
        wall_time=wall,
    )


class _EngineError(Exception):
    """An error raised by a backend's own call in the run loop (reset, read, step), carried to its handler."""

    def __init__(self, cause: Exception, logged: bool = False) -> None:
        super().__init__(str(cause))
        self.cause = cause
        self.logged = logged  # the tick's row was written before the call failed (a step): it is kept


#: What a backend declares of itself, recorded beside its info (what verification predicts and scores by).
_DECLARED: tuple[tuple[str, Callable[[Backend], Any]], ...] = (
    ("integrator_family", lambda b: b.integrator_family()),
    ("sub_steps", lambda b: b.sub_steps()),
    ("engine_contact", lambda b: bool(b.engine_contact())),
    ("sliding_coefficient", lambda b: b.slides_with()),
)


def _declared(backend: Backend) -> dict[str, Any]:
    """What a backend whose :meth:`~Backend.info` failed still declares (the profile and :data:`_DECLARED`),
    each only if asking for it does not fail too."""
    out: dict[str, Any] = {"profile": backend.profile}
    for key, ask in _DECLARED:
        try:
            out[key] = ask(backend)
        except Exception:  # noqa: S112 - the run already failed with the reason; this is only what is known
            continue
    return out


def backend_info(backend: Backend) -> dict[str, Any]:
    """What run.json records of a backend: its :meth:`~Backend.info`, the ``profile`` it was loaded with,
    its declared ``integrator_family``, ``sub_steps``, ``engine_contact`` and ``sliding_coefficient``
    (:data:`_DECLARED`), and its
    :meth:`~Backend.warnings` after the run (e.g. a sub-step too coarse for the contact law), each beginning with the
    backend's name (added where the backend's sentence does not begin with it), as every reader shows them.

    Raises:
        LegbenchError: the backend's info breaks what legbench reads of it
            (:func:`~legbench.backends.base.info_problem`), or what it declares of itself does
            (:func:`~legbench.backends.base.declared_problem`).
    """
    info = backend.info()
    problem = info_problem(info)
    if problem is not None:
        raise LegbenchError(f"{backend.name}: info() {problem}")
    declared = {key: ask(backend) for key, ask in _DECLARED}
    problem = declared_problem(declared["integrator_family"], declared["sub_steps"], declared["sliding_coefficient"])
    if problem is not None:
        raise LegbenchError(f"{backend.name}: {problem}")
    named = f"{backend.name}: "
    warnings = [w if w.startswith(named) else named + w for w in backend.warnings()]
    return {**info, "profile": backend.profile, **declared, "warnings": warnings}


def run_backend(scenario: Scenario, name: str, contact_mode: str | None = None, progress: bool = False) -> RunResult:
    """Load ``name``, run the scenario, close; any failure is returned as a failed result."""
    physics = physics_of(scenario, contact_mode)
    try:
        backend = registry.load(name, physics, scenario.backends.get(name, {}), scenario.profile)
    except BackendNotFound as exc:
        return RunResult.empty(name, "missing", str(exc))
    except Exception as exc:  # an engine that cannot load must not stop the others
        return RunResult.empty(name, "failed", one_line(f"load failed: {type(exc).__name__}: {exc}"))
    bar = _ProgressBar(f"{scenario.name}/{name}") if progress else None
    try:
        return simulate(scenario, backend, physics, bar, keep_interrupted=True)
    finally:
        if bar is not None:
            bar.done()
        backend.close()


class _ProgressBar:
    """One run's progress on one stderr line, only where a bar is drawn (:func:`legbench.progress.enabled`)."""

    def __init__(self, label: str) -> None:
        self.label = label
        self.tty = progress_mod.enabled()

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


#: Where earlier measured wall times are looked up to order the runs (besides each output directory itself).
BASELINE_ROOT = Path("results") / "baseline"


def crashed(backend: str, why: str) -> RunResult:
    """The result of ``backend``'s run whose worker process died under it (the engine crashed): failed, with
    ``why`` (the executor's words); for ``legbench run`` and the sweeps."""
    return RunResult.empty(backend, "failed", f"the engine crashed: {why}")


def _crashed(task: tuple[Scenario, str, str | None, bool], why: str) -> RunResult:
    return crashed(task[1], why)


def cost_hints(
    out_dirs: Sequence[Path | None], roots: Sequence[Path] = (BASELINE_ROOT,)
) -> dict[tuple[str, str], float]:
    """Measured wall time per simulated second [s/s] of earlier runs, by (run directory name, backend).

    Read from the run.json already in each output directory and in the
    directory of the same name under each of ``roots`` (the committed
    baseline); unreadable or missing files give no hint. Only used to start
    the longest runs first: results never depend on it.
    """
    hints: dict[tuple[str, str], float] = {}
    for out in out_dirs:
        if out is None:
            continue
        for d in (out, *(Path(r) / out.name for r in roots)):
            try:
                meta = read_meta(d)
                duration = float(meta["scenario"]["duration"])
                for name, e in meta["backends"].items():
                    wall = float(e.get("wall_time") or 0.0)
                    sim = float(e.get("failed_at") or duration) if e.get("status") != "ok" else duration
                    if wall > 0 and sim > 0 and (out.name, name) not in hints:
                        hints[(out.name, name)] = wall / sim
            except (LegbenchError, KeyError, TypeError, ValueError, AttributeError):
                continue
    return hints


def backend_rates(root: Path = BASELINE_ROOT) -> dict[str, float]:
    """Each backend's median measured wall time per simulated second [s/s] over the run directories under
    ``root`` (the committed baseline): a cost hint for studies that order their own runs longest first.
    Empty where nothing is readable; results never depend on it."""
    try:
        dirs: list[Path | None] = list(run_dirs(root).values())
    except LegbenchError:
        return {}
    return _medians(cost_hints(dirs, ()))


def _medians(hints: Mapping[tuple[str, str], float]) -> dict[str, float]:
    """Each backend's median over the directories of ``hints`` (from :func:`cost_hints`) [s/s]."""
    by_backend: dict[str, list[float]] = {}
    for (_, name), v in hints.items():
        by_backend.setdefault(name, []).append(v)
    return {k: float(np.median(v)) for k, v in by_backend.items()}


def _estimates(
    plan: Sequence[tuple[int, Scenario, str, str | None]],
    outs: Sequence[Path | None],
    hints: Mapping[tuple[str, str], float],
) -> list[float]:
    """Expected wall time [s] of each planned run: duration x the measured s/s of that run, else of that backend
    in any other directory (median), else 1 s/s (then only the durations order the runs)."""
    median = _medians(hints)
    out = []
    for i, sc, name, _ in plan:
        d = outs[i]
        rate = hints.get((d.name, name)) if d is not None else None
        out.append(sc.duration * (rate if rate is not None else median.get(name, 1.0)))
    return out


@contextmanager
def deferred_interrupts() -> Iterator[list[int]]:
    """Hold SIGINT and SIGTERM while results are written: a signal then is acted on (KeyboardInterrupt) after
    the block, so a write is never cut half-way. Only in the main thread (elsewhere a plain block)."""
    got: list[int] = []
    if threading.current_thread() is not threading.main_thread():
        yield got
        return

    def hold(signum: int, frame: object) -> None:
        got.append(signum)

    previous = {sig: signal.signal(sig, hold) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield got
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    if got:
        raise KeyboardInterrupt


def check_outs(
    plan: Sequence[tuple[Scenario, str | None, Path]],
    force: bool,
    new_place: str,
    replace: str = "--force",
    option: str = "--out",
    backends: Sequence[str] | None = None,
) -> None:
    """Before any work, each (scenario, contact mode, output directory) of a plan: the directory holds no other
    scenario's results (:func:`legbench.results.check_out_dir`), and a finished run there, or an interrupted one
    of other settings or (``backends``: the run's) of other backends too, is replaced only with ``force`` (an
    interrupted run of the same settings is resumed).

    Raises:
        LegbenchError: one line naming the directory, what it holds, ``new_place`` (where a new one goes) and
            ``replace`` (the option that replaces it); for a directory holding another scenario's results or
            anything else, ``option``, what the caller named the directory with (the Python API's ``out``).
    """
    for sc, mode, out in plan:
        check_out_dir(sc, out, option)
        held = None if force else replaced_by_run(sc, out, mode, backends)
        if held is not None:
            raise LegbenchError(f"{out} holds {held}; {new_place} for a new one, or {replace} to replace it")


def check_tree(root: Path, dirs: Sequence[str], option: str = "--out", foreign: bool = True) -> None:
    """Before any work, ``root`` as the root of a results tree whose run directories are ``dirs`` (several runs,
    or one run in both contact modes): not itself a run directory (its pages would be rewritten), no report.md or
    report.html there but an index legbench wrote, and, with ``foreign``, holding nothing legbench did not put
    there (the tree's index pages and a regression check's summaries may be).

    Raises:
        LegbenchError: one line naming ``option`` and the root.
    """
    from legbench.report_figures import ASSETS

    if (root / "run.json").is_file():
        raise LegbenchError(f"{option} {root}: holds one run, and {len(dirs)} runs make a tree of run directories; "
                            f"choose another {option}")  # fmt: skip
    if foreign:
        check_out_tree(root, [*dirs, ASSETS], ("report.html", "report.md", *CHECK_OUTPUTS), "results tree", option)
    check_index_pages(root)  # the tree's index is written at the end: a page of the user's there is refused now


def run_preload(backend_names: Sequence[str] | None = None) -> tuple[str, ...]:
    """What the workers of :func:`run_many` import when they start: the run loop, the study tasks and the engines
    of ``backend_names`` (their modules, :func:`legbench.backends.module_of`), or every installed engine (None):
    a run of MuJoCo and Pinocchio does not wait for the fork server to import Drake."""
    if backend_names is None:
        return DEFAULT_PRELOAD
    engines = (registry.module_of(n) for n in backend_names)
    return (*TASK_PRELOAD, *dict.fromkeys(m for m in engines if m is not None))


def start_pool(jobs: int, tasks: int | None = None, backend_names: Sequence[str] | None = None) -> LocalExecutor | None:
    """A pool of ``jobs`` workers (no more than ``tasks``, the runs it will have) started now, for
    :func:`run_many`: they import the engines of ``backend_names`` (every installed one: None,
    :func:`run_preload`) while the caller reads scenarios and runs its pre-flight. None for ``jobs <= 1`` (the runs
    go in this process)."""
    if jobs <= 1:
        return None
    pool = LocalExecutor(jobs, preload=run_preload(backend_names), tasks=tasks)
    pool.start()
    return pool


def run_many(
    jobs_list: Sequence[tuple[Scenario, str | None, Path | None]],
    backend_names: Sequence[str],
    jobs: int = 1,
    csv: bool = False,
    progress: bool = True,
    pool: LocalExecutor | None = None,
) -> list[list[RunResult]]:
    """Run several (scenario, contact mode, output dir) on every backend, in ``jobs`` processes.

    Each (scenario, mode, backend) is one task, handed to the pool longest
    first (duration x the wall time per simulated second measured in an earlier
    run of it, :func:`cost_hints`), so no long run is left alone at the end.
    Results are put back in input order, so the output is the same
    (bit-identical logs) for any ``jobs``. A failing backend is logged up to its
    failure and the others still run; one whose engine crashes its worker process
    (a segmentation fault) is marked failed and the others run on
    (:meth:`~legbench.studies.executors.LocalExecutor.imap_unordered`). ``progress``: with ``jobs > 1`` an overall
    count with the ETA, with ``jobs = 1`` each run's bar, both only on a terminal
    and outside CI (:mod:`legbench.progress`).

    On Ctrl-C (or SIGTERM, turned into KeyboardInterrupt by the CLI) the
    workers are stopped; every run that finished is written as a complete
    backend of its directory (run.json marks the others ``interrupted``, the
    directory incomplete), a line on stderr says what was kept, and the
    interrupt is re-raised. A rerun into the same directories runs only the
    backends that did not finish.

    ``pool``: workers started earlier (:func:`start_pool`, ``jobs`` of them), used instead of a new pool;
    like a new one it is closed when the runs end, or stopped on an error.
    """
    plan: list[tuple[int, Scenario, str, str | None]] = []
    kept: list[dict[str, Any]] = []
    try:
        for i, (sc, mode, out) in enumerate(jobs_list):
            done: dict[str, Any] = {}
            if out is not None:
                check_out_dir(sc, out)
                done = {k: v for k, v in resumable(sc, out, mode).items() if k in backend_names}
            kept.append(done)
            plan += [(i, sc, name, mode) for name in backend_names if name not in done]
    except BaseException:
        if pool is not None:
            pool.terminate()
        raise
    # no more workers than runs left (each a process importing every engine; a resume runs fewer)
    jobs = pool.jobs if pool is not None else capped(jobs, len(plan))
    outs = [out for _, _, out in jobs_list]
    cost = _estimates(plan, outs, cost_hints(outs) if jobs > 1 and len(plan) > jobs else {})
    first = sorted(range(len(plan)), key=lambda j: (-cost[j], j))
    per_run_bar = progress and jobs <= 1
    tasks = [(sc, name, mode, per_run_bar) for _, sc, name, mode in plan]
    got: dict[int, RunResult] = {}
    interrupted = False
    pool = pool if pool is not None else LocalExecutor(jobs, preload=run_preload(backend_names))
    with progress_mod.bar(len(plan), "runs", quiet=not progress or jobs <= 1) as bar:
        try:
            for j, tr in pool.imap_unordered(_task, tasks, first, _crashed):
                got[j] = tr
                bar.update(1, f"{plan[j][1].name}/{plan[j][2]}")
                if tr.status == "interrupted":  # Ctrl-C reached the run in this process
                    interrupted = True
                    break
        except (KeyboardInterrupt, BrokenExecutor):  # Ctrl-C; workers killed by a signal to the process group
            interrupted = True
        except BaseException:
            pool.terminate()
            raise
        try:
            pool.close() if not interrupted else pool.terminate()
        except KeyboardInterrupt:  # while idle workers were being joined: every run has finished
            interrupted = True
            pool.terminate()
    results: list[list[RunResult]] = [[] for _ in jobs_list]
    for j in sorted(got):  # plan order: scenario by scenario, backends in the order asked for
        results[plan[j][0]].append(got[j])
    with deferred_interrupts():
        for (sc, mode, out), res, done in zip(jobs_list, results, kept, strict=True):
            if out is not None and (res or done):
                if interrupted and len(res) + len(done) < len(backend_names):
                    res = [*res, *_not_run(sc, backend_names, res, done)]
                write_run(sc, res, out, csv, mode, done)
    if interrupted:
        _say_kept(jobs_list, results, kept, len(backend_names))
        raise KeyboardInterrupt
    return results


def _say_kept(
    jobs_list: Sequence[tuple[Scenario, str | None, Path | None]],
    results: Sequence[Sequence[RunResult]],
    kept: Sequence[Mapping[str, Any]],
    n_backends: int,
) -> None:
    """One stderr line per output directory of an interrupted run: which backends are kept, which are not."""
    for (_, _, out), res, done in zip(jobs_list, results, kept, strict=True):
        finished = [*done, *(tr.backend for tr in res if tr.status != "interrupted")]
        partial = [tr.backend for tr in res if tr.status == "interrupted" and len(tr.t)]
        where = str(out) if out is not None else "(not written)"
        line = f"interrupted: {where}: {len(finished)} of {n_backends} backends finished and kept"
        if finished:
            line += f" ({', '.join(finished)})"
        if partial:
            line += f"; kept up to the interrupt, marked interrupted: {', '.join(partial)}"
        print(line, file=sys.stderr, flush=True)


def _not_run(sc: Scenario, names: Sequence[str], res: Sequence[RunResult], done: Mapping[str, Any]) -> list[RunResult]:
    """Placeholders for backends an interrupt stopped before they finished (their run is not kept)."""
    have = {tr.backend for tr in res} | set(done)
    why = "not run: interrupted before it finished"
    return [RunResult.empty(n, "interrupted", why) for n in names if n not in have]


def run(scenario: Scenario, backend_names: Sequence[str], out_dir: Path | None, csv: bool = False,
        contact_mode: str | None = None, progress: bool = True, jobs: int = 1) -> list[RunResult]:  # fmt: skip
    """Run one scenario on every named backend and write the results into ``out_dir`` (see :func:`run_many`)."""
    return run_many([(scenario, contact_mode, out_dir)], backend_names, jobs, csv, progress)[0]
