"""Drake backend: pydrake ``MultibodyPlant`` from the generated URDF, compliant point (or hydroelastic) contact.

Model: ``models/leg.urdf`` through ``Parser``, the URDF's root link ``base``
welded to the world, one ``JointActuator`` per joint (effort limit = the
torque limit) and a ``HalfSpace`` ground at z_W = 0 on the world body. Only
the foot sphere meets the ground: every other leg geometry is filtered out
(``CollisionFilterDeclaration``). Torques enter through the actuation input
port, fixed once per control period (zero-order hold).

Solvers (setting ``solver``): the discrete plant (``time_step = dt``) with
Drake's discrete contact approximations ``sap`` (convex, linear Kelvin-Voigt
normal force), ``tamsi`` (Hunt-Crossley, regularised friction), ``lagged`` and
``similar`` (Hunt-Crossley inside SAP's convex solver; ``lagged`` is Drake's
default), or ``continuous``: ``time_step = 0`` and Drake's error-controlled
``runge_kutta3`` integrator run by a ``Simulator`` to the end of each control
period (``accuracy``), with Hunt-Crossley contact and Stribeck friction.

Native point contact, mapped onto Drake's per-geometry ``ProximityProperties``
(group ``material``). Drake combines two geometries' stiffnesses in series (an
infinite one leaves the other), their Hunt-Crossley dissipations weighted by
the other's stiffness (an infinitely stiff partner leaves the compliant one's),
their relaxation times by sum, and their friction by
mu = 2 mu_A mu_B / (mu_A + mu_B); the discrete plant puts the contact point
between the two witness points, weighted by stiffness. An infinitely stiff
geometry makes that weight inf/inf (the discrete solvers then fail: NaN, or
TAMSI not converging), so the foot is near-rigid
(``point_contact_stiffness = 1e8 Kp``, relaxation time 0) and the ground
carries the spec's numbers: the pair's stiffness is exactly Kp and, in the
discrete solvers, the contact point is the sphere's lowest point (the spec's
true poc) to 1e-8 of the penetration. The ``continuous`` plant takes the
plain midpoint of the witness points instead (multibody_plant.cc), y/2 above
the true poc whatever the stiffnesses (measured: 2.02 mm above the lowest
point at y = 4.05 mm; statics residual 6.6e-4 of Fn against SAP's 1.6e-6).
Both get the same friction and Hunt-Crossley dissipation.

- Stiffness: ground 1 / (1/Kp - 1/(1e8 Kp)), in series with the foot: Kp exactly.
- SAP: ground ``relaxation_time = Kd / Kp``, so fn = Kp (x + tau_d xdot)_+ =
  Kp x + Kd xdot, the spec's spring-damper exactly while pressing in. It cannot
  switch the damping off while releasing (the spec does), and the force is
  clamped at zero instead of staying Kp x while the foot lifts quickly.
- Hunt-Crossley (``tamsi``, ``lagged``, ``similar``, ``continuous``):
  fn = k x (1 + d xdot)_+, a damping k d x xdot that grows with the
  penetration x. No d gives Kd xdot at every depth; ``d = Kd / (Kp x_ref)``
  gives it at the reference depth ``x_ref = hc_reference_depth`` (default 5 mm,
  the order of the tasks' steady sink under 50-90 N) and less (more) above
  (below) it; it also damps while releasing.
- Friction: the discrete solvers use only Drake's dynamic coefficient, set to
  ``mu_s`` (the foot holds up to mu_s Fn, like the other Coulomb engines).
  All but SAP regularise friction over ``stiction_tolerance`` v_s, chosen by
  :func:`stiction_tolerance` so that the slope near zero slip is the spec's
  mu_s / v_th, and with it the creep under small tangential loads: TAMSI's
  mu s (2 - s), s = v / v_s, rises as 2 mu v / v_s, so v_s = 2 v_th (with
  v_s = v_th it crept at half the law's speed: measured 0.52 x the law, now
  1.04 x, 40 N press with 0.13 of the friction limit); lagged and similar
  (mu s / sqrt(1 + s^2)) take v_th (1.01 x). The continuous plant's point
  contact follows mu_s step5(s), which starts cubic, with no slope to match:
  v_th (2.1 x the law's creep at 0.13 of the friction limit, 1.03 x at 0.47);
  it drops to mu_k (``CoulombFriction(mu_s, mu_k)``) from v_s to 3 v_s, where
  the spec's drops at 1.5 v_th. Its hydroelastic contact follows
  mu_k 2/pi atan(s): v_s = 2 mu_k v_th / (pi mu_s) (1.03 x; 1.89 x at v_th).
  SAP regularises friction with its own regularisation: the foot sticks
  (measured creep 0.004 mm/s in the effort task).

Hydroelastic option (``contact_model = "hydroelastic"``): the foot is a compliant
hydroelastic sphere (``hydroelastic_modulus`` E, mesh ``resolution_hint``) on a
rigid half-space. Its pressure field is E times the depth-fraction inside the
sphere, so the force at penetration x is F(x) = 2 pi E / R (R a^2 / 2 - (R^3 - h^3) / 3),
h = R - x, a^2 = R^2 - h^2 (about pi E x^2: stiffening, not a linear spring).
E is chosen so that F(x_ref) = Kp x_ref, and the relaxation time (SAP) as
Kd / F'(x_ref) so the linearised damping is Kd at x_ref. Hunt-Crossley scales
the pressure, p = p_e (1 + d xdot), so the force F(x) (1 + d xdot) damps with
F(x) d: d = Kd / F(x_ref), as for point contact (measured 99.7 N s/m at x_ref;
the former Kd / (F'(x_ref) x_ref) gave 54.6). The tessellated sphere makes the
force differ from the formula by the mesh resolution (measured in
docs/backends/drake.md).

Reference contact (``contact_mode = "reference"``): no ground geometry; before
every discrete update (sub-step) ``J_poc^T F`` of
:class:`~legbench.contact.ReferenceContact` enters the plant's applied
generalized force port. The continuous plant holds it over the control
period (first order in the contact force).

Profiles: ``matched`` is :attr:`DrakeBackend.defaults` (SAP at 50 us, the
mapping above). ``engine-defaults`` is what a Drake user gets from
``MultibodyPlantConfig()`` (1 ms ``lagged``, stiction tolerance 1e-4 m/s)
with Kp, Kd and mu set on the foot: ``point_contact_stiffness = Kp``,
``hunt_crossley_dissipation = Kd / (Kp x_ref)`` [s/m] (legbench's mapping of a damping Kd [N s/m] onto Drake's
Hunt-Crossley d, Kd at the reference depth as above: Drake gives no conversion, so this is not a Drake user's
usual way but the mapping applied to Drake's defaults) and ``relaxation_time = Kd / Kp`` [s] (read only by SAP),
the ground registered with friction only, so it gets
``SceneGraphConfig().default_proximity_properties`` (Drake 1.51: ``point_stiffness``
1e6 N/m, ``hunt_crossley_dissipation`` 50 s/m, ``relaxation_time`` 0.1 s; the
``penetration_allowance`` estimate is only for geometry that still lacks a value): 1e6 N/m
in series with Kp gives Fn / (Kp y) = 1/1.01, and the ground's 50 s/m weighted by the foot's
share of the stiffness, 50 Kp / (1e6 + Kp) = 0.50 s/m, adds to 0.99 of the foot's d.
"""

