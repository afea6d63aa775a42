"""The lagrange backend's control period: Dormand-Prince 5(4) (:mod:`legbench.backends.dopri`) over the generated
equations of motion, the contact law and the joint limits, compiled into one call (numba) or run as Python
(the reference).

:func:`period` binds :func:`_rhs` to one model's generated ``qdd`` (:mod:`legbench.backends.lagrange_eom`)
and the stepper to that right-hand side, and either compiles both or returns them as Python: one
implementation, the compiled and the Python periods agree to the last bit (tests). Compiled, numba inlines
``qdd`` (itself compiled and cached beside the generated module); the copies are named for the model's key,
so numba's disk cache holds one period per model (first compile about 2 s, a later process loads it in
about 0.2 s) and an edit of this file, the stepper, the law or the limit law recompiles it.

Units: q [rad], qd [rad/s], tau [N m], g [m/s^2], t [s].
"""

from __future__ import annotations

import types
from collections.abc import Callable
from typing import Any

from legbench import contact, jit
from legbench.backends import dopri, joint_limits

try:
    import numba
except ImportError:  # the backend runs its Python path and says so
    numba = None  # type: ignore[assignment]

__all__ = ["available", "period"]


def available() -> bool:
    """numba is installed."""
    return numba is not None


#: the model's forward dynamics, bound per model in the copies of :func:`_rhs` (:func:`period`)
qdd: Any = None


def _rhs(lc: Any, lim: Any, u: Any, g: float, y: Any, out: Any, data: Any) -> None:
    """d/dt (q, qd) = (qd, qdd) into ``out`` under the held torque u [N m], the law and the limits; ``qdd`` is
    the model's, bound by :func:`period` (``data``: unused)."""
    q1, q2, q3, qd1, qd2, qd3 = y[0], y[1], y[2], y[3], y[4], y[5]
    tc1, tc2, tc3, _f1, _f2, _f3 = contact.law_wrench(lc, q1, q2, q3, qd1, qd2, qd3)
    tl1, tl2, tl3 = joint_limits.limit_torques(lim, q1, q2, q3, qd1, qd2, qd3)
    a1, a2, a3 = qdd(q1, q2, q3, qd1, qd2, qd3, u[0] + tc1 + tl1, u[1] + tc2 + tl2, u[2] + tc3 + tl3, g)
    out[0], out[1], out[2], out[3], out[4], out[5] = qd1, qd2, qd3, a1, a2, a3


#: (model key, compiled) -> its period, in this process
_PERIODS: dict[tuple[str, bool], Any] = {}


def period(key: str, qdd: Callable[..., tuple[float, float, float]], compiled: bool = True) -> Callable[..., int]:
    """The control period of the model whose generated ``qdd`` this is (``key``: its chain key).

    ``period(key, qdd)(x, u, g, lc, lim, t_bound, rtol, atol, max_step, k, ())`` integrates x = (q [rad],
    qd [rad/s]) in place over ``t_bound`` [s] under the held torque u [N m], gravity g [m/s^2], the law of
    constants ``lc`` and the limits ``lim``, scratch ``k`` of shape (9, 6) (:func:`legbench.backends.dopri.bind`).
    ``compiled``: compiled with numba (the default), else the same code run as Python.
    """
    if (key, compiled) not in _PERIODS:
        tag = key[:16]
        namespace = dict(globals(), qdd=jit.njit(qdd) if compiled else qdd)
        rhs = types.FunctionType(_rhs.__code__, namespace, f"_rhs_{tag}")
        rhs.__qualname__ = f"_rhs_{tag}"
        if compiled:
            rhs = jit.njit(rhs, depends_on=(contact, joint_limits))
        sources = (contact, joint_limits, dopri, _rhs)  # what the compiled period holds, besides qdd (the key)
        _PERIODS[key, compiled] = dopri.bind(rhs, f"_period_lagrange_{tag}", compiled, sources)
    return _PERIODS[key, compiled]  # type: ignore[no-any-return]


# compiled into the right-hand side as they are: the law and the limits the Python path calls
jit.jitable(contact.law_wrench, joint_limits.limit_torques)
