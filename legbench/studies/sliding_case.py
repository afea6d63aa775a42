"""Verification case with a closed-form answer for sliding: the foot dragged above the friction limit.

The leg stands at q* on the ground and presses with the effort controller
(h_d = (0, 0, -FN) in W) until :data:`T_DRAG`, then is dragged sideways with
h_d = (0, FT, -FN), FT = 0.8 FN, above the static limit mu_s FN = 0.7 FN. Over the window
:data:`WINDOW` the foot slides, and the law gives in closed form, at each logged
sample (q, qd, tau, Fn):

* the friction: |F_t| = mu Fn, opposite the slip (mu = the coefficient the backend declares it
  slides with for its loaded settings, ``Backend.slides_with()``, recorded in the run's info as
  ``sliding_coefficient``: mu_k for the stick-slip law, where the slip is far above 1.5 v_th, and
  for an engine given a dynamic coefficient mu_k; mu_s for a Coulomb engine with one coefficient);
  the friction shape as the run's info declares it (``friction_cone``): a cone, the axis-by-axis
  pyramid (:func:`pyramid_friction`) or the diamond |F_t1| + |F_t2| <= mu Fn (:func:`diamond_friction`:
  it slides on the vertex against the slip's larger component), the pyramid's and the diamond's tangent axes
  t1, t2 as the run's info declares them (``friction_axes``, :func:`friction_axes`; W x and W y where it
  declares none);
* the slip acceleration: qdd = M(q)^-1 (tau - nle(q, qd) + J_poc^T F), F = (-mu Fn v_t/|v_t|, Fn),
  and a_t = (J_poc qdd + Jdot_poc qd)_t, the poc's horizontal acceleration, along the slip
  (F applied where the backend applies it: its info's ``contact.poc`` and ``contact.lift``,
  :func:`~legbench.backends.base.contact_point`; a point y/2 above the lowest point alone moves the
  acceleration by 4 % here, the sphere's centre instead of the lowest point by 64 %);
  M and nle from the leg's model (``model.Dynamics`` on the generated URDF), the same for every
  backend.

The measured friction is the backend's reported ground force, held to the closed form at the window's worst
sample (a friction that chatters about mu does not pass on its mean), at the window's samples in contact (Fn above
:data:`FN_MIN`); the measured acceleration is the central difference of the poc's horizontal velocity J_poc qd of
the 1 kHz log, (v[k+1] - v[k-1]) / 2 Ts, at the samples whose whole stencil k-1, k, k+1 is in contact (a sample
beside a step without contact carries that step's frictionless acceleration). The window's samples out of contact
are counted, not scored: each row carries the counts (:data:`COUNT_KEYS`) and its note says them, so a foot that
hops is measured. :func:`sliding_case` returns one row per quantity. A backend that
applies the law itself (no contact of its own, or reference contact mode:
:func:`applies_law`; Pinocchio, Lagrange) reports the law evaluated at the logged
state, so its friction and angle rows read the law back (they check the read-out,
and say so in their notes); its acceleration row is the one that tests its dynamics.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from legbench import backends as registry
from legbench import kinematics, resources
from legbench import scenario as scenario_mod
from legbench.backends.base import FRICTION_COEFFICIENTS, Backend, Physics, contact_point, explained_note
from legbench.model import Dynamics, load_params
from legbench.results import RunResult
from legbench.run import physics_of, simulate

#: Normal push [N] and the drag as a fraction of it (above mu_s = 0.7).
FN = 15.0
DRAG = 0.8
#: Start of the drag [s] and the window scored [s] (slip established, foot still near q*).
T_DRAG = 0.3
WINDOW = (0.33, 0.38)
#: Tolerances: friction coefficient (relative, at the worst sample of the window: the law and a Coulomb cone are
#: exact at every sample, measured to 1e-16; an engine's friction regularised near zero slip reads up to 0.22 %
#: under mu, Drake's defaults; 1 % is the read-out's check, per sample so a friction that chatters about mu does
#: not pass on its mean; its size is held far tighter by the slip acceleration, which the drag's net force
#: (DRAG - mu) Fn = 0.1 Fn makes ten times as sensitive to it: ODE's bound 0.98 % over mu passes here and moves
#: the acceleration by 11 %), angle [deg] (1: the law is exactly opposite), acceleration (relative; 2 %: central
#: differences of a 1 kHz log and forces averaged over a control period against a prediction at the sample;
#: measured 0.1-0.2 %).
TOL_MU, TOL_ANGLE, TOL_ACC = 0.01, 1.0, 0.02
#: A sample counts as in contact above this normal force [N].
FN_MIN = 0.5
#: The diamond's vertex is the sliding force of a soft pyramidal cone (MuJoCo's) only while the slip is within this
#: of a tangent axis [deg]: measured, a sphere dragged at a held slip direction (1 ms, raw solref, default solimp),
#: mean (max) angle of the force off the vertex 0.00 deg at 5-15 deg, 0.13 (3.3) at 20, 6.2 (14) at 30, 29 at 40:
#: the soft edge rows split the force along the face. The drag here slips up to 10 deg off W y.
DIAMOND_AXIS_DEG = 15.0

ROW_KEYS = ("case", "backend", "quantity", "unit", "measured", "expected", "error", "tolerance", "passed", "note")
#: The window's counts every row carries beside :data:`ROW_KEYS`: its samples, those out of contact (Fn <=
#: :data:`FN_MIN`: a lift-off, measured) and those whose central difference's stencil k-1, k, k+1 is all in contact
#: (the slip acceleration's samples).
COUNT_KEYS = ("window_samples", "out_of_contact", "acceleration_samples")


def _scenario(duration: float = WINDOW[1] + 0.01, overrides: Mapping[str, Any] | None = None) -> Any:
    events = [
        {"t": 0.0, "effort": {"force": [0.0, 0.0, -FN]}},
        {"t": T_DRAG, "effort": {"force": [0.0, DRAG * FN, -FN]}},
    ]
    base = {"events": events, "duration": duration, "comparison.steady_window": 0.01, "name": "sliding"}
    return scenario_mod.load(resources.scenario("effort"), {**base, **(overrides or {})})


def predicted_acceleration(q: np.ndarray, qd: np.ndarray, tau: np.ndarray, force: np.ndarray, lift: float = 0.0,
                           poc: str = "true", gravity: float | None = None) -> np.ndarray:  # fmt: skip
    """Horizontal acceleration in W [m/s^2] (n x 2), under tau [N m] and the ground force in W [N], of the shank's
    point where the force acts (:func:`~legbench.backends.base.contact_point`, the backend's info's ``contact``):
    ``poc`` ``"true"``, the sphere's lowest point raised by ``lift`` times the penetration y (``contact.lift``; 0:
    the lowest point itself), or ``"centre"``, E (the law applied at the sphere's centre: the force's lever is then
    R_foot shorter), the point whose slip the sliding case measures. Its acceleration is J qdd + Jdot qd with the
    material point (its depth d below E) held: Jdot qd by a difference of J at q + eps qd and the same d.
    ``gravity`` [m/s^2]: the run's (its physics'; default the parameter file's).
    """
    R = load_params().geometry.R_foot
    dyn = Dynamics(gravity)
    out = np.empty((len(q), 2))
    eps = 1e-7
    zero = np.zeros(3)
    for k in range(len(q)):
        M = dyn.mass_matrix(q[k])
        nle = dyn.inverse_dynamics(q[k], qd[k], zero)
        d = 0.0 if poc == "centre" else R - lift * max(R - float(kinematics.fk(q[k])[2]), 0.0)
        J = kinematics.jacobian_below(q[k], d)
        qdd = np.linalg.solve(M, tau[k] - nle + J.T @ force[k])
        Jdot_qd = (kinematics.jacobian_below(q[k] + eps * qd[k], d) - J) / eps @ qd[k]
        out[k] = (J @ qdd + Jdot_qd)[:2]
    return out


def drag(
    backend: str,
    profile: str = "matched",
    settings: Mapping[str, Any] | None = None,
    duration: float = WINDOW[1] + 0.01,
    overrides: Mapping[str, Any] | None = None,
) -> tuple[RunResult, Physics]:
    """Run the drag on ``backend`` (native contact, ``profile`` and backend ``settings``) for ``duration`` [s].

    ``overrides``: scenario keys set on top (e.g. ``{"physics.contact.Kd": 50.0}``). A backend that cannot
    load gives a failed :class:`~legbench.results.RunResult` saying why. Where the backend's contact solver bounds
    friction by a frictionless normal impulse (:meth:`~legbench.backends.base.Backend.frictionless_normal`), the
    run's info carries it after the run, ``frictionless_fn`` [N] at every logged sample from :data:`T_DRAG` on (NaN
    before), which the pyramid's scoring predicts the bound from.
    """
    sc = _scenario(duration, overrides)
    physics = physics_of(sc, "native")
    try:
        b = registry.load(backend, physics, dict(settings or {}), profile)
    except Exception as exc:
        return RunResult.empty(backend, "failed", f"{type(exc).__name__}: {exc}"), physics
    try:
        tr = simulate(sc, b, physics)
        if tr.status == "ok":
            fn0 = _frictionless(b, tr)
            if fn0 is not None:
                tr.info = {**tr.info, "frictionless_fn": fn0.tolist()}
        return tr, physics
    finally:
        b.close()


def _frictionless(b: Backend, tr: RunResult) -> np.ndarray | None:
    """The backend's frictionless normal force [N] at the run's samples from :data:`T_DRAG` on (NaN before), or None
    where it gives none (asked after the run: it resets the engine)."""
    ks = np.flatnonzero(tr.t >= T_DRAG - 1e-9)
    out = np.full(len(tr.t), math.nan)
    for k in ks:
        fn0 = b.frictionless_normal(tr.q[k], tr.qd[k], tr.tau[k])
        if fn0 is None:
            return None
        out[k] = fn0
    return out


def applies_law(info: Mapping[str, Any], physics: Physics) -> bool:
    """True if the run's ground force is the spec's law, applied by legbench at its known point of contact:
    the backend has no contact of its own (``engine_contact`` False in the run's info, as
    :func:`legbench.run.backend_info` records it for every run) or runs in reference contact mode."""
    return physics.contact_mode == "reference" or not info.get("engine_contact", True)


def sliding_case(backend: str, profile: str = "matched") -> list[dict[str, Any]]:
    """Run the drag on ``backend`` (native contact, ``profile``) and score it against the closed form.

    Returns:
        Rows with :data:`ROW_KEYS` and :data:`COUNT_KEYS`: friction coefficient, friction angle to the slip, slip
        acceleration along the slip; a backend that cannot run gives one failed row saying why.
    """
    tr, physics = drag(backend, profile)
    return score(tr, physics, WINDOW)


def score(tr: RunResult, physics: Physics, window: tuple[float, float] = WINDOW) -> list[dict[str, Any]]:
    """Score a drag run (:func:`drag`) over ``window`` [s] against the closed form: the rows of :func:`sliding_case`."""
    case, backend = "sliding", tr.backend
    if tr.status != "ok":
        return [_failed_row(backend, f"{tr.status}: {tr.reason}", (0, 0, 0))]
    cls = registry.get(backend)
    p = physics.contact
    coef = sliding_coefficient(tr.info, cls)
    mu = float(getattr(p, coef))
    poc, lift = contact_point(tr.info, p.poc)
    J = kinematics.jacobian_at(tr.q, poc, lift)  # the slip where the force acted
    v = np.einsum("nij,nj->ni", J, tr.qd)[:, :2]
    k = np.flatnonzero((tr.t >= window[0] - 1e-9) & (tr.t <= window[1] + 1e-9))
    k = k[(k > 0) & (k < len(tr.t) - 1)]
    # samples in contact only (an engine's foot may hop: the closed form is for sliding contact); those out of it
    # are counted (a lift-off, measured), and the acceleration takes only the samples whose whole central
    # difference k-1, k, k+1 is in contact (:func:`_stencil`)
    touching = tr.f[:, 2] > FN_MIN
    counts = (len(k), int(np.count_nonzero(~touching[k])), 0)
    k = k[touching[k]]
    shape = str(tr.info.get("friction_cone", cls.friction_cone))
    if shape == "pyramid" and len(k):
        return _score_pyramid(tr, physics, cls, coef, mu, v, k, touching, counts, lift, poc)
    k = k[np.linalg.norm(v[k], axis=1) > 0.0]
    if len(k) == 0:
        return [_failed_row(backend, f"no sample of the window in sliding contact; {_contact_text(counts)}", counts)]
    fn = tr.f[k, 2]
    ft = tr.f[k, :2]
    vk = v[k]
    speed = np.linalg.norm(vk, axis=1)
    if shape == "diamond":  # scored on its own closed form (the cone's below would be computed for nothing)
        return _score_diamond(tr, physics, cls, coef, mu, v, k, touching, counts, lift, poc)
    u = vk / speed[:, None]
    ratio, _ = _worst(np.linalg.norm(ft, axis=1) / fn, mu)
    cosang = -np.sum(ft * u, axis=1) / np.linalg.norm(ft, axis=1)
    angle = float(np.degrees(np.arccos(np.clip(cosang, -1.0, 1.0))).max())
    s = _stencil(touching, k)
    counts = (counts[0], counts[1], int(s.sum()))
    slip = f"slip {_span(1e3 * speed)} mm/s, Fn {fn.mean():.3g} N, {_contact_text(counts)}"
    ka, ua = k[s], u[s]
    vb = v[ka - 1]
    nb = np.linalg.norm(vb, axis=1)[:, None]
    # a stalled step before (no slip: no friction direction) takes the slip's at k: one such sample made the mean NaN
    ub = np.divide(vb, nb, out=ua.copy(), where=nb > 0.0)
    am, ap, steps = _accelerations(tr, physics, v, ka, ua, -mu * fn[s, None] * ua,
                                   -mu * tr.f[ka - 1, 2, None] * ub, lift, poc)  # fmt: skip
    # a law backend's force is the law evaluated at the logged state: its ratio and angle are the law read back
    law = ("the law read back (the force is the law at the logged state): checks the read-out, not an engine; "
           if applies_law(tr.info, physics) else "")  # fmt: skip
    rows = [
        _relative(case, backend, "friction |F_t| / Fn while sliding (worst sample)", "1", ratio, mu, TOL_MU,
                  f"{law}{coef} = {mu:g}; {slip}"),
        (case, backend, "angle between friction and -slip (max)", "deg", angle, 0.0, angle, TOL_ANGLE,
         angle <= TOL_ANGLE, f"{law}{slip}"),
        _relative(case, backend, "slip acceleration along the slip (mean)", "m/s^2", am, ap, TOL_ACC,
                  f"closed form M^-1 (tau - nle + J_poc^T F), F = mu Fn vs the slip{_at(poc)}; {slip}"),
    ]  # fmt: skip
    return _with_known(cls, tr, rows, counts, {"over_steps": steps})


def sliding_coefficient(info: Mapping[str, Any], cls: type[Backend]) -> str:
    """The ContactParams coefficient (``mu_k`` or ``mu_s``) the run's native contact slides with, as the backend
    declared it for its loaded settings (:meth:`~legbench.backends.base.Backend.slides_with`, recorded in the run's
    info as ``sliding_coefficient`` by :func:`legbench.run.backend_info`), else the class's
    :attr:`~legbench.backends.base.Backend.sliding_coefficient`."""
    coef = info.get("sliding_coefficient")
    return coef if coef in FRICTION_COEFFICIENTS else cls.sliding_coefficient


def _declared_axes(info: Mapping[str, Any] | None) -> np.ndarray | None:
    """The tangent axes t1, t2 (rows, 2 x 3, in W) the run's info declares (``friction_axes``:
    :data:`~legbench.backends.base.INFO_KEYS`), or None where it declares none or malformed ones."""
    try:
        a = np.asarray((info or {}).get("friction_axes"), float)
    except (TypeError, ValueError):
        return None
    return a if a.shape == (2, 3) and np.isfinite(a).all() else None


def friction_axes(info: Mapping[str, Any] | None) -> np.ndarray:
    """The run's pyramid's or diamond's tangent axes t1, t2 (rows, 2 x 3, in W) as its info declares them, else W x
    and W y (a run.json written before the key, or a backend that declares none)."""
    a = _declared_axes(info)
    return np.eye(3)[:2] if a is None else a


def drag_frame(axes: np.ndarray) -> np.ndarray:
    """The declared tangent axes (:func:`friction_axes`, 2 x 3) as the rows (across, along) of a 2 x 2 frame on
    the ground's W x, W y: ``along`` the axis nearest the drag (W y), pointing with it, ``across`` the other,
    pointing where the drag turned by -90 deg about z_W points (W x for an along W y): for axes along W x and W y
    exactly the identity, whatever their order and signs, so the rows keep their W x / W y reading."""
    t = np.asarray(axes, float)[:, :2]
    i = int(np.argmax(np.abs(t[:, 1])))
    along = t[i] if t[i, 1] >= 0.0 else -t[i]
    across = t[1 - i] if t[1 - i] @ np.array([along[1], -along[0]]) >= 0.0 else -t[1 - i]
    return np.vstack([across, along])


def _axes_text(info: Mapping[str, Any] | None) -> str:
    """The tangent axes the closed form took (:func:`friction_axes`), in words for a note."""
    t = _declared_axes(info)
    if t is None:
        return "axes W x, W y (the run declares none)"
    rows = ", ".join(f"t{i + 1} ({', '.join(f'{x + 0.0:.3g}' for x in row)})" for i, row in enumerate(t))
    return f"axes {rows} (the backend's friction_axes)"


def _at(poc: str) -> str:
    """Where the closed form applies F, said in a note where it is not the sphere's lowest point."""
    return ", applied at the sphere's centre (the backend's poc)" if poc == "centre" else ""


