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
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=slave, cwd=ROOT)
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
