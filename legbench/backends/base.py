"""The one backend interface: load, reset, step one control period, read.

A backend knows nothing of controllers, scenarios or logging. The run loop
hands it the same joint torques at the same instants as every other backend;
it advances its engine one control period under that held torque (zero-order
hold) with whatever sub-steps it uses, and reports state and ground force.
"""

from __future__ import annotations

import math
import numbers
from abc import ABC, abstractmethod
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from legbench.contact import ContactParams
from legbench.exceptions import LegbenchError, SimulationDiverged

#: Integrator families, by what verification can predict for them: ``euler`` (semi-implicit
#: Euler: qd += h qdd, then q += h qd), ``implicit`` (implicit in velocity, first order, e.g.
#: MuJoCo's ``implicit``), ``rk4`` (classic fixed-step), ``adaptive`` (error-controlled, one
#: solve per control period), ``first-order`` (a first-order step with no closed form of its own,
#: e.g. one in maximal coordinates: verification bounds it by the size of a first-order error),
#: ``other`` (no closed-form prediction at all: verification reports not-applicable rows).
INTEGRATOR_FAMILIES = ("euler", "implicit", "rk4", "adaptive", "first-order", "other")
#: How a backend without an ``integrator`` setting is named, by its family (verification's variant column, the
#: report's step and settings tables).
FAMILY_TEXT = {"euler": "semi-implicit euler", "implicit": "implicit euler", "rk4": "rk4", "adaptive": "adaptive",
               "first-order": "first order", "other": "other"}  # fmt: skip

#: The two profiles every backend offers (a backend may add its own, e.g. ``gazebo``).
PROFILES = ("matched", "engine-defaults")

#: The ContactParams coefficients a Coulomb contact with one coefficient may be given (a backend's
#: ``friction_coefficient`` setting, :meth:`Backend.slides_with`): ``mu_s``, the foot holds up to mu_s Fn as the law
#: does and slides at mu_s where the law slides at mu_k; ``mu_k``, it slides as the law does above 1.5 v_th and holds
#: only to mu_k Fn, where the law holds to mu_s Fn.
FRICTION_COEFFICIENTS = ("mu_s", "mu_k")

#: The keys of :meth:`Backend.info` that legbench reads (verification, calibration, the report), and what each
#: holds; any is optional, every other key is the backend's own and only recorded (run.json).
INFO_KEYS = {
    "engine": "the engine's name (text)",
    "version": "the engine's version (text)",
    "integrator": "the integrator's name as the backend's settings call it (text)",
    "dynamics": "what computes the dynamics, where it is not the engine's own stepper alone (text): the report's "
    "backend table shows it beside the engine, so a backend that runs legbench's code on an engine's model says so",
    "contact": "the contact as loaded: a mapping; its 'poc' ('true' or 'centre') is the point the force acts at "
    "(the law's poc where legbench applies the law; 'true' for an engine's own contact), its 'lift' (0..1, default "
    "0) raises that point by that fraction of the penetration y, where an engine's own contact acts above the "
    "sphere's lowest point (0.5: halfway between the two surfaces; 1: on the ground plane), its 'Kp' the normal "
    "stiffness [N/m], null for rigid contact (no stiffness declared)",
    "friction_cone": "the native friction limit's shape as loaded, where a setting chooses it (default: the class's "
    "friction_cone): 'cone' (|F_t| <= mu Fn), 'pyramid' (each tangent axis on its own, |F_ti| <= mu Fn) or 'diamond' "
    "(|F_t1| + |F_t2| <= mu Fn: a pyramid whose edges are n +- mu t_i); the sliding verification scores a pyramid by "
    "its own closed form, the report's residuals hold each shape to its own bounds",
    "friction_axes": "a pyramid's or diamond's two tangent axes t1, t2 in W as the engine builds them for a contact "
    "on the ground plane z = 0 with normal +z (2 x 3 floats: unit, orthogonal, horizontal), which the sliding "
    "verification projects the slip and the force onto (none declared: W x and W y)",
    "at_end": "quantities the run measured, not settings (a mapping): of the state it ended in (e.g. the contact's "
    "Delassus matrix J M^-1 J^T) or recorded over it (e.g. a largest share), which the backend's known_deviation may "
    "read; the report's settings table leaves them out",
    "max_step": "an adaptive solver's largest step [s] (a number)",
    "rtol": "an adaptive solver's relative tolerance (a number)",
    "atol": "an adaptive solver's absolute tolerance (a number)",
}


