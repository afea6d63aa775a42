"""The metrics: deviation of one run from another, and the figures made of it (docs/metrics.md).

The only implementation of each figure; compare, sweep, horizon and check use
these.

Conventions:
    * Deviation of run a from reference r: d(t) = x_a(t) - x_r(t); for the
      angle of a continuous joint (the hip), the shortest angle
      mod(x_a - x_r + pi, 2 pi) - pi, so a wrapped log and an unwrapped one agree.
    * Simulation error % = max_t |d| / max_t |x_r| * 100 per component; NaN
      when the reference's peak is at or below :data:`PEAK_FLOOR`.
    * Time lag: a lag L > 0 means a is late, x_a(t) ~ x_r(t - L); removing it
      compares x_a(t + L) with x_r(t).
    * The analytic force check inverts tau = J_poc^T h + G(q): h is the force
      the foot exerts on the environment, the ground force on the foot is -h.

Data flow: two :class:`~legbench.results.RunResult` -> :func:`align` (one time
grid) -> :func:`deviation` -> :func:`pair_metrics` (:class:`PairMetrics`);
one run -> :func:`steady_state`; a run in both contact modes ->
:func:`contact_split` (:class:`ModeSplit`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from legbench import kinematics
from legbench.exceptions import ResultsError
from legbench.model import load_params
from legbench.results import Run, RunResult
from legbench.signals import LABELS, SIGNALS, SLICE

__all__ = [
    "COND_MAX",
    "LAG_MODES",
    "PEAK_FLOOR",
    "T_EPS",
    "LagEstimate",
    "ModeSplit",
    "PairMetrics",
    "SteadyState",
    "align",
    "check_lag_mode",
    "contact_split",
    "deviation",
    "estimate_lag",
    "max_abs",
    "mean",
    "pair_metrics",
    "peak_pct",
    "reference_peak",
    "rms",
    "signal_errors",
    "steady_state",
    "wrap_mask",
    "wrapped",
]

#: Reference peaks at or below this are zero: the simulation error % is undefined (NaN) [signal unit].
PEAK_FLOOR = 1e-12
#: Two time stamps closer than this are the same tick [s].
T_EPS = 1e-9
#: How a constant time lag is treated: not estimated, estimated and recorded, or estimated and removed.
LAG_MODES = ("off", "report", "remove")
#: Jacobians with a larger condition number are treated as singular in the analytic check.
COND_MAX = 1e8
#: A steady foot whose point of contact moves slower than this has no direction of slide [m/s]
#: (MuJoCo's matched foot: 1e-17 m/s; the slowest that slides, DART's, 2e-8 m/s).
SLIDE_FLOOR = 1e-9
#: A steady foot carrying less friction than this has no friction direction to compare its slide with [N] (a
#: round-off 1e-13 N gave a cosine of 0.9955).
FRICTION_FLOOR = 1e-6


# --------------------------------------------------------------------------- #
# Results


@dataclass(frozen=True)
class LagEstimate:
    """A constant time lag found by cross-correlation.

    Attributes:
        seconds: lag L [s]; L > 0 means the backend is late, x_a(t) ~ x_ref(t - L).
        samples: the same in samples of ``dt`` (sub-sample by parabolic interpolation).
        dt: grid spacing of the correlation [s].
        correlation: normalised cross-correlation at the peak, in [-1, 1].
        signals: the signals correlated.
        note: why no lag was identified (seconds and samples NaN) or why it was not removed; "" otherwise.
    """

    seconds: float
    samples: float
    dt: float
    correlation: float
    signals: tuple[str, ...]
    note: str = ""


@dataclass(frozen=True, eq=False)
class PairMetrics:
    """Deviation of one backend from a reference, per column of :data:`LABELS`.

    Metric arrays have shape (12,) and are computed over ``t >= skip``, each component over
    its samples that are not NaN (an imported log's missing ones); NaN where a signal is
    missing (no such sample) or the window is empty.

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
        held: per column, True where both runs hold the same constant value at every sample from ``skip`` on
            (a torque at its limit throughout): a deviation of 0 there is the clamp's, not the engines'.
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
    held: np.ndarray = field(default_factory=lambda: np.zeros(len(LABELS), bool))


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
            -(J_poc(q)^T)^-1 (tau - G(q)), J_poc the Jacobian of the point the force acted at: the true point
            of contact, raised by ``lift`` of the penetration where the backend declares its contact there [N].
        analytic_centre: the same with the foot centre's Jacobian J_E; only for runs
            whose contact law takes the poc at the sphere centre, else None [N].
        cond: condition number of J_poc at the mean state (inf if singular; NaN if the window has
            no finite q or tau, as in a log without torques: no check possible).
        qd_max: the largest |qd| of any joint over the window [rad/s] (NaN without a finite qd): the check
            holds only at rest, where it is near 0.
        lift: where the backend's force acted, as the check took it: that fraction of the penetration above the
            sphere's lowest point (:func:`~legbench.backends.base.contact_point`; 0: the true poc, and 0 where
            the foot is out of the ground at the window's mean q).
        poc: the backend's point of contact, ``"true"`` or ``"centre"`` (a law taking the poc at the sphere
            centre): :attr:`residual` is against the analytic force at that point.
        analytic_lowest: the spec's check, with the Jacobian of the sphere's lowest point, where the force acted
            above it (``lift`` > 0), else None [N]: :attr:`lift_compensation` is the lever between the two.
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
    qd_max: float = math.nan
    lift: float = 0.0
    poc: str = "true"
    analytic_lowest: np.ndarray | None = None

    @property
    def residual(self) -> np.ndarray:
        """Measured minus analytic ground force at the backend's point of contact [N]: with J_E for a law taking
        the poc at the sphere centre (its force acts there: 0.89 N of Fn off with J_poc), else J_poc."""
        if self.poc == "centre" and self.analytic_centre is not None:
            return self.force - self.analytic_centre
        return self.force - self.analytic_poc

    @property
    def poc_compensation(self) -> np.ndarray | None:
        """Analytic force with J_poc minus with J_E [N] (None unless the run's poc is the centre)."""
        return None if self.analytic_centre is None else self.analytic_poc - self.analytic_centre

    @property
    def slide_cosine(self) -> float:
        """Cosine between the mean horizontal velocity of the point where the force acts (J(q) qd at the window's
        mean q and qd) and the mean friction force (Fx, Fy) on the foot [1]: -1 for a foot creeping against its
        friction, as the law's does; towards +1 for one moving along it (a solver's drift, not friction). NaN
        where the point moves slower than :data:`SLIDE_FLOOR`, carries less friction than :data:`FRICTION_FLOOR`
        (an airborne foot none), or q or qd is not finite."""
        if not (np.isfinite(self.q).all() and np.isfinite(self.qd).all() and np.isfinite(self.force[:2]).all()):
            return math.nan
        v = (kinematics.jacobian_at(self.q, self.poc, self.lift) @ self.qd)[:2]
        speed, friction = float(np.linalg.norm(v)), float(np.linalg.norm(self.force[:2]))
        if not speed > SLIDE_FLOOR or not friction > FRICTION_FLOOR:
            return math.nan
        return float(v @ self.force[:2]) / (speed * friction)

    @property
    def lift_compensation(self) -> np.ndarray | None:
        """Analytic force at the backend's lifted point minus at the sphere's lowest point [N]: what the lever
        between where its force acts and the spec's true poc accounts for (None where ``lift`` is 0)."""
        return None if self.analytic_lowest is None else self.analytic_poc - self.analytic_lowest


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


