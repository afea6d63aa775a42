"""The lagrange backend's control period: Dormand-Prince 5(4) over the generated equations of motion, the
contact law and the joint limits, compiled into one call (numba) or run as Python (the reference).

* :func:`_period` is scipy's ``solve_ivp(method="RK45")`` algorithm step for step (the same tableau, initial
  step selection (Hairer, Norsett, Wanner II.4), local extrapolation, the RMS error norm scaled by
  atol + rtol max(|y|, |y_new|), the same safety factor and step-size bounds, the last step cut to end on
  the period), on preallocated arrays; :func:`_rhs` is the right-hand side: the law of
  :func:`legbench.contact.law_wrench`, the limits of :func:`legbench.backends.joint_limits.limit_torques` and
  the model's generated ``qdd`` (:mod:`legbench.backends.lagrange_eom`).
* :func:`period` binds the two to one model's ``qdd`` and either compiles them (numba's disk cache, per
  model: ``qdd`` beside the generated module, the period as a copy named for the model's key; first compile
  about 2 s, a later process loads it in about 0.2 s) or returns them as Python. One implementation: the
  compiled and the Python periods are the same code, and agree to the last bit (tests).
* The RMS norm is sqrt(sum x_i^2) / sqrt(n) summed in index order (scipy's ``norm``).

Units: q [rad], qd [rad/s], tau [N m], g [m/s^2], t [s].
"""

from __future__ import annotations

import math
import types
from collections.abc import Callable
from typing import Any

import numpy as np

from legbench import contact, jit
from legbench.backends import joint_limits

try:
    import numba
except ImportError:  # the backend runs its Python path and says so
    numba = None  # type: ignore[assignment]

__all__ = ["available", "period", "rms", "stepper"]

# Dormand-Prince 5(4), the tableau of scipy.integrate.RK45 (and of MATLAB's ode45); b2 = e2 = 0.
A21 = 1 / 5
A31, A32 = 3 / 40, 9 / 40
A41, A42, A43 = 44 / 45, -56 / 15, 32 / 9
A51, A52, A53, A54 = 19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729
A61, A62, A63, A64, A65 = 9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656
B1, B3, B4, B5, B6 = 35 / 384, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84
E1, E3, E4, E5, E6, E7 = -71 / 57600, 71 / 16695, -71 / 1920, 17253 / 339200, -22 / 525, 1 / 40
# scipy's step-size control (scipy/integrate/_ivp/rk.py): safety, min and max factor, -1/(4 + 1)
SAFETY, MIN_FACTOR, MAX_FACTOR, EXPONENT = 0.9, 0.2, 10.0, -1 / 5


def available() -> bool:
    """numba is installed."""
    return numba is not None


def rms(x: Any) -> float:
    """RMS norm, scipy's ``norm``: sqrt(x_1^2 + ... + x_n^2) / sqrt(n), summed in index order."""
    s = 0.0
    for v in x:
        s += v * v
    return math.sqrt(s) / math.sqrt(len(x))


#: the model's forward dynamics, bound per model in the compiled copies of the two functions below (:func:`period`)
qdd: Any = None


def _rhs(lc: Any, lim: Any, u: Any, g: float, y: Any, out: Any) -> None:
    """d/dt (q, qd) = (qd, qdd) into ``out`` under the held torque u [N m], the law and the limits; ``qdd`` is
    the model's, bound by :func:`period`."""
    q1, q2, q3, qd1, qd2, qd3 = y[0], y[1], y[2], y[3], y[4], y[5]
    tc1, tc2, tc3, _f1, _f2, _f3 = contact.law_wrench(lc, q1, q2, q3, qd1, qd2, qd3)
    tl1, tl2, tl3 = joint_limits.limit_torques(lim, q1, q2, q3, qd1, qd2, qd3)
    a1, a2, a3 = qdd(q1, q2, q3, qd1, qd2, qd3, u[0] + tc1 + tl1, u[1] + tc2 + tl2, u[2] + tc3 + tl3, g)
    out[0], out[1], out[2], out[3], out[4], out[5] = qd1, qd2, qd3, a1, a2, a3


