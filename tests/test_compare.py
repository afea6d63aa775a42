"""The comparator on synthetic runs whose metrics are known by hand (no physics engine runs)."""

from __future__ import annotations

import hashlib
import json
import math
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from fakerun import Base, Transform, add_to, base_signals, frame, offset, scale, write_run

from legbench import compare as C
from legbench import kinematics, logs, metrics, results, signals
from legbench.exceptions import ResultsError

RATE = 1000.0
DT = 1.0 / RATE
AMPL = np.array([0.1, 0.3, 0.2, 0.5, 1.0, 1.5, 0.8, 2.0, 1.2, 3.0, 2.5, 40.0])
W = 2 * np.pi * 1.0  # [rad/s]: two whole periods in the default 2 s run


def sine(t: np.ndarray) -> np.ndarray:
    """Every column a pure sine of 1 Hz with its own amplitude."""
    return np.sin(W * t)[:, None] * AMPL[None, :]


def lagged_by(tau: float, base: Base = base_signals) -> Transform:
    """Transform replacing the data with base(t - tau): the backend is late by tau [s]."""
    return lambda t, x: base(t - tau)


# --------------------------------------------------------------------------- #
# Metrics with known answers


def test_scaled_copy_has_ten_percent_error_on_every_signal(tmp_path: Path) -> None:
    """x_a = 1.1 x_ref: sim error 10 %, RMS 0.1 rms(x_ref), max 0.1 max|x_ref| at its argmax; to 1e-12 relative."""
    d = write_run(tmp_path / "s", {"ref": None, "a": scale(1.1)})
    res = C.compare(d)
    p = res.pair("a")
    assert p is not None
    ref = base_signals(np.arange(2001) / RATE)
    np.testing.assert_allclose(p.sim_error_pct, 10.0, rtol=1e-12)
    np.testing.assert_allclose(p.rms, 0.1 * np.sqrt(np.mean(ref**2, axis=0)), rtol=1e-12)
    np.testing.assert_allclose(p.max_abs, 0.1 * np.max(np.abs(ref), axis=0), rtol=1e-12)
    np.testing.assert_allclose(p.ref_peak, np.max(np.abs(ref), axis=0), rtol=0)
    np.testing.assert_array_equal(p.t_max_abs, np.argmax(np.abs(ref), axis=0) / RATE)


def test_offset_copy_has_constant_deviation(tmp_path: Path) -> None:
    """x_a = x_ref + 0.01: RMS = max = 0.01 and sim error = 1 / max|x_ref| per column; to 1e-9 relative."""
    d = write_run(tmp_path / "s", {"ref": None, "a": offset(0.01)})
    p = C.compare(d).pair("a")
    assert p is not None
    peak = np.max(np.abs(base_signals(np.arange(2001) / RATE)), axis=0)
    np.testing.assert_allclose(p.rms, 0.01, rtol=1e-9)
    np.testing.assert_allclose(p.max_abs, 0.01, rtol=1e-9)
    np.testing.assert_allclose(p.sim_error_pct, 1.0 / peak, rtol=1e-9)


def test_delayed_sine_metrics_match_the_closed_form(tmp_path: Path) -> None:
    """A sin(w t) against A sin(w (t - tau)), tau = 8 ms, two whole periods sampled at 1 kHz (N = 2001 ticks).

    d(t) = -2 A sin(w tau / 2) cos(w (t - tau/2)): its peaks fall on ticks, so
    max|d| = 2 A sin(w tau / 2) and the sim error is 200 sin(w tau / 2) %; the
    mean of cos^2 over the N ticks is exactly 1/2 + cos(w tau) / (2 N). Equal to 1e-12 relative.
    """
    tau, n = 0.008, 2001
    d = write_run(tmp_path / "s", {"ref": None, "a": lagged_by(tau, sine)}, base=sine)
    p = C.compare(d).pair("a")
    assert p is not None
    s = math.sin(W * tau / 2)
    np.testing.assert_allclose(p.max_abs, 2 * AMPL * s, rtol=1e-12)
    np.testing.assert_allclose(p.sim_error_pct, 200 * s, rtol=1e-12)
    np.testing.assert_allclose(p.rms, 2 * AMPL * s * math.sqrt(0.5 + math.cos(W * tau) / (2 * n)), rtol=1e-12)


def test_skip_leaves_the_start_out_of_every_metric(tmp_path: Path) -> None:
    """A 1.0 bump in tau2 at t = 0.1 s is invisible with skip = 0.2 s (deviation exactly 0) and measured without."""
    bump = add_to("tau2", lambda t: np.where(np.abs(t - 0.1) < 0.01, 1.0, 0.0))
    d = write_run(tmp_path / "s", {"ref": None, "a": bump}, skip=0.2)
    p = C.compare(d).pair("a")
    assert p is not None
    i = signals.LABELS.index("tau2")
    assert p.max_abs[i] == 0.0 and p.rms[i] == 0.0
    assert np.max(np.abs(p.deviation[:, i])) == pytest.approx(1.0, abs=1e-12)  # the full series is kept for plots
    d0 = write_run(tmp_path / "s0", {"ref": None, "a": bump}, skip=0.0)
    p0 = C.compare(d0).pair("a")
    assert p0 is not None and p0.max_abs[i] == pytest.approx(1.0, abs=1e-12) and 0.09 <= p0.t_max_abs[i] <= 0.11


def test_hip_angle_is_compared_on_the_circle(tmp_path: Path) -> None:
    """q2 one full turn apart is the same pose: deviation below 1e-12 rad; the knee (revolute) is not wrapped."""
    turn = add_to("q2", lambda t: np.full_like(t, 2 * np.pi))
    p = C.compare(write_run(tmp_path / "s", {"ref": None, "a": turn})).pair("a")
    assert p is not None
    assert p.max_abs[signals.LABELS.index("q2")] < 1e-12
    knee = add_to("q3", lambda t: np.full_like(t, 2 * np.pi))
    p3 = C.compare(write_run(tmp_path / "k", {"ref": None, "a": knee})).pair("a")
    assert p3 is not None
    assert p3.max_abs[signals.LABELS.index("q3")] == pytest.approx(2 * np.pi, rel=1e-12)


def test_zero_reference_signal_gives_undefined_error_not_infinity(tmp_path: Path) -> None:
    """No contact: the reference force is 0, so its sim error % is NaN (null in metrics.json); RMS still measured."""

    def no_contact(t: np.ndarray) -> np.ndarray:
        x = base_signals(t)
        x[:, 9:12] = 0.0
        return x

    d = write_run(tmp_path / "s", {"ref": None, "a": add_to("fz", lambda t: 0.5 * t)}, base=no_contact)
    res = C.compare(d)
    p = res.pair("a")
    assert p is not None
    assert np.isnan(p.sim_error_pct[9:12]).all()
    assert p.rms[signals.LABELS.index("fz")] > 0
    doc = json.loads(results.write_metrics(res.to_json(), res.run.path / "metrics.json").read_text())
    fz = [r for r in doc["metrics"] if r["metric"] == "sim_error_pct" and r["signal"] == "force" and r["joint"] == "z"]
    assert fz[0]["value"] is None


# --------------------------------------------------------------------------- #
# Alignment and lag


@pytest.mark.parametrize("lag_samples", [-37, 0, 5, 23])
def test_lag_estimate_recovers_a_planted_lag_to_one_sample(tmp_path: Path, lag_samples: int) -> None:
    """x_a(t) = x_ref(t - L dt) for L in {-37, 0, 5, 23}: the cross-correlation finds L within 1 sample."""
    d = write_run(tmp_path / "s", {"ref": None, "a": lagged_by(lag_samples * DT)})
    run = results.load_run(d)
    est = metrics.estimate_lag(run.traces["a"], run.traces["ref"], max_lag=0.1)
    assert abs(est.samples - lag_samples) <= 1.0
    assert est.seconds == pytest.approx(est.samples * DT)
    assert est.correlation > 0.99


