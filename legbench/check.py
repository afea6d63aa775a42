"""Regression check: new comparison metrics against a committed baseline.

``legbench check NEW --baseline BASE`` compares, scenario by scenario, the
metrics of NEW with those of BASE (same layout: one run directory per
scenario, each with metrics.json, or a single run directory each). A metric
may move within its tolerance; beyond it, or a backend that stopped working,
or a metric that disappeared, is a regression and the exit status is 1.

Checked metrics and rules (defaults in :data:`DEFAULT_TOLERANCES`, documented
in docs/metrics.md):

* ``sim_error_pct`` and ``rms`` (each backend against its reference, per signal
  component) may *grow* by at most max(abs, rel * |baseline|); shrinking is an
  improvement and passes.
* ``steady_mean`` (steady-state qd and ground force) may *change either way*
  by at most max(abs, rel * |baseline|).
* ``max_sim_error_pct``: optional absolute ceilings on the new sim_error_pct,
  whatever the baseline.

Tolerances come from the defaults, overridden by a tolerance file (YAML or
JSON) and its section for the scenario, overridden by the scenario's own
``comparison.tolerances`` in the new run.json: for each component, the most
specific source that gives a value wins whole (a file's ``{default: x}`` beats a
default keyed by signal; :func:`legbench.signals.keyed`). When both sides
still hold their parquet logs, each backend's time series is also compared bit
for bit ("identical" or "changed").

The check never passes on results it cannot read: both sides' run.json and
metrics.json are read through :mod:`legbench.results`' checked readers, and a
directory's logs are read (and checked) even when its metrics.json was computed from them, so
an empty, cut-short or column-less log is a ResultsError (exit 2), and a log
run.json calls ok that is gone makes the backend ``missing`` (a FAILED row).
"""

from __future__ import annotations

import json
import math
import sys
import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TextIO

import numpy as np
import pandas as pd

from legbench import yamlfile
from legbench.compare import compare
from legbench.exceptions import LegbenchError, ResultsError, ScenarioError
from legbench.results import (
    CHECK_OUTPUTS,
    Run,
    atomic_write_bytes,
    atomic_write_text,
    enclosing_run,
    load_run,
    log_digests,
    profile_of,
    read_log,
    read_meta,
    read_metrics,
    run_dirs,
    run_label,
    tolerances_of,
)
from legbench.scenario import TOLERANCE_METRICS, is_leg_parameter_file, validate_tolerances
from legbench.signals import keyed
from legbench.signals import label as column_label

__all__ = [
    "DEFAULT_TOLERANCES",
    "CheckReport",
    "CheckRow",
    "TraceCheck",
    "check",
    "format_table",
    "load_tolerances",
    "run_check",
    "write_junit",
    "write_markdown",
]

#: Default tolerances. ``abs`` and ``rel`` are a number, or a mapping keyed by
#: component label (``tau2``, ``fz``), signal (``tau``, ``force``) or ``default``.
#: Runs are deterministic (bit-identical on one machine, and the three engines agree to 1e-10 % in
#: reference mode), so the defaults only absorb round-off across machines: a 4x change of one
#: engine's sub-step moves its metrics by 0.6-0.8 %, which they catch.
#: One per metric of :data:`legbench.scenario.TOLERANCE_METRICS` (the valid names, kept there), in its order.
DEFAULT_TOLERANCES: dict[str, Any] = dict(
    zip(
        TOLERANCE_METRICS,
        (
            {"abs": 0.01, "rel": 0.005},  # sim_error_pct: [percentage points], [1]
            {"abs": {"q": 1e-5, "qd": 1e-4, "tau": 1e-4, "force": 1e-3}, "rel": 0.005},  # rms: [signal unit], [1]
            # steady_mean: [signal unit], [1]; qd's floor under the engines' creep (1e-7 to 9e-4 rad/s in the
            # baseline: at 1e-4, 15 of 21 creeps on the contact tasks were under it, and ten times one passed)
            {"abs": {"qd": 1e-8, "force": 1e-2}, "rel": 0.005},
            {},  # max_sim_error_pct: label or signal -> ceiling [%]
        ),
        strict=True,
    )
)
#: Metrics that may only grow within tolerance; the others may move either way.
ONE_SIDED = ("sim_error_pct", "rms")
#: Row statuses that fail the check.
FAILING = ("REGRESSION", "MISSING", "FAILED", "OVER LIMIT")
#: Statuses that pass without a baseline value to check against: a metric not in the baseline, an imported log only
#: the baseline was compared with (JUnit: skipped).
UNCHECKED = ("new", "unchecked")
_KEYS = ["scenario", "backend", "reference", "signal", "joint", "metric"]


@dataclass(frozen=True)
class CheckRow:
    """One metric (or backend status) checked.

    Attributes:
        scenario: scenario label.
        backend: backend name.
        reference: the backend it is measured against ("" for per-backend metrics).
        signal: signal name (``-`` for a backend status).
        joint: component.
        metric: metric name, or ``status``.
        baseline: baseline value (NaN if none).
        new: new value (NaN if none).
        allowed: largest change allowed (NaN if not applicable).
        status: ``pass``, ``improved``, ``moved`` (within tolerance), ``new``, ``unchecked`` (an imported log the
            baseline was compared with and the new run was not: an input, not a result), or a failing one of
            :data:`FAILING`.
        message: one sentence naming the signal and the numbers.
    """

    scenario: str
    backend: str
    reference: str
    signal: str
    joint: str
    metric: str
    baseline: float
    new: float
    allowed: float
    status: str
    message: str

    @property
    def label(self) -> str:
        """Component label, ``tau2`` or ``fz`` (``-`` for a status row)."""
        return "-" if self.signal == "-" else column_label(self.signal, self.joint)

    @property
    def failed(self) -> bool:
        """True if this row is a regression."""
        return self.status in FAILING

    @property
    def change(self) -> float:
        """new - baseline."""
        return self.new - self.baseline


