"""Nothing lost, nothing half-done: Ctrl-C keeps what was simulated, a rerun completes it;
and runs are bit-identical."""

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
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from legbench import backends, run, scenario

ROOT = Path(__file__).resolve().parent.parent
SCENARIOS = ROOT / "scenarios"


def _cmd(out: Path, quiet: bool = True) -> list[str]:
    # 30 s of ellipse with RK4 sub-steps: long enough (~8 s wall) to interrupt in the middle
    return [sys.executable, "-m", "legbench.cli", "run", str(SCENARIOS / "ellipse.yaml"), "--backends", "pinocchio",
            "--out", str(out), *(["-q"] if quiet else []), "--no-compare", "--set", "duration=30", "--set",
            "backends.pinocchio.integrator=rk4"]  # fmt: skip


#: How long the run may take to show progress at all (start-up on a loaded machine); an upper bound, not a wait.
START_TIMEOUT = 300.0


def _start_and_wait_for_progress(cmd: list[str], percent: float) -> tuple[subprocess.Popen[bytes], int]:
    """Start ``cmd`` with stderr on a pseudo-terminal (so the progress bar is drawn) and return once it shows
    at least ``percent`` % simulated: the observable event that simulation is under way."""
    master, slave = pty.openpty()
    env = {k: v for k, v in os.environ.items() if k != "CI"}  # progress is quiet in CI
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=slave, cwd=ROOT, env=env)
    os.close(slave)
    seen, deadline = b"", time.monotonic() + START_TIMEOUT
    while time.monotonic() < deadline:
        ready, _, _ = select.select([master], [], [], 1.0)
        if ready:
            try:
                seen += os.read(master, 4096)
            except OSError:  # the child closed the terminal: it ended
                break
            done = [float(x) for x in re.findall(rb"(\d+\.\d) %", seen)]
            if done and max(done) >= percent:
                return proc, master
        if proc.poll() is not None:
            break
    proc.kill()
    raise AssertionError(f"no progress to {percent} % shown (exit {proc.poll()}): {seen[-500:]!r}")


def _drain(master: int) -> bytes:
    out = b""
    while True:
        try:
            chunk = os.read(master, 4096)
        except OSError:
            return out
        if not chunk:
            return out
        out += chunk


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_interrupt_keeps_data_marked_incomplete_and_rerun_completes(tmp_path: Path, sig: int) -> None:
    out = tmp_path / "run"
    proc, master = _start_and_wait_for_progress(_cmd(out, quiet=False), percent=5.0)
    assert proc.poll() is None, "run finished before it could be interrupted"
    os.kill(proc.pid, sig)
    proc.wait(timeout=120)
    err = _drain(master).decode(errors="replace")
    os.close(master)
    assert proc.returncode == 130, err
    meta = json.loads((out / "run.json").read_text())
    assert meta["complete"] is False
    entry = meta["backends"]["pinocchio"]
    assert entry["status"] == "interrupted"
    df = pd.read_parquet(out / "pinocchio.parquet")
    assert 1500 <= len(df) < 30001  # interrupted after at least 5 % of the 30000 ticks were shown done
    assert np.isfinite(df[["q1", "q2", "q3"]].to_numpy()).all()
    assert entry["failed_at"] == pytest.approx(df["t"].iloc[-1])
    assert not list(tmp_path.glob(".*"))  # no temporary directory left behind

    done = subprocess.run(_cmd(out), capture_output=True, text=True, cwd=ROOT, timeout=600, check=False)
    assert done.returncode == 0, done.stderr
    meta = json.loads((out / "run.json").read_text())
    assert meta["complete"] is True and meta["backends"]["pinocchio"]["status"] == "ok"
    assert len(pd.read_parquet(out / "pinocchio.parquet")) == 30001


@pytest.mark.parametrize("task", ["position", "ellipse", "effort", "combined"])
@pytest.mark.parametrize("name", backends.available())
def test_two_runs_of_each_task_are_bit_identical(task: str, name: str) -> None:
    sc = scenario.load(SCENARIOS / f"{task}.yaml")
    (a,) = run.run(sc, [name], None, progress=False)
    (b,) = run.run(sc, [name], None, progress=False)
    assert a.status == b.status == "ok"
    for field in ("q", "qd", "tau", "f"):
        np.testing.assert_array_equal(getattr(a, field), getattr(b, field))


