"""Compare the backends of a run directory: every metric of docs/metrics.md, one table, metrics.json.

Data flow: :func:`legbench.results.load_run` (a :class:`~legbench.results.Run`
of :class:`~legbench.results.RunResult`) and an optional external log
(:func:`legbench.logs.load_log`) -> :func:`compare`, which measures with
:mod:`legbench.metrics` (:class:`ComparisonResult` of
:class:`~legbench.metrics.PairMetrics`, :class:`~legbench.metrics.SteadyState`,
:class:`~legbench.metrics.ModeSplit`) -> the long metrics table
(:meth:`ComparisonResult.frame`) and the metrics.json document
(:meth:`ComparisonResult.to_json`, written by :func:`legbench.results.write_metrics`).
Between stages everything is frozen dataclasses of numpy arrays; pandas
appears only when the table is built. The keys of ``metrics.json`` are
documented in ``docs/metrics.md``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from legbench.backends.base import contact_point, rigid_contact
from legbench.contact import ContactParams
from legbench.contact_residuals import FN_MIN, ContactResiduals, residuals
from legbench.exceptions import ResultsError
from legbench.logs import RosOptions, digest, is_ros_bag, load_log
from legbench.metrics import (
    COND_MAX,
    T_EPS,
    ModeSplit,
    PairMetrics,
    SteadyState,
    check_lag_mode,
    contact_split,
    pair_metrics,
    reference_peak,
    steady_state,
)
from legbench.resources import shown
from legbench.results import FRAME_COLUMNS, METRICS_SCHEMA, Run, RunResult, load_run, log_digests, result_from_frame
from legbench.signals import JOINT_OF, LABELS, SIGNAL_OF

__all__ = ["ComparisonResult", "compare", "first_contact", "log_settings_problem", "reference_sibling"]


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
        residuals: contact-law residuals per trace (:mod:`legbench.contact_residuals`): scores of each
            backend against the law it was meant to follow, needing no reference backend.
    """

    run: Run
    reference: str
    traces: Mapping[str, RunResult]
    pairs: tuple[PairMetrics, ...]
    steady: tuple[SteadyState, ...]
    split: tuple[ModeSplit, ...] = ()
    split_run: Run | None = None
    notes: tuple[str, ...] = ()
    residuals: Mapping[str, ContactResiduals] = field(default_factory=dict)

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
            # a component both runs hold at one constant value (a torque at its limit throughout): its 0 is the clamp's
            add(p.backend, p.reference, "held", p.held.astype(float), np.flatnonzero(p.held).tolist())
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
            if s.analytic_lowest is not None and s.lift_compensation is not None:
                forces |= {"analytic_lowest": s.analytic_lowest, "lift_compensation": s.lift_compensation}
            for metric, v in forces.items():
                add(s.backend, "", metric, np.concatenate([np.zeros(9), v]), range(9, 12))
        for m in self.split:
            for part in ("native", "contact", "integration", "drift"):
                add(m.backend, m.reference, f"split_{part}_rms", getattr(m, f"{part}_rms"))
                add(m.backend, m.reference, f"split_{part}_pct", getattr(m, f"{part}_pct"))
        for backend, r in self.residuals.items():
            for key, value in r.to_dict().items():
                rows.append(_row(sc, backend, "", "contact", "-", f"residual_{key}", float(value)))
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
            if b.info.get("integrator_family"):  # what the headline says of a deviation's cause
                backends[name]["integrator_family"] = b.info["integrator_family"]
            if run.contact_mode == "native" and rigid_contact(b.info):  # no spring: the headline says so
                backends[name]["contact_rigid"] = True
            n_sub = b.info.get("sub_steps")
            if b.info.get("integrator_family") != "adaptive" and isinstance(n_sub, int) and n_sub >= 1:
                backends[name]["step"] = run.control_dt / n_sub  # [s] a fixed step, beside its family
        for name, tr in self.traces.items():
            if name not in run.backends:  # an imported log, and which recording it was
                recorded = {k: tr.info[k] for k in ("file", "sha256") if k in tr.info}
                backends[name] = {"status": "ok", "reason": None, "source": "log", **recorded}
        for s in self.steady:  # where its force acted, as the force check and the residuals took it
            backends[s.backend]["contact_lift"] = s.lift
            backends[s.backend]["contact_poc"] = s.poc
            # [rad/s] the steady window's largest joint speed: whether its means are statics (the index says so)
            backends[s.backend]["steady_qd_max"] = _json_value(s.qd_max)
        for name, tr in self.traces.items():  # when a deviation is a touch-down transient (the report says so)
            backends[name]["first_contact"] = first_contact(tr)
        return {
            "schema": METRICS_SCHEMA,
            "scenario": run.label,
            "name": run.name,
            "contact_mode": run.contact_mode,
            "poc": run.poc,
            "reference": self.reference,
            "skip": run.skip,
            "steady_window": run.steady_window,
            "duration": _json_value(run.duration),  # null for a run.json without scenario.duration
            # [s]: the sample spacing of the logs (the report tells a task that starts on the ground by it)
            "control_dt": _json_value(run.control_dt),
            "split_with": None if self.split_run is None else self.split_run.label,
            "events": [{"t": e.t, "controller": e.controller} for e in run.events],
            "backends": backends,
            "logs": log_digests(run.path),
            "notes": list(self.notes),
            "columns": list(FRAME_COLUMNS),
            "metrics": [{k: _json_value(v) for k, v in r.items()} for r in self.records()],
        }


