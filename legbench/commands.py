"""The core subcommands: ``model``, ``run``, ``validate``, ``compare``, ``check``.

Each ``add_*`` registrar adds its subcommand's parser and sets ``func``, the
handler, which takes the parsed arguments and returns the exit status.
:mod:`legbench.cli` imports this module only when one of these subcommands
is asked for.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
from collections.abc import Callable, Collection, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from legbench import backends, kinematics, model, resources, results, scenario, yamlfile
from legbench.backends.base import PROFILES
from legbench.contact import CONTACT_MODES
from legbench.exceptions import LegbenchError
from legbench.exitcodes import EXIT_BACKEND_FAILED, EXIT_OK, EXIT_USER_ERROR

# check, logs, report, run, doctor and sweep (pandas, matplotlib, plotly's page code) are imported by the
# handlers that use them: `legbench validate` or `schema` does not pay for the report's imports.


def _floats(values: Any) -> list[float]:
    return [float(v) for v in values]


# --------------------------------------------------------------------------- #
# legbench model ...


def _model_fk(args: argparse.Namespace) -> int:
    ee = kinematics.fk(np.array(args.q))
    if args.json:
        print(json.dumps({"ee": _floats(ee)}))
    else:
        print(f"foot centre E in W [m]: x = {ee[0]:.6f}, y = {ee[1]:.6f}, z = {ee[2]:.6f}")
    return 0


def _model_ik(args: argparse.Namespace) -> int:
    res = kinematics.ik(np.array(args.p))
    if args.json:
        out: dict[str, object] = {"solutions": [_floats(s) for s in res.solutions]}
        if not res:
            out["reason"] = res.reason
        print(json.dumps(out))
        return 0 if res else 1
    if not res:
        print(f"unreachable: {res.reason}")
        return 1
    for i, s in enumerate(res.solutions):
        print(f"solution {i + 1}: q1 = {s[0]:+.6f}, q2 = {s[1]:+.6f}, q3 = {s[2]:+.6f} [rad]")
    return 0


def _model_gravity(args: argparse.Namespace) -> int:
    tau = kinematics.gravity(np.array(args.q))
    if args.json:
        print(json.dumps({"tau": _floats(tau)}))
    else:
        print(f"gravity torque G(q) [N m]: {tau[0]:+.6f} {tau[1]:+.6f} {tau[2]:+.6f}")
    return 0


def _model_urdf(args: argparse.Namespace) -> int:
    """Write the URDF. An ``--out`` given is refused when it is the parameter file itself (even with ``--force``),
    and when it holds a file legbench did not generate (no stamp in its header), unless ``--force``: a URDF
    generated before is regenerated in place, anything else is the user's."""
    given = args.out is not None
    args = _with_defaults(args)
    out = Path(args.out)
    if given and out.exists():
        if Path(args.params).exists() and os.path.samefile(out, args.params):
            raise LegbenchError(f"--out {out}: is the parameter file the URDF is generated from; choose another "
                                "file")  # fmt: skip
        if resources.urdf_stamp(out) is None and not args.force:
            raise LegbenchError(f"--out {out}: exists and is not a URDF legbench generated; choose another file, or "
                                "pass --force to replace it")  # fmt: skip
    path = model.write_urdf(model.read_params(args.params), out)
    print(f"wrote {path}")
    return 0


#: The largest mass scale factor `model calibrate` offers: beyond it G_star at q_star does not fit the leg (a
#: singular solve gave factors of 2e16).
CALIBRATE_MAX = 1e3


