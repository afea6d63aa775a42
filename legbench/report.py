"""Reports of a comparison: Markdown and HTML pages with interactive figures, and the index of a tree.

:func:`write_report` turns one run directory into ``metrics.json``,
``report.md`` and ``report.html`` (tables, then the interactive figures of
:mod:`legbench.report_figures`). :func:`write_index` writes the top-level
``report.html``/``report.md`` of a results tree: every scenario grouped by task
with its profiles and contact modes, one sentence per run on what differs and
why, simulation error % coloured against the tolerances, the studies collapsed
to counts. :func:`write_all` does both for a tree, one page per worker process
(``jobs``), with an optional callback per page written. Both read and render
everything first and put files in place after (staged ``.<name>.out.tmp-<pid>``
files renamed over the old ones): a malformed run directory anywhere in the
tree leaves every report, the index and the assets as they were.

plotly.js and the figures' loader are written once per results tree into
``<tree>/assets/`` (:func:`legbench.report_figures.write_assets`); every page
refers to them by a relative URL, so the report works from ``file://``
without a network.
"""

from __future__ import annotations

import contextlib
import itertools
import logging
import math
import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pandas as pd

from legbench.backends.base import FAMILY_TEXT, PROFILES, rigid_contact
from legbench.compare import ComparisonResult, compare
from legbench.contact_residuals import FN_MIN
from legbench.exceptions import ResultsError
from legbench.metrics import SteadyState
from legbench.report_figures import (
    ASSETS,
    NAMES,
    PLOTLY_JS,
    Arrays,
    ModelMatch,
    model_advice,
    model_match,
    no_ground_force,
    run_figures,
    run_title,
    write_assets,
)
from legbench.report_html import (
    Block,
    Details,
    Heading,
    Nav,
    Para,
    Table,
    num,
    num_apart,
    relpath,
    to_html,
    to_markdown,
)
from legbench.results import (
    INDEX_TITLE,
    SHOWN_SCALE,
    Run,
    atomic_write_text,
    check_index_pages,
    checks_summary,
    commit_staged,
    discard_staged,
    metrics_text,
    profile_of,
    read_meta,
    read_metrics,
    read_study,
    run_dirs,
    run_label,
    stage_text,
    study_dir,
    tolerances_of,
)
from legbench.signals import JOINT_OF, LABELS, SIGNAL_OF, UNITS, keyed
from legbench.signals import label as column_label
from legbench.studies.executors import make_executor

__all__ = [
    "BANDS",
    "SMALL_MARK",
    "IndexFiles",
    "PageItem",
    "Progress",
    "ReportFiles",
    "colour_key",
    "page_markdown",
    "sentence",
    "sim_class",
    "small_peaks",
    "transient",
    "write_all",
    "write_index",
    "write_page",
    "write_report",
]

logger = logging.getLogger("legbench.report")

#: Colour bands of a simulation error % without a ceiling in the scenario's tolerances: (upper bound [%],
#: class, "range: meaning"). Round-off is 1e-8 % (1e-10 of the peak): engines that compute the same thing
#: differ by 1e-14 to 7e-10 % over the four tasks (MuJoCo, DART and PyBullet in free space), while the
#: smallest real difference, a first-order integrator at another step, is already 1e-4-1e-3 %.
BANDS: tuple[tuple[float, str, str], ...] = (
    (1e-8, "agree", "< 1e-8 %: the same to round-off"),
    (1.0, "close", "< 1 %: close"),
    (10.0, "differ", "< 10 %: differs"),
    (math.inf, "far", ">= 10 %: differs a lot"),
)
_PROFILE_ORDER = {"matched": 0, "engine-defaults": 1}
_MODE_ORDER = {"native": 0, "reference": 1}

#: Called once per page written, with its path.
Progress = Callable[[Path], None]


@dataclass(frozen=True)
class ReportFiles:
    """Files written by :func:`write_report`.

    Attributes:
        metrics: ``DIR/metrics.json``.
        markdown: ``DIR/report.md``.
        html: ``DIR/report.html``.
        figures: the ids of the figures in report.html, in page order.
        assets: the directory holding plotly.min.js and legbench.js that report.html loads.
    """

    metrics: Path
    markdown: Path
    html: Path
    figures: tuple[str, ...]
    assets: Path


@dataclass(frozen=True)
class IndexFiles:
    """Files written by :func:`write_index`.

    Attributes:
        html: ``ROOT/report.html``.
        markdown: ``ROOT/report.md``.
        scenarios: the run directories indexed.
    """

    html: Path
    markdown: Path
    scenarios: tuple[Path, ...]


# --------------------------------------------------------------------------- #
# Colours and sentences


#: Why a component both runs hold at one constant value is not coloured as agreement (the cell is n/a-grey).
HELD = ("held: constant and equal in both runs at every sample measured (from the scenario's skip on; a torque "
        "at its limit throughout): the 0 is the clamp's, not a measure of the engines")  # fmt: skip


def sim_class(
    value: float,
    signal: str,
    joint: str,
    tolerances: Mapping[str, Any],
    held: bool = False,
    small: tuple[float, float] | None = None,
) -> tuple[str, str, tuple[float, ...]]:
    """(CSS class, why, the bounds ``value`` was held to) of one simulation error % against the scenario's ceiling
    (``comparison.tolerances.max_sim_error_pct``), else against :data:`BANDS` (the band's edges); ``held`` (the
    pair's ``held`` metric): n/a, :data:`HELD`; ``small`` (the component's reference peak and its signal's
    largest, for a component :func:`small_peaks` names) without a ceiling: the bands applied to the deviation as
    a % of the signal's largest peak instead of the component's own (:func:`small_note`; no bounds on ``value``
    itself): effort q1's 30.7 % of a 0.004 rad peak is 0.1 % of the knee's 1.26 rad (close), MuJoCo
    engine-defaults' 3759 % is a 0.149 rad walk, 11.9 % of it (differs a lot). A number is written with the
    digits that set it apart from its bounds (:func:`~legbench.report_html.num_apart`)."""
    if held:
        return "na", HELD, ()
    if not math.isfinite(value):
        return "", "", ()
    ceiling = keyed([tolerances.get("max_sim_error_pct")], signal, joint, math.inf)
    if math.isfinite(ceiling):
        shown, limit = num_apart(value, (ceiling,)), num_apart(ceiling, (value,))  # each apart from the other
        if value > ceiling:
            return "over", f"{shown} % exceeds the scenario's limit {limit} %", (ceiling,)
        return "within", f"{shown} % within the scenario's limit {limit} %", (ceiling,)
    if small is not None:
        peak, largest = small
        rel = value * peak / largest if largest > 0.0 else math.nan
        for bound, cls, why in BANDS:
            if rel < bound:
                return (
                    cls,
                    f"{small_note(value, signal, peak, largest)}; {num_apart(rel, (bound,), 3)} % of the "
                    f"largest: {why}",
                    (),
                )
        return "", "", ()
    below = 0.0
    for bound, cls, why in BANDS:
        if value < bound:
            return cls, f"{num_apart(value, (below, bound), 6)} %: {why}", (below, bound)
        below = bound
    return "", "", ()


#: A component whose reference peak is under this fraction of its signal's largest (the effort task's q1, 0.004 rad
#: beside the knee's 1.26 rad; qd1, 0.089 rad/s beside 2.24 rad/s) turns a small deviation into a large
#: percentage: the headline leaves it out, and says what it left out when that was larger.
SMALL_PEAK = 0.1
#: A small-peak component's cell reads ``30.7 (small peak)``: its number, and why its colour is by another measure.
SMALL_MARK = "small peak"


def small_peaks(df: pd.DataFrame, ref: str) -> dict[tuple[str, str], tuple[float, float]]:
    """(signal, joint) -> (its reference peak, its signal's largest) [signal unit] of the components whose
    reference peak (metric ``ref_peak`` against ``ref``, the largest over the backends) is under
    :data:`SMALL_PEAK` of their signal's largest: the effort task's q1 (0.004 rad beside q3's 1.26 rad) and qd1
    (0.089 rad/s beside 2.24 rad/s). The headline sentence leaves them out; the tables colour them by their
    deviation against the signal's largest peak (:func:`sim_class`)."""
    rows = df[(df["metric"] == "ref_peak") & (df["reference"] == ref)]
    peaks: dict[tuple[str, str], float] = {}
    for sig, j, x in zip(rows["signal"], rows["joint"], rows["value"], strict=True):
        if math.isfinite(float(x)):
            peaks[(str(sig), str(j))] = max(peaks.get((str(sig), str(j)), 0.0), float(x))
    largest: dict[str, float] = {}
    for (sig, _), x in peaks.items():
        largest[sig] = max(largest.get(sig, 0.0), x)
    return {c: (x, largest[c[0]]) for c, x in peaks.items() if x < SMALL_PEAK * largest[c[0]]}


def small_note(value: float, signal: str, peak: float, largest: float) -> str:
    """Why a small-peak component's simulation error % is coloured by another measure, with what it amounts to."""
    unit = UNITS[signal]
    dev = f": {num(value, 3)} % of it is {num(value * peak / 100.0, 3)} {unit}" if math.isfinite(value) else ""
    return (
        f"small reference peak: {num(peak, 3)} {unit}, under {num(SMALL_PEAK * 100.0)} % of the largest in its "
        f"signal ({num(largest, 3)} {unit}){dev}; a small deviation makes a large percentage here, so the colour is "
        "that of the deviation as a % of the largest peak, and the headline sentence leaves it out"
    )


#: The contact-mode split names one part "mostly" the cause only when its peak is at least this many times the
#: other's: the two peaks are taken at their own times, so a closer pair says both (today's runs: 3e5 and 3e4).
MOSTLY = 3.0
#: Backends whose simulation error in the headline's component is within this fraction of the largest deviate
#: as much, and are named with it (the 1 ms engines of an engine-defaults run, equal to 1e-5).
TIE = 1e-3


def time_text(t: float) -> str:
    """A time [s] to the millisecond of a 1 kHz log at least (``11.009``, not ``11.01``; ``3``, ``0.004``)."""
    if not math.isfinite(t) or t == 0.0:
        return num(t)
    return num(t, max(4, math.floor(math.log10(abs(t))) + 4))


#: How long after an onset [s] a largest deviation is that onset's transient: the foot's first contact, or a
#: controller switch with the reference's foot already in contact (the combined task's push at 2 s). The effort
#: task's reference friction peaks at t = 0.006 s, 5 ms after its first sample in contact (fx 16.8 N, three times
#: its steady 5.6 N), and is at 5.5 N by t = 0.010 s; the engines' largest force deviations fall at 4-7 ms (at 5 ms
#: of the push in the combined task).
ONSET = 0.010


def transient(meta: Mapping[str, Any], backend: str, t: float) -> str:
    """Which onset transient a largest deviation of ``backend`` at ``t`` [s] falls in: within :data:`ONSET` after
    the foot's first contact (the earlier of the backend's and the reference's: metrics.json
    ``backends.<name>.first_contact``), else after a controller switch (``events``) at which the reference's foot
    was already in contact. ``touch-down transient: 5 ms after the foot's first contact at t = 0.001 s``; empty
    where it is in neither (and for a metrics.json of an older legbench, which records neither)."""
    if not math.isfinite(t):
        return ""
    entries = meta.get("backends") or {}
    ref = str(meta.get("reference", ""))
    firsts = [x for n in (backend, ref) if isinstance(x := (entries.get(n) or {}).get("first_contact"), int | float)]

    def after(t0: float) -> bool:
        return t0 - 1e-9 <= t <= t0 + ONSET + 1e-9

    if firsts and after(c := min(firsts)):
        dt = meta.get("control_dt")  # [s]; an older metrics.json has none: no such onset said
        tick = float(dt) if isinstance(dt, int | float) else -math.inf
        for e in meta.get("events") or ():
            # a task that starts on the ground (its first contact within a tick of a switch): the switch's onset
            t0 = float(e.get("t", math.nan))
            if t0 - 1e-9 <= c <= t0 + tick + 1e-9:
                since = f"{num((t - t0) * 1e3, 3)} ms after" if t - t0 > 1e-9 else "the tick of"
                return (f"onset transient: {since} the switch to {e.get('controller')} control at t = "
                        f"{time_text(t0)} s, the foot in contact from its next tick")  # fmt: skip
        if t - c <= 1e-9:
            return "touch-down transient: the foot's first contact tick"
        return (
            f"touch-down transient: {num((t - c) * 1e3, 3)} ms after the foot's first contact at t = {time_text(c)} s"
        )
    ref_first = (entries.get(ref) or {}).get("first_contact")
    if not isinstance(ref_first, int | float):
        return ""
    for e in meta.get("events") or ():
        t0 = float(e.get("t", math.nan))
        if t0 >= ref_first - 1e-9 and after(t0):  # a switch while the foot is on the ground: its onset
            since = f"{num((t - t0) * 1e3, 3)} ms after" if t - t0 > 1e-9 else "the tick of"
            return (f"onset transient: {since} the switch to {e.get('controller')} control at t = {time_text(t0)} s, "
                    "the foot in contact")  # fmt: skip
    return ""


def _when(meta: Mapping[str, Any], backend: str, t: float, inside: bool = False) -> str:
    """`` (touch-down transient: ...)`` after a quoted time where :func:`transient` names one (``inside``
    parentheses already: ``, touch-down transient: ...``), else empty."""
    what = transient(meta, backend, t)
    return "" if not what else f", {what}" if inside else f" ({what})"


def deviation_note(meta: Mapping[str, Any], backend: str, signal: str, dev: float, t: float) -> str:
    """A cell's hover note on where its simulation error % comes from: ``largest deviation 10.7 N at t = 0.006 s``
    and the transient it falls in (:func:`transient`); empty without a finite deviation and time."""
    if not (math.isfinite(dev) and math.isfinite(t)) or dev == 0.0:
        return ""
    return f"largest deviation {num(dev, 3)} {UNITS[signal]} at t = {time_text(t)} s{_when(meta, backend, t)}"


