"""The README's code runs as printed: its Python API example, and its shell command sequence in a fresh copy.

Shell: every ```sh block of README.md, in order, in a clone of this repository (``git clone`` of the tree; the
tree's uncommitted edits are copied over it so the test sees what it tests). Lines that install (``pip install``,
``make`` targets: they install the environment, run the full comparison or the test suite) and ``$EDITOR`` are
skipped; every line that starts with ``legbench`` or runs it (``eval "$(legbench completion bash)"``) is run, with
``legbench`` on PATH running the clone's code on this interpreter. No duration is shortened. The two logs the README
compares are the user's own (``hardware.csv``, ``hardware.bag``): the test writes them, before the line that reads
them, from the README's own ``runs/effort`` run (headers renamed and time in ms, as the README's options expect).
"""

from __future__ import annotations

import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"

pytestmark = pytest.mark.slow


def _blocks(lang: str) -> list[tuple[str, str]]:
    """(section heading, code) of every fenced block in ``lang``, in order."""
    out: list[tuple[str, str]] = []
    heading = ""
    lines = README.read_text().splitlines()
    i = 0
    while i < len(lines):
        line = lines[i]
        if line.startswith("#"):
            heading = line.lstrip("#").strip()
        if line.strip() == f"```{lang}":
            j = i + 1
            while lines[j].strip() != "```":
                j += 1
            out.append((heading, "\n".join(lines[i + 1 : j])))
            i = j
        i += 1
    return out


def _commands(code: str) -> list[str]:
    """Logical lines (backslash continuations joined), comments kept for the shell to ignore."""
    joined = re.sub(r"\\\n\s*", " ", code)
    return [c for c in (ln.strip() for ln in joined.splitlines()) if c and not c.startswith("#")]


def _runs(cmd: str) -> bool:
    return cmd.startswith("legbench ") or "$(legbench " in cmd


def test_readme_api_example_runs(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The ```python block of the "Python API" section, verbatim: it runs and its report exists."""
    pytest.importorskip("mujoco")
    (code,) = [c for h, c in _blocks("python") if h == "Python API"]
    monkeypatch.chdir(tmp_path)
    ns: dict[str, object] = {}
    exec(compile(code, "README.md:Python API", "exec"), ns)
    res = ns["res"]
    assert (res.path / "report.html").is_file()  # type: ignore[attr-defined]
    assert set(res.frames) == {"pinocchio", "mujoco"}  # type: ignore[attr-defined]


def _clone(dest: Path) -> None:
    subprocess.run(["git", "clone", "--quiet", str(ROOT), str(dest)], check=True)
    changed = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no", "-z"], cwd=ROOT,
                             capture_output=True, check=True).stdout.decode()  # fmt: skip
    for entry in filter(None, changed.split("\0")):
        rel = entry[3:]
        src = ROOT / rel
        if src.is_file() and not src.is_symlink():
            shutil.copy2(src, dest / rel)


def _hardware_logs(clone: Path) -> None:
    """The user's logs: pinocchio's effort log as the lab's CSV (their headers, ms) and mujoco's as a ROS 1 bag."""
    pin = pd.read_parquet(clone / "runs" / "effort" / "pinocchio.parquet")
    csv = pin.drop(columns=["controller"]).rename(
        columns={"t": "time_ms", "q1": "hip_aa", "q2": "hip_fe", "q3": "knee"}
    )
    csv["time_ms"] *= 1000.0
    csv.to_csv(clone / "hardware.csv", index=False)
    if (clone / "hardware.bag").exists():
        return
    test_logs = pytest.importorskip("test_logs", reason="rosbags: pip install 'legbench[ros]'")
    muj = pd.read_parquet(clone / "runs" / "effort" / "mujoco.parquet")
    cols = ["q1", "q2", "q3", "qd1", "qd2", "qd3", "tau1", "tau2", "tau3"]
    t = muj["t"].to_numpy()
    test_logs.write_bag("ros1", clone / "hardware.bag", t, muj[cols].to_numpy(), ("hip_aa", "hip_fe", "knee"),
                        (0, 1, 2), t, muj[["fx", "fy", "fz"]].to_numpy())  # fmt: skip


def test_readme_shell_sequence_from_a_fresh_clone(tmp_path: Path) -> None:
    pytest.importorskip("mujoco")
    pytest.importorskip("pybullet")
    clone = tmp_path / "legbench"
    _clone(clone)
    shim = tmp_path / "bin"
    shim.mkdir()
    (shim / "legbench").write_text(f'#!/bin/sh\nexec {shlex.quote(sys.executable)} -m legbench.cli "$@"\n')
    (shim / "legbench").chmod(0o755)
    env = {k: v for k, v in os.environ.items() if k not in ("LEGBENCH_MODEL",)}
    env |= {"PATH": f"{shim}{os.pathsep}{env['PATH']}", "PYTHONPATH": str(clone)}
    ran: list[str] = []
    for _, code in _blocks("sh"):
        for cmd in _commands(code):
            if not _runs(cmd):
                assert cmd.startswith(("make ", "pip install", "$EDITOR")), (
                    f"README line neither run nor skipped: {cmd}"
                )
                continue
            if "hardware." in cmd:
                _hardware_logs(clone)
            proc = subprocess.run(["bash", "-c", f"set -e\n{cmd}"], cwd=clone, env=env, capture_output=True,
                                  text=True, timeout=1800, check=False)  # fmt: skip
            assert proc.returncode == 0, f"README: {cmd}\nexit {proc.returncode}\n{proc.stdout[-3000:]}\n{proc.stderr}"
            ran.append(cmd)
    assert len(ran) >= 12, ran
    # nothing went where it was not asked to: every run named its --out, and no run overwrote another's
    assert not (clone / "results" / "latest").exists()
    for out, backends in {"runs/effort": {"pinocchio", "mujoco"}, "runs/effort-again": {"pinocchio", "mujoco"},
                          "runs/effort-fine": {"pinocchio"}}.items():  # fmt: skip
        assert {p.stem for p in (clone / out).glob("*.parquet")} == backends, out
    assert {p.name for p in (clone / "runs" / "effort-all").iterdir() if p.is_dir()} >= {"effort", "effort__reference"}
    assert {p.name for p in (clone / "runs" / "tasks").iterdir() if p.is_dir()} >= {"position", "effort"}
    # `legbench model urdf` rewrote models/leg.urdf identically: the clone has no change
    status = subprocess.run(["git", "status", "--porcelain", "--", "models"], cwd=clone, capture_output=True,
                            text=True, check=True).stdout  # fmt: skip
    assert status == ""
