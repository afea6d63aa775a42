"""PyBullet backend: the generated URDF in Bullet's multibody, compliant native contact or the reference law.

Model: ``models/leg.urdf`` loaded with ``useFixedBase=True`` and
``URDF_USE_INERTIA_FROM_FILE`` (otherwise Bullet recomputes inertia from the
collision shapes), in a ``DIRECT`` client of its own (several backends may run
side by side). The ground is a static ``GEOM_PLANE`` at z_W = 0 (no
``pybullet_data`` needed). Every default that would make Bullet differ from
the spec is switched off (docs/contact_mapping.md): the velocity motors that brake the
joints until disabled, link linear/angular damping (0.04 by default), joint
damping, and the 100 rad/s joint-speed clamp (raised to 1000 rad/s, far above
the 55 rad/s the motors can reach, so it never binds silently). Only the foot
sphere collides, and only with the ground (pair collision filters).

Native contact: ``contactStiffness = Kp`` and ``contactDamping = Kd`` on the
foot, which Bullet turns into an implicit spring-damper through ERP/CFM.
Bullet combines the two bodies' stiffnesses in series and adds their
dampings, and a body's default damping is 0.1 N s/m, so the plane gets an
explicit rigid, undamped pair (1e30 N/m, 0): the contact is then exactly
(Kp, Kd) (the plane's default would add 0.025 N to a 39 N impact). Lateral
friction ``mu_s`` on the foot and 1 on the plane (Bullet multiplies them), no
spinning or rolling friction, restitution 0, and ``contactSlop = 0`` /
``contactProcessingThreshold = 0`` so the spring acts on the true
penetration (PyBullet's slop is 1e-5 m, PhysicsServerCommandProcessor.cpp
``m_linearSlop = 0.00001``, added to the contact distance in
btMultiBodyConstraintSolver.cpp: the foot would rest 10 um deeper; Bullet's own
``btContactSolverInfo`` default is 0). Friction is a hard Coulomb cone at the
velocity level: the foot holds to micrometres, but with no positional correction
(Bullet's friction anchor, which PyBullet leaves off: setting ``friction_anchor: on``) it drifts under a tangential
load: 13 um/s in the calibration's 13.2 N push at 40 N, 3 um over the effort task
(with ``frictionAnchor`` on, 5e-13 m/s, but the read-out against the statics goes
from 2e-9 to 1.6e-3 of Fn; a reviewer's check, 27 Nov).

Profiles: ``matched`` is the above (the defaults); ``engine-defaults`` keeps
Bullet's own plane (no explicit stiffness/damping: its default contact damping
adds to Kd), PyBullet's slop (1e-5 m) and Bullet's processing threshold
(BT_LARGE_FLOAT), PyBullet's 50 solver iterations, and takes one
1 ms ``stepSimulation`` per control period, with Kp, Kd as the foot's
``contactStiffness``/``contactDamping`` and mu as its ``lateralFriction`` on a
plane of friction 1 (pybullet_data's plane.urdf). Both hold the foot (Coulomb cone);
the steady effort-task force differs by 0.04 % (docs/contact_mapping.md).

Reference contact: the foot-ground collision pair is disabled and ``J_poc^T F`` of
:class:`~legbench.contact.ReferenceContact` at the sub-step's start state is
added to the commanded torque before every ``stepSimulation``.

Sub-stepping: native contact (``sub_stepping: bullet``, the default) commands the (clamped)
torque once per control period, as a list (cheaper across the binding than an array), and
calls ``stepSimulation`` once with ``fixedTimeStep`` = the control period and ``numSubSteps =
n_sub``: Bullet holds the torque over its internal steps and clears it after the last, so the
states are bit-identical to ``n_sub`` x (command + ``stepSimulation``) (``sub_stepping: python``;
tests/test_backend_pybullet.py compares the logs). ``getContactPoints`` then reports the last
internal step's impulse divided by the whole period, ``n_sub`` times too small: the read-out is
multiplied by ``n_sub`` (the force of the last sub-step, as with one call per sub-step). Bullet counts
its internal steps from an accumulator, ``int(time / fixedTimeStep)`` per call, clamped to ``numSubSteps``
(``btDiscreteDynamicsWorld::stepSimulation``): for some ``n_sub`` a period of n_sub steps of T / n_sub
rounds to n_sub - 1 plus a remainder, and a later call is clamped, so time is lost (n_sub = 61 at 1 kHz:
500 of 1000 calls one step short, the run 0.8 % slow; also 105, 109, 115, 122, 123, ...). Its own
sub-stepping is therefore used only where that accumulator comes back to exactly 0 after one period
(:func:`bullet_substeps_exact`: every n_sub from 1 to 60, the default 20 among them); elsewhere the
backend steps n_sub times itself, which is bit-identical. Bullet's
contact sticks without chatter, and the read-out matches the leg's statics over the effort task's
last 0.5 s to 2e-9 of Fn (2e-7 %; matched) and 3e-9 (engine-defaults). Reference contact needs the law at
every sub-step's start state, so there the backend calls ``stepSimulation`` per sub-step
(``numSubSteps = 1``) and adds the law to the command before each call. Bullet
applies a ``TORQUE_CONTROL`` command only to the next ``stepSimulation`` and
adds up repeated commands, so the torque is commanded exactly once
before each call. The integrator is Bullet's semi-implicit Euler; ``dt``
defaults to 5e-5 s like the other backends (free-space error < 0.1 % of the
motion, tests/test_backends_engines.py).
"""

from __future__ import annotations

