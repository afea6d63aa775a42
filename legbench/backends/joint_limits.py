"""The one-sided spring-damper at the joint position limits, for backends whose dynamics know no limits.

Used by the backends that integrate the equations of motion themselves (Pinocchio's ABA, the symbolic
Euler-Lagrange model): past a limit the joint feels tau_lim = -k (q - q_lim) - b qd, the damping only
while moving further out; inside the limits nothing. With k = 1e4 N m/rad, 10 N m pushing the knee into
its 2.229 rad limit rests at 2.230 rad, as the engines' limit constraints do (MuJoCo rests at 2.2292
after overshooting to 2.252, PyBullet's hard limit peaks at 2.2293).
"""

from __future__ import annotations

from collections.abc import Sequence

#: Default limit stiffness [N m/rad] and damping [N m s/rad] (about critical for the knee, I ~ 0.01 kg m^2).
STIFFNESS = 1.0e4
DAMPING = 20.0


def limit_torques(
    args: Sequence[float], q1: float, q2: float, q3: float, qd1: float, qd2: float, qd3: float
) -> tuple[float, float, float]:
    """Limit torques [N m] for q [rad], qd [rad/s], zero inside the limits; ``args`` = (lo1, lo2, lo3, hi1, hi2,
    hi3, k, b). Plain floats and indexing only: the Pinocchio backend's compiled period compiles this very
    function (numba), :class:`JointLimitLaw` calls it in Python."""
    lo1, lo2, lo3, hi1, hi2, hi3, k, b = args[0], args[1], args[2], args[3], args[4], args[5], args[6], args[7]
    t1 = t2 = t3 = 0.0
    if q1 > hi1:
        t1 = -k * (q1 - hi1) - (b * qd1 if qd1 > 0.0 else 0.0)
    elif q1 < lo1:
        t1 = -k * (q1 - lo1) - (b * qd1 if qd1 < 0.0 else 0.0)
    if q2 > hi2:
        t2 = -k * (q2 - hi2) - (b * qd2 if qd2 > 0.0 else 0.0)
    elif q2 < lo2:
        t2 = -k * (q2 - lo2) - (b * qd2 if qd2 < 0.0 else 0.0)
    if q3 > hi3:
        t3 = -k * (q3 - hi3) - (b * qd3 if qd3 > 0.0 else 0.0)
    elif q3 < lo3:
        t3 = -k * (q3 - lo3) - (b * qd3 if qd3 < 0.0 else 0.0)
    return t1, t2, t3


class JointLimitLaw:
    """tau_lim for the three joints, on plain floats (it runs at every sub-step or integrator stage).

    Args:
        lower, upper: position limits [rad] per joint; +-inf where there is none (the continuous hip).
        stiffness: k [N m/rad]; damping: b [N m s/rad].
    """

    def __init__(self, lower: Sequence[float], upper: Sequence[float], stiffness: float, damping: float) -> None:
        self.lower = tuple(float(x) for x in lower)
        self.upper = tuple(float(x) for x in upper)
        self.k, self.b = float(stiffness), float(damping)
        self._args = (*self.lower, *self.upper, self.k, self.b)

    def __call__(
        self, q1: float, q2: float, q3: float, qd1: float, qd2: float, qd3: float
    ) -> tuple[float, float, float]:
        """Limit torques [N m] for q [rad], qd [rad/s]: zero inside the limits."""
        return limit_torques(self._args, q1, q2, q3, qd1, qd2, qd3)

    def describe(self) -> str:
        """One sentence for :attr:`Limits.enforcement`."""
        return f"one-sided spring-damper {self.k:g} N m/rad, {self.b:g} N m s/rad"