def implicit_note(infos: Mapping[str, Mapping[str, Any]]) -> str:
    """The sentence on what reference contact mode shares between backends, for the backends whose run.json info
    says ``reference_friction: implicit`` (the engines' default): the law and its linearly implicit friction step
    are legbench's code (:meth:`legbench.contact.ReferenceContact.implicit_generalized`), and that step's M^-1 and
    explicit acceleration come from the reference model (Pinocchio on the same URDF), not from the engine. Empty
    where no backend declares it."""
    names = sorted(n for n, info in infos.items() if str((info or {}).get("reference_friction")) == "implicit")
    if not names:
        return ""
    verb = "takes" if len(names) == 1 else "take"
    return (
        f"In reference contact mode the contact law, its implicit friction step included, is legbench's own code "
        f"(legbench/contact.py), and {_names(names)} (reference_friction: implicit) {verb} that step's M^-1 and "
        "explicit acceleration from legbench's own model of the leg (the same URDF), not from the engine: agreement in "
        "this mode, even to the same digits, is not independent evidence of the engines' dynamics in contact."
    )


def coefficient_note(infos: Mapping[str, Mapping[str, Any]], reference: str) -> str:
    """The sentence on the Coulomb coefficient, for a native-contact run whose foot touches the ground: the backends
    whose run.json info declares a ``friction_coefficient`` (one Coulomb coefficient) and slides with another
    coefficient (``sliding_coefficient``) than the ``reference`` backend's, which the law sets. Empty where none
    does."""
    ref = str((infos.get(reference) or {}).get("sliding_coefficient", ""))
    names = sorted(n for n, info in infos.items() if n != reference and "friction_coefficient" in (info or {})
                   and str(info.get("sliding_coefficient")) not in ("", ref))  # fmt: skip
    if not names or not ref:
        return ""
    theirs = {str(infos[n].get("sliding_coefficient")) for n in names}
    coef = theirs.pop() if len(theirs) == 1 else "their coefficient"
    verb = "slides" if len(names) == 1 else "slide"
    return (
        f"{_names(names)} {verb} with {coef} (friction_coefficient: one Coulomb coefficient), where {reference} "
        f"slides with {ref}: wherever both feet slide (an onset, a push) their friction differs by |{coef} - {ref}| "
        "Fn, which can be most of a contact task's onset force difference (mu_k is a scenario parameter: the lab "
        "report gives mu_s alone). The other coefficient keeps the sliding friction and gives up the stick limit "
        "(--set backends.NAME.friction_coefficient=...); docs/contact_mapping.md measures both on every task."
    )


def _rows(n: int, what: str = "row") -> str:
    """``n`` rows (or ``what``s), for a summary: "1 row", "3 rows", "1 backend"."""
    return f"{n} {what}" if n == 1 else f"{n} {what}s"


def _names(items: Sequence[str]) -> str:
    return items[0] if len(items) == 1 else f"{', '.join(items[:-1])} and {items[-1]}"


def sentence(meta: Mapping[str, Any], df: pd.DataFrame) -> str:
    """One sentence from the metrics of a run: the largest deviation, whose, in what signal, and why.

    The headline is the largest simulation error % among the components whose reference peak is at least
    :data:`SMALL_PEAK` of their signal's largest (else a deviation of 0.09 rad/s in a joint that barely moves
    outranks one of 2.2 rad/s in one that swings); backends within :data:`TIE` of it in the same component are
    named with it; the largest of every other backend over the same components is named, with its backend,
    component, size and time; a left-out component that exceeds what the sentence says is stated after it, with
    its size and time. Every percentage is in the run tables' 4 digits, sizes and peaks in 3.
    """
    ref = str(meta.get("reference", ""))
    cols = [df[c].tolist() for c in ("backend", "reference", "signal", "joint", "metric", "value")]
    value = {(b, r, s, j, m): float(v) for b, r, s, j, m, v in zip(*cols, strict=True)}
    sim = {k: v for k, v in value.items() if k[4] == "sim_error_pct" and k[1] == ref and math.isfinite(v)}
    if not sim:
        if ((meta.get("backends") or {}).get(ref) or {}).get("status") == "ok":  # the others have none
            return f"No deviation measured: no backend but the reference '{ref}' has data."
        return f"No deviation measured: the reference backend '{ref}' has no data."
    nan = math.nan
    peaks = {c: x for c, (x, _) in small_peaks(df, ref).items()}
    small = set(peaks)
    main = {k: v for k, v in sim.items() if (k[2], k[3]) not in small} or sim
    (b, _, s, j, _), v = max(main.items(), key=lambda kv: kv[1])
    lab = column_label(s, j)
    dev, t = value.get((b, ref, s, j, "max_abs"), nan), value.get((b, ref, s, j, "t_max_abs"), nan)
    tied = sorted(k[0] for k, x in sim.items() if k[0] != b and k[2:4] == (s, j) and abs(x - v) <= TIE * v)
    rest = {k: x for k, x in main.items() if k[0] != b and k[0] not in tied}
    others = list(rest.values())
    top_key, top = max(sim.items(), key=lambda kv: kv[1])
    if top < BANDS[0][0]:
        text = (
            f"Every backend agrees with {ref} to round-off: the largest simulation error is {num(top, 3)} % "
            f"({top_key[0]}, {column_label(top_key[2], top_key[3])})."
        )
    else:
        peak = value.get((b, ref, s, j, "ref_peak"), nan)
        peak = peak if math.isfinite(peak) else dev * 100.0 / v
        text = (
            f"Largest difference: {b}'s {lab} ({NAMES[s]}) deviates from {ref} by up to {num(dev, 3)} "
            f"{UNITS[s]} at t = {time_text(t)} s{_when(meta, b, t)}, {num(v)} % of the reference's peak "
            f"({num(peak, 3)} {UNITS[s]})"
        )
        if tied:
            text += f"; {_names(tied)} deviate as much (within {num(TIE * 100.0)} % of it)"
        if rest:  # named, in the tables' own 4 digits (a bound rounded up read 105.3 beside the table's 105.2)
            (b3, _, s3, j3, _), v3 = max(rest.items(), key=lambda kv: kv[1])
            dev3, t3 = value.get((b3, ref, s3, j3, "max_abs"), nan), value.get((b3, ref, s3, j3, "t_max_abs"), nan)
            text += (
                f"; of the other backends, the largest is {b3}'s {column_label(s3, j3)}, {num(v3)} % "
                f"({num(dev3, 3)} {UNITS[s3]} at t = {time_text(t3)} s{_when(meta, b3, t3, inside=True)})."
            )
        else:
            text += "."
    contact = value.get((b, ref, s, j, "split_contact_pct"), nan)
    integ = value.get((b, ref, s, j, "split_integration_pct"), nan)
    airborne = _airborne(df)  # no contact: the split's contact part is 0 by construction
    if top >= BANDS[0][0] and math.isfinite(contact) and math.isfinite(integ) and not airborne:
        split = f"contact-mode split: contact {num(contact, 3)} %, integration {num(integ, 3)} %"
        if max(contact, integ) >= MOSTLY * min(contact, integ):
            part = "contact model" if contact >= integ else "integration and dynamics"
            text += f" Why: mostly the {part} ({split})."
        else:  # each part's peak is taken at its own time: without a clear ratio neither is 'mostly'
            text += f" Why: both the contact model and the integration ({split}; each a peak at its own time)."
    elif airborne:
        text += " The foot never touches the ground, so what differs is integration and dynamics."
    elif meta.get("contact_mode") == "reference":
        text += " Every engine runs the same contact law here, so what differs is integration and dynamics."
    if top >= BANDS[0][0] and not airborne and ((meta.get("backends") or {}).get(b) or {}).get("contact_rigid"):
        text += (
            f" {b}'s own contact is rigid (no stiffness: run.json's contact.Kp null), so the reference's sinking "
            "into its spring, and the joint motion that comes with it, has no counterpart there."
        )
    if top >= BANDS[0][0] and (airborne or meta.get("contact_mode") == "reference"):  # the step error differs
        where = "in free space" if airborne else "in reference contact mode"
        text += _higher_order_note(meta, b, ref, where) or _coarser_step_note(meta, [b, *tied], ref, where)
    if top >= BANDS[0][0]:
        bound = max(others) if others else v
        beyond = {k: x for k, x in sim.items() if (k[2], k[3]) in small
                  and x > (v if k[0] == b or k[0] in tied else bound)}  # fmt: skip
        if beyond:
            (b2, _, s2, j2, _), v2 = max(beyond.items(), key=lambda kv: kv[1])
            dev2, t2 = value.get((b2, ref, s2, j2, "max_abs"), nan), value.get((b2, ref, s2, j2, "t_max_abs"), nan)
            left = [f"{column_label(*c)} ({num(peaks[c], 3)} {UNITS[c[0]]})" for c in sorted(small, key=_order)]
            text += (
                f" Left out above, as their reference peak is under {num(SMALL_PEAK * 100.0)} % of their signal's "
                f"largest: {_names(left)}; there {b2}'s {column_label(s2, j2)} reaches {num(v2)} % "
                f"({num(dev2, 3)} {UNITS[s2]} at t = {time_text(t2)} s{_when(meta, b2, t2, inside=True)})."
            )
    return text


#: Order of accuracy of each integrator family (:data:`~legbench.backends.base.INTEGRATOR_FAMILIES`) where known.
_ORDER = {"euler": 1, "implicit": 1, "first-order": 1, "rk4": 4, "adaptive": 5}


def _higher_order_note(meta: Mapping[str, Any], b: str, ref: str, where: str) -> str:
    """Where the backend that deviates most integrates at a higher order than a first-order reference (``where``:
    in free space, or in reference contact mode, where every backend applies the same law, so the step error is
    what differs): with the same dynamics, the deviation is mostly the reference's own step error rather than the
    other backend's. The position task: the 50 us semi-implicit Euler reference is itself 0.20 % off a converged
    run, the rk45 symbolic model 0.01 %; the effort task in reference mode (against Pinocchio's rk45 at rtol
    1e-10): the reference misses fy by 0.46 N, the symbolic model (rk45, rtol 1e-8, atol 1e-6) by 0.026 N.
    Empty otherwise."""
    entries = meta.get("backends") or {}
    fam_b, fam_r = (str((entries.get(n) or {}).get("integrator_family", "")) for n in (b, ref))
    if _ORDER.get(fam_r) != 1 or _ORDER.get(fam_b, 0) <= 1:
        return ""
    return (
        f" {b} integrates at a higher order ({fam_b}) than the first-order reference {ref} ({fam_r} "
        f"integration): {where}, with the same dynamics (the verification checks them), such a deviation "
        f"is mostly the reference's own step error rather than {b}'s (the time-step sweep measures each "
        "backend's)."
    )


def _coarser_step_note(meta: Mapping[str, Any], names: Sequence[str], ref: str, where: str) -> str:
    """Where the backends that deviate most (``names``: the largest and those tied with it) all step at one fixed
    step at least twice the reference's, in an integrator family of the reference's order (metrics.json's
    ``step`` and ``integrator_family``): ``where`` every backend has the same dynamics, so that deviation is mostly
    the coarser step's error, which the engines share, not one engine's (the engine-defaults profile's 1 ms against
    the reference's 50 us sub-steps: every engine's tau1 3.965 % in the position task). Empty otherwise."""
    entries = meta.get("backends") or {}
    steps = {(entries.get(n) or {}).get("step") for n in names}
    h_ref = (entries.get(ref) or {}).get("step")
    orders = {_ORDER.get(str((entries.get(n) or {}).get("integrator_family", ""))) for n in [*names, ref]}
    if len(steps) != 1 or not isinstance(h_ref, float) or orders != {1}:
        return ""
    (h,) = steps
    if not isinstance(h, float) or not h >= 2.0 * h_ref:
        return ""
    who = f"{names[0]} steps" if len(names) == 1 else f"{_names(sorted(names))} all step"
    return (
        f" {who} at {num(h, 3)} s against the reference's {num(h_ref, 3)} s (first-order integration each): "
        f"{where}, with the same dynamics (the verification checks them), such a deviation is mostly the coarser "
        "step's error, not an engine's (the time-step sweep measures each backend's)."
    )


def _order(c: tuple[str, str]) -> int:
    """A component's place among the 12 data columns (q1..q3, qd1..qd3, tau1..tau3, fx..fz)."""
    lab = column_label(*c)
    return LABELS.index(lab) if lab in LABELS else len(LABELS)


def colour_key(limits: bool = False) -> Table:
    """One row showing every colour of a simulation error % on the page and what it means; the two colours of a
    scenario's own limit (``comparison.tolerances.max_sim_error_pct``) only where ``limits``: some scenario sets
    one (none of the bundled ones does, and a key entry for a colour that never appears misleads)."""
    bands = [(why.split(": ")[0], why.split(": ")[1], cls) for _, cls, why in BANDS]
    limit = [("<= scenario limit", "within the limit", "within"), ("> scenario limit", "exceeds the limit", "over")]
    grey = ("grey", "held (both runs at one constant value: the 0 is the clamp's), or n/a", "na")
    cols = [*bands, *(limit if limits else []), grey]
    caption = "Colour key of the simulation error %" + (" (a scenario's own limit overrides the bands)" if limits
                                                          else "")  # fmt: skip
    caption += (f". A cell marked ({SMALL_MARK}): the reference's peak of that component is under "
                f"{num(SMALL_PEAK * 100.0)} % of its signal's largest, so a small deviation makes a large %: its "
                "colour is that of the deviation as a % of the signal's largest peak; the headline leaves it "
                "out")  # fmt: skip
    return Table(tuple(c[0] for c in cols), (tuple(c[1] for c in cols),), caption,
                 classes={(0, j): c[2] for j, c in enumerate(cols)})  # fmt: skip


# --------------------------------------------------------------------------- #
# Tables of a run report


def _col_header(i: int) -> str:
    return f"{LABELS[i]} [{UNITS[SIGNAL_OF[i]]}]"


