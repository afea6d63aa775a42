"""Contact calibration: each backend's effective normal stiffness, damping and creep, beside the spec's.

The leg stands on the ground at q* (the effort task's pose) under the effort
controller tau = Jv^T h_d + G, driven directly through the Backend API:

1. static push, h_d = (0, 0, -F1) then a step to (0, 0, -F2): the effective
   normal stiffness is k = (Fn2 - Fn1) / (y2 - y1) from the two rests
   (penetration y = R_foot - z_E), and the effective damping c is the
   least-squares fit of Fn - (k y + b) = c ydot over the pressing-in part of
   the step's transient (ydot > 1 mm/s; the spec's damping acts only while
   pressing in), k y + b being the chord through the two rests: exact for a
   normal law linear in y, from the origin or from an offset (PyBullet's
   slop). Where the chord misses the origin by more than
   :data:`CHORD_INTERCEPT_RTOL` of F1 the normal law is not linear in the
   depth and no spring-damper fits the step: c is n/a (NaN) and the note
   gives the intercept b;
2. slow tangential load: F_x of h_d ramps from 0 to ``ratio`` mu_s F2 (below
   the friction limit) over ``ramp`` seconds and is held; the creep is the
   net slip of the point of contact over the end of the hold: the magnitude
   of the mean of its horizontal velocity v_t (= J_poc qd), its slip
   integrated over the window divided by the window's length, so a contact
   that jitters about a slow drift reads the drift. The jitter is the RMS of
   v_t about that mean. The spec's stick-slip law creeps at
   v = v_th F_t / (mu_s Fn) (the linear part of mu(v)); a Coulomb engine
   sticks; an engine with a regularised (soft) friction cone creeps at about
   F_t / Kd (the lab report). The effective tangential damping F_t / creep
   is printed too.

Data flow: :func:`push` (one backend, a :class:`~legbench.results.RunResult`) ->
:func:`estimate` (:class:`Calibration`, frozen) -> :func:`calibrate` (a
DataFrame, one row per backend) -> :func:`write_calibration`
(``calibration.json`` and ``calibration.md``).
"""

from __future__ import annotations

import argparse
import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from legbench import backends as registry
from legbench import kinematics, model, resources
from legbench import scenario as scenario_mod
from legbench.backends.base import FRICTION_COEFFICIENTS, PROFILES, contact_point, rigid_contact
from legbench.contact import ContactParams
from legbench.controllers import EffortController, saturate
from legbench.exceptions import BackendNotFound, LegbenchError
from legbench.results import (
    SHOWN_SCALE,
    RunResult,
    atomic_write_text,
    check_study_out,
    platform_info,
    study_dir,
    versions,
    write_json,
)
from legbench.run import backend_info, backend_rates
from legbench.scenario import Event, physics_of
from legbench.studies.executors import DEFAULT_PRELOAD, make_executor
from legbench.yamlfile import one_line

__all__ = [
    "CHORD_INTERCEPT_RTOL",
    "C_EFF_RTOL",
    "STATUSES",
    "STICK_SPEED",
    "Calibration",
    "Program",
    "add_cli",
    "calibrate",
    "estimate",
    "push",
    "write_calibration",
]