def test_removing_the_lag_removes_the_deviation(tmp_path: Path) -> None:
    """After removing a planted 23 ms lag, the RMS deviation of q falls below 1 % of its value with the lag."""
    d = write_run(tmp_path / "s", {"ref": None, "a": lagged_by(0.023)})
    res = C.compare(d, lag="remove")
    p = res.pair("a")
    assert p is not None and p.lag is not None
    assert p.lag_removed == p.lag.seconds and abs(p.lag.seconds - 0.023) <= DT
    before = C.compare(d, lag="report").pair("a")
    assert before is not None and before.lag_removed == 0.0
    assert np.all(p.rms[0:3] < 0.01 * before.rms[0:3])
    rows = res.frame()
    assert rows.query("metric == 'lag_removed'")["value"].iloc[0] == pytest.approx(0.023, abs=DT)


def test_log_at_another_rate_and_length_is_interpolated_within_the_linear_bound(tmp_path: Path) -> None:
    """A 250 Hz log of the same signals, 0.3 s shorter: on the 1 kHz grid the deviation is at most
    h^2/8 max|x''| (linear interpolation error, h = 4 ms), and the common span ends where the log does."""
    d = write_run(tmp_path / "s", {"ref": None})
    t_log = np.arange(0, 1.7 + 1e-9, 0.004)
    log = tmp_path / "slow.csv"
    frame(t_log, base_signals(t_log)).to_csv(log, index=False)
    res = C.compare(d, log=log)
    p = res.pair("log:slow")
    assert p is not None
    assert p.t[-1] == pytest.approx(1.7) and p.t[0] == 0.0
    t = np.arange(0, 2.0005, DT)
    x = base_signals(t)
    curv = np.max(np.abs(np.diff(x, 2, axis=0)), axis=0) / DT**2
    assert np.all(p.max_abs <= 0.004**2 / 8 * curv * 1.01)


def test_estimated_lag_of_a_slower_log_is_within_one_fine_sample(tmp_path: Path) -> None:
    """A 250 Hz log late by 12 ms: the lag found on the 1 kHz correlation grid is 12 ms within 1 ms."""
    d = write_run(tmp_path / "s", {"ref": None})
    t_log = np.arange(0, 2.0 + 1e-9, 0.004)
    log = tmp_path / "late.csv"
    frame(t_log, base_signals(t_log - 0.012)).to_csv(log, index=False)
    p = C.compare(d, log=log, lag="report").pair("log:late")
    assert p is not None and p.lag is not None
    assert abs(p.lag.seconds - 0.012) <= DT


# --------------------------------------------------------------------------- #
# Imported logs


def test_imported_csv_of_a_run_compares_to_it_with_zero_deviation(tmp_path: Path) -> None:
    """A backend's parquet written as CSV (units in headers, other names mapped) deviates from it by exactly 0."""
    d = write_run(tmp_path / "s", {"ref": None, "a": scale(1.05)})
    df = pd.read_parquet(d / "a.parquet")
    df = df.rename(columns={"t": "time [s]", "q1": "q1 [rad]", "fz": "Fn (N)", "tau1": "effort_1", "tau2": "effort_2"})
    log = tmp_path / "external.csv"
    df.to_csv(log, index=False)
    res = C.compare(d, log=log, log_name="external", column_map={"effort_1": "tau1", "effort_2": "tau2"})
    assert "external" in res.traces
    p = res.pair("external")
    assert p is not None
    pa = res.pair("a")
    assert pa is not None
    np.testing.assert_array_equal(p.deviation, pa.deviation)  # log vs ref is exactly a vs ref
    as_ref = C.compare(d, log=log, log_name="external", column_map={"effort_1": "tau1", "effort_2": "tau2"},
                       log_is_reference=True).pair("a")  # fmt: skip
    assert as_ref is not None and as_ref.reference == "external"
    assert np.all(as_ref.max_abs == 0.0) and np.all(as_ref.rms == 0.0)


def test_a_log_that_ends_before_the_runs_skip_is_refused(tmp_path: Path) -> None:
    """A review's log of 0-0.5 s against the ellipse run's skip of 1 s: every metric n/a, exit 0, nothing said.
    It is refused in one line naming the log, its end and the skip; one reaching past the skip is measured."""
    d = write_run(tmp_path / "s", {"ref": None}, skip=1.0)
    short, longer = tmp_path / "short.csv", tmp_path / "longer.csv"
    t = np.arange(0, 0.5 + 1e-9, DT)
    frame(t, base_signals(t)).to_csv(short, index=False)
    with pytest.raises(ResultsError, match=r"short.csv: ends at t = 0.5 s, before the run's skip \(1 s, its "
                                           r"scenario's comparison.skip\): no sample of it is compared"):  # fmt: skip
        C.compare(d, log=short)
    t = np.arange(0, 1.2 + 1e-9, DT)
    frame(t, base_signals(t)).to_csv(longer, index=False)
    p = C.compare(d, log=longer).pair("log:longer")
    assert p is not None and np.isfinite(p.max_abs).all()


def test_load_log_keeps_missing_optional_signals_as_nan(tmp_path: Path) -> None:
    """A log with only t and q1..q3: the other signals are NaN and their metrics NaN; q is measured."""
    d = write_run(tmp_path / "s", {"ref": None})
    log = tmp_path / "qonly.csv"
    pd.read_parquet(d / "ref.parquet")[["t", "q1", "q2", "q3"]].to_csv(log, index=False)
    df = logs.load_log(log)
    assert list(df.columns) == list(signals.RUN_COLUMNS)
    assert df["tau1"].isna().all() and not df["q1"].isna().any()
    p = C.compare(d, log=log).pair("log:qonly")
    assert p is not None
    assert np.all(p.max_abs[0:3] == 0.0) and np.isnan(p.max_abs[3:]).all()


def test_load_log_time_scale_converts_milliseconds(tmp_path: Path) -> None:
    """time_scale = 1e-3 turns a millisecond time column into seconds."""
    log = tmp_path / "ms.csv"
    pd.DataFrame({"t_ms": [0.0, 1.0, 2.0], "q1": 0.0, "q2": 0.0, "q3": 0.0}).to_csv(log, index=False)
    df = logs.load_log(log, column_map={"t_ms": "t"}, time_scale=1e-3)
    np.testing.assert_allclose(df["t"], [0.0, 0.001, 0.002])


