"""MuJoCo backend: the generated URDF compiled through ``MjSpec``, native soft contact or the reference law.

Model: ``models/leg.urdf`` is loaded with :func:`mujoco.MjSpec.from_string` (no
hand-written MJCF copy of the leg), with MuJoCo's ``<mujoco><compiler fusestatic="false"/>``
added by this backend (:data:`COMPILER`): it keeps the foot a body of its own, welded to link 3
at the foot centre E; a site ``E`` marks that point (MuJoCo's URDF default ``fusestatic="true"``
would fuse the foot into link 3; the ``engine-defaults`` force depends on it, see below). On the
spec we add the ground plane z_W = 0, one ``motor`` actuator per joint (gear 1, control range
= torque limit), stiff joint limits (docs/contact_mapping.md: solref (0.002, 1), solimp
(0.99, 0.999, ...): the knee driven from q = (0, 0, 1.8) rad into its 2.229 rad limit with 10 N m, gravity
off, matched profile, peaks at 2.2547 rad (0.026 rad over, at 25 ms) and rests at 2.2292 rad) and collision
filters so that only the foot sphere touches the ground (no link-link or other link-ground contact).

Native contact (``contact_mode = "native"``), on one explicit contact pair per
foot geom (``<pair>``: its parameters bypass the two-geom mixing rules; no
other geom collides). Profiles (docs/contact_mapping.md has the study):

* ``matched`` (the defaults): the "direct" reference ``solref = (-Kp A, -Kd A)``
  with the impedance pinned at ``d = 1e-4`` (``solimp = (1e-4, 1e-4, 0.001, 0.5, 2)``)
  makes the normal force ``Kp pen + Kd pen_rate`` in newtons, where
  ``A = body_invweight0[foot, 0]`` is the inverse inertia MuJoCo uses for the
  contact's regulariser (frozen at qpos0); on the pyramidal cone, whose four rows
  each take 2 (mu^2 / impratio) (1 + mu^2) times that regulariser, the solref is
  scaled by that factor over 4 as well (the four rows' normal forces add up), so the law is the same on
  either cone (measured Fn / y 10,001 N/m on both, impratio 1 and 10). Friction: elliptic cone with
  ``mu_s`` (condim 3), the noslip post-pass (``noslip``, 10 iterations) and
  "deadbeat" friction rows, ``solreffriction = (-1, -dmax / h)``: the friction
  rows' reference acceleration -v_t / h asks the unregularised noslip pass to
  stop the slip within one sub-step, inside the cone. The foot then sticks below
  mu_s Fn like a Coulomb cone (0.5 um over the effort task) and slides at mu_s Fn
  above it. Without noslip these rows are nearly force-free (the regulariser
  dominates) and the foot slides: :meth:`warnings` says so.
* ``engine-defaults``: MuJoCo's option defaults (pyramidal cone, impratio 1,
  Newton, 100 iterations, no noslip, solimp (0.9, 0.95, 0.001, 0.5, 2)) with Kp,
  Kd as the usual direct ``solref = (-Kp, -Kd)`` and mu as the pair friction,
  one 1 ms step per control period (MuJoCo's 2 ms default does not divide it).
  Friction is then the regularised cone: the foot creeps, 19.4 mm/s under F_t = 6.9 N
  in the effort task (F_t / creep = 3.5 Kd; F_t / Kd holds for the scaled solref).
  The raw solref's stiffness is per unit of the foot body's ``body_invweight0``
  (``mj_diagApprox`` takes the contact geom's body), so it depends on ``fusestatic="false"``:
  MuJoCo's URDF default (foot fused into link 3, A = 0.8431 instead of 2.2101 1/kg) gives
  Fn 75.0 N instead of 59.0 N in the effort task (docs/contact_mapping.md). So besides the
  1 ms step this profile keeps three things that are not MuJoCo's defaults: that compiler option,
  the stiff joint limits above (MuJoCo's: solref (0.02, 1), solimp (0.9, 0.95, ...); none
  of the four tasks reaches a limit) and ``mjDSBL_AUTORESET`` (below; ``info()['disableflags']``).
  Kp and Kd are then not the contact's stiffness and damping: ``info()['contact']['Kp_Kd_note']``
  gives the stiffness at rest MuJoCo has (1.264e5 N/m at 40 N).

Ground force read-out (setting ``force_readout``): ``end`` (default) is the force
at the end state of the control period (one more ``mj_forward`` after the sub-steps, whose position
and velocity stages the next period's first sub-step reuses, so it adds only one acceleration stage;
``efc_force`` through ``mj_contactForce``, rotated out of the contact
frame, after the noslip pass): the constraint solve at the logged end state under the period's held torque
(MuJoCo's contact force depends on the applied torque through the unconstrained acceleration, so unlike the
law's it is not a function of q and qd alone; at reset, before any torque, it is solved with zero control: so
where the torque jumps, at a controller switch, the row's force is the one under the period's torque before it,
not under the row's tau: 1 tick of 4000 in the combined task, (-1.49, 2.73, 7.74) N at 2 s where the next torque
gives (1.28, -5.27, 7.75) N; a review, 27 Nov);
``last`` is the force the last sub-step applied (Bullet's convention, one
sub-step behind); ``mean`` averages the applied force over the control period's
sub-steps (impulse / period, half a period behind). With a stiff friction row
(impratio 100, or noslip with the contact's own solref) the friction alternates
from sub-step to sub-step at the cone's edge, so any single read is wrong
(impratio 100 on the effort task: ``end`` read (-2.3, -37.3, 53.5) N and ``last``
(13.2, 25.8, 52.9) N where the statics said (5.6, -8.7, 53.1) N): only ``mean`` is
right then (0.18 % of Fn), and :meth:`warnings` says so. In the
profiles the friction does not alternate and all three agree. Measured against
the leg's statics F = -(J_poc^T)^-1 (tau - G(q)) (the ground's force on the foot; the
spec's h, the force the foot exerts, is -F) over the effort task's last
0.5 s: 0.2 % of Fn (matched), 0.01 % (engine-defaults); the 0.2 % is MuJoCo's
contact point, which sits in the middle of the penetration, y/2 above the true
poc (``info()['contact']['lift']`` 0.5). With ``rk4``, ``last`` and ``mean`` read a step's last (4th)
stage's solve (``mj_RungeKutta`` runs stages 2-4 with ``mj_forwardSkip`` and restores only
qpos, qvel and act), not its first stage's; ``end`` solves again at the end state.

Reference contact (``contact_mode = "reference"``): engine contact off
(``mjDSBL_CONTACT``); before every sub-step, ``qfrc_applied`` is set to
``J_poc^T F`` of :class:`~legbench.contact.ReferenceContact` at the sub-step's
start state. With ``euler`` this is exactly the semi-implicit Euler of the
Pinocchio backend; with ``rk4`` the contact force is held over the sub-step's
four stages (first order in the contact force, not a true RK4 of the law).

Sub-step ``dt`` (default 5e-5 s, 20 per 1 ms control period; 1 ms in
``engine-defaults``): MuJoCo's ``euler`` is semi-implicit Euler (the leg has no
joint damping, so ``implicitfast`` is the same scheme), first order; the same
sub-step as the Pinocchio backend, so in free space the two agree to round-off.
In reference mode the law's stiff friction slope is treated implicitly by
default (``reference_friction``; docs/contact_law.md says why it must be).
MuJoCo's automatic reset on a bad
acceleration is disabled: a divergence raises
:class:`~legbench.exceptions.SimulationDiverged` instead of silently
restarting from qpos0.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, ClassVar

import mujoco
import numpy as np

from legbench import kinematics
from legbench.backends.base import (
    FRICTION_COEFFICIENTS,
    Backend,
    Limits,
    Physics,
    held,
    reference_contact,
    sub_step_count,
)
from legbench.contact import ReferenceContact, law_step_warnings
from legbench.exceptions import LegbenchError, SimulationDiverged, Unreachable
from legbench.model import FOOT_FRAME, JOINT_NAMES, LINK_NAMES, Inertial, combine, load_params

#: Joint-limit constraint: time constant 2 ms, critically damped [s, 1].
LIMIT_SOLREF = (0.002, 1.0)
#: Joint-limit impedance: nearly rigid from the first millimetre-radian on.
LIMIT_SOLIMP = (0.99, 0.999, 0.001, 0.5, 2.0)
#: Contact impedance pinned at d = 1e-4 for every penetration, so the force is
#: the spring-damper of solref and does not vary with depth.
CONTACT_SOLIMP = (1e-4, 1e-4, 0.001, 0.5, 2.0)

_CONES = {"elliptic": mujoco.mjtCone.mjCONE_ELLIPTIC, "pyramidal": mujoco.mjtCone.mjCONE_PYRAMIDAL}
_SOLVERS = {"newton": mujoco.mjtSolver.mjSOL_NEWTON, "cg": mujoco.mjtSolver.mjSOL_CG, "pgs": mujoco.mjtSolver.mjSOL_PGS}
#: Contact impedance choices: pinned at 1e-4 (force = the solref spring-damper in N), or MuJoCo's default.
_SOLIMPS = {"pinned": CONTACT_SOLIMP, "default": (0.9, 0.95, 0.001, 0.5, 2.0)}

_INTEGRATORS = {
    "euler": mujoco.mjtIntegrator.mjINT_EULER,
    "rk4": mujoco.mjtIntegrator.mjINT_RK4,
    "implicitfast": mujoco.mjtIntegrator.mjINT_IMPLICITFAST,
    "implicit": mujoco.mjtIntegrator.mjINT_IMPLICIT,
}

#: What ``mj_step`` calls after ``mj_forward`` and ``mj_checkAcc``, per integrator.
_INTEGRATE = {
    "euler": mujoco.mj_Euler,
    "rk4": lambda m, d: mujoco.mj_RungeKutta(m, d, 4),
    "implicitfast": mujoco.mj_implicit,
    "implicit": mujoco.mj_implicit,
}
_STAGE_VEL = mujoco.mjtStage.mjSTAGE_VEL


#: MuJoCo's own URDF import options, which this backend adds (the generated URDF carries no engine's element):
#: visual geoms kept, no inertia balancing, and ``fusestatic="false"`` so that the foot,
#: welded to link 3 by a fixed joint, stays a body of its own (its contact pair and the site E need it).
#: MuJoCo's URDF default is ``fusestatic="true"`` (the foot fused into link 3), so the ``engine-defaults``
#: force depends on this option: its raw solref (-Kp, -Kd) is per unit of the contact body's
#: ``body_invweight0`` (foot 2.2101 1/kg, fused link 3 0.8431), effort task Fn 59.0 N here, 75.0 N fused.
COMPILER = '<mujoco><compiler discardvisual="false" fusestatic="false" balanceinertia="false"/></mujoco>'


def urdf_with_compiler(urdf: Path) -> str:
    """The URDF's text with :data:`COMPILER` as the first element of ``<robot>`` (kept if it has a ``<mujoco>``)."""
    text = urdf.read_text()
    if "<mujoco>" in text:
        return text
    start = text.index("<robot")
    end = text.index(">", start) + 1
    return text[:end] + COMPILER + text[end:]