import importlib
import math
import sys
from collections.abc import Mapping
from importlib import metadata
from pathlib import Path
from typing import Any, ClassVar

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
    sub_step_count,
)
from legbench.contact import ReferenceContact, law_step_warnings
from legbench.model import FOOT_FRAME, LINK_NAMES, Inertial, combine

#: The line pybullet's C module prints (to stderr) when it is imported.
_BANNER = b"pybullet build time:"


def _import_quietly() -> Any:
    """Import pybullet without its build banner.

    The banner is a C ``printf`` to stderr at module initialisation, below Python's
    ``sys.stderr``, so file descriptor 2 is pointed at a temporary file for the import and
    every other line written there is written back to the real stderr: only the banner is
    hidden (an import error is an exception, raised as usual).
    """
    import ctypes
    import os
    import tempfile

    try:
        sys.stderr.flush()
        saved = os.dup(2)
    except (OSError, ValueError):  # no usable fd 2: import as it is
        return importlib.import_module("pybullet")
    with tempfile.TemporaryFile() as tmp:
        os.dup2(tmp.fileno(), 2)
        try:
            module = importlib.import_module("pybullet")
        finally:
            try:  # anything C's stdio still buffers goes to the file, not after the restore
                ctypes.CDLL(None).fflush(None)
            except (OSError, AttributeError):
                pass
            os.dup2(saved, 2)
            os.close(saved)
            tmp.seek(0)
            kept = b"".join(line for line in tmp.readlines() if not line.startswith(_BANNER))
            if kept:
                os.write(2, kept)
    return module


p = _import_quietly()

#: Joint-speed clamp [rad/s]: Bullet's default of 100 replaced by a bound the leg cannot reach, ten times the run
#: loop's divergence bound (1000 rad/s, ``scenario.MAX_JOINT_SPEED``): at 1000 itself a runaway PyBullet run sat
#: clamped at exactly the bound, which the loop's strict test never trips, and stayed 'ok' where every other
#: engine was stopped as diverged (a harness review).
MAX_JOINT_VELOCITY = 1.0e4
#: PyBullet's contact slop [m] (PhysicsServerCommandProcessor.cpp: ``m_linearSlop = 0.00001``; Bullet's own
#: btContactSolverInfo default is 0): added to the contact distance (btMultiBodyConstraintSolver.cpp), so a
#: resting contact sinks that much deeper. ``contact_margins: zero`` sets it to 0.
PYBULLET_CONTACT_SLOP = 1.0e-5
#: PyBullet's solver residual threshold (PhysicsServerCommandProcessor.cpp: ``m_leastSquaresResidualThreshold =
#: 1e-7``; getPhysicsEngineParameters does not report it): the constraint solver's passes stop at the first whose
#: largest squared row residual is below it (btSequentialImpulseConstraintSolver.cpp), so a held contact keeps
#: what the last pass left (:func:`pgs_creep`). Set explicitly, to the same value (the runs are bit-identical).
PYBULLET_RESIDUAL_THRESHOLD = 1.0e-7
#: The contact rows of a foot on the ground as Bullet orders them: the normal n = +z, then the friction directions
#: btPlaneSpace1(n) gives, d1 = (0, -1, 0) and d2 = n x d1 = (1, 0, 0) (two, as btMultiBodyDynamicsWorld sets
#: SOLVER_USE_2_FRICTION_DIRECTIONS).
CONTACT_ROWS = ((0.0, 0.0, 1.0), (0.0, -1.0, 0.0), (1.0, 0.0, 0.0))
#: A collision object's contact stiffness [N/m] and damping [N s/m] until set (btCollisionObject.cpp:
#: ``m_contactStiffness(BT_LARGE_FLOAT)``, 1e30 in PyBullet's double-precision build, ``m_contactDamping(.1)``),
#: which the pair's combination uses; ``getDynamicsInfo`` reports -1 for both while they are unset
#: (PhysicsServerCommandProcessor.cpp, without ``CF_HAS_CONTACT_STIFFNESS_DAMPING``).
BULLET_DEFAULT_CONTACT_STIFFNESS = 1.0e30
BULLET_DEFAULT_CONTACT_DAMPING = 0.1
#: Contact stiffness of the plane [N/m]: Bullet combines stiffnesses in series, so a
#: rigid plane leaves the foot's Kp (1/(1/Kp + 1e-30) = Kp in double precision).
PLANE_STIFFNESS = 1.0e30


