"""The Python API: run a scenario, get pandas DataFrames, compare, report.

Example (also in the README)::

    import legbench

    res = legbench.run_scenario("effort", backends=["pinocchio", "mujoco"], overrides={"duration": 0.5})
    res["mujoco"]            # the log of one backend: DataFrame of the run columns (t [s], q1 [rad], ...)
    cmp = res.compare()      # every metric of docs/metrics.md against the scenario's reference backend
    cmp.metrics              # the long metrics table (DataFrame)
    res.report("my-report")  # report.html / report.md / metrics.json in a new directory
    old = legbench.open_run("results/latest/effort")  # a run directory already on disk, as the same Result

Everything is measured by :mod:`legbench.compare` and :mod:`legbench.metrics` and written by
:mod:`legbench.report`, as by the command line; this module only ties them together. A
:class:`Result` and a :class:`Comparison` render as small HTML tables in Jupyter.

Runs are written to a run directory (the same layout as ``legbench run --out``): the ``out``
argument, else a new temporary directory, so nothing the user has is ever overwritten. :func:`open_run`
reads one back, whoever wrote it (``legbench run``, ``make compare``, :func:`run_scenario`).
"""

from __future__ import annotations

import copy
import dataclasses
import html
import math
import numbers
import os
import reprlib
import shutil
import stat
import tempfile
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from legbench import logs, resources, yamlfile
from legbench import scenario as scenario_mod
from legbench.compare import ComparisonResult, compare, log_settings_problem, reference_sibling
from legbench.exceptions import LegbenchError, ResultsError, ScenarioError
from legbench.metrics import LAG_MODES
from legbench.results import (
    Run,
    RunResult,
    check_out_path,
    load_run,
    out_dir_for,
)
from legbench.scenario import Scenario
from legbench.signals import RUN_COLUMNS, SIGNALS, SLICE

__all__ = ["Comparison", "Result", "load_scenario", "open_run", "run_scenario"]


# --------------------------------------------------------------------------- #
# The arguments of the API, checked once where they come in: a wrong one is one LegbenchError naming the argument
# and what it expects (not a TypeError from pathlib, nor a truthy "no" taken for force=True), before any work.


def _wrong(name: str, value: object, expected: str) -> LegbenchError:
    """``name`` was given ``value`` of the wrong type: one line naming the argument, what it takes and the type."""
    return LegbenchError(f"{name} {reprlib.repr(value)}: expected {expected}, not {type(value).__name__}")


def _flag(value: object, name: str) -> bool:
    """A switch of the API: True or False (numpy's bools too). Anything else is refused, not taken for its truth
    value: ``force="no"`` replaced a finished run."""
    if isinstance(value, bool | np.bool_):
        return bool(value)
    raise _wrong(name, value, "True or False")


def _path(value: object, name: str, what: str = "a path (str or os.PathLike)") -> Path:
    """A path given to the API (str or os.PathLike of str, not empty: "" would be the working directory)."""
    try:
        text = os.fspath(value)  # type: ignore[call-overload]
    except TypeError:
        text = None
    if not isinstance(text, str):
        raise _wrong(name, value, what)
    if not text or "\0" in text:
        raise LegbenchError(f"{name} {text!r}: expected {what}, not an empty name or one holding a NUL character")
    return Path(text)


def _positive(value: object, name: str, hint: str) -> float:
    """A finite number > 0 (not a bool)."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real) or not math.isfinite(value) or value <= 0:
        raise LegbenchError(f"{name} {reprlib.repr(value)}: must be a finite number > 0 {hint}")
    return float(value)


def _finite(value: object, name: str, hint: str) -> float:
    """A finite number (not a bool)."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real) or not math.isfinite(value):
        raise LegbenchError(f"{name} {reprlib.repr(value)}: must be a finite number {hint}")
    return float(value)


_CONTACT_MODES = ("native", "reference", "both")
_SCENARIO = "a bundled scenario's name, a scenario file (str or os.PathLike)"


def _check_source(source: object, scenario_ok: bool) -> None:
    """``scenario`` of :func:`run_scenario` (``scenario_ok``: a :class:`Scenario` too) or ``source`` of
    :func:`load_scenario`."""
    if isinstance(source, Mapping) or (scenario_ok and isinstance(source, Scenario)):
        return
    name, expected = (("scenario", f"{_SCENARIO}, a mapping in the scenario format or a Scenario") if scenario_ok
                      else ("source", f"{_SCENARIO} or a mapping in the scenario format"))  # fmt: skip
    _path(source, name, expected)


