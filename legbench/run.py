"""The run loop: owns the clock, the controllers and the log; drives any backend.

At each control tick k (t = k Ts) the loop reads the backend's state, fires the
events due, computes the active controller's torque, saturates it at the joint
limits, logs the tick into preallocated arrays, and steps the backend one
control period under that torque (zero-order hold). Row k of the log holds the
state and ground force at t_k and the torque applied over [t_k, t_k + Ts).
"""

from __future__ import annotations

import json
import math
import os
import platform
import shutil
import sys
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from legbench import backends as registry
from legbench import kinematics
from legbench.backends.base import Backend, Physics
from legbench.controllers import Controller, make_controller
from legbench.exceptions import BackendNotFound, LegbenchError, SimulationDiverged
from legbench.model import URDF_FILE, load_params
from legbench.scenario import Scenario

COLUMNS = ("t", "q1", "q2", "q3", "qd1", "qd2", "qd3", "tau1", "tau2", "tau3", "fx", "fy", "fz",
           "ee_x", "ee_y", "ee_z")  # fmt: skip
#: Divergence bounds no physical run of this leg reaches: joint speed [rad/s] (20x the hip's
#: speed limit) and foot penetration [m] (5 cm is 500 N at Kp = 1e4 N/m; the leg pushes <= 100 N).
MAX_JOINT_SPEED = 1.0e3
MAX_PENETRATION = 0.05


@dataclass
class Trajectory:
    """One backend's logged run: arrays of shape (n,) or (n, 3)."""

    backend: str
    t: np.ndarray  # [s]
    q: np.ndarray  # [rad]
    qd: np.ndarray  # [rad/s]
    tau: np.ndarray  # [N m], after saturation
    f: np.ndarray  # ground force on the foot in W [N]
    controller: np.ndarray  # active controller name per tick
    status: str = "ok"  # ok | failed
    reason: str | None = None
    info: dict[str, Any] = field(default_factory=dict)
    wall_time: float = 0.0  # [s]

    @property
    def ee(self) -> np.ndarray:
        """Foot centre in W [m], from the logged joint angles."""
        return kinematics.fk(self.q)

    def frame(self) -> pd.DataFrame:
        """The log as a DataFrame with the columns of :data:`COLUMNS` plus ``controller``."""
        data = np.column_stack([self.t, self.q, self.qd, self.tau, self.f, self.ee])
        df = pd.DataFrame(data, columns=list(COLUMNS))
        df["controller"] = self.controller
        return df


def physics_of(scenario: Scenario, contact_mode: str | None = None) -> Physics:
    """Physics settings every backend gets for this scenario."""
    lim = load_params().effort
    return Physics(
        gravity=scenario.gravity,
        contact=scenario.contact,
        contact_mode=contact_mode or scenario.contact_mode,
        control_dt=scenario.control_dt,
        torque_limit=(float(lim[0]), float(lim[1]), float(lim[2])),
    )


def simulate(
    scenario: Scenario,
    backend: Backend,
    physics: Physics,
    progress: Callable[[float], None] | None = None,
) -> Trajectory:
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
    ticks = [int(round(e.t / Ts)) for e in scenario.events]
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
    return Trajectory(
        backend=backend.name,
        t=t[:n] if status != "ok" else t,
        q=q_log[:n] if status != "ok" else q_log,
        qd=qd_log[:n] if status != "ok" else qd_log,
        tau=tau_log[:n] if status != "ok" else tau_log,
        f=f_log[:n] if status != "ok" else f_log,
        controller=controller,
        status=status,
        reason=reason,
        info=backend.info(),
        wall_time=wall,
    )


def run_backend(scenario: Scenario, name: str, contact_mode: str | None = None, progress: bool = False) -> Trajectory:
    """Load ``name``, run the scenario, close; any failure is returned as a failed trajectory."""
    physics = physics_of(scenario, contact_mode)
    empty = np.empty((0, 3))
    try:
        backend = registry.load(name, physics, scenario.backends.get(name, {}))
    except BackendNotFound as exc:
        return Trajectory(name, np.empty(0), empty, empty, empty, empty, np.empty(0, dtype=object), "missing", str(exc))
    except Exception as exc:  # an engine that cannot load must not stop the others
        return Trajectory(name, np.empty(0), empty, empty, empty, empty, np.empty(0, dtype=object), "failed",
                          f"load failed: {type(exc).__name__}: {exc}")  # fmt: skip
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


