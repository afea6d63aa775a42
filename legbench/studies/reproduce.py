"""``legbench reproduce``: the lab report's comparison regenerated in one command.

The lab compared three frameworks: Gazebo (ODE), Simscape Multibody (ode45) and
its own Euler-Lagrange simulation. A *framework file* (default
``scenarios/reproduce.yaml``) says which backend and profile stands for which
framework, which tasks to run and which of the report's tables each task feeds;
nothing here names an engine::

    frameworks:                    # in table order
      - {name: Gazebo, backend: <name>, profile: <one of its profiles>, note: <optional: what it is not>}
    others: matched                # profile of every other backend that runs
    tasks:                         # scenario files, relative to this file
      - {file: effort.yaml, tables: [steady]}     # steady, force, sim_error, switch

Table roles: ``steady`` (the report's table 10, steady |qd| beside the scenario's published rows with the
direction of each foot's slide against its friction, and legbench's table of the steady ground force with the
analytic check h = (J^T)^-1 (tau - G) where each backend's force acts and, for a centre-poc law, the force its
torques hold at the true poc: the source names no table of it), ``force`` (legbench's: the steady Fn, one column
per task), ``switch`` (the combined task as the report saw it: first contact and the torque at the switch to
effort control, beside the scenario's published row) and ``sim_error`` (tasks 1 and 2: the simulation error %
between the framework analogues, each pair once, per joint, after the scenario's ``comparison.skip``, over the
scenario reference's peak as every simulation error % of legbench).

Every task runs once on every backend through :func:`legbench.run.run_many`
(the framework backends with their profile as ``backends.<name>.profile``), into
``OUT/<task>/``: ordinary run directories with their metrics.json and report.
The tables are computed from those directories with :mod:`legbench.metrics`,
printed as Markdown and written to ``OUT/reproduce.{md,html,json}``. A backend
that is missing or fails gets a row saying so; the others go on.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from legbench import backends as registry
from legbench import report, resources, results, run, scenario, yamlfile
from legbench.backends.base import PROFILES, contact_point
from legbench.compare import first_contact
from legbench.exceptions import BackendNotFound, LegbenchError, ScenarioError
from legbench.exitcodes import EXIT_BACKEND_FAILED, EXIT_OK
from legbench.metrics import FRICTION_FLOOR, SLIDE_FLOOR, T_EPS, SteadyState, pair_metrics, reference_peak, steady_state
from legbench.results import Run, load_run
from legbench.scenario import Scenario
from legbench.signals import SLICE

FRAMEWORKS_FILE = resources.scenario("reproduce")
DEFAULT_OUT = Path("results") / "reproduce"
#: What a task can feed: table 10 and the steady force, the steady Fn per task, the simulation error % between the
#: framework analogues, the combined task's contact and switch torque.
ROLES = ("steady", "force", "sim_error", "switch")
#: The pages of a reproduce, beside its run directories in OUT.
PAGES = ("reproduce.md", "reproduce.html", "reproduce.json")


# --------------------------------------------------------------------------- #
# The framework file


@dataclass(frozen=True)
class Framework:
    """A framework of the lab report and the backend (with its profile) that stands for it."""

    name: str
    backend: str
    profile: str
    note: str = ""  # what the analogue is and is not (the page prints it beside the mapping)


@dataclass(frozen=True)
class Task:
    """A scenario file and the tables (:data:`ROLES`) it feeds."""

    file: Path
    tables: tuple[str, ...]


@dataclass(frozen=True)
class Plan:
    """A validated framework file."""

    file: str
    frameworks: tuple[Framework, ...]
    others: str
    tasks: tuple[Task, ...]

    def label(self, backend: str, profile: str | None = None) -> str:
        """Row label of a backend: ``Gazebo: ode (gazebo)`` for a framework analogue, else ``mujoco (matched)``."""
        for fw in self.frameworks:
            if fw.backend == backend:
                return f"{fw.name}: {backend} ({profile or fw.profile})"
        return f"{backend} ({profile or self.others})"


def load_plan(path: str | Path = FRAMEWORKS_FILE) -> Plan:
    """Read and validate a framework file; every error names the file and the key.

    A backend must be one legbench knows (built in or by entry point); its profile
    is checked against the backend's ``profiles`` where the engine is installed
    (elsewhere the run reports the backend missing).

    Each task's scenario is loaded as :func:`scenarios_of` loads it (the frameworks' profiles set), so a task
    that is not a valid scenario is refused here, by ``legbench validate`` too, naming the task's key.

    Raises:
        ScenarioError: unknown key, backend, profile, role, a framework name given twice, a task file that does
            not exist or is not a valid scenario, two tasks of one scenario name (one run directory).
    """
    doc, root = yamlfile.read_yaml(path)
    ctx = yamlfile.YamlContext(str(path), root)
    other = yamlfile.other_file(doc, "a framework file")  # another of legbench's files, given as a framework file
    if other is not None and "frameworks" not in doc:
        raise ctx.error([], other)
    yamlfile.check_keys(ctx, [], doc, ["frameworks", "others", "tasks"], ["frameworks", "tasks"])
    fws = doc["frameworks"]
    if not isinstance(fws, list) or not fws:
        raise ctx.error(["frameworks"], "expected a non-empty list of {name, backend, profile}")
    known = list(dict.fromkeys([*registry.BUILTIN, *registry.available()]))
    frameworks: list[Framework] = []
    for i, fw in enumerate(fws):
        yamlfile.check_keys(ctx, ["frameworks", i], fw, ["name", "backend", "profile", "note"],
                            ["name", "backend", "profile"])  # fmt: skip
        name, backend, profile = (fw[k] for k in ("name", "backend", "profile"))
        note = fw.get("note", "")
        if not isinstance(note, str):
            raise ctx.error(["frameworks", i, "note"], "expected text: what the analogue is and is not")
        if not isinstance(name, str) or not name:
            raise ctx.error(["frameworks", i, "name"], "expected the framework's name")
        if any(f.name == name for f in frameworks):  # the tables' rows and columns are named by it
            raise ctx.error(["frameworks", i, "name"], f"{name!r} names another framework already")
        if backend not in known:
            raise ctx.error(["frameworks", i, "backend"], f"unknown backend {backend!r}; known: {', '.join(known)}")
        if any(f.backend == backend for f in frameworks):
            raise ctx.error(["frameworks", i, "backend"], f"{backend} already stands for another framework")
        try:
            offered = list(registry.get(backend).profiles)
        except BackendNotFound:
            offered = None  # not installed here: the run reports it missing
        if not isinstance(profile, str) or (offered is not None and profile not in offered):
            raise ctx.error(["frameworks", i, "profile"], f"{backend} offers the profiles {', '.join(offered or [])}, "
                                                          f"got {profile!r}")  # fmt: skip
        frameworks.append(Framework(name, backend, profile, note))
    others = doc.get("others", PROFILES[0])
    if others not in PROFILES:
        raise ctx.error(
            ["others"], f"expected one of {', '.join(PROFILES)} (every backend offers them), got {others!r}"
        )
    tdoc = doc["tasks"]
    if not isinstance(tdoc, list) or not tdoc:
        raise ctx.error(["tasks"], "expected a non-empty list of {file, tables}")
    tasks: list[Task] = []
    names: dict[str, int] = {}  # scenario name -> task: each task's run directory is OUT/<name>
    for i, t in enumerate(tdoc):
        yamlfile.check_keys(ctx, ["tasks", i], t, ["file", "tables"], ["file", "tables"])
        if not isinstance(t["file"], str) or not t["file"]:
            raise ctx.error(["tasks", i, "file"], "expected the path of a scenario file, relative to this file")
        file = Path(path).parent / t["file"]
        try:
            found = file.is_file()
        except OSError as exc:  # a name too long, a loop of links: no file can be there
            raise ctx.error(["tasks", i, "file"], f"cannot be a scenario file: {exc.strerror or exc}") from None
        if not found:
            raise ctx.error(["tasks", i, "file"], f"no scenario file {file}")
        roles = t["tables"]
        if not isinstance(roles, list) or not roles:
            raise ctx.error(["tasks", i, "tables"], f"expected a list of {', '.join(ROLES)}")
        for j, r in enumerate(roles):
            if r not in ROLES:
                raise ctx.error(["tasks", i, "tables", j], f"expected one of {', '.join(ROLES)}, got {r!r}")
            if r in roles[:j]:
                raise ctx.error(["tasks", i, "tables", j], f"{r} given twice")
        # the task as reproduce runs it (the frameworks' profiles set), so validate finds what the run would refuse
        sets: dict[str, Any] = {"profile": str(others)}
        sets |= {f"backends.{fw.backend}.profile": fw.profile for fw in frameworks}
        try:
            sc = scenario.load(file, sets)
        except ScenarioError as exc:
            raise ctx.error(["tasks", i, "file"], str(exc)) from None
        if sc.name in names:
            raise ctx.error(["tasks", i, "file"], f"scenario {sc.name!r} is task {names[sc.name]}'s too: both would "
                                                  "run into one directory")  # fmt: skip
        names[sc.name] = i
        tasks.append(Task(file, tuple(roles)))
    return Plan(resources.shown(path), tuple(frameworks), str(others), tuple(tasks))


def scenarios_of(
    plan: Plan, overrides: Mapping[str, Any] | None = None, duration: float | None = None
) -> list[Scenario]:
    """Every task's scenario with the framework backends' profiles set (``backends.<name>.profile``),
    the others' profile as the scenario's ``profile``, ``overrides`` applied, cut to ``duration`` [s]."""
    sets: dict[str, Any] = {"profile": plan.others}
    sets |= {f"backends.{fw.backend}.profile": fw.profile for fw in plan.frameworks}
    out = [scenario.load(task.file, {**sets, **(overrides or {})}) for task in plan.tasks]
    return scenario.shorten_each(out, duration) if duration is not None else out


def backend_names(plan: Plan, others: str | Sequence[str] = "all") -> list[str]:
    """The framework backends (installed or not: a missing one gets its row), then the others:
    ``"all"`` available ones, ``"none"``, or the names given."""
    first = [fw.backend for fw in plan.frameworks]
    if others == "none":
        rest: list[str] = []
    elif others == "all":
        rest = registry.available()
    else:
        rest = registry.resolve(list(others) if not isinstance(others, str) else others)
    return list(dict.fromkeys([*first, *rest]))


# --------------------------------------------------------------------------- #
# The tables


@dataclass(frozen=True)
class Table:
    """One of the report's tables: numbers where a backend ran, text where it did not.

    Attributes:
        key: ``table10``, ``steady_force``, ``steady_fn``, ``sim_error_<task>``, ``switch_<task>``.
        title: heading.
        caption: what the numbers are, with units.
        header: column names.
        rows: each a label, then floats (NaN: not applicable) or a text cell.
    """

    key: str
    title: str
    caption: str
    header: tuple[str, ...]
    rows: tuple[tuple[Any, ...], ...] = field(default=())

    def text_rows(self) -> list[list[str]]:
        return [[_cell(v) for v in r] for r in self.rows]


def _cell(v: Any) -> str:
    if isinstance(v, float | np.floating):
        return "-" if math.isnan(v) else f"{v:.4g}"
    return str(v)


def _json_cell(v: Any) -> Any:
    return None if isinstance(v, float | np.floating) and math.isnan(v) else v


def _published(run_: Run) -> list[tuple[str, Mapping[str, Any]]]:
    """The scenario's published rows (``comparison.published``), each with its label: the source, and its own
    caveat beside it where the scenario gives one."""
    rows = (run_.meta.get("scenario") or {}).get("comparison", {}).get("published") or []
    return [(f"{pub['source']} ({pub['note']})" if pub.get("note") else pub["source"], pub) for pub in rows]


def _status(run_: Run, name: str) -> str | None:
    """None if ``name`` ran to the end in ``run_``, else a sentence saying what happened."""
    if name in run_.traces:
        return None
    st = run_.backends.get(name)
    if st is None:
        return "not run"
    return f"{st.status}: {st.reason or 'no reason given'}"


def _profile(run_: Run, name: str) -> str | None:
    st = run_.backends.get(name)
    info = (st.info if st is not None else None) or {}
    return info.get("profile") if isinstance(info, Mapping) else None


def backend_poc(run_: Run, name: str) -> tuple[str, float]:
    """Where a backend's contact force acted, ``(poc, lift)`` (:func:`~legbench.backends.base.contact_point`): its
    info's ``contact.poc`` and ``contact.lift``, else the scenario's poc."""
    st = run_.backends.get(name)
    return contact_point(st.info if st is not None else None, run_.poc)


def steady_of(run_: Run, name: str) -> SteadyState:
    """The steady state of one backend over the scenario's window, its check at its own poc."""
    poc, lift = backend_poc(run_, name)
    return steady_state(run_.traces[name], run_.steady_window, poc, run_.gravity, lift=lift)