def declared_problem(family: object, sub_steps: object, coefficient: object) -> str | None:
    """What is wrong with what a backend declares of itself (:meth:`Backend.integrator_family`,
    :meth:`Backend.sub_steps`, :meth:`Backend.slides_with`), or None. Verification predicts by the family: one
    outside :data:`INTEGRATOR_FAMILIES` (``"semi-implicit"``, the text of :data:`FAMILY_TEXT`) turned every
    check of the backend not-applicable, silently; ``sub_steps`` 0 divided by zero there."""
    if family not in INTEGRATOR_FAMILIES:
        return f"integrator_family() returned {family!r}, not one of {', '.join(INTEGRATOR_FAMILIES)}"
    if not isinstance(sub_steps, int) or isinstance(sub_steps, bool) or sub_steps < 1:
        return f"sub_steps() returned {sub_steps!r}, not a whole number >= 1 (1 for an adaptive solve per period)"
    if coefficient not in FRICTION_COEFFICIENTS:
        return f"slides_with() returned {coefficient!r}, not 'mu_s' or 'mu_k'"
    return None


def info_problem(info: object) -> str | None:
    """What is wrong with a backend's :meth:`~Backend.info` for the keys legbench reads (:data:`INFO_KEYS`), or
    None: it must be a mapping with text keys, ``contact`` a mapping (``poc`` 'true' or 'centre', ``Kp`` a
    number or None), ``max_step``, ``rtol`` and ``atol`` numbers, ``friction_axes`` two rows of 3 numbers."""
    if not isinstance(info, Mapping):
        return f"expected a mapping of setting -> value, got {type(info).__name__}"
    bad = [k for k in info if not isinstance(k, str)]
    if bad:
        return f"key {bad[0]!r}: expected text keys"
    contact = info.get("contact")
    if contact is not None:
        if not isinstance(contact, Mapping):
            return f"contact: expected a mapping ({INFO_KEYS['contact']}), got {contact!r}"
        if contact.get("poc", "true") not in ("true", "centre"):
            return f"contact.poc: expected 'true' or 'centre', got {contact['poc']!r}"
        lift = contact.get("lift", 0.0)
        if not _is_number(lift) or not 0.0 <= lift <= 1.0:
            return f"contact.lift: expected a fraction of the penetration in [0, 1], got {lift!r}"
        kp = contact.get("Kp")
        if kp is not None and not _is_number(kp):
            return f"contact.Kp: expected a stiffness [N/m] or null (rigid contact), got {kp!r}"
    if "at_end" in info and not isinstance(info["at_end"], Mapping):
        return f"at_end: expected a mapping ({INFO_KEYS['at_end']}), got {info['at_end']!r}"
    if "dynamics" in info and not isinstance(info["dynamics"], str):
        return f"dynamics: expected text ({INFO_KEYS['dynamics']}), got {info['dynamics']!r}"
    for key in ("max_step", "rtol", "atol"):
        if key in info and not _is_number(info[key]):
            return f"{key}: expected a number, got {info[key]!r}"
    axes = info.get("friction_axes")
    if axes is not None and not (
        isinstance(axes, Sequence)
        and len(axes) == 2
        and all(isinstance(t, Sequence) and len(t) == 3 and all(_is_number(x) for x in t) for t in axes)
    ):
        return f"friction_axes: expected two directions of 3 numbers ({INFO_KEYS['friction_axes']}), got {axes!r}"
    return None


