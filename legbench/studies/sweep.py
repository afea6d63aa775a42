"""Parameter sweeps: a grid over any scenario or backend setting, one tidy table, plots.

Data flow: sweep YAML -> :func:`load_sweep` (:class:`Sweep`, validated) ->
:func:`plan` (:class:`Plan`: unique runs as :class:`~legbench.studies.tasks.RunTask`
and one :class:`Row` per grid point or reference) -> the executor runs the
references, then the other runs (:func:`execute`) -> :func:`tabulate` (the
table: swept values, backend, wall time, real-time factor, error against the
row's reference) -> :func:`fit_slopes` (convergence order) -> :func:`write_sweep`
(``sweep.csv``, ``sweep.parquet``, ``fits.csv``, ``sweep.json``, PNG plots).
:func:`run_sweep` does it all; ``legbench sweep`` is its command line.

The sweep file format is documented in docs/studies.md; in short::

    name: timestep                         # output folder name
    description: ...
    scenario: ../verification/free_space.yaml   # relative to this file
    set: {duration: 0.5}                   # dotted overrides for every run
    contact_mode: native                   # optional override
    signals: [q, qd]                       # compared: q, qd, tau, force, ee
    skip: 0.0                              # [s] ignored at the start
    metric: q_max                          # column plotted (and fitted)
    fit: {x: dt, floor: 1.0e-12}           # log-log slope of metric vs x per study
    short_horizon: {window: 0.05}          # [s] optional, see legbench.studies.horizon
    studies:
      - label: "{backend} euler"
        backends: [engine_a, engine_b]     # backend names, or one name, or "all"
        set: {backends.*.integrator: euler}
        grid: {backends.*.dt: [1.0e-3, 5.0e-4]}   # Cartesian product of the lists
        reference: {set: {backends.*.dt: 5.0e-6}} # and/or backend: <name>

A key part ``*`` stands for the run's backend (``backends.*.dt``), ``{backend}``
in a label for its name. A swept key's table column is its name without
``backends.*.`` (``dt``, ``integrator``); other keys keep their dotted name
(``gains.Kp``).

Error metrics, per signal component over t >= skip (docs/metrics.md, computed by
:func:`legbench.metrics.signal_errors`): ``<c>_max`` = max_t |x - x_ref| (in the
signal's unit), ``<c>_pct`` = max_t |x - x_ref| / max_t |x_ref| x 100; per
signal ``<s>_max`` / ``<s>_pct`` are the maxima over its components. The hip
angle's deviation is the shortest angle.
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import itertools
import json
import math
import os
import sys
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import BrokenExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from legbench import backends as registry
from legbench import progress, resources
from legbench import scenario as scenario_mod
from legbench.contact import CONTACT_MODES
from legbench.exceptions import LegbenchError, ScenarioError
from legbench.metrics import T_EPS, signal_errors
from legbench.results import RunResult, atomic_dir, platform_info, versions
from legbench.run import crashed, deferred_interrupts
from legbench.scenario import NAME_RE
from legbench.signals import COLUMNS, UNITS
from legbench.studies import horizon
from legbench.studies.executors import DEFAULT_PRELOAD, EXECUTORS, Executor, make_executor, warm_up
from legbench.studies.horizon import HorizonResult
from legbench.studies.tasks import RunTask, TaskResult, run_task
from legbench.yamlfile import YamlContext, check_keys, keys_overlap, limit, other_file, read_yaml

__all__ = [
    "COMPONENTS",
    "SIGNALS",
    "Plan",
    "Row",
    "Study",
    "Sweep",
    "SweepResult",
    "add_cli",
    "check_out",
    "fit_slopes",
    "load_sweep",
    "plan",
    "run_metrics",
    "run_sweep",
    "tabulate",
    "write_sweep",
]

#: Signals a sweep can compare, and their components (table column prefixes).
COMPONENTS: dict[str, tuple[str, ...]] = dict(COLUMNS)
SIGNALS = tuple(COMPONENTS)
SCHEMA = "legbench.sweep/1"
TOP_KEYS = ("name", "description", "scenario", "set", "contact_mode", "signals", "skip", "metric", "fit",
            "short_horizon", "studies")  # fmt: skip
STUDY_KEYS = ("label", "backends", "set", "grid", "reference")


# --------------------------------------------------------------------------- #
# Sweep file


@dataclass(frozen=True)
class Study:
    """One block of runs: backends x the Cartesian product of the grid, each against its reference.

    Attributes:
        label: label template (``{backend}`` is replaced); empty: derived from backend and ``set``.
        backends: backend names.
        set: dotted keys fixed for this study (a part ``*`` is the run's backend).
        grid: dotted key -> values; every combination is one run.
        reference_backend: backend of the reference run (None: the run's own).
        reference_set: dotted keys set on top of the run's for its reference.
    """

    label: str
    backends: tuple[str, ...]
    set: Mapping[str, Any]
    grid: Mapping[str, tuple[Any, ...]]
    reference_backend: str | None
    reference_set: Mapping[str, Any]


@dataclass(frozen=True)
class Fit:
    """Log-log slope of the sweep's metric against a swept column, per study and backend.

    Attributes:
        x: the swept column (e.g. ``dt``).
        floor: points whose metric is at or below this are left out (round-off floor).
    """

    x: str
    floor: float = 0.0


@dataclass(frozen=True)
class Sweep:
    """A validated sweep file."""

    name: str
    description: str
    file: str
    scenario: Path
    set: Mapping[str, Any]
    contact_mode: str | None
    signals: tuple[str, ...]
    skip: float  # [s]
    metric: str
    fit: Fit | None
    short_horizon: float | None  # window [s]
    studies: tuple[Study, ...]
    raw: Mapping[str, Any] = field(default_factory=dict, hash=False, compare=False)
    #: the base scenario as the sweep was loaded with it: its hash and document (sweep.json records both, so the
    #: sweep can be repeated after the scenario file changed; the runs' own logs are not written)
    base_sha256: str = ""
    base_raw: Mapping[str, Any] = field(default_factory=dict, hash=False, compare=False)


def _number(doc: YamlContext, path: list[str | int], v: Any, positive: bool = False) -> float:
    if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(float(v)):
        raise doc.error(path, f"expected a finite number, got {v!r}")
    if float(v) < 0 or (positive and float(v) == 0):
        raise doc.error(path, f"must be {'>' if positive else '>='} 0, got {v!r}")
    return float(v)


def _dotted(doc: YamlContext, path: list[str | int], d: Any) -> dict[str, Any]:
    """A mapping of dotted keys to values; a key part ``*`` stands for the run's backend."""
    if d is None:
        return {}
    if not isinstance(d, Mapping):
        raise doc.error(path, "expected a mapping of dotted keys to values, e.g. {backends.*.dt: 1.0e-4}")
    out: dict[str, Any] = {}
    for k, v in d.items():
        if not isinstance(k, str) or not k or any(not part for part in k.split(".")):
            raise doc.error([*path, str(k)], "expected a dotted key such as gains.Kp or backends.*.dt")
        if any("*" in part and part != "*" for part in k.split(".")):
            raise doc.error([*path, k], "'*' must be a whole key part (backends.*.dt), standing for the backend")
        out[k] = v
    return out


def load_sweep(path: str | Path) -> Sweep:
    """Read and validate a sweep file (format: module docstring and docs/studies.md).

    Raises:
        ScenarioError: naming the file, the key path and the problem.
    """
    path = Path(path)
    raw, root = read_yaml(path)
    doc = YamlContext(str(path), root)
    other = other_file(raw, "a sweep")  # another of legbench's files (a scenario) given as a sweep
    if other is not None and "studies" not in raw:
        raise doc.error([], other)
    check_keys(doc, [], raw, TOP_KEYS, ["name", "scenario", "studies"])
    name = raw["name"]
    if not isinstance(name, str) or not NAME_RE.fullmatch(name) or set(name) == {"."}:  # a directory name
        raise doc.error(["name"], f"expected a plain name (letters, digits, - _ ., at most 64), got {name!r}")
    description = raw.get("description")
    if description is None:  # absent or empty; a list or number is no text and refused
        description = ""
    if not isinstance(description, str):
        raise doc.error(["description"], "expected text")
    if not isinstance(raw["scenario"], str):
        raise doc.error(["scenario"], "expected the path of a scenario file, relative to this sweep file")
    try:
        scenario = (path.parent / raw["scenario"]).resolve()
        found = scenario.is_file()
    except OSError as exc:  # a name too long, a loop of links: no file can be there
        raise doc.error(["scenario"], f"cannot be a scenario file: {exc.strerror or exc}") from None
    if not found:
        what = "is a directory, not a scenario file" if scenario.is_dir() else "no such scenario file"
        raise doc.error(["scenario"], f"{what}: {scenario}")
    try:  # the scenario on its own first, so its own problems name its file, not a study's override
        base_scenario = scenario_mod.load(scenario)
    except ScenarioError as exc:
        raise doc.error(["scenario"], str(exc)) from None
    common = _dotted(doc, ["set"], raw.get("set"))
    mode = raw.get("contact_mode")
    if mode is not None and mode not in CONTACT_MODES:
        raise doc.error(["contact_mode"], f"expected one of {', '.join(CONTACT_MODES)}, got {mode!r}")
    signals = raw.get("signals", ["q", "qd"])
    if isinstance(signals, str):
        signals = [signals]
    if not isinstance(signals, list) or not signals:
        raise doc.error(["signals"], f"expected a list of signals from {', '.join(SIGNALS)}")
    for i, s in enumerate(signals):
        if s not in SIGNALS:
            raise doc.error(["signals", i], f"unknown signal {s!r}; choose from {', '.join(SIGNALS)}")
    skip = _number(doc, ["skip"], raw.get("skip", 0.0))
    metric = raw.get("metric", f"{signals[0]}_max")
    valid_metrics = [f"{x}_{m}" for s in signals for x in (s, *COMPONENTS[s]) for m in ("max", "pct")]
    if metric not in valid_metrics:
        raise doc.error(["metric"], f"unknown metric {metric!r}; with these signals: {', '.join(valid_metrics)}")
    fit = None
    if raw.get("fit") is not None:
        check_keys(doc, ["fit"], raw["fit"], ["x", "floor"], ["x"])
        if not isinstance(raw["fit"]["x"], str):
            raise doc.error(["fit", "x"], "expected the name of a swept column, e.g. dt")
        fit = Fit(raw["fit"]["x"], _number(doc, ["fit", "floor"], raw["fit"].get("floor", 0.0)))
    window = None
    if raw.get("short_horizon") is not None:
        check_keys(doc, ["short_horizon"], raw["short_horizon"], ["window"], ["window"])
        window = _number(doc, ["short_horizon", "window"], raw["short_horizon"]["window"], positive=True)
    studies_raw = raw["studies"]
    if not isinstance(studies_raw, list) or not studies_raw:
        raise doc.error(["studies"], "expected a non-empty list of studies")
    studies = tuple(_study(doc, i, s) for i, s in enumerate(studies_raw))
    if fit is not None and not any(_column(k) == fit.x for st in studies for k in st.grid):
        raise doc.error(["fit", "x"], f"no study sweeps a column named {fit.x!r}")
    fit_x = fit.x if fit is not None else None
    for i, st in enumerate(studies if fit_x is not None else ()):  # a log-log slope against numbers
        for k, values in st.grid.items():
            text = next((v for v in values if isinstance(v, bool) or not isinstance(v, int | float)), None)
            if _column(k) == fit_x and text is not None:
                raise doc.error(["fit", "x"], f"{fit_x!r} is not a numeric column: studies[{i}].grid.{k} sweeps "
                                              f"{text!r}; the fit is a log-log slope of the metric against x, which "
                                              "must be a swept number such as dt")  # fmt: skip
    for i, st in enumerate(studies if fit_x is not None else ()):  # one slope per study and backend, over one key
        others = [k for k in st.grid if _column(k) != fit_x]
        if others and len(others) < len(st.grid):
            raise doc.error(["studies", i, "grid"], f"the fit over {fit_x!r} takes one slope per study and backend, "
                                                    f"but this study also sweeps {', '.join(others)}: that slope "
                                                    "would mix their lines; give each value its own study (as "
                                                    "scenarios/sweeps/timestep.yaml does per integrator)")  # fmt: skip
    _check_values(doc, scenario, common, studies)
    _check_references(doc, common, studies)  # after the values: a bad one is named as it is, not as a same run
    duration = float(common.get("duration", base_scenario.duration))  # the runs' (the sweep's own set may change it)
    if skip >= duration:  # every error metric would be undefined (NaN), and the sweep would still pass
        raise doc.error(["skip"], f"{skip:g} s skips the whole of the runs ({duration:g} s)")
    if window is not None:  # against the runs' control period and length
        control_dt = 1.0 / float(common.get("control_rate", base_scenario.control_rate))
        try:
            horizon.window_ticks(window, control_dt)
        except LegbenchError as exc:
            raise doc.error(["short_horizon", "window"], str(exc)) from None
        if window > duration:
            raise doc.error(["short_horizon", "window"], f"{window:g} s is longer than the runs ({duration:g} s)")
    return Sweep(name, description, str(path), scenario, common, mode, tuple(signals), skip, metric, fit, window,
                 studies, raw, base_scenario.sha256, dict(base_scenario.raw))  # fmt: skip


def _check_values(doc: YamlContext, scenario: Path, common: Mapping[str, Any], studies: Sequence[Study]) -> None:
    """Every value of every grid (and set) validated as the scenario would take it, one value at a time
    (linear in the grid sizes, not their product): ``dt: [abc]`` is refused here, naming the sweep's key."""
    for i, st in enumerate(studies):
        for backend in st.backends:
            base = {_fill(k, backend): v for k, v in {**common, **st.set}.items() if _applies(_fill(k, backend),
                                                                                               backend)}  # fmt: skip
            # the fixed values together (a pair of settings may be valid only together: MuJoCo's pyramidal cone
            # with the contact's friction reference); where they fail, the one value that fails alone with the same
            # problem is named (not one that fails alone only against the defaults the others replace)
            try:
                scenario_mod.load(scenario, base, origin="the study's")
            except ScenarioError as together:
                # the sweep's own set (top level) first, then the study's: the one key named where it was given
                for where, fixed in ((["set"], common), (["studies", i, "set"], st.set)):
                    for key, v in fixed.items():
                        filled = _fill(key, backend)
                        if not _applies(filled, backend):
                            continue
                        one = {filled: v}
                        try:
                            scenario_mod.load(scenario, one, origin="the study's")
                        except ScenarioError as alone:
                            if (alone.key, alone.problem) != (together.key, together.problem):
                                continue
                            if where == ["set"]:  # worded as the sweep's
                                _check_point(doc, scenario, [*where, key], one, backend, origin="the sweep's")
                            raise _study_error(doc, [*where, key], backend, alone) from None
                raise _study_error(doc, ["studies", i, "set"] if st.set else ["set"], backend, together) from None
            checks: list[tuple[list[str | int], dict[str, Any]]] = []
            ref_set = {_fill(k, backend): v for k, v in st.reference_set.items()}
            ref_set = {k: v for k, v in ref_set.items() if _applies(k, backend)}
            if ref_set:
                checks.append((["studies", i, "reference", "set"], {**base, **ref_set}))
            for key, values in st.grid.items():
                for v in values:
                    if _applies(_fill(key, backend), backend):
                        checks.append((["studies", i, "grid", key], {**base, _fill(key, backend): v}))
            for path, overrides in checks:
                _check_point(doc, scenario, path, overrides, backend)


def _check_point(doc: YamlContext, scenario: Path, path: list[str | int], overrides: Mapping[str, Any],
                 backend: str, origin: str = "the study's") -> None:  # fmt: skip
    """The scenario with ``overrides`` loads, else the sweep's error at ``path`` (the key that gave them)."""
    try:
        scenario_mod.load(scenario, overrides, origin=origin)
    except ScenarioError as exc:
        raise _study_error(doc, path, backend, exc) from None


def _study_error(doc: YamlContext, path: list[str | int], backend: str, exc: ScenarioError) -> ScenarioError:
    """The sweep file's error at ``path`` for the scenario's ``exc`` with ``backend``'s settings."""
    where = f"{exc.key}: " if exc.key else ""
    return doc.error(path, f"with {backend}: {where}{exc.problem}")


def _study(doc: YamlContext, i: int, d: Any) -> Study:
    p: list[str | int] = ["studies", i]
    check_keys(doc, p, d, STUDY_KEYS, ["backends", "reference"])
    label = d.get("label")
    if label is None:
        label = ""
    if not isinstance(label, str):
        raise doc.error([*p, "label"], "expected text (may contain {backend})")
    names = d["backends"]
    if isinstance(names, str):
        names = registry.available() if names == "all" else [names]
    if not isinstance(names, list) or not names:
        raise doc.error([*p, "backends"], "expected a backend name, a list of names, or 'all'")
    known = sorted(set(registry.BUILTIN) | set(registry.available()))
    for j, n in enumerate(names):
        if n not in known:
            raise doc.error([*p, "backends", j], f"unknown backend {n!r}; known: {', '.join(known)}")
        if n in names[:j]:  # each of its runs would be a second row of the table, and a second point of the fit
            raise doc.error([*p, "backends", j], f"{n} given twice")
    fixed = _dotted(doc, [*p, "set"], d.get("set"))
    grid_raw = _dotted(doc, [*p, "grid"], d.get("grid"))
    grid: dict[str, tuple[Any, ...]] = {}
    for k, v in grid_raw.items():
        if not isinstance(v, list) or not v:
            raise doc.error([*p, "grid", k], "expected a non-empty list of values")
        grid[k] = tuple(v)
    _check_overlaps(doc, p, names, fixed, grid)
    points = math.prod(len(v) for v in grid.values()) * len(names)
    if points > limit("sweep_points"):
        raise doc.error([*p, "grid"], f"{points} runs ({' x '.join(str(len(v)) for v in grid.values())} grid points "
                                      f"x {len(names)} backends) is more than {limit('sweep_points')} "
                                      "(limit sweep_points: LEGBENCH_LIMITS=sweep_points=N raises it)")  # fmt: skip
    ref = d["reference"]
    check_keys(doc, [*p, "reference"], ref, ["backend", "set"])
    ref_backend = ref.get("backend")
    if ref_backend is not None and ref_backend not in known:
        raise doc.error([*p, "reference", "backend"], f"unknown backend {ref_backend!r}; known: {', '.join(known)}")
    ref_set = _dotted(doc, [*p, "reference", "set"], ref.get("set"))
    if not ref_set and ref_backend is None:
        raise doc.error([*p, "reference"], "give a backend and/or a set: as written the reference is the run itself")
    return Study(label, tuple(names), fixed, grid, ref_backend, ref_set)


def _check_overlaps(doc: YamlContext, p: list[str | int], names: Sequence[str], fixed: Mapping[str, Any],
                    grid: Mapping[str, Any]) -> None:  # fmt: skip
    """No two of a study's keys set the same value for any of its backends: a grid key and another (or a set key)
    where one is the other or a whole part of it (``physics.contact`` and ``physics.contact.Kp``; ``backends.*.dt``
    and ``backends.mujoco.dt``), else the runs took one of them and the table recorded the other's values."""
    for k in grid:
        if k in fixed:
            raise doc.error([*p, "grid", k], "also given in this study's set; give it in one place")
        others = [(o, "another grid key") for o in grid if o != k] + [(o, "this study's set") for o in fixed]
        for n in names:
            a = _fill(k, n)
            for other, where in others:
                b = _fill(other, n)
                if keys_overlap(a, b):
                    raise doc.error([*p, "grid", k], f"sets what {other} in {where} sets too (with {n}: {b}); "
                                                     "give it in one place")  # fmt: skip


# --------------------------------------------------------------------------- #
# Plan


def _column(key: str, backend: str | None = None) -> str:
    """Table column of a swept key: ``backends.*.dt`` (or ``backends.<backend>.dt``) -> ``dt``; others unchanged."""
    for prefix in ("backends.*.", f"backends.{backend}." if backend else None):
        if prefix and key.startswith(prefix) and len(key) > len(prefix):
            return key[len(prefix) :]
    return key


def _applies(key: str, backend: str) -> bool:
    """A concrete dotted key affects a run of ``backend`` (it is not another backend's setting)."""
    parts = key.split(".")
    return not (len(parts) > 2 and parts[0] == "backends" and parts[1] != backend)


def _fill(key: str, backend: str) -> str:
    return ".".join(backend if part == "*" else part for part in key.split("."))


def _overrides(
    backend: str, sources: Sequence[tuple[list[str | int], Mapping[str, Any], str]]
) -> tuple[dict[str, Any], dict[str, list[str | int]]]:
    """The scenario overrides of a run of ``backend`` from ``sources`` (path, mapping, the backend ``*`` means),
    later ones winning, other backends' settings dropped; and the sweep key each came from."""
    overrides: dict[str, Any] = {}
    origin: dict[str, list[str | int]] = {}
    for path, mapping, star in sources:
        for k, v in mapping.items():
            dotted = _fill(k, star)
            if not _applies(dotted, backend):
                continue  # another backend's setting: no effect on this run
            overrides[dotted] = v
            origin[dotted] = [*path, k]
    return overrides, origin


def _check_references(doc: YamlContext, common: Mapping[str, Any], studies: Sequence[Study]) -> None:
    """No run is its own reference (docs/studies.md): a reference on the run's backend whose ``reference.set``
    leaves every override of some grid point as the run has it (none given, the same values, or only other
    backends' settings) would be the same run, every error 0 and the sweep passing, as :func:`plan` builds it."""
    for i, st in enumerate(studies):
        points = list(itertools.product(*st.grid.values())) if st.grid else [()]
        for backend in st.backends:
            if (st.reference_backend or backend) != backend:
                continue
            for point in points:
                gp = dict(zip(st.grid, point, strict=True))
                sources: list[tuple[list[str | int], Mapping[str, Any], str]] = [
                    ([], common, backend),
                    ([], st.set, backend),
                    ([], gp, backend),
                ]
                run, _ = _overrides(backend, sources)
                ref, _ = _overrides(backend, [*sources, ([], st.reference_set, backend)])
                if json.dumps(run, sort_keys=True, default=str) != json.dumps(ref, sort_keys=True, default=str):
                    continue
                at = " at " + ", ".join(f"{_column(k, backend)}={v!r}" for k, v in gp.items()) if gp else ""
                given = f"reference.backend {backend}" if st.reference_backend else "no reference.backend"
                raise doc.error(["studies", i, "reference"],
                                f"with {backend}{at}, the reference is the run itself ({given}, and "
                                f"reference.set changes none of its settings): every error would be 0; give the "
                                f"reference another backend or a setting of {backend} that differs")  # fmt: skip


@dataclass(frozen=True)
class Row:
    """One row of the sweep table: a grid point of a study on one backend, or a reference run.

    Attributes:
        study: study index.
        label: label of the row's series (study and backend).
        role: ``"run"`` (a grid point) or ``"reference"`` (a run only used as a reference).
        backend: backend name.
        run: index of the task that produced the row's run.
        ref: index of the reference task (None for a reference row).
        params: table column -> swept value.
    """

    study: int
    label: str
    role: str
    backend: str
    run: int
    ref: int | None
    params: Mapping[str, Any]


@dataclass(frozen=True)
class Plan:
    """Unique runs to execute and the table rows they make.

    Attributes:
        tasks: the runs, ``tasks[i].index == i``.
        rows: table rows in order.
        notes: what was skipped and why (a backend not installed here).
    """

    tasks: tuple[RunTask, ...]
    rows: tuple[Row, ...]
    notes: tuple[str, ...]


def _label(study: Study, backend: str) -> str:
    if study.label:
        return study.label.replace("{backend}", backend)
    extra = " ".join(f"{_column(k, backend)}={v}" for k, v in study.set.items())
    return f"{backend} {extra}".strip()


def plan(sweep: Sweep) -> Plan:
    """Expand the studies into unique runs and table rows; check every run's scenario.

    Each run's overrides (common ``set``, study ``set``, grid point, and for a
    reference its ``reference.set``) are validated by loading the scenario with
    them, so a bad value is reported before anything runs. A ``*`` key part
    stands for the run's backend, also in the overrides its reference inherits
    (``backends.*.dt`` of a study of backend A sets A's step, not that of a
    reference on backend B); only ``reference.set`` fills ``*`` with the reference's
    backend. Settings of other backends are dropped from a run's overrides, so
    runs that differ only there are one run.

    Raises:
        ScenarioError: naming the sweep file and the key whose value the scenario rejects.
    """
    here = set(registry.available())
    tasks: list[RunTask] = []
    index: dict[tuple[Any, ...], int] = {}
    rows: list[Row] = []
    ref_rows: dict[int, Row] = {}
    notes: list[str] = []

    def task_for(backend: str, sources: list[tuple[list[str | int], Mapping[str, Any], str]], ref: int | None) -> int:
        """The task of ``backend`` with the overrides of ``sources`` (path, mapping, backend that ``*`` means)."""
        overrides, origin = _overrides(backend, sources)
        key = (backend, json.dumps(overrides, sort_keys=True, default=str), ref)
        if key in index:
            return index[key]
        try:
            scenario_mod.load(sweep.scenario, overrides, origin="the study's")
        except ScenarioError as exc:
            for concrete, where in origin.items():
                if keys_overlap(exc.key, concrete):
                    raise _doc_of(sweep).error(where, f"{overrides[concrete]!r} for {backend}: {exc.problem}") from None
            raise
        i = len(tasks)
        tasks.append(RunTask(i, str(sweep.scenario), overrides, backend, sweep.contact_mode))
        index[key] = i
        return i

    for si, st in enumerate(sweep.studies):
        base: list[str | int] = ["studies", si]
        ref_name = st.reference_backend
        if ref_name is not None and ref_name not in here:
            notes.append(f"study {si} ({st.label or 'unlabelled'}): reference backend {ref_name} is not installed "
                         "here; study skipped")  # fmt: skip
            continue
        points = list(itertools.product(*st.grid.values())) if st.grid else [()]
        for backend in st.backends:
            if backend not in here:
                notes.append(f"study {si}: backend {backend} is not installed here; skipped")
                continue
            label = _label(st, backend)
            for point in points:
                gp = dict(zip(st.grid, point, strict=True))
                sources: list[tuple[list[str | int], Mapping[str, Any], str]] = [
                    (["set"], sweep.set, backend),
                    ([*base, "set"], st.set, backend),
                    ([*base, "grid"], gp, backend),
                ]
                rb = ref_name or backend
                ref_sources = [*sources, ([*base, "reference", "set"], st.reference_set, rb)]
                ref = task_for(rb, ref_sources, None)
                params = {_column(k, backend): v for k, v in {**st.set, **gp}.items()}
                if ref not in ref_rows:
                    inherited = {k: v for k, v in {**st.set, **gp}.items() if _applies(_fill(k, backend), rb)}
                    own = {**inherited, **st.reference_set}
                    rparams = {_column(k, rb): v for k, v in own.items()}
                    settings = " ".join(f"{_column(k, rb)}={v}" for k, v in own.items() if k.startswith("backends."))
                    ref_label = f"{rb} reference {settings}".strip()
                    ref_rows[ref] = Row(si, ref_label, "reference", rb, ref, None, rparams)
                run = task_for(backend, sources, ref if sweep.short_horizon else None)
                rows.append(Row(si, label, "run", backend, run, ref, params))
    run_tasks = {r.run for r in rows}
    rows += [r for i, r in sorted(ref_rows.items()) if i not in run_tasks]
    return Plan(tuple(tasks), tuple(rows), tuple(notes))


def _doc_of(sweep: Sweep) -> YamlContext:
    try:
        return YamlContext(sweep.file, read_yaml(sweep.file)[1])
    except ScenarioError:
        return YamlContext(sweep.file, None)


# --------------------------------------------------------------------------- #
# Execute


class SweepInterrupted(KeyboardInterrupt):
    """Ctrl-C (or SIGTERM) during :func:`execute`; ``results`` holds every run that finished."""

    def __init__(self, results: dict[int, TaskResult]) -> None:
        super().__init__("interrupted")
        self.results = results


#: Reason given to a run an interrupt stopped before it finished.
NOT_RUN = "not run: interrupted"


def _cost(task: RunTask, default: float) -> float:
    """Relative cost of a run, to start the longest first: 1 / its finest step override (``*.dt``, ``*.max_step``)
    [1/s], else ``default``; the same scenario for every run, so its duration does not matter."""
    steps = [float(v) for k, v in task.overrides.items() if k.rsplit(".", 1)[-1] in ("dt", "max_step")
             and isinstance(v, int | float) and not isinstance(v, bool) and v > 0]  # fmt: skip
    return 1.0 / min(steps) if steps else default


def _crashed(task: RunTask, why: str) -> TaskResult:
    """The row of a run whose worker process died under it (the engine crashed): failed, with why."""
    return TaskResult(task.index, crashed(task.backend, why))


def execute(sweep: Sweep, p: Plan, executor: Executor, bar: progress.Progress | None = None) -> dict[int, TaskResult]:
    """Run every task of the plan, the longest first.

    Without short-horizon replays every run is independent: all go to the
    executor at once. With them, the references run first and the other runs
    after, each with its reference's log to replay.

    Args:
        sweep: the sweep.
        p: its plan.
        executor: where the runs go.
        bar: counts finished runs (one :meth:`~legbench.progress.Progress.update` per run).

    Returns:
        task index -> the :class:`~legbench.studies.tasks.TaskResult`.

    Raises:
        SweepInterrupted: Ctrl-C; carries the runs that finished (the executor is terminated).
    """
    results: dict[int, TaskResult] = {}

    def run(batch: list[RunTask]) -> None:
        order = sorted(range(len(batch)), key=lambda j: (-_cost(batch[j], 1.0e3), j))
        for _, r in executor.imap_unordered(run_task, batch, order, _crashed):
            results[r.index] = r
            if r.run.status == "interrupted":  # Ctrl-C reached a run in this process (one job)
                raise KeyboardInterrupt
            if bar is not None:
                bar.update(1, r.run.backend)

    try:
        if sweep.short_horizon is None:
            run(list(p.tasks))
            return results
        ref_ids = sorted({r.ref for r in p.rows if r.ref is not None})
        run([p.tasks[i] for i in ref_ids])
        second: list[RunTask] = []
        ref_of = {r.run: r.ref for r in p.rows if r.role == "run"}
        for t in p.tasks:
            if t.index in results:
                continue
            ref = ref_of.get(t.index)
            if ref is not None and results[ref].run.status == "ok":
                t = dataclasses.replace(t, replay_window=sweep.short_horizon, reference=results[ref].run)
            second.append(t)
        run(second)
    except (KeyboardInterrupt, BrokenExecutor):
        executor.terminate()
        raise SweepInterrupted(results) from None
    return results


# --------------------------------------------------------------------------- #
# Table


def run_metrics(res: RunResult, ref: RunResult, signals: Sequence[str], skip: float = 0.0) -> dict[str, float]:
    """Error of a run against its reference: ``<c>_max`` [unit] and ``<c>_pct`` [%] per component and signal.

    Compared over the ticks both runs logged with t >= ``skip`` [s]
    (:func:`legbench.metrics.signal_errors`); NaN when either run failed
    before that or the time grids differ.
    """
    out = {f"{x}_{m}": math.nan for s in signals for x in (s, *COMPONENTS[s]) for m in ("max", "pct")}
    if res.status != "ok" or ref.status != "ok":
        return out
    for s in signals:
        d, pct = signal_errors(res, ref, s, skip)
        for j, c in enumerate(COMPONENTS[s]):
            out[f"{c}_max"], out[f"{c}_pct"] = float(d[j]), float(pct[j])
        out[f"{s}_max"] = float(d.max())
        out[f"{s}_pct"] = float(np.nanmax(pct)) if np.isfinite(pct).any() else math.nan
    return out


def _peak_columns(h: HorizonResult | None, skip: float, prefix: str) -> dict[str, float]:
    """``<prefix><component>_max`` and ``<prefix><signal>_max``: the largest peak deviation of ``h`` over the
    windows that start at or after ``skip`` [s] (NaN without ``h``)."""
    out: dict[str, float] = {}
    kept = None if h is None else np.asarray(h.t0) >= skip - T_EPS
    for s in horizon.SIGNALS:
        peak = None if h is None else np.asarray(h.peak[s])[kept]
        for j, c in enumerate(COMPONENTS[s]):
            col = None if peak is None else peak[:, j]
            out[f"{prefix}{c}_max"] = horizon.largest_peak(col) if col is not None else math.nan
        vals = [out[f"{prefix}{c}_max"] for c in COMPONENTS[s]]
        out[f"{prefix}{s}_max"] = max(vals) if all(math.isfinite(v) for v in vals) else math.nan
    return out


def _horizon_columns(
    h: HorizonResult | None, skip: float = 0.0, floor: HorizonResult | None = None
) -> dict[str, float | bool]:
    """The short-horizon columns: ``sh_<component>_max``, the largest peak deviation over the windows that start
    at or after ``skip`` [s] (the sweep's skip, as its other columns; every window is in the windows table);
    ``sh_floor_<component>_max`` the same for the reset floor ``floor`` (the run's own log replayed on its
    backend); ``sh_<signal>_reset_limited``, whether the signal's local error cannot be told from that floor
    (:func:`legbench.studies.horizon.reset_limited`)."""
    out: dict[str, float | bool] = {**_peak_columns(h, skip, "sh_"), **_peak_columns(floor, skip, "sh_floor_")}
    for s in horizon.SIGNALS:
        out[f"sh_{s}_reset_limited"] = horizon.reset_limited(float(out[f"sh_{s}_max"]), float(out[f"sh_floor_{s}_max"]))
    return out


def _plain(v: Any) -> Any:
    """A table cell: numbers stay numbers, lists and mappings become JSON text."""
    if isinstance(v, list | tuple | dict):
        return json.dumps(v)
    return v


def tabulate(sweep: Sweep, p: Plan, results: Mapping[int, TaskResult]) -> tuple[pd.DataFrame, pd.DataFrame]:
    """The sweep table (one row per :class:`Row`) and the short-horizon windows table (may be empty)."""
    param_cols = list(dict.fromkeys(k for r in p.rows for k in r.params))
    records: list[dict[str, Any]] = []
    windows: list[dict[str, Any]] = []
    for r in p.rows:
        task = results[r.run]
        res = task.run
        sim_time = float(res.t[-1]) if len(res.t) else 0.0
        wall = float(res.wall_time)
        rec: dict[str, Any] = {
            "sweep": sweep.name, "study": r.study, "label": r.label, "role": r.role, "backend": r.backend,
            "run": r.run, "ref": r.ref if r.ref is not None else -1,
            **{c: _plain(r.params.get(c)) for c in param_cols},
            "status": res.status, "reason": res.reason or "",
            "sim_time": sim_time, "wall_time": wall,
            "rtf": sim_time / wall if wall > 0 and res.status == "ok" else math.nan,
            "wall_per_sim_s": wall / sim_time if sim_time > 0 and res.status == "ok" else math.nan,
        }  # fmt: skip
        if r.ref is not None:
            ref = results[r.ref].run
            rec.update(run_metrics(res, ref, sweep.signals, sweep.skip))
            if ref.status != "ok":
                rec["reason"] = (rec["reason"] + "; " if rec["reason"] else "") + f"reference failed: {ref.reason}"
        else:
            rec.update({f"{x}_{m}": math.nan for s in sweep.signals for x in (s, *COMPONENTS[s])
                        for m in ("max", "pct")})  # fmt: skip
        if sweep.short_horizon is not None:
            h = task.horizon if r.role == "run" else None
            fl = task.floor if r.role == "run" else None
            rec.update(_horizon_columns(h, sweep.skip, fl))
            rec["sh_status"] = h.status if h else ""
            if h is not None:
                nf = 0 if fl is None else len(fl.t0)  # the same windows: both logs have the scenario's ticks
                for w, t0 in enumerate(np.asarray(h.t0)):
                    for s in horizon.SIGNALS:
                        for j, c in enumerate(COMPONENTS[s]):
                            end, peak = float(h.end[s][w, j]), float(h.peak[s][w, j])
                            f_end = float(fl.end[s][w, j]) if fl is not None and w < nf else math.nan
                            f_peak = float(fl.peak[s][w, j]) if fl is not None and w < nf else math.nan
                            windows.append({"run": r.run, "ref": r.ref, "label": r.label, "backend": r.backend,
                                            "t0": float(t0), "signal": s, "component": c, "end": end,
                                            "peak": peak, "floor_end": f_end, "floor_peak": f_peak})  # fmt: skip
        records.append(rec)
    table = pd.DataFrame.from_records(records)
    for c in param_cols:  # one type per column, so Parquet can hold it
        vals = [v for v in table[c] if v is not None and not (isinstance(v, float) and math.isnan(v))]
        if vals and all(isinstance(v, int | float) and not isinstance(v, bool) for v in vals):
            table[c] = pd.to_numeric(table[c], errors="coerce").astype(float)
        else:
            table[c] = [None if v is None or (isinstance(v, float) and math.isnan(v)) else str(v) for v in table[c]]
    return table, pd.DataFrame.from_records(windows)


def fit_slopes(table: pd.DataFrame, metric: str, fit: Fit) -> pd.DataFrame:
    """Least-squares slope of log(metric) against log(x) per study and backend (the convergence order).

    Only rows of role ``run`` that succeeded, with finite positive x and a
    metric above ``fit.floor``, are used; fewer than two points give NaN and a note.
    """
    rows: list[dict[str, Any]] = []
    if fit.x not in table.columns:
        return pd.DataFrame(rows)
    runs = table[(table["role"] == "run")]
    for (study, backend), g in runs.groupby(["study", "backend"], sort=True):
        x = pd.to_numeric(g[fit.x], errors="coerce").to_numpy(float)
        y = g[metric].to_numpy(float)
        ok = (g["status"].to_numpy() == "ok") & np.isfinite(x) & (x > 0) & np.isfinite(y) & (y > fit.floor)
        rec: dict[str, Any] = {"study": int(study), "label": g["label"].iloc[0], "backend": backend, "x": fit.x,
                               "metric": metric, "n_points": int(ok.sum()), "slope": math.nan,
                               "intercept": math.nan, "x_min": math.nan, "x_max": math.nan, "note": ""}  # fmt: skip
        if ok.sum() >= 2 and len(set(x[ok])) >= 2:
            slope, intercept = np.polyfit(np.log(x[ok]), np.log(y[ok]), 1)
            rec.update(slope=float(slope), intercept=float(intercept), x_min=float(x[ok].min()),
                       x_max=float(x[ok].max()))  # fmt: skip
            left = int(len(x) - ok.sum())
            if left:
                rec["note"] = (
                    f"{left} point(s) left out (failed, {fit.x} not > 0, or at or below the floor {fit.floor:g})"
                )
        elif len(set(x[np.isfinite(x)])) < 2:  # the study holds it at one value (an adaptive solver's sweep)
            rec["note"] = f"{fit.x} takes one value in this study: no slope against it"
        else:
            rec["note"] = f"fewer than two usable points (at two values of {fit.x} > 0) above the floor {fit.floor:g}"
        rows.append(rec)
    return pd.DataFrame(rows)


# --------------------------------------------------------------------------- #
# Output


def _figure(width: float = 7.0, height: float = 5.0) -> Any:
    # matplotlib is imported where figures are drawn (the pool's workers), not by every sweep's main process
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height))
    FigureCanvasAgg(fig)
    return fig