def _sim_cell(
    value: float,
    signal: str,
    joint: str,
    tolerances: Mapping[str, Any],
    held: bool,
    small: tuple[float, float] | None,
    meta: Mapping[str, Any],
    backend: str,
    dev: float,
    t: float,
    digits: int = 4,
) -> tuple[str, str, str]:
    """(text, CSS class, hover) of one simulation error % cell, as every table of them shows it: the number
    (``digits`` significant, more where fewer would read as a bound it was held to: :func:`sim_class`) and the
    mark ``held`` or :data:`SMALL_MARK` after it (or none), :func:`sim_class`'s class, and its why followed by
    where the largest deviation ``dev`` [signal unit] at ``t`` [s] is (:func:`deviation_note`; none for a held
    one)."""
    cls, why, bounds = sim_class(value, signal, joint, tolerances, held, small)
    mark = "held" if held else SMALL_MARK if small is not None and math.isfinite(value) else ""
    where = "" if held else deviation_note(meta, backend, signal, dev, t)
    text = num_apart(value, bounds, digits)
    return f"{text} ({mark})" if mark else text, cls, f"{why}; {where}" if where else why


def _pair_table(
    result: ComparisonResult,
    metric: str,
    caption: str,
    unit: bool,
    meta: Mapping[str, Any] | None = None,
    df: pd.DataFrame | None = None,
) -> Table:
    """One row per pair of ``metric``; for ``sim_error_pct`` each cell marked, coloured and with its hover
    (:func:`_sim_cell`; ``meta`` the page's metrics.json document, ``df`` its metrics table, else computed)."""
    header = ("backend", "vs", *(_col_header(i) if unit else LABELS[i] for i in range(12)))
    rows: list[tuple[str, ...]] = []
    classes: dict[tuple[int, int], str] = {}
    titles: dict[tuple[int, int], str] = {}
    small = _small_of(result, result.frame() if df is None else df) if metric == "sim_error_pct" else {}
    for r, p in enumerate(result.pairs):
        if metric != "sim_error_pct":
            rows.append((p.backend, p.reference, *(num(float(v)) for v in getattr(p, metric))))
            continue
        cells = []
        for i, v in enumerate(p.sim_error_pct):
            tiny = small.get(i) if p.reference == result.reference else None
            text, cls, title = _sim_cell(float(v), SIGNAL_OF[i], LABELS[i][-1], result.run.tolerances,
                                         bool(p.held[i]), tiny, meta or {}, p.backend, float(p.max_abs[i]),
                                         float(p.t_max_abs[i]))  # fmt: skip
            cells.append(text)
            if cls:
                classes[(r, i + 2)], titles[(r, i + 2)] = cls, title
        rows.append((p.backend, p.reference, *cells))
    return Table(header, tuple(rows), caption, classes=classes, titles=titles)


def _small_of(result: ComparisonResult, df: pd.DataFrame) -> dict[int, tuple[float, float]]:
    """Column index -> (reference peak, its signal's largest) of the run's small-peak components
    (:func:`small_peaks`, the one rule, on its metrics table ``df``), against the run's reference."""
    small = small_peaks(df, result.reference)
    return {i: small[(SIGNAL_OF[i], JOINT_OF[i])] for i in range(len(LABELS)) if (SIGNAL_OF[i], JOINT_OF[i]) in small}


def _at_time(m: float, t: float) -> str:
    """A largest deviation and its time; a component that never deviates (0) or has no data has no time."""
    return f"{num(m, 3)} @ {time_text(t)} s" if math.isfinite(m) and m != 0.0 and math.isfinite(t) else num(m, 3)


def _from_skip(run: Run) -> str:
    """`` for t >= <skip> s`` where the run's metrics leave a start out, for a caption; empty otherwise."""
    return f" for t >= {num(run.skip)} s" if run.skip > 0 else ""


def _maxdev_table(result: ComparisonResult) -> Table:
    header = ("backend", "vs", *(_col_header(i) for i in range(12)))
    rows = tuple(
        (p.backend, p.reference, *(_at_time(float(m), float(t)) for m, t in zip(p.max_abs, p.t_max_abs, strict=True)))
        for p in result.pairs
    )
    return Table(header, rows, f"Largest deviation |x - x_ref| and the time it happens{_from_skip(result.run)}")


#: Largest joint speed [rad/s] in the steady window at which the analytic force check is shown; at or above it
#: the check is n/a. The check is statics (qd = qdd = 0): it leaves out the window's mean of M qdd + C qd, and the
#: mean of qdd over a window T is (qd(t1) - qd(t0)) / T, at most 2 max|qd| / T, so max |qd| bounds what it leaves
#: out. The static windows stay under a fifth of it (results/latest, every profile and contact mode: effort and
#: combined 4e-13..1e-3 rad/s; position 2e-8, at its target), the moving ones over it (ellipse 0.40 rad/s, where
#: the check reads -0.1 N of a force that is 0; MuJoCo's engine defaults let the pressed foot creep at
#: 0.047-0.052 rad/s on effort and combined: a slide, not statics; ODE's engine defaults, its quick step's rows
#: in a new random order each step, jitter at up to 0.09 rad/s there, 2.1e-3 with one order per step).
STATIC_QD = 0.01
#: |measured - analytic| of a static leg above this share of |F| is marked: the logged force is not the force that
#: holds the leg (results/latest, every static window: at most 1.6e-4, the symbolic model's adaptive step; an
#: explicit friction beyond its step bound logged 19-44 %, docs/pinocchio.md).
STATIC_RESIDUAL = 1e-2
#: A backend's declared contact lift [1 of y] at or above which the check names its lifted point and shows the
#: spec's J_poc check beside it; below, the point is the lowest one (Drake's matched profile declares 1e-8).
LIFT_SHOWN = 1e-6


def _mark_residual(s: SteadyState, r: int, classes: dict[tuple[int, int], str], titles: dict[tuple[int, int], str]
                   ) -> None:  # fmt: skip
    """Row ``r``'s force cells marked ``fail`` where the static leg's residual exceeds :data:`STATIC_RESIDUAL` of
    |F|, with why in their titles."""
    size, off = math.hypot(*s.force), math.hypot(*s.residual)
    if size > 0.0 and off > STATIC_RESIDUAL * size:
        why = (f"the logged force departs from the leg's statics by {num(100.0 * off / size, 3)} % of |F| (more "
               f"than {num(100.0 * STATIC_RESIDUAL)} %): it is not the force that holds the leg, e.g. a force read "
               "at a step too coarse for the contact (see the backend's warnings)")  # fmt: skip
        for c in range(5, 8):
            classes[(r, c)], titles[(r, c)] = "fail", why


def _steady_table(result: ComparisonResult) -> Table:
    header = ("backend", "row", "qd1 [rad/s]", "qd2 [rad/s]", "qd3 [rad/s]", "Fx [N]", "Fy [N]", "Fn [N]")
    rows: list[tuple[str, ...]] = []
    classes: dict[tuple[int, int], str] = {}
    titles: dict[tuple[int, int], str] = {}
    blank = ("", "", "")
    for s in result.steady:
        win = f"measured (mean over {s.t0:.3f}..{s.t1:.3f} s)"
        rows.append((s.backend, win, *(num(v) for v in s.qd), *(num(v) for v in s.force)))
        speed = s.qd_max
        if speed >= STATIC_QD:  # the leg moves: statics does not hold, whatever the check would print
            why = (
                f"the leg moves in the steady window: max |qd| {num(speed, 3)} rad/s, static means below "
                f"{num(STATIC_QD)} rad/s"
            )
            r = len(rows)
            rows.append((s.backend, f"analytic check: n/a ({why})", *blank, "n/a", "n/a", "n/a"))
            for c in range(5, 8):
                classes[(r, c)], titles[(r, c)] = "na", why
            continue
        # where its own contact acts
        at = "J_poc" if s.lift < LIFT_SHOWN else f"J at {num(s.lift, 3)} y above the poc"
        unchecked = " (no qd logged: static not checked)" if math.isnan(speed) else ""
        if s.poc == "centre" and s.analytic_centre is not None and s.poc_compensation is not None:
            # a law taking the poc at the sphere centre applies its force there: the check is J_E's
            rows.append((s.backend, f"analytic check, J_E (its law's poc, the centre){unchecked}", *blank,
                         *(num(v) for v in s.analytic_centre)))  # fmt: skip
            rows.append((s.backend, "measured - analytic (J_E)", *blank, *(num(v) for v in s.residual)))
            _mark_residual(s, len(rows) - 1, classes, titles)
            rows.append((s.backend, "analytic check, J_poc (the true poc)", *blank, *(num(v) for v in s.analytic_poc)))
            rows.append((s.backend, "poc compensation (J_poc - J_E)", *blank, *(num(v) for v in s.poc_compensation)))
            continue
        rows.append((s.backend, f"analytic check, {at}{unchecked}", *blank, *(num(v) for v in s.analytic_poc)))
        rows.append((s.backend, f"measured - analytic ({at})", *blank, *(num(v) for v in s.residual)))
        _mark_residual(s, len(rows) - 1, classes, titles)
        if s.lift >= LIFT_SHOWN and s.analytic_lowest is not None and s.lift_compensation is not None:
            # the spec's check at the lowest point, and the lever between the two
            rows.append((s.backend, "analytic check, J_poc (the spec's: the sphere's lowest point)", *blank,
                         *(num(v) for v in s.analytic_lowest)))  # fmt: skip
            rows.append((s.backend, f"lever compensation ({at} - J_poc)", *blank,
                         *(num(v) for v in s.lift_compensation)))  # fmt: skip
        if s.analytic_centre is not None and s.poc_compensation is not None:
            rows.append(
                (s.backend, "analytic check, J_E (poc at centre)", *blank, *(num(v) for v in s.analytic_centre))
            )
            rows.append((s.backend, "poc compensation (J_poc - J_E)", *blank, *(num(v) for v in s.poc_compensation)))
    published = ((result.run.meta.get("scenario") or {}).get("comparison") or {}).get("published") or []
    for row in published:  # the lab report's numbers for this task, as the scenario file gives them
        qd = [num(v) for v in row["qd_abs"]] if "qd_abs" in row else list(blank)
        force = [num(v) for v in row["force"]] if "force" in row else list(blank)
        what = "published (|qd| magnitudes)" if "qd_abs" in row else "published"
        if row.get("note"):
            what = f"{what}; caveat: {row['note']}"
        rows.append((str(row["source"]), what, *qd, *force))
    return Table(
        header,
        tuple(rows),
        "Steady state over the final window; analytic check F = -(J^T)^-1 (tau - G(q)) at the mean q and tau "
        f"(ground force on the foot; valid when the leg is static: n/a where max |qd| over the window reaches "
        f"{num(STATIC_QD)} rad/s); J_poc: the Jacobian of the sphere's lowest point"
        + (
            "; J at a fraction of the penetration y above it: where that engine's own contact applies the force "
            "(0.5: halfway between the surfaces), followed by the spec's check with J_poc and the lever between the "
            "two"
            if any(s.lift >= LIFT_SHOWN for s in result.steady)
            else ""
        ),  # fmt: skip
        classes=classes,
        titles=titles,
    )


def _matched_infos(run: Run) -> dict[str, Mapping[str, Any]]:
    """backend -> run.json info of the same scenario's matched run beside this one (``<tree>/<name>``, or its
    ``__reference`` twin for a reference-mode run), if that directory holds one in the matched profile; else {}."""
    sibling = run.path.parent / run_label(run.name, "matched", run.contact_mode)
    if sibling == run.path or not (sibling / "run.json").is_file():
        return {}
    try:
        meta = read_meta(sibling)
    except ResultsError:
        return {}
    if profile_of(meta) != "matched":
        return {}
    return {str(n): dict(v.get("info") or {}) for n, v in (meta.get("backends") or {}).items()}


def _free_space_steps(result: ComparisonResult) -> str:
    """What separates a free-space run of another profile from the reference, from run.json: the backends that run
    the reference's integrator family at another step (the engines' 1 ms against Pinocchio's 50 us x 20), with
    their own step in the matched run beside it where there is one, and those that change their integrator too.
    In free space the contact settings act on nothing, so for the former the step is what the profile changes."""
    infos, ref = _infos(result.run), result.reference
    matched = _matched_infos(result.run)
    ref_info = infos.get(ref) or {}
    ref_step, _ = _step_text(ref_info)
    family = ref_info.get("integrator_family")
    profile = result.run.profile
    stepped: list[str] = []
    changed: list[str] = []
    steps: set[str] = set()
    for name, info in infos.items():
        if name == ref or not info or result.run.backends[name].status != "ok":
            continue
        step, _ = _step_text(info)
        was = matched.get(name)
        if was and _integrator_text(was) != _integrator_text(info):
            changed.append(f"{name} changes its integrator too ({_integrator_text(was)} in the matched profile, "
                           f"{_integrator_text(info)} here, at {step})")  # fmt: skip
        elif family and info.get("integrator_family") == family and step != ref_step:
            stepped.append(name)
            steps.add(step)
    text = "The foot never touches the ground here, so the contact settings act on nothing"
    if stepped:
        were = sorted({_step_text(matched[n])[0] for n in stepped if n in matched})
        text += (
            f" and the {profile} profile's change that acts here is chiefly the step (settings such as joint limits "
            f"that the motion never reaches act on nothing either): {_names(stepped)} "
            f"{'runs' if len(stepped) == 1 else 'run'} the reference's integrator family ({family}) at "
            f"{_names(sorted(steps))} per control tick, against {ref}'s {ref_step}"
            + (
                f" ({'its' if len(stepped) == 1 else 'their'} own step in the matched profile: {_names(were)})"
                if were
                else ""
            )
            + ", as run.json records"
        )
    return text + "".join(f"; {c}" for c in changed) + "."


def _touches(df: pd.DataFrame) -> bool:
    """Some backend's foot touches the ground in the run (metric ``residual_n_contact`` > 0)."""
    n = df[df["metric"] == "residual_n_contact"]["value"]
    return bool(len(n)) and float(n.max()) > 0


def _airborne(df: pd.DataFrame) -> bool:
    """No backend's foot touches the ground (metric ``residual_n_contact`` recorded, and 0 for every backend). A run
    whose run.json names no contact law has no residuals: it is not known to be airborne (its split is kept)."""
    n = df[df["metric"] == "residual_n_contact"]["value"]
    return bool(len(n)) and float(n.max()) == 0


