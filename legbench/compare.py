"""Compare runs: align time series, compute the metrics of LEG_SPEC.md section 8.

Data flow: ``DIR/run.json`` + ``DIR/<backend>.parquet`` -> :func:`load_run`
(:class:`Run` of :class:`Trace`) -> :func:`compare` (:class:`ComparisonResult`
of :class:`PairMetrics`, :class:`SteadyState`, :class:`ModeSplit`) -> the long
metrics table (:meth:`ComparisonResult.frame`) and ``DIR/metrics.json``
(:func:`write_metrics`). Between stages everything is frozen dataclasses of
numpy arrays; pandas appears only when files are read and the table is built.
The keys of ``metrics.json`` are documented in ``docs/metrics.md``.

Conventions:
    * A *signal* is one of ``q`` [rad], ``qd`` [rad/s], ``tau`` [N m] (after
      saturation) and ``force`` [N] (the ground force on the foot, in W). Its
      *joints* are ``"1"``, ``"2"``, ``"3"``, or ``"x"``, ``"y"``, ``"z"`` for
      the force (``z`` is Fn).
    * Deviation of backend a from reference r: d(t) = x_a(t) - x_r(t); for the
      angle of a continuous joint (the hip), the shortest angle
      mod(x_a - x_r + pi, 2 pi) - pi, so a wrapped log and an unwrapped one agree.
    * Time lag: a lag L > 0 means a is late, x_a(t) ~ x_r(t - L); removing it
      compares x_a(t + L) with x_r(t).
    * The analytic force check inverts tau = J_poc^T h + G(q): h is the force
      the foot exerts on the environment, the ground force on the foot is -h.
"""

from __future__ import annotations

import json
import logging
import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from legbench.exceptions import ResultsError

__all__ = [
    "COLUMNS",
    "JOINTS",
    "JOINT_OF",
    "SIGNAL_OF",
    "SLICE",
    "LABELS",
    "METRICS_SCHEMA",
    "SIGNALS",
    "UNITS",
    "BackendStatus",
    "ComparisonResult",
    "EventMark",
    "LagEstimate",
    "ModeSplit",
    "PairMetrics",
    "Run",
    "SteadyState",
    "Trace",
    "align",
    "compare",
    "contact_split",
    "deviation",
    "estimate_lag",
    "label",
    "load_log",
    "load_run",
    "load_trace",
    "pair_metrics",
    "read_metrics",
    "steady_state",
    "trace_from_frame",
    "write_metrics",
]

logger = logging.getLogger("legbench.compare")

#: Signals compared, in the order of a trace's data columns.
SIGNALS = ("q", "qd", "tau", "force")
#: Units of each signal.
UNITS = {"q": "rad", "qd": "rad/s", "tau": "N m", "force": "N", "ee": "m", "t": "s"}
#: Component names of each signal ("joint" column of the metrics table).
JOINTS = {"q": ("1", "2", "3"), "qd": ("1", "2", "3"), "tau": ("1", "2", "3"), "force": ("x", "y", "z")}
#: Parquet/CSV column names of each signal.
COLUMNS = {
    "q": ("q1", "q2", "q3"),
    "qd": ("qd1", "qd2", "qd3"),
    "tau": ("tau1", "tau2", "tau3"),
    "force": ("fx", "fy", "fz"),
}
#: The 12 data columns of a trace, in order (q1..q3, qd1..qd3, tau1..tau3, fx, fy, fz).
LABELS: tuple[str, ...] = tuple(c for s in SIGNALS for c in COLUMNS[s])
#: Signal and joint of each of the 12 data columns.
SIGNAL_OF = tuple(s for s in SIGNALS for _ in range(3))
JOINT_OF = tuple(j for s in SIGNALS for j in JOINTS[s])
#: Data columns of each signal.
SLICE = {s: slice(3 * i, 3 * i + 3) for i, s in enumerate(SIGNALS)}
EE_COLUMNS = ("ee_x", "ee_y", "ee_z")
#: Every column of a backend's parquet file.
RUN_COLUMNS = ("t", *LABELS, *EE_COLUMNS, "controller")
#: Version tag written into metrics.json.
METRICS_SCHEMA = "legbench.metrics/1"
#: Columns of the long metrics table.
FRAME_COLUMNS = ("scenario", "backend", "reference", "signal", "joint", "metric", "value")
#: Reference peaks at or below this are zero: the simulation error % is undefined (NaN) [signal unit].
PEAK_FLOOR = 1e-12
#: Two time stamps closer than this are the same tick [s].
T_EPS = 1e-9
#: Jacobians with a larger condition number are treated as singular in the analytic check.
COND_MAX = 1e8

_ALIASES = {"time": "t", "fn": "fz", "f_x": "fx", "f_y": "fy", "f_z": "fz"}


# --------------------------------------------------------------------------- #
# Data


@dataclass(frozen=True, eq=False)
class Trace:
    """One backend's (or log's) time series.

    Attributes:
        name: backend name (or the name given to an imported log).
        t: time stamps, strictly increasing, shape (N,) [s].
        data: the 12 :data:`LABELS` columns, shape (N, 12); NaN where a log lacks a signal.
        ee: foot centre in W, shape (N, 3) [m]; NaN if unknown.
        controller: active controller name per tick, shape (N,) (empty strings if unknown).
        source: file the trace was read from.
    """

    name: str
    t: np.ndarray
    data: np.ndarray
    ee: np.ndarray
    controller: np.ndarray
    source: str = ""

    def signal(self, signal: str) -> np.ndarray:
        """The (N, 3) columns of one signal in its unit (see :data:`UNITS`)."""
        return self.data[:, SLICE[signal]]

    def has(self, signal: str) -> bool:
        """True if the signal has at least one finite sample."""
        return bool(np.isfinite(self.signal(signal)).any())


