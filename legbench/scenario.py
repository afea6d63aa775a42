"""Scenario files: one YAML document describes one task (docs/spec.md section 7).

Format (every key but ``name``, ``duration`` and ``events`` has a default)::

    name: effort                      # also the output folder name
    description: push down with 100 N
    duration: 3.0                     # [s]
    control_rate: 1000                # [Hz]
    gains: {Kp: 10, Kd: 1, Ki: 0}     # scalars or one value per joint
    initial: {q: [-0.0025, -1.1899, -1.2599], qd: [0, 0, 0]}
    events:                           # in time order; each has t and one controller
      - t: 0.0
        position: {joint: [0, 0, 0]}          # or {cartesian: [x, y, z]} (foot centre in W)
      - t: 1.0
        trajectory: {waypoints: [[x, y, z], ...], times: [t1, ...]}  # times after the event
      - t: 1.0
        ellipse: {a: 0.15, b: 0.06, DY: 0.11208, DZ: 0.105, dth: 0, T: 5, points: 50,
                  repetitions: 2, approach: 1.0}
      - t: 2.0
        effort: {force: [0, 0, -100]}        # h_d, force the foot exerts, in W [N]
        delay: 0.013                  # optional [s]: the switch happens this much later (ROS)
        force_delay: 0.007            # optional, effort only [s]: h_d = 0 (tau = G(q)) this long after it
    physics:
      gravity: 9.81
      contact_mode: native            # or reference
      contact: {Kp: 1e4, Kd: 100, mu_s: 0.7, mu_k: 0.6, v_th: 1.0e-3, poc: true}
    backends:                         # per-backend settings (see each backend's defaults)
      <name>: {dt: 1.0e-4}            # e.g. the reference backend's step and integrator
    comparison: {reference: pinocchio, skip: 0.0, steady_window: 0.5, tolerances: {}}

Unknown keys are errors. Every error names the file, the key path and the problem.
"""

from __future__ import annotations

import copy
import difflib
import hashlib
import json
import logging
import math
import re
from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from legbench import backends, kinematics, resources
from legbench.backends.base import PROFILES, Physics, Range, dt_problem
from legbench.contact import CONTACT_MODES, ContactParams
from legbench.exceptions import BackendNotFound, LegbenchError, ScenarioError
from legbench.model import SECTIONS as LEG_SECTIONS
from legbench.model import load_params
from legbench.trajectories import ellipse_waypoints
from legbench.yamlfile import (
    LIMITS,
    YamlContext,
    check_keys,
    check_magnitude,
    integer,
    keypath,
    limit,
    number,
    other_file,
    read_yaml,
    set_key,
    vector,
)

logger = logging.getLogger("legbench.scenario")

CONTROLLERS = ("position", "trajectory", "ellipse", "effort", "torque")
#: Keys of each controller's event body: (allowed, required). The validator and :func:`json_schema` use them.
EVENT_BODY_KEYS: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    "position": (("joint", "cartesian"), ()),
    "trajectory": (("waypoints", "times"), ("waypoints", "times")),
    "ellipse": (("a", "b", "DY", "DZ", "dth", "T", "points", "repetitions", "approach"), ("a", "b", "DY", "DZ", "T")),
    "torque": (("amplitude", "frequency", "phase"), ("amplitude", "frequency")),
    "effort": (("force",), ("force",)),
}
#: Keys of the scenario's sections: (allowed, required).
SECTION_KEYS: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    "gains": (("Kp", "Kd", "Ki"), ()),
    "initial": (("q", "qd"), ()),
    "physics": (("gravity", "contact_mode", "contact"), ()),
    "physics.contact": (("Kp", "Kd", "mu_s", "mu_k", "v_th", "poc"), ()),
    "comparison": (("reference", "skip", "steady_window", "tolerances", "published"), ()),
}
#: Scenario names become directory names: no separators, nothing that can climb out.
#: Longest run accepted: 1e7 ticks (2.8 h at 1 kHz) keep the log under ~1.3 GB.
MAX_TICKS = 10_000_000  # the default of limit('ticks'); LEGBENCH_LIMITS=ticks=N raises it
MAX_WAYPOINTS = 100_000
#: The default ``comparison.steady_window`` [s]: the last 0.5 s of a run (the whole of a shorter one).
STEADY_WINDOW = 0.5
NAME_RE = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.-]{0,63}")
#: Names a results tree's root holds beside its run directories, which a scenario's folder would clash with:
#: the tree's index pages, ``legbench check``'s summaries (``results.CHECK_OUTPUTS``) and the plotly assets
#: folder (``report_figures.ASSETS``). They live in modules this one may not import (docs/architecture.md), so
#: they are spelled here; tests/test_scenario.py keeps them equal. Compared case-folded (a case-blind disk).
RESERVED_NAMES = ("report.html", "report.md", "check.md", "check-junit.xml", "assets")
#: Suffixes ``results.out_dir_for`` gives a scenario's folder in another contact mode or profile than its own
#: (``effort__reference``, ``effort__engine-defaults``): a scenario named so would share that folder.
RESERVED_SUFFIXES = ("__reference", *(f"__{p}" for p in PROFILES))
#: Divergence bounds no physical run of this leg reaches: joint speed [rad/s] (20x the hip's speed limit) and
#: foot penetration [m] (5 cm is 500 N at Kp = 1e4 N/m; the leg pushes <= 100 N). The run loop stops a backend
#: beyond them; the loader refuses an initial state beyond them (every run would stop at t = 0).
MAX_JOINT_SPEED = 1.0e3
MAX_PENETRATION = 0.05
#: The metrics a tolerance may be given for (``comparison.tolerances``, a tolerance file): their defaults are
#: :data:`legbench.check.DEFAULT_TOLERANCES`, built from these names.
TOLERANCE_METRICS = ("sim_error_pct", "rms", "steady_mean", "max_sim_error_pct")
#: The keys of a per-component tolerance mapping: ``default``, a signal and a component label (the names of
#: :mod:`legbench.signals`, which :func:`legbench.signals.keyed` looks up; tests/test_scenario.py keeps them equal).
TOLERANCE_KEYS = ("default", "q", "qd", "tau", "force", "q1", "q2", "q3", "qd1", "qd2", "qd3", "tau1", "tau2", "tau3",
                  "fx", "fy", "fz")  # fmt: skip


@dataclass(frozen=True)
class Gains:
    """PID gains per joint (torque per rad, per rad/s, per rad s)."""

    Kp: tuple[float, float, float] = (10.0, 10.0, 10.0)
    Kd: tuple[float, float, float] = (1.0, 1.0, 1.0)
    Ki: tuple[float, float, float] = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class Event:
    """A controller switch at time ``t`` [s].

    Attributes:
        t: activation time [s].
        controller: one of :data:`CONTROLLERS`.
        joint: joint target [rad] (position).
        cartesian: foot-centre target in W [m] (position).
        waypoints: foot-centre waypoints in W [m], shape (n, 3) (trajectory, ellipse).
        times: waypoint times after ``t`` [s] (trajectory, ellipse).
        force: desired force h_d the foot exerts on the environment, in W [N] (effort).
        amplitude, frequency, phase: open-loop joint torques
            tau_i = amplitude_i sin(2 pi frequency_i (t - t_event) + phase_i), in [N m], [Hz], [rad] (torque).
        params: the event's own keys as written (for the report).
        delay: the switch happens at ``t + delay`` [s]; until then the previous controller
            keeps running (the lab report's ROS latency: 13 ms to switch to effort control).
        force_delay: effort only: for this long after the switch [s] the controller sends
            h_d = 0, i.e. tau = G(q) (the report's 7 ms more before the force was sent).
    """

    t: float
    controller: str
    joint: tuple[float, ...] | None = None
    cartesian: tuple[float, ...] | None = None
    waypoints: tuple[tuple[float, ...], ...] = ()
    times: tuple[float, ...] = ()
    force: tuple[float, ...] | None = None
    amplitude: tuple[float, ...] | None = None
    frequency: tuple[float, ...] | None = None
    phase: tuple[float, ...] | None = None
    params: Mapping[str, Any] = field(default_factory=dict, hash=False, compare=False)
    delay: float = 0.0
    force_delay: float = 0.0

    @property
    def t_switch(self) -> float:
        """When the controller actually takes over [s]: ``t + delay``."""
        return self.t + self.delay