def contact_point(info: Mapping[str, Any] | None, law_poc: str) -> tuple[str, float]:
    """Where a backend's contact force acted on the foot, ``(poc, lift)`` for
    :func:`~legbench.kinematics.jacobian_at`: its info's ``contact.poc`` (else ``law_poc``, the scenario's: a
    backend or log that declares none) and ``contact.lift`` (else 0). Every check that maps the force to joint
    torques or takes the slip at the contact (the steady-state force check, the contact-law residuals, the
    studies) evaluates there."""
    contact = (info or {}).get("contact")
    if not isinstance(contact, Mapping):
        return law_poc, 0.0
    poc, lift = contact.get("poc"), contact.get("lift", 0.0)
    return (poc if poc in ("true", "centre") else law_poc), (float(lift) if _is_number(lift) else 0.0)


def explained_note(cls: type[Backend], case: str, quantity: str, info: Mapping[str, Any], passed: bool,
                   measured: float, expected: float, tolerance: float, note: str) -> str:  # fmt: skip
    """A verification row's note, with the backend's explanation of its miss before it
    (:meth:`Backend.known_deviation`) where the row fails on a run that ran (a row of a run that failed,
    ``measured`` NaN, is not the engine's known miss)."""
    if passed or not math.isfinite(measured):
        return note
    known = cls.known_deviation(case, quantity, info, measured, expected, tolerance)
    return (f"{known}; {note}" if note else known) if known else note


def held(explanation: str, measured: float, predicted: float, tolerance: float, after: str = "") -> str | None:
    """An explanation that is a closed form of the engine's own, given only where it holds: ``explanation``, then
    "met to X %" (the measured value against ``predicted``, relative) and ``after``, where ``measured`` lies within
    ``tolerance`` of ``predicted``; None where it does not (a deviation it does not account for is not explained:
    :meth:`Backend.known_deviation`)."""
    if not abs(measured - predicted) <= tolerance:
        return None
    # relative where the prediction stands clear of 0; a prediction within the tolerance of 0 (a held foot's
    # acceleration, -1e-16) has no scale of its own: the difference itself
    relative = abs(predicted) > tolerance
    met = f"{100 * abs(measured / predicted - 1):.2g} %" if relative else f"{abs(measured - predicted):.2g} (absolute)"
    return f"{explanation}, met to {met}{after}"


def solver_bound_note(solver: str, drag: object, quantity: str, measured: float, tolerance: float,
                      after: str = "") -> str | None:  # fmt: skip
    """A sliding-case row (``quantity``) explained by a friction bound the contact solver sets from a frictionless
    normal impulse (:meth:`Backend.frictionless_normal`), held to the row: ``drag`` is what the sliding case computed
    with that bound (``predicted_bound``, the mean bound / Fn; ``friction_bound``, the one the run slid with,
    measured; ``predicted_holds``, the share of samples at which the
    axis along the drag holds under it; ``at_predicted``, the pyramid's closed form with it for the rows ``along``,
    ``across`` and ``acceleration``), ``solver`` names the solver in the note. None where the run has no prediction,
    the row is none of the three, or its ``measured`` value misses the closed form by more than ``tolerance``."""
    if not isinstance(drag, Mapping) or not isinstance(at := drag.get("at_predicted"), Mapping):
        return None
    key = ("acceleration" if quantity.startswith("slip acceleration") else "across" if "across the drag" in quantity
           else "along" if "along the drag" in quantity else None)  # fmt: skip
    if key is None or key not in at:
        return None
    mu, bound, holds = (float(drag.get(k, math.nan)) for k in ("mu", "predicted_bound", "predicted_holds"))
    along = float(at.get("along", math.nan))
    state = (f"holds under it at every sample (it needs {along:.4g} Fn there; a held foot's rows do not depend on "
             "the bound beyond that, so this checks the bound against the hold's need only)" if holds == 1.0
             else "slides at it at every sample" if holds == 0.0
             else f"holds under it at {100 * holds:.0f} % of the samples")  # fmt: skip
    value, slid = float(at[key]), float(drag.get("friction_bound", math.nan))
    slid_at = f"; measured, the run slid at {slid:.4g} Fn" if holds == 0.0 and math.isfinite(slid) else ""
    return held(f"known: {solver} bounds the friction by mu times the normal impulse solved before the friction "
                f"rows; re-solved without friction at each sample, that bound is predicted at {bound:.4g} Fn (mu "
                f"{mu:g} x Fn0 / Fn{slid_at}), and the axis along the drag {state}: the pyramid's closed form with "
                f"it reads {value:.4g}", measured, value, tolerance, after)  # fmt: skip