def _check_backends(backends: object) -> str | list[str]:
    """Backend names: a comma-separated string (``"all"``) or an iterable of strings; the registry checks the names."""
    expected = "backend names: a list of strings, a comma-separated string or 'all'"
    if isinstance(backends, str):
        return backends
    if not isinstance(backends, Iterable) or isinstance(backends, bytes | bytearray | Mapping):
        raise _wrong("backends", backends, expected)
    names = list(backends)
    for n in names:
        if not isinstance(n, str):
            raise LegbenchError(f"backends {reprlib.repr(names)}: expected {expected}, not a list holding "
                                f"{reprlib.repr(n)} ({type(n).__name__})")  # fmt: skip
    return names


def _check_ros(ros: object, name: str = "ros") -> None:
    """``ros``: a :class:`legbench.logs.RosOptions` whose fields are what the command line's options can give."""
    if not isinstance(ros, logs.RosOptions):
        raise _wrong(name, ros, "legbench.logs.RosOptions(...)")
    for f in ("joint_topic", "wrench_topic"):
        topic = getattr(ros, f)
        if topic is not None and not isinstance(topic, str):
            raise _wrong(f"{name}.{f}", topic, "a topic name (str) or None")
    joints = ros.joints
    if joints is not None and not (
        isinstance(joints, Sequence) and not isinstance(joints, str) and len(joints) == 3
        and all(isinstance(j, str) and j for j in joints)
    ):  # fmt: skip
        raise LegbenchError(f"{name}.joints {reprlib.repr(joints)}: expected the names of joints 1, 2, 3 (three "
                            "strings) or None")  # fmt: skip
    if isinstance(ros.force_sign, bool) or ros.force_sign not in (1.0, -1.0):
        raise LegbenchError(f"{name}.force_sign {reprlib.repr(ros.force_sign)}: expected 1.0 or -1.0")
    t0 = ros.t0
    if t0 is not None and (isinstance(t0, bool) or not isinstance(t0, numbers.Real) or not math.isfinite(t0)):
        raise _wrong(f"{name}.t0", t0, "a finite bag time [s] or None")


def _check_compare_args(kwargs: Mapping[str, Any], method: str) -> None:
    """The keyword arguments of :meth:`Result.compare` and :meth:`Result.report` (those of
    :func:`legbench.compare.compare`), with the rules of ``legbench compare``'s options: a log's settings need the
    log, ``ros`` a ROS bag; ``lag`` one of three."""
    unknown = sorted(set(kwargs) - set(_COMPARE_ARGS))
    if unknown:
        raise LegbenchError(f"{', '.join(unknown)}: not an argument of {method} (it takes {', '.join(_COMPARE_ARGS)})")
    for name, value in kwargs.items():
        _COMPARE_ARGS[name](value, name)
    problem = log_settings_problem(kwargs.get("log"), kwargs.get("column_map"), bool(kwargs.get("log_is_reference")),
                                   kwargs.get("log_time_scale", 1.0), kwargs.get("ros") is not None,
                                   log_t0=kwargs.get("log_t0"))  # fmt: skip
    if problem is not None:  # as legbench compare refuses them
        raise LegbenchError(problem)


#: A check of one argument: its value and its name, raising LegbenchError.
_Check = Callable[[Any, str], object]


def _optional(check: _Check) -> _Check:
    """``check``, or None."""

    def run(value: object, name: str) -> None:
        if value is not None:
            check(value, name)

    return run


def _check_column_map(value: object, name: str) -> None:
    if not isinstance(value, Mapping):
        raise _wrong(name, value, "a mapping of the log's header names to legbench columns, e.g. {'joint1_pos': 'q1'}")
    for src, dst in value.items():
        if not (isinstance(src, str) and src.strip() and isinstance(dst, str) and dst.strip()):
            raise LegbenchError(f"{name} {{{src!r}: {dst!r}}}: expected HEADER: COLUMN, two non-empty strings, "
                                "e.g. {'joint1_pos': 'q1'}")  # fmt: skip


def _check_log_name(value: object, name: str) -> None:
    if not isinstance(value, str) or not value.strip():
        raise _wrong(name, value, "a non-empty name (str)")


def _check_lag(value: object, name: str) -> None:
    if not isinstance(value, str) or value not in LAG_MODES:
        raise LegbenchError(f"{name} {reprlib.repr(value)}: expected one of {', '.join(map(repr, LAG_MODES))}")


def _check_lag_signals(value: object, name: str) -> None:
    if (
        isinstance(value, str) or not isinstance(value, Sequence) or not value
        or not all(isinstance(s, str) and s in SIGNALS for s in value)
    ):  # fmt: skip
        raise LegbenchError(f"{name} {reprlib.repr(value)}: expected a non-empty list of signal names from "
                            f"{', '.join(SIGNALS)}, e.g. ['q']")  # fmt: skip