SCENARIO = resources.scenario("effort")
#: Below this creep [m/s] the foot is taken to stick (``c_tangential`` = inf): 1 um in 1000 s, six orders
#: below the spec's law's creep here (4.7e-4 m/s) and well above round-off in J_poc qd (a Coulomb engine
#: that holds the foot reads 1e-16-1e-12 m/s); a ratio against round-off would print 1e16 N s/m.
STICK_SPEED = 1e-9
#: A compliant contact's k eff further than this from Kp (relative) gets a note: the backend's explanation of its
#: rest (``Backend.known_deviation``, as in the verification's rest case) or the deviation itself.
K_EFF_RTOL = 1e-3
#: A creep further than this from the law's (relative) is asked about (``Backend.known_deviation``, case
#: ``creep``), and an explanation that is a closed form must meet the measured creep within it: the closed forms
#: are steady states, and over the hold the creeping leg's configuration moves on (MuJoCo: 0.03 %).
CREEP_RTOL = 1e-2
#: The chord between the rests, k y + b, may miss the origin by this share of F1 (|b| / F1) before the normal law
#: counts as not linear in the depth and c eff is n/a. Measured |b| / F1: matched profile at most 3.2e-7 (Lagrange;
#: the others 1e-12 to 2e-8); engine-defaults ODE 3.1e-4 (its quick step's jittering rests), PyBullet 5.0e-3 (its
#: 1e-5 m slop: a linear spring from an offset, Kp slop = 0.1 N, whose line through the rests gives c = 100.15
#: against its pair damping 100.1 N s/m), MuJoCo 0.209 (the usual solref through the impedance: nonlinear; the
#: origin fit read 522.5 N s/m, with k free 1681, with k and b free 30.5). Below it, a power law Fn ~ y^p curved
#: enough to move b by 1e-2 F1 (p = 0.993 or 1.007) biases the fit through the chord by under 0.5 % (0.08 % on the
#: matched profile's transient, 0.44 % on a monotone rise: tests/test_calibrate_contact.py), where the fit through
#: the origin it replaces was 2 % and 10 % off.
CHORD_INTERCEPT_RTOL = 1e-2
#: A compliant contact's c eff further than this from Kd (relative) is off the spec. The fit over the pressing-in
#: transient reads a linear spring-damper's damping to 1e-4 (matched profile: 99.9998-100.01 N s/m against
#: Kd = 100) and the engine-defaults' linear dampers to 0.15 % (PyBullet 100.145 against its pair damping 100.1,
#: ODE 99.91); a curved normal law may move it by up to 0.5 % before c eff is n/a (:data:`CHORD_INTERCEPT_RTOL`).
C_EFF_RTOL = 1e-2
#: A row's ``status`` against the spec: every value within its tolerance (k eff :data:`K_EFF_RTOL`, c eff
#: :data:`C_EFF_RTOL`, creep :data:`CREEP_RTOL` of the law's); one off but explained (its backend's closed form
#: meets it; a rigid contact, which has no Kp or Kd; a Coulomb foot that sticks where the law creeps); one off with
#: no explanation; or a push that could not run.
STATUSES = ("as specified", "explained", "not explained", "failed")


@dataclass(frozen=True)
class Program:
    """The load program, all forces being h_d, what the foot exerts on the ground, in W.

    Attributes:
        F1: first normal push [N].
        F2: second normal push, from ``phase`` on [N].
        phase: length of each normal phase [s].
        ratio: tangential load as a share of mu_s F2 (below 1: below the friction limit).
        ramp: duration of the tangential ramp [s].
        hold: duration of the hold at full tangential load [s].
        window: averaging window at the end of each phase [s].
        transient: part of the F1 -> F2 step used for the damping fit [s].
    """

    F1: float = 20.0
    F2: float = 40.0
    phase: float = 0.5
    ratio: float = 0.5
    ramp: float = 0.5
    hold: float = 1.0
    window: float = 0.2
    transient: float = 0.1

    @property
    def duration(self) -> float:
        """Total length [s]."""
        return 2 * self.phase + self.ramp + self.hold

    def h_d(self, t: float, mu_s: float) -> np.ndarray:
        """Desired foot force on the ground in W at time t [N]."""
        if t < self.phase:
            return np.array([0.0, 0.0, -self.F1])
        if t < 2 * self.phase:
            return np.array([0.0, 0.0, -self.F2])
        share = min((t - 2 * self.phase) / self.ramp, 1.0)
        return np.array([share * self.ratio * mu_s * self.F2, 0.0, -self.F2])