def table10(plan: Plan, run_: Run, names: Sequence[str]) -> Table:
    """Steady |qd| per joint: the scenario's published rows, then each backend with the direction of its foot's
    slide against its friction force (:attr:`~legbench.metrics.SteadyState.slide_cosine`)."""
    rows: list[tuple[Any, ...]] = []
    for source, pub in _published(run_):
        if "qd_abs" in pub:
            rows.append((source, *(float(x) for x in pub["qd_abs"]), ""))
    for n in names:
        label = f"legbench, {plan.label(n, _profile(run_, n))}"
        why = _status(run_, n)
        if why:
            rows.append((label, why, "", "", ""))
            continue
        s = steady_of(run_, n)
        rows.append((label, *np.abs(s.qd).tolist(), s.slide_cosine))
    return Table(
        "table10",
        f"Table 10: steady joint velocities, task {run_.name}",
        f"|mean qd| over the last {run_.steady_window:g} s [rad/s]; the lab report's published rows first. The "
        "law's v_th was fitted to the Simscape row (docs/contact_law.md): the agreement of the law backends at the "
        "true poc with it is by construction, a consistency check, not a validation; the custom-sim row (centre "
        "poc) was not fitted. cos(v, F_t): the cosine between the foot's mean horizontal velocity at its point "
        "of contact and its mean friction force, -1 for a foot creeping against its friction as the law's does, "
        f"towards +1 for one drifting along it; - where the foot moves under {SLIDE_FLOOR:g} m/s or carries under "
        f"{FRICTION_FLOOR:g} N of friction",
        ("source", "|qd1|", "|qd2|", "|qd3|", "cos(v, F_t)"),
        tuple(rows),
    )