def _check_split_dir(value: object, name: str) -> None:
    if value is not None and value != "auto":
        _path(value, name, "a run directory (str or os.PathLike), 'auto' or None")


#: Every keyword argument of :func:`legbench.compare.compare` the API passes on, with its check.
_COMPARE_ARGS: dict[str, _Check] = {
    "log": _optional(lambda v, n: _path(v, n, "a log file or ROS bag (str or os.PathLike)")),
    "log_name": _optional(_check_log_name),
    "column_map": _optional(_check_column_map),
    "log_time_scale": lambda v, n: _positive(v, n, "(1e-3 for ms)"),
    "log_t0": _optional(lambda v, n: _finite(v, n, "[s] (the log's time at the run's t = 0)")),
    "log_is_reference": _flag,
    "ros": _optional(_check_ros),
    "all_pairs": _flag,
    "lag": _check_lag,
    "max_lag": lambda v, n: _positive(v, n, "[s] (the largest lag searched)"),
    "lag_signals": _check_lag_signals,
    "split_dir": _check_split_dir,
}


def load_scenario(source: str | Path | Mapping[str, Any], overrides: Mapping[str, Any] | None = None) -> Scenario:
    """A validated scenario from a file, a bundled scenario's name or a mapping (the YAML format).

    Args:
        source: a path to a scenario YAML; a bundled scenario's name (``"effort"``,
            ``"verification/energy"``) when no such file exists; or a mapping with the keys of
            the scenario format.
        overrides: dotted keys set before validation (``{"duration": 0.5, "backends.mujoco.dt": 5e-4}``).

    Raises:
        ScenarioError: the scenario is invalid (file, key and problem); ``overrides`` is not a mapping of dotted keys.
        LegbenchError: ``source`` is none of the three (``None``, a number, bytes).
    """
    _check_source(source, scenario_ok=False)
    _check_overrides(overrides)
    return _load_scenario(source, overrides)


def _plain(value: Any) -> Any:
    """A scenario document (or a value of one) in the scenario format's own types, copied: a tuple or numpy array
    becomes a list, a numpy scalar the Python number or bool it holds, a mapping a dict; anything else is kept for
    the validator to name (``joint: np.array([0, -1, -1])`` was refused as "expected a list of 3 numbers")."""
    if isinstance(value, Mapping):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, np.ndarray | np.generic):
        return value.tolist()  # nested lists of Python numbers; a 0-d array or a numpy scalar the number itself
    if isinstance(value, list | tuple):
        return [_plain(v) for v in value]
    return copy.deepcopy(value)


def _load_scenario(source: str | Path | Mapping[str, Any], overrides: Mapping[str, Any] | None) -> Scenario:
    """:func:`load_scenario` of arguments already checked."""
    overrides = None if overrides is None else {k: _plain(v) for k, v in overrides.items()}
    if isinstance(source, Mapping):
        doc: dict[str, Any] = _plain(source)
        scenario_mod.apply_overrides(doc, overrides, "overrides")
        return scenario_mod.parse(doc, "<mapping>", overridden=tuple(overrides or ()), origin="overrides")
    path = Path(source)
    if not path.is_file() and resources.scenario(str(source)).is_file():  # a folder of that name is no scenario
        path = resources.scenario(str(source))
    return scenario_mod.load(path, overrides, "overrides")


def _fmt(v: float, unit: str = "") -> str:
    if not math.isfinite(v):
        return "&ndash;"
    return f"{v:.4g}{(' ' + unit) if unit else ''}"


def _html_table(caption: str, header: Sequence[str], rows: Sequence[Sequence[str]]) -> str:
    head = "".join(f"<th>{html.escape(h)}</th>" for h in header)
    body = "".join("<tr>" + "".join(f"<td>{c}</td>" for c in r) + "</tr>" for r in rows)
    return (
        f"<table><caption>{html.escape(caption)}</caption><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"
    )


def _nanmax(a: np.ndarray) -> float:
    a = np.asarray(a, float)
    return float(np.nanmax(np.abs(a))) if np.isfinite(a).any() else float("nan")