def pgs_creep(W: np.ndarray, h: float, kp: float, kd: float, force: np.ndarray, threshold: float,
              iterations: int) -> tuple[float, int]:  # fmt: skip
    """The steady creep [m/s] of a foot Bullet holds below the friction limit, and the solver passes it takes.

    Bullet's multibody solver starts each step from zero impulses (no warm start) and stops at the first pass whose
    largest squared row residual is below ``threshold`` (at most ``iterations``); a pass solves the normal row, then
    the two friction rows together from the same velocity (the implicit cone). With A = W + C (C the normal row's
    CFM 1 / (h (h kp + kd)) of a contact stiffness and damping; the friction rows have none) and S that pass's
    splitting (A's diagonal, with the normal row's coupling below it), n passes leave the error E = (I - S^-1 A)^n
    of the full solve, and in the steady state the rows move at -h W E (I - E)^-1 F per step, F the contact force
    in the rows (n, d1, d2) of :data:`CONTACT_ROWS`; the creep is its tangential part. n is found with it: the
    residuals of the passes (A_ii times each row's impulse change, the friction pair's summed) from the steady
    right-hand side A (I - E)^-1 h F. Where the pass counts cycle (no count leaves a steady state that stops at
    it), NaN: no steady creep to explain.
    (btMultiBodyConstraintSolver.cpp, btSequentialImpulseConstraintSolver.cpp; measured on the calibration's hold:
    1.2561e-5 against 1.2560e-5 m/s matched, n = 2; 5.2153e-6 against 5.2152e-6 engine-defaults, n = 4.)

    Args:
        W: J M^-1 J^T of the contact rows [1/kg].
        h: Bullet's internal step [s].
        kp, kd: the pair's contact stiffness [N/m] and damping [N s/m].
        force: the contact force on the foot in W [N].
        threshold: the solver's residual threshold.
        iterations: the solver's pass limit.
    """
    A = W + np.diag([1.0 / (h * (h * kp + kd)), 0.0, 0.0])
    d = np.diag(A)
    S = np.diag(d)
    S[1:, 0] = A[1:, 0]
    G = np.eye(3) - np.linalg.solve(S, A)
    F = np.array(CONTACT_ROWS) @ force
    n, seen = 1, set()
    for _ in range(iterations):  # n and the steady state it leaves, found together (1-2 rounds)
        if n in seen:  # no fixed point: the passes alternate between counts from step to step, no steady creep
            return math.nan, n
        seen.add(n)
        E = np.linalg.matrix_power(G, n)
        r = A @ np.linalg.solve(np.eye(3) - E, h * F)
        impulse, stop = np.zeros(3), iterations
        for k in range(iterations):
            change = np.linalg.solve(S, r - A @ impulse)
            impulse += change
            if max((d[0] * change[0]) ** 2, (d[1] * change[1] + d[2] * change[2]) ** 2) <= threshold:
                stop = k + 1
                break
        if stop == n:
            break
        n = stop
    E = np.linalg.matrix_power(G, n)
    w = -h * W @ E @ np.linalg.solve(np.eye(3) - E, F)
    return float(math.hypot(w[1], w[2])), n


