"""Equations of motion of a serial chain, derived symbolically (Euler-Lagrange) and cached as Python code.

The derivation follows the lab report's analytic model: link frames from the
modified (Craig) DH parameters, the kinetic energy of every link from its
mass, COM and inertia tensor, the potential energy in gravity along -z_W, and
the Euler-Lagrange equations collected as

    B(q) qdd + C(q, qd) qd + G(q) = tau

with B the mass matrix (the Hessian of the kinetic energy in qd), C from the
Christoffel symbols of B, c_ijk = (dB_ij/dq_k + dB_ik/dq_j - dB_jk/dq_i) / 2,
C_ij = sum_k c_ijk qd_k, and G = dV/dq. Nothing here is specific to the leg:
:class:`Chain` describes any chain of revolute joints (the tests derive a 1-DOF
pendulum and a planar 2-DOF arm with it), :func:`leg_chain` builds the leg's.

The only simplification is exact and cheap: every entry, a polynomial in sin q_i and cos q_i, is
reduced modulo sin^2 q_i + cos^2 q_i = 1.

Generated code: one Python module per chain, written to a cache directory
under a name that is the SHA-256 of the chain's numbers, of this module's source
and of sympy's version (:data:`DERIVATION`), so a chain is derived once per machine
and derivation code and only loaded afterwards (:func:`load_eom`); an edit to the
derivation or another sympy derives again. Expressions go through
common-subexpression elimination (a cold load, sympy's import, the derivation, the code's generation and
import, takes 1-2.5 s of CPU: docs/lagrange.md).
"""

from __future__ import annotations

import hashlib
import importlib.util
import json
import math
import os
import sys
import tempfile
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType
from typing import TYPE_CHECKING, Any, TypeAlias

from legbench import resources
from legbench.model import W_T_0, LegParams

if TYPE_CHECKING:
    import sympy as sp

# sympy is imported only where a derivation needs it: loading cached equations does not pay for it.

#: Bumped whenever the generated code changes shape; part of the cache key (4: squares written x*x).
GENERATOR_VERSION = 4


def _derivation() -> str:
    """What derives the equations, for the cache key: this module's source and sympy's version (an edited
    derivation, or another sympy, must not reuse equations derived by the old one)."""
    from importlib import metadata

    try:
        sympy_version = metadata.version("sympy")
    except metadata.PackageNotFoundError:  # no sympy: nothing can be derived; cached equations still load
        sympy_version = "none"
    return hashlib.sha256(Path(__file__).read_bytes() + sympy_version.encode()).hexdigest()


#: SHA-256 of this module's source and sympy's version, part of every chain's cache key.
DERIVATION = _derivation()

#: Number of symbolic derivations made in this process (the cache test observes it).
derivations = 0

Number: TypeAlias = "float | sp.Expr"


@dataclass(frozen=True)
class Link:
    """One moving link behind a revolute joint, modified DH (Craig).

    ``i-1_T_i = Rx(alpha) Tx(a) Rz(theta) Tz(d)`` with ``theta = q_i + offset``.

    Attributes:
        alpha: twist alpha_{i-1} [rad] (a float or an exact sympy value such as ``pi/2``).
        a: length a_{i-1} [m].
        d: offset d_i [m].
        offset: joint angle offset, theta_i - q_i [rad].
        mass: [kg].
        com: centre of mass in the link frame [m], (3,).
        inertia: inertia tensor about the COM in the link frame [kg m^2], 3x3 (URDF convention,
            I_xy = -integral(x y dm)).
    """

    alpha: Number
    a: Number
    d: Number
    offset: Number
    mass: Number
    com: tuple[Number, Number, Number]
    inertia: tuple[tuple[Number, ...], ...]


@dataclass(frozen=True)
class Chain:
    """A fixed-base serial chain: the base frame 0 in W, then the links in order.

    Gravity acts along -z_W.

    Attributes:
        base: W_T_0, 4x4 homogeneous transform (rows).
        links: the moving links, joint 1 first.
    """

    base: tuple[tuple[Number, ...], ...]
    links: tuple[Link, ...]

    @property
    def n(self) -> int:
        """Degrees of freedom."""
        return len(self.links)

    def key(self) -> str:
        """SHA-256 of every number of the chain (full double precision), the generator version and
        :data:`DERIVATION` (this module's source and sympy's version)."""

        def enc(x: Any) -> Any:
            if isinstance(x, tuple | list):
                return [enc(v) for v in x]
            if isinstance(x, int | float):
                return float(x).hex()
            import sympy as sp

            return sp.srepr(x)

        body = {
            "version": GENERATOR_VERSION,
            "derivation": DERIVATION,
            "base": enc(self.base),
            "links": [enc([ln.alpha, ln.a, ln.d, ln.offset, ln.mass, ln.com, ln.inertia]) for ln in self.links],
        }
        return hashlib.sha256(json.dumps(body, sort_keys=True).encode()).hexdigest()