def test_nan_samples_of_an_imported_log_leave_out_only_those_samples(tmp_path: Path) -> None:
    """A log of backend a with fx NaN in 3 of 2001 rows (as a ROS bag's force where no wrench covers the time):
    its fx max |d|, RMS and sim error % are a's over the other 1998 rows, and its steady fx mean is the mean of the
    window's finite samples (each to 1e-12 relative), not null; every other column equals a's exactly."""
    d = write_run(tmp_path / "s", {"ref": None, "a": scale(1.05)})
    df = pd.read_parquet(d / "a.parquet")
    gaps = [100, 700, 1500]  # the last one inside the steady window [1.5, 2.0] s
    df.loc[gaps, "fx"] = np.nan
    log = tmp_path / "gappy.csv"
    df.to_csv(log, index=False)
    res = C.compare(d, log=log)
    p, pa = res.pair("log:gappy"), res.pair("a")
    assert p is not None and pa is not None
    keep = np.ones(len(pa.t), dtype=bool)
    keep[gaps] = False
    dx = pa.deviation[keep, 9]
    np.testing.assert_allclose(p.max_abs[9], np.max(np.abs(dx)), rtol=1e-12)
    np.testing.assert_allclose(p.rms[9], np.sqrt(np.mean(dx**2)), rtol=1e-12)
    np.testing.assert_allclose(p.sim_error_pct[9], 100 * np.max(np.abs(dx)) / pa.ref_peak[9], rtol=1e-12)
    others = np.arange(12) != 9
    for metric in ("max_abs", "rms", "sim_error_pct", "ref_peak"):
        np.testing.assert_array_equal(getattr(p, metric)[others], getattr(pa, metric)[others])
    steady = {s.backend: s for s in res.steady}
    fx = df["fx"].to_numpy()[df["t"].to_numpy() >= 1.5 - 1e-9]
    np.testing.assert_allclose(steady["log:gappy"].force[0], np.mean(fx[np.isfinite(fx)]), rtol=1e-12)
    rows = res.frame().query("backend == 'log:gappy' and signal == 'force' and joint == 'x'")
    assert rows.query("metric in ['sim_error_pct', 'rms', 'max_abs', 'steady_mean']")["value"].notna().all()


def test_column_map_wins_over_the_automatic_match_of_its_target(tmp_path: Path) -> None:
    """A header with q2 and hip_filtered, column_map {hip_filtered: q2}: q2 is hip_filtered's column exactly and the
    header's own q2 is ignored (not a clash); two explicit maps to one column still are one."""
    log = tmp_path / "filtered.csv"
    pd.DataFrame({"t": [0.0, 0.001, 0.002], "q1": 0.0, "q2": [0.1, 0.2, 0.3], "q3": 0.0,
                  "hip_filtered": [0.15, 0.25, 0.35]}).to_csv(log, index=False)  # fmt: skip
    df = logs.load_log(log, {"hip_filtered": "q2"})
    np.testing.assert_array_equal(df["q2"], [0.15, 0.25, 0.35])
    with pytest.raises(ResultsError, match=r"several header columns map to \['q2'\]"):
        logs.load_log(log, {"hip_filtered": "q2", "q2": "q2"})


def test_imported_log_without_foot_columns_gets_the_foot_from_q(tmp_path: Path) -> None:
    """A log of backend a without ee_x..ee_z: its foot centre is a's own (kinematics.fk of q, as the run logs it)
    to 1e-12 m, in load_log's frame and in the compared trace; a foot column the log has is kept as logged."""
    d = write_run(tmp_path / "s", {"ref": None, "a": scale(1.05)})
    run = pd.read_parquet(d / "a.parquet")
    ee = list(signals.EE_COLUMNS)
    log = tmp_path / "noee.csv"
    run.drop(columns=ee).to_csv(log, index=False)
    np.testing.assert_allclose(logs.load_log(log)[ee].to_numpy(), run[ee].to_numpy(), rtol=0, atol=1e-12)
    res = C.compare(d, log=log)
    np.testing.assert_allclose(res.traces["log:noee"].ee, res.traces["a"].ee, rtol=0, atol=1e-12)
    partial = tmp_path / "eex.csv"
    run.drop(columns=ee[1:]).assign(ee_x=run["ee_x"] + 1e-3).to_csv(partial, index=False)
    got = logs.load_log(partial)[ee].to_numpy()
    np.testing.assert_array_equal(got[:, 0], run["ee_x"].to_numpy() + 1e-3)  # as logged
    np.testing.assert_allclose(got[:, 1:], run[ee[1:]].to_numpy(), rtol=0, atol=1e-12)  # from q
    gap = tmp_path / "eegap.csv"  # a logged column with one missing sample stays the log's, gap and all
    x = run["ee_x"].to_numpy() + 1e-3
    x[5] = np.nan
    run.drop(columns=ee[1:]).assign(ee_x=x).to_csv(gap, index=False)
    np.testing.assert_array_equal(logs.load_log(gap)["ee_x"].to_numpy(), x)


@pytest.mark.parametrize(
    ("content", "column_map", "fragment"),
    [
        ("t,q1,q3\n0,0,0\n1,0,0\n", None, "no column matches ['q2'] in the header ['t', 'q1', 'q3']"),
        ("time_ms,hip\n0,0\n1,0\n", None, "no column matches ['t', 'q1', 'q2', 'q3'] in the header ['time_ms', 'hip']"),
        ("t,q1,q2,q3\n0,0,0,0\n0,0,0,0\n", None, "not strictly increasing at data row 2 (t = 0 s after 0 s)"),
        ("t,q1,q2,q3\n0,0,0,0\n1,x,0,0\n", None, "column 'q1' is not numeric"),
        ("t,q1,q2,q3\n0,0,0,0\n1,0,0,0\n", {"joint_1": "q1"}, "not in the header"),
        ("t,q1,q2,q3\n0,0,0,0\n1,0,0,0\n", {"q1": "angle"}, "not legbench columns"),
        ("t,q1,q1 [rad],q2,q3\n0,0,0,0,0\n1,0,0,0,0\n", None, "several header columns map to ['q1']"),
    ],
)
def test_malformed_log_raises_naming_the_file_and_problem(
    tmp_path: Path, content: str, column_map: dict[str, str] | None, fragment: str
) -> None:
    """Every malformed log is a ResultsError whose one-line message names the file and the problem."""
    log = tmp_path / "bad.csv"
    log.write_text(content)
    with pytest.raises(ResultsError) as err:
        logs.load_log(log, column_map)
    assert str(log) in str(err.value) and fragment in str(err.value)
    assert "\n" not in str(err.value)


def test_missing_log_file_raises(tmp_path: Path) -> None:
    """A log path that does not exist is a ResultsError naming it; a directory is named as one."""
    with pytest.raises(ResultsError, match="no such log file"):
        logs.load_log(tmp_path / "nope.csv")
    with pytest.raises(ResultsError, match="is a directory, not a log file"):
        logs.load_log(tmp_path)


def test_a_log_that_does_not_overlap_the_run_names_both_spans(tmp_path: Path) -> None:
    """A log of t = 100..101 s as the reference of a 2 s run: the error gives both spans (the reference's
    first), not an inverted 'common' one."""
    d = write_run(tmp_path / "s", {"ref": None})
    log = tmp_path / "late.csv"
    log.write_text("t,q1,q2,q3\n100,0,0,0\n101,0,0,0\n")
    with pytest.raises(
        ResultsError, match=r"do not overlap by two ticks: the reference's \[100, 101\] s and \[0, 2\] s"
    ):
        C.compare(d, log=log, log_is_reference=True)


def test_log_name_clashing_with_a_backend_raises(tmp_path: Path) -> None:
    """An imported log may not take the name of a backend of the run."""
    d = write_run(tmp_path / "s", {"ref": None, "a": None})
    log = tmp_path / "a.csv"
    pd.read_parquet(d / "a.parquet").to_csv(log, index=False)
    with pytest.raises(ResultsError, match="already a backend"):
        C.compare(d, log=log, log_name="a")


# --------------------------------------------------------------------------- #
# Run directories


def test_missing_run_directory_and_run_json_raise(tmp_path: Path) -> None:
    """A missing DIR, and a DIR without run.json, are ResultsErrors naming the directory."""
    with pytest.raises(ResultsError, match="no such run directory"):
        results.load_run(tmp_path / "nope")
    (tmp_path / "empty").mkdir()
    with pytest.raises(ResultsError, match="no run.json"):
        results.load_run(tmp_path / "empty")
    d = write_run(tmp_path / "bad", {"ref": None})
    (d / "run.json").write_text("{not json")
    with pytest.raises(ResultsError, match=r"run.json: invalid JSON at line 1"):
        results.load_run(d)