@dataclass(frozen=True, eq=False)
class Comparison:
    """The comparison of one run: a thin view of :class:`legbench.compare.ComparisonResult`.

    Attributes:
        result: everything :func:`legbench.compare.compare` measured.
    """

    result: ComparisonResult

    @property
    def reference(self) -> str:
        """The backend (or log) every other one was measured against."""
        return self.result.reference

    @property
    def metrics(self) -> pd.DataFrame:
        """The long metrics table (columns and metric names in docs/metrics.md)."""
        return self.result.frame()

    def summary(self) -> pd.DataFrame:
        """One row per trace: steady-state means over the final window and the largest deviations from the reference.

        Columns: ``backend``; ``q1..q3_steady`` [rad] and ``fx, fy, fz_steady`` [N] (means over the
        scenario's steady window, force on the foot in W); ``q_max_abs`` [rad], the largest
        |q - q_ref| over the joints after ``skip``; ``q_sim_error_pct`` [%], the largest simulation
        error of q over the joints (NaN for the reference itself or where undefined).
        """
        pairs = {p.backend: p for p in self.result.pairs if p.reference == self.reference}
        rows = []
        q = SLICE["q"]
        for s in self.result.steady:
            p = pairs.get(s.backend)
            row: dict[str, Any] = {"backend": s.backend}
            row |= {f"q{i + 1}_steady": float(s.q[i]) for i in range(3)}
            row |= {f"f{c}_steady": float(s.force[i]) for i, c in enumerate("xyz")}
            row["q_max_abs"] = _nanmax(p.max_abs[q]) if p is not None else float("nan")
            row["q_sim_error_pct"] = _nanmax(p.sim_error_pct[q]) if p is not None else float("nan")
            rows.append(row)
        return pd.DataFrame(rows)

    def _repr_html_(self) -> str:
        df = self.summary()
        header = ["backend", "q steady [rad]", "F steady in W [N]", "max |q - q_ref| [rad]", "sim error q [%]"]
        rows = []
        for r in df.itertuples(index=False):
            name = html.escape(str(r.backend)) + (" (reference)" if r.backend == self.reference else "")
            rows.append(
                [
                    name,
                    ", ".join(_fmt(getattr(r, f"q{i}_steady")) for i in (1, 2, 3)),
                    ", ".join(_fmt(getattr(r, f"f{c}_steady")) for c in "xyz"),
                    _fmt(r.q_max_abs),
                    _fmt(r.q_sim_error_pct),
                ]
            )
        notes = "".join(f"<li>{html.escape(n)}</li>" for n in self.result.notes)
        caption = f"{self.result.run.label}: against {self.reference}"
        return _html_table(caption, header, rows) + (f"<ul>{notes}</ul>" if notes else "")

    def __repr__(self) -> str:
        return f"Comparison({self.result.run.label!r}, reference={self.reference!r}, pairs={len(self.result.pairs)})"