def leg_chain(params: LegParams) -> Chain:
    """The leg as a :class:`Chain`: the DH table and W_T_0 of the lab report, the model's inertials.

    Link 3 carries the foot (its composite inertial, :meth:`LegParams.body_inertial`).
    """
    g = params.geometry
    dh = (  # (alpha_{i-1}, a_{i-1}, d_i, theta_i - q_i)
        (0, 0.0, -g.L_01, 0),
        (math.pi / 2, 0.0, g.L_12, -math.pi / 2),
        (0, g.L_23, 0.0, 0),
    )
    links = []
    for (alpha, a, d, offset), name in zip(dh, ("link1", "link2", "link3"), strict=True):
        inr = params.body_inertial(name)
        links.append(Link(alpha, a, d, offset, inr.mass, tuple(inr.com), inr.inertia))  # type: ignore[arg-type]
    base = tuple(tuple(float(v) for v in row) for row in W_T_0(g))
    return Chain(base=base, links=tuple(links))


# --------------------------------------------------------------------------- #
# Derivation


def _num(x: Number) -> sp.Expr:
    """A number for the derivation: sympy values as given; whole floats exact (so 0 * x vanishes); any other
    float with all its 53 bits (a mass or length that happens to equal pi/2 stays a number: as sympy's pi it
    reached the generated code, which has no pi)."""
    import sympy as sp

    if isinstance(x, sp.Basic):
        return x  # type: ignore[return-value]
    xf = float(x)
    if xf.is_integer():
        return sp.Integer(int(xf))
    return sp.Float(xf)


def _angle(x: Number) -> sp.Expr:
    """A DH twist or offset [rad]: :func:`_num`, but a whole multiple of pi/2 to the last bit exact, so that
    cos(pi/2) vanishes and cos(q + pi/2) becomes -sin(q)."""
    import sympy as sp

    if not isinstance(x, sp.Basic):
        xf = float(x)
        k = round(xf / (math.pi / 2))
        if k != 0 and k * (math.pi / 2) == xf:
            return k * sp.pi / 2  # type: ignore[no-any-return]
    return _num(x)


def _dh(alpha: sp.Expr, a: sp.Expr, d: sp.Expr, theta: sp.Expr) -> sp.Matrix:
    """Modified-DH transform i-1_T_i."""
    import sympy as sp

    ca, sa, ct, st = sp.cos(alpha), sp.sin(alpha), sp.cos(theta), sp.sin(theta)
    return sp.Matrix([[ct, -st, 0, a], [ca * st, ca * ct, -sa, -sa * d], [sa * st, sa * ct, ca, ca * d], [0, 0, 0, 1]])


@dataclass
class Derivation:
    """The symbolic equations of motion of a chain (gravity magnitude 1: G scales with g).

    Attributes:
        q, qd, qdd: joint symbols.
        T: kinetic energy [J]; V: potential energy per unit g [J / (m/s^2)].
        el: the Euler-Lagrange left-hand side d/dt(dL/dqd) - dL/dq (unit g), in q, qd, qdd.
        B: mass matrix; C: Coriolis/centrifugal matrix (Christoffel); G: gravity torque per unit g.
    """

    q: list[sp.Symbol]
    qd: list[sp.Symbol]
    qdd: list[sp.Symbol]
    T: sp.Expr
    V: sp.Expr
    B: sp.Matrix
    C: sp.Matrix
    G: sp.Matrix

    @property
    def el(self) -> sp.Matrix:
        """Euler-Lagrange equations d/dt(dT/dqd_i) - dT/dq_i + dV/dq_i (unit g), taken from the energies."""
        import sympy as sp

        n = len(self.q)
        out = []
        for i in range(n):
            p = sp.diff(self.T, self.qd[i])
            dpdt = sum(sp.diff(p, self.q[k]) * self.qd[k] + sp.diff(p, self.qd[k]) * self.qdd[k] for k in range(n))
            out.append(dpdt - sp.diff(self.T, self.q[i]) + sp.diff(self.V, self.q[i]))
        return sp.Matrix(out)