def versions() -> dict[str, str]:
    """Versions of legbench, Python and every engine package that imports."""
    from importlib import metadata

    out = {"python": platform.python_version()}
    for pkg in ("legbench", "numpy", "scipy", "pandas", "pin", "mujoco", "pybullet", "sympy"):
        try:
            out[pkg] = metadata.version(pkg)
        except metadata.PackageNotFoundError:
            continue
    return out


def platform_info() -> dict[str, Any]:
    return {"system": platform.system(), "machine": platform.machine(), "processor": platform.processor(),
            "cpus": os.cpu_count(), "node": platform.node()}  # fmt: skip


def _previous(out_dir: Path) -> dict[str, Any] | None:
    """The run.json already in ``out_dir``, or None."""
    try:
        return json.loads((out_dir / "run.json").read_text())  # type: ignore[no-any-return]
    except FileNotFoundError:
        return None
    except (ValueError, OSError):
        return {}


def check_out_dir(scenario: Scenario, out_dir: Path) -> None:
    """Refuse an output directory holding another scenario's results (or anything else)."""
    out_dir = Path(out_dir)
    prev = _previous(out_dir)
    if prev is None:
        if out_dir.exists() and any(out_dir.iterdir()):
            raise LegbenchError(f"{out_dir}: not empty and not a legbench run directory; choose another --out")
        return
    name = (prev.get("scenario") or {}).get("name")
    if name != scenario.name:
        raise LegbenchError(
            f"{out_dir}: holds results of scenario {name!r}, not {scenario.name!r}; choose another --out or remove it"
        )


def resumable(scenario: Scenario, out_dir: Path, contact_mode: str | None) -> dict[str, Any]:
    """Entries of backends already finished in an interrupted run of the same scenario (same hash and mode)."""
    prev = _previous(Path(out_dir))
    if not prev or prev.get("complete", True):
        return {}
    sc = prev.get("scenario", {})
    if sc.get("sha256") != scenario.sha256 or sc.get("contact_mode") != (contact_mode or scenario.contact_mode):
        return {}
    return {name: e for name, e in prev.get("backends", {}).items() if e.get("status") == "ok"}


def write_run(scenario: Scenario, results: Sequence[Trajectory], out_dir: Path, csv: bool = False,
              contact_mode: str | None = None, kept: dict[str, Any] | None = None) -> Path:  # fmt: skip
    """Write <backend>.parquet (and .csv) and run.json into ``out_dir``, atomically.

    Everything goes to a temporary sibling directory first, which replaces
    ``out_dir`` only when complete. ``kept`` are entries of backends finished in
    an earlier, interrupted run into the same directory; their files are carried
    over. ``run.json["complete"]`` is false when a backend was interrupted.
    """
    out_dir = Path(out_dir)
    check_out_dir(scenario, out_dir)
    out_dir.parent.mkdir(parents=True, exist_ok=True)
    tmp = out_dir.parent / f".{out_dir.name}.tmp-{os.getpid()}"
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir()
    meta_backends: dict[str, Any] = {}
    for name, old_entry in (kept or {}).items():
        for suffix in (".parquet", ".csv"):
            if (out_dir / f"{name}{suffix}").exists():
                shutil.copy2(out_dir / f"{name}{suffix}", tmp / f"{name}{suffix}")
        meta_backends[name] = old_entry
    for tr in results:
        entry: dict[str, Any] = {"status": tr.status, "reason": tr.reason, "info": tr.info,
                                 "wall_time": tr.wall_time, "file": None, "rtf": None, "failed_at": None}  # fmt: skip
        if len(tr.t):
            df = tr.frame()
            df.to_parquet(tmp / f"{tr.backend}.parquet", index=False)
            if csv:
                df.to_csv(tmp / f"{tr.backend}.csv", index=False)
            entry["file"] = f"{tr.backend}.parquet"
            sim_time = float(tr.t[-1])
            entry["rtf"] = sim_time / tr.wall_time if tr.wall_time > 0 else None
            entry["failed_at"] = sim_time if tr.status != "ok" else None
        meta_backends[tr.backend] = entry
    sdict = scenario.to_dict()
    if contact_mode:
        sdict["contact_mode"] = contact_mode
    vers = versions()
    meta = {
        "complete": all(e["status"] != "interrupted" for e in meta_backends.values()),
        "scenario": sdict,
        "backends": meta_backends,
        "versions": vers,
        "platform": platform_info(),
        "legbench_version": vers.get("legbench", "unknown"),
        "urdf": str(URDF_FILE.name),
    }
    (tmp / "run.json").write_text(json.dumps(meta, indent=2, default=_json_default))
    if out_dir.exists():
        old = out_dir.parent / f".{out_dir.name}.old-{os.getpid()}"
        out_dir.rename(old)
        tmp.rename(out_dir)
        shutil.rmtree(old)
    else:
        tmp.rename(out_dir)
    return out_dir


