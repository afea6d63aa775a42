"""ODE backend: the Open Dynamics Engine (the engine under Gazebo classic), bodies and hinges built from the URDF.

Model: ODE has no URDF loader, so ``models/leg.urdf`` is parsed with yourdfpy
and every number comes from it: one ODE body per moving link, placed at the
link's COM with the link frame's orientation (ODE needs the body origin at the
COM), mass and inertia about the COM from the link's ``<inertial>``; the foot
hangs on link 3 by a ``fixed`` joint, so its inertial is merged into link 3's
body (parallel-axis theorem), as the URDF says. The base is fixed: joint 1
attaches link 1 to the static world. Each revolute/continuous joint is an ODE
hinge at the URDF joint origin about the URDF axis; the hinge's zero is the
URDF's q = 0 (bodies are created at q = 0, then posed by :meth:`reset`). The
continuous hip has no stops; the ab/ad and knee stops are the URDF limits as
ODE joint stops (``dParamLoStop`` / ``dParamHiStop``) with ``stop_erp`` and
``stop_cfm`` (``matched``: ERP 0.2, CFM 0: a hard stop whose penetration is
corrected at 20 % per step; ODE's defaults are the world ERP and CFM, 0.2 and
1e-10 in double precision).

Actuation: the clamped torque tau is applied with ``dJointAddHingeTorque`` (tau
on the child, -tau on the parent) before every sub-step, so it is held over
the control period (ODE clears the accumulators after each step).

Native contact: one sphere geom (the URDF foot collision, radius R_foot) on
link 3's body at the foot centre E and a static plane z_W = 0; nothing else
collides (the link cylinders are not built). Contact joints are created for that
one pair (``dCollide`` every sub-step, what ``dSpaceCollide``'s near callback
would be handed) with the profile's surface: per-contact
``soft_erp = h Kp / (h Kp + Kd)`` and ``soft_cfm = 1 / (h Kp + Kd)`` (the ODE
manual's spring-damper mapping, the same as Gazebo's; h the ODE step), which
makes the normal force ``Kp y(t+h) + Kd ydot(t+h)``: an implicit spring-damper
that also damps while releasing and is clamped at zero, unlike the spec's law.
Friction is ODE's pyramid: ``dContactApprox1`` (bound mu times the normal
force) with ``mu = mu2 = mu_s`` (or mu_k: ``friction_coefficient``) along ODE's two tangent directions, so the
foot sticks (Coulomb) and the largest tangential force is between mu Fn and
sqrt(2) mu Fn depending on the direction. Without ``dContactApprox1`` ODE's
mu would be a force bound in newtons.

Ground force: ``dJointFeedback`` of the contact joints, which ODE fills during
a step. With several sub-steps per control period the backend reports the
**last sub-step's** force (the contact joints of earlier sub-steps are gone),
like the PyBullet backend: the force over the final sub-step, not an average.

Reference contact: no collision at all (``dCollide`` is not called); before
every sub-step ``J_poc^T F`` of :class:`~legbench.contact.ReferenceContact` at
the sub-step's start state (hinge angles and rates) is added to the hinge
torques.

Integrator: ``dWorldStep`` (direct Dantzig pivoting; with ``dContactApprox1`` the friction bounds
are set once from the frictionless normal impulse, so the pyramid is solved approximately: docs/backends/ode.md)
or ``dWorldQuickStep``
(projected Gauss-Seidel with SOR), both a first-order semi-implicit step in
maximal coordinates: body velocities v += h M^-1 (f + J^T lambda) with the
joint constraints solved at velocity level (with ERP position correction),
then positions x += h v. :meth:`integrator_family` is ``first-order``, see there.
Quick-step randomly reorders its constraint rows with ODE's one global random
generator (stock ODE 0.16 compiles the shuffle in). Setting ``row_order``:
``advancing`` (default) keeps each instance's generator state, seeded at reset, set
before each control period's steps and read back after them, so the permutations
advance from step to step as in ODE; ``repeated`` (the ``gazebo`` profile) re-seeds
before every step, so every step solves its rows in one fixed order, the nearest
stock ODE comes to Gazebo's fork, which does not reorder. Either way runs repeat bit
for bit and instances do not disturb each other.

Profiles: ``matched`` (the spec's physics: direct solver, rigid joints (CFM 0),
ERP 0.2, 0.05 ms sub-step), ``engine-defaults`` (ODE's documented defaults: quick step
with 20 iterations and SOR 1.3, one 1 ms step per control period), ``gazebo``
(Gazebo classic's ODE set-up; every value and its source line in
docs/backends/ode.md).
"""

from __future__ import annotations

import ctypes
import ctypes.util
import functools
import math
import subprocess
import threading
from collections.abc import Mapping
from importlib import metadata
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from legbench.backends.base import (
    FRICTION_COEFFICIENTS,
    Backend,
    Limits,
    Physics,
    Range,
    check_finite,
    clamp_torque,
    reference_contact,
    solver_bound_note,
    sub_step_count,
)
from legbench.contact import ReferenceContact
from legbench.exceptions import LegbenchError
from legbench.model import FOOT_FRAME, JOINT_NAMES, LINK_NAMES, Inertial, combine

INSTALL = "apt-get install -y libode8 && pip install ode-python"
try:
    import odepy as ode
except ImportError:
    raise
except Exception as exc:  # odepy raises its own OdePyError when libode is absent
    raise ImportError(f"the ODE shared library libode is missing: {exc}") from exc

#: Contacts ODE may generate for the foot-ground pair per step (sphere-plane gives one).
MAX_CONTACTS = 4
#: ODE's world defaults in double precision (ode/src/objects.cpp: dxWorld::dxWorld).
ODE_ERP, ODE_CFM = 0.2, 1e-10
#: Settings only ``dWorldQuickStep`` reads (left out of :meth:`OdeBackend.info` under ``dWorldStep``).
QUICK_ONLY = ("iterations", "sor", "row_order")
#: Settings only the contact joints read (native contact): none acts in reference contact.
CONTACT_ONLY = ("contact_max_correcting_vel", "contact_surface_layer", "surface_max_vel", "surface_min_depth",
                "ground_kp", "ground_kd", "friction_coefficient")  # fmt: skip
