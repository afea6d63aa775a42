"""External logs (hardware, another simulator such as Gazebo) read as one more backend.

A CSV log is matched to legbench's columns by header name and becomes a
DataFrame of :data:`~legbench.signals.RUN_COLUMNS` (then a
:class:`~legbench.results.RunResult` in :func:`legbench.compare.compare`).
"""

from __future__ import annotations

import logging
import math
import re
from collections.abc import Mapping
from pathlib import Path

import numpy as np
import pandas as pd

from legbench.exceptions import LegbenchError, ResultsError
from legbench.results import result_from_frame
from legbench.signals import EE_COLUMNS, LABELS, RUN_COLUMNS

logger = logging.getLogger("legbench.logs")

__all__ = ["load_log"]

#: Header names (after unit stripping, lower case) taken for legbench columns.
ALIASES = {"time": "t", "fn": "fz", "f_x": "fx", "f_y": "fy", "f_z": "fz"}


def _normalise_header(col: str) -> str:
    """``"q1 [rad]"`` -> ``"q1"``; ``" Fz (N)"`` -> ``"fz"``; ``"time"`` -> ``"t"``."""
    base = re.sub(r"\s*[\[(].*?[\])]\s*$", "", str(col)).strip().lower()
    return ALIASES.get(base, base)


#: Largest magnitude a logged value may have [SI units]: beyond it the column is not a physical signal.
PLAUSIBLE_MAX = 1e9


def _check_plausible(t: np.ndarray, data: np.ndarray, source: str) -> None:
    """Refuse a log with no finite joint angle or with values no leg produces; warn, with the evidence, on
    units that look wrong (time in ms, angles in degrees)."""
    q = data[:, 0:3]
    if not np.isfinite(q).any():
        raise ResultsError(source, "q1..q3 hold no finite value (NaN only): nothing to compare")
    finite = np.abs(np.where(np.isfinite(data), data, 0.0))
    if finite.max(initial=0.0) > PLAUSIBLE_MAX:
        i, j = np.unravel_index(int(np.argmax(finite)), finite.shape)
        raise ResultsError(source, f"column '{LABELS[j]}' reaches {data[i, j]:.3g} at row {i + 1}: not a physical "
                                   f"value (limit {PLAUSIBLE_MAX:g})")  # fmt: skip
    step = float(np.median(np.diff(t))) if len(t) > 1 else 0.0
    if step > 0.1:
        logger.warning("legbench: warning: %s: median time step %.4g s: is the time in ms? (--log-time-scale 1e-3)",
                       source, step)  # fmt: skip
    qmax = float(np.nanmax(np.abs(q)))
    if qmax > 2 * np.pi + 0.1:
        logger.warning("legbench: warning: %s: joint angles reach %.4g: above 2 pi rad, are they in degrees? "
                       "legbench logs radians", source, qmax)  # fmt: skip


def load_log(path: str | Path, column_map: Mapping[str, str] | None = None, time_scale: float = 1.0) -> pd.DataFrame:
    """Read an external CSV log into the run columns, as one more "backend".

    Header names are matched to :data:`RUN_COLUMNS` case-insensitively, with a
    trailing unit in brackets or parentheses ignored (``"q1 [rad]"`` is ``q1``;
    ``time`` is ``t``). ``column_map`` maps other names, ``{"their name": "q1"}``,
    and wins over the automatic match. Only ``t`` and ``q1..q3`` are required;
    other missing signals become NaN and are left out of the metrics.

    Args:
        path: the CSV file.
        column_map: header name in the file -> legbench column name.
        time_scale: factor taking the file's time unit to seconds (1e-3 for ms).

    Returns:
        DataFrame with the columns of :data:`RUN_COLUMNS` (controller "" if absent).

    Raises:
        ResultsError: the file is missing or unreadable, a mapped column is absent,
            two columns map to one name, a required column is missing, a value is not
            numeric or time is not strictly increasing.
    """
    path = Path(path)
    if not (math.isfinite(time_scale) and time_scale > 0):
        raise LegbenchError(f"--log-time-scale {time_scale!r}: must be a finite number > 0 (1e-3 for ms)")
    if not path.is_file():
        raise ResultsError(str(path), "no such log file")
    try:
        raw = pd.read_csv(path)
    except Exception as exc:  # parser errors come in several types
        raise ResultsError(str(path), f"not a readable CSV file ({type(exc).__name__}: {exc})") from exc
    cmap = dict(column_map or {})
    unknown_targets = sorted(set(cmap.values()) - set(RUN_COLUMNS))
    if unknown_targets:
        raise ResultsError(
            str(path), f"column_map targets {unknown_targets} are not legbench columns {list(RUN_COLUMNS)}"
        )
    absent = sorted(set(cmap) - set(map(str, raw.columns)))
    if absent:
        raise ResultsError(str(path), f"column_map names {absent} are not in the header {list(map(str, raw.columns))}")
    rename: dict[str, str] = {}
    for col in map(str, raw.columns):
        target = cmap.get(col) or _normalise_header(col)
        if target in RUN_COLUMNS:
            rename[col] = target
    targets = list(rename.values())
    dupes = sorted({c for c in targets if targets.count(c) > 1})
    if dupes:
        raise ResultsError(str(path), f"several header columns map to {dupes}; pass column_map to choose")
    df = raw[list(rename)].rename(columns=rename)
    required = ["t", "q1", "q2", "q3"]
    trace = result_from_frame(df, path.stem, str(path), required)  # validates
    _check_plausible(trace.t * time_scale, trace.data, str(path))
    out = {"t": trace.t * time_scale}
    out |= {c: trace.data[:, i] for i, c in enumerate(LABELS)}
    out |= {c: trace.ee[:, i] for i, c in enumerate(EE_COLUMNS)}
    out["controller"] = trace.controller.astype(str) if "controller" in df.columns else np.full(len(df), "")
    return pd.DataFrame(out, columns=list(RUN_COLUMNS))