def _minor_label(v: float, _: Any) -> str:
    return f"{v:g}" if f"{v:.0e}"[0] in "25" else ""


def _no_label(v: float, _: Any) -> str:
    return ""


def _save(fig: Any, ax: Any, path: Path) -> Path:
    """Grid, legend, fixed margins; the figure written to ``path`` (PNG, 120 dpi).

    Fixed margins instead of ``tight_layout``: it measured every tick label's extent, 0.7 s of the 1.2 s a
    figure took, serial after the parallel runs; the labels here are short and fit the margins. Log axes
    get plain labels ("1e-05", "0.001"): mathtext typesetting of "10^-5" was a third of a figure's time."""
    from matplotlib.ticker import FuncFormatter

    for axis in (ax.xaxis, ax.yaxis):
        if axis.get_scale() == "log":  # plain "1e-05" labels: the default's mathtext was a third of the figure
            plain = FuncFormatter(lambda v, _: f"{v:g}")
            axis.set_major_formatter(plain)
            lo, hi = sorted(axis.get_view_interval())
            short = lo > 0 and hi / lo < 30.0  # within about a decade and a half: label 2 and 5 as well
            axis.set_minor_formatter(FuncFormatter(_minor_label if short else _no_label))
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    fig.subplots_adjust(left=0.13, right=0.97, bottom=0.1, top=0.93)
    fig.savefig(path, dpi=120)
    return path