#: The seed of an instance's random generator at reset (quick-step row reordering), and before every step with
#: ``row_order: repeated``.
SEED = 0

_STEPPERS = ("world", "quick")
_TWO_PI = 2.0 * math.pi
_CONTACT_STRIDE = ctypes.sizeof(ode.dContact)
# bound once: odepy's own dJointAttach re-creates its ctypes function on every call
_attach = ode.loadOde("dJointAttach", None, ode.dJointID, ode.dBodyID, ode.dBodyID)
_collide, _geom_body = ode.dCollide, ode.dGeomGetBody
_create_contact, _set_feedback = ode.dJointCreateContact, ode.dJointSetFeedback
_set_seed, _get_seed = ode.dRandSetSeed, ode.dRandGetSeed


def friction_axes(normal: tuple[float, float, float] = (0.0, 0.0, 1.0)) -> list[list[float]]:
    """The two friction directions t1, t2 in W of a contact joint with ``normal`` and no ``dContactFDir1``, from
    ODE itself: ``dxJointContact::getInfo2`` takes ``dPlaneSpace(normal, t1, t2)`` (ode/src/joints/contact.cpp:
    218-226, ODE 0.16; dxPlaneSpace in ode/src/odemath.cpp:224-250), called here through the binding. For the
    ground's +z: t1 = -W y, t2 = W x. The foot's contact has that normal: the pair collides foot first
    (``_use_pair``), so dCollideSpherePlane's normal is the plane's +z (read back from a contact: (0, 0, 1)) and the
    joint, foot as body 1, is not reversed (contact.cpp:161-167)."""
    n, t1, t2 = (ode.dReal * 4)(*normal, 0.0), (ode.dReal * 4)(), (ode.dReal * 4)()
    ode.dPlaneSpace(n, t1, t2)
    return [[float(x) for x in t1[:3]], [float(x) for x in t2[:3]]]