@dataclass(frozen=True)
class TraceCheck:
    """Bit-for-bit comparison of one backend's time series with the baseline's.

    Attributes:
        scenario: scenario label.
        backend: backend name.
        status: ``identical``, ``changed`` or ``no baseline log``.
        max_abs_change: largest absolute difference over the numeric columns (NaN if shapes differ).
        detail: what differs, in words.
    """

    scenario: str
    backend: str
    status: str
    max_abs_change: float
    detail: str = ""


@dataclass(frozen=True)
class CheckReport:
    """Outcome of :func:`check`.

    Attributes:
        new: the new results directory.
        baseline: the baseline directory.
        rows: every metric and status checked.
        traces: bit-for-bit comparisons of time series.
        tolerance_sources: scenario -> where its tolerances came from.
        versions: the packages whose versions differ between the two sides' run.json (``numpy 2.4.6 -> 2.5.0``),
            what a moved metric may come from; empty where they agree or a side records none. Not a failure.
    """

    new: Path
    baseline: Path
    rows: tuple[CheckRow, ...]
    traces: tuple[TraceCheck, ...]
    tolerance_sources: Mapping[str, str]
    versions: tuple[str, ...] = ()

    @property
    def regressions(self) -> tuple[CheckRow, ...]:
        """The failing rows."""
        return tuple(r for r in self.rows if r.failed)

    @property
    def passed(self) -> bool:
        """True if nothing regressed."""
        return not self.regressions

    @property
    def exit_status(self) -> int:
        """0 if nothing regressed, 1 otherwise."""
        return 0 if self.passed else 1


# --------------------------------------------------------------------------- #
# Tolerances


def _validate(
    tol: Any, file: str, prefix: str | list[str | int], ctx: yamlfile.YamlContext | None = None
) -> dict[str, Any]:
    """Tolerances checked by the rules a scenario's own are (:func:`legbench.scenario.validate_tolerances`); with
    ``ctx`` (the file's node tree) an error names the line."""
    return validate_tolerances(tol, file, prefix, ctx)


def load_tolerances(path: str | Path) -> tuple[dict[str, Any], dict[str, dict[str, Any]]]:
    """Read a tolerance file (YAML or JSON).

    Format: the keys of :data:`DEFAULT_TOLERANCES` at the top level (applied to
    every scenario), and optionally ``scenarios: {<key>: {...}}`` with overrides
    for one scenario, keyed by its name (``effort``: every run of it) or its run
    label (``effort__reference``); :func:`check` refuses a key that matches no
    scenario it checks.

    Returns:
        (tolerances for every scenario, per-scenario overrides).

    Raises:
        ScenarioError: the file is missing or malformed, naming the key.
    """
    path = Path(path)
    if not path.is_file() and not path.is_dir():
        raise ScenarioError(str(path), "", "no such tolerance file")
    doc, root = yamlfile.parse_text(yamlfile.read_text(path, "tolerance file"), str(path))
    ctx = yamlfile.YamlContext(str(path), root)  # errors name the line
    if doc is None:  # empty, or comments only: a file given for nothing (legbench validate says so too)
        raise ScenarioError(str(path), "", "empty tolerance file: it names no metric and no scenarios section (leave "
                                           "--tolerances out for the defaults)")  # fmt: skip
    if not isinstance(doc, Mapping):
        raise ScenarioError(str(path), "", "top level must be a mapping")
    _refuse_other_file(doc, path)
    doc = dict(doc)
    per = doc.pop("scenarios", None)
    if per is None:
        per = {}
    if not isinstance(per, Mapping):
        raise ScenarioError(str(path), "scenarios", "must be a mapping of scenario name or run label to tolerances")
    common = _validate(doc, str(path), "", ctx)
    return common, {str(k): _validate(v, str(path), ["scenarios", str(k)], ctx) for k, v in per.items()}


def _refuse_other_file(doc: Mapping[str, Any], path: Path) -> None:
    """Another of legbench's files given to ``--tolerances`` is named for what it is (a leg parameter file read
    "geometry: unknown tolerance", a scenario "name: unknown tolerance")."""
    other = yamlfile.other_file(doc, "a tolerance file")
    if other is None and is_leg_parameter_file(doc):
        other = "is a leg parameter file, not a tolerance file: give it to legbench --model (or LEGBENCH_MODEL)"
    if other is not None:
        raise ScenarioError(str(path), "", other)


def tolerance_errors(path: str | Path) -> list[ScenarioError]:
    """Every problem of a tolerance file, one :class:`ScenarioError` each with its line, as
    :func:`load_tolerances` names it (empty: the file is valid)."""
    try:
        doc, root = yamlfile.read_yaml(path)
    except ScenarioError as exc:
        return [exc]
    if not isinstance(doc, Mapping):
        return [ScenarioError(str(path), "", "top level must be a mapping")]
    ctx = yamlfile.YamlContext(str(path), root)
    errors: list[ScenarioError] = []
    sections: list[tuple[list[str | int], Any]] = [([], {k: v}) for k, v in doc.items() if k != "scenarios"]
    per = doc.get("scenarios")
    if per is None:
        per = {}
    if not isinstance(per, Mapping):
        errors.append(
            ScenarioError(str(path), "scenarios", "must be a mapping of scenario name or run label to tolerances")
        )
        per = {}
    for name, tol in per.items():
        if not isinstance(tol, Mapping):
            sections.append((["scenarios", str(name)], tol))
            continue
        sections += [(["scenarios", str(name)], {k: v}) for k, v in tol.items()]
    for prefix, one in sections:
        try:
            _validate(one, str(path), prefix, ctx)
        except ScenarioError as exc:
            errors.append(exc)
    return errors