def _series(table: pd.DataFrame) -> list[tuple[str, pd.DataFrame]]:
    runs = table[(table["role"] == "run") & (table["status"] == "ok")]
    return [(str(g["label"].iloc[0]), g) for _, g in runs.groupby(["study", "backend"], sort=True)]


#: Markers given to backends in registry order (so overlapping lines of different engines stay visible).
MARKERS = ("o", "s", "^", "D", "v", "P", "X")


@functools.cache
def _backend_order() -> tuple[str, ...]:
    # the registry scans the installed distributions' entry points: once per process, not once per line drawn
    return tuple(registry.available())


def _style(g: pd.DataFrame) -> dict[str, Any]:
    """Marker by backend (its place among the available backends), open symbols."""
    names = [*_backend_order(), str(g["backend"].iloc[0])]
    marker = MARKERS[names.index(str(g["backend"].iloc[0])) % len(MARKERS)]
    return {"marker": marker, "mfc": "none", "ls": "-", "ms": 7}


def _axis_label(metric: str) -> str:
    base, _, kind = metric.rpartition("_")
    if kind == "pct":
        return f"{metric} [%]"
    signal = next((s for s in SIGNALS if base == s or base in COMPONENTS[s]), "")
    return f"{metric} [{UNITS.get(signal, '')}]"