def test_parquet_without_a_contract_column_raises(tmp_path: Path) -> None:
    """A backend file lacking a contract column (fz) is a ResultsError naming the file and the column."""
    d = write_run(tmp_path / "s", {"ref": None})
    pd.read_parquet(d / "ref.parquet").drop(columns=["fz"]).to_parquet(d / "ref.parquet")
    with pytest.raises(ResultsError, match=r"ref.parquet: missing column\(s\) \['fz'\]"):
        results.load_run(d)


def _damage(d: Path, backend: str, how: str) -> Path:
    log = d / f"{backend}.parquet"
    df = pd.read_parquet(log)
    if how == "cut to 10 rows":
        df = df.iloc[:10]
    elif how == "first rows gone":
        df = df.iloc[100:]
    elif how == "NaN in one row":
        df.loc[5, "q2"] = np.nan
    elif how == "inf in one row":
        df.loc[7, "fz"] = -np.inf
    df.to_parquet(log, index=False)
    return log


@pytest.mark.parametrize(
    ("how", "fragment"),
    [
        ("cut to 10 rows", "column 't' spans 0 .. 0.009 s (10 rows), not the scenario's 0 .. 2 s"),
        ("first rows gone", "column 't' spans 0.1 .. 2 s (1901 rows), not the scenario's 0 .. 2 s"),
        ("NaN in one row", "column 'q2' holds nan at data row 6 (t = 0.005 s) (1 such value(s))"),
        ("inf in one row", "column 'fz' holds -inf at data row 8 (t = 0.007 s) (1 such value(s))"),
    ],
)
def test_a_damaged_log_of_an_ok_backend_is_refused_naming_file_and_column(
    tmp_path: Path, how: str, fragment: str
) -> None:
    """run.json says a is ok, so its log must be whole: the run loop logs every tick from 0 to the duration and
    only finite, checked states. A log cut short (a full disk, an interrupted copy) used to be measured over
    the 9 ms left, and a NaN passed silently; neither is a backend failure run.json could report (those are
    notes), so it is a ResultsError naming the file and the column, and no metric is computed from it."""
    d = write_run(tmp_path / "s", {"ref": None, "a": scale(1.1)})
    log = _damage(d, "a", how)
    with pytest.raises(ResultsError) as err:
        C.compare(d)
    assert str(err.value).startswith(f"{log}: {fragment}"), str(err.value)
    assert "\n" not in str(err.value)


def test_a_failed_backend_s_partial_log_may_be_short(tmp_path: Path) -> None:
    """The length rule is for ok backends: a failed backend's log stops where it failed and is still kept
    (plotted, not measured)."""
    d = write_run(tmp_path / "s", {"ref": None, "a": None})
    _damage(d, "a", "cut to 10 rows")
    doc = json.loads((d / "run.json").read_text())
    doc["backends"]["a"] |= {"status": "failed", "reason": "diverged at t = 0.009 s"}
    (d / "run.json").write_text(json.dumps(doc))
    run = results.load_run(d)
    assert list(run.partial) == ["a"] and len(run.partial["a"].t) == 10 and list(run.traces) == ["ref"]


def test_a_signal_nan_throughout_is_not_logged_not_damaged(tmp_path: Path) -> None:
    """A column NaN in every row is a signal the log does not hold (like an absent column): accepted, n/a."""

    def no_force(t: np.ndarray, x: np.ndarray) -> np.ndarray:
        x[:, 9:12] = np.nan
        return x

    d = write_run(tmp_path / "s", {"ref": no_force, "a": no_force})
    assert not C.compare(d).traces["a"].has("force")


def test_inf_in_an_imported_log_is_refused_without_numpy_warnings(tmp_path: Path) -> None:
    """An infinite value in a CSV reference log used to reach the metrics and print numpy RuntimeWarnings
    (invalid value in remainder, sin, cos) before a report of inf/NaN; now load_log refuses it, naming the
    file and the column, and no warning is emitted on the way."""
    d = write_run(tmp_path / "s", {"ref": None, "a": scale(1.1)})
    df = pd.read_parquet(d / "ref.parquet")
    df.loc[5, "q2"] = np.inf
    log = tmp_path / "robot.csv"
    df.to_csv(log, index=False)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # any RuntimeWarning fails the test
        with pytest.raises(ResultsError) as err:
            C.compare(d, log=log, log_is_reference=True)
    assert str(err.value) == (f"{log}: column 'q2' holds inf at data row 6 (t = 0.005 s) (1 such value(s)): a log must "
                              "hold finite numbers")  # fmt: skip


def test_failed_and_missing_backends_are_reported_not_measured(tmp_path: Path) -> None:
    """A failed backend and an 'ok' one without a file appear in notes and metrics.json, with no metrics."""
    d = write_run(tmp_path / "s", {"ref": None, "a": None, "b": None}, failed={"c": "diverged at t = 0.3 s"})
    (d / "b.parquet").unlink()
    res = C.compare(d)
    assert [p.backend for p in res.pairs] == ["a"]
    assert any("'c' failed: diverged at t = 0.3 s" in n for n in res.notes)
    assert any("'b' missing" in n for n in res.notes)
    doc = res.to_json()
    assert doc["backends"]["c"] == {"status": "failed", "reason": "diverged at t = 0.3 s", "source": "run"}
    assert doc["backends"]["b"]["status"] == "missing"
    assert set(res.frame()["backend"]) == {"ref", "a"}


def test_failed_reference_means_no_deviation_and_a_note(tmp_path: Path) -> None:
    """Without the reference backend's data there are no pair metrics; steady states are still measured."""
    d = write_run(tmp_path / "s", {"a": None, "b": None}, failed={"ref": "engine not installed"})
    res = C.compare(d)
    assert res.pairs == ()
    assert any("reference backend 'ref' has no data (engine not installed)" in n for n in res.notes)
    assert [s.backend for s in res.steady] == ["a", "b"]


def test_all_pairs_measures_every_ordered_pair(tmp_path: Path) -> None:
    """Three traces give n (n - 1) = 6 ordered pairs; a vs b is the negated deviation of b vs a."""
    d = write_run(tmp_path / "s", {"ref": None, "a": scale(1.1), "b": offset(0.01)})
    res = C.compare(d, all_pairs=True)
    assert sorted((p.backend, p.reference) for p in res.pairs) == sorted(
        [("a", "ref"), ("b", "ref"), ("ref", "a"), ("ref", "b"), ("a", "b"), ("b", "a")]
    )
    ab, ba = res.pair("a", "b"), res.pair("b", "a")
    assert ab is not None and ba is not None
    np.testing.assert_allclose(ab.deviation[:, 3:], -ba.deviation[:, 3:], atol=1e-15)


def test_every_pair_divides_by_the_scenario_reference_s_peak(tmp_path: Path) -> None:
    """The spec's simulation error % is max_t |x_a - x_b| / max_t |x_ref| with x_ref the reference's: in the pair
    (a, b) b's own peak was the denominator, so a-vs-b and b-vs-a differed (effort, MuJoCo vs ODE q1: 11.30 % and
    10.19 %, peaks 2.50e-3 and 2.78e-3 rad; with the reference's 3.97e-3 rad both are 7.12 %). Every pair now divides
    by the reference's peak: a-vs-b equals b-vs-a (shared ticks), and is 100 max_abs / the reference's peak."""
    d = write_run(tmp_path / "s", {"ref": None, "a": scale(1.3), "b": scale(0.8)})
    res = C.compare(d, all_pairs=True)
    ab, ba, a_ref = res.pair("a", "b"), res.pair("b", "a"), res.pair("a", "ref")
    assert ab is not None and ba is not None and a_ref is not None
    np.testing.assert_array_equal(ab.ref_peak, a_ref.ref_peak)  # the reference's, not b's (0.8 of it)
    np.testing.assert_allclose(ab.sim_error_pct, ba.sim_error_pct, rtol=1e-12)
    moving = a_ref.ref_peak > 0
    np.testing.assert_allclose(ab.sim_error_pct[moving], 100.0 * ab.max_abs[moving] / a_ref.ref_peak[moving],
                               rtol=1e-12)  # fmt: skip