@dataclass(frozen=True)
class BackendStatus:
    """A backend's entry of run.json.

    Attributes:
        name: backend name.
        status: ``"ok"``, ``"failed"`` or ``"missing"``.
        reason: why it failed or is missing (None when ok).
        info: engine, version and settings as the backend reported them.
        wall_time: wall-clock time of the run [s] (NaN if unknown).
        rtf: real-time factor, simulated time / wall time (NaN if unknown).
        file: its parquet file name, relative to the run directory.
    """

    name: str
    status: str
    reason: str | None
    info: Mapping[str, Any] = field(default_factory=dict, hash=False)
    wall_time: float = math.nan
    rtf: float = math.nan
    file: str = ""


@dataclass(frozen=True)
class EventMark:
    """A controller switch at ``t`` [s] (for vertical lines in plots)."""

    t: float
    controller: str


@dataclass(frozen=True, eq=False)
class Run:
    """A run directory read into memory.

    Attributes:
        path: the directory.
        meta: run.json as read.
        name: scenario name.
        label: ``name`` in native contact mode, ``name + "__reference"`` in reference mode;
            the ``scenario`` column of the metrics table.
        contact_mode: ``"native"`` or ``"reference"``.
        poc: point of contact of the analytic law, ``"true"`` or ``"centre"``.
        reference: the scenario's reference backend.
        skip: start time excluded from the deviation metrics [s].
        steady_window: final window of the steady-state means [s].
        duration: scenario duration [s].
        events: controller switches.
        backends: every backend of run.json, by name, in file order.
        traces: time series of the backends whose status is ok.
        partial: time series of failed backends whose file exists (plotted, not measured).
    """

    path: Path
    meta: Mapping[str, Any]
    name: str
    label: str
    contact_mode: str
    poc: str
    reference: str
    skip: float
    steady_window: float
    duration: float
    events: tuple[EventMark, ...]
    backends: Mapping[str, BackendStatus]
    traces: Mapping[str, Trace]
    partial: Mapping[str, Trace] = field(default_factory=dict)

    @property
    def tolerances(self) -> Mapping[str, Any]:
        """``scenario.comparison.tolerances`` of run.json (empty if absent)."""
        tol = self.meta.get("scenario", {}).get("comparison", {}).get("tolerances") or {}
        return tol if isinstance(tol, Mapping) else {}


@dataclass(frozen=True)
class LagEstimate:
    """A constant time lag found by cross-correlation.

    Attributes:
        seconds: lag L [s]; L > 0 means the backend is late, x_a(t) ~ x_ref(t - L).
        samples: the same in samples of ``dt`` (sub-sample by parabolic interpolation).
        dt: grid spacing of the correlation [s].
        correlation: normalised cross-correlation at the peak, in [-1, 1].
        signals: the signals correlated.
    """

    seconds: float
    samples: float
    dt: float
    correlation: float
    signals: tuple[str, ...]


@dataclass(frozen=True, eq=False)
class PairMetrics:
    """Deviation of one backend from a reference, per column of :data:`LABELS`.

    Metric arrays have shape (12,) and are computed over ``t >= skip``; NaN where a
    signal is missing or the window is empty.

    Attributes:
        backend: the backend compared.
        reference: the backend compared against.
        t: common time grid (the reference's ticks inside both spans), shape (M,) [s].
        deviation: x_a - x_ref on ``t``, shape (M, 12) [signal units].
        sim_error_pct: max_t |d| / max_t |x_ref| * 100 [%]; NaN if max_t |x_ref| <= PEAK_FLOOR.
        rms: sqrt(mean_t d^2) [signal units].
        max_abs: max_t |d| [signal units].
        t_max_abs: first time at which |d| is largest [s].
        ref_peak: max_t |x_ref| [signal units].
        skip: start of the measured window [s].
        lag: the lag estimate, if one was asked for.
        lag_removed: lag taken out of the backend before measuring [s] (0 if none).
    """

    backend: str
    reference: str
    t: np.ndarray
    deviation: np.ndarray
    sim_error_pct: np.ndarray
    rms: np.ndarray
    max_abs: np.ndarray
    t_max_abs: np.ndarray
    ref_peak: np.ndarray
    skip: float
    lag: LagEstimate | None = None
    lag_removed: float = 0.0


@dataclass(frozen=True, eq=False)
class SteadyState:
    """Means over the final window of one backend, and the analytic force check.

    Attributes:
        backend: backend name.
        t0: start of the window [s].
        t1: end of the window [s].
        q: mean joint angles [rad].
        qd: mean joint velocities [rad/s].
        tau: mean joint torques [N m].
        force: mean ground force on the foot in W (Fx, Fy, Fn) [N].
        analytic_poc: ground force on the foot in W from the mean state and torques,
            -(J_poc(q)^T)^-1 (tau - G(q)), J_poc the true point of contact's Jacobian [N].
        analytic_centre: the same with the foot centre's Jacobian J_E; only for runs
            whose contact law takes the poc at the sphere centre, else None [N].
        cond: condition number of J_poc at the mean state (inf if singular).
    """

    backend: str
    t0: float
    t1: float
    q: np.ndarray
    qd: np.ndarray
    tau: np.ndarray
    force: np.ndarray
    analytic_poc: np.ndarray
    analytic_centre: np.ndarray | None
    cond: float

    @property
    def residual(self) -> np.ndarray:
        """Measured minus analytic (J_poc) ground force [N]."""
        return self.force - self.analytic_poc

    @property
    def poc_compensation(self) -> np.ndarray | None:
        """Analytic force with J_poc minus with J_E [N] (None unless the run's poc is the centre)."""
        return None if self.analytic_centre is None else self.analytic_poc - self.analytic_centre