class PybulletBackend(Backend):
    """PyBullet (Bullet multibody, sequential-impulse solver) simulating the leg."""

    name: ClassVar[str] = "pybullet"
    defaults: ClassVar[Mapping[str, Any]] = {
        "dt": 5.0e-5,  # sub-step [s]: the Pinocchio default (docs/pinocchio.md), so defaults are same-step
        # sequential-impulse iterations per step: PyBullet's default 50 (PhysicsServerCommandProcessor.cpp,
        # m_numIterations = 50; Bullet's own btContactSolverInfo default is 10)
        "solver_iterations": 50,
        "plane_contact": "rigid",  # rigid: plane (1e30 N/m, 0 N s/m); default: Bullet's plane (adds its damping)
        "plane_friction": 1.0,  # lateral friction of the plane (Bullet multiplies it with the foot's mu)
        "reference_friction": "implicit",  # reference mode: the law's friction slope implicit (as Pinocchio's)
        "contact_margins": "zero",  # zero: contactSlop = contactProcessingThreshold = 0; default: Bullet's
        "sub_stepping": "bullet",  # native: bullet: one command + numSubSteps; python: n x (command + step)
        # Bullet's friction anchor (changeDynamics frictionAnchor): off, PyBullet's default; on holds the contact
        # point against the velocity-level friction's drift (module docstring)
        "friction_anchor": "off",
        "friction_coefficient": "mu_s",  # the foot's lateralFriction: mu_s (holds to mu_s Fn) or mu_k (slides at it)
    }
    #: One friction coefficient (mu_s on the cone unless ``friction_coefficient`` says mu_k): it slides with it.
    sliding_coefficient: ClassVar[str] = "mu_s"

    @property
    def bench_targets(self) -> Mapping[str, float]:
        """The full run within 1.15x the engine's own stepping in native contact; in reference contact the floor
        steps without the law legbench applies every sub-step, so it is no floor of that run: no target."""
        return {} if self.reference else {"full/floor": 1.15}

    choices: ClassVar[Mapping[str, tuple[str, ...]]] = {
        "plane_contact": ("rigid", "default"),
        "contact_margins": ("zero", "default"),
        "reference_friction": ("implicit", "explicit"),
        "sub_stepping": ("bullet", "python"),
        "friction_anchor": ("off", "on"),
        "friction_coefficient": FRICTION_COEFFICIENTS,
    }
    #: ``engine-defaults``: one Bullet step per control period, Bullet's plane, slop and
    #: thresholds; Kp, Kd as the foot's contactStiffness/contactDamping, mu as its
    #: lateralFriction on a plane of friction 1 (as pybullet_data's plane.urdf).
    profiles: ClassVar[Mapping[str, Mapping[str, Any]]] = {
        "matched": {},
        "engine-defaults": {
            "dt": 1.0e-3,
            "solver_iterations": 50,
            "plane_contact": "default",
            "plane_friction": 1.0,
            "contact_margins": "default",
        },
    }

    @classmethod
    def known_deviation(cls, case: str, quantity: str, info: Mapping[str, Any], measured: float = math.nan,
                        expected: float = math.nan, tolerance: float = math.nan) -> str | None:  # fmt: skip
        """PyBullet's contact slop deepens the rest by one slop (engine-defaults; docs/studies.md, section 4): said
        where the rest penetration misses Fn/Kp by the slop, within the row's tolerance; a held foot creeps by what
        the solver's passes leave (:func:`pgs_creep`, the calibration's case ``creep``), said where it meets the
        measured creep."""
        contact = info.get("contact")
        slop = contact.get("contact_slop") if isinstance(contact, Mapping) else None
        if case == "rest_penetration" and isinstance(slop, float) and slop > 0.0:
            return held(f"known: with a contact stiffness set, Bullet springs from the depth less the contact slop "
                        f"({slop:g} m here, PyBullet's default; Bullet's own is 0), so the foot rests one slop deeper "
                        f"than Fn/Kp: {1e6 * (measured - expected):+.2f} um", measured, expected + slop, tolerance,
                        " (-0.17 um with slop 0, +19.8 um with 2e-5, measured; ERP, split impulse, the plane's "
                        "damping and the iterations do not move it)")  # fmt: skip
        at_end, load = info.get("at_end"), info.get("load")
        delassus = at_end.get("delassus") if isinstance(at_end, Mapping) else None
        if (case == "creep" and isinstance(load, Mapping) and "F" in load and isinstance(delassus, list)
                and info.get("friction_anchor") == "off" and isinstance(contact, Mapping)):  # fmt: skip
            h, iterations = float(info["timestep"]), int(info["solver_iterations"])
            threshold = float(contact["solver_residual_threshold"])
            v, n = pgs_creep(np.array(delassus), h, float(contact["pair_stiffness"]), float(contact["pair_damping"]),
                             np.asarray(load["F"], float), threshold, iterations)  # fmt: skip
            return held(f"known: Bullet's solver stops at the first pass whose squared row residual is below its "
                        f"threshold ({threshold:g}; PyBullet sets 1e-7), here after {n} of {iterations} passes, each "
                        f"step from zero impulses (no warm start): the friction rows keep what the passes leave, "
                        f"h W E (I - E)^-1 F with E = (I - S^-1 A)^{n} the passes' error map, a creep of "
                        f"{1e3 * v:.4g} mm/s", measured, v, tolerance, "; with the threshold at 0 the foot sticks "
                        "(tests/test_backend_pybullet.py; docs/contact_mapping.md)")  # fmt: skip
        return None

    # ----------------------------------------------------------------- load
    def load(self, urdf: Path, physics: Physics, settings: Mapping[str, Any]) -> None:
        """Connect a DIRECT client, load the URDF and the ground, switch off Bullet's extra damping and clamps.

        Args:
            urdf: the generated leg URDF.
            physics: gravity, contact law and mode, control period, torque limits.
            settings: overrides of :attr:`defaults` (``dt`` [s], ``solver_iterations``).

        Raises:
            LegbenchError: a ``dt`` that does not divide the control period.
        """
        cfg = self.settings(settings)
        n_sub = sub_step_count(self.name, cfg["dt"], physics.control_dt)
        self.cfg, self.physics, self.n_sub = cfg, physics, n_sub
        self.reference = physics.contact_mode == "reference"
        # Bullet's own sub-stepping: one stepSimulation of the control period split into n_sub
        # internal steps; reference contact needs the law at every sub-step, so it steps itself
        self.engine_sub = (
            not self.reference and cfg["sub_stepping"] == "bullet" and bullet_substeps_exact(physics.control_dt, n_sub)
        )
        self.cid = cid = p.connect(p.DIRECT)

        p.setPhysicsEngineParameter(
            fixedTimeStep=physics.control_dt if self.engine_sub else physics.control_dt / n_sub,
            numSubSteps=n_sub if self.engine_sub else 1,
            numSolverIterations=int(cfg["solver_iterations"]),
            solverResidualThreshold=PYBULLET_RESIDUAL_THRESHOLD,
            physicsClientId=cid,
        )
        self.exact_margins = cfg["contact_margins"] == "zero"
        if self.exact_margins:
            p.setPhysicsEngineParameter(contactSlop=0.0, physicsClientId=cid)
        p.setGravity(0.0, 0.0, -physics.gravity, physicsClientId=cid)
        self.body = body = p.loadURDF(
            str(urdf), useFixedBase=True, flags=p.URDF_USE_INERTIA_FROM_FILE, physicsClientId=cid
        )
        names = {
            p.getJointInfo(body, j, physicsClientId=cid)[12].decode(): j
            for j in range(p.getNumJoints(body, physicsClientId=cid))
        }
        self.links = {name: names[name] for name in (*LINK_NAMES, FOOT_FRAME)}
        self.joints = [self.links[name] for name in LINK_NAMES]  # joint i drives link i
        self.foot = self.links[FOOT_FRAME]

        plane = p.createCollisionShape(p.GEOM_PLANE, physicsClientId=cid)
        self.ground = p.createMultiBody(baseMass=0.0, baseCollisionShapeIndex=plane, physicsClientId=cid)

        # no velocity motors, no damping, no hidden speed clamp
        p.setJointMotorControlArray(body, self.joints, p.VELOCITY_CONTROL, forces=[0.0] * 3, physicsClientId=cid)
        for link in (-1, *self.links.values()):
            p.changeDynamics(
                body, link, linearDamping=0.0, angularDamping=0.0, jointDamping=0.0,
                maxJointVelocity=MAX_JOINT_VELOCITY, physicsClientId=cid,
            )  # fmt: skip

        # collisions: foot <-> ground only, by explicit pair filters (in this build a pair
        # collides if either body's group meets the other's mask, so clearing the foot's
        # mask alone did not stop it); self-collision is off by default
        for name, link in self.links.items():
            enable = name == FOOT_FRAME and not self.reference
            p.setCollisionFilterPair(body, self.ground, link, -1, int(enable), physicsClientId=cid)

        c = physics.contact
        margins = {"contactProcessingThreshold": 0.0} if self.exact_margins else {}
        p.changeDynamics(
            body, self.foot, contactStiffness=c.Kp, contactDamping=c.Kd,
            lateralFriction=float(getattr(c, cfg["friction_coefficient"])),
            spinningFriction=0.0, rollingFriction=0.0, restitution=0.0, physicsClientId=cid,
            frictionAnchor=int(cfg["friction_anchor"] == "on"), **margins,
        )  # fmt: skip
        rigid = {"contactStiffness": PLANE_STIFFNESS, "contactDamping": 0.0} if cfg["plane_contact"] == "rigid" else {}
        p.changeDynamics(
            self.ground, -1, lateralFriction=float(cfg["plane_friction"]), spinningFriction=0.0,
            rollingFriction=0.0, restitution=0.0, physicsClientId=cid, **margins, **rigid,
        )  # fmt: skip

        implicit = self.reference and cfg["reference_friction"] == "implicit"
        self.contact = ReferenceContact.from_leg(c, physics.gravity if implicit else None)
        self._limit = tuple(float(x) for x in physics.torque_limit)  # [N m]
        self._dt = physics.control_dt
        if self.reference:
            self._step = self._step_reference
        else:
            self._step = self._step_native_engine if self.engine_sub else self._step_native
        #: getContactPoints reports the last internal step's impulse over the whole stepSimulation
        #: (fixedTimeStep): with Bullet's sub-stepping that is n_sub times the internal step
        self._force_scale = float(n_sub) if self.engine_sub else 1.0
        self._tau_list = [0.0, 0.0, 0.0]  # the clamped torque [N m], as the command takes it
        self._force = np.zeros(3)
        self._q = np.zeros(3)
        self._qd = np.zeros(3)
        #: q [rad], qd [rad/s], F in W [N] after the last step, as nine floats (what read() returns)
        self._reading: tuple[float, ...] = (0.0,) * 9
        self.t = 0.0
        self._fn_peak, self._q_peak = 0.0, [0.0, 0.0, 0.0]

    # ---------------------------------------------------------------- reset
    def reset(self, q: np.ndarray, qd: np.ndarray) -> None:
        """Set q [rad] and qd [rad/s]; the contact force reads zero until the first step."""
        for j, qj, qdj in zip(self.joints, q, qd, strict=True):
            p.resetJointState(self.body, j, float(qj), float(qdj), physicsClientId=self.cid)
        self._read()
        self.t = 0.0
        self._fn_peak = 0.0
        if self.reference:
            self._reference_force()
        else:
            self._force[:] = 0.0
        self._reading = (*self._q.tolist(), *self._qd.tolist(), *self._force.tolist())

    # ----------------------------------------------------------------- step
    def step(self, tau: np.ndarray) -> None:
        """Advance one control period with tau [N m], clamped to the torque limits, held."""
        self._tau_list[:] = clamp_torque(tau, self._limit)
        self._step()
        self.t += self._dt
        r = self._reading
        check_finite(self.name, self.t, r[0:3], r[3:6])

    def _step_native_engine(self) -> None:
        """Native contact, Bullet's own sub-stepping: one torque command (a list: cheaper across the
        binding than an array) and one ``stepSimulation`` that takes ``numSubSteps`` internal steps.

        Bullet keeps the commanded joint torque for every internal step and clears it after the
        last, so this is bit-identical to ``n_sub`` x (command + ``stepSimulation``) of
        :meth:`_step_native` (tests/test_backend_pybullet.py compares the logs).
        """
        p.setJointMotorControlArray(self.body, self.joints, p.TORQUE_CONTROL, forces=self._tau_list,
                                    physicsClientId=self.cid)  # fmt: skip
        p.stepSimulation(physicsClientId=self.cid)
        self._read_native()

    def _step_native(self) -> None:
        """Native contact, ``sub_stepping: python``: ``n_sub`` x (command + ``stepSimulation``)."""
        body, cid, joints, n_sub = self.body, self.cid, self.joints, self.n_sub
        tau, control, step, torque = self._tau_list, p.setJointMotorControlArray, p.stepSimulation, p.TORQUE_CONTROL
        for _ in range(n_sub):
            control(body, joints, torque, forces=tau, physicsClientId=cid)
            step(physicsClientId=cid)
        self._read_native()

    def _step_reference(self) -> None:
        """Reference mode: the law's J_poc^T F at each sub-step's start state added to the torque.

        ``reference_friction: implicit`` (default) adds the linearly implicit friction correction
        (:meth:`ReferenceContact.implicit_generalized`, the clamped command as the other torque);
        ``explicit`` applies the law as it is (stable only below m v_th / (mu_s Fn)).
        """
        body, cid, joints = self.body, self.cid, self.joints
        implicit = self.cfg["reference_friction"] == "implicit"
        law, law_i, h = (
            self.contact.generalized,
            self.contact.implicit_generalized,
            self.physics.control_dt / self.n_sub,
        )
        control, step, states = p.setJointMotorControlArray, p.stepSimulation, p.getJointStates
        torque = p.TORQUE_CONTROL
        u1, u2, u3 = self._tau_list
        q, qd = self._q, self._qd
        # the state as floats through the sub-steps, written back once
        q1, q2, q3 = q.tolist()
        qd1, qd2, qd3 = qd.tolist()
        for _ in range(self.n_sub):
            if implicit:
                t1, t2, t3 = law_i(q1, q2, q3, qd1, qd2, qd3, u1, u2, u3, h).tolist()
            else:
                t1, t2, t3 = law(q1, q2, q3, qd1, qd2, qd3).tolist()
            control(body, joints, torque, forces=[u1 + t1, u2 + t2, u3 + t3], physicsClientId=cid)
            step(physicsClientId=cid)
            s1, s2, s3 = states(body, joints, physicsClientId=cid)
            q1, q2, q3, qd1, qd2, qd3 = s1[0], s2[0], s3[0], s1[1], s2[1], s3[1]
        q[0], q[1], q[2], qd[0], qd[1], qd[2] = q1, q2, q3, qd1, qd2, qd3
        self._reference_force()
        self._reading = (*q.tolist(), *qd.tolist(), *self._force.tolist())

    def _read(self) -> None:
        """Joint states into the ``_q``, ``_qd`` arrays (the reference path's sub-steps read them)."""
        states = p.getJointStates(self.body, self.joints, physicsClientId=self.cid)
        for i, s in enumerate(states):
            self._q[i] = s[0]
            self._qd[i] = s[1]

    def _read_native(self) -> None:
        """Native contact, end of a period: joint states and :meth:`_native_force` into ``_reading``, as floats."""
        s1, s2, s3 = p.getJointStates(self.body, self.joints, physicsClientId=self.cid)
        fx, fy, fz = self._native_force()
        self._reading = (s1[0], s2[0], s3[0], s1[1], s2[1], s3[1], fx, fy, fz)

    def _reference_force(self) -> None:
        q, qd = self._q, self._qd
        self.contact.generalized(q[0], q[1], q[2], qd[0], qd[1], qd[2])
        self._force[:] = self.contact.force
        if self._force[2] > self._fn_peak:
            self._fn_peak, self._q_peak = float(self._force[2]), q.tolist()

    def _native_force(self) -> tuple[float, float, float]:
        """Sum of the foot's contact forces over the last sub-step (impulse / sub-step), on the foot, in W [N].

        Bullet divides the impulse by ``fixedTimeStep``, the whole period with its own sub-stepping:
        ``_force_scale`` (``n_sub`` then, else 1) turns that into the sub-step's force.

        With the foot as body A, ``contactNormalOnB`` points from the ground
        towards the foot, the normal force pushes the foot along it, and the
        two friction forces act on A along ``lateralFrictionDir1/2``.

        That last holds because Bullet itself keeps the foot first: when a query's
        (A, B) is the contact manifold's (body1, body0), getContactPoints swaps the
        bodies and negates the normal but leaves the friction directions as they
        are (PhysicsServerCommandProcessor.cpp,
        processRequestContactpointInformationCommand), which would flip the
        friction force read on the foot. A sphere-plane pair's manifold is always
        (sphere, plane) (btConvexPlaneCollisionAlgorithm.cpp: getNewManifold(convex,
        plane) whichever order the broadphase gives), so the foot is the manifold's
        body0 and nothing is swapped; tests/test_backend_pybullet.py checks the order.
        """
        fx = fy = fz = 0.0
        for cp in p.getContactPoints(self.body, self.ground, self.foot, -1, physicsClientId=self.cid):
            fn, f1, d1, f2, d2, n = cp[9], cp[10], cp[11], cp[12], cp[13], cp[7]
            fx += fn * n[0] + f1 * d1[0] + f2 * d2[0]
            fy += fn * n[1] + f1 * d1[1] + f2 * d2[1]
            fz += fn * n[2] + f1 * d1[2] + f2 * d2[2]
        s = self._force_scale
        return fx * s, fy * s, fz * s

    # ----------------------------------------------------------------- read
    def state(self) -> tuple[np.ndarray, np.ndarray]:
        """Joint positions q [rad] (Bullet's raw, unwrapped hip angle) and velocities qd [rad/s]."""
        r = self._reading
        return np.array(r[0:3]), np.array(r[3:6])

    def ground_force(self) -> np.ndarray:
        """Force of the ground on the foot in W [N].

        Native: Bullet's contact impulse of the last sub-step divided by its
        duration ``dt`` (the force over the final sub-step, 0.05 ms by default,
        not at the end instant). Reference: the law at the current state.
        """
        return np.array(self._reading[6:9])

    def read(self) -> tuple[float, ...]:
        """:meth:`state` and :meth:`ground_force` as nine floats, without the copies."""
        return self._reading

    def info(self) -> dict[str, Any]:
        """Engine, version and every physics setting actually used, read back where Bullet allows."""
        cid, c = self.cid, self.physics.contact
        foot = p.getDynamicsInfo(self.body, self.foot, physicsClientId=cid)
        ground = p.getDynamicsInfo(self.ground, -1, physicsClientId=cid)
        engine = p.getPhysicsEngineParameters(physicsClientId=cid)
        (k_foot, c_foot), (k_plane, c_plane) = _stiffness_damping(foot), _stiffness_damping(ground)
        unused = {"plane_contact", "plane_friction", "contact_margins", "sub_stepping", "friction_anchor",
                  "friction_coefficient"} if (
            self.reference) else {"reference_friction"}  # fmt: skip
        return {
            "engine": "pybullet",
            "version": metadata.version("pybullet"),
            "api_version": p.getAPIVersion(physicsClientId=cid),
            **{k: self.cfg[k] for k in self.defaults if k not in unused},
            "sub_steps": self.n_sub,
            "timestep": engine["fixedTimeStep"] / max(int(engine["numSubSteps"]), 1),
            "engine_sub_steps": engine["numSubSteps"],
            "step_calls_per_period": 1 if self.engine_sub else self.n_sub,
            "gravity": self.physics.gravity,
            "contact_mode": self.physics.contact_mode,
            "contact": reference_contact(
                c, "J_poc^T F added to the torque per sub-step", self.cfg["reference_friction"]
            )
            if self.reference
            else {
                "enabled": True,
                # Bullet applies and reports the impulse at the foot's witness point, the sphere's lowest
                "poc": "true",
                "lift": 0.0,  # measured: the statics hold there to 1e-7 N (docs/metrics.md)
                # the values the pair combines (getDynamicsInfo's -1, "unset", replaced by Bullet's own defaults)
                "foot_stiffness": k_foot,
                "foot_damping": c_foot,
                "plane_stiffness": k_plane,
                "plane_damping": c_plane,
                # the pair's contact as Bullet combines it (btManifoldResult.cpp: stiffness in series, damping added)
                "pair_stiffness": 1.0 / (1.0 / k_foot + 1.0 / k_plane),
                "pair_damping": c_foot + c_plane,
                "foot_lateral_friction": foot[1],
                "plane_lateral_friction": ground[1],
                "friction": foot[1] * ground[1],
                "spinning_friction": foot[7],
                "rolling_friction": foot[6],
                "restitution": foot[5],
                # [m] PyBullet's slop, which getPhysicsEngineParameters does not report
                "contact_slop": 0.0 if self.exact_margins else PYBULLET_CONTACT_SLOP,
                "contact_processing_threshold": (
                    0.0 if self.exact_margins else "Bullet default (BT_LARGE_FLOAT, btCollisionObject.cpp)"
                ),
                "cone": "Coulomb cone (sticks below mu Fn, slides at mu Fn)",
                "solver_residual_threshold": PYBULLET_RESIDUAL_THRESHOLD,
                "Kp": c.Kp,
                "Kd": c.Kd,
            },
            "damping": {"linear": 0.0, "angular": 0.0, "joint": 0.0},
            "max_joint_velocity": MAX_JOINT_VELOCITY,
            # J M^-1 J^T of the contact rows (CONTACT_ROWS) at the lowest point, in the state the run ended in [1/kg]
            "at_end": {"delassus": self._delassus()},
        }

    def _delassus(self) -> list[list[float]] | None:
        """W = J M^-1 J^T [1/kg] of the contact rows (:data:`CONTACT_ROWS`) at the sphere's lowest point, with
        Bullet's own mass matrix, in the present state: what its solver iterates on (:func:`pgs_creep`). None in
        reference contact and for a state that is not finite (a diverged run)."""
        q, _ = self.state()
        if self.reference or not np.all(np.isfinite(q)):
            return None
        M = np.array(p.calculateMassMatrix(self.body, q.tolist(), physicsClientId=self.cid))
        J = np.array(CONTACT_ROWS) @ kinematics.jacobian_at(q, "true")
        return np.asarray(J @ np.linalg.solve(M, J.T)).tolist()

    def warnings(self) -> list[str]:
        """Reference mode: the explicit law's step bound at the run's peak Fn (native Coulomb contact has none)."""
        if not self.reference or self.cfg["reference_friction"] == "implicit":
            return []
        return law_step_warnings(self.name, self.physics.control_dt / self.n_sub, self._fn_peak, self._q_peak,
                                 self.physics.contact)  # fmt: skip

    # ------------------------------------------------------- declared abilities
    def integrator_family(self) -> str:
        """Bullet's multibody integration is semi-implicit Euler (velocity first, then position)."""
        return "euler"

    def sub_steps(self) -> int:
        return self.n_sub

    def kernels(self, q: np.ndarray, qd: np.ndarray, tau: np.ndarray) -> dict[str, Any]:
        """The engine-only floors, one call = one control period over the given torques [N m].

        From the first row's state (q [rad], qd [rad/s]), per row: ``bullet_substeps_tick``, one
        torque command (a list) and one ``stepSimulation`` with Bullet's own ``numSubSteps =
        n_sub``; ``python_substeps_tick``, ``n_sub`` x (command + ``stepSimulation``) at the
        sub-step. Nothing is read back during a pass. Each pass sets the engine's step parameters it needs and
        restores the backend's. Rows are a run's consecutive periods, so native contact retraces
        the run, and each floor's ``end_state()`` is then the run's last state, which the bench checks bit for bit
        (Bullet's own sub-stepping is offered only where it is bit-identical to the sub-steps, as the run uses
        it: with other step counts its accumulator drops steps and the floor would do less work); in reference
        mode the foot-ground pair is off and the law is not applied (Bullet's stepping alone: no end state to
        check, no target).
        """
        body, cid, joints, n = self.body, self.cid, self.joints, self.n_sub
        dt = self.physics.control_dt
        q0, qd0 = np.asarray(q[0], float).tolist(), np.asarray(qd[0], float).tolist()
        rows = np.asarray(tau, float).tolist()
        control, step, torque, setp = (
            p.setJointMotorControlArray,
            p.stepSimulation,
            p.TORQUE_CONTROL,
            p.setPhysicsEngineParameter,
        )
        own = {"fixedTimeStep": dt if self.engine_sub else dt / n, "numSubSteps": n if self.engine_sub else 1}

        def start(fixed: float, subs: int) -> None:
            setp(fixedTimeStep=fixed, numSubSteps=subs, physicsClientId=cid)
            for j, a, v in zip(joints, q0, qd0, strict=True):
                p.resetJointState(body, j, a, v, physicsClientId=cid)

        def bullet_substeps_tick() -> None:
            start(dt, n)
            for t in rows:
                control(body, joints, torque, forces=t, physicsClientId=cid)
                step(physicsClientId=cid)
            setp(physicsClientId=cid, **own)

        def python_substeps_tick() -> None:
            start(dt / n, 1)
            for t in rows:
                for _ in range(n):
                    control(body, joints, torque, forces=t, physicsClientId=cid)
                    step(physicsClientId=cid)
            setp(physicsClientId=cid, **own)

        out: dict[str, Any] = {"python_substeps_tick": python_substeps_tick}
        if self.engine_sub:
            out["bullet_substeps_tick"] = bullet_substeps_tick
        if not self.reference:

            def end_state() -> tuple[np.ndarray, np.ndarray]:
                self._read()  # the engine's joint states after the pass, as the backend reads them
                return self._q.copy(), self._qd.copy()

            for fn in out.values():
                fn.end_state = end_state
        return out

    def limits(self) -> Limits:
        """``getJointInfo`` limits (lower > upper means none) and effort, ``getPhysicsEngineParameters``."""
        cid = self.cid
        lower, upper, effort = [], [], []
        for j in self.joints:
            info = p.getJointInfo(self.body, j, physicsClientId=cid)
            lo, hi = float(info[8]), float(info[9])
            if lo > hi:  # Bullet's way of saying "no limit"
                lo, hi = -math.inf, math.inf
            lower.append(lo)
            upper.append(hi)
            effort.append(float(info[10]))
        params = p.getPhysicsEngineParameters(physicsClientId=cid)
        return Limits(
            gravity=-float(params["gravityAccelerationZ"]), lower=tuple(lower), upper=tuple(upper),  # type: ignore[arg-type]
            effort=tuple(effort),  # type: ignore[arg-type]
            timestep=float(params["fixedTimeStep"]) / max(int(params["numSubSteps"]), 1),
            enforcement="hard joint-limit constraint in the sequential-impulse solver",
        )  # fmt: skip

    def mass_properties(self) -> dict[str, dict[str, Any]]:
        """Per moving body: mass [kg], COM [m] and inertia about the COM [kg m^2] in the link frame.

        From ``getDynamicsInfo`` (principal inertia rotated by the local
        inertial orientation); link 3 includes the foot link, placed by the
        two links' world frames.
        """
        out = {}
        for name in LINK_NAMES:
            inr = self._inertial(self.links[name])
            if name == LINK_NAMES[-1]:
                R, pos = self._foot_pose()
                foot = self._inertial(self.foot)
                moved = Inertial(foot.mass, tuple(R @ foot.com + pos), tuple(map(tuple, R @ foot.I @ R.T)))  # type: ignore[arg-type]
                inr = combine([inr, moved])
            out[name] = {"mass": inr.mass, "com": list(inr.com), "inertia": inr.I.tolist()}
        return out

    def _inertial(self, link: int) -> Inertial:
        info = p.getDynamicsInfo(self.body, link, physicsClientId=self.cid)
        R = _quat_mat(info[4])
        I = R @ np.diag(info[2]) @ R.T
        return Inertial(float(info[0]), tuple(info[3]), tuple(map(tuple, I.tolist())))  # type: ignore[arg-type]

    def _foot_pose(self) -> tuple[np.ndarray, np.ndarray]:
        """Rotation and position of the foot frame in link 3's frame.

        Bullet gives a joint's parent frame relative to the parent's inertial
        (COM) frame; composing it with that frame keeps double precision
        (``getLinkState`` frames are single precision, ~1e-8 m).
        """
        info = p.getDynamicsInfo(self.body, self.links[LINK_NAMES[-1]], physicsClientId=self.cid)
        joint = p.getJointInfo(self.body, self.foot, physicsClientId=self.cid)
        R_com, p_com = _quat_mat(info[4]), np.array(info[3])
        return R_com @ _quat_mat(joint[15]), R_com @ np.array(joint[14]) + p_com

    def close(self) -> None:
        """Disconnect this backend's Bullet client."""
        if getattr(self, "cid", None) is not None and p.isConnected(self.cid):
            p.disconnect(self.cid)
        self.cid = None  # type: ignore[assignment]


