"""Executors: the one way legbench runs independent tasks in parallel, on a local process pool or Dask.

Every parallel run goes through here: ``legbench run --jobs`` (one task per
scenario, contact mode and backend) and sweeps (:mod:`legbench.studies.tasks`).
A task and its result are plain picklable data, so any worker with legbench
installed can run it. Every run is deterministic and single-threaded, and
:meth:`Executor.map` and :meth:`Executor.imap` return results in task order, so
the output is bit-identical whichever executor and however many jobs ran it;
only the measured wall times differ.

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
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor
from types import TracebackType
from typing import Any, TypeVar

from legbench.exceptions import LegbenchError

__all__ = [
    "EXECUTORS",
    "DaskExecutor",
    "Executor",
    "LocalExecutor",
    "make_executor",
]

log = logging.getLogger("legbench.executors")

#: Executor names accepted by :func:`make_executor`.
EXECUTORS = ("local", "dask")

T = TypeVar("T")
R = TypeVar("R")


# --------------------------------------------------------------------------- #
# Executors


class Executor(ABC):
    """Maps a picklable top-level function over tasks; results come back in task order."""

    name: str = ""

    @abstractmethod
    def map(self, fn: Callable[[T], R], items: Sequence[T]) -> list[R]:
        """``[fn(x) for x in items]``, computed by the executor's workers."""

    def imap(self, fn: Callable[[T], R], items: Sequence[T], first: Sequence[int] | None = None) -> Iterator[R]:
        """``fn(x)`` for each item, yielded in item order as each becomes available.

        Args:
            fn: a picklable top-level function.
            items: its arguments.
            first: item indices in the order to start them (e.g. longest first); default item order.
        """
        yield from self.map(fn, items)

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
        ctx.set_forkserver_preload(["legbench.run", "legbench.studies.tasks"])  # type: ignore[attr-defined]
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
        return list(self.imap(fn, items))

    def imap(self, fn: Callable[[T], R], items: Sequence[T], first: Sequence[int] | None = None) -> Iterator[R]:
        """As :meth:`Executor.imap`; ``jobs = 1`` runs each item in this process when its result is asked for.

        On an exception while waiting (Ctrl-C), tasks not yet started are cancelled.
        """
        if self.jobs == 1 or len(items) <= 1:
            for x in items:
                yield fn(x)
            return
        if self._pool is None:
            self._pool = ProcessPoolExecutor(max_workers=self.jobs, mp_context=_mp_context())
        pool = self._pool
        order = list(first) if first is not None else list(range(len(items)))
        submitted = {j: pool.submit(fn, items[j]) for j in order}
        futures = [submitted[j] for j in range(len(items))]
        try:
            for fut in futures:
                yield fut.result()
        finally:
            for fut in futures:
                fut.cancel()

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
            raise LegbenchError("executor 'dask' needs Dask distributed: pip install 'legbench[dask]'") from exc
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