def _infos(run: Run) -> dict[str, Mapping[str, Any]]:
    """backend -> its run.json info (the settings it used)."""
    return {name: b.info for name, b in run.backends.items()}


def _split_table(result: ComparisonResult, kind: str, df: pd.DataFrame) -> Table:
    """The contact-mode split of ``kind`` (``rms`` or ``pct``); ``df``: the page's metrics table."""
    header = ("backend", "part", *(_col_header(i) if kind == "rms" else LABELS[i] for i in range(12)))
    rows = []
    for m in result.split:
        for part in ("native", "contact", "integration", "drift"):
            rows.append((m.backend, part, *(num(v) for v in getattr(m, f"{part}_{kind}"))))
    what = "RMS" if kind == "rms" else "max |part| / max |x_ref| x 100 [%]"
    return Table(
        header,
        tuple(rows),
        f"Contact-mode split ({what}"
        + (f",{_from_skip(result.run)}" if result.run.skip > 0 else "")
        + "): native = contact (a_native - a_reference-mode) + integration "
        "(a_reference-mode - ref_reference-mode) + drift (ref_reference-mode - ref_native), sample by sample"
        + (f". {shared}" if kind == "pct" and result.split_run is not None and _touches(df)
           and (shared := implicit_note(_infos(result.split_run))) else ""),
    )  # fmt: skip


def _flat(d: Mapping[str, Any], prefix: str = "") -> dict[str, str]:
    """Nested settings as ``a.b = value`` strings, numbers in the report's format."""
    out: dict[str, str] = {}
    for k, v in d.items():
        key = f"{prefix}{k}"
        if isinstance(v, Mapping):
            out |= _flat(v, key + ".") if v else {key: "{}"}
        elif isinstance(v, bool) or v is None:
            out[key] = str(v).lower() if v is not None else "none"
        elif isinstance(v, int | float):
            out[key] = num(v, 6)
        elif isinstance(v, list | tuple):
            out[key] = (
                ", ".join(num(x, 6) if isinstance(x, int | float) and not isinstance(x, bool) else str(x) for x in v)
                or "[]"
            )
        else:
            out[key] = str(v)
    return out


#: Units of the contact law's parameters in the scenario table (docs/spec.md section 4).
_CONTACT_UNITS = {"Kp": " [N/m]", "Kd": " [N s/m]", "v_th": " [m/s]"}


#: Units of the settings keys legbench itself defines (base.INFO_KEYS and the shared settings), for the settings
#: table; an engine's own parameters keep the engine's units (its docs/backends page).
_SETTING_UNITS = {
    "dt": " [s]", "timestep": " [s]", "max_step": " [s]", "gravity": " [m/s^2]", "stiction_tolerance": " [m/s]",
    "hc_reference_depth": " [m]", "contact.lift": " [1 of y]", **{f"contact.{k}": u for k, u in _CONTACT_UNITS.items()},
}  # fmt: skip


def _settings(info: Mapping[str, Any]) -> dict[str, str]:
    rest = {k: v for k, v in info.items() if k not in ("engine", "version", "warnings", "at_end")}  # at_end: no setting
    if set(rest) == {"settings"} and isinstance(rest["settings"], Mapping):
        rest = dict(rest["settings"])
    return _flat(rest)


def _backend_tables(result: ComparisonResult) -> list[Block]:
    header = ("backend", "status", "reason", "engine", "version", "dynamics", "wall time [s]",
              "RTF (simulated s per wall s)")  # fmt: skip
    rows = []
    for b in result.run.backends.values():
        rows.append(
            (
                b.name,
                b.status,
                b.reason or "",
                str(b.info.get("engine", "")),
                str(b.info.get("version", "")),
                str(b.info.get("dynamics", "the engine's")),
                num(b.wall_time, 3),
                num(b.rtf, 3),
            )
        )
    for name, tr in result.traces.items():
        if name not in result.run.backends:
            rows.append((name, "ok", "", "imported log", tr.source, "", "", ""))
    blocks: list[Block] = [Table(header, tuple(rows), "Backends: status, engine and version (from run.json); wall "
                                 "time of the simulation loop; RTF, the real-time factor: the run's simulated "
                                 "time over that wall time (> 1: faster than real time)")]  # fmt: skip
    per = {b.name: _settings(b.info) for b in result.run.backends.values()}
    for b in result.run.backends.values():  # an engine with no integrator setting: its declared family, as the index
        if "integrator" not in per[b.name] and b.info.get("integrator_family"):
            per[b.name]["integrator"] = _integrator_text(b.info)
    keys = list(dict.fromkeys(k for s in per.values() for k in s))
    if keys:
        names = list(per)
        srows = tuple((f"{k}{_SETTING_UNITS.get(k, '')}", *(per[n].get(k, "") for n in names)) for k in keys)
        table = Table(("setting", *names), srows, "Settings each backend reports it used (run.json); units where "
                      "legbench defines the key, an engine's own parameters in the engine's units")  # fmt: skip
        blocks.append(Details(f"Settings of every backend ({_rows(len(keys))})", (table,)))
    return blocks


def _rigid(result: ComparisonResult, name: str) -> bool:
    """The backend reports its own contact as rigid (run.json: engine contact on, ``contact.Kp`` null, as DART's
    LCP): it has no spring, so the law's penetration Fn/Kp is not what it was meant to follow."""
    b = result.run.backends.get(name)
    if b is None or not rigid_contact(b.info):
        return False
    return b.info["contact"].get("enabled") is not False


#: What the contact-law residuals should read for a backend that follows the law, and how far a cell may depart
#: before it is coloured: (column, expected, tolerance) [the column's unit]. Penetration 0 mm within 0.05 mm (1 %
#: of the effort task's 5.25 mm rest penetration; the matched compliant engines read 0.005-0.014 mm); the spring's
#: relative error 0 within 1 %; the friction ratio 1 within 1 % (the sliding verification's tolerance); the angle
#: 0 within 10 deg: it is a maximum over every sample slipping at 0.1 mm/s or more, where a stick-slip transition
#: sample pairs the last sub-step's force with the tick's velocity (the matched cone engines read 0.15-8 deg).
RESIDUAL_EXPECTED: dict[str, tuple[float, float]] = {
    "penetration_max_mm": (0.0, 0.05),
    "penetration_rel": (0.0, 0.01),
    "friction_ratio": (1.0, 0.01),
    "angle_max": (0.0, 10.0),
}
#: A non-conic friction limit's own bounds while sliding: |F_t| / (mu Fn) from, to, and the largest angle [deg]
#: between F_t and -v. A pyramid (each tangent axis limited by mu Fn on its own): 1 along an axis to sqrt(2) on the
#: diagonal; a diamond (|F_t1| + |F_t2| <= mu Fn): 1/sqrt(2) on the diagonal to 1 along an axis; either holds its
#: force at a vertex over a 90 deg fan of slip directions, so within 45 deg of -v.
SHAPE_BOUNDS: dict[str, tuple[float, float, float]] = {
    "pyramid": (1.0, math.sqrt(2.0), 45.0),
    "diamond": (1.0 / math.sqrt(2.0), 1.0, 45.0),
}


def friction_shape(info: Mapping[str, Any]) -> str:
    """The backend's native friction limit: its run.json info's ``friction_cone`` (``cone``, ``pyramid``,
    ``diamond``; :data:`~legbench.backends.base.INFO_KEYS`), else ``pyramid`` where its contact description says
    so (a run written before the key: "... friction pyramid"), else ``cone``."""
    if info.get("friction_cone"):
        return str(info["friction_cone"])
    contact = info.get("contact")
    said = isinstance(contact, Mapping) and any(isinstance(v, str) and "pyramid" in v for v in contact.values())
    return "pyramid" if said else "cone"


def _residual_edges(column: str, shape: str = "cone") -> tuple[float, ...]:
    """The values a contact-law residual of ``column`` is held to by :func:`_residual_marks`: the expected value
    +- its tolerance, or a non-conic friction limit's own bounds widened by it."""
    expected, tol = RESIDUAL_EXPECTED[column]
    bounds = SHAPE_BOUNDS.get(shape)
    if bounds is not None and column == "friction_ratio":
        return bounds[0] - tol, bounds[1] + tol
    if bounds is not None and column == "angle_max":
        return (bounds[2] + tol,)
    return expected - tol, expected + tol


def _residual_text(value: float, column: str, shape: str = "cone") -> str:
    """One contact-law residual as its cell writes it: with the digits that set it apart from its edges."""
    return num_apart(value, _residual_edges(column, shape))


def _residual_marks(value: float, column: str, shape: str = "cone") -> tuple[str, str]:
    """(CSS class, why) of one contact-law residual against :data:`RESIDUAL_EXPECTED` (a non-conic friction
    limit's own bounds, :data:`SHAPE_BOUNDS`, for its friction columns): ``pass`` within the tolerance, ``fail``
    beyond it (:func:`_residual_edges`); nothing for n/a."""
    if not math.isfinite(value):
        return "", ""
    expected, tol = RESIDUAL_EXPECTED[column]
    bounds = SHAPE_BOUNDS.get(shape)
    edges = _residual_edges(column, shape)
    ok = edges[0] <= value <= edges[1] if len(edges) == 2 else value <= edges[0]
    shown = _residual_text(value, column, shape)
    if bounds is not None and column in ("friction_ratio", "angle_max"):  # the shape's bounds, widened by tol
        what = (f"a friction {shape}'s own bounds, {num(bounds[0])} to {num(bounds[1])}" if column == "friction_ratio"
                else f"a friction {shape}'s own bound, <= {num(bounds[2])} deg")  # fmt: skip
        widened = f"{'±' if column == 'friction_ratio' else '+'} the tolerance {num(tol)}"
        return ("pass", f"{shown}: within {what}, {widened}") if ok else (
            "fail", f"{shown}: beyond {what}, {widened}")  # fmt: skip
    what = f"expected {num(expected)}"
    return ("pass", f"{shown}: within the tolerance {num(tol)} of {what}") if ok else (
        "fail", f"{shown}: departs from {what} by more than the tolerance {num(tol)}")  # fmt: skip


def _native_shape(result: ComparisonResult, name: str) -> str:
    """The friction shape a backend's residuals are held to: its own (:func:`friction_shape`) in native contact;
    in reference mode every backend applies the law, a cone."""
    b = result.run.backends.get(name)
    return friction_shape(b.info) if b is not None and result.run.contact_mode == "native" else "cone"


def _residual_table(result: ComparisonResult) -> Table:
    rows = []
    classes: dict[tuple[int, int], str] = {}
    titles: dict[tuple[int, int], str] = {}
    bounds = {c: f"{num(e)} ± {num(t)}" for c, (e, t) in RESIDUAL_EXPECTED.items()}
    shapes = {name: _native_shape(result, name) for name in result.residuals}
    # only the shapes some row has: a bound no backend on the page is held to reads as if one were
    present = [k for k in SHAPE_BOUNDS if k in shapes.values()]

    def also(text: Callable[[str], str]) -> str:
        return f" ({'; '.join(f'{k}: {text(k)}' for k in present)})" if present else ""

    ratio_tol, angle_tol = RESIDUAL_EXPECTED["friction_ratio"][1], RESIDUAL_EXPECTED["angle_max"][1]
    rows.append(
        ("expected (tolerance)", "", f"{bounds['penetration_max_mm']} mm", bounds["penetration_rel"], "",
         bounds["friction_ratio"] + also(lambda k: f"{num(SHAPE_BOUNDS[k][0])} to {num(SHAPE_BOUNDS[k][1])} "
                                                   f"± {num(ratio_tol)}"),
         bounds["angle_max"] + also(lambda k: f"<= {num(SHAPE_BOUNDS[k][2])} + {num(angle_tol)}"),
         "", "the law's creep", "")
    )  # fmt: skip
    for name, r in result.residuals.items():
        rigid = _rigid(result, name)
        shape = shapes[name]
        rows.append(
            (
                f"{name} ({shape})" if shape in SHAPE_BOUNDS else name,
                str(r.n_contact),
                "n/a (rigid)" if rigid else _residual_text(r.penetration_max * 1e3, "penetration_max_mm", shape),
                "n/a (rigid)" if rigid else _residual_text(r.penetration_rel, "penetration_rel", shape),
                str(r.n_sliding),
                _residual_text(r.friction_ratio, "friction_ratio", shape),
                _residual_text(r.angle_max, "angle_max", shape),
                str(r.n_creep),
                num(r.creep_speed * 1e3),
                num(r.creep_law * 1e3),
            )
        )
        marks = {5: ("friction_ratio", r.friction_ratio), 6: ("angle_max", r.angle_max)}
        if not rigid:
            marks |= {2: ("penetration_max_mm", r.penetration_max * 1e3), 3: ("penetration_rel", r.penetration_rel)}
        for c, (column, value) in marks.items():
            cls, why = _residual_marks(float(value), column, shape)
            if cls:
                classes[(len(rows) - 1, c)], titles[(len(rows) - 1, c)] = cls, why
    return Table(
        (
            "backend",
            "contact samples",
            "max |y - Fn_spring/Kp| [mm]",
            "median |y Kp/Fn_spring - 1|",
            "sliding samples",
            "|F_t| / (mu Fn) sliding",
            "max angle F_t vs -v [deg]",
            "sub-limit samples",
            "creep [mm/s]",
            "law's creep [mm/s]",
        ),
        tuple(rows),
        "Each backend against the contact law it was meant to follow (docs/metrics.md, section Contact-law "
        "residuals): penetration against the spring, Fn_spring = Fn - Kd max(ydot, 0), friction magnitude while "
        "sliding against mu Fn, mu the coefficient the backend slides with (mu_k for the law, the one coefficient of "
        "a Coulomb engine, mu_s unless its friction_coefficient says mu_k: 1 for both when they slide as they "
        "should), friction direction against the slip, and creep under a sub-limit load beside the law's "
        "v_th |F_t| / (mu_s Fn); the slip taken where "
        "each engine applies its force (run.json: contact.lift); n/a where no sample qualifies; n/a (rigid) for a "
        "backend whose contact reports no stiffness (run.json: contact.Kp null), which has no spring to compare. "
        "The first row gives what a backend following the law reads, and the tolerance: green within it, red "
        "beyond (hover for the value against it); a backend whose native friction is not a cone (marked "
        "'(pyramid)', each tangent axis limited on its own, or '(diamond)', |F_t1| + |F_t2| <= mu Fn: run.json's "
        "friction_cone, or its contact description) is held to its own bounds, |F_t| / (mu Fn) from 1 to sqrt(2) "
        "or from 1/sqrt(2) to 1, and the angle up to 45 deg, each widened by the tolerance (the angle's 10 deg, "
        "where the sliding verification holds 1 deg: its drag is steady, while this maximum takes every sample "
        "slipping at 0.1 mm/s or more, stick-slip transitions included); creep is not coloured "
        "(a Coulomb engine sticks by design: read it beside the law's)",
        classes=classes,
        titles=titles,
    )