@dataclass(eq=False)
class Result:
    """One scenario run on several backends, held in its run directory (:func:`run_scenario` makes one,
    :func:`open_run` opens one already on disk).

    Attributes:
        scenario: the validated scenario that ran.
        path: the run directory (run.json, ``<backend>.parquet``).
        traces: each backend's outcome, by name (``status`` ``ok``, ``failed``, ``missing`` or, in a run
            stopped by Ctrl-C, ``interrupted``).
        contact_mode: the contact mode it ran in.
        reference_mode: with ``contact_mode="both"`` (or, opened, a sibling ``<name>__reference`` run), the same
            scenario in the reference contact mode (its :meth:`compare` is then split into contact and integration
            parts), else None.
    """

    scenario: Scenario
    path: Path
    traces: dict[str, RunResult]
    contact_mode: str
    reference_mode: Result | None = None
    _comparison: Comparison | None = field(default=None, repr=False)

    @property
    def backends(self) -> list[str]:
        """The backends asked for, in order."""
        return list(self.traces)

    @property
    def frames(self) -> dict[str, pd.DataFrame]:
        """The log of every backend that ran: DataFrames with the columns of :data:`RUN_COLUMNS`
        (t [s]; q [rad], qd [rad/s], tau [N m] per joint; fx, fy, fz, the ground force on the foot in W [N];
        ee_x, ee_y, ee_z, the foot centre in W [m]; controller)."""
        return {name: tr.frame() for name, tr in self.traces.items() if tr.status == "ok"}

    def __getitem__(self, backend: str) -> pd.DataFrame:
        """The log of one backend that ran (see :attr:`frames`).

        Raises:
            KeyError: not a backend of this run (the message lists them), or one that did not run ok (its reason).
        """
        if not isinstance(backend, str) or backend not in self.traces:
            raise KeyError(f"no backend {reprlib.repr(backend)} in this run; its backends: "
                           f"{', '.join(self.traces) or 'none'}")  # fmt: skip
        tr = self.traces[backend]
        if tr.status != "ok":
            raise KeyError(f"backend '{backend}' {tr.status}: {tr.reason}")
        return tr.frame()

    def status(self) -> dict[str, str]:
        """``ok``, or the status and reason, per backend."""
        return {n: tr.status if tr.status == "ok" else f"{tr.status}: {tr.reason}" for n, tr in self.traces.items()}

    def compare(self, **kwargs: Any) -> Comparison:
        """Every metric of docs/metrics.md for this run (:func:`legbench.compare.compare`; its keyword arguments,
        e.g. ``log=`` an external log, ``lag="report"``, ``all_pairs=True``). Cached when called without arguments.
        An error about the log names these arguments (``log_time_scale``, ``column_map``, ``ros``).

        Raises:
            LegbenchError: an argument compare does not take, or of the wrong type or value, named, before anything
                is read; as ``legbench compare`` refuses them, ``column_map``, ``log_is_reference=True`` or
                ``log_time_scale`` without ``log``, ``ros`` without ``log`` naming a ROS bag.
            ResultsError: the run directory or the log is missing or malformed.
        """
        _check_compare_args(kwargs, "compare")
        if kwargs:
            with logs.worded(logs.API_WORDS):
                return Comparison(compare(self.path, **kwargs))
        if self._comparison is None:
            self._comparison = Comparison(compare(self.path))
        return self._comparison

    def report(self, out_dir: str | Path | None = None, **kwargs: Any) -> Path:
        """Write the report (report.html, report.md, metrics.json, figures) and return report.html.

        Args:
            out_dir: a new or empty directory the run is copied into first (an existing non-empty one is
                refused, so nothing is overwritten); None, or the run directory itself, writes into the run
                directory.
            **kwargs: as for :meth:`compare`.

        Raises:
            ResultsError: ``out_dir`` exists and is not empty.
            LegbenchError: ``out_dir`` not a path, a regular file (or other non-directory), a link to nothing, in a
                place that is not writable, another run directory or inside one (this run's too: the copy would be
                taken for part of it); an argument as :meth:`compare` refuses it. All before anything is written.
        """
        _check_compare_args(kwargs, "report")
        from legbench import report  # deferred: matplotlib

        target, fresh = self.path, False
        if out_dir is not None:
            given = _path(out_dir, "out_dir", "a directory (str or os.PathLike) or None")
            try:
                itself = given.resolve() == self.path.resolve()
            except (OSError, RuntimeError):  # a loop of links: not the run, and check_out_path says what it is
                itself = False
            if not itself:
                target = check_out_path(given, "out_dir")  # as legbench's --out: no file, no run, nothing in a run
                fresh = not target.exists()
                try:
                    full = not fresh and any(target.iterdir())
                except OSError as exc:
                    raise ResultsError(str(target), f"cannot read: {exc.strerror or exc}") from None
                if full:
                    raise ResultsError(str(target), "exists and is not empty; name a new directory")
        result = None if kwargs or self._comparison is None else self._comparison.result
        try:
            if target != self.path:  # the run's entries, not the directory: out_dir keeps its own mode
                entries = [e for e in self.path.iterdir() if e.resolve() != target.resolve()]  # before it exists
                target.mkdir(parents=True, exist_ok=True)
                for entry in entries:
                    if entry.is_dir():
                        shutil.copytree(entry, target / entry.name)
                    else:
                        shutil.copy2(entry, target / entry.name)
            with logs.worded(logs.API_WORDS):  # the log's errors name compare's arguments, not the command's options
                files = report.write_report(target, result, **kwargs)
        except BaseException:  # a bad log=, an interrupt: out_dir goes back to how it was, absent or empty
            if target != self.path:
                _empty_again(target, remove=fresh)
            raise
        return Path(files.html)

    def _repr_html_(self) -> str:
        sc = self.scenario
        head = (
            f"<p><b>{html.escape(sc.name)}</b>: {sc.duration:g} s at {sc.control_rate:g} Hz, profile "
            f"{html.escape(sc.profile)}, contact {html.escape(self.contact_mode)} &rarr; "
            f"<code>{html.escape(str(self.path))}</code></p>"
        )
        rows = []
        for name, tr in self.traces.items():
            if tr.status != "ok":
                rows.append([html.escape(name), html.escape(f"{tr.status}: {tr.reason}"), "", ""])
                continue
            rtf = tr.t[-1] / tr.wall_time if tr.wall_time > 0 else float("nan")
            rows.append([html.escape(name), "ok", _fmt(tr.wall_time, "s"), _fmt(rtf)])
        out = head + _html_table("backends", ["backend", "status", "wall time", "real-time factor"], rows)
        if any(tr.status == "ok" for tr in self.traces.values()):
            try:
                out += self.compare()._repr_html_()
            except LegbenchError as exc:
                out += f"<p>comparison: {html.escape(str(exc))}</p>"
        return out

    def __repr__(self) -> str:
        return f"Result({self.scenario.name!r}, backends={self.status()}, path={str(self.path)!r})"