# --------------------------------------------------------------------------- #
# Reading both sides


def _metrics(d: Path) -> tuple[dict[str, Any], pd.DataFrame, Run | None]:
    """metrics.json of a run directory; recomputed from the logs when absent or not computed from the logs
    there now (its ``logs`` digests differ from theirs; a metrics.json without them: older than any log);
    and the run read back from run.json and its logs, when it has both (None otherwise).

    A committed baseline usually holds only run.json and metrics.json: its metrics.json is used as is, and
    its run.json is still read (checked, :func:`legbench.results.read_meta`). A directory that holds logs
    has them read through :func:`legbench.results.load_run` even when its metrics.json was computed from them: a
    metrics.json is only as good as the logs beside it, so a log that is empty, cut short, lacks a
    column or holds non-finite values is a :class:`ResultsError` (exit 2), and a log run.json calls ok
    but which is gone makes that backend ``missing`` (see :func:`_with_run_statuses`).
    """
    mfile = d / "metrics.json"
    logs = list(d.glob("*.parquet"))
    doc, df = read_metrics(mfile) if mfile.is_file() else ({}, pd.DataFrame())
    kept = doc.get("logs")  # the SHA-256 of the logs it was computed from (older metrics.json: none)
    if doc and (not logs or (log_digests(d) == kept if kept is not None else
                             all(p.stat().st_mtime <= mfile.stat().st_mtime for p in logs))):  # fmt: skip
        run = None
        if (d / "run.json").is_file():
            run = load_run(d) if logs else None
            if run is None:
                read_meta(d)
        return doc, df, run
    if not logs:
        raise ResultsError(str(d), "neither metrics.json nor backend logs (*.parquet) to measure")
    res = compare(d)
    doc = res.to_json()
    doc.pop("metrics")
    return doc, res.frame(), res.run


def _check_baseline_rows(bdir: Path, meta: Mapping[str, Any], df: pd.DataFrame) -> None:
    """A baseline's metrics hold rows for every backend they call ok (a comparison measures each one it ran:
    its steady state at least). One without (``"metrics": []``, rows deleted) checked nothing of that backend:
    every new row passed as "new", and the check passed on an empty baseline.

    Raises:
        ResultsError: naming the baseline's metrics.json and the first such backend.
    """
    measured = set(df["backend"]) if "backend" in df.columns else set()
    bare = [n for n, b in (meta.get("backends") or {}).items() if b.get("status") == "ok" and n not in measured]
    if bare:
        raise ResultsError(str(bdir / "metrics.json"), f"no metric rows for backend '{bare[0]}', which it says ran "
                           "ok: a baseline that checks nothing of it; restore it, or choose another "
                           "--baseline")  # fmt: skip


def _with_run_statuses(doc: dict[str, Any], run: Run | None) -> dict[str, Any]:
    """metrics.json's header with each run backend's status as run.json and the logs on disk say now.

    A metrics.json newer than the logs says what the backends did when it was written; a backend whose log
    has since gone (run.json says ok, the file is not there) is ``missing`` now, and a backend run.json no
    longer lists is ``absent``: :func:`_status_rows` fails either if it was ok in the baseline.
    """
    if run is None:
        return doc
    backends = {}
    for name, b in (doc.get("backends") or {}).items():
        if b.get("source", "run") == "run":
            st = run.backends.get(name)
            if st is None:
                b = {**b, "status": "absent", "reason": f"not in {run.path / 'run.json'}"}
            elif st.status != b.get("status"):
                b = {**b, "status": st.status, "reason": st.reason}
        backends[name] = b
    return {**doc, "backends": backends}


def _tolerances(
    new_dir: Path, keys: Sequence[str], common: Mapping[str, Any], per: Mapping[str, Mapping[str, Any]], tfile: str
) -> tuple[tuple[Mapping[str, Any], ...], str]:
    """The tolerance layers of one scenario, the most specific first (its own ``comparison.tolerances`` in
    NEW's run.json, the file's ``scenarios.<key>`` sections for its run label then its name, the file's
    common part, the defaults), and where they came from, least specific first."""
    layers: list[Mapping[str, Any]] = [DEFAULT_TOLERANCES]
    sources = ["defaults"]
    if common:
        layers, sources = [common, *layers], [*sources, tfile]
    for key in dict.fromkeys(keys):  # the name, then the label (more specific): each goes in front
        if key in per:
            layers, sources = [per[key], *layers], [*sources, f"{tfile} scenarios.{key}"]
    rj = new_dir / "run.json"
    if rj.is_file():
        own = tolerances_of(read_meta(new_dir))
        if own:
            layers = [_validate(own, str(rj), "scenario.comparison.tolerances"), *layers]
            sources.append(f"{rj} scenario.comparison.tolerances")
    return tuple(layers), " < ".join(sources)


# --------------------------------------------------------------------------- #
# The check


def _fmt(v: float) -> str:
    return "n/a" if not math.isfinite(v) else f"{v:.4g}"