def _event_text(e: Any) -> str:
    """One event of run.json's scenario in a few words: its controller and time, its delay, and what it holds (a
    force [N], a joint target [rad], a Cartesian target [m]), as the file gave it."""
    if not isinstance(e, Mapping):
        return str(e)
    ctrl = str(e.get("controller", "?"))
    body = e.get(ctrl)
    what = ""
    if isinstance(body, Mapping):
        what = ", ".join(f"{k} {v}" for k, v in body.items() if not isinstance(v, Mapping | list) or len(str(v)) < 60)
    delay = f" (+{num(e['delay'])} s delay)" if e.get("delay") else ""
    return f"{ctrl} @ {num(e.get('t', math.nan))} s{delay}" + (f": {what}" if what else "")


def _scenario_table(result: ComparisonResult) -> Table:
    run = result.run
    sc = run.meta.get("scenario", {})
    contact = sc.get("contact") or {}
    gains = sc.get("gains") or {}
    initial = sc.get("initial") or {}
    rows = [
        ("scenario file", str(sc.get("file", ""))),
        (
            "scenario as run, sha256",
            f"{str(sc.get('sha256', ''))[:12]} (run.json's scenario.raw: the file with its "
            "overrides, a command-line profile or contact mode included)",
        ),
        ("profile", run.profile),
        ("duration [s]", num(run.duration)),
        ("control rate [Hz]", num(sc.get("control_rate", math.nan))),
        *(
            (f"gains {k} [{u}]", ", ".join(num(x) for x in gains[k]))
            for k, u in (("Kp", "N m/rad"), ("Kd", "N m s/rad"), ("Ki", "N m/(rad s)"))
            if isinstance(gains.get(k), list)
        ),
        *(
            (f"initial {k} [{u}]", ", ".join(num(x) for x in initial[k]))
            for k, u in (("q", "rad"), ("qd", "rad/s"))
            if isinstance(initial.get(k), list)
        ),
        ("contact mode", run.contact_mode),
        *(
            (
                f"contact {k}{_CONTACT_UNITS.get(k, '')}",
                num(v) if isinstance(v, int | float) and not isinstance(v, bool) else str(v),
            )
            for k, v in contact.items()
        ),  # fmt: skip
        ("reference", result.reference),
        ("skip [s]", num(run.skip)),
        ("steady window [s]", num(run.steady_window)),
        (
            "events",
            "; ".join(_event_text(e) for e in sc.get("events") or ())
            or ", ".join(f"{e.controller} @ {num(e.t)} s" for e in run.events),
        ),
        (
            "legbench version",
            str(run.meta.get("legbench_version", ""))
            + (f", commit {commit}" if (commit := (run.meta.get("versions") or {}).get("legbench_commit")) else ""),
        ),
        *((("written (UTC)", str(run.meta["written"])),) if run.meta.get("written") else ()),
        *((f"platform {k}", v) for k, v in _flat(run.meta.get("platform") or {}).items() if v not in ("", None)),
    ]
    return Table(("item", "value"), tuple(rows), "Scenario")


def _model_notes(result: ComparisonResult, match: ModelMatch) -> tuple[Para, Para]:
    """(why the 3D leg view is left out, which model the model-dependent checks used) for a run made with another
    leg model than the active one."""
    advice = model_advice(match, result.run)
    leg = Para(
        f"The 3D leg view is left out: this run used another leg model (run.json: {match.run}) than the active "
        f"one ({match.active}), whose geometry the view would draw; to get it, report the run with its own "
        f"model: {advice}."
    )
    checks = Para(
        f"The analytic force check and the contact-law residuals on this page (and in metrics.json) used the "
        f"active leg model ({match.active}: its J(q), G(q), lengths and foot radius), not this run's "
        f"({match.run}); for the run's own, {advice}.",
        warn=True,
    )
    return leg, checks


def _sibling_pages(run: Run) -> list[tuple[str, str]]:
    """Links to the pages of the same scenario's other runs beside this one in its tree (its other profile or
    contact mode), named by them, in the index's order: (profile, mode), the relative path."""
    found = []
    for d in sorted(run.path.parent.iterdir()):
        if d == run.path or not (d.name == run.name or d.name.startswith(f"{run.name}__")):
            continue
        try:
            meta = read_meta(d)
        except (ResultsError, OSError):
            continue  # not a run directory, or not one to link: the index says what it is
        sc = meta.get("scenario") or {}
        if sc.get("name") != run.name:
            continue
        profile, mode = profile_of(meta), str(sc.get("contact_mode") or "native")
        found.append(((_PROFILE_ORDER.get(profile, 9), _MODE_ORDER.get(mode, 9)), f"{profile}, {mode}",
                      f"../{d.name}/report.html"))  # fmt: skip
    return [(text, href) for _, text, href in sorted(found)]


def _blocks(result: ComparisonResult, figures: Sequence[Any], index: str | None) -> list[Block]:
    run = result.run
    sc = run.meta.get("scenario", {})
    match = model_match(run)
    leg_note, checks_note = _model_notes(result, match) if match.differs else (None, None)
    nav = [("\u2190 all scenarios", index)] if index else []
    nav += _sibling_pages(run) if index else []
    nav += [("tables", "#tables"), ("figures", "#figures")]
    if leg_note is not None or any(getattr(f, "key", None) == "leg" for f in figures):
        nav.append(("3D leg", "#leg"))
    b: list[Block] = [Nav(tuple(nav)), Heading(1, f"legbench comparison: {run_title(run)}")]
    if sc.get("description"):
        b.append(Para(str(sc["description"])))
    doc, df = result.to_json(), result.frame()
    b.append(Para(sentence(doc, df)))
    airborne = _airborne(df)  # the sentence's rule: without residuals (no contact law) not known to be
    if run.contact_mode == "reference" and _touches(df) and (shared := implicit_note(_infos(run))):
        b.append(Para(shared))
    if run.contact_mode == "native" and _touches(df) and (coef := coefficient_note(_infos(run), run.reference)):
        b.append(Para(coef))
    if run.profile != "matched" and airborne:
        b.append(Para(_free_space_steps(result)))
    for n in result.notes:
        b.append(Para(n, warn=True))
    for bk in result.run.backends.values():
        for w in bk.info.get("warnings") or ():  # each begins with the backend's name (run.backend_info)
            b.append(Para(str(w), warn=True))
    b.append(Heading(2, "Settings", "tables"))
    b.append(_scenario_table(result))
    b += _backend_tables(result)
    if result.pairs:
        b.append(Heading(2, "Deviation from the reference"))
        skip = _from_skip(run)
        legend = "; ".join(why for _, _, why in BANDS)
        b.append(
            _pair_table(
                result,
                "sim_error_pct",
                f"Simulation error % = max|x - x_ref| / max|x_ref| x 100{skip} "
                f"(colours: the scenario's limits where it sets them, else {legend}; hover a cell for the largest "
                "deviation's size and time)",
                False,
                doc,
                df,
            )
        )
        b.append(_pair_table(result, "rms", f"RMS deviation{skip}", True))
        b.append(_maxdev_table(result))
        lags = [p for p in result.pairs if p.lag is not None]
        if lags:
            b.append(
                Table(
                    ("backend", "vs", "lag [ms]", "samples", "correlation", "removed [ms]", "note"),
                    tuple(
                        (
                            p.backend,
                            p.reference,
                            num(p.lag.seconds * 1e3),
                            num(p.lag.samples),
                            num(p.lag.correlation),
                            num(p.lag_removed * 1e3),
                            p.lag.note,
                        )
                        for p in lags
                        if p.lag is not None
                    ),
                    "Constant time lag by cross-correlation (> 0: the backend is late)",
                )
            )
    b.append(Heading(2, "Steady state and analytic force check"))
    if checks_note is not None:
        b.append(checks_note)
    saturated = [LABELS[i] for i in range(6, 9) if result.pairs and all(p.held[i] for p in result.pairs)]
    if saturated:  # a commanded force the torque limits cannot give: the ground force is what they hold
        verb = "sits at its torque limit" if len(saturated) == 1 else "sit at their torque limits"
        b.append(Para(f"{_names(saturated)} {verb} throughout in every backend compared (held): "
                      "the controller asks for more than the limits give, so the ground force below is what the "
                      "saturated torques hold at the leg's pose, not the commanded one."))  # fmt: skip
    b.append(_steady_table(result))
    if any(r.n_contact for r in result.residuals.values()):
        b.append(Heading(2, "Contact-law residuals"))
        if checks_note is not None:
            b.append(checks_note)
        b.append(_residual_table(result))
    if result.split and not airborne:  # the foot in the air: no contact part to split off (it is 0 throughout)
        b.append(
            Heading(2, f"Contact model vs integration (with {result.split_run.label if result.split_run else ''})")
        )
        b.append(_split_table(result, "rms", df))
        b.append(_split_table(result, "pct", df))
    b.append(Heading(2, "Figures", "figures"))
    b.append(
        Para(
            "Drag to zoom (double-click to reset), hover for values; the rows of a figure share their time axis, "
            "except in the focus on transients (one window of its own per row)."
        )
    )
    if no_ground_force(result):
        b.append(Para("No figures of the ground force: every backend's is 0 at every sample (the foot never touches "
                      "the ground)."))  # fmt: skip
    b.extend(figures)
    if leg_note is not None:
        b += [Heading(3, "3D leg view", "leg"), leg_note]
    if index:
        b.append(Nav((("\u2190 all scenarios", index), ("top", "#"))))
    return b


def _assets_for(run_dir: Path) -> Path:
    """The tree's assets directory when the run directory sits in a results tree (its parent holds the tree's
    index, report.html, and the assets), else its own: a run never loads, or writes, files outside itself
    because of what happens to lie beside it (other runs in a plain folder, another tool's /tmp/assets)."""
    shared = run_dir.parent / ASSETS
    if (run_dir.parent / "report.html").is_file() and (shared / PLOTLY_JS).is_file():
        return shared
    return run_dir / ASSETS


def write_report(
    run_dir: str | Path,
    result: ComparisonResult | None = None,
    *,
    assets: str | Path | None = None,
    index: str | None = None,
    **compare_kwargs: Any,
) -> ReportFiles:
    """Write metrics.json, report.md and report.html into a run directory.

    Everything is read and rendered first; only then are the assets, metrics.json and the two pages put in
    place, so a malformed run directory leaves nothing behind (no assets/, no half-written report).

    Args:
        run_dir: the run directory.
        result: a comparison already computed for it (else :func:`legbench.compare.compare`
            is called with ``compare_kwargs``).
        assets: directory for plotly.min.js and legbench.js (default: the tree's ``assets/`` beside the
            run directory when it exists, else ``run_dir/assets``); written there if absent.
        index: relative URL of the tree's index for the back link (default: ``../report.html`` when it exists).
        **compare_kwargs: passed to :func:`legbench.compare.compare` (log, lag, all_pairs, ...).

    Returns:
        The files written.

    Raises:
        ResultsError: the run directory is missing or malformed.
    """
    tag = _tag()
    try:
        staged = _stage_report(Path(run_dir), result, assets, index, tag, compare_kwargs)
    except BaseException:
        _discard([Path(run_dir)], tag)
        raise
    _commit([staged])
    return staged.files


@dataclass(frozen=True)
class _Staged:
    """A run report rendered into staged files beside their final names, not yet in place.

    Attributes:
        files: the files as they will be once committed.
        moves: (staged file, final file) pairs, metrics.json first, report.html last.
    """

    files: ReportFiles
    moves: tuple[tuple[Path, Path], ...]


#: The files a run report writes into its run directory (and the index into the tree's root).
_PAGE_FILES = ("metrics.json", "report.md", "report.html")


def _tag() -> str:
    """The suffix of this command's staged files (the parent's PID, also when workers render)."""
    return str(os.getpid())


def _discard(dirs: Sequence[Path], tag: str) -> None:
    """Remove the staged files of an aborted report (those rendered by workers that finished, too)."""
    discard_staged([d / name for d in dirs for name in _PAGE_FILES], tag)


def _stage_report(
    path: Path, result: ComparisonResult | None, assets: str | Path | None, index: str | None, tag: str,
    compare_kwargs: Mapping[str, Any],
) -> _Staged:  # fmt: skip
    """Read and measure a run directory and render its report into staged files (nothing in place yet)."""
    res = result if result is not None else compare(path, **compare_kwargs)
    metrics_doc = metrics_text(res.to_json())
    adir = Path(assets) if assets is not None else _assets_for(path)
    if index is None and (path.parent / "report.html").is_file() and path.parent != path:
        index = "../report.html"
    arrays = Arrays()
    figures = run_figures(res, arrays)
    blocks = _blocks(res, figures, index)
    markdown = to_markdown(blocks)
    html = to_html(blocks, f"legbench: {run_title(res.run)}", relpath(adir, path), arrays)
    md, page, metrics = path / "report.md", path / "report.html", path / "metrics.json"
    moves = (stage_text(metrics, metrics_doc, tag), stage_text(md, markdown, tag), stage_text(page, html, tag))
    logger.info("rendered %s and %s (%d figures)", md, page, len(figures))
    return _Staged(ReportFiles(metrics, md, page, tuple(f.key for f in figures), adir), moves)


