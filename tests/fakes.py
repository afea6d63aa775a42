"""A fake backend so the run loop and comparator can be tested without an engine."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from legbench.backends.base import Backend, Limits, Physics


class FakeBackend(Backend):
    """Three decoupled unit inertias, exact under zero-order-hold torque: qdd = tau / I.

    Over one control period T with held tau: qd+ = qd + tau T / I, q+ = q + qd T + tau T^2 / (2 I).
    The ground force is a fixed, known vector so logging can be checked.
    """

    name: ClassVar[str] = "fake"
    defaults: ClassVar[Mapping[str, Any]] = {"inertia": 0.01}

    def load(self, urdf: Path, physics: Physics, settings: Mapping[str, Any]) -> None:
        self.cfg = self.settings(settings)
        self.T = physics.control_dt
        self.I = float(self.cfg["inertia"])
        self.steps: list[np.ndarray] = []

    def reset(self, q: np.ndarray, qd: np.ndarray) -> None:
        self.q = np.array(q, float)
        self.qd = np.array(qd, float)

    def step(self, tau: np.ndarray) -> None:
        self.steps.append(np.array(tau))
        a = tau / self.I
        self.q = self.q + self.qd * self.T + 0.5 * a * self.T**2
        self.qd = self.qd + a * self.T

    def state(self) -> tuple[np.ndarray, np.ndarray]:
        return self.q.copy(), self.qd.copy()

    def ground_force(self) -> np.ndarray:
        return np.array([1.0, 2.0, 3.0])

    def info(self) -> dict[str, Any]:
        return {"engine": "fake", "version": "0", **self.cfg}

    def integrator_family(self) -> str:
        return "other"  # exact flow of decoupled inertias: nothing for verification to predict

    def sub_steps(self) -> int:
        return 1

    def limits(self) -> Limits:
        inf = float("inf")
        return Limits(gravity=0.0, lower=(-inf, -inf, -inf), upper=(inf, inf, inf), enforcement="none")


def install_crashing_engine(site: Path) -> str:
    """Write a plug-in distribution into ``site`` (put it on sys.path; pool workers inherit it): backend
    ``crashy``, the Pinocchio backend whose first step kills its process with SIGSEGV, as a crash in an
    engine's C code would. Only ever run it in a worker process. Returns the backend's name."""
    site.mkdir(parents=True, exist_ok=True)
    (site / "legbench_crashy.py").write_text(
        "import os, signal\n"
        "from legbench.backends.pinocchio_ import PinocchioBackend\n\n\n"
        "class CrashyBackend(PinocchioBackend):\n"
        "    name = 'crashy'\n\n"
        "    def step(self, tau):\n"
        "        os.kill(os.getpid(), signal.SIGSEGV)\n"
    )
    dist = site / "legbench_crashy-0.1.dist-info"
    dist.mkdir(exist_ok=True)
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: legbench-crashy\nVersion: 0.1\n")
    (dist / "entry_points.txt").write_text("[legbench.backends]\ncrashy = legbench_crashy:CrashyBackend\n")
    return "crashy"
