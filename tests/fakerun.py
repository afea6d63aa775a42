"""Synthetic ``legbench run`` output directories for engine-free tests of compare, report and check.

A fake run follows the run-output contract exactly: ``DIR/run.json`` and one
``DIR/<backend>.parquet`` per backend with the columns t, q1..q3, qd1..qd3,
tau1..tau3, fx, fy, fz, ee_x, ee_y, ee_z, controller. Every backend starts
from the same smooth base signals; a per-backend function perturbs them.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from legbench import kinematics
from legbench.compare import LABELS

Transform = Callable[[np.ndarray, np.ndarray], np.ndarray]
Base = Callable[[np.ndarray], np.ndarray]

EVENTS = ({"t": 0.0, "controller": "position"}, {"t": 1.0, "controller": "effort"})


def base_signals(t: np.ndarray) -> np.ndarray:
    """Smooth, varying values of the 12 data columns at times t [s], shape (N, 12)."""
    w = 2 * np.pi
    q = np.column_stack([0.1 * np.sin(w * 0.5 * t), -1.0 + 0.3 * np.sin(w * t + 0.3), -1.2 + 0.2 * np.cos(w * 1.5 * t)])
    qd = np.column_stack(
        [0.1 * w * 0.5 * np.cos(w * 0.5 * t), 0.3 * w * np.cos(w * t + 0.3), -0.2 * w * 1.5 * np.sin(w * 1.5 * t)]
    )
    tau = np.column_stack([1.0 + 0.5 * np.sin(w * t), 2.0 * np.cos(w * 0.7 * t), -1.5 + np.sin(w * 2 * t)])
    force = np.column_stack([np.cos(w * t), 0.5 * np.sin(w * 0.3 * t), 20.0 + 5.0 * np.sin(w * 0.8 * t)])
    return np.hstack([q, qd, tau, force])


def frame(t: np.ndarray, data: np.ndarray, events: Sequence[Mapping[str, Any]] = EVENTS) -> pd.DataFrame:
    """The parquet table of one backend from its (N, 12) data block."""
    cols: dict[str, Any] = {"t": t}
    cols |= {c: data[:, i] for i, c in enumerate(LABELS)}
    ee = kinematics.fk(data[:, 0:3])
    cols |= {"ee_x": ee[:, 0], "ee_y": ee[:, 1], "ee_z": ee[:, 2]}
    starts = np.array([e["t"] for e in events])
    names = np.array([e["controller"] for e in events], dtype=object)
    idx = np.clip(np.searchsorted(starts, t, side="right") - 1, 0, len(names) - 1)
    cols["controller"] = names[idx].astype(str)
    return pd.DataFrame(cols)


def write_run(
    path: Path,
    backends: Mapping[str, Transform | None],
    *,
    name: str = "fake",
    duration: float = 2.0,
    rate: float = 1000.0,
    contact_mode: str = "native",
    poc: str = "true",
    reference: str = "ref",
    skip: float = 0.0,
    steady_window: float = 0.5,
    tolerances: Mapping[str, Any] | None = None,
    failed: Mapping[str, str] | None = None,
    base: Base = base_signals,
    events: Sequence[Mapping[str, Any]] = EVENTS,
    gravity: float | None = None,
) -> Path:
    """Write a fake run directory and return it.

    Args:
        path: the directory (created).
        backends: name -> transform(t, data) -> data of the base signals (None: unchanged).
        failed: name -> reason of backends listed as failed (no parquet written).
        Others: the run.json scenario fields of the same name.
    """
    path.mkdir(parents=True, exist_ok=True)
    t = np.arange(int(round(duration * rate)) + 1) / rate
    data = base(t)
    entries: dict[str, Any] = {}
    for bname, fn in backends.items():
        x = data.copy() if fn is None else fn(t, data.copy())
        frame(t, x, events).to_parquet(path / f"{bname}.parquet", index=False)
        entries[bname] = {
            "status": "ok",
            "reason": None,
            "info": {"engine": f"fake-{bname}", "version": "0.0", "settings": {"dt": 1e-4}},
            "wall_time": 0.5,
            "rtf": duration / 0.5,
            "file": f"{bname}.parquet",
        }
    for bname, reason in (failed or {}).items():
        entries[bname] = {"status": "failed", "reason": reason, "info": {"engine": f"fake-{bname}"}, "file": None}
    meta = {
        "scenario": {
            "name": name,
            "file": f"scenarios/{name}.yaml",
            "sha256": "0" * 64,
            "description": "synthetic run for tests",
            "duration": duration,
            "control_rate": rate,
            "contact_mode": contact_mode,
            "events": [dict(e) for e in events],
            "comparison": {
                "reference": reference,
                "skip": skip,
                "steady_window": steady_window,
                "tolerances": dict(tolerances or {}),
            },
            "contact": {"Kp": 1e4, "Kd": 100.0, "mu_s": 0.7, "mu_k": 0.6, "v_th": 0.01, "poc": poc},
            **({} if gravity is None else {"gravity": gravity}),
        },
        "backends": entries,
        "platform": {"python": "3.11", "machine": "test"},
        "legbench_version": "0.1.0",
    }
    (path / "run.json").write_text(json.dumps(meta, indent=1))
    return path


def add_to(col: str, fn: Callable[[np.ndarray], np.ndarray]) -> Transform:
    """A transform adding fn(t) to one column (by label, e.g. ``"tau2"``)."""
    i = LABELS.index(col)

    def tr(t: np.ndarray, x: np.ndarray) -> np.ndarray:
        x[:, i] += fn(t)
        return x

    return tr


def scale(k: float) -> Transform:
    """A transform multiplying every column by k."""
    return lambda t, x: k * x


def offset(c: float) -> Transform:
    """A transform adding c to every column."""
    return lambda t, x: x + c