def _commit(
    staged: Sequence[_Staged], progress: Progress | None = None, then: Sequence[tuple[Path, Path]] = ()
) -> None:
    """Put rendered reports in place: the assets they load, then each page's files (one rename each), the
    static figures of earlier versions removed, then the staged files ``then`` (a tree's index); ``progress`` is
    called with each page once it is in place. A failure (a full disk writing the assets) leaves no staged file
    behind: what was not put in place is removed."""
    try:
        for adir in dict.fromkeys(st.files.assets for st in staged):
            write_assets(adir)
        for st in staged:
            path = st.files.html.parent
            figs = path / "figures"
            for old in figs.glob("*.png") if figs.is_dir() else ():
                old.unlink()  # the static figures of earlier versions
            if figs.is_dir() and not any(figs.iterdir()):
                figs.rmdir()
            commit_staged(st.moves)
            if progress is not None:
                progress(st.files.html)
        commit_staged(then)
    except BaseException:
        for tmp, _ in [*(m for st in staged for m in st.moves), *then]:
            with contextlib.suppress(OSError):
                tmp.unlink()  # already renamed into place, or never written: nothing there
        raise


#: One piece of a page for :func:`write_page`: a heading (``"## text"``), a paragraph (any
#: other text) or a table ``(caption, header, rows)`` of text cells.
PageItem = str | tuple[str, Sequence[str], Sequence[Sequence[str]]]


def _page_blocks(items: Sequence[PageItem]) -> list[Block]:
    blocks: list[Block] = []
    for item in items:
        if isinstance(item, str):
            level = len(item) - len(item.lstrip("#"))
            blocks.append(Heading(level, item[level:].strip()) if level else Para(item))
        else:
            caption, header, rows = item
            blocks.append(Table(tuple(header), tuple(tuple(r) for r in rows), caption))
    return blocks


def page_markdown(items: Sequence[PageItem]) -> str:
    """The Markdown of a page of headings, paragraphs and tables (see :data:`PageItem`)."""
    return to_markdown(_page_blocks(items))