def test_the_pairs_denominator_is_the_references_whole_peak_whatever_the_first_pair_covered(tmp_path: Path) -> None:
    """The all-pairs denominator was the first pair's reference peak, taken over the ticks that pair compared: a
    first backend late by 50 ms with ``lag: remove`` compares up to t = 1.95 s of 2 s, and every other pair divided
    by the reference's peak up to 1.95 s, and that first pair too. With signals that grow over the run (peaks at
    t = 2 s) every pair, (a, ref) and (b, c) alike, now divides by the reference's peak over the whole run,
    max_t |x_ref|, as docs/metrics.md says (1e-12 relative)."""
    ramp = lambda t: base_signals(t) * (1.0 + 1.5 * t)[:, None]  # noqa: E731
    d = write_run(tmp_path / "s", {"ref": None, "a": lagged_by(0.05, ramp), "b": scale(1.2), "c": scale(0.9)},
                  base=ramp)  # fmt: skip
    res = C.compare(d, all_pairs=True, lag="remove")
    a_ref, bc = res.pair("a", "ref"), res.pair("b", "c")
    assert a_ref is not None and bc is not None
    assert 1.94 < a_ref.t[-1] < 1.96  # the first pair's ticks end about 50 ms early
    peak = np.max(np.abs(ramp(np.arange(2001) / 1000.0)), axis=0)
    np.testing.assert_allclose(bc.ref_peak, peak, rtol=1e-12)
    np.testing.assert_allclose(bc.sim_error_pct, 100.0 * bc.max_abs / peak, rtol=1e-12)
    np.testing.assert_allclose(a_ref.ref_peak, peak, rtol=1e-12)  # not the peak over its own 1.95 s
    assert np.sum(np.max(np.abs(ramp(a_ref.t)), axis=0) < peak * (1 - 1e-3)) >= 4  # which differs in 4 columns


# --------------------------------------------------------------------------- #
# Steady state and the analytic force check

Q_STAR = np.array([-0.0025, -1.1899, -1.2599])


def static_base(h: np.ndarray, poc_true: bool = True, g_scale: float = 1.0) -> Base:
    """The leg at rest at q*: tau = G(q*) + J^T h, ground force on the foot -h (G for g_scale x the leg
    file's gravity: G is linear in g)."""
    J = kinematics.jacobian_poc(Q_STAR, true_poc=poc_true)
    tau = g_scale * kinematics.gravity(Q_STAR) + J.T @ h

    def base(t: np.ndarray) -> np.ndarray:
        row = np.concatenate([Q_STAR, np.zeros(3), tau, -h])
        return np.tile(row, (len(t), 1))

    return base


def test_analytic_check_recovers_the_ground_force_of_a_static_pose(tmp_path: Path) -> None:
    """At rest with tau = G + J_poc^T h, the check returns -h, the ground force on the foot, within 1e-9 N."""
    h = np.array([3.0, -2.0, -40.0])  # force the foot exerts on the ground [N]
    d = write_run(tmp_path / "s", {"ref": None}, base=static_base(h))
    (s,) = C.compare(d).steady
    np.testing.assert_allclose(s.analytic_poc, -h, atol=1e-9)
    np.testing.assert_allclose(s.residual, 0.0, atol=1e-9)
    np.testing.assert_allclose(s.force, -h, rtol=1e-15)
    assert s.analytic_centre is None and s.poc_compensation is None  # the run's poc is the true one
    assert s.t0 == pytest.approx(1.5) and s.t1 == pytest.approx(2.0)


def test_analytic_check_uses_the_runs_gravity(tmp_path: Path) -> None:
    """The same static pose simulated under Mars gravity (3.71 m/s^2, run.json's scenario.gravity): the check
    subtracts that G(q*), not the leg file's 9.81 one, and recovers -h within 1e-9 N (with 9.81 it would be
    off by (J^T)^-1 (G_9.81 - G_3.71), newtons)."""
    h = np.array([3.0, -2.0, -40.0])
    d = write_run(tmp_path / "s", {"ref": None}, base=static_base(h, g_scale=3.71 / 9.81), gravity=3.71)
    (s,) = C.compare(d).steady
    np.testing.assert_allclose(s.analytic_poc, -h, atol=1e-9)
    J = kinematics.jacobian_poc(Q_STAR, true_poc=True)
    assert np.linalg.norm(np.linalg.solve(J.T, (1 - 3.71 / 9.81) * kinematics.gravity(Q_STAR))) > 1.0


def test_poc_compensation_vanishes_for_a_vertical_force_and_not_with_friction(tmp_path: Path) -> None:
    """With the poc at the sphere centre (J_E) the moment r x F of a horizontal force is missed.

    A purely vertical force is parallel to r = -R z: compensation below 1e-9 N.
    With 5 N of friction, the J_E answer is wrong by more than 0.1 N, and equals
    -(J_E^T)^-1 J_poc^T h computed by hand (1e-9 N).
    """
    for h, expect_zero in ((np.array([0.0, 0.0, -40.0]), True), (np.array([4.0, -3.0, -40.0]), False)):
        d = write_run(tmp_path / f"s{expect_zero}", {"ref": None}, base=static_base(h), poc="centre")
        (s,) = C.compare(d).steady
        assert s.poc_compensation is not None and s.analytic_centre is not None
        JE = kinematics.jacobian_poc(Q_STAR, true_poc=False)
        JP = kinematics.jacobian_poc(Q_STAR, true_poc=True)
        np.testing.assert_allclose(s.analytic_centre, -np.linalg.solve(JE.T, JP.T @ h), atol=1e-9)
        if expect_zero:
            np.testing.assert_allclose(s.poc_compensation, 0.0, atol=1e-9)
        else:
            assert np.linalg.norm(s.poc_compensation) > 0.1
        rows = C.compare(d).frame()
        assert {"analytic_poc", "analytic_centre", "poc_compensation", "analytic_residual"} <= set(rows["metric"])


def test_the_check_at_a_singular_j_poc_is_undefined_with_a_note(tmp_path: Path) -> None:
    """At a pose where J_poc loses rank (found by minimising det(J_poc)^2 over q2, q3 with q1 = 0; condition number
    3.8e16, at least COND_MAX = 1e8; a straight knee is not one: J_poc's cond there is 61, the sphere's lowest point
    being off the shank's line) the check gives NaN with one note naming the singular J_poc, not a force made of
    (J^T)^-1's round-off."""
    q = np.array([0.0, 1.8298834292396862, 2.969711102182886])
    tau = kinematics.gravity(q)

    def straight(t: np.ndarray) -> np.ndarray:
        return np.tile(np.concatenate([q, np.zeros(3), tau, np.zeros(3)]), (len(t), 1))

    res = C.compare(write_run(tmp_path / "s", {"ref": None}, base=straight))
    (s,) = res.steady
    assert not s.cond < metrics.COND_MAX and np.isnan(s.analytic_poc).all()
    assert res.notes.count("ref: J_poc is singular at the steady-state pose; analytic check undefined") == 1