def steady_force_table(plan: Plan, run_: Run, names: Sequence[str]) -> Table:
    """Steady ground force, its analytic check h at the point each backend's force acts (the true poc, raised by
    its declared ``contact.lift``, or the sphere centre for a law taking the poc there), and for the latter the
    force its joint torques hold at the true poc."""
    rows: list[tuple[Any, ...]] = []
    for n in names:
        label = plan.label(n, _profile(run_, n))
        why = _status(run_, n)
        if why:
            rows.append((label, why, *[""] * 9))
            continue
        s = steady_of(run_, n)
        check = s.force - s.residual  # the analytic force where its force acts (SteadyState.residual's choice)
        at_true = s.analytic_poc if s.poc_compensation is not None else np.full(3, np.nan)
        poc, lift = backend_poc(run_, n)
        at = poc if lift == 0.0 else f"{poc}, {lift:.3g} y above"
        rows.append((label, at, *s.force.tolist(), *check.tolist(), *at_true.tolist()))
    return Table(
        "steady_force",
        f"Steady ground force and its analytic check, task {run_.name} (legbench's; the source names no table of it)",
        f"means over the last {run_.steady_window:g} s, ground force on the foot in W [N]: measured F; the "
        "analytic check -h with h = (J^T)^-1 (tau - G(q)) at the point the backend's force acts, the poc column's: "
        "the true poc (raised by the fraction of the penetration y it says, where an engine's own contact acts "
        "above the lowest point) or the sphere centre E (J_E, the report's analytic model). For a centre row, "
        "'at true poc' is -h(J_poc): the force the same torques hold at the true poc, in the same pose. It is "
        "not what the law taken at the true poc settles to, whose pose and creep differ (a row of the law "
        "at the true poc shows that)",
        ("backend", "poc", *(f"{at}F{c}" for at in ("", "check ", "at true poc ") for c in "xyn")),
        tuple(rows),
    )