def write_page(out_dir: str | Path, stem: str, title: str, items: Sequence[PageItem]) -> tuple[Path, Path]:
    """Write ``out_dir/stem.md`` and ``out_dir/stem.html`` (self-contained) from headings, paragraphs and
    tables (see :data:`PageItem`), in the same style as the run reports; returns both paths."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    blocks = _page_blocks(items)
    md, page = out / f"{stem}.md", out / f"{stem}.html"
    atomic_write_text(md, to_markdown(blocks))
    atomic_write_text(page, to_html(blocks, title))
    return md, page


# --------------------------------------------------------------------------- #
# Index of a results tree


@dataclass(frozen=True)
class _Entry:
    """One run directory as the index sees it."""

    dir: Path
    label: str  # the run directory's name: unique in a tree (a profile's runs share the scenario label)
    name: str
    profile: str
    mode: str
    meta: Mapping[str, Any]  # metrics.json without its rows
    tolerances: Mapping[str, Any]
    df: pd.DataFrame
    has_page: bool  # the run has a report.html to link to
    infos: Mapping[str, Mapping[str, Any]]  # backend -> its info in run.json (settings as used)
    made_by: str = "of no recorded commit"  # the legbench commit that made the run, as the index says it


def _entries(dirs: Sequence[Path], metrics_files: Mapping[Path, Path] | None = None,
             pages: Sequence[Path] = ()) -> list[_Entry]:  # fmt: skip
    """The index's view of each run directory. ``metrics_files``: a metrics.json to read instead of the
    directory's own (the staged one of a report not yet in place); ``pages``: directories whose report.html
    is about to be put in place."""
    out = []
    for d in dirs:
        mfile = (metrics_files or {}).get(d, d / "metrics.json")
        if mfile.is_file():
            meta, df = read_metrics(mfile)
        else:
            res = compare(d)
            meta, df = res.to_json(), res.frame()
        run_meta = read_meta(d)
        sc = run_meta["scenario"]
        out.append(
            _Entry(
                d,
                d.name or str(meta.get("scenario", "")),
                str(sc["name"]),
                profile_of(run_meta),
                str(meta.get("contact_mode", "native")),
                meta,
                tolerances_of(run_meta),
                df,
                d in pages or (d / "report.html").is_file(),
                {str(b): dict(v.get("info") or {}) for b, v in (run_meta.get("backends") or {}).items()},
                _commit_text((run_meta.get("versions") or {}).get("legbench_commit")),
            )
        )
    return out


def _task_blocks(entries: Sequence[_Entry]) -> list[Block]:
    """Per task: one sentence per run, then one table of simulation error % grouped by profile and contact."""
    header = ("run", "profile", "contact", "backend", "vs", *LABELS)
    blocks: list[Block] = []
    nan = math.nan
    for name in dict.fromkeys(e.name for e in entries):
        runs = sorted(
            (e for e in entries if e.name == name),
            key=lambda e: (_PROFILE_ORDER.get(e.profile, 9), _MODE_ORDER.get(e.mode, 9), e.label),
        )
        blocks.append(Heading(2, name, f"task-{name}"))
        rows: list[tuple[str, ...]] = []
        links: dict[tuple[int, int], str] = {}
        classes: dict[tuple[int, int], str] = {}
        titles: dict[tuple[int, int], str] = {}
        groups: dict[int, str] = {}
        for e in runs:
            href = f"{e.dir.name}/report.html" if e.has_page else ""
            shared = implicit_note(e.infos) if e.mode == "reference" and _touches(e.df) else ""
            if e.mode == "native" and _touches(e.df):  # the run page's sentence on the Coulomb coefficient, here too
                shared = coefficient_note(e.infos, str(e.meta.get("reference", "")))
            blocks.append(Para(f"{e.label} ({e.profile} profile, {e.mode} contact): {sentence(e.meta, e.df)}"
                               + (f" {shared}" if shared else "")))  # fmt: skip
            groups[len(rows)] = f"{e.profile} profile, {e.mode} contact"
            sim = e.df[e.df["metric"] == "sim_error_pct"]
            at = {(str(b), str(r), str(s), str(j), str(m)): float(v) for b, r, s, j, m, v in zip(
                *(e.df[c] for c in ("backend", "reference", "signal", "joint", "metric", "value")), strict=True)
                if m in ("max_abs", "t_max_abs")}  # fmt: skip
            kept = e.df[(e.df["metric"] == "held") & (e.df["value"] == 1.0)]
            tiny = small_peaks(e.df, str(e.meta.get("reference", "")))
            held = set(zip(kept["backend"], kept["reference"], kept["signal"], kept["joint"], strict=True))
            first = len(rows)
            for (backend, ref), g in sim.groupby(["backend", "reference"], sort=False):
                vals = {
                    column_label(s, j): (s, j, float(v))
                    for s, j, v in zip(g["signal"], g["joint"], g["value"], strict=True)
                }
                r = len(rows)
                cells = []
                for c, lab in enumerate(LABELS):
                    s, j, v = vals.get(lab, (SIGNAL_OF[c], lab[-1], math.nan))
                    kept_here = (backend, ref, s, j) in held
                    small = tiny.get((s, j)) if str(ref) == str(e.meta.get("reference", "")) else None
                    key = (str(backend), str(ref), s, j)
                    text, cls, title = _sim_cell(
                        v,
                        s,
                        j,
                        e.tolerances,
                        kept_here,
                        small,
                        e.meta,
                        str(backend),
                        at.get((*key, "max_abs"), nan),
                        at.get((*key, "t_max_abs"), nan),
                        digits=3,
                    )
                    cells.append(text)
                    if cls:
                        classes[(r, 5 + c)], titles[(r, 5 + c)] = cls, title
                rows.append((e.label, e.profile, e.mode, str(backend), str(ref), *cells))
            if len(rows) == first:
                rows.append(
                    (e.label, e.profile, e.mode, "-", str(e.meta.get("reference", "")), *("n/a" for _ in LABELS))
                )
            if href:
                for i in range(first, len(rows)):
                    links[(i, 0)] = href
        blocks.append(
            Table(
                header,
                tuple(rows),
                f"{name}: simulation error % (backend x signal component"
                + "".join(
                    sorted(
                        {
                            f"; from t = {num(float(e.meta['skip']))} s (the scenario's skip)"
                            for e in runs
                            if float(e.meta.get("skip") or 0.0) > 0.0
                        }
                    )
                )  # fmt: skip
                + ")",
                links,
                classes,
                titles,
                groups,
            )
        )
    return blocks


def write_index(root: str | Path) -> IndexFiles:
    """Write ROOT/report.html and ROOT/report.md for a tree of run directories.

    Scenarios are grouped by task, each task's runs ordered by profile and
    contact mode, each with one sentence on what differs most and why, and one
    table of simulation error % (backend x signal component) coloured against
    the scenario's ceilings or :data:`BANDS`; run names link to their reports.
    Numbers come from each directory's metrics.json (computed in memory if
    absent). Backends that failed are listed with their reason; verification
    and calibration are collapsed to counts.

    Raises:
        ResultsError: ROOT is missing or holds no run directory.
    """
    root = Path(root)
    blocks, dirs = _index_blocks(root)
    check_index_pages(root)
    md = root / "report.md"
    atomic_write_text(md, to_markdown(blocks))
    page = root / "report.html"
    atomic_write_text(page, to_html(blocks, INDEX_TITLE))
    return IndexFiles(page, md, tuple(dirs))


def _index_blocks(root: Path, metrics_files: Mapping[Path, Path] | None = None,
                  pages: Sequence[Path] = ()) -> tuple[list[Block], list[Path]]:  # fmt: skip
    """The blocks of the index of ``root`` and the run directories in it (reads everything, writes nothing;
    ``metrics_files`` and ``pages`` as for :func:`_entries`)."""
    dirs = list(run_dirs(root).values())
    entries = _entries(dirs, metrics_files, pages)
    problems: list[tuple[str, ...]] = []
    for e in entries:
        for bname, b in (e.meta.get("backends") or {}).items():
            if b.get("status") != "ok":
                problems.append((e.label, bname, str(b.get("status")), str(b.get("reason") or "")))
    tasks = list(dict.fromkeys(e.name for e in entries))
    series, aside = _series(entries)
    legend = "; ".join(why for _, _, why in BANDS)
    limits = any(e.tolerances.get("max_sim_error_pct") for e in entries)
    colours = (f"Colours: the scenario's limits (comparison.tolerances.max_sim_error_pct) where it sets them, else "
               f"{legend}." if limits else f"Colours: {legend} (no scenario here sets its own limit).")  # fmt: skip
    blocks: list[Block] = [
        Heading(1, INDEX_TITLE),
        Nav(tuple((t, f"#task-{t}") for t in tasks)),
        Para(
            "Simulation error % = max_t |x_a - x_ref| / max_t |x_ref| x 100 per signal component, each backend "
            "against its scenario's reference backend (n/a: the reference signal is zero, or missing). "
            + _reference_text(series)
            + colours
            + " Hover a cell for its exact value; run names link to their reports."
        ),
    ]
    blocks.append(colour_key(limits))
    studies = _read_studies(root)
    if (made := provenance(entries, studies)) is not None:
        blocks.append(made)
    blocks += _study_blocks(root, studies)
    if problems:
        blocks.append(Heading(2, "Backends that did not run"))
        blocks.append(Table(("scenario", "backend", "status", "reason"), tuple(problems)))
    blocks += _task_blocks(entries)
    if aside:
        blocks.append(Para(
            f"Left out of the tables across runs below: {', '.join(aside)}, each one of several runs of a scenario in "
            "one profile and contact mode (the tables take the one under the tree's own name for them, the "
            "scenario's name with __<profile> and __reference, where there is one); listed in its task's table above."
        ))  # fmt: skip
    blocks += _step_blocks(series)
    blocks += _profile_blocks(series)
    blocks += _bench_blocks(root)
    return blocks, dirs


#: A study found in a tree: its :data:`STUDIES` entry, its JSON file, and that file's header and rows.
_FoundStudy = tuple[tuple[str, str, str, str, tuple[str, ...], str], Path, dict[str, Any], list[dict[str, Any]]]


def _read_studies(root: Path) -> list[_FoundStudy]:
    """The verification and calibration studies under ``root``, each profile's, read once for the index's
    provenance line and its study tables, in :data:`STUDIES` then :data:`PROFILES` order."""
    found: list[_FoundStudy] = []
    for spec, folder in itertools.product(STUDIES, PROFILES):
        path = study_dir(root, spec[0], folder) / spec[1]
        if path.is_file():
            found.append((spec, path, *read_study(path, spec[3])))
    return found


def provenance(entries: Sequence[_Entry], studies: Sequence[_FoundStudy]) -> Para | None:
    """Which legbench commits made the tree's runs (run.json's ``versions.legbench_commit``) and its verification and
    calibration studies (their JSON's, :func:`_read_studies`): one sentence naming the commit where one made them
    all, else each commit with what it made, as a warning (a tree mixing commits compares the results of different
    code: a reviewer read a tree 41 commits behind its checkout). None for an empty tree."""
    made: dict[str, list[str]] = {}
    for e in entries:  # each run's run.json, as the index read it
        made.setdefault(e.made_by, []).append(e.dir.name)
    for _, path, doc, _ in studies:
        commit = (doc.get("versions") or {}).get("legbench_commit")
        made.setdefault(_commit_text(commit), []).append(path.parent.name)
    if not made:
        return None
    if len(made) == 1:
        (commit,) = made
        return Para(f"Made by legbench {commit}: every run and study this index lists.")
    parts = "; ".join(f"{commit}: {', '.join(names)}" for commit, names in made.items())
    return Para(f"Made by {len(made)} legbench versions, so its tables compare the results of different code: "
                f"{parts}. `make compare` remakes the tree at one.", warn=True)  # fmt: skip


def _commit_text(commit: object) -> str:
    """run.json's ``legbench_commit`` as the index says it: ``commit 1a2b3c4d5e6f`` (with `` (uncommitted
    changes)`` where it says so), or ``of no recorded commit`` (an installed wheel, an older file)."""
    if not isinstance(commit, str) or not commit:
        return "of no recorded commit"
    sha, _, rest = commit.partition(" ")
    return f"commit {sha[:12]}" + (f" {rest}" if rest else "")


def _series(entries: Sequence[_Entry]) -> tuple[list[_Entry], list[str]]:
    """One run per scenario, profile and contact mode for the tables across runs (the step table, the profiles
    side by side, the reference's description), and the labels of the others: where several runs share those, the
    one under the tree's own name for them (:func:`~legbench.results.run_label`: ``effort__engine-defaults``),
    else none of them. A user's run of the effort task kept beside ``make compare``'s as ``myrun`` took the effort
    rows of the profile table (its Fn for pinocchio's, n/a for the backends it did not run)."""
    groups: dict[tuple[str, str, str], list[_Entry]] = {}
    for e in entries:
        groups.setdefault((e.name, e.profile, e.mode), []).append(e)
    kept: set[str] = set()  # labels: unique in a tree
    for (name, profile, mode), group in groups.items():
        own = run_label(name, profile, mode)
        kept |= {e.label for e in group if len(group) == 1 or e.label == own}
    return [e for e in entries if e.label in kept], [e.label for e in entries if e.label not in kept]


def _reference_text(entries: Sequence[_Entry]) -> str:
    """What the reference backend ("vs pinocchio") is: the scenarios' ``comparison.reference``, with its step and
    integrator per profile from run.json; not ground truth."""
    seen: dict[str, dict[str, str]] = {}
    computed: dict[str, str] = {}  # what computes the reference's dynamics, where not the engine's own stepper
    for e in entries:
        ref = str(e.meta.get("reference", ""))
        info = e.infos.get(ref)
        if ref and info and e.mode == "native":
            step, integ = _step_text(info)
            seen.setdefault(ref, {}).setdefault(e.profile, f"{integ} at {step} per 1 ms control tick")
            if isinstance(info.get("dynamics"), str):
                computed.setdefault(ref, info["dynamics"])
    if not seen:
        return ""
    parts = []
    for ref, by in seen.items():
        order = sorted(by, key=lambda p: _PROFILE_ORDER.get(p, 9))
        dynamics = f"; dynamics: {computed[ref]}" if ref in computed else ""
        if len(order) > 1 and len(set(by.values())) == 1:
            parts.append(f"{ref} ({by[order[0]]} in every profile{dynamics})")
        else:
            parts.append(f"{ref} ({', '.join(f'{by[p]} in the {p} profile' for p in order)}{dynamics})")
    said = "; ".join(parts)
    return (
        f"The reference ('vs' column) is the backend each scenario names as its comparison.reference, run with its "
        f"own settings: {said}. It is not ground truth: 'simulation error' is a difference from it, and it has a "
        "step error of its own (see 'How each backend integrates'). "
    )


def _step_text(info: Mapping[str, Any]) -> tuple[str, str]:
    """(step, integrator) of a backend's run.json info: ``50 us x 20`` per control period, or ``adaptive``;
    the integrator's name with its solver where the backend names one (Drake's contact approximation)."""
    dt, n = info.get("dt"), info.get("sub_steps")
    if isinstance(dt, int | float) and dt > 0:
        step = f"{num(dt * 1e6, 3)} us" if dt < 1e-3 else f"{num(dt * 1e3, 3)} ms"
        step += f" x {n}" if isinstance(n, int) and n > 1 else ""
    else:
        step = "adaptive"
    name = _integrator_text(info)
    solver = info.get("solver")
    return step, f"{name}, {solver}" if isinstance(solver, str) else name


def _integrator_text(info: Mapping[str, Any]) -> str:
    """A backend's integrator as its run.json info names it (``integrator``), else its declared family marked as
    such: PyBullet has no integrator setting (Bullet's step is semi-implicit Euler) and declares only
    ``integrator_family: euler``, which the step table showed as if it were a setting the settings table left blank."""
    if info.get("integrator"):
        return str(info["integrator"])
    family = info.get("integrator_family")
    return f"{FAMILY_TEXT.get(str(family), family)} (declared family; no integrator setting)" if family else "-"


def _steps(entries: Sequence[_Entry]) -> dict[str, dict[str, tuple[str, str]]]:
    """backend -> profile -> (step, integrator) of its native-contact runs (``varies by task`` where they
    differ)."""
    cells: dict[str, dict[str, tuple[str, str]]] = {}
    for e in entries:
        if e.mode != "native":
            continue
        for backend, info in e.infos.items():
            if info:
                mine, seen = _step_text(info), cells.setdefault(backend, {})
                old = seen.setdefault(e.profile, mine)
                if old != mine:  # tasks set it differently
                    seen[e.profile] = (old[0] if old[0] == mine[0] else "varies by task",
                                       old[1] if old[1] == mine[1] else "varies by task")  # fmt: skip
    return cells


def _step_blocks(entries: Sequence[_Entry]) -> list[Block]:
    """How each backend integrated, per profile (native contact): the step, the sub-steps per control period
    and the integrator, from each run's run.json, so a difference can be read against the steps that made it
    (the reference carries its own step error too)."""
    cells = _steps(entries)
    if not cells:
        return []
    profiles = sorted({p for c in cells.values() for p in c}, key=lambda p: _PROFILE_ORDER.get(p, 9))
    header = ("backend", *(f"{h} ({p})" for p in profiles for h in ("step per control tick", "integrator")))
    rows = tuple((b, *(x for p in profiles for x in c.get(p, ("-", "-")))) for b, c in cells.items())
    return [
        Heading(2, "How each backend integrates"),
        Para(
            "Native contact, from each run's run.json: the engine's step (x the sub-steps per control period) "
            "and its integrator. Differences between backends in free space are their integrators' and steps' "
            "errors as much as the engines'; the reference's own step error is one of them."
        ),
        Table(header, rows, "step and integrator per backend and profile"),
    ]


def _profile_blocks(entries: Sequence[_Entry]) -> list[Block]:
    """What configuration costs: each scenario's native-contact runs in the ``matched`` and
    ``engine-defaults`` profiles side by side (largest joint-angle error %, steady ground force)."""
    by_key = {(e.name, e.profile): e.df for e in entries if e.mode == "native"}
    by_meta = {(e.name, e.profile): e.meta for e in entries if e.mode == "native"}
    names = [
        n
        for n in dict.fromkeys(e.name for e in entries)
        if (n, "engine-defaults") in by_key and (n, "matched") in by_key
    ]
    if not names:
        return []
    kept = [
        b
        for b, c in _steps(entries).items()
        if "matched" in c and c["matched"] == c.get("engine-defaults") and "varies by task" not in c["matched"]
    ]
    pocs: dict[str, dict[str, str]] = {}  # backend -> profile -> its point of contact (metrics.json)
    for en in entries:
        if en.mode == "native":
            for b, entry in (en.meta.get("backends") or {}).items():
                if isinstance(entry, Mapping) and entry.get("contact_poc"):
                    pocs.setdefault(str(b), {})[en.profile] = str(entry["contact_poc"])
    moved = [b for b in kept if len(set(pocs.get(b, {}).values())) > 1]
    same = (
        f" Here {_names(kept)} {'keeps' if len(kept) == 1 else 'keep'} the same step and integrator in both "
        "profiles (see the step table above)"
        + (f"; {_names(moved)} {'takes' if len(moved) == 1 else 'take'} the point of contact at the sphere centre "
           "in engine-defaults (the lab's own simplification in its custom model), which moves its contact tasks' "
           "numbers" if moved else "")
        + "."
        if kept
        else ""
    )  # fmt: skip
    rows: list[tuple[str, ...]] = []
    left_out: set[tuple[str, str]] = set()  # (scenario, joint) of a q component the headline leaves out too
    for name in names:
        cells: dict[str, dict[str, tuple[str, str]]] = {}
        for prof in ("matched", "engine-defaults"):
            df = by_key[(name, prof)]
            ref = str(by_meta[(name, prof)].get("reference", ""))
            small = _small_q(df, ref)
            left_out |= {(name, j) for j in small}
            entries_of = by_meta[(name, prof)].get("backends") or {}
            for backend, g in df.groupby("backend", sort=False):
                q = g[(g["metric"] == "sim_error_pct") & (g["signal"] == "q") & (g["reference"] == ref)
                      & ~g["joint"].isin(small)]  # fmt: skip
                q = q[q["value"].notna()]
                fz = g[(g["metric"] == "steady_mean") & (g["signal"] == "force") & (g["joint"] == "z")]["value"]
                top = q.loc[q["value"].idxmax()] if len(q) else None
                entry = entries_of.get(backend)
                speed = entry.get("steady_qd_max") if isinstance(entry, Mapping) else None
                fn = num(float(fz.iloc[0]), 4) if len(fz) else num(math.nan)
                # in contact (an airborne foot's 0 N is no mean to qualify) with a joint moving in the window
                moving = isinstance(speed, (int, float)) and speed >= STATIC_QD and len(fz) > 0 and fz.iloc[0] > FN_MIN
                cells.setdefault(str(backend), {})[prof] = (
                    f"{num(float(top['value']), 3)} (q{top['joint']})" if top is not None else num(math.nan),
                    f"{fn} (moving: max |qd| {num(float(speed or 0.0), 2)} rad/s)" if moving else fn,
                )
        for backend, by_prof in cells.items():
            m = by_prof.get("matched", (num(math.nan), num(math.nan)))
            e = by_prof.get("engine-defaults", (num(math.nan), num(math.nan)))
            rows.append((name, backend, m[0], e[0], m[1], e[1]))
    return [
        Heading(2, "Profiles side by side: what configuration costs"),
        Para(
            "Native contact. 'matched': each engine configured to the spec's physics as faithfully as it allows; "
            "'engine-defaults': the engine's own solver and contact defaults at one step per 1 ms control period, "
            "with Kp, Kd and mu set through its own parameters the way its users usually do (not always in the "
            "spec's units: an engine's parameter may be per unit of constraint mass), a few choices the engine "
            "leaves open made by legbench, and some model settings held in both profiles that are not the engine's "
            "defaults (a compiler option that sets the constraint mass a raw contact parameter is per unit of, stiff "
            "joint limits, link damping and a joint-speed clamp left off): docs/contact_mapping.md lists them, and "
            "the units, per engine, and each run's settings table shows them. "
            "A difference between the two columns is the settings', not the engine's." + same
        ),
        Table(
            (
                "scenario",
                "backend",
                "max q error % (matched)",
                "max q error % (engine-defaults)",
                "steady Fn [N] (matched)",
                "steady Fn [N] (engine-defaults)",
            ),
            tuple(rows),
            "Largest joint-angle simulation error % against the scenario's reference backend in the same profile "
            "(the joint it is in; as in the sentences, a joint whose reference peak is under "
            f"{num(SMALL_PEAK * 100.0)} % of the largest joint's is left out"
            + (
                ": " + ", ".join(f"{n}'s q{j}" for n, j in sorted(left_out)) + ", on the task's own table"
                if left_out
                else ""
            )
            + "), and the steady normal ground force (mean over the steady window; 'moving' where a joint moves at "
            f"{num(STATIC_QD)} rad/s or more in that window, so the mean is no static force: the task's page gives "
            "no analytic check there)",
        ),
    ]


def _small_q(df: pd.DataFrame, ref: str) -> set[str]:
    """Joints whose reference peak of q is under :data:`SMALL_PEAK` of the largest joint's (the effort task's
    q1, 0.004 rad beside 1.26 rad): their simulation error % is a small deviation over a near-zero peak, left
    out of the headline (:func:`sentence`) and of the profiles' table alike."""
    return {j for s, j in small_peaks(df, ref) if s == "q"}


#: Study outputs the index shows when present under the results root, each once per profile, in the folder
#: ``results.study_dir`` gives it: (study, file, heading, record list key, columns, caption).
STUDIES: tuple[tuple[str, str, str, str, tuple[str, ...], str], ...] = (
    (
        "verification",
        "verification.json",
        "Verification against closed-form answers",
        "checks",
        ("case", "backend", "variant", "quantity", "unit", "measured", "expected", "error", "tolerance", "pass"),
        "legbench verify: each case, backend and integrator against its closed-form answer "
        "(legbench/studies/verify.py)",
    ),
    (
        "calibration",
        "calibration.json",
        "Contact calibration",
        "rows",
        (
            "backend",
            "Kp",
            "k_eff",
            "Kd",
            "c_eff",
            "mu_s",
            "Fn",
            "Ft",
            "creep",
            "jitter",
            "creep_law",
            "c_tangential",
            "status",
            "against_spec",
            "note",
        ),
        "legbench calibrate-contact: effective normal stiffness k_eff from the rests under two pushes (20 N, 40 N), "
        "damping c_eff from the step's pressing-in transient, creep under a tangential load Ft below mu_s Fn (half "
        "of it commanded through the sphere centre's Jacobian: Ft is what reached the ground, a little less "
        "where an engine's force acts below the centre, all of it where the law acts at the centre): the point of "
        "contact's net slip over the last 0.2 s divided by 0.2 s, jitter the RMS of its slip velocity about that "
        "mean, beside the spec (Kp, Kd, mu_s) and the law's own creep v_th Ft / (mu_s Fn); c_eff fitted through the "
        "chord between the rests (n/a for a rigid contact, and where the chord misses the origin by more than 1 % of "
        "the 20 N rest's force: a normal law not linear in the depth); c_tangential = Ft / creep (inf: the foot "
        "sticks, a creep below 1e-6 mm/s); calibration.json holds SI units (creep, jitter, creep_law in m/s); a note "
        "'known: ...' is the backend's closed form of a stiffness off Kp, a damping off Kd or a creep off the law's, "
        "given only where it meets the measurement; status against the spec: as specified (k_eff within 0.1 % of "
        "Kp, c_eff within 1 % of Kd, creep within 1 % of the law's), explained (each value off it has its "
        "backend's closed form, or is a rigid contact's n/a, or a Coulomb foot that sticks where the law creeps), "
        "not explained (against_spec names the value), failed",
    ),
)


#: Units of the study tables' columns, shown in their headers (a column of
#: :data:`~legbench.results.SHOWN_SCALE` is scaled to its unit).
STUDY_UNITS = {
    "Kp": "N/m",
    "k_eff": "N/m",
    "Kd": "N s/m",
    "c_eff": "N s/m",
    "Fn": "N",
    "Ft": "N",
    "creep": "mm/s",
    "jitter": "mm/s",
    "creep_law": "mm/s",
    "c_tangential": "N s/m",
}


def _cell(v: Any, scale: float = 1.0) -> str:
    if isinstance(v, bool):
        return "yes" if v else "NO"
    if isinstance(v, int | float):
        x = float(v) * scale
        return ("inf" if x > 0 else "-inf") if math.isinf(x) else num(x, 4)  # inf is a value; n/a is NaN
    return str(v)


def _error_cell(r: Mapping[str, Any]) -> str:
    """A verification row's error, written with the digits that set it apart from its tolerance (an error of
    0.010004 against 0.01 is not shown as 0.01)."""
    e, tol = r.get("error", ""), r.get("tolerance")
    if isinstance(e, bool) or not isinstance(e, int | float) or not isinstance(tol, int | float) or math.isinf(e):
        return _cell(e)
    return num_apart(float(e), (float(tol),))


def _status(r: Mapping[str, Any]) -> str:
    """A check's status: ``pass``, ``fail`` or ``not-applicable`` (files without ``status``: from ``pass``)."""
    status = r.get("status")
    if status in ("pass", "fail", "not-applicable"):
        return str(status)
    return "pass" if r.get("pass") is True else "fail"


#: What a profile's verification tells, beside the other's (the index's paragraph over its table).
PROFILE_VERIFIED = {
    PROFILES[0]: "Its closed forms are the spec's physics as each backend declares it runs them (its integrator "
    "family, the friction shape and coefficient it slides with, its point of contact; a rigid contact expected to "
    "sink by its own regularisation's closed form where it declares one, else not at all, where the spec's spring "
    "would sink Fn/Kp), with these settings chosen to match the spec: a failure "
    "here is the engine's, or its mapping's; a pass says the engine does what it declares, and how far that is "
    "from the spec is in the declarations (the settings tables).",
    PROFILES[1]: "The same closed forms, with each engine at its own defaults (its integrator and step, Kp, Kd and "
    "mu set the engine's usual way), the sliding drag scored against the friction shape, coefficient and point "
    "each run declares: a check that passes matched and fails here is mostly what the defaults and that usual way "
    "cost (a solver's own limit shows in both profiles where the profiles share the solver); each such row's note "
    "gives the engine's own answer where it has been measured (docs/studies.md, section 4).",
}


def _study_blocks(root: Path, studies: Sequence[_FoundStudy]) -> list[Block]:
    """The verification and calibration studies found under ``root`` (:func:`_read_studies`): a count, the table on
    demand (failing checks, and checks whose closed form does not apply to an engine, shown open with their
    notes)."""
    blocks: list[Block] = []
    for (study, name, heading, _, cols, caption), path, doc, records in studies:
        # the study's Markdown and JSON linked as files, not its folder (a static host lists no folder)
        md, js = f"{path.parent.name}/{path.stem}.md", f"{path.parent.name}/{path.name}"
        profile = str(doc.get("profile") or PROFILES[0])  # older files: the one profile legbench ran, matched
        if "pass" not in cols:
            rows = tuple(tuple(_cell(r.get(c, ""), SHOWN_SCALE.get(c, 1.0)) for c in cols) for r in records)
            header = tuple(f"{c} [{STUDY_UNITS[c]}]" if c in STUDY_UNITS else c for c in cols)
            # a calibration row's status against the spec: a deviation without an explanation is a failure to read
            at = cols.index("status") if "status" in cols else -1
            css = {"as specified": "pass", "not explained": "fail", "failed": "fail"}
            marks = {(i, at): css[st] for i, r in enumerate(records) if (st := str(r.get("status"))) in css}
            bad = [str(records[i].get("backend")) for (i, _), v in marks.items() if v == "fail"]
            open_ = f", {len(bad)} not explained or failed ({', '.join(bad)})" if bad else ""
            blocks.append(Heading(2, f"{heading}, {profile} profile: {_rows(len(records), 'backend')} measured"
                                     f"{open_}"))  # fmt: skip
            blocks.append(Details(f"the {_rows(len(records))}", (Table(header, rows, caption, classes=marks),),
                                  "fail" if bad else ""))  # fmt: skip
            blocks.append(Nav(((md, md), (js, js))))
            continue
        status = [_status(r) for r in records]
        shown = {"pass": "yes", "fail": "NO", "not-applicable": "n/a"}
        last = len(cols) - 1
        err, tol = cols.index("error"), cols.index("tolerance")
        rows = tuple(
            tuple(_error_cell(r) if c == err else _cell(r.get(cols[c], "")) for c in range(last)) + (shown[st],)
            for r, st in zip(records, status, strict=True)
        )
        css = {"pass": "pass", "fail": "fail", "not-applicable": "na"}
        classes = {(i, last): css[st] for i, st in enumerate(status)}
        basis = doc.get("tolerance_basis")
        basis = basis if isinstance(basis, Mapping) else {}  # older files: none
        titles = {(i, c): _tolerance_basis(r, basis) for i, r in enumerate(records) for c in (tol, last)}
        failed = [i for i, st in enumerate(status) if st == "fail"]
        na = [i for i, st in enumerate(status) if st == "not-applicable"]
        blocks.append(Heading(2, f"{heading}, {profile} profile: {checks_summary(status)}"))
        scope = f" ({doc['scope']})" if isinstance(doc.get("scope"), str) else ""  # older files: none
        unverified = [p for p in PROFILES if p != profile and not (study_dir(root, study, p) / name).is_file()]
        blocks.append(Para(" ".join([
            f"legbench verify --profile {profile} runs every check with each backend's {profile} settings{scope}.",
            *([PROFILE_VERIFIED[profile]] if profile in PROFILE_VERIFIED else []),
            *([f"The {' and '.join(unverified)} profile's settings are not verified in this tree."] * bool(unverified)),
            "error is |measured - expected| unless the row's note says otherwise (an energy prediction: the largest "
            "gap between the drift curve and its prediction; a one-sided bound: how far past it). Each case's "
            "tolerance is derived below; hover a row's tolerance or pass cell for it and the row's note "
            "(legbench/studies/verify.py).",
        ])))  # fmt: skip
        if basis:
            blocks.append(Details("how each case's tolerance is derived", (Table(
                ("case", "tolerance"), tuple((case, str(text)) for case, text in basis.items()),
                "verification.json's tolerance_basis (the derivations: legbench/studies/verify.py)",
                classes={(k, 1): "text" for k in range(len(basis))}),)))  # fmt: skip
        for which, title, cls in ((failed, "Failing checks", "fail"), (na, "Not applicable: no closed form for this "
                                  "engine's integrator or friction model (the note says which)", "na")):  # fmt: skip
            if which:
                noted = tuple(rows[i] + (note,) for i, note in zip(which, _shortened_notes(records, which),
                                                                    strict=True))  # fmt: skip
                marks = {(k, last): cls for k in range(len(which))}
                marks.update({(k, last + 1): "text" for k in range(len(which))})
                # the hover the paragraph promises, here too: the case's basis (the note has its own column)
                hover = {(k, c): _tolerance_basis({"case": records[i].get("case")}, basis)
                         for k, i in enumerate(which) for c in (tol, last)}  # fmt: skip
                blocks.append(Table((*cols, "note"), noted, title, classes=marks,
                                    titles={key: h for key, h in hover.items() if h}))  # fmt: skip
        table = Table(cols, rows, caption, classes=classes, titles=titles)
        blocks.append(Details(f"all {len(records)} checks", (table,), "fail" if failed else ""))
        blocks.append(Nav(((md, md), (js, js))))
    return blocks


def _shortened_notes(records: Sequence[Mapping[str, Any]], which: Sequence[int]) -> list[str]:
    """The notes of the rows ``which`` as a table of them shows them: where a row's note begins with the same
    explanation as the row above it of the same backend and case (a backend's known deviation, shared by every
    pole of a mode fit, every row of a drag), that part reads "as above" (the rest, the row's own numbers, stays;
    the full note is in the table of all checks and in verification.json)."""
    out: list[str] = []
    prev: Mapping[str, Any] | None = None
    for i in which:
        r = records[i]
        note = str(r.get("note") or "")
        if prev is not None and (prev.get("backend"), prev.get("case")) == (r.get("backend"), r.get("case")):
            above = str(prev.get("note") or "")
            shared = os.path.commonprefix([above, note])
            cut = shared.rfind("; ") if len(shared) < len(note) else len(shared)
            if cut >= 80:  # a shared explanation, not a shared word
                note = "as above" + (note[cut:] if cut < len(note) else "")
        out.append(note)
        prev = r
    return out


def _tolerance_basis(r: Mapping[str, Any], bases: Mapping[str, Any]) -> str:
    """A verification row's hover: how its case's tolerance is derived (``bases``, verification.json's
    ``tolerance_basis``), then the row's own note (its terms and numbers)."""
    basis = str(bases.get(str(r.get("case", "")), ""))
    note = str(r.get("note") or "")
    parts = ([f"tolerance: {basis}"] if basis else []) + ([f"this row: {note}"] if note else [])
    return "; ".join(parts)


def _bench_blocks(root: Path) -> list[Block]:
    """The latest `legbench bench` figures (results/bench/bench.json beside the results root), if any."""
    path = next((p for p in (root / "bench" / "bench.json", root.parent / "bench" / "bench.json") if p.is_file()), None)
    if path is None:
        return []
    doc, results = read_study(path, "results")
    try:
        rows = []
        for r in results:
            if r.get("status") != "ok":
                rows.append((r["task"], r["backend"], r.get("status", "?"), "", "", "", "", "", ""))
                continue
            mem = r["mem_peak_bytes"] / r["series_bytes"] if r.get("mem_peak_bytes") and r.get("series_bytes") else None
            rows.append(
                (
                    r["task"],
                    r["backend"],
                    _cell(r["full_us_per_tick"]["median"]),
                    _cell(r["engine_us_per_tick"]["median"]),
                    _cell(r["harness_us_per_tick"]),
                    _cell(r["overhead_ratio"]["median"]),
                    _cell(r["rtf_full"]),
                    _cell(mem) if mem is not None else "-",
                    "yes" if r.get("replay_identical") else "NO",
                )
            )
    except (ValueError, KeyError, TypeError) as exc:
        raise ResultsError(str(path), f"malformed benchmark output: {exc}") from None
    cols = (
        "task",
        "backend",
        "full [us/tick]",
        "engine only [us/tick]",
        "harness [us/tick]",
        "overhead ratio",
        "RTF",
        "memory / series",
        "replay identical",
    )
    caption = (
        f"legbench bench ({doc.get('created', '')}, {doc.get('machine', {}).get('cpus', '?')} CPUs): medians; "
        "overhead ratio = full run / engine-only replay of the same torques; RTF, the real-time factor: simulated "
        "seconds per wall-clock second of the full run (> 1: faster than real time)"
    )
    return [Heading(2, "Performance"), Details(_rows(len(rows)), (Table(cols, tuple(rows), caption),))]


def _report_page(task: tuple[str, str, dict[str, Any], str]) -> _Staged:
    """One run directory's report rendered into staged files (a top-level function, so a process pool can
    map it)."""
    run_dir, assets, compare_kwargs, tag = task
    return _stage_report(Path(run_dir), None, assets, "../report.html", tag, compare_kwargs)


#: What a report worker imports once when it starts: the page renderer and what it reads with (no engine).
REPORT_PRELOAD = ("legbench.report",)


def write_all(
    root: str | Path, *, jobs: int = 1, progress: Progress | None = None, **compare_kwargs: Any
) -> list[ReportFiles | IndexFiles]:
    """Report a run directory, or every run directory under ``root`` and then the index.

    Read everything first, write after: every run directory is read, measured and rendered (into staged
    files beside the final ones) and the index built before anything is put in place, so one malformed run
    directory (a corrupt log, a hand-edited run.json) leaves every report of the tree, the index and the
    assets as they were, and no staged file behind.

    Args:
        root: a run directory (has run.json) or a tree of them (results/latest).
        jobs: worker processes rendering the run reports (one page per task; 1: this process).
        progress: called with each page's path once it is in place (run reports in order, then the index).
        **compare_kwargs: passed to :func:`legbench.compare.compare`.

    Returns:
        Every :class:`ReportFiles` written, then the :class:`IndexFiles` for a tree.
    """
    root = Path(root)
    if (root / "run.json").is_file():
        files = write_report(root, **compare_kwargs)
        if progress is not None:
            progress(files.html)
        return [files]
    if not root.is_dir():
        raise ResultsError(str(root), "no such results directory")
    if compare_kwargs.get("log") is not None:
        raise ResultsError(str(root), "an imported log belongs to one scenario: pass that scenario's run directory")
    dirs = list(run_dirs(root).values())
    check_index_pages(root)
    tag = _tag()
    tasks = [(str(d), str(root / ASSETS), dict(compare_kwargs), tag) for d in dirs]
    staged: list[_Staged] = []
    try:
        # the workers render pages only: they import the report's modules, not the engines
        with make_executor("local", jobs, preload=REPORT_PRELOAD, tasks=len(tasks)) as ex:  # <= a worker a page
            staged += ex.imap(_report_page, tasks)
        metrics_files = {st.files.html.parent: tmp for st in staged for tmp, final in st.moves
                         if final.name == "metrics.json"}  # fmt: skip
        blocks, _ = _index_blocks(root, metrics_files, [st.files.html.parent for st in staged])
        html = to_html(blocks, INDEX_TITLE)
        index_moves = (stage_text(root / "report.md", to_markdown(blocks), tag),
                       stage_text(root / "report.html", html, tag))  # fmt: skip
    except BaseException:
        _discard([*dirs, root], tag)
        raise
    _commit(staged, progress, index_moves)
    index = IndexFiles(root / "report.html", root / "report.md", tuple(dirs))
    if progress is not None:
        progress(index.html)
    return [*(st.files for st in staged), index]
