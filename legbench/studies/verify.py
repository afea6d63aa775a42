"""Verification cases: scenarios whose answer is known in closed form, checked on every backend.

Each case is a scenario in ``scenarios/verification/`` plus a closed-form
answer computed here from the leg's reference model (:class:`legbench.model.Dynamics`):

``energy``
    No torque, no contact, no damping (``energy.yaml``): T + V of the exact
    motion is constant; E is evaluated from each backend's logged (q, qd).
    First-order integrators do not conserve it, and how they drift is known:
    the exact flow conserves E, so E_N - E_0 is the sum of the one-step energy
    errors, e2(x) h^2 + O(h^3) per step, i.e. E(t) - E(0) = h int_0^t e2 dt +
    O(h^2). e2 is computed here for the step the backend declares (family
    ``euler``: velocity-form semi-implicit Euler; ``implicit``: the velocity
    update also holds the Coriolis derivative) along the logged
    motion, and the predicted curve is compared with the measured one over the
    whole run. Tolerance: max|prediction| x (h W + (Ts W)^2), the O(h^2)
    remainder relative to the O(h) term (W = max joint speed) plus the
    trapezoid sum on the 1 ms log, plus round-off 4 sqrt(n) eps |E| (n steps: rounding errors of
    independent steps add as a random walk; n eps, the worst case, was 9e-11 J for RK4, enough to pass RK4 at
    ten times its declared step, 4.9e-11 J, against its 2.3e-14 J at the step). E is
    evaluated on the URDF, which carries the parameter file's numbers exactly
    (written with ``repr``; at 12 significant digits it put 1.2e-11 J between the
    Lagrange model, built from the parameter file, and the reference: now 8e-15 J).
    RK4 (family ``rk4``): predicted the same way one order up: the one-step
    energy error is e5 h^5 + e6 h^6 + O(h^7) (e5, e6 fitted by Richardson on
    RK4 steps of the reference model at each logged state), so E(t) - E(0) =
    h^4 int e5 dt + h^5 (int e6 dt - (e5(t) - e5(0)) / 2) + O(h^6) (the sum over
    steps by Euler-Maclaurin; the integral Simpson's on the 1 ms log); tolerance
    max|prediction| (h W + (Ts W)^2) + round-off 4 sqrt(n) eps |E|. At the
    declared 50 us RK4's drift (5e-15 J) is below round-off (2.3e-14 J
    measured), so that run alone passes a real step up to ~3 times the declared
    one; the check therefore also runs the backend's RK4 at its own step, the
    control period over :data:`RK4_CHECK_SUB_STEPS` (0.5 ms), where the drift,
    4.92e-11 J, is 290 times the round-off bound and met to 1.3e-14 J (tolerance
    6.5e-13 J): a real step twice the declared one misses by 7.3e-10 J. The row
    shows the run (declared step or the check's) furthest beyond its tolerance
    and passes iff both are within theirs. (The former bound, (h W)^4 W T_end
    max T + round-off = 1.5e-11 J, passed a step up to ~7 times the declared.)
    Adaptive (a 5(4) pair with local extrapolation, or DOP853): expected 0, to
    (h W)^5 W T_end max T + round-off over n = T_end / h steps with the longest
    step it can take, h = max_step (at most the control period): a shorter step
    chosen by its error control only lowers the error, and the bound of that
    error control, n_periods (rtol |x| + atol) |grad E|, is 5e-4 J (Pinocchio)
    and 3e-3 J (Lagrange's atol 1e-6): larger than semi-implicit Euler's
    max |E - E0| at 50 us, 4.9e-4 J, so it cannot tell a fifth-order step from a
    first-order one, while this bound (8.2e-13 J at max_step 1e-4 s) can. What
    it detects: a drift above 8.2e-13 J, i.e. any first- to third-order step, and
    RK4 at steps over ~1.8e-4 s (3.1e-12 J at 2.5e-4 s). What it cannot: the
    solvers' own truncation is below round-off at every step up to the control
    period (Pinocchio's rk45 at max_step 1e-4, 5e-4, 1e-3 s: 1.4e-14, 1.1e-14,
    3.8e-13 J; dop853 1.2e-14, 6e-15, 4e-15 J), so no drift can be predicted
    and no order measured: a 5(4) pair ignoring its max_step (rk45 taking 1 ms
    steps drifts 3.8e-13 J, within the bound), RK4 at steps up to ~1.8e-4 s
    (8e-14 J at 1e-4 s), or a wrong rtol / atol pass. A backend
    declaring the family ``first-order`` (a first-order step with no closed form here,
    e.g. one in maximal coordinates): no prediction of the drift D_h(t) = E(t) - E(0),
    so the check is that it is the step's own, D_h = a h + O(h^2) (Richardson): the
    same run at h/2 and h/4, and the remainder R_h = max |D_h - 2 D_h/2| of order 2 in h,
    log2(R_h / R_h/2) >= 1.5 (ODE: 2.003 at 50 us, 2.057 with its quick step at 1 ms),
    where a defect that does not vanish with h (a damping, a solver's energy leak:
    order -1 for a per-step damping) does not fall 4x; one-sided (a remainder that
    falls faster is no defect), and R_h/2 at round-off passes.
``rest_penetration``
    The effort task at rest (``effort_rest.yaml``): mean y = mean Fn/Kp over the
    window. Tolerance: 0.1 % of y (the engines' contact solvers) plus the damping
    force's mean over the window over Kp (the means differ by exactly that):
    Kd |mean(ydot)|/Kp for an engine's own contact, whose damper acts both ways,
    Kd mean(max(ydot, 0))/Kp for a law backend (the spec's law damps only while
    pressing in). Not Kd max|ydot|/Kp: a jitter that leaves the mean rest where it
    is made that 85 um on a 5.2 mm rest (ODE's engine-defaults quick step, max|ydot|
    7.9 mm/s; its mean damping allows 0.06 um). A backend whose native
    contact is rigid (``info()["contact"]["Kp"]`` is None) has no spring, so
    neither Fn / Kp nor the damping allowance applies: expected the engine's own
    closed form of its sink under the window's mean Fn, where its class gives
    one (a classmethod ``rest_sink(info, Fn)`` [m]; DART: its constraint force
    mixing and error reduction, cfm A_nn Fn h^2 / ERP, 6.1173e-10 m at 50 us,
    met to 2.5e-6 of it, 2.448e-7 m at 1 ms, to 3e-8), within 0.1 % of it (the
    contact solver's share, as a compliant rest's); one with no closed form is
    expected not to sink, y = 0, within :data:`RIGID_REST_BOUND` (1 um; it was
    0.1 % of Fn / Kp plus that spring's damping, 5.1 um, 8300 times DART's sink
    at 50 us). A law backend (one that applies the
    spec's law itself: no contact of its own, ``Backend.engine_contact()`` False,
    or reference contact mode; :func:`applies_law`) reads Fn as the law at the
    logged y, so its residual is -Kd mean(max(ydot, 0))/Kp by construction: the
    row checks the force read-out's consistency, not the engine.
``static_balance``
    Same run: F = -(J_poc^T)^-1 (tau - G(q)) per component of the ground force, at
    every tick of the window, each tick against its own tolerance (the row shows the
    tick with the largest error over its tolerance, and passes iff every tick is
    within its own; the largest tolerance of the window against the worst error let a
    tick 12 times over its own pass beside another tick's large dynamic term), and
    the leg at rest: the inertial force |(J_poc^T)^-1 (M qdd + C qd)| within
    0.1 % of |F| at every tick (:data:`AT_REST_RTOL`; else the row fails, not at rest).
    Tolerance at a tick: the dynamic terms left, |(J_poc^T)^-1 (M qdd + C qd)|
    with qdd the central difference of the 1 kHz log, plus the held torque's
    step at the sample, |(J_poc^T)^-1| |tau_k - tau_{k-1}| (the central
    difference averages the step out, the contact's slow normal mode does not
    follow it within the period: 2e-4 N here, Pinocchio's whole 5e-5 N). An
    engine's own contact is checked at the point it declares (its info's
    ``contact.lift``: MuJoCo halfway through the penetration, Drake's discrete
    plant by the two stiffnesses, the others the sphere's lowest point), plus
    1e-5 of |F| (its contact solver, :data:`BALANCE_SOLVER_RTOL`: measured at
    most 1.2e-6 |F|, Drake's; it was 0.1 %); one that declares no point adds the lever
    of the force's application point (anywhere between the undeformed sphere's
    lowest point and the ground surface, a band of height y):
    |(J_poc^T)^-1| y |F_t| (0.48 N here). A law backend applies the force at the
    point its law declares (J_poc of its ``poc``), exactly, with no contact
    solver: no lever term (a lever error of y moves F by 0.02-0.2 N, which it
    must catch) and round-off 8 eps (|F| + |(J_poc^T)^-1| (|tau| + |G|))
    instead of the solver's share of |F|; an adaptive one adds the law's slopes times the
    state error one step of its solver admits, |J_poc| ((max(mu_s, 2|mu_s -
    mu_k|) Fn / v_th + Kd (1 + mu_s)) e_qd + Kp (1 + mu_s) e_q) with e =
    sqrt(6) (atol + rtol |x|) (scipy's RMS error norm <= 1): the law reads the
    state, and the friction's slope mu_s Fn / v_th = 3.7e4 N s/m makes Lagrange's
    atol 1e-6 worth 0.06 N (measured 0.023 N; 5e-5 N at atol 1e-10).
``small_oscillation``
    PD hold about q_eq from a 1e-4 rad offset (``small_oscillation.yaml``): the
    closed-loop poles. Expected: eigenvalues of the linearised loop
    M dq'' + dG/dq dq = du with du = -Kp dq_k - Kd (dq_k - dq_{k-1})/Ts as the
    harness computes it at 1 kHz, torque held over the period, the plant
    discretised by the backend's own sub-step integrator (semi-implicit Euler,
    RK4, or the exact flow for adaptive ones), so the effect of sampling is
    part of the answer, not an error; the continuous-time poles are given in
    the note for contrast. Measured: poles fitted to the response by the
    matrix pencil method. Tolerance: 0.5 % of |s| per pole (the response
    departs from the linear model by 2e-5 of its amplitude; the pencil of
    three close, heavily damped modes amplifies that by up to ~100). Family
    ``first-order``: the exact flow as the model and 0.5 % + h |s| (the O(h |s|) pole
    shift of any first-order step).

Data flow: scenario -> :func:`legbench.run.simulate` on each backend ->
:class:`Check` (frozen, numbers) -> :func:`verify` (a DataFrame with columns
``case, backend, variant, quantity, unit, measured, expected, error,
tolerance, pass, status, note``) -> :func:`write_verification` (``verification.json``
and ``verification.md``).
"""