def _empty_again(directory: Path, remove: bool) -> None:
    """Undo a report into ``directory``, which was empty or absent before (``remove``): what was put in it goes,
    the directory itself (its mode, owner, a link to it) stays unless this call made it."""
    if remove:
        shutil.rmtree(directory, ignore_errors=True)
        return
    for entry in list(directory.iterdir()):
        if entry.is_dir() and not entry.is_symlink():
            shutil.rmtree(entry, ignore_errors=True)
        else:
            entry.unlink(missing_ok=True)


def _check_overrides(overrides: object) -> None:
    """``overrides`` is None or a mapping of dotted keys (strings), else a ScenarioError (not an AttributeError or
    TypeError from inside the loader)."""
    if overrides is None:
        return
    if not isinstance(overrides, Mapping):
        raise ScenarioError(
            "<overrides>", "", f"expected a mapping of dotted keys to values, got {type(overrides).__name__}"
        )
    for key in overrides:
        if not isinstance(key, str) or not key:
            raise ScenarioError("<overrides>", repr(key), "expected a dotted scenario key (a non-empty string)")


def _trace(run: Run, name: str) -> RunResult:
    """One backend of a run directory read back: an ok backend's log, else an empty result with its status and
    reason (a failed backend's partial log, if any, is in ``run.partial``); either way with the settings
    (``info``) and wall time [s] run.json records for it (NaN where it records none)."""
    b = run.backends[name]
    tr = run.traces[name] if name in run.traces else RunResult.empty(name, b.status, b.reason or "")
    return dataclasses.replace(tr, info=dict(b.info), wall_time=b.wall_time)


def _traces(run_dir: Path, names: Sequence[str], ran: Sequence[RunResult]) -> dict[str, RunResult]:
    """Every backend asked for, in that order: those that ran now, and those an interrupted run into the same
    directory had finished (resumed, not run again: read back from the run directory)."""
    got = {tr.backend: tr for tr in ran}
    missing = [n for n in names if n not in got]
    if missing:
        run = load_run(run_dir)
        got |= {n: _trace(run, n) for n in missing if n in run.backends}
    return {n: got[n] for n in names if n in got}