def push(name: str, program: Program = Program(), scenario_file: Path = SCENARIO,
         contact_mode: str | None = None, profile: str = PROFILES[0]) -> tuple[RunResult, int]:  # fmt: skip
    """Run the load program on backend ``name`` from the scenario's initial pose, with its physics and settings,
    the backend in ``profile``.

    Returns:
        The run (torques as applied, after saturation), and the number of ticks at which a
        torque hit its limit.
    """
    sc = scenario_mod.load(scenario_file)
    physics = physics_of(sc, contact_mode)
    backend = registry.load(name, physics, sc.backends.get(name, {}), profile)
    Ts = sc.control_dt
    n = int(round(program.duration / Ts)) + 1
    t = np.arange(n) * Ts
    Q, QD, TAU, F = np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((n, 3))
    limit = np.array(physics.torque_limit)
    saturated = 0
    ctrl, h_prev = None, None
    try:
        backend.reset(np.array(sc.q0), np.array(sc.qd0))
        for k in range(n):
            q, qd = backend.state()
            Q[k], QD[k], F[k] = q, qd, backend.ground_force()
            h = tuple(program.h_d(t[k], sc.contact.mu_s).tolist())
            if ctrl is None or h != h_prev:  # a new effort event whenever h_d changes (every tick of the ramp)
                ctrl, h_prev = EffortController(Event(float(t[k]), "effort", force=h), gravity=sc.gravity), h
                ctrl.start(float(t[k]), q, qd)
            raw = np.asarray(ctrl(k, q, qd), float)
            saturated += int(np.any(np.abs(raw) > limit))
            TAU[k] = saturate(raw.copy(), limit)
            if k < n - 1:
                backend.step(TAU[k])
        info = backend_info(backend)
    finally:
        backend.close()
    return RunResult(name, t, Q, QD, TAU, F, np.full(n, "effort", dtype=object), info=info), saturated


@dataclass(frozen=True)
class Calibration:
    """Effective contact parameters of one backend, beside the spec's.

    Attributes:
        backend: backend name.
        Kp, Kd, mu_s, v_th: the spec's (scenario's) normal stiffness [N/m], damping [N s/m],
            static friction coefficient and stick-slip threshold speed [m/s].
        k_eff: effective normal stiffness [N/m] (NaN, not applicable, for a rigid contact: the note gives its
            sink).
        c_eff: effective normal damping while pressing in [N s/m], fitted through the chord between the rests (NaN
            for a rigid contact, and for a normal law not linear in the depth: the chord misses the origin by more
            than :data:`CHORD_INTERCEPT_RTOL` of F1, the note giving by how much).
        Fn: normal force at the end of the hold [N].
        Ft: tangential force at the end of the hold [N].
        creep: net slip speed of the point of contact at the end of the hold, |mean v_t| over the window (its slip
            over the window divided by the window's length) [m/s].
        jitter: RMS of the point of contact's horizontal velocity v_t about its mean over the same window [m/s]
            (0 to round-off for a steady creep; an unconverged solver's contact shakes about its drift).
        creep_law: the spec's law's creep for the same Fn and Ft, v_th Ft / (mu_s Fn) [m/s].
        c_tangential: Ft / creep, the net creep [N s/m] (inf when the foot sticks: creep below :data:`STICK_SPEED`).
        compliant: the backend's native contact declares a stiffness (``info()["contact"]["Kp"]`` is
            not None); a rigid one (e.g. an LCP engine) has no Kp or Kd to match: its k_eff and c_eff are
            NaN (the report's n/a) and the note gives the rests' sink and the backend's closed form of it.
        note: saturation or fit problems.
        status: the row against the spec, one of :data:`STATUSES`.
        against_spec: each value off the spec, by how much, and whether it is explained ("" where none is).
    """

    backend: str
    Kp: float
    Kd: float
    mu_s: float
    v_th: float
    k_eff: float
    c_eff: float
    Fn: float
    Ft: float
    creep: float
    creep_law: float
    c_tangential: float
    jitter: float = math.nan
    compliant: bool = True
    note: str = ""
    status: str = "failed"
    against_spec: str = ""


