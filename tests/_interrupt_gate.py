"""Plug-in backends for tests/test_interrupt.py: real engines that stop at a known tick until a test lets them go.

``gated-pinocchio`` and ``gated-mujoco`` are the Pinocchio and MuJoCo backends under other names. When the
environment variable :data:`ENV` names a directory, each run's step call number :data:`AT` first creates a
marker file ``<dir>/<backend>-*.blocked`` and then waits there until the test writes to the named pipe
``<marker>.go`` (:func:`release`) or a signal ends the wait (Ctrl-C: KeyboardInterrupt; SIGTERM: the CLI's
handler, or a worker's death). So a test that has seen the marker knows the run is in progress, :data:`AT`
ticks simulated, and that it stays so until the test acts: no run is ever assumed to last long enough to be
interrupted. Without :data:`ENV` they run as their engines do.

A gate nobody opens or interrupts for :data:`TIMEOUT` seconds (or whose process was orphaned) fails its run with
a RuntimeError, loudly, instead of blocking for ever. The tests register the classes as a plug-in distribution
would (``tests/test_interrupt.py``: a ``*.dist-info`` with the ``legbench.backends`` entry points).
"""

from __future__ import annotations

import os
import select
import tempfile
import time
from pathlib import Path
from typing import ClassVar

import numpy as np

from legbench.backends.base import Backend
from legbench.backends.mujoco_ import MujocoBackend
from legbench.backends.pinocchio_ import PinocchioBackend

#: The environment variable naming the gate directory; unset or empty: no gate.
ENV = "LEGBENCH_TEST_GATE"
#: The step call (0-based) that waits: ticks 0 .. AT - 1 are simulated and logged before it.
AT = 500
#: Suffix of the marker a waiting run creates; ``<marker>`` + :data:`RELEASE` is the named pipe it waits on,
#: which the test writes to let it go on (:func:`release`).
BLOCKED = ".blocked"
RELEASE = ".go"
#: Longest wait [s] before the run fails (a test that neither released nor interrupted it is broken).
TIMEOUT = 600.0
#: How often a waiting run wakes, between the release's events, to check it was not orphaned or timed out [s].
CHECK = 1.0

ENTRY_POINTS = {
    "gated-pinocchio": f"{__name__}:GatedPinocchio",
    "gated-mujoco": f"{__name__}:GatedMujoco",
}


def wait_at_gate(backend: str) -> None:
    """Create this run's marker in the gate directory and wait until it is released (see the module doc).

    The release is a named pipe, ``<marker>.go``, made and opened before the marker appears: the wait is a
    ``select`` on it, woken by the test's write (or a signal); every :data:`CHECK` s it also wakes to see whether
    it was orphaned or waited past :data:`TIMEOUT`, the safety net only."""
    gate = os.environ.get(ENV)
    if not gate:
        return
    fd, pending = tempfile.mkstemp(prefix=f"{backend}-", suffix=".pending", dir=gate)
    os.close(fd)
    marker = pending.removesuffix(".pending") + BLOCKED
    os.mkfifo(marker + RELEASE)
    pipe = os.open(marker + RELEASE, os.O_RDONLY | os.O_NONBLOCK)  # no writer yet: select waits for one
    os.rename(pending, marker)  # now the test sees the run waiting, and may release it
    parent, deadline = os.getppid(), time.monotonic() + TIMEOUT
    try:
        while not select.select([pipe], [], [], CHECK)[0]:  # a signal ends the wait with its handler's exception
            if os.getppid() != parent:
                raise RuntimeError(f"gate {marker}: orphaned while waiting (the command that ran it is gone)")
            if time.monotonic() > deadline:
                raise RuntimeError(f"gate {marker}: neither released nor interrupted within {TIMEOUT:g} s")
    finally:
        os.close(pipe)


def release(marker: str | Path) -> None:
    """Let the run waiting at ``marker`` go on: one byte into its release pipe (refused at once, ENXIO, if the run
    no longer waits there)."""
    pipe = os.open(f"{marker}{RELEASE}", os.O_WRONLY | os.O_NONBLOCK)
    try:
        os.write(pipe, b"1")
    finally:
        os.close(pipe)


class _Gated(Backend):
    """A backend stopping at step :data:`AT` while a gate directory is set (mixed in before the engine's class,
    whose reset and step it calls)."""

    _steps = 0

    def reset(self, q: np.ndarray, qd: np.ndarray) -> None:
        super().reset(q, qd)  # type: ignore[safe-super]  # the engine's, next in the MRO
        self._steps = 0

    def step(self, tau: np.ndarray) -> None:
        if self._steps == AT:
            wait_at_gate(self.name)
        self._steps += 1
        super().step(tau)  # type: ignore[safe-super]  # the engine's, next in the MRO


class GatedPinocchio(_Gated, PinocchioBackend):
    """The Pinocchio backend, stopping at step :data:`AT` while a gate directory is set."""

    name: ClassVar[str] = "gated-pinocchio"


class GatedMujoco(_Gated, MujocoBackend):
    """The MuJoCo backend, stopping at step :data:`AT` while a gate directory is set."""

    name: ClassVar[str] = "gated-mujoco"


def install(site: Path) -> dict[str, str]:
    """Write the distribution metadata that registers :data:`ENTRY_POINTS` into ``site`` and return the
    environment of a subprocess that finds them: ``site`` and this module's folder on ``PYTHONPATH``."""
    dist = site / "legbench_interrupt_gate-0.1.dist-info"
    dist.mkdir(parents=True, exist_ok=True)
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: legbench-interrupt-gate\nVersion: 0.1\n")
    lines = "".join(f"{name} = {target}\n" for name, target in ENTRY_POINTS.items())
    (dist / "entry_points.txt").write_text(f"[legbench.backends]\n{lines}")
    path = [str(site), str(Path(__file__).resolve().parent), os.environ.get("PYTHONPATH", "")]
    return {"PYTHONPATH": os.pathsep.join(p for p in path if p)}