# --------------------------------------------------------------------------- #
# Alignment


def _same_grid(t1: np.ndarray, t2: np.ndarray) -> bool:
    return len(t1) == len(t2) and bool(np.all(np.abs(t1 - t2) <= T_EPS))


def _resample(t: np.ndarray, x: np.ndarray, grid: np.ndarray, wrap: np.ndarray | None = None) -> np.ndarray:
    """Linear interpolation of each column of x (N, k) onto ``grid`` (inside [t0, tN]).

    The ``wrap`` columns (angles of continuous joints) are unwrapped first (their finite samples), also where
    ``t`` is already ``grid``, so a log that wraps the hip to [-pi, pi) is neither interpolated nor correlated
    across the jump; :func:`deviation` wraps their differences again, so wrapped and unwrapped logs agree.
    A log without a jump over pi comes back unchanged, to the bit.
    """
    if wrap is not None:
        x = _unwrap_columns(x, np.asarray(wrap, dtype=bool))
    if _same_grid(t, grid):
        return x
    g = np.clip(grid, t[0], t[-1])
    return np.column_stack([np.interp(g, t, x[:, j]) for j in range(x.shape[1])])


def _unwrap_finite(c: np.ndarray) -> np.ndarray:
    """``np.unwrap`` of the finite samples of an angle column [rad]; a missing sample (NaN) stays missing and
    the unwrapping goes on across it (unwrapped whole, one NaN would make every later sample NaN)."""
    ok = np.isfinite(c)
    if ok.all():
        return np.unwrap(c)
    out = c.copy()
    out[ok] = np.unwrap(c[ok])
    return out