def estimate(log: RunResult, program: Program, contact: Any, saturated: int = 0) -> Calibration:
    """Stiffness, damping and creep from the run of :func:`push` (module docstring).

    Args:
        log: the push run.
        program: the load program it ran.
        contact: the scenario's contact parameters.
        saturated: ticks at which a torque hit its limit (noted: h_d was then not fully applied).
    """
    R = model.load_params().geometry.R_foot
    y = R - kinematics.fk(log.q)[:, 2]
    J = kinematics.jacobian_at(log.q, *contact_point(log.info, contact.poc))  # the slip where the force acts
    v = np.einsum("nij,nj->ni", J, log.qd)
    ydot = -v[:, 2]
    t, f = log.t, log.f

    def window(end: float) -> np.ndarray:
        return (t > end - program.window - 1e-9) & (t <= end + 1e-9)

    w1, w2 = window(program.phase - 1e-3), window(2 * program.phase - 1e-3)
    (y1, f1), (y2, f2) = ((float(y[w].mean()), float(f[w, 2].mean())) for w in (w1, w2))  # the two rests [m, N]
    dy = y2 - y1
    k_eff = (f2 - f1) / dy if abs(dy) > 0 else math.nan
    b = f1 - k_eff * y1  # the chord's force at y = 0 [N]: 0 for a spring linear in y from the origin
    tr = (t >= program.phase) & (t < program.phase + program.transient) & (ydot > 1e-3)
    notes = []
    compliant = not rigid_contact(log.info)
    depth = math.nan  # the fit's samples' penetration, weighted as the fit weights them [m]
    if tr.sum() >= 3 and math.isfinite(k_eff):
        r = f[tr, 2] - (k_eff * y[tr] + b)  # the spring taken as the chord through the rests, offset and all
        c_eff = float(r @ ydot[tr] / (ydot[tr] @ ydot[tr]))
        depth = float(y[tr] @ ydot[tr] ** 2 / (ydot[tr] @ ydot[tr]))
    else:
        c_eff = math.nan
        if compliant:  # a rigid contact's damping does not apply whatever the fit (below)
            notes.append("too few pressing-in samples for the damping fit")
    end = window(program.duration)
    Fn = float(f[end, 2].mean())
    Ft = float(np.hypot(f[end, 0], f[end, 1]).mean())
    vt = v[end, :2]
    v_net = vt.mean(axis=0)  # the slip over the window / its length [m/s]: what a jittering contact nets
    creep = float(np.hypot(*v_net))
    jitter = float(np.sqrt(np.mean(np.sum((vt - v_net) ** 2, axis=1))))
    if saturated:
        notes.append(f"{saturated} ticks saturated a joint torque: h_d was not fully applied")
    off: list[tuple[str, bool]] = []  # each value off the spec, in words, and whether it is explained
    k_known = False  # a stiffness off Kp that its backend's closed form explains
    if compliant and not math.isfinite(k_eff):
        off.append(("k eff not measured (the rests did not move apart)", False))
    if compliant and math.isfinite(k_eff) and abs(k_eff / contact.Kp - 1.0) > K_EFF_RTOL:
        # the second rest is the verification's rest case (y = Fn/Kp): the backend's measured explanation of a
        # miss there, held to its own closed form at this rest, says why the stiffness is not Kp
        known, k_known = _known(log, "rest_penetration", "penetration R_foot - z_E", log.info, y2, f2 / contact.Kp,
                                K_EFF_RTOL * y2)  # fmt: skip
        # k eff is the chord between the two rests: explained where the backend's closed form holds both rests (a
        # stiffness at one rest, a secant, is not the chord of a law that curves); the note gives the second's
        _, first_known = _known(log, "rest_penetration", "penetration R_foot - z_E", log.info, y1, f1 / contact.Kp,
                                K_EFF_RTOL * y1)  # fmt: skip
        k_known = k_known and first_known
        where = (f"k eff is the chord between the two rests; the backend's closed form holds the first (Fn = {f1:.4g} "
                 f"N) {'too' if first_known else 'not'}; at the second (Fn = {f2:.4g} N): ")  # fmt: skip
        notes.append(where + known if known else f"k eff {100 * (k_eff / contact.Kp - 1.0):+.3g} % off Kp")
        off.append((f"k eff {k_eff / contact.Kp:.4g}x Kp", k_known))
    if compliant and math.isfinite(c_eff) and abs(b) > CHORD_INTERCEPT_RTOL * abs(f1):
        notes.append(f"c eff n/a: the normal law is not linear in the depth: the chord between the rests (k eff) meets "
                     f"y = 0 at {b:.3g} N ({b / f1:+.2g} of F1, beyond {CHORD_INTERCEPT_RTOL:g}), so no spring-damper "
                     f"fits the step (the fit through that chord read {c_eff:.4g} N s/m)")  # fmt: skip
        c_eff = math.nan
        # no damping to hold to Kd: explained where the stiffness off Kp is (the backend's closed form of a normal
        # law that is not linear, e.g. through an impedance); a curved law beside a Kp-like chord is not
        off.append(("c eff n/a (the normal law is not linear in the depth)", k_known))
    elif compliant and not math.isfinite(c_eff):
        off.append(("c eff not measured", False))
    elif compliant and abs(c_eff / contact.Kd - 1.0) > C_EFF_RTOL:
        # the engine's own normal damping, where it has one in closed form (e.g. growing with the depth), held to it
        known, ok = _known(log, "damping", "normal damping c eff while pressing in", {**log.info,
                           "transient": {"depth": depth}}, c_eff, contact.Kd, C_EFF_RTOL * abs(c_eff))  # fmt: skip
        notes.append(known if known else f"c eff {c_eff:.4g} N s/m against Kd {contact.Kd:g}: the backend gives no "
                     "closed form of its damping (docs/studies.md, section 5)")  # fmt: skip
        off.append((f"c eff {c_eff / contact.Kd:.4g}x Kd", ok))
    creep_law = contact.v_th * Ft / (contact.mu_s * Fn) if Fn > 0.0 else math.nan  # the foot off the ground: none
    if creep <= STICK_SPEED:
        if math.isfinite(creep_law) and creep_law > 0.0:
            # Coulomb friction holds a load below its mu Fn exactly, the law's creep being its regularisation's
            # (v_th): explained for an engine's own contact under such a load; a law backend that sticks is not
            own = bool(log.info.get("engine_contact", True)) and log.info.get("contact_mode") != "reference"
            coef = log.info.get("sliding_coefficient")
            coef = coef if coef in FRICTION_COEFFICIENTS else "mu_s"  # a run that recorded none: the spec's limit
            mu = float(getattr(contact, coef))
            held_below = Ft < mu * Fn
            why = ("held by the engine's contact below its mu Fn, as Coulomb friction holds" if own and held_below
                   else "no Coulomb contact to hold it" if not own else f"Ft above {coef} Fn")  # fmt: skip
            off.append((f"sticks where the law creeps {1e3 * creep_law:.4g} mm/s ({why})", own and held_below))
    elif math.isfinite(creep_law) and not math.isclose(creep, creep_law, rel_tol=CREEP_RTOL):
        # the engine's own tangential law, where it has one in closed form, held to the measured creep
        load = {"Fn": Fn, "Ft": Ft, "F": f[end].mean(axis=0).tolist()}
        known, ok = _known(log, "creep", "creep of the point of contact", {**log.info, "load": load}, creep,
                           creep_law, CREEP_RTOL * creep)  # fmt: skip
        ratio = f"{creep / creep_law:.4g}x the law's" if creep_law > 0.0 else f"{1e3 * creep:.4g} mm/s, the law 0"
        notes.append(
            known
            if known
            else f"creep {ratio} ({1e3 * creep:.4g} mm/s net, {1e3 * jitter:.3g} mm/s RMS "
            "jitter about it): the backend gives no closed form of its creep (docs/studies.md, section 5)"
        )
        off.append((f"creep {ratio}", ok))
    if not compliant:
        # no spring to fit: what the rests' dFn/dy measures is the engine's constraint regularisation, and a rest
        # that moves the other way (the pose settling) gave "inf"; the backend's closed form of its sink, if any
        fitted = f"dFn/dy {k_eff:.4g} N/m" if dy > 0.0 else "no dFn/dy"
        known, _ = _known(log, "rest_penetration", "penetration R_foot - z_E", {**log.info, "load": {"Fn": f2}}, y2,
                          0.0, K_EFF_RTOL * abs(y2))  # fmt: skip
        notes.append(f"rigid contact: no Kp, Kd to match, so k eff and c eff do not apply (n/a): the rests moved by "
                     f"{dy:.2g} m under the added {f2 - f1:.3g} N ({fitted}): the "
                     f"engine's constraint regularisation and the pose settling, not a spring; y = {y2:.3g} m at Fn = "
                     f"{f2:.3g} N"
                     + (f"; {known}" if known else ""))  # fmt: skip
        k_eff = c_eff = math.nan
        off.insert(0, ("rigid: no Kp, Kd (k eff, c eff n/a)", True))
    status = ("not explained" if any(not known for _, known in off) else "explained" if off
              else "as specified")  # fmt: skip
    against = "; ".join(f"{what}{'' if known else ': not explained'}" for what, known in off)
    return Calibration(
        backend=log.backend, Kp=contact.Kp, Kd=contact.Kd, mu_s=contact.mu_s, v_th=contact.v_th, k_eff=k_eff,
        c_eff=c_eff, Fn=Fn, Ft=Ft, creep=creep, creep_law=creep_law,
        c_tangential=Ft / creep if creep > STICK_SPEED else math.inf, jitter=jitter, compliant=compliant,
        note="; ".join(notes), status=status, against_spec=against,
    )  # fmt: skip


