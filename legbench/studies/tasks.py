"""One run of a study as plain data: a scenario file, overrides and a backend in, a run result out.

A :class:`RunTask` and its :class:`TaskResult` pickle cheaply, so an executor
(:mod:`legbench.studies.executors`) can run the task on any worker with
legbench installed.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from legbench import scenario as scenario_mod
from legbench.results import RunResult
from legbench.run import run_backend
from legbench.studies import horizon
from legbench.studies.horizon import HorizonResult

__all__ = ["RunTask", "TaskResult", "run_task"]


@dataclass(frozen=True)
class RunTask:
    """One run: a scenario file with dotted-key overrides on one backend.

    Attributes:
        index: position of the task in its study; results are ordered by it.
        scenario: path of the scenario YAML file (readable by the worker).
        overrides: dotted keys set before validation, e.g. ``{"backends.<name>.dt": 1e-4}``.
        backend: backend name.
        contact_mode: ``"native"``, ``"reference"`` or None (the scenario's).
        replay_window: after the free run, replay ``reference`` in windows of this length [s]
            (short-horizon mode, :mod:`legbench.studies.horizon`); None: no replay.
        reference: the reference run to replay.
    """

    index: int
    scenario: str
    overrides: Mapping[str, Any] = field(default_factory=dict)
    backend: str = scenario_mod.DEFAULT_REFERENCE
    contact_mode: str | None = None
    replay_window: float | None = None
    reference: RunResult | None = None


@dataclass(frozen=True)
class TaskResult:
    """What a task gave: its index, the run, and the short-horizon replay if one was asked for, with its reset
    floor (the run's own log replayed on its backend in the same windows, :mod:`legbench.studies.horizon`)."""

    index: int
    run: RunResult
    horizon: HorizonResult | None = None
    floor: HorizonResult | None = None


def run_task(task: RunTask) -> TaskResult:
    """Run one task; never raises for a simulation problem (it is reported in the run's status)."""
    sc = scenario_mod.load(task.scenario, dict(task.overrides))
    tr = run_backend(sc, task.backend, task.contact_mode)
    h = floor = None
    if task.replay_window is not None and task.reference is not None and tr.status == "ok":
        h, floor = horizon.replay_task(sc, task.backend, [task.reference, tr], task.replay_window, task.contact_mode)
    return TaskResult(task.index, tr, h, floor)