def _period(x: np.ndarray, u: np.ndarray, g: float, lc: np.ndarray, lim: np.ndarray, t_bound: float, rtol: float,
            atol: float, max_step: float, k: np.ndarray) -> int:  # fmt: skip
    """One control period (see :func:`period`); the model's ``_rhs`` is bound by :func:`period`."""
    k1, k2, k3, k4, k5, k6, k7, ys, w = k[0], k[1], k[2], k[3], k[4], k[5], k[6], k[7], k[8]
    n = x.shape[0]
    _rhs(lc, lim, u, g, x, k1)
    # initial step (scipy.integrate._ivp.common.select_initial_step, order 4)
    for i in range(n):
        w[i] = x[i] / (atol + abs(x[i]) * rtol)
    d0 = rms(w)
    for i in range(n):
        w[i] = k1[i] / (atol + abs(x[i]) * rtol)
    d1 = rms(w)
    h0 = 1e-6 if d0 < 1e-5 or d1 < 1e-5 else 0.01 * d0 / d1
    h0 = min(h0, t_bound)
    for i in range(n):
        ys[i] = x[i] + h0 * k1[i]
    _rhs(lc, lim, u, g, ys, k2)
    for i in range(n):
        w[i] = (k2[i] - k1[i]) / (atol + abs(x[i]) * rtol)
    d2 = rms(w) / h0
    if d1 <= 1e-15 and d2 <= 1e-15:
        h1 = max(1e-6, h0 * 1e-3)
    else:
        h1 = (0.01 / max(d1, d2)) ** (1 / 5)
    h_abs = min(100 * h0, h1, t_bound, max_step)
    nfev = 2
    t = 0.0
    while t < t_bound:
        min_step = 10 * abs(np.nextafter(t, np.inf) - t)
        if h_abs > max_step:
            h_abs = max_step
        elif h_abs < min_step:
            h_abs = min_step
        rejected = False
        while True:
            if h_abs < min_step:
                return -1
            t_new = t + h_abs
            if t_new > t_bound:
                t_new = t_bound
            h = t_new - t
            h_abs = abs(h)
            for i in range(n):
                ys[i] = x[i] + (A21 * k1[i]) * h
            _rhs(lc, lim, u, g, ys, k2)
            for i in range(n):
                ys[i] = x[i] + (A31 * k1[i] + A32 * k2[i]) * h
            _rhs(lc, lim, u, g, ys, k3)
            for i in range(n):
                ys[i] = x[i] + (A41 * k1[i] + A42 * k2[i] + A43 * k3[i]) * h
            _rhs(lc, lim, u, g, ys, k4)
            for i in range(n):
                ys[i] = x[i] + (A51 * k1[i] + A52 * k2[i] + A53 * k3[i] + A54 * k4[i]) * h
            _rhs(lc, lim, u, g, ys, k5)
            for i in range(n):
                ys[i] = x[i] + (A61 * k1[i] + A62 * k2[i] + A63 * k3[i] + A64 * k4[i] + A65 * k5[i]) * h
            _rhs(lc, lim, u, g, ys, k6)
            for i in range(n):
                ys[i] = x[i] + h * (B1 * k1[i] + B3 * k3[i] + B4 * k4[i] + B5 * k5[i] + B6 * k6[i])
            _rhs(lc, lim, u, g, ys, k7)
            nfev += 6
            for i in range(n):
                w[i] = ((E1 * k1[i] + E3 * k3[i] + E4 * k4[i] + E5 * k5[i] + E6 * k6[i] + E7 * k7[i]) * h
                        / (atol + max(abs(x[i]), abs(ys[i])) * rtol))  # fmt: skip
            error_norm = rms(w)
            if error_norm < 1:
                factor = MAX_FACTOR if error_norm == 0 else min(MAX_FACTOR, SAFETY * error_norm**EXPONENT)
                if rejected:
                    factor = min(1.0, factor)
                h_abs *= factor
                break
            h_abs *= max(MIN_FACTOR, SAFETY * error_norm**EXPONENT)
            rejected = True
        t = t_new
        for i in range(n):
            x[i] = ys[i]
            k1[i] = k7[i]
    return nfev


#: (model key, compiled) -> its period, in this process
_PERIODS: dict[tuple[str, bool], Any] = {}


def _bound(fn: Any, name: str, namespace: dict[str, Any]) -> Any:
    """A copy of the plain function ``fn`` whose globals are ``namespace`` and whose qualified name is ``name``."""
    copy = types.FunctionType(fn.__code__, namespace, name, fn.__defaults__, fn.__closure__)
    copy.__qualname__ = name
    return copy


def period(key: str, qdd: Callable[..., tuple[float, float, float]], compiled: bool = True) -> Callable[..., int]:
    """The control period of the model whose generated ``qdd`` this is (``key``: its chain key).

    ``period(key, qdd)(x, u, g, lc, lim, t_bound, rtol, atol, max_step, k)`` integrates x = (q [rad],
    qd [rad/s]) in place from 0 to ``t_bound`` [s] under the held torque u [N m], gravity g [m/s^2], the law
    of constants ``lc`` and the limits ``lim``, with scratch ``k`` of shape (9, 6); it returns the number of
    right-hand-side evaluations, or -1 where the step size fell below 10 ulp of t (scipy's "Required step
    size is less than spacing between numbers").

    ``compiled``: :func:`_period` and :func:`_rhs` compiled with numba (the default), else the same two
    functions run as Python (the reference, and the path without numba). Both are bound to this ``qdd`` as
    copies whose globals hold it. Compiled, numba inlines ``qdd`` (itself compiled and cached beside the
    generated module), and the copies' names carry the key (``_period_<key>``): numba's disk cache is indexed
    by the function's name and stamped with this file's source (and the law's and the limits',
    :func:`legbench.jit.njit`), so each model has its own cached period and an edit recompiles it.
    """
    if (key, compiled) not in _PERIODS:
        tag = key[:16]
        if compiled:
            namespace = dict(globals(), qdd=jit.njit(qdd))
            namespace["_rhs"] = jit.njit(_bound(_rhs, f"_rhs_{tag}", namespace), depends_on=(contact, joint_limits))
            fn = jit.njit(_bound(_period, f"_period_{tag}", namespace), depends_on=(contact, joint_limits))
        else:
            namespace = dict(globals(), qdd=qdd)
            namespace["_rhs"] = _bound(_rhs, f"_rhs_{tag}", namespace)
            fn = _bound(_period, f"_period_{tag}", namespace)
        _PERIODS[key, compiled] = fn
    return _PERIODS[key, compiled]  # type: ignore[no-any-return]


def stepper(rhs: Callable[..., None]) -> Callable[..., int]:
    """:func:`_period` run as Python over another right-hand side ``rhs(lc, lim, u, g, y, out)`` writing dy/dt
    into ``out`` (any number of states): the same stepper, for checking it against scipy on other problems."""
    namespace = dict(globals(), _rhs=rhs)
    return _bound(_period, "_period_custom", namespace)  # type: ignore[no-any-return]


# compiled into the period as they are: the law and the limits the Python path calls, the norm it uses
jit.jitable(contact.law_wrench, joint_limits.limit_torques, rms)