def derive(chain: Chain) -> Derivation:
    """Kinetic and potential energy of ``chain`` and its B(q), C(q, qd), G(q).

    B is collected from the kinetic energy T = sum_i (m_i v_ci^2 + w_i^T I_i w_i) / 2 as its
    Hessian in qd, C from B's Christoffel symbols, G = dV/dq with V = sum_i m_i z_ci (unit g);
    each entry reduced modulo sin^2 + cos^2 = 1 (:class:`_TrigReduction`), nothing else.
    """
    import sympy as sp

    global derivations
    derivations += 1
    n = chain.n
    q = list(sp.symbols(f"q1:{n + 1}", real=True))
    qd = list(sp.symbols(f"qd1:{n + 1}", real=True))
    qdd = list(sp.symbols(f"qdd1:{n + 1}", real=True))
    T_w = sp.Matrix([[_num(v) for v in row] for row in chain.base])
    T = sp.Integer(0)
    V = sp.Integer(0)
    omega = sp.zeros(3, 1)  # angular velocity of the current link in W
    for i, link in enumerate(chain.links):
        T_w = T_w * _dh(_angle(link.alpha), _num(link.a), _num(link.d), q[i] + _angle(link.offset))
        R, p = T_w[:3, :3], T_w[:3, 3]
        omega = omega + R[:, 2] * qd[i]
        c = sp.Matrix([_num(v) for v in link.com])
        p_c = p + R * c
        v_c = p_c.jacobian(q[: i + 1]) * sp.Matrix(qd[: i + 1])
        w_local = R.T * omega
        inertia = sp.Matrix([[_num(v) for v in row] for row in link.inertia])
        m = _num(link.mass)
        T += (m * (v_c.T * v_c)[0, 0] + (w_local.T * inertia * w_local)[0, 0]) / 2
        V += m * p_c[2]
    reduce = _TrigReduction(q)
    B = sp.hessian(T, qd).applyfunc(reduce)
    dB = [B.diff(qk) for qk in q]  # dB[k][i, j] = dB_ij / dq_k
    C = sp.zeros(n, n)
    for i in range(n):
        for j in range(n):
            C[i, j] = reduce(sum((dB[k][i, j] + dB[j][i, k] - dB[i][j, k]) * qd[k] for k in range(n)) / 2)
    G = sp.Matrix([reduce(sp.diff(V, qi)) for qi in q])
    return Derivation(q=q, qd=qd, qdd=qdd, T=T, V=V, B=B, C=C, G=G)


class _TrigReduction:
    """The one simplification: an expression in sin q_i, cos q_i as a polynomial reduced modulo sin^2 + cos^2 = 1.

    Angle sums are expanded, sin q_i and cos q_i become polynomial variables s_i, c_i, and the
    expanded polynomial is reduced by the ideal (s_i^2 + c_i^2 - 1) (a lex Groebner basis: every
    s_i^2 becomes 1 - c_i^2). Exact, cheap (a fraction of a second for the leg) and it shrinks the
    leg's forward dynamics from ~360 to ~150 operations.
    """

    def __init__(self, q: Sequence[sp.Symbol]) -> None:
        import sympy as sp

        n = len(q)
        self.s = sp.symbols(f"_s1:{n + 1}", real=True)
        self.c = sp.symbols(f"_c1:{n + 1}", real=True)
        self.to_poly = {**{sp.sin(qi): si for qi, si in zip(q, self.s, strict=True)},
                        **{sp.cos(qi): ci for qi, ci in zip(q, self.c, strict=True)}}  # fmt: skip
        self.back = {v: k for k, v in self.to_poly.items()}
        self.ideal = [si**2 + ci**2 - 1 for si, ci in zip(self.s, self.c, strict=True)]

    def __call__(self, e: sp.Expr) -> sp.Expr:
        import sympy as sp

        e = sp.expand(sp.expand_trig(e).xreplace(self.to_poly))
        if e == 0:
            return sp.Integer(0)
        _, r = sp.reduced(e, self.ideal, *self.s, *self.c, order="lex")
        return r.xreplace(self.back)  # type: ignore[no-any-return]


# --------------------------------------------------------------------------- #
# Code generation


def _printer() -> Any:
    """A Python code printer: plain ``sin``/``cos`` names, floats with all 17 significant digits, and squares
    as products: CPython computes ``x**2`` with the C library's pow, numba as ``x*x``, and the two differ in
    the last bit for some x (45 of 50,000 uniform draws on [-3, 3]), so the compiled period and the Python
    one drifted apart; ``(x*x)`` is the same operation in both."""
    from sympy.printing.precedence import precedence
    from sympy.printing.pycode import PythonCodePrinter

    class Printer(PythonCodePrinter):  # type: ignore[misc]
        def _print_Float(self, expr: Any) -> str:
            return repr(float(expr))

        def _print_Pow(self, expr: Any, rational: bool = False) -> str:
            if expr.exp == 2:
                base = self.parenthesize(expr.base, precedence(expr))
                return f"({base}*{base})"
            return str(super()._print_Pow(expr, rational=rational))

    return Printer({"fully_qualified_modules": False, "standard": "python3"})


