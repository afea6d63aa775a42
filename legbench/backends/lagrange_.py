"""The lab report's own analytic model: symbolic Euler-Lagrange equations of the leg, integrated by RK45.

The equations of motion B(q) qdd + C(q, qd) qd + G(q) = tau + tau_c + tau_lim are
derived with sympy from the leg model (:mod:`legbench.backends.lagrange_eom`: link
frames from the modified DH parameters, energies from the model's inertials, link 3
with the foot), generated once as Python code and cached by the SHA-256 of the
model's numbers, so a run only imports them. This is a dynamics implementation of
its own: it shares no code with the Pinocchio backend beyond the contact law and
the joint-limit law that every custom integrator uses.

Per control period the torque is held and one adaptive solve covers the period
(the report's custom simulation: ode45, i.e. Dormand-Prince 5(4), max step 1e-4 s; rtol 1e-8,
atol 1e-6, the report's as legbench's issue 13 gives them: docs/spec.md section 7). ``rk45`` is
:mod:`legbench.backends.lagrange_kernel`'s period,
scipy's ``solve_ivp(method="RK45")`` algorithm step for step (same tableau, initial step selection,
error norm and step-size control) on preallocated arrays, compiled into one numba call per control
period (setting ``kernel: compiled``, the default; 0.013-0.07 ms per period) or run as Python (``kernel:
python``, the reference: the same code); ``dop853`` goes through solve_ivp.
tau_c = J_poc^T F is the analytic ground contact law of
:mod:`legbench.contact` evaluated at every right-hand-side call; tau_lim the
one-sided spring-damper of :mod:`legbench.backends.joint_limits` at the revolute
limits. The model has no contact of its own, so both contact modes, ``native``
and ``reference``, apply that same law.

Profiles: ``matched`` takes the point of contact from the scenario's contact
parameters (the true poc, the sphere's lowest point, unless the scenario says
otherwise); ``engine-defaults`` is the report's custom simulation as far as the report
describes it, with the poc at the sphere centre.
"""

from __future__ import annotations

import dataclasses
import importlib.util
import os
from collections.abc import Callable, Mapping
from importlib import metadata
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from legbench.backends import dopri, joint_limits, lagrange_kernel
from legbench.backends.base import Backend, Limits, Physics, Range
from legbench.backends.joint_limits import JointLimitLaw
from legbench.backends.lagrange_eom import GENERATOR_VERSION, Loaded, leg_chain, load_eom
from legbench.contact import ReferenceContact
from legbench.exceptions import LegbenchError
from legbench.model import LINK_NAMES, load_params

# The derivation needs sympy; a cached load does not import it, so only its presence is checked here
# (the registry reports the backend missing, with the command that installs it, when it is absent).
if importlib.util.find_spec("sympy") is None:
    raise ImportError("No module named 'sympy' (the lagrange backend derives its equations with it)")

#: Setting ``integrator`` -> scipy solve_ivp method (the Pinocchio backend's names for the same solvers).
_METHODS = {"rk45": "RK45", "dop853": "DOP853"}
_POC = ("physics", "true", "centre")


def _cache_dir(setting: str) -> Path:
    """The directory a ``cache_dir`` setting names, a leading ``~`` expanded as the shell does (``~/eom`` made a
    folder named ``~`` in the working directory).

    Raises:
        RuntimeError: ``~user`` names no user (:meth:`pathlib.Path.expanduser`).
    """
    return Path(setting).expanduser()