def first_contact(trace: RunResult) -> float | None:
    """The time [s] of the first sample at which ``trace``'s normal ground force exceeds
    :data:`~legbench.contact_residuals.FN_MIN` (the residuals' "in contact"), or None: the foot never touches
    the ground (or the force is not logged)."""
    fz = trace.f[:, 2] if trace.f.ndim == 2 and trace.f.shape[1] == 3 else np.empty(0)
    hit = np.flatnonzero(np.nan_to_num(fz, nan=0.0) > FN_MIN)
    return float(trace.t[hit[0]]) if hit.size else None


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


def reference_sibling(run_dir: Path, contact_mode: str) -> Path | None:
    """The reference-contact-mode run beside a native-mode run directory, ``<run_dir>__reference``, if it holds a
    run (run.json); None otherwise or for a run not in native mode."""
    if contact_mode != "native":
        return None
    if run_dir.name in ("", ".", ".."):  # "." or "..": no name to find the sibling by until resolved
        run_dir = run_dir.resolve()
    cand = run_dir.parent / f"{run_dir.name}__reference"
    return cand if (cand / "run.json").is_file() else None


def _coverage_notes(log: RunResult, run_end: float, window: float) -> list[str]:
    """What an imported log leaves out of the run it is measured against: a span that starts after the run's
    start or ends before its end by more than one of its samples (its deviations are measured over the overlap
    only), and a steady window the log does not reach (no steady state for it)."""
    t0, t1 = float(log.t[0]), float(log.t[-1])
    slack = float(np.median(np.diff(log.t))) + T_EPS if len(log.t) > 1 else T_EPS  # one of its own samples
    notes: list[str] = []
    if t0 > slack or t1 < run_end - slack:
        share = 100 * max(min(t1, run_end) - max(t0, 0.0), 0.0) / run_end if run_end > 0 else math.nan
        notes.append(f"{log.backend} covers {t0:.3f}..{t1:.3f} s of the run's 0..{run_end:g} s ({share:.0f} %): its "
                     "deviations are measured over that span only")  # fmt: skip
    if t1 < run_end - window - T_EPS:
        notes.append(f"{log.backend} ends at {t1:.3f} s, before the steady window {run_end - window:.3f}.."
                     f"{run_end:.3f} s: no steady state for it")  # fmt: skip
    return notes


def _sign_note(log: RunResult, ref: RunResult) -> list[str]:
    """A log whose normal force has the opposite sign of the reference's where the reference pushes (> 1 N): the
    foot's force on the ground, where legbench logs the ground's on the foot. Said, not changed."""
    pressed = ref.f[:, 2] > 1.0
    t = ref.t[pressed]
    if len(t) < 2 or not np.isfinite(log.f[:, 2]).any():
        return []
    fz = np.interp(t, log.t, log.f[:, 2], left=np.nan, right=np.nan)
    fz = fz[np.isfinite(fz)]
    if len(fz) < 2 or not np.median(fz) < -1.0:
        return []
    return [f"{log.backend}: its normal force is negative where the reference's foot is pressed (median "
            f"{np.median(fz):.3g} N against {np.median(ref.f[pressed, 2]):.3g} N): the foot's force on the "
            "ground? legbench compares the ground's force on the foot (a ROS bag: its force sign option, "
            "--ros-force-sign -1; a CSV: negate fx, fy, fz)"]  # fmt: skip


def _contact_law(run: Run) -> ContactParams | None:
    """The contact law the run was meant to follow (run.json ``scenario.contact``, whose keys
    :func:`legbench.results.load_run` has checked), None where it names none."""
    contact = (run.meta.get("scenario") or {}).get("contact")
    return ContactParams(**contact) if contact else None