def _block(printer: Any, exprs: Sequence[sp.Expr], fast: bool = False) -> tuple[list[str], list[str]]:
    """Code lines computing ``exprs`` through common subexpressions, and the final expressions' text.

    ``fast``: also sympy's basic cse optimizations (half the operations, five times the generation time;
    used for the forward dynamics, which runs at every integrator stage).
    """
    import sympy as sp

    subs, reduced = sp.cse(list(exprs), symbols=sp.numbered_symbols("x"), optimizations="basic" if fast else None)
    indent = "    "
    lines = [f"{indent}{printer.doprint(s)} = {printer.doprint(e)}" for s, e in subs]
    return lines, [printer.doprint(e) for e in reduced]


def _solve_lines(n: int, indent: str = "    ") -> list[str]:
    """Unrolled Cholesky solve of B qdd = r for the symmetric positive-definite B (names b{i}{j}, r{i})."""
    out = []
    for j in range(n):
        s = " - ".join([f"b{j}{j}"] + [f"l{j}{k} * l{j}{k}" for k in range(j)])
        out.append(f"{indent}l{j}{j} = sqrt({s})")
        for i in range(j + 1, n):
            s = " - ".join([f"b{i}{j}"] + [f"l{i}{k} * l{j}{k}" for k in range(j)])
            out.append(f"{indent}l{i}{j} = ({s}) / l{j}{j}")
    for i in range(n):
        s = " - ".join([f"r{i}"] + [f"l{i}{k} * y{k}" for k in range(i)])
        out.append(f"{indent}y{i} = ({s}) / l{i}{i}")
    for i in reversed(range(n)):
        s = " - ".join([f"y{i}"] + [f"l{k}{i} * a{k}" for k in range(i + 1, n)])
        out.append(f"{indent}a{i} = ({s}) / l{i}{i}")
    return out


def _links_literal(chain: Chain) -> tuple[Any, ...]:
    """The chain's inertials as nested tuples of floats (what the generated code was derived from)."""
    return tuple(
        (float(ln.mass), tuple(float(v) for v in ln.com), tuple(tuple(float(v) for v in row) for row in ln.inertia))
        for ln in chain.links
    )


def generate(chain: Chain, d: Derivation | None = None) -> str:
    """Python source of the chain's equations of motion (floats in, tuples of floats out).

    The module defines, for n joints with arguments q1..qn [rad], qd1..qdn [rad/s]:
    ``mass_matrix(q...)`` (B row-major, n*n), ``coriolis(q..., qd...)`` (C row-major, n*n),
    ``bias(q..., qd...)`` (C qd, n), ``gravity(q...)`` (G for g = 1 m/s^2, n) and
    ``qdd(q..., qd..., tau..., g)`` [rad/s^2], the forward dynamics
    B^-1 (tau - C qd - g G) by an unrolled Cholesky solve.
    """
    import sympy as sp

    d = d or derive(chain)
    n = chain.n
    pr = _printer()
    qs = ", ".join(f"q{i + 1}" for i in range(n))
    qds = ", ".join(f"qd{i + 1}" for i in range(n))
    taus = ", ".join(f"tau{i + 1}" for i in range(n))
    h = d.C * sp.Matrix(d.qd)
    src = [
        f'"""Equations of motion generated by legbench.backends.lagrange_eom (version {GENERATOR_VERSION}).',
        "",
        f"Chain key {chain.key()}. Do not edit: regenerated when the chain changes.",
        '"""',
        "",
        "from math import cos, pi, sin, sqrt  # pi: in case an angle's exact multiple of pi/2 survives",
        "",
        f"N = {n}",
        f"KEY = {chain.key()!r}",
        "#: Per link: (mass [kg], COM in the link frame [m], inertia about the COM in the link frame [kg m^2]).",
        f"LINKS = {_links_literal(chain)!r}",
        "",
    ]

    def fn(sig: str, doc: str, exprs: Sequence[sp.Expr]) -> None:
        lines, outs = _block(pr, exprs)
        src.extend([f"def {sig}:", f'    """{doc}"""', *lines, f"    return ({', '.join(outs)},)", "", ""])

    fn(f"mass_matrix({qs})", "B(q), row-major [kg m^2].", list(d.B))
    fn(f"coriolis({qs}, {qds})", "C(q, qd), row-major [kg m^2 / s].", list(d.C))
    fn(f"bias({qs}, {qds})", "C(q, qd) qd [N m].", list(h))
    fn(f"gravity({qs})", "G(q) for gravity 1 m/s^2 along -z_W [N m / (m/s^2)].", list(d.G))
    # forward dynamics: upper triangle of B, C qd and G in one cse block, then the solve
    upper = [d.B[i, j] for i in range(n) for j in range(i, n)]
    lines, outs = _block(pr, upper + list(h) + list(d.G), fast=True)
    names = [f"b{i}{j}" for i in range(n) for j in range(i, n)] + [f"h{i}" for i in range(n)]
    names += [f"g{i}" for i in range(n)]
    src += [f"def qdd({qs}, {qds}, {taus}, g):", '    """Forward dynamics qdd [rad/s^2] under gravity g [m/s^2]."""']
    src += lines
    src += [f"    {nm} = {o}" for nm, o in zip(names, outs, strict=True)]
    src += [f"    b{j}{i} = b{i}{j}" for i in range(n) for j in range(i + 1, n)]
    src += [f"    r{i} = tau{i + 1} - h{i} - g * g{i}" for i in range(n)]
    src += _solve_lines(n)
    src += [f"    return ({', '.join(f'a{i}' for i in range(n))},)", ""]
    return "\n".join(src)