def _known(log: RunResult, *args: Any) -> tuple[str | None, bool]:
    """The explanation the run's backend gives of a deviation (``Backend.known_deviation(*args)``) and whether it is
    one: (None, False) where it gives none or is not installed here; where it raises, the note saying so and False
    (a failing explanation explains nothing)."""
    try:
        cls = registry.get(log.backend)
    except BackendNotFound:
        return None, False
    try:
        text = cls.known_deviation(*args)
    except Exception as exc:  # a backend's (a plug-in's) explanation failing must not lose the calibration
        return one_line(f"no explanation: {log.backend}'s known_deviation raised {type(exc).__name__}: {exc}"), False
    return text, text is not None


def _failed_row(name: str, contact: ContactParams, why: str) -> dict[str, Any]:
    """A backend's row of NaN whose note says why it could not be calibrated."""
    nan = math.nan
    return dataclasses.asdict(Calibration(
        backend=name, Kp=contact.Kp, Kd=contact.Kd, mu_s=contact.mu_s, v_th=contact.v_th, k_eff=nan, c_eff=nan,
        Fn=nan, Ft=nan, creep=nan, creep_law=nan, c_tangential=nan, note=f"failed: {why}",
    ))  # fmt: skip


def _calibrate_one(task: tuple[str, Program, Path, str | None, ContactParams, str]) -> dict[str, Any]:
    """One backend's row, ``(name, program, scenario_file, contact_mode, contact)``: a task for the pool. An
    engine that fails (any error, as in the run loop) gives a row of NaN whose note says why,
    and the other backends are still calibrated."""
    name, program, scenario_file, contact_mode, contact, profile = task
    try:
        log, saturated = push(name, program, scenario_file, contact_mode, profile)
    except Exception as exc:  # as the run loop: any error of the engine's fails this backend alone
        return _failed_row(name, contact, f"{type(exc).__name__}: {exc}")
    return dataclasses.asdict(estimate(log, program, contact, saturated))