def compiler_options(text: str) -> dict[str, str]:
    """The attributes of the ``<mujoco><compiler .../></mujoco>`` element of a URDF's text (empty if none): the
    MuJoCo compiler options that text is loaded with (:func:`urdf_with_compiler`), for :meth:`MujocoBackend.info`."""
    import xml.etree.ElementTree as ET

    element = ET.fromstring(text).find("mujoco/compiler")
    return dict(element.attrib) if element is not None else {}


#: The normal loads [N] at which ``contact.Kp_Kd_note`` of the raw solref gives MuJoCo's stiffness at rest.
RAW_NOTE_LOADS = (20.0, 40.0, 60.0)


def disabled_flags(flags: int) -> list[str]:
    """The names of the ``mjtDisableBit`` bits set in ``opt.disableflags`` (e.g. ``["mjDSBL_AUTORESET"]``)."""
    bits = mujoco.mjtDisableBit.__members__.items()
    return [name for name, bit in bits if name.startswith("mjDSBL_") and int(flags) & int(bit)]


def _impedance(solimp: Sequence[float], y: float) -> float:
    """MuJoCo's impedance d(y) [1] at penetration ``y`` [m] for ``solimp`` (dmin, dmax, width, midpoint, power)
    (MuJoCo's modelling documentation, "Solver parameters"); the Python binding does not expose it."""
    dmin, dmax, width, mid, power = (float(v) for v in solimp)
    x = min(max(y / width, 0.0), 1.0)
    s = x**power / mid ** (power - 1) if x <= mid else 1.0 - (1.0 - x) ** power / (1.0 - mid) ** (power - 1)
    return dmin + s * (dmax - dmin)