def _allowed(layers: Sequence[Mapping[str, Any]], metric: str, signal: str, joint: str, baseline: float) -> float:
    """max(abs, rel * |baseline|) for one component, each from the first layer that gives it
    (NaN if the baseline is undefined)."""
    if not math.isfinite(baseline):
        return math.nan
    a = keyed([(t.get(metric) or {}).get("abs") for t in layers], signal, joint, 0.0)
    r = keyed([(t.get(metric) or {}).get("rel") for t in layers], signal, joint, 0.0)
    return max(a, r * abs(baseline))


def _check_rows(sc: str, base: pd.DataFrame, new: pd.DataFrame, layers: Sequence[Mapping[str, Any]]) -> list[CheckRow]:
    checked = [m for m in DEFAULT_TOLERANCES if m != "max_sim_error_pct"]
    b = base[base["metric"].isin(checked)]
    n = new[new["metric"].isin(checked)]
    merged = b.merge(n, on=_KEYS, how="outer", suffixes=("_base", "_new"), indicator="side", sort=False)
    rows: list[CheckRow] = []
    ceilings = [t.get("max_sim_error_pct") for t in layers]
    for rec in merged.itertuples(index=False):
        signal, joint, metric = str(rec.signal), str(rec.joint), str(rec.metric)
        bv, nv = float(rec.value_base), float(rec.value_new)
        lab = column_label(signal, joint)
        who = f"{sc}/{rec.backend} {lab} {metric}"
        allowed = _allowed(layers, metric, signal, joint, bv)
        if rec.side == "left_only":
            status, msg = "MISSING", f"{who}: in the baseline ({_fmt(bv)}) but not in the new results"
        elif rec.side == "right_only":
            status, msg = "new", f"{who}: new metric ({_fmt(nv)}), not in the baseline"
        elif not math.isfinite(bv) and not math.isfinite(nv):
            status, msg = "pass", f"{who}: undefined in both"
        elif not math.isfinite(nv):
            status, msg = "REGRESSION", f"{who}: became undefined (baseline {_fmt(bv)})"
        elif not math.isfinite(bv):
            status, msg = "new", f"{who}: now defined ({_fmt(nv)}), undefined in the baseline"
        else:
            delta = nv - bv
            grew = delta if metric in ONE_SIDED else abs(delta)
            verb = "grew" if delta > 0 else "fell"
            if grew > allowed:
                status = "REGRESSION"
            elif delta == 0.0:
                status = "pass"
            elif metric in ONE_SIDED and delta < 0:
                status = "improved"
            else:
                status = "moved"
            sign = "+" if metric in ONE_SIDED else "+-"
            msg = f"{who} {verb} {_fmt(bv)} -> {_fmt(nv)} ({delta:+.3g}; allowed {sign}{allowed:.3g})"
        if metric == "sim_error_pct" and math.isfinite(nv) and status not in FAILING:
            ceiling = keyed(ceilings, signal, joint, math.inf)
            if nv > ceiling:
                status, msg = "OVER LIMIT", f"{who} = {_fmt(nv)} % exceeds its limit {ceiling:g} %"
        rows.append(
            CheckRow(sc, str(rec.backend), str(rec.reference), signal, joint, metric, bv, nv, allowed, status, msg)
        )
    return rows


def _unmatched_logs(base_meta: Mapping[str, Any], new_meta: Mapping[str, Any]) -> dict[str, str]:
    """The imported logs (``legbench compare --reference-log``: metrics.json's ``source: log``) of the baseline's
    metrics that the new run was not compared with, each with why: not given to the new run, or given under the
    same name holding another recording (their ``sha256`` differ; a metrics.json without one is taken at its name).
    What was compared against them is not the code's result, so it is left unchecked rather than failed (a README
    review: a run given a hardware log, used as a baseline, failed every fresh run with 31 regressions)."""
    nb = new_meta.get("backends") or {}
    out = {}
    for name, b in (base_meta.get("backends") or {}).items():
        if b.get("source") != "log":
            continue
        now = nb.get(name)
        if now is None:
            out[name] = ("an imported log the baseline was compared with and this run was not; compare it with the "
                         "same --reference-log to check it")  # fmt: skip
        elif b.get("sha256") and now.get("sha256") and b["sha256"] != now["sha256"]:
            out[name] = (f"an imported log of the baseline's name holding another recording (SHA-256 "
                         f"{now['sha256'][:12]}... against the baseline's {b['sha256'][:12]}...): its metrics compare "
                         "other data; compare the baseline's log to check it")  # fmt: skip
    return out


def _status_rows(sc: str, base_meta: Mapping[str, Any], new_meta: Mapping[str, Any]) -> list[CheckRow]:
    rows = []
    bb, nb = base_meta.get("backends") or {}, new_meta.get("backends") or {}
    nan = math.nan
    for name, b in bb.items():
        was = b.get("status")
        now = (nb.get(name) or {}).get("status", "absent")
        why = (nb.get(name) or {}).get("reason") or "not in the new run"
        if was == "ok" and now != "ok":
            msg = f"{sc}/{name}: backend was ok in the baseline, now {now}: {why}"
            rows.append(CheckRow(sc, name, "", "-", "-", "status", nan, nan, nan, "FAILED", msg))
        else:
            rows.append(CheckRow(sc, name, "", "-", "-", "status", nan, nan, nan, "pass", f"{sc}/{name}: {now}"))
    return rows