def _model_calibrate(args: argparse.Namespace) -> int:
    try:
        scale = model.calibrate(model.load_raw(args.params))
    except np.linalg.LinAlgError:  # exactly singular: no link's weight moves some joint at q_star
        scale = {"every link": math.nan}
    bad = {k: v for k, v in scale.items() if not (math.isfinite(v) and 0.0 < v < CALIBRATE_MAX)}
    if bad:  # a factor the parameter file refuses, or one of a pose whose solve is singular: not one to paste
        k, v = next(iter(bad.items()))
        raise LegbenchError(f"{args.params}: calibration.G_star at q_star needs a {k} mass scale of {v:.6g}, not a "
                            f"physical one (> 0 and < {CALIBRATE_MAX:g}): G_star's signs or q_star (a pose where "
                            "a link's weight moves no joint) do not fit this leg")  # fmt: skip
    print("mass scale factors that reproduce G(q*) (paste into calibration.scale of the parameter file):")
    print("  scale: {" + ", ".join(f"{k}: {v:.8f}" for k, v in scale.items()) + "}")
    return 0


def _model_check(args: argparse.Namespace) -> int:
    """Print the model's headline numbers against the spec's."""
    p = model.load_params()
    q_star = np.array(p.q_star)
    G = kinematics.gravity(q_star)
    ee = kinematics.fk(q_star)
    bundled = resources.is_bundled(resources.model_file())
    foot = "the lab report's foot at q*: [0.16669, -0.00001, 0.0225]" if bundled else "the foot centre at q_star"
    print(f"FK(q*) = {np.round(ee, 5).tolist()} m ({foot}; on the ground it is at z = R_foot = {p.geometry.R_foot:g})")
    print(
        f"G(q*)  = {np.round(G, 4).tolist()} N m (calibration.G_star{', the report' if bundled else ''}: "
        f"{list(p.G_star)})"
    )
    diff, ref = np.abs(G - np.array(p.G_star)), np.abs(np.array(p.G_star))
    # a component the report gives as 0: exact (0 %) or infinitely off (no division warning on stderr)
    rel = np.divide(diff, ref, out=np.where(diff == 0.0, 0.0, np.inf), where=ref > 0.0)
    print(f"relative error per component: {np.round(100 * rel, 3).tolist()} %")
    masses = {b: round(p.body_inertial(b).mass, 4) for b in model.LINK_NAMES}
    print(f"moving masses [kg]: {masses}, total {sum(masses.values()):.4f}")
    if np.all(rel < 0.05):
        print("PASS: G(q*) within 5 % of G_star in every joint")
        return 0
    off = [f"joint {j + 1}" for j in range(3) if not rel[j] < 0.05]
    print(f"FAIL: G(q*) more than 5 % off G_star in {', '.join(off)} (calibration.scale, or legbench model calibrate)")
    return 1


def add_model(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    m = sub.add_parser("model", help="the leg model: kinematics, gravity, URDF generation")
    msub = m.add_subparsers(dest="model_cmd", required=True)

    def joint_cmd(name: str, fn: Callable[[argparse.Namespace], int], help_: str) -> None:
        p = msub.add_parser(name, help=help_)
        p.add_argument("q", nargs=3, type=yamlfile.physical_float, metavar="Q", help="joint angles q1 q2 q3 [rad]")
        p.add_argument("--json", action="store_true", help="print one JSON object")
        p.set_defaults(func=fn)

    joint_cmd("fk", _model_fk, "foot centre in W for joint angles")
    joint_cmd("gravity", _model_gravity, "gravity torque G(q)")
    p = msub.add_parser("ik", help="every joint solution for a foot-centre point in W")
    p.add_argument("p", nargs=3, type=yamlfile.physical_float, metavar="P", help="foot centre x y z in W [m]")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=_model_ik)
    p = msub.add_parser("urdf", help="regenerate the URDF of the parameter file (models/leg.urdf for the bundled leg)")
    p.add_argument("--params", default=None,
                   help="parameter file (default: the active model, models/leg.yaml unless --model)")  # fmt: skip
    p.add_argument("--out", default=None,
                   help="output URDF (default: where legbench reads that parameter file's URDF: models/leg.urdf "
                        "for the bundled leg, else the cache's urdf/<stem>-<hash>.urdf, never the bundled "
                        "model's)")  # fmt: skip
    p.add_argument("--force", action="store_true",
                   help="replace an --out file legbench did not generate (never the parameter file)")  # fmt: skip
    p.set_defaults(func=_model_urdf)
    p = msub.add_parser("calibrate", help="mass scale factors that reproduce the report's G(q*)")
    p.add_argument("--params", default=None,
                   help="parameter file to calibrate (default: the active model, models/leg.yaml unless "
                        "--model); nothing is written")  # fmt: skip
    p.set_defaults(func=lambda a: _model_calibrate(_with_defaults(a)))
    p = msub.add_parser("check", help="print FK(q*), G(q*) and masses against the spec")
    p.set_defaults(func=_model_check)


