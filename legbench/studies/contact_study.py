"""Steady-contact measurements of one run: the numbers the contact profiles are chosen and checked by.

:func:`steady_contact` reduces a logged run (t, q, qd, tau, ground force) to the
quantities docs/contact_mapping.md tabulates per profile and setting: mean
ground force over the final window, its standard deviation (chatter, and any drift over the window), the
mean joint velocities (creep), how far the foot moved after the first 50 ms,
and the read-out error against the leg's own statics
F = -(J_poc^T)^-1 (tau - G(q)) (the force of the ground on the foot in W).
:func:`run_case` runs a scenario on one backend with a profile and settings;
``python -m legbench.studies.contact_study`` prints the table of a grid (the study of
``scenarios/sweeps/contact_profiles.yaml``, with these columns).
"""

from __future__ import annotations

import argparse
import itertools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from legbench import backends as registry
from legbench import kinematics, metrics
from legbench import scenario as scenario_mod
from legbench.backends.base import contact_point
from legbench.exceptions import LegbenchError
from legbench.results import RunResult
from legbench.run import physics_of, simulate

#: Motion of the foot centre counted from this time on [s] (the first 50 ms settle the contact).
SETTLE = 0.05


@dataclass(frozen=True)
class SteadyContact:
    """Steady-contact summary of one run.

    Attributes:
        force: mean ground force on the foot in W over the final window (Fx, Fy, Fn) [N].
        force_std: standard deviation of each component over the window [N].
        statics: F = -(J_poc^T)^-1 (tau - G(q)) at the window's mean q and tau, in W [N]
            (:func:`legbench.metrics.steady_state`).
        readout_error: max_k |force_k - statics_k| / Fn over the three components [1].
        qd: mean joint velocities over the window [rad/s].
        foot_travel: largest horizontal distance of the foot centre from its position at
            :data:`SETTLE` over the rest of the run [m].
        foot_drift: horizontal distance of the foot centre at the end from where it was at
            :data:`SETTLE` [m].
    """

    force: np.ndarray
    force_std: np.ndarray
    statics: np.ndarray
    readout_error: float
    qd: np.ndarray
    foot_travel: float
    foot_drift: float

    @property
    def qd_norm(self) -> float:
        """|mean qd| [rad/s]."""
        return float(np.linalg.norm(self.qd))


def steady_contact(tr: RunResult, window: float = 0.5, point: tuple[str, float] = ("true", 0.0),
                   gravity: float | None = None) -> SteadyContact:  # fmt: skip
    """Summarise the final ``window`` [s] of run ``tr`` (the closed interval metrics.steady_state takes); the
    statics at ``point``, where the backend's force acts (``(poc, lift)``,
    :func:`~legbench.backends.base.contact_point`), with G(q) for the run's ``gravity`` [m/s^2] (None: the leg
    file's): metrics.steady_state's analytic force check, the one implementation of it."""
    ss = metrics.steady_state(tr, window, point[0], gravity, lift=point[1])
    sel = (tr.t >= ss.t0 - metrics.T_EPS) & (tr.t <= ss.t1 + metrics.T_EPS)
    f = tr.f[sel]
    # deviations from the window's first sample: numpy's mean over axis 0 of an N x 3 log sums row
    # by row, so mean and std of the raw samples carry round-off of the force's size (a bit-constant
    # 52.5 N read 2.3e-13 N std, 33 ulp); of the deviations they are exact for a constant force and
    # at the fluctuation's own scale otherwise (std is shift-invariant)
    dev = f - f[0]
    mean_f = f[0] + dev.mean(axis=0)
    statics = ss.force - ss.residual  # the analytic force at the backend's point
    fn = abs(float(mean_f[2])) or math.nan
    ee = kinematics.fk(tr.q)[:, :2]
    later = tr.t >= SETTLE - 1e-9
    d = np.linalg.norm(ee[later] - ee[later][0], axis=1)
    return SteadyContact(
        force=mean_f,
        force_std=dev.std(axis=0),
        statics=statics,
        readout_error=float(np.max(np.abs(mean_f - statics)) / fn),
        qd=tr.qd[sel].mean(axis=0),
        foot_travel=float(d.max()),
        foot_drift=float(d[-1]),
    )