def _crashed(task: tuple[str, Program, Path, str | None, ContactParams, str], why: str) -> dict[str, Any]:
    """The row of a backend whose worker process died under it (the engine crashed)."""
    return _failed_row(task[0], task[4], f"the engine crashed: {why}")


def calibrate(
    out_dir: str | Path | None = None,
    backends: Sequence[str] | None = None,
    program: Program = Program(),
    scenario_file: Path = SCENARIO,
    contact_mode: str | None = None,
    jobs: int = 1,
    profile: str = PROFILES[0],
) -> pd.DataFrame:
    """Calibrate every backend (default: all available) in ``profile``; one row per backend, optionally written to
    ``out_dir``.

    ``jobs``: worker processes (1: in this process); the rows are the same whatever the number.
    """
    if not 0 < program.ratio < 1:
        raise LegbenchError(f"tangential ratio {program.ratio} must lie in (0, 1): below the friction limit")
    registry.check_profile(profile)
    sc = scenario_mod.load(scenario_file)
    contact = sc.contact
    names = list(backends) if backends is not None else registry.available()
    tasks = [(n, program, Path(scenario_file), contact_mode, contact, profile) for n in names]
    rates = backend_rates() if jobs > 1 else {}
    first = sorted(range(len(tasks)), key=lambda i: -rates.get(names[i], 1.0))  # the slowest backend first
    with make_executor("local", jobs, preload=(*DEFAULT_PRELOAD, __name__)) as ex:
        rows = list(ex.imap(_calibrate_one, tasks, first, _crashed))
    df = pd.DataFrame(rows)
    if out_dir is not None:
        write_calibration(df, Path(out_dir), program, profile, contact_mode or physics_of(sc).contact_mode)
    return df


_HEADERS = {
    "backend": "backend", "Kp": "Kp spec [N/m]", "k_eff": "k eff: dFn/dy between the rests [N/m]",
    "Kd": "Kd spec [N s/m]", "c_eff": "c eff [N s/m]", "mu_s": "mu_s", "Fn": "Fn [N]", "Ft": "Ft [N]",
    "creep": "creep: net slip [mm/s]", "jitter": "jitter: RMS slip about it [mm/s]", "creep_law": "law creep [mm/s]",
    "c_tangential": "Ft/creep [N s/m] (inf: sticks)", "status": "against the spec",
    "against_spec": "off the spec",
}  # fmt: skip