def _with_defaults(args: argparse.Namespace) -> argparse.Namespace:
    """``--params`` defaults to the active model; ``--out`` to where legbench reads the URDF of ``--params``
    (:func:`legbench.resources.urdf_destination`): models/leg.urdf only for the bundled leg (in a source checkout
    even when it is out of date with leg.yaml: that is how it is regenerated), another parameter file's URDF goes
    to the cache, so ``--params other.yaml`` never replaces the bundled model's URDF."""
    if getattr(args, "params", None) is None:
        args.params = model.PARAMS_FILE
    if hasattr(args, "out") and args.out is None:
        args.out = resources.urdf_destination(args.params)
    return args


# --------------------------------------------------------------------------- #
# legbench run


def _run(args: argparse.Namespace) -> int:
    from legbench import report, run
    from legbench.studies import doctor

    overrides = yamlfile.parse_overrides(args.set)
    variant = "--variant" if args.variant else None
    yamlfile.check_one_place(overrides, {
        "profile": f"--profile {args.profile}" if args.profile else variant,
        "physics.contact_mode": f"--contact-mode {args.contact_mode}" if args.contact_mode else variant,
    })  # fmt: skip
    if args.variant and (args.profile or args.contact_mode):
        raise LegbenchError("--variant: give the profile and contact mode of each run there, not also "
                            "--profile or --contact-mode")  # fmt: skip
    twice = sorted({v for v in args.variant if args.variant.count(v) > 1})
    if twice:
        raise LegbenchError(f"--variant {':'.join(twice[0])}: given twice (each pair runs once)")
    modes: list[str | None] = ["native", "reference"] if args.contact_mode == "both" else [args.contact_mode]
    runs: list[tuple[scenario.Scenario, str | None]] = []  # all validated before any runs
    names = backends.resolve(args.backends)
    for path in args.scenarios:
        sc = scenario.load(path, overrides, engines=names)
        profiles = list(PROFILES) if args.profile == "both" else [args.profile or sc.profile]
        variants = args.variant or [(prof, mode) for prof in profiles for mode in modes]
        loaded = {sc.profile: sc}
        for prof, mode in variants:  # a profile or mode other than the file's is an override: in the scenario's hash
            if prof not in loaded:
                loaded[prof] = scenario.load(path, {**overrides, "profile": prof}, engines=names)
            base = loaded[prof]
            if mode is not None and mode != base.contact_mode:  # checked as if the file gave it, then recorded so
                given = f"--variant {prof}:{mode}" if args.variant else f"--contact-mode {args.contact_mode}"
                scenario.check_contact_mode(base, names, mode, given)
            runs.append((scenario.in_contact_mode(base, mode), mode))
    single = len(runs) == 1
    root = Path(args.out) if args.out else Path("results") / "latest"
    plan = [(sc, mode, root if (single and args.out) else results.out_dir_for(root, sc, mode)) for sc, mode in runs]
    if not single:  # a tree: not inside a run, and a --out of someone else's is refused (its index goes there)
        run.check_tree(root, [out.name for *_, out in plan], foreign=args.out is not None)
    # a run of this command whose backends all finished but whose comparison an interrupt stopped: compared only
    pending = set() if args.force or args.no_compare else {
        out for sc, mode, out in plan if results.comparison_pending(sc, out, mode, names, csv=args.csv)}  # fmt: skip
    _check_plan(plan, names, args, pending)
    plan_run = [p for p in plan if p[2] not in pending]
    # the workers (no more than the runs) import the engines while the pre-flight runs here (one run needs none)
    n_runs = len(plan_run) * len(names)
    pool = run.start_pool(args.jobs, tasks=n_runs, backend_names=names) if n_runs > 1 else None
    try:
        if not args.no_preflight:
            checked: set[str] = set()
            for sc, mode, _ in plan_run:  # every engine must hold the spec's leg, in the run's mode, before any run
                mode = mode or sc.contact_mode
                key = json.dumps([sc.gravity, mode, sc.profile, {k: dict(v) for k, v in sc.backends.items()}],
                                 sort_keys=True)  # fmt: skip
                if key not in checked:  # the pre-flight depends only on gravity, mode, profile and backend settings
                    doctor.preflight(sc, names, mode)  # resolve loaded each: no other engine is imported
                    checked.add(key)
    except BaseException:
        if pool is not None:
            pool.terminate()
        raise
    ran = iter(run.run_many(plan_run, names, jobs=args.jobs, csv=args.csv, progress=not args.quiet, pool=pool)
               if plan_run else [])  # fmt: skip
    not_ok: list[str] = []  # run directory/backend of each run that did not finish ok
    for sc, mode, out in plan:
        if out in pending:
            print(f"{sc.name}: {out}: every backend finished in an earlier run of the same scenario, settings and "
                  f"leg, which has no comparison yet: kept as it is and compared only, as legbench compare {out} "
                  "would (--force runs it again)")  # fmt: skip
            for bname, entry in results.read_meta(out)["backends"].items():  # as the earlier run printed them
                if entry["status"] != "ok":
                    not_ok.append(f"{out.name}/{bname}")
                    print(f"  {bname:<10} {str(entry['status']).upper()}: {entry.get('reason')}")
            continue
        res = next(ran)
        print(
            f"{sc.name}: {sc.duration:g} s at {sc.control_rate:g} Hz, profile {sc.profile}, "
            f"contact {mode or sc.contact_mode} -> {out}"
        )
        for tr in res:
            if tr.status != "ok":
                not_ok.append(f"{out.name}/{tr.backend}")
                print(f"  {tr.backend:<10} {tr.status.upper()}: {tr.reason}")
                continue
            rtf = tr.t[-1] / tr.wall_time if tr.wall_time > 0 else float("nan")
            print(
                f"  {tr.backend:<10} ok  wall {tr.wall_time:6.2f} s  RTF {rtf:7.2f}  "
                f"q_end [{', '.join(f'{x:+.4f}' for x in tr.q[-1])}] rad  "
                f"F_end [{', '.join(f'{x:+.2f}' for x in tr.f[-1])}] N"
            )
            for w in tr.info.get("warnings") or ():  # each begins with the backend's name (run.backend_info)
                print(f"  warning: {w}")
    if not args.no_compare:
        if single:
            files = report.write_report(plan[0][2])
            print(f"report: {files.html}")
        else:
            report.write_all(root, jobs=args.jobs)
            print(f"report: {root / 'report.html'}")
    if not_ok:  # the status a script reads, and one line where it looks for errors; the reasons are above
        print(f"legbench: {len(not_ok)} run(s) did not finish ok ({', '.join(not_ok)}); the others' results are "
              "written", file=sys.stderr)  # fmt: skip
    return EXIT_BACKEND_FAILED if not_ok else EXIT_OK