def plot_convergence(table: pd.DataFrame, fits: pd.DataFrame, metric: str, fit: Fit, path: Path) -> Path:
    """Log-log plot of the metric against the fitted column, one line per study and backend, slopes in the legend."""
    fig = _figure()
    ax = fig.add_subplot()
    slopes = {(int(r.study), r.backend): r.slope for r in fits.itertuples()} if len(fits) else {}
    for label, g in _series(table):
        x = pd.to_numeric(g[fit.x], errors="coerce").to_numpy(float)
        y = g[metric].to_numpy(float)
        ok = np.isfinite(x) & (x > 0) & np.isfinite(y) & (y > 0)
        if not ok.any():
            continue
        order = np.argsort(x[ok])
        s = slopes.get((int(g["study"].iloc[0]), g["backend"].iloc[0]), math.nan)
        ax.loglog(x[ok][order], y[ok][order], label=f"{label} (slope {s:.2f})", **_style(g))
    if fit.floor > 0:
        ax.axhline(fit.floor, color="0.6", ls=":", lw=1, label=f"floor {fit.floor:g}")
    ax.set_xlabel(f"{fit.x} [s]" if fit.x == "dt" else fit.x)
    ax.set_ylabel(_axis_label(metric))
    ax.set_title("error against the reference run")
    return _save(fig, ax, path)