def _trace_checks(sc: str, base_dir: Path, new_dir: Path, backends: Mapping[str, Any]) -> list[TraceCheck]:
    out = []
    for name, b in backends.items():
        if b.get("status") != "ok" or b.get("source") == "log":
            continue
        fb, fn = base_dir / f"{name}.parquet", new_dir / f"{name}.parquet"
        if not fn.is_file():
            continue
        if not fb.is_file():
            out.append(TraceCheck(sc, name, "no baseline log", math.nan))
            continue
        db, dn = read_log(fb), read_log(fn)
        if list(db.columns) != list(dn.columns) or len(db) != len(dn):
            detail = f"shape {db.shape} -> {dn.shape}"
            out.append(TraceCheck(sc, name, "changed", math.nan, detail))
            continue
        num = [c for c in db.columns if c != "controller"]
        xb = db[num].to_numpy(dtype=float)
        xn = dn[num].to_numpy(dtype=float)
        same_ctrl = "controller" not in db.columns or bool((db["controller"] == dn["controller"]).all())
        if np.array_equal(xb, xn, equal_nan=True):
            if same_ctrl:
                out.append(TraceCheck(sc, name, "identical", 0.0))
            else:  # the same numbers, another controller logged at some tick (an event's switch moved)
                out.append(TraceCheck(sc, name, "changed", 0.0, "the controller column only"))
        else:
            with np.errstate(invalid="ignore"):
                diff = np.abs(xn - xb)
            worst = float(np.nanmax(diff)) if np.isfinite(diff).any() else math.nan
            col = num[int(np.nanargmax(np.nanmax(diff, axis=0)))] if np.isfinite(diff).any() else "controller"
            out.append(TraceCheck(sc, name, "changed", worst, f"largest change in {col}"))
    return out


#: The keys of run.json's ``scenario`` that make the task (the leg's physics, its controllers, what is compared):
#: a baseline that differs in one is another experiment. The backends' settings are not among them: an engine's
#: setting changed (a sub-step) is what the check is for; the comparison's tolerances neither (the new run's apply),
#: nor its published rows (a source's numbers shown beside the runs).
TASK_KEYS = ("duration", "control_rate", "contact_mode", "profile", "gravity", "gains", "initial", "contact", "events")


def _task_of(sc: Mapping[str, Any]) -> dict[str, Any]:
    task = {k: sc[k] for k in TASK_KEYS if k in sc}
    if isinstance(sc.get("comparison"), Mapping):  # an older run.json without it: not compared
        task["comparison"] = {k: v for k, v in sc["comparison"].items() if k not in ("tolerances", "published")}
    return task


def _first_difference(old: Any, new: Any, path: str) -> tuple[str, Any, Any]:
    """The first key path (``contact.v_th``) under which two values of run.json differ, and the two values there."""
    if isinstance(old, Mapping) and isinstance(new, Mapping):
        for k in sorted(set(old) | set(new), key=str):
            if old.get(k) != new.get(k):
                return _first_difference(old.get(k), new.get(k), f"{path}.{k}")
    if isinstance(old, list) and isinstance(new, list) and len(old) == len(new):
        for i, (a, b) in enumerate(zip(old, new, strict=True)):
            if a != b:
                return _first_difference(a, b, f"{path}[{i}]")
    return path, old, new


def _run_json(d: Path) -> dict[str, Any] | None:
    """A run directory's run.json, read once for :func:`_label` and :func:`_same_inputs`; None where it has none (a
    baseline of metrics.json alone)."""
    return read_meta(d) if (d / "run.json").is_file() else None


def _label(meta: Mapping[str, Any] | None, doc: Mapping[str, Any], key: str) -> str:
    """A run directory's label (:func:`legbench.results.run_label`) from its run.json ``meta``, where it has one (a
    metrics.json written before labels named the profile says ``effort`` for ``effort__engine-defaults``), else
    its metrics.json's ``scenario`` (``doc``)."""
    if meta is None:
        return str(doc.get("scenario", key))
    sc = meta.get("scenario") or {}
    return run_label(str(sc.get("name", key)), profile_of(meta), str(sc.get("contact_mode") or "native"))


def _same_inputs(b: Mapping[str, Any] | None, n: Mapping[str, Any] | None, bdir: Path, ndir: Path) -> None:
    """Refuse a baseline made from another task than the new run: its scenario's physics, controllers or
    comparison (:data:`TASK_KEYS` of run.json's ``scenario``, with any ``--set``) or its leg model (run.json's
    ``leg`` digest where both have one, else its ``urdf``, named by the parameter file's digest where it is not the
    bundled leg). Its metrics would move as the
    task did, and pass or fail as regressions of the engines: a gains change of 20 % passed, a shank 10 % heavier
    passed. A backend's settings may differ (what the check measures). Either side without the key (an older
    run.json) is not compared; ``b``, ``n``: the two run.json (:func:`_run_json`)."""
    if b is None or n is None:
        return  # a baseline of metrics.json alone: nothing to compare
    bt, nt = _task_of(b.get("scenario") or {}), _task_of(n.get("scenario") or {})
    # in TASK_KEYS order, the comparison last: its steady window's default follows the duration, and a difference
    # there led the message where the user had changed the duration
    order = [*TASK_KEYS, "comparison"]
    shared = sorted(bt.keys() & nt.keys(), key=lambda k: order.index(k) if k in order else len(order))
    diffs = [_first_difference(bt[k], nt[k], k) for k in shared if bt[k] != nt[k]]
    diffs = [(f"the scenario's {where}", old, new) for where, old, new in diffs]
    bleg, nleg = (r.get("leg") or {} for r in (b, n))
    if bleg.get("digest") and nleg.get("digest"):  # the parameters' digest: a byte copy under another name is the leg
        if bleg["digest"] != nleg["digest"]:
            diffs.append(("the leg model (its parameters' digest)", f"{bleg['digest']} ({bleg.get('parameters')})",
                          f"{nleg['digest']} ({nleg.get('parameters')})"))  # fmt: skip
    elif b.get("urdf") and n.get("urdf") and b["urdf"] != n["urdf"]:
        diffs.append(("the leg model (urdf)", b["urdf"], n["urdf"]))
    if diffs:
        what, old, new = diffs[0]
        more = f" (and {len(diffs) - 1} more: {', '.join(d[0] for d in diffs[1:])})" if len(diffs) > 1 else ""
        raise ResultsError(str(ndir), f"{what} is {_short(new)}, the baseline's ({bdir}) {_short(old)}{more}: a "
                                      "regression check compares runs of one task; refresh the baseline on purpose "
                                      "(make baseline) or choose the matching --baseline")  # fmt: skip


