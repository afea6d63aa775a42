"""Executors: run independent simulation tasks on a local process pool or a Dask cluster.

A task is plain data, a :class:`RunTask` (scenario file + dotted overrides +
backend name, and optionally a reference run to replay in short windows), and
its result is a plain dict of numpy arrays and numbers (:func:`run_task`), so
both pickle cheaply and any worker with legbench installed can run it. Every
run is deterministic and single-threaded, and :meth:`Executor.map` returns
results in task order, so a sweep's table is bit-identical whichever executor
and however many jobs ran it; only the measured wall times differ.

Executors:
    * ``local`` (:class:`LocalExecutor`): ``jobs`` worker processes
      (:class:`concurrent.futures.ProcessPoolExecutor`, started by a fork
      server so the parent's threads are never forked); ``jobs = 1`` runs in
      this process, one task after the other.
    * ``dask`` (:class:`DaskExecutor`): one Dask ``distributed`` task per run,
      on the scheduler at ``scheduler`` (``tcp://host:8786``) or on a
      :class:`distributed.LocalCluster` of ``jobs`` single-threaded workers.
      docs/studies.md says how to set up a real cluster.
"""

from __future__ import annotations

import logging
import multiprocessing
import os
from abc import ABC, abstractmethod
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from types import TracebackType
from typing import Any, TypeVar

import numpy as np

from legbench.exceptions import LegbenchError

__all__ = [
    "EXECUTORS",
    "DaskExecutor",
    "Executor",
    "LocalExecutor",
    "ReplaySpec",
    "RunTask",
    "make_executor",
    "run_task",
]

log = logging.getLogger("legbench.executors")

#: Executor names accepted by :func:`make_executor`.
EXECUTORS = ("local", "dask")

T = TypeVar("T")
R = TypeVar("R")


# --------------------------------------------------------------------------- #
# Tasks


@dataclass(frozen=True)
class ReplaySpec:
    """A reference run to replay in short windows (short-horizon mode, :mod:`legbench.horizon`).

    Attributes:
        window: window length [s], a whole number of control periods.
        t: reference tick times [s], shape (n,).
        q: reference joint positions [rad], shape (n, 3).
        qd: reference joint velocities [rad/s], shape (n, 3).
        tau: reference torques applied over [t_k, t_k + Ts) [N m], shape (n, 3).
        f: reference ground force on the foot in W [N], shape (n, 3).
    """

    window: float
    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    tau: np.ndarray
    f: np.ndarray


@dataclass(frozen=True)
class RunTask:
    """One run: a scenario file with dotted-key overrides on one backend.

    Attributes:
        index: position of the task in its sweep; results are ordered by it.
        scenario: path of the scenario YAML file (readable by the worker).
        overrides: dotted keys set before validation, e.g. ``{"backends.pinocchio.dt": 1e-4}``.
        backend: backend name.
        contact_mode: ``"native"``, ``"reference"`` or None (the scenario's).
        replay: a reference run to replay in windows after the free run, or None.
    """

    index: int
    scenario: str
    overrides: Mapping[str, Any] = field(default_factory=dict)
    backend: str = "pinocchio"
    contact_mode: str | None = None
    replay: ReplaySpec | None = None


def run_task(task: RunTask) -> dict[str, Any]:
    """Run one task; never raises for a simulation problem (it is reported in the result).

    Returns:
        ``index``, ``backend``, ``status`` (``ok`` / ``failed`` / ``missing``),
        ``reason``, ``wall_time`` [s] (simulation loop only), ``info`` (the
        backend's settings), arrays ``t`` [s], ``q`` [rad], ``qd`` [rad/s],
        ``tau`` [N m], ``f`` [N] (W), and ``horizon`` (a dict of arrays, see
        :func:`legbench.horizon.replay`) when the task asks for a replay.
    """
    from legbench import run, scenario

    sc = scenario.load(task.scenario, dict(task.overrides))
    tr = run.run_backend(sc, task.backend, task.contact_mode)
    out: dict[str, Any] = {
        "index": task.index,
        "backend": task.backend,
        "status": tr.status,
        "reason": tr.reason,
        "wall_time": float(tr.wall_time),
        "info": tr.info,
        "t": tr.t,
        "q": tr.q,
        "qd": tr.qd,
        "tau": tr.tau,
        "f": tr.f,
        "horizon": None,
    }
    if task.replay is not None and tr.status == "ok":
        from legbench.studies import horizon

        out["horizon"] = horizon.replay_task(sc, task.backend, task.replay, task.contact_mode)
    return out


# --------------------------------------------------------------------------- #
# Executors