def plot_speed_accuracy(table: pd.DataFrame, metric: str, path: Path) -> Path:
    """Wall time per simulated second against the metric, every study and backend on one figure."""
    fig = _figure()
    ax = fig.add_subplot()
    for label, g in _series(table):
        x = g[metric].to_numpy(float)
        y = g["wall_per_sim_s"].to_numpy(float)
        ok = np.isfinite(x) & (x > 0) & np.isfinite(y) & (y > 0)
        if ok.any():
            order = np.argsort(x[ok])
            ax.loglog(x[ok][order], y[ok][order], label=label, **_style(g))
    ax.axhline(1.0, color="0.6", ls=":", lw=1, label="real time")
    ax.set_xlabel(_axis_label(metric))
    ax.set_ylabel("wall time per simulated second [s/s]")
    ax.set_title("speed against accuracy")
    return _save(fig, ax, path)


def plot_sweep(table: pd.DataFrame, metric: str, path: Path) -> Path | None:
    """The metric against each study's first swept column (log axes where the values span a decade)."""
    fig = _figure()
    ax = fig.add_subplot()
    drawn = False
    xcol = ""
    for label, g in _series(table):
        params = [c for c in g.columns if c not in _FIXED_COLUMNS and not _is_metric(c) and g[c].notna().any()]
        varying = [c for c in params if g[c].nunique() > 1]
        if not varying:
            continue
        xcol = varying[0]
        x = pd.to_numeric(g[xcol], errors="coerce").to_numpy(float)
        y = g[metric].to_numpy(float)
        ok = np.isfinite(x) & np.isfinite(y)
        if not ok.any():
            continue
        order = np.argsort(x[ok])
        ax.plot(x[ok][order], y[ok][order], label=f"{label} vs {xcol}", **_style(g))
        drawn = True
        if (x[ok] > 0).all() and x[ok].max() >= 10 * x[ok].min():
            ax.set_xscale("log")
    if not drawn:
        return None
    if (table[metric] > 0).any():
        ax.set_yscale("log")
    ax.set_xlabel(xcol)
    ax.set_ylabel(_axis_label(metric))
    return _save(fig, ax, path)