@dataclass(frozen=True, eq=False)
class ModeSplit:
    """One backend's deviation split by cause, from its native and reference-mode runs.

    With a = the backend, r = the reference backend, n = native, R = reference
    contact mode, the native deviation splits exactly, sample by sample::

        a_n - r_n = (a_n - a_R) + (a_R - r_R) + (r_R - r_n)
                     contact      integration   drift

    *contact* is what swapping the analytic contact law for the engine's own
    does to this backend; *integration* is its deviation when every backend
    uses the same contact law (dynamics, integrator, solver); *drift* is the
    reference backend's own mode difference (zero when its native contact is
    the analytic law). Arrays have shape (12,), over ``t >= skip``.

    Attributes:
        backend: the backend split.
        reference: the reference backend.
        native_rms: RMS of a_n - r_n [signal units].
        contact_rms: RMS of a_n - a_R.
        integration_rms: RMS of a_R - r_R.
        drift_rms: RMS of r_R - r_n.
        native_pct: max |a_n - r_n| / max |r_n| * 100 [%].
        contact_pct: max |a_n - a_R| / max |r_n| * 100 [%].
        integration_pct: max |a_R - r_R| / max |r_n| * 100 [%].
        drift_pct: max |r_R - r_n| / max |r_n| * 100 [%].
    """

    backend: str
    reference: str
    native_rms: np.ndarray
    contact_rms: np.ndarray
    integration_rms: np.ndarray
    drift_rms: np.ndarray
    native_pct: np.ndarray
    contact_pct: np.ndarray
    integration_pct: np.ndarray
    drift_pct: np.ndarray


@dataclass(frozen=True, eq=False)
class ComparisonResult:
    """Everything :func:`compare` measured on one run directory.

    Attributes:
        run: the run.
        reference: the reference backend used (the scenario's, or the imported log's name).
        traces: time series compared, by name (ok backends and an imported log).
        pairs: one entry per (backend, reference) pair measured.
        steady: one entry per trace, in :attr:`traces` order.
        split: contact-mode split per backend (empty without a reference-mode sibling).
        split_run: the reference-mode run used for the split.
        notes: plain sentences about what could not be measured and why.
    """

    run: Run
    reference: str
    traces: Mapping[str, Trace]
    pairs: tuple[PairMetrics, ...]
    steady: tuple[SteadyState, ...]
    split: tuple[ModeSplit, ...] = ()
    split_run: Run | None = None
    notes: tuple[str, ...] = ()

    def frame(self) -> pd.DataFrame:
        """The long metrics table, columns :data:`FRAME_COLUMNS` (see docs/metrics.md)."""
        return pd.DataFrame(self.records(), columns=list(FRAME_COLUMNS))

    def records(self) -> list[dict[str, Any]]:
        """The metrics table as a list of dicts (value NaN where undefined)."""
        rows: list[dict[str, Any]] = []
        sc = self.run.label

        def add(backend: str, ref: str, metric: str, values: np.ndarray, idx: Sequence[int] | None = None) -> None:
            for i in idx if idx is not None else range(len(LABELS)):
                rows.append(_row(sc, backend, ref, SIGNAL_OF[i], JOINT_OF[i], metric, values[i]))

        for p in self.pairs:
            for metric in ("sim_error_pct", "rms", "max_abs", "t_max_abs", "ref_peak"):
                add(p.backend, p.reference, metric, getattr(p, metric))
            if p.lag is not None:
                rows.append(_row(sc, p.backend, p.reference, "t", "-", "lag", p.lag.seconds))
                rows.append(_row(sc, p.backend, p.reference, "t", "-", "lag_correlation", p.lag.correlation))
            if p.lag is not None or p.lag_removed:
                rows.append(_row(sc, p.backend, p.reference, "t", "-", "lag_removed", p.lag_removed))
        qd_force = [*range(3, 6), *range(9, 12)]
        for s in self.steady:
            add(s.backend, "", "steady_mean", np.concatenate([np.zeros(3), s.qd, np.zeros(3), s.force]), qd_force)
            forces = {"analytic_poc": s.analytic_poc, "analytic_residual": s.residual}
            if s.analytic_centre is not None and s.poc_compensation is not None:
                forces |= {"analytic_centre": s.analytic_centre, "poc_compensation": s.poc_compensation}
            for metric, v in forces.items():
                add(s.backend, "", metric, np.concatenate([np.zeros(9), v]), range(9, 12))
        for m in self.split:
            for part in ("native", "contact", "integration", "drift"):
                add(m.backend, m.reference, f"split_{part}_rms", getattr(m, f"{part}_rms"))
                add(m.backend, m.reference, f"split_{part}_pct", getattr(m, f"{part}_pct"))
        return rows

    def pair(self, backend: str, reference: str | None = None) -> PairMetrics | None:
        """The pair metrics of ``backend`` against ``reference`` (default: :attr:`reference`)."""
        ref = reference or self.reference
        return next((p for p in self.pairs if p.backend == backend and p.reference == ref), None)

    def to_json(self) -> dict[str, Any]:
        """The content of metrics.json (schema :data:`METRICS_SCHEMA`, keys in docs/metrics.md)."""
        run = self.run
        backends: dict[str, Any] = {}
        for name, b in run.backends.items():
            backends[name] = {"status": b.status, "reason": b.reason, "source": "run"}
        for name in self.traces:
            if name not in run.backends:
                backends[name] = {"status": "ok", "reason": None, "source": "log"}
        return {
            "schema": METRICS_SCHEMA,
            "scenario": run.label,
            "name": run.name,
            "contact_mode": run.contact_mode,
            "poc": run.poc,
            "reference": self.reference,
            "skip": run.skip,
            "steady_window": run.steady_window,
            "duration": run.duration,
            "split_with": None if self.split_run is None else self.split_run.label,
            "backends": backends,
            "notes": list(self.notes),
            "columns": list(FRAME_COLUMNS),
            "metrics": [{k: _json_value(v) for k, v in r.items()} for r in self.records()],
        }


def _row(scenario: str, backend: str, ref: str, signal: str, joint: str, metric: str, value: Any) -> dict[str, Any]:
    return {
        "scenario": scenario,
        "backend": backend,
        "reference": ref,
        "signal": signal,
        "joint": joint,
        "metric": metric,
        "value": float(value),
    }