def _json_default(o: Any) -> Any:
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, Path):
        return str(o)
    return str(o)


def out_dir_for(root: Path, scenario: Scenario, contact_mode: str | None) -> Path:
    """Directory of one scenario in a results tree: <root>/<name>, or <name>__reference in reference mode."""
    mode = contact_mode or scenario.contact_mode
    return Path(root) / (scenario.name if mode == "native" else f"{scenario.name}__reference")


def _task(args: tuple[Scenario, str, str | None, bool]) -> Trajectory:
    scenario, name, mode, progress = args
    return run_backend(scenario, name, mode, progress)


def run_many(
    jobs_list: Sequence[tuple[Scenario, str | None, Path | None]],
    backend_names: Sequence[str],
    jobs: int = 1,
    csv: bool = False,
    progress: bool = True,
) -> list[list[Trajectory]]:
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
    results: list[list[Trajectory]] = [[] for _ in jobs_list]
    interrupted = False
    if jobs <= 1:
        for i, sc, name, mode in plan:
            tr = run_backend(sc, name, mode, progress)
            results[i].append(tr)
            if tr.status == "interrupted":
                interrupted = True
                break
    else:
        from concurrent.futures import ProcessPoolExecutor

        # longest runs first, so the pool does not wait on one long run at the end; results are
        # still collected in plan order, so the output does not depend on ``jobs``
        order = sorted(range(len(plan)), key=lambda j: -plan[j][1].duration)
        with ProcessPoolExecutor(max_workers=jobs) as pool:
            submitted = {j: pool.submit(_task, (plan[j][1], plan[j][2], plan[j][3], False)) for j in order}
            futures = [submitted[j] for j in range(len(plan))]
            try:
                for (i, *_), fut in zip(plan, futures, strict=True):
                    results[i].append(fut.result())
            except KeyboardInterrupt:
                interrupted = True
                for fut in futures:
                    fut.cancel()
    for (sc, mode, out), res, done in zip(jobs_list, results, kept, strict=True):
        if out is not None and (res or done):
            if interrupted and len(res) + len(done) < len(backend_names):
                res = [*res, *_not_run(sc, backend_names, res, done)]
            write_run(sc, res, out, csv, mode, done)
    if interrupted:
        raise KeyboardInterrupt
    return results


def _not_run(
    sc: Scenario, names: Sequence[str], res: Sequence[Trajectory], done: Mapping[str, Any]
) -> list[Trajectory]:
    """Placeholders for backends an interrupt stopped before they started."""
    have = {tr.backend for tr in res} | set(done)
    empty = np.empty((0, 3))
    return [Trajectory(n, np.empty(0), empty, empty, empty, empty, np.empty(0, dtype=object), "interrupted",
                       "interrupted before it started") for n in names if n not in have]  # fmt: skip


def run(scenario: Scenario, backend_names: Sequence[str], out_dir: Path | None, csv: bool = False,
        contact_mode: str | None = None, progress: bool = True, jobs: int = 1) -> list[Trajectory]:  # fmt: skip
    """Run one scenario on every named backend and write the results into ``out_dir`` (see :func:`run_many`)."""
    return run_many([(scenario, contact_mode, out_dir)], backend_names, jobs, csv, progress)[0]