def diamond_friction(v: np.ndarray, fn: np.ndarray, mu: float, axes: np.ndarray | None = None) -> np.ndarray:
    """The friction diamond's sliding force in W [N] (n x 2, W x and W y) for the slip velocity ``v`` (n x 2, W x
    and W y) and the normal force ``fn`` [N]: the diamond |F_t1| + |F_t2| <= mu Fn (a pyramidal cone whose edges
    are n +- mu t_i), its tangent axes ``axes`` (2 x 2 or 2 x 3 rows t1, t2 in W: the run's ``friction_axes``,
    :func:`friction_axes`; default W x, W y), slides with the force of maximal dissipation, the point of the
    diamond furthest against the slip. With s_i = v . t_i that is the vertex on the axis of the slip's larger
    component, -mu Fn sign(s_i) t_i, |F_t| = mu Fn, off -slip by atan(|s_j| / |s_i|); on the diagonal |s_1| = |s_2|
    every point of the face between the two vertices dissipates as much, and the face's middle is returned. Unlike
    the axis-by-axis pyramid (:func:`pyramid_friction`), no axis can hold with a force while the other slides: with
    F on the vertex the other component is 0."""
    v = np.asarray(v, float)
    fn = np.asarray(fn, float)
    E = np.eye(2) if axes is None else np.asarray(axes, float)[:, :2]
    s = v @ E.T
    ax, ay = np.abs(s[:, 0]), np.abs(s[:, 1])
    w = np.column_stack([(ax > ay) + 0.5 * (ax == ay), (ay > ax) + 0.5 * (ax == ay)])
    return (-mu * fn[:, None] * w * np.sign(s)) @ E