def steady_fn_table(plan: Plan, runs: Sequence[Run], names: Sequence[str]) -> Table:
    """Steady Fn per backend, one column per task."""
    rows: list[tuple[Any, ...]] = []
    for n in names:
        cells: list[Any] = []
        for r in runs:
            why = _status(r, n)
            cells.append(why if why else float(steady_of(r, n).force[2]))
        rows.append((plan.label(n, next((p for r in runs if (p := _profile(r, n))), None)), *cells))
    return Table(
        "steady_fn",
        "Steady normal ground force per task (legbench's; the source names no table of it)",
        "mean Fn over each task's last steady window [N]",
        ("backend", *(f"Fn, {r.name}" for r in runs)),
        tuple(rows),
    )


def sim_error_table(plan: Plan, run_: Run) -> Table:
    """Simulation error % of q between the framework analogues: max |q_a - q_b| over the scenario reference's
    peak (docs/metrics.md: one denominator, so a against b is b against a, and each pair is shown once), every
    ordered pair over b's own peak where the reference did not run."""
    ref = run_.traces.get(run_.reference)
    peak = None if ref is None else reference_peak(ref, run_.skip)
    fws = plan.frameworks
    pairs = [(a, b) for i, a in enumerate(fws) for j, b in enumerate(fws) if (i < j if ref is not None else i != j)]
    rows: list[tuple[Any, ...]] = []
    for a, b in pairs:
        why = _status(run_, a.backend) or _status(run_, b.backend)
        if why:
            missing = a.backend if _status(run_, a.backend) else b.backend
            rows.append((a.name, b.name, f"{missing} {why}", "", ""))
            continue
        pm = pair_metrics(run_.traces[a.backend], run_.traces[b.backend], run_.skip, peak=peak)
        rows.append((a.name, b.name, *pm.sim_error_pct[SLICE["q"]].tolist()))
    whose = "; each pair once: a against b is b against a" if ref is not None else ": it did not run, so q_b's own"
    return Table(
        f"sim_error_{run_.name}",
        f"Simulation error %, task {run_.name}",
        f"max_t |q_a - q_b| / max_t |q_ref| x 100 per joint, t >= {run_.skip:g} s, q_ref the scenario's reference "
        f"({run_.reference}{whose}; docs/metrics.md). All analogues "
        "run legbench's one leg model (the report's frameworks each had their own): two analogues with the same "
        "law differ by integration and where the contact force acts only",
        ("framework a", "against b", "q1 %", "q2 %", "q3 %"),
        tuple(rows),
    )