from __future__ import annotations

import contextlib
import logging
import math
import operator
from collections.abc import Iterator, Mapping
from importlib import metadata
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
from pydrake.geometry import (
    AddCompliantHydroelasticProperties,
    AddContactMaterial,
    AddRigidHydroelasticProperties,
    CollisionFilterDeclaration,
    GeometrySet,
    HalfSpace,
    ProximityProperties,
    RoleAssign,
)
from pydrake.math import RigidTransform
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import AddMultibodyPlant, CoulombFriction, MultibodyPlantConfig
from pydrake.multibody.tree import JacobianWrtVariable
from pydrake.systems.analysis import ResetIntegratorFromFlags, Simulator
from pydrake.systems.framework import DiagramBuilder

from legbench import kinematics
from legbench.backends.base import (
    FRICTION_COEFFICIENTS,
    Backend,
    Limits,
    Physics,
    Range,
    check_finite,
    clamp_torque,
    held,
    reference_contact,
    sub_step_count,
)
from legbench.contact import ContactParams, ReferenceContact
from legbench.exceptions import LegbenchError
from legbench.model import FOOT_FRAME, JOINT_NAMES, LINK_NAMES, Inertial, combine, load_params

#: Discrete contact approximations offered, and the continuous plant.
SOLVERS = ("sap", "tamsi", "lagged", "similar", "continuous")
#: Solvers whose normal force is Hunt-Crossley (the others: SAP's linear Kelvin-Voigt).
HUNT_CROSSLEY = ("tamsi", "lagged", "similar", "continuous")
#: Contact models offered.
CONTACT_MODELS = ("point", "hydroelastic")
#: SAP's friction regularisation over the Delassus estimate, R_t = sigma w: a constant of Drake's (``sap_driver.cc``,
#: ``constexpr double sigma = 1.0e-3``), not a setting.
SAP_SIGMA = 1.0e-3
#: SAP's sliding term mu (Kd + Kp h) |v_t| (:func:`sap_glide_force`) as a share of Fn above which a run warns (it
#: lifts a sliding foot: docs/backends/drake.md), estimated where Fn exceeds SAP_LIFT_FN [N] (a share of a smaller
#: force says nothing of the task).
SAP_LIFT_SAID, SAP_LIFT_FN = 0.01, 1.0
#: How near the engine's own normal force carries the estimated gliding term (relative): Fn - (Kp y + Kd ydot) at
#: the foot's state of the run's largest share (``at_end.sap_glide``; measured 4.3e-5 at 50 us and 1.0e-3 at 1 ms in
#: the drag, where the estimate without Kp h misses by 0.50 % and 10.1 %). Not an explanation of the sliding
#: verification's rows: the glide is a normal force, not the row's acceleration, and the window's samples out of
#: contact are counted by the sliding case itself.
SAP_GLIDE_TOL = 0.003
#: Foot stiffness over Kp in the matched point contact: the foot is near-rigid, the ground carries the spring.
FOOT_STIFFNESS_RATIO = 1.0e8
#: Ways of setting the contact parameters: the mapping of the module docstring, or on the foot alone over Drake's
#: defaults (engine-defaults; its d = Kd / (Kp x_ref) is legbench's mapping, not a Drake convention).
CONTACT_PARAMS = ("mapped", "usual")


def sap_glide_force(mu: float, Kp: float, Kd: float, h: float, slip: float) -> float:
    """The normal force [N] SAP adds while a point contact slides at ``slip`` [m/s]: mu (Kd + Kp h) |v_t|, ``Kp``
    [N/m] and ``Kd`` [N s/m] the pair's stiffness and damping (relaxation time tau_d = Kd / Kp), ``h`` [s] the
    plant's time step, ``mu`` the pair's (dynamic) coefficient. SAP's regularisation Rn = 1 / (h k (h + tau_d)) and
    bias vn_hat = -phi / (h + tau_d) (``sap_friction_cone_constraint.cc:71-76``, Drake v1.51.1) and its sliding
    projection gn = (yn + mu_hat yr) / (1 + mu_tilde^2) (line 133; mu_tilde^2 = mu^2 R_t / Rn, 1e-5 here) give
    fn = gn / h = Kp y + Kd ydot + (Kd + Kp h) mu |v_t| at the step's end state (y the penetration, ydot its rate):
    the separation speed mu |v_t| of the convex approximation's gliding, entering through h + tau_d."""
    return mu * (Kd + Kp * h) * slip


def hydro_force_per_modulus(x: float, R: float) -> float:
    """F(x) / E [m^2] of a compliant hydroelastic sphere (radius R [m]) pressed x [m] into a rigid plane."""
    h = R - x
    a2 = R * R - h * h
    return 2.0 * math.pi / R * (R * a2 / 2.0 - (R**3 - h**3) / 3.0)


def hydro_stiffness_per_modulus(x: float, R: float) -> float:
    """dF/dx / E [m] of the same sphere: 2 pi x h / R ... exact: d/dx of :func:`hydro_force_per_modulus`."""
    h = R - x
    # dF/dx = 2 pi / R (R h - h^2) = 2 pi h x / R
    return 2.0 * math.pi * h * x / R


def stiction_tolerance(solver: str, contact_model: str, contact: ContactParams) -> float:
    """Drake's ``stiction_tolerance`` v_s [m/s] that gives its regularised friction the spec's slope near
    zero slip, mu_s / v_th (so the same creep under small tangential loads), from Drake 1.51's curves:

    - TAMSI: mu s (2 - s), s = v / v_s (``tamsi_solver.h``), slope 2 mu / v_s: v_s = 2 v_th;
    - lagged, similar: mu s / sqrt(1 + s^2) (``sap_hunt_crossley_constraint.h``), slope mu / v_s: v_th;
    - continuous, hydroelastic: mu_k 2/pi atan(s) (``hydroelastic_traction_calculator.cc``, the dynamic
      coefficient), slope 2 mu_k / (pi v_s): v_s = 2 mu_k v_th / (pi mu_s);
    - continuous, point: mu_s step5(s) (``MultibodyPlant::StribeckModel``), a cubic start with no slope at
      zero, so none matches; v_th (measured creep 1.03 x the law's at 0.47 of the friction limit, 2.1 x at 0.13);
    - SAP: not read (it regularises friction itself); v_th.
    """
    if solver == "tamsi":
        return 2.0 * contact.v_th
    if solver == "continuous" and contact_model == "hydroelastic" and contact.mu_k > 0:
        return 2.0 * contact.mu_k * contact.v_th / (math.pi * contact.mu_s)
    return float(contact.v_th)