def markdown(df: pd.DataFrame) -> str:
    """The calibration table as Markdown (creep and jitter in mm/s; n/a where a value is undefined, e.g. a rigid
    contact's damping, or a nonlinear normal law's), each row's status against the spec (:data:`STATUSES`) and what
    is off it last."""
    lines = ["| " + " | ".join(_HEADERS.values()) + " |", "|" + "---|" * len(_HEADERS)]
    for r in df.to_dict(orient="records"):
        cells = [
            str(r[k]) if isinstance(r[k], str) else "n/a" if math.isnan(r[k])
            else f"{r[k] * SHOWN_SCALE.get(k, 1.0):.4g}"
            for k in _HEADERS
        ]  # fmt: skip
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def write_calibration(df: pd.DataFrame, out_dir: Path, program: Program = Program(), profile: str = PROFILES[0],
                      contact_mode: str = "native") -> Path:  # fmt: skip
    """Write ``calibration.json`` (with the ``profile`` and ``contact_mode`` the pushes ran in) and
    ``calibration.md`` into ``out_dir``."""
    out_dir.mkdir(parents=True, exist_ok=True)
    meta = {"schema": "legbench.calibration/1", "program": dataclasses.asdict(program), "profile": profile,
            "contact_mode": contact_mode,
            "rows": df.to_dict(orient="records"), "versions": versions(), "platform": platform_info()}  # fmt: skip
    write_json(meta, out_dir / "calibration.json")
    notes = [f"- {r['backend']}: {r['note']}" for r in df.to_dict(orient="records") if r["note"]]
    units = {"F1": "N", "F2": "N", "ratio": "of mu_s F2"}
    spec = ", ".join(f"{k} {v:g} {units.get(k, 's')}" for k, v in dataclasses.asdict(program).items())
    text = [f"# Contact calibration, {profile} profile, {contact_mode} contact\n",
            f"Program (legbench/studies/calibrate_contact.py, `Program`): {spec}.\n", markdown(df),
            *notes]  # fmt: skip
    atomic_write_text(out_dir / "calibration.md", "\n".join(text) + "\n")
    return out_dir


def _cli(args: argparse.Namespace) -> int:
    out = args.out or study_dir("results", "calibration", args.profile)
    check_study_out(out, "calibration.json", ("calibration.json", "calibration.md"), "calibration", args.force)
    df = calibrate(out, registry.resolve(args.backends), contact_mode=args.contact_mode, jobs=args.jobs,
                   profile=args.profile)  # fmt: skip
    print(markdown(df))
    for r in df.to_dict(orient="records"):
        if r["note"]:
            print(f"note: {r['backend']}: {r['note']}")
    print(f"wrote {out} ({args.profile} profile)")
    return 1 if (df["status"] == "failed").any() else 0


def add_cli(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Register ``legbench calibrate-contact [--out DIR] [--backends all] [--contact-mode native|reference]
    [--jobs N] [--profile P]``."""
    p = subparsers.add_parser("calibrate-contact", help="effective contact stiffness, damping and creep per backend")
    p.add_argument("--out", default=None, help="output directory (default results/calibration, "
                   "results/calibration__engine-defaults for --profile engine-defaults)")  # fmt: skip
    p.add_argument("--profile", choices=PROFILES, default=PROFILES[0],
                   help=f"the backends' profile (default {PROFILES[0]}; engine-defaults: the engine's own settings, "
                   "Kp, Kd and mu set its usual way)")  # fmt: skip
    p.add_argument("--backends", default="all", help="comma-separated backend names, or 'all' (default)")
    p.add_argument("--contact-mode", choices=("native", "reference"), default=None,
                   help="contact of the calibration pushes: each engine's own ('native', default) or the "
                        "spec's law applied in every engine ('reference')")  # fmt: skip
    p.add_argument("--jobs", type=int, default=1, help="worker processes, one backend each (default 1)")
    p.add_argument("--force", action="store_true", help="replace a finished calibration in --out")
    p.set_defaults(func=_cli)