def switch_table(plan: Plan, run_: Run, names: Sequence[str]) -> Table:
    """The combined task as the report saw it: each backend's first contact (Fn > 0.5 N, as metrics.json's
    ``first_contact``) and its torque at the tick of the switch to effort control (the last effort event's
    switch, its delay included), beside the scenario's published rows (``first_contact``, ``tau_switch``)."""
    switch = next((e.t for e in reversed(run_.events) if e.controller == "effort"), math.nan)
    rows: list[tuple[Any, ...]] = []
    for source, pub in _published(run_):
        if "first_contact" in pub or "tau_switch" in pub:
            tau = [float(x) for x in pub.get("tau_switch") or [math.nan] * 3]
            rows.append((source, float(pub.get("first_contact", math.nan)), *tau))
    for n in names:
        label = plan.label(n, _profile(run_, n))
        why = _status(run_, n)
        if why:
            rows.append((label, why, "", "", ""))
            continue
        tr = run_.traces[n]
        k = int(np.searchsorted(tr.t, switch - T_EPS)) if math.isfinite(switch) else len(tr.t)
        touch = first_contact(tr)
        tau = tr.tau[k].tolist() if k < len(tr.t) else [math.nan] * 3
        rows.append((label, math.nan if touch is None else touch, *tau))
    return Table(
        f"switch_{run_.name}",
        f"Contact and the switch to effort control, task {run_.name}",
        f"first contact [s] (Fn > 0.5 N) and tau [N m] at the switch to effort control, t = {switch:g} s; the lab "
        "report's published row first",
        ("source", "first contact [s]", "tau1", "tau2", "tau3"),
        tuple(rows),
    )


