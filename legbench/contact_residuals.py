"""Contact-law residuals of one run: scores that need no reference backend.

:func:`residuals` compares a logged run with the contact law it was meant to
follow (docs/spec.md section 4), sample by sample, from the joint state and the
ground force alone:

* penetration against the spring: y - (Fn - Kd max(ydot, 0)) / Kp while in
  contact, y = R_foot - z_E the foot's penetration [m];
* friction against mu Fn while sliding (slip speed >= 1.5 v_th, where the law
  gives mu_k): |F_t| / (mu Fn), mu the coefficient the backend slides with (mu_k
  for the law; a single-coefficient Coulomb engine's one coefficient, mu_s unless its ``friction_coefficient``
  says mu_k);
* the angle between the friction force and the slip direction (the law puts
  it exactly opposite the slip) [deg];
* creep under a sub-limit load (|F_t| < 0.9 min(mu_s, mu_k) Fn, so that kinetic sliding
  is not counted): the measured slip speed
  against the law's v_th |F_t| / (mu_s Fn) [m/s].

The slip is taken where the backend's force acted, as its info declares
(:func:`legbench.backends.base.contact_point`): the law's poc (the sphere's
lowest point, or the centre, as the law's ``poc`` says) where legbench applies
the law, an engine's own point in native contact (the sphere's lowest point, or
halfway through the penetration); velocities are J(q) qd from
:func:`legbench.kinematics.jacobian_at`. The penetration rate is the same at
every point on the vertical through E.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from legbench import kinematics
from legbench.contact import ContactParams
from legbench.model import load_params

#: Normal force below which a sample does not count as in contact [N].
FN_MIN = 0.5
#: Sub-limit load: |F_t| below this fraction of min(mu_s, mu_k) Fn.
SUB_LIMIT = 0.9
#: Slip speed from which the friction direction is scored [m/s]: below it the direction of a
#: Coulomb engine's (sticking) foot is numerical noise.
V_DIRECTION = 1.0e-4


@dataclass(frozen=True)
class ContactResiduals:
    """Residuals of one run against the law (NaN where no sample qualifies).

    Attributes:
        n_contact: samples in contact (Fn > :data:`FN_MIN`).
        penetration_max: max |y - (Fn - Kd max(ydot, 0)) / Kp| over contact samples [m].
        penetration_rms: its RMS [m].
        penetration_rel: median |y Kp / Fn_spring - 1| over contact samples [1].
        n_sliding: contact samples slipping at >= 1.5 v_th.
        friction_ratio: median |F_t| / (mu Fn) over sliding samples [1], mu the coefficient the backend slides
            with (``sliding``): 1 for the law and for a Coulomb engine that slides as it should.
        n_direction: contact samples slipping at >= :data:`V_DIRECTION` with friction.
        angle_max: max angle between F_t and -v_t over those samples [deg].
        angle_median: its median [deg].
        n_creep: contact samples under a sub-limit load.
        creep_speed: median slip speed under sub-limit load [m/s].
        creep_law: median of the law's creep speed v_th |F_t| / (mu_s Fn) over the same samples [m/s].
    """

    n_contact: int
    penetration_max: float
    penetration_rms: float
    penetration_rel: float
    n_sliding: int
    friction_ratio: float
    n_direction: int
    angle_max: float
    angle_median: float
    n_creep: int
    creep_speed: float
    creep_law: float

    def to_dict(self) -> dict[str, Any]:
        """Plain floats and ints (NaN stays NaN)."""
        return asdict(self)


def _median(x: np.ndarray) -> float:
    return float(np.median(x)) if x.size else math.nan


def residuals(
    t: np.ndarray,
    q: np.ndarray,
    qd: np.ndarray,
    force: np.ndarray,
    params: ContactParams,
    point: tuple[str, float] | None = None,
    sliding: str = "mu_k",
) -> ContactResiduals:
    """The law's residuals over a run.

    Args:
        t: sample times [s] (n,) (only its length is used: every sample counts).
        q: joint angles [rad] (n, 3).
        qd: joint velocities [rad/s] (n, 3).
        force: ground force on the foot in W [N] (n, 3), as the backend reported it.
        params: the contact law the run was meant to follow.
        point: where the backend's force acted, ``(poc, lift)`` (:func:`legbench.backends.base.contact_point`:
            its info's ``contact.poc`` and ``contact.lift``); the slip is that point's velocity. Default: the
            law's poc.
        sliding: the coefficient the backend slides with (its declared ``sliding_coefficient``): ``mu_k`` for
            the law, ``mu_s`` for a single-coefficient Coulomb engine, so that the friction ratio is 1 for both
            (it read 1.167 = mu_s / mu_k for MuJoCo, Bullet and Drake, as if their friction were 17 % high).
    """
    q = np.asarray(q, float).reshape(len(t), 3)
    qd = np.asarray(qd, float).reshape(len(t), 3)
    f = np.asarray(force, float).reshape(len(t), 3)
    R = load_params().geometry.R_foot
    z_E = kinematics.fk(q)[:, 2]
    y = R - z_E
    J = kinematics.jacobian_at(q, *(point or (params.poc, 0.0)))
    v = np.einsum("nij,nj->ni", J, qd)
    ydot = -v[:, 2]
    fn = f[:, 2]
    contact = fn > FN_MIN

    fn_spring = fn - params.Kd * np.maximum(ydot, 0.0)
    # A sample missing a value a score needs (an imported log's NaN: a ROS bag's force outside the wrench
    # topic's span, a velocity not logged) does not qualify for that score; the others still do.
    pen_all = y - fn_spring / params.Kp
    pen = pen_all[contact & np.isfinite(pen_all)]
    rel = np.abs(y[contact] * params.Kp / np.where(fn_spring[contact] > 0, fn_spring[contact], np.nan) - 1.0)
    rel = rel[np.isfinite(rel)]

    vt = np.hypot(v[:, 0], v[:, 1])
    ft = np.hypot(f[:, 0], f[:, 1])
    slides = contact & (vt >= 1.5 * params.v_th) & np.isfinite(ft)
    mu_slide = params.mu_s if sliding == "mu_s" else params.mu_k
    # frictionless ground (mu 0): no friction bound to measure against, n/a (it divided by zero)
    ratio = ft[slides] / (mu_slide * fn[slides]) if mu_slide > 0 else np.empty(0)

    scored = contact & (vt >= V_DIRECTION) & (ft > 1e-9)
    cosang = -(f[scored, 0] * v[scored, 0] + f[scored, 1] * v[scored, 1]) / (ft[scored] * vt[scored])
    angle = np.degrees(np.arccos(np.clip(cosang, -1.0, 1.0)))

    creep = contact & (ft < SUB_LIMIT * min(params.mu_s, params.mu_k) * fn) & np.isfinite(vt)
    law = params.v_th * ft[creep] / (params.mu_s * fn[creep])
    return ContactResiduals(
        n_contact=int(contact.sum()),
        penetration_max=float(np.abs(pen).max()) if pen.size else math.nan,
        penetration_rms=float(np.sqrt(np.mean(pen**2))) if pen.size else math.nan,
        penetration_rel=_median(rel),
        n_sliding=int(slides.sum()),
        friction_ratio=_median(ratio),
        n_direction=int(scored.sum()),
        angle_max=float(angle.max()) if angle.size else math.nan,
        angle_median=_median(angle),
        n_creep=int(creep.sum()),
        creep_speed=_median(vt[creep]),
        creep_law=_median(law),
    )


__all__ = ["ContactResiduals", "residuals"]
