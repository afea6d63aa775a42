"""Executors: a sweep gives the same table, bit for bit, on the local pool and on Dask, at any job count."""

from __future__ import annotations

import math
import os
from collections.abc import Generator
from concurrent.futures import BrokenExecutor, Future
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path
from typing import Any, cast

import pandas as pd
import pytest

from legbench import backends
from legbench.exceptions import LegbenchError
from legbench.studies import executors, sweep, tasks

FREE_SPACE = Path(__file__).resolve().parents[1] / "scenarios" / "verification" / "free_space.yaml"
TIMING = ["wall_time", "rtf", "wall_per_sim_s"]  # measured, so they differ between runs


@pytest.fixture(scope="module")
def small_sweep(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Two backends x two steps against a Pinocchio reference, with short-horizon replays (exercises both phases)."""
    names = [n for n in ("pinocchio", "mujoco") if n in backends.available()]
    path = tmp_path_factory.mktemp("sweep") / "small.yaml"
    path.write_text(f"""
name: small
scenario: {FREE_SPACE}
set: {{duration: 0.1}}
signals: [q, qd, force, ee]
short_horizon: {{window: 0.02}}
studies:
  - backends: {names}
    set: {{backends.*.integrator: euler}}
    grid: {{backends.*.dt: [1.0e-3, 5.0e-4]}}
    reference: {{backend: pinocchio, set: {{backends.pinocchio.dt: 1.0e-4}}}}
""")
    return path


def _physics(result: sweep.SweepResult) -> pd.DataFrame:
    return result.table.drop(columns=TIMING)


@pytest.fixture(scope="module")
def serial(small_sweep: Path) -> sweep.SweepResult:
    return sweep.run_sweep(small_sweep, None, "local", jobs=1)


def test_local_pool_matches_serial_bit_for_bit(small_sweep: Path, serial: sweep.SweepResult) -> None:
    pooled = sweep.run_sweep(small_sweep, None, "local", jobs=2)
    pd.testing.assert_frame_equal(_physics(pooled), _physics(serial), check_exact=True)
    pd.testing.assert_frame_equal(pooled.windows, serial.windows, check_exact=True)
    assert len(serial.windows) and (serial.table["status"] == "ok").all()


def test_dask_local_cluster_matches_local_pool(small_sweep: Path, serial: sweep.SweepResult) -> None:
    pytest.importorskip("distributed")
    with executors.DaskExecutor(jobs=2, processes=False) as ex:
        result = sweep.run_sweep(small_sweep, None, ex)
        assert ex.describe()["executor"] == "dask"
    pd.testing.assert_frame_equal(_physics(result), _physics(serial), check_exact=True)
    pd.testing.assert_frame_equal(result.windows, serial.windows, check_exact=True)


def test_dask_scheduler_address_matches_local_pool(small_sweep: Path, serial: sweep.SweepResult) -> None:
    """The path a real cluster takes: connect to a scheduler by address (here one started in-process)."""
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=1, threads_per_worker=2, processes=False, dashboard_address=None) as c:
        result = sweep.run_sweep(small_sweep, None, "dask", scheduler=c.scheduler_address)
    pd.testing.assert_frame_equal(_physics(result), _physics(serial), check_exact=True)


def test_local_pool_returns_results_in_task_order() -> None:
    with executors.LocalExecutor(2) as ex:
        assert ex.map(math.sqrt, [16.0, 1.0, 9.0, 4.0]) == [4.0, 1.0, 3.0, 2.0]
    assert executors.LocalExecutor(1).map(math.sqrt, []) == []


def test_run_task_reports_a_missing_backend_instead_of_raising() -> None:
    res = tasks.run_task(tasks.RunTask(7, str(FREE_SPACE), {"duration": 0.1}, "nonexistent"))
    assert res.index == 7 and res.run.status == "missing" and "nonexistent" in (res.run.reason or "")


def test_executor_errors_are_clear() -> None:
    with pytest.raises(LegbenchError, match="unknown executor 'ray'; choose one of local, dask"):
        executors.make_executor("ray")
    with pytest.raises(LegbenchError, match="--scheduler needs --executor dask"):
        executors.make_executor("local", scheduler="tcp://x:8786")
    with pytest.raises(LegbenchError, match="jobs must be >= 1"):
        executors.LocalExecutor(-1)


def _worker_state(_: int) -> tuple[int, bool, bool]:
    """In a worker: its pid, whether it ignores SIGINT, whether the run loop and the engines were preloaded."""
    import os
    import signal
    import sys

    engines = any(m.startswith("legbench.backends.") and m.endswith("_") for m in sys.modules)
    return os.getpid(), signal.getsignal(signal.SIGINT) is signal.SIG_IGN, "legbench.run" in sys.modules and engines


def test_workers_ignore_sigint_import_once_and_are_reused() -> None:
    """Workers are long-lived: two maps on one executor run in the same <= jobs processes, which imported
    the run loop and the engines when they started and leave Ctrl-C to the parent."""
    with executors.LocalExecutor(2) as ex:
        first = ex.map(_worker_state, list(range(4)))
        second = ex.map(_worker_state, list(range(4)))
    pids = {pid for pid, _, _ in first + second}
    assert 1 <= len(pids) <= 2  # new processes per map would be up to four (which worker takes a task is not fixed)
    assert all(ign for _, ign, _ in first) and all(pre for _, _, pre in first)


def test_start_spawns_the_workers_before_the_first_task() -> None:
    """``start()`` spawns ``jobs`` workers at once (they import the engines while the caller plans); the tasks
    then run in those same processes. With one job nothing is spawned (tasks run in this process)."""
    serial = executors.LocalExecutor(1)
    serial.start()
    assert serial._pool is None
    ex = executors.LocalExecutor(2)  # bound outside the with: __enter__ is typed as returning the base Executor
    with ex:
        ex.start()  # returns at once; the workers are spawned from a thread
        ex._started()  # the thread has handed out its tasks: the processes exist
        pool = ex._pool
        assert pool is not None
        started = {p.pid for p in (getattr(pool, "_processes", None) or {}).values()}
        assert len(started) == 2  # spawned by start(), before any task was submitted by a map
        got = ex.map(_worker_state, list(range(4)))
    assert {pid for pid, _, _ in got} <= started
    assert all(ign and pre for _, ign, pre in got)


def test_a_pool_starts_no_more_workers_than_its_tasks() -> None:
    """``tasks``: a pool told it has two tasks starts two workers, not ``jobs`` (``--jobs 8`` for two runs
    started eight processes, each importing every engine); at least one, and ``jobs`` below 1 is still refused."""
    ex = executors.LocalExecutor(8, preload=(), tasks=2)
    with ex:
        ex.start()
        ex._started()  # the thread has handed out its tasks: the processes exist
        assert ex._pool is not None
        assert len(ex._pool._processes) == 2  # type: ignore[attr-defined]
        assert ex.map(math.sqrt, [4.0, 9.0]) == [2.0, 3.0]
        assert len(ex._pool._processes) == 2  # type: ignore[attr-defined]
    assert executors.make_executor("local", 8, tasks=3).jobs == 3  # type: ignore[attr-defined]
    assert executors.make_executor("local", 2, tasks=5).jobs == 2  # type: ignore[attr-defined]
    assert executors.LocalExecutor(4, tasks=0).jobs == 1
    with pytest.raises(LegbenchError, match="jobs must be >= 1"):
        executors.LocalExecutor(-1, tasks=2)


def test_the_start_spawns_every_worker_even_when_the_first_is_already_idle(monkeypatch: pytest.MonkeyPatch) -> None:
    """The pool spawns a worker per task only while none is idle: when the first no-op is done before the second
    is handed out (as a warm fork server makes it within milliseconds; forced here by waiting for each), the
    second found that worker idle and spawned none (seen as a failure of the start test under load); the start
    tops the pool up to its two workers."""
    pool = executors.ProcessPoolExecutor(max_workers=2, mp_context=executors._mp_context(executors.DEFAULT_PRELOAD))
    submit = pool.submit

    def submit_and_wait(*args: Any) -> Future[Any]:
        fut = submit(*args)
        fut.result()
        return fut

    monkeypatch.setattr(pool, "submit", submit_and_wait)
    try:
        executors._spawn(pool, 2)
        assert len(pool._processes) == 2  # type: ignore[attr-defined]
    finally:
        pool.shutdown(wait=True)


def test_imap_unordered_starts_in_the_given_order_and_yields_every_item_once() -> None:
    items = [0.0, 1.0, 4.0, 9.0, 16.0]
    order = [4, 2, 0, 1, 3]
    serial = list(executors.LocalExecutor(1).imap_unordered(math.sqrt, items, order))
    assert serial == [(j, math.sqrt(items[j])) for j in order]  # one job: exactly the order given
    with executors.LocalExecutor(2) as ex:
        pooled = list(ex.imap_unordered(math.sqrt, items, order))
        assert list(ex.imap(math.sqrt, items, order)) == [0.0, 1.0, 2.0, 3.0, 4.0]  # imap: item order
    assert sorted(pooled) == sorted(serial)
    with pytest.raises(ValueError, match="permutation"):
        list(executors.LocalExecutor(1).imap_unordered(math.sqrt, items, [0, 0, 1, 2, 3]))


def _square_or_crash(task: tuple[int, str, Any]) -> int:
    """In a worker: x * x; for x == 3 the process writes its pid to ``marker``, sets ``ready`` (an Event of a
    multiprocessing manager) and kills itself with SIGSEGV, as an engine's segmentation fault. Items after it
    return only once that process has ended (the observable event: they block on ``ready``, then on a pidfd of
    the process, which becomes readable when it exits), so they are still in the pool when it breaks, however
    fast the machine; 60 s bounds each wait, it is not a wait."""
    import os
    import select
    import signal
    from pathlib import Path

    x, marker, ready = task
    if x == 3:
        Path(marker).write_text(str(os.getpid()))
        ready.set()
        os.kill(os.getpid(), signal.SIGSEGV)
    if x > 3:
        if not ready.wait(60.0):
            raise TimeoutError("item 3 never ran")
        try:
            fd = os.pidfd_open(int(Path(marker).read_text()))
        except ProcessLookupError:  # ended and reaped already
            return x * x
        try:
            if not select.select([fd], [], [], 60.0)[0]:
                raise TimeoutError("item 3's worker never ended")
        finally:
            os.close(fd)
    return x * x


def test_a_task_that_kills_its_worker_gets_on_crash_and_the_others_their_results(tmp_path: Path) -> None:
    """Item 3 of 8 kills its worker (SIGSEGV): the pool breaks with every item in it, and with ``on_crash``
    those are run again one by one in a pool of their own: item 3 gets on_crash's result naming the signal,
    every other item its own square, each exactly once. Without on_crash the map ends with BrokenExecutor."""
    import multiprocessing

    marker = str(tmp_path / "crashed.pid")
    with multiprocessing.Manager() as manager:
        ready = manager.Event()
        items = [(x, marker, ready) for x in range(8)]
        with executors.LocalExecutor(2) as ex:
            got = list(ex.imap_unordered(_square_or_crash, items, None, lambda t, why: f"crashed {t[0]}: {why}"))
            again = sorted(ex.imap_unordered(_square_or_crash, [(4, marker, ready), (5, marker, ready)]))
            assert again == [(0, 16), (1, 25)]  # the new pool works on
        assert sorted(j for j, _ in got) == list(range(8))
        res = dict(got)
        assert str(res[3]).startswith("crashed 3: its worker process died (killed by SIGSEGV)"), res[3]
        assert all(res[j] == j * j for j in range(8) if j != 3)
        fresh = manager.Event()
        with pytest.raises(BrokenExecutor), executors.LocalExecutor(2) as ex:
            list(ex.imap_unordered(_square_or_crash, [(x, marker, fresh) for x in range(8)]))


class _OncePool:
    """A stand-in process pool that runs each task at once in this process. ``break_after``: the submission after
    that many raises BrokenProcessPool, as a pool whose worker died between a result and the next item;
    ``crash_on``: the task for that item comes back broken (its future holds BrokenProcessPool), as the futures
    of a pool whose worker died under them."""

    def __init__(self, break_after: int | None = None, crash_on: float | None = None) -> None:
        self.break_after, self.crash_on, self.submitted = break_after, crash_on, 0

    def submit(self, fn: Any, *args: Any) -> Future[Any]:
        if self.break_after is not None and self.submitted >= self.break_after:
            raise BrokenProcessPool("a worker died")
        self.submitted += 1
        fut: Future[Any] = Future()
        if self.crash_on is not None and args and args[-1] == self.crash_on:
            fut.set_exception(BrokenProcessPool("a worker died"))
        else:
            fut.set_result(fn(*args))
        return fut

    def shutdown(self, wait: bool = True, cancel_futures: bool = False) -> None:
        pass


def test_a_pool_that_breaks_between_a_result_and_the_next_submission_goes_on_in_a_new_pool(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The pool breaks after two submissions, with nothing of it running (its worker died idle, or just after
    returning): with on_crash the third item goes to a new pool and every item comes back once (it raised
    BrokenProcessPool out of the map); without on_crash that is still the map's end."""
    pools = iter([_OncePool(2), _OncePool(None), _OncePool(2)])
    monkeypatch.setattr(executors, "ProcessPoolExecutor", lambda **kw: next(pools))
    ex = executors.LocalExecutor(2)
    got = list(ex.imap_unordered(math.sqrt, [0.0, 1.0, 4.0, 9.0, 16.0], None, lambda x, why: -1.0))
    assert sorted(got) == [(0, 0.0), (1, 1.0), (2, 2.0), (3, 3.0), (4, 4.0)]
    with pytest.raises(BrokenProcessPool):
        list(executors.LocalExecutor(2).imap_unordered(math.sqrt, [0.0, 1.0, 4.0]))


def test_a_result_finished_beside_the_crash_is_kept_and_the_crash_alone_is_rerun(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Items 2 (the crash) and 3 are in the pool together and both done when it breaks: item 3's result, finished
    before the break, is yielded as it is; only item 2 runs again, alone (it crashes again: on_crash's -1),
    then item 4 goes on in a new pool. Three pools in all (the first, item 2's one-worker pool, the new one),
    every item exactly once."""
    pools = [_OncePool(crash_on=4.0), _OncePool(crash_on=4.0), _OncePool()]
    made: list[_OncePool] = []

    def make(**kw: Any) -> _OncePool:
        made.append(pools[len(made)])
        return made[-1]

    monkeypatch.setattr(executors, "ProcessPoolExecutor", make)
    got = list(
        executors.LocalExecutor(2).imap_unordered(math.sqrt, [0.0, 1.0, 4.0, 9.0, 16.0], None, lambda x, why: -1.0)
    )
    assert sorted(got) == [(0, 0.0), (1, 1.0), (2, -1.0), (3, 3.0), (4, 4.0)]
    assert made == pools


def test_terminate_stops_running_workers_and_keeps_what_finished() -> None:
    """A worker busy with a long task is stopped by terminate() (SIGTERM, then SIGKILL after 2 s: the blocked
    tasks never end by themselves); the result that finished before is kept."""
    ex = executors.LocalExecutor(2)
    # LocalExecutor.imap_unordered is a generator function, so its result has close()
    it = cast("Generator[tuple[int, int], None, None]", ex.imap_unordered(_pid_or_block, [0, 1, 1], [0, 1, 2]))
    j, pid = next(it)  # the quick item finished: the others are running or queued
    assert j == 0 and isinstance(pid, int)
    pool = ex._pool
    assert pool is not None
    procs = list(pool._processes.values())  # type: ignore[attr-defined]
    ex.terminate()
    assert procs and all(not p.is_alive() for p in procs)
    assert all(p.pid is not None and not _alive(p.pid) for p in procs)
    it.close()


def _pid_or_block(block: int) -> int:
    """In a worker: its pid now (0), or never (1: a task that only terminate() ends)."""
    import os
    import threading

    if block:
        threading.Event().wait()
    return os.getpid()


def _alive(pid: int) -> bool:
    import os

    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return True


def test_terminate_during_a_half_sent_result_lets_the_interpreter_exit(tmp_path: Path) -> None:
    """A worker stopped in the middle of sending its result (Ctrl-C at that instant) leaves half a message in
    the result pipe. After terminate() the command still exits, at once and with status 0: before the fix it
    hung at exit, the pool's thread waiting for the rest of the message (seen in a sweep interrupted under load).
    The workers here write that half message themselves, then block, so the state is certain, not a race."""
    import subprocess
    import sys

    (tmp_path / "half_sent.py").write_text("""
import gc, os, struct, threading
from multiprocessing.queues import SimpleQueue

def half_send(marker: str) -> int:
    q = next(o for o in gc.get_objects() if isinstance(o, SimpleQueue))  # the pool's result queue
    os.write(q._writer.fileno(), struct.pack("!i", 1 << 20) + b"half")  # a 1 MiB message, 4 bytes of it
    open(marker + str(os.getpid()), "w").close()
    threading.Event().wait()
    return 0
""")
    (tmp_path / "main.py").write_text(f"""
import os, select, sys, threading
sys.path.insert(0, {str(tmp_path)!r})
from half_sent import half_send
from legbench.studies.executors import LocalExecutor

if __name__ == "__main__":
    marker = {str(tmp_path / "sent-")!r}
    ex = LocalExecutor(2, preload=())
    threading.Thread(target=lambda: list(ex.imap_unordered(half_send, [marker, marker])), daemon=True).start()
    d = os.path.dirname(marker)
    while len([f for f in os.listdir(d) if f.startswith("sent-")]) < 2:  # both workers wrote their half message
        select.select([], [], [], 0.01)
    ex.terminate()
    print("terminated", flush=True)
""")
    done = subprocess.run([sys.executable, str(tmp_path / "main.py")], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0 and "terminated" in done.stdout, done.stderr


def test_dask_imap_unordered_yields_every_item_once() -> None:
    pytest.importorskip("distributed")
    items = [1.0, 4.0, 9.0]
    with executors.DaskExecutor(jobs=2, processes=False, preload=()) as ex:
        got = sorted(ex.imap_unordered(math.sqrt, items, [2, 1, 0]))
        assert ex.map(math.sqrt, items) == [1.0, 2.0, 3.0]
    assert got == [(0, 1.0), (1, 2.0), (2, 3.0)]


def test_preloading_the_engines_survives_a_backend_that_fails_to_import(tmp_path: Path) -> None:
    """``legbench.backends.installed`` (imported by the pool's fork server before it forks the workers) imports
    every backend that can run here and lets none that fails stop the import: a built-in whose module is
    missing is left out and the others are there; so is one that raises something else than ImportError (it
    emptied the preload before; escaping, it would kill the fork server)."""
    import subprocess
    import sys

    (tmp_path / "raising_engine_.py").write_text("raise RuntimeError('engine broken at import')\n")

    def names(module: str) -> list[str]:
        code = (
            "from legbench import backends\n"
            f"backends.BUILTIN['broken'] = ({module!r}, 'X', 'nothing')\n"
            "import legbench.backends.installed as inst\n"
            "print(','.join(inst.NAMES))\n"
        )
        env = {**os.environ, "PYTHONPATH": str(tmp_path)}
        out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120)
        assert out.returncode == 0, out.stderr
        return out.stdout.strip().split(",")

    for module in ("legbench.backends.no_such_engine_", "raising_engine_"):  # the second raises RuntimeError
        preloaded = names(module)
        assert "broken" not in preloaded, module
        assert set(backends.available()) <= set(preloaded) and "pinocchio" in preloaded, module


def test_a_pool_started_at_a_scripts_top_level_is_refused(tmp_path: Path) -> None:
    """A script that starts a pool of 2 in its top-level code, outside ``if __name__ == "__main__":``: the fork
    server's workers import the script again and run that code again (a sweep's or a reproduce's workers died).
    The pool refuses to start, naming the script's line and the guard; no worker process is made."""
    import subprocess
    import sys

    script = tmp_path / "bare.py"
    script.write_text("from legbench.studies import executors\n\nex = executors.LocalExecutor(2, preload=())\n"
                      "print(ex.map(abs, [-1, -2]))\n")  # fmt: skip
    done = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=300)
    last = done.stderr.strip().splitlines()[-1]
    assert done.returncode == 1 and done.stdout == "", done.stdout
    assert last.startswith(f"legbench.exceptions.LegbenchError: {script}:4: 2 worker processes started outside")


def test_workers_run_the_legbench_the_parent_runs_not_the_one_in_the_current_directory(tmp_path: Path) -> None:
    """Started from a directory holding another legbench (another checkout), the fork server, a ``python -c``
    process with the current directory first on its path, imported that one for its preload and every worker
    ran it (CPython gh-117378, Python < 3.12.8). Each worker now has the parent's legbench, and the parent's
    PYTHONPATH and PYTHONSAFEPATH (set for the server's start only), and so has a worker of another library's
    fork-server pool in the same program (the server is one per process)."""
    import subprocess
    import sys

    import legbench

    other = tmp_path / "other_checkout"
    (other / "legbench").mkdir(parents=True)
    (other / "legbench" / "__init__.py").write_text("OTHER_CHECKOUT = True\n")
    script = tmp_path / "main.py"
    script.write_text(
        "import multiprocessing, os\n"
        "from legbench.studies import executors\n\n"
        "def where(_):\n"
        "    import legbench\n"
        "    return legbench.__file__, os.environ.get('PYTHONSAFEPATH'), os.environ.get('PYTHONPATH')\n\n"
        "if __name__ == '__main__':\n"
        "    with executors.LocalExecutor(2, preload=('legbench.studies.executors',)) as ex:\n"
        "        rows = ex.map(where, [0, 1])\n"
        "    with multiprocessing.get_context('forkserver').Pool(1) as pool:  # another library's, the same server\n"
        "        rows += pool.map(where, [2])\n"
        "    for row in rows:\n"
        "        print(*row, sep='|')\n"
    )
    env = {k: v for k, v in os.environ.items() if k != "PYTHONSAFEPATH"}
    # the legbench under test first (the checkout this test runs from, not necessarily the installed one)
    env["PYTHONPATH"] = os.pathsep.join([str(Path(legbench.__file__).parents[1]), str(tmp_path / "no_such_dir")])
    done = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, cwd=other, env=env,
                          timeout=300)  # fmt: skip
    assert done.returncode == 0, done.stderr
    rows = [line.split("|") for line in done.stdout.splitlines()]
    assert rows == [[legbench.__file__, "None", env["PYTHONPATH"]]] * 3


def test_a_crashed_tasks_log_line_names_it_in_a_few_words() -> None:
    """A crashed run's warning printed the task's repr: the whole Scenario, 2.3 kB on one line. It names the
    scenario and backend now."""
    from legbench import scenario
    from legbench.studies.executors import _task_text
    from legbench.studies.tasks import RunTask

    sc = scenario.load(Path(__file__).resolve().parents[1] / "scenarios" / "effort.yaml")
    assert _task_text((sc, "mujoco", "native", False)) == "effort, mujoco, native, False"
    assert _task_text(RunTask(3, "x.yaml", backend="ode")) == "ode"