_FIXED_COLUMNS = frozenset({"sweep", "study", "label", "role", "backend", "run", "ref", "status", "reason",
                            "sim_time", "wall_time", "rtf", "wall_per_sim_s", "sh_status"})  # fmt: skip


def _is_metric(col: str) -> bool:
    return col.endswith(("_max", "_pct"))


@dataclass(frozen=True)
class SweepResult:
    """What :func:`run_sweep` produced.

    Attributes:
        sweep: the validated sweep.
        table: one row per grid point and reference run.
        fits: convergence slopes (empty without ``fit``).
        windows: short-horizon windows (empty without ``short_horizon``).
        notes: what was skipped and why.
        out_dir: where the files are (None if not written).
        complete: every run finished (False after an interrupt: the runs not finished have status
            ``interrupted``).
    """

    sweep: Sweep
    table: pd.DataFrame
    fits: pd.DataFrame
    windows: pd.DataFrame
    notes: tuple[str, ...]
    out_dir: Path | None
    complete: bool = True


def _plot(figure: tuple[str, Any]) -> str | None:
    """One of the sweep's figures, ``(kind, arguments)``, drawn in this process (or a pool worker): its path."""
    kind, args = figure
    draws: dict[str, Callable[..., Path | None]] = {
        "convergence": plot_convergence, "speed_accuracy": plot_speed_accuracy, "sweep": plot_sweep}  # fmt: skip
    draw = draws[kind]
    path = draw(*args[:-1], Path(args[-1]))
    return str(path) if path is not None else None