def _json_value(v: Any) -> Any:
    if isinstance(v, float) and not math.isfinite(v):
        return None
    return v


def label(signal: str, joint: str) -> str:
    """Short column label of a signal component: ``q2``, ``tau1``, ``fz``."""
    return f"f{joint}" if signal == "force" else f"{signal}{joint}"


# --------------------------------------------------------------------------- #
# Reading


def _frame_to_trace(df: pd.DataFrame, name: str, source: str, required: Sequence[str]) -> Trace:
    missing = [c for c in required if c not in df.columns]
    if missing:
        raise ResultsError(source, f"missing column(s) {missing}; columns present: {list(df.columns)}")
    n = len(df)
    if n < 2:
        raise ResultsError(source, f"has {n} row(s); at least 2 are needed")

    def block(cols: Sequence[str]) -> np.ndarray:
        out = np.full((n, len(cols)), np.nan)
        for i, c in enumerate(cols):
            if c in df.columns:
                try:
                    out[:, i] = pd.to_numeric(df[c], errors="raise").to_numpy(dtype=float, na_value=np.nan)
                except (ValueError, TypeError) as exc:
                    raise ResultsError(source, f"column '{c}' is not numeric ({exc})") from exc
        return out

    t = block(["t"])[:, 0]
    if not np.isfinite(t).all():
        raise ResultsError(source, "column 't' has non-finite values")
    steps = np.diff(t)
    if (steps <= 0).any():
        i = int(np.argmax(steps <= 0))
        raise ResultsError(source, f"time is not strictly increasing at row {i + 1} (t = {t[i + 1]!r} s)")
    ctrl = (
        df["controller"].astype(str).to_numpy(dtype=object)
        if "controller" in df.columns
        else np.full(n, "", dtype=object)
    )
    return Trace(name=name, t=t, data=block(LABELS), ee=block(EE_COLUMNS), controller=ctrl, source=source)


def trace_from_frame(df: pd.DataFrame, name: str, source: str = "<frame>") -> Trace:
    """A :class:`Trace` from a DataFrame with (some of) :data:`RUN_COLUMNS`; ``t`` is required.

    Raises:
        ResultsError: ``t`` missing, not numeric or not strictly increasing, or fewer than 2 rows.
    """
    return _frame_to_trace(df, name, source, ["t"])


def load_trace(path: str | Path, name: str | None = None) -> Trace:
    """Read one backend's parquet file (every column of :data:`RUN_COLUMNS` required).

    Raises:
        ResultsError: the file is missing, unreadable or lacks a column.
    """
    path = Path(path)
    if not path.is_file():
        raise ResultsError(str(path), "no such file")
    try:
        df = pd.read_parquet(path)
    except Exception as exc:  # pyarrow raises several unrelated types
        raise ResultsError(str(path), f"not a readable parquet file ({type(exc).__name__}: {exc})") from exc
    return _frame_to_trace(df, name or path.stem, str(path), [c for c in RUN_COLUMNS if c != "controller"])


def _normalise_header(col: str) -> str:
    """``"q1 [rad]"`` -> ``"q1"``; ``" Fz (N)"`` -> ``"fz"``; ``"time"`` -> ``"t"``."""
    base = re.sub(r"\s*[\[(].*?[\])]\s*$", "", str(col)).strip().lower()
    return _ALIASES.get(base, base)


def load_log(path: str | Path, column_map: Mapping[str, str] | None = None, time_scale: float = 1.0) -> pd.DataFrame:
    """Read an external CSV log into the run columns, as one more "backend".

    Header names are matched to :data:`RUN_COLUMNS` case-insensitively, with a
    trailing unit in brackets or parentheses ignored (``"q1 [rad]"`` is ``q1``;
    ``time`` is ``t``). ``column_map`` maps other names, ``{"their name": "q1"}``,
    and wins over the automatic match. Only ``t`` and ``q1..q3`` are required;
    other missing signals become NaN and are left out of the metrics.

    Args:
        path: the CSV file.
        column_map: header name in the file -> legbench column name.
        time_scale: factor taking the file's time unit to seconds (1e-3 for ms).

    Returns:
        DataFrame with the columns of :data:`RUN_COLUMNS` (controller "" if absent).

    Raises:
        ResultsError: the file is missing or unreadable, a mapped column is absent,
            two columns map to one name, a required column is missing, a value is not
            numeric or time is not strictly increasing.
    """
    path = Path(path)
    if not path.is_file():
        raise ResultsError(str(path), "no such log file")
    try:
        raw = pd.read_csv(path)
    except Exception as exc:  # parser errors come in several types
        raise ResultsError(str(path), f"not a readable CSV file ({type(exc).__name__}: {exc})") from exc
    cmap = dict(column_map or {})
    unknown_targets = sorted(set(cmap.values()) - set(RUN_COLUMNS))
    if unknown_targets:
        raise ResultsError(
            str(path), f"column_map targets {unknown_targets} are not legbench columns {list(RUN_COLUMNS)}"
        )
    absent = sorted(set(cmap) - set(map(str, raw.columns)))
    if absent:
        raise ResultsError(str(path), f"column_map names {absent} are not in the header {list(map(str, raw.columns))}")
    rename: dict[str, str] = {}
    for col in map(str, raw.columns):
        target = cmap.get(col) or _normalise_header(col)
        if target in RUN_COLUMNS:
            rename[col] = target
    targets = list(rename.values())
    dupes = sorted({c for c in targets if targets.count(c) > 1})
    if dupes:
        raise ResultsError(str(path), f"several header columns map to {dupes}; pass column_map to choose")
    df = raw[list(rename)].rename(columns=rename)
    required = ["t", "q1", "q2", "q3"]
    trace = _frame_to_trace(df, path.stem, str(path), required)  # validates
    out = {"t": trace.t * time_scale}
    out |= {c: trace.data[:, i] for i, c in enumerate(LABELS)}
    out |= {c: trace.ee[:, i] for i, c in enumerate(EE_COLUMNS)}
    out["controller"] = trace.controller.astype(str) if "controller" in df.columns else np.full(len(df), "")
    return pd.DataFrame(out, columns=list(RUN_COLUMNS))