def _score_diamond(tr: RunResult, physics: Physics, cls: type[Backend], coef: str, mu: float, v: np.ndarray,
                   k: np.ndarray, touching: np.ndarray, counts: tuple[int, int, int], lift: float,
                   poc: str) -> list[dict[str, Any]]:  # fmt: skip
    """The drag scored against the friction diamond's closed form (:func:`diamond_friction`) on the run's declared
    tangent axes (:func:`friction_axes`) at the samples ``k`` in sliding contact: |F_t1| + |F_t2| = mu Fn (at every
    sample: the boundary holds at any slip direction), the tangential force's angle to the closed form's (the
    vertex against the slip's larger component) and the slip acceleration along the slip under that force, at the
    samples whose slip is within :data:`DIAMOND_AXIS_DEG` of a tangent axis (the vertex is a soft pyramid's force
    only there) and whose central difference's stencil is in contact (``touching``, :func:`_stencil`); ``counts``:
    the window's (:data:`COUNT_KEYS`)."""
    case, backend = "sliding", tr.backend
    E = drag_frame(friction_axes(tr.info))  # rows: the axis across the drag, the axis along it
    l1, _ = _worst(np.sum(np.abs(tr.f[k, :2] @ E.T), axis=1) / tr.f[k, 2], mu)
    n_contact = len(k)
    speed, fn_mean = np.linalg.norm(v[k], axis=1), float(tr.f[k, 2].mean())  # of every sample sliding in contact
    sk = np.abs(v[k] @ E.T)
    off_axis = np.degrees(np.arctan2(sk.min(axis=1), sk.max(axis=1)))
    k = k[off_axis <= DIAMOND_AXIS_DEG]
    if len(k) == 0:
        why = (f"no sample slips within {DIAMOND_AXIS_DEG:g} deg of a tangent axis (from {off_axis.min():.3g} deg): "
               "the diamond's vertex is not the soft pyramid's force there")  # fmt: skip
        return [_failed_row(backend, why, counts)]
    s = _stencil(touching, k)
    counts = (counts[0], counts[1], int(s.sum()))
    slip = f"slip {_span(1e3 * speed)} mm/s, Fn {fn_mean:.3g} N, {_contact_text(counts)}"
    fn, ft, vk = tr.f[k, 2], tr.f[k, :2], v[k]
    u = vk / np.linalg.norm(vk, axis=1)[:, None]
    ft_pred = diamond_friction(vk, fn, mu, E)
    cosang = np.sum(ft * ft_pred, axis=1) / (np.linalg.norm(ft, axis=1) * np.linalg.norm(ft_pred, axis=1))
    angle = float(np.degrees(np.arccos(np.clip(cosang, -1.0, 1.0))).max())
    off = float(np.degrees(np.arccos(np.clip(-np.sum(ft_pred * u, axis=1) / np.linalg.norm(ft_pred, axis=1),
                                             -1.0, 1.0))).max())  # fmt: skip
    sv = vk @ E.T
    along = int(np.sum(np.abs(sv[:, 1]) > np.abs(sv[:, 0])))
    ctx = (f"diamond |F_t1| + |F_t2| <= {coef} Fn on {_axes_text(tr.info)}, {coef} = {mu:g}: slides on the vertex "
           f"against the slip's larger component (the axis along the drag at {along} of {len(k)} samples), up to "
           f"{off:.3g} deg off -slip; angle and acceleration at the {len(k)} of {n_contact} samples within "
           f"{DIAMOND_AXIS_DEG:g} deg of an axis; {slip}")  # fmt: skip
    ka = k[s]
    am, ap, steps = _accelerations(tr, physics, v, ka, u[s], ft_pred[s],
                                   diamond_friction(v[ka - 1], tr.f[ka - 1, 2], mu, E), lift, poc)  # fmt: skip
    rows = [
        _relative(case, backend, "friction (|F_x| + |F_y|) / Fn while sliding (worst sample; diamond)", "1", l1, mu,
                  TOL_MU,
                  ctx),
        (case, backend, "angle between friction and the diamond's closed form (max)", "deg", angle, 0.0, angle,
         TOL_ANGLE, angle <= TOL_ANGLE, ctx),
        _relative(case, backend, "slip acceleration along the slip (mean; diamond)", "m/s^2", am, ap, TOL_ACC,
                  f"closed form M^-1 (tau - nle + J_poc^T F), F the diamond's{_at(poc)}; {ctx}"),
    ]  # fmt: skip
    return _with_known(cls, tr, rows, counts, {"over_steps": steps})