#: Every file a sweep writes into its output directory (:func:`write_sweep`); nothing else is legbench's there.
OUTPUTS = ("sweep.json", "sweep.csv", "sweep.parquet", "fits.csv", "short_horizon.csv", "short_horizon.parquet",
           "convergence.png", "speed_accuracy.png", "sweep.png")  # fmt: skip


def check_out(out_dir: Path, name: str) -> None:
    """Refuse an output directory holding another sweep's results or anything else (empty or missing: fine; a
    sweep of this name holding only its own :data:`OUTPUTS`: replaced). Checked before the runs and again before
    writing. A sweep is written whole and swapped in place of the old directory, so a file or folder of the
    user's in it (notes, plots) is refused, never lost (as ``legbench run --force`` refuses such a run directory).

    Raises:
        LegbenchError: one line naming the directory and what it holds (the first entry not legbench's).
    """
    out_dir = Path(out_dir)
    old = out_dir / "sweep.json"
    if old.is_file():
        try:
            prev = json.loads(old.read_text()).get("name")
        except (OSError, ValueError, AttributeError):
            prev = None
        if prev != name:
            raise LegbenchError(f"{out_dir}: holds results of sweep {prev!r}, not {name!r}; choose another --out or "
                                "remove it")  # fmt: skip
        # only its own files: what a results tree holds beside them (a run directory, a study's output, a
        # temporary) is not a sweep's own either, and the swap would lose it
        nested = next((p.name for p in sorted(out_dir.iterdir()) if p.name not in OUTPUTS or not p.is_file()), None)
        if nested is not None:
            raise LegbenchError(f"{out_dir}: not only a legbench sweep directory (it holds {nested}), and a sweep "
                                "replaces the whole directory; move it away, or choose another --out")  # fmt: skip
    elif out_dir.is_dir() and any(out_dir.iterdir()):
        first = sorted(p.name for p in out_dir.iterdir())[0]
        raise LegbenchError(f"{out_dir}: not empty and not a legbench sweep directory (it holds {first}); choose "
                            "another --out")  # fmt: skip


def write_sweep(
    result: SweepResult,
    out_dir: Path,
    executor: Mapping[str, Any] | None = None,
    plots_on: Executor | None = None,
) -> Path:
    """Write the table (CSV + Parquet), fits, windows, ``sweep.json`` and plots into ``out_dir`` atomically.

    ``plots_on``: an executor whose workers draw the figures side by side (the sweep's own pool, still
    running); None draws them here, one after the other.

    Refuses to replace a directory holding another sweep or anything else.
    """
    out_dir = Path(out_dir)
    check_out(out_dir, result.sweep.name)
    # built whole in a temporary beside it and swapped in (removed on a failure: a full disk, an interrupt);
    # temporaries of killed sweeps beside it are cleaned first (results.clean_stale)
    with atomic_dir(out_dir) as tmp:
        sw = result.sweep
        result.table.to_csv(tmp / "sweep.csv", index=False)
        result.table.to_parquet(tmp / "sweep.parquet", index=False)
        files = ["sweep.csv", "sweep.parquet"]
        if len(result.fits):
            result.fits.to_csv(tmp / "fits.csv", index=False)
            files.append("fits.csv")
        if len(result.windows):
            result.windows.to_csv(tmp / "short_horizon.csv", index=False)
            result.windows.to_parquet(tmp / "short_horizon.parquet", index=False)
            files += ["short_horizon.csv", "short_horizon.parquet"]
        figures: list[tuple[str, Any]] = [
            ("speed_accuracy", (result.table, sw.metric, str(tmp / "speed_accuracy.png"))),
            ("sweep", (result.table, sw.metric, str(tmp / "sweep.png"))),
        ]
        if sw.fit is not None:
            args = (result.table, result.fits, sw.metric, sw.fit, str(tmp / "convergence.png"))
            figures.insert(0, ("convergence", args))
        drawn = plots_on.map(_plot, figures) if plots_on is not None else [_plot(f) for f in figures]
        files += [Path(p).name for p in drawn if p is not None]
        meta = {
            "schema": SCHEMA,
            "name": sw.name,
            "complete": result.complete,
            "description": sw.description,
            "file": sw.file,
            "scenario": resources.shown(sw.scenario),
            "scenario_sha256": sw.base_sha256,  # the base scenario's document as loaded (its runs' overrides aside)
            "scenario_raw": dict(sw.base_raw),
            "sweep": dict(sw.raw),
            "metric": sw.metric,
            "runs": int((result.table["role"] == "run").sum()),
            "failed": int(result.table["status"].isin(["failed", "missing"]).sum()),
            "not_run": int((result.table["status"] == "interrupted").sum()),
            "fits": result.fits.to_dict(orient="records"),
            "notes": list(result.notes),
            "executor": dict(executor or {}),
            "files": files,
            "versions": versions(),
            "platform": platform_info(),
        }
        (tmp / "sweep.json").write_text(json.dumps(meta, indent=2, default=str))
    return out_dir


