"""Signals of a run, their components, units and log columns.

A *signal* is one of ``q`` [rad], ``qd`` [rad/s], ``tau`` [N m] (after
saturation) and ``force`` [N] (the ground force on the foot, in W); ``ee`` is
the foot centre in W [m], derived from q. Its *joints* (components) are
``"1"``, ``"2"``, ``"3"``, or ``"x"``, ``"y"``, ``"z"`` for the force (``z`` is
Fn). The 12 data columns of a run, in order, are :data:`LABELS`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

__all__ = [
    "COLUMNS",
    "EE_COLUMNS",
    "JOINTS",
    "JOINT_OF",
    "LABELS",
    "RUN_COLUMNS",
    "SIGNALS",
    "SIGNAL_OF",
    "SLICE",
    "UNITS",
    "keyed",
    "label",
]

#: Signals compared, in the order of a run's data columns.
SIGNALS = ("q", "qd", "tau", "force")
#: Units of each signal.
UNITS = {"q": "rad", "qd": "rad/s", "tau": "N m", "force": "N", "ee": "m", "t": "s"}
#: Component names of each signal ("joint" column of the metrics table).
JOINTS = {"q": ("1", "2", "3"), "qd": ("1", "2", "3"), "tau": ("1", "2", "3"), "force": ("x", "y", "z")}
#: Parquet/CSV column names of each signal.
COLUMNS = {
    "q": ("q1", "q2", "q3"),
    "qd": ("qd1", "qd2", "qd3"),
    "tau": ("tau1", "tau2", "tau3"),
    "force": ("fx", "fy", "fz"),
    "ee": ("ee_x", "ee_y", "ee_z"),
}
#: The 12 data columns of a run, in order (q1..q3, qd1..qd3, tau1..tau3, fx, fy, fz).
LABELS: tuple[str, ...] = tuple(c for s in SIGNALS for c in COLUMNS[s])
#: Signal and joint of each of the 12 data columns.
SIGNAL_OF = tuple(s for s in SIGNALS for _ in range(3))
JOINT_OF = tuple(j for s in SIGNALS for j in JOINTS[s])
#: Data columns of each signal.
SLICE = {s: slice(3 * i, 3 * i + 3) for i, s in enumerate(SIGNALS)}
#: Foot-centre columns of a log [m].
EE_COLUMNS = COLUMNS["ee"]
#: Every column of a backend's log file, in file order.
RUN_COLUMNS = ("t", *LABELS, *EE_COLUMNS, "controller")


def label(signal: str, joint: str) -> str:
    """Short column label of a signal component: ``q2``, ``tau1``, ``fz``."""
    return f"f{joint}" if signal == "force" else f"{signal}{joint}"


def keyed(layers: Sequence[Any], signal: str, joint: str, default: float) -> float:
    """A per-component setting (a tolerance, a ceiling) from the first of ``layers`` that gives it.

    ``layers`` run from the most specific (a scenario's own) to the least (legbench's defaults); a layer
    is a number (every component), a mapping keyed by component label (``tau2``), signal (``tau``) or
    ``default``, most specific key first, or None (it gives nothing). A layer that gives a value wins
    over every layer after it, whatever keys those hold: a file's ``{default: 1e-6}`` overrides a
    default of ``{force: 1e-2}``. ``default`` if no layer gives one.
    """
    lab = label(signal, joint)
    for spec in layers:
        if spec is None:
            continue
        if not isinstance(spec, Mapping):
            return float(spec)
        for key in (lab, signal, "default"):
            if key in spec:
                return float(spec[key])
    return default
