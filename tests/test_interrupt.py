"""Nothing lost, nothing half-done: Ctrl-C keeps what was simulated, a rerun completes it;
and runs are bit-identical.

The interrupt tests run the real command line (a run, a run with ``--jobs``, a sweep) on the plug-in backends of
:mod:`_interrupt_gate`: the Pinocchio and MuJoCo engines, registered through the ``legbench.backends`` entry
point, which stop at a known tick and wait there until the test releases them or its signal arrives. The signal
is sent only once the test has seen the runs it needs waiting (their marker files) or finished (the count on the
progress bar): no run is assumed to last long enough, and no test waits a fixed time.
"""

from __future__ import annotations

import json
import os
import pty
import re
import select
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Mapping
from pathlib import Path

import _interrupt_gate as gate
import numpy as np
import pandas as pd
import pytest

from legbench import backends, run, scenario

ROOT = Path(__file__).resolve().parent.parent
SCENARIOS = ROOT / "scenarios"

#: How long a command may take to reach an awaited event at all (start-up on a loaded machine); an upper bound
#: after which the test fails, never a wait.
START_TIMEOUT = 300.0
#: How long a command may take to exit after the signal; an upper bound, as :data:`START_TIMEOUT`.
EXIT_TIMEOUT = 120.0
#: How often the files of the gate directory are looked at while the command's stderr is read [s].
POLL = 0.02

#: ``python -m legbench.cli`` with every thread's stack dumped to stderr on SIGUSR1 (faulthandler), so that a
#: command that does not exit after an interrupt can say where it is (:meth:`Command.interrupt`).
LEGBENCH_CLI = [sys.executable, "-c", "import faulthandler, signal, sys; "
                "faulthandler.register(signal.SIGUSR1, all_threads=True); "
                "from legbench.cli import main; sys.exit(main())"]  # fmt: skip


@pytest.fixture
def gated(tmp_path: Path) -> tuple[Path, dict[str, str]]:
    """The gate directory and the environment of a command whose gated backends stop there: the plug-in
    registered (its metadata in ``tmp_path/site``) and CI unset (the progress is drawn: the tests watch it)."""
    where = tmp_path / "gate"
    where.mkdir()
    env = {k: v for k, v in os.environ.items() if k != "CI"}  # progress is quiet in CI
    env |= gate.install(tmp_path / "site") | {gate.ENV: str(where)}
    return where, env


def waiting(where: Path) -> list[Path]:
    """The markers of the runs that reached the gate, in the order of their names (each waits until released)."""
    return sorted(where.glob(f"*{gate.BLOCKED}"))


def release(marker: Path) -> None:
    """Let the run waiting at ``marker`` go on to its end."""
    gate.release(marker)