def _variant(text: str) -> tuple[str, str]:
    """``--variant PROFILE:MODE`` -> (profile, contact mode); argparse reports a bad one (exit status 2)."""
    prof, sep, mode = text.partition(":")
    if not sep or prof not in PROFILES or mode not in CONTACT_MODES:
        raise argparse.ArgumentTypeError(
            f"{text!r}: expected PROFILE:MODE with PROFILE one of {', '.join(PROFILES)} "
            f"and MODE one of {', '.join(CONTACT_MODES)}"
        )
    return prof, mode


def _check_plan(
    plan: list[tuple[scenario.Scenario, str | None, Path]],
    names: Sequence[str],
    args: argparse.Namespace,
    pending: Collection[Path] = (),
) -> None:
    """Before any work: no two runs of the plan into one directory, and no finished result replaced that the
    user did not ask to replace: a run into a directory holding a finished run (``run.json``, not an interrupted
    run of the same scenario, which is resumed) needs ``--force``, with or without ``--out``. The ``pending``
    directories (:func:`legbench.results.comparison_pending`) are compared only, not replaced."""
    seen: dict[Path, str] = {}
    for sc, _, out in plan:
        if out in seen:
            raise LegbenchError(f"{sc.file} and {seen[out]} are both scenario {sc.name!r}: their results would "
                                f"collide in {out}; rename one")  # fmt: skip
        seen[out] = sc.file
    from legbench import run

    new_place = "choose another --out" if args.out is not None else "pass --out DIR"
    run.check_outs([p for p in plan if p[2] not in pending], args.force, new_place, backends=names)