def _version_changes(b: Mapping[str, Any] | None, n: Mapping[str, Any] | None) -> list[str]:
    """The packages whose versions differ between two run.json (``mujoco 4.0.0 -> 4.1.0``; legbench's commit to 12
    digits), each side's ``versions``; none where either records none."""
    bv, nv = ((r or {}).get("versions") or {} for r in (b, n))
    if not bv or not nv:
        return []
    out = []
    for k in dict.fromkeys([*bv, *nv]):
        old, new = str(bv.get(k, "none")), str(nv.get(k, "none"))
        if old != new:
            if k == "legbench_commit":  # 12 of the 40 digits, and any " (uncommitted changes)"
                old, new = old[:12] + old[40:], new[:12] + new[40:]
            out.append(f"{k} {old} -> {new}")
    return out


def _short(v: Any) -> str:
    text = json.dumps(v, sort_keys=True, default=str) if not isinstance(v, str) else v
    return text if len(text) <= 80 else text[:77] + "..."


def check(new: str | Path, baseline: str | Path, tolerance_file: str | Path | None = None) -> CheckReport:
    """Check new results against a baseline.

    Args:
        new: a run directory or a tree of them (results/latest).
        baseline: the baseline, same layout.
        tolerance_file: optional YAML/JSON tolerance file (see :func:`load_tolerances`).

    Returns:
        The :class:`CheckReport`; ``exit_status`` is 1 on any regression.

    Raises:
        ResultsError: a directory or metrics file is missing or malformed; a run of another scenario, or of
            another task or leg model than its baseline (:func:`_same_inputs`).
        ScenarioError: a tolerance file or run.json tolerances are malformed, or a ``scenarios`` section of the
            file matches no scenario name or run label checked.
    """
    new, baseline = Path(new), Path(baseline)
    common, per = load_tolerances(tolerance_file) if tolerance_file is not None else ({}, {})
    tfile = str(tolerance_file)
    nd, bd = run_dirs(new), run_dirs(baseline)
    if "" in nd or "" in bd:  # a single run directory on either side: compare the one pair
        if len(nd) != 1 or len(bd) != 1:
            raise ResultsError(str(new if "" in bd else baseline), "one side is a run directory, the other a tree")
        nd, bd = {"": next(iter(nd.values()))}, {"": next(iter(bd.values()))}
    rows: list[CheckRow] = []
    traces: list[TraceCheck] = []
    sources: dict[str, str] = {}
    changed: dict[str, None] = {}  # the version changes, in order, once each
    used: set[str] = set()  # scenario names and run labels checked, for the file's scenarios sections
    nan = math.nan
    for key, bdir in bd.items():
        if key not in nd:
            msg = f"scenario {key}: in the baseline but not in {new}"
            rows.append(CheckRow(key, "-", "", "-", "-", "status", nan, nan, nan, "MISSING", msg))
            continue
        ndir = nd[key]
        bmeta, bdf, brun = _metrics(bdir)
        ran = (brun.meta.get("backends") or {}) if brun is not None else {}
        # a log run.json says was written and is gone (not a backend that was missing when the baseline ran)
        lost = [b for b in (brun.backends.values() if brun is not None else ())
                if b.status == "missing" and (ran.get(b.name) or {}).get("status") == "ok"]  # fmt: skip
        if lost:  # its numbers would be n/a, and every new row of that backend would pass unchecked
            raise ResultsError(str(bdir), f"a baseline with a log missing (backend '{lost[0].name}': {lost[0].reason});"
                                          " restore it, or choose another --baseline")  # fmt: skip
        _check_baseline_rows(bdir, bmeta, bdf)
        nmeta, ndf, nrun = _metrics(ndir)
        nmeta = _with_run_statuses(nmeta, nrun)
        bjson, njson = _run_json(bdir), _run_json(ndir)
        bname, nname = _label(bjson, bmeta, key), _label(njson, nmeta, key)
        if bname != nname:  # another scenario's baseline: name the mismatch instead of 66 "regressions"
            raise ResultsError(str(ndir), f"holds scenario {nname!r} but the baseline {bdir} holds {bname!r}: "
                                          "not the same scenario; choose the matching --baseline")  # fmt: skip
        _same_inputs(bjson, njson, bdir, ndir)
        for change in _version_changes(bjson, njson):
            changed.setdefault(change)
        sc = nname
        # the rows pair by the run's label: a baseline's metrics.json written before labels named the profile
        # (effort__engine-defaults labelled effort) is the same run
        bdf, ndf = bdf.assign(scenario=sc), ndf.assign(scenario=sc)
        keys = (str(nmeta.get("name", sc)), sc)
        used.update(keys)
        layers, sources[sc] = _tolerances(ndir, keys, common, per, tfile)
        logs = _unmatched_logs(bmeta, nmeta)
        if bmeta.get("reference") in logs:  # every pair metric is against the log: none to check against
            ref = bmeta["reference"]
            raise ResultsError(str(bdir), f"the baseline was compared with {ref} as its reference (--log-is-reference)"
                                          f": {logs[ref]} ({ndir}), or choose another --baseline")  # fmt: skip
        for name, why in logs.items():
            rows.append(CheckRow(sc, name, "", "-", "-", "status", nan, nan, nan, "unchecked", f"{sc}/{name}: {why}"))
        bmeta = {**bmeta, "backends": {k: v for k, v in (bmeta.get("backends") or {}).items() if k not in logs}}
        nmeta = {**nmeta, "backends": {k: v for k, v in (nmeta.get("backends") or {}).items() if k not in logs}}
        bdf = bdf[~(bdf["backend"].isin(logs) | bdf["reference"].isin(logs))]
        ndf = ndf[~(ndf["backend"].isin(logs) | ndf["reference"].isin(logs))]
        rows += _status_rows(sc, bmeta, nmeta)
        rows += _check_rows(sc, bdf, ndf, layers)
        traces += _trace_checks(sc, bdir, ndir, nmeta.get("backends") or {})
    for key in nd.keys() - bd.keys():
        rows.append(CheckRow(key, "-", "", "-", "-", "status", nan, nan, nan, "new", f"scenario {key}: no baseline"))
    unused = sorted(set(per) - used)
    if unused:  # a typo, or a section for results not checked here, would otherwise be silently not applied
        raise ScenarioError(tfile, f"scenarios.{unused[0]}",
                            f"matches no scenario checked here; valid: {sorted(used)}")  # fmt: skip
    return CheckReport(new, baseline, tuple(rows), tuple(traces), sources, tuple(changed))