class Command:
    """A legbench command in a subprocess, its stderr on a pseudo-terminal (so progress is drawn and read)."""

    def __init__(self, cmd: list[str], env: Mapping[str, str], group: bool = False) -> None:
        """``group``: in its own process group, which the signal then goes to (as Ctrl-C at a terminal)."""
        self.master, slave = pty.openpty()
        self.proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=slave, cwd=ROOT, env=dict(env),
                                     start_new_session=group)  # fmt: skip
        os.close(slave)
        self.group, self.err, self.reading = group, b"", True

    def _read(self, timeout: float) -> None:
        """What the command wrote to its stderr within ``timeout`` s (nothing once every writer closed it)."""
        if self.reading and select.select([self.master], [], [], timeout)[0]:
            try:
                chunk = os.read(self.master, 65536)
            except OSError:  # every writer closed the terminal
                chunk = b""
            self.err += chunk
            self.reading = bool(chunk)

    def count(self, pattern: bytes) -> int:
        """The largest count ``pattern`` (a regex whose group 1 is the count) shows on stderr so far (-1: none)."""
        return max((int(x) for x in re.findall(pattern, self.err)), default=-1)

    def wait_until(self, what: str, ready: Callable[[], bool]) -> None:
        """Read stderr until ``ready()``; the command ending first, or :data:`START_TIMEOUT`, fails the test."""
        deadline = time.monotonic() + START_TIMEOUT
        while not ready():
            if self.proc.poll() is not None or time.monotonic() > deadline:
                self.kill()
                raise AssertionError(f"never {what} (exit {self.proc.returncode}): {self.text()[-2000:]}")
            self._read(POLL)

    def text(self) -> str:
        return self.err.decode(errors="replace")

    def _drain(self, timeout: float) -> None:
        """Read stderr until every writer has closed the terminal, for at most ``timeout`` s."""
        until = time.monotonic() + timeout
        while self.reading and time.monotonic() < until:
            self._read(min(0.5, max(until - time.monotonic(), 0.0)))

    def kill(self) -> None:
        """Kill the command (its whole process group if it has one), read what it wrote, close the terminal."""
        try:
            os.killpg(self.proc.pid, signal.SIGKILL) if self.group else self.proc.kill()
        except ProcessLookupError:  # nothing of it left
            pass
        self.proc.wait()
        self._drain(5.0)
        os.close(self.master)

    def interrupt(self, sig: int) -> str:
        """``sig`` to the command (to its process group if it has one); its stderr once it has exited.

        The terminal is read while waiting, so the command never blocks on a full terminal. A command still
        running :data:`EXIT_TIMEOUT` s later fails the test with its threads' stacks (SIGUSR1,
        :data:`LEGBENCH_CLI`).
        """
        os.killpg(self.proc.pid, sig) if self.group else os.kill(self.proc.pid, sig)
        deadline = time.monotonic() + EXIT_TIMEOUT
        while self.proc.poll() is None and time.monotonic() < deadline:
            if not self.reading:  # every writer has closed the terminal: wait for the exit itself
                try:
                    self.proc.wait(timeout=max(deadline - time.monotonic(), 0.0))
                except subprocess.TimeoutExpired:
                    break
            self._read(0.5)
        if self.proc.poll() is None:
            os.kill(self.proc.pid, signal.SIGUSR1)  # faulthandler writes every thread's stack to the terminal
            until = time.monotonic() + 20.0
            while self.reading and time.monotonic() < until:
                before = len(self.err)
                self._read(0.5)
                if len(self.err) == before and b"Current thread" in self.err:  # nothing more came for 0.5 s
                    break
            self.kill()
            raise AssertionError(f"still running {EXIT_TIMEOUT:g} s after the signal; stderr:\n{self.text()}")
        self._drain(EXIT_TIMEOUT)  # what the command and its workers wrote until they closed the terminal
        os.close(self.master)
        return self.text()


def _cmd(out: Path, quiet: bool = True) -> list[str]:
    # 2 s of ellipse (2001 ticks) on the gated Pinocchio backend, which waits at tick gate.AT until interrupted
    return [sys.executable, "-m", "legbench.cli", "run", str(SCENARIOS / "ellipse.yaml"), "--backends",
            "gated-pinocchio", "--out", str(out), *(["-q"] if quiet else []), "--no-compare", "--set",
            "duration=2"]  # fmt: skip


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_interrupt_keeps_data_marked_incomplete_and_rerun_completes(
    tmp_path: Path, gated: tuple[Path, dict[str, str]], sig: int
) -> None:
    """The signal comes while the run waits at tick gate.AT of 2001: the ticks before it are kept, marked
    interrupted, the run incomplete, exit 130; the same command, ungated, then completes the run."""
    where, env = gated
    out = tmp_path / "run"
    cmd = Command(_cmd(out, quiet=False), env)
    cmd.wait_until("reached the gate", lambda: len(waiting(where)) == 1)
    err = cmd.interrupt(sig)
    assert cmd.proc.returncode == 130, err
    meta = json.loads((out / "run.json").read_text())
    assert meta["complete"] is False
    entry = meta["backends"]["gated-pinocchio"]
    assert entry["status"] == "interrupted"
    df = pd.read_parquet(out / "gated-pinocchio.parquet")
    assert gate.AT <= len(df) <= gate.AT + 1 < 2001  # every tick simulated before the wait, no more
    assert np.isfinite(df[["q1", "q2", "q3"]].to_numpy()).all()
    assert entry["failed_at"] == pytest.approx(df["t"].iloc[-1])
    assert not list(tmp_path.glob(".*"))  # no temporary directory left behind
    if sig == signal.SIGINT:  # compare says it was interrupted (it was quiet, exit 0: only the report said so)
        cmp = subprocess.run([*LEGBENCH_CLI, "compare", str(out)], capture_output=True, text=True, cwd=ROOT, env=env,
                             timeout=600, check=False)  # fmt: skip
        assert cmp.returncode == 0, cmp.stderr
        assert cmp.stderr == (f"legbench: {out}: an interrupted run (gated-pinocchio not finished), compared as far "
                              "as it went; rerun the command that wrote it to finish it\n")  # fmt: skip

    ungated = {k: v for k, v in env.items() if k != gate.ENV}
    done = subprocess.run(_cmd(out), capture_output=True, text=True, cwd=ROOT, env=ungated, timeout=600,
                          check=False)  # fmt: skip
    assert done.returncode == 0, done.stderr
    meta = json.loads((out / "run.json").read_text())
    assert meta["complete"] is True and meta["backends"]["gated-pinocchio"]["status"] == "ok"
    assert len(pd.read_parquet(out / "gated-pinocchio.parquet")) == 2001