def _validate(args: argparse.Namespace) -> int:
    """Scenario, sweep (has ``studies``), framework (``legbench reproduce``'s: has ``frameworks``), tolerance
    (:func:`legbench.scenario.is_tolerance_file`, the rule a run uses too) and leg parameter files (a section of
    :data:`legbench.model.SECTIONS`: :func:`legbench.scenario.is_leg_parameter_file`, checked as ``--model`` reads
    one), told apart by content.

    Every file is checked and every independent problem of a file is one line on stderr
    (:func:`legbench.scenario.errors`, :func:`legbench.check.tolerance_errors`); exit 2 if any.
    """
    bad = 0
    overrides = yamlfile.parse_overrides(args.set)
    for path in args.files:
        try:
            ok, problems = _validate_one(path, overrides)
        except LegbenchError as exc:
            ok, problems = "", [exc]
        for problem in problems:
            print(f"legbench: error: {yamlfile.one_line(str(problem))}", file=sys.stderr)
        if problems:
            bad += 1
        else:
            print(ok)
    return EXIT_USER_ERROR if bad else EXIT_OK


def _set_refused(path: str, kind: str) -> tuple[str, list[LegbenchError]]:
    return "", [LegbenchError(f"{path}: --set applies to scenario files; this is {kind}")]


def _validate_one(path: str, overrides: Mapping[str, Any] | None = None) -> tuple[str, list[LegbenchError]]:
    try:
        doc, _ = yamlfile.read_yaml(path)
    except LegbenchError as exc:
        return "", [exc]
    if scenario.is_leg_parameter_file(doc):
        if overrides:
            return _set_refused(path, "a leg parameter file")
        model.read_params(path)  # ModelError: the file, the entry, why
        return f"{path}: ok (a leg parameter file: give it to legbench --model {path}, or LEGBENCH_MODEL)", []
    if isinstance(doc, dict) and "studies" in doc:
        if overrides:  # --set is a scenario's, as legbench run's
            return _set_refused(path, "a sweep file")
        from legbench.studies import sweep

        sw = sweep.load_sweep(path)
        return f"{path}: ok (sweep {sw.name}: {len(sw.studies)} studies)", []
    if isinstance(doc, dict) and "frameworks" in doc:
        if overrides:
            return _set_refused(path, "a framework file")
        from legbench.studies import reproduce

        plan = reproduce.load_plan(path)
        return f"{path}: ok (frameworks: {len(plan.frameworks)}, tasks: {len(plan.tasks)})", []
    if scenario.is_tolerance_file(doc):
        if overrides:
            return _set_refused(path, "a tolerance file")
        from legbench import check

        problems: list[LegbenchError] = list(check.tolerance_errors(path))  # each with its line
        return f"{path}: ok (tolerances: {', '.join(sorted(map(str, doc)))})", problems
    problems = list(scenario.errors(path, overrides))
    if problems:
        return "", problems
    sc = scenario.load(path, overrides)
    n = len(sc.events)
    return f"{path}: ok ({sc.name}: {n} event{'' if n == 1 else 's'}, {sc.duration:g} s)", []