class DrakeBackend(Backend):
    """Drake (MultibodyPlant; SAP, TAMSI or continuous) simulating the leg."""

    name: ClassVar[str] = "drake"
    #: Drake's discrete solvers slide with the dynamic coefficient alone, which the matched profile (the one the
    #: sliding case runs) sets to mu_s. Not so elsewhere: engine-defaults sets CoulombFriction(mu_s, mu_k), so its
    #: discrete solvers slide at mu_k, and ``continuous`` uses Stribeck friction, mu_k above 3 v_s.
    sliding_coefficient: ClassVar[str] = "mu_s"
    defaults: ClassVar[Mapping[str, Any]] = {
        "solver": "sap",  # one of SOLVERS
        "dt": 5.0e-5,  # discrete time step [s], the others' sub-step (ignored by "continuous": one solve per period)
        "contact_model": "point",  # "point" or "hydroelastic"
        "contact_params": "mapped",  # "mapped" (module docstring) or "usual" (engine-defaults)
        "hc_reference_depth": 5.0e-3,  # x_ref [m] at which Hunt-Crossley (and hydroelastic) damping equals Kd
        "stiction_tolerance": None,  # friction regularisation speed v_s [m/s]; None: stiction_tolerance()
        "accuracy": 1.0e-6,  # continuous: target accuracy of the error-controlled runge_kutta3
        "resolution_hint": 5.0e-3,  # hydroelastic: mesh edge length of the foot sphere [m]
        "sap_near_rigid_threshold": 1.0,  # SAP's near-rigid regime threshold (Drake's default)
        "reference_friction": "implicit",  # reference mode: the law's friction slope implicit (as Pinocchio's)
        # the discrete solvers' one coefficient (Drake's dynamic friction, mapped parameters): mu_s (holds to mu_s Fn)
        # or mu_k (slides at it); the continuous plant's Stribeck curve has both
        "friction_coefficient": "mu_s",
    }
    #: A regularisation speed is > 0; null: :func:`stiction_tolerance` (the law's slope near zero slip).
    #: ``resolution_hint`` >= 1 mm: the foot's hydroelastic mesh grows as (R_foot / hint)^3 tetrahedra; measured
    #: (27 Nov, 20 ticks from q = (0, -1.2, -1.2)) 0.01 s per 1 ms tick at the default 5 mm, 0.12 s at 2 mm, 0.43 s
    #: at 1 mm (a 4 s task: half an hour); at 0.2 mm the load did not end in 170 s
    ranges: ClassVar[Mapping[str, Range]] = {
        "stiction_tolerance": Range(open_low=True, nullable=True),
        "resolution_hint": Range(1.0e-3),
    }
    choices: ClassVar[Mapping[str, tuple[str, ...]]] = {
        "solver": SOLVERS,
        "contact_model": CONTACT_MODELS,
        "contact_params": CONTACT_PARAMS,
        "reference_friction": ("implicit", "explicit"),
        "friction_coefficient": FRICTION_COEFFICIENTS,
    }
    profiles: ClassVar[Mapping[str, Mapping[str, Any]]] = {
        "matched": {},
        # MultibodyPlantConfig() defaults: 1 ms, "lagged", stiction tolerance 1e-4 m/s
        "engine-defaults": {"solver": "lagged", "dt": 1.0e-3, "contact_params": "usual", "stiction_tolerance": 1.0e-4},
    }
    install: ClassVar[str] = "pip install 'drake>=1.51,<2'"

    @classmethod
    def known_deviation(cls, case: str, quantity: str, info: Mapping[str, Any], measured: float = math.nan,
                        expected: float = math.nan, tolerance: float = math.nan) -> str | None:  # fmt: skip
        """The creep of a held foot; Hunt-Crossley's damping k d x; the engine-defaults ground's default stiffness.
        Not the sliding drag: SAP's
        point contact lifts the sliding foot (docs/backends/drake.md, the run's ``at_end.sap_glide``), but that holds
        the normal force, not the slip-acceleration row's measured value, so its miss stays a plain one (the sliding
        case counts the window's samples out of contact)."""
        contact = info.get("contact")
        contact = contact if isinstance(contact, Mapping) else {}
        if case == "creep":
            return cls._known_creep(info, contact, measured, tolerance)
        if case == "damping":
            return cls._known_damping(info, contact, measured, tolerance)
        pair, kp = contact.get("pair_stiffness"), contact.get("Kp")
        ground = (contact.get("properties") or {}).get("ground") or {}
        defaulted = "material.point_contact_stiffness" not in ground  # the scene graph's default, not legbench's
        if (case == "rest_penetration" and isinstance(pair, float) and isinstance(kp, float) and defaulted
                and abs(pair / kp - 1) > 1e-6):  # fmt: skip
            return held(f"known: the ground, registered with friction only, takes the scene graph's default point "
                        f"stiffness ({1.0 / (1.0 / pair - 1.0 / kp):.3g} N/m) in series with the foot's Kp: the foot "
                        f"rests on {pair:.6g} N/m and sinks {100 * (kp / pair - 1):.2f} % deeper than Fn/Kp, at "
                        f"Fn/pair_stiffness", measured, expected * kp / pair, tolerance,
                        " (info contact.pair_stiffness)")  # fmt: skip
        return None

    @classmethod
    def _known_damping(cls, info: Mapping[str, Any], contact: Mapping[str, Any], measured: float,
                       tolerance: float) -> str | None:  # fmt: skip
        """The normal damping of Hunt-Crossley's law (every approximation but SAP's linear one), fn = k x (1 + d
        xdot): dfn/dxdot = k d x, the pair's stiffness and dissipation (``contact.pair_stiffness``,
        ``pair_dissipation``) at the depth x, so a damping fitted over a pressing-in transient reads k d at the
        fit's weighted depth (the calibration's case ``damping``, ``info["transient"]["depth"]`` [m]), where the
        measured c eff [N s/m] meets it within ``tolerance``."""
        transient = info.get("transient")
        depth = transient.get("depth") if isinstance(transient, Mapping) else None
        k, d = contact.get("pair_stiffness"), contact.get("pair_dissipation")
        approx = str(contact.get("discrete_contact_approximation"))
        if approx.endswith("kSap") or not (isinstance(depth, float) and isinstance(k, float) and isinstance(d, float)):
            return None
        c = k * d * depth
        return held(f"known: Hunt-Crossley's normal force k x (1 + d xdot) damps at k d x, not a constant Kd: k = "
                    f"{k:.6g} N/m, d = {d:.4g} s/m (the pair's), x = {1e3 * depth:.4g} mm (the fit's samples' depth, "
                    f"weighted as the fit weights them): {c:.4g} N s/m", measured, c, tolerance,
                    " (docs/backends/drake.md)")  # fmt: skip

    @classmethod
    def _known_creep(cls, info: Mapping[str, Any], contact: Mapping[str, Any], measured: float,
                     tolerance: float) -> str | None:  # fmt: skip
        """The creep of a foot held below the friction limit by SAP's regularised friction (the calibration's case
        ``creep``; ``info["load"]`` the held Fn, Ft [N]), where the measured creep meets it within ``tolerance``:
        SAP sticking, the impulse -v_t / R_t with R_t = sigma w, so v = sigma w dt Ft (``sap_friction_cone_
        constraint.cc``); ``lagged``, Ft = mu_k Fn v / sqrt(v^2 + eps^2) with eps = max(v_s, mu_k sigma w dt Fn)
        (``sap_hunt_crossley_constraint.cc``; n0 = dt Fn at rest), so v = eps r / sqrt(1 - r^2), r = Ft / (mu_k Fn).
        w is the run's Delassus estimate at its end (``at_end.delassus_w``)."""
        at_end = info.get("at_end")
        load, dt = info.get("load"), info.get("timestep")
        w = at_end.get("delassus_w") if isinstance(at_end, Mapping) else None
        approx = str(contact.get("discrete_contact_approximation"))
        if not (isinstance(load, Mapping) and isinstance(w, float) and isinstance(dt, float)):
            return None
        fn, ft = float(load["Fn"]), float(load["Ft"])
        if not fn > 0.0:  # the foot off the ground: no held contact
            return None
        if approx.endswith("kSap"):
            v = SAP_SIGMA * w * dt * ft
            law = (f"SAP regularises friction: sticking, the tangential impulse is -v_t / R_t with R_t = sigma w "
                   f"(sigma = {SAP_SIGMA:g}, Drake's constant; w = {w:.4g} 1/kg, its Delassus estimate at the end "
                   f"pose), so Ft creeps at sigma w dt Ft")  # fmt: skip
        elif approx.endswith("kLagged") and isinstance(mu := contact.get("mu_dynamic"), float):
            v_s = float(contact.get("stiction_tolerance") or 0.0)
            eps, r = max(v_s, mu * SAP_SIGMA * w * dt * fn), ft / (mu * fn)
            if not 0.0 < r < 1.0:
                return None
            v = eps * r / math.sqrt(1.0 - r * r)
            law = (f"the lagged approximation's friction is mu_k Fn v / sqrt(v^2 + eps^2), eps = max(v_s, mu_k sigma "
                   f"w dt Fn) = {eps:.4g} m/s (mu_k = {mu:.3g}, w = {w:.4g} 1/kg), so Ft = {ft:.4g} N creeps at "
                   f"eps r / sqrt(1 - r^2), r = Ft / (mu_k Fn) = {r:.4g}")  # fmt: skip
        else:
            return None
        return held(f"known: {law} = {1e3 * v:.4g} mm/s", measured, v, tolerance, " (docs/backends/drake.md)")

    # ----------------------------------------------------------------- load
    @classmethod
    def settings_problem(
        cls, settings: Mapping[str, Any], contact_mode: str
    ) -> tuple[str | tuple[str, ...], str] | None:
        """``solver: continuous`` in reference contact: the law is applied at each sub-step's start state, and the
        continuous plant has no sub-steps (it ran with a step of 0: every AdvanceTo(0) left the leg where it
        started)."""
        if settings.get("solver") == "continuous" and contact_mode == "reference":
            return "solver", ("'continuous' cannot run reference contact (the law is applied at each sub-step's "
                              "start and the continuous plant has none); use a discrete solver (sap, tamsi, "
                              "lagged, similar) with contact_mode: reference")  # fmt: skip
        return None

    def load(self, urdf: Path, physics: Physics, settings: Mapping[str, Any]) -> None:
        """Build plant, scene graph and simulator; map the contact parameters (module docstring).

        Args:
            urdf: the generated leg URDF.
            physics: gravity, contact law and mode, control period, torque limits.
            settings: overrides of :attr:`defaults`.

        Raises:
            LegbenchError: an unknown solver, contact model or contact-parameter way, a
                ``dt`` that does not divide the control period, or the continuous plant in reference contact.
        """
        cfg = self.settings(settings)
        for key, offered in self.choices.items():
            if cfg[key] not in offered:
                raise LegbenchError(f"drake: unknown {key} '{cfg[key]}'; choose one of {list(offered)}")
        self.cfg, self.physics = cfg, physics
        self.reference = physics.contact_mode == "reference"
        self.continuous = cfg["solver"] == "continuous"
        # SAP's point contact adds mu (Kd + Kp h) |v_t| to the normal force while the foot slides (its convex
        # approximation, sap_glide_force): the largest share of Fn the estimate reached, and when, for warnings()
        # and info's at_end.sap_glide (with the mapped parameters: the pair's stiffness and damping are then the
        # spec's Kp and Kd, which the estimate takes)
        self._sap_point = (cfg["solver"], cfg["contact_model"], self.reference, cfg["contact_params"]) == (
            "sap",
            "point",
            False,
            "mapped",
        )
        self._sap_lift, self._sap_lift_t, self._sap_lift_n = 0.0, math.nan, 0.0
        # the period of the largest share: Drake's Fn [N] and slip [m/s], the end state (preallocated: the hot path
        # copies into them) and the foot radius [m] the measurement takes the penetration with
        self._glide_fn, self._glide_slip = math.nan, math.nan
        self._glide_q, self._glide_qd = np.zeros(3), np.zeros(3)
        self._r_foot = load_params().geometry.R_foot
        self.refuse_settings(cfg, physics.contact_mode)
        self.n_sub = 1 if self.continuous else sub_step_count(self.name, cfg["dt"], physics.control_dt)
        c = physics.contact
        self.v_s = float(
            stiction_tolerance(cfg["solver"], cfg["contact_model"], c)
            if cfg["stiction_tolerance"] is None
            else cfg["stiction_tolerance"]
        )
        usual = cfg["contact_params"] == "usual"

        plant_cfg = MultibodyPlantConfig(
            time_step=0.0 if self.continuous else physics.control_dt / self.n_sub,
            contact_model="hydroelastic" if cfg["contact_model"] == "hydroelastic" else "point",
            discrete_contact_approximation="tamsi" if self.continuous else cfg["solver"],
            stiction_tolerance=self.v_s,
            sap_near_rigid_threshold=float(cfg["sap_near_rigid_threshold"]),
        )
        # Drake warns that a rigid half-space takes no part in deformable contact (there is none here)
        with _drake_log_level(logging.ERROR):
            self._build(urdf, physics, plant_cfg, usual)
        self._implicit = self.reference and cfg["reference_friction"] == "implicit"
        self.contact = ReferenceContact.from_leg(c, physics.gravity if self._implicit else None)
        self._limit = tuple(float(x) for x in physics.torque_limit)  # [N m]
        self._tau = np.zeros(3)  # the clamped torque [N m], what the actuation port takes
        self._force = np.zeros(3)
        self._q = np.zeros(3)
        self._qd = np.zeros(3)
        self.tick = 0

    def _build(self, urdf: Path, physics: Physics, plant_cfg: MultibodyPlantConfig, usual: bool) -> None:
        """Plant, scene graph, ground, contact properties, simulator and input ports."""
        cfg, c = self.cfg, physics.contact
        builder = DiagramBuilder()
        plant, scene_graph = AddMultibodyPlant(plant_cfg, builder)
        Parser(plant).AddModels(Path(urdf))
        plant.WeldFrames(plant.world_frame(), plant.GetFrameByName("base"))
        plant.mutable_gravity_field().set_gravity_vector([0.0, 0.0, -physics.gravity])
        self.joints = [plant.GetJointByName(n) for n in JOINT_NAMES]
        self.actuators = [
            plant.AddJointActuator(n, j, float(lim))
            for n, j, lim in zip(JOINT_NAMES, self.joints, physics.torque_limit, strict=True)
        ]
        self.foot_body = plant.GetBodyByName(FOOT_FRAME)
        foot_geoms = plant.GetCollisionGeometriesForBody(self.foot_body)
        leg_geoms = [g for b in (*LINK_NAMES, FOOT_FRAME) for g in plant.GetCollisionGeometriesForBody(
            plant.GetBodyByName(b))]  # fmt: skip
        self.ground = None
        self.contact_props: dict[str, Any] = {}
        if not self.reference:
            self.ground = self._ground(plant, usual)
        plant.Finalize()
        # only the foot meets the ground: every other leg geometry collides with nothing
        others = [g for g in leg_geoms if g not in foot_geoms]
        if others:
            scene_graph.collision_filter_manager().Apply(
                CollisionFilterDeclaration().ExcludeWithin(GeometrySet(leg_geoms))
                .ExcludeBetween(GeometrySet(others), GeometrySet([self.ground] if self.ground else []))
            )  # fmt: skip
        if self.reference:
            scene_graph.collision_filter_manager().Apply(
                CollisionFilterDeclaration().ExcludeWithin(GeometrySet(leg_geoms))
            )
        else:
            for g in foot_geoms:
                scene_graph.AssignRole(plant.get_source_id(), g, self._foot_props(c, usual), RoleAssign.kReplace)
        self.foot_geoms = frozenset(foot_geoms)

        self.diagram = builder.Build()
        self.plant, self.scene_graph = plant, scene_graph
        self.simulator = Simulator(self.diagram)
        self.root = self.simulator.get_mutable_context()
        self.ctx = plant.GetMyMutableContextFromRoot(self.root)
        if self.continuous:
            ResetIntegratorFromFlags(self.simulator, "runge_kutta3", physics.control_dt)
            integ = self.simulator.get_mutable_integrator()
            integ.set_target_accuracy(float(cfg["accuracy"]))
        self._default = self.diagram.CreateDefaultContext()
        self.simulator.Initialize()
        self._act = plant.get_actuation_input_port().FixValue(self.ctx, np.zeros(3))
        self._gen = plant.get_applied_generalized_force_input_port().FixValue(self.ctx, np.zeros(3))
        self._results_port = plant.get_contact_results_output_port()
        #: Drake's discrete period [s] (0: continuous); targets are integer multiples of it
        self._h = 0.0 if self.continuous else float(plant.time_step())
        #: where each joint's q and qd sit in the plant's [q; v] state vector, as index arrays made once
        self._q_idx = np.array([j.position_start() for j in self.joints])
        self._qd_idx = plant.num_positions() + np.array([j.velocity_start() for j in self.joints])
        #: (q1, q2, q3, qd1, qd2, qd3) out of the state vector as a list
        self._pick = operator.itemgetter(*self._q_idx.tolist(), *self._qd_idx.tolist())
        #: the foot body's index, an int (read per contact)
        self._foot_index = int(self.foot_body.index())

    def _ground(self, plant: Any, usual: bool) -> Any:
        """Register the ground half-space on the world body: rigid, the foot's friction (or friction only)."""
        c = self.physics.contact
        props = ProximityProperties()
        if usual:
            # engine-defaults: a half-space with friction; stiffness and dissipation left to Drake's defaults
            friction = CoulombFriction(c.mu_s, c.mu_k)
            AddContactMaterial(friction=friction, properties=props)
        elif self.cfg["contact_model"] == "hydroelastic":
            AddContactMaterial(friction=self._friction(), properties=props)
            props.AddProperty("material", "relaxation_time", 0.0)
        else:
            # the ground carries the spring and its damping, the foot is near-rigid (see _foot_props)
            k_ground = 1.0 / (1.0 / c.Kp - 1.0 / (FOOT_STIFFNESS_RATIO * c.Kp))
            d = c.Kd / (c.Kp * float(self.cfg["hc_reference_depth"]))
            AddContactMaterial(dissipation=d, point_stiffness=k_ground, friction=self._friction(), properties=props)
            props.AddProperty("material", "relaxation_time", c.Kd / c.Kp)
        if self.cfg["contact_model"] == "hydroelastic":
            AddRigidHydroelasticProperties(props)
        self.contact_props["ground"] = _props_dict(props)
        return plant.RegisterCollisionGeometry(plant.world_body(), RigidTransform(), HalfSpace(), "ground", props)

    def _friction(self) -> Any:
        """Discrete solvers use the dynamic coefficient only: (mu_s, the ``friction_coefficient``, mu_s unless it
        says mu_k); continuous: (mu_s, mu_k)."""
        c = self.physics.contact
        return CoulombFriction(c.mu_s, c.mu_k if self.continuous else getattr(c, self.cfg["friction_coefficient"]))

    def _foot_props(self, c: Any, usual: bool) -> ProximityProperties:
        """The foot sphere's proximity properties (module docstring)."""
        props = ProximityProperties()
        R = load_params().geometry.R_foot
        x_ref = float(self.cfg["hc_reference_depth"])
        if usual:
            # Hunt-Crossley d [s/m]: k d x xdot = Kd xdot at x = x_ref; relaxation time [s] (SAP only)
            d, tau_d = c.Kd / (c.Kp * x_ref), c.Kd / c.Kp
            AddContactMaterial(
                dissipation=d, point_stiffness=c.Kp, friction=CoulombFriction(c.mu_s, c.mu_k), properties=props
            )
            props.AddProperty("material", "relaxation_time", tau_d)
            if self.cfg["contact_model"] == "hydroelastic":
                AddCompliantHydroelasticProperties(float(self.cfg["resolution_hint"]), c.Kp / x_ref, props)
        elif self.cfg["contact_model"] == "hydroelastic":
            E = c.Kp * x_ref / hydro_force_per_modulus(x_ref, R)
            k_lin = E * hydro_stiffness_per_modulus(x_ref, R)
            # Hunt-Crossley scales the elastic pressure, p = p_e (1 + d xdot), so the force F(x) (1 + d xdot)
            # damps with F(x) d: Kd at x_ref for d = Kd / F(x_ref) (F(x_ref) = Kp x_ref, as for point contact)
            d = c.Kd / (E * hydro_force_per_modulus(x_ref, R))
            tau_d = c.Kd / k_lin
            AddContactMaterial(dissipation=d, friction=self._friction(), properties=props)
            props.AddProperty("material", "relaxation_time", tau_d)
            AddCompliantHydroelasticProperties(float(self.cfg["resolution_hint"]), E, props)
            self.contact_props["hydroelastic_modulus"] = E
            self.contact_props["linearised_stiffness_at_x_ref"] = k_lin
        else:
            # near-rigid foot: the discrete plant places the contact point between the two witness points
            # weighted by stiffness, so this puts it on the sphere's lowest point (the spec's true poc) to 1e-8 x
            # (the continuous plant uses the midpoint, y/2 higher: module docstring)
            d = c.Kd / (c.Kp * x_ref)
            AddContactMaterial(dissipation=d, point_stiffness=FOOT_STIFFNESS_RATIO * c.Kp, friction=self._friction(),
                               properties=props)  # fmt: skip
            props.AddProperty("material", "relaxation_time", 0.0)
        self.contact_props["foot"] = _props_dict(props)
        return props

    # ---------------------------------------------------------------- reset
    def reset(self, q: np.ndarray, qd: np.ndarray) -> None:
        """Set q [rad] and qd [rad/s] at t = 0; the contact force reads zero until the first step (native)."""
        self.root.SetTime(0.0)
        # back to the default state (this also clears the sampled contact results of a previous run)
        self.root.SetTimeStateAndParametersFrom(self._default)
        x = np.zeros(6)
        x[self._q_idx] = q
        x[self._qd_idx] = qd
        self.plant.SetPositionsAndVelocities(self.ctx, x)
        _set(self._act, np.zeros(3))
        _set(self._gen, np.zeros(3))
        self.simulator.Initialize()
        self.tick = 0
        self._sap_lift, self._sap_lift_t, self._sap_lift_n = 0.0, math.nan, 0.0
        self._glide_fn, self._glide_slip = math.nan, math.nan
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
        _set(self._act, u)
        Ts, n, h = self.physics.control_dt, self.n_sub, self._h
        if self.reference:
            implicit, gen, advance = self._implicit, self._gen, self.simulator.AdvanceTo
            law, law_i = self.contact.generalized, self.contact.implicit_generalized
            get, ctx, pick = self.plant.GetPositionsAndVelocities, self.ctx, self._pick
            q, qd = self._q, self._qd
            # the state as floats through the sub-steps, written back once
            q1, q2, q3 = q.tolist()
            qd1, qd2, qd3 = qd.tolist()
            first = self.tick * n + 1
            for k in range(n):
                if implicit:  # the friction slope linearly implicit over the sub-step (docs/pinocchio.md)
                    _set(gen, law_i(q1, q2, q3, qd1, qd2, qd3, u1, u2, u3, h))
                else:
                    _set(gen, law(q1, q2, q3, qd1, qd2, qd3))
                advance((first + k) * h)
                q1, q2, q3, qd1, qd2, qd3 = pick(get(ctx).tolist())
            q[0], q[1], q[2], qd[0], qd[1], qd[2] = q1, q2, q3, qd1, qd2, qd3
            self._reference_force()
        else:
            # an integer count of Drake's own period, so every target is exactly one of its event times
            self.simulator.AdvanceTo((self.tick + 1) * n * h if h else (self.tick + 1) * Ts)
            self._read()
            self._native_force()
        self.tick += 1
        check_finite(self.name, self.tick * Ts, self._q, self._qd)

    def _read(self) -> None:
        q, qd = self._q, self._qd
        q[0], q[1], q[2], qd[0], qd[1], qd[2] = self._pick(self.plant.GetPositionsAndVelocities(self.ctx).tolist())

    def _reference_force(self) -> None:
        q, qd = self._q, self._qd
        self.contact.generalized(q[0], q[1], q[2], qd[0], qd[1], qd[2])
        self._force[:] = self.contact.force

    def _native_force(self) -> None:
        """Sum of the contact forces on the foot from the plant's ContactResults, in W [N].

        Discrete plant: the results of the last discrete update (sampled output ports),
        i.e. the force over the last sub-step. Continuous: at the current state.
        """
        results = self._results_port.Eval(self.ctx)
        force, foot = self._force, self._foot_index
        force[:] = 0.0
        slip = 0.0
        for i in range(results.num_point_pair_contacts()):
            info = results.point_pair_contact_info(i)
            if int(info.bodyB_index()) == foot:
                force += info.contact_force()
            elif int(info.bodyA_index()) == foot:
                force -= info.contact_force()
            else:
                continue
            slip = max(slip, float(info.slip_speed()))
        if self._sap_point and force[2] > SAP_LIFT_FN:
            c = self.physics.contact
            extra = sap_glide_force(getattr(c, self.slides_with()), c.Kp, c.Kd, self._h, slip)  # [N], estimated
            if extra / force[2] > self._sap_lift:
                t = (self.tick + 1) * self.physics.control_dt  # the period's end, before tick counts it
                self._sap_lift, self._sap_lift_t, self._sap_lift_n = extra / force[2], t, extra
                self._glide_fn, self._glide_slip = float(force[2]), slip
                self._glide_q[:] = self._q
                self._glide_qd[:] = self._qd
        for i in range(results.num_hydroelastic_contacts()):
            info = results.hydroelastic_contact_info(i)
            f_A = info.F_Ac_W().translational()
            if info.contact_surface().id_M() in self.foot_geoms:
                force += f_A
            else:
                force -= f_A

    def _glide_sample(self) -> dict[str, float] | None:
        """info's ``at_end.sap_glide``, the period that set the run's largest estimated gliding share (None where
        none did): its end ``t`` [s], Drake's ``fn`` [N] and ``slip`` [m/s], the ``estimated`` term mu (Kd + Kp h)
        |v_t| [N] (:func:`sap_glide_force`) and the ``measured`` one, fn - (Kp y + Kd ydot) [N] with y and ydot the
        sphere's penetration and its rate from that period's end state (legbench's kinematics, the lowest point)."""
        if not math.isfinite(self._glide_fn):
            return None
        c, q, qd, R = self.physics.contact, self._glide_q, self._glide_qd, self._r_foot
        y = R - float(kinematics.fk(q)[2])
        ydot = -float((kinematics.jacobian_below(q, R) @ qd)[2])
        return {"t": self._sap_lift_t, "fn": self._glide_fn, "slip": self._glide_slip,
                "estimated": self._sap_lift_n, "measured": self._glide_fn - (c.Kp * y + c.Kd * ydot)}  # fmt: skip

    # ----------------------------------------------------------------- read
    def state(self) -> tuple[np.ndarray, np.ndarray]:
        """Joint positions q [rad] (revolute angles, unwrapped) and velocities qd [rad/s]."""
        return self._q.copy(), self._qd.copy()

    def ground_force(self) -> np.ndarray:
        """Force of the ground on the foot in W [N]: Drake's contact results (native) or the law (reference)."""
        return self._force.copy()

    def read(self) -> tuple[float, ...]:
        """:meth:`state` and :meth:`ground_force` as nine floats, without the copies."""
        return (*self._q.tolist(), *self._qd.tolist(), *self._force.tolist())

    def info(self) -> dict[str, Any]:
        """Engine, version and every setting actually used, read back from the plant where Drake allows."""
        plant, c = self.plant, self.physics.contact
        unused = self._unused_settings()
        out: dict[str, Any] = {
            "engine": "drake",
            "version": metadata.version("drake"),
            **{k: self.cfg[k] for k in self.defaults if k not in unused},
            "sub_steps": self.n_sub,
            "timestep": plant.time_step() if not self.continuous else None,
            "integrator": "runge_kutta3" if self.continuous else "euler",  # the family verification predicts by
            "scheme": self._integrator_name(),
            "gravity": self.physics.gravity,
            "contact_mode": self.physics.contact_mode,
            "contact": reference_contact(
                c, "J_poc^T F via the applied generalized force port per sub-step", self.cfg["reference_friction"]
            )
            if self.reference
            else {
                "enabled": True,
                "poc": "true",
                "lift": self._lift(),
                "model": str(plant.get_contact_model()),
                "discrete_contact_approximation": (
                    str(plant.get_discrete_contact_approximation()) if not self.continuous else None
                ),
                "stiction_tolerance": self.v_s if "stiction_tolerance" not in unused else None,
                "Kp": c.Kp,
                "Kd": c.Kd,
                # the pair's friction, read back from the scene graph and combined as Drake does: the discrete
                # solvers slide with the dynamic one alone (matched sets it to mu_s)
                **self._pair_friction(),
                **self._pair_point_contact(),
                "sap_sigma": SAP_SIGMA if self._sap_family() else None,
                "normal_law": "linear Kelvin-Voigt Kp (x + tau_d xdot)_+"
                if self.cfg["solver"] == "sap"
                else "Hunt-Crossley k x (1 + d xdot)_+",
                "properties": self.contact_props,
            },  # fmt: skip
        }
        # the state the run ended in, not a setting; sap_glide: the largest gliding share up to the end (SAP point)
        out["at_end"] = {"delassus_w": self._delassus_estimate(), "sap_glide": self._glide_sample()}
        if self.continuous:
            integ = self.simulator.get_integrator()
            out["target_accuracy"] = integ.get_target_accuracy()
        return out

    def _pair_friction(self) -> dict[str, float | None]:
        """``mu_static``, ``mu_dynamic``: the foot-ground pair's Coulomb friction, the two geometries' coefficients
        as the scene graph holds them, combined as Drake combines them, 2 a b / (a + b) (None where one has none, and
        in reference contact, which registers no ground: the law's mu_s and mu_k apply)."""
        out: dict[str, float | None] = {"mu_static": None, "mu_dynamic": None}
        if self.ground is None or not self.foot_geoms:
            return out

        def friction(props: Any) -> Any:
            has = props is not None and props.HasProperty("material", "coulomb_friction")
            return props.GetProperty("material", "coulomb_friction") if has else None

        pair = [friction(props) for props in self._pair_properties()]
        if pair[0] is not None and pair[1] is not None:
            for key, part in (("mu_static", "static_friction"), ("mu_dynamic", "dynamic_friction")):
                a, b = (float(getattr(f, part)()) for f in pair)
                out[key] = 2.0 * a * b / (a + b) if a + b > 0 else 0.0
        return out

    def _pair_point_contact(self) -> dict[str, Any]:
        """``held``: each geometry's point-contact stiffness [N/m], Hunt-Crossley dissipation [s/m] and relaxation
        time [s] as the scene graph holds them, with the defaults it filled in for what legbench left unset
        (engine-defaults registers the ground with friction only, so it gets ``SceneGraphConfig()
        .default_proximity_properties``: 1e6 N/m, 50 s/m, 0.1 s in Drake 1.51; ``properties`` shows only what
        legbench set); ``pair_stiffness`` and ``pair_dissipation`` the discrete plant's combination of them (in
        series; each d weighted by the other's share of the stiffness): the spring the foot rests on, y = Fn /
        pair_stiffness. None in reference contact (no ground) and for the hydroelastic model."""
        out: dict[str, Any] = {"held": None, "pair_stiffness": None, "pair_dissipation": None}
        if self.ground is None or not self.foot_geoms or self.cfg["contact_model"] == "hydroelastic":
            return out
        names = ("point_contact_stiffness", "hunt_crossley_dissipation", "relaxation_time")
        held = {
            who: {n: float(p.GetProperty("material", n)) if p.HasProperty("material", n) else None for n in names}
            for who, p in zip(("foot", "ground"), self._pair_properties(), strict=True)
        }
        out["held"] = held
        k1, k2 = held["foot"]["point_contact_stiffness"], held["ground"]["point_contact_stiffness"]
        d1, d2 = held["foot"]["hunt_crossley_dissipation"], held["ground"]["hunt_crossley_dissipation"]
        if k1 is not None and k2 is not None:
            out["pair_stiffness"] = k1 * k2 / (k1 + k2)
            if d1 is not None and d2 is not None:
                out["pair_dissipation"] = (k2 * d1 + k1 * d2) / (k1 + k2)
        return out

    def _sap_family(self) -> bool:
        """Whether the plant's contact is solved by SAP's machinery: the discrete plant with the ``sap``, ``lagged``
        or ``similar`` approximation (TAMSI and the continuous plant are not)."""
        return not self.continuous and self.cfg["solver"] in ("sap", "lagged", "similar")

    def _delassus_estimate(self) -> float | None:
        """w [1/kg]: SAP's estimate of the Delassus operator's diagonal for the foot's point contact in the present
        state, ||J diag(M)^-1 J^T||_F / 3, J the translational Jacobian of the point where the discrete plant applies
        the force (the witness points weighted by stiffness) and only M's diagonal (``SapModel``'s diagonal
        approximation, A = M + dt D with no joint damping on the leg; ``sap_model.cc``): the scale SAP's friction
        regularisation takes, R_t = sigma w. None outside SAP's family, in reference or hydroelastic contact,
        where the foot is not in contact and for a state that is not finite."""
        if not self._sap_family() or self.ground is None or not self.foot_geoms:
            return None
        if self.cfg["contact_model"] == "hydroelastic":  # no point pair: a contact surface
            return None
        plant, ctx = self.plant, self.ctx
        if not np.all(np.isfinite(plant.GetPositions(ctx))):  # a diverged run: no geometry query on it
            return None
        pairs = plant.get_geometry_query_input_port().Eval(ctx).ComputePointPairPenetration()
        if len(pairs) != 1:
            return None
        pair = pairs[0]
        on_foot, on_ground = (pair.p_WCa, pair.p_WCb) if pair.id_A in self.foot_geoms else (pair.p_WCb, pair.p_WCa)
        p_WC = on_foot + self._lift() * (on_ground - on_foot)  # the stiffness-weighted point
        p_FC = plant.EvalBodyPoseInWorld(ctx, self.foot_body).inverse() @ p_WC
        world = plant.world_frame()
        J = plant.CalcJacobianTranslationalVelocity(
            ctx, JacobianWrtVariable.kV, self.foot_body.body_frame(), p_FC, world, world
        )
        W = J @ (J.T / np.diag(plant.CalcMassMatrix(ctx))[:, None])
        return float(np.linalg.norm(W) / 3.0)

    def _pair_properties(self) -> tuple[Any, Any]:
        """The foot's and the ground's ProximityProperties as the scene graph holds them (defaults filled in)."""
        sg = self.scene_graph
        inspector = sg.get_query_output_port().Eval(sg.GetMyContextFromRoot(self.root)).inspector()
        return inspector.GetProximityProperties(min(self.foot_geoms)), inspector.GetProximityProperties(self.ground)

    def _lift(self) -> float:
        """Where Drake's own contact force acts, as the fraction of the penetration above the sphere's lowest
        point (``info()['contact']['lift']``): the continuous plant takes the plain midpoint of the two witness
        points (0.5); the discrete plant weights them by stiffness, p_WC = (k_foot p_foot + k_ground p_ground) /
        (k_foot + k_ground) (``discrete_update_manager.cc:674-679``, Drake v1.51.1), so k_ground / (k_foot +
        k_ground), with the stiffnesses as Drake applied them (mapped: 1e-8; engine-defaults, Kp against the
        default 1e6 N/m: 0.99); hydroelastic, the compliant foot on the rigid ground: the contact surface lies on
        the ground plane (1)."""
        if self.cfg["contact_model"] == "hydroelastic":
            return 1.0
        if self.continuous:
            return 0.5
        k_foot, k_ground = (
            float(p.GetProperty("material", "point_contact_stiffness")) for p in self._pair_properties()
        )
        return k_ground / (k_foot + k_ground)

    def _unused_settings(self) -> dict[str, str]:
        """Settings the configured solver and contact model do not read, each with why (for :meth:`warnings`), left
        out of :meth:`info` so the report's settings table lists only what acted: SAP regularises friction itself
        (no stiction tolerance) and reads the relaxation time, not the Hunt-Crossley d of ``hc_reference_depth``
        (point contact); the near-rigid threshold is SAP's; ``accuracy`` the continuous plant's; ``resolution_hint``
        the hydroelastic mesh's; ``friction_coefficient`` the mapped discrete pair's (its cause is the contact
        parameters, not the solver)."""
        solver, model = self.cfg["solver"], self.cfg["contact_model"]
        by_solver = f"not read by solver '{solver}' with {model} contact"
        unused = {"stiction_tolerance" if solver == "sap" else "sap_near_rigid_threshold": by_solver}
        if solver == "sap" and model == "point":
            unused["hc_reference_depth"] = by_solver
        if solver != "continuous":
            unused["accuracy"] = by_solver
        if model != "hydroelastic":
            unused["resolution_hint"] = by_solver
        if not self.reference:
            unused["reference_friction"] = by_solver
        if self.reference or self.continuous or self.cfg["contact_params"] != "mapped":
            why = ("reference contact applies the law's mu_s and mu_k" if self.reference
                   else "the continuous plant's Stribeck friction takes both mu_s and mu_k" if self.continuous
                   else "contact_params 'usual' gives the pair CoulombFriction(mu_s, mu_k)")  # fmt: skip
            unused["friction_coefficient"] = f"not read ({why})"
        return unused

    def _integrator_name(self) -> str:
        if self.continuous:
            return "runge_kutta3 (error-controlled)"
        return f"discrete {self.cfg['solver']} (semi-implicit Euler in free space)"

    def warnings(self) -> list[str]:
        """A setting given (it differs from the profile's) that the configured solver or contact model does not
        read (:meth:`_unused_settings`): it had no effect, which :meth:`info` alone (it leaves such settings out)
        did not say."""
        base = {**self.defaults, **self.profiles.get(self.profile, {})}
        # reference_friction is the contact mode's business (a scenario run in both modes gives it for one)
        unused = self._unused_settings()
        unused.pop("reference_friction", None)
        given = sorted(k for k in unused if k in base and self.cfg.get(k) != base[k])
        out = []
        for why in dict.fromkeys(unused.values()):  # one sentence per cause: the solver's, then the parameters'
            what = ", ".join(f"{k} {self.cfg[k]!r}" for k in given if unused[k] == why)
            if what:
                out.append(f"drake: {what}: {why}, so without effect")
        if self._sap_lift > SAP_LIFT_SAID:
            out.append(f"drake: SAP's point contact adds mu (Kd + Kp h) |v_t| to the normal force while the foot "
                       f"slides (its convex approximation; the spec's law has none): estimated from Drake's slip "
                       f"speed, up to {self._sap_lift_n:.3g} N, {100 * self._sap_lift:.3g} % of Fn, at t = "
                       f"{self._sap_lift_t:.3f} s (docs/backends/drake.md)")  # fmt: skip
        return out

    # ------------------------------------------------------- declared abilities
    def slides_with(self) -> str:
        """The ``friction_coefficient`` (mu_s unless it says mu_k) for the discrete solvers in the mapped profile
        (the dynamic coefficient set to it), ``mu_k``
        where the dynamic coefficient is mu_k (the usual parameters, engine-defaults) or for the continuous
        plant's Stribeck friction above 3 v_s."""
        if not self.continuous and self.cfg["contact_params"] == "mapped":
            return str(self.cfg["friction_coefficient"])
        return "mu_k"

    def integrator_family(self) -> str:
        """``adaptive`` (continuous), ``euler`` (discrete: symplectic Euler in free space, see the docs)."""
        return "adaptive" if self.continuous else "euler"

    def sub_steps(self) -> int:
        return self.n_sub

    def limits(self) -> Limits:
        """Joint position limits and actuator effort limits from the plant, gravity from its gravity field."""
        plant = self.plant
        lower = tuple(float(j.position_lower_limits()[0]) for j in self.joints)
        upper = tuple(float(j.position_upper_limits()[0]) for j in self.joints)
        effort = tuple(float(a.effort_limit()) for a in self.actuators)
        if self.continuous:
            how = "none: a continuous MultibodyPlant does not enforce joint position limits"
        elif self.cfg["solver"] == "tamsi":
            how = "compliant limit springs (TAMSI: stiffness and damping from the discrete time step)"
        else:
            how = "SAP joint-limit constraint (near-rigid, regularised by the time step)"
        return Limits(
            gravity=-float(plant.gravity_field().gravity_vector()[2]), lower=lower, upper=upper,  # type: ignore[arg-type]
            effort=effort, timestep=None if self.continuous else float(plant.time_step()),  # type: ignore[arg-type]
            enforcement=how,
        )  # fmt: skip

    def mass_properties(self) -> dict[str, dict[str, Any]]:
        """Per moving body: mass [kg], COM [m] and inertia about the COM [kg m^2] in the link frame.

        From each body's spatial inertia in the simulated context (about the body
        origin, in the body frame); link 3 includes the foot, placed by its pose in link 3.
        """
        plant, ctx = self.plant, self.ctx
        out = {}
        for name in LINK_NAMES:
            inr = self._inertial(plant.GetBodyByName(name), ctx)
            if name == LINK_NAMES[-1]:
                X = plant.CalcRelativeTransform(ctx, plant.GetFrameByName(name), self.foot_body.body_frame())
                R, p = X.rotation().matrix(), X.translation()
                foot = self._inertial(self.foot_body, ctx)
                moved = Inertial(foot.mass, tuple(R @ foot.com + p), tuple(map(tuple, R @ foot.I @ R.T)))  # type: ignore[arg-type]
                inr = combine([inr, moved])
            out[name] = {"mass": inr.mass, "com": list(inr.com), "inertia": inr.I.tolist()}
        return out

    @staticmethod
    def _inertial(body: Any, ctx: Any) -> Inertial:
        M = body.CalcSpatialInertiaInBodyFrame(ctx)
        m = float(M.get_mass())
        com = np.asarray(M.get_com())
        I_o = M.CalcRotationalInertia().CopyToFullMatrix3()  # about the body origin
        I_c = I_o - m * (float(com @ com) * np.eye(3) - np.outer(com, com))  # parallel-axis shift to the COM
        return Inertial(m, tuple(com.tolist()), tuple(map(tuple, I_c.tolist())))  # type: ignore[arg-type]

    def close(self) -> None:
        """Drop the simulator and diagram."""
        self.simulator = None  # type: ignore[assignment]
        self.diagram = None  # type: ignore[assignment]