def _worst(measured: np.ndarray, expected: np.ndarray | float) -> tuple[float, float]:
    """(measured, expected) at the sample where they differ most: a row held at every sample of the window
    (:data:`TOL_MU`). Where the closed form varies by sample (the pyramid's force along the drag, held below its
    bound at some samples) the largest difference is taken, not the largest ratio (a sample it puts at 0)."""
    measured_i, expected_i, _ = _worst_at(measured, expected)
    return measured_i, expected_i


def _worst_at(measured: np.ndarray, expected: np.ndarray | float) -> tuple[float, float, int]:
    """:func:`_worst` and the sample's index in ``measured``."""
    exp = np.broadcast_to(np.asarray(expected, float), measured.shape)
    i = int(np.argmax(np.abs(measured - exp)))
    return float(measured[i]), float(exp[i]), i


def _span(x: np.ndarray) -> str:
    """``min-max`` of ``x`` to 3 digits, or the one value where they print the same (a stuck foot's slip)."""
    lo, hi = f"{float(x.min()):.3g}", f"{float(x.max()):.3g}"
    return lo if lo == hi else f"{lo}-{hi}"


def _with_known(cls: type[Backend], tr: RunResult, rows: list[tuple[Any, ...]], counts: tuple[int, int, int],
                measured: Mapping[str, Any] | None = None) -> list[dict[str, Any]]:  # fmt: skip
    """``rows`` (tuples of :data:`ROW_KEYS`) as mappings with the window's ``counts`` (:data:`COUNT_KEYS`) and each
    failing row's measured and explained miss (``Backend.known_deviation``:
    :func:`~legbench.backends.base.explained_note`) before its note; the row still fails. The backend is asked
    with the run's info and, under ``drag``, what this scoring measured of the run: the counts and ``measured``
    (a pyramid's friction bound, measured, and where the solver's own bound is predicted the closed form with it,
    :func:`_score_pyramid`; a cone's or diamond's closed form of the central difference with each step under the
    force read at its start, ``over_steps``: :func:`_over_steps`), which its explanation may hold the row's measured
    value to. ``measured`` may hold a mapping (``at_predicted``)."""
    context = {**tr.info, "drag": {**dict(zip(COUNT_KEYS, counts, strict=True)), **(measured or {})}}
    out = []
    for row in rows:
        r = {**dict(zip(ROW_KEYS, row, strict=True)), **dict(zip(COUNT_KEYS, counts, strict=True))}
        r["note"] = explained_note(cls, "sliding", str(r["quantity"]), context, bool(r["passed"]),
                                   float(r["measured"]), float(r["expected"]), float(r["tolerance"]),
                                   str(r["note"]))  # fmt: skip
        out.append(r)
    return out