def add_run(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = sub.add_parser("run", help="run scenarios on one or more backends, then compare them")
    p.add_argument("scenarios", nargs="+", metavar="SCENARIO", help="scenario YAML files")
    p.add_argument("--backends", default="all", help="comma-separated backend names, or 'all' (default)")
    p.add_argument("--out", default=None,
                   help="output directory: the run directory for one scenario, else the root of one directory "
                        "per scenario (default results/latest)")  # fmt: skip
    p.add_argument("--jobs", type=int, default=1, help="processes to run backends and scenarios in (default 1)")
    p.add_argument("--csv", action="store_true", help="also write <backend>.csv")
    p.add_argument("--contact-mode", choices=("native", "reference", "both"), default=None,
                   help="override the scenario's contact mode; 'both' runs each scenario in both modes "
                        "(<name>/ and <name>__reference/)")  # fmt: skip
    p.add_argument("--profile", choices=(*PROFILES, "both"), default=None,
                   help="how every backend is configured (default: the scenario's profile, else matched): "
                        "'matched' maps the spec's physics as faithfully as each engine allows, "
                        "'engine-defaults' is each engine's documented defaults with only Kp, Kd and mu set; "
                        "'both' runs each scenario in both (<name>/ and <name>__engine-defaults/)")  # fmt: skip
    variant = p.add_argument("--variant", action="append", type=_variant, default=[], metavar="PROFILE:MODE",
                   help="run each scenario in this profile and contact mode, e.g. engine-defaults:native; "
                        "repeat for several, all in one pool (instead of --profile and --contact-mode)")  # fmt: skip
    variant.completer = lambda **_: [f"{prof}:{mode}" for prof in PROFILES for mode in CONTACT_MODES]  # type: ignore[attr-defined]
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="override a scenario key, e.g. --set backends.<name>.dt=5e-5 (a list item with a dot: "
                        "events.0.t=0.5)")  # fmt: skip
    p.add_argument("--no-compare", action="store_true", help="do not write the comparison report")
    p.add_argument("--no-preflight", action="store_true",
                   help="skip the parity pre-flight (legbench doctor) before running")  # fmt: skip
    p.add_argument("--force", action="store_true",
                   help="replace a finished run (or an interrupted one of other settings, or holding the log "
                        "of a backend not asked for) in the output directory, --out or results/latest/<name>; "
                        "refused otherwise (an interrupted run of the same command is resumed)")  # fmt: skip
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=_run)


#: compare's log arguments as ``legbench compare`` names them (:func:`legbench.compare.log_settings_problem`).
_LOG_WORDS = {"log": "--reference-log", "column_map": "--log-columns", "log_is_reference": "--log-is-reference",
              "log_time_scale": "--log-time-scale", "log_t0": "--log-t0"}  # fmt: skip


