"""steady_contact's standard deviation: no round-off floor from the mean of a large window.

MuJoCo's matched profile holds the effort task's ground force bit for bit constant from 0.22 s
on (the state is a fixed point of its step); numpy's two-pass std over axis 0 of the N x 3 log
accumulates the mean row by row and reported 2.8e-14, 6.4e-14, 2.3e-13 N (31-36 ulp) for it.
"""

from __future__ import annotations

import statistics

import numpy as np

from legbench.studies.contact_study import steady_contact

#: MuJoCo matched, effort task: the end-state ground force in W of every tick after 0.22 s [N].
F_MUJOCO = (5.623675303644926, -9.162420932828212, 52.50416933389686)
#: Its joint angles over the same ticks [rad].
Q_STEADY = (-0.00275166, -1.20399552, -1.22273677)


def _log(force: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    n = len(force)
    t = np.arange(n) * 1e-3
    q = np.tile(Q_STEADY, (n, 1))
    return t, q, np.zeros((n, 3)), np.zeros((n, 3)), force


def test_constant_force_has_zero_std() -> None:
    s = steady_contact(*_log(np.tile(F_MUJOCO, (3001, 1))))
    assert s.force_std.tolist() == [0.0, 0.0, 0.0], s.force_std
    assert s.force.tolist() == list(F_MUJOCO)


def test_std_is_at_most_half_the_peak_to_peak() -> None:
    """A force that flips by one ulp (ODE's matched Fn): std <= (max - min) / 2 (it read 90 ulp)."""
    f = np.tile(F_MUJOCO, (3001, 1))
    f[1::3, 2] = np.nextafter(f[1::3, 2], np.inf)
    s = steady_contact(*_log(f))
    w = f[-501:]
    assert np.all(s.force_std <= np.ptp(w, axis=0) / 2), (s.force_std, np.ptp(w, axis=0))


def test_std_of_a_fluctuating_force_is_the_population_std() -> None:
    rng = np.random.default_rng(0)
    f = np.asarray(F_MUJOCO) + rng.normal(0.0, [0.3, 0.2, 0.1], (3001, 3))
    s = steady_contact(*_log(f))
    w = f[-501:]
    exact = [statistics.pstdev(w[:, i].tolist()) for i in range(3)]
    np.testing.assert_allclose(s.force_std, exact, rtol=1e-12)