class OdeBackend(Backend):
    """The Open Dynamics Engine (through the odepy ctypes binding) simulating the leg."""

    name: ClassVar[str] = "ode"
    #: ODE's contact friction here is the pyramid mu = mu2 = mu_s (or mu_k: ``friction_coefficient``;
    #: dContactApprox1 on: each bound is mu times
    #: the normal force): one coefficient, each of the two friction directions (-W y and W x for the ground's
    #: normal: dPlaneSpace, :func:`friction_axes`, info ``friction_axes``) limited on its own. dWorldStep's
    #: Dantzig LCP takes the normal force solved without friction for that bound (see :meth:`known_deviation`);
    #: dWorldQuickStep the current one.
    sliding_coefficient: ClassVar[str] = "mu_s"
    friction_cone: ClassVar[str] = "pyramid"
    install: ClassVar[str] = INSTALL
    defaults: ClassVar[Mapping[str, Any]] = {
        "dt": 5.0e-5,  # ODE step [s]: 1e-4 s leaves the swing at 0.0996 % of max q vs DOP853, 5e-5 s 0.050 %
        "stepper": "world",  # dWorldStep (Dantzig LCP, pivoting) or dWorldQuickStep (PGS + SOR)
        "iterations": 20,  # quick-step iterations (ODE's default)
        "sor": 1.3,  # quick-step over-relaxation (ODE's default)
        "erp": ODE_ERP,  # world error reduction parameter (joint drift correction)
        "cfm": 0.0,  # world constraint force mixing: rigid joints (ODE's 1e-10 softens G(q) by 5e-6 N m at 5e-5 s)
        "stop_erp": ODE_ERP,  # joint-stop ERP (ODE default: the world ERP)
        "stop_cfm": 0.0,  # joint-stop CFM: a hard stop (ODE default: the world CFM)
        "contact_max_correcting_vel": None,  # [m/s] world cap of the contact's ERP velocity; None: ODE's infinity
        "contact_surface_layer": 0.0,  # [m] world depth left uncorrected (ODE default 0)
        "surface_max_vel": None,  # [m/s] per-collision cap (Gazebo's ODE fork only); None: not used
        "surface_min_depth": None,  # [m] per-collision layer (Gazebo's ODE fork only); None: not used
        "ground_kp": None,  # [N/m] ground surface stiffness in series with Kp (Gazebo); None: rigid
        "ground_kd": 0.0,  # [N s/m] ground surface damping added to Kd (Gazebo)
        # world damping scale (ODE default 0): a body's linear (angular) velocity is scaled by 1 - damping after a
        # step only while its speed is above 0.01 m/s (0.01 rad/s), ODE's default thresholds (ode/src/objects.cpp
        # dxDampingParameters, ode/src/util.cpp dxStepBody)
        "damping": 0.0,
        "reference_friction": "implicit",  # reference mode: the law's friction slope implicit (as Pinocchio's)
        # quick step's row shuffle: ODE's generator carried on from step to step (stock ODE), or re-seeded before
        # every step (one fixed order per step, as near as stock ODE comes to Gazebo's fork, which does not reorder)
        "row_order": "advancing",
        "friction_coefficient": "mu_s",  # the pyramid's mu = mu2: mu_s (holds to mu_s Fn) or mu_k (slides at it)
    }
    choices: ClassVar[Mapping[str, tuple[str, ...]]] = {
        "stepper": _STEPPERS,
        "row_order": ("advancing", "repeated"),
        "reference_friction": ("implicit", "explicit"),
        "friction_coefficient": FRICTION_COEFFICIENTS,
    }
    #: The ranges the ODE manual gives: an ERP in [0, 1] (above 1 the correction overshoots and the joints
    #: diverge), a CFM >= 0 (0: a hard constraint), a damping scale in [0, 1], lengths, speeds and the ground's
    #: damping >= 0; ``ground_kp`` (a stiffness in series) > 0. ``None``: the setting off.
    ranges: ClassVar[Mapping[str, Range]] = {
        "erp": Range(0.0, 1.0),
        "stop_erp": Range(0.0, 1.0),
        "cfm": Range(),
        "stop_cfm": Range(),
        "damping": Range(0.0, 1.0),
        "contact_surface_layer": Range(),
        "ground_kd": Range(),
        "contact_max_correcting_vel": Range(nullable=True),
        "surface_max_vel": Range(nullable=True),
        "surface_min_depth": Range(nullable=True),
        "ground_kp": Range(open_low=True, nullable=True),
    }
    profiles: ClassVar[Mapping[str, Mapping[str, Any]]] = {
        "matched": {},
        # ODE's documented defaults (world ERP 0.2 and CFM 1e-10 in double precision, quick step 20
        # iterations, SOR 1.3), stepped once per 1 ms control period
        "engine-defaults": {"dt": 1.0e-3, "stepper": "quick", "cfm": ODE_CFM, "stop_cfm": ODE_CFM},
        # Gazebo classic's ODE set-up with SDFormat's defaults (docs/backends/ode.md: file and line of each)
        "gazebo": {
            "dt": 1.0e-3,  # <max_step_size> 0.001
            "stepper": "quick",  # <ode><solver><type> quick
            "iterations": 50,  # <iters> 50
            "sor": 1.3,  # <sor> 1.3
            "erp": 0.2,  # <constraints><erp> 0.2
            "cfm": 0.0,  # <constraints><cfm> 0
            "stop_erp": 0.2,  # <joint><physics><ode><limit><erp> 0.2
            "stop_cfm": 0.0,  # <joint><physics><ode><limit><cfm> 0
            "contact_max_correcting_vel": 100.0,  # <constraints><contact_max_correcting_vel> 100
            "contact_surface_layer": 0.001,  # <constraints><contact_surface_layer> 0.001: the world's, unused
            # the foot's <surface><contact><ode><max_vel>: left off, stock ODE cannot do what the fork does with it
            # (docs/backends/ode.md, "What stock ODE cannot reproduce")
            "surface_max_vel": None,
            # the foot's <min_depth>, SDFormat's default 0 (surface.sdf): ODELink::UpdateSurface gives every link
            # with a collision dBodySetMinDepth, and the fork's contact row then uses it instead of the world's
            # contact_surface_layer (deps/opende/src/joints/contact.cpp), so the foot's layer is 0
            "surface_min_depth": 0.0,
            "ground_kp": 1.0e12,  # ground plane's <surface><contact><ode><kp> default
            "ground_kd": 1.0,  # ground plane's <kd> default
            # ODEPhysics::Load sets dWorldSetDamping(0.0001, 0.0001), but ODELink::Init then sets every link's own
            # damping to its <velocity_decay> (Link::GetLinearDamping: 0 by default, link.sdf), which switches
            # ODE's damping off for that body (dBodySetLinearDamping / dBodySetAngularDamping with 0)
            "damping": 0.0,
            # the fork's quick step does not reorder its rows (deps/opende/src/quickstep.cpp: '// #define
            # RANDOMLY_REORDER_CONSTRAINTS 1'); stock ODE always does, so one fixed order per step is the nearest
            "row_order": "repeated",
        },
    }

    @classmethod
    def known_deviation(cls, case: str, quantity: str, info: Mapping[str, Any], measured: float = math.nan,
                        expected: float = math.nan, tolerance: float = math.nan) -> str | None:  # fmt: skip
        """dWorldStep's friction bound: its Dantzig LCP bounds friction by mu times the normal impulse solved without
        friction, so the sliding drag slides above mu Fn and accelerates less than the pyramid at mu; the row is
        explained where the pyramid's closed form with that bound, predicted by re-solving each sample without
        friction (:meth:`frictionless_normal`), meets it (:func:`~legbench.backends.base.solver_bound_note`).
        Nothing else: the quick step's pole misses at engine-defaults have no closed form of the fitted poles, so
        they stay plain misses."""
        if case == "sliding" and info.get("stepper") == "world":
            return solver_bound_note("dWorldStep's Dantzig LCP (lcp.cpp)", info.get("drag"), quantity, measured,
                                     tolerance, " (docs/backends/ode.md)")  # fmt: skip
        return None

    # ----------------------------------------------------------------- load
    def load(self, urdf: Path, physics: Physics, settings: Mapping[str, Any]) -> None:
        """Create the world, bodies, hinges and geoms from the URDF; set the profile's solver and contact.

        Args:
            urdf: the generated leg URDF.
            physics: gravity, contact law and mode, control period, torque limits.
            settings: overrides of :attr:`defaults` (see the class attributes).

        Raises:
            LegbenchError: an unknown stepper, or a ``dt`` that does not divide the control period.
        """
        cfg = self.settings(settings)
        if cfg["stepper"] not in _STEPPERS:
            raise LegbenchError(f"ode: unknown stepper '{cfg['stepper']}'; choose one of {list(_STEPPERS)}")
        n_sub = sub_step_count(self.name, cfg["dt"], physics.control_dt)
        self.cfg, self.physics, self.n_sub = cfg, physics, n_sub
        self.h = h = physics.control_dt / n_sub
        self.reference = physics.contact_mode == "reference"
        self.world = None
        _init_ode()

        self.world = world = ode.dWorldCreate()
        ode.dWorldSetGravity(world, 0.0, 0.0, -physics.gravity)
        ode.dWorldSetERP(world, float(cfg["erp"]))
        ode.dWorldSetCFM(world, float(cfg["cfm"]))
        ode.dWorldSetQuickStepNumIterations(world, int(cfg["iterations"]))
        ode.dWorldSetQuickStepW(world, float(cfg["sor"]))
        ode.dWorldSetDamping(world, float(cfg["damping"]), float(cfg["damping"]))
        ode.dWorldSetAutoDisableFlag(world, 0)
        max_vel, layer = _effective_correction(cfg)
        if max_vel is not None:
            ode.dWorldSetContactMaxCorrectingVel(world, max_vel)
        ode.dWorldSetContactSurfaceLayer(world, layer)
        self._world_step = ode.dWorldStep if cfg["stepper"] == "world" else ode.dWorldQuickStep
        self._quick = cfg["stepper"] == "quick"

        self._build(urdf, physics, cfg)

        # contact surface: Kp (in series with the ground's, Gazebo) and Kd (plus the ground's) as ERP/CFM
        c = physics.contact
        kp = c.Kp if cfg["ground_kp"] is None or c.Kp <= 0 else 1.0 / (1.0 / c.Kp + 1.0 / float(cfg["ground_kp"]))
        kd = c.Kd + float(cfg["ground_kd"])
        self.kp, self.kd = kp, kd
        # a contact with neither stiffness nor damping exerts no force: no contact joints at all
        self._collide_on = not self.reference and h * kp + kd > 0
        self.soft_erp, self.soft_cfm = kp_kd_to_erp_cfm(h, kp, kd) if h * kp + kd > 0 else (0.0, math.inf)
        self.space = ode.dSimpleSpaceCreate(0)
        self.plane = ode.dCreatePlane(self.space, 0.0, 0.0, 1.0, 0.0)
        self.foot_geom = ode.dCreateSphere(self.space, self.R_foot)
        ode.dGeomSetBody(self.foot_geom, self.bodies[-1])
        ode.dGeomSetOffsetWorldPosition(self.foot_geom, *self._foot0)
        self.contact_group = ode.dJointGroupCreate(0)
        self.contacts = (ode.dContact * MAX_CONTACTS)()
        for ct in self.contacts:
            s = ct.surface
            # dContactMu2: ODE reads mu2 only with it (as Gazebo sets it); mu2 = mu, so either gives the same pyramid
            s.mode = ode.dContactSoftERP | ode.dContactSoftCFM | ode.dContactApprox1 | ode.dContactMu2
            s.mu = s.mu2 = float(getattr(c, cfg["friction_coefficient"]))
            s.soft_erp, s.soft_cfm = self.soft_erp, self.soft_cfm
            s.bounce, s.bounce_vel = 0.0, 0.0
        self._contact_geoms = ctypes.cast(
            ctypes.addressof(self.contacts) + ode.dContact.geom.offset, ctypes.POINTER(ode.dContactGeom)
        )
        self._feedback = (ode.dJointFeedback * MAX_CONTACTS)()
        self._contact_refs = [ctypes.byref(ct) for ct in self.contacts]
        self._feedback_refs = [ctypes.byref(fb) for fb in self._feedback]
        self._n_contacts = 0
        self._foot_body = _address(self.bodies[-1])
        self._contact_joints: list[Any] = [None] * MAX_CONTACTS
        # the space's one pair, foot sphere and ground plane, collided directly (dCollide) in the order
        # dSpaceCollide hands a simple space's pair to its near callback: its geoms from the newest
        # (ode/src/collision_space.cpp: dxSpace::add puts a geom first, dxSimpleSpace::collide pairs each
        # with those after it); no per-sub-step callback from C into Python
        n_geoms = ode.dSpaceGetNumGeoms(self.space)
        pair = tuple(ode.dSpaceGetGeom(self.space, i) for i in range(n_geoms))
        if n_geoms != 2 or {_address(g) for g in pair} != {_address(self.plane), _address(self.foot_geom)}:
            raise LegbenchError(
                "ode: the collision space must hold exactly the foot sphere and the ground plane "
                f"(the native step collides that one pair), it holds {n_geoms} geoms"
            )
        self._use_pair(*pair)

        self._implicit = self.reference and cfg["reference_friction"] == "implicit"
        self.contact = ReferenceContact.from_leg(c, physics.gravity if self._implicit else None)
        self._hi = np.asarray(physics.torque_limit, float)
        self._limit = tuple(float(x) for x in physics.torque_limit)  # [N m]
        self._u = (0.0, 0.0, 0.0)  # the clamped torque of the period [N m]
        self._force = np.zeros(3)
        self._q = np.zeros(3)
        self._qd = np.zeros(3)
        self._step = self._step_reference if self.reference else self._step_native
        self._rng = SEED  # ODE's random generator state of this instance (quick step's row reordering)
        # the quick step's row order (row_order): this instance's generator carried over the periods, or re-seeded
        # before every step
        self._advancing = self._quick and cfg["row_order"] == "advancing"
        self._repeated = self._quick and cfg["row_order"] == "repeated"
        self.t = 0.0

    def _build(self, urdf: Path, physics: Physics, cfg: Mapping[str, Any]) -> None:
        """Bodies at q = 0 (origin at the COM, axes of the link frame), hinges with the URDF's axes and stops."""
        import yourdfpy

        robot = yourdfpy.URDF.load(
            str(urdf), build_scene_graph=False, load_meshes=False,
            build_collision_scene_graph=False, load_collision_meshes=False,
        )  # fmt: skip
        joints = {j.child: j for j in robot.robot.joints}
        links = robot.link_map
        foot_joint = joints[FOOT_FRAME]
        if foot_joint.type != "fixed" or foot_joint.parent != LINK_NAMES[-1]:
            raise LegbenchError(f"ode: expected the foot fixed to {LINK_NAMES[-1]} in {urdf}")
        T_foot = np.asarray(foot_joint.origin, float)  # foot frame in link 3's frame
        sphere = links[FOOT_FRAME].collisions[0]
        self.R_foot = float(sphere.geometry.sphere.radius)

        self.bodies: list[Any] = []
        self.joints: list[Any] = []
        self._T0: list[np.ndarray] = []  # link frames in W at q = 0
        self._axis_local: list[np.ndarray] = []  # joint axes in the link (child) frame
        self._com_local: list[np.ndarray] = []
        T_parent = np.eye(4)  # the fixed base frame is W
        parent_body = None
        for i, (link, jname) in enumerate(zip(LINK_NAMES, JOINT_NAMES, strict=True)):
            joint = joints[link]
            if joint.name != jname:
                raise LegbenchError(f"ode: joint of {link} is {joint.name} in {urdf}, expected {jname}")
            T = T_parent @ np.asarray(joint.origin, float)
            inertial = _link_inertial(links[link])
            if i == len(LINK_NAMES) - 1:  # merge the fixed foot, moved into link 3's frame
                foot = _link_inertial(links[FOOT_FRAME])
                R, p = T_foot[:3, :3], T_foot[:3, 3]
                moved = Inertial(foot.mass, tuple(R @ foot.com + p), tuple(map(tuple, R @ foot.I @ R.T)))
                inertial = combine([inertial, moved])
            body = ode.dBodyCreate(self.world)
            mass = ode.dMass()
            I = inertial.I
            ode.dMassSetParameters(
                ctypes.byref(mass), inertial.mass, 0.0, 0.0, 0.0,
                I[0, 0], I[1, 1], I[2, 2], I[0, 1], I[0, 2], I[1, 2],
            )  # fmt: skip
            ode.dBodySetMass(body, ctypes.byref(mass))
            com = np.asarray(inertial.com, float)
            pos = T[:3, :3] @ com + T[:3, 3]
            ode.dBodySetPosition(body, *pos)
            ode.dBodySetRotation(body, _dmatrix3(T[:3, :3]))

            hinge = ode.dJointCreateHinge(self.world, None)
            ode.dJointAttach(hinge, body, parent_body)  # angle: child relative to parent
            axis_local = np.asarray(joint.axis, float)
            axis_w = T[:3, :3] @ axis_local
            ode.dJointSetHingeAnchor(hinge, *T[:3, 3])
            ode.dJointSetHingeAxis(hinge, *axis_w)
            if joint.type == "revolute" and joint.limit is not None:
                ode.dJointSetHingeParam(hinge, ode.dParamLoStop, float(joint.limit.lower))
                ode.dJointSetHingeParam(hinge, ode.dParamHiStop, float(joint.limit.upper))
            ode.dJointSetHingeParam(hinge, ode.dParamStopERP, float(cfg["stop_erp"]))
            ode.dJointSetHingeParam(hinge, ode.dParamStopCFM, float(cfg["stop_cfm"]))
            ode.dJointSetHingeParam(hinge, ode.dParamFMax, 0.0)  # no joint motor

            self.bodies.append(body)
            self.joints.append(hinge)
            self._T0.append(T)
            self._axis_local.append(axis_local)
            self._com_local.append(com)
            T_parent, parent_body = T, body
        self._joint_origins = [np.asarray(joints[link].origin, float) for link in LINK_NAMES]
        T3 = self._T0[-1]
        self._foot0 = tuple(T3[:3, :3] @ T_foot[:3, 3] + T3[:3, 3])

    # ---------------------------------------------------------------- reset
    def reset(self, q: np.ndarray, qd: np.ndarray) -> None:
        """Pose every body for q [rad] with the velocities of qd [rad/s]; contacts and accumulators cleared."""
        omega = np.zeros(3)
        v_origin = np.zeros(3)  # velocity of the current link's frame origin in W
        T_parent = np.eye(4)
        o_parent = np.zeros(3)
        for i, body in enumerate(self.bodies):
            J = self._joint_origins[i]
            T = T_parent @ J
            o = T[:3, 3]
            v_origin = v_origin + np.cross(omega, o - o_parent)  # the joint point moves with the parent
            axis_w = T[:3, :3] @ self._axis_local[i]
            T = T.copy()
            T[:3, :3] = T[:3, :3] @ _axis_angle(self._axis_local[i], float(q[i]))
            omega = omega + axis_w * float(qd[i])
            com_w = T[:3, :3] @ self._com_local[i] + o
            v_com = v_origin + np.cross(omega, com_w - o)
            ode.dBodySetPosition(body, *com_w)
            ode.dBodySetRotation(body, _dmatrix3(T[:3, :3]))
            ode.dBodySetLinearVel(body, *v_com)
            ode.dBodySetAngularVel(body, *omega)
            ode.dBodySetForce(body, 0.0, 0.0, 0.0)
            ode.dBodySetTorque(body, 0.0, 0.0, 0.0)
            T_parent, o_parent = T, o
        ode.dJointGroupEmpty(self.contact_group)
        self._n_contacts = 0
        self._rng = SEED  # the row-reordering generator starts afresh: a reset run repeats bit for bit
        self._q[:] = q  # the unwrapping reference for the hip
        self._read()
        self.t = 0.0
        if self.reference:
            self._reference_force()
        else:
            self._force[:] = 0.0

    # ----------------------------------------------------------------- step
    def step(self, tau: np.ndarray) -> None:
        """Advance one control period with tau [N m], clamped to the torque limits, held over the sub-steps."""
        self._u = clamp_torque(tau, self._limit)
        self._step()
        self.t += self.physics.control_dt
        check_finite(self.name, self.t, self._q, self._qd)

    def _step_native(self) -> None:
        world, h, joints = self.world, self.h, self.joints
        add, step = ode.dJointAddHingeTorque, self._world_step
        group, empty = self.contact_group, ode.dJointGroupEmpty
        g1, g2 = self._pair
        contact_geoms, contacts = self._contact_geoms, self._add_contacts
        t0, t1, t2 = self._u
        j0, j1, j2 = joints
        collide_on = self._collide_on
        n = 0
        advancing, repeated, seed, get_seed = self._advancing, self._repeated, _set_seed, _get_seed
        if advancing:  # this instance's generator, where its last period left it
            seed(self._rng)
        for _ in range(self.n_sub):
            empty(group)
            if collide_on:
                # what dSpaceCollide's near callback did, called here (dCollide updates the geoms' poses itself;
                # the space's bounding-box test it skips only ever spared a dCollide that finds no contact)
                n = _collide(g1, g2, MAX_CONTACTS, contact_geoms, _CONTACT_STRIDE)
                if n:
                    contacts(n)
            add(j0, t0)
            add(j1, t1)
            add(j2, t2)
            if repeated:
                seed(SEED)
            step(world, h)
        if advancing:
            self._rng = get_seed()
        self._n_contacts = n
        self._read()
        self._native_force()

    def frictionless_normal(self, q: np.ndarray, qd: np.ndarray, tau: np.ndarray) -> float | None:
        """dWorldStep's friction bound: its Dantzig LCP (lcp.cpp) bounds the friction rows by mu times the normal
        impulse solved before them (the first row's exactly; a later row's after the rows before it are in), so the
        normal force of one sub-step from (q, qd) under tau with mu =
        mu2 = 0 [N], mu times which was the bound; None for the quick step (it bounds by the current normal force),
        in reference contact or without a contact. Resets the engine to (q, qd) and steps it once."""
        if self.reference or self._quick or not self._collide_on:
            return None
        kept, n_sub = [(ct.surface.mu, ct.surface.mu2) for ct in self.contacts], self.n_sub
        try:
            for ct in self.contacts:
                ct.surface.mu = ct.surface.mu2 = 0.0
            self.reset(q, qd)
            self._u = clamp_torque(tau, self._limit)
            self.n_sub = 1
            self._step_native()
            return float(self._force[2])
        finally:
            self.n_sub = n_sub
            for ct, (mu, mu2) in zip(self.contacts, kept, strict=True):
                ct.surface.mu, ct.surface.mu2 = mu, mu2

    def _use_pair(self, g1: Any, g2: Any) -> None:
        """Collide the geoms in this order in the native step; their bodies and the foot's feedback side cached
        (neither geom changes body after load)."""
        b1, b2 = _geom_body(g1), _geom_body(g2)
        self._pair, self._pair_bodies = (g1, g2), (b1, b2)
        # which feedback side is the foot's: dJointAttach moves a null (static) body to the joint's second place
        # (ode/src/ode.cpp), and ODE writes f1 for the first body, f2 only for a second one (ode/src/step.cpp,
        # quickstep.cpp); so the foot is f1 unless two bodies collide and the foot is the second
        self._foot_first = not (b1 and b2) or _address(b1) == self._foot_body

    def _add_contacts(self, n: int) -> None:
        """Contact joints with the profile's surface for the pair's ``n`` contacts (in ``_contact_geoms``)."""
        b1, b2 = self._pair_bodies
        world, group, contacts, feedback = self.world, self.contact_group, self._contact_refs, self._feedback_refs
        for k in range(n):
            joint = _create_contact(world, group, contacts[k])
            _attach(joint, b1, b2)
            _set_feedback(joint, feedback[k])
            self._contact_joints[k] = joint

    def _step_reference(self) -> None:
        world, h, joints = self.world, self.h, self.joints
        add, step = ode.dJointAddHingeTorque, self._world_step
        angle, rate = ode.dJointGetHingeAngle, ode.dJointGetHingeAngleRate
        law, law_i, implicit = self.contact.generalized, self.contact.implicit_generalized, self._implicit
        j0, j1, j2 = joints
        u1, u2, u3 = self._u
        advancing, repeated, seed, get_seed = self._advancing, self._repeated, _set_seed, _get_seed
        if advancing:  # this instance's generator, where its last period left it
            seed(self._rng)
        for _ in range(self.n_sub):
            q1, q2, q3, qd1, qd2, qd3 = angle(j0), angle(j1), angle(j2), rate(j0), rate(j1), rate(j2)
            if implicit:  # the friction slope linearly implicit over the sub-step (docs/pinocchio.md)
                t1, t2, t3 = law_i(q1, q2, q3, qd1, qd2, qd3, u1, u2, u3, h).tolist()
            else:
                t1, t2, t3 = law(q1, q2, q3, qd1, qd2, qd3).tolist()
            add(j0, u1 + t1)
            add(j1, u2 + t2)
            add(j2, u3 + t3)
            if repeated:
                seed(SEED)
            step(world, h)
        if advancing:
            self._rng = get_seed()
        self._read()
        self._reference_force()

    def _read(self) -> None:
        """Hinge angles (unwrapped against the previous reading) and rates."""
        angle, rate = ode.dJointGetHingeAngle, ode.dJointGetHingeAngleRate
        q, qd = self._q, self._qd
        for i, j in enumerate(self.joints):
            prev = float(q[i])
            d = angle(j) - prev
            if d > math.pi or d < -math.pi:  # the hinge angle wrapped at +-pi
                d -= _TWO_PI * round(d / _TWO_PI)
            q[i] = prev + d
            qd[i] = rate(j)

    def _reference_force(self) -> None:
        q, qd = self._q, self._qd
        self.contact.generalized(q[0], q[1], q[2], qd[0], qd[1], qd[2])
        self._force[:] = self.contact.force

    def _native_force(self) -> None:
        """Sum of the contact joints' feedback forces on the foot over the last sub-step, in W."""
        force = self._force
        force[:] = 0.0
        foot_first = self._foot_first
        for k in range(self._n_contacts):
            fb = self._feedback[k]
            f = fb.f1 if foot_first else fb.f2
            force[0] += f[0]
            force[1] += f[1]
            force[2] += f[2]

    # ----------------------------------------------------------------- read
    def state(self) -> tuple[np.ndarray, np.ndarray]:
        """Hinge angles q [rad] (hip unwrapped) and rates qd [rad/s]."""
        return self._q.copy(), self._qd.copy()

    def ground_force(self) -> np.ndarray:
        """Force of the ground on the foot in W [N].

        Native: ``dJointFeedback`` of the contact joints of the last sub-step
        (the constraint force over that step, not an average over the control
        period). Reference: the law at the current state.
        """
        return self._force.copy()

    def read(self) -> tuple[float, ...]:
        """:meth:`state` and :meth:`ground_force` as nine floats, without the copies."""
        return (*self._q.tolist(), *self._qd.tolist(), *self._force.tolist())

    def contact_bodies(self) -> list[tuple[str | None, str | None]]:
        """Link names of the two bodies (None: the static world) of each contact joint of the last sub-step."""
        names = {_address(b): name for name, b in zip(LINK_NAMES, self.bodies, strict=True)}
        return [
            (names.get(_address(ode.dJointGetBody(j, 0))), names.get(_address(ode.dJointGetBody(j, 1))))
            for j in self._contact_joints[: self._n_contacts]
        ]

    def info(self) -> dict[str, Any]:
        """Engine, version and every physics setting actually used, read back from ODE where it allows."""
        world = self.world
        max_vel = float(ode.dWorldGetContactMaxCorrectingVel(world))
        return {
            "engine": "ode",
            "version": _ode_version(),
            "binding": f"ode-python {metadata.version('ode-python')}",
            # the settings this load reads (the report's settings table lists what acted: _unused_settings)
            **{k: self.cfg[k] for k in self.defaults if k not in self._unused_settings()},
            "integrator": f"ODE {'dWorldStep' if not self._quick else 'dWorldQuickStep'} (semi-implicit, first order)",
            "integrator_family": self.integrator_family(),
            "sub_steps": self.n_sub,
            "timestep": self.h,
            "gravity": self.physics.gravity,
            "world": {
                "erp": float(ode.dWorldGetERP(world)),
                "cfm": float(ode.dWorldGetCFM(world)),
                "quick_step_iterations": int(ode.dWorldGetQuickStepNumIterations(world)),
                "quick_step_sor": float(ode.dWorldGetQuickStepW(world)),
                "contact_max_correcting_vel": max_vel if math.isfinite(max_vel) else None,
                "contact_surface_layer": float(ode.dWorldGetContactSurfaceLayer(world)),
                "linear_damping": float(ode.dWorldGetLinearDamping(world)),
                "angular_damping": float(ode.dWorldGetAngularDamping(world)),
            },
            **({"friction_axes": friction_axes()} if self._collide_on else {}),
            "contact_mode": self.physics.contact_mode,
            "contact": reference_contact(
                self.physics.contact,
                "J_poc^T F added to the hinge torques per sub-step",
                self.cfg["reference_friction"],
            )
            if self.reference
            else {
                "enabled": self._collide_on,
                # dCollideSpherePlane puts the contact at the sphere's lowest point (centre - R n)
                "poc": "true",
                "lift": 0.0,
                "Kp": self.physics.contact.Kp,
                "Kd": self.physics.contact.Kd,
                "kp_effective": self.kp,
                "kd_effective": self.kd,
                "soft_erp": self.soft_erp,
                "soft_cfm": self.soft_cfm if math.isfinite(self.soft_cfm) else None,
                "mu": self.contacts[0].surface.mu,
                "mu2": self.contacts[0].surface.mu2,
                "friction": "pyramid (dContactApprox1: bound mu x normal force per tangent direction)",
                "force_reported": "dJointFeedback of the last sub-step",
            },
        }

    def _unused_settings(self) -> set[str]:
        """Settings this load does not read, left out of :meth:`info` so the report's settings table lists only
        what acted: the quick step's own under dWorldStep, ``reference_friction`` in native contact, and in
        reference contact (no contact joints) the contact joints' settings."""
        unused = set() if self._quick else set(QUICK_ONLY)
        if self.reference:
            unused |= set(CONTACT_ONLY)
        else:
            unused.add("reference_friction")
        return unused

    # ------------------------------------------------------- declared abilities
    def integrator_family(self) -> str:
        """``first-order``: ODE's step is semi-implicit and first order, but in maximal coordinates.

        Body velocities are updated with the constraint forces solved at
        velocity level (plus ERP drift correction, CFM regularisation and ODE
        0.16's implicit gyroscopic torque: ode/src/step.cpp and quickstep.cpp,
        Lacoursiere 2006, the explicit one under ``#if 0``; on for every body,
        dBodyCreate sets dxBodyGyroscopic), then body positions and
        orientations are advanced with the new velocities. Projected to joint space this is not
        the scheme qd += h qdd(q, qd), q += h qd that verification's ``euler``
        prediction models: its trajectory is close (1.4e-7 rad in the reference
        contact test at 5e-5 s) but its energy is not (verification's energy case
        at 5e-5 s: -2.4e-4 J measured, +3.1e-4 J predicted for Euler), so no
        closed-form prediction applies; verification bounds it as a first-order step.
        """
        return "first-order"

    def sub_steps(self) -> int:
        return self.n_sub

    def limits(self) -> Limits:
        """Hinge stops (``dJointGetHingeParam``, +-dInfinity: none), gravity (``dWorldGetGravity``), torque clamp.

        ODE itself holds no torque limit; ``effort`` is the clamp this backend
        applies to every torque before handing it to ODE.
        """
        lower, upper = [], []
        for j in self.joints:
            lower.append(float(ode.dJointGetHingeParam(j, ode.dParamLoStop)))
            upper.append(float(ode.dJointGetHingeParam(j, ode.dParamHiStop)))
        g = ode.dVector3()
        ode.dWorldGetGravity(self.world, g)
        erp = float(ode.dJointGetHingeParam(self.joints[-1], ode.dParamStopERP))
        cfm = float(ode.dJointGetHingeParam(self.joints[-1], ode.dParamStopCFM))
        return Limits(
            gravity=-float(g[2]), lower=tuple(lower), upper=tuple(upper),  # type: ignore[arg-type]
            effort=tuple(float(x) for x in self._hi),  # type: ignore[arg-type]
            timestep=self.h,
            enforcement=(f"ODE joint stops: one-sided velocity-level constraint, stop ERP {erp:g} "
                         f"(penetration corrected by that fraction per step), stop CFM {cfm:g}; torques "
                         f"clamped by the backend before dJointAddHingeTorque (ODE has no torque limit)"),
        )  # fmt: skip

    def mass_properties(self) -> dict[str, dict[str, Any]]:
        """Per moving body: mass [kg], COM [m] and inertia about the COM [kg m^2] in the link frame.

        Read back from ODE: ``dBodyGetMass`` (inertia in body axes), the body's
        position and rotation, and the hinge anchor (the link frame's origin,
        the URDF joint origin). The body axes are the link frame's axes, so
        com = R^T (p_body - anchor) and the inertia is ODE's as it stands.
        Link 3 includes the foot (one ODE body).
        """
        out = {}
        mass = ode.dMass()
        anchor = ode.dVector3()
        for name, body, joint in zip(LINK_NAMES, self.bodies, self.joints, strict=True):
            ode.dBodyGetMass(body, ctypes.byref(mass))
            ode.dJointGetHingeAnchor(joint, anchor)
            R = _read_rotation(ode.dBodyGetRotation(body))
            p = np.ctypeslib.as_array(ode.dBodyGetPosition(body), shape=(3,)).copy()
            c_body = np.array([mass.c[0], mass.c[1], mass.c[2]])
            com = R.T @ (p - np.array([anchor[0], anchor[1], anchor[2]])) + c_body
            I = np.array([[mass.I[4 * r + k] for k in range(3)] for r in range(3)])
            out[name] = {"mass": float(mass.mass), "com": com.tolist(), "inertia": I.tolist()}
        return out

    def close(self) -> None:
        """Destroy this backend's ODE world, space and contact group."""
        if getattr(self, "world", None) is None:
            return
        if getattr(self, "contact_group", None) is not None:
            ode.dJointGroupDestroy(self.contact_group)
            self.contact_group = None
        if getattr(self, "space", None) is not None:
            ode.dGeomDestroy(self.foot_geom)
            ode.dGeomDestroy(self.plane)
            ode.dSpaceDestroy(self.space)
            self.space = None
        ode.dWorldDestroy(self.world)
        self.world = None