@pytest.mark.parametrize("task", ["position", "ellipse", "effort", "combined"])
@pytest.mark.parametrize("name", backends.available())
def test_two_runs_of_each_task_are_bit_identical(task: str, name: str) -> None:
    sc = scenario.load(SCENARIOS / f"{task}.yaml")
    (a,) = run.run(sc, [name], None, progress=False)
    (b,) = run.run(sc, [name], None, progress=False)
    assert a.status == b.status == "ok"
    for field in ("q", "qd", "tau", "f"):
        np.testing.assert_array_equal(getattr(a, field), getattr(b, field))


def _backend_of(marker: Path) -> str:
    """The backend whose run created ``marker`` (``<backend>-<random>.blocked``)."""
    return marker.name.rsplit("-", 1)[0]


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_interrupt_with_jobs_keeps_every_finished_backend_and_says_so(
    tmp_path: Path, gated: tuple[Path, dict[str, str]], sig: int
) -> None:
    """--jobs 2, two contact modes x two gated backends (4 runs, each waiting at tick gate.AT until released).
    Once both workers' runs wait, one is released; once it is counted done and the next run waits in the freed
    worker, the signal goes to the process group (workers included): two runs in progress, one not started.
    The run that finished is written as a complete backend, the others are marked not run, stderr names what
    was kept, no worker prints a traceback, exit 130."""
    where, env = gated
    tree = tmp_path / "tree"
    cmd = Command([*LEGBENCH_CLI, "run", str(SCENARIOS / "ellipse.yaml"), "--backends",
                   "gated-pinocchio,gated-mujoco", "--contact-mode", "both", "--jobs", "2", "--out", str(tree),
                   "--no-compare", "--no-preflight", "--set", "duration=2"], env, group=True)  # fmt: skip
    cmd.wait_until("two runs waiting at the gate", lambda: len(waiting(where)) == 2)
    finished = waiting(where)[0]
    release(finished)
    cmd.wait_until("the released run counted done and the next run waiting",
                   lambda: cmd.count(rb"runs: (\d+)/4") >= 1 and len(waiting(where)) == 3)  # fmt: skip
    err = cmd.interrupt(sig)
    assert cmd.proc.returncode == 130, err
    assert "Traceback" not in err and "KeyboardInterrupt" not in err, err
    statuses: dict[str, str] = {}
    for d in sorted(tree.iterdir()):
        meta = json.loads((d / "run.json").read_text())
        for name, entry in meta["backends"].items():
            statuses[f"{d.name}/{name}"] = entry["status"]
            if entry["status"] == "ok":  # a finished run is whole
                assert len(pd.read_parquet(d / entry["file"])) == 2001
            else:
                assert entry["status"] == "interrupted" and "not run" in entry["reason"]
        assert meta["complete"] is all(e["status"] == "ok" for e in meta["backends"].values())
    kept = [k for k, v in statuses.items() if v == "ok"]
    assert len(kept) == 1 and kept[0].endswith(f"/{_backend_of(finished)}"), statuses  # the released run alone
    said = sum(int(n) for n in re.findall(r"interrupted: .*?: (\d+) of 2 backends finished and kept", err))
    assert said == len(kept), err  # what stderr says was kept is what is on disk
    assert not list(tree.glob(".*"))  # no temporary directory left behind


SWEEP = """
name: s
scenario: {scenario}
set: {{duration: 1.0}}
studies:
  - backends: [gated-pinocchio]
    set: {{backends.*.integrator: euler}}
    grid: {{backends.*.dt: [1.0e-3, 5.0e-4]}}
    reference: {{set: {{backends.*.dt: 1.0e-4}}}}
  - backends: [gated-mujoco]
    grid: {{backends.*.dt: [1.0e-3, 5.0e-4]}}
    reference: {{set: {{backends.*.dt: 1.0e-4}}}}
"""