def _read_json(path: Path) -> dict[str, Any]:
    try:
        doc = json.loads(path.read_text())
    except json.JSONDecodeError as exc:
        raise ResultsError(str(path), f"invalid JSON at line {exc.lineno}: {exc.msg}") from exc
    if not isinstance(doc, dict):
        raise ResultsError(str(path), "top level is not a JSON object")
    return doc


def _get(doc: Mapping[str, Any], keys: str, file: Path, default: Any = ...) -> Any:
    cur: Any = doc
    for k in keys.split("."):
        if not isinstance(cur, Mapping) or k not in cur:
            if default is not ...:
                return default
            raise ResultsError(str(file), f"missing key '{keys}'")
        cur = cur[k]
    return cur


def _float_or_nan(v: Any) -> float:
    try:
        return float(v)
    except (TypeError, ValueError):
        return math.nan


def load_run(run_dir: str | Path) -> Run:
    """Read a run directory (run.json and one parquet per backend whose status is ok).

    A backend listed as ok whose file is absent is reported as ``missing``;
    a failed backend's file, if present, is kept in :attr:`Run.partial`.

    Raises:
        ResultsError: the directory or run.json is missing or malformed, or a parquet file is malformed.
    """
    path = Path(run_dir)
    if not path.is_dir():
        raise ResultsError(str(path), "no such run directory")
    rj = path / "run.json"
    if not rj.is_file():
        raise ResultsError(str(path), "no run.json here: not a legbench run directory")
    meta = _read_json(rj)
    sc = _get(meta, "scenario", rj)
    name = str(_get(sc, "name", rj))
    mode = str(_get(sc, "contact_mode", rj, "native"))
    if mode not in ("native", "reference"):
        raise ResultsError(str(rj), f"scenario.contact_mode is '{mode}', not 'native' or 'reference'")
    cmp_ = _get(sc, "comparison", rj, {}) or {}
    backends_doc = _get(meta, "backends", rj)
    if not isinstance(backends_doc, Mapping):
        raise ResultsError(str(rj), "'backends' is not an object")
    events = tuple(EventMark(float(e.get("t", 0.0)), str(e.get("controller", ""))) for e in (sc.get("events") or []))
    backends: dict[str, BackendStatus] = {}
    traces: dict[str, Trace] = {}
    partial: dict[str, Trace] = {}
    for bname, b in backends_doc.items():
        if not isinstance(b, Mapping) or "status" not in b:
            raise ResultsError(str(rj), f"backends.{bname} has no 'status'")
        status, reason = str(b["status"]), b.get("reason")
        fname = str(b.get("file") or f"{bname}.parquet")
        fpath = path / fname
        if status == "ok" and not fpath.is_file():
            status, reason = "missing", f"run.json says ok but {fname} is not in {path}"
        if status == "ok":
            traces[bname] = load_trace(fpath, bname)
        elif fpath.is_file():
            try:
                partial[bname] = load_trace(fpath, bname)
            except ResultsError as exc:
                logger.info("partial log of %s not readable: %s", bname, exc)
        backends[bname] = BackendStatus(
            name=bname,
            status=status,
            reason=None if reason is None else str(reason),
            info=dict(b.get("info") or {}),
            wall_time=_float_or_nan(b.get("wall_time")),
            rtf=_float_or_nan(b.get("rtf")),
            file=fname,
        )
    return Run(
        path=path,
        meta=meta,
        name=name,
        label=name if mode == "native" else f"{name}__reference",
        contact_mode=mode,
        poc=str((sc.get("contact") or {}).get("poc", "true")),
        reference=str(cmp_.get("reference", "pinocchio")),
        skip=float(cmp_.get("skip", 0.0) or 0.0),
        steady_window=float(cmp_.get("steady_window", 0.5) or 0.5),
        duration=float(sc.get("duration", math.nan)),
        events=events,
        backends=backends,
        traces=traces,
        partial=partial,
    )


# --------------------------------------------------------------------------- #
# Alignment


def _same_grid(t1: np.ndarray, t2: np.ndarray) -> bool:
    return len(t1) == len(t2) and bool(np.all(np.abs(t1 - t2) <= T_EPS))


def _resample(t: np.ndarray, x: np.ndarray, grid: np.ndarray) -> np.ndarray:
    """Linear interpolation of each column of x (N, k) onto ``grid`` (inside [t0, tN])."""
    if _same_grid(t, grid):
        return x
    g = np.clip(grid, t[0], t[-1])
    return np.column_stack([np.interp(g, t, x[:, j]) for j in range(x.shape[1])])


def _common_grid(ref_t: np.ndarray, *spans: np.ndarray, source: str = "") -> np.ndarray:
    lo = max([ref_t[0], *(s[0] for s in spans)])
    hi = min([ref_t[-1], *(s[-1] for s in spans)])
    grid = ref_t[(ref_t >= lo - T_EPS) & (ref_t <= hi + T_EPS)]
    if len(grid) < 2:
        raise ResultsError(source, f"time spans do not overlap (common span [{lo:.6g}, {hi:.6g}] s)")
    return grid


