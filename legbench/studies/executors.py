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
      server so the parent's threads are never forked), long-lived: each
      imports the engines once (``preload``) and ignores SIGINT, the parent
      stops them; ``jobs = 1`` runs in this process, one task after the other.
    * ``dask`` (:class:`DaskExecutor`): one Dask ``distributed`` task per run,
      on the scheduler at ``scheduler`` (``tcp://host:8786``) or on a
      :class:`distributed.LocalCluster` of ``jobs`` single-threaded workers.
      docs/studies.md says how to set up a real cluster.
"""

from __future__ import annotations

import ast
import importlib
import json
import logging
import multiprocessing
import os
import signal
import sys
import threading
from abc import ABC, abstractmethod
from collections import deque
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, BrokenExecutor, Future, ProcessPoolExecutor, wait
from pathlib import Path
from types import TracebackType
from typing import Any, TypeVar

from legbench.exceptions import LegbenchError

__all__ = [
    "DEFAULT_PRELOAD",
    "EXECUTORS",
    "DaskExecutor",
    "Executor",
    "LocalExecutor",
    "capped",
    "make_executor",
    "warm_up",
]

log = logging.getLogger("legbench.executors")

#: Executor names accepted by :func:`make_executor`.
EXECUTORS = ("local", "dask")

T = TypeVar("T")
R = TypeVar("R")


# --------------------------------------------------------------------------- #
# Executors


class Executor(ABC):
    """Maps a picklable top-level function over tasks.

    The API other modules use (runs, sweeps, report pages): :meth:`map` (a list
    in item order), :meth:`imap` (item order, as each becomes available) and
    :meth:`imap_unordered` (``(index, result)`` pairs as each finishes, longest
    first if ``first`` says so), :meth:`terminate` (stop now: pending items are
    dropped, running ones stopped) and :meth:`close`. An executor is a context
    manager; leaving it by an exception terminates it, otherwise closes it.
    """

    name: str = ""

    def map(self, fn: Callable[[T], R], items: Sequence[T]) -> list[R]:
        """``[fn(x) for x in items]``, computed by the executor's workers."""
        out: list[Any] = [None] * len(items)
        for i, r in self.imap_unordered(fn, items):
            out[i] = r
        return out

    def imap(
        self,
        fn: Callable[[T], R],
        items: Sequence[T],
        first: Sequence[int] | None = None,
        on_crash: Callable[[T, str], R] | None = None,
    ) -> Iterator[R]:
        """``fn(x)`` for each item, yielded in item order as each becomes available.

        Args:
            fn: a picklable top-level function.
            items: its arguments.
            first: item indices in the order to start them (e.g. longest first); default item order.
            on_crash: the result for an item whose worker process died under it (:meth:`imap_unordered`).
        """
        ready: dict[int, R] = {}
        nxt = 0
        for i, r in self.imap_unordered(fn, items, first, on_crash):
            ready[i] = r
            while nxt in ready:
                yield ready.pop(nxt)
                nxt += 1

    @abstractmethod
    def imap_unordered(
        self,
        fn: Callable[[T], R],
        items: Sequence[T],
        first: Sequence[int] | None = None,
        on_crash: Callable[[T, str], R] | None = None,
    ) -> Iterator[tuple[int, R]]:
        """``(i, fn(items[i]))`` for each item, as each finishes; started in the order of ``first``.

        ``on_crash(item, why)``: the result to give for an item whose worker process died under it (an
        engine's segmentation fault, abort, the kernel's out-of-memory kill), so that one crashing task
        does not take the others down; None: such a death ends the whole map (``BrokenExecutor``).
        """

    def start(self) -> None:  # noqa: B027 - optional hook
        """Start the workers now, in the background, so their start-up overlaps the caller's own work (loading
        and planning) instead of delaying the first task. Optional: the first task starts them otherwise."""

    def close(self) -> None:  # noqa: B027 - optional hook
        """Release workers and connections (waits for nothing: every result asked for has been returned)."""

    def terminate(self) -> None:
        """Stop now: drop items not started, stop running ones, release the workers (after Ctrl-C)."""
        self.close()

    def describe(self) -> dict[str, Any]:
        """Executor name and settings, for the sweep's metadata."""
        return {"executor": self.name}

    def __enter__(self) -> Executor:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        if exc_type is None:
            self.close()
        else:
            self.terminate()


#: The modules a worker has imported when it starts: the run loop, the study tasks and every installed engine
#: (importing ``legbench.backends.installed`` imports them), so no task pays for it. The fork server imports
#: them before it forks the workers (:func:`_mp_context`).
DEFAULT_PRELOAD = ("legbench.run", "legbench.studies.tasks", "legbench.backends.installed")
#: :data:`DEFAULT_PRELOAD` without the engines: what a pool of named backends adds their engines' modules to.
TASK_PRELOAD = DEFAULT_PRELOAD[:2]


def _worker_init(preload: Sequence[str]) -> None:
    """Start of a worker process: Ctrl-C is the parent's business (it stops its workers), then the imports."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _preload(preload)


def _preload(preload: Sequence[str]) -> None:
    """Import each module ``preload`` names; failures are left to the tasks."""
    for name in preload:
        try:
            importlib.import_module(name)
        except Exception as exc:  # a task that needs it reports the problem itself
            log.debug("worker preload %s failed: %s", name, exc)


def _noop() -> None:
    """The task :meth:`LocalExecutor.start` gives each worker so that it is spawned."""


def _spawn(pool: ProcessPoolExecutor, n: int) -> None:
    """Hand ``n`` no-op tasks to ``pool``: it spawns its workers (:meth:`LocalExecutor.start`, in a thread).

    The pool spawns a worker per task only while none is idle: a no-op that finished before the next one was
    handed out (a warm fork server forks a ready worker in milliseconds) left one worker for both, so the
    pool is topped up to ``n`` workers here, as its own ``_adjust_process_count`` would spawn them.
    """
    for _ in range(n):
        pool.submit(_noop)
    spawn = getattr(pool, "_spawn_process", None)
    lock = getattr(pool, "_shutdown_lock", None)
    procs = getattr(pool, "_processes", None)
    if spawn is None or lock is None or procs is None:  # another Python's pool: as many as it spawned
        return
    with lock:
        while len(procs) < n and not getattr(pool, "_broken", False) and not getattr(pool, "_shutdown_thread", False):
            spawn()


def _call(fn: Callable[[T], R], x: T) -> R | None:
    """Run one task in a worker; an interrupt reaching it anyway ends the task quietly (no traceback)."""
    try:
        return fn(x)
    except KeyboardInterrupt:
        return None


def _task_text(x: Any) -> str:
    """A task in a few words for a log line: its parts' names (a scenario's, a backend's), not their reprs (a
    Scenario's ran to 2.3 kB on one line)."""
    parts = x if isinstance(x, tuple) else (x,)
    words = [p if isinstance(p, str | int | float) else
             getattr(p, "name", None) or getattr(p, "backend", None) or type(p).__name__ for p in parts]  # fmt: skip
    return ", ".join(map(str, words))[:200]


def _died(code: int | None) -> str:
    """How a worker process ended, in words: ``killed by SIGSEGV`` or ``exit status 1``."""
    if code is None:
        return "ended"
    if code < 0:
        try:
            return f"killed by {signal.Signals(-code).name}"
        except ValueError:
            return f"killed by signal {-code}"
    return f"exit status {code}"


def _mp_context(preload: Sequence[str]) -> multiprocessing.context.BaseContext:
    """Fork server where the platform has one (no fork of a threaded parent), else spawn; the fork server started
    (:func:`_start_server`).

    The fork server imports the numerical stack and the modules ``preload`` names once, before it forks
    the workers: they start with them loaded (shared copy-on-write) instead of each importing them, which
    on two cores competed with the parent's own loading and planning. The server is one per process and
    keeps the preload of the first pool that started it; a worker's initializer imports what is missing.
    """
    method = "forkserver" if "forkserver" in multiprocessing.get_all_start_methods() else "spawn"
    ctx = multiprocessing.get_context(method)
    if method == "forkserver":
        first = ["legbench.studies.server_env", "numpy", "pandas"]  # the environment put back before any import
        ctx.set_forkserver_preload(list(dict.fromkeys([*first, *preload])))  # type: ignore[attr-defined]
        _start_server()
    return ctx


_SERVER_LOCK = threading.Lock()
#: Python's fork server ignores the import path its parent sends (CPython gh-117378, fixed in 3.12.8 and 3.13.1).
_SERVER_PATH_IGNORED = sys.version_info < (3, 12, 8) or (3, 13) <= sys.version_info < (3, 13, 1)


def _start_server() -> None:
    """Start the fork server, if it is not running, on this process's import path, not the current directory's.

    The server is a ``python -c`` process, which puts the current directory first on its path, and the Pythons of
    :data:`_SERVER_PATH_IGNORED` ignore the path the parent sends it: run from another checkout's directory, the
    server imported that checkout's legbench for its preload and every worker forked from it ran that code, not
    the one the user called. There the server is started with ``PYTHONSAFEPATH`` (no current directory) and
    ``PYTHONPATH`` this process's ``sys.path``, the workaround the CPython fix names; this process's environment is
    put back as soon as the server process exists, and the server's by the first module it imports
    (:mod:`legbench.studies.server_env`), so nothing it forks inherits them. (An interpreter run with ``-E`` or
    ``-I`` passes that flag on and the server ignores both variables; a server that died and is started again by
    the pool itself is started without them.)
    """
    from multiprocessing import forkserver

    if not _SERVER_PATH_IGNORED or getattr(forkserver._forkserver, "_forkserver_pid", None) is not None:
        forkserver.ensure_running()  # already started (a no-op), or a Python that sends the path itself
        return
    path = os.pathsep.join(os.path.abspath(p) if p == "" else p for p in sys.path)
    with _SERVER_LOCK:
        saved = {name: os.environ.get(name) for name in ("PYTHONSAFEPATH", "PYTHONPATH", "LEGBENCH_FORKSERVER_ENV")}
        try:
            parent = {name: saved[name] for name in ("PYTHONSAFEPATH", "PYTHONPATH")}  # for server_env to put back
            os.environ.update(PYTHONSAFEPATH="1", PYTHONPATH=path, LEGBENCH_FORKSERVER_ENV=json.dumps(parent))
            forkserver.ensure_running()
        finally:
            for name, value in saved.items():
                if value is None:
                    os.environ.pop(name, None)
                else:
                    os.environ[name] = value


def warm_up(preload: Sequence[str] = DEFAULT_PRELOAD) -> None:
    """Start the fork server now, for a caller that learns how many tasks it has only later: the server imports
    ``preload`` in the background while the caller plans, and the workers a :class:`LocalExecutor` made after
    (sized to the tasks) fork from it ready, in milliseconds. Nothing where there is no fork server."""
    _mp_context(preload)  # starts the fork server where there is one


def capped(jobs: int | None, tasks: int | None) -> int:
    """The worker count: ``jobs`` (default: the CPU count), checked >= 1, at most ``tasks`` (and at least 1)."""
    n = int(jobs) if jobs else (os.cpu_count() or 1)
    if n < 1:
        raise LegbenchError(f"jobs must be >= 1, got {jobs}")
    return n if tasks is None else max(1, min(n, tasks))


def _check_main_guard(jobs: int) -> None:
    """Before a pool of ``jobs > 1`` workers that import the main script anew (fork server or spawn) is made,
    refuse a start from the script's top-level code outside ``if __name__ == "__main__":``: each worker would run
    that code again, and died (every backend of a run came back "failed: the engine crashed"; a sweep's or a
    reproduce's workers alike). A main module read from stdin cannot be imported by a worker at all. Interactive
    sessions (Jupyter, ``python -c``) have no main file, and a start from another thread no module frame to
    look at: nothing to check."""
    main = sys.modules.get("__main__")
    file = getattr(main, "__file__", None)
    if jobs <= 1 or main is None or not isinstance(file, str):
        return
    if not Path(file).is_file():
        raise LegbenchError(f"jobs {jobs}: the main module {file} is not a file the worker processes can import; "
                            "run a script file, or jobs=1")  # fmt: skip
    frame: Any = sys._getframe(1)
    while frame is not None and not (frame.f_globals is vars(main) and frame.f_code.co_name == "<module>"):
        frame = frame.f_back
    if frame is None or frame.f_code.co_filename != file:
        return  # called from elsewhere (a function run by another entry point)
    try:
        tree = ast.parse(Path(file).read_text(encoding="utf-8"))
    except (OSError, SyntaxError, ValueError):
        return
    line = frame.f_lineno
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and any(
            isinstance(n, ast.Name) and n.id == "__name__" for n in ast.walk(node.test)
        ):
            if node.body[0].lineno <= line <= (node.end_lineno or line):
                return
    raise LegbenchError(f'{file}:{line}: {jobs} worker processes started outside `if __name__ == "__main__":`; '
                        "they import the script again and would run it again: put the call under that guard, or "
                        "use jobs=1")  # fmt: skip


class LocalExecutor(Executor):
    """A pool of ``jobs`` long-lived local worker processes; ``jobs = 1`` runs in this process.

    The pool is started on first use and kept until :meth:`close`, so a study
    that maps several times (a sweep's references, then its runs) reuses the
    same workers, each of which imported the engines once (``preload``).
    Workers ignore SIGINT: Ctrl-C reaches the parent, which stops them
    (:meth:`terminate`), so no worker prints a traceback.
    """

    name = "local"

    def __init__(
        self, jobs: int | None = None, preload: Sequence[str] = DEFAULT_PRELOAD, tasks: int | None = None
    ) -> None:
        """Args:
        jobs: number of worker processes (default: the CPU count).
        preload: imported by each worker when it starts (see :data:`DEFAULT_PRELOAD`).
        tasks: how many tasks the pool will have at most at once, where the caller knows it: no more workers
            than that are started (each is a process that imports the engines; ``--jobs 1000`` for two
            runs started 1000).
        """
        self.jobs = capped(jobs, tasks)
        self.preload = tuple(preload)
        self._pool: ProcessPoolExecutor | None = None
        self._starter: threading.Thread | None = None

    def _get_pool(self) -> ProcessPoolExecutor:
        if self._pool is None:
            _check_main_guard(self.jobs)  # fork server or spawn: the workers import the main script again
            context = _mp_context(self.preload)  # (checked before a server is started)
            self._pool = ProcessPoolExecutor(
                max_workers=self.jobs,
                mp_context=context,
                initializer=_worker_init,
                initargs=(self.preload,),
            )
        return self._pool

    def imap_unordered(
        self,
        fn: Callable[[T], R],
        items: Sequence[T],
        first: Sequence[int] | None = None,
        on_crash: Callable[[T, str], R] | None = None,
    ) -> Iterator[tuple[int, R]]:
        """As :meth:`Executor.imap_unordered`; ``jobs = 1`` runs each item in this process, in ``first`` order.

        Items are handed to the workers one at a time as workers free up, in the
        order of ``first``, so the longest can be started first. On an exception
        while waiting (Ctrl-C) the items not started are cancelled.

        A worker that dies breaks the whole process pool, and every item then in
        it with it. With ``on_crash`` the items that were in the pool are run
        again one at a time, each alone in a one-worker pool: the one whose worker
        dies again gets ``on_crash(item, why)``, the others their results; then
        the remaining items go on in a new pool. (Ctrl-C and SIGTERM reach this
        process as KeyboardInterrupt: workers ignore SIGINT, and a signal to the
        process group interrupts this process's wait before the pool notices its
        workers gone.)
        """
        order = list(first) if first is not None else list(range(len(items)))
        if sorted(order) != list(range(len(items))):
            raise ValueError("first must be a permutation of the item indices")
        if self.jobs == 1 or len(items) <= 1:
            for j in order:
                yield j, fn(items[j])
            return
        self._started()
        pool = self._get_pool()
        pending = deque(order)
        running: dict[Future[Any], int] = {}
        broken = False  # the pool refused a submission: it broke between a result and the next item

        def submit() -> None:
            nonlocal broken
            if pending and not broken:
                j = pending.popleft()
                try:
                    running[pool.submit(_call, fn, items[j])] = j
                except BrokenExecutor:
                    if on_crash is None:
                        raise
                    pending.appendleft(j)  # not started: it goes on in the next pool
                    broken = True

        try:
            for _ in range(self.jobs):
                submit()
            while running or (broken and pending):
                done, _ = wait(running, return_when=FIRST_COMPLETED) if running else (set(), set())
                if on_crash is not None and (broken or any(isinstance(f.exception(), BrokenExecutor) for f in done)):
                    broken = False
                    suspects = []
                    for fut, j in sorted(running.items(), key=lambda fj: fj[1]):
                        ok = fut.done() and not fut.cancelled() and fut.exception() is None
                        if ok:  # finished before the pool broke
                            yield j, fut.result()
                        else:
                            suspects.append(j)
                    running.clear()
                    self.terminate()
                    for j in suspects:
                        yield j, self._alone(fn, items[j], on_crash)
                    pool = self._get_pool()
                    for _ in range(self.jobs):
                        submit()
                    continue
                for fut in sorted(done, key=lambda f: running[f]):
                    j = running.pop(fut)
                    submit()
                    yield j, fut.result()
        finally:
            for fut in running:
                fut.cancel()

    def _alone(self, fn: Callable[[T], R], x: T, on_crash: Callable[[T, str], R]) -> R:
        """``fn(x)`` alone in a one-worker pool; ``on_crash(x, why)`` if its worker dies (it is the culprit)."""
        solo = ProcessPoolExecutor(
            max_workers=1,
            mp_context=_mp_context(self.preload),
            initializer=_worker_init,
            initargs=(self.preload,),
        )
        fut: Future[Any] = solo.submit(_call, fn, x)
        procs = list((getattr(solo, "_processes", None) or {}).values())
        finished = False
        try:
            try:
                out = fut.result()
            except BrokenExecutor:
                # the pool's own thread reaps its worker: wait for it, then read the exit status it read (a
                # second reader of the fork server's status pipe racing it got end-of-file: "exit status 255")
                solo.shutdown(wait=True)
                why = _died(procs[0].exitcode if procs else None)
                log.warning("a worker process died (%s) running %s", why, _task_text(x))
                out = on_crash(x, f"its worker process died ({why}); the other tasks ran on")
            finished = True
            return out
        finally:
            if finished:
                solo.shutdown(wait=True)
            else:  # interrupted while it ran: stop it now
                solo.shutdown(wait=False, cancel_futures=True)
                for p in procs:
                    if p.is_alive():
                        p.kill()
                        p.join()

    def start(self) -> None:
        """Spawn the ``jobs`` workers now (one no-op task each, not waited for): they import ``preload`` while
        the caller goes on. Nothing with ``jobs = 1`` (the tasks run in this process)."""
        if self.jobs > 1 and self._pool is None:
            pool = self._get_pool()
            # from a thread: the first worker's start waits for the fork server to import its preload (~1.5 s)
            self._starter = threading.Thread(target=_spawn, args=(pool, self.jobs), daemon=True)
            self._starter.start()

    def _started(self) -> None:
        """Wait until :meth:`start`'s thread has handed out its tasks (before using or stopping the pool)."""
        if self._starter is not None:
            self._starter.join()
            self._starter = None

    def close(self) -> None:
        self._started()
        if self._pool is not None:
            self._pool.shutdown(wait=True)
            self._pool = None

    def terminate(self) -> None:
        """Stop the workers now (SIGTERM, then SIGKILL after ``2 s``); results already returned are kept.

        A worker stopped while it was sending a result leaves half a message in the result pipe, and the
        pool's manager thread, reading it, would wait for the rest forever (this process holds the pipe's
        write end too, so no end-of-file comes), and with it the interpreter's exit, which joins that thread.
        Once the workers are gone this process closes its write end: the read ends with EOFError, which
        the pool takes as a broken pool, and its thread ends.
        """
        self._started()
        pool, self._pool = self._pool, None
        if pool is None:
            return
        procs = list((getattr(pool, "_processes", None) or {}).values())
        results = getattr(pool, "_result_queue", None)  # shutdown() forgets it
        pool.shutdown(wait=False, cancel_futures=True)
        for p in procs:
            if p.is_alive():
                p.terminate()
        for p in procs:
            p.join(2.0)
            if p.is_alive():
                p.kill()
                p.join()
        writer = getattr(results, "_writer", None)
        if writer is not None:
            writer.close()

    def describe(self) -> dict[str, Any]:
        return {"executor": self.name, "jobs": self.jobs}


class DaskExecutor(Executor):
    """Each item a Dask ``distributed`` task, on a given scheduler or on a local cluster."""

    name = "dask"

    def __init__(
        self,
        scheduler: str | None = None,
        jobs: int | None = None,
        processes: bool = True,
        preload: Sequence[str] = DEFAULT_PRELOAD,
        tasks: int | None = None,
    ) -> None:
        """Args:
        scheduler: address of a running scheduler (``tcp://host:8786``); None starts a
            :class:`distributed.LocalCluster` owned by this executor.
        jobs: workers of the local cluster (default: the CPU count); ignored with a scheduler.
        processes: local cluster workers are processes (True) or threads of this process.
        preload: imported once by every worker before the first task (:data:`DEFAULT_PRELOAD`).
        tasks: at most this many tasks at once, where known: the local cluster has no more workers.
        """
        try:
            import distributed
        except ImportError as exc:
            raise LegbenchError("executor 'dask' needs Dask distributed: pip install 'legbench[dask]'") from exc
        self.scheduler = scheduler
        self.jobs = capped(jobs, tasks)
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
        if preload:  # each worker imports the engines once, before the first task
            self.client.run(_preload, tuple(preload))

    def imap_unordered(
        self,
        fn: Callable[[T], R],
        items: Sequence[T],
        first: Sequence[int] | None = None,
        on_crash: Callable[[T, str], R] | None = None,
    ) -> Iterator[tuple[int, R]]:
        """As :meth:`Executor.imap_unordered`: one Dask task per item, with priority by ``first``.

        The workers are long-lived (a Dask worker keeps its imports between
        tasks), so the engines are imported once per worker. ``on_crash`` is not
        used: Dask itself retries a task whose worker died and, after its
        ``allowed-failures``, raises ``KilledWorker`` for it.
        """
        if not items:
            return
        import distributed

        order = list(first) if first is not None else list(range(len(items)))
        rank = {j: len(order) - r for r, j in enumerate(order)}  # higher priority starts first
        futures = {self.client.submit(fn, items[j], pure=False, priority=rank[j]): j for j in order}
        try:
            for fut in distributed.as_completed(list(futures)):
                yield futures[fut], fut.result()
        finally:
            for fut in futures:
                if not fut.done():
                    fut.cancel()

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


def make_executor(
    kind: str = "local",
    jobs: int | None = None,
    scheduler: str | None = None,
    preload: Sequence[str] = DEFAULT_PRELOAD,
    tasks: int | None = None,
) -> Executor:
    """The executor named ``kind`` (one of :data:`EXECUTORS`).

    Args:
        kind: ``"local"`` or ``"dask"``.
        jobs: worker count (local pool size, or local Dask cluster size).
        scheduler: Dask scheduler address; only with ``kind = "dask"``.
        preload: what each local worker imports once when it starts (:data:`DEFAULT_PRELOAD`).
        tasks: the most tasks it will run at once, where the caller knows it: no more workers than that.

    Raises:
        LegbenchError: an unknown executor, a scheduler given to the local one,
            Dask not installed, or a scheduler that cannot be reached.
    """
    if kind == "local":
        if scheduler:
            raise LegbenchError("--scheduler needs --executor dask")
        return LocalExecutor(jobs, preload, tasks)
    if kind == "dask":
        return DaskExecutor(scheduler, jobs, preload=preload, tasks=tasks)
    raise LegbenchError(f"unknown executor '{kind}'; choose one of {', '.join(EXECUTORS)}")