def rigid_contact(info: Mapping[str, Any]) -> bool:
    """The backend's info declares its contact rigid: ``contact.Kp`` given and null (:data:`INFO_KEYS`)."""
    contact = info.get("contact")
    return isinstance(contact, Mapping) and "Kp" in contact and contact["Kp"] is None


def reference_contact(contact: ContactParams, applied: str, friction: str) -> dict[str, Any]:
    """:meth:`Backend.info`'s ``contact`` in reference contact mode: the engine's contact off, the law legbench
    applies (its poc and constants: compliant, whatever the engine's own contact is) and how the backend applies it
    (``applied``, with its ``reference_friction`` setting ``friction``: the law's friction slope explicit, or
    linearly implicit over each sub-step); its force is read as the law at the state a step ended in. The engine's
    own contact settings act on nothing there and are left out, so the report's settings table does not list them
    beside the law's."""
    how = (", less K dqd: the friction slope K linearly implicit over the sub-step, dqd from the leg's model "
           "(docs/contact_law.md)" if friction == "implicit" else ", the friction slope explicit")  # fmt: skip
    return {"enabled": False, "poc": contact.poc, "lift": 0.0, "Kp": contact.Kp, "Kd": contact.Kd,
            "mu_s": contact.mu_s, "mu_k": contact.mu_k, "v_th": contact.v_th, "reference_law": applied + how,
            "force_readout": "the law at the end state"}  # fmt: skip


def _is_number(v: object) -> bool:
    return isinstance(v, numbers.Real) and not isinstance(v, bool)


@dataclass(frozen=True)
class Physics:
    """Physics every backend must honour.

    Attributes:
        gravity: magnitude of gravity along -z_W [m/s^2].
        contact: ground contact parameters.
        contact_mode: ``"native"`` (the engine's own contact with the spec's
            parameters mapped onto it) or ``"reference"`` (engine contact off;
            the analytic law of :mod:`legbench.contact` applied as J_poc^T F at
            every sub-step).
        control_dt: control period, the length of one :meth:`Backend.step` [s].
        torque_limit: joint torque limits [N m], applied by the harness; a
            backend may also configure its actuators with them.
    """

    gravity: float = 9.81
    contact: ContactParams = field(default_factory=ContactParams)
    contact_mode: str = "native"
    control_dt: float = 1e-3
    torque_limit: tuple[float, float, float] = (7.051408, 10.07344, 10.07344)


@dataclass(frozen=True)
class Limits:
    """What the loaded engine itself holds and enforces, read back from the engine's model.

    Attributes:
        gravity: gravity magnitude along -z_W [m/s^2].
        lower: lower joint position limits [rad] (``-inf``: none, e.g. the continuous hip).
        upper: upper joint position limits [rad] (``inf``: none).
        effort: torque limits the engine applies [N m] (``inf``: none; the harness saturates anyway).
        timestep: the engine's own integration step [s], ``None`` where it has none (adaptive).
        enforcement: one sentence on how the position limits are enforced (soft constraint,
            hard constraint, penalty spring-damper with its numbers).
    """

    gravity: float
    lower: tuple[float, float, float]
    upper: tuple[float, float, float]
    effort: tuple[float, float, float] = (math.inf, math.inf, math.inf)
    timestep: float | None = None
    enforcement: str = ""