def _failed_row(backend: str, why: str, counts: tuple[int, int, int]) -> dict[str, Any]:
    """The one row of a drag that could not be scored (a failed run, no sample to score), saying ``why``."""
    row = ("sliding", backend, "run", "", math.nan, math.nan, math.nan, 0.0, False, why)
    return {**dict(zip(ROW_KEYS, row, strict=True)), **dict(zip(COUNT_KEYS, counts, strict=True))}


def _stencil(touching: np.ndarray, k: np.ndarray) -> np.ndarray:
    """Which of the samples ``k`` (each 0 < k < n - 1) have the whole central difference k-1, k, k+1 in contact
    (``touching``: Fn above :data:`FN_MIN` at each sample of the log): the slip acceleration's samples. A contact
    sample beside a step without contact carries that step's frictionless drag (MuJoCo's engine-defaults hop,
    SAP's glide), which is not the closed form's sliding contact."""
    return touching[k - 1] & touching[k] & touching[k + 1]


def _contact_text(counts: tuple[int, int, int]) -> str:
    """The window's counts (:data:`COUNT_KEYS`) in words for a note."""
    n, out, acc = counts
    return (f"{n - out} of {n} samples in contact, {out} out (Fn <= {FN_MIN:g} N); acceleration at the {acc} whose "
            "difference stencil k-1, k, k+1 is in contact")  # fmt: skip