def _common_grid(ref_t: np.ndarray, *spans: np.ndarray, source: str = "") -> np.ndarray:
    lo = max([ref_t[0], *(s[0] for s in spans)])
    hi = min([ref_t[-1], *(s[-1] for s in spans)])
    grid = ref_t[(ref_t >= lo - T_EPS) & (ref_t <= hi + T_EPS)]
    if len(grid) < 2:
        spans_text = ", ".join(f"[{x[0]:.6g}, {x[-1]:.6g}] s" for x in spans)
        raise ResultsError(source, f"time spans do not overlap by two ticks: the reference's [{ref_t[0]:.6g}, "
                                   f"{ref_t[-1]:.6g}] s and {spans_text}")  # fmt: skip
    return grid


def align(
    a: RunResult, ref: RunResult, shift: float = 0.0, wrap: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Put two traces on one time grid.

    The grid is the reference's ticks inside the common span; ``a`` is linearly
    interpolated onto it (no interpolation when both share the grid, as engine
    runs do). A lag ``shift`` [s] is removed from ``a`` first (its time stamps
    become t - shift). ``wrap``: the columns that are angles on a circle, unwrapped
    before interpolating (default: :func:`wrap_mask`).

    Returns:
        (t, x_a, x_ref): grid (M,) [s] and the two (M, 12) data blocks; the reference's ``wrap`` columns
        unwrapped too, so its peak (the percentages' denominator) is the same for a wrapped and an unwrapped log.

    Raises:
        ResultsError: the two spans do not overlap by two reference ticks.
    """
    ta = a.t - shift
    grid = _common_grid(ref.t, ta, source=a.source or a.backend)
    w = wrap_mask() if wrap is None else np.asarray(wrap, dtype=bool)
    xr = _unwrap_columns(ref.data, w)
    xr = xr if len(grid) == len(ref.t) else xr[np.searchsorted(ref.t, grid[0] - T_EPS) :][: len(grid)]
    return grid, _resample(ta, a.data, grid, w), xr


def _uniform_pair(a: RunResult, ref: RunResult, cols: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Both traces on one uniform grid over the common span (for correlation).

    The angles of continuous joints (the hip) are unwrapped on every path, also where a trace is already on
    the grid and is not interpolated: a log that wraps the hip to [-pi, pi) at the reference's rate would
    otherwise be correlated across its 2 pi jumps.
    """
    w = wrap_mask()[cols]
    if _same_grid(a.t, ref.t) and np.allclose(np.diff(ref.t), ref.t[1] - ref.t[0], rtol=1e-6, atol=T_EPS):
        grid = ref.t
    else:
        dt = min(float(np.median(np.diff(a.t))), float(np.median(np.diff(ref.t))))
        lo, hi = max(a.t[0], ref.t[0]), min(a.t[-1], ref.t[-1])
        if hi - lo < 2 * dt:
            raise ResultsError(a.source or a.backend, f"time spans of {a.backend} and {ref.backend} do not overlap")
        grid = lo + dt * np.arange(int(math.floor((hi - lo) / dt + 1e-9)) + 1)
    return grid, _resample(a.t, a.data[:, cols], grid, w), _resample(ref.t, ref.data[:, cols], grid, w)


def _unwrap_columns(x: np.ndarray, wrap: np.ndarray) -> np.ndarray:
    """x (N, k) with its ``wrap`` columns unwrapped (:func:`_unwrap_finite`); x itself when none is."""
    if not wrap.any():
        return x
    out = np.array(x, dtype=float, copy=True)
    for j in np.flatnonzero(wrap):
        out[:, j] = _unwrap_finite(out[:, j])
    return out


def _columns(signals: Sequence[str]) -> np.ndarray:
    """The data columns of ``signals``, in order (:data:`LABELS`)."""
    return np.concatenate([np.arange(len(LABELS))[SLICE[s]] for s in signals])


def _moving(x: np.ndarray, signals: Sequence[str]) -> np.ndarray:
    """Per column of ``x`` (the components of ``signals``, in order): True where it moves, its span above 0 and
    above 1e-9 of the largest span of its signal's components (round-off on a joint at rest does not)."""
    with np.errstate(invalid="ignore"):
        span = np.ptp(x, axis=0) if len(x) else np.zeros(x.shape[1])
    out = np.zeros(len(span), dtype=bool)
    start = 0
    for s in signals:
        n = SLICE[s].stop - SLICE[s].start
        part = span[start : start + n]
        out[start : start + n] = (part > 0) & (part > 1e-9 * np.nanmax(np.append(part, 0.0)))
        start += n
    return out


def estimate_lag(
    a: RunResult, ref: RunResult, max_lag: float = 0.1, signals: Sequence[str] = ("q",), skip: float = 0.0
) -> LagEstimate:
    """Constant time lag of ``a`` behind ``ref`` by cross-correlation.

    Both traces are put on one uniform grid (the finer of the two median steps)
    over their common span from ``skip`` [s] on (the samples the deviation metrics
    measure). For each candidate lag k within +-``max_lag``, the Pearson
    correlation of x_a[n + k] with x_ref[n] is taken over the samples that
    overlap (so a longer overlap is not favoured, unlike the plain
    cross-correlation sum, which biases slow signals towards zero lag); the
    per-column correlations are averaged, the best k is refined to a sub-sample
    by a parabola through the peak and its neighbours. Sums over the overlap come
    from prefix sums and one FFT per column, so the cost is O(M log M).
    Constant or missing columns are left out, and so is a component that moves
    less than 1e-9 of its signal's largest (round-off on a joint at rest, whose
    correlation is noise). No lag is identified (NaN, with a
    note) where the peak is at the search limit or the correlation is flat over
    the window (the peak less than 1e-3 above either end: slow ramps or creep
    correlate at any lag, and a side that barely falls does not bound the lag).

    Args:
        a: the trace that may lag.
        ref: the reference trace.
        max_lag: largest lag searched, either sign [s]; at most half the common span is searched.
        signals: signals correlated (any of :data:`SIGNALS`).
        skip: samples before this time are left out [s], as the deviation metrics leave them out.

    Returns:
        The lag; 0 with correlation NaN when no column varies; NaN with a note when none is identified.
    """
    cols = _columns(signals)
    grid, xa, xr = _uniform_pair(a, ref, cols)
    dt = float(grid[1] - grid[0])
    if skip > grid[0]:
        sel = grid >= skip - T_EPS
        grid, xa, xr = grid[sel], xa[sel], xr[sel]
        if len(grid) < 3:  # nothing left to correlate after skip
            return LagEstimate(0.0, 0.0, dt, math.nan, tuple(signals))
    # a component that moves less than 1e-9 of its signal's largest (round-off on a joint at rest) is noise whose
    # correlation would weigh as much as a swinging joint's
    keep = np.isfinite(xa).all(axis=0) & np.isfinite(xr).all(axis=0) & _moving(xr, signals) & _moving(xa, signals)
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
    if i in (0, len(rho) - 1):
        return LagEstimate(math.nan, math.nan, dt, float(rho[i]), tuple(signals),
                           f"the correlation peaks at the search limit ({kmax * dt * 1e3:g} ms): no lag "
                           "identified within it")  # fmt: skip
    if rho[i] - max(rho[0], rho[-1]) < 1e-3:
        return LagEstimate(math.nan, math.nan, dt, float(rho[i]), tuple(signals),
                           f"the correlation is flat over the search window (peak {rho[i]:.4f}, within 1e-3 of "
                           "its ends): no lag identified")  # fmt: skip
    k = float(lags[i])
    y0, y1, y2 = rho[i - 1], rho[i], rho[i + 1]  # inside the window: the limits were refused above
    den = y0 - 2 * y1 + y2
    if den < 0:
        k += 0.5 * (y0 - y2) / den
    return LagEstimate(k * dt, k, dt, float(rho[i]), tuple(signals))


# --------------------------------------------------------------------------- #
# Metrics


def wrapped(signal: str) -> np.ndarray:
    """True for the components of ``signal`` that are angles of continuous joints (the hip's q)."""
    if signal == "q":
        return np.array(load_params().continuous, dtype=bool)
    return np.zeros(3, dtype=bool)


def wrap_mask() -> np.ndarray:
    """True for the columns of :data:`~legbench.signals.LABELS` that are angles of continuous joints."""
    return np.concatenate([wrapped(s) for s in SIGNALS])


def deviation(xa: np.ndarray, xr: np.ndarray, wrap: np.ndarray | None = None) -> np.ndarray:
    """x_a - x_ref per column [signal units]; shortest angle on the ``wrap`` columns.

    Args:
        xa, xr: samples, shape (..., k): the 12 data columns, or the components of one signal.
        wrap: the columns that are angles on a circle (default: :func:`wrap_mask`, the 12 data columns).
    """
    d = np.asarray(xa, float) - np.asarray(xr, float)
    w = wrap_mask() if wrap is None else np.asarray(wrap, dtype=bool)
    if w.any():
        d[..., w] = np.mod(d[..., w] + np.pi, 2.0 * np.pi) - np.pi
    return d


def peak_pct(max_abs: np.ndarray, peak: np.ndarray) -> np.ndarray:
    """Simulation error % per column: 100 max |d| / max |x_ref|; NaN where the peak is <= :data:`PEAK_FLOOR`."""
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(peak > PEAK_FLOOR, 100.0 * max_abs / np.where(peak > PEAK_FLOOR, peak, 1.0), np.nan)


def mean(x: np.ndarray) -> np.ndarray:
    """Mean of each column over its samples that are not NaN [signal units]; NaN for a column with none.

    A NaN sample (an imported log's missing value: a ROS bag's force outside the wrench topic's
    span) is left out of its column only, not spread to the whole column. Without NaN, equal to
    the last bit to ``np.mean(x, axis=0)``.
    """
    x = np.asarray(x, float)
    ok = ~np.isnan(x)
    n = ok.sum(axis=0)
    total = np.where(ok, x, 0.0).sum(axis=0)
    return np.where(n > 0, total / np.maximum(n, 1), np.nan)


def rms(d: np.ndarray) -> np.ndarray:
    """Root mean square of each column over its samples that are not NaN [signal units]; NaN for a column with none."""
    if len(d) == 0:
        return np.full(d.shape[1], np.nan)
    return np.sqrt(mean(d * d))


def max_abs(d: np.ndarray) -> np.ndarray:
    """Largest absolute value of each column over its samples that are not NaN [signal units]; NaN for a column with
    none."""
    if len(d) == 0:
        return np.full(d.shape[1], np.nan)
    a = np.abs(d)
    nan = np.isnan(a)
    return np.where(nan.all(axis=0), np.nan, np.where(nan, -np.inf, a).max(axis=0))


def signal_errors(a: RunResult, ref: RunResult, signal: str, skip: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Largest deviation [signal unit] and simulation error % per component of one signal (hip wrapped).

    Over the ticks both runs logged (the shorter's span) with t >= ``skip`` [s]; the two runs must
    share their tick times there (runs of one scenario do). NaN when there is no such tick or the
    grids differ.

    Returns:
        (max |x_a - x_ref|, 100 max |x_a - x_ref| / max |x_ref|), each shape (3,).
    """
    n = min(len(a.t), len(ref.t))
    t = ref.t[:n]
    keep = t >= skip - T_EPS
    if n == 0 or not np.array_equal(a.t[:n], t) or not keep.any():
        return np.full(3, np.nan), np.full(3, np.nan)
    xa, xr = a.signal(signal)[:n], ref.signal(signal)[:n]
    xr = _unwrap_columns(xr, wrapped(signal))[keep]  # the peak of a wrapped log's hip is the unwrapped one's
    d = max_abs(deviation(xa[keep], xr, wrapped(signal)))
    return d, peak_pct(d, max_abs(xr))


def check_lag_mode(lag: str) -> None:
    """Raise ValueError unless ``lag`` is one of :data:`LAG_MODES`."""
    if lag not in LAG_MODES:
        raise ValueError(f"lag must be 'off', 'report' or 'remove', not {lag!r}")


def reference_peak(ref: RunResult, skip: float = 0.0, wrap: np.ndarray | None = None) -> np.ndarray:
    """The scenario reference's peak max_t |x_ref| over its samples at t >= ``skip`` [signal units], the hip
    unwrapped (as :func:`align` gives it): the one denominator of ``sim_error_pct`` for every pair of a comparison
    (``pair_metrics(..., peak=)``), whatever span each pair compares."""
    w = wrap_mask() if wrap is None else np.asarray(wrap, dtype=bool)
    return max_abs(_unwrap_columns(ref.data, w)[ref.t >= skip - T_EPS])


def pair_metrics(
    a: RunResult,
    ref: RunResult,
    skip: float = 0.0,
    lag: str = "off",
    max_lag: float = 0.1,
    lag_signals: Sequence[str] = ("q",),
    wrap: np.ndarray | None = None,
    peak: np.ndarray | None = None,
) -> PairMetrics:
    """Deviation metrics of ``a`` against ``ref`` (docs/metrics.md).

    Args:
        a: the backend measured.
        ref: the reference.
        skip: only samples with t >= skip are measured [s].
        lag: ``"off"``, ``"report"`` (estimate and record the lag) or ``"remove"``
            (estimate it and take it out of ``a`` before measuring).
        max_lag: largest lag searched [s].
        lag_signals: signals the lag is estimated from.
        wrap: columns compared as angles on a circle (default: the hip angle).
        peak: the denominator of ``sim_error_pct`` per column [signal units]: the spec's max_t |x_ref| of the
            scenario's reference backend over the run (:func:`reference_peak`); None: ``ref``'s own peak over the
            compared ticks.

    Returns:
        The metrics; see :class:`PairMetrics`.
    """
    check_lag_mode(lag)
    est = estimate_lag(a, ref, max_lag, lag_signals, skip) if lag != "off" else None
    shift = est.seconds if (est is not None and lag == "remove" and math.isfinite(est.seconds)) else 0.0
    t, xa, xr = align(a, ref, shift, wrap)
    d = deviation(xa, xr, wrap)
    if shift and est is not None:  # removed only where it lowers the RMS deviation of every component it came from
        t0, xa0, xr0 = align(a, ref, 0.0, wrap)
        d0 = deviation(xa0, xr0, wrap)
        cols = _columns(lag_signals)
        sel0 = t0 >= skip - T_EPS
        after, before = rms(d[t >= skip - T_EPS][:, cols]), rms(d0[sel0][:, cols])
        moving = _moving(xr0[sel0][:, cols], lag_signals) & np.isfinite(before) & np.isfinite(after)
        if not (np.all(after[moving] <= before[moving]) and np.any(after[moving] < before[moving])):
            est = LagEstimate(est.seconds, est.samples, est.dt, est.correlation, est.signals,
                              "not removed: shifting by it did not lower the RMS deviation of every component it "
                              "was estimated from")  # fmt: skip
            shift, t, xa, xr, d = 0.0, t0, xa0, xr0, d0
    sel = t >= skip - T_EPS
    ds, rs, ts = d[sel], xr[sel], t[sel]
    largest = max_abs(ds)
    ref_peak = max_abs(rs) if peak is None else np.asarray(peak, dtype=float)
    if len(ds):
        t_max = ts[np.argmax(np.nan_to_num(np.abs(ds), nan=-1.0), axis=0)]
        t_max = np.where(np.isfinite(largest), t_max, np.nan)
    else:
        t_max = np.full(len(LABELS), np.nan)
    return PairMetrics(
        backend=a.backend,
        reference=ref.backend,
        t=t,
        deviation=d,
        sim_error_pct=peak_pct(largest, ref_peak),
        rms=rms(ds),
        max_abs=largest,
        t_max_abs=t_max,
        ref_peak=ref_peak,
        skip=skip,
        lag=est,
        lag_removed=shift,
        held=held(rs, ds),
    )


def held(ref: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Per column of a measured window (the reference's values ``ref`` and the deviation ``d``, (M, k)): True
    where the reference is one constant value above :data:`PEAK_FLOOR` at every sample (no NaN) and the other run
    equals it at every sample, as for a torque both runs hold at its limit throughout; False for an empty window
    and for a component that is 0 throughout (a ground force in free space: no percentage at all)."""
    if not len(ref):
        return np.zeros(ref.shape[1], bool)
    with np.errstate(invalid="ignore"):
        constant = np.all(ref == ref[0], axis=0) & np.isfinite(ref[0]) & (np.abs(ref[0]) > PEAK_FLOOR)
    return constant & np.all(d == 0.0, axis=0)


def steady_state(
    trace: RunResult,
    window: float,
    poc: str = "true",
    gravity: float | None = None,
    end: float | None = None,
    lift: float = 0.0,
) -> SteadyState:
    """Means over the final ``window`` [s] of ``trace``, and the analytic force check.

    The window is the closed interval [t_end - window, t_end] (both ends included: 501 ticks for
    0.5 s at 1 kHz); each column's mean is over its samples there that are not NaN (:func:`mean`). ``end``
    [s]: t_end where it is not the trace's own last time (an imported log measured against a run: the run's
    end); a trace with no sample in that window has every mean NaN (no steady state to report).

    The check solves J_poc(q)^T h = tau - G(q) at the window's mean q and tau
    (valid when the leg is static: qd ~ 0 and no acceleration) and reports the
    ground force on the foot, -h. ``poc`` and ``lift``: where the backend's force acted
    (:func:`~legbench.backends.base.contact_point`): J_poc is the Jacobian of the sphere's lowest point,
    raised by ``lift`` of the penetration where an engine's own contact acts above it
    (:func:`~legbench.kinematics.jacobian_at`), and the check is also done at the lowest point, the spec's
    J_poc, where the force acted above it; with ``poc == "centre"`` the check is also done with
    J_E, the foot centre's Jacobian, which is what a contact law taking the poc
    at the sphere centre applies. G(q) is for the run's ``gravity`` [m/s^2] along
    -z_W (None: the leg parameter file's; G is linear in it).
    """
    g_file = load_params().gravity
    g_scale = 1.0 if gravity is None or gravity == g_file else gravity / g_file
    t_end = float(trace.t[-1]) if end is None else float(end)
    sel = (trace.t >= t_end - window - T_EPS) & (trace.t <= t_end + T_EPS)
    if not sel.any():
        nan3 = np.full(3, np.nan)
        return SteadyState(trace.backend, t_end - window, t_end, nan3, nan3, nan3, nan3, nan3, None, math.nan,
                           math.nan, lift, poc)  # fmt: skip
    avg = mean(trace.data[sel])
    q, qd, tau, force = (avg[SLICE[s]] for s in SIGNALS)

    def ground_force(point: str, raised: float = 0.0) -> tuple[np.ndarray, float]:
        if not np.isfinite(q).all() or not np.isfinite(tau).all():
            return np.full(3, np.nan), math.nan
        J = kinematics.jacobian_at(q, point, raised)
        cond = float(np.linalg.cond(J))
        if not cond < COND_MAX:
            return np.full(3, np.nan), cond
        G = kinematics.gravity(q) if g_scale == 1.0 else g_scale * kinematics.gravity(q)
        h = np.linalg.solve(J.T, tau - G)
        return -h, cond

    # the lifted point is the lowest point where the foot is out of the ground (kinematics.contact_depth)
    in_ground = bool(np.isfinite(q).all() and float(kinematics.fk(q)[2]) < load_params().geometry.R_foot)
    f_poc, cond = ground_force("true", lift)
    f_centre = ground_force("centre")[0] if poc == "centre" else None
    f_lowest = ground_force("true")[0] if in_ground and lift > 0.0 else None  # the spec's J_poc, for the lever
    speeds = max_abs(trace.data[sel][:, SLICE["qd"]])
    qd_max = float(np.nanmax(speeds)) if np.isfinite(speeds).any() else math.nan
    return SteadyState(
        trace.backend, float(trace.t[sel][0]), float(trace.t[sel][-1]), q, qd, tau, force, f_poc, f_centre, cond,
        qd_max, lift if in_ground else 0.0, poc, f_lowest,
    )  # fmt: skip


def contact_split(
    native: Run, refmode: Run, reference: str | None = None, shifts: Mapping[str, float] | None = None
) -> tuple[ModeSplit, ...]:
    """Split each backend's native-mode deviation into contact, integration and drift parts.

    See :class:`ModeSplit`. Backends must be ok in both runs; all four traces
    are put on the native reference's ticks inside their common span.

    Args:
        native: the run in native contact mode.
        refmode: the same scenario in reference contact mode.
        reference: reference backend (default: the native run's).
        shifts: backend -> the lag [s] removed from its native trace before measuring (the pair's
            ``lag_removed``, with ``lag="remove"``): its native trace a_n is shifted by it, as
            :func:`pair_metrics` shifts it, so the parts still add up to the deviation reported
            (``native`` equals the pair's) and the lag, estimated on the native pair, stays with a_n.
    """
    ref = reference or native.reference
    if ref not in native.traces or ref not in refmode.traces:
        return ()
    rn, rr = native.traces[ref], refmode.traces[ref]
    wrap = wrap_mask()
    out = []
    for name, an in native.traces.items():
        if name == ref or name not in refmode.traces:
            continue
        ar = refmode.traces[name]
        shift = float((shifts or {}).get(name, 0.0))
        tan = an.t - shift if shift else an.t
        grid = _common_grid(rn.t, tan, ar.t, rr.t, source=str(native.path))
        xrn, xan = _resample(rn.t, rn.data, grid, wrap), _resample(tan, an.data, grid, wrap)
        xar, xrr = _resample(ar.t, ar.data, grid, wrap), _resample(rr.t, rr.data, grid, wrap)
        sel = grid >= native.skip - T_EPS
        parts = {
            "native": deviation(xan, xrn, wrap)[sel],
            "contact": deviation(xan, xar, wrap)[sel],
            "integration": deviation(xar, xrr, wrap)[sel],
            "drift": deviation(xrr, xrn, wrap)[sel],
        }
        peak = max_abs(xrn[sel])
        kw: dict[str, Any] = {}
        for part, d in parts.items():
            kw[f"{part}_rms"] = rms(d)
            kw[f"{part}_pct"] = peak_pct(max_abs(d), peak)
        out.append(ModeSplit(backend=name, reference=ref, **kw))
    return tuple(out)