def _compare(args: argparse.Namespace) -> int:
    from legbench import logs, report
    from legbench.compare import log_settings_problem

    if not args.dir:  # Path("") is the working directory
        raise LegbenchError("'': an empty path; give a run directory or a results tree")
    try:
        a_file = Path(args.dir).exists() and not Path(args.dir).is_dir()
    except OSError as exc:  # a name too long: no such directory can exist
        raise LegbenchError(f"{args.dir}: {exc.strerror or exc}") from None
    if a_file:
        raise LegbenchError(f"{args.dir}: is a file, not a results directory (give a run directory or a tree)")
    ros_given = [opt for opt, value in (("--ros-joint-topic", args.ros_joint_topic),
                                        ("--ros-wrench-topic", args.ros_wrench_topic),
                                        ("--ros-force-sign", args.ros_force_sign)) if value is not None]  # fmt: skip
    problem = log_settings_problem(args.reference_log, args.log_columns, args.log_is_reference, args.log_time_scale,
                                   bool(ros_given), {**_LOG_WORDS, "ros": " / ".join(ros_given)},
                                   args.log_t0)  # fmt: skip
    if problem is not None:
        raise LegbenchError(problem)
    column_map: dict[str, str] = {}
    for item in args.log_columns.split(",") if args.log_columns else []:
        src, sep, dst = item.partition("=")
        if not sep or not src.strip() or not dst.strip():
            raise LegbenchError(f"--log-columns {item!r}: expected HEADER=COLUMN, e.g. joint1_pos=q1")
        if src.strip() in column_map:
            raise LegbenchError(f"--log-columns {args.log_columns!r}: header {src.strip()!r} is mapped twice "
                                f"({column_map[src.strip()]} and {dst.strip()}); map each header once")  # fmt: skip
        column_map[src.strip()] = dst.strip()
    ros = None
    if args.reference_log is not None and logs.is_ros_bag(args.reference_log):
        ros = logs.RosOptions(
            joint_topic=args.ros_joint_topic,
            wrench_topic=args.ros_wrench_topic,
            force_sign=args.ros_force_sign if args.ros_force_sign is not None else 1.0,
        )
    report.write_all(
        args.dir,
        log=args.reference_log,
        ros=ros,
        column_map=column_map or None,
        log_time_scale=args.log_time_scale,
        log_t0=args.log_t0,
        log_is_reference=args.log_is_reference,
        lag=args.lag,
        all_pairs=args.all_pairs,
        jobs=args.jobs,
        progress=lambda page: print(f"wrote {page}", flush=True),  # each page as it is put in place (after all render)
    )
    # a missing log is reported without that backend, as a failed one is; a failed backend with the status `legbench
    # run` gave it, for a script reading this one
    problems = results.run_problems(args.dir)
    for line in [*problems.missing, *problems.incomplete]:
        print(f"legbench: {line}", file=sys.stderr)
    if problems.failed:
        print(f"legbench: {len(problems.failed)} run(s) did not finish ok ({', '.join(problems.failed)}); the "
              "others' results are compared", file=sys.stderr)  # fmt: skip
    return EXIT_BACKEND_FAILED if problems.missing or problems.failed else EXIT_OK