# --------------------------------------------------------------------------- #
# helpers


def kp_kd_to_erp_cfm(h: float, kp: float, kd: float) -> tuple[float, float]:
    """ODE's (ERP, CFM) of a spring-damper (kp [N/m], kd [N s/m]) at step h [s].

    erp = h kp / (h kp + kd), cfm = 1 / (h kp + kd): the ODE manual's mapping
    and Gazebo classic's (ODEPhysics::Collide), which makes the constraint
    force kp y(t+h) + kd ydot(t+h).
    """
    return h * kp / (h * kp + kd), 1.0 / (h * kp + kd)


def _effective_correction(cfg: Mapping[str, Any]) -> tuple[float | None, float]:
    """World max correcting velocity [m/s] (None: ODE's infinity) and surface layer [m] to set in stock ODE.

    Gazebo's ODE fork gives each body the collision's ``max_vel`` and
    ``min_depth``: a contact with such a body uses min(body max_vel, world
    contact_max_correcting_vel) and the body's min_depth instead of the world's
    contact_surface_layer (deps/opende/src/joints/contact.cpp). Stock ODE has
    only the world values, so those are set to the effective ones when a
    per-collision value is given. The layer is then exact. The cap is not:
    stock ODE clamps the contact row's push-out itself (ode/src/joints/contact.cpp),
    so a binding cap slows the position correction too, while the fork's quick
    step keeps the cap in ``c_v_max`` and solves twice, the capped problem for
    the velocities it keeps and for dJointFeedback, the uncapped one for the
    position update (deps/opende/src/quickstep.cpp: rhs, rhs_erp). Both agree
    while the push-out stays below the cap.
    """
    max_vel = cfg["contact_max_correcting_vel"]
    layer = float(cfg["contact_surface_layer"])
    if cfg["surface_max_vel"] is not None:
        surf = float(cfg["surface_max_vel"])
        max_vel = surf if max_vel is None else min(surf, float(max_vel))
    if cfg["surface_min_depth"] is not None:
        layer = float(cfg["surface_min_depth"])
    return (None if max_vel is None else float(max_vel)), layer


