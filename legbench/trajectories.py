"""Task-space paths of the tasks: the ellipse of the ellipse task, as waypoints in W.

Pure geometry of the leg's workspace (from the parameter file); the
trajectory controller (:mod:`legbench.controllers`) interpolates the
waypoints in joint space.
"""

from __future__ import annotations

import numpy as np

from legbench.model import load_params

__all__ = ["ellipse_waypoints"]


def ellipse_waypoints(
    a: float, b: float, DY: float, DZ: float, dth: float, T: float, points: int, repetitions: int, approach: float
) -> tuple[np.ndarray, np.ndarray]:
    """Waypoints of the ellipse task in W [m] and their times after activation [s].

    Polar form r(th) = a b / sqrt(a^2 sin^2(th - dth) + b^2 cos^2(th - dth)),
    W_P = r(th) [0, cos th, sin th] + [L_B0 + L12, DY, DZ]; ``points`` per period
    ``T``, ``repetitions`` laps; the first point is reached after ``approach``.
    """
    g = load_params().geometry
    k = np.arange(points * repetitions + 1)
    th = 2.0 * np.pi * k / points
    r = a * b / np.sqrt(a**2 * np.sin(th - dth) ** 2 + b**2 * np.cos(th - dth) ** 2)
    P = np.stack([np.full_like(th, g.L_B0 + g.L_12), DY + r * np.cos(th), DZ + r * np.sin(th)], axis=1)
    times = approach + k * T / points
    return P, times