def align(a: Trace, ref: Trace, shift: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Put two traces on one time grid.

    The grid is the reference's ticks inside the common span; ``a`` is linearly
    interpolated onto it (no interpolation when both share the grid, as engine
    runs do). A lag ``shift`` [s] is removed from ``a`` first (its time stamps
    become t - shift).

    Returns:
        (t, x_a, x_ref): grid (M,) [s] and the two (M, 12) data blocks.

    Raises:
        ResultsError: the two spans do not overlap by two reference ticks.
    """
    ta = a.t - shift
    grid = _common_grid(ref.t, ta, source=a.source or a.name)
    xr = ref.data if len(grid) == len(ref.t) else ref.data[np.searchsorted(ref.t, grid[0] - T_EPS) :][: len(grid)]
    return grid, _resample(ta, a.data, grid), xr


def _uniform_pair(a: Trace, ref: Trace, cols: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Both traces on one uniform grid over the common span (for correlation)."""
    if _same_grid(a.t, ref.t) and np.allclose(np.diff(ref.t), ref.t[1] - ref.t[0], rtol=1e-6, atol=T_EPS):
        return ref.t, a.data[:, cols], ref.data[:, cols]
    dt = min(float(np.median(np.diff(a.t))), float(np.median(np.diff(ref.t))))
    lo, hi = max(a.t[0], ref.t[0]), min(a.t[-1], ref.t[-1])
    if hi - lo < 2 * dt:
        raise ResultsError(a.source or a.name, f"time spans of {a.name} and {ref.name} do not overlap")
    grid = lo + dt * np.arange(int(math.floor((hi - lo) / dt + 1e-9)) + 1)
    return grid, _resample(a.t, a.data[:, cols], grid), _resample(ref.t, ref.data[:, cols], grid)


def estimate_lag(a: Trace, ref: Trace, max_lag: float = 0.1, signals: Sequence[str] = ("q",)) -> LagEstimate:
    """Constant time lag of ``a`` behind ``ref`` by cross-correlation.

    Both traces are put on one uniform grid (the finer of the two median steps)
    over their common span. For each candidate lag k within +-``max_lag``, the
    Pearson correlation of x_a[n + k] with x_ref[n] is taken over the samples
    that overlap (so a longer overlap is not favoured, unlike the plain
    cross-correlation sum, which biases slow signals towards zero lag); the
    per-column correlations are averaged, the best k is refined to a sub-sample
    by a parabola through the peak and its neighbours. Sums over the overlap come
    from prefix sums and one FFT per column, so the cost is O(M log M).
    Constant or missing columns are left out.

    Args:
        a: the trace that may lag.
        ref: the reference trace.
        max_lag: largest lag searched, either sign [s]; at most half the common span is searched.
        signals: signals correlated (any of :data:`SIGNALS`).

    Returns:
        The lag; 0 with correlation NaN when no column varies.
    """
    cols = np.concatenate([np.arange(len(LABELS))[SLICE[s]] for s in signals])
    grid, xa, xr = _uniform_pair(a, ref, cols)
    dt = float(grid[1] - grid[0])
    keep = (
        np.isfinite(xa).all(axis=0) & np.isfinite(xr).all(axis=0) & (np.ptp(xa, axis=0) > 0) & (np.ptp(xr, axis=0) > 0)
    )
    if not keep.any():
        return LagEstimate(0.0, 0.0, dt, math.nan, tuple(signals))
    x = xa[:, keep] - xa[:, keep].mean(axis=0)
    y = xr[:, keep] - xr[:, keep].mean(axis=0)
    m = len(grid)
    kmax = max(1, min(int(round(max_lag / dt)), m // 2))
    lags = np.arange(-kmax, kmax + 1)
    nfft = 1 << int(math.ceil(math.log2(2 * m)))
    # sxy[k] = sum_n x[n + k] y[n] over the overlap (n and n + k both in 0..m-1)
    sxy = np.fft.irfft(np.fft.rfft(x, nfft, axis=0) * np.conj(np.fft.rfft(y, nfft, axis=0)), nfft, axis=0)[lags % nfft]
    zero = np.zeros((1, x.shape[1]))
    px, pxx = np.vstack([zero, np.cumsum(x, axis=0)]), np.vstack([zero, np.cumsum(x * x, axis=0)])
    py, pyy = np.vstack([zero, np.cumsum(y, axis=0)]), np.vstack([zero, np.cumsum(y * y, axis=0)])
    pos = lags >= 0
    x_lo, x_hi = np.where(pos, lags, 0), np.where(pos, m, m + lags)  # x[n + k] segment
    y_lo, y_hi = np.where(pos, 0, -lags), np.where(pos, m - lags, m)  # y[n] segment
    n = (m - np.abs(lags))[:, None].astype(float)
    sx, sxx = px[x_hi] - px[x_lo], pxx[x_hi] - pxx[x_lo]
    sy, syy = py[y_hi] - py[y_lo], pyy[y_hi] - pyy[y_lo]
    cov = sxy - sx * sy / n
    var = (sxx - sx * sx / n) * (syy - sy * sy / n)
    with np.errstate(invalid="ignore", divide="ignore"):
        rho = np.where(var > 0, cov / np.sqrt(np.where(var > 0, var, 1.0)), 0.0).mean(axis=1)
    i = int(np.argmax(rho))
    k = float(lags[i])
    if 0 < i < len(rho) - 1:
        y0, y1, y2 = rho[i - 1], rho[i], rho[i + 1]
        den = y0 - 2 * y1 + y2
        if den < 0:
            k += 0.5 * (y0 - y2) / den
    return LagEstimate(k * dt, k, dt, float(rho[i]), tuple(signals))


# --------------------------------------------------------------------------- #
# Metrics


def _wrap_mask() -> np.ndarray:
    """True for the angle columns of continuous joints (from the leg's parameter file)."""
    from legbench.model import load_params

    mask = np.zeros(len(LABELS), dtype=bool)
    mask[SLICE["q"]] = load_params().continuous
    return mask


def deviation(xa: np.ndarray, xr: np.ndarray, wrap: np.ndarray | None = None) -> np.ndarray:
    """x_a - x_ref per column [signal units]; shortest angle on the ``wrap`` columns (default: the hip angle)."""
    d = xa - xr
    w = _wrap_mask() if wrap is None else np.asarray(wrap, dtype=bool)
    if w.any():
        d[:, w] = np.mod(d[:, w] + np.pi, 2.0 * np.pi) - np.pi
    return d


def _peak_pct(max_abs: np.ndarray, peak: np.ndarray) -> np.ndarray:
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(peak > PEAK_FLOOR, 100.0 * max_abs / np.where(peak > PEAK_FLOOR, peak, 1.0), np.nan)


def _rms(d: np.ndarray) -> np.ndarray:
    if len(d) == 0:
        return np.full(d.shape[1], np.nan)
    return np.sqrt(np.mean(d * d, axis=0))


def _max_abs(d: np.ndarray) -> np.ndarray:
    if len(d) == 0:
        return np.full(d.shape[1], np.nan)
    return np.max(np.abs(d), axis=0)


def pair_metrics(
    a: Trace,
    ref: Trace,
    skip: float = 0.0,
    lag: str = "off",
    max_lag: float = 0.1,
    lag_signals: Sequence[str] = ("q",),
    wrap: np.ndarray | None = None,
) -> PairMetrics:
    """Deviation metrics of ``a`` against ``ref`` (LEG_SPEC.md section 8).

    Args:
        a: the backend measured.
        ref: the reference.
        skip: only samples with t >= skip are measured [s].
        lag: ``"off"``, ``"report"`` (estimate and record the lag) or ``"remove"``
            (estimate it and take it out of ``a`` before measuring).
        max_lag: largest lag searched [s].
        lag_signals: signals the lag is estimated from.
        wrap: columns compared as angles on a circle (default: the hip angle).

    Returns:
        The metrics; see :class:`PairMetrics`.
    """
    if lag not in ("off", "report", "remove"):
        raise ValueError(f"lag must be 'off', 'report' or 'remove', not {lag!r}")
    est = estimate_lag(a, ref, max_lag, lag_signals) if lag != "off" else None
    shift = est.seconds if (est is not None and lag == "remove") else 0.0
    t, xa, xr = align(a, ref, shift)
    d = deviation(xa, xr, wrap)
    sel = t >= skip - T_EPS
    ds, rs, ts = d[sel], xr[sel], t[sel]
    max_abs = _max_abs(ds)
    ref_peak = _max_abs(rs)
    if len(ds):
        t_max = ts[np.argmax(np.nan_to_num(np.abs(ds), nan=-1.0), axis=0)]
        t_max = np.where(np.isfinite(max_abs), t_max, np.nan)
    else:
        t_max = np.full(len(LABELS), np.nan)
    return PairMetrics(
        backend=a.name,
        reference=ref.name,
        t=t,
        deviation=d,
        sim_error_pct=_peak_pct(max_abs, ref_peak),
        rms=_rms(ds),
        max_abs=max_abs,
        t_max_abs=t_max,
        ref_peak=ref_peak,
        skip=skip,
        lag=est,
        lag_removed=shift,
    )


def steady_state(trace: Trace, window: float, poc: str = "true") -> SteadyState:
    """Means over the final ``window`` [s] of ``trace``, and the analytic force check.

    The check solves J_poc(q)^T h = tau - G(q) at the window's mean q and tau
    (valid when the leg is static: qd ~ 0 and no acceleration) and reports the
    ground force on the foot, -h. With ``poc == "centre"`` it also does so with
    J_E, the foot centre's Jacobian, which is what a contact law taking the poc
    at the sphere centre applies.
    """
    from legbench import kinematics

    sel = trace.t >= trace.t[-1] - window - T_EPS
    mean = trace.data[sel].mean(axis=0)
    q, qd, tau, force = (mean[SLICE[s]] for s in SIGNALS)

    def ground_force(true_poc: bool) -> tuple[np.ndarray, float]:
        if not np.isfinite(q).all() or not np.isfinite(tau).all():
            return np.full(3, np.nan), math.nan
        J = kinematics.jacobian_poc(q, true_poc=true_poc)
        cond = float(np.linalg.cond(J))
        if not cond < COND_MAX:
            return np.full(3, np.nan), cond
        h = np.linalg.solve(J.T, tau - kinematics.gravity(q))
        return -h, cond

    f_poc, cond = ground_force(True)
    f_centre = ground_force(False)[0] if poc == "centre" else None
    return SteadyState(trace.name, float(trace.t[sel][0]), float(trace.t[-1]), q, qd, tau, force, f_poc, f_centre, cond)


def contact_split(native: Run, refmode: Run, reference: str | None = None) -> tuple[ModeSplit, ...]:
    """Split each backend's native-mode deviation into contact, integration and drift parts.

    See :class:`ModeSplit`. Backends must be ok in both runs; all four traces
    are put on the native reference's ticks inside their common span.

    Args:
        native: the run in native contact mode.
        refmode: the same scenario in reference contact mode.
        reference: reference backend (default: the native run's).
    """
    ref = reference or native.reference
    if ref not in native.traces or ref not in refmode.traces:
        return ()
    rn, rr = native.traces[ref], refmode.traces[ref]
    wrap = _wrap_mask()
    out = []
    for name, an in native.traces.items():
        if name == ref or name not in refmode.traces:
            continue
        ar = refmode.traces[name]
        grid = _common_grid(rn.t, an.t, ar.t, rr.t, source=str(native.path))
        xrn, xan = _resample(rn.t, rn.data, grid), _resample(an.t, an.data, grid)
        xar, xrr = _resample(ar.t, ar.data, grid), _resample(rr.t, rr.data, grid)
        sel = grid >= native.skip - T_EPS
        parts = {
            "native": deviation(xan, xrn, wrap)[sel],
            "contact": deviation(xan, xar, wrap)[sel],
            "integration": deviation(xar, xrr, wrap)[sel],
            "drift": deviation(xrr, xrn, wrap)[sel],
        }
        peak = _max_abs(xrn[sel])
        kw: dict[str, Any] = {}
        for part, d in parts.items():
            kw[f"{part}_rms"] = _rms(d)
            kw[f"{part}_pct"] = _peak_pct(_max_abs(d), peak)
        out.append(ModeSplit(backend=name, reference=ref, **kw))
    return tuple(out)


def _sibling(run: Run) -> Path | None:
    if run.contact_mode != "native":
        return None
    cand = run.path.parent / f"{run.path.name}__reference"
    return cand if (cand / "run.json").is_file() else None


def compare(
    run_dir: str | Path,
    *,
    log: str | Path | None = None,
    log_name: str | None = None,
    column_map: Mapping[str, str] | None = None,
    log_time_scale: float = 1.0,
    log_is_reference: bool = False,
    all_pairs: bool = False,
    lag: str = "off",
    max_lag: float = 0.1,
    lag_signals: Sequence[str] = ("q",),
    split_dir: str | Path | None = "auto",
) -> ComparisonResult:
    """Measure every backend of a run directory against the scenario's reference backend.

    Args:
        run_dir: a ``legbench run`` output directory (run.json + parquet files).
        log: an external CSV log (see :func:`load_log`) compared as one more backend.
        log_name: its name in tables and plots (default: ``log:<file stem>``).
        column_map: header name -> legbench column, for the log.
        log_time_scale: factor taking the log's time unit to seconds.
        log_is_reference: measure every backend against the log instead of the
            scenario's reference backend.
        all_pairs: also measure every ordered pair of traces (a against b, a != b).
        lag: ``"off"``, ``"report"`` or ``"remove"``: estimate (and remove) a
            constant time lag of each backend behind its reference.
        max_lag: largest lag searched [s].
        lag_signals: signals the lag is estimated from.
        split_dir: reference-contact-mode run of the same scenario for the
            contact/integration split; ``"auto"`` looks for the sibling
            ``<run_dir>__reference``; None for no split.

    Returns:
        A :class:`ComparisonResult`.

    Raises:
        ResultsError: a directory or file is missing or malformed, or the log does not overlap the run.
    """
    if lag not in ("off", "report", "remove"):
        raise ValueError(f"lag must be 'off', 'report' or 'remove', not {lag!r}")
    run = load_run(run_dir)
    traces: dict[str, Trace] = dict(run.traces)
    notes: list[str] = []
    for st in run.backends.values():
        if st.status != "ok":
            notes.append(f"backend '{st.name}' {st.status}: {st.reason or 'no reason given'}")
    reference = run.reference
    if log is not None:
        name = log_name or f"log:{Path(log).stem}"
        if name in traces:
            raise ResultsError(str(log), f"log name '{name}' is already a backend of {run.path}; pass another name")
        traces[name] = trace_from_frame(load_log(log, column_map, log_time_scale), name, str(log))
        if log_is_reference:
            reference = name
    pairs: list[PairMetrics] = []
    if reference not in traces:
        why = run.backends[reference].reason if reference in run.backends else "not in run.json"
        notes.append(f"reference backend '{reference}' has no data ({why}): no deviations measured")
    else:
        for name, tr in traces.items():
            if name != reference:
                pairs.append(pair_metrics(tr, traces[reference], run.skip, lag, max_lag, lag_signals))
    if all_pairs:
        for a in traces:
            for b in traces:
                if a != b and b != reference:
                    pairs.append(pair_metrics(traces[a], traces[b], run.skip, lag, max_lag, lag_signals))
    steady = tuple(steady_state(tr, run.steady_window, run.poc) for tr in traces.values())
    for s in steady:
        if not s.cond < COND_MAX:
            notes.append(f"{s.backend}: J_poc is singular at the steady-state pose; analytic check undefined")
    split: tuple[ModeSplit, ...] = ()
    split_run = None
    sdir = _sibling(run) if split_dir == "auto" else (Path(split_dir) if split_dir is not None else None)
    if sdir is not None:
        split_run = load_run(sdir)
        if split_run.contact_mode != "reference":
            raise ResultsError(str(sdir), f"contact_mode is '{split_run.contact_mode}', expected 'reference'")
        if split_run.name != run.name:
            raise ResultsError(str(sdir), f"scenario '{split_run.name}' is not '{run.name}'")
        split = contact_split(run, split_run)
        if not split:
            notes.append(f"no contact-mode split: reference backend '{run.reference}' missing in one mode")
    return ComparisonResult(run, reference, traces, tuple(pairs), steady, split, split_run, tuple(notes))


# --------------------------------------------------------------------------- #
# metrics.json


def write_metrics(result: ComparisonResult, path: str | Path | None = None) -> Path:
    """Write ``metrics.json`` (default: in the run directory) and return its path.

    The header keys are indented, one metrics row per line (diff-friendly); the
    document is plain JSON (NaN written as null).
    """
    out = Path(path) if path is not None else result.run.path / "metrics.json"
    doc = result.to_json()
    rows = doc.pop("metrics")
    head = json.dumps(doc, indent=1, allow_nan=False)
    body = ",\n  ".join(json.dumps(r, allow_nan=False) for r in rows)
    out.write_text(
        f'{head[:-2]},\n "metrics": [\n  {body}\n ]\n}}\n' if rows else f'{head[:-2]},\n "metrics": []\n}}\n'
    )
    return out


def read_metrics(path: str | Path) -> tuple[dict[str, Any], pd.DataFrame]:
    """Read a metrics.json: (header without the rows, long table with NaN for null).

    Raises:
        ResultsError: missing file, wrong schema or malformed rows.
    """
    path = Path(path)
    if not path.is_file():
        raise ResultsError(str(path), "no such metrics file")
    doc = _read_json(path)
    if doc.get("schema") != METRICS_SCHEMA:
        raise ResultsError(str(path), f"schema is {doc.get('schema')!r}, expected {METRICS_SCHEMA!r}")
    rows = doc.pop("metrics", None)
    if not isinstance(rows, list) or any(not isinstance(r, dict) or set(r) != set(FRAME_COLUMNS) for r in rows):
        raise ResultsError(str(path), f"'metrics' must be a list of objects with keys {list(FRAME_COLUMNS)}")
    df = pd.DataFrame(rows, columns=list(FRAME_COLUMNS))
    df["value"] = pd.to_numeric(df["value"], errors="coerce").astype(float)
    for c in FRAME_COLUMNS[:-1]:
        df[c] = df[c].astype(str)
    return doc, df
