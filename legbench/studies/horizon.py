"""Short-horizon comparison: local error per window, reported next to the free-running divergence.

Two backends that each integrate well can still drift apart over a long run,
because small differences grow along an unstable or marginally stable motion.
To tell the local (per-step) error of a backend from that divergence, every
``window`` seconds the backend is re-initialised from the reference backend's
logged state, the reference's logged torques for the window are replayed (the
torques come from the harness, so replaying them is exact), and the deviation
accumulated within the window is measured. Only the public Backend API is used
(``reset``, ``step``, ``state``, ``ground_force``).

The reset floor: a backend whose engine state is more than its joint coordinates
(maximal coordinates: bodies held on their joints by constraints with ERP
position correction) carries a constraint drift through a free run that
``reset(q, qd)`` removes, putting the bodies exactly on their joints. Replaying
its own log on itself then does not give zero, and that part of the windowed
error against the reference is ``reset``'s artefact, not the step's local
error. So every backend's own free-running log is replayed on itself with the
same windows (one more replay per backend, as many steps as its free run; none
more for the reference, whose replay on itself is that) and the result, the
reset floor, is reported beside the local error; a row whose floor is not below
:data:`FLOOR_FRACTION` of its local error is marked (:func:`reset_limited`):
there the local error cannot be told from the reset artefact. A backend whose
state is its generalized coordinates has a floor of exactly zero.

Data flow: reference :class:`~legbench.results.RunResult` -> :func:`replay`
(:class:`HorizonResult`, numpy) -> :func:`short_horizon` (a pandas table with
the free-running deviation beside the windowed one and the reset floor). Deviations are
:func:`legbench.metrics.deviation` (hip wrapped).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from legbench import backends as registry
from legbench.backends.base import Backend
from legbench.exceptions import LegbenchError, ScenarioError
from legbench.metrics import deviation, max_abs, wrapped
from legbench.results import RunResult
from legbench.run import run_backend
from legbench.scenario import Scenario, physics_of
from legbench.signals import COLUMNS, UNITS

__all__ = [
    "FLOOR_FRACTION",
    "SIGNALS",
    "HorizonResult",
    "largest_peak",
    "replay",
    "replay_task",
    "reset_limited",
    "short_horizon",
]

#: Signals compared per window: joint positions [rad], velocities [rad/s], ground force in W [N].
SIGNALS = ("q", "qd", "force")
#: A local error is told from ``reset``'s artefact only where the reset floor (the backend's own log replayed on
#: itself) is below this fraction of it (the largest over the windows, both): a floor of 10 % or more of the local
#: error is a share of it that the backend's step did not make (:func:`reset_limited`).
FLOOR_FRACTION = 0.1


@dataclass(frozen=True)
class HorizonResult:
    """Deviation of a backend from the reference within each re-initialised window.

    Attributes:
        window: window length [s].
        t0: window start times [s], shape (n_w,).
        end: signal -> |x_b - x_ref| at each window's end, shape (n_w, 3).
        peak: signal -> max over each window of |x_b - x_ref|, shape (n_w, 3).
        status: ``ok`` or ``failed`` (the backend diverged in a window).
        reason: why it failed, or None.
    """

    window: float
    t0: np.ndarray
    end: dict[str, np.ndarray]
    peak: dict[str, np.ndarray]
    status: str = "ok"
    reason: str | None = None


def window_ticks(window: float, control_dt: float) -> int:
    """Number of control periods in ``window`` [s]; it must be a whole, positive number."""
    n = round(window / control_dt)
    if n < 1 or abs(window / control_dt - n) > 1e-6:
        raise LegbenchError(
            f"short-horizon window {window} s is not a whole number of control periods ({control_dt} s)"
        )
    return int(n)


def replay(backend: Backend, reference: RunResult, window: float) -> HorizonResult:
    """Re-initialise ``backend`` from the reference state every ``window`` and replay the reference torques.

    Args:
        backend: a loaded backend (its own settings; left in an arbitrary state).
        reference: the reference run: ticks uniform with the control period, its torques held
            over [t_k, t_k + Ts).
        window: window length [s].

    Returns:
        The deviation at each window's end and its maximum over the window.
    """
    t, q, qd, tau = reference.t, reference.q, reference.qd, reference.tau
    n = len(t)
    if n < 2:
        raise LegbenchError("short-horizon replay needs a reference of at least two ticks")
    W = window_ticks(window, float(t[1] - t[0]))
    starts = [int(s) for s in range(0, n - 1, W)]
    ref = {"q": q, "qd": qd, "force": reference.f}
    wrap = {s: wrapped(s) for s in SIGNALS}
    end = {s: np.full((len(starts), 3), np.nan) for s in SIGNALS}
    peak = {s: np.full((len(starts), 3), np.nan) for s in SIGNALS}
    status, reason = "ok", None
    for w, s0 in enumerate(starts):
        stop = min(s0 + W, n - 1)
        backend.reset(np.array(q[s0]), np.array(qd[s0]))
        acc = {s: np.zeros(3) for s in SIGNALS}
        try:
            for k in range(s0, stop):
                backend.step(np.array(tau[k]))
                qb, qdb = backend.state()
                got = {"q": qb, "qd": qdb, "force": backend.ground_force()}
                for s in SIGNALS:
                    d = np.abs(deviation(got[s], ref[s][k + 1], wrap[s]))
                    np.maximum(acc[s], d, out=acc[s])
                    if k == stop - 1:
                        end[s][w] = d
        except Exception as exc:  # as the run loop: any error of the engine's fails this backend alone
            status, reason = "failed", f"window at t = {t[s0]:.4f} s: {type(exc).__name__}: {exc}"
            break
        if not all(math.isfinite(float(acc[s].sum())) for s in SIGNALS):
            status, reason = "failed", f"window at t = {t[s0]:.4f} s: state is not finite"
            break
        for s in SIGNALS:
            peak[s][w] = acc[s]
    return HorizonResult(window, np.asarray(t, float)[starts], end, peak, status, reason)


def reset_limited(local_max: float, floor_max: float) -> bool:
    """Whether a local error ``local_max`` cannot be told from the reset floor ``floor_max`` (both the largest over
    the windows, in the signal's units): the floor is above zero and not below :data:`FLOOR_FRACTION` of the local
    error. A floor of exactly zero (``reset`` restores the state a run was in) never limits; NaN (either not
    measured: a replay failed) does not either."""
    return floor_max > 0.0 and not math.isnan(local_max) and not floor_max < FLOOR_FRACTION * local_max


def _floor_note(local_max: float, floor_max: float, unit: str) -> str:
    """The marked row's note: the floor, named with its size against the local error."""
    share = f"{floor_max / local_max:.2f}x the local error" if local_max > 0.0 else "while the local error is 0"
    return (f"reset-limited: reset floor {floor_max:.3g} {unit} (its own log replayed on itself), {share} "
            f"({local_max:.3g} {unit}; told apart below {FLOOR_FRACTION:g}x): reset() puts the engine in a state its "
            "free run is not in, and this local error cannot be told from that artefact")  # fmt: skip


def largest_peak(col: np.ndarray) -> float:
    """The largest of a component's in-window peaks over the windows measured (NaN where none was: no finite one)."""
    return float(np.nanmax(col)) if np.isfinite(col).any() else math.nan


def _peak_stats(col: np.ndarray) -> tuple[float, float]:
    """Largest (:func:`largest_peak`) and median of a component's in-window peaks (NaN where none was measured)."""
    top = largest_peak(col)
    return top, math.nan if math.isnan(top) else float(np.nanmedian(col))


def _load(scenario: Scenario, name: str, contact_mode: str | None) -> Backend:
    return registry.load(name, physics_of(scenario, contact_mode), scenario.backends.get(name, {}))


def replay_task(
    scenario: Scenario, name: str, references: Sequence[RunResult], window: float, contact_mode: str | None = None
) -> list[HorizonResult]:
    """Load backend ``name`` for ``scenario`` once and :func:`replay` each of the ``references`` runs on it in
    windows of ``window`` [s] (a sweep's task: the reference's run, then its own for the reset floor; each replay
    resets the backend at every window, so one instance serves them all)."""
    backend = _load(scenario, name, contact_mode)
    try:
        return [replay(backend, reference, window) for reference in references]
    finally:
        backend.close()


def _free_deviation(tr: RunResult, ref: RunResult, signal: str) -> np.ndarray:
    """Max over the common ticks of |x_b - x_ref| per component (free-running)."""
    n = min(len(tr.t), len(ref.t))
    return max_abs(deviation(tr.signal(signal)[:n], ref.signal(signal)[:n], wrapped(signal)))


def short_horizon(
    scenario: Scenario,
    backend_names: Sequence[str],
    window: float,
    reference: str | None = None,
    contact_mode: str | None = None,
) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Free-running deviation and windowed (local) error of each backend against the reference backend.

    Args:
        scenario: the scenario to run.
        backend_names: backends to compare (the reference among them is compared with itself,
            which gives its reset floor as its local error: zero for a backend whose state is
            its generalized coordinates, a check of determinism and of ``reset``).
        window: re-initialisation period [s].
        reference: reference backend (default: the scenario's ``comparison.reference``).
        contact_mode: override of the scenario's contact mode.

    Returns:
        ``summary``: one row per backend, signal and component with ``free_max`` (max
        free-running deviation), ``local_max`` and ``local_median`` (over windows of the
        in-window maximum), ``reset_floor_max`` and ``reset_floor_median`` (the same for the
        backend's own free-running log replayed on itself: what ``reset`` alone contributes),
        ``reset_limited`` (:func:`reset_limited`) and ``note`` (the floor named, where marked;
        else empty), all in ``unit``; ``windows``: one row per backend, window and component
        (``end`` and ``peak`` of the local error, ``floor_end`` and ``floor_peak`` of the floor).

        Cost: one replay more per backend than the local error alone (the reference's replay on
        itself is its floor), as many steps as the backend's free run.

    Raises:
        ScenarioError: the window is not a whole number of control periods.
        LegbenchError: the reference run failed.
    """
    ref_name = reference or scenario.comparison.reference
    try:
        window_ticks(window, scenario.control_dt)
    except LegbenchError as exc:
        raise ScenarioError(scenario.file, "short_horizon.window", str(exc)) from None
    ref = run_backend(scenario, ref_name, contact_mode)
    if ref.status != "ok":
        raise LegbenchError(f"reference backend {ref_name} failed: {ref.reason}")
    rows: list[dict[str, Any]] = []
    wrows: list[dict[str, Any]] = []
    for name in backend_names:
        tr = ref if name == ref_name else run_backend(scenario, name, contact_mode)
        if tr.status != "ok":
            rows.append({"backend": name, "status": tr.status, "reason": tr.reason})
            continue
        backend = _load(scenario, name, contact_mode)
        try:
            res = replay(backend, ref, window)
            floor = res if tr is ref else replay(backend, tr, window)  # the reset floor: its own log on itself
        finally:
            backend.close()
        for s in SIGNALS:
            free = _free_deviation(tr, ref, s)
            for j, comp in enumerate(COLUMNS[s]):
                local_max, local_median = _peak_stats(res.peak[s][:, j])
                floor_max, floor_median = _peak_stats(floor.peak[s][:, j])
                limited = reset_limited(local_max, floor_max)
                note = _floor_note(local_max, floor_max, UNITS[s]) if limited else ""
                if floor.status != "ok":
                    note = f"reset floor not measured in full: {floor.reason}"
                rows.append({
                    "backend": name, "reference": ref_name, "window": window, "signal": s, "component": comp,
                    "unit": UNITS[s], "free_max": float(free[j]), "local_max": local_max, "local_median": local_median,
                    "reset_floor_max": floor_max, "reset_floor_median": floor_median, "reset_limited": limited,
                    "status": res.status, "reason": res.reason, "note": note,
                })  # fmt: skip
                for w, t0 in enumerate(res.t0):
                    mine = w < len(floor.t0)  # the same windows: both logs have the scenario's ticks
                    wrows.append({"backend": name, "t0": float(t0), "signal": s, "component": comp,
                                  "end": float(res.end[s][w, j]), "peak": float(res.peak[s][w, j]),
                                  "floor_end": float(floor.end[s][w, j]) if mine else math.nan,
                                  "floor_peak": float(floor.peak[s][w, j]) if mine else math.nan})  # fmt: skip
    return pd.DataFrame(rows), pd.DataFrame(wrows)
