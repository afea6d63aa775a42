"""Short-horizon mode: re-initialised windows separate a backend's local error from the divergence of a long run."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from legbench import backends, scenario
from legbench.exceptions import ScenarioError
from legbench.studies import horizon

FREE_SPACE = Path(__file__).resolve().parents[1] / "scenarios" / "verification" / "free_space.yaml"

#: Backends in maximal coordinates: their engine state is more than (q, qd) (bodies held on their hinges by
#: constraints whose drift ERP corrects), so reset(q, qd), which puts the bodies exactly on their axes, does not
#: restore the state a free run was in, and a self-replay is not zero. Every other backend's state is its
#: generalized coordinates.
INEXACT_RESET = {"ode"}


def _needs(*names: str) -> None:
    missing = [n for n in names if n not in backends.available()]
    if missing:
        pytest.skip(f"needs {', '.join(missing)} (not installed)")


@pytest.mark.parametrize("name", sorted(backends.BUILTIN))
def test_own_log_replayed_on_itself_gives_the_reset_floor(name: str) -> None:
    """reset() from a logged state plus the logged torques reproduces the backend's own log (free space, 0.2 s,
    50 ms windows, the backend as the reference, so its local error is its reset floor).

    Generalized coordinates: exactly 0 in every signal, window and column, nothing marked (measured: 0 for
    Pinocchio, MuJoCo, PyBullet, Drake, DART, Lagrange). Maximal coordinates (ODE): the floor is the constraint
    drift that reset() removes; measured 3.46e-5 rad (q) and 7.07e-4 rad/s (qd), asserted within a factor 3
    (1e-5..1e-4 rad, 2e-4..2e-3 rad/s: far above round-off, 1e-15, and below the 1e-3 rad/s scale of the local
    error against Pinocchio at 10 ms), marked reset-limited with the floor named in its note. No contact: the
    force is exactly 0 in both cases.
    """
    _needs(name)
    sc = scenario.load(FREE_SPACE, {"duration": 0.2})
    summary, windows = horizon.short_horizon(sc, [name], window=0.05, reference=name)
    assert set(summary["signal"]) == {"q", "qd", "force"}
    assert sorted(set(windows["t0"])) == pytest.approx([0.0, 0.05, 0.1, 0.15])
    assert (summary["status"] == "ok").all() and (summary["free_max"] == 0.0).all()
    # the reference's replay on itself is its floor: the same numbers, window by window
    assert (summary["local_max"] == summary["reset_floor_max"]).all()
    assert (windows["peak"] == windows["floor_peak"]).all() and (windows["end"] == windows["floor_end"]).all()
    force = summary[summary["signal"] == "force"]
    assert (force["reset_floor_max"] == 0.0).all() and not force["reset_limited"].any()
    if name not in INEXACT_RESET:
        assert (summary["local_max"] == 0.0).all() and (summary["reset_floor_max"] == 0.0).all()
        assert (windows["floor_peak"] == 0.0).all() and (windows["floor_end"] == 0.0).all()
        assert not summary["reset_limited"].any() and (summary["note"] == "").all()
        return
    moving = summary[summary["signal"] != "force"]
    q = moving[moving["signal"] == "q"]["reset_floor_max"].max()
    qd = moving[moving["signal"] == "qd"]["reset_floor_max"].max()
    assert 1e-5 < q < 1e-4 and 2e-4 < qd < 2e-3, (q, qd)
    assert moving["reset_limited"].all()
    for _, row in moving.iterrows():
        assert f"reset floor {row['reset_floor_max']:.3g} {row['unit']}" in row["note"]


def test_reset_floor_marks_a_local_error_it_explains() -> None:
    """ODE against Pinocchio in free space (0.5 s, 10 ms windows): its local error in q, 4.08e-5 rad at most
    (q3; median 6.3e-6), is what its own log replayed on itself gives, 4.22e-5 rad (median 6.6e-6): the floor
    is 1.03x the local error (asserted 0.5x..2x) and at least FLOOR_FRACTION (0.1x) of it in every q and qd
    column (measured 0.91x..1.17x), so every one is marked reset-limited, and the local error is not ODE's step.
    The values are held within 10 % of the measured ones (each run repeats bit for bit).
    """
    _needs("pinocchio", "ode")
    sc = scenario.load(FREE_SPACE)
    summary, windows = horizon.short_horizon(sc, ["pinocchio", "ode"], window=0.01, reference="pinocchio")
    ode = summary[(summary["backend"] == "ode") & (summary["signal"] != "force")]
    q3 = ode[ode["component"] == "q3"].iloc[0]
    assert q3["local_max"] == pytest.approx(4.08e-5, rel=0.1)
    assert q3["reset_floor_max"] == pytest.approx(4.22e-5, rel=0.1)
    assert q3["reset_floor_median"] == pytest.approx(6.56e-6, rel=0.1)
    assert 0.5 < q3["reset_floor_max"] / q3["local_max"] < 2.0
    assert (ode["reset_floor_max"] >= horizon.FLOOR_FRACTION * ode["local_max"]).all()
    assert ode["reset_limited"].all() and ode["note"].str.startswith("reset-limited: reset floor").all()
    ref = summary[summary["backend"] == "pinocchio"]
    assert (ref["reset_floor_max"] == 0.0).all() and not ref["reset_limited"].any()
    assert windows[windows["backend"] == "ode"]["floor_peak"].max() > 0.0


def test_the_reset_floor_rule() -> None:
    """A floor limits a local error from FLOOR_FRACTION of it up; a floor of exactly zero never does, nor NaN."""
    f = horizon.FLOOR_FRACTION
    assert not horizon.reset_limited(1e-4, 0.0)
    assert not horizon.reset_limited(0.0, 0.0)
    assert not horizon.reset_limited(1e-4, 0.5 * f * 1e-4)
    assert horizon.reset_limited(1e-4, f * 1e-4)
    assert horizon.reset_limited(1e-4, 2e-4)
    assert horizon.reset_limited(0.0, 1e-12)
    assert not horizon.reset_limited(1e-4, float("nan")) and not horizon.reset_limited(float("nan"), 1e-4)


@pytest.mark.skipif("mujoco" not in backends.available(), reason="needs a second backend (mujoco)")
def test_local_error_grows_linearly_with_short_windows() -> None:
    """MuJoCo at a 1 ms step against Pinocchio at 50 us: from an exact start, a first-order method's error
    after W seconds is C h W to leading order, so doubling a short window doubles the local error (ratio
    2 within 10 %, measured 1.90 to 2.00), and it stays well below the free run's deviation. MuJoCo's state
    is its generalized coordinates: its reset floor is exactly 0 (measured), so none of it is reset's.

    Long windows are a different matter: the torques are replayed open loop, so without the feedback that
    corrects the free run a 100 ms window can drift further than the whole closed-loop run (docs/studies.md).
    """
    sc = scenario.load(FREE_SPACE, {"duration": 0.3, "backends.mujoco.dt": 1.0e-3})
    w5, _ = horizon.short_horizon(sc, ["mujoco"], window=0.005, reference="pinocchio")
    w10, _ = horizon.short_horizon(sc, ["mujoco"], window=0.01, reference="pinocchio")
    q5 = w5[w5["signal"] == "q"]["local_max"].to_numpy()
    q10 = w10[w10["signal"] == "q"]["local_max"].to_numpy()
    free = w10[w10["signal"] == "q"]["free_max"].to_numpy()
    assert np.all(q5 > 0)
    assert q10 / q5 == pytest.approx(np.full(3, 2.0), rel=0.1)
    assert np.all(q10 < 0.5 * free)
    for w in (w5, w10):
        assert (w["reset_floor_max"] == 0.0).all() and not w["reset_limited"].any()


def test_window_must_be_whole_control_periods() -> None:
    sc = scenario.load(FREE_SPACE, {"duration": 0.1})
    with pytest.raises(ScenarioError, match="short_horizon.window"):
        horizon.short_horizon(sc, ["pinocchio"], window=0.0025)