def usual_rest_depth(contact: Mapping[str, Any], fn: float) -> tuple[float, float]:
    """MuJoCo's steady contact under the normal force ``fn`` [N] for a contact as :meth:`MujocoBackend.info`
    records it (raw solref (-Kp, -Kd), solimp, A = the foot body's ``body_invweight0``, friction, cone): the
    penetration y [m] at which the soft constraint's force balances ``fn``, and its stiffness Fn / y [N/m].

    At rest (no motion, a = J qacc = 0) each row's force is its reference acceleration over its regulariser,
    f = aref / R, with aref = K d(y) y, K = Kp / dmax^2 (raw solref), and R = (1 - d) / d A (A the contact's
    ``mj_diagApprox``, the foot body's ``body_invweight0``): Fn = Kp d^2 y / (dmax^2 (1 - d) A) on an elliptic
    cone (impratio divides only its friction rows' R). A pyramidal cone's four rows n +- mu t_i each take
    R_py = 2 mu_r^2 R_0 with R_0 = (1 - d) / d (1 + mu^2) A (their diagApprox) and mu_r^2 = mu^2 / impratio
    (src/engine/engine_core_constraint.c, mj_diagApprox and mj_makeImpedance: R[1] = R[0] / impratio,
    mu_r = mu sqrt(R[1] / R[0])), and their normal forces add up: x 4 R / R_py = 2 impratio / (mu^2 (1 + mu^2))
    (2.74 at mu 0.7 and impratio 1; 27.4 at impratio 10). Met by MuJoCo's own efc_aref / efc_R at 0.42 mm to
    4e-16 (tests/test_backend_mujoco.py holds it to 1e-9), and by the engine-defaults calibration's rest at 40 N,
    Fn / y 126,389.75 N/m measured against 126,389.75 (1.6e-9; docs/contact_mapping.md)."""
    from scipy.optimize import brentq  # imported where it is used: the trajectory controller's scipy brings it

    dmax = float(contact["solimp"][1])
    kp, a_inv, mu = -float(contact["solref"][0]), float(contact["A"]), float(contact["friction"][0])
    impratio = float(contact.get("impratio", 1.0))
    share = 2.0 * impratio / (mu**2 * (1.0 + mu**2)) if contact.get("cone") == "mjCONE_PYRAMIDAL" else 1.0

    def stiffness(y: float) -> float:
        d = _impedance(contact["solimp"], y)
        return kp * d**2 / (dmax**2 * (1.0 - d) * a_inv) * share

    y = float(brentq(lambda y: stiffness(y) * y - fn, 1e-12, 1.0, xtol=1e-18, rtol=4 * np.finfo(float).eps))
    return y, stiffness(y)


def usual_creep(contact: Mapping[str, Any], fn: float, ft: float) -> float:
    """MuJoCo's steady creep [m/s] of a foot held by the raw solref (-Kp, -Kd) on a pyramidal cone under the
    normal force ``fn`` and a tangential force ``ft`` below the cone [N], for a contact as
    :meth:`MujocoBackend.info` records it.

    Each of the pyramid's four rows n +- mu t_i is a soft constraint at the rest depth y (:func:`usual_rest_depth`)
    whose steady force is its reference acceleration over its regulariser, f = (-B v_row - K d(y) (-y)) / R, with
    K = Kp / dmax^2 and B = Kd / dmax (raw solref). Along the slip the rows move at v_row = +- mu v: their forces
    sum to Fn = 4 K d y / R and differ by 2 B mu v / R, and Ft = mu (f+ - f-); so v = 2 (Ft / Fn) Kp d y /
    (Kd dmax mu^2), whatever R: impratio enters only through y (checked against the solver's own efc_aref and
    efc_R at the end of the calibration: 40.99 against 41.00 mm/s, 0.03 %; at impratio 1 and 10 against a slipping
    foot's efc quantities: tests/test_backend_mujoco.py)."""
    y, _ = usual_rest_depth(contact, fn)
    dmax, mu = float(contact["solimp"][1]), float(contact["friction"][0])
    kp, kd = -float(contact["solref"][0]), -float(contact["solref"][1])
    return 2.0 * (ft / fn) * kp * _impedance(contact["solimp"], y) * y / (kd * dmax * mu**2)