class LagrangeBackend(Backend):
    """Symbolic Euler-Lagrange model of the leg + the analytic contact law, integrated by scipy's RK45 algorithm
    (compiled; solve_ivp for dop853)."""

    name: ClassVar[str] = "lagrange"
    #: rtol at or above scipy's floor (:data:`~legbench.backends.dopri.RTOL_MIN`, 2.2e-14): below it scipy raises it.
    ranges: ClassVar[Mapping[str, Range]] = {"rtol": Range(low=dopri.RTOL_MIN)}
    #: max_step [s] bounds the adaptive solve's step: control period / max_step is held to the sub-step limit.
    step_bounds: ClassVar[tuple[str, ...]] = ("max_step",)
    defaults: ClassVar[Mapping[str, Any]] = {
        "integrator": "rk45",  # scipy's RK45 algorithm, compiled (or "dop853": solve_ivp), one solve per period
        "rtol": 1.0e-8,  # the report's custom simulation's, as issue 13 gives them (docs/spec.md section 7)
        "atol": 1.0e-6,
        "max_step": 1.0e-4,  # [s]
        "poc": "physics",  # "physics": as the scenario's contact parameters say; "true"; "centre"
        "limit_stiffness": joint_limits.STIFFNESS,  # [N m/rad]
        "limit_damping": joint_limits.DAMPING,  # [N m s/rad]
        "cache_dir": "",  # generated equations; "" = $LEGBENCH_CACHE_DIR or the user cache (~/.cache/legbench)
        "kernel": "compiled",  # rk45 only: one compiled call per control period (lagrange_kernel), or python
    }
    choices: ClassVar[Mapping[str, tuple[str, ...]]] = {
        "integrator": tuple(_METHODS),
        "poc": _POC,
        "kernel": ("compiled", "python"),
    }
    profiles: ClassVar[Mapping[str, Mapping[str, Any]]] = {
        "matched": {},
        "engine-defaults": {"poc": "centre"},  # the report's custom simulation: poc at the sphere centre
    }
    install: ClassVar[str] = "pip install 'sympy>=1.12,<2'"

    @classmethod
    def settings_problem(
        cls, settings: Mapping[str, Any], contact_mode: str
    ) -> tuple[str | tuple[str, ...], str] | None:
        """``cache_dir`` that cannot hold the generated equations: not text, a ``~user`` that names no user, a
        path that exists (or whose nearest existing ancestor is) not a directory (``/dev/null``, a regular file), or
        one in a legbench run directory (it or an ancestor holds ``run.json``: the cache's file would sit among the
        run's, which a later run there then refuses to replace); any contact mode. A leading ``~`` is the home
        directory, as in the shell (:func:`_cache_dir`)."""
        cache = settings.get("cache_dir", "")
        if not isinstance(cache, str):
            return "cache_dir", f"expected a directory path as text ('' for the default cache), got {cache!r}"
        if cache:
            try:
                path = _cache_dir(cache)  # os.path's tests below, not Path's: False where stat fails (no permission)
            except RuntimeError as exc:  # ~nosuchuser
                return "cache_dir", f"{cache!r}: {exc}"
            existing = next((p for p in (path, *path.parents) if os.path.lexists(p)), None)
            if existing is not None and not os.path.isdir(existing):
                if existing == path:
                    return "cache_dir", f"{cache!r} exists and is not a directory (the generated equations' cache)"
                return "cache_dir", f"{cache!r} cannot be made a directory: {str(existing)!r} is not one"
            real = path.resolve()  # links and '..' resolved: RUN/../x is not in RUN, a link into RUN is
            run = next((p for p in (real, *real.parents) if os.path.isfile(p / "run.json")), None)
            if run is not None:
                return "cache_dir", (f"{cache!r} is in the legbench run directory {str(run)!r}; give the equations' "
                                     "cache a directory of its own")  # fmt: skip
        return None

    # ----------------------------------------------------------------- load
    def load(self, urdf: Path, physics: Physics, settings: Mapping[str, Any]) -> None:
        """Load (or derive once and cache) the leg's equations of motion and set up the solve.

        Args:
            urdf: the generated leg URDF (unused: the model is built from the same parameter file
                the URDF is generated from, :func:`legbench.model.load_params`).
            physics: gravity, contact law and mode, control period, torque limits.
            settings: overrides of :attr:`defaults`.

        Raises:
            LegbenchError: an unknown integrator or poc.
        """
        cfg = self.settings(settings)
        for key, allowed in self.choices.items():
            if cfg[key] not in allowed:
                raise LegbenchError(f"lagrange: unknown {key} '{cfg[key]}'; choose one of {list(allowed)}")
        self.refuse_settings(cfg, physics.contact_mode)
        self.cfg = cfg
        self.physics = physics
        params = load_params()
        #: The generated equations and whether this load derived them (cold) or read the cache.
        self.eom: Loaded = load_eom(leg_chain(params), _cache_dir(cfg["cache_dir"]) if cfg["cache_dir"] else None)
        self._qdd = self.eom.module.qdd
        poc = physics.contact.poc if cfg["poc"] == "physics" else cfg["poc"]
        self.contact_params = dataclasses.replace(physics.contact, poc=poc)
        self.contact = ReferenceContact.from_leg(self.contact_params)
        #: The contact law called at every right-hand-side evaluation (floats in, (tau_c, F) out).
        self.law = self.contact.wrench
        self.lower = tuple(float(j.lower) for j in params.joints)
        self.upper = tuple(float(j.upper) for j in params.joints)
        self.limit_law = JointLimitLaw(self.lower, self.upper, cfg["limit_stiffness"], cfg["limit_damping"])
        self.effort = tuple(float(x) for x in physics.torque_limit)
        self.g = float(physics.gravity)
        self._span = (0.0, float(physics.control_dt))
        self._solve = {"method": _METHODS[cfg["integrator"]], "rtol": float(cfg["rtol"]), "atol": float(cfg["atol"]),
                       "max_step": float(cfg["max_step"])}  # fmt: skip
        #: (rtol, atol, max_step [s]) of the rk45 solve.
        self._tols = (float(cfg["rtol"]), float(cfg["atol"]), float(cfg["max_step"]))
        self._u = [0.0, 0.0, 0.0]  # the held torque [N m], updated in place
        self.x = np.zeros(6)
        self.force = np.zeros(3)
        #: Right-hand-side evaluations in the last step (cost accounting); over the steps since the reset, and
        #: those steps (the bench's floor: :meth:`kernels`).
        self.nfev = 0
        self.nfev_total, self.periods = 0, 0
        self._kernel_note = ""
        self._compiled = False
        self._period = self._load_kernel()

    def _load_kernel(self) -> Callable[..., int] | None:
        """The rk45 period (:mod:`legbench.backends.lagrange_kernel`), compiled unless ``kernel: python`` or numba
        is missing (then the same code as Python), and the arrays it takes; None for dop853 (solve_ivp)."""
        if self._solve["method"] != "RK45":
            return None
        compiled = self.cfg["kernel"] == "compiled"
        if compiled and not lagrange_kernel.available():
            self._kernel_note = "lagrange: numba is not installed: the Python solve runs (pip install numba)"
            compiled = False
        self._compiled = compiled
        #: the law's constants, the limit law's, the held torque and the stages' scratch, as the period takes them
        self._lc = np.array(self.contact.constants)
        self._lim = np.array([*self.lower, *self.upper, self.limit_law.k, self.limit_law.b], dtype=float)
        self._ua = np.zeros(3)
        self._k = np.zeros((9, 6))
        return lagrange_kernel.period(self.eom.module.KEY, self._qdd, compiled)

    # ---------------------------------------------------------------- reset
    def reset(self, q: np.ndarray, qd: np.ndarray) -> None:
        self.x = np.concatenate([np.asarray(q, dtype=float), np.asarray(qd, dtype=float)])
        self.nfev_total, self.periods = 0, 0
        self._update_force()

    # ----------------------------------------------------------------- step
    def rhs(self, _t: float, x: np.ndarray) -> np.ndarray:
        """d/dt (q, qd) = (qd, qdd) under the held torque, the contact law and the limit law."""
        q1, q2, q3, qd1, qd2, qd3 = x.tolist()
        u1, u2, u3 = self._u
        tc1, tc2, tc3, _, _, _ = self.law(q1, q2, q3, qd1, qd2, qd3)
        tl1, tl2, tl3 = self.limit_law(q1, q2, q3, qd1, qd2, qd3)
        a1, a2, a3 = self._qdd(q1, q2, q3, qd1, qd2, qd3, u1 + tc1 + tl1, u2 + tc2 + tl2, u3 + tc3 + tl3, self.g)
        return np.array((qd1, qd2, qd3, a1, a2, a3))

    def step(self, tau: np.ndarray) -> None:
        """One control period with tau [N m] (clamped to the torque limits) held, one adaptive solve."""
        t1, t2, t3 = np.asarray(tau, dtype=float).tolist()
        e1, e2, e3 = self.effort
        self._u[:] = (min(max(t1, -e1), e1), min(max(t2, -e2), e2), min(max(t3, -e3), e3))
        if self._period is not None:
            u = self._ua
            u[0], u[1], u[2] = self._u
            rtol, atol, max_step = self._tols
            nfev = self._period(
                self.x, u, self.g, self._lc, self._lim, self._span[1], rtol, atol, max_step, self._k, ()
            )
            if nfev < 0:
                raise LegbenchError("lagrange: rk45 failed: Required step size is less than spacing between numbers.")
            self.nfev = nfev
            self.nfev_total, self.periods = self.nfev_total + nfev, self.periods + 1
            self._update_force()
            return
        from scipy.integrate import solve_ivp  # 0.7 s of imports: only when an adaptive solver runs

        sol = solve_ivp(self.rhs, self._span, self.x, **self._solve)
        if not sol.success:
            raise LegbenchError(f"lagrange: {self.cfg['integrator']} failed: {sol.message}")
        self.x = sol.y[:, -1]
        self.nfev = int(sol.nfev)
        self.nfev_total, self.periods = self.nfev_total + self.nfev, self.periods + 1
        self._update_force()

    def _update_force(self) -> None:
        q1, q2, q3, qd1, qd2, qd3 = self.x.tolist()
        f = self.force
        _, _, _, f[0], f[1], f[2] = self.law(q1, q2, q3, qd1, qd2, qd3)

    # ----------------------------------------------------------------- read
    def state(self) -> tuple[np.ndarray, np.ndarray]:
        return self.x[:3].copy(), self.x[3:].copy()

    def ground_force(self) -> np.ndarray:
        return self.force.copy()

    def read(self) -> tuple[float, ...]:
        """:meth:`state` and :meth:`ground_force` as nine floats, without the copies."""
        return (*self.x.tolist(), *self.force.tolist())

    def info(self) -> dict[str, Any]:
        c = self.contact_params
        return {
            "engine": "lagrange",
            "version": f"sympy {metadata.version('sympy')}, generator {GENERATOR_VERSION}",
            "dynamics": "legbench's Euler-Lagrange equations derived with sympy; legbench's integrator and contact law",
            **{k: self.cfg[k] for k in self.defaults if k != "kernel" or self._solve["method"] == "RK45"},
            "sub_steps": 1,
            "kernel_used": "compiled (numba)" if self._compiled else "python",
            "gravity": self.physics.gravity,
            "contact_mode": self.physics.contact_mode,
            "eom_key": self.eom.module.KEY[:16],
            "contact": {
                "law": "analytic (the lab report's contact law), J_poc^T F; no engine contact, so native = reference",
                "Kp": c.Kp,
                "Kd": c.Kd,
                "mu_s": c.mu_s,
                "mu_k": c.mu_k,
                "v_th": c.v_th,
                "poc": c.poc,
            },
            "readback": {
                "gravity": self.g,
                "lower": list(self.lower),
                "upper": list(self.upper),
                "effort": list(self.effort),
            },
        }

    def warnings(self) -> list[str]:
        """Why the Python solve runs where the compiled one was asked for (numba missing)."""
        return [self._kernel_note] if self._kernel_note else []

    # ------------------------------------------------------- declared abilities
    def integrator_family(self) -> str:
        return "adaptive"

    def engine_contact(self) -> bool:
        """No contact model of its own: native and reference mode both apply the analytic law."""
        return False

    def sub_steps(self) -> int:
        return 1

    def limits(self) -> Limits:
        """Gravity of the solve, the clamped torque limits, position limits as the limit law enforces them."""
        return Limits(
            gravity=self.g,
            lower=self.lower,  # type: ignore[arg-type]
            upper=self.upper,  # type: ignore[arg-type]
            effort=self.effort,  # type: ignore[arg-type]
            timestep=None,
            enforcement=self.limit_law.describe(),
        )

    def kernels(self, q: np.ndarray, qd: np.ndarray, tau: np.ndarray) -> dict[str, Callable[[], None]]:
        """The generated forward dynamics and the contact law, as one right-hand-side evaluation calls them, marked
        with the right-hand sides the solves since the reset made per period on average (the run the bench timed:
        62-440 a period, not 1), so the floor is that many evaluations."""
        qdd, law, g = self._qdd, self.law, self.g
        rows = [
            (*a, *v, *t)
            for a, v, t in zip(np.asarray(q).tolist(), np.asarray(qd).tolist(), np.asarray(tau).tolist(), strict=True)
        ]

        def qdd_loop() -> None:
            for r in rows:
                qdd(*r, g)

        def law_loop() -> None:
            for r in rows:
                law(*r[:6])

        qdd_loop.calls_per_sub_step = law_loop.calls_per_sub_step = (  # type: ignore[attr-defined]
            self.nfev_total / self.periods if self.periods else 1.0
        )
        return {"qdd": qdd_loop, "law": law_loop}

    def mass_properties(self) -> dict[str, dict[str, Any]]:
        """Mass, COM and inertia per link as the generated equations hold them (link 3 with the foot)."""
        out = {}
        for name, (mass, com, inertia) in zip(LINK_NAMES, self.eom.module.LINKS, strict=True):
            out[name] = {"mass": mass, "com": list(com), "inertia": [list(row) for row in inertia]}
        return out