def test_a_log_without_torques_gets_a_note_that_the_check_needs_tau_and_q(tmp_path: Path) -> None:
    """A CSV log with t, q and the force only, at the regular static pose q* (cond(J_poc) ~ 10, far below 1e8): its
    analytic force is undefined (NaN) and the one note about it says the check needs tau and q, not that J_poc is
    singular."""
    d = write_run(tmp_path / "s", {"ref": None}, base=static_base(np.array([3.0, -2.0, -40.0])))
    log = tmp_path / "notau.csv"
    pd.read_parquet(d / "ref.parquet")[["t", "q1", "q2", "q3", "fx", "fy", "fz"]].to_csv(log, index=False)
    res = C.compare(d, log=log)
    (s,) = (s for s in res.steady if s.backend == "log:notau")
    assert np.isnan(s.analytic_poc).all()
    (note,) = (n for n in res.notes if n.startswith("log:notau"))
    assert "needs tau and q" in note and "singular" not in note
    (ref,) = (s for s in res.steady if s.backend == "ref")
    assert ref.cond < 100  # the pose itself is regular


def test_steady_state_means_are_over_the_final_window(tmp_path: Path) -> None:
    """qd1 = t: its mean over [1.5, 2.0] s is 1.75 rad/s (1e-12)."""

    def ramp(t: np.ndarray) -> np.ndarray:
        x = base_signals(t)
        x[:, 3] = t
        return x

    (s,) = C.compare(write_run(tmp_path / "s", {"ref": None}, base=ramp)).steady
    assert s.qd[0] == pytest.approx(1.75, rel=1e-12)


# --------------------------------------------------------------------------- #
# Contact-mode split


def test_contact_mode_split_separates_the_two_causes(tmp_path: Path) -> None:
    """a_native = x + 0.03 + 0.01, a_reference = x + 0.01, reference backend identical in both modes:
    contact part RMS 0.03, integration 0.01, drift 0, native 0.04 (1e-9), found from the sibling directory."""
    both = offset(0.04)
    write_run(tmp_path / "fake", {"ref": None, "a": both})
    write_run(tmp_path / "fake__reference", {"ref": None, "a": offset(0.01)}, contact_mode="reference")
    res = C.compare(tmp_path / "fake")
    assert res.split_run is not None and res.split_run.label == "fake__reference"
    (m,) = res.split
    np.testing.assert_allclose(m.contact_rms, 0.03, rtol=1e-9)
    np.testing.assert_allclose(m.integration_rms, 0.01, rtol=1e-9)
    np.testing.assert_allclose(m.native_rms, 0.04, rtol=1e-9)
    np.testing.assert_array_equal(m.drift_rms, 0.0)
    pn = res.pair("a")
    assert pn is not None
    np.testing.assert_allclose(m.native_pct, pn.sim_error_pct, rtol=1e-12)
    assert res.to_json()["split_with"] == "fake__reference"
    ref_side = C.compare(tmp_path / "fake__reference")
    assert ref_side.split == () and ref_side.run.label == "fake__reference"


def test_contact_mode_split_with_a_drifting_reference_adds_up_sample_by_sample(tmp_path: Path) -> None:
    """The reference backend differs between the modes (r_R = x + 0.02: its own contact is not the law), a_n = x +
    0.06, a_R = x + 0.05: contact a_n - a_R is 0.01, integration a_R - r_R 0.03 (against the reference-mode
    reference, not the native one: 0.05), drift r_R - r_n 0.02, and they add up to native 0.06 (RMS, 1e-9). Every
    part's % is over the native reference's peak max |r_n| (1e-9 relative), not the reference-mode one's."""
    write_run(tmp_path / "fake", {"ref": None, "a": offset(0.06)})
    write_run(tmp_path / "fake__reference", {"ref": offset(0.02), "a": offset(0.05)}, contact_mode="reference")
    res = C.compare(tmp_path / "fake")
    (m,) = res.split
    for part, want in (("native", 0.06), ("contact", 0.01), ("integration", 0.03), ("drift", 0.02)):
        np.testing.assert_allclose(getattr(m, f"{part}_rms"), want, rtol=1e-9, err_msg=part)
        peak = np.abs(res.run.traces["ref"].data).max(axis=0)
        np.testing.assert_allclose(getattr(m, f"{part}_pct"), want / peak * 100, rtol=1e-9, err_msg=part)
    np.testing.assert_allclose(m.contact_rms + m.integration_rms + m.drift_rms, m.native_rms, rtol=1e-9)