#: The reference backend a scenario's comparison uses unless it names another (a setting).
DEFAULT_REFERENCE = "pinocchio"


@dataclass(frozen=True)
class Comparison:
    """How runs of this scenario are compared."""

    reference: str = DEFAULT_REFERENCE
    skip: float = 0.0  # [s] ignored at the start
    steady_window: float = STEADY_WINDOW  # [s] at the end, for steady-state means (or the whole of a shorter run)
    tolerances: Mapping[str, Any] = field(default_factory=dict, hash=False)
    #: Published steady states to show beside the backends' (the lab report's rows): each
    #: ``{source: text, qd_abs: [3 magnitudes, rad/s]}`` and/or ``force: [fx, fy, fz in W, N]``, and an optional
    #: ``note``: a caveat the report prints beside the row.
    published: tuple[Mapping[str, Any], ...] = ()


@dataclass(frozen=True)
class Scenario:
    """A validated scenario."""

    name: str
    description: str
    duration: float  # [s]
    control_rate: float  # [Hz]
    gains: Gains
    q0: tuple[float, float, float]  # [rad]
    qd0: tuple[float, float, float]  # [rad/s]
    events: tuple[Event, ...]
    gravity: float  # [m/s^2]
    contact: ContactParams
    contact_mode: str
    profile: str  # every backend's profile unless its settings name another (backends.<name>.profile)
    backends: Mapping[str, Mapping[str, Any]] = field(hash=False)
    comparison: Comparison
    file: str = "<memory>"
    sha256: str = ""
    raw: Mapping[str, Any] = field(default_factory=dict, hash=False, compare=False)

    @property
    def control_dt(self) -> float:
        """Control period [s]."""
        return 1.0 / self.control_rate

    @property
    def n_ticks(self) -> int:
        """Number of control ticks logged, t = 0 .. duration inclusive."""
        return int(round(self.duration * self.control_rate)) + 1

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary for run.json."""
        return {
            "name": self.name,
            "file": resources.shown(self.file) if self.file != "<memory>" else self.file,
            "sha256": self.sha256,
            "description": self.description,
            "duration": self.duration,
            "control_rate": self.control_rate,
            "contact_mode": self.contact_mode,
            "profile": self.profile,
            "gravity": self.gravity,
            "gains": {"Kp": list(self.gains.Kp), "Kd": list(self.gains.Kd), "Ki": list(self.gains.Ki)},
            "initial": {"q": list(self.q0), "qd": list(self.qd0)},
            "events": [{"t": e.t, "controller": e.controller, **dict(e.params)} for e in self.events],
            "contact": {**self.contact.__dict__},
            "backends": {k: dict(v) for k, v in self.backends.items()},
            "comparison": {
                "reference": self.comparison.reference,
                "skip": self.comparison.skip,
                "steady_window": self.comparison.steady_window,
                "tolerances": dict(self.comparison.tolerances),
                "published": [dict(r) for r in self.comparison.published],
            },
            "raw": dict(self.raw),
        }


# --------------------------------------------------------------------------- #
# Events


def _reachable(ctx: YamlContext, path: list[str | int], p: tuple[float, ...]) -> None:
    res = kinematics.ik(np.array(p))
    if not res:
        raise ctx.error(path, f"W point {list(p)} is unreachable: {res.reason}")


#: Optional event keys: delays [s] of the switch and, on effort events, of the force.
DELAY_KEYS = ("delay", "force_delay")


def _event(ctx: YamlContext, path: list[str | int], d: Any) -> Event:
    """One event, with its delays (:data:`DELAY_KEYS`) checked and attached."""
    check_keys(ctx, path, d, ["t", *CONTROLLERS, *DELAY_KEYS], ["t"])
    ev = _event_body(ctx, path, d)
    delays = {k: number(ctx, [*path, k], d[k], nonneg=True) for k in DELAY_KEYS if k in d}
    if "force_delay" in delays and ev.controller != "effort":
        raise ctx.error([*path, "force_delay"], "only an effort event has a force to delay")
    if not delays:
        return ev
    delay, force_delay = delays.get("delay", 0.0), delays.get("force_delay", 0.0)
    return replace(ev, params={**ev.params, **delays}, delay=delay, force_delay=force_delay)


def _event_body(ctx: YamlContext, path: list[str | int], d: Any) -> Event:
    t = number(ctx, [*path, "t"], d["t"], nonneg=True)
    kinds = [k for k in CONTROLLERS if k in d]
    if len(kinds) != 1:
        raise ctx.error(path, f"an event needs exactly one of {', '.join(CONTROLLERS)}; got {kinds or 'none'}")
    kind = kinds[0]
    body = d[kind]
    bp: list[str | int] = [*path, kind]
    params = {kind: body}
    p = load_params()
    if kind == "position":
        check_keys(ctx, bp, body, *EVENT_BODY_KEYS[kind])
        if ("joint" in body) == ("cartesian" in body):
            raise ctx.error(bp, "give exactly one of 'joint' or 'cartesian'")
        if "joint" in body:
            q = vector(ctx, [*bp, "joint"], body["joint"])
            for i, (qi, lo, hi) in enumerate(zip(q, p.lower, p.upper, strict=True)):
                if not lo <= qi <= hi:
                    raise ctx.error([*bp, "joint", i], f"{qi} rad outside the joint limits [{lo:.4f}, {hi:.4f}]")
            return Event(t, kind, joint=q, params=params)
        c = vector(ctx, [*bp, "cartesian"], body["cartesian"])
        _reachable(ctx, [*bp, "cartesian"], c)
        return Event(t, kind, cartesian=c, params=params)
    if kind == "trajectory":
        check_keys(ctx, bp, body, *EVENT_BODY_KEYS[kind])
        wps, times = body["waypoints"], body["times"]
        if not isinstance(wps, list) or not wps:
            raise ctx.error([*bp, "waypoints"], "expected a non-empty list of [x, y, z] points")
        if not isinstance(times, list) or len(times) != len(wps):
            raise ctx.error([*bp, "times"], f"expected {len(wps)} times, one per waypoint")
        W = tuple(vector(ctx, [*bp, "waypoints", i], w) for i, w in enumerate(wps))
        ts = tuple(number(ctx, [*bp, "times", i], x, positive=True) for i, x in enumerate(times))
        if any(b <= a for a, b in zip(ts, ts[1:], strict=False)):
            raise ctx.error([*bp, "times"], "waypoint times must increase strictly")
        for i, w in enumerate(W):
            _reachable(ctx, [*bp, "waypoints", i], w)
        return Event(t, kind, waypoints=W, times=ts, params=params)
    if kind == "ellipse":
        check_keys(ctx, bp, body, *EVENT_BODY_KEYS[kind])
        a = number(ctx, [*bp, "a"], body["a"], positive=True)
        b = number(ctx, [*bp, "b"], body["b"], positive=True)
        DY = number(ctx, [*bp, "DY"], body["DY"])
        DZ = number(ctx, [*bp, "DZ"], body["DZ"])
        dth = number(ctx, [*bp, "dth"], body.get("dth", 0.0))
        T = number(ctx, [*bp, "T"], body["T"], positive=True)
        n = integer(ctx, [*bp, "points"], body.get("points", 50), minimum=3)
        reps = integer(ctx, [*bp, "repetitions"], body.get("repetitions", 1))
        approach = number(ctx, [*bp, "approach"], body.get("approach", 1.0), positive=True)
        if n * reps > MAX_WAYPOINTS:
            raise ctx.error([*bp, "points"], f"points x repetitions = {n * reps} is more than {MAX_WAYPOINTS}")
        P, tw = ellipse_waypoints(a, b, DY, DZ, dth, T, n, reps, approach)
        for i, point in enumerate(P[:n]):
            if not kinematics.ik(point):
                raise ctx.error(bp, f"ellipse point {i} at W {np.round(point, 4).tolist()} is unreachable")
        return Event(t, "trajectory", waypoints=tuple(map(tuple, P)), times=tuple(tw.tolist()), params=params)
    if kind == "torque":
        check_keys(ctx, bp, body, *EVENT_BODY_KEYS[kind])
        amp = vector(ctx, [*bp, "amplitude"], body["amplitude"])
        freq = vector(ctx, [*bp, "frequency"], body["frequency"])
        for i, f in enumerate(freq):
            number(ctx, [*bp, "frequency", i], f, nonneg=True)
        phase = vector(ctx, [*bp, "phase"], body.get("phase", [0.0, 0.0, 0.0]))
        return Event(t, kind, amplitude=amp, frequency=freq, phase=phase, params=params)
    check_keys(ctx, bp, body, *EVENT_BODY_KEYS[kind])
    return Event(t, kind, force=vector(ctx, [*bp, "force"], body["force"]), params=params)


# --------------------------------------------------------------------------- #
# Loading

TOP_KEYS = ["name", "description", "duration", "control_rate", "gains", "initial", "events", "physics",
            "profile", "backends", "comparison"]  # fmt: skip


def is_tolerance_file(doc: Any) -> bool:
    """Whether ``doc`` (parsed YAML) is a tolerance file (``legbench check --tolerances``) rather than a scenario:
    no scenario key (:data:`TOP_KEYS`), and a key of a tolerance file (a metric of :data:`TOLERANCE_METRICS` or
    ``scenarios``), a key one letter or two from one (``sim_error_pc``), or a section of ``abs``/``rel``. The one
    rule for ``legbench validate`` (which then checks the file as tolerances, each problem with its line) and for
    a tolerance file given where a scenario goes (``run``: it was "unknown key" per key, then "missing required
    key 'name'", whenever one key was misspelt)."""
    if not isinstance(doc, Mapping) or not doc or set(map(str, doc)) & set(TOP_KEYS):
        return False
    keys = [*TOLERANCE_METRICS, "scenarios"]
    for k, v in doc.items():
        if str(k) in keys or difflib.get_close_matches(str(k), keys, n=1, cutoff=0.8):
            return True
        if isinstance(v, Mapping) and v and set(v) <= {"abs", "rel"}:
            return True
    return False


def is_leg_parameter_file(doc: Any) -> bool:
    """Whether ``doc`` (parsed YAML) is a leg parameter file (``--model``, ``LEGBENCH_MODEL``) rather than a scenario:
    a section of one (:data:`legbench.model.SECTIONS`) and no scenario key (:data:`TOP_KEYS`). The one rule for
    ``legbench validate`` (which then checks it as ``--model`` reads it) and for such a file given where a scenario
    goes (``run``)."""
    if not isinstance(doc, Mapping):
        return False
    keys = set(map(str, doc))
    return bool(keys & set(LEG_SECTIONS)) and not keys & set(TOP_KEYS)


def parse(
    doc: Any,
    file: str = "<memory>",
    root: yaml.Node | None = None,
    overridden: Sequence[str] = (),
    placeholders: Collection[str] = (),
    every_engine: bool = False,
    origin: str = "--set",
    cut: bool = False,
    engines: Collection[str] = (),
) -> Scenario:
    """Validate a scenario document (already parsed YAML) into a :class:`Scenario`; ``overridden``: the dotted
    keys ``--set`` replaced (their errors name the override, not the file's line: ``(from ORIGIN KEY)``,
    ``origin`` what set them in the caller's words, the Python API's ``overrides``); ``placeholders``: top-level
    keys (``duration``, ``control_rate``) whose values stand in for invalid ones (:func:`errors` looks past
    them so): the checks that compare other values with them are skipped. ``every_engine`` (``legbench
    validate``): also check that the control period suits the default (or profile) sub-step of every
    installed engine the scenario gives no ``dt`` (this imports them all); ``engines``: only these, the
    engines a run will load (``legbench run``: the misfit blamed on ``control_rate``, not on a ``dt`` the file
    never set). ``cut``: the document is a scenario cut short (:func:`shorten`), the start of the whole run, so
    a delayed force may start after it (a trajectory or an ellipse may outlast any run)."""
    ctx = YamlContext(file, root, overridden, origin)
    exact_d, exact_r = "duration" not in placeholders, "control_rate" not in placeholders
    if isinstance(doc, Mapping) and "events" not in doc:  # another of legbench's files, given where a scenario goes
        other = other_file(doc, "a scenario")
        if other is not None:
            raise ctx.error([], other)
        if is_tolerance_file(doc):
            raise ctx.error([], "is a tolerance file, not a scenario: give it to legbench check --tolerances")
        if is_leg_parameter_file(doc):
            raise ctx.error([], "is a leg parameter file, not a scenario: give it to legbench --model (or "
                                "LEGBENCH_MODEL)")  # fmt: skip
    check_keys(ctx, [], doc, TOP_KEYS, ["name", "duration", "events"])
    name = doc["name"]
    if isinstance(name, int | float) and not isinstance(name, bool):  # YAML read it as a number
        raise ctx.error(["name"], f"a name is text: quote it ('{name}'), or YAML reads it as the number {name!r}")
    if not isinstance(name, str) or not NAME_RE.fullmatch(name) or set(name) == {"."}:
        raise ctx.error(["name"], f"expected a plain name (letters, digits, - _ ., at most 64), got {name!r}")
    why = name_problem(name)
    if why is not None:
        raise ctx.error(["name"], why)
    description = doc.get("description", "")
    if not isinstance(description, str):
        raise ctx.error(["description"], "expected text")
    duration = number(ctx, ["duration"], doc["duration"], positive=True)
    rate = number(ctx, ["control_rate"], doc.get("control_rate", 1000.0), positive=True)
    # a problem of the two together is the duration's, unless only the rate was overridden (then the file's
    # duration line did not change and the override is what to blame)
    pair: list[str | int] = (
        ["control_rate"] if "control_rate" in ctx.overridden and "duration" not in ctx.overridden else ["duration"]
    )
    if exact_d and exact_r and duration * rate > limit("ticks"):
        raise ctx.error(pair, f"{duration} s at {rate} Hz is more than {limit('ticks'):.0e} control ticks "
                              "(limit ticks: LEGBENCH_LIMITS=ticks=N raises it)")  # fmt: skip
    if exact_d and exact_r and abs(duration * rate - round(duration * rate)) > 1e-6:
        raise ctx.error(pair, f"{duration} s is not a whole number of control periods at {rate} Hz")

    gains_d = doc.get("gains", {})
    check_keys(ctx, ["gains"], gains_d, *SECTION_KEYS["gains"])
    gdef = Gains()
    gains = Gains(
        *(  # type: ignore[arg-type]
            vector(ctx, ["gains", k], gains_d[k]) if k in gains_d else getattr(gdef, k) for k in ("Kp", "Kd", "Ki")
        )
    )
    for k in ("Kp", "Kd", "Ki"):
        for i, g in enumerate(getattr(gains, k)):
            if g < 0:
                raise ctx.error(["gains", k, i] if isinstance(gains_d.get(k), list) else ["gains", k],
                                f"a negative gain ({g}) destabilises the controller; must be >= 0")  # fmt: skip
    init = doc.get("initial", {})
    check_keys(ctx, ["initial"], init, *SECTION_KEYS["initial"])
    q0 = vector(ctx, ["initial", "q"], init.get("q", [0.0, 0.0, 0.0]))
    qd0 = vector(ctx, ["initial", "qd"], init.get("qd", [0.0, 0.0, 0.0]))
    p = load_params()
    for i, (qi, lo, hi) in enumerate(zip(q0, p.lower, p.upper, strict=True)):
        if not lo <= qi <= hi:
            raise ctx.error(["initial", "q", i] if isinstance(init.get("q"), list) else ["initial", "q"],
                            f"{qi} rad outside the joint limits [{lo:.4f}, {hi:.4f}]")  # fmt: skip
    depth = p.geometry.R_foot - float(kinematics.fk(np.array(q0))[2])  # of the foot sphere's lowest point [m]
    if depth > MAX_PENETRATION:
        raise ctx.error(["initial", "q"], f"puts the foot {depth:.4g} m into the ground, deeper than "
                        f"{MAX_PENETRATION:g} m, where the run loop stops a backend as diverged: every run would "
                        "end at t = 0")  # fmt: skip
    for i, v in enumerate(qd0):
        if abs(v) > MAX_JOINT_SPEED:
            raise ctx.error(["initial", "qd", i] if isinstance(init.get("qd"), list) else ["initial", "qd"],
                            f"{v:g} rad/s is faster than {MAX_JOINT_SPEED:g} rad/s, where the run loop stops a "
                            "backend as diverged: every run would end at t = 0")  # fmt: skip

    evs = doc["events"]
    if not isinstance(evs, list) or not evs:
        raise ctx.error(["events"], "expected a non-empty list of events")
    events = tuple(_event(ctx, ["events", i], e) for i, e in enumerate(evs))
    for i, (a, b) in enumerate(zip(events, events[1:], strict=False)):
        if b.t < a.t:
            raise ctx.error(["events", i + 1, "t"], f"events out of order: {b.t} s comes after {a.t} s")
        if b.t == a.t:
            raise ctx.error(["events", i + 1, "t"], f"two events at the same instant ({b.t} s): the first would "
                                                    "never act")  # fmt: skip
    if events[0].t != 0.0:
        raise ctx.error(["events", 0, "t"], "the first event must start at t = 0 (something must control the leg)")
    if events[0].delay != 0.0:
        raise ctx.error(["events", 0, "delay"], "the first event cannot be delayed (nothing would control the leg)")
    for i, e in enumerate(events):
        for key, value in (("t", e.t), ("delay", e.delay), ("force_delay", e.force_delay)):
            if exact_r and abs(value * rate - round(value * rate)) > 1e-6:  # the tolerance of the duration's check
                raise ctx.error(["events", i, key], f"{value:g} s is not a whole number of control periods at "
                                                    f"{rate:g} Hz: a controller switches only on a tick")  # fmt: skip
        if exact_d and e.t >= duration:
            raise ctx.error(["events", i, "t"], f"event at {e.t} s is past the end ({duration} s)")
        if exact_d and e.t_switch >= duration:
            raise ctx.error(["events", i, "delay"], f"the switch at {e.t_switch:g} s is past the end ({duration} s)")
        if exact_d and not cut:
            _check_ends_in_run(ctx, i, e, events[i + 1].t_switch if i + 1 < len(events) else None, duration)
        for j, f in enumerate(e.frequency or ()):  # a torque event's sine, held over each control period
            if exact_r and f >= rate / 2:
                raise ctx.error(["events", i, "torque", "frequency", j],
                                f"{f:g} Hz is not below half the control rate ({rate / 2:g} Hz): the torque is "
                                f"sampled once per tick, so it would alias (at {rate:g} Hz every sample is "
                                "sin(phase))")  # fmt: skip
    for i, (a, b) in enumerate(zip(events, events[1:], strict=False)):
        if b.t_switch < a.t_switch:
            raise ctx.error(["events", i + 1, "t"], f"with its delay this event switches at {b.t_switch:g} s, before "
                                                    f"the previous one ({a.t_switch:g} s)")  # fmt: skip

    for i, e in enumerate(events):
        if e.controller == "trajectory":
            _check_speed(ctx, ["events", i, next(iter(e.params), "trajectory")], e, q0 if e.t == 0.0 else None)

    phys = doc.get("physics", {})
    check_keys(ctx, ["physics"], phys, *SECTION_KEYS["physics"])
    gravity = number(ctx, ["physics", "gravity"], phys.get("gravity", p.gravity), nonneg=True)
    mode = phys.get("contact_mode", "native")
    if mode not in CONTACT_MODES:
        raise ctx.error(["physics", "contact_mode"], f"expected one of {', '.join(CONTACT_MODES)}, got {mode!r}")
    cdoc = phys.get("contact", {})
    ckeys = SECTION_KEYS["physics.contact"][0]
    check_keys(ctx, ["physics", "contact"], cdoc, *SECTION_KEYS["physics.contact"])
    leg_c = p.contact
    vals: dict[str, Any] = {}
    for k in ckeys[:-1]:
        default = getattr(leg_c, k)
        vals[k] = number(ctx, ["physics", "contact", k], cdoc.get(k, default), nonneg=True)
    for k in ("Kp", "v_th"):
        if vals[k] <= 0:
            raise ctx.error(["physics", "contact", k], "must be > 0")
    if vals["mu_k"] > vals["mu_s"]:
        raise ctx.error(["physics", "contact", "mu_k" if "mu_k" in cdoc else "mu_s"],
                        f"kinetic friction mu_k = {vals['mu_k']} above static mu_s = {vals['mu_s']}")  # fmt: skip
    poc = cdoc.get("poc", True)
    if poc not in (True, False, "true", "centre"):
        raise ctx.error(["physics", "contact", "poc"], f"expected true (true poc) or 'centre', got {poc!r}")
    vals["poc"] = "true" if poc in (True, "true") else "centre"
    contact = ContactParams(**vals)

    profile = doc.get("profile", PROFILES[0])
    if profile not in PROFILES:
        raise ctx.error(["profile"], f"expected one of {', '.join(PROFILES)} (an engine's own profile goes under "
                                     f"backends.<name>.profile), got {profile!r}")  # fmt: skip
    bdoc = doc.get("backends", {})
    if not isinstance(bdoc, Mapping):
        raise ctx.error(["backends"], "expected a mapping of backend name -> settings")
    backends: dict[str, dict[str, Any]] = {}
    for bname, bset in bdoc.items():
        backends[bname] = _backend_settings(ctx, str(bname), {} if bset is None else bset)  # `name:` alone
        for key, divides in _sub_step_keys(str(bname)) if exact_r else ():
            why = _sub_step_problem(backends[bname].get(key), 1.0 / rate, divides)
            if why is not None:
                raise ctx.error(["backends", bname, key], why)
        _check_combination(ctx, str(bname), backends[bname], profile, mode)
    if exact_r and (every_engine or engines):
        _check_default_sub_steps(ctx, backends, profile, 1.0 / rate, None if every_engine else engines)

    cmp_d = doc.get("comparison", {})
    # default: the last 0.5 s, or the whole of a shorter run (a window given longer than the run is refused)
    window = min(STEADY_WINDOW, duration) if exact_d else STEADY_WINDOW
    check_keys(ctx, ["comparison"], cmp_d, *SECTION_KEYS["comparison"])
    comparison = Comparison(
        reference=str(cmp_d.get("reference", DEFAULT_REFERENCE)),
        skip=number(ctx, ["comparison", "skip"], cmp_d.get("skip", 0.0), nonneg=True),
        steady_window=number(ctx, ["comparison", "steady_window"], cmp_d.get("steady_window", window), positive=True),
        tolerances={} if cmp_d.get("tolerances") is None else cmp_d["tolerances"],  # [] is no mapping: refused
        published=_published(ctx, cmp_d.get("published", [])),
    )
    if not _known_backend(comparison.reference):
        raise ctx.error(["comparison", "reference"], f"unknown backend {comparison.reference!r}; known: "
                        f"{_known_names()}")  # fmt: skip
    if not isinstance(comparison.tolerances, Mapping):
        raise ctx.error(["comparison", "tolerances"], "expected a mapping of metric -> tolerance")
    validate_tolerances(comparison.tolerances, file, "comparison.tolerances", ctx)
    if exact_d and comparison.skip >= duration:
        raise ctx.error(["comparison", "skip"], f"skips the whole run ({duration} s)")
    if exact_d and exact_r and _skips_too_much(comparison.skip, duration, rate):
        raise ctx.error(["comparison", "skip"], f"leaves fewer than two control ticks of the {duration} s run to "
                                                "compare")  # fmt: skip
    if exact_r and "steady_window" in cmp_d and comparison.steady_window < 1.0 / rate - 1e-9:
        raise ctx.error(["comparison", "steady_window"], f"{comparison.steady_window:g} s is shorter than one control "
                        f"period ({1.0 / rate:g} s): the window would hold one tick, no mean")  # fmt: skip
    if exact_d and comparison.steady_window > duration:
        raise ctx.error(["comparison", "steady_window"],
                        f"longer than the run ({duration} s): give a shorter one (--set comparison.steady_window=...)"
                        )  # fmt: skip
    return Scenario(
        name=name,
        description=description,
        duration=duration,
        control_rate=rate,
        gains=gains,
        q0=q0,  # type: ignore[arg-type]
        qd0=qd0,  # type: ignore[arg-type]
        events=events,
        gravity=gravity,
        contact=contact,
        contact_mode=mode,
        profile=profile,
        backends=backends,
        comparison=comparison,
        file=file,
        sha256=hashlib.sha256(json.dumps(doc, sort_keys=True, default=str).encode()).hexdigest(),
        raw=doc,
    )


def _check_ends_in_run(ctx: YamlContext, i: int, e: Event, t_next: float | None, duration: float) -> None:
    """Refuse event ``i`` whose delayed force would never be applied in the run (``duration`` [s]; ``t_next`` [s]:
    the next event's switch, or None), as a switch past the end is: an effort event's force starts
    ``force_delay`` after its switch, which must come before the end and before the next event's switch. A
    trajectory (an ellipse) may outlast the run: a run cut short measures its start (a sweep's ``set:
    {duration: 0.1}``)."""
    if e.force_delay > 0.0:
        t_force = e.t_switch + e.force_delay
        if t_force >= duration:
            raise ctx.error(["events", i, "force_delay"], f"the force would start at {t_force:g} s, past the end "
                                                          f"({duration:g} s): it would never be applied")  # fmt: skip
        if t_next is not None and t_force >= t_next:
            raise ctx.error(["events", i, "force_delay"], f"the force would start at {t_force:g} s, not before the "
                                                          f"next event switches ({t_next:g} s): it would never be "
                                                          "applied")  # fmt: skip


def name_problem(name: str) -> str | None:
    """Why the plain ``name`` (:data:`NAME_RE`) cannot name a scenario's folder in a results tree: it is one of
    legbench's own entries there (:data:`RESERVED_NAMES`) or ends in a suffix legbench gives a folder
    (:data:`RESERVED_SUFFIXES`); None otherwise."""
    folded = name.casefold()
    if folded in RESERVED_NAMES:
        return f"{name!r} is reserved: a results tree holds legbench's own {folded} there; choose another name"
    suffix = next((s for s in RESERVED_SUFFIXES if folded.endswith(s)), None)
    if suffix is not None:
        return (f"{name!r} ends in {suffix!r}, the suffix legbench gives a scenario's folder in another contact mode "
                "or profile; choose another name")  # fmt: skip
    return None


def _check_speed(ctx: YamlContext, path: list[str | int], ev: Event, q_start: tuple[float, ...] | None) -> None:
    """Reject a trajectory whose mean joint speed on a segment exceeds the joint speed limit.

    The joint path is the IK chain the controller will follow (each solution
    nearest the previous). The first segment starts from the measured state,
    known here only for an event at t = 0 (the initial state).
    """
    p = load_params()
    prev = np.array(q_start if q_start is not None else kinematics.ik(np.array(ev.waypoints[0])).solutions[0])
    Q = [prev]
    for w in ev.waypoints:
        prev = kinematics.ik_nearest(np.array(w), prev)
        Q.append(prev)
    times = np.array([0.0, *ev.times])
    first = 0 if q_start is not None else 1
    speed = np.abs(np.diff(np.array(Q), axis=0)) / np.diff(times)[:, None]
    for j in range(first, len(speed)):
        over = speed[j] > p.velocity
        if over.any():
            k = int(np.argmax(over))
            raise ctx.error(
                [*path, "times"] if path[-1] == "trajectory" else path,
                f"segment {j} (to waypoint {j}) needs {speed[j, k]:.1f} rad/s on joint {k + 1}, "
                f"above its {p.velocity[k]:.2f} rad/s limit",
            )


def _published(ctx: YamlContext, rows: Any) -> tuple[dict[str, Any], ...]:
    """``comparison.published``: a list of ``{source, qd_abs?, force?, tau_switch?, first_contact?, note?}`` rows,
    each vector of 3 numbers (``tau_switch`` [N m]: the torque at the switch to effort control), ``first_contact``
    a time [s], ``note`` a caveat the report prints beside the row (e.g. the source's own doubt about it)."""
    path: list[str | int] = ["comparison", "published"]
    if not isinstance(rows, list):
        raise ctx.error(path, "expected a list of {source, qd_abs, force} rows")
    out = []
    for i, row in enumerate(rows):
        check_keys(
            ctx, [*path, i], row, ["source", "qd_abs", "force", "tau_switch", "first_contact", "note"], ["source"]
        )
        if not isinstance(row["source"], str):
            raise ctx.error([*path, i, "source"], "expected text naming the source")
        item: dict[str, Any] = {"source": row["source"]}
        if "note" in row:
            if not isinstance(row["note"], str) or not row["note"].strip():
                raise ctx.error([*path, i, "note"], "expected text: the caveat shown beside the row")
            item["note"] = row["note"]
        if "first_contact" in row:
            item["first_contact"] = number(ctx, [*path, i, "first_contact"], row["first_contact"], positive=True)
        for key in ("qd_abs", "force", "tau_switch"):
            if key in row:
                vec = row[key]
                if not isinstance(vec, list) or len(vec) != 3:
                    raise ctx.error([*path, i, key], "expected 3 numbers")
                item[key] = [number(ctx, [*path, i, key, j], v) for j, v in enumerate(vec)]
        out.append(item)
    return tuple(out)


def validate_tolerances(
    tol: Any, file: str, prefix: str | Sequence[str | int] = "", ctx: YamlContext | None = None
) -> dict[str, Any]:
    """Tolerances, checked: a scenario's ``comparison.tolerances``, a tolerance file or one of its sections
    (:func:`legbench.check.load_tolerances`); the one set of rules for all of them.

    A mapping of :data:`TOLERANCE_METRICS`: ``max_sim_error_pct`` to ``{label or signal: ceiling}``, each other
    metric to ``{abs: x, rel: x}``, each ``x`` a number or a mapping of label, signal or ``default``
    (:data:`TOLERANCE_KEYS`) to one; every number finite and >= 0. A key that is no label, signal or
    ``default`` would never be looked up (a typo silently leaving the tolerance as it was), and a key that is
    not text could not be written to run.json: both are refused. Errors name ``prefix`` (dotted text, or the
    keys as a list where one holds a dot: a scenario named ``my.task``) and the key below it, with its line where
    ``ctx`` knows it.

    Raises:
        ScenarioError: the first problem found.
    """
    base: list[str | int] = (list(prefix.split(".")) if prefix else []) if isinstance(prefix, str) else list(prefix)

    def error(path: list[str | int], problem: str) -> ScenarioError:
        return ctx.error([*base, *path], problem) if ctx is not None else ScenarioError(file, keypath([*base, *path]),
                                                                                          problem)  # fmt: skip

    def nonneg(x: Any, path: list[str | int]) -> None:
        if isinstance(x, bool) or not isinstance(x, int | float) or not x >= 0:
            raise error(path, f"must be a number >= 0, not {x!r}")
        try:
            finite = math.isfinite(x)
        except OverflowError:  # an integer beyond a double
            finite = False
        if not finite:  # run.json would hold Infinity, which is not JSON
            raise error(path, f"must be a finite number >= 0, not {x!r}")
        check_magnitude(float(x), lambda why: error(path, why))  # as every other number: no 1e-40, no 1e300

    def component(lab: Any, path: list[str | int]) -> None:
        if lab not in TOLERANCE_KEYS:
            raise error([*path, str(lab)], f"unknown component; valid: {', '.join(TOLERANCE_KEYS)}")

    if not isinstance(tol, Mapping):
        raise error([], "tolerances must be a mapping")
    for k, v in tol.items():
        key: list[str | int] = [str(k)]
        if k not in TOLERANCE_METRICS:
            raise error(key, f"unknown tolerance; valid: {sorted(TOLERANCE_METRICS)}")
        if not isinstance(v, Mapping):
            raise error(key, "must be a mapping")
        if k == "max_sim_error_pct":
            for lab, x in v.items():
                component(lab, key)
                nonneg(x, [*key, str(lab)])
            continue
        for sub, x in v.items():
            if sub not in ("abs", "rel"):
                raise error([*key, str(sub)], "unknown key; valid: ['abs', 'rel']")
            if isinstance(x, Mapping):
                for lab, y in x.items():
                    component(lab, [*key, sub])
                    nonneg(y, [*key, sub, str(lab)])
            else:
                nonneg(x, [*key, sub])
    return dict(tol)


def _sub_step_problem(dt: Any, control_dt: float, divides: bool = True) -> str | None:
    """Why an engine's sub-step ``dt`` [s] does not fit the control period ``control_dt`` [s]: it does not divide
    it (the one rule, :func:`legbench.backends.base.dt_problem`; only where ``divides``: not for a bound on an
    adaptive solve's step, :attr:`Backend.step_bounds`) or more than ``limit("sub_steps")`` times; None if it
    fits, or is not a positive number (an engine without a fixed step, one not installed here)."""
    if isinstance(dt, bool) or not isinstance(dt, int | float) or not dt > 0:
        return None
    ratio = control_dt / dt
    if ratio > limit("sub_steps"):
        return f"{dt:g} s is {ratio:.3g} sub-steps per control tick, more than {limit('sub_steps')} (limit sub_steps)"
    return dt_problem(float(dt), control_dt) if divides else None


def _step_bounds(name: str) -> tuple[str, ...]:
    """The settings of backend ``name`` that bound an adaptive solve's step (:attr:`Backend.step_bounds`); none
    where it is not installed here."""
    try:
        return tuple(backends.get(name).step_bounds)
    except BackendNotFound:
        return ()


def _sub_step_keys(name: str) -> tuple[tuple[str, bool], ...]:
    """(key, must divide the control period) of every setting of backend ``name`` that sets how many steps a
    control period takes: ``dt`` (a fixed sub-step) and its :attr:`Backend.step_bounds`."""
    return (("dt", True), *((k, False) for k in _step_bounds(name) if k != "dt"))


def _check_default_sub_steps(ctx: YamlContext, settings: Mapping[str, Mapping[str, Any]], profile: str,
                             control_dt: float, engines: Collection[str] | None = None) -> None:  # fmt: skip
    """The default (or profile) sub-step of every installed engine the scenario gives no ``dt`` for, and its
    default bound on an adaptive step (:attr:`Backend.step_bounds`, where not given), fit the control period
    (:func:`_sub_step_problem`): else the engine would refuse to load (``legbench run``, ``doctor``, with no
    file named) or take more steps per tick than the limit, so ``control_rate`` is blamed, naming the engines."""
    misfits: list[tuple[str, str]] = []
    for name in dict.fromkeys([*backends.BUILTIN, *settings] if engines is None else engines):
        given = settings.get(name, {})
        try:
            resolved = backends.get(name).resolve_settings({}, str(given.get("profile", profile)))
        except LegbenchError:  # not installed here (BackendNotFound), or a plug-in without this profile
            continue
        for key, divides in _sub_step_keys(name):
            if key in given:
                continue  # checked as the scenario's own
            why = _sub_step_problem(resolved.get(key), control_dt, divides)
            if why is not None:
                misfits.append((name, f"backends.{name}.{key}: {why}"))
                break
    if misfits:
        names = ", ".join(n for n, _ in misfits)
        raise ctx.error(["control_rate"], f"{1.0 / control_dt:g} Hz does not suit the default (or profile) sub-step "
                        f"of {names}: {misfits[0][1]}; set the key named to such a step for each, or choose "
                        "another control_rate")  # fmt: skip


def _mode_problem(name: str, given: Mapping[str, Any], profile: str, mode: str) -> tuple[list[str | int], str] | None:
    """The key path and why, when the settings ``given`` to an installed backend (with the scenario's ``profile``)
    cannot run in contact ``mode`` (the backend's own rule, :meth:`Backend.settings_problem`, as its load asks
    it): the setting where it is given, else ``physics.contact_mode``; None otherwise or when not installed."""
    try:
        cls = backends.get(name)
    except BackendNotFound:
        return None  # not installed here: the run reports it missing
    settings = dict(given)
    resolved = cls.resolve_settings(settings, str(settings.pop("profile", profile)))
    bad = cls.settings_problem(resolved, mode)
    if bad is None:
        return None
    keys, why = bad
    named = [k for k in ((keys,) if isinstance(keys, str) else keys) if k in given]
    return (["backends", name, named[0]] if named else ["physics", "contact_mode"]), why


def _check_combination(ctx: YamlContext, name: str, given: Mapping[str, Any], profile: str, mode: str) -> None:
    """Refuse settings of an installed backend that cannot run in the scenario's contact ``mode``, naming the
    setting (:func:`_mode_problem`)."""
    bad = _mode_problem(name, given, profile, mode)
    if bad is not None:
        raise ctx.error(*bad)


def check_contact_mode(sc: Scenario, names: Sequence[str], mode: str, option: str | None = None) -> None:
    """Refuse, before any work, running ``sc`` on the backends ``names`` in another contact ``mode`` than its own
    where a backend's settings cannot run in it, as the scenario file would be refused with that mode in it
    (``legbench bench``, ``legbench run`` with or without its pre-flight). ``option``: what set the mode, as the
    user wrote it (default ``--contact-mode <mode>``).

    Raises:
        ScenarioError: naming the scenario's file, the setting and why.
    """
    for name in names:
        bad = _mode_problem(name, sc.backends.get(name, {}), sc.profile, mode)
        if bad is not None:
            path, why = bad
            raise ScenarioError(sc.file, keypath(path), f"{why} (with {option or '--contact-mode ' + mode})")


def _known_names() -> str:
    """Every backend name a scenario may use, for messages: the built-ins (installed or not), then the plug-ins
    registered here."""
    return ", ".join(dict.fromkeys([*backends.BUILTIN, *backends.available()]))


def _known_backend(name: str) -> bool:
    """``name`` is a built-in backend (installed or not) or a registered plug-in."""
    if name in backends.BUILTIN:
        return True
    try:
        backends.get(name)
    except BackendNotFound:
        return False
    return True


def _backend_settings(ctx: YamlContext, name: str, given: Any) -> dict[str, Any]:
    path: list[str | int] = ["backends", name]
    if not isinstance(given, Mapping):
        raise ctx.error(path, "expected a mapping of settings")
    try:
        cls = backends.get(name)
    except BackendNotFound:
        if name in backends.BUILTIN:
            return dict(given)  # engine not installed here: keep the settings, the run reports it missing
        raise ctx.error(path, f"unknown backend; known: {_known_names()}") from None
    check_keys(ctx, path, given, [*cls.defaults, "profile"])
    out: dict[str, Any] = {}
    for k, v in given.items():
        if k == "profile":
            if v not in cls.profiles:
                raise ctx.error([*path, k], f"{name} offers the profiles {', '.join(cls.profiles)}, got {v!r}")
            out[k] = v
            continue
        default = cls.defaults[k]
        if k in cls.choices:
            if v not in cls.choices[k]:
                raise ctx.error([*path, k], f"expected one of {', '.join(cls.choices[k])}, got {v!r}")
            out[k] = v
        elif k in cls.ranges:
            out[k] = _ranged(ctx, [*path, k], v, cls.ranges[k])
        elif isinstance(default, bool):
            if not isinstance(v, bool):
                raise ctx.error([*path, k], f"expected true or false, got {v!r}")
            out[k] = v
        elif isinstance(default, int):
            out[k] = integer(ctx, [*path, k], v)
        elif isinstance(default, float):
            out[k] = number(ctx, [*path, k], v, positive=True)
        else:
            out[k] = v
    return out


def _ranged(ctx: YamlContext, path: list[str | int], v: Any, rng: Range) -> float | None:
    """A number setting in the range its backend declares (:attr:`Backend.ranges`), or ``null`` where allowed."""
    if v is None and rng.nullable:
        return None
    x = number(ctx, path, v)
    why = rng.problem(x)
    if why is not None:
        raise ctx.error(path, why + (" (or null: the backend's default for it)" if rng.nullable else ""))
    return x


def load(path: str | Path, overrides: Mapping[str, Any] | None = None, origin: str = "--set",
         engines: Collection[str] = ()) -> Scenario:  # fmt: skip
    """Read and validate a scenario file; ``overrides`` are dotted keys set before validation, their errors
    naming ``origin`` (what set them in the caller's words: ``--set``, the Python API's ``overrides``);
    ``engines``: the backends the caller will load, whose default sub-steps must suit the control period
    (:func:`parse`)."""
    try:
        doc, root = read_yaml(path)
    except ScenarioError as exc:  # a bundled scenario's bare name (the Python API takes those): say where it is
        bundled = resources.scenario(str(path))
        if str(exc).endswith(": no such file") and Path(path).parent == Path() and bundled.is_file():
            where = resources.shown(bundled)
            where = where if Path(where).is_file() else str(bundled)  # a path the user can give from here
            raise ScenarioError(str(path), "", f"no such file; the bundled scenario of that name is {where}: give "
                                               "its path") from None  # fmt: skip
        raise
    apply_overrides(doc, overrides, origin)
    return parse(doc, str(path), root, tuple(overrides or ()), origin=origin, engines=engines)


def apply_overrides(doc: Any, overrides: Mapping[str, Any] | None, origin: str = "--set") -> None:
    """Set the dotted ``overrides`` in the document ``doc`` (their errors naming ``origin``), if it is a mapping:
    a document that is none is refused by :func:`parse`, naming the file, not an override."""
    if isinstance(doc, dict):
        for key, value in (overrides or {}).items():
            set_key(doc, key, value, origin)


def json_schema() -> dict[str, Any]:
    """A JSON Schema (draft 2020-12) of the scenario format, built from the validator's own key tables
    (:data:`TOP_KEYS`, :data:`SECTION_KEYS`, :data:`EVENT_BODY_KEYS`, :data:`CONTROLLERS`, the contact modes,
    the profiles and each installed backend's defaults and choices). It describes the shape (keys, types,
    enumerations, signs); the physical checks (joint limits, reachability, speeds) are ``legbench validate``'s.
    """
    num: dict[str, Any] = {"type": "number"}
    pos: dict[str, Any] = {"type": "number", "exclusiveMinimum": 0}
    nonneg: dict[str, Any] = {"type": "number", "minimum": 0}
    vec3: dict[str, Any] = {"oneOf": [num, {"type": "array", "items": num, "minItems": 3, "maxItems": 3}]}
    vec3_nonneg: dict[str, Any] = {"oneOf": [nonneg, {"type": "array", "items": nonneg, "minItems": 3,
                                                      "maxItems": 3}]}  # fmt: skip
    points = {"type": "array", "minItems": 1, "items": {"type": "array", "items": num, "minItems": 3, "maxItems": 3}}

    def obj(keys: tuple[tuple[str, ...], tuple[str, ...]], props: Mapping[str, Any]) -> dict[str, Any]:
        allowed, required = keys
        out: dict[str, Any] = {"type": "object", "additionalProperties": False,
                               "properties": {k: props.get(k, {}) for k in allowed}}  # fmt: skip
        if required:
            out["required"] = list(required)
        return out

    body_props: dict[str, Mapping[str, Any]] = {
        "position": {"joint": vec3, "cartesian": vec3},
        "trajectory": {"waypoints": points, "times": {"type": "array", "items": pos}},
        "ellipse": {
            "a": pos,
            "b": pos,
            "DY": num,
            "DZ": num,
            "dth": num,
            "T": pos,
            "points": {"type": "integer", "minimum": 3},
            "repetitions": {"type": "integer", "minimum": 1},
            "approach": pos,
        },  # fmt: skip
        "torque": {"amplitude": vec3, "frequency": vec3_nonneg, "phase": vec3},
        "effort": {"force": vec3},
    }
    event = {
        "type": "object",
        "additionalProperties": False,
        "required": ["t"],
        "properties": {
            "t": nonneg,
            **{k: nonneg for k in DELAY_KEYS},
            **{c: obj(EVENT_BODY_KEYS[c], body_props[c]) for c in CONTROLLERS},
        },  # fmt: skip
        "oneOf": [{"required": [c]} for c in CONTROLLERS],
    }
    backend_props: dict[str, Any] = {}
    # the built-ins (installed or not), then the plug-ins installed here (their entry points)
    for name in dict.fromkeys([*backends.BUILTIN, *backends.available()]):
        try:
            cls = backends.get(name)
        except BackendNotFound:  # not installed here: its settings are not known, any mapping
            backend_props[name] = {"type": "object"}
            continue
        props: dict[str, Any] = {"profile": {"enum": list(cls.profiles)}}
        for k, default in cls.defaults.items():
            if k in cls.choices:
                props[k] = {"enum": list(cls.choices[k])}
            elif k in cls.ranges:
                props[k] = _range_schema(cls.ranges[k])
            elif isinstance(default, bool):
                props[k] = {"type": "boolean"}
            elif isinstance(default, int):
                props[k] = {"type": "integer", "minimum": 1, "maximum": LIMITS["integer"]}
            elif isinstance(default, float):
                props[k] = pos
            else:
                props[k] = {}  # a setting the backend reads as it likes (None by default)
        backend_props[name] = {"type": "object", "additionalProperties": False, "properties": props}
    sections = {
        "gains": obj(SECTION_KEYS["gains"], {"Kp": vec3_nonneg, "Kd": vec3_nonneg, "Ki": vec3_nonneg}),
        "initial": obj(SECTION_KEYS["initial"], {"q": vec3, "qd": vec3}),
        "physics": obj(SECTION_KEYS["physics"], {
            "gravity": nonneg, "contact_mode": {"enum": list(CONTACT_MODES)},
            "contact": obj(SECTION_KEYS["physics.contact"], {"Kp": pos, "Kd": nonneg, "mu_s": nonneg, "mu_k": nonneg,
                                                              "v_th": pos, "poc": {"enum": [True, False, "true",
                                                                                           "centre"]}})}),
        "comparison": obj(SECTION_KEYS["comparison"], {
            "reference": {"type": "string"}, "skip": nonneg, "steady_window": pos, "tolerances": {"type": "object"},
            "published": {"type": "array", "items": {"type": "object", "required": ["source"]}}}),
    }  # fmt: skip
    top: dict[str, Any] = {
        "name": {"type": "string", "pattern": f"^{NAME_RE.pattern}$"},
        "description": {"type": "string"},
        "duration": pos,
        "control_rate": pos,
        "events": {"type": "array", "minItems": 1, "items": event},
        "profile": {"enum": list(PROFILES)},
        "backends": {"type": "object", "additionalProperties": False, "properties": backend_props},
        **sections,
    }
    return {
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "$id": "https://legbench/scenario.schema.json",
        "title": "legbench scenario",
        "type": "object",
        "additionalProperties": False,
        "required": ["name", "duration", "events"],
        "properties": {k: top[k] for k in TOP_KEYS},
    }


def _range_schema(rng: Range) -> dict[str, Any]:
    """JSON Schema of a number setting's :class:`~legbench.backends.base.Range`."""
    out: dict[str, Any] = {"type": ["number", "null"] if rng.nullable else "number"}
    out["exclusiveMinimum" if rng.open_low else "minimum"] = rng.low
    if rng.high != math.inf:
        out["maximum"] = rng.high
    return out


#: Valid values put in place of an invalid name, duration [s] or control rate [Hz] to look for further errors.
_STAND_INS: dict[str, Any] = {"name": "scenario", "duration": 1.0, "control_rate": 1000.0}
#: Optional sections dropped (their defaults apply) to look for further errors after one in them.
_DROPPABLE = ("description", "gains", "initial", "physics", "profile", "backends", "comparison")


def errors(path: str | Path, overrides: Mapping[str, Any] | None = None) -> list[ScenarioError]:
    """Every independent problem of a scenario file, with ``overrides`` (dotted keys, as ``--set``) set first,
    one :class:`ScenarioError` each (empty: valid).

    After an error, the optional section it is in (or the one backend's settings) is dropped, so its
    defaults apply, and the document is validated again; an error in ``events`` replaces them by one
    hold so the sections after them are still checked; an invalid ``name``, ``duration`` or
    ``control_rate`` is replaced by a stand-in (:data:`_STAND_INS`) and the checks that compare other
    values with a stand-in duration or rate are skipped (``parse``'s ``placeholders``), so that what does not
    depend on them is still checked and nothing is blamed on the stand-in. At most 50 errors.
    """
    try:
        doc, root = read_yaml(path)
        apply_overrides(doc, overrides)
    except ScenarioError as exc:
        return [exc]
    found: list[ScenarioError] = []
    doc = copy.deepcopy(doc)
    placeholders: set[str] = set()
    while len(found) < 50:
        try:
            parse(doc, str(path), root, tuple(overrides or ()), placeholders=placeholders, every_engine=True)
            return found
        except ScenarioError as exc:
            if any(str(e) == str(exc) for e in found):  # the section's defaults refused as the file's: said once
                return found
            found.append(exc)
            top = re.split(r"[.\[]", exc.key, maxsplit=1)[0] if exc.key else ""
            if not isinstance(doc, dict) or top not in doc:
                return found
            if top in _STAND_INS:
                if top in placeholders:  # the stand-in itself refused: nothing more to learn
                    return found
                doc[top] = _STAND_INS[top]
                placeholders.add(top)
                continue
            if top == "backends" and isinstance(doc["backends"], dict) and exc.key.count(".") >= 1:
                bname = exc.key.split(".")[1]
                if bname in doc["backends"]:
                    del doc["backends"][bname]
                    continue
            if top in _DROPPABLE or top not in TOP_KEYS:
                del doc[top]
            elif top == "events" and doc["events"] != [{"t": 0.0, "position": {"joint": [0.0, 0.0, 0.0]}}]:
                doc["events"] = [{"t": 0.0, "position": {"joint": [0.0, 0.0, 0.0]}}]
            else:
                return found
    return found


def _skips_too_much(skip: float, duration: float, rate: float) -> bool:
    """Whether ``skip`` [s] leaves fewer than two control ticks of a ``duration`` [s] run at ``rate`` [Hz] to
    compare (the loader refuses it; a cut scenario lets go of it)."""
    return skip > duration - 1.0 / rate + 1e-9


def shorten(sc: Scenario, duration: float, option: str = "--duration") -> Scenario:
    """The scenario cut to ``duration`` [s].

    Events that switch (``t + delay``) at or after the new end are dropped, and the
    comparison windows (``skip``, ``steady_window``) are shrunk to fit, so the result validates.

    Raises:
        ScenarioError: ``duration`` cannot be this scenario's (not a whole number of its control periods),
            naming ``option`` (what gave it), not the file's ``duration:`` key.
    """
    if duration >= sc.duration:
        return sc
    doc = dict(sc.raw)
    doc["events"] = [e for e in doc["events"] if float(e["t"]) + float(e.get("delay", 0.0)) < duration]
    doc["duration"] = duration
    cmp = dict(doc.get("comparison") or {})
    if _skips_too_much(float(cmp.get("skip", 0.0)), duration, sc.control_rate):
        cmp["skip"] = 0.0
    if float(cmp.get("steady_window", 0.0)) > duration:
        cmp["steady_window"] = duration
    if cmp:
        doc["comparison"] = cmp
    try:
        return parse(doc, sc.file, cut=True)
    except ScenarioError as exc:
        if exc.key != "duration":
            raise
        raise ScenarioError(option, "", f"{exc.problem} ({sc.name}, {sc.file})") from None


def shorten_each(scs: Sequence[Scenario], duration: float, option: str = "--duration") -> list[Scenario]:
    """Each scenario cut to ``duration`` [s] (:func:`shorten`); one note names those ``duration`` does not
    shorten (they run whole), so a ``--duration`` above a task's length is not mistaken for that length."""
    whole = [f"{sc.name} ({sc.duration:g} s)" for sc in scs if duration >= sc.duration]
    if whole:
        logger.warning(
            "legbench: note: %s %g s is not shorter than %s: %s whole",
            option,
            duration,
            ", ".join(whole),
            "it runs" if len(whole) == 1 else "they run",
        )
    return [shorten(sc, duration, option) for sc in scs]


def in_contact_mode(sc: Scenario, contact_mode: str | None) -> Scenario:
    """The scenario as run in ``contact_mode`` (None or its own: itself): its document with
    ``physics.contact_mode`` set, so the mode a run was asked for is in the scenario run.json records (``raw``) and in
    its hash, as a profile given on the command line is. Re-running a reference-mode run's recorded scenario ran it
    natively, and ``effort`` and ``effort__reference`` had one hash. Check the mode first
    (:func:`check_contact_mode`): this does not."""
    if contact_mode is None or contact_mode == sc.contact_mode:
        return sc
    doc = dict(sc.raw)
    doc["physics"] = {**dict(doc.get("physics") or {}), "contact_mode": contact_mode}
    return parse(doc, sc.file)


def physics_of(scenario: Scenario, contact_mode: str | None = None) -> Physics:
    """Physics every backend gets for this scenario (``contact_mode`` overrides the scenario's)."""
    lim = load_params().effort
    return Physics(
        gravity=scenario.gravity,
        contact=scenario.contact,
        contact_mode=contact_mode or scenario.contact_mode,
        control_dt=scenario.control_dt,
        torque_limit=(float(lim[0]), float(lim[1]), float(lim[2])),
    )