from __future__ import annotations

import argparse
import dataclasses
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import scipy.integrate
import scipy.linalg
from scipy.optimize import linear_sum_assignment

from legbench import backends as registry
from legbench import kinematics, model, resources
from legbench import scenario as scenario_mod
from legbench.backends.base import FAMILY_TEXT, PROFILES, Physics, contact_point, explained_note, rigid_contact
from legbench.exceptions import LegbenchError
from legbench.results import (
    atomic_write_text,
    check_study_out,
    checks_summary,
    platform_info,
    study_dir,
    versions,
    write_json,
)
from legbench.run import backend_rates, simulate
from legbench.scenario import physics_of
from legbench.studies.executors import DEFAULT_PRELOAD, make_executor
from legbench.studies.sliding_case import TOL_ACC, TOL_ANGLE, TOL_MU, WINDOW, applies_law, sliding_case

__all__ = [
    "CASES",
    "COLUMNS",
    "VERIFICATION_DIR",
    "Check",
    "add_cli",
    "applies_law",
    "check_energy",
    "check_rest",
    "check_small_oscillation",
    "discrete_loop",
    "every_integrator",
    "matrix_pencil",
    "scope",
    "verify",
    "write_verification",
]

VERIFICATION_DIR = resources.scenarios_dir() / "verification"
#: The scenarios of the energy, rest (penetration and balance) and small-oscillation cases.
ENERGY_SCENARIO = VERIFICATION_DIR / "energy.yaml"
REST_SCENARIO = VERIFICATION_DIR / "effort_rest.yaml"
OSCILLATION_SCENARIO = VERIFICATION_DIR / "small_oscillation.yaml"
CASES = ("energy", "rest_penetration", "static_balance", "small_oscillation", "sliding")
COLUMNS = ("case", "backend", "variant", "quantity", "unit", "measured", "expected", "error", "tolerance", "pass",
           "status", "note")  # fmt: skip
#: Row status: ``pass``, ``fail``, or ``not-applicable`` (no closed-form prediction for the backend's
#: integrator family; the note says why).
STATUSES = ("pass", "fail", "not-applicable")
#: The discrete plant each small-oscillation model steps with, in words for the rows' notes.
MODEL_TEXT = {"euler": "semi-implicit Euler steps", "rk4": "RK4 steps", "exact": "the exact flow over each step"}
#: Relative tolerance on each closed-loop pole (module docstring).
POLE_RTOL = 5e-3
#: Share of the rest penetration the engines' contact solvers may miss by (rest check; a rigid contact's: of its own
#: sink). Measured: MuJoCo 1.2e-4 of y (matched: its soft contact's mean rest 0.64 um off Fn / Kp), PyBullet
#: 1.5e-5, Drake 2e-8, DART's sink its closed form to 2.5e-6 (round-off of the foot's height); not tightened: 1e-4
#: would fail MuJoCo's matched rest, which meets its own contact's law.
SOLVER_RTOL = 1e-3
#: A rigid native contact (info ``contact.Kp`` None) whose backend gives no closed form of its sink
#: (``rest_sink(info, Fn)``, a classmethod) is expected not to sink, within this [m]: 2e-4 of the compliant rest
#: (5.2 mm); a rigid contact sinks only by its solver's regularisation (DART: 6.1e-10 m at 50 us, 2.4e-7 m at
#: 1 ms, each its own closed form). Not SOLVER_RTOL of Fn / Kp (5.1 um), a spring the engine does not have.
RIGID_REST_BOUND = 1e-6
#: At rest, the static balance's inertial force |(J_poc^T)^-1 (M qdd + C qd)| is at most this share of |F| at every
#: tick of the window. The dynamic allowance is an estimate (a central difference of the 1 kHz log, blind at the
#: log's Nyquist rate, where an alternating qd reads qdd = 0), fit to stand in for motion too small to matter; above
#: 0.1 % of |F| the row would test that estimate, not the static closed form. Measured: at most 3.3e-5 |F| (MuJoCo,
#: engine-defaults), 1.2e-6 (Lagrange), the others below 1e-8; ODE's engine-defaults quick step jitters at up to
#: 0.17 |F|. (It was the contact solver's share, 0.1 %, when that was; at BALANCE_SOLVER_RTOL, 1e-5, MuJoCo's
#: engine-defaults rest, which meets the balance within its tolerance, would read as moving.)
AT_REST_RTOL = 1e-3
#: Share of |F| an engine's contact solver may miss the static balance by (at every tick, beside the dynamic terms).
#: Measured at the worst tick, matched: Drake 6.1e-5 N (1.2e-6 |F|, err/tol 0.115 at this share, 1.2e-3 at the
#: former 1e-3), PyBullet 1.1e-7 N, DART 1.1e-8 N, MuJoCo 2e-14 N, ODE 9e-14 N; engine-defaults: Drake 4.9e-5 N
#: (err/tol 0.087), DART 4.8e-6 N (0.009), PyBullet 1.6e-7 N, MuJoCo 6.3e-3 N (0.36: its tolerance there is the
#: dynamic term). 1e-5 |F| (5.3e-4 N) holds the largest with 8.7 times to spare; 1e-3 allowed a solver a thousand
#: times worse than any measured. No engine-defaults row that passed at 1e-3 fails at 1e-5 (ODE's quick step fails
#: either way: not at rest).
BALANCE_SOLVER_RTOL = 1e-5
#: A first-order family's Richardson remainder R_h = max|D_h - 2 D_h/2| (the energy drift at h less twice its drift
#: at h/2) is O(h^2) when the drift is the step's own: its order log2(R_h / R_h/2) must be no more than this below 2
#: (one-sided: a remainder that falls faster is no defect; R_h/2 at round-off passes). Measured:
#: ODE 2.003 (dWorldStep, 50 us), 2.057 (its quick step at 1 ms); a per-step velocity damping, an error that does
#: not vanish with h, gives -1.0 (2e-8 at 50 us) and -1.4 (4e-7 at 1 ms). (A fixed share of the drift instead, 5 %,
#: failed correct steps at 1 ms, where the second-order part is 15 % of the drift with ODE's exact solver too.)
REMAINDER_ORDER, REMAINDER_ORDER_TOL = 2.0, 0.5
EPS = float(np.finfo(float).eps)
#: The largest step [s] of the Richardson fit of RK4's one-step energy error, e5 h^5 + e6 h^6 (fitted at this step,
#: half and a quarter of it): eta W = 0.076 at the energy case's W = 18.9 rad/s, where two-step fits from 8 ms and
#: from 4 ms agreed to 5e-5 of e5, and the quarter step's energy change, 4.4e-13 J, is ~400 times the round-off of
#: E (eps |E| = 1e-15 J).
RK4_ETA = 4e-3
#: RK4's energy check also runs at the control period over this many steps (0.5 ms; the check's own step, where
#: the declared one is shorter): at the declared 50 us RK4's drift (5e-15 J predicted) is below round-off
#: (2.3e-14 J measured), so a step up to 3.2 times the declared one (drift x 3.2^4) stays within the round-off
#: bound there; at 0.5 ms the predicted drift, 4.92e-11 J, is 290 times the round-off bound (1.7e-13 J) and met to
#: 1.3e-14 J (2.7e-4 of itself) against a tolerance of 6.5e-13 J, so a real step 2 times the declared one (16 times
#: the drift) fails by a factor 1000, and one 1.05 times it (1.22 times the drift) by 16. Two steps per period, so a
#: step twice the declared one still fits in a period.
RK4_CHECK_SUB_STEPS = 2
#: The profile every backend is loaded in unless another is asked for (the case scenario's backend settings over
#: it). Recorded in verification.json (``profile``).
VERIFY_PROFILE = PROFILES[0]


def every_integrator(profile: str) -> bool:
    """Whether ``profile``'s verification runs every integrator a backend offers (the matched profile's) or only
    the profile's own (another: the engine as its settings have it)."""
    return profile == VERIFY_PROFILE