# --------------------------------------------------------------------------- #
# Cache


def default_cache_dir() -> Path:
    """``lagrange`` in legbench's cache directory (:func:`legbench.resources.cache_dir`: ``$LEGBENCH_CACHE_DIR``,
    else ``$XDG_CACHE_HOME/legbench``, else ``~/.cache/legbench``); not created here."""
    return resources.cache_dir() / "lagrange"


@dataclass(frozen=True)
class Loaded:
    """Generated equations of motion and how they were obtained.

    Attributes:
        module: the generated module (``mass_matrix``, ``coriolis``, ``bias``, ``gravity``, ``qdd``).
        path: the cached source file.
        derived: True if this call derived the chain (cold), False if it loaded the cache.
        seconds: wall time of this call [s] (derivation + generation + import, or import only).
    """

    module: ModuleType
    path: Path
    derived: bool
    seconds: float


def _import(path: Path, key: str) -> ModuleType:
    name = f"legbench_lagrange_eom_{key[:16]}"
    spec = importlib.util.spec_from_file_location(name, path)
    if spec is None or spec.loader is None:  # pragma: no cover - a .py path always has a loader
        raise ImportError(f"cannot import {path}")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    if getattr(module, "KEY", None) != key:
        raise ImportError(f"{path}: key mismatch")
    sys.modules.setdefault(name, module)
    return module


def load_eom(chain: Chain, cache_dir: Path | str | None = None) -> Loaded:
    """The chain's generated equations of motion: from the cache, or derived, written and loaded.

    The file is ``<cache_dir>/eom_<sha256>.py``; it is written atomically (a parallel
    derivation of the same chain writes the same text). A cached file that does not
    import or carries another key is derived again.
    """
    t0 = time.perf_counter()
    key = chain.key()
    directory = Path(cache_dir) if cache_dir is not None else default_cache_dir()
    path = directory / f"eom_{key}.py"
    if path.exists():
        try:
            return Loaded(_import(path, key), path, False, time.perf_counter() - t0)
        except (ImportError, SyntaxError, OSError):  # damaged, or unreadable here (another user's file): derive
            pass
    text = generate(chain)
    if cache_dir is None:  # a cache that cannot be made is one line naming where it came from
        directory = resources.cache_subdir("lagrange")
    directory.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=directory, prefix=".eom_", suffix=".py")
    with os.fdopen(fd, "w") as f:
        f.write(text)
    os.chmod(tmp, 0o644)  # mkstemp makes it 0600: others sharing the cache directory may read it
    os.replace(tmp, path)
    return Loaded(_import(path, key), path, True, time.perf_counter() - t0)


def lambdified(d: Derivation) -> dict[str, Any]:
    """The derivation as numpy functions (tests): B(q), C(q, qd), G(q), el(q, qd, qdd)."""
    import sympy as sp

    return {
        "B": sp.lambdify([d.q], d.B, "numpy", cse=True),
        "C": sp.lambdify([d.q, d.qd], d.C, "numpy", cse=True),
        "G": sp.lambdify([d.q], d.G, "numpy", cse=True),
        "el": sp.lambdify([d.q, d.qd, d.qdd], d.el, "numpy", cse=True),
    }


__all__ = ["Chain", "Derivation", "Link", "Loaded", "derive", "generate", "leg_chain", "load_eom"]