def add_compare(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = sub.add_parser("compare", help="compare the backends of a run directory (or a tree of them) and report")
    p.add_argument("dir", help="a run directory, or a results tree such as results/latest")
    p.add_argument(
        "--reference-log",
        default=None,
        metavar="LOG",
        help="an external log to compare as one more backend: a CSV file (header with legbench column names) or "
        "a ROS bag (ROS 1 .bag file, ROS 2 bag directory, sqlite3 or MCAP; needs legbench[ros])",
    )
    p.add_argument("--ros-joint-topic", default=None, metavar="TOPIC",
                   help="the bag's sensor_msgs/JointState topic (default: its only one)")  # fmt: skip
    p.add_argument("--ros-wrench-topic", default=None, metavar="TOPIC",
                   help="the bag's geometry_msgs/WrenchStamped topic of the ground force on the foot in W "
                        "(default: its only one, if any; '' for none)")  # fmt: skip
    p.add_argument("--ros-force-sign", type=float, choices=(1.0, -1.0), default=None,
                   help="-1 if the wrench is the force the foot exerts on the ground (default +1: the ground "
                        "on the foot)")  # fmt: skip
    p.add_argument(
        "--log-columns",
        default="",
        metavar="HEADER=COLUMN,...",
        help="map the log's headers to legbench columns (t, q1..q3, qd1..qd3, tau1..tau3, fx, fy, fz); for a "
        "ROS bag, its joint names to joints 1..3 (NAME=q1,NAME=q2,NAME=q3; default q1_abad, q2_hip, q3_knee)",
    )
    p.add_argument(
        "--log-time-scale",
        type=yamlfile.positive_float,
        default=1.0,
        help="factor taking the log's time unit to seconds (e.g. 1e-3 for ms; default 1: seconds)",
    )
    p.add_argument(
        "--log-t0",
        type=yamlfile.finite_float,
        default=None,
        metavar="SECONDS",
        help="the log's time [s, after --log-time-scale] that is the run's t = 0 (a log stamped in epoch seconds, "
        "or started before the run; default: 0 for a CSV, a bag's first joint-state sample)",
    )
    p.add_argument(
        "--log-is-reference",
        action="store_true",
        help="measure every backend against the log instead of the scenario's reference backend",
    )
    p.add_argument("--lag", choices=("off", "report", "remove"), default="off",
                   help="estimate ('report') or estimate and remove ('remove') a constant time lag by "
                        "cross-correlation (default off: the logs are compared as they are)")  # fmt: skip
    p.add_argument("--all-pairs", action="store_true", help="metrics for every pair of backends, not only vs reference")
    p.add_argument("--jobs", type=int, default=1, help="processes rendering the run reports of a tree (default 1)")
    p.set_defaults(func=_compare)


def _check(args: argparse.Namespace) -> int:
    from legbench import check

    return check.run_check(args.dir, args.baseline, args.tolerances, args.summary, args.junit, all_rows=args.all)


def add_check(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = sub.add_parser("check", help="regression check of new results against a committed baseline")
    p.add_argument("dir", help="new results (run directory or tree)")
    p.add_argument("--baseline", required=True, help="baseline results, same layout (e.g. results/baseline)")
    p.add_argument("--tolerances", default=None, help="tolerance file (YAML)")
    p.add_argument("--summary", default=None,
                   help="Markdown summary (default DIR/check.md, rewritten each time); an existing file is "
                        "replaced only with --force")  # fmt: skip
    p.add_argument("--junit", default=None,
                   help="JUnit XML (default DIR/check-junit.xml, rewritten each time); an existing file is "
                        "replaced only with --force")  # fmt: skip
    p.add_argument("--force", action="store_true", help="replace an existing --summary or --junit file")
    p.add_argument("--all", action="store_true", help="print every checked row, not only what moved")
    p.set_defaults(func=_check)


def _schema(args: argparse.Namespace) -> int:
    print(json.dumps(scenario.json_schema(), indent=2))
    return EXIT_OK


def _backends(args: argparse.Namespace) -> int:
    """Every backend legbench finds: those that can run here (built-in or plug-in, with their profiles and
    integrators), then those that cannot, with why (the command that installs the engine)."""
    names = backends.available()
    missing = backends.unavailable()
    width = max(len(n) for n in [*names, *missing])
    for name in names:
        cls = backends.get(name)
        origin = "built-in" if name in backends.BUILTIN else f"plug-in {cls.__module__}:{cls.__qualname__}"
        line = f"{name:<{width}}  {origin}; profiles: {', '.join(cls.profiles)}"
        integrators = cls.choices.get("integrator")
        if integrators:
            matched = cls.resolve_settings({}, PROFILES[0]).get("integrator")
            line += f"; integrators: {', '.join(map(str, integrators))} ({PROFILES[0]}: {matched})"
        print(line)
    for name, why in missing.items():
        print(f"{name:<{width}}  not available: {why}")
    return EXIT_OK


def add_backends(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = sub.add_parser("backends", help="the backends legbench finds: what runs here, and how to install the rest")
    p.set_defaults(func=_backends)


def add_schema(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = sub.add_parser("schema", help="print the JSON Schema of the scenario format (for editors)")
    p.set_defaults(func=_schema)


def add_validate(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = sub.add_parser("validate", help="check scenario, sweep, tolerance, framework and leg parameter files "
                                        "without running them")  # fmt: skip
    p.add_argument("files", nargs="+", help="YAML files")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="override a key of every scenario file first, as legbench run --set does")  # fmt: skip
    p.set_defaults(func=_validate)