def scope(profile: str) -> str:
    """What runs in ``profile``, in one sentence (the report shows it beside the profile). Recorded in
    verification.json (``scope``). The matched profile verifies every integrator a backend offers; another profile
    is the engine as its settings have it, one integrator (:func:`every_integrator`)."""
    if every_integrator(profile):
        return ("the case scenario's backend settings over the profile's; the variant column names the integrator "
                "and step: the energy case once per integrator a backend offers, the small oscillation also with RK4 "
                "where offered, the sliding drag in native contact")  # fmt: skip
    return ("the case scenario's backend settings over the profile's; the profile's own integrator and step only, "
            "the engine as its settings have it, which the variant column names; the sliding drag in native "
            "contact")  # fmt: skip


#: How each case's tolerance is derived, in one line (the module docstring has the derivation; each row's note its
#: own terms and numbers). Recorded in verification.json (``tolerance_basis``), which the report shows on hover.
TOLERANCE_BASIS = {
    "energy": "a first-order step with a closed form: max |predicted drift| x (h W + (Ts W)^2), the O(h^2) "
    "remainder and the 1 ms log's trapezoid sum, + round-off 4 sqrt(n) eps |E|; a first-order step without one: "
    f"the Richardson remainder max|D_h - 2 D_h/2| of order at least {REMAINDER_ORDER - REMAINDER_ORDER_TOL:g} in h "
    "(runs at h, h/2, h/4: the drift is the step's own); RK4: the predicted drift h^4 int e5 dt + h^5 (int e6 dt - "
    "(e5(t) - e5(0)) / 2) within max|pred| (h W + (Ts W)^2) + round-off, at the declared step and at the check's "
    f"own Ts / {RK4_CHECK_SUB_STEPS} (where truncation, not round-off, dominates: it fails a real step 2x the "
    "declared one), the row the run furthest beyond its tolerance; adaptive: expected 0 within (h W)^5 W T_end "
    "max T at h = max_step + round-off (8.2e-13 J: it fails a first- to third-order step and RK4 over ~1.8e-4 s; "
    "its own truncation is below round-off, so it cannot see a max_step ignored or a wrong rtol/atol)",
    "rest_penetration": f"mean y against mean Fn / Kp: {SOLVER_RTOL * 100:g} % of y (the contact solver) + the "
    "damping force's mean over the window / Kp (an engine's damper both ways: Kd |mean ydot| / Kp; the spec's law, "
    "pressing in only: Kd mean(max(ydot, 0)) / Kp); a rigid contact: the engine's own closed form of its sink at "
    f"mean Fn (the backend's rest_sink) within {SOLVER_RTOL * 100:g} % of it, else y = 0 within "
    f"{RIGID_REST_BOUND:g} m",
    "static_balance": "every tick of the window within its own tolerance (the row: the tick furthest beyond it), at "
    f"rest (the inertial force within {AT_REST_RTOL * 100:g} % of |F| at every tick): the tick's dynamic term "
    "|(J_poc^T)^-1 (M qdd + C qd)| + the held torque's step, "
    f"+ {BALANCE_SOLVER_RTOL:g} |F| for an engine's contact solver (a law backend: round-off 8 eps, and the "
    "law's slopes times one solver step's state error if adaptive), + the lever |(J_poc^T)^-1| y |F_t| where an "
    "engine declares no point",
    "small_oscillation": f"{POLE_RTOL * 100:g} % of |s| per pole (the pencil fit of three close, heavily damped "
    f"modes); a first-order step of unknown form: ({POLE_RTOL * 100:g} % + h |s|) of |s|, h |s| the pole shift any "
    "first-order step may have; a damping ratio zeta = -Re(s) / |s| within the largest change the pole's "
    "tolerance allows it, rel sqrt(1 - zeta^2)",
    "sliding": f"friction |F_t| / Fn within {TOL_MU * 100:g} % of mu at every sample of the window (its worst), "
    f"its angle to -slip within {TOL_ANGLE:g} deg, "
    f"the slip acceleration (along the slip: positive where it speeds up) within {TOL_ACC * 100:g} % of the closed "
    "form M^-1 (tau - nle + J_poc^T F), with the "
    "friction the run declares: a cone as said, a pyramid axis by axis (the sliding axis at mu Fn, the other's force "
    "the closed form's), a diamond at (|F_x| + |F_y|) / Fn = mu and its angle to the diamond's vertex",
}


@dataclass(frozen=True)
class Check:
    """One verified quantity on one backend.

    Attributes:
        case: one of :data:`CASES`.
        backend: backend name.
        variant: the backend settings that matter (e.g. ``integrator=rk4``).
        quantity: what is compared (``max |E - E0|``, ``Fz``, ``mode 1 frequency``).
        unit: its unit.
        measured: value from the simulation.
        expected: closed-form value.
        error: |measured - expected|.
        tolerance: allowed error (module docstring says why).
        passed: error <= tolerance (False for a not-applicable row).
        status: ``pass``, ``fail`` or ``not-applicable`` (:data:`STATUSES`).
        note: context (family, sub-step, continuous-time value, ...).
    """

    case: str
    backend: str
    variant: str
    quantity: str
    unit: str
    measured: float
    expected: float
    error: float
    tolerance: float
    passed: bool
    note: str = ""
    status: str = ""

    def __post_init__(self) -> None:
        if not self.status:
            object.__setattr__(self, "status", "pass" if self.passed else "fail")


def _check(case: str, backend: str, variant: str, quantity: str, unit: str, measured: float, expected: float,
           tolerance: float, note: str = "") -> Check:  # fmt: skip
    error = abs(measured - expected)
    ok = bool(math.isfinite(error) and error <= tolerance)
    return Check(case, backend, variant, quantity, unit, float(measured), float(expected), float(error),
                 float(tolerance), ok, note)  # fmt: skip


def _failed(case: str, backend: str, variant: str, reason: str) -> Check:
    return Check(case, backend, variant, "run", "", math.nan, math.nan, math.nan, math.nan, False, reason)


def _not_applicable(case: str, backend: str, variant: str, quantity: str, family: str) -> Check:
    why = (f"integrator family '{family}': no closed-form prediction of {quantity} for this integrator; "
           "measured only")  # fmt: skip
    return Check(case, backend, variant, quantity, "", math.nan, math.nan, math.nan, math.nan, False, why,
                 "not-applicable")  # fmt: skip


# --------------------------------------------------------------------------- #
# Running a backend


def _variants(name: str, base: Mapping[str, Any], integrators: Sequence[str] | None,
              profile: str = VERIFY_PROFILE) -> list[dict[str, Any]]:  # fmt: skip
    """Backend settings to verify: the scenario's, once per integrator the backend offers (or once; once in a
    profile other than the matched one: its own integrator, :func:`scope`)."""
    cls = registry.get(name)
    offered = cls.choices.get("integrator")
    if not offered or not every_integrator(profile):
        return [dict(base)]
    chosen = [i for i in offered if integrators is None or i in integrators]
    return [{**base, "integrator": i} for i in chosen]


def _family(info: Mapping[str, Any]) -> str:
    """The run's integrator family as its backend declared it (recorded in the run's backend info)."""
    return str(info["integrator_family"])


def _sub_step(info: Mapping[str, Any], control_dt: float) -> float:
    """The backend's integration sub-step [s]: the control period over its declared sub-step count."""
    return control_dt / float(info["sub_steps"])


def _variant(info: Mapping[str, Any], control_dt: float) -> str:
    if "integrator_family" not in info or "sub_steps" not in info:  # a failed run's info may lack them
        return str(info.get("integrator", "?"))
    integ = info.get("integrator", FAMILY_TEXT.get(_family(info), "?"))
    if _family(info) == "adaptive" and "max_step" in info:  # its steps are bounded by max_step, not a sub-step
        return f"integrator={integ} max_step={float(info['max_step']):g}"
    return f"integrator={integ} dt={_sub_step(info, control_dt):g}"


def _explained(checks: list[Check], infos: Mapping[tuple[str, str], Mapping[str, Any]]) -> list[Check]:
    """``checks`` with each failing row's measured and explained miss (``Backend.known_deviation`` of the run's
    info, ``infos`` by (backend, variant): :func:`~legbench.backends.base.explained_note`) before its note: an
    explanation, the row still fails."""
    out = []
    for c in checks:
        info = infos.get((c.backend, c.variant))
        if info is None or c.status != "fail":
            out.append(c)
            continue
        note = explained_note(registry.get(c.backend), c.case, c.quantity, info, c.passed, c.measured, c.expected,
                              c.tolerance, c.note)  # fmt: skip
        out.append(dataclasses.replace(c, note=note))
    return out


def _simulate(scenario: Any, name: str, physics: Physics, settings: Mapping[str, Any], profile: str) -> Any:
    backend = registry.load(name, physics, settings, profile)
    try:
        return simulate(scenario, backend, physics)
    finally:
        backend.close()


# --------------------------------------------------------------------------- #
# Energy