def _link_inertial(link: Any) -> Inertial:
    """A URDF link's inertial in its link frame (inertia rotated by the inertial origin's rotation)."""
    inr = link.inertial
    T = np.asarray(inr.origin, float) if inr.origin is not None else np.eye(4)
    R = T[:3, :3]
    I = R @ np.asarray(inr.inertia, float) @ R.T
    return Inertial(float(inr.mass), tuple(T[:3, 3].tolist()), tuple(map(tuple, I.tolist())))


def _axis_angle(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rotation matrix of ``angle`` [rad] about the unit ``axis`` (Rodrigues)."""
    x, y, z = axis / np.linalg.norm(axis)
    c, s = math.cos(angle), math.sin(angle)
    C = 1.0 - c
    return np.array(
        [
            [c + x * x * C, x * y * C - z * s, x * z * C + y * s],
            [y * x * C + z * s, c + y * y * C, y * z * C - x * s],
            [z * x * C - y * s, z * y * C + x * s, c + z * z * C],
        ]
    )


def _dmatrix3(R: np.ndarray) -> Any:
    """ODE's dMatrix3 (3 rows of 4, the 4th unused) of a rotation matrix."""
    m = ode.dMatrix3()
    for r in range(3):
        for k in range(3):
            m[4 * r + k] = float(R[r, k])
    return m


def _address(handle: Any) -> int | None:
    """The address an ODE handle (a ctypes pointer) points at, None for a null handle."""
    return ctypes.cast(handle, ctypes.c_void_p).value


def _read_rotation(ptr: Any) -> np.ndarray:
    """A rotation matrix from ODE's dMatrix3 pointer."""
    return np.array([[ptr[4 * r + k] for k in range(3)] for r in range(3)])


_THREAD = threading.local()


def _init_ode() -> None:
    """dInitODE2 (idempotent) and ODE's per-thread collision data, once per thread."""
    if not getattr(_THREAD, "ready", False):
        ode.dInitODE2(0)
        ode.dAllocateODEDataForThread(0xFFFFFFFF)  # dAllocateMaskAll
        _THREAD.ready = True


@functools.cache
def _ode_version() -> str:
    """ODE's release, the library file loaded and its configuration string (precision etc.). libode names no
    version of its own (its soname, libode.so.8, spans releases), so the release is the one of the system package
    that owns the loaded file, where the package manager knows it: "0.16.2 (Debian libode8 2:0.16.2-1;
    /usr/lib/.../libode.so.8.0.2; ODE ... ODE_double_precision)"."""
    config = (ctypes.cast(ode.dGetConfiguration(), ctypes.c_char_p).value or b"").decode()
    path = _loaded_library()
    release, package = _package_release(path) or ("release unknown", "no package owns it")
    return f"{release} ({package}; {path or ctypes.util.find_library('ode')}; {config})"


def _loaded_library() -> str | None:
    """The path of the libode file this process loaded (Linux: /proc/self/maps), or None where it cannot be read."""
    try:
        with open("/proc/self/maps", encoding="utf-8") as maps:
            paths = {line.split()[-1] for line in maps if "/libode.so" in line}
    except OSError:
        return None
    return min(paths) if paths else None


def _package_release(path: str | None) -> tuple[str, str] | None:
    """The upstream release of the Debian package owning ``path`` and the package as dpkg names it ("0.16.2",
    "Debian libode8 2:0.16.2-1"), or None without dpkg or an owner (a library built from source)."""
    if path is None:
        return None
    try:
        owner = subprocess.run(["dpkg-query", "-S", path], capture_output=True, text=True, timeout=30, check=True)
        package = owner.stdout.split(": ", 1)[0].split(":", 1)[0].strip()
        shown = subprocess.run(["dpkg-query", "-W", "-f=${Version}", package], capture_output=True, text=True,
                               timeout=30, check=True).stdout.strip()  # fmt: skip
    except (OSError, subprocess.SubprocessError):
        return None
    if not package or not shown:
        return None
    release = shown.split(":", 1)[-1].rsplit("-", 1)[0]  # the epoch and the Debian revision dropped
    return release, f"Debian {package} {shown}"


__all__ = ["OdeBackend", "kp_kd_to_erp_cfm"]