@dataclass(frozen=True)
class Range:
    """The values a number setting of a backend may take (:attr:`Backend.ranges`): ``low <= x <= high``, or
    ``low < x <= high`` where ``open_low``; ``nullable``: ``null`` too (the backend's default for it: off, or
    derived, as the backend documents)."""

    low: float = 0.0
    high: float = math.inf
    open_low: bool = False
    nullable: bool = False

    def problem(self, x: float) -> str | None:
        """Why ``x`` is out of this range (one phrase), or None."""
        if (x <= self.low if self.open_low else x < self.low) or x > self.high:
            return f"must be {self}, got {x:g}"
        return None

    def __str__(self) -> str:
        if self.high == math.inf:
            return f"{'>' if self.open_low else '>='} {self.low:g}"
        return f"in {'(' if self.open_low else '['}{self.low:g}, {self.high:g}]"


def dt_problem(dt: float, control_dt: float) -> str | None:
    """Why a sub-step of ``dt`` [s] cannot make up the control period ``control_dt`` [s] (not positive, or not a
    whole fraction of it), one phrase; None if ``control_dt / dt`` is a whole number >= 1. The one sub-step rule:
    :func:`sub_step_count` and the scenario loader both ask it."""
    ratio = control_dt / dt if dt > 0 else 0.0
    n = round(ratio)
    if n < 1 or abs(ratio - n) > 1e-9:
        return (f"{dt:g} s does not divide the control period {control_dt:g} s "
                f"(choose control_dt / n, e.g. {control_dt / max(n, 1):g} s)")  # fmt: skip
    return None


def sub_step_count(backend: str, dt: float, control_dt: float) -> int:
    """Number of sub-steps of length ``dt`` [s] in one control period ``control_dt`` [s].

    Raises:
        LegbenchError: ``dt`` is not positive or does not divide the control period (:func:`dt_problem`).
    """
    why = dt_problem(dt, control_dt)
    if why is not None:
        raise LegbenchError(f"backends.{backend}.dt: {why}")
    return round(control_dt / dt)


def clamp_torque(tau: np.ndarray, limit: Sequence[float]) -> tuple[float, float, float]:
    """tau [N m] (3,) clamped to +-limit [N m] per joint, as three floats: what ``np.clip(tau, -limit, limit)``
    gives (a NaN passes), without its cost on three numbers (1.2 against 0.15 us per tick)."""
    t1, t2, t3 = tau.tolist()
    l1, l2, l3 = limit
    return (
        -l1 if t1 < -l1 else (l1 if t1 > l1 else t1),
        -l2 if t2 < -l2 else (l2 if t2 > l2 else t2),
        -l3 if t3 < -l3 else (l3 if t3 > l3 else t3),
    )


def check_finite(backend: str, t: float, q: Sequence[float] | np.ndarray, qd: Sequence[float] | np.ndarray) -> None:
    """Raise :class:`SimulationDiverged` if the joint state q [rad], qd [rad/s] at time t [s] is not finite.

    One sum of six floats per control period: cheap enough for every backend's step.
    """
    if not math.isfinite(q[0] + q[1] + q[2] + qd[0] + qd[1] + qd[2]):
        raise SimulationDiverged(backend, t, "non-finite joint state")