def run_scenario(
    scenario: str | Path | Mapping[str, Any] | Scenario,
    backends: str | Sequence[str] = "all",
    overrides: Mapping[str, Any] | None = None,
    profile: str | None = None,
    contact_mode: str | None = None,
    out: str | Path | None = None,
    jobs: int = 1,
    progress: bool | np.bool_ = False,
    force: bool | np.bool_ = False,
) -> Result:
    """Run one scenario on several backends, as ``legbench run`` does, and return the :class:`Result`.

    Args:
        scenario: a scenario file, a bundled scenario's name (``"effort"``), a mapping in the scenario
            format, or a :class:`~legbench.scenario.Scenario`.
        backends: backend names, a comma-separated string, or ``"all"`` (every installed backend).
        overrides: dotted scenario keys set before validation (``{"duration": 0.5}``), as ``--set``.
        profile: ``"matched"`` or ``"engine-defaults"`` (default: the scenario's).
        contact_mode: ``"native"``, ``"reference"`` or ``"both"`` (default: the scenario's). With
            ``"both"`` the result is the native run and :attr:`Result.reference_mode` the other.
        out: the run directory (with ``"both"``: the root of ``<name>/`` and ``<name>__reference/``); it
            must not hold another scenario's run. Default: a new temporary directory.
        jobs: processes to run the backends in (at least 1). A script that passes ``jobs > 1`` runs its
            call under ``if __name__ == "__main__":``: the worker processes (fork server or spawn) import
            the main module again.
        progress: show a progress bar on stderr.
        force: replace a finished run (or an interrupted one of other settings) in ``out``, as ``--force``;
            without it that is refused, and an interrupted run of the same settings is resumed.

    Raises:
        ScenarioError: invalid scenario or override (``overrides`` not a mapping of string keys included).
        BackendNotFound: an unknown backend name.
        LegbenchError: an argument of the wrong type, named (``scenario`` none of the four, ``backends`` not
            strings, ``out`` not a path, ``progress`` or ``force`` not True or False: ``force="no"`` is refused,
            not taken for true); ``jobs`` not a whole number at least 1; ``contact_mode`` not one of the three;
            ``out`` a regular file or in a place that is not writable; ``out`` holds another scenario's run or
            anything that is not a legbench run (with ``"both"``: not a results tree); ``out`` holds a finished run
            and ``force`` is not set. All before anything runs.
    """
    from legbench import backends as registry
    from legbench import run as run_mod  # deferred: imports the backends

    # every argument's type first, then what needs the scenario: nothing is read, made or run for a wrong one
    _check_source(scenario, scenario_ok=True)
    given_backends = _check_backends(backends)
    _check_overrides(overrides)
    if profile is not None and not isinstance(profile, str):  # its value is the scenario's to check, below
        raise _wrong("profile", profile, "'matched' or 'engine-defaults'")
    if contact_mode is not None and (not isinstance(contact_mode, str) or contact_mode not in _CONTACT_MODES):
        raise LegbenchError(f"contact_mode {reprlib.repr(contact_mode)}: expected 'native', 'reference' or 'both'")
    given = {"profile": None if profile is None else f"profile={profile!r}",
             "physics.contact_mode": None if contact_mode is None else f"contact_mode={contact_mode!r}"}  # fmt: skip
    yamlfile.check_one_place(overrides or {}, given, "overrides")  # as the command line: one would win in silence
    out_path = _path(out, "out", "a directory (str or os.PathLike) or None") if out is not None else None
    if isinstance(jobs, bool) or not isinstance(jobs, numbers.Integral):  # 1.5 ran in one process, "2" a TypeError
        raise LegbenchError(f"jobs {jobs!r}: expected a whole number of processes, at least 1")
    jobs = int(jobs)  # numpy's integers too
    if jobs < 1:  # as the command line's --jobs: 0 would still run, in one process
        raise LegbenchError(f"jobs {jobs}: must be at least 1")
    progress, force = _flag(progress, "progress"), _flag(force, "force")  # force="no" replaced a finished run
    if isinstance(scenario, Scenario):
        sc = _load_scenario(scenario.raw, overrides) if overrides else scenario
    else:
        sc = _load_scenario(scenario, overrides)
    if profile is not None and profile != sc.profile:  # as the CLI: a profile override is part of the scenario
        doc = {**copy.deepcopy(dict(sc.raw)), "profile": profile}
        sc = scenario_mod.parse(doc, sc.file or "<mapping>")  # not overrides: a bad profile names the file
    names = registry.resolve(given_backends, "backends")
    for mode in ("native", "reference") if contact_mode == "both" else (contact_mode,):
        if mode is not None and mode != sc.contact_mode:  # as the command line: the mode checked as if the file gave it
            scenario_mod.check_contact_mode(sc, names, mode, f"contact_mode={contact_mode!r}")
    if out_path is not None:  # as the command line's --out: a regular file is one error, not NotADirectoryError
        check_out_path(out_path, "out", run_dir_ok=True)
    root = out_path if out_path is not None else Path(tempfile.mkdtemp(prefix=f"legbench-{sc.name}-"))
    if contact_mode == "both":  # each mode in the scenario it records (scenario.in_contact_mode), as the CLI's
        plan = [(scenario_mod.in_contact_mode(sc, m), m, out_dir_for(root, sc, m)) for m in ("native", "reference")]
        run_mod.check_tree(root, [d.name for *_, d in plan], "out")
    else:
        plan = [(scenario_mod.in_contact_mode(sc, contact_mode), contact_mode or sc.contact_mode, root)]
    # as the command line: another scenario's run or a foreign folder is refused outright, a finished run of this
    # one is replaced only when asked
    run_mod.check_outs(plan, force, "choose another out", "force=True", "out", backends=names)
    outcome = run_mod.run_many(plan, names, jobs=jobs, progress=progress)
    made = [Result(s, d, _traces(d, names, res), mode) for (s, mode, d), res in zip(plan, outcome, strict=True)]
    if len(made) == 2:
        made[0].reference_mode = made[1]
    return made[0]


def _run_dir(path: Path) -> None:
    """``path`` is a run directory to open, else a one-line :class:`ResultsError` saying what it is: missing, a
    file (or another non-directory), or a results tree's root (naming one of its runs). A folder with neither
    run.json nor runs in it is left to :func:`legbench.results.load_run` ("no run.json here")."""
    try:
        mode = path.stat().st_mode
        if not stat.S_ISDIR(mode):
            hint = f"open its folder, {path.parent}" if path.name == "run.json" else "a folder holding run.json"
            raise ResultsError(str(path), f"is {yamlfile.file_kind(mode)}, not a run directory ({hint})")
        if (path / "run.json").is_file():
            return
        runs = sorted(p.name for p in path.iterdir() if (p / "run.json").is_file())
    except (FileNotFoundError, NotADirectoryError):
        raise ResultsError(str(path), "no such run directory") from None
    except OSError as exc:  # permissions, a name too long
        raise ResultsError(str(path), f"cannot read: {exc.strerror or exc}") from None
    if runs:
        raise ResultsError(str(path), f"is a results tree of {len(runs)} run(s), not a run directory: open one of "
                                      f"them, e.g. {path / runs[0]}")  # fmt: skip


