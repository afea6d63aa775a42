"""legbench.metrics on hand-made traces: each figure against its documented definition (docs/metrics.md)."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from legbench import metrics, results, signals

REQUIRED = ["t", "q1", "q2", "q3"]
I_Q2 = signals.LABELS.index("q2")


def _hip_trace(name: str, t: np.ndarray, lag: float, wrap: bool) -> results.RunResult:
    """q only, late by ``lag`` [s]; the hip (q2, continuous) swings 1.8..3.4 rad, through pi, and is logged
    wrapped to [-pi, pi) when ``wrap``."""
    s = t - lag
    q2 = 2.6 + 0.8 * np.sin(2 * np.pi * s)
    if wrap:
        q2 = np.mod(q2 + np.pi, 2 * np.pi) - np.pi
    df = pd.DataFrame({"t": t, "q1": 0.1 * np.sin(np.pi * s), "q2": q2, "q3": -1.2 + 0.2 * np.cos(3 * np.pi * s)})
    return results.result_from_frame(df, name, required=REQUIRED)


@pytest.mark.parametrize("wrapped", ["backend", "reference"])
def test_lag_of_a_hip_log_wrapped_at_the_reference_rate_is_the_unwrapped_one(wrapped: str) -> None:
    """A 1 kHz log late by 20 ms whose hip is wrapped to [-pi, pi) on the reference's own ticks: the lag is the
    same as from the unwrapped log (20 ms within 1e-3 sample; its 2e-4-sample parabola error) at correlation
    1 (within 1e-9). The grid-sharing path used the wrapped column as it is, so the 2 pi jumps entered the
    correlation: 19.66 ms at correlation 0.45, and after removing that lag 1.2 mrad of RMS hip deviation
    was left instead of 5e-7 rad."""
    t = np.arange(0.0, 2.0 + 1e-12, 1e-3)
    a = _hip_trace("a", t, 0.02, wrap=wrapped == "backend")
    ref = _hip_trace("ref", t, 0.0, wrap=wrapped == "reference")
    plain = metrics.estimate_lag(_hip_trace("a", t, 0.02, wrap=False), _hip_trace("ref", t, 0.0, wrap=False))
    est = metrics.estimate_lag(a, ref)
    assert abs(est.samples - 20.0) < 1e-3
    assert est.seconds == plain.seconds
    assert est.correlation == pytest.approx(1.0, abs=1e-9)
    p = metrics.pair_metrics(a, ref, lag="remove")
    assert p.rms[I_Q2] < 1e-6


def test_lag_of_a_wrapped_hip_on_a_grid_equal_to_the_correlation_grid_is_unwrapped() -> None:
    """The other path: a 250 Hz log (from t = 0) against a 1 kHz reference wrapped on its ticks; the
    correlation grid (1 ms from 0) is the reference's own, so the reference is not interpolated and was used
    wrapped. Lag 12 ms within 1e-3 sample, correlation 1 within 1e-6 (linear interpolation of the log)."""
    ref = _hip_trace("ref", np.arange(0.0, 2.0 + 1e-12, 1e-3), 0.0, wrap=True)
    a = _hip_trace("a", np.arange(0.0, 2.0 + 1e-12, 4e-3), 0.012, wrap=False)
    est = metrics.estimate_lag(a, ref)
    assert abs(est.samples - 12.0) < 1e-2
    assert est.correlation == pytest.approx(1.0, abs=1e-6)


def test_pair_metrics_against_an_independent_computation() -> None:
    """sim_error_pct, rms, max_abs, t_max_abs and ref_peak of two 1 kHz traces with the hip one turn apart
    plus a bump, with skip = 0.3 s, recomputed here with numpy (hip difference wrapped by hand): equal to
    1e-12 relative, times exactly."""
    t = np.arange(0.0, 1.0 + 1e-12, 1e-3)
    ref = _hip_trace("ref", t, 0.0, wrap=False)
    a0 = _hip_trace("a", t, 0.004, wrap=False)
    df = pd.DataFrame({"t": t, "q1": a0.q[:, 0], "q2": a0.q[:, 1] + 2 * np.pi, "q3": a0.q[:, 2] + 0.01 * (t > 0.6)})
    a = results.result_from_frame(df, "a", required=REQUIRED)
    p = metrics.pair_metrics(a, ref, skip=0.3)
    sel = t >= 0.3
    d = a0.q[sel] - ref.q[sel]
    d[:, 2] += 0.01 * (t[sel] > 0.6)
    peak = np.max(np.abs(ref.q[sel]), axis=0)
    np.testing.assert_allclose(p.max_abs[:3], np.max(np.abs(d), axis=0), rtol=1e-12)
    np.testing.assert_allclose(p.rms[:3], np.sqrt(np.mean(d**2, axis=0)), rtol=1e-12)
    np.testing.assert_allclose(p.sim_error_pct[:3], 100 * np.max(np.abs(d), axis=0) / peak, rtol=1e-12)
    np.testing.assert_array_equal(p.ref_peak[:3], peak)
    np.testing.assert_array_equal(p.t_max_abs[:3], t[sel][np.argmax(np.abs(d), axis=0)])
    assert np.isnan(p.sim_error_pct[3:]).all()  # no qd, tau, force in these traces: null, not 0


def test_lag_is_estimated_over_the_samples_the_metrics_measure() -> None:
    """skip excludes a log's start from the deviations; the lag was estimated over the whole span all the same. A
    log late by 20 ms whose first 0.5 s hold a start-up glitch (the leg still at its parking pose): with skip 0.5 s
    the lag is 20 ms within 1e-3 sample (measured 1.2e-4), correlation 1 within 1e-6; over the whole span it was
    23.05 ms at correlation 0.41. pair_metrics passes its skip."""
    t = np.arange(0.0, 3.0 + 1e-12, 1e-3)
    a, ref = _hip_trace("a", t, 0.02, wrap=False), _hip_trace("ref", t, 0.0, wrap=False)
    start = t < 0.5
    a.q[start] = (0.3, 1.0, -0.3)  # parked, then the motion
    whole = metrics.estimate_lag(a, ref)
    est = metrics.estimate_lag(a, ref, skip=0.5)
    assert abs(whole.samples - 20.0) > 1.0
    assert abs(est.samples - 20.0) < 1e-3 and est.correlation == pytest.approx(1.0, abs=1e-6)
    assert metrics.pair_metrics(a, ref, skip=0.5, lag="report").lag == est
    assert np.isnan(metrics.estimate_lag(a, ref, skip=3.0).correlation)  # one sample left: nothing to correlate


def test_signal_errors_largest_deviation_and_its_percentage_of_the_reference_peak() -> None:
    """signal_errors (the sweeps' figure): per component max |a - ref| and 100 max |a - ref| / max |ref| over
    the ticks both logged with t >= skip, the hip's one-turn offset wrapped away: q1 off by 0.01 rad only before
    skip (0), q2 one turn plus 0.02 rad, q3 0.03 rad after 0.6 s; equal to the hand computation to 1e-12
    relative. A shorter log is measured over its own span; grids that differ, or no tick after skip: NaN."""
    t = np.arange(0.0, 1.0 + 1e-12, 1e-3)
    ref = _hip_trace("ref", t, 0.0, wrap=False)
    q = ref.q.copy()
    q[:, 0] += 0.01 * (t < 0.3)
    q[:, 1] += 2 * np.pi + 0.02
    q[:, 2] += 0.03 * (t > 0.6)
    df = pd.DataFrame({"t": t, "q1": q[:, 0], "q2": q[:, 1], "q3": q[:, 2]})
    a = results.result_from_frame(df, "a", required=REQUIRED)
    d, pct = metrics.signal_errors(a, ref, "q", skip=0.3)
    np.testing.assert_allclose(d, [0.0, 0.02, 0.03], rtol=1e-12, atol=1e-12)
    peak = np.max(np.abs(ref.q[t >= 0.3]), axis=0)
    np.testing.assert_allclose(pct, 100 * np.array([0.0, 0.02, 0.03]) / peak, rtol=1e-12, atol=1e-12)
    short = results.result_from_frame(df[t <= 0.5], "a", required=REQUIRED)  # ends before q3's step
    d, _ = metrics.signal_errors(short, ref, "q", skip=0.3)
    np.testing.assert_allclose(d, [0.0, 0.02, 0.0], rtol=1e-12, atol=1e-12)
    shifted = results.result_from_frame(df.assign(t=t + 1e-4), "a", required=REQUIRED)
    assert np.isnan(metrics.signal_errors(shifted, ref, "q")[0]).all()
    assert np.isnan(metrics.signal_errors(a, ref, "q", skip=2.0)[1]).all()


def test_held_marks_only_a_component_both_runs_hold_at_one_value() -> None:
    """``held``: constant in the reference and equal in the other run at every sample; a constant reference the
    other run leaves once, a varying pair that agrees exactly, a NaN reference, a component 0 throughout (a
    ground force in free space, which has no percentage) and an empty window are not."""
    ref = np.array([[-7.05, 1.0, 2.0, np.nan, 0.0], [-7.05, 1.0, 3.0, np.nan, 0.0], [-7.05, 1.0, 4.0, np.nan, 0.0]])
    d = np.zeros_like(ref)
    d[1, 1] = 1e-15  # the other run leaves the constant once
    assert metrics.held(ref, d).tolist() == [True, False, False, False, False]
    assert metrics.held(ref[:0], d[:0]).tolist() == [False] * 5


def test_a_wrapped_reference_hip_has_the_unwrapped_peak() -> None:
    """The hip swings 1.8..3.4 rad (through pi): its deviations are taken on the circle, but the percentage's
    denominator, max |x_ref|, was taken on the raw reference, 3.4 unwrapped against 3.14 wrapped (0.0294 against
    0.0318 % for the same 1e-3 rad). The reference's hip is unwrapped before its peak in pair_metrics and
    signal_errors: the figures of a wrapped and an unwrapped reference log are equal."""
    t = np.arange(0.0, 2.0 + 1e-12, 1e-3)
    a = _hip_trace("a", t, 0.0, wrap=False)
    a = dataclasses.replace(a, q=a.q + np.array([0.0, 1e-3, 0.0]))
    plain, wrapped = (metrics.pair_metrics(a, _hip_trace("ref", t, 0.0, wrap=w)) for w in (False, True))
    assert plain.ref_peak[I_Q2] == pytest.approx(3.4, rel=1e-6)
    assert wrapped.ref_peak[I_Q2] == plain.ref_peak[I_Q2]
    assert wrapped.sim_error_pct[I_Q2] == pytest.approx(plain.sim_error_pct[I_Q2], rel=1e-12)
    for w in (False, True):
        d, pct = metrics.signal_errors(a, _hip_trace("ref", t, 0.0, wrap=w), "q")
        assert pct[1] == pytest.approx(plain.sim_error_pct[I_Q2], rel=1e-12)


def _trace(name: str, t: np.ndarray, q: np.ndarray) -> results.RunResult:
    return results.result_from_frame(pd.DataFrame({"t": t, "q1": q[:, 0], "q2": q[:, 1], "q3": q[:, 2]}), name,
                                     required=REQUIRED)  # fmt: skip


def _swing(t: np.ndarray, lag: float) -> np.ndarray:
    """Three joints' slow swings [rad] at times t - lag [s]: the lag tests' signal."""
    s = t - lag
    return np.column_stack([0.1 * np.sin(np.pi * s), 2.6 + 0.8 * np.sin(2 * np.pi * s), np.cos(3 * np.pi * s)])


def test_a_lag_at_the_search_limit_or_on_a_flat_correlation_is_not_identified() -> None:
    """A 150 ms lag searched within 100 ms came back as 100 ms at correlation 0.88, and two slow ramps (which
    correlate at any lag) as the search limit at correlation 1: both now give no lag (NaN) with a note, and
    ``remove`` removes nothing. A 20 ms lag inside the window is still found (to 1e-3 sample), and so are 20.4 and
    20.7 ms, between samples (measured within 1.1e-4 sample; without the sub-sample step 0.4 and 0.3 sample off)."""
    t = np.arange(0.0, 2.0 + 1e-12, 1e-3)

    def swing(lag: float) -> np.ndarray:
        return _swing(t, lag)

    ref = _trace("ref", t, swing(0.0))
    far = metrics.estimate_lag(_trace("a", t, swing(0.15)), ref, max_lag=0.1)
    assert math.isnan(far.seconds) and "search limit" in far.note
    ramp = np.column_stack([0.1 * t, 0.2 * t, -0.3 * t])
    flat = metrics.estimate_lag(_trace("a", t, ramp + 1e-4), _trace("ref", t, ramp))
    assert math.isnan(flat.seconds) and flat.note
    p = metrics.pair_metrics(_trace("a", t, swing(0.15)), ref, lag="remove", max_lag=0.1)
    assert p.lag_removed == 0.0
    near = metrics.estimate_lag(_trace("a", t, swing(0.02)), ref)
    assert abs(near.samples - 20.0) < 1e-3 and near.note == ""
    for lag in (0.0204, 0.0207):  # between samples: the parabola through the peak's neighbours finds it
        between = metrics.estimate_lag(_trace("a", t, swing(lag)), ref)
        assert abs(between.samples - lag / 1e-3) < 1e-3, (lag, between.samples)


def test_at_most_half_the_common_span_is_searched_whatever_max_lag() -> None:
    """A 0.2 s trace at 1 kHz (201 samples) with max_lag 1 s: the search is capped at half the common span, 100
    samples (100 ms), as documented (docs/metrics.md). A 130 ms lag, beyond that half, peaks at the limit and is
    not identified (NaN), the note naming the 100 ms limit; a 50 ms lag within it is still found (to 1e-2 sample:
    the slow swing's parabola error, measured 6e-3), so the large max_lag itself does no harm."""
    t = np.arange(0.0, 0.2 + 1e-12, 1e-3)
    ref = _trace("ref", t, _swing(t, 0.0))
    beyond = metrics.estimate_lag(_trace("a", t, _swing(t, 0.13)), ref, max_lag=1.0)
    assert math.isnan(beyond.seconds) and math.isnan(beyond.samples)
    assert "search limit (100 ms)" in beyond.note, beyond.note
    within = metrics.estimate_lag(_trace("a", t, _swing(t, 0.05)), ref, max_lag=1.0)
    assert abs(within.samples - 50.0) < 1e-2 and within.note == ""


def _resting_q1(t: np.ndarray, lag: float, rng: np.random.Generator) -> np.ndarray:
    """q (N, 3) [rad]: q1 at rest but for 1e-17 rad of round-off (drawn from ``rng``), q2 and q3 swinging, late by
    ``lag`` [s]."""
    s = t - lag
    return np.column_stack([1e-17 * rng.standard_normal(len(t)), 2.6 + 0.8 * np.sin(2 * np.pi * s),
                            -1.2 + 0.2 * np.cos(3 * np.pi * s)])  # fmt: skip


def test_a_component_at_rest_does_not_steer_the_lag_and_a_lag_that_hurts_is_not_removed() -> None:
    """q1 at rest but for 1e-17 rad of round-off: its Pearson correlation is noise and weighed as much as a
    swinging joint's (a planted 20 ms lag came back as 5.3 ms). It is left out: 20 ms. And where shifting by the
    estimate makes any component's RMS deviation worse (the engines' spurious 12-76 ms lags on the effort task,
    which made q3 twelve times worse), the lag is reported but not removed."""
    t = np.arange(0.0, 2.0 + 1e-12, 1e-3)
    rng = np.random.default_rng(0)

    def legs(lag: float) -> np.ndarray:
        return _resting_q1(t, lag, rng)

    est = metrics.estimate_lag(_trace("a", t, legs(0.02)), _trace("ref", t, legs(0.0)))
    assert abs(est.samples - 20.0) < 1e-3
    base = legs(0.0)
    worse = base.copy()
    worse[:, 1] = 2.6 + 0.8 * np.sin(2 * np.pi * (t - 0.02))  # q2 late by 20 ms, q3 on time: a shift hurts q3
    p = metrics.pair_metrics(_trace("a", t, worse), _trace("ref", t, base), lag="remove")
    assert p.lag is not None and p.lag_removed == 0.0 and p.lag.note.startswith("not removed")


def _pressing(
    lift: float, depth: float = 0.005, v: tuple[float, float] = (0.0, 0.0)
) -> tuple[results.RunResult, np.ndarray]:
    """The leg with its foot ``depth`` [m] in the ground, the ground force F on the foot acting ``lift``
    of that depth above the sphere's lowest point: tau = G(q) - J_lift^T F; the joints move so that point moves
    at ``v`` [m/s] in W x, y (0 along z; at rest by default)."""
    from legbench import kinematics
    from legbench.model import load_params

    r_foot = load_params().geometry.R_foot
    q = kinematics.ik_nearest(np.array([0.1667, 0.0, r_foot - depth]), np.array([0.0, -1.0, -1.2]))
    F = np.array([4.0, -3.0, 50.0])  # ground force on the foot, in W [N]; 5 N of friction
    J = kinematics.jacobian_at(q, "true", lift)
    tau = kinematics.gravity(q) - J.T @ F
    qd = np.linalg.solve(J, [*v, 0.0])
    t = np.arange(0.0, 1.0 + 1e-12, 1e-3)
    row = dict(zip(["q1", "q2", "q3", "qd1", "qd2", "qd3", "tau1", "tau2", "tau3", "fx", "fy", "fz"],
                   [*q, *qd, *tau, *F], strict=True))  # fmt: skip
    df = pd.DataFrame({"t": t, **{k: np.full(t.size, v) for k, v in row.items()}})
    return results.result_from_frame(df, "a", required=REQUIRED), F


def test_a_force_acting_above_the_lowest_point_is_checked_there_and_at_the_spec_s_j_poc() -> None:
    """An engine whose force acts y/2 above the sphere's lowest point (MuJoCo's contact.lift 0.5), at rest 5 mm in
    the ground with 5 N of friction: the check at its point gives the force back (1e-9 N); the spec's check at the
    lowest point (``analytic_lowest``) is off by the lever, which ``lift_compensation`` gives exactly
    (analytic_poc - analytic_lowest, and more than 1e-3 N here). Where the force acts at the lowest point (lift 0),
    there is no second check, nor where the foot is out of the ground (the lifted point is the lowest point: the
    reported lift is 0)."""
    from legbench import kinematics

    trace, F = _pressing(0.5)
    s = metrics.steady_state(trace, 0.5, "true", lift=0.5)
    np.testing.assert_allclose(s.residual, 0.0, atol=1e-9)
    assert s.analytic_lowest is not None and s.lift_compensation is not None
    J_poc = kinematics.jacobian_at(s.q, "true")
    want = -np.linalg.solve(J_poc.T, s.tau - kinematics.gravity(s.q))
    np.testing.assert_allclose(s.analytic_lowest, want, atol=1e-9)
    np.testing.assert_array_equal(s.lift_compensation, s.analytic_poc - s.analytic_lowest)
    assert np.abs(s.force - s.analytic_lowest).max() > 1e-3  # [N]: the lever the spec's point does not see
    plain = metrics.steady_state(_pressing(0.0)[0], 0.5, "true")
    np.testing.assert_allclose(plain.residual, 0.0, atol=1e-9)
    assert plain.analytic_lowest is None and plain.lift_compensation is None
    airborne = metrics.steady_state(_pressing(0.0, depth=-0.01)[0], 0.5, "true", lift=0.5)  # the foot 10 mm up
    assert airborne.lift == 0.0 and airborne.analytic_lowest is None  # no penetration to lift the point into


def test_the_slide_cosine_is_the_direction_of_the_point_s_slide_against_the_friction_force() -> None:
    """The foot pressed 5 mm in with 5 N of friction (4, -3) N acting y/2 above its lowest point: its point
    moving at 1e-4 m/s against the friction gives -1, along it +1, across it 0 (each to 1e-9: the velocity is
    taken at the point the force acts, the lifted one); slower than SLIDE_FLOOR (5e-10 m/s), or with friction under
    FRICTION_FLOOR, no direction (NaN)."""
    f_t = np.array([4.0, -3.0]) / 5.0
    for v, want in ((-1e-4 * f_t, -1.0), (1e-4 * f_t, 1.0), (1e-4 * np.array([f_t[1], -f_t[0]]), 0.0)):
        s = metrics.steady_state(_pressing(0.5, v=(float(v[0]), float(v[1])))[0], 0.5, "true", lift=0.5)
        assert s.slide_cosine == pytest.approx(want, abs=1e-9)
    still = metrics.steady_state(_pressing(0.5, v=(-4e-10, 3e-10))[0], 0.5, "true", lift=0.5)
    assert math.isnan(still.slide_cosine) and metrics.SLIDE_FLOOR > 5e-10
    # a friction force of round-off (1e-13 N: it gave 0.9955) or none (the foot in the air): no direction either
    for friction in ((8e-14, -6e-14), (0.0, 0.0)):
        trace = _pressing(0.5, v=(1e-4, 0.0))[0]
        trace.data[:, 9:11] = np.array(friction)  # fx, fy of the log [N]
        assert math.isnan(metrics.steady_state(trace, 0.5, "true", lift=0.5).slide_cosine)


def test_the_flat_correlation_threshold_is_1e3_between_its_peak_and_the_window_ends() -> None:
    """Docstring: no lag where the correlation's peak is within 1e-3 of both window ends (slow motions correlate
    at any lag). Sines lagging 5 ms over a 2 s window: with a 16 s period the peak stands more than 1e-3 above
    the ends and 5 ms is found (to 1e-3 ms); with a 40 s period it does not, and no lag is identified (a mutation
    audit: a threshold of 1e-6 passed every test)."""
    t = np.arange(0.0, 2.0 + 1e-12, 1e-3)

    def slow(period: float, lag: float) -> np.ndarray:
        return np.column_stack([np.sin(2 * np.pi * (t - lag) / period + p) for p in (0.0, 1.0, 2.0)])

    found = metrics.estimate_lag(_trace("a", t, slow(16.0, 0.005)), _trace("ref", t, slow(16.0, 0.0)))
    assert abs(found.seconds - 0.005) < 1e-6 and found.note == ""
    flat = metrics.estimate_lag(_trace("a", t, slow(40.0, 0.005)), _trace("ref", t, slow(40.0, 0.0)))
    assert math.isnan(flat.seconds) and "flat over the search window" in flat.note


def _run(traces: dict[str, results.RunResult], skip: float, mode: str) -> results.Run:
    """A run directory's contents in memory: reference backend ``ref``, the metrics' window from ``skip`` [s]."""
    return results.Run(path=Path("fake"), meta={}, name="fake", label="fake", contact_mode=mode, poc="true",
                       reference="ref", skip=skip, steady_window=0.5, duration=1.0, events=(), backends={},
                       traces=traces)  # fmt: skip


def test_the_contact_split_measures_from_skip_as_the_deviation_it_splits() -> None:
    """ModeSplit works over t >= skip. With skip = 0.5 s, backend a's native trace is 1 rad off every joint
    before skip and 0.03 rad after; its reference-mode trace and the reference backend (in both modes) follow the
    swing exactly. Over the measured window the native and contact parts are 0.03 rad (RMS, 1e-12 relative) and
    the integration and drift parts exactly 0; the native part's RMS and % equal pair_metrics' with the same skip
    (1e-12 relative). A mutation audit found that measuring from the first sample (RMS 0.71 rad) passed every
    test."""
    t = np.arange(0.0, 1.0 + 1e-12, 1e-3)
    x = _swing(t, 0.0)
    early = t < 0.5 - metrics.T_EPS
    an = _trace("a", t, x + np.where(early, 1.0, 0.03)[:, None])
    rn, ar, rr = _trace("ref", t, x), _trace("a", t, x), _trace("ref", t, x)
    native = _run({"ref": rn, "a": an}, 0.5, "native")
    (m,) = metrics.contact_split(native, _run({"ref": rr, "a": ar}, 0.5, "reference"))
    q = slice(0, 3)
    np.testing.assert_allclose(m.native_rms[q], 0.03, rtol=1e-12)
    np.testing.assert_allclose(m.contact_rms[q], 0.03, rtol=1e-12)
    np.testing.assert_array_equal(m.integration_rms[q], 0.0)
    np.testing.assert_array_equal(m.drift_rms[q], 0.0)
    np.testing.assert_array_equal(m.integration_pct[q], 0.0)
    np.testing.assert_array_equal(m.drift_pct[q], 0.0)
    p = metrics.pair_metrics(an, rn, skip=0.5)
    np.testing.assert_allclose(m.native_rms[q], p.rms[q], rtol=1e-12)
    np.testing.assert_allclose(m.native_pct[q], p.sim_error_pct[q], rtol=1e-12)
    np.testing.assert_allclose(m.contact_pct[q], p.sim_error_pct[q], rtol=1e-12)


def test_a_backend_component_at_rest_is_left_out_of_the_lag_correlation() -> None:
    """The reference swings all three joints; backend a holds q1 at one value (a joint clamped at rest) while its
    q2 and q3 swing 5 ms late. Its q1 has no correlation to give (variance 0): it is left out as the docstring
    says, so the lag is 5 ms (1e-3 sample) and the correlation is that of q2 and q3 alone, 1 (1e-6), equal to the
    estimate with q1 at rest in both traces (1e-12 relative); counted as a 0 it would read 2/3. A mutation audit
    found that leaving out only the reference's resting components passed every test."""
    t = np.arange(0.0, 2.0 + 1e-12, 1e-3)
    ref, late = _swing(t, 0.0), _swing(t, 0.005)
    late[:, 0] = 0.05  # [rad]: q1 at rest in the backend
    est = metrics.estimate_lag(_trace("a", t, late), _trace("ref", t, ref))
    ref_rest = ref.copy()
    ref_rest[:, 0] = 0.05
    alone = metrics.estimate_lag(_trace("a", t, late), _trace("ref", t, ref_rest))
    assert abs(est.samples - 5.0) < 1e-3 and est.note == ""
    assert est.correlation == pytest.approx(1.0, abs=1e-6)
    assert est.correlation == pytest.approx(alone.correlation, rel=1e-12)


def test_the_percentage_is_undefined_for_a_reference_peak_at_or_below_1e12() -> None:
    """PEAK_FLOOR = 1e-12: a reference whose peak is 1e-12 (q1) has no simulation error % (NaN), one whose peak
    is 1.5e-12 (q3) has one, 100 max |d| / peak with max |d| = 1e-13 (1e-9 relative: the difference of two
    numbers near 1.6e-12 is exact to ~2e-28). A mutation audit found that a floor of 1e-11 passed every test."""
    t = np.arange(0.0, 0.1 + 1e-12, 1e-3)
    ref = np.tile([1e-12, 2.6, 1.5e-12], (len(t), 1))
    p = metrics.pair_metrics(_trace("a", t, ref + 1e-13), _trace("ref", t, ref))
    np.testing.assert_array_equal(p.ref_peak[:3], [1e-12, 2.6, 1.5e-12])
    assert math.isnan(p.sim_error_pct[0])
    assert p.sim_error_pct[2] == pytest.approx(100 * 1e-13 / 1.5e-12, rel=1e-9)


def _static(q: np.ndarray, F: np.ndarray) -> results.RunResult:
    """The leg at rest at ``q`` for 1 s at 1 kHz, the ground force ``F`` [N] on the foot's lowest point:
    tau = G(q) - J_poc^T F."""
    from legbench import kinematics

    tau = kinematics.gravity(q) - kinematics.jacobian_at(q, "true", 0.0).T @ F
    t = np.arange(0.0, 1.0 + 1e-12, 1e-3)
    cols = dict(zip(["q1", "q2", "q3", "qd1", "qd2", "qd3", "tau1", "tau2", "tau3", "fx", "fy", "fz"],
                    [*q, 0.0, 0.0, 0.0, *tau, *F], strict=True))  # fmt: skip
    df = pd.DataFrame({"t": t, **{k: np.full(t.size, v) for k, v in cols.items()}})
    return results.result_from_frame(df, "a", required=REQUIRED)


def test_the_analytic_check_holds_up_to_a_condition_number_of_1e8() -> None:
    """COND_MAX = 1e8: near the pose where J_poc loses rank (q1 = 0, q2 = 1.82988, q3 = 2.96971, test_compare's
    singular pose; cond(J_poc) ~ 3.37 / dq3), the knee moved so that cond is 5e7 (between 4e7 and 1e8 as measured
    by steady_state) still gets the check, which gives the force back (1e-3 N: the solve loses ~cond x 1e-16 of
    the torques; measured 4.4e-5 N); moved so that cond is 2e8 (between 1e8 and 2.5e8) it is singular: NaN. A
    mutation audit found that COND_MAX = 1e7 passed every test."""
    from legbench import kinematics

    q_sing = np.array([0.0, 1.8298834292396862, 2.969711102182886])

    def moved(dq3: float) -> np.ndarray:
        return q_sing + np.array([0.0, 0.0, dq3])

    gain = float(np.linalg.cond(kinematics.jacobian_at(moved(1e-5), "true", 0.0))) * 1e-5  # cond x dq3 [rad]
    F = np.array([4.0, -3.0, 50.0])  # [N]
    below = metrics.steady_state(_static(moved(gain / 5e7), F), 0.5)
    assert 4e7 < below.cond < 1e8
    np.testing.assert_allclose(below.analytic_poc, F, rtol=0, atol=1e-3)
    above = metrics.steady_state(_static(moved(gain / 2e8), F), 0.5)
    assert 1e8 < above.cond < 2.5e8
    assert np.isnan(above.analytic_poc).all()


def test_a_peak_barely_above_one_end_of_the_window_is_flat() -> None:
    """No lag is identified where the correlation's peak stands less than 1e-3 above EITHER end of the search
    window (a side that barely falls does not bound the lag). Three sines of 16 s period over 2 s, the backend
    60 ms late, searched within 100 ms: the peak is 3.2e-3 above the -100 ms end but only 1.95e-4 above the
    +100 ms end (measured), so the lag is NaN and the note says the correlation is flat. A mutation audit found
    that comparing with the lower end (min) passed every test."""
    t = np.arange(0.0, 2.0 + 1e-12, 1e-3)

    def slow(lag: float) -> np.ndarray:
        return np.column_stack([np.sin(2 * np.pi * (t - lag) / 16.0 + p) for p in (0.0, 1.0, 2.0)])

    est = metrics.estimate_lag(_trace("a", t, slow(0.06)), _trace("ref", t, slow(0.0)), max_lag=0.1)
    assert math.isnan(est.seconds) and math.isnan(est.samples)
    assert "flat over the search window" in est.note, est.note


def test_a_joint_at_rest_does_not_veto_removing_a_lag_that_helps_every_moving_joint() -> None:
    """q1 at rest but for 1e-17 rad of round-off in both runs (independent draws), q2 and q3 of the backend
    20 ms late: with lag="remove" the lag is removed, 20 ms within 1e-6 s (measured 2e-7 s: the parabola's
    sub-sample error), and q2's RMS deviation after removal is below 1e-6 rad (measured 7e-7 rad; 0.071 rad with
    the lag left in). The resting joint's round-off RMS may rise or fall with the shift; it is no component the
    lag came from, so it must not veto the removal. A mutation audit found that letting every finite component
    vote passed every test."""
    t = np.arange(0.0, 2.0 + 1e-12, 1e-3)
    rng = np.random.default_rng(0)
    a = _resting_q1(t, 0.02, rng)  # drawn first: the backend's round-off, then the reference's
    ref = _resting_q1(t, 0.0, rng)
    p = metrics.pair_metrics(_trace("a", t, a), _trace("ref", t, ref), lag="remove")
    assert p.lag is not None and p.lag.note == "", p.lag
    assert p.lag_removed == pytest.approx(0.02, abs=1e-6)
    assert p.rms[I_Q2] < 1e-6


def test_a_small_genuine_motion_is_kept_among_the_correlated_components() -> None:
    """Only a component moving less than 1e-9 of its signal's largest span is round-off left out of the
    correlation; q1 swinging 4e-4 rad at 1.5 Hz (2.5e-4 of q2's 1.6 rad span) is a motion and is kept. Its own
    lag (100 ms) differs from q2's and q3's (20 ms), so keeping it moves the estimate (51.6 ms at correlation
    0.945, measured): the reported correlation equals the mean of the three columns' Pearson correlations at the
    integer lag of the peak (1e-9 relative; measured 1e-15). A mutation audit found that a threshold of 1e-3
    (which drops q1: 20 ms at correlation 1) passed every test."""
    t = np.arange(0.0, 2.0 + 1e-12, 1e-3)

    def legs(lag: float, q1_lag: float) -> np.ndarray:
        s = t - lag
        return np.column_stack([2e-4 * np.sin(3 * np.pi * (t - q1_lag)), 2.6 + 0.8 * np.sin(2 * np.pi * s),
                                -1.2 + 0.2 * np.cos(3 * np.pi * s)])  # fmt: skip

    a, ref = legs(0.02, 0.1), legs(0.0, 0.0)
    span = np.ptp(ref, axis=0)
    assert 1e-9 < span[0] / span.max() < 1e-3
    est = metrics.estimate_lag(_trace("a", t, a), _trace("ref", t, ref))
    assert est.note == "" and math.isfinite(est.samples)
    k = round(est.samples)  # the peak's integer lag: the parabola moves it by less than half a sample
    m = len(t)
    xa, xr = (a[k:], ref[: m - k]) if k >= 0 else (a[: m + k], ref[-k:])  # x_a[n + k] against x_ref[n]
    pearson = [np.corrcoef(xa[:, j], xr[:, j])[0, 1] for j in range(3)]
    assert est.correlation == pytest.approx(float(np.mean(pearson)), rel=1e-9)


def test_friction_below_the_floor_has_no_direction_and_above_it_opposes_the_slide() -> None:
    """FRICTION_FLOOR = 1e-6 N: the foot pressed 5 mm in, its point (y/2 above the lowest) sliding at
    (1e-4, 0) m/s, with a friction force of 1e-9 N, (8e-10, -6e-10) N, carries no friction direction (NaN);
    with 1e-5 N opposing the slide, (-1e-5, 0) N, the cosine is -1 (1e-9). A mutation audit found that a floor
    of 1e-12 N passed every test."""
    for friction, want in (((8e-10, -6e-10), math.nan), ((-1e-5, 0.0), -1.0)):
        trace = _pressing(0.5, v=(1e-4, 0.0))[0]
        trace.data[:, 9:11] = np.array(friction)  # fx, fy of the log [N]
        cosine = metrics.steady_state(trace, 0.5, "true", lift=0.5).slide_cosine
        if math.isnan(want):
            assert math.isnan(cosine), (friction, cosine)
        else:
            assert cosine == pytest.approx(want, abs=1e-9), (friction, cosine)


def test_a_missing_signal_has_no_time_of_its_largest_deviation() -> None:
    """A trace with only q logged (qd, tau and force NaN) measured from skip = 0.3 s: the missing columns have
    no largest deviation (max_abs NaN) and so no time of it, t_max_abs NaN, not the window's first time 0.3 s;
    q's times are finite, inside [0.3, 1] s."""
    t = np.arange(0.0, 1.0 + 1e-12, 1e-3)
    p = metrics.pair_metrics(_hip_trace("a", t, 0.004, wrap=False), _hip_trace("ref", t, 0.0, wrap=False), skip=0.3)
    assert np.isnan(p.max_abs[3:]).all()
    assert np.isnan(p.t_max_abs[3:]).all(), p.t_max_abs
    assert ((p.t_max_abs[:3] >= 0.3 - 1e-12) & (p.t_max_abs[:3] <= 1.0 + 1e-12)).all()