def _accelerations(
    tr: RunResult,
    physics: Physics,
    v: np.ndarray,
    ka: np.ndarray,
    u: np.ndarray,
    ft_at: np.ndarray,
    ft_before: np.ndarray,
    lift: float,
    poc: str,
) -> tuple[float, float, float]:
    """The slip acceleration along the slip ``u`` (n x 2 in W) at the samples ``ka`` (each with its stencil in
    contact, :func:`_stencil`) as the row measures it and its closed forms [m/s^2]: the mean central difference of
    the poc's horizontal velocity ``v``, the mean closed form M^-1 (tau - nle + J_poc^T F) with the tangential force
    ``ft_at`` (n x 2) and the logged Fn at each sample, and the mean over the difference's two steps
    (:func:`_over_steps`) with ``ft_before`` the force at the sample before each."""
    a_meas = (v[ka + 1] - v[ka - 1]) / (2 * physics.control_dt)
    kb = ka - 1  # the step before: the closed form under the force read at its start

    def closed_form(j: np.ndarray, ft: np.ndarray) -> np.ndarray:
        f = np.column_stack([ft, tr.f[j, 2]])
        return predicted_acceleration(tr.q[j], tr.qd[j], tr.tau[j], f, lift, poc, physics.gravity)

    a_at, a_before = closed_form(ka, ft_at), closed_form(kb, ft_before)
    return _mean(np.sum(a_meas * u, axis=1)), _mean(np.sum(a_at * u, axis=1)), _over_steps(a_at, a_before, u)


def _over_steps(a_at: np.ndarray, a_before: np.ndarray, u: np.ndarray) -> float:
    """The closed form of the central difference (v[k+1] - v[k-1]) / 2 Ts where each control period's step
    applies the force read at its start (an engine stepped once per period whose logged force is the one its next
    step applies, MuJoCo's 1 ms step): the mean over the samples k of the closed form at k and at k - 1 (``a_at``,
    ``a_before``, n x 2 in W), each along the slip at k (``u``, n x 2). Where the acceleration varies little over a
    step it is the closed form at k; where it varies fast (a foot landing after a hop) it lags it by half a step."""
    return _mean(np.sum(0.5 * (a_at + a_before) * u, axis=1))


def _mean(x: np.ndarray) -> float:
    """The mean of ``x``, NaN where it is empty (no sample to score: the row then fails, unexplained)."""
    return float(np.mean(x)) if len(x) else math.nan


def _relative(case: str, backend: str, quantity: str, unit: str, measured: float, expected: float, rel: float,
              note: str) -> tuple[Any, ...]:  # fmt: skip
    """A row whose tolerance is ``rel`` of the closed form's value: error |measured - expected| and tolerance
    rel |expected|, both in the row's unit (as every verification row's), the fraction said in the note."""
    error, tol = abs(measured - expected), rel * abs(expected)
    return (case, backend, quantity, unit, measured, expected, error, tol, bool(error <= tol),
            f"{note}; tolerance {100 * rel:g} % of the closed form")  # fmt: skip


