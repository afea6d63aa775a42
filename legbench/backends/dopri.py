"""Dormand-Prince 5(4) over one control period, for the backends that integrate their own equations
adaptively: scipy's ``solve_ivp(method="RK45")`` algorithm step for step, on preallocated arrays, one
implementation run compiled (numba) or as Python (the reference). (The stages are summed term by term where scipy
calls ``np.dot``: at the default tolerances the step sequences are the same; at rtol 1e-10 an error norm within
round-off of 1 can be accepted by one and rejected by the other, docs/lagrange.md.)

:func:`_period` is the algorithm: the same tableau, initial step selection (Hairer, Norsett, Wanner II.4),
local extrapolation, the RMS error norm scaled by atol + rtol max(|y|, |y_new|) (sqrt(sum x_i^2) / sqrt(n)
summed in index order, scipy's ``norm``), the same safety factor and step-size bounds, the last step cut to
end on the period. It calls a right-hand side ``_rhs(lc, lim, u, g, y, out, data)`` (the law's constants,
the limit law's, the held torque [N m], gravity [m/s^2], the state, dy/dt written into ``out``, and the
backend's own arrays) that :func:`bind` supplies: the lagrange backend's over its generated equations
(:mod:`legbench.backends.lagrange_kernel`), the Pinocchio backend's over its compiled ABA
(:mod:`legbench.backends.pinocchio_kernel`).
"""

from __future__ import annotations

import inspect
import math
import types
from collections.abc import Callable, Iterable
from typing import Any

import numpy as np

from legbench import jit

#: The smallest relative tolerance [1] scipy's RK45 and DOP853 take (``validate_tol`` raises a smaller one to it,
#: with a warning): the backends that solve adaptively refuse less, so that "scipy's RK45, step for step" holds.
RTOL_MIN = 100 * float(np.finfo(float).eps)

__all__ = ["bind", "rms", "stepper"]

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


def rms(x: Any) -> float:
    """RMS norm, scipy's ``norm``: sqrt(x_1^2 + ... + x_n^2) / sqrt(n), summed in index order."""
    s = 0.0
    for v in x:
        s += v * v
    return math.sqrt(s) / math.sqrt(len(x))


#: the right-hand side, bound per use in the copies :func:`bind` makes
_rhs: Any = None


def _period(x: np.ndarray, u: np.ndarray, g: float, lc: np.ndarray, lim: np.ndarray, t_bound: float, rtol: float,
            atol: float, max_step: float, k: np.ndarray, data: Any) -> int:  # fmt: skip
    """One control period over the bound ``_rhs`` (see :func:`bind`)."""
    k1, k2, k3, k4, k5, k6, k7, ys, w = k[0], k[1], k[2], k[3], k[4], k[5], k[6], k[7], k[8]
    n = x.shape[0]
    _rhs(lc, lim, u, g, x, k1, data)
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
    _rhs(lc, lim, u, g, ys, k2, data)
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
            _rhs(lc, lim, u, g, ys, k2, data)
            for i in range(n):
                ys[i] = x[i] + (A31 * k1[i] + A32 * k2[i]) * h
            _rhs(lc, lim, u, g, ys, k3, data)
            for i in range(n):
                ys[i] = x[i] + (A41 * k1[i] + A42 * k2[i] + A43 * k3[i]) * h
            _rhs(lc, lim, u, g, ys, k4, data)
            for i in range(n):
                ys[i] = x[i] + (A51 * k1[i] + A52 * k2[i] + A53 * k3[i] + A54 * k4[i]) * h
            _rhs(lc, lim, u, g, ys, k5, data)
            for i in range(n):
                ys[i] = x[i] + (A61 * k1[i] + A62 * k2[i] + A63 * k3[i] + A64 * k4[i] + A65 * k5[i]) * h
            _rhs(lc, lim, u, g, ys, k6, data)
            for i in range(n):
                ys[i] = x[i] + h * (B1 * k1[i] + B3 * k3[i] + B4 * k4[i] + B5 * k5[i] + B6 * k6[i])
            _rhs(lc, lim, u, g, ys, k7, data)
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


def _bound(fn: Any, name: str, namespace: dict[str, Any]) -> Any:
    """A copy of the plain function ``fn`` whose globals are ``namespace`` and whose qualified name is ``name``."""
    copy = types.FunctionType(fn.__code__, namespace, name, fn.__defaults__, fn.__closure__)
    copy.__qualname__ = name
    return copy


def bind(rhs: Callable[..., None], name: str, compiled: bool, depends_on: Iterable[Any] = ()) -> Callable[..., int]:
    """:func:`_period` over the right-hand side ``rhs``: compiled with numba (disk-cached), else as Python.

    The period is ``period(x, u, g, lc, lim, t_bound, rtol, atol, max_step, k, data)``: x (n states) integrated
    in place from 0 to ``t_bound`` [s], scratch ``k`` of shape (9, n), ``data`` handed to ``rhs``; it returns
    the number of right-hand-side evaluations, or -1 where the step size fell below 10 ulp of t (scipy's
    "Required step size is less than spacing between numbers"). Compiled, ``rhs`` must be compiled already
    (numba inlines it), and numba's cache holds the copy under ``name`` plus a hash of the sources of
    ``depends_on`` (the modules whose code ``rhs`` compiles in): another right-hand side needs another
    ``name``, and an edit of any of those sources gives a new entry instead of a stale one.
    """
    files = sorted({inspect.getfile(m) for m in depends_on})
    full = f"{name}_{jit.sources_hash(files)[:12]}" if files else name
    copy = _bound(_period, full, dict(globals(), _rhs=rhs))
    return jit.njit(copy) if compiled else copy  # type: ignore[no-any-return]


def stepper(rhs: Callable[..., None]) -> Callable[..., int]:
    """:func:`_period` run as Python over another right-hand side (any number of states): for checking the
    stepper against scipy on other problems."""
    return bind(rhs, "_period_custom", compiled=False)


jit.jitable(rms)
