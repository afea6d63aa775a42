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
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from legbench import backends as registry
from legbench import kinematics
from legbench.backends.base import Backend, Physics
from legbench.controllers import Controller, make_controller, saturate
from legbench.exceptions import BackendNotFound, LegbenchError, SimulationDiverged
from legbench.model import URDF_FILE, load_params
from legbench.scenario import Scenario

COLUMNS = ("t", "q1", "q2", "q3", "qd1", "qd2", "qd3", "tau1", "tau2", "tau3", "fx", "fy", "fz",
           "ee_x", "ee_y", "ee_z")  # fmt: skip
#: Divergence bounds no physical run of this leg reaches: joint speed [rad/s], ground force [N]
#: (the leg pushes with at most ~100 N; 5 kN means the foot is 0.5 m into a 1e4 N/m ground).
MAX_JOINT_SPEED = 1.0e3
MAX_GROUND_FORCE = 5.0e3


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
    """Run one scenario on one loaded-and-ready backend; a divergence ends the log early, marked failed."""
    n = scenario.n_ticks
    Ts = scenario.control_dt
    limit = np.array(physics.torque_limit)
    t = np.arange(n) * Ts
    q_log = np.full((n, 3), np.nan)
    qd_log = np.full((n, 3), np.nan)
    tau_log = np.full((n, 3), np.nan)
    f_log = np.full((n, 3), np.nan)
    ctrl_idx = np.zeros(n, dtype=np.int16)
    ticks = [int(round(e.t / Ts)) for e in scenario.events]
    names = [e.controller for e in scenario.events]
    controllers: list[Controller] = [make_controller(e, scenario.gains, Ts, n) for e in scenario.events]
    backend.reset(np.array(scenario.q0), np.array(scenario.qd0))
    active: Controller = controllers[0]
    next_event = 0
    status, reason, k = "ok", None, 0
    every = max(n // 50, 1)
    start = time.perf_counter()
    try:
        for k in range(n):
            q, qd = backend.state()
            f = backend.ground_force()
            if not (math.isfinite(q.sum() + qd.sum() + f.sum())):
                raise SimulationDiverged(backend.name, k * Ts, "state is not finite")
            if np.abs(qd).max() > MAX_JOINT_SPEED:
                raise SimulationDiverged(backend.name, k * Ts, f"joint speed above {MAX_JOINT_SPEED} rad/s")
            if abs(f[2]) > MAX_GROUND_FORCE:
                raise SimulationDiverged(backend.name, k * Ts, f"ground force {f[2]:.0f} N: foot far below ground")
            while next_event < len(ticks) and ticks[next_event] <= k:
                active = controllers[next_event]
                active.start(k * Ts, q, qd)
                next_event += 1
            tau = saturate(np.asarray(active(k, q, qd), dtype=float).copy(), limit)
            q_log[k], qd_log[k], tau_log[k], f_log[k] = q, qd, tau, f
            ctrl_idx[k] = next_event - 1
            if k < n - 1:
                backend.step(tau)
            if progress is not None and k % every == 0:
                progress(k / n)
    except SimulationDiverged as exc:
        status, reason = "failed", str(exc)
        n = k
    except (LegbenchError, FloatingPointError, RuntimeError, ValueError) as exc:
        status, reason = "failed", f"{type(exc).__name__} at t = {k * Ts:.4f} s: {exc}"
        n = k
    wall = time.perf_counter() - start
    return Trajectory(
        backend=backend.name,
        t=t[:n] if status != "ok" else t,
        q=q_log[:n] if status != "ok" else q_log,
        qd=qd_log[:n] if status != "ok" else qd_log,
        tau=tau_log[:n] if status != "ok" else tau_log,
        f=f_log[:n] if status != "ok" else f_log,
        controller=np.array(names, dtype=object)[ctrl_idx[: len(t) if status == "ok" else n]],
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
        backend = registry.get(name)()
    except BackendNotFound as exc:
        return Trajectory(name, np.empty(0), empty, empty, empty, empty, np.empty(0, dtype=object), "missing", str(exc))
    try:
        backend.load(URDF_FILE, physics, scenario.backends.get(name, {}))
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
    for pkg in ("legbench", "numpy", "scipy", "pandas", "pin", "mujoco", "pybullet"):
        try:
            out[pkg] = metadata.version(pkg)
        except metadata.PackageNotFoundError:
            continue
    return out


def platform_info() -> dict[str, Any]:
    return {"system": platform.system(), "machine": platform.machine(), "processor": platform.processor(),
            "cpus": os.cpu_count(), "node": platform.node()}  # fmt: skip


def write_run(scenario: Scenario, results: Sequence[Trajectory], out_dir: Path, csv: bool = False,
              contact_mode: str | None = None) -> Path:  # fmt: skip
    """Write <backend>.parquet (and .csv) and run.json atomically into ``out_dir``.

    Refuses to replace a directory holding a different scenario's results.
    """
    out_dir = Path(out_dir)
    old = out_dir / "run.json"
    if old.exists():
        try:
            prev = json.loads(old.read_text())["scenario"]["name"]
        except (ValueError, KeyError, TypeError):
            prev = None
        if prev != scenario.name:
            raise LegbenchError(f"{out_dir}: holds results of scenario {prev!r}, not {scenario.name!r}; "
                                "choose another --out or remove it")  # fmt: skip
    elif out_dir.exists() and any(out_dir.iterdir()):
        raise LegbenchError(f"{out_dir}: not empty and not a legbench run directory; choose another --out")
    out_dir.parent.mkdir(parents=True, exist_ok=True)
    tmp = out_dir.parent / f".{out_dir.name}.tmp-{os.getpid()}"
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir()
    meta_backends: dict[str, Any] = {}
    for tr in results:
        entry: dict[str, Any] = {"status": tr.status, "reason": tr.reason, "info": tr.info,
                                 "wall_time": tr.wall_time, "file": None}  # fmt: skip
        if len(tr.t):
            df = tr.frame()
            df.to_parquet(tmp / f"{tr.backend}.parquet", index=False)
            if csv:
                df.to_csv(tmp / f"{tr.backend}.csv", index=False)
            entry["file"] = f"{tr.backend}.parquet"
            sim_time = float(tr.t[-1]) if len(tr.t) else 0.0
            entry["rtf"] = sim_time / tr.wall_time if tr.wall_time > 0 else None
            entry["failed_at"] = sim_time if tr.status == "failed" else None
        meta_backends[tr.backend] = entry
    sdict = scenario.to_dict()
    if contact_mode:
        sdict["contact_mode"] = contact_mode
    meta = {
        "scenario": sdict,
        "backends": meta_backends,
        "versions": versions(),
        "platform": platform_info(),
        "legbench_version": versions().get("legbench", "unknown"),
        "urdf": str(URDF_FILE.name),
    }
    (tmp / "run.json").write_text(json.dumps(meta, indent=2, default=_json_default))
    if out_dir.exists():
        shutil.rmtree(out_dir)
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


def run(scenario: Scenario, backend_names: Sequence[str], out_dir: Path | None, csv: bool = False,
        contact_mode: str | None = None, progress: bool = True) -> list[Trajectory]:  # fmt: skip
    """Run a scenario on every named backend (one after the other) and write the results."""
    results = [run_backend(scenario, name, contact_mode, progress) for name in backend_names]
    if out_dir is not None:
        write_run(scenario, results, out_dir, csv, contact_mode)
    return results