def run_case(scenario: str | Path, backend: str, profile: str = "matched", settings: Mapping[str, Any] | None = None,
             overrides: Mapping[str, Any] | None = None, window: float | None = None) -> SteadyContact:  # fmt: skip
    """Run ``scenario`` on ``backend`` (native contact unless overridden) and summarise its steady contact.

    Args:
        scenario: scenario file.
        backend: backend name.
        profile: settings profile of the backend.
        settings: backend settings over the profile.
        overrides: dotted scenario keys (e.g. ``physics.contact.v_th``).
        window: final window [s]; default the scenario's ``comparison.steady_window``.
    """
    sc = scenario_mod.load(scenario, overrides)
    physics = physics_of(sc)
    b = registry.load(backend, physics, dict(settings or {}), profile)
    try:
        tr = simulate(sc, b, physics)
    finally:
        b.close()
    if tr.status != "ok":
        raise LegbenchError(f"{backend} {profile} {settings}: {tr.status}: {tr.reason}")
    w = window if window is not None else sc.comparison.steady_window
    return steady_contact(tr, w, contact_point(tr.info, physics.contact.poc), physics.gravity)


def table(rows: Sequence[tuple[str, SteadyContact]]) -> str:
    """A markdown table of labelled summaries."""
    head = ("| case | Fn [N] | Fx [N] | Fy [N] | std Fx, Fy [N] | read-out err [% Fn] | steady qd [rad/s] "
            "| foot travel [mm] |\n|---|---|---|---|---|---|---|---|")  # fmt: skip
    lines = [head]
    for label, s in rows:
        lines.append(
            f"| {label} | {s.force[2]:.2f} | {s.force[0]:.2f} | {s.force[1]:.2f} | "
            f"{s.force_std[0]:.3g}, {s.force_std[1]:.3g} | {100 * s.readout_error:.3g} | "
            f"({s.qd[0]:.2g}, {s.qd[1]:.2g}, {s.qd[2]:.2g}) | {1e3 * s.foot_travel:.3g} |"
        )
    return "\n".join(lines)


def _value(text: str) -> Any:
    """A grid value: a number where it parses as one (YAML 1.1 reads ``1e-4`` as text), else YAML."""
    try:
        return int(text)
    except ValueError:
        pass
    try:
        return float(text)
    except ValueError:
        return yaml.safe_load(text)


def main(argv: Sequence[str] | None = None) -> None:
    """``python -m legbench.studies.contact_study SCENARIO BACKEND [--profile P] [--grid key=v1,v2 ...]``."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenario")
    ap.add_argument("backend")
    ap.add_argument("--profile", default="matched")
    ap.add_argument("--grid", nargs="*", default=[], help="setting=v1,v2 (backend settings; physics.* are overrides)")
    args = ap.parse_args(argv)
    keys, values = [], []
    for item in args.grid:
        k, _, vs = item.partition("=")
        keys.append(k)
        values.append([_value(v) for v in vs.split(",")])
    rows = []
    for combo in itertools.product(*values) if keys else [()]:
        settings = {k: v for k, v in zip(keys, combo, strict=True) if not k.startswith("physics.")}
        overrides = {k: v for k, v in zip(keys, combo, strict=True) if k.startswith("physics.")}
        label = f"{args.backend} {args.profile} " + " ".join(f"{k}={v}" for k, v in zip(keys, combo, strict=True))
        rows.append((label.strip(), run_case(args.scenario, args.backend, args.profile, settings, overrides)))
        print(table(rows[-1:]).splitlines()[-1], flush=True)
    print(table(rows))


if __name__ == "__main__":
    main()
