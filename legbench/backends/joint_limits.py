"""The one-sided spring-damper at the joint position limits, for backends whose dynamics know no limits.

Used by the backends that integrate the equations of motion themselves (Pinocchio's ABA, the symbolic
Euler-Lagrange model): past a limit the joint feels tau_lim = -k (q - q_lim) - b qd, the damping only
while moving further out; inside the limits nothing. With k = 1e4 N m/rad, 10 N m pushing the knee into
its 2.229 rad limit rests at 2.230 rad, as the engines' limit constraints do (MuJoCo rests at 2.2292
after overshooting to 2.252, PyBullet's hard limit peaks at 2.2293).
"""

from __future__ import annotations

import cmath
import math
from collections.abc import Sequence

#: Default limit stiffness [N m/rad] and damping [N m s/rad]: over-damped for the knee at its limit (effective
#: inertia 0.0064-0.0075 kg m^2, damping ratio b / (2 sqrt(k I)) = 1.15-1.25).
STIFFNESS = 1.0e4
DAMPING = 20.0
#: The fixed-step integrators :func:`step_bound` knows.
INTEGRATORS = ("euler", "rk4")


def _rk4_stable_h(lam: complex) -> float:
    """Largest h [s] with |R(h lam)| <= 1, R(z) = 1 + z + z^2/2 + z^3/6 + z^4/24 (classical RK4's amplification
    factor), for an eigenvalue lam [1/s] with Re lam <= 0: a scan of |h lam| in steps of 1e-3 up to 3 (RK4's
    stability region reaches 2.785 along the negative real axis and 2.828 along the imaginary one) for the
    first unstable point, then bisection to 1e-12."""
    r = abs(lam)
    if r == 0.0:
        return math.inf
    u = lam / r

    def unstable(x: float) -> bool:
        z = x * u
        return abs(1.0 + z + z * z / 2.0 + z**3 / 6.0 + z**4 / 24.0) > 1.0

    lo, hi = 0.0, 3.0
    for i in range(1, 3001):
        if unstable(i * 1e-3):
            lo, hi = (i - 1) * 1e-3, i * 1e-3
            break
    while hi - lo > 1e-12:
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if unstable(mid) else (mid, hi)
    return lo / r


def step_bound(stiffness: float, damping: float, inertia: float, integrator: str) -> float:
    """Largest sub-step h [s] at which a fixed-step integrator keeps the limit spring-damper stable.

    Past its limit a joint of effective inertia I = ``inertia`` [kg m^2] (1 / (M^-1)_jj at the pose: the
    other joints free) obeys I x'' = -k x - b x' while moving further out (x the excursion [rad], k =
    ``stiffness`` [N m/rad], b = ``damping`` [N m s/rad]; the damper is off while it moves back in). With
    c = b / I [1/s] and w2 = k / I [1/s^2]:

    * ``euler`` (semi-implicit, as the explicit and the implicit-friction step both take the limit law):
      v+ = v + h (-c v - w2 x), x+ = x + h v+ has the step matrix [[1 - h c, -h w2], [h (1 - h c),
      1 - h^2 w2]] with trace 2 - h c - h^2 w2 and determinant 1 - h c, so both eigenvalues lie inside the
      unit circle (Jury) iff h c < 2 and h^2 w2 + 2 h c < 4; the second is the tighter:
      h < 4 / (c + sqrt(c^2 + 4 w2)). Without the damper the step is marginally stable up to h = 2 / sqrt(w2),
      larger, and dissipates nothing, so the damped phase sets the bound. Measured on the knee (I = 0.0065
      kg m^2, bound 570 us; zero gravity, 10 N m into the limit, 1 s, h = control period): at rest to 1e-9 rad
      up to 570 us, still ringing by 1e-6-1e-5 rad at 580-620 us, bouncing off the limit from 630 us,
      diverging to NaN from 670 us.
    * ``rk4``: the largest h with |R(h lambda)| <= 1 (R RK4's amplification factor) for the eigenvalues
      lambda of [[0, 1], [-w2, -c]] (damper on) and +-i sqrt(w2) (damper off, h sqrt(w2) <= 2 sqrt 2). A
      sufficient bound, not a sharp one: RK4 dissipates in the undamped phase, and the knee (bound 1.14 ms)
      still comes to rest at 1.7 ms and bounces off its limit at 1.8 ms.

    ``inf`` for I <= 0 or no stiffness and no damping.
    """
    if integrator not in INTEGRATORS:
        raise ValueError(f"step_bound knows {INTEGRATORS}, not {integrator!r}")
    if inertia <= 0.0 or (stiffness <= 0.0 and damping <= 0.0):
        return math.inf
    c, w2 = damping / inertia, stiffness / inertia
    if integrator == "euler":
        return 4.0 / (c + math.sqrt(c * c + 4.0 * w2))
    root = cmath.sqrt(c * c - 4.0 * w2)
    damped = min(_rk4_stable_h(complex(0.5 * (-c + root))), _rk4_stable_h(complex(0.5 * (-c - root))))
    return min(damped, _rk4_stable_h(complex(0.0, math.sqrt(w2))))


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