def bullet_substeps_exact(period: float, n_sub: int) -> bool:
    """Whether one ``stepSimulation`` of ``period`` [s] with ``numSubSteps = n_sub`` takes exactly ``n_sub``
    internal steps every call: Bullet's accumulator (``btDiscreteDynamicsWorld::stepSimulation``, double
    precision as PyBullet builds it) takes ``int(t / (period / n_sub))`` steps of the time ``t`` it holds and
    keeps the rest; it holds exactly 0 after the first call only if the period rounds to ``n_sub`` steps with
    nothing left, and then every later call starts from 0 too."""
    step = period / n_sub
    held = 0.0 + period
    taken = int(held / step) if held >= step else 0
    return taken == n_sub and held - taken * step == 0.0


def _stiffness_damping(dynamics_info: Any) -> tuple[float, float]:
    """A body's contact stiffness [N/m] and damping [N s/m] from its ``getDynamicsInfo`` row: the values set by
    ``changeDynamics``, or Bullet's defaults where PyBullet reports -1 (unset)."""
    k, c = float(dynamics_info[9]), float(dynamics_info[8])
    if k < 0.0:
        return BULLET_DEFAULT_CONTACT_STIFFNESS, BULLET_DEFAULT_CONTACT_DAMPING
    return k, c


def _quat_mat(quat: Any) -> np.ndarray:
    """Rotation matrix of a Bullet quaternion (x, y, z, w)."""
    x, y, z, w = quat
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


__all__ = ["PybulletBackend"]