class Backend(ABC):
    """A physics engine simulating the leg.

    Subclasses set :attr:`name` and :attr:`defaults` (their settings with
    documented default values) and implement the abstract methods. Settings a
    scenario gives for this backend are merged over :attr:`defaults`; an
    unknown key is an error (the scenario loader checks it against
    :attr:`defaults`).
    """

    name: ClassVar[str]
    #: Backend settings and their defaults, e.g. {"dt": 1e-4, "integrator": "euler"}.
    defaults: ClassVar[Mapping[str, Any]] = {}
    #: Allowed values of string settings, e.g. {"integrator": ("euler", "rk4")}.
    choices: ClassVar[Mapping[str, tuple[str, ...]]] = {}
    #: Allowed values of number settings, where the engine documents them (e.g. an ERP in [0, 1], a CFM >= 0),
    #: and of those whose default is ``None`` (``Range(nullable=True)``). A float setting not listed must be > 0.
    ranges: ClassVar[Mapping[str, Range]] = {}
    #: Number settings that bound the step of an adaptive solve [s] (e.g. ``max_step``): a control period takes at
    #: least control period / value steps, so the scenario loader holds each to the limit on sub-steps per control
    #: tick (``limit("sub_steps")``) as it holds ``dt``, naming the key; the value need not divide the period.
    step_bounds: ClassVar[tuple[str, ...]] = ()
    #: Named settings overlays on :attr:`defaults`. ``matched``: the spec's physics mapped as
    #: faithfully as the engine allows (usually :attr:`defaults` itself, ``{}``);
    #: ``engine-defaults``: what a user gets from the engine's documented defaults with only
    #: Kp, Kd and mu set the engine's usual way. A backend may add more (e.g. ``gazebo``).
    #: Every key of an overlay must be a key of :attr:`defaults`.
    profiles: ClassVar[Mapping[str, Mapping[str, Any]]] = {"matched": {}, "engine-defaults": {}}
    #: The ContactParams coefficient the backend's native contact slides with: ``mu_k`` for the
    #: stick-slip law, ``mu_s`` for an engine whose friction has a single (Coulomb) coefficient.
    sliding_coefficient: ClassVar[str] = "mu_k"
    #: The shape of the native friction limit: ``cone`` (isotropic, |F_t| <= mu Fn, what the law and
    #: the sliding verification's closed form assume), ``pyramid`` (each tangent axis of the contact
    #: frame limited on its own, so |F_t| reaches sqrt(2) mu Fn on the diagonal) or ``diamond``
    #: (|F_t1| + |F_t2| <= mu Fn, so |F_t| is mu Fn / sqrt(2) on the diagonal). Where a setting chooses it, info()
    #: records the one loaded (``friction_cone``, :data:`INFO_KEYS`).
    friction_cone: ClassVar[str] = "cone"
    #: One command that installs the engine where it is missing (shown by the registry).
    install: ClassVar[str] = ""
    #: The profile this instance was loaded with (set by the registry's ``load``).
    profile: str = "matched"

    @classmethod
    def known_deviation(cls, case: str, quantity: str, info: Mapping[str, Any], measured: float = math.nan,
                        expected: float = math.nan, tolerance: float = math.nan) -> str | None:  # fmt: skip
        """Why this backend, run as ``info`` says (its :meth:`info`), misses the verification ``quantity`` of
        ``case``, where that has been measured and explained; None otherwise. Shown beside the row, which still
        fails: an explanation, not a pass. Where the explanation is a closed form of its own (the engine's own
        stiffness, an offset), it should hold the row's ``measured`` value to it within ``tolerance`` (the row's
        units; ``expected`` is the case's closed form) and say nothing when it does not: a miss it does not
        account for is not explained. Consulted by every verification case for its failing rows
        (:func:`explained_note`), and by the contact calibration for a stiffness off Kp (case
        ``rest_penetration``, as the verification's: ``measured`` the second rest's penetration [m]; for a rigid
        contact, ``expected`` 0 and ``info`` with ``load``: its Fn [N]) and a creep off the law's (case ``creep``:
        ``measured`` the creep [m/s], ``expected`` the law's, ``info`` with the held load ``load``: Fn, Ft and the
        mean contact force F in W [N]) and a damping off Kd (case ``damping``: ``measured`` the fitted c eff
        [N s/m], ``expected`` Kd, ``info`` with ``transient``: ``depth``, the fit's samples' penetration weighted as
        the fit weights them, sum(y ydot^2) / sum(ydot^2) [m]). Its explanations may hold the row to what the run
        recorded in ``at_end`` as well (the state it ended in, or a largest share over it)."""
        return None

    def frictionless_normal(self, q: np.ndarray, qd: np.ndarray, tau: np.ndarray) -> float | None:
        """For a contact solver that bounds the friction rows by mu times the normal impulse it solved before them,
        without friction (a boxed LCP solved the Dantzig way: ODE's dWorldStep, DART's Dantzig; exactly so for the
        first friction row): the normal force [N] of that solve, one engine step from q [rad], qd [rad/s] under tau
        [N m] with the friction off, so mu times it is the bound the step's friction had; None where the bound is the
        current normal force or not known (default). Asked by the sliding case after its run, at every sample from
        the drag's start (the sub-step after each logged state, whose force the log reads one sub-step earlier:
        measured on ODE, the two agree to 2e-5 of Fn); it may leave the engine anywhere."""
        return None

    @classmethod
    def rest_sink(cls, info: Mapping[str, Any], fn: float) -> float | None:
        """A rigid native contact's own closed form of the foot's rest penetration [m] under the normal force ``fn``
        [N], run as ``info`` says (its :meth:`info`): what its regularisation lets the foot sink (the verification's
        rest row expects it); None where the backend has none (a compliant contact: the spec's Fn / Kp applies)."""
        return None

    @classmethod
    def rest_sink_text(cls, info: Mapping[str, Any], fn: float) -> str:
        """:meth:`rest_sink` in words with its numbers, for a row's note ('' where it gives None)."""
        return ""

    @classmethod
    def resolve_settings(cls, given: Mapping[str, Any], profile: str = "matched") -> dict[str, Any]:
        """Defaults, overlaid with the profile's settings, overlaid with the scenario's ``given``.

        Raises:
            LegbenchError: ``profile`` is not one of :attr:`profiles`.
        """
        if profile not in cls.profiles:
            raise LegbenchError(
                f"backends.{cls.name}.profile: unknown profile '{profile}'; {cls.name} offers {sorted(cls.profiles)}"
            )
        return {**cls.defaults, **cls.profiles[profile], **given}

    @classmethod
    def settings_problem(
        cls, settings: Mapping[str, Any], contact_mode: str
    ) -> tuple[str | tuple[str, ...], str] | None:
        """A combination of resolved ``settings`` (:meth:`resolve_settings`) that cannot run in ``contact_mode``:
        (the setting's key, or the keys of the settings that cannot go together, the first the one to name when
        the scenario gives several; why, one phrase), or None. The one rule the scenario loader (``legbench
        validate`` and every run's load of the file, which names the key the scenario gave) and the backend's
        :meth:`load` both ask (:meth:`refuse_settings`)."""
        return None

    @classmethod
    def refuse_settings(cls, settings: Mapping[str, Any], contact_mode: str) -> None:
        """Raise what :meth:`settings_problem` finds, for a backend's :meth:`load`.

        Raises:
            LegbenchError: ``backends.<name>.<key>: why``, the first key of a combination.
        """
        bad = cls.settings_problem(settings, contact_mode)
        if bad is not None:
            key = bad[0] if isinstance(bad[0], str) else bad[0][0]
            raise LegbenchError(f"backends.{cls.name}.{key}: {bad[1]}")

    @abstractmethod
    def load(self, urdf: Path, physics: Physics, settings: Mapping[str, Any]) -> None:
        """Build the engine's model of the leg from the generated URDF."""

    @abstractmethod
    def reset(self, q: np.ndarray, qd: np.ndarray) -> None:
        """Set joint positions q [rad] and velocities qd [rad/s]; contact state cleared."""

    @abstractmethod
    def step(self, tau: np.ndarray) -> None:
        """Advance one control period with joint torques tau [N m] held constant."""

    @abstractmethod
    def state(self) -> tuple[np.ndarray, np.ndarray]:
        """Joint positions q [rad] (hip unwrapped, continuous in time) and velocities qd [rad/s]."""

    @abstractmethod
    def ground_force(self) -> np.ndarray:
        """Force of the ground on the foot in W [N] (fx, fy, fz), at the end of the last step."""

    def read(self) -> tuple[float, ...]:
        """(q1, q2, q3, qd1, qd2, qd3, fx, fy, fz): :meth:`state` and :meth:`ground_force` as nine floats, what
        the run loop reads every tick [rad, rad/s, N in W]. A backend may override it with a read that builds
        no arrays; it must return the same numbers."""
        q, qd = self.state()
        f = self.ground_force()
        return (*q.tolist(), *qd.tolist(), *f.tolist())

    @abstractmethod
    def info(self) -> dict[str, Any]:
        """Engine name and version and every physics setting actually used (JSON-serialisable, text keys).

        The keys legbench reads, when given, hold what :data:`INFO_KEYS` says (checked after each run by
        :func:`info_problem`: a backend whose info breaks it fails its run with the reason); the others are
        recorded in run.json as they are.
        """

    # ------------------------------------------------------- declared abilities
    @abstractmethod
    def integrator_family(self) -> str:
        """The loaded integrator's family, one of :data:`INTEGRATOR_FAMILIES` (verification predicts by it)."""

    @abstractmethod
    def sub_steps(self) -> int:
        """Engine steps per control period (1 for an adaptive solve per period)."""

    def slides_with(self) -> str:
        """The ContactParams coefficient this loaded backend's native contact slides with (``mu_k`` or ``mu_s``):
        its ``friction_coefficient`` setting where it has one (:data:`FRICTION_COEFFICIENTS`: the one coefficient of
        a Coulomb contact), else :attr:`sliding_coefficient`; a backend whose other settings change it overrides
        this (recorded in run.json; the contact residuals' friction ratio is taken against it)."""
        coefficient = getattr(self, "cfg", {}).get("friction_coefficient")
        return coefficient if coefficient in FRICTION_COEFFICIENTS else self.sliding_coefficient

    def engine_contact(self) -> bool:
        """True if the engine has a contact model of its own, which ``native`` mode uses; False if it has
        none and both contact modes apply the analytic law of :mod:`legbench.contact`."""
        return True

    @abstractmethod
    def limits(self) -> Limits:
        """Gravity, joint and torque limits as the loaded engine holds them, and how it enforces them."""

    def warnings(self) -> list[str]:
        """Why this run's numbers may not be trusted, one sentence each with its numbers (default none).

        E.g. a sub-step too coarse for the contact law: ``h > m v_th / (mu_s Fn)``. Called after a
        run; the run loop carries the sentences into run.json, the terminal and the report.
        """
        return []

    def kernels(self, q: np.ndarray, qd: np.ndarray, tau: np.ndarray) -> dict[str, Callable[[], None]]:
        """The engine's own calls, for the benchmark's floors (``legbench bench``).

        Args:
            q, qd, tau: states [rad, rad/s] and torques [N m], one row per control period of a
                run, consecutive (N x 3): a kernel may start from the first row's state and step
                through the torques, or use each row on its own.

        Returns:
            name -> a callable that makes one pass over the N rows (inputs prepared beforehand).
            By default a call per row is one sub-step's call (e.g. ``{"aba": ..., "law": ...}``:
            the bench adds such kernels up and multiplies by :meth:`sub_steps`, and by their attribute
            ``calls_per_sub_step`` where the run calls them more than once a sub-step: RK4's four stages, an
            adaptive solve's right-hand sides per period); a callable with
            the attribute ``per_tick = True``, or a name ending in ``_tick``, covers one whole
            control period per row (e.g. ``mj_step(m, d, n)``, a compiled sub-step loop). A callable
            that steps the run itself may carry ``end_state``, a function returning the pass's final
            (q [rad], qd [rad/s]): the bench then checks it against the run's last state bit for bit, as
            it checks the replay, so the floor is known to do the run's work.
        """
        raise NotImplementedError(f"kernels are not supported by {self.name}")

    def close(self) -> None:  # noqa: B027 - optional hook
        """Release engine resources."""

    def mass_properties(self) -> dict[str, dict[str, Any]]:
        """Per moving body (link1, link2, link3 incl. foot): mass [kg], com [m] and inertia
        about the COM [kg m^2], in the link's DH frame, as read back from the engine."""
        raise NotImplementedError(f"mass_properties is not supported by {self.name}")

    def settings(self, given: Mapping[str, Any]) -> dict[str, Any]:
        """Defaults overlaid with the scenario's settings for this backend."""
        return {**self.defaults, **given}