class Executor(ABC):
    """Maps a picklable top-level function over tasks; results come back in task order."""

    name: str = ""

    @abstractmethod
    def map(self, fn: Callable[[T], R], items: Sequence[T]) -> list[R]:
        """``[fn(x) for x in items]``, computed by the executor's workers."""

    def close(self) -> None:  # noqa: B027 - optional hook
        """Release workers and connections."""

    def describe(self) -> dict[str, Any]:
        """Executor name and settings, for the sweep's metadata."""
        return {"executor": self.name}

    def __enter__(self) -> Executor:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()


def _mp_context() -> multiprocessing.context.BaseContext:
    """Fork server where the platform has one (no fork of a threaded parent), else spawn."""
    method = "forkserver" if "forkserver" in multiprocessing.get_all_start_methods() else "spawn"
    ctx = multiprocessing.get_context(method)
    if method == "forkserver":
        # import the engines once in the fork server, not once per worker
        ctx.set_forkserver_preload(["legbench.studies.executors", "legbench.run"])  # type: ignore[attr-defined]
    return ctx


class LocalExecutor(Executor):
    """A pool of ``jobs`` local worker processes; ``jobs = 1`` runs in this process."""

    name = "local"

    def __init__(self, jobs: int | None = None) -> None:
        """Args:
        jobs: number of worker processes (default: the CPU count).
        """
        self.jobs = int(jobs) if jobs else (os.cpu_count() or 1)
        if self.jobs < 1:
            raise LegbenchError(f"jobs must be >= 1, got {jobs}")
        self._pool: ProcessPoolExecutor | None = None

    def map(self, fn: Callable[[T], R], items: Sequence[T]) -> list[R]:
        if self.jobs == 1 or len(items) <= 1:
            return [fn(x) for x in items]
        if self._pool is None:
            self._pool = ProcessPoolExecutor(max_workers=self.jobs, mp_context=_mp_context())
        return list(self._pool.map(fn, items))

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=True)
            self._pool = None

    def describe(self) -> dict[str, Any]:
        return {"executor": self.name, "jobs": self.jobs}


class DaskExecutor(Executor):
    """Each item a Dask ``distributed`` task, on a given scheduler or on a local cluster."""

    name = "dask"

    def __init__(self, scheduler: str | None = None, jobs: int | None = None, processes: bool = True) -> None:
        """Args:
        scheduler: address of a running scheduler (``tcp://host:8786``); None starts a
            :class:`distributed.LocalCluster` owned by this executor.
        jobs: workers of the local cluster (default: the CPU count); ignored with a scheduler.
        processes: local cluster workers are processes (True) or threads of this process.
        """
        try:
            import distributed
        except ImportError as exc:
            raise LegbenchError("executor 'dask' needs Dask distributed: pip install 'dask[distributed]'") from exc
        self.scheduler = scheduler
        self.jobs = int(jobs) if jobs else (os.cpu_count() or 1)
        self.processes = processes
        self._cluster: Any = None
        if scheduler is None:
            self._cluster = distributed.LocalCluster(
                n_workers=self.jobs if processes else 1,
                threads_per_worker=1 if processes else self.jobs,
                processes=processes,
                dashboard_address=None,
            )
            self.client = distributed.Client(self._cluster)
        else:
            try:
                self.client = distributed.Client(scheduler, timeout="10s")
            except OSError as exc:
                raise LegbenchError(f"cannot reach the Dask scheduler at {scheduler}: {exc}") from exc

    def map(self, fn: Callable[[T], R], items: Sequence[T]) -> list[R]:
        if not items:
            return []
        futures = self.client.map(fn, list(items), pure=False)
        return list(self.client.gather(futures))

    def close(self) -> None:
        self.client.close()
        if self._cluster is not None:
            self._cluster.close()
            self._cluster = None

    def describe(self) -> dict[str, Any]:
        return {
            "executor": self.name,
            "scheduler": self.scheduler or "LocalCluster",
            "workers": len(self.client.scheduler_info(n_workers=-1).get("workers", {})),
        }


def make_executor(kind: str = "local", jobs: int | None = None, scheduler: str | None = None) -> Executor:
    """The executor named ``kind`` (one of :data:`EXECUTORS`).

    Args:
        kind: ``"local"`` or ``"dask"``.
        jobs: worker count (local pool size, or local Dask cluster size).
        scheduler: Dask scheduler address; only with ``kind = "dask"``.

    Raises:
        LegbenchError: an unknown executor, a scheduler given to the local one,
            Dask not installed, or a scheduler that cannot be reached.
    """
    if kind == "local":
        if scheduler:
            raise LegbenchError("--scheduler needs --executor dask")
        return LocalExecutor(jobs)
    if kind == "dask":
        return DaskExecutor(scheduler, jobs)
    raise LegbenchError(f"unknown executor '{kind}'; choose one of {', '.join(EXECUTORS)}")