def tables(plan: Plan, runs: Sequence[Run], names: Sequence[str]) -> list[Table]:
    """The report's tables from the run directories of the plan's tasks (same order as ``plan.tasks``)."""
    out: list[Table] = []
    for task, r in zip(plan.tasks, runs, strict=True):
        if "steady" in task.tables:
            out += [table10(plan, r, names), steady_force_table(plan, r, names)]
    force_runs = [r for task, r in zip(plan.tasks, runs, strict=True) if "force" in task.tables]
    if force_runs:
        out.append(steady_fn_table(plan, force_runs, names))
    for task, r in zip(plan.tasks, runs, strict=True):
        if "sim_error" in task.tables:
            out.append(sim_error_table(plan, r))
    for task, r in zip(plan.tasks, runs, strict=True):
        if "switch" in task.tables:
            out.append(switch_table(plan, r, names))
    return out


def page_items(plan: Plan, tabs: Sequence[Table]) -> list[report.PageItem]:
    """The tables as a page: a heading, what stands for what, then each table."""
    items: list[report.PageItem] = [
        "# The lab report's comparison, regenerated",
        "Framework analogues ("
        + plan.file
        + "): "
        + "; ".join(
            f"{fw.name} -> {fw.backend} with profile {fw.profile}" + (f" ({fw.note})" if fw.note else "")
            for fw in plan.frameworks
        )
        + f"; every other backend with profile {plan.others}.",
    ]
    for t in tabs:
        items += [f"## {t.title}", (t.caption, t.header, t.text_rows())]
    return items


# --------------------------------------------------------------------------- #
# The command


def check_out(scs: Sequence[Scenario], out: Path, force: bool = False, new_place: str = "choose another --out",
              names: Sequence[str] | None = None) -> None:  # fmt: skip
    """Before any work, as ``legbench run`` decides for its runs: ``out`` holds nothing but what a reproduce
    writes (its task run directories, any other run directory, its pages), each task's directory holds no other
    scenario's results, and nothing finished is replaced without ``force``: a task directory holding a finished
    run (or an interrupted one of other settings), or ``reproduce.json`` when no task is resumed. An interrupted
    reproduce of the same command (task runs ``"complete": false``) is resumed.

    Raises:
        LegbenchError: one line naming the directory and what it holds (``new_place``: where a new one goes).
    """
    out = Path(out)
    results.check_out_tree(out, [sc.name for sc in scs], PAGES, "reproduce")
    run.check_outs([(sc, None, out / sc.name) for sc in scs], force, new_place, backends=names)
    resumed = any((out / sc.name / "run.json").is_file() for sc in scs)  # left: interrupted runs of these settings
    if not force and not resumed and (out / "reproduce.json").is_file():
        raise LegbenchError(f"{out} holds a finished reproduce (reproduce.json); {new_place} for a new one, "
                            "or --force to replace it")  # fmt: skip