def run_sweep(
    sweep_file: str | Path,
    out_dir: str | Path | None = None,
    executor: str | Executor = "local",
    jobs: int | None = None,
    scheduler: str | None = None,
    quiet: bool = True,
) -> SweepResult:
    """Validate, plan, run and tabulate a sweep, and write it to ``out_dir`` (None: do not write).

    Args:
        sweep_file: the sweep YAML file.
        out_dir: output directory; None writes nothing.
        executor: ``"local"``, ``"dask"``, or an :class:`~legbench.studies.executors.Executor` (not closed here).
        jobs: worker count for a named executor (default: the CPU count).
        scheduler: Dask scheduler address (``executor="dask"``); None starts a local cluster.
        quiet: no progress bar (else a count of finished runs with the ETA, on a terminal outside CI).

    Raises:
        ScenarioError: the sweep file, or a value it sets, is invalid.
        LegbenchError: the executor cannot start, or ``out_dir`` holds something else.
        KeyboardInterrupt: Ctrl-C or SIGTERM; the runs that finished are written first (``sweep.json``
            ``complete: false``, the others ``interrupted`` in the table) and a line on stderr says so.
    """
    own = not isinstance(executor, Executor)
    # the workers also import this module and matplotlib while they start: they draw the figures at the end
    preload = (*DEFAULT_PRELOAD, "legbench.studies.sweep", "matplotlib.figure", "matplotlib.backends.backend_agg")
    if executor == "local" and (jobs or os.cpu_count() or 1) > 1:
        warm_up(preload)  # the fork server imports the engines while the sweep is read and planned here
    sw = load_sweep(sweep_file)
    if out_dir is not None:  # before any run: a folder of someone else's was refused only when writing
        check_out(Path(out_dir), sw.name)
    p = plan(sw)
    # no more workers than runs (each is a process holding every engine; --jobs 1000 started 1000)
    ex = executor if isinstance(executor, Executor) else make_executor(executor, jobs, scheduler, preload,
                                                                       tasks=len(p.tasks))  # fmt: skip
    try:
        ex.start()
    except BaseException:
        if own:
            ex.terminate()
        raise
    interrupted = False
    results: dict[int, TaskResult] = {}
    try:
        with progress.bar(len(p.tasks), f"sweep {sw.name}", quiet=quiet) as bar:
            results = execute(sw, p, ex, bar) if p.tasks else {}
        described = ex.describe()
    except KeyboardInterrupt as exc:  # SweepInterrupted carries the finished runs; one before the first, none
        results = dict(exc.results) if isinstance(exc, SweepInterrupted) else {}
        interrupted, described = True, {"executor": getattr(ex, "name", "")}
        for t in p.tasks:  # what did not finish, as rows marked interrupted
            if t.index not in results:
                results[t.index] = TaskResult(t.index, RunResult.empty(t.backend, "interrupted", NOT_RUN))
    except BaseException:
        if own:
            ex.close()
        raise
    try:
        with deferred_interrupts():  # a signal now acts once the table is written (the runs are done)
            table, windows = tabulate(sw, p, results) if p.rows else (pd.DataFrame(), pd.DataFrame())
            fits = fit_slopes(table, sw.metric, sw.fit) if sw.fit is not None and len(table) else pd.DataFrame()
            result = SweepResult(sw, table, fits, windows, p.notes, None, not interrupted)
            kept = any(t.run.status != "interrupted" for t in results.values())
            if out_dir is not None and len(table) and (not interrupted or kept):
                # the figures on the sweep's own pool while it still runs (not after an interrupt: it is stopped)
                plots_on = ex if own and not interrupted and getattr(ex, "jobs", 1) > 1 else None
                path = write_sweep(result, Path(out_dir), described, plots_on)
                result = SweepResult(sw, table, fits, windows, p.notes, path, not interrupted)
    finally:
        if own:
            ex.close()
    if interrupted:
        done = sum(t.run.status != "interrupted" for t in results.values())
        where = f"written to {result.out_dir} (complete: false)" if result.out_dir else "nothing written"
        print(f"interrupted: sweep {sw.name}: {done} of {len(p.tasks)} runs finished and kept, {where}",
              file=sys.stderr, flush=True)  # fmt: skip
        raise KeyboardInterrupt
    return result


# --------------------------------------------------------------------------- #
# Command line


def _complete(out: Path) -> bool:
    """Whether the sweep in ``out`` finished (its sweep.json says ``complete``; an unreadable one counts as
    finished: it is not ours to call interrupted)."""
    try:
        return bool(json.loads((out / "sweep.json").read_text()).get("complete", True))
    except (OSError, ValueError, AttributeError):
        return True


def _cli(args: argparse.Namespace) -> int:
    out = Path(args.out) if args.out is not None else Path("results") / "sweeps" / load_sweep(args.sweep).name
    if (out / "sweep.json").exists() and not args.force:  # with or without --out, as for runs
        held = "a finished sweep" if _complete(out) else "an interrupted sweep (a sweep is not resumed)"
        raise LegbenchError(f"{out} holds {held}; choose another --out for a new one, or --force to replace it")
    res = run_sweep(args.sweep, out, args.executor, args.jobs, args.scheduler, quiet=args.quiet)
    t = res.table
    if not len(t):
        print(f"{res.sweep.name}: nothing to run")
        for n in res.notes:
            print(f"  note: {n}")
        return 1
    runs = t[t["role"] == "run"]
    print(f"{res.sweep.name}: {len(runs)} runs + {int((t['role'] == 'reference').sum())} references, "
          f"{int((t['status'] != 'ok').sum())} failed")  # fmt: skip
    for n in res.notes:
        print(f"  note: {n}")
    for r in t[t["status"] != "ok"].itertuples():
        print(f"  {r.label}: {r.status}: {r.reason}")
    for f in res.fits.itertuples() if len(res.fits) else ():
        print(f"  {f.label:<34} slope of {f.metric} vs {f.x}: {f.slope:6.2f} ({f.n_points} points) {f.note}")
    print(f"wrote {res.out_dir}")
    refs_failed = t[(t["role"] == "reference") & (t["status"] != "ok")]
    return 1 if len(refs_failed) else 0


def add_cli(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Register ``legbench sweep SWEEP.yaml [--out DIR] [--jobs N] [--executor local|dask] [--scheduler ADDR]``."""
    p = subparsers.add_parser("sweep", help="run a parameter sweep (grid over scenario and backend settings)")
    p.add_argument("sweep", help="sweep YAML file (format: docs/studies.md)")
    p.add_argument("--out", default=None, help="output directory (default results/sweeps/<sweep name>)")
    p.add_argument("--force", action="store_true",
                   help="replace a sweep (finished or interrupted) in the output directory")  # fmt: skip
    p.add_argument("--jobs", type=int, default=None, help="parallel runs (default: CPU count)")
    p.add_argument("--executor", choices=EXECUTORS, default="local",
                   help="local process pool or Dask (default local)")  # fmt: skip
    p.add_argument("--scheduler", default=None, help="Dask scheduler address, e.g. tcp://host:8786 "
                                                     "(default with --executor dask: a local cluster)")  # fmt: skip
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=_cli)
