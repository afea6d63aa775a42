"""DART backend: dartpy from the generated URDF, rigid LCP contact with Coulomb friction, or the reference law.

Model: ``models/leg.urdf`` through ``DartLoader`` with a fixed root joint
(``RootJointType.FIXED``), in a ``World`` of its own. The ground is a second
skeleton: a welded 20 m x 20 m x 1 m box whose top face is z_W = 0 (every
collision detector offered handles sphere-box). Only the foot sphere collides:
the link cylinders' collision aspects are removed, self-collision is off.
Joint position limits are enforced (``setLimitEnforcement``) in ``matched``;
DART's URDF loader leaves them off, which ``engine-defaults`` keeps. The same
switch makes DART's joint constraint enforce the velocity limits too, which the
loader takes from the URDF's ``<limit velocity>`` (38.84 and 55.49 rad/s): no
other backend enforces a joint speed, so with the limits enforced each DOF's
velocity limits are set to +-inf (position limits kept).

Native contact is DART's rigid contact: a ``ContactConstraint`` per contact
point solved with the other constraints as a boxed LCP (``lcp_solver``: the
friction solvers dartpy 6.20 constructs, ``nsgs`` (``NsgsFrictionSolver``, the
matched profile's) and ``fbf`` (``FbfFrictionSolver``), each with DART's PGS
fallback kept, bound |F_t| by mu times the current normal impulse, a cone;
``dantzig``, DART's default (engine-defaults), with PGS as its fallback, and
``pgs`` alone bound each friction direction on its own, a pyramid), on
the collision detector ``collision_detector`` (``fcl`` default, ``dart``,
``bullet``, ``ode``). Rigid contact has no settable stiffness or damping: the spec's
Kp and Kd do not apply (the foot sinks only by DART's fixed constraint regularisation,
a relative CFM of 1e-5 and an error reduction of 0.01 capped at 1e-3 m/s, not settable
from dartpy: 5e-10 m under 40 N at 0.05 ms; it reports no Kp y). Friction is
Coulomb's with DART's combination rule mu = min(mu_foot, mu_ground): both shapes get mu_s (or mu_k:
``friction_coefficient``); restitution 0. The foot sticks below mu Fn (no creep), unlike the spec's stick-slip law.

Integration: DART's ``World.step`` is semi-implicit Euler (velocities from the
forward dynamics and the constraint impulses, then positions with the new
velocities), so in free space it is the Pinocchio backend's scheme: at the same
sub-step they agree to round-off.

Reference contact (``contact_mode = "reference"``): no foot collision; before
every sub-step ``J_poc^T F`` of :class:`~legbench.contact.ReferenceContact` at
the sub-step's start state is added to the joint forces.

The contact force is read from the last collision result: DART stores on each
contact the force of its constraint impulse over the step (impulse / dt), in W;
``force_readout: mean`` averages it over the period's sub-steps (the
period's impulse / the period), which keeps an impact resolved inside a period.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from importlib import metadata
from pathlib import Path
from typing import Any, ClassVar

import dartpy as dart
import numpy as np

from legbench import kinematics
from legbench.backends.base import (
    FRICTION_COEFFICIENTS,
    Backend,
    Limits,
    Physics,
    check_finite,
    clamp_torque,
    held,
    reference_contact,
    solver_bound_note,
    sub_step_count,
)
from legbench.contact import ReferenceContact
from legbench.exceptions import LegbenchError
from legbench.model import FOOT_FRAME, JOINT_NAMES, LINK_NAMES, Inertial, combine

_DETECTORS = {
    "fcl": dart.collision.FCLCollisionDetector,
    "dart": dart.collision.DARTCollisionDetector,
    "bullet": dart.collision.BulletCollisionDetector,
    "ode": dart.collision.OdeCollisionDetector,
}
_LCP = ("dantzig", "pgs", "nsgs", "fbf")
#: Boxed LCP solvers dartpy constructs (Dantzig and PGS it does not: PGS is promoted from DART's fallback).
_CONSTRUCTED_LCP = {"nsgs": dart.constraint.NsgsFrictionSolver, "fbf": dart.constraint.FbfFrictionSolver}
#: Ground box: full size [m] in x and y (BoxShape takes the full edge lengths), thickness [m]; its top face is
#: z_W = 0.
GROUND_SIZE = (20.0, 20.0, 1.0)
#: DART's constraint force mixing on a contact's rows (ContactConstraint.cpp: ``#define DART_CFM 1e-5``,
#: ``mConstraintForceMixing``; dartpy binds no ContactConstraint to read it): the LCP solves with A's diagonal
#: times (1 + cfm), the impulse acts through the dynamics without it, so a sticking friction row keeps a velocity
#: -cfm A_ii x_i, which no position correction removes (the error reduction acts on the normal row only).
DART_CFM = 1.0e-5
#: DART's error reduction on a contact's normal row (ContactConstraint.cpp: ``DART_ERP`` 0.01, capped at
#: ``DART_MAX_ERV`` 1e-3 m/s): the bias velocity ERP y / h that pushes a penetration y out over a step h.
DART_ERP, DART_MAX_ERV = 0.01, 1.0e-3


def friction_shape(lcp_solver: str) -> str:
    """The friction limit's shape with the boxed LCP solver ``lcp_solver``: ``cone`` (NSGS, FBF: |F_t| <= mu Fn) or
    ``pyramid`` (Dantzig, PGS: each friction direction on its own)."""
    return "cone" if lcp_solver in _CONSTRUCTED_LCP else "pyramid"


def friction_axes(normal: tuple[float, float, float] = (0.0, 0.0, 1.0)) -> list[list[float]]:
    """The two friction directions t1, t2 in W of DART's contact constraint with ``normal``, by DART's rule
    (``ContactConstraint::getTangentBasisMatrixODE``, dart/constraint/ContactConstraint.cpp, DART 6.13 and later;
    dartpy binds no ContactConstraint to read them from): tangent = n x d1, d1 the first friction direction, which
    no shape here sets (dartpy's DynamicsAspect offers none), so DART's default +z (``DART_DEFAULT_FRICTION_DIR``);
    parallel to n, so tangent = n x X (then n x Y), normalised; T.col(0) = tangent turned 90 deg about n (n x
    tangent), T.col(1) = tangent. For the ground's +z: t1 = -W x, t2 = W y. The foot's contact, read back
    (``getLastCollisionResult``), has the ground as object 1 and the normal -z: t1 = -W x, t2 = -W y, the same two
    lines, and the pyramid |F_ti| <= mu Fn does not see the sign."""
    n = np.asarray(normal, float)
    for d in ((0.0, 0.0, 1.0), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0)):
        tangent = np.cross(n, d)
        if tangent @ tangent >= 1e-12:  # DART_CONTACT_CONSTRAINT_EPSILON_SQUARED
            break
    tangent = tangent / np.linalg.norm(tangent)
    return [np.cross(n, tangent).tolist(), tangent.tolist()]


class DartBackend(Backend):
    """DART (dartpy; rigid boxed-LCP contact) simulating the leg."""

    name: ClassVar[str] = "dart"
    sliding_coefficient: ClassVar[str] = "mu_s"
    #: The friction limit's shape depends on ``lcp_solver`` (:func:`friction_shape`, recorded in :meth:`info`):
    #: ``nsgs`` and ``fbf`` bound |F_t| by mu Fn, a cone (measured: a diagonal drag of 0.85 Fn slides at
    #: |F_t| = 0.700 Fn); Dantzig and PGS bound each of the contact's two friction directions (-W x and W y for the
    #: ground's normal: :func:`friction_axes`, info ``friction_axes``) on its own, a pyramid (the same drag
    #: holds, |F_t| = 0.846 Fn), Dantzig by mu times the normal impulse solved without friction (see
    #: :meth:`known_deviation`). The class declares the matched profile's.
    friction_cone: ClassVar[str] = "cone"
    defaults: ClassVar[Mapping[str, Any]] = {
        "dt": 5.0e-5,  # sub-step [s]: the Pinocchio default, so free space is the same scheme at the same step
        # boxed LCP solver: "nsgs" (NsgsFrictionSolver: Coulomb's cone at mu Fn; DART's default Dantzig bounds the
        # friction by the normal impulse solved without it, 0.83 Fn in the sliding case), "fbf", "dantzig" (with PGS
        # fallback), "pgs"
        "lcp_solver": "nsgs",
        "collision_detector": "fcl",  # one of _DETECTORS
        "enforce_limits": True,  # joint position limits as constraints (DART's URDF loader leaves them off)
        "split_impulse": False,  # DART's split-impulse position correction (off by default)
        # DART's body sleeping (World's DeactivationOptions; on in dartpy 6.20's World(): below 0.01 m/s and
        # 0.05 rad/s for 0.5 s an island sleeps, its contact forces read zero): off, so a resting foot is simulated
        "deactivation": False,
        "reference_friction": "implicit",  # reference mode: the law's friction slope implicit (as Pinocchio's)
        # native force read-out (MuJoCo's names): "last", the last sub-step's impulse / dt (a sample at the
        # period's end, as every backend reports), or "mean", the period's contact impulse / the control period,
        # which keeps an impact that a rigid contact resolves inside a period (docs/backends/dart.md)
        "force_readout": "last",
        "friction_coefficient": "mu_s",  # both shapes' coefficient: mu_s (holds to mu_s Fn) or mu_k (slides at it)
    }
    choices: ClassVar[Mapping[str, tuple[str, ...]]] = {
        "lcp_solver": _LCP,
        "collision_detector": tuple(_DETECTORS),
        "reference_friction": ("implicit", "explicit"),
        "force_readout": ("last", "mean"),
        "friction_coefficient": FRICTION_COEFFICIENTS,
    }
    profiles: ClassVar[Mapping[str, Mapping[str, Any]]] = {
        "matched": {},
        # World() defaults: 1 ms step, Dantzig + PGS fallback, FCL, body sleeping on; URDF limits not enforced
        "engine-defaults": {"dt": 1.0e-3, "lcp_solver": "dantzig", "enforce_limits": False, "deactivation": True},
    }
    install: ClassVar[str] = "pip install 'dartpy>=6.20,<7'"

    @classmethod
    def known_deviation(cls, case: str, quantity: str, info: Mapping[str, Any], measured: float = math.nan,
                        expected: float = math.nan, tolerance: float = math.nan) -> str | None:  # fmt: skip
        """The rigid rest's sink and the creep of DART's constraint force mixing, each held to its closed form; the
        sliding drag that Dantzig's friction bound holds (docs/backends/dart.md): the bound is mu times the normal
        impulse solved without friction, predicted by re-solving each sample so (:meth:`frictionless_normal`), and
        each row is explained where the pyramid's closed form with it meets the row
        (:func:`~legbench.backends.base.solver_bound_note`)."""
        if case == "sliding" and info.get("lcp_solver") == "dantzig":
            return solver_bound_note("DART's Dantzig boxed LCP (DantzigBoxedLcpSolver)", info.get("drag"), quantity,
                                     measured, tolerance, " (docs/backends/dart.md)")  # fmt: skip
        contact, load, h, at_end = info.get("contact"), info.get("load"), info.get("timestep"), info.get("at_end")
        contact = contact if isinstance(contact, Mapping) else {}
        W = at_end.get("delassus") if isinstance(at_end, Mapping) else None
        cfm_set = contact.get("constraint_force_mixing")
        if case == "rest_penetration" and isinstance(load, Mapping) and "Fn" in load:
            sink = cls.rest_sink(info, float(load["Fn"]))
            if sink is None:
                return None
            return held(f"known: rigid: {cls.rest_sink_text(info, float(load['Fn']))}", measured, sink, tolerance,
                        " (docs/backends/dart.md)")  # fmt: skip
        if (case == "creep" and info.get("lcp_solver") in ("dantzig", "nsgs") and isinstance(load, Mapping)
                and "F" in load and isinstance(W, list) and isinstance(h, float)
                and isinstance(cfm_set, float)):  # fmt: skip
            # the exact solvers only: Dantzig, and NSGS, whose local solve is exact for the one contact here; PGS
            # and FBF leave their own residuals (docs/backends/dart.md)
            cfm, A, F = cfm_set, np.array(W), np.asarray(load["F"], float)
            v = cfm * h * np.linalg.norm(sum((t @ A @ t) * (F @ t) * t for t in np.array(friction_axes())))
            return held(f"known: DART mixes a constraint force into its contact rows (cfm {cfm:g}): the LCP solves "
                        f"with A_ii (1 + cfm), the impulse acts without it, so each sticking friction row keeps "
                        f"-cfm A_ii x_i and the foot creeps at cfm h |sum_i A_ii F_i t_i| = {1e3 * v:.4g} mm/s",
                        measured, float(v), tolerance, " (docs/backends/dart.md)")  # fmt: skip
        return None

    @classmethod
    def rest_sink(cls, info: Mapping[str, Any], fn: float) -> float | None:
        """The rigid contact's own closed form of the foot's rest penetration [m] under a normal force ``fn`` [N],
        run as ``info`` says (its :meth:`info`): at rest the normal row's velocity is 0, so the error reduction's
        bias ERP y / h equals the velocity the constraint force mixing leaves, cfm A_nn Fn h, and
        y = cfm A_nn Fn h^2 / ERP (A_nn the Delassus matrix's normal entry at the run's end, ``at_end.delassus``;
        h the engine's step, ``timestep``). None where it does not hold: reference contact (no DART contact), an
        info without those entries, or the bias capped at ``DART_MAX_ERV`` (no closed form of the rest).
        Measured in the verification's rest (Fn = 51.3 N, A_nn = 4.769 1/kg): 6.1173e-10 m at 50 us, 2.4480e-7 m
        at 1 ms, each met to 3e-6 (round-off of the foot's height) and 3e-8. The verification's rest row expects it,
        the calibration explains a rigid rest by it (:meth:`known_deviation`)."""
        contact, h, at_end = info.get("contact"), info.get("timestep"), info.get("at_end")
        W = at_end.get("delassus") if isinstance(at_end, Mapping) else None
        cfm = contact.get("constraint_force_mixing") if isinstance(contact, Mapping) else None
        if not (isinstance(W, list) and isinstance(h, float) and isinstance(cfm, float) and math.isfinite(fn)):
            return None
        sink = cfm * float(W[2][2]) * fn * h * h / DART_ERP
        return None if DART_ERP * sink / h > DART_MAX_ERV else sink  # the bias capped: no closed form of the rest

    @classmethod
    def rest_sink_text(cls, info: Mapping[str, Any], fn: float) -> str:
        """:meth:`rest_sink` in words with its numbers (empty where it gives None), for a row's note."""
        sink = cls.rest_sink(info, fn)
        if sink is None:
            return ""
        W, h = info["at_end"]["delassus"], info["timestep"]
        cfm = info["contact"]["constraint_force_mixing"]
        return (f"sink = cfm A_nn Fn h^2 / ERP (DART's constraint force mixing cfm {cfm:g}, A_nn = "
                f"{float(W[2][2]):.4g} 1/kg, Fn = {fn:.4g} N, h = {h:g} s, error reduction {DART_ERP:g}) = "
                f"{sink:.4g} m")  # fmt: skip

    # ----------------------------------------------------------------- load
    def load(self, urdf: Path, physics: Physics, settings: Mapping[str, Any]) -> None:
        """Build the world: leg skeleton (fixed root), ground box, solver and detector.

        Args:
            urdf: the generated leg URDF.
            physics: gravity, contact law and mode, control period, torque limits.
            settings: overrides of :attr:`defaults`.

        Raises:
            LegbenchError: an unknown LCP solver or collision detector, or a ``dt`` that does not
                divide the control period.
        """
        cfg = self.settings(settings)
        for key, offered in self.choices.items():
            if cfg[key] not in offered:
                raise LegbenchError(f"dart: unknown {key} '{cfg[key]}'; choose one of {list(offered)}")
        n_sub = sub_step_count(self.name, cfg["dt"], physics.control_dt)
        self.cfg, self.physics, self.n_sub = cfg, physics, n_sub
        self.reference = physics.contact_mode == "reference"
        c = physics.contact
        mu = float(getattr(c, cfg["friction_coefficient"]))  # DART takes the smaller of the two shapes'

        loader = dart.utils.DartLoader()
        options = dart.utils.DartLoader.Options()
        options.mDefaultRootJointType = dart.utils.DartLoader.RootJointType.FIXED
        loader.setOptions(options)
        self.skel = skel = loader.parseSkeleton(str(urdf))
        if skel is None:
            raise LegbenchError(f"dart: could not load {urdf}")
        skel.disableSelfCollisionCheck()
        self.joints = [skel.getJoint(n) for n in JOINT_NAMES]
        self.dofs = [j.getIndexInSkeleton(0) for j in self.joints]
        for j in self.joints:
            j.setLimitEnforcement(bool(cfg["enforce_limits"]))
            if cfg["enforce_limits"]:
                # DART's joint constraint enforces velocity limits with the position limits
                # (dart/constraint/JointConstraint.cpp: a bound row where qd leaves [lower, upper]);
                # the URDF's <limit velocity> is a motor rating, enforced by no other backend
                j.setVelocityLowerLimit(0, -np.inf)
                j.setVelocityUpperLimit(0, np.inf)
            j.setDampingCoefficient(0, 0.0)
            j.setCoulombFriction(0, 0.0)
            j.setSpringStiffness(0, 0.0)
        self.foot = skel.getBodyNode(FOOT_FRAME)
        for name in LINK_NAMES:  # only the foot sphere collides
            body = skel.getBodyNode(name)
            for i in range(body.getNumShapeNodes()):
                body.getShapeNode(i).removeCollisionAspect()
        for i in range(self.foot.getNumShapeNodes()):
            sn = self.foot.getShapeNode(i)
            if self.reference:
                sn.removeCollisionAspect()
            elif sn.hasDynamicsAspect():
                sn.getDynamicsAspect().setFrictionCoeff(mu)
                sn.getDynamicsAspect().setRestitutionCoeff(0.0)

        self.ground = ground = dart.dynamics.Skeleton("ground")
        _, box_body = ground.createWeldJointAndBodyNodePair()
        box = dart.dynamics.BoxShape(np.array(GROUND_SIZE))
        sn = box_body.createShapeNode(box)
        sn.createCollisionAspect()
        dyn = sn.createDynamicsAspect()
        dyn.setFrictionCoeff(mu)
        dyn.setRestitutionCoeff(0.0)
        T = np.eye(4)
        T[2, 3] = -GROUND_SIZE[2] / 2.0
        sn.setRelativeTransform(dart.math.Isometry3(T[:3, :3], T[:3, 3]) if hasattr(dart.math, "Isometry3")
                                else T)  # fmt: skip

        self.world = world = dart.simulation.World()
        world.setTimeStep(physics.control_dt / n_sub)
        world.setGravity(np.array([0.0, 0.0, -physics.gravity]))
        sleep = world.getDeactivationOptions()
        sleep.mEnabled = bool(cfg["deactivation"])
        world.setDeactivationOptions(sleep)
        world.addSkeleton(skel)
        world.addSkeleton(ground)
        solver = world.getConstraintSolver()
        self._lcp = None
        if cfg["lcp_solver"] == "pgs":
            # dartpy cannot construct a PGS solver: promote DART's PGS fallback to primary, no fallback
            pgs = solver.getSecondaryBoxedLcpSolver()
            solver.setSecondaryBoxedLcpSolver(None)
            solver.setBoxedLcpSolver(pgs)
        elif cfg["lcp_solver"] in _CONSTRUCTED_LCP:
            # constructed by dartpy; held here as well as by the solver; DART's PGS fallback kept
            self._lcp = _CONSTRUCTED_LCP[cfg["lcp_solver"]]()
            solver.setBoxedLcpSolver(self._lcp)
        solver.setCollisionDetector(_DETECTORS[cfg["collision_detector"]]())
        solver.setSplitImpulseEnabled(bool(cfg["split_impulse"]))

        self._implicit = self.reference and cfg["reference_friction"] == "implicit"
        self.contact = ReferenceContact.from_leg(c, physics.gravity if self._implicit else None)
        self._limit = tuple(float(x) for x in physics.torque_limit)  # [N m]
        self._tau = np.zeros(3)  # the clamped torque [N m], what setForces takes
        self._cmd = np.zeros(3)
        self._force = np.zeros(3)
        self._impulse = np.zeros(3)  # force_readout mean: the sub-steps' forces summed
        self._period_mean = cfg["force_readout"] == "mean" and not self.reference
        self._q = np.zeros(3)
        self._qd = np.zeros(3)
        self.t = 0.0

    # ---------------------------------------------------------------- reset
    def reset(self, q: np.ndarray, qd: np.ndarray) -> None:
        """Set q [rad] and qd [rad/s], clear forces, impulses and the last collision result."""
        skel = self.skel
        self.world.reset()
        skel.resetCommands()
        skel.resetGeneralizedForces()
        skel.clearConstraintImpulses()
        skel.clearExternalForces()
        skel.resetAccelerations()
        skel.setPositions(np.asarray(q, float))
        skel.setVelocities(np.asarray(qd, float))
        self.world.getConstraintSolver().clearLastCollisionResult()
        self.t = 0.0
        self._read()
        if self.reference:
            self._reference_force()
        else:
            self._force[:] = 0.0

    # ----------------------------------------------------------------- step
    def step(self, tau: np.ndarray) -> None:
        """Advance one control period with tau [N m], clamped to the torque limits, held."""
        u1, u2, u3 = clamp_torque(tau, self._limit)
        u = self._tau
        u[0], u[1], u[2] = u1, u2, u3
        skel, world, n = self.skel, self.world, self.n_sub
        if self.reference:
            cmd, h, setf = self._cmd, self.physics.control_dt / n, skel.setForces
            getp, getv, advance = skel.getPositions, skel.getVelocities, world.step
            implicit, law, law_i = self._implicit, self.contact.generalized, self.contact.implicit_generalized
            q, qd = self._q, self._qd
            # the state as floats through the sub-steps, written back once
            q1, q2, q3 = q.tolist()
            qd1, qd2, qd3 = qd.tolist()
            for _ in range(n):
                if implicit:  # the friction slope linearly implicit over the sub-step (docs/pinocchio.md)
                    c1, c2, c3 = law_i(q1, q2, q3, qd1, qd2, qd3, u1, u2, u3, h).tolist()
                else:
                    c1, c2, c3 = law(q1, q2, q3, qd1, qd2, qd3).tolist()
                cmd[0], cmd[1], cmd[2] = u1 + c1, u2 + c2, u3 + c3
                setf(cmd)
                advance()
                q1, q2, q3 = getp().tolist()
                qd1, qd2, qd3 = getv().tolist()
            q[0], q[1], q[2], qd[0], qd[1], qd[2] = q1, q2, q3, qd1, qd2, qd3
            self._reference_force()
        elif self._period_mean:
            total = self._impulse
            total[:] = 0.0
            # World.step() clears the joint forces after the step, World.step(False) keeps them: set once, cleared
            # after the last sub-step as before
            skel.setForces(u)
            for k in range(n):
                world.step(k == n - 1)
                self._native_force()
                total += self._force
            self._read()
            np.divide(total, n, out=self._force)  # sum of (impulse / h) x h / Ts
        else:
            skel.setForces(u)  # held over the sub-steps (World.step(False)), cleared after the last
            for _ in range(n - 1):
                world.step(False)
            world.step()
            self._read()
            self._native_force()
        self.t += self.physics.control_dt
        check_finite(self.name, self.t, self._q, self._qd)

    def _read(self) -> None:
        self._q[:] = self.skel.getPositions()
        self._qd[:] = self.skel.getVelocities()

    def _reference_force(self) -> None:
        q, qd = self._q, self._qd
        self.contact.generalized(q[0], q[1], q[2], qd[0], qd[1], qd[2])
        self._force[:] = self.contact.force

    def _native_force(self) -> None:
        """Sum of the contact forces on the foot over the last sub-step, in W [N] (``force_readout: last``; with
        ``mean`` the step averages these over the period's sub-steps).

        DART stores on each contact the force its constraint applied on the
        first collision object (impulse / dt, along the normal that points from
        the second object to the first); the sign is flipped where the foot is
        the second object.
        """
        force, foot = self._force, FOOT_FRAME
        force[:] = 0.0
        for contact in self.world.getLastCollisionResult().getContacts():
            if contact.collisionObject1.getShapeFrame().getBodyNodePtr().getName() == foot:
                force += contact.force
            else:
                force -= contact.force

    def frictionless_normal(self, q: np.ndarray, qd: np.ndarray, tau: np.ndarray) -> float | None:
        """The Dantzig solver's friction bound: DART's boxed LCP (DantzigBoxedLcpSolver, ODE's lcp.cpp) bounds the
        friction rows by mu times the normal impulse solved before them (the first row's exactly), so the normal
        force of one step
        from (q, qd) under tau with both shapes' friction 0 [N], mu times which was the bound; None for the other
        solvers (NSGS and PGS bound by the current normal impulse) and in reference contact. Resets the engine to
        (q, qd) and steps it once."""
        if self.reference or self.cfg["lcp_solver"] != "dantzig":
            return None
        aspects = [sn.getDynamicsAspect() for sn in self._contact_shapes()]
        kept = [a.getFrictionCoeff() for a in aspects]
        try:
            for a in aspects:
                a.setFrictionCoeff(0.0)
            self.reset(q, qd)
            self.skel.setForces(np.array(clamp_torque(tau, self._limit), float))
            self.world.step()
            self._native_force()
            return float(self._force[2])
        finally:
            for a, mu in zip(aspects, kept, strict=True):
                a.setFrictionCoeff(mu)

    def _contact_shapes(self) -> list[Any]:
        """The shape nodes whose friction the contact takes (DART: the smaller of the two): the foot's, the
        ground's."""
        foot = [self.foot.getShapeNode(i) for i in range(self.foot.getNumShapeNodes())]
        ground = [
            self.ground.getBodyNode(0).getShapeNode(i) for i in range(self.ground.getBodyNode(0).getNumShapeNodes())
        ]
        return [sn for sn in (*foot, *ground) if sn.hasDynamicsAspect()]

    # ----------------------------------------------------------------- read
    def state(self) -> tuple[np.ndarray, np.ndarray]:
        """Joint positions q [rad] (revolute angles, unwrapped) and velocities qd [rad/s]."""
        return self._q.copy(), self._qd.copy()

    def ground_force(self) -> np.ndarray:
        """Force of the ground on the foot in W [N]: DART's contact impulse / dt (native) or the law (reference)."""
        return self._force.copy()

    def read(self) -> tuple[float, ...]:
        """:meth:`state` and :meth:`ground_force` as nine floats, without the copies."""
        return (*self._q.tolist(), *self._qd.tolist(), *self._force.tolist())

    def _delassus(self) -> list[list[float]] | None:
        """W = J M^-1 J^T [1/kg] of the sphere's lowest point in W, with DART's own mass matrix, in the present
        state: what the contact's LCP rows are built from (their A_ii = t_i^T W t_i). None in reference contact
        and for a state that is not finite (a diverged run)."""
        if self.reference or not np.all(np.isfinite(self._q)):
            return None
        J = kinematics.jacobian_at(self._q, "true")
        return np.asarray(J @ np.linalg.solve(self.skel.getMassMatrix(), J.T)).tolist()

    def _slip(self) -> float | None:
        """The horizontal speed [m/s] of the sphere's lowest point in the present state (None for a state that is not
        finite, as :meth:`_delassus`: run.json holds no NaN)."""
        if not np.all(np.isfinite(self._q) & np.isfinite(self._qd)):
            return None
        return float(np.linalg.norm((kinematics.jacobian_at(self._q, "true") @ self._qd)[:2]))

    def info(self) -> dict[str, Any]:
        """Engine, version and every setting actually used, read back from the world where DART allows."""
        world, c = self.world, self.physics.contact
        solver = world.getConstraintSolver()
        # settings that do not act, left out so the report's settings table lists only what did: in reference contact
        # (nothing collides) the contact's own, in native contact the reference law's
        unused = {"friction_coefficient", "force_readout", "collision_detector"} if (
            self.reference) else {"reference_friction"}  # fmt: skip
        # the pair's coefficient as DART combines them, min(mu_foot, mu_ground): the foot's shapes and the ground's
        pair_dyn = [
            body.getShapeNode(i).getDynamicsAspect()
            for body in (self.foot, self.ground.getBodyNode(0))
            for i in range(body.getNumShapeNodes())
            if body.getShapeNode(i).hasDynamicsAspect()
        ]
        return {
            "engine": "dart",
            "version": metadata.version("dartpy"),
            **({} if self.reference else {"friction_cone": friction_shape(self.cfg["lcp_solver"])}),
            **(
                {"friction_axes": friction_axes()}
                if not self.reference and friction_shape(self.cfg["lcp_solver"]) == "pyramid"
                else {}
            ),
            **{k: self.cfg[k] for k in self.defaults if k not in unused},
            "sub_steps": self.n_sub,
            "timestep": world.getTimeStep(),
            "integrator": "euler",  # World.step: semi-implicit Euler (the family verification predicts by)
            "gravity": -float(world.getGravity()[2]),
            "contact_mode": self.physics.contact_mode,
            "contact": reference_contact(
                c, "J_poc^T F added to the joint forces per sub-step", self.cfg["reference_friction"]
            )
            if self.reference
            else {
                "enabled": True,
                "poc": "true",  # rigid: the sphere's lowest point, on the ground
                "lift": 0.0,
                "model": f"rigid (boxed LCP), Coulomb friction {friction_shape(self.cfg['lcp_solver'])}",
                "lcp_solver": solver.getBoxedLcpSolver().getType(),
                "secondary_lcp_solver": (
                    solver.getSecondaryBoxedLcpSolver().getType() if solver.getSecondaryBoxedLcpSolver() else None
                ),
                "collision_detector": solver.getCollisionDetector().getType(),
                "friction": min([d.getFrictionCoeff() for d in pair_dyn] or [getattr(c, self.slides_with())]),
                "restitution": 0.0,
                "Kp": None,
                "Kd": None,
                "Kp_Kd_note": "rigid contact: DART has no contact stiffness or damping; Kp, Kd do not apply",
                "constraint_force_mixing": DART_CFM,
                "force_readout": (
                    "contact impulse over the control period / the period"
                    if self._period_mean
                    else "last sub-step's contact impulse / dt"
                ),
            },
            "deactivation_enabled": bool(world.getDeactivationOptions().mEnabled),  # read back
            "joint_limits_enforced": bool(self.cfg["enforce_limits"]),
            # read back: a speed is bounded only where the limits are enforced and a velocity limit is finite
            "joint_velocity_limits_enforced": all(j.areLimitsEnforced() for j in self.joints)
            and any(
                np.isfinite(self.skel.getVelocityLowerLimit(i)) or np.isfinite(self.skel.getVelocityUpperLimit(i))
                for i in self.dofs
            ),
            # the state the run ended in: J M^-1 J^T at the lowest point in W with DART's mass matrix [1/kg], the
            # lowest point's horizontal speed [m/s] and the read ground force [N] (whether the foot ended held, and
            # at what share of Fn: the Dantzig hold docs/backends/dart.md reports)
            "at_end": {
                "delassus": self._delassus(),
                "slip": self._slip(),
                "force": self._force.tolist() if np.all(np.isfinite(self._force)) else None,
            },  # fmt: skip
        }

    # ------------------------------------------------------- declared abilities
    def integrator_family(self) -> str:
        """DART's World.step is semi-implicit Euler (velocity, then position with the new velocity)."""
        return "euler"

    def sub_steps(self) -> int:
        return self.n_sub

    def limits(self) -> Limits:
        """Joint position and force limits and gravity, read back from the skeleton and world."""
        skel = self.skel
        lower = tuple(float(skel.getPositionLowerLimit(i)) for i in self.dofs)
        upper = tuple(float(skel.getPositionUpperLimit(i)) for i in self.dofs)
        effort = tuple(float(skel.getForceUpperLimit(i)) for i in self.dofs)
        enforced = all(j.areLimitsEnforced() for j in self.joints)
        return Limits(
            gravity=-float(self.world.getGravity()[2]), lower=lower, upper=upper, effort=effort,  # type: ignore[arg-type]
            timestep=float(self.world.getTimeStep()),
            enforcement="hard joint-limit constraint in the boxed LCP" if enforced else "none (not enforced)",
        )  # fmt: skip

    def mass_properties(self) -> dict[str, dict[str, Any]]:
        """Per moving body: mass [kg], COM [m] and inertia about the COM [kg m^2] in the link frame.

        From each body node's ``Inertia`` (mass, local COM, moment about the COM in
        the body frame); link 3 includes the foot, placed by its transform in link 3.
        """
        out = {}
        for name in LINK_NAMES:
            body = self.skel.getBodyNode(name)
            inr = _inertial(body)
            if name == LINK_NAMES[-1]:
                T = self.foot.getTransform(body).matrix()
                R, p = T[:3, :3], T[:3, 3]
                foot = _inertial(self.foot)
                moved = Inertial(foot.mass, tuple(R @ foot.com + p), tuple(map(tuple, R @ foot.I @ R.T)))  # type: ignore[arg-type]
                inr = combine([inr, moved])
            out[name] = {"mass": inr.mass, "com": list(inr.com), "inertia": inr.I.tolist()}
        return out

    def close(self) -> None:
        """Drop the world."""
        self.world = None  # type: ignore[assignment]


def _inertial(body: Any) -> Inertial:
    inertia = body.getInertia()
    I = np.asarray(inertia.getMoment())
    com = np.asarray(inertia.getLocalCOM())
    return Inertial(float(inertia.getMass()), tuple(com.tolist()), tuple(map(tuple, I.tolist())))  # type: ignore[arg-type]


__all__ = ["DartBackend"]
