"""Custom integrator on Pinocchio's articulated-body algorithm with the report's contact law.

Forward dynamics qdd = aba(q, qd, tau + tau_c + tau_lim): tau_c = J_poc^T F is the
analytic ground force (:mod:`legbench.contact`) applied at the point of contact,
equivalent to an external force on the foot; tau_lim is a stiff one-sided
spring-damper at the revolute joint limits (ABA knows no limits; Pinocchio's own
constraint models and solvers are not used: :mod:`legbench.backends.joint_limits`), which makes
the knee stop like the engines' limit constraints: 10 N m pushing the knee into
its 2.229 rad limit rests at 2.230 rad (1e4 N m/rad); MuJoCo rests at 2.2292
after overshooting to 2.252, PyBullet's hard limit peaks at 2.2293.

Integrators (setting ``integrator``): ``euler`` (semi-implicit: qd += dt qdd,
then q += dt qd, as MuJoCo's Euler and Bullet), ``rk4`` (classic, fixed step),
``rk45`` / ``dop853`` (adaptive, one solve per control period so control updates
stay on the grid: rk45 scipy's RK45 algorithm compiled, :mod:`legbench.backends.dopri`,
or scipy's solve_ivp with ``kernel: python``; dop853 solve_ivp). The sub-step ``dt``
must divide the control period.

Friction (setting ``friction``, ``euler`` only): ``implicit`` (default) solves
(I + h M0^-1 K) dqd = h ABA(q, qd, tau + J_poc^T F + tau_lim) per sub-step, with
K = -J_t^T dF_t/dv_t J_t the friction's slope and M0 the mass matrix frozen over
the control period (linearly implicit Euler in the friction, a W-method; explicit
in the rest, and exactly ``explicit`` out of contact). ``explicit`` is plain
semi-implicit Euler, which resolves the stick-slip law only for
h < m v_th / (mu_s Fn) (~5.9 us at the effort task's steady 52.5 N with v_th = 1e-3 m/s, m the
foot's apparent tangential mass 0.217 kg; 5.2 us at its 59.5 N peak)
and chatters above it: :meth:`warnings` says so with the numbers (for ``rk4`` at 2.785 times that bound,
RK4's stability interval). The joint-limit spring-damper is explicit in every fixed-step integrator and has a
step bound of its own (:func:`joint_limits.step_bound`: semi-implicit Euler 4 / (c + sqrt(c^2 + 4 k/I)),
c = b/I, I = 1/(M^-1)_jj; 570 us for the knee, whose limit diverges at 1 ms); :meth:`warnings` says so when
a run reached a limit with h above it.
docs/pinocchio.md has the trade-off, convergence and cost. Pinocchio is
legbench's own integrator, so its ``engine-defaults`` profile is these defaults.

Profiles: ``matched`` and ``engine-defaults`` are the defaults above (Pinocchio is
legbench's own integrator). ``ode45`` is the lab report's Simscape Multibody set-up,
MATLAB's ode45 (Dormand-Prince 5(4), adaptive): ``integrator: rk45`` (scipy's RK45 is the
same Dormand-Prince pair, its error norm RMS where ode45's is a max-norm: docs/pinocchio.md)
with the report's Simscape max step 2e-4 s and rtol 1e-6, atol 1e-8 (the report's, as legbench's
issue 13 gives them: docs/spec.md section 7), one solve per
control period; the contact law at the true point of contact as Simscape had it (the scenario's
``physics.contact.poc``, true by default: the poc is physics every backend shares, not a backend setting).

Ground force read-out: the law at the state at the end of the control period
(it is a function of the state); it matches the leg's statics over the effort
task's last 0.5 s to 1.2e-6 of Fn.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import pinocchio as pin

from legbench.backends import dopri, joint_limits, pinocchio_kernel
from legbench.backends.base import Backend, Limits, Physics, Range, sub_step_count
from legbench.backends.joint_limits import JointLimitLaw
from legbench.contact import (
    EULER_FRICTION_STABILITY,
    RK4_FRICTION_STABILITY,
    ReferenceContact,
    implicit_velocity_step,
    law_step_warnings,
)
from legbench.exceptions import LegbenchError, ModelError
from legbench.model import JOINT_NAMES, LINK_NAMES, load_params


class PinocchioBackend(Backend):
    """Pinocchio ABA + the analytic contact law, integrated by legbench."""

    name: ClassVar[str] = "pinocchio"
    #: rtol at or above scipy's floor (:data:`~legbench.backends.dopri.RTOL_MIN`, 2.2e-14): below it scipy raises it.
    ranges: ClassVar[Mapping[str, Range]] = {"rtol": Range(low=dopri.RTOL_MIN)}
    #: max_step [s] bounds the adaptive solve's step: control period / max_step is held to the sub-step limit.
    step_bounds: ClassVar[tuple[str, ...]] = ("max_step",)
    defaults: ClassVar[Mapping[str, Any]] = {
        "dt": 5.0e-5,  # sub-step [s]; docs/pinocchio.md: convergence check
        "integrator": "euler",
        "rtol": 1.0e-8,  # adaptive integrators only
        "atol": 1.0e-10,
        "max_step": 1.0e-4,  # [s], adaptive only (the report's ode45 setting)
        "limit_stiffness": joint_limits.STIFFNESS,  # [N m/rad]
        "limit_damping": joint_limits.DAMPING,  # [N m s/rad], over-damped for the knee (damping ratio 1.15-1.25)
        "friction": "implicit",  # euler only: friction slope linearly implicit (docs/pinocchio.md)
        "kernel": "compiled",  # euler, rk4, rk45: one compiled call per control period (pinocchio_kernel), or python
    }
    choices: ClassVar[Mapping[str, tuple[str, ...]]] = {
        "integrator": ("euler", "rk4", "rk45", "dop853"),
        "friction": ("implicit", "explicit"),
        "kernel": ("compiled", "python"),
    }
    #: Pinocchio is legbench's own integrator: its "engine defaults" are these defaults.
    #: ``ode45``: the lab report's Simscape solver (adaptive Dormand-Prince, its max step and tolerances).
    profiles: ClassVar[Mapping[str, Mapping[str, Any]]] = {
        "matched": {},
        "engine-defaults": {},
        "ode45": {"integrator": "rk45", "rtol": 1.0e-6, "atol": 1.0e-8, "max_step": 2.0e-4},
    }

    @property
    def bench_targets(self) -> Mapping[str, float]:
        """`legbench bench` targets (CPU time): the full run within 1.2x the engine-only replay (the harness's
        share); with the compiled fixed-step period (``kernel: compiled``, euler or rk4) also the replay within
        1.3x ``period_loop``, that period over the whole run in one numba call (ABA, law, limits and integration).
        The Python path and the adaptive integrators have no compiled floor to hold their replay to: that target
        does not apply to them (it read "not measured", and ``bench --check`` failed)."""
        if getattr(self, "_compiled", None) is not None:
            return {"replay/period_loop": 1.3, "full/replay": 1.2}
        return {"full/replay": 1.2}

    # ----------------------------------------------------------------- load
    def load(self, urdf: Path, physics: Physics, settings: Mapping[str, Any]) -> None:
        self.cfg = self.settings(settings)
        self.physics = physics
        self.model = pin.buildModelFromUrdf(str(urdf))
        self.model.gravity.linear = np.array([0.0, 0.0, -physics.gravity])
        self.data = self.model.createData()
        self.n_sub = sub_step_count(self.name, self.cfg["dt"], physics.control_dt)
        self.h = physics.control_dt / self.n_sub
        self.contact = ReferenceContact.from_leg(physics.contact)
        p = load_params()
        self.lower = [j.lower for j in p.joints]
        self.upper = [j.upper for j in p.joints]
        self._check_model(urdf)
        #: tau_lim at the revolute limits (the continuous hip has none: +-inf)
        self.limit_law = JointLimitLaw(self.lower, self.upper, self.cfg["limit_stiffness"], self.cfg["limit_damping"])
        self._qp = np.zeros(self.model.nq)
        self._v = np.zeros(3)
        self._tau = np.zeros(3)
        self.q = [0.0, 0.0, 0.0]
        self.qd = [0.0, 0.0, 0.0]
        self.force = np.zeros(3)
        #: The contact law called at every sub-step (floats in, (tau_c, F) out); `legbench bench` times it.
        self.law = self.contact.wrench
        self._aba = pin.aba
        self.slope = self.contact.wrench_slope
        self.implicit = self.cfg["integrator"] == "euler" and self.cfg["friction"] == "implicit"
        euler = self._euler_implicit if self.implicit else self._euler
        self._step = {"euler": euler, "rk4": self._rk4}.get(self.cfg["integrator"], self._adaptive)
        self._fn_peak, self._q_peak = 0.0, [0.0, 0.0, 0.0]
        self._nfev, self._periods = 0, 0  # an adaptive solve's right-hand sides since the reset (the bench's floor)
        #: per joint the largest (M^-1)_jj [1/(kg m^2)] at which it was past its limit in this run, 0 if never
        #: (the Python sub-steps; the compiled period keeps it in its scratch: pinocchio_kernel.limit_record)
        self._limit_minv = [0.0, 0.0, 0.0]
        self._kernel_note = ""
        self._compiled = self._load_kernel() if self.cfg["integrator"] in ("euler", "rk4") else None
        if self._compiled is not None:
            self._step = self._period_compiled
        self._dopri = self._load_dopri() if self.cfg["integrator"] == "rk45" else None
        if self._dopri is not None:
            self._step = self._rk45_compiled

    def _check_model(self, urdf: Path) -> None:
        """Refuse a URDF whose joints this backend would simulate otherwise than it says: joint damping or dry
        friction (``<dynamics>``; ``pin.aba`` and the compiled ABA ignore both), or position limits other than the
        leg's (the limit law takes them from the leg's parameters, not from the URDF). legbench's own URDF has
        neither; one given to :meth:`load` by hand could."""
        model = self.model
        for what, values in (("damping", model.damping), ("friction", model.friction)):
            if np.any(np.asarray(values) != 0.0):
                raise ModelError(f"{urdf}: joint {what} {np.asarray(values).tolist()}: pin.aba does not apply it; "
                                 "the leg's joints have none (put it in the controller, or use an engine that models "
                                 "it)")  # fmt: skip
        for name, lo, hi in zip(JOINT_NAMES, self.lower, self.upper, strict=True):
            idx = model.getJointId(name)
            if idx >= model.njoints:
                raise ModelError(f"{urdf}: no joint {name!r}")
            if model.joints[idx].nq != 1 or not math.isfinite(lo):  # the continuous hip: no limits to compare
                continue
            got = (float(model.lowerPositionLimit[model.joints[idx].idx_q]),
                   float(model.upperPositionLimit[model.joints[idx].idx_q]))  # fmt: skip
            if not np.allclose(got, (lo, hi), rtol=0.0, atol=1e-9):
                raise ModelError(f"{urdf}: joint {name} limits {got} rad, the leg's are ({lo}, {hi}) rad: the limit "
                                 "law takes the leg's")  # fmt: skip

    def _kernel_inputs(self, fallback: str) -> tuple[Any, ...] | None:
        """The model's arrays (:func:`pinocchio_kernel.model_arrays`), the law's constants and the limits', for a
        compiled period; or None, and why in :meth:`warnings` where the compiled period was asked for: numba
        missing, or a model the kernel cannot integrate (``fallback``: what runs instead)."""
        if self.cfg["kernel"] != "compiled":
            return None
        if not pinocchio_kernel.available():
            self._kernel_note = f"pinocchio: numba is not installed: {fallback} runs (pip install numba)"
            return None
        try:
            R, p, inertia, a0 = pinocchio_kernel.model_arrays(self.model)
        except pinocchio_kernel.KernelUnavailable as exc:
            self._kernel_note = f"pinocchio: {exc}: {fallback} runs"
            return None
        lc = np.array(self.contact.constants)
        lim = np.array([*self.lower, *self.upper, self.limit_law.k, self.limit_law.b], dtype=float)
        return R, p, inertia, a0, lc, lim

    def _load_kernel(self) -> tuple[Any, ...] | None:
        """The compiled period's arguments (:mod:`legbench.backends.pinocchio_kernel`), or None: the Python
        path then runs (setting ``kernel: python``, numba missing, or a model the kernel cannot integrate)."""
        inputs = self._kernel_inputs("the Python sub-steps")
        if inputs is None:
            return None
        R, p, inertia, a0, lc, lim = inputs
        #: state and read-out (q1..3, qd1..3, fx, fy, fz) and the kernel's arrays: all reused every period
        self._x = np.zeros(9)
        model, scratch = pinocchio_kernel.pack(R, p, inertia, a0, lc, lim)
        self._limit_view = pinocchio_kernel.limit_record(scratch)
        if self.cfg["integrator"] == "rk4":
            method = pinocchio_kernel.RK4
        else:
            method = pinocchio_kernel.EULER_IMPLICIT if self.implicit else pinocchio_kernel.EULER
        return (model, scratch, self._x, self.h, self.n_sub, method)

    def _load_dopri(self) -> tuple[Any, ...] | None:
        """The compiled ``rk45`` period (:func:`pinocchio_kernel.dopri_period`) and its arrays, or None: solve_ivp
        then runs (setting ``kernel: python``, numba missing, or a model the kernel cannot integrate)."""
        inputs = self._kernel_inputs("scipy's solve_ivp")
        if inputs is None:
            return None
        R, p, inertia, a0, lc, lim = inputs
        #: (period, x, u, law constants, limits, stages' scratch, model and ABA scratch), all reused every period
        return (pinocchio_kernel.dopri_period(), np.zeros(6), np.zeros(3), lc, lim, np.zeros((9, 6)),
                pinocchio_kernel.dopri_data(R, p, inertia, a0))  # fmt: skip

    # ---------------------------------------------------------------- reset
    def reset(self, q: np.ndarray, qd: np.ndarray) -> None:
        self._fn_peak, self._q_peak = 0.0, [float(x) for x in q]
        self._nfev, self._periods = 0, 0  # an adaptive solve's right-hand sides since the reset (the bench's floor)
        self._limit_minv = [0.0, 0.0, 0.0]
        self.q = [float(x) for x in q]
        self.qd = [float(x) for x in qd]
        self._update_force()
        if self._compiled is not None:
            x = self._x
            x[0:3], x[3:6], x[6:9] = self.q, self.qd, self.force
            self._limit_view[:] = 0.0

    # ----------------------------------------------------------------- step
    def _qdd(self, q: Sequence[float], qd: Sequence[float], tau: Sequence[float]) -> tuple[float, float, float]:
        """Joint accelerations [rad/s^2] for state (q, qd) and applied torque tau, as floats."""
        q1, q2, q3 = q
        qd1, qd2, qd3 = qd
        tc1, tc2, tc3, _, _, _ = self.law(q1, q2, q3, qd1, qd2, qd3)
        tl1, tl2, tl3 = self.limit_law(q1, q2, q3, qd1, qd2, qd3)
        t1, t2, t3 = tau[0] + tc1 + tl1, tau[1] + tc2 + tl2, tau[2] + tc3 + tl3
        qp, v, t = self._qp, self._v, self._tau
        qp[0], qp[1], qp[2], qp[3] = q1, math.cos(q2), math.sin(q2), q3
        v[0], v[1], v[2] = qd1, qd2, qd3
        t[0], t[1], t[2] = t1, t2, t3
        a1, a2, a3 = self._aba(self.model, self.data, qp, v, t).tolist()
        return a1, a2, a3

    def _euler(self, tau: np.ndarray) -> None:
        """Semi-implicit Euler sub-steps: :meth:`_qdd` inlined, on floats, everything bound to locals."""
        h = self.h
        aba, model, data, law = self._aba, self.model, self.data, self.law
        qp, v, t = self._qp, self._v, self._tau
        cos, sin = math.cos, math.sin
        limit_law = self.limit_law
        u1, u2, u3 = np.asarray(tau, dtype=float).tolist()
        q1, q2, q3 = self.q
        qd1, qd2, qd3 = self.qd
        seen = 0  # joints whose limit this period has recorded (bits)
        for _ in range(self.n_sub):
            tc1, tc2, tc3, _, _, _ = law(q1, q2, q3, qd1, qd2, qd3)
            tl1, tl2, tl3 = limit_law(q1, q2, q3, qd1, qd2, qd3)
            t1, t2, t3 = u1 + tc1 + tl1, u2 + tc2 + tl2, u3 + tc3 + tl3
            qp[0], qp[1], qp[2], qp[3] = q1, cos(q2), sin(q2), q3
            if tl1 != 0.0 or tl2 != 0.0 or tl3 != 0.0:
                seen = self._record_limits(qp, (tl1, tl2, tl3), seen)
            v[0], v[1], v[2] = qd1, qd2, qd3
            t[0], t[1], t[2] = t1, t2, t3
            a1, a2, a3 = aba(model, data, qp, v, t).tolist()
            qd1 = qd1 + h * a1
            qd2 = qd2 + h * a2
            qd3 = qd3 + h * a3
            q1 = q1 + h * qd1
            q2 = q2 + h * qd2
            q3 = q3 + h * qd3
        self.q = [q1, q2, q3]
        self.qd = [qd1, qd2, qd3]

    def _euler_implicit(self, tau: np.ndarray) -> None:
        """Semi-implicit Euler with the friction slope linearly implicit (the default).

        Per sub-step, with a = ABA(q, qd, tau + J_poc^T F + tau_lim) the explicit acceleration:
        (I + h M0^-1 K) dqd = h a, qd += dqd, q += h qd. K = -J_t^T dF_t/dv_t J_t is the
        friction's slope from :meth:`ReferenceContact.wrench_slope` at the sub-step's start, M0^-1
        the inverse mass matrix at the period's first sub-step in contact (a W-method: the exact
        M enters through ABA, the frozen one only the implicit correction). Below v_th the law is a viscous
        friction of coefficient mu_s Fn / v_th, which explicit Euler resolves only for
        h < m v_th / (mu_s Fn); treated implicitly it is stable at any h, and a fixed point of the
        step (dqd = 0 <=> a = 0) is a fixed point of the law, so steady creep and force are the
        law's. Out of contact K = 0 and the step is exactly :meth:`_euler`.
        """
        h = self.h
        aba, model, data, slope = self._aba, self.model, self.data, self.slope
        qp, v, t = self._qp, self._v, self._tau
        cos, sin = math.cos, math.sin
        limit_law = self.limit_law
        u1, u2, u3 = np.asarray(tau, dtype=float).tolist()
        q1, q2, q3 = self.q
        qd1, qd2, qd3 = self.qd
        minv: tuple[float, ...] | None = None  # M0^-1, at the period's first sub-step in contact
        solve = implicit_velocity_step
        seen = 0  # joints whose limit this period has recorded (bits)
        for _ in range(self.n_sub):
            tc1, tc2, tc3, _, _, _, K11, K12, K13, K22, K23, K33 = slope(q1, q2, q3, qd1, qd2, qd3)
            tl1, tl2, tl3 = limit_law(q1, q2, q3, qd1, qd2, qd3)
            t1, t2, t3 = u1 + tc1 + tl1, u2 + tc2 + tl2, u3 + tc3 + tl3
            qp[0], qp[1], qp[2], qp[3] = q1, cos(q2), sin(q2), q3
            if tl1 != 0.0 or tl2 != 0.0 or tl3 != 0.0:
                seen = self._record_limits(qp, (tl1, tl2, tl3), seen)
            v[0], v[1], v[2] = qd1, qd2, qd3
            t[0], t[1], t[2] = t1, t2, t3
            a1, a2, a3 = aba(model, data, qp, v, t).tolist()
            if K11 == 0.0 and K22 == 0.0 and K33 == 0.0:
                x1, x2, x3 = h * a1, h * a2, h * a3
            else:
                if minv is None:  # first sub-step in contact of this period
                    (m11, m12, m13), (_, m22, m23), (_, _, m33) = self._minverse(qp).tolist()
                    minv = (m11, m12, m13, m22, m23, m33)
                x1, x2, x3 = solve(h, minv, (K11, K12, K13, K22, K23, K33), a1, a2, a3)
            qd1 = qd1 + x1
            qd2 = qd2 + x2
            qd3 = qd3 + x3
            q1 = q1 + h * qd1
            q2 = q2 + h * qd2
            q3 = q3 + h * qd3
        self.q = [q1, q2, q3]
        self.qd = [qd1, qd2, qd3]

    def _record_limits(self, qp: np.ndarray, tl: tuple[float, float, float], seen: int) -> int:
        """:func:`pinocchio_kernel._record_limits` for the Python sub-steps: for each joint past its limit (limit
        torque ``tl`` [N m] non-zero) not yet recorded this period (bit j of ``seen``), the largest (M^-1)_jj
        [1/(kg m^2)] at Pinocchio's configuration ``qp`` into :attr:`_limit_minv`; returns the new ``seen``."""
        if all(t == 0.0 or seen & (1 << j) for j, t in enumerate(tl)):
            return seen
        mi = self._minverse(qp)
        rec = self._limit_minv
        for j, t in enumerate(tl):
            if t != 0.0:
                rec[j] = max(rec[j], float(mi[j, j]))
                seen |= 1 << j
        return seen

    def _minverse(self, qp: np.ndarray) -> np.ndarray:
        """M(q)^-1 [1/(kg m^2)] at Pinocchio's configuration vector ``qp``, symmetric (both triangles)."""
        Mi = pin.computeMinverse(self.model, self.data, qp)
        return np.triu(Mi) + np.triu(Mi, 1).T

    def _rk4(self, tau: np.ndarray) -> None:
        h = self.h
        u = np.asarray(tau, dtype=float).tolist()
        q, qd = self.q, self.qd
        limit_law, qp, cos, sin = self.limit_law, self._qp, math.cos, math.sin
        seen = 0  # joints whose limit this period has recorded (bits)
        for _ in range(self.n_sub):
            tl = limit_law(q[0], q[1], q[2], 0.0, 0.0, 0.0)  # the spring alone: non-zero past a limit
            if tl[0] != 0.0 or tl[1] != 0.0 or tl[2] != 0.0:
                qp[0], qp[1], qp[2], qp[3] = q[0], cos(q[1]), sin(q[1]), q[2]
                seen = self._record_limits(qp, tl, seen)
            a1 = self._qdd(q, qd, u)
            v1 = qd
            q2 = [q[i] + 0.5 * h * v1[i] for i in range(3)]
            v2 = [qd[i] + 0.5 * h * a1[i] for i in range(3)]
            a2 = self._qdd(q2, v2, u)
            q3 = [q[i] + 0.5 * h * v2[i] for i in range(3)]
            v3 = [qd[i] + 0.5 * h * a2[i] for i in range(3)]
            a3 = self._qdd(q3, v3, u)
            q4 = [q[i] + h * v3[i] for i in range(3)]
            v4 = [qd[i] + h * a3[i] for i in range(3)]
            a4 = self._qdd(q4, v4, u)
            q = [q[i] + h / 6.0 * (v1[i] + 2 * v2[i] + 2 * v3[i] + v4[i]) for i in range(3)]
            qd = [qd[i] + h / 6.0 * (a1[i] + 2 * a2[i] + 2 * a3[i] + a4[i]) for i in range(3)]
        self.q, self.qd = q, qd

    def _adaptive(self, tau: np.ndarray) -> None:
        u = np.asarray(tau, dtype=float).tolist()

        def f(_t: float, x: np.ndarray) -> np.ndarray:
            q, qd = x[:3].tolist(), x[3:].tolist()
            return np.concatenate([x[3:], self._qdd(q, qd, u)])

        from scipy.integrate import solve_ivp  # 0.7 s of imports: only when an adaptive solver runs

        sol = solve_ivp(
            f,
            (0.0, self.physics.control_dt),
            np.array(self.q + self.qd),
            method="RK45" if self.cfg["integrator"] == "rk45" else "DOP853",
            rtol=self.cfg["rtol"],
            atol=self.cfg["atol"],
            max_step=self.cfg["max_step"],
        )
        if not sol.success:
            raise LegbenchError(f"pinocchio: {self.cfg['integrator']} failed: {sol.message}")
        x = sol.y[:, -1]
        self.q, self.qd = x[:3].tolist(), x[3:].tolist()
        self._nfev, self._periods = self._nfev + int(sol.nfev), self._periods + 1

    def _rk45_compiled(self, tau: np.ndarray) -> None:
        """:meth:`_adaptive`'s RK45 solve in one compiled call: scipy's algorithm step for step
        (:mod:`legbench.backends.dopri`) over the compiled law, limits and ABA."""
        period, x, u, lc, lim, k, data = self._dopri  # type: ignore[misc]
        q, qd = self.q, self.qd
        x[0], x[1], x[2], x[3], x[4], x[5] = q[0], q[1], q[2], qd[0], qd[1], qd[2]
        u[0], u[1], u[2] = float(tau[0]), float(tau[1]), float(tau[2])
        cfg = self.cfg
        n = period(x, u, 0.0, lc, lim, self.physics.control_dt, cfg["rtol"], cfg["atol"], cfg["max_step"], k, data)
        if n < 0:
            raise LegbenchError("pinocchio: rk45 failed: Required step size is less than spacing between numbers.")
        self.q, self.qd = x[0:3].tolist(), x[3:6].tolist()
        self._nfev, self._periods = self._nfev + n, self._periods + 1

    def _period_compiled(self, tau: np.ndarray) -> None:
        """:meth:`_euler_implicit` (or :meth:`_euler`, :meth:`_rk4`) and the force read-out in one compiled call."""
        model, scratch, x, h, n_sub, method = self._compiled  # type: ignore[misc]
        if type(tau) is not np.ndarray or tau.dtype != np.float64 or tau.shape != (3,):  # a list, ints, a column
            tau = np.array(tau, dtype=float).reshape(3)
        self._period(model, scratch, tau, x, h, n_sub, method)
        if x[8] > self._fn_peak:
            self._fn_peak, self._q_peak = float(x[8]), x[0:3].tolist()

    _period = staticmethod(pinocchio_kernel.period)

    def step(self, tau: np.ndarray) -> None:
        if self._compiled is not None:
            self._period_compiled(tau)
            return
        self._step(tau)
        self._update_force()

    def _update_force(self) -> None:
        q, qd = self.q, self.qd
        f = self.force
        _, _, _, f[0], f[1], f[2] = self.law(q[0], q[1], q[2], qd[0], qd[1], qd[2])
        if f[2] > self._fn_peak:
            self._fn_peak, self._q_peak = float(f[2]), list(q)

    # ----------------------------------------------------------------- read
    def state(self) -> tuple[np.ndarray, np.ndarray]:
        if self._compiled is not None:
            return self._x[0:3].copy(), self._x[3:6].copy()
        return np.array(self.q), np.array(self.qd)

    def ground_force(self) -> np.ndarray:
        if self._compiled is not None:
            return self._x[6:9].copy()
        return self.force.copy()

    def read(self) -> tuple[float, ...]:
        if self._compiled is not None:
            return tuple(self._x.tolist())
        f = self.force
        return (*self.q, *self.qd, float(f[0]), float(f[1]), float(f[2]))

    def info(self) -> dict[str, Any]:
        c = self.physics.contact
        # only the settings the integrator reads: the tolerances are the adaptive solvers', the sub-step the
        # fixed-step ones', the implicit friction semi-implicit Euler's, the compiled kernel all but dop853's
        adaptive = self.integrator_family() == "adaptive"
        unused = {"dt"} if adaptive else {"rtol", "atol", "max_step"}
        if self.cfg["integrator"] == "dop853":
            unused |= {"kernel"}
        if self.cfg["integrator"] != "euler":
            unused |= {"friction"}
        compiled = self._compiled is not None or self._dopri is not None
        return {
            "engine": "pinocchio",
            "version": pin.__version__,
            "dynamics": (
                "legbench's ABA compiled with numba on Pinocchio's model (its qdd agrees with pin.aba to round-off, "
                "its runs with the pin.aba path's to 1e-12 rad); "
                "legbench's integrator and contact law"
                if compiled
                else "pin.aba (Pinocchio); legbench's integrator and contact law"
            ),
            **{k: self.cfg[k] for k in self.defaults if k not in unused},
            "sub_steps": self.sub_steps(),
            "kernel_used": "compiled (numba)" if compiled else "python",
            "gravity": self.physics.gravity,
            "contact_mode": self.physics.contact_mode,
            "contact": {
                "law": "analytic (docs/spec.md section 4), J_poc^T F",
                "Kp": c.Kp,
                "Kd": c.Kd,
                "mu_s": c.mu_s,
                "mu_k": c.mu_k,
                "v_th": c.v_th,
                "poc": c.poc,
            },
        }

    def warnings(self) -> list[str]:
        """Why the compiled period does not run where it was asked for; for the fixed-step integrators the step
        bounds the run exceeded: the explicit law's (euler with ``friction: explicit``: h <= m v_th / (mu_s Fn);
        rk4: 2.785 times that, :data:`~legbench.contact.RK4_FRICTION_STABILITY`) at the run's peak Fn, and the
        joint-limit spring-damper's (:meth:`limit_step_warnings`)."""
        notes = [self._kernel_note] if self._kernel_note else []
        integ = self.cfg["integrator"]
        if integ not in ("euler", "rk4"):
            return notes
        notes += self.limit_step_warnings()
        if self.implicit:
            return notes
        stability = RK4_FRICTION_STABILITY if integ == "rk4" else EULER_FRICTION_STABILITY
        return notes + law_step_warnings(self.name, self.h, self._fn_peak, self._q_peak, self.physics.contact,
                                         stability)  # fmt: skip

    def limit_step_warnings(self) -> list[str]:
        """The warning for a run that reached a joint limit with a sub-step h [s] above the limit spring-damper's
        stability bound, or none.

        The bound is :func:`joint_limits.step_bound` for the integrator (semi-implicit Euler, also with the
        implicit friction: the limit law is explicit in it, h < 4 / (c + sqrt(c^2 + 4 k/I)) with c = b/I; RK4:
        its stability region), k and b the limit's stiffness [N m/rad] and damping [N m s/rad], and
        I = 1 / (M^-1)_jj [kg m^2] the joint's effective inertia, the smallest at which the run was past the
        joint's limit (recorded at each period's first sub-step past it: the compiled period keeps it in its
        scratch, three comparisons per sub-step inside the limits, see :func:`pinocchio_kernel._record_limits`).
        Empty for the adaptive integrators (their error control sets the step) and for a run that stayed inside
        the limits.
        """
        integ = self.cfg["integrator"]
        if integ not in joint_limits.INTEGRATORS:
            return []
        rec = self._limit_view.tolist() if self._compiled is not None else self._limit_minv
        k, b = self.limit_law.k, self.limit_law.b
        reached = [(joint_limits.step_bound(k, b, 1.0 / m, integ), j, 1.0 / m) for j, m in enumerate(rec) if m > 0.0]
        if not reached:
            return []
        bound, j, inertia = min(reached)
        if self.h <= bound:
            return []
        how = ("semi-implicit Euler is stable there for h < 4 / (c + sqrt(c^2 + 4 k / I)), c = b / I"
               if integ == "euler" else "RK4 is stable there for h within its stability region")  # fmt: skip
        return [
            f"{self.name}: sub-step {self.h:.3g} s is too coarse for the joint-limit spring-damper: "
            f"{JOINT_NAMES[j]} reached its limit, there with effective inertia down to I = 1/(M^-1)_jj = "
            f"{inertia:.3g} kg m^2, and with k = {k:g} N m/rad, b = {b:g} N m s/rad {how}: {bound:.3g} s; the limit "
            f"bounces or diverges (use a sub-step <= {bound:.2g} s)"
        ]

    # ------------------------------------------------------- declared abilities
    def integrator_family(self) -> str:
        integ = self.cfg["integrator"]
        return integ if integ in ("euler", "rk4") else "adaptive"

    def engine_contact(self) -> bool:
        """The contact is legbench's analytic law in both modes: Pinocchio's ABA has none, and Pinocchio's
        own constraint solvers (unilateral point contacts in a friction cone, rigid or linearly compliant, ADMM
        or PGS), which cannot express the law's press-in-only damping and its slip-speed friction, are not used."""
        return False

    def sub_steps(self) -> int:
        """Fixed-step sub-steps per control period; 1 for the adaptive integrators (one solve per period, as
        the lagrange backend declares), whose steps their error control chooses."""
        return 1 if self.integrator_family() == "adaptive" else self.n_sub

    def limits(self) -> Limits:
        """Model gravity and ``effortLimit``; position limits as the integrator enforces them."""
        m = self.model
        return Limits(
            gravity=-float(m.gravity.linear[2]),
            lower=tuple(float(x) for x in self.lower),  # type: ignore[arg-type]
            upper=tuple(float(x) for x in self.upper),  # type: ignore[arg-type]
            effort=tuple(float(x) for x in m.effortLimit),  # type: ignore[arg-type]
            timestep=self.h if self.cfg["integrator"] in ("euler", "rk4") else None,
            enforcement=self.limit_law.describe(),
        )

    def kernels(self, q: np.ndarray, qd: np.ndarray, tau: np.ndarray) -> dict[str, Any]:
        """The bench's floors (:meth:`Backend.kernels`).

        ``aba`` and ``law`` (per evaluation; the bench adds them up as ``aba+law``, as many times per sub-step as the
        run evaluates them: 1 for euler, 4 for rk4, an adaptive solve's right-hand sides per period as the run
        made them): ``pin.aba`` on this backend's model and data and the contact law, called from Python at each
        logged state: the Python path's calls through the binding, without the integration (not a floor of the
        compiled period, which calls neither). With the compiled period (``kernel: compiled``, ``euler`` or
        ``rk4``) also ``period_loop`` (per control period): the backend's own compiled period
        (:func:`pinocchio_kernel.period`, the same arguments as :meth:`step` passes) once per logged torque, the
        whole pass one compiled call (:func:`pinocchio_kernel.period_loop`: no Python per tick), from the first
        row's state (the run's initial state), on its own scratch and state arrays (the backend's state is left
        alone). Its
        ``end_state()`` is the pass's final (q, qd): the run's last logged state, bit for bit, which the bench
        checks as it checks the replay's. What the replay adds to it is the Python loop, one numba dispatch
        per period and the peak-force record."""
        aba, model, data, law = self._aba, self.model, self.data, self.law
        pin_in = [
            (np.array([a[0], math.cos(a[1]), math.sin(a[1]), a[2]]), np.array(v), np.array(t))
            for a, v, t in zip(np.asarray(q), np.asarray(qd), np.asarray(tau), strict=True)
        ]
        law_in = [(*a, *v) for a, v in zip(np.asarray(q).tolist(), np.asarray(qd).tolist(), strict=True)]

        def aba_loop() -> None:
            for qp, v, t in pin_in:
                aba(model, data, qp, v, t)

        def law_loop() -> None:
            for x in law_in:
                law(*x)

        # as often as the run calls them per sub-step: RK4's four stages; an adaptive solve's right-hand sides per
        # period, as many as the backend's own solves since its reset made on average (the run the bench timed)
        if self.integrator_family() == "adaptive":
            calls = self._nfev / self._periods if self._periods else 1.0
        else:
            calls = 4.0 if self.cfg["integrator"] == "rk4" else 1.0
        aba_loop.calls_per_sub_step = law_loop.calls_per_sub_step = calls  # type: ignore[attr-defined]
        out: dict[str, Any] = {"aba": aba_loop, "law": law_loop}
        if self._compiled is not None and len(tau) > 0:
            packed, scratch, _, h, n_sub, method = self._compiled
            own = np.zeros_like(scratch)  # the floor's own scratch; the packed model is only read
            x0, x = np.zeros(9), np.zeros(9)
            x0[0:3], x0[3:6] = np.asarray(q, dtype=float)[0], np.asarray(qd, dtype=float)[0]
            TAU = np.ascontiguousarray(tau, dtype=float)
            loop = pinocchio_kernel.period_loop

            def period_loop() -> None:
                loop(packed, own, x0, TAU, x, h, n_sub, method)

            def end_state() -> tuple[np.ndarray, np.ndarray]:
                return x[0:3].copy(), x[3:6].copy()

            period_loop.per_tick = True  # type: ignore[attr-defined]
            period_loop.end_state = end_state  # type: ignore[attr-defined]
            out["period_loop"] = period_loop
        return out

    def mass_properties(self) -> dict[str, dict[str, Any]]:
        out = {}
        for i, name in enumerate(LINK_NAMES, start=1):
            Y = self.model.inertias[i]
            out[name] = {"mass": float(Y.mass), "com": Y.lever.tolist(), "inertia": Y.inertia.tolist()}
        return out