def _recorded_scenario(run: Run) -> Scenario:
    """The scenario run.json records, validated again: its ``scenario.raw`` (the scenario document as run, overrides
    applied), which must still validate here and hash to the recorded ``scenario.sha256``.

    Raises:
        ResultsError: naming run.json and ``scenario.raw``: absent or not an object; invalid with this legbench,
            its leg model and the backends installed here (a plug-in's settings, a joint target outside another
            model's limits); or not the document that ran (its hash differs: edited afterwards).
    """
    rj = run.path / "run.json"
    recorded = run.meta["scenario"]  # an object with a name: load_run checked it
    raw = recorded.get("raw")
    if raw is None:
        raise ResultsError(str(rj), "missing key 'scenario.raw' (the scenario document as run)")
    if not isinstance(raw, Mapping):
        raise ResultsError(str(rj), f"must be an object, not {type(raw).__name__}", "scenario.raw")
    file = recorded.get("file")
    try:
        sc = scenario_mod.parse(copy.deepcopy(dict(raw)), file if isinstance(file, str) and file else str(rj))
    except ScenarioError as exc:
        where = f"{exc.key}: " if exc.key else ""
        raise ResultsError(str(rj), f"does not validate here ({where}{exc.problem}): validated again with this "
                                    "legbench, its leg model and the backends installed here",
                           "scenario.raw") from None  # fmt: skip
    sha = recorded.get("sha256")
    if isinstance(sha, str) and sha and sha != sc.sha256:
        raise ResultsError(str(rj), f"hashes to {sc.sha256[:12]}..., not to scenario.sha256 {sha[:12]}...: not the "
                                    "scenario that ran (edited afterwards)", "scenario.raw")  # fmt: skip
    return sc


def open_run(path: str | Path) -> Result:
    """Open a run directory already on disk as a :class:`Result`, as :func:`run_scenario` returns it.

    Any run directory will do: ``legbench run SCENARIO --out DIR``, one of a results tree
    (``results/latest/effort`` after ``make compare``), or a :func:`run_scenario` ``out``. Everything is
    read through :func:`legbench.results.load_run`, which checks run.json and every ok backend's log
    (columns, finite values, t spanning the scenario's 0 .. duration [s]); nothing runs again.

    * :attr:`Result.scenario`: run.json's ``scenario.raw`` (the scenario document as run, overrides
      applied) validated again, with the recorded hash; its ``file`` is the one run.json names.
    * :attr:`Result.traces`: every backend of run.json, in its order: an ok backend's log, else an
      empty trace with its status (``failed``, ``missing``, ``interrupted``) and reason; each with the
      settings (``info``) and wall time [s] run.json records.
    * :attr:`Result.contact_mode`: run.json's (``native`` when it names none).
    * :attr:`Result.reference_mode`: for a native-mode run whose sibling ``<name>__reference`` holds a run of
      the same scenario name in reference contact mode (``legbench run --contact-mode both``,
      ``contact_mode="both"``, ``make compare``), that run opened too; :meth:`Result.compare` then holds the
      contact / integration split, as :func:`legbench.compare.compare` finds the same sibling. Else None.

    :meth:`Result.report` with no directory writes the report into the run directory itself, as
    ``legbench compare DIR`` does (metrics.json, report.md, report.html replaced; the logs and run.json
    untouched).

    Example::

        import legbench

        res = legbench.open_run("results/latest/effort")
        res.status()                       # {"pinocchio": "ok", "mujoco": "ok", ...}
        res["mujoco"][["t", "q1", "fz"]]   # t [s], q1 [rad], fz [N]
        res.compare().summary()            # split by contact mode: results/latest/effort__reference

    Args:
        path: the run directory (the folder holding run.json).

    Raises:
        LegbenchError: ``path`` is not a path (str or os.PathLike: not None, bytes or a number).
        ResultsError: one line naming the path: it is missing, a file, a folder without run.json or a
            results tree's root (naming one of its runs); or run.json, a log or the sibling reference-mode run
            is malformed; or the recorded scenario no longer validates here (another leg model, a plug-in
            backend not installed) or is not the one that ran (see :func:`legbench.results.load_run`).
    """
    given = _path(path, "path", "a run directory (str or os.PathLike)")
    _run_dir(given)
    run = load_run(given)
    scenario = _recorded_scenario(run)
    res = Result(scenario, given, {n: _trace(run, n) for n in run.backends}, run.contact_mode)
    sibling = reference_sibling(given, run.contact_mode)
    if sibling is not None:
        other = open_run(sibling)
        if other.contact_mode == "reference" and other.scenario.name == res.scenario.name:
            res.reference_mode = other
    return res


#: The log columns of every DataFrame the API returns (see :attr:`Result.frames`).
COLUMNS = RUN_COLUMNS