def test_split_found_from_inside_the_run_directory(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """`legbench compare .` from inside fake/ (and `..` from a folder inside it) finds fake__reference: the name the
    sibling is found by is the resolved directory's, "." and ".." have none."""
    write_run(tmp_path / "fake", {"ref": None, "a": offset(0.04)})
    write_run(tmp_path / "fake__reference", {"ref": None, "a": offset(0.01)}, contact_mode="reference")
    monkeypatch.chdir(tmp_path / "fake")
    for given in (".", "./"):
        res = C.compare(given)
        assert res.split_run is not None and res.split_run.label == "fake__reference", given
    (tmp_path / "fake" / "sub").mkdir()
    monkeypatch.chdir(tmp_path / "fake" / "sub")
    res = C.compare("..")
    assert res.split_run is not None and res.split_run.label == "fake__reference"


def test_split_with_the_lag_removed_splits_the_deviation_reported(tmp_path: Path) -> None:
    """With lag="remove" the pair is measured after shifting a by its 20 ms lag; the split shifts a's native trace
    by the same lag, so split_native_pct equals sim_error_pct and split_native_rms equals rms (1e-12 relative),
    as docs/metrics.md says, and the parts still add up: contact (a_n shifted - a_R) is the whole of it, the
    reference-mode a being the reference. Unshifted, the split decomposed the raw deviation: 6.3 % of q1 beside
    a reported 5e-5 %."""
    write_run(tmp_path / "fake", {"ref": None, "a": lagged_by(0.02)})
    write_run(tmp_path / "fake__reference", {"ref": None, "a": None}, contact_mode="reference")
    res = C.compare(tmp_path / "fake", lag="remove")
    p = res.pair("a")
    assert p is not None and abs(p.lag_removed - 0.02) < 1e-6
    (m,) = res.split
    np.testing.assert_allclose(m.native_pct, p.sim_error_pct, rtol=1e-12)
    np.testing.assert_allclose(m.native_rms, p.rms, rtol=1e-12)
    np.testing.assert_allclose(m.contact_rms, p.rms, rtol=1e-12)
    np.testing.assert_array_equal(m.integration_rms, 0.0)
    assert np.all(m.native_pct[:3] < 1e-3)
    off = C.compare(tmp_path / "fake").split[0]  # lag off: nothing shifted, the raw deviation is split
    pn = C.compare(tmp_path / "fake").pair("a")
    assert pn is not None
    np.testing.assert_array_equal(off.native_pct, pn.sim_error_pct)


def test_a_backend_missing_in_reference_mode_gets_a_note_not_a_silent_gap(tmp_path: Path) -> None:
    """Backend b failed in the reference-mode run: a is split, b is not, and a note names b, the run and why;
    the reference backend is there in both modes, so there is no note that it is missing."""
    write_run(tmp_path / "fake", {"ref": None, "a": offset(0.02), "b": offset(0.03)})
    write_run(tmp_path / "fake__reference", {"ref": None, "a": offset(0.01)}, contact_mode="reference",
              failed={"b": "diverged at t = 0.2 s"})  # fmt: skip
    res = C.compare(tmp_path / "fake")
    assert [m.backend for m in res.split] == ["a"]
    assert "no contact-mode split for 'b': no data in fake__reference (failed: diverged at t = 0.2 s)" in res.notes
    assert not any("reference backend" in n for n in res.notes)


def test_split_with_a_different_scenario_raises(tmp_path: Path) -> None:
    """A reference-mode directory of another scenario cannot be used for the split."""
    write_run(tmp_path / "fake", {"ref": None})
    write_run(tmp_path / "other", {"ref": None}, name="other", contact_mode="reference")
    with pytest.raises(ResultsError, match="scenario 'other' is not 'fake'"):
        C.compare(tmp_path / "fake", split_dir=tmp_path / "other")


# --------------------------------------------------------------------------- #
# metrics.json


def test_metrics_json_round_trips_and_keeps_its_documented_keys(tmp_path: Path) -> None:
    """write_metrics then read_metrics gives back the same long table (NaN <-> null) and the schema's keys."""
    d = write_run(tmp_path / "s", {"ref": None, "a": scale(1.1)}, failed={"b": "boom"})
    res = C.compare(d, lag="report")
    path = results.write_metrics(res.to_json(), res.run.path / "metrics.json")
    assert path == d / "metrics.json"
    head, df = results.read_metrics(path)
    assert list(head) == [
        "schema", "scenario", "name", "contact_mode", "poc", "reference", "skip", "steady_window",
        "duration", "control_dt", "split_with", "events", "backends", "logs", "notes", "columns",
    ]  # fmt: skip
    assert head["logs"] == {n: hashlib.sha256((d / n).read_bytes()).hexdigest() for n in ("a.parquet", "ref.parquet")}
    assert head["schema"] == results.METRICS_SCHEMA and head["columns"] == list(results.FRAME_COLUMNS)
    pd.testing.assert_frame_equal(df, res.frame().astype({"value": float}), check_dtype=False)
    metrics = set(df["metric"])
    assert {"sim_error_pct", "rms", "max_abs", "t_max_abs", "ref_peak", "lag", "steady_mean"} <= metrics


def test_first_contact_is_the_first_sample_above_half_a_newton() -> None:
    """first_contact (metrics.json ``backends.<name>.first_contact``) is the first sample whose normal force
    exceeds FN_MIN = 0.5 N, the residuals' "in contact", not the first nonzero one: a 1 kHz log with no force
    until 20 ms, a light 0.3 N touch from 20 ms, then a 7 N/s ramp from 50 ms (0.3 + 7 (t - 0.05) N) crosses
    0.5 N at 78.57 ms, so 78 ms (0.496 N) is not in contact and 79 ms (0.503 N) is the first contact (1e-12 s:
    a sample time, exact); the 0.3 N touch from 20 ms is not."""
    t = np.arange(101) * 1e-3
    fz = np.zeros_like(t)
    fz[20:] = 0.3
    fz[50:] += 7.0 * (t[50:] - 0.05)
    assert fz[78] < 0.5 < fz[79]  # the hand numbers: 0.496 and 0.503 N
    trace = results.result_from_frame(pd.DataFrame({"t": t, "fx": 0.0, "fy": 0.0, "fz": fz}), "a")
    assert C.first_contact(trace) == pytest.approx(0.079, abs=1e-12)
    light = results.result_from_frame(pd.DataFrame({"t": t, "fx": 0.0, "fy": 0.0, "fz": np.minimum(fz, 0.3)}), "a")
    assert C.first_contact(light) is None  # a touch that never exceeds 0.5 N is no contact


def test_read_metrics_rejects_a_wrong_schema(tmp_path: Path) -> None:
    """A metrics.json of another schema is a ResultsError naming the file."""
    f = tmp_path / "metrics.json"
    f.write_text(json.dumps({"schema": "other/9", "metrics": []}))
    with pytest.raises(ResultsError, match="schema is 'other/9'"):
        results.read_metrics(f)


def test_a_log_that_wraps_the_hip_is_not_interpolated_across_the_jump() -> None:
    """The hip (q2, continuous) ramping 3.0 -> 3.3 rad through pi: the reference logs it unwrapped at 1 kHz,
    an imported log wrapped to [-pi, pi) at 500 Hz on grid points offset by 1 ms... half a reference tick.
    Linear interpolation of a ramp is exact, so the deviation is round-off (< 1e-9 rad), not the 1.57 rad
    of interpolating straight across the -2 pi jump."""
    t_ref = np.arange(0.0, 1.0 + 1e-12, 1e-3)
    t_a = np.arange(0.0005, 1.0, 2e-3)

    def frame_of(t: np.ndarray, wrap: bool) -> pd.DataFrame:
        q2 = 3.0 + 0.3 * t
        q2 = np.mod(q2 + np.pi, 2 * np.pi) - np.pi if wrap else q2
        return pd.DataFrame({"t": t, "q1": 0.1 * t, "q2": q2, "q3": -1.0 + 0.2 * t})

    ref = results.result_from_frame(frame_of(t_ref, False), "ref", required=["t", "q1", "q2", "q3"])
    a = results.result_from_frame(frame_of(t_a, True), "a", required=["t", "q1", "q2", "q3"])
    assert np.ptp(a.q[:, 1]) > 6.0  # the log really wraps
    p = metrics.pair_metrics(a, ref)
    assert np.nanmax(np.abs(p.deviation[:, signals.LABELS.index("q2")])) < 1e-9
    plain = metrics.pair_metrics(a, ref, wrap=np.zeros(len(signals.LABELS), dtype=bool))  # told: no angle wraps
    assert np.nanmax(np.abs(plain.deviation[:, signals.LABELS.index("q2")])) > 6.0  # then the jump is a deviation


def test_a_wrapped_hip_with_a_missing_sample_is_still_unwrapped() -> None:
    """The same wrapped 500 Hz hip log with one sample missing (NaN, as an imported log has) far from the jump:
    only that sample is left out; the jump is still unwrapped, so away from the gap the deviation stays
    round-off (< 1e-9 rad). Unwrapping nothing when a column had a NaN put 1.57 rad of false deviation there."""
    t_ref = np.arange(0.0, 1.0 + 1e-12, 1e-3)
    t_a = np.arange(0.0005, 1.0, 2e-3)
    q2 = np.mod(3.0 + 0.3 * t_a + np.pi, 2 * np.pi) - np.pi
    q2[50] = np.nan  # t = 0.1005 s; the jump through pi is at t = 0.472 s
    ref = results.result_from_frame(
        pd.DataFrame({"t": t_ref, "q1": 0.1 * t_ref, "q2": 3.0 + 0.3 * t_ref, "q3": -1.0 + 0.2 * t_ref}),
        "ref",
        required=["t", "q1", "q2", "q3"],
    )
    a = results.result_from_frame(
        pd.DataFrame({"t": t_a, "q1": 0.1 * t_a, "q2": q2, "q3": -1.0 + 0.2 * t_a}),
        "a",
        required=["t", "q1", "q2", "q3"],
    )
    p = metrics.pair_metrics(a, ref)
    d = p.deviation[:, signals.LABELS.index("q2")]
    far = np.abs(p.t - t_a[50]) > 2.5e-3  # the ticks interpolated from the missing sample are NaN
    assert np.isnan(d[~far]).any() and np.isfinite(d[far]).all()  # np.unwrap of the whole column: NaN after the gap
    assert np.max(np.abs(d[far])) < 1e-9


@pytest.mark.parametrize("contact", ["absent", None, {}, {"Kp": 1e4, "stiffness": 3}])
def test_a_run_json_without_a_usable_contact_law(tmp_path: Path, contact: object) -> None:
    """The residuals score a run against the law in run.json's scenario.contact. Without one they were scored
    against ContactParams' built-in defaults (not the run's law, and not said); ``contact: null`` crashed with a
    TypeError. No law (absent, null, empty): no residuals and a note saying why; a mapping of other keys: the
    reader's one ResultsError naming run.json and the key."""
    d = write_run(tmp_path / "s", {"ref": None, "a": scale(1.01)})
    meta = json.loads((d / "run.json").read_text())
    if contact == "absent":
        del meta["scenario"]["contact"]
    else:
        meta["scenario"]["contact"] = contact
    (d / "run.json").write_text(json.dumps(meta))
    if isinstance(contact, dict) and contact:
        with pytest.raises(ResultsError, match=r"run\.json: scenario\.contact\.stiffness: unknown contact parameter"):
            C.compare(d)
        return
    res = C.compare(d)
    assert res.residuals == {}
    assert "no contact-law residuals: run.json's scenario names no contact law" in res.notes


def test_a_log_that_covers_part_of_the_run_says_so_and_has_no_steady_state_outside_it(tmp_path: Path) -> None:
    """A log of the run's first 0.5 s of 2 s: its deviations are over that span (0 here: the same data), and its
    steady state was the mean over its own last 0.5 s (0..0.5 s) shown as the run's steady window. Now a note says
    what it covers, its steady state is NaN (the window 1.5..2 s has none of its samples), and no note claims a
    missing tau. A log covering the run to within one of its samples gets no note."""
    d = write_run(tmp_path / "fake", {"ref": None, "a": None})
    df = pd.read_parquet(d / "ref.parquet")
    part = tmp_path / "part.csv"
    df[df["t"] <= 0.5][["t", "q1", "q2", "q3"]].to_csv(part, index=False)
    res = C.compare(d, log=part)
    assert "log:part covers 0.000..0.500 s of the run's 0..2 s (25 %): its deviations are measured over that span " \
           "only" in res.notes  # fmt: skip
    assert "log:part ends at 0.500 s, before the steady window 1.500..2.000 s: no steady state for it" in res.notes
    (s,) = [s for s in res.steady if s.backend == "log:part"]
    assert np.isnan(s.q).all() and (s.t0, s.t1) == (1.5, 2.0)
    assert not any("log:part: the analytic force check" in n for n in res.notes)
    whole = tmp_path / "whole.csv"
    df[df["t"] < 2.0 - 1e-6][["t", "q1", "q2", "q3"]].to_csv(whole, index=False)  # the last sample left out
    assert not any("covers" in n for n in C.compare(d, log=whole).notes)


def test_a_log_longer_than_the_run_is_measured_over_the_run_s_steady_window_and_says_so(tmp_path: Path) -> None:
    """A log running 0.5 s past a 2 s run: its steady state is the run's window 1.5..2.0 s (the mean was right,
    the window shown read 1.5..2.5 s); a log over the whole run with no q or tau in the window keeps the note
    that its analytic check is undefined (only a log ending before the window is left to the coverage note)."""
    d = write_run(tmp_path / "fake", {"ref": None, "a": None})
    df = pd.read_parquet(d / "ref.parquet")[["t", "q1", "q2", "q3"]]
    tail = df[df["t"] > 1.5].assign(t=lambda x: x["t"] + 0.5)
    longer = tmp_path / "longer.csv"
    pd.concat([df, tail[tail["t"] > 2.0]]).to_csv(longer, index=False)
    (s,) = [s for s in C.compare(d, log=longer).steady if s.backend == "log:longer"]
    assert (s.t0, s.t1) == (1.5, 2.0)
    dropout = tmp_path / "dropout.csv"
    df.assign(q1=df["q1"].where(df["t"] < 1.0)).to_csv(dropout, index=False)
    notes = C.compare(d, log=dropout).notes
    assert any(n.startswith("log:dropout: the analytic force check needs tau and q") for n in notes), notes


def test_a_centre_poc_backend_is_checked_at_the_centre() -> None:
    """The symbolic model's engine-defaults takes the lab's poc at the sphere centre (info contact.poc 'centre'):
    its force acts through J_E, so the steady check's residual is against J_E (measured 4e-3 N) where against
    J_poc it was 0.89 N of Fn, which read as a broken read-out; the J_poc force and the compensation stay."""
    pytest.importorskip("sympy")
    from legbench import run, scenario

    root = Path(__file__).resolve().parents[1]
    sc = scenario.load(root / "scenarios" / "effort.yaml", {"backends.lagrange.profile": "engine-defaults"})
    tr = run.run_backend(sc, "lagrange")
    assert tr.status == "ok" and tr.info["contact"]["poc"] == "centre"
    s = metrics.steady_state(tr, 0.5, "centre")
    assert s.poc == "centre" and s.analytic_centre is not None and s.poc_compensation is not None
    assert np.abs(s.residual).max() < 0.02  # [N]
    np.testing.assert_allclose(s.residual, s.force - s.analytic_centre, rtol=0, atol=0)
    assert np.abs(s.force - s.analytic_poc).max() > 0.5  # what the J_poc check showed


def test_a_log_stamped_in_epoch_seconds_is_compared_with_log_t0(tmp_path: Path) -> None:
    """A hardware CSV stamped in epoch milliseconds failed (exit 2, 'do not overlap' with spans rounded to 1.7e+09)
    and one started 2 s before the run was compared misaligned: --log-t0 (log_t0) gives the log's time that is
    the run's t = 0, after the time scale. The same log shifted back reads as the run's own copy (0 deviation);
    without a log it is refused as the other log settings are."""
    d = write_run(tmp_path / "s", {"ref": None})
    t = np.arange(0, 2.0 + 1e-9, DT)
    epoch = 1.7e12  # [ms]
    log = tmp_path / "hw.csv"
    df = frame(t, base_signals(t))
    df["t"] = np.round(epoch + t * 1e3, 3)
    df.to_csv(log, index=False)
    res = C.compare(d, log=log, log_time_scale=1e-3, log_t0=epoch * 1e-3)
    p = res.pair("log:hw")
    assert p is not None
    # the same samples, their times rounded to a double near 1.7e12 ms (spacing 2.4e-4 ms): off by at most
    # that times each signal's slope
    x = base_signals(t)
    slope = np.max(np.abs(np.diff(x, axis=0)), axis=0) / DT
    assert np.all(p.max_abs <= 2.5e-7 * slope), p.max_abs / slope
    assert C.log_settings_problem(None, None, False, 1.0, False, {"log": "--reference-log", "log_t0": "--log-t0"},
                                  log_t0=3.0) == "--log-t0: need --reference-log (they describe that log)"  # fmt: skip


def test_a_log_whose_force_is_the_foot_on_the_ground_is_told_so(tmp_path: Path) -> None:
    """A review's log with the wrench of the foot on the ground (steady fz -52.5 N against the run's +52.5 N) got
    no hint: a note names the sign and the way to turn it; a log of the right sign gets none."""
    d = write_run(tmp_path / "s", {"ref": None})
    t = np.arange(0, 2.0 + 1e-9, DT)
    said: dict[str, list[str]] = {}
    for name, sign in (("flipped", -1.0), ("right", 1.0)):
        df = frame(t, base_signals(t))
        for c in ("fx", "fy", "fz"):
            df[c] = sign * df[c]
        df.to_csv(tmp_path / f"{name}.csv", index=False)
        notes = C.compare(d, log=tmp_path / f"{name}.csv").notes
        said[name] = [n for n in notes if "its normal force is negative where the reference's foot is pressed" in n]
    assert said["right"] == [] and len(said["flipped"]) == 1, said
    assert said["flipped"][0].endswith("(a ROS bag: its force sign option, --ros-force-sign -1; a CSV: negate fx, "
                                       "fy, fz)")  # fmt: skip