# --------------------------------------------------------------------------- #
# Output


def _moved(r: CheckRow) -> bool:
    return r.failed or r.status in ("moved", "improved", *UNCHECKED)


def _table_rows(report: CheckReport, all_rows: bool) -> list[list[str]]:
    out = []
    for r in report.rows:
        if all_rows or _moved(r):
            chg = _fmt(r.change) if math.isfinite(r.change) else ""
            out.append(
                [
                    r.scenario,
                    r.backend,
                    r.label,
                    r.metric,
                    _fmt(r.baseline),
                    _fmt(r.new),
                    chg,
                    _fmt(r.allowed),
                    r.status,
                ]
            )
    return out


_HEADER = ["scenario", "backend", "signal", "metric", "baseline", "new", "change", "allowed", "status"]


def format_table(report: CheckReport, all_rows: bool = False) -> str:
    """Plain-text table of what moved (every row with ``all_rows``), then a one-line verdict."""
    rows = _table_rows(report, all_rows)
    lines = []
    if rows:
        widths = [max(len(h), *(len(r[i]) for r in rows)) for i, h in enumerate(_HEADER)]
        lines.append("  ".join(h.ljust(w) for h, w in zip(_HEADER, widths, strict=True)))
        lines.append("  ".join("-" * w for w in widths))
        lines += ["  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)) for r in rows]
    else:
        lines.append("no metric moved")
    lines += [r.message for r in report.rows if r.status == "unchecked"]
    for t in report.traces:
        if t.status == "changed":
            lines.append(f"{t.scenario}/{t.backend}: time series changed ({t.detail})")
    if report.traces:
        counts = {k: sum(t.status == k for t in report.traces) for k in ("identical", "changed", "no baseline log")}
        lines.append(
            f"time series against the baseline: {counts['identical']} identical, {counts['changed']} changed, "
            f"{counts['no baseline log']} without a baseline log"
        )
    if report.versions:
        lines.append(f"versions differ from the baseline's (not a failure): {'; '.join(report.versions)}")
    lines.append(_verdict(report))
    return "\n".join(lines)


def _verdict(report: CheckReport) -> str:
    """The one-line verdict: how many metrics had a baseline to be checked against (a new one, not in the baseline,
    passes unchecked and is counted apart), and the regressions."""
    metrics = [r for r in report.rows if r.metric != "status"]
    new = sum(r.status == "new" for r in metrics)
    n = f"{len(metrics) - new} metrics checked" + (f" ({new} new, not in the baseline)" if new else "")
    reg = report.regressions
    if not reg:
        return f"PASS: {n} against {report.baseline}, no regression"
    named = "; ".join(r.message for r in reg[:10]) + ("; ..." if len(reg) > 10 else "")
    return f"FAIL: {len(reg)} regression(s) of {n} against {report.baseline}: {named}"


def write_markdown(report: CheckReport, path: str | Path) -> Path:
    """Write the Markdown summary: verdict, regressions, what moved, time-series identity, tolerance sources."""
    path = Path(path)
    lines = [f"# legbench check: {report.new} against {report.baseline}", "", f"**{_verdict(report)}**", ""]
    if report.regressions:
        lines += ["## Regressions", ""] + [f"- {r.message}" for r in report.regressions] + [""]
    unchecked = [r.message for r in report.rows if r.status == "unchecked"]
    if unchecked:
        lines += ["## Not checked", ""] + [f"- {m}" for m in unchecked] + [""]
    rows = _table_rows(report, all_rows=False)
    lines += ["## What moved", ""]
    if rows:
        lines += ["| " + " | ".join(_HEADER) + " |", "|" + "---|" * len(_HEADER)]
        lines += ["| " + " | ".join(r) + " |" for r in rows]
    else:
        lines.append("Nothing moved.")
    lines.append("")
    if report.traces:
        lines += [
            "## Time series against the baseline",
            "",
            "| scenario | backend | status | detail |",
            "|---|---|---|---|",
        ]
        lines += [f"| {t.scenario} | {t.backend} | {t.status} | {t.detail} |" for t in report.traces]
        lines.append("")
    if report.versions:
        lines += ["## Versions that differ from the baseline's", ""] + [f"- {v}" for v in report.versions] + [""]
    lines += ["## Tolerances", ""] + [f"- {sc}: {src}" for sc, src in report.tolerance_sources.items()] + [""]
    atomic_write_text(path, "\n".join(lines))
    return path


def write_junit(report: CheckReport, path: str | Path) -> Path:
    """Write a JUnit XML file: one testsuite per scenario, one testcase per metric (or backend status) checked."""
    path = Path(path)
    suites = ET.Element("testsuites", name="legbench.check")
    by_sc: dict[str, list[CheckRow]] = {}
    for r in report.rows:
        by_sc.setdefault(r.scenario, []).append(r)
    for sc, rows in by_sc.items():
        fails = sum(r.failed for r in rows)
        skipped = sum(r.status in UNCHECKED for r in rows)
        suite = ET.SubElement(
            suites, "testsuite", name=f"legbench.{sc}", tests=str(len(rows)), failures=str(fails), skipped=str(skipped)
        )
        for r in rows:
            name = (
                "status"
                if r.metric == "status"
                else f"{r.label} {r.metric}" + (f" vs {r.reference}" if r.reference else "")
            )
            case = ET.SubElement(suite, "testcase", classname=f"legbench.{sc}.{r.backend}", name=name)
            if r.failed:
                ET.SubElement(case, "failure", message=r.message, type=r.status).text = r.message
            elif r.status in UNCHECKED:
                ET.SubElement(case, "skipped", message=r.message)
    suites.set("tests", str(len(report.rows)))
    suites.set("failures", str(len(report.regressions)))
    ET.indent(suites)
    atomic_write_bytes(path, ET.tostring(suites, encoding="utf-8", xml_declaration=True))
    return path


def _not_an_input(opt: str, path: Path, new: Path, baseline: Path, tolerance_file: str | Path | None) -> None:
    """Refuse an output file that is or may become one of the check's inputs, even with ``--force`` (which
    replaces an earlier summary): anything in the baseline, the tolerance file, or a file inside a run directory
    (one holding run.json) other than the check's own (:data:`CHECK_OUTPUTS`): a run's run.json or log replaced by
    the summary was lost, and a file of another name there would be taken for part of the run."""
    where = path.resolve()
    if where.is_relative_to(baseline.resolve()):
        raise LegbenchError(f"{opt} {path}: inside the baseline {baseline}, which the check reads; choose another "
                            "file")  # fmt: skip
    if tolerance_file is not None and Path(tolerance_file).exists() and where == Path(tolerance_file).resolve():
        raise LegbenchError(f"{opt} {path}: is the tolerance file; choose another file")
    parent = enclosing_run(path) if path.name not in CHECK_OUTPUTS else None
    if parent is not None:
        raise LegbenchError(f"{opt} {path}: inside the run directory {parent}, which holds one run's files (a file "
                            "there is read as part of it); choose another file")  # fmt: skip


def run_check(
    new: str | Path,
    baseline: str | Path,
    tolerance_file: str | Path | None = None,
    summary: str | Path | None = None,
    junit: str | Path | None = None,
    stream: TextIO | None = None,
    all_rows: bool = False,
) -> int:
    """Check, print the table, write the Markdown summary and JUnit XML; return the exit status.

    Args:
        new: new results (run directory or tree).
        baseline: baseline, same layout.
        tolerance_file: optional tolerance file.
        summary: Markdown summary path (default ``NEW/check.md``).
        junit: JUnit XML path (default ``NEW/check-junit.xml``).
        stream: where the table is printed (default stdout).
        all_rows: print every row, not only what moved.

    Returns:
        0 if nothing regressed, 1 otherwise.

    Raises:
        ResultsError: as :func:`check`, and where ``baseline`` is ``new`` itself.
        LegbenchError: a path no file system can hold (a name too long), naming its option.
    """
    for what, given in (("", new), ("--baseline ", baseline), ("--tolerances ", tolerance_file)):
        try:
            if given is not None:
                Path(given).exists()
        except OSError as exc:  # a name too long for the file system: bad input, not a failed read or write
            raise LegbenchError(f"{what}{given}: {exc.strerror or exc}") from None
    if Path(new).exists() and Path(new).resolve() == Path(baseline).resolve():  # would pass, and write into it
        raise ResultsError(str(baseline), "the baseline is the new results directory itself: nothing to check")
    for opt, given in (("--summary", summary), ("--junit", junit)):
        if given is not None:
            _not_an_input(opt, Path(given), Path(new), Path(baseline), tolerance_file)
    summary = summary if summary is not None else Path(new) / CHECK_OUTPUTS[0]
    junit = junit if junit is not None else Path(new) / CHECK_OUTPUTS[1]
    if Path(summary).resolve() == Path(junit).resolve():  # the second would replace the first
        raise LegbenchError(f"--summary and --junit name the same file {summary}: the second would replace the first")
    report = check(new, baseline, tolerance_file)
    out = stream if stream is not None else sys.stdout
    print(format_table(report, all_rows), file=out)
    write_markdown(report, summary)
    write_junit(report, junit)
    return report.exit_status