def reproduce(
    plan: Plan,
    out: Path,
    names: Sequence[str],
    overrides: Mapping[str, Any] | None = None,
    duration: float | None = None,
    jobs: int = 1,
    progress: bool = False,
    reports: bool = True,
    force: bool = False,
    new_place: str = "choose another --out",
) -> tuple[list[Table], list[Run]]:
    """Run every task on every backend into ``out/<task>/``, then build, print-ready, the tables.

    ``out`` is checked first (:func:`check_out`): finished results there are replaced only with ``force``.

    Returns:
        The tables and the run directories read back (``plan.tasks`` order).
    """
    scs = scenarios_of(plan, overrides, duration)
    check_out(scs, out, force, new_place, names)
    dirs = [out / sc.name for sc in scs]
    run.run_many([(sc, None, d) for sc, d in zip(scs, dirs, strict=True)], names, jobs=jobs, progress=progress)
    if reports:
        for d in dirs:
            report.write_report(d)
    runs = [load_run(d) for d in dirs]
    tabs = tables(plan, runs, names)
    report.write_page(out, "reproduce", "legbench: the lab report's comparison", page_items(plan, tabs))
    doc = {
        "framework_file": plan.file,
        "frameworks": [fw.__dict__ for fw in plan.frameworks],
        "backends": list(names),
        "duration": duration,  # [s] each task cut to it (--duration), None: whole
        "overrides": dict(overrides or {}),  # --set, in every task
        "runs": {r.name: str(r.path) for r in runs},  # each run's run.json: its scenario as run, versions, platform
        "versions": results.versions(),
        "platform": results.platform_info(),
        "tables": {  # n/a as null: strict JSON (a NaN token is no JSON value)
            t.key: {"title": t.title, "header": list(t.header), "rows": [[_json_cell(v) for v in r] for r in t.rows]}
            for t in tabs
        },
    }
    results.write_json(doc, out / "reproduce.json")
    return tabs, runs


def add_cli(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Register ``legbench reproduce [--frameworks FILE] [--out DIR] [--force] [--jobs N] [--duration S] ...``."""
    p = subparsers.add_parser(
        "reproduce",
        help="the lab report's comparison in one command: its tables from the framework analogues",
        description="Run the lab report's four tasks on the backends standing for its frameworks (a framework "
        "file) and on every other backend; print and write its table 10, the steady force and Fn, the combined "
        "task's contact and switch torque and the simulation error % between frameworks "
        "(OUT/reproduce.{md,html,json}; one ordinary run directory per task).",
    )
    p.add_argument("--frameworks", default=str(FRAMEWORKS_FILE), metavar="FILE",
                   help="which backend and profile stands for which framework, and the tasks "
                        "(default scenarios/reproduce.yaml)")  # fmt: skip
    p.add_argument("--backends", default="all",
                   help="the other backends besides the framework analogues: 'all' available (default), "
                        "'none', or comma-separated names")  # fmt: skip
    p.add_argument("--out", default=None, help=f"results tree (default {DEFAULT_OUT})")
    p.add_argument("--force", action="store_true",
                   help="replace finished task runs (or interrupted ones of other settings) and the tables in the "
                        "output directory; refused otherwise (an interrupted reproduce of the same command is "
                        "resumed)")  # fmt: skip
    p.add_argument("--jobs", type=int, default=1, help="parallel runs (default 1)")
    p.add_argument("--duration", type=yamlfile.positive_float, default=None,
                   help="cut every task to at most this many seconds (a smoke test; later events dropped)")  # fmt: skip
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="override a key of every task, e.g. --set physics.contact.v_th=0.01")  # fmt: skip
    p.add_argument("--no-report", action="store_true", help="skip each run directory's report and figures")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bars")
    p.set_defaults(func=_cli)


def _cli(args: argparse.Namespace) -> int:
    plan = load_plan(args.frameworks)
    others = args.backends if args.backends in ("all", "none") else args.backends.split(",")
    names = backend_names(plan, others)
    out = Path(args.out) if args.out is not None else DEFAULT_OUT
    new_place = "choose another --out" if args.out is not None else "pass --out DIR"
    tabs, runs = reproduce(plan, out, names, yamlfile.parse_overrides(args.set), args.duration, args.jobs,
                           progress=not args.quiet, reports=not args.no_report, force=args.force,
                           new_place=new_place)  # fmt: skip
    print(report.page_markdown(page_items(plan, tabs)))
    print(f"written: {out / 'reproduce.md'}, {out / 'reproduce.html'}, {out / 'reproduce.json'}")
    failed = any(st.status == "failed" for r in runs for st in r.backends.values())
    return EXIT_BACKEND_FAILED if failed else EXIT_OK