def _missing_of(tr: RunResult) -> str:
    """What a log lacks of tau and q, which the analytic force check needs: no finite tau, q or either, or no
    sample with both."""
    gone = [name for name, x in (("tau", tr.tau), ("q", tr.q)) if not np.isfinite(x).any()]
    return f"no finite {' or '.join(gone)}" if gone else "no sample with both tau and q finite"


def log_settings_problem(
    log: str | Path | None,
    column_map: object,
    log_is_reference: bool,
    log_time_scale: float,
    ros_given: bool,
    words: Mapping[str, str] | None = None,
    log_t0: float | None = None,
) -> str | None:
    """Why :func:`compare`'s log settings cannot apply, or None: settings that shape a log given without one (they
    would be ignored), or ROS options without a log that is a ROS bag. ``column_map`` counts as given when truthy
    (the mapping, or the command line's text); ``words``: the caller's names for the arguments (the command line's
    options), the others named as :func:`compare` names them."""
    w = dict(words or {})
    if log is None:
        given = [w.get(n, n) for n, on in (("column_map", bool(column_map)), ("log_is_reference", log_is_reference),
                                          ("log_time_scale", log_time_scale != 1.0),
                                          ("log_t0", log_t0 is not None)) if on]  # fmt: skip
        if given:
            return f"{', '.join(given)}: need {w.get('log', 'log')} (they describe that log)"
    if log is not None and log_time_scale != 1.0 and is_ros_bag(log):  # bag stamps are ns: it would be ignored
        return (f"{w.get('log_time_scale', 'log_time_scale')}: a ROS bag's times are its stamps (ns), read as such; "
                "it applies to a CSV log")  # fmt: skip
    if ros_given and (log is None or not is_ros_bag(log)):
        return (
            f"{w.get('ros', 'ros')}: need {w.get('log', 'log')} naming a ROS bag (a .bag file, a ROS 2 bag "
            "directory or its .db3 / .mcap file)"
        )
    return None