class MujocoBackend(Backend):
    """MuJoCo simulating the leg from the generated URDF."""

    name: ClassVar[str] = "mujoco"
    defaults: ClassVar[Mapping[str, Any]] = {
        "dt": 5.0e-5,  # sub-step [s]: the Pinocchio default (docs/pinocchio.md), so defaults are same-step
        "integrator": "euler",  # semi-implicit Euler, like PyBullet and the Pinocchio backend
        "impratio": 1.0,  # opt.impratio: friction-to-normal impedance ratio (MuJoCo default 1)
        "noslip": True,  # the unregularised friction post-pass on (MuJoCo default off: noslip_iterations 0)
        "noslip_iterations": 10,  # opt.noslip_iterations when noslip is on
        "cone": "elliptic",  # opt.cone (MuJoCo default pyramidal)
        "solver": "newton",  # opt.solver (MuJoCo default Newton)
        "iterations": 100,  # opt.iterations (MuJoCo default 100)
        "contact_solref": "scaled",  # scaled: (-Kp A, -Kd A) [N]; raw: (-Kp, -Kd), the usual stiffness/damping form
        "friction_solref": "deadbeat",  # deadbeat: friction rows stop the slip in one sub-step; contact: = solref
        "reference_friction": "implicit",  # reference mode: the law's friction slope implicit (as Pinocchio's)
        "force_readout": "end",  # end: at the end state; last: the last sub-step's; mean: impulse / period
        "contact_solimp": "pinned",  # pinned: d = 1e-4 at every depth; default: MuJoCo's (0.9, 0.95, 0.001, 0.5, 2)
        "friction_coefficient": "mu_s",  # the cone's one coefficient: mu_s (holds to mu_s Fn) or mu_k (slides at it)
    }
    #: One friction coefficient (mu_s on the cone unless ``friction_coefficient`` says mu_k): it slides with it.
    sliding_coefficient: ClassVar[str] = "mu_s"

    @property
    def bench_targets(self) -> Mapping[str, float]:
        """The full run within 1.15x the engine's own stepping in native contact; in reference contact the floor
        steps without the law legbench applies every sub-step, so it is no floor of that run: no target."""
        return {} if self.reference else {"full/floor": 1.15}

    choices: ClassVar[Mapping[str, tuple[str, ...]]] = {
        "integrator": tuple(_INTEGRATORS),
        "cone": tuple(_CONES),
        "solver": tuple(_SOLVERS),
        "contact_solref": ("scaled", "raw"),
        "friction_solref": ("deadbeat", "contact"),
        "contact_solimp": tuple(_SOLIMPS),
        "force_readout": ("end", "last", "mean"),
        "reference_friction": ("implicit", "explicit"),
        "friction_coefficient": FRICTION_COEFFICIENTS,
    }
    #: ``engine-defaults``: MuJoCo's documented option defaults (2 ms is replaced by the control
    #: period: a step must divide it), Kp and Kd as the usual direct solref (-Kp, -Kd) with the
    #: default solimp, mu as the pair friction (``pair_friction`` of the explicit pair, like all
    #: its parameters). Not MuJoCo's defaults: ``fusestatic="false"`` (:data:`COMPILER`), the
    #: stiff joint limits (:data:`LIMIT_SOLREF`, :data:`LIMIT_SOLIMP`) and ``mjDSBL_AUTORESET`` in
    #: ``opt.disableflags`` (MuJoCo's default 0; ``info()['disableflags']``).
    profiles: ClassVar[Mapping[str, Mapping[str, Any]]] = {
        "matched": {},
        "engine-defaults": {
            "dt": 1.0e-3,
            "integrator": "euler",
            "impratio": 1.0,
            "noslip": False,
            "cone": "pyramidal",
            "solver": "newton",
            "iterations": 100,
            "contact_solref": "raw",
            "friction_solref": "contact",
            "contact_solimp": "default",
        },
    }

    @classmethod
    def known_deviation(cls, case: str, quantity: str, info: Mapping[str, Any], measured: float = math.nan,
                        expected: float = math.nan, tolerance: float = math.nan) -> str | None:  # fmt: skip
        """The usual normal mapping (raw solref, default impedance): the rest is MuJoCo's own steady state, not Fn/Kp
        (said where the row's measured rest meets :func:`usual_rest_depth`); at a 1 ms step the sliding foot hops,
        and the sliding case's central differences at the landings lag the closed form at their sample by half a step
        (:meth:`_known_step_lag`, held to the row; docs/contact_mapping.md)."""
        usual = (info.get("contact_mode"), info.get("contact_solref"), info.get("contact_solimp")) == (
            "native", "raw", "default")  # fmt: skip
        contact = info.get("contact")
        if case == "rest_penetration" and usual and isinstance(contact, Mapping) and math.isfinite(expected):
            y, k = usual_rest_depth(contact, expected * float(contact["Kp"]))
            return held(f"known: the usual solref (-Kp, -Kd) is not Kp N/m: it goes through the impedance d(y) "
                        f"{tuple(contact['solimp'])} and the constraint's mass, and MuJoCo's steady state is Fn / y = "
                        f"Kp d^2 / (dmax^2 (1 - d) A) (x 2 impratio / (mu^2 (1 + mu^2)) on the pyramidal cone; a "
                        f"secant, rising with the load through d(y)): {k:.4g} N/m, y = {y:.4g} m for this Fn",
                        measured, y, tolerance, " (docs/contact_mapping.md)")  # fmt: skip
        load = info.get("load")
        if (case == "creep" and usual and isinstance(contact, Mapping) and contact.get("cone") == "mjCONE_PYRAMIDAL"
                and isinstance(load, Mapping) and float(load["Fn"]) > 0.0):  # fmt: skip
            v = usual_creep(contact, float(load["Fn"]), float(load["Ft"]))
            return held(f"known: the pyramid's rows n +- mu t_i are soft constraints at the rest depth (the usual "
                        f"solref through the impedance): their steady forces, reference acceleration over R, differ "
                        f"by the slip's damping term alone, so Ft creeps at 2 (Ft / Fn) Kp d y / (Kd dmax mu^2) = "
                        f"{1e3 * v:.4g} mm/s", measured, v, tolerance, " (docs/contact_mapping.md)")  # fmt: skip
        if case == "sliding" and quantity.startswith("slip acceleration") and usual and info.get("dt", 0) >= 1e-3:
            return cls._known_step_lag(info.get("drag"), measured, tolerance)
        return None

    @classmethod
    def _known_step_lag(cls, drag: object, measured: float, tolerance: float) -> str | None:
        """The sliding case's slip-acceleration miss at a 1 ms step with the usual normal mapping, held to the row:
        the force read at a sample (the end state's ``mj_forward``, ``force_readout: end``) is the one the next step
        applies (its ``mj_forwardSkip`` from the acceleration stage keeps that solve), so the central
        difference at sample k spans the steps under the forces read at k - 1 and k; where the acceleration varies
        fast over a step (the foot landing after each hop of the soft contact) the mean of the closed form at the two
        (the run's ``drag.over_steps``, as the sliding case computed it) is the row's closed form, not the one at k.
        Said where the row's ``measured`` meets it within the row's ``tolerance``, with the window's samples out of
        contact (``drag.out_of_contact``) counted; None otherwise."""
        if not isinstance(drag, Mapping):
            return None
        steps = float(drag.get("over_steps", math.nan))
        if not math.isfinite(steps):
            return None
        n, out, acc = (int(drag.get(key, 0)) for key in ("window_samples", "out_of_contact", "acceleration_samples"))
        hops = (f"the sliding foot hops (out of contact at {out} of the window's {n} samples) and each landing's "
                "contact force changes the acceleration step by step" if out else
                f"the sliding foot stays in contact (at the window's {n} samples)")  # fmt: skip
        return held(f"known: with the raw solref (-Kp, -Kd), MuJoCo's default impedance and a 1 ms step {hops}; "
                    f"MuJoCo's step applies the force read at its "
                    f"start, so the central difference at k spans the steps under the forces read at k - 1 and k: "
                    f"the closed form's mean over those two steps, at the {acc} samples whose stencil is in "
                    f"contact, is {steps:.4g} m/s^2", measured, steps, tolerance,
                    " (within the row's tolerance of that closed form; docs/contact_mapping.md)")  # fmt: skip

    @classmethod
    def settings_problem(
        cls, settings: Mapping[str, Any], contact_mode: str
    ) -> tuple[str | tuple[str, ...], str] | None:
        """``cone: pyramidal`` with ``friction_solref: deadbeat`` in native contact: MuJoCo applies a pair's
        ``solreffriction`` to an elliptic cone's friction rows only (a pyramid's rows, each mixing the normal and a
        friction direction, take the contact's ``solref``), so the deadbeat reference was silently dropped (the
        run was bit-identical to ``friction_solref: contact``)."""
        if (
            contact_mode == "native"
            and settings.get("cone") == "pyramidal"
            and settings.get("friction_solref") == "deadbeat"
        ):
            return ("cone", "friction_solref"), (
                "cone 'pyramidal' ignores friction_solref 'deadbeat' (MuJoCo applies solreffriction to an elliptic "
                "cone's friction rows only); set friction_solref: contact with it, or keep the elliptic cone"
            )
        return None

    # ----------------------------------------------------------------- load
    def load(self, urdf: Path, physics: Physics, settings: Mapping[str, Any]) -> None:
        """Compile the URDF with ground, foot site, actuators, limits and contact settings.

        Args:
            urdf: the generated leg URDF.
            physics: gravity, contact law and mode, control period, torque limits.
            settings: overrides of :attr:`defaults` (``dt`` [s], ``integrator``).

        Raises:
            LegbenchError: an unknown integrator, or a ``dt`` that does not divide
                the control period.
        """
        cfg = self.settings(settings)
        if cfg["integrator"] not in _INTEGRATORS:
            raise LegbenchError(f"mujoco: unknown integrator '{cfg['integrator']}'; choose one of {list(_INTEGRATORS)}")
        self.refuse_settings(cfg, physics.contact_mode)
        n_sub = sub_step_count(self.name, cfg["dt"], physics.control_dt)
        self.cfg, self.physics, self.n_sub = cfg, physics, n_sub
        self.reference = physics.contact_mode == "reference"

        text = urdf_with_compiler(urdf)
        self.compiler = compiler_options(text)
        spec = mujoco.MjSpec.from_string(text)
        opt = spec.option
        opt.timestep = physics.control_dt / n_sub
        opt.integrator = _INTEGRATORS[cfg["integrator"]]
        opt.gravity = [0.0, 0.0, -physics.gravity]
        opt.cone = _CONES[cfg["cone"]]
        opt.solver = _SOLVERS[cfg["solver"]]
        opt.iterations = int(cfg["iterations"])
        opt.impratio = float(cfg["impratio"])
        opt.noslip_iterations = int(cfg["noslip_iterations"]) if cfg["noslip"] else 0
        # not MuJoCo's default (disableflags 0), in every profile: a bad acceleration raises instead of resetting
        opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_AUTORESET
        if self.reference:
            opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT

        # only the foot sphere collides, and only with the ground: no dynamic collisions at all,
        # one explicit pair per foot geom (its parameters bypass the two-geom mixing rules)
        foot_names = []
        for i, geom in enumerate(spec.geoms):
            geom.contype, geom.conaffinity = 0, 0
            if geom.parent.name == FOOT_FRAME:
                geom.name = geom.name or f"foot_{i}"
                foot_names.append(geom.name)
        spec.worldbody.add_geom(
            name="ground", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0.0, 0.0, 1.0], contype=0, conaffinity=0
        )
        for name in foot_names:
            spec.add_pair(geomname1="ground", geomname2=name, condim=3)
        spec.body(FOOT_FRAME).add_site(name="E", pos=[0.0, 0.0, 0.0])

        for joint, limit in zip(JOINT_NAMES, physics.torque_limit, strict=True):
            jnt = spec.joint(joint)
            jnt.damping = [0.0, 0.0, 0.0]  # (linear, ...) coefficients in MuJoCo 4
            jnt.armature, jnt.frictionloss = 0.0, 0.0
            jnt.solref_limit = list(LIMIT_SOLREF)
            jnt.solimp_limit = list(LIMIT_SOLIMP)
            spec.add_actuator(
                name=joint,
                target=joint,
                trntype=mujoco.mjtTrn.mjTRN_JOINT,
                gear=[1.0, 0, 0, 0, 0, 0],
                ctrllimited=mujoco.mjtLimited.mjLIMITED_TRUE,
                ctrlrange=[-limit, limit],
            )

        self.model = m = spec.compile()
        self.data = mujoco.MjData(m)
        self.foot_body = m.body(FOOT_FRAME).id
        self.foot_geoms = frozenset(int(g) for g in np.flatnonzero(m.geom_bodyid == self.foot_body))

        # native contact on the explicit pairs: N = Kp pen + Kd pen_rate
        c = physics.contact
        self.A = float(m.body_invweight0[self.foot_body, 0])
        scale = self.A if cfg["contact_solref"] == "scaled" else 1.0
        mu = float(getattr(c, cfg["friction_coefficient"]))  # the cone's one coefficient
        if cfg["contact_solref"] == "scaled" and cfg["cone"] == "pyramidal":
            # the pyramid's rows share R = 2 mu_r^2 (1 + mu^2) times the elliptic normal row's regulariser, mu_r^2
            # = mu^2 / impratio the regularised cone's (engine_core_constraint.c: Rpy = 2 mu_r^2 R, R from the
            # edge rows' diagA, (1 + mu^2) A), so the same solref gives 2 / (mu_r^2 (1 + mu^2)) times the stiffness
            # and damping (2.74 at mu 0.7, impratio 1): scaled back, Fn = Kp y + Kd ydot in newtons on either cone
            scale *= 0.5 * mu**2 * (1.0 + mu**2) / float(cfg["impratio"])
        solimp = _SOLIMPS[cfg["contact_solimp"]]
        if cfg["contact_solref"] == "scaled" and cfg["contact_solimp"] == "pinned":
            # at rest the row's force is aref / R with aref = k d y, k = -solref[0] / d^2, and R = A (1 - d) / d
            # (d = dmax, pinned): Kp y / (1 - d) for solref[0] = -Kp A, the damping likewise; (1 - d) makes the rest
            # force Kp y exactly, where it was 1 + 1e-4 times it (k eff 10001 N/m, the rest 6.4e-7 m shallow)
            scale *= 1.0 - solimp[1]
        if cfg["friction_solref"] == "deadbeat":
            # friction rows' reference acceleration aref = -B v_t with B = -solreffriction[1] / dmax:
            # B = 1 / h asks the unregularised noslip pass to stop the slip within one sub-step
            solreffriction = [-1.0, -solimp[1] / m.opt.timestep]
        else:
            solreffriction = [0.0, 0.0]  # MuJoCo's default: the friction rows use solref
        for i in range(m.npair):
            m.pair_solref[i] = [-c.Kp * scale, -c.Kd * scale]
            m.pair_solreffriction[i] = solreffriction
            m.pair_solimp[i] = solimp
            m.pair_friction[i] = [mu, mu, 0.0, 0.0, 0.0]
            m.pair_margin[i] = 0.0

        implicit = self.reference and cfg["reference_friction"] == "implicit"
        self.contact = ReferenceContact.from_leg(c, physics.gravity if implicit else None)
        native = {"end": self._step_native, "last": self._step_native_last, "mean": self._step_native_mean}[
            cfg["force_readout"]
        ]
        self._step = self._step_reference if self.reference else native
        self._f6 = np.zeros(6)
        self._frame: tuple[float, ...] | None = None  # the ground contact's frame, read at the first contact
        self._fw = np.zeros(3)
        self._force = np.zeros(3)
        self._impulse = np.zeros(3)
        self._fn_peak, self._q_peak = 0.0, [0.0, 0.0, 0.0]
        # live views into d, taken once: the hot loop looks nothing up and allocates nothing
        self._ctrl = self.data.ctrl
        self._qpos, self._qvel = self.data.qpos, self.data.qvel
        self._bad_qacc = self.data.warning[int(mujoco.mjtWarning.mjWARN_BADQACC)]
        self._integrate = _INTEGRATE[cfg["integrator"]]
        mujoco.mj_forward(m, self.data)  # every step may reuse the position and velocity stages of d
        self._axes = self._friction_axes() if not self.reference and cfg["cone"] == "pyramidal" else None

    def _friction_axes(self) -> list[list[float]] | None:
        """The ground contact's tangent axes t1, t2 in W, read back from MuJoCo: rows 2 and 3 of ``mjContact.frame``
        (row 1 the normal, from the ground, geom1, into the foot, geom2: +z_W) after an ``mj_forward`` of a scratch
        ``MjData`` with the foot sphere 1 mm into the ground z = 0 (q* moved down by IK). The pyramidal cone's edges
        are n +- mu t_i along them. The plane-sphere collider leaves the tangent unset and ``mj_collideGeoms``
        completes the frame with ``mju_makeFrame`` (src/engine/engine_collision_driver.c:1865,
        src/engine/engine_util_spatial.c:512, mujoco main 2026-08): t1 = W y, t2 = n x t1 = -W x. None where the
        foot cannot be put on the ground (the run's info then declares no axes)."""
        m, p = self.model, load_params()
        q_star = np.asarray(p.q_star, float)
        e = kinematics.fk(q_star)
        try:
            q = kinematics.ik_nearest(np.array([e[0], e[1], p.geometry.R_foot - 1e-3]), q_star)
        except Unreachable:
            return None
        d = mujoco.MjData(m)
        d.qpos[:] = q
        mujoco.mj_forward(m, d)
        for i in range(d.ncon):
            con = d.contact[i]
            if con.geom2 in self.foot_geoms and con.geom1 not in self.foot_geoms:
                return [con.frame[3:6].tolist(), con.frame[6:9].tolist()]
        return None

    # ---------------------------------------------------------------- reset
    def reset(self, q: np.ndarray, qd: np.ndarray) -> None:
        """Set q [rad] and qd [rad/s], clear time, warm start, applied forces and warnings."""
        m, d = self.model, self.data
        mujoco.mj_resetData(m, d)
        d.qpos[:] = q
        d.qvel[:] = qd
        mujoco.mj_forward(m, d)
        self._fn_peak = 0.0
        self._read_force()

    # ----------------------------------------------------------------- step
    def step(self, tau: np.ndarray) -> None:
        """Advance one control period with tau [N m] held (clamped to the torque limits by MuJoCo)."""
        self._ctrl[:] = tau
        self._step()
        if self._bad_qacc.number:
            raise SimulationDiverged(self.name, float(self.data.time), "MuJoCo reported a bad qacc")

    def _step_native(self) -> None:
        """``n_sub`` steps, then the ground force at the end state (``force_readout: end``).

        ``mj_step`` leaves the contact forces of the last sub-step's start state (with ``rk4`` its
        last stage's); the force at the end state needs the constraint solve at that state, so one
        ``mj_forward`` per period is kept (the end-state force aligned with the logged state, like
        the law's). It is not wasted: the next period's first sub-step starts from the same qpos and
        qvel with only ``ctrl`` changed, so it reuses that call's position and velocity stages
        (kinematics, mass matrix, collision, constraint Jacobians) and runs ``mj_forwardSkip`` from
        the acceleration stage, then the integrator: bit-identical to ``mj_step``
        (tests/test_backend_mujoco.py). :meth:`reset` and :meth:`load` end with ``mj_forward``, so d
        always holds those stages of its current state when a period starts.
        """
        m, d = self.model, self.data
        mujoco.mj_checkPos(m, d)
        mujoco.mj_checkVel(m, d)
        mujoco.mj_forwardSkip(m, d, _STAGE_VEL, 0)
        mujoco.mj_checkAcc(m, d)
        self._integrate(m, d)
        if self.n_sub > 1:
            mujoco.mj_step(m, d, self.n_sub - 1)
        mujoco.mj_forward(m, d)
        self._contact_force()

    def _step_native_plain(self) -> None:
        """``n_sub`` x ``mj_step``, then ``mj_forward`` at the end state: what :meth:`_step_native`
        does without reusing the stages (the reference its test compares against)."""
        m, d = self.model, self.data
        mujoco.mj_step(m, d, self.n_sub)
        mujoco.mj_forward(m, d)
        self._contact_force()

    def _step_native_last(self) -> None:
        """``n_sub`` steps; the ground force is the one the last sub-step applied (``force_readout: last``).

        After ``mj_step`` the contacts and ``efc_force`` are those the step used (computed at its
        start state, after the noslip pass when there is one): Bullet's convention, one sub-step
        behind the state. With ``rk4`` they are the step's last (4th) stage's, not its start state's.
        """
        mujoco.mj_step(self.model, self.data, self.n_sub)
        self._contact_force()

    def _step_native_mean(self) -> None:
        """``n_sub`` calls of ``mj_step``, averaging the contact force each sub-step applied
        (``force_readout: mean``): the control period's contact impulse over its length
        (with ``rk4``: each sub-step's last-stage force, what ``mj_step`` leaves in ``efc_force``).

        Use it with settings under which the friction force alternates from sub-step to
        sub-step (a stiff friction row: impratio >> 1, or noslip with the contact's own
        solref): one sub-step's force is then not the period's. Its sample is the mean over
        the period ending at the sample, half a period behind the state.
        """
        m, d, acc, fw = self.model, self.data, self._impulse, self._force
        acc[:] = 0.0
        for _ in range(self.n_sub):
            mujoco.mj_step(m, d)
            if d.ncon:
                self._contact_force()
                acc += fw
        fw[:] = acc
        fw /= self.n_sub

    def _step_reference(self) -> None:
        """Reference mode: ``qfrc_applied`` = the law's J_poc^T F at each sub-step's start state.

        ``reference_friction: implicit`` (default) adds the linearly implicit friction correction
        -K dqd (:meth:`ReferenceContact.implicit_generalized`, with the commanded torque as the
        other applied torque), so the law's stiff friction slope does not chatter at the sub-step;
        ``explicit`` applies the law as it is (stable only below m v_th / (mu_s Fn)).
        """
        m, d = self.model, self.data
        q, qd, applied = d.qpos, d.qvel, d.qfrc_applied
        if self.cfg["reference_friction"] == "implicit":
            law_i, h, u = self.contact.implicit_generalized, float(m.opt.timestep), d.ctrl
            for _ in range(self.n_sub):
                applied[:] = law_i(q[0], q[1], q[2], qd[0], qd[1], qd[2], u[0], u[1], u[2], h)
                mujoco.mj_step(m, d)
        else:
            law = self.contact.generalized
            for _ in range(self.n_sub):
                applied[:] = law(q[0], q[1], q[2], qd[0], qd[1], qd[2])
                mujoco.mj_step(m, d)
        self._read_force()

    def _read_force(self) -> None:
        """Reference mode: the law at the current state; native: the contact force MuJoCo holds now."""
        d = self.data
        if self.reference:
            q, qd = d.qpos, d.qvel
            self.contact.generalized(q[0], q[1], q[2], qd[0], qd[1], qd[2])
            self._force[:] = self.contact.force
            if self._force[2] > self._fn_peak:
                self._fn_peak, self._q_peak = float(self._force[2]), q.tolist()
            return
        self._contact_force()

    def _contact_force(self) -> None:
        """Force of the ground on the foot in W [N] from ``efc_force`` of the current contacts, into ``self._force``.

        The only contacts are the explicit pairs (ground as geom1, a foot geom as geom2), so each
        contact's force in its frame is the one the ground exerts on the foot. The frame of a
        contact with the static plane z_W = 0 is the same at every contact (normal +z_W, tangents
        from it), so it is read once, at the first contact, and kept as floats: per contact
        then one ``mj_contactForce`` and F_W = frame^T f, in ``mju_mulMatTVec3``'s order of
        operations (:meth:`_contact_force_general` reads everything each time; the test compares).
        """
        d, force = self.data, self._force
        ncon = d.ncon
        if not ncon:
            force[0] = force[1] = force[2] = 0.0
            return
        frame = self._frame
        if frame is None:
            frame = self._frame = tuple(d.contact.frame[0].tolist())
        f6, contact_force, m = self._f6, mujoco.mj_contactForce, self.model
        a0, a1, a2, b0, b1, b2, c0, c1, c2 = frame
        fx = fy = fz = 0.0
        for i in range(ncon):
            contact_force(m, d, i, f6)
            f0, f1, f2, _, _, _ = f6.tolist()
            fx += a0 * f0 + b0 * f1 + c0 * f2
            fy += a1 * f0 + b1 * f1 + c1 * f2
            fz += a2 * f0 + b2 * f1 + c2 * f2
        force[0], force[1], force[2] = fx, fy, fz

    def _contact_force_general(self) -> None:
        """:meth:`_contact_force` reading each contact's frame and geoms from ``d`` every time (the reference)."""
        d, force = self.data, self._force
        force[:] = 0.0
        for i in range(d.ncon):
            con = d.contact[i]
            # contact frame rows: normal (from geom1 to geom2), then the two tangents; the
            # force in that frame is the one geom1 exerts on geom2
            mujoco.mj_contactForce(self.model, d, i, self._f6)
            mujoco.mju_mulMatTVec3(self._fw, con.frame, self._f6[:3])
            if con.geom2 in self.foot_geoms:
                force += self._fw
            elif con.geom1 in self.foot_geoms:
                force -= self._fw

    # ----------------------------------------------------------------- read
    def state(self) -> tuple[np.ndarray, np.ndarray]:
        """Joint positions q [rad] (hinges: qpos is the angle, unwrapped) and velocities qd [rad/s]."""
        return self.data.qpos.copy(), self.data.qvel.copy()

    def ground_force(self) -> np.ndarray:
        """Force of the ground on the foot in W [N], summed over the foot's contacts: native, the force the
        last sub-step applied (``force_readout: last``) or the period's mean (``mean``); reference, the law
        at the current state."""
        return self._force.copy()

    def read(self) -> tuple[float, ...]:
        """:meth:`state` and :meth:`ground_force` as nine floats, without the copies."""
        return (*self._qpos.tolist(), *self._qvel.tolist(), *self._force.tolist())

    def info(self) -> dict[str, Any]:
        """Engine, version, sub-stepping, every contact and limit setting actually used and ``opt.disableflags`` by
        name; with the raw solref, ``contact.Kp_Kd_note`` (:meth:`_raw_solref_note`)."""
        m, c = self.model, self.physics.contact
        unused = self._unused_settings()
        out = {
            "engine": "mujoco",
            "version": mujoco.__version__,
            **{k: self.cfg[k] for k in self.defaults if k not in unused},
            # MuJoCo's URDF compiler options as loaded (COMPILER): fusestatic="false" is not MuJoCo's URDF default
            # ("true"), and the engine-defaults profile's raw solref depends on it (docs/contact_mapping.md)
            "compiler": {**self.compiler, "urdf_default_fusestatic": "true"},
            # the pyramidal cone's edges are n +- mu t_i (engine_core_constraint.c), so |F_t1| + |F_t2| <= mu Fn, with
            # t_1, t_2 = W y, -W x on the ground: dragged along W y (engine-defaults, no noslip) it slides on the
            # vertex, F_t = (0, -0.700 Fn), 8-10 deg off -slip, as maximal dissipation on the diamond has it
            # (sliding_case.diamond_friction; within about 15 deg of an axis: sliding_case.DIAMOND_AXIS_DEG);
            # with noslip (matched) |F_x| + |F_y| = 0.700 Fn at the end read,
            # |F_t| = 0.608 Fn, alternating at the edge (mean read 0.599 Fn): not sliding at the bound
            **({} if self.reference else {"friction_cone": "cone" if self.cfg["cone"] == "elliptic" else "diamond"}),
            # the diamond's axes t1, t2 (W y, -W x), read back from a contact on the ground (_friction_axes)
            **({"friction_axes": self._axes} if self._axes is not None else {}),
            "sub_steps": self.n_sub,
            "timestep": float(m.opt.timestep),
            "gravity": self.physics.gravity,
            "contact_mode": self.physics.contact_mode,
            "contact": reference_contact(c, "J_poc^T F via qfrc_applied per sub-step", self.cfg["reference_friction"])
            if self.reference
            else {
                "method": "explicit foot-ground pair, direct solref",
                "enabled": True,
                "poc": "true",
                # MuJoCo places a contact halfway between the two surfaces (mjContact.pos): its force acts, and its
                # slip is taken, y/2 above the sphere's lowest point
                "lift": 0.5,
                "solref": m.pair_solref[0].tolist() if m.npair else None,
                "solreffriction": m.pair_solreffriction[0].tolist() if m.npair else None,
                "solimp": m.pair_solimp[0].tolist() if m.npair else None,
                "A": self.A,
                "Kp": c.Kp,
                "Kd": c.Kd,
                "friction": m.pair_friction[0].tolist() if m.npair else None,
                "condim": int(m.pair_dim[0]) if m.npair else None,
                "cone": mujoco.mjtCone(m.opt.cone).name,
                "impratio": float(m.opt.impratio),
                "noslip_iterations": int(m.opt.noslip_iterations),
                "force_readout": self.cfg["force_readout"],
            },
            # opt.disableflags by name (MuJoCo's default: none): mjDSBL_AUTORESET always, mjDSBL_CONTACT in reference
            "disableflags": disabled_flags(m.opt.disableflags),
            "joint_limits": {"solref": list(LIMIT_SOLREF), "solimp": list(LIMIT_SOLIMP)},
            "solver": {
                "type": mujoco.mjtSolver(m.opt.solver).name,
                "iterations": int(m.opt.iterations),
                "tolerance": float(m.opt.tolerance),
            },
        }
        if not self.reference and self.cfg["contact_solref"] == "raw":
            out["contact"]["Kp_Kd_note"] = self._raw_solref_note(out["contact"])
        return out

    def _raw_solref_note(self, contact: Mapping[str, Any]) -> str:
        """``contact.Kp_Kd_note`` of :meth:`info` for ``contact_solref: raw``: Kp and Kd given to solref as
        (-Kp, -Kd) in MuJoCo's units, and the stiffness at rest Fn / y [N/m] that this model has for them
        (:func:`usual_rest_depth` on info's ``contact``, the loaded pair: impedance, A, cone, friction, impratio)
        at normal loads of 20, 40 and 60 N (the calibration's two rests, about the effort task's 59 N)."""
        k = {fn: usual_rest_depth(contact, fn)[1] for fn in RAW_NOTE_LOADS}
        at = ", ".join(f"{k[fn]:.4g} N/m at {fn:g} N" for fn in RAW_NOTE_LOADS)
        return (f"Kp, Kd are the spec's numbers given to solref as (-Kp, -Kd) in MuJoCo's units (solref[0] 1/s^2, "
                f"solref[1] 1/s, through the impedance d(y) and the regulariser (1 - d) / d A, A = body_invweight0 "
                f"{self.A:.4g} 1/kg), not its stiffness [N/m] or damping [N s/m]: MuJoCo's stiffness at rest Fn / y "
                f"is {at} (a secant, rising with the load; docs/contact_mapping.md)")  # fmt: skip

    def _unused_settings(self) -> set[str]:
        """Settings this load does not read, left out of :meth:`info` so the report's settings table lists only
        what acted (as the Drake backend does): ``noslip_iterations`` without ``noslip`` (the engine runs 0),
        ``reference_friction`` in native contact, and in reference contact (engine contact off) the native
        contact's own settings."""
        unused = set() if self.cfg["noslip"] else {"noslip_iterations"}
        if self.reference:
            unused |= {"impratio", "noslip", "noslip_iterations", "cone", "contact_solref", "friction_solref",
                       "contact_solimp", "force_readout", "friction_coefficient"}  # fmt: skip
        else:
            unused.add("reference_friction")
        return unused

    def warnings(self) -> list[str]:
        """Reference mode: the explicit law's step bound; native: deadbeat friction without its noslip pass."""
        if self.reference:
            if self.cfg["reference_friction"] == "implicit":
                return []
            return law_step_warnings(self.name, float(self.model.opt.timestep), self._fn_peak, self._q_peak,
                                     self.physics.contact)  # fmt: skip
        out = []
        noslip = self.model.opt.noslip_iterations > 0
        if self.cfg["friction_solref"] == "deadbeat" and not noslip:
            out.append(
                "mujoco: friction_solref 'deadbeat' without noslip iterations leaves the friction rows almost "
                "force-free in the regularised solver (the foot slides); set noslip: true"
            )
        stiff = self.model.opt.impratio > 1.0 or (noslip and self.cfg["friction_solref"] == "contact")
        if stiff and self.cfg["force_readout"] != "mean":
            out.append(
                f"mujoco: with impratio {self.model.opt.impratio:g}, noslip {noslip} and friction_solref "
                f"'{self.cfg['friction_solref']}' the friction force can alternate between sub-steps, so the "
                "force of one sub-step is not the control period's; set force_readout: mean"
            )
        return out

    # ------------------------------------------------------- declared abilities
    def integrator_family(self) -> str:
        """``euler`` for Euler and implicitfast (no joint damping: both semi-implicit Euler), else the integrator."""
        return {"euler": "euler", "implicitfast": "euler", "implicit": "implicit", "rk4": "rk4"}[self.cfg["integrator"]]

    def sub_steps(self) -> int:
        return self.n_sub

    def kernels(self, q: np.ndarray, qd: np.ndarray, tau: np.ndarray) -> dict[str, Any]:
        """The engine-only floor: ``mj_step(m, d, n_sub)`` per control period over the given torques.

        ``mj_step_tick`` (one call = one control period): from the first row's state, ``ctrl`` set
        to each row's tau [N m] and ``mj_step(m, d, n_sub)``, nothing read back (no ground force, no
        end-state ``mj_forward``). Rows are a run's consecutive periods, so the steps retrace the
        run (in and out of contact as it was): in native contact its ``end_state()`` is the run's last state,
        which the bench checks bit for bit (the run's end-state ``mj_forward`` reused by its next step is
        plain ``mj_step``'s arithmetic). In reference mode the engine's contact is off and the law is not
        applied, so this floor is MuJoCo's stepping alone (no end state to check, no target).
        """
        m, d, n, ctrl = self.model, self.data, self.n_sub, self._ctrl
        q0, qd0 = np.array(q[0], float), np.array(qd[0], float)
        rows = [np.array(t, float) for t in np.asarray(tau)]
        step = mujoco.mj_step

        def mj_step_tick() -> None:
            mujoco.mj_resetData(m, d)
            d.qpos[:] = q0
            d.qvel[:] = qd0
            for t in rows:
                ctrl[:] = t
                step(m, d, n)

        if not self.reference:
            mj_step_tick.end_state = self.state  # type: ignore[attr-defined]  # d's qpos, qvel after the pass
        return {"mj_step_tick": mj_step_tick}

    def limits(self) -> Limits:
        """``jnt_range`` where ``jnt_limited``, ``actuator_ctrlrange`` where ``ctrllimited``, ``opt.gravity``."""
        m = self.model
        lower, upper, effort = [], [], []
        for name in JOINT_NAMES:
            j = m.joint(name).id
            limited = bool(m.jnt_limited[j])
            lower.append(float(m.jnt_range[j, 0]) if limited else -math.inf)
            upper.append(float(m.jnt_range[j, 1]) if limited else math.inf)
            a = m.actuator(name).id
            effort.append(float(m.actuator_ctrlrange[a, 1]) if m.actuator_ctrllimited[a] else math.inf)
        return Limits(
            gravity=-float(m.opt.gravity[2]), lower=tuple(lower), upper=tuple(upper),  # type: ignore[arg-type]
            effort=tuple(effort), timestep=float(m.opt.timestep),  # type: ignore[arg-type]
            enforcement=f"soft limit constraint, solref {list(LIMIT_SOLREF)}, solimp {list(LIMIT_SOLIMP)}",
        )  # fmt: skip

    def mass_properties(self) -> dict[str, dict[str, Any]]:
        """Per moving body: mass [kg], COM [m] and inertia about the COM [kg m^2] in the link frame.

        Read back from the compiled model (principal inertia ``body_inertia``
        rotated by ``body_iquat``, COM ``body_ipos``); link 3 includes the foot body.
        """
        m = self.model
        out = {}
        for name in LINK_NAMES:
            b = m.body(name).id
            inr = self._inertial(b)
            if name == LINK_NAMES[-1]:
                foot = self._inertial(self.foot_body)
                R = _quat_mat(m.body_quat[self.foot_body])
                p = m.body_pos[self.foot_body]
                moved = Inertial(foot.mass, tuple(R @ foot.com + p), tuple(map(tuple, R @ foot.I @ R.T)))  # type: ignore[arg-type]
                inr = combine([inr, moved])
            out[name] = {"mass": inr.mass, "com": list(inr.com), "inertia": inr.I.tolist()}
        return out

    def _inertial(self, body: int) -> Inertial:
        m = self.model
        R = _quat_mat(m.body_iquat[body])
        I = R @ np.diag(m.body_inertia[body]) @ R.T
        return Inertial(float(m.body_mass[body]), tuple(m.body_ipos[body].tolist()), tuple(map(tuple, I.tolist())))  # type: ignore[arg-type]


def _quat_mat(quat: np.ndarray) -> np.ndarray:
    """Rotation matrix of a MuJoCo quaternion (w, x, y, z)."""
    R = np.zeros(9)
    mujoco.mju_quat2Mat(R, np.asarray(quat, float))
    return R.reshape(3, 3)


__all__ = ["MujocoBackend"]