def _start_group_and_wait_for(cmd: list[str], pattern: bytes, at_least: int) -> tuple[subprocess.Popen[bytes], int]:
    """Start ``cmd`` in its own process group, stderr on a pseudo-terminal (so the overall count is drawn), and
    return once the count ``pattern`` (a regex whose group 1 is the finished count) reaches ``at_least``."""
    master, slave = pty.openpty()
    env = {k: v for k, v in os.environ.items() if k != "CI"}  # progress is quiet in CI
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=slave, cwd=ROOT, env=env, start_new_session=True)
    os.close(slave)
    seen, deadline = b"", time.monotonic() + START_TIMEOUT
    while time.monotonic() < deadline:
        ready, _, _ = select.select([master], [], [], 1.0)
        if ready:
            try:
                seen += os.read(master, 4096)
            except OSError:
                break
            counts = [int(x) for x in re.findall(pattern, seen)]
            if counts and max(counts) >= at_least:
                return proc, master
        if proc.poll() is not None:
            break
    os.killpg(proc.pid, signal.SIGKILL)
    raise AssertionError(f"count never reached {at_least} (exit {proc.poll()}): {seen[-500:]!r}")


#: ``python -m legbench.cli`` with every thread's stack dumped to stderr on SIGUSR1 (faulthandler), so that a
#: command that does not exit after an interrupt can say where it is (:func:`_interrupt_group`).
LEGBENCH_CLI = [sys.executable, "-c", "import faulthandler, signal, sys; "
                "faulthandler.register(signal.SIGUSR1, all_threads=True); "
                "from legbench.cli import main; sys.exit(main())"]  # fmt: skip


def _interrupt_group(proc: subprocess.Popen[bytes], master: int, sig: int) -> str:
    """``sig`` to the whole process group (as Ctrl-C at a terminal does); the command's stderr after it.

    The stderr pseudo-terminal is read while waiting, so the command never blocks on a full terminal. A command
    still running 120 s later fails the test with its threads' stacks (SIGUSR1, :data:`LEGBENCH_CLI`).
    """
    os.killpg(proc.pid, sig)
    err, deadline, reading = b"", time.monotonic() + 120.0, True
    while proc.poll() is None and time.monotonic() < deadline:
        if not reading:  # every writer has closed the terminal: wait for the exit itself
            try:
                proc.wait(timeout=max(deadline - time.monotonic(), 0.0))
            except subprocess.TimeoutExpired:
                break
        elif select.select([master], [], [], 0.5)[0]:
            try:
                err += os.read(master, 65536)
            except OSError:
                reading = False
    if proc.poll() is None:
        os.kill(proc.pid, signal.SIGUSR1)  # faulthandler writes every thread's stack to the terminal
        until = time.monotonic() + 20.0
        while reading and time.monotonic() < until:
            if select.select([master], [], [], 0.5)[0]:
                try:
                    err += os.read(master, 65536)
                except OSError:
                    break
            elif b"Current thread" in err:  # the dump is complete: nothing more came for 0.5 s
                break
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
        os.close(master)
        raise AssertionError(f"still running 120 s after the signal; stderr:\n{err.decode(errors='replace')}")
    err += _drain(master)
    os.close(master)
    return err.decode(errors="replace")


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_interrupt_with_jobs_keeps_every_finished_backend_and_says_so(tmp_path: Path, sig: int) -> None:
    """--jobs 2, two contact modes x two backends (4 runs); the signal goes to the process group (workers
    included) once the first run is counted done. Every run that finished is written as a complete backend,
    the others are marked not run, stderr names what was kept, no worker prints a traceback, exit 130."""
    tree = tmp_path / "tree"
    cmd = [*LEGBENCH_CLI, "run", str(SCENARIOS / "ellipse.yaml"), "--backends",
           "pinocchio,mujoco", "--contact-mode", "both", "--jobs", "2", "--out", str(tree), "--no-compare",
           "--no-preflight", "--set", "duration=10", "--set", "backends.pinocchio.integrator=rk4"]  # fmt: skip
    proc, master = _start_group_and_wait_for(cmd, rb"runs: (\d+)/4", 1)
    err = _interrupt_group(proc, master, sig)
    assert proc.returncode == 130, err
    assert "Traceback" not in err and "KeyboardInterrupt" not in err, err
    statuses: dict[str, str] = {}
    for d in sorted(tree.iterdir()):
        meta = json.loads((d / "run.json").read_text())
        for name, entry in meta["backends"].items():
            statuses[f"{d.name}/{name}"] = entry["status"]
            if entry["status"] == "ok":  # a finished run is whole
                assert len(pd.read_parquet(d / entry["file"])) == 10001
            else:
                assert entry["status"] == "interrupted" and "not run" in entry["reason"]
        assert meta["complete"] is all(e["status"] == "ok" for e in meta["backends"].values())
    kept = [k for k, v in statuses.items() if v == "ok"]
    assert 1 <= len(kept) < 4, statuses  # the first counted run is kept; the signal came before the last
    said = sum(int(n) for n in re.findall(r"interrupted: .*?: (\d+) of 2 backends finished and kept", err))
    assert said == len(kept), err  # what stderr says was kept is what is on disk
    assert not list(tree.glob(".*"))  # no temporary directory left behind