@contextlib.contextmanager
def _drake_log_level(level: int) -> Iterator[None]:
    """Raise the ``drake`` logger's level for the block (pydrake syncs it to Drake's C++ logger)."""
    log = logging.getLogger("drake")
    before = log.level
    log.setLevel(level)
    try:
        yield
    finally:
        log.setLevel(before)


def _set(fixed: Any, value: np.ndarray) -> None:
    """Write a fixed input port's vector in place (``GetMutableData`` also marks its dependents stale)."""
    fixed.GetMutableData().get_mutable_value().SetFromVector(value)


def _props_dict(props: ProximityProperties) -> dict[str, Any]:
    """JSON-serialisable view of the ``material`` and ``hydroelastic`` groups of a ProximityProperties."""
    out: dict[str, Any] = {}
    for group in ("material", "hydroelastic"):
        if not props.HasGroup(group):
            continue
        for name in props.GetPropertiesInGroup(group):
            try:
                value = props.GetProperty(group, name)
            except RuntimeError:  # a value type pydrake does not bind (e.g. the hydroelastic compliance type)
                value = "<unbound>"
            if isinstance(value, CoulombFriction):
                value = {"static": value.static_friction(), "dynamic": value.dynamic_friction()}
            elif not isinstance(value, int | float | str | bool):
                value = str(value)
            out[f"{group}.{name}"] = value
    return out


__all__ = ["DrakeBackend"]