def compare(
    run_dir: str | Path,
    *,
    log: str | Path | None = None,
    log_name: str | None = None,
    column_map: Mapping[str, str] | None = None,
    log_time_scale: float = 1.0,
    log_t0: float | None = None,
    log_is_reference: bool = False,
    ros: RosOptions | None = None,
    all_pairs: bool = False,
    lag: str = "off",
    max_lag: float = 0.1,
    lag_signals: Sequence[str] = ("q",),
    split_dir: str | Path | None = "auto",
) -> ComparisonResult:
    """Measure every backend of a run directory against the scenario's reference backend.

    Args:
        run_dir: a ``legbench run`` output directory (run.json + parquet files).
        log: an external log, CSV or ROS bag (see :func:`load_log`), compared as one more backend.
        log_name: its name in tables and plots (default: ``log:<file stem>``).
        column_map: header name -> legbench column, for the log.
        log_time_scale: factor taking the log's time unit to seconds.
        log_t0: the log's time [s, after ``log_time_scale``] that is the run's t = 0 (a CSV stamped in epoch
            seconds, a bag's clock); None: 0 for a CSV, a bag's first joint-state sample.
        log_is_reference: measure every backend against the log instead of the
            scenario's reference backend.
        ros: topics and joints of a ROS bag log (:class:`legbench.logs.RosOptions`).
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
        ResultsError: a directory or file is missing or malformed, or the log does not overlap the run (or
            ends before its skip).
    """
    check_lag_mode(lag)
    run = load_run(run_dir)
    traces: dict[str, RunResult] = dict(run.traces)
    notes: list[str] = []
    for st in run.backends.values():
        if st.status != "ok":
            notes.append(f"backend '{st.name}' {st.status}: {st.reason or 'no reason given'}")
    reference = run.reference
    log_key: str | None = None
    if log is not None:
        name = log_key = log_name or f"log:{Path(log).stem}"
        if name in traces:
            raise ResultsError(str(log), f"log name '{name}' is already a backend of {run.path}; pass another name")
        traces[name] = result_from_frame(load_log(log, column_map, log_time_scale, ros, log_t0), name, str(log))
        # which recording it was (metrics.json), so a log re-recorded under the same name is not taken for it
        traces[name].info.update(file=shown(log), sha256=digest(log))
        end = float(traces[name].t[-1])
        if run.skip > 0.0 and end <= run.skip + T_EPS:  # every metric would be n/a, and said nowhere
            raise ResultsError(str(log), f"ends at t = {end:.4g} s, before the run's skip ({run.skip:g} s, its "
                                         "scenario's comparison.skip): no sample of it is compared")  # fmt: skip
        if log_is_reference:
            reference = name
    pairs: list[PairMetrics] = []
    if reference not in traces:
        why = run.backends[reference].reason if reference in run.backends else "not in run.json"
        notes.append(f"reference backend '{reference}' has no data ({why}): no deviations measured")
    # the spec's denominator for every pair: the scenario reference's peak over the run (docs/metrics.md), so a-vs-b
    # and b-vs-a share it and every pair of a component is a share of one number, whatever span each pair compares
    # (a log shorter than the run, a lag removed); None without the reference's data: each pair its own
    peak = reference_peak(traces[reference], run.skip) if reference in traces else None
    if reference in traces:
        for name, tr in traces.items():
            if name != reference:
                pairs.append(pair_metrics(tr, traces[reference], run.skip, lag, max_lag, lag_signals, peak=peak))
    if all_pairs:
        for a in traces:
            for b in traces:
                if a != b and b != reference:
                    pairs.append(pair_metrics(traces[a], traces[b], run.skip, lag, max_lag, lag_signals, peak=peak))
    # an imported log is measured over the run's steady window, not its own last seconds (which may be elsewhere)
    run_end = float(traces[run.reference].t[-1]) if run.reference in traces else run.duration
    ends = {name: run_end if name not in run.traces else None for name in traces}
    unreached: set[str] = set()  # a log ending before the steady window: the coverage note says so
    if log_key is not None:
        notes += _coverage_notes(traces[log_key], run_end, run.steady_window)
        if run.reference in traces and log_key != run.reference:
            notes += _sign_note(traces[log_key], traces[run.reference])
        if float(traces[log_key].t[-1]) < run_end - run.steady_window - T_EPS:
            unreached.add(log_key)
    infos = {n: b.info for n, b in run.backends.items()}
    points = {n: contact_point(infos.get(n), run.poc) for n in traces}  # where each force acted
    steady = tuple(steady_state(tr, run.steady_window, points[n][0], run.gravity, ends[n], points[n][1])
                   for n, tr in traces.items())  # fmt: skip
    for s in steady:
        if s.backend in unreached:
            continue
        if math.isnan(s.cond):
            notes.append(
                f"{s.backend}: the analytic force check needs tau and q, and the log has "
                f"{_missing_of(traces[s.backend])} over the steady window; analytic check undefined"
            )
        elif not s.cond < COND_MAX:
            notes.append(f"{s.backend}: J_poc is singular at the steady-state pose; analytic check undefined")
    split: tuple[ModeSplit, ...] = ()
    split_run = None
    if split_dir == "auto":
        sdir = reference_sibling(run.path, run.contact_mode)
    else:
        sdir = Path(split_dir) if split_dir is not None else None
    if sdir is not None:
        split_run = load_run(sdir)
        if split_run.contact_mode != "reference":
            raise ResultsError(str(sdir), f"contact_mode is '{split_run.contact_mode}', expected 'reference'")
        if split_run.name != run.name:
            raise ResultsError(str(sdir), f"scenario '{split_run.name}' is not '{run.name}'")
        shifts = {p.backend: p.lag_removed for p in pairs if p.reference == run.reference and p.lag_removed}
        split = contact_split(run, split_run, shifts=shifts)
        if run.reference not in run.traces or run.reference not in split_run.traces:
            notes.append(f"no contact-mode split: reference backend '{run.reference}' missing in one mode")
        else:
            for name in run.traces:
                if name != run.reference and name not in split_run.traces:
                    bs = split_run.backends.get(name)
                    why = f"{bs.status}: {bs.reason or 'no reason given'}" if bs is not None else "not in its run.json"
                    notes.append(f"no contact-mode split for '{name}': no data in {split_run.label} ({why})")
    law = _contact_law(run)
    if law is None:
        notes.append("no contact-law residuals: run.json's scenario names no contact law")
    # mu_s: a Coulomb engine's own contact; in reference mode every backend applies the law, which slides at mu_k
    slide = {n: str((infos.get(n) or {}).get("sliding_coefficient", "mu_k")) if run.contact_mode == "native"
             else "mu_k" for n in traces}  # fmt: skip
    res = {} if law is None else {n: residuals(tr.t, tr.q, tr.qd, tr.f, law, points[n], slide[n])
                                  for n, tr in traces.items()}  # fmt: skip
    return ComparisonResult(run, reference, traces, tuple(pairs), steady, split, split_run, tuple(notes), res)