def pyramid_friction(q: np.ndarray, qd: np.ndarray, tau: np.ndarray, fn: np.ndarray, mu: float,
                     lift: float = 0.0, poc: str = "true", axes: np.ndarray | None = None,
                     gravity: float | None = None,
                     bound: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """The friction pyramid's closed form at each sample: the tangential ground force in W [N] (n x 2, W x and
    W y) and the poc's horizontal acceleration in W [m/s^2] (n x 2) it gives, under tau [N m] and the normal
    force fn [N], at ``gravity`` [m/s^2] (the run's; default the parameter file's).

    The pyramid bounds each of its tangent axes ``axes`` on its own, |F . t_i| <= mu Fn (2 x 2 or 2 x 3 rows t1,
    t2 in W: the run's ``friction_axes``, :func:`friction_axes`; default W x and W y), or by ``bound`` [N] per
    sample where given (a solver's own bound, e.g. mu times a frictionless normal force). The acceleration is affine
    in the force (:func:`predicted_acceleration`); the axes that can hold (|F_i| <= mu Fn with the foot stuck
    along both) hold, an axis that cannot slides with |F_i| = mu Fn in its holding force's direction (against the
    slip), the other is solved again with it (and slides too if it then cannot hold).
    """
    n = len(q)
    E = np.eye(2) if axes is None else np.asarray(axes, float)[:, :2]
    force = np.zeros((n, 3))
    force[:, 2] = fn
    a0 = predicted_acceleration(q, qd, tau, force, lift, poc, gravity)
    cols = []
    for i in range(2):
        unit = force.copy()
        unit[:, :2] = E[i]
        cols.append(predicted_acceleration(q, qd, tau, unit, lift, poc, gravity) - a0)
    a0_t = a0 @ E.T  # the acceleration along each axis
    cols_t = [c @ E.T for c in cols]
    ft = np.empty((n, 2))
    acc = np.empty((n, 2))
    for s in range(n):
        A = np.column_stack([cols_t[0][s], cols_t[1][s]])
        limit = mu * fn[s] if bound is None else float(bound[s])
        f = np.linalg.solve(A, -a0_t[s])  # both axes held
        over = np.abs(f) > limit
        if over.any():
            i = int(np.argmax(np.abs(f)))  # the axis furthest past its (common) bound slides first
            j = 1 - i
            f[i] = math.copysign(limit, f[i])
            f[j] = -(a0_t[s, j] + A[j, i] * f[i]) / A[j, j]
            if abs(f[j]) > limit:
                f[j] = math.copysign(limit, f[j])
        ft[s] = f @ E
        acc[s] = a0[s] + np.column_stack([cols[0][s], cols[1][s]]) @ f
    return ft, acc


def _score_pyramid(tr: RunResult, physics: Physics, cls: type[Backend], coef: str, mu: float, v: np.ndarray,
                   k: np.ndarray, touching: np.ndarray, counts: tuple[int, int, int], lift: float = 0.0,
                   poc: str = "true") -> list[dict[str, Any]]:  # fmt: skip
    """The drag scored against the friction pyramid's closed form (:func:`pyramid_friction`) on the run's declared
    tangent axes (:func:`friction_axes`; rows below by :func:`drag_frame`: the axis along the drag, W y for
    today's engines, and the one across it, W x): the force along the drag at mu Fn, the force across it at the
    closed form's (which holds that axis: an engine with no friction along W x passed a bound |F_x| <= mu Fn, and
    its W y acceleration moved by 1.6 % only, within 2 %), the slip acceleration along the drag's axis; ``coef``:
    the coefficient the backend slides with (:func:`sliding_coefficient`); ``lift``, ``poc``: where its force
    acts (:func:`~legbench.backends.base.contact_point`); the acceleration at the samples whose central difference
    is in contact (``touching``, :func:`_stencil`); ``counts``: the window's (:data:`COUNT_KEYS`).

    The backend's explanation of a miss is asked with what the run measured (:func:`_with_known`, ``drag``):
    ``mu``; ``friction_bound``, the friction the axis along the drag slid with, mean |F_along| / Fn over the samples
    where the closed form slides it (NaN where no sample slides); and where the backend's solver bounds friction by
    a frictionless normal impulse, its bound predicted and the closed form with it (:func:`_at_predicted_bound`)."""
    case, backend = "sliding", tr.backend
    Ts = physics.control_dt
    E = drag_frame(friction_axes(tr.info))  # rows: the axis across the drag, the axis along it
    fn = tr.f[k, 2]
    ft_pred, a_pred = pyramid_friction(tr.q[k], tr.qd[k], tr.tau[k], fn, mu, lift, poc, E, physics.gravity)
    ft_pred, a_pred, f_meas, v_ax = ft_pred @ E.T, a_pred @ E.T, tr.f[:, :2] @ E.T, v @ E.T  # on (across, along)
    slides = np.abs(ft_pred[:, 1]) >= mu * fn * (1.0 - 1e-12)  # the closed form's along-drag axis at its bound
    # at its worst sample against the closed form's there (mu where it slides, the force that holds it elsewhere)
    along, expected_along, worst = _worst_at(np.abs(f_meas[k, 1]) / fn, np.abs(ft_pred[:, 1]) / fn)
    across, across_pred = float(np.mean(f_meas[k, 0] / fn)), float(np.mean(ft_pred[:, 0] / fn))
    s = _stencil(touching, k)
    counts = (counts[0], counts[1], int(s.sum()))
    ka = k[s]
    a_meas = (v_ax[ka + 1, 1] - v_ax[ka - 1, 1]) / (2 * Ts)
    am, ap = _mean(a_meas), _mean(a_pred[s, 1])
    # the bound the engine slid with along the drag, measured (beside the one its solver predicts, if any)
    bound = float(np.mean(np.abs(f_meas[k[slides], 1]) / fn[slides])) if slides.any() else math.nan
    predicted = _at_predicted_bound(tr, physics, mu, k, s, fn, slides, worst, lift, poc, E)
    speed = np.abs(v_ax[k, 1])
    ctx = (f"pyramid on {_axes_text(tr.info)}, {coef} = {mu:g}; the closed form at {coef} slides the axis along the "
           f"drag at {int(slides.sum())} of {len(k)} samples; slip along it {_span(1e3 * speed)} mm/s, "
           f"Fn {fn.mean():.3g} N, {_contact_text(counts)}")  # fmt: skip
    acc = f"closed form M^-1 (tau - nle + J_poc^T F), F the pyramid's{_at(poc)}; {ctx}"
    if ap != 0.0:
        acc_row = _relative(case, backend, "slip acceleration along the drag (mean; pyramid)", "m/s^2", am, ap,
                            TOL_ACC, acc)  # fmt: skip
    else:  # the closed form holds both axes: the scale is the acceleration the drag gives without friction
        free = np.column_stack([np.zeros((len(ka), 2)), fn[s]])
        scale = _mean(np.abs((predicted_acceleration(tr.q[ka], tr.qd[ka], tr.tau[ka], free, lift, poc,
                                                     physics.gravity) @ E.T)[:, 1]))  # fmt: skip
        acc_row = (case, backend, "slip acceleration along the drag (mean; pyramid)", "m/s^2", am, 0.0, abs(am),
                   TOL_ACC * scale, abs(am) <= TOL_ACC * scale,
                   f"{acc}; tolerance {100 * TOL_ACC:g} % of the frictionless acceleration")  # fmt: skip
    rows = [
        (case, backend, "friction along the drag |F_y| / Fn (worst sample; pyramid)", "1", along, expected_along,
         abs(along - expected_along), TOL_MU * mu, abs(along - expected_along) <= TOL_MU * mu,
         f"{ctx}; tolerance {100 * TOL_MU:g} % of mu (the closed form's force is mu Fn where the axis slides, the "
         "holding force where it holds)"),
        (case, backend, "friction across the drag F_x / Fn (mean; pyramid)", "1", across, across_pred,
         abs(across - across_pred), TOL_MU * mu, abs(across - across_pred) <= TOL_MU * mu,
         f"the closed form's force across the drag, which holds the foot there; {ctx}; tolerance {100 * TOL_MU:g} % "
         "of mu"),
        acc_row,
    ]  # fmt: skip
    return _with_known(cls, tr, rows, counts, {"mu": mu, "friction_bound": bound, **predicted})


def _at_predicted_bound(tr: RunResult, physics: Physics, mu: float, k: np.ndarray, s: np.ndarray, fn: np.ndarray,
                        slides: np.ndarray, worst: int, lift: float, poc: str,
                        E: np.ndarray) -> dict[str, Any]:  # fmt: skip
    """The pyramid's closed form with the bound the backend's solver had, predicted (``frictionless_fn`` in the
    run's info, :func:`drag`: mu times the frictionless normal force at each sample) rather than measured: its
    ``predicted_bound`` (mean bound / Fn over the samples the closed form at mu slides, as ``friction_bound`` is
    measured), ``predicted_holds`` (the share of the scored samples at which the axis along the drag holds under
    it) and ``at_predicted``, what each row would read: ``along`` at the row's own sample ``worst``, ``across`` and
    ``acceleration`` as the rows average them. Empty where the run has no prediction."""
    fn0 = np.asarray(tr.info.get("frictionless_fn", ()), float)
    if fn0.shape != tr.t.shape or not np.isfinite(fn0[k]).all():
        return {}
    limit = mu * fn0[k]
    ft_b, a_b = pyramid_friction(tr.q[k], tr.qd[k], tr.tau[k], fn, mu, lift, poc, E, physics.gravity, limit)
    ft_b, a_b = ft_b @ E.T, a_b @ E.T
    holds = np.abs(ft_b[:, 1]) < limit * (1.0 - 1e-12)
    return {
        "predicted_bound": float(np.mean(limit[slides] / fn[slides])) if slides.any() else math.nan,
        "predicted_holds": float(np.mean(holds)),
        "at_predicted": {"along": float(np.abs(ft_b[worst, 1]) / fn[worst]),
                         "across": float(np.mean(ft_b[:, 0] / fn)), "acceleration": _mean(a_b[s, 1])},
    }  # fmt: skip


__all__ = [
    "COUNT_KEYS",
    "ROW_KEYS",
    "applies_law",
    "diamond_friction",
    "drag",
    "drag_frame",
    "friction_axes",
    "predicted_acceleration",
    "pyramid_friction",
    "score",
    "sliding_case",
    "sliding_coefficient",
]
