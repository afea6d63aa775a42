"""The run loop's control tick in one compiled call: divergence checks, the controller's law, saturation, log.

:func:`control_tick` is what :func:`legbench.run.simulate` does between reading a backend and stepping
it, on plain floats and arrays: check the state (finite, joint speeds, foot height), evaluate the active
controller's law (:func:`legbench.controllers.control_law`, the one implementation, compiled in),
saturate the torque at the joint limits and write the tick's row of the (n, 12) log (q, qd, f, tau)
and the torque buffer the backend is stepped with.
numba compiles it (:mod:`legbench.jit`; without numba it runs as Python, the same numbers): one call of
well under a microsecond where the same work in Python bytecode costs several, so the harness stays a
small fraction of an engine's step.

Units: q [rad], qd [rad/s], f in W [N], tau [N m], lengths [m].
"""

from __future__ import annotations

import math

import numpy as np

from legbench import controllers, jit, kinematics
from legbench.controllers import control_law
from legbench.model import Geometry

__all__ = ["NOT_FINITE", "OK", "TOO_DEEP", "TOO_FAST", "constants", "control_tick", "tick"]

#: :func:`control_tick`'s return codes: the row was written, or why the state is diverged (nothing written)
OK, NOT_FINITE, TOO_FAST, TOO_DEEP = 0, 1, 2, 3

# the constants array: torque limits [N m], L_12, L_23, L_3E, H [m], lowest foot-centre height [m],
# highest joint speed [rad/s]
C_LIM, C_L12, C_L23, C_L3E, C_H, C_ZMIN, C_VMAX, C_SIZE = 0, 3, 4, 5, 6, 7, 8, 9


def constants(torque_limit: tuple[float, ...], g: Geometry, z_min: float, v_max: float) -> np.ndarray:
    """The tick's constants: torque limits [N m], the lengths its foot-height check needs [m], the lowest
    foot-centre height before the run counts as diverged [m], the highest joint speed [rad/s]."""
    c = np.empty(C_SIZE)
    c[C_LIM : C_LIM + 3] = torque_limit
    c[C_L12], c[C_L23], c[C_L3E], c[C_H] = g.L_12, g.L_23, g.L_3E, g.H
    c[C_ZMIN], c[C_VMAX] = z_min, v_max
    return c


def control_tick(
    k: int, q1: float, q2: float, q3: float, qd1: float, qd2: float, qd3: float, f1: float, f2: float, f3: float,
    p: np.ndarray, s: np.ndarray, c: np.ndarray, log: np.ndarray, u: np.ndarray,
) -> int:  # fmt: skip
    """One control tick k: check the measured state, compute and saturate the torque, write log row k.

    Args:
        k: the tick (t = k Ts).
        q1..q3, qd1..qd3, f1..f3: the backend's reading: q [rad], qd [rad/s], the ground force on the
            foot in W [N].
        p, s: the active controller's ``params`` and ``state`` (``state`` is updated).
        c: :func:`constants`.
        log: the (n, 12) log; row k gets (q, qd, f, tau) with tau saturated at +-limit (NaN passes).
        u: (3,): gets the same saturated tau [N m], the buffer the loop hands the backend.

    Returns:
        :data:`OK`, or the first check the state fails (:data:`NOT_FINITE`, :data:`TOO_FAST`,
        :data:`TOO_DEEP`: foot-centre height z_W below the limit), with row k left unwritten.
    """
    if not math.isfinite(q1 + q2 + q3 + qd1 + qd2 + qd3 + f1 + f2 + f3):
        return NOT_FINITE
    v_max = c[C_VMAX]
    if abs(qd1) > v_max or abs(qd2) > v_max or abs(qd3) > v_max:
        return TOO_FAST
    z = c[C_L12] * math.sin(q1) + math.cos(q1) * (c[C_L23] * math.sin(q2) + c[C_L3E] * math.sin(q2 + q3)) + c[C_H]
    if z < c[C_ZMIN]:
        return TOO_DEEP
    u1, u2, u3 = control_law(k, q1, q2, q3, qd1, qd2, qd3, p, s)
    lim1, lim2, lim3 = c[C_LIM], c[C_LIM + 1], c[C_LIM + 2]
    log[k, 0], log[k, 1], log[k, 2] = q1, q2, q3
    log[k, 3], log[k, 4], log[k, 5] = qd1, qd2, qd3
    log[k, 6], log[k, 7], log[k, 8] = f1, f2, f3
    u[0] = log[k, 9] = -lim1 if u1 < -lim1 else (lim1 if u1 > lim1 else u1)
    u[1] = log[k, 10] = -lim2 if u2 < -lim2 else (lim2 if u2 > lim2 else u2)
    u[2] = log[k, 11] = -lim3 if u3 < -lim3 else (lim3 if u3 > lim3 else u3)
    return OK


jit.jitable(*kinematics.SCALAR, *controllers.LAWS)
#: :func:`control_tick` compiled (or itself without numba): what the run loop calls
tick = jit.njit(control_tick, depends_on=(controllers, kinematics))