def test_interrupt_of_a_sweep_keeps_the_finished_runs(tmp_path: Path) -> None:
    """A sweep with --jobs 2 interrupted (Ctrl-C to the group) after its first run: the finished runs are
    written (sweep.json complete: false, the others 'interrupted' in the table), exit 130, no traceback."""
    sw = tmp_path / "s.yaml"
    sw.write_text(f"""
name: s
scenario: {SCENARIOS / "verification" / "free_space.yaml"}
set: {{duration: 2.0}}
studies:
  - backends: [pinocchio]
    set: {{backends.*.integrator: euler}}
    grid: {{backends.*.dt: [1.0e-3, 5.0e-4]}}
    reference: {{set: {{backends.*.dt: 1.0e-4}}}}
  - backends: [mujoco]
    grid: {{backends.*.dt: [1.0e-3, 5.0e-4]}}
    reference: {{set: {{backends.*.dt: 1.0e-6}}}}
""")
    # runs start longest first: the 1e-6 s reference (2e6 steps) is still running when the others finish
    out = tmp_path / "out"
    cmd = [*LEGBENCH_CLI, "sweep", str(sw), "--out", str(out), "--jobs", "2"]
    proc, master = _start_group_and_wait_for(cmd, rb"sweep s: (\d+)/6", 1)
    err = _interrupt_group(proc, master, signal.SIGINT)
    assert proc.returncode == 130, err
    assert "Traceback" not in err and "KeyboardInterrupt" not in err, err
    meta = json.loads((out / "sweep.json").read_text())
    assert meta["complete"] is False and meta["not_run"] >= 1
    table = pd.read_csv(out / "sweep.csv")
    ok = int((table["status"] == "ok").sum())
    assert ok >= 1 and set(table["status"]) <= {"ok", "interrupted"}
    m = re.search(r"interrupted: sweep s: (\d+) of 6 runs finished and kept", err)
    assert m is not None, err
    assert not list(tmp_path.glob(".*"))

    # one job: the run in this process is stopped at once (the longest, started first); nothing finished,
    # nothing is written, and it says so
    out1 = tmp_path / "out1"
    cmd = [*LEGBENCH_CLI, "sweep", str(sw), "--out", str(out1), "--jobs", "1"]
    proc, master = _start_group_and_wait_for(cmd, rb"sweep s: (\d+)/6", 0)
    err = _interrupt_group(proc, master, signal.SIGINT)
    assert proc.returncode == 130, err
    assert "Traceback" not in err, err
    assert re.search(r"interrupted: sweep s: \d of 6 runs finished and kept", err), err
    assert not out1.exists() or json.loads((out1 / "sweep.json").read_text())["complete"] is False