class _Energy(model.Dynamics):
    """Energy of the leg from (q, qd) on the reference model, and one-step integrator maps."""

    def __call__(self, q: np.ndarray, qd: np.ndarray) -> tuple[float, float]:
        """(T [J], V [J])."""
        return self.energy(q, qd)

    def along(self, tr: Any) -> tuple[np.ndarray, np.ndarray]:
        """(T, V) at every logged state of run ``tr``, (n, 2) [J], and the drift D(t) = E(t) - E(0), (n,) [J]."""
        TV = np.array([self.energy(q, qd) for q, qd in zip(tr.q, tr.qd, strict=True)])
        return TV, TV.sum(axis=1) - TV[0].sum()

    def step(self, q: np.ndarray, qd: np.ndarray, h: float, family: str) -> tuple[np.ndarray, np.ndarray]:
        """One zero-torque step of length h [s] of a first-order family.

        ``euler``: qd' = qd + h qdd(q, qd), q' = q + h qd' (velocity-first
        semi-implicit Euler). ``implicit``: the velocity update implicit in the
        bias's velocity derivative, (M + h D) (qd' - qd) = -h b with the bias
        b = C qd + G and D = db/dqd, then q' = q + h qd'.
        """
        qd1 = qd + h * self.free_qdd(q, qd, h if family == "implicit" else 0.0)
        return q + h * qd1, qd1

    def free_qdd(self, q: np.ndarray, qd: np.ndarray, h_implicit: float = 0.0) -> np.ndarray:
        """The zero-torque acceleration -M^-1 b [rad/s^2], b = C qd + G the bias; with ``h_implicit`` > 0 [s], the
        implicit step's -(M + h D)^-1 b, D = db/dqd."""
        M = self.mass_matrix(q)
        if h_implicit > 0.0:
            M = M + h_implicit * self.bias_velocity_derivative(q, qd)
        return np.linalg.solve(M, -self.inverse_dynamics(q, qd, np.zeros(3)))

    def rk4_step(self, q: np.ndarray, qd: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
        """One zero-torque classic RK4 step of length h [s] of (q, qd)' = (qd, -M^-1 b)."""

        def f(x: np.ndarray) -> np.ndarray:
            return np.concatenate([x[3:], self.free_qdd(x[:3], x[3:])])

        x = np.concatenate([q, qd])
        k1 = f(x)
        k2 = f(x + h / 2 * k1)
        k3 = f(x + h / 2 * k2)
        k4 = f(x + h * k3)
        x1 = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        return x1[:3], x1[3:]

    def rk4_rates(self, q: np.ndarray, qd: np.ndarray, eta: float = RK4_ETA) -> tuple[float, float]:
        """(e5 [J/s^5], e6 [J/s^6]) in E(rk4_h(x)) - E(x) = e5(x) h^5 + e6(x) h^6 + O(h^7): the quotient
        (E(rk4_s(x)) - E(x)) / s^5 at s = eta, eta/2, eta/4 fitted by e5 + e6 s + e7 s^2 (Richardson)."""
        E0 = sum(self(q, qd))
        s = eta / np.array([1.0, 2.0, 4.0])
        r = [(sum(self(*self.rk4_step(q, qd, float(si)))) - E0) / si**5 for si in s]
        e5, e6, _ = np.linalg.solve(np.vander(s, 3, increasing=True), r)
        return float(e5), float(e6)

    def local_rate(self, q: np.ndarray, qd: np.ndarray, family: str, eta: float = 1e-3) -> float:
        """e2 [J/s^2] in E(step_h(x)) - E(x) = e2(x) h^2 + O(h^3), by Richardson extrapolation in h."""
        E0 = sum(self(q, qd))
        r1 = (sum(self(*self.step(q, qd, eta, family))) - E0) / eta**2
        r2 = (sum(self(*self.step(q, qd, eta / 2, family))) - E0) / (eta / 2) ** 2
        return 2.0 * r2 - r1


def check_energy(
    backends: Sequence[str], scenario_file: Path = ENERGY_SCENARIO,
    integrators: Sequence[str] | None = None, profile: str = VERIFY_PROFILE,
) -> list[Check]:  # fmt: skip
    """Energy with no torque, contact or damping, per backend and integrator (module docstring), in ``profile``."""
    sc = scenario_mod.load(scenario_file)
    base = physics_of(sc, "reference")
    physics = dataclasses.replace(base, contact=dataclasses.replace(base.contact, Kp=0.0, Kd=0.0))
    energy = _Energy(sc.gravity)
    lower, upper = model.load_params().lower, model.load_params().upper
    Ts = sc.control_dt
    out: list[Check] = []
    infos: dict[tuple[str, str], Mapping[str, Any]] = {}
    for name in backends:
        for settings in _variants(name, sc.backends.get(name, {}), integrators, profile):
            tr = _simulate(sc, name, physics, settings, profile)
            variant = _variant(tr.info, Ts)
            infos[name, variant] = tr.info
            if tr.status != "ok":
                out.append(_failed("energy", name, variant, tr.reason or tr.status))
                continue
            TV, D = energy.along(tr)
            family = _family(tr.info)
            h = _sub_step(tr.info, Ts)
            roundoff = _roundoff(TV, (len(tr.t) - 1) * round(Ts / h))
            W = float(np.abs(tr.qd).max())
            inside = bool(np.all((tr.q >= lower - 1e-9) & (tr.q <= upper + 1e-9)))
            invalid = "" if inside else "; INVALID: a joint limit was reached"
            if family in ("euler", "implicit"):
                e2 = np.array([energy.local_rate(q, qd, family) for q, qd in zip(tr.q, tr.qd, strict=True)])
                P = h * np.concatenate([[0.0], np.cumsum(0.5 * (e2[1:] + e2[:-1]) * np.diff(tr.t))])
                tol = _drift_tolerance(P, h, Ts, W, roundoff)
                note = (f"{family} x{round(Ts / h)}: predicted E(t) - E(0) = h int e2 dt (local energy error "
                        f"e2 h^2 per step); error = max over t of |measured - predicted|; max|E - E0| = "
                        f"{np.abs(D).max():.3g} J; W = {W:.3g} rad/s{invalid}")  # fmt: skip
                err = float(np.abs(D - P).max())
                out.append(Check("energy", name, variant, "E(t_end) - E(0)", "J", float(D[-1]), float(P[-1]), err,
                                 tol, bool(inside and err <= tol), note))  # fmt: skip
                continue
            if family == "first-order":
                # no closed form for the step (e.g. one in maximal coordinates): the drift must be the step's own,
                # D_h = a h + O(h^2) (Richardson): the remainder R_h = max|D_h - 2 D_h/2| is O(h^2), so it falls 4x
                # from h to h/2, where a defect that does not vanish with h (a damping, a solver's energy leak)
                # does not (the same runs at h/2 and h/4)
                finer = [_simulate(sc, name, physics, {**settings, "dt": h / 2.0**k}, profile) for k in (1, 2)]
                bad = next((r for r in finer if r.status != "ok" or len(r.t) != len(tr.t)), None)
                if bad is not None:
                    out.append(_failed("energy", name, variant, f"the run at a finer step: {bad.reason or bad.status}"))
                    continue
                D2, D4 = (energy.along(r)[1] for r in finer)
                drifts = [float(np.abs(x).max()) for x in (D, D2, D4)]
                R1, R2 = float(np.abs(D - 2.0 * D2).max()), float(np.abs(D2 - 2.0 * D4).max())
                order = math.log2(R1 / R2) if R1 > 0.0 and R2 > 0.0 else math.nan
                # R_h/2 holds the h/2 and h/4 runs' round-off, (sqrt 2 + 4) times the h run's: 12 x leaves a margin
                floor = 12.0 * roundoff
                at_roundoff = R2 <= floor  # nothing left to fall: R_h/2 is round-off
                share = 100 * R1 / drifts[0]
                why = (f"first order x{round(Ts / h)}: no closed-form prediction; Richardson: the same run at h/2 and "
                       f"h/4, max|E - E0| {drifts[0]:.4g}, {drifts[1]:.4g}, {drifts[2]:.4g} J; remainder R = max|D_h - "
                       f"2 D_h/2| {R1:.4g} J at h, {R2:.4g} J at h/2 ({share:.1f} % of the drift at h): its "
                       f"order log2(R_h / R_h/2) must be at least {REMAINDER_ORDER - REMAINDER_ORDER_TOL:g} (the "
                       f"step's own O(h^2); error: how far below {REMAINDER_ORDER:g}), W = {W:.3g} rad/s"
                       + ("; R_h/2 at round-off" if at_roundoff else ""))  # fmt: skip
                # one-sided: the defect is a remainder that does not fall; one falling faster than h^2 is fine
                short = max(REMAINDER_ORDER - order, 0.0) if math.isfinite(order) else math.inf
                ok = at_roundoff or short <= REMAINDER_ORDER_TOL
                c = Check("energy", name, variant, "order of R_h = max|D_h - 2 D_h/2| in h", "1", order,
                          REMAINDER_ORDER, short, REMAINDER_ORDER_TOL, ok, why + invalid)  # fmt: skip
                out.append(c if inside else dataclasses.replace(c, passed=False, status="fail"))
                continue
            if family == "rk4":
                runs = [("declared", tr, h)]
                h_c = Ts / RK4_CHECK_SUB_STEPS  # the check's own step, where truncation dominates round-off
                if h < h_c * (1.0 - 1e-9) and "dt" in registry.get(name).defaults:
                    coarse = _simulate(sc, name, physics, {**settings, "dt": h_c}, profile)
                    if coarse.status != "ok" or len(coarse.t) != len(tr.t):
                        out.append(_failed("energy", name, variant, f"the run at the check's step {h_c:g} s: "
                                           f"{coarse.reason or coarse.status}"))  # fmt: skip
                        continue
                    runs.append(("check's", coarse, _sub_step(coarse.info, Ts)))
                rk4_fits = [_rk4_drift(energy, r, hr, Ts, (TV, D) if r is tr else None) for _, r, hr in runs]
                w = max(range(len(runs)), key=lambda i: rk4_fits[i][2] / rk4_fits[i][3])  # the furthest beyond its own
                texts = [f"{label} h = {hr:g} s: max|E - E0| = {d[4]:.3g} J, predicted {d[5]:.3g} J, error "
                         f"{d[2]:.3g} J, tolerance {d[3]:.3g} J (round-off {d[6]:.2g} J)"
                         for (label, _, hr), d in zip(runs, rk4_fits, strict=True)]  # fmt: skip
                note = (f"RK4 x{round(Ts / h)}: predicted E(t) - E(0) = h^4 int e5 dt + h^5 (int e6 dt - (e5(t) - "
                        f"e5(0)) / 2) (one-step energy error e5 h^5 + e6 h^6 on the reference model, the sum over "
                        f"steps by Euler-Maclaurin); error = max over t of |measured - predicted|; tolerance max|pred| "
                        f"(h W + (Ts W)^2) + round-off; " + "; ".join(texts)
                        + (f"; the row shows the {runs[w][0]} step's run, the furthest beyond its tolerance (at "
                           f"the declared step RK4's drift is below round-off; at the check's {h_c:g} s, "
                           f"{RK4_CHECK_SUB_STEPS} steps per period, it is not)" if len(runs) > 1 else
                           f"; no run at the check's {h_c:g} s (no dt setting): where the declared step's drift is "
                           f"below round-off, only a real step several times the declared one is seen"
                           if h < h_c * (1.0 - 1e-9) else "")
                        + f"; W = {W:.3g} rad/s")  # fmt: skip
                D_end, P_end, err, tol = rk4_fits[w][:4]
                ok = bool(inside and all(d[2] <= d[3] for d in rk4_fits))
                out.append(Check("energy", name, variant, "E(t_end) - E(0)", "J", D_end, P_end, err, tol, ok,
                                 note + invalid))  # fmt: skip
                continue
            if family == "adaptive":
                h_max = min(float(tr.info.get("max_step", Ts)), Ts)  # one solve per period: no step is longer
                n_min = (len(tr.t) - 1) * math.ceil(Ts / h_max - 1e-9)  # the fewest steps the solver can take
                trunc = (h_max * W) ** 5 * W * float(tr.t[-1]) * float(TV[:, 0].max())
                roundoff = _roundoff(TV, n_min)
                tol = trunc + roundoff
                why = (f"adaptive 5(4) or higher, steps <= h = {h_max:g} s (max_step): (h W)^5 W T_end max T = "
                       f"{trunc:.2g} J with W = {W:.3g} rad/s, + round-off {roundoff:.2g} J "
                       f"({n_min} steps)")  # fmt: skip
            else:
                out.append(_not_applicable("energy", name, variant, "max |E(t) - E(0)|", family))
                continue
            c = _check("energy", name, variant, "max |E(t) - E(0)|", "J", float(np.abs(D).max()), 0.0, tol,
                       why + invalid)  # fmt: skip
            out.append(c if inside else dataclasses.replace(c, passed=False, status="fail"))
    return _explained(out, infos)


def _roundoff(TV: np.ndarray, n_steps: int) -> float:
    """The energy's round-off over ``n_steps`` steps [J], adding as a random walk: 4 sqrt(n) eps max|T, V| (``TV``,
    the run's (T, V) at every logged state)."""
    return 4.0 * math.sqrt(n_steps) * EPS * float(np.abs(TV).max())


def _drift_tolerance(P: np.ndarray, h: float, Ts: float, W: float, roundoff: float) -> float:
    """The tolerance [J] on a predicted energy drift ``P`` at step ``h`` [s]: max|P| (h W + (Ts W)^2), the
    prediction's next order and its quadrature on the log of period ``Ts`` [s] (W the run's largest joint speed
    [rad/s]), plus ``roundoff``."""
    return float(np.abs(P).max()) * (h * W + (Ts * W) ** 2) + roundoff


def _rk4_drift(energy: _Energy, tr: Any, h: float, Ts: float,
               along: tuple[np.ndarray, np.ndarray] | None = None) -> tuple[float, ...]:  # fmt: skip
    """RK4's predicted energy drift along run ``tr`` at step ``h`` [s] against the measured one: (D(t_end),
    P(t_end), max_t |D - P|, tolerance, max|D|, max|P|, round-off) [J]. The exact flow conserves E, so
    D(t_k) = sum over the steps before t_k of the one-step error e5(x_j) h^5 + e6(x_j) h^6 + O(h^7) (e5, e6:
    :meth:`_Energy.rk4_rates`); the sum over steps is h^-1 int dt less (h/2)(g(t) - g(0)) (Euler-Maclaurin), the
    integral Simpson's on the 1 ms log. Tolerance max|P| (h W + (Ts W)^2) + 4 sqrt(n) eps max|E|: the terms left,
    O(h^2) of P (h^6, the fitted e6's own error) and the quadrature on the log, bounded as the first-order rows'
    O(h) remainder is (measured: 2.7e-4 |P| at 0.5 ms, 4.5e-4 at 1 ms, against h W + (Ts W)^2 = 9.8e-3 and 1.9e-2;
    the prediction to h^4 alone missed by 2.2e-2 and 4.4e-2, 2.3 h W), and the round-off of n steps adding as a
    random walk (2.3e-14 J measured at 50 us against 5.4e-13 J). ``along``: the run's :meth:`_Energy.along`, where
    the caller has it."""
    TV, D = energy.along(tr) if along is None else along
    e = np.array([energy.rk4_rates(q, qd) for q, qd in zip(tr.q, tr.qd, strict=True)])
    I5, I6 = (scipy.integrate.cumulative_simpson(e[:, i], x=tr.t, initial=0.0) for i in (0, 1))
    P = h**4 * (I5 + h * (I6 - 0.5 * (e[:, 0] - e[0, 0])))
    roundoff = _roundoff(TV, (len(tr.t) - 1) * round(Ts / h))
    tol = _drift_tolerance(P, h, Ts, float(np.abs(tr.qd).max()), roundoff)
    return (float(D[-1]), float(P[-1]), float(np.abs(D - P).max()), tol, float(np.abs(D).max()),
            float(np.abs(P).max()), roundoff)  # fmt: skip


# --------------------------------------------------------------------------- #
# Rest penetration and static balance


def check_rest(backends: Sequence[str], scenario_file: Path = REST_SCENARIO,
               profile: str = VERIFY_PROFILE) -> list[Check]:  # fmt: skip
    """Rest penetration y = Fn/Kp and static balance F = -(J_poc^T)^-1 (tau - G), each backend's own contact, in
    ``profile``."""
    sc = scenario_mod.load(scenario_file)
    physics = physics_of(sc)
    c = sc.contact
    R = model.load_params().geometry.R_foot
    leg = model.Dynamics(sc.gravity)
    out: list[Check] = []
    infos: dict[tuple[str, str], Mapping[str, Any]] = {}
    for name in backends:
        tr = _simulate(sc, name, physics, sc.backends.get(name, {}), profile)
        variant = _variant(tr.info, sc.control_dt)
        infos[name, variant] = tr.info
        if tr.status != "ok":
            out += [_failed(case, name, variant, tr.reason or tr.status) for case in ("rest_penetration",
                                                                                      "static_balance")]  # fmt: skip
            continue
        law = applies_law(tr.info, physics)
        # where the force acted, as the backend declares: a law backend's law's poc (the scenario's unless its
        # settings say), an engine's own contact point (the sphere's lowest point, or halfway through the penetration)
        poc, lift = contact_point(tr.info, c.poc)
        contact_info = tr.info.get("contact")
        declared = isinstance(contact_info, Mapping) and "lift" in contact_info  # an engine's own point, known
        idx = np.flatnonzero(tr.t >= tr.t[-1] - sc.comparison.steady_window - 1e-9)
        q, qd, tau, f = tr.q[idx], tr.qd[idx], tr.tau[idx], tr.f[idx]
        tau_step = tau - tr.tau[np.maximum(idx - 1, 0)]  # the held torque's step at each sample
        qdd = np.gradient(tr.qd, tr.t, axis=0)[idx]
        y = R - kinematics.fk(q)[:, 2]
        J = kinematics.jacobian_at(q, poc, lift)
        ydot = -np.einsum("nj,nj->n", J[:, 2, :], qd)
        # rest penetration: mean(Fn) = Kp mean(y) + the damping force's mean, so the row, which compares the means,
        # allows that mean [m], not the largest damping force: a jitter (ODE's engine-defaults quick step: max|ydot|
        # 7.9 mm/s, mean 6.4 um/s) does not move the mean rest, and Kd max|ydot|/Kp allowed it 85 um on 5.2 mm. Which
        # mean is the damper's: a law backend applies the spec's law, damping only while pressing in, Kd max(ydot, 0)
        # (its read-out's residual is exactly that, by construction); an engine's own contact damps both ways, Kd
        # ydot (every built-in one: ODE's implicit Kp y + Kd ydot, Drake's Kelvin-Voigt or Hunt-Crossley normal_law,
        # MuJoCo's reference acceleration -b v - k r, Bullet's ERP/CFM spring-damper), so Kd |mean(ydot)|. Not the
        # larger of the two for an engine: with a zero-mean jitter mean(max(ydot, 0)) is mean|ydot|/2 (ODE: 0.9 mm/s,
        # 9 um), a force its damper does not exert, the same defect at half its size.
        y_m, fn = float(y.mean()), float(f[:, 2].mean())
        if law:
            v_damp, damp_text = float(np.maximum(ydot, 0.0).mean()), "mean(max(ydot, 0))"  # [m/s]
        else:
            v_damp, damp_text = abs(float(ydot.mean())), "|mean(ydot)|"  # [m/s]
        damping = c.Kd * v_damp / c.Kp  # [m]
        tol = SOLVER_RTOL * abs(fn / c.Kp) + damping
        allowance = (f"damping allowance Kd {damp_text}/Kp = {damping:.2e} m (mean ydot = {float(ydot.mean()):.2e} "
                     f"m/s, max|ydot| = {float(np.abs(ydot).max()):.2e} m/s)")  # fmt: skip
        if rigid_contact(tr.info):
            # rigid native contact (the backend declares no stiffness): no spring, so neither Fn / Kp nor a damping
            # allowance Kd ydot / Kp applies. Expected: the engine's own closed form of its sink (its regularisation),
            # where its class gives one (``rest_sink(info, Fn)``), to the contact solver's share of it as a compliant
            # rest; else no sinking, to an absolute bound (RIGID_REST_BOUND)
            cls = registry.get(name)
            sink = cls.rest_sink(tr.info, fn)
            if sink is not None:
                how = cls.rest_sink_text(tr.info, fn) or f"sink {sink:.4g} m"
                note = (f"rigid contact (no Kp declared): expected the engine's own closed form of its sink at the "
                        f"window's mean Fn, {how}; tolerance {SOLVER_RTOL:g} of it (the contact solver's share, as "
                        f"a compliant rest's)")  # fmt: skip
                out.append(_check("rest_penetration", name, variant, "penetration R_foot - z_E", "m", y_m, sink,
                                  SOLVER_RTOL * abs(sink), note))  # fmt: skip
            else:
                note = (f"rigid contact (no Kp declared) with no closed form of its sink: expected no sinking, within "
                        f"{RIGID_REST_BOUND:g} m; Fn = {fn:.3f} N")  # fmt: skip
                out.append(_check("rest_penetration", name, variant, "penetration R_foot - z_E", "m", y_m, 0.0,
                                  RIGID_REST_BOUND, note))  # fmt: skip
        else:
            note = f"mean Fn = {fn:.3f} N, Kp = {c.Kp:g} N/m, {allowance}"
            if law:
                note = (f"law backend: Fn is the law at the logged y, so y - Fn/Kp = -Kd mean(max(ydot, 0))/Kp = "
                        f"{-damping:.2e} m by construction: this checks "
                        f"the force read-out's consistency, not the engine; {note}")  # fmt: skip
            out.append(_check("rest_penetration", name, variant, "penetration R_foot - z_E", "m", y_m, fn / c.Kp, tol,
                              note))  # fmt: skip
        # static balance, per tick: each tick against its own tolerance
        n = len(f)
        F_exp, dyn = np.empty_like(f), np.empty_like(f)
        step, lever, solver, roundoff, inertial = np.empty(n), np.zeros(n), np.zeros(n), np.empty(n), np.empty(n)
        adaptive_law = law and _family(tr.info) == "adaptive"
        rtol, atol = float(tr.info.get("rtol", 0.0)), float(tr.info.get("atol", 0.0))
        slope_v = max(c.mu_s, 2.0 * abs(c.mu_s - c.mu_k)) / c.v_th  # [1/(m/s)], times Fn: the friction's slope
        for k in range(n):
            G = leg.gravity(q[k])  # at the scenario's gravity, as the run's physics
            JTinv = np.linalg.inv(J[k].T)
            F_exp[k] = -JTinv @ (tau[k] - G)
            F_dyn = JTinv @ (leg.inverse_dynamics(q[k], qd[k], qdd[k]) - G)  # (J^T)^-1 (M qdd + C qd) [N]
            dyn[k] = np.abs(F_dyn)
            inertial[k] = np.linalg.norm(F_dyn)
            norm_JTinv = np.linalg.norm(JTinv, 2)
            step[k] = norm_JTinv * np.linalg.norm(tau_step[k])
            roundoff[k] = 8 * EPS * (np.linalg.norm(f[k]) + norm_JTinv * (np.linalg.norm(tau[k]) + np.linalg.norm(G)))
            if not law and not declared:
                lever[k] = norm_JTinv * max(y[k], 0.0) * math.hypot(f[k, 0], f[k, 1])
            elif adaptive_law:
                # the law's slopes times the state error one step of the solver admits (scipy's RMS norm <= 1:
                # each component within sqrt(6) (atol + rtol |x|)); the contact's modes damp it, it does not add up
                e_q = math.sqrt(6) * (atol + rtol * float(np.abs(q[k]).max()))
                e_qd = math.sqrt(6) * (atol + rtol * float(np.abs(qd[k]).max()))
                slope = (slope_v * max(f[k, 2], 0.0) + c.Kd * (1.0 + c.mu_s)) * e_qd + c.Kp * (1.0 + c.mu_s) * e_q
                solver[k] = np.linalg.norm(J[k], 2) * slope
        f_norm = np.linalg.norm(f, axis=1)
        # an engine's contact solver may miss by BALANCE_SOLVER_RTOL of |F|; the law has no solver, only round-off
        rest = roundoff if law else BALANCE_SOLVER_RTOL * f_norm
        static = step + lever + solver + rest  # [N] each tick's tolerance less its dynamic term
        # at rest: the inertial force within AT_REST_RTOL of |F| at every tick (AT_REST_RTOL says why that share)
        moving = inertial > AT_REST_RTOL * f_norm
        share = np.divide(inertial, f_norm, out=np.full(n, math.inf), where=f_norm > 0)
        share[inertial == 0.0] = 0.0
        w = int(np.argmax(share))
        for j, comp in enumerate(("Fx", "Fy", "Fz")):
            err = np.abs(f[:, j] - F_exp[:, j])
            tol_k = dyn[:, j] + static
            # the tick furthest beyond its own tolerance decides the row (an error over a zero tolerance: inf)
            ratio = np.divide(err, tol_k, out=np.where(err > 0, math.inf, 0.0), where=tol_k > 0)
            ratio[np.isnan(err)] = math.nan  # a non-finite error is the row's (np.argmax takes the first nan)
            k = int(np.argmax(ratio))
            quantity = f"{comp} (worst tick of the last {sc.comparison.steady_window:g} s)"
            terms = (f"worst tick t = {float(tr.t[idx[k]]):.3f} s (error {ratio[k]:.3g} of its own tolerance, "
                     f"{int((err > tol_k).sum())} of {n} ticks over theirs): dynamic term there {dyn[k, j]:.2e} N "
                     f"(up to {dyn[:, j].max():.2e} N), torque step up to {step.max():.2e} N")  # fmt: skip
            if law:
                note = (f"law backend (the law's force at its known point of contact, poc {poc}): no lever term; "
                        f"{terms}, solver tolerance up to {solver.max():.2e} N, "
                        f"round-off {roundoff.max():.1e} N")  # fmt: skip
            elif declared:
                note = (f"engine contact at its declared point ({lift:.3g} of the penetration above the lowest point): "
                        f"no lever term; {terms}, solver {BALANCE_SOLVER_RTOL:g} |F|")  # fmt: skip
            else:
                note = f"{terms}, lever term up to {lever.max():.2e} N, solver {BALANCE_SOLVER_RTOL:g} |F|"
            check = _check("static_balance", name, variant, quantity, "N", float(f[k, j]), float(F_exp[k, j]),
                           float(tol_k[k]), note)  # fmt: skip
            if moving.any():
                check = dataclasses.replace(check, passed=False, status="fail", note=(
                    f"not at rest: the inertial force |(J_poc^T)^-1 (M qdd + C qd)| is {100 * share[w]:.3g} % of |F| "
                    f"({inertial[w]:.3g} N at t = {float(tr.t[idx[w]]):.3f} s; over {100 * AT_REST_RTOL:g} % at "
                    f"{int(moving.sum())} of {n} ticks), so the static closed form does not hold to the row's "
                    f"precision; {note}"))  # fmt: skip
            out.append(check)
    return _explained(out, infos)


# --------------------------------------------------------------------------- #
# Small oscillations


def matrix_pencil(Y: np.ndarray, order: int, L: int | None = None) -> np.ndarray:
    """Discrete poles z of a sum of damped exponentials fitted to uniformly sampled signals.

    Hua and Sarkar's matrix pencil on the block Hankel matrix of all channels.

    Args:
        Y: samples, shape (channels, n).
        order: number of poles (the model order).
        L: pencil parameter (default n // 3).

    Returns:
        ``order`` poles z (complex), s = ln(z) / Ts.
    """
    Y = np.atleast_2d(np.asarray(Y, float))
    n = Y.shape[1]
    L = L or n // 3
    H = np.vstack([np.lib.stride_tricks.sliding_window_view(y, L + 1) for y in Y])
    _, _, Vh = np.linalg.svd(H, full_matrices=False)
    V = Vh[:order].conj().T
    return np.linalg.eigvals(np.linalg.pinv(V[:-1]) @ V[1:])  # type: ignore[no-any-return]


def equilibrium(q_des: np.ndarray, Kp: np.ndarray, q0: np.ndarray, tol: float = 1e-13,
                leg: model.Dynamics | None = None) -> np.ndarray:  # fmt: skip
    """The pose where the PD hold balances gravity, Kp (q_des - q) = G(q), by Newton from q0 [rad]; G at ``leg``'s
    gravity (default: the parameter file's)."""
    leg = leg or model.Dynamics()
    q = np.array(q0, float)
    for _ in range(50):
        r = Kp @ kinematics.joint_error(q, q_des) - leg.gravity(q)
        if np.abs(r).max() < tol:
            return q
        q = q + np.linalg.solve(Kp + gravity_stiffness(q, leg=leg), r)
    raise LegbenchError(f"no PD equilibrium found near {np.round(q0, 4).tolist()} rad")


def gravity_stiffness(q: np.ndarray, eps: float = 1e-6, leg: model.Dynamics | None = None) -> np.ndarray:
    """dG/dq [N m/rad] by central differences; G at ``leg``'s gravity (default: the parameter file's)."""
    leg = leg or model.Dynamics()
    return np.column_stack([(leg.gravity(q + e) - leg.gravity(q - e)) / (2 * eps) for e in np.eye(3) * eps])


def discrete_loop(M: np.ndarray, Kg: np.ndarray, Kp: np.ndarray, Kd: np.ndarray, Ts: float, family: str = "exact",
                  n_sub: int = 1) -> np.ndarray:  # fmt: skip
    """Closed-loop transition matrix of the linearised leg under the harness's 1 kHz PD.

    Plant M dq'' + Kg dq = du, the torque held over each period, integrated
    over the period the way the backend does it (``family``: ``exact`` flow,
    ``euler`` = n_sub semi-implicit Euler steps, ``rk4`` = n_sub RK4 steps).
    Controller du_k = -Kp dq_k - Kd (dq_k - dq_{k-1}) / Ts. State
    X_k = (dq_k, dqd_k, dq_{k-1}), shape 9.
    """
    Mi = np.linalg.inv(M)
    Z, eye = np.zeros((3, 3)), np.eye(3)
    A = np.block([[Z, eye], [-Mi @ Kg, Z]])
    B = np.vstack([Z, Mi])
    if family == "exact":
        E = scipy.linalg.expm(np.block([[A, B], [np.zeros((3, 9))]]) * Ts)
        Ad, Bd = E[:6, :6], E[:6, 6:]
    else:
        h = Ts / n_sub
        if family == "euler":
            S = np.block([[eye - h * h * Mi @ Kg, h * eye], [-h * Mi @ Kg, eye]])
            b = np.vstack([h * h * Mi, h * Mi])
        elif family == "rk4":
            hA = h * A
            S = np.eye(6) + hA + hA @ hA / 2 + hA @ hA @ hA / 6 + hA @ hA @ hA @ hA / 24
            b = h * (np.eye(6) + hA / 2 + hA @ hA / 6 + hA @ hA @ hA / 24) @ B
        else:
            raise ValueError(f"unknown integrator family {family!r}")
        Ad, Bd = np.eye(6), np.zeros((6, 3))
        for _ in range(n_sub):
            Ad, Bd = S @ Ad, S @ Bd + b
    Kx = np.hstack([-Kp - Kd / Ts, Z, Kd / Ts])
    top = np.hstack([Ad, np.zeros((6, 3))]) + Bd @ Kx
    return np.vstack([top, np.hstack([eye, np.zeros((3, 6))])])  # type: ignore[no-any-return]


def _modes(s: np.ndarray) -> list[np.ndarray]:
    """Poles grouped into modes: one per real pole, one per conjugate pair (Im > 0 kept)."""
    return [x for x in s if x.imag >= -1e-9 * max(abs(x), 1.0)]


def damping_tolerance(s: complex, rel: float) -> float:
    """The largest change of a pole's damping ratio zeta = -Re(s) / |s| = -cos(arg s) while the pole stays within
    ``rel`` |s| of ``s`` (the pole's own tolerance): its angle seen from the origin turns by at most asin(rel),
    so |d zeta| <= rel sqrt(1 - zeta^2) to first order, computed exactly here (it was 2 rel, up to 3.6 times
    this at the leg's zeta 0.83)."""
    phi, a = float(np.angle(s)), math.asin(min(rel, 1.0))
    return max(abs(math.cos(phi + a) - math.cos(phi)), abs(math.cos(phi - a) - math.cos(phi)))


def check_small_oscillation(backends: Sequence[str], scenario_file: Path = OSCILLATION_SCENARIO,
                            integrators: Sequence[str] | None = ("default", "rk4"),
                            profile: str = VERIFY_PROFILE) -> list[Check]:  # fmt: skip
    """Closed-loop poles of the PD hold: fitted to each backend's response vs the linearised discrete loop, in
    ``profile`` (only its own integrator outside the matched one, :func:`scope`)."""
    sc = scenario_mod.load(scenario_file)
    if any(sc.gains.Ki) or len(sc.events) != 1 or sc.events[0].joint is None:
        raise LegbenchError(f"{scenario_file}: small_oscillation needs one joint position event and Ki = 0")
    Ts = sc.control_dt
    Kp, Kd = np.diag(sc.gains.Kp), np.diag(sc.gains.Kd)
    q_des = np.array(sc.events[0].joint)
    energy = _Energy(sc.gravity)  # the leg at the scenario's gravity, as the runs' physics
    q_eq = equilibrium(q_des, Kp, np.array(sc.q0), leg=energy)
    M, Kg = energy.mass_matrix(q_eq), gravity_stiffness(q_eq, leg=energy)
    Mi = np.linalg.inv(M)
    s_cont = np.linalg.eigvals(np.block([[np.zeros((3, 3)), np.eye(3)], [-Mi @ (Kp + Kg), -Mi @ Kd]]))
    physics = physics_of(sc)
    out: list[Check] = []
    infos: dict[tuple[str, str], Mapping[str, Any]] = {}
    for name in backends:
        base = dict(sc.backends.get(name, {}))
        offered = registry.get(name).choices.get("integrator", ())
        others = integrators if every_integrator(profile) else ()
        runs = [base] + [{**base, "integrator": i} for i in (others or ()) if i in offered and i != "default"
                         and i != base.get("integrator", registry.get(name).defaults.get("integrator"))]  # fmt: skip
        for settings in runs:
            tr = _simulate(sc, name, physics, settings, profile)
            variant = _variant(tr.info, Ts)
            infos[name, variant] = tr.info
            if tr.status != "ok":
                out.append(_failed("small_oscillation", name, variant, tr.reason or tr.status))
                continue
            family = _family(tr.info)
            if family == "other":
                out.append(_not_applicable("small_oscillation", name, variant, "closed-loop poles", family))
                continue
            n_sub = int(tr.info["sub_steps"])
            # an implicit step adds the Coriolis derivative, zero at rest: Euler in the linearisation
            model_family = {"euler": "euler", "implicit": "euler", "rk4": "rk4"}.get(family, "exact")
            z_pred = np.linalg.eigvals(discrete_loop(M, Kg, Kp, Kd, Ts, model_family, n_sub))
            h_sub = _sub_step(tr.info, Ts)
            fitted = z_pred[np.abs(z_pred) > 0.1]  # poles that shape more than the first few samples
            # fitted to the response's differences: a constant (the engine's equilibrium off the model's q_eq by
            # 3e-9 rad failed a correct engine's 0.5 %) is no mode of the difference, whose poles are the same
            z_meas = matrix_pencil(np.diff(tr.q - q_eq, axis=0).T, len(fitted))
            s_pred = np.log(fitted.astype(complex)) / Ts
            s_meas = np.log(z_meas.astype(complex)) / Ts
            cost = np.abs(s_pred[:, None] - s_meas[None, :]) / np.abs(s_pred)[:, None]
            rows, cols = linear_sum_assignment(cost)
            pairs = sorted(((s_pred[r], s_meas[c]) for r, c in zip(rows, cols, strict=True)), key=lambda p: -p[0].real)
            shown = [p for p in pairs if abs(np.exp(p[0] * Ts)) > 0.5 and p[0].imag >= -1e-9 * abs(p[0])]
            for i, (sp, sm) in enumerate(shown, start=1):
                sc_near = s_cont[np.argmin(np.abs(s_cont - sp))]
                note = (f"model: {MODEL_TEXT[model_family]}, {n_sub} per control period; pole {sp:.2f}/s, fitted "
                        f"{sm:.2f}/s; continuous-time model (no sampling) {sc_near:.2f}/s")  # fmt: skip
                # a step with no discrete model of its own ("first-order", modelled by the exact flow) may move a
                # pole by O(h |s|) relative, as any first-order step does
                rel = POLE_RTOL + (h_sub * abs(sp) if family == "first-order" else 0.0)
                tol_s = rel * abs(sp)
                if abs(sp.imag) > 1e-6 * abs(sp):
                    out.append(_check("small_oscillation", name, variant, f"mode {i} frequency", "Hz",
                                      abs(sm.imag) / (2 * math.pi), abs(sp.imag) / (2 * math.pi),
                                      tol_s / (2 * math.pi), note))  # fmt: skip
                    out.append(_check("small_oscillation", name, variant, f"mode {i} damping ratio", "1",
                                      -sm.real / abs(sm), -sp.real / abs(sp), damping_tolerance(sp, rel),
                                      note))  # fmt: skip
                else:
                    note += f"; the model's pole is real (a decay), the fitted pole's imaginary part {sm.imag:.2g}/s"
                    out.append(_check("small_oscillation", name, variant, f"mode {i} decay rate", "1/s",
                                      -sm.real, -sp.real, tol_s, note))  # fmt: skip
    return _explained(out, infos)


# --------------------------------------------------------------------------- #
# Table and files


def check_sliding(backends: Sequence[str], profile: str = VERIFY_PROFILE) -> list[Check]:
    """The foot dragged above the friction limit (:mod:`legbench.studies.sliding_case`): friction = mu Fn
    against the slip and the slip acceleration of the closed form, per backend (native contact, ``profile``); a
    backend whose friction is a pyramid or a diamond against that shape's closed form, with the coefficient and
    the point of contact its run declares."""
    out = []
    variant = f"native, {profile}"
    for name in backends:
        for r in sliding_case(name, profile):
            if r["quantity"] == "run":
                out.append(_failed("sliding", name, variant, r["note"]))
            else:
                out.append(_check("sliding", name, variant, r["quantity"], r["unit"], r["measured"],
                                  r["expected"], r["tolerance"], r["note"]) if r["quantity"].startswith("angle")
                           else _ratio_check(r, name, variant))  # fmt: skip
    return out


def _ratio_check(r: Mapping[str, Any], name: str, variant: str) -> Check:
    """A sliding row scored as a relative error (``error`` = |measured / expected - 1|)."""
    return Check("sliding", name, variant, r["quantity"], r["unit"], float(r["measured"]),
                 float(r["expected"]), float(r["error"]), float(r["tolerance"]), bool(r["passed"]),
                 note=str(r["note"]))  # fmt: skip


#: Each group of cases: the cases it checks, its function (rest_penetration and static_balance share one
#: run; each takes the backends and, by keyword, the profile) and its scenario (None: the sliding drag,
#: :mod:`legbench.studies.sliding_case`); a pool task names its group, so it is plain data.
_GROUPS: dict[str, tuple[tuple[str, ...], Callable[..., list[Check]], Path | None]] = {
    "energy": (("energy",), check_energy, ENERGY_SCENARIO),
    "rest": (("rest_penetration", "static_balance"), check_rest, REST_SCENARIO),
    "small_oscillation": (("small_oscillation",), check_small_oscillation, OSCILLATION_SCENARIO),
    "sliding": (("sliding",), check_sliding, None),
}


def _group_checks(task: tuple[str, str, str]) -> list[Check]:
    """One group of cases on one backend in one profile, ``(group, backend, profile)``: a task for the pool (a
    top-level function)."""
    group, name, profile = task
    try:
        return _GROUPS[group][1]([name], profile=profile)
    except Exception as exc:  # a backend that cannot load or run fails its own rows, not the whole verification
        return _failed_group(task, f"{type(exc).__name__}: {exc}")


def _failed_group(task: tuple[str, str, str], why: str) -> list[Check]:
    """One failed row per case of a group, ``(group, backend, profile)``, each saying ``why``."""
    group, name, _ = task
    return [_failed(case, name, "", why) for case in _GROUPS[group][0]]


def _crashed_group(task: tuple[str, str, str], why: str) -> list[Check]:
    """The rows of a group whose worker process died under it (the engine crashed)."""
    return _failed_group(task, f"the engine crashed: {why}")


def verify(
    out_dir: str | Path | None = None,
    backends: Sequence[str] | None = None,
    cases: Sequence[str] = CASES,
    jobs: int = 1,
    profile: str = VERIFY_PROFILE,
) -> pd.DataFrame:
    """Run the verification cases on the backends (default: all available) in ``profile`` and tabulate them.

    Args:
        out_dir: where to write ``verification.json`` and ``verification.md`` (None: nowhere).
        backends: backend names (default: every available backend).
        cases: subset of :data:`CASES`.
        jobs: worker processes (:mod:`legbench.studies.executors`; 1: in this process); the table is the
            same whatever the number (each case and backend is one deterministic task, results in order).
        profile: the profile every backend is loaded in (one of :data:`~legbench.backends.base.PROFILES`;
            the matched one verifies every integrator a backend offers, another its own only: :func:`scope`).

    Returns:
        One row per checked quantity, columns :data:`COLUMNS`.

    Raises:
        LegbenchError: an unknown case, backend or profile.
    """
    registry.check_profile(profile)
    for c in cases:
        if c not in CASES:
            raise LegbenchError(f"unknown verification case '{c}'; choose from {', '.join(CASES)}")
    names = list(backends) if backends is not None else registry.available()
    for n in names:
        registry.get(n)
    groups = {g: file for g, (members, _, file) in _GROUPS.items() if set(members) & set(cases)}
    tasks = [(g, n, profile) for g in groups for n in names]
    # the longest first (simulated seconds x the backend's measured cost in the baseline), so that no long
    # task is left alone at the end; the order of the table does not depend on it
    seconds = {g: scenario_mod.load(file).duration if file is not None else WINDOW[1] for g, file in groups.items()}
    rates = backend_rates() if jobs > 1 else {}
    first = sorted(range(len(tasks)), key=lambda i: -seconds[tasks[i][0]] * rates.get(tasks[i][1], 1.0))
    with make_executor("local", jobs, preload=(*DEFAULT_PRELOAD, __name__)) as ex:
        parts = list(ex.imap(_group_checks, tasks, first, _crashed_group))
    checks = [c for part in parts for c in part if c.case in cases]
    df = pd.DataFrame([dataclasses.asdict(c) for c in checks]).rename(columns={"passed": "pass"})
    df = df.reindex(columns=list(COLUMNS))
    if out_dir is not None:
        write_verification(df, Path(out_dir), profile)
    return df


def _fmt(v: Any) -> str:
    if isinstance(v, bool | np.bool_):
        return "yes" if v else "**NO**"
    if isinstance(v, float):
        return "nan" if math.isnan(v) else f"{v:.4g}"
    return str(v).replace("|", "\\|")


def markdown(df: pd.DataFrame) -> str:
    """The verification table as Markdown."""
    cols = [c for c in COLUMNS if c not in ("note", "status")]

    def cell(r: Mapping[str, Any], c: str) -> str:
        return "n/a" if c == "pass" and r["status"] == "not-applicable" else _fmt(r[c])

    lines = ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    lines += ["| " + " | ".join(cell(r, c) for c in cols) + " |" for r in df.to_dict(orient="records")]
    return "\n".join(lines) + "\n"


def write_verification(df: pd.DataFrame, out_dir: Path, profile: str = VERIFY_PROFILE) -> Path:
    """Write ``verification.json`` (records, versions, platform, the ``profile`` the backends ran in) and
    ``verification.md`` into ``out_dir``."""
    out_dir.mkdir(parents=True, exist_ok=True)
    passed = int(df["pass"].sum())
    na = int((df["status"] == "not-applicable").sum())
    meta = {"schema": "legbench.verification/1", "passed": passed, "total": len(df), "not_applicable": na,
            "profile": profile, "scope": scope(profile), "tolerance_basis": TOLERANCE_BASIS,
            "checks": df.to_dict(orient="records"), "versions": versions(), "platform": platform_info()}  # fmt: skip
    write_json(meta, out_dir / "verification.json")
    md = [f"# Verification: {checks_summary(list(df['status']))}\n",
          "Cases and tolerances: `legbench/studies/verify.py`. Every backend runs in its "
          f"{profile} profile's settings: {scope(profile)}.\n", markdown(df), "\n## Notes\n"]  # fmt: skip
    md += [f"- {r['case']} / {r['backend']} / {r['variant']} / {r['quantity']}: {r['note']}"
           for r in df.to_dict(orient="records") if r["note"]]  # fmt: skip
    atomic_write_text(out_dir / "verification.md", "\n".join(md) + "\n")
    return out_dir


def _cli(args: argparse.Namespace) -> int:
    names = registry.resolve(args.backends)
    cases = list(CASES) if args.cases is None else [c.strip() for c in args.cases.split(",") if c.strip()]
    if not cases:
        raise LegbenchError(f"--cases {args.cases!r}: names no case (give some of {', '.join(CASES)})")
    out = args.out or study_dir("results", "verification", args.profile)
    check_study_out(out, "verification.json", ("verification.json", "verification.md"), "verification",
                    args.force)  # fmt: skip
    df = verify(out, names, cases, args.jobs, args.profile)
    with pd.option_context("display.width", 200, "display.max_columns", 20, "display.max_colwidth", 40):
        print(df.drop(columns=["note"]).to_string(index=False))
    print(f"{checks_summary(list(df['status']))} ({args.profile} profile); wrote {out}")
    return 0 if not bool((df["status"] == "fail").any()) else 1


def add_cli(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Register ``legbench verify [--out DIR] [--backends all] [--cases a,b] [--jobs N] [--profile P]``."""
    p = subparsers.add_parser("verify", help="verification cases with closed-form answers, on every backend")
    p.add_argument("--out", default=None, help="output directory (default results/verification, "
                   "results/verification__engine-defaults for --profile engine-defaults)")  # fmt: skip
    p.add_argument("--profile", choices=PROFILES, default=VERIFY_PROFILE,
                   help=f"the backends' profile (default {VERIFY_PROFILE}: every integrator a backend offers; "
                   "engine-defaults: the engine's own settings and integrator)")  # fmt: skip
    p.add_argument("--backends", default="all", help="comma-separated backend names, or 'all' (default)")
    p.add_argument("--cases", default=None, help=f"comma-separated subset of {', '.join(CASES)}")
    p.add_argument("--jobs", type=int, default=1, help="worker processes, one case and backend each (default 1)")
    p.add_argument("--force", action="store_true", help="replace a finished verification in --out")
    p.set_defaults(func=_cli)