def test_interrupt_of_a_sweep_keeps_the_finished_runs(tmp_path: Path, gated: tuple[Path, dict[str, str]]) -> None:
    """A sweep of 6 gated runs with --jobs 2 interrupted (Ctrl-C to the group) once one run finished and two
    wait: the finished run is written (sweep.json complete: false, the others 'interrupted' in the table),
    exit 130, no traceback."""
    where, env = gated
    sw = tmp_path / "s.yaml"
    sw.write_text(SWEEP.format(scenario=SCENARIOS / "verification" / "free_space.yaml"))
    out = tmp_path / "out"
    cmd = Command([*LEGBENCH_CLI, "sweep", str(sw), "--out", str(out), "--jobs", "2"], env, group=True)
    cmd.wait_until("two runs waiting at the gate", lambda: len(waiting(where)) == 2)
    release(waiting(where)[0])
    cmd.wait_until("the released run counted done and the next run waiting",
                   lambda: cmd.count(rb"sweep s: (\d+)/6") >= 1 and len(waiting(where)) == 3)  # fmt: skip
    err = cmd.interrupt(signal.SIGINT)
    assert cmd.proc.returncode == 130, err
    assert "Traceback" not in err and "KeyboardInterrupt" not in err, err
    meta = json.loads((out / "sweep.json").read_text())
    assert meta["complete"] is False and meta["not_run"] == 5
    table = pd.read_csv(out / "sweep.csv")
    assert int((table["status"] == "ok").sum()) == 1 and set(table["status"]) == {"ok", "interrupted"}
    assert "interrupted: sweep s: 1 of 6 runs finished and kept" in err, err
    assert "a sweep is not resumed: rerun it with --force" in err, err  # not 'rerun the same command', refused
    assert not list(tmp_path.glob(".*"))

    # one job: the run in this process is stopped while it waits at the gate (the first, none finished before);
    # nothing finished, nothing is written, and it says so
    where1 = tmp_path / "gate1"
    where1.mkdir()
    out1 = tmp_path / "out1"
    cmd = Command([*LEGBENCH_CLI, "sweep", str(sw), "--out", str(out1), "--jobs", "1"], env | {gate.ENV: str(where1)},
                  group=True)  # fmt: skip
    cmd.wait_until("the first run waiting at the gate", lambda: len(waiting(where1)) == 1)
    err = cmd.interrupt(signal.SIGINT)
    assert cmd.proc.returncode == 130, err
    assert "Traceback" not in err, err
    assert "interrupted: sweep s: 0 of 6 runs finished and kept, nothing written" in err, err
    assert not out1.exists()


@pytest.mark.parametrize(
    "args",
    [
        ["verify", "--backends", "gated-pinocchio", "--cases", "rest_penetration,static_balance"],
        ["bench", str(SCENARIOS / "effort.yaml"), "--backends", "gated-pinocchio", "--repeats", "1", "--no-memory"],
    ],
    ids=["verify", "bench"],
)
def test_an_interrupted_study_in_one_process_writes_nothing(
    tmp_path: Path, gated: tuple[Path, dict[str, str]], args: list[str]
) -> None:
    """verify and bench with one job run their engines in the command's own process: the signal comes while a
    run waits at the gate, mid-simulation. It stops the study (exit 130, nothing written, no traceback) instead
    of ending that run as the engine's failure and writing a finished-looking result (it was: rows 'failed:
    interrupted at t = ...', exit 1 or 3, and the result then refused a rerun without --force)."""
    where, env = gated
    out = tmp_path / "out"
    for sig in (signal.SIGINT, signal.SIGTERM):
        for marker in waiting(where):
            marker.unlink()
        cmd = Command([*LEGBENCH_CLI, *args, "--out", str(out)], env, group=True)
        cmd.wait_until("a run waiting at the gate", lambda: len(waiting(where)) == 1)
        err = cmd.interrupt(sig)
        assert cmd.proc.returncode == 130, err
        assert "Traceback" not in err and "failed" not in err, err
        assert not out.exists(), sorted(p.name for p in out.iterdir())
        assert not list(tmp_path.glob(".*"))
