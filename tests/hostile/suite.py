"""A hostile user's suite: many bad inputs over every subcommand, run in-process through ``cli.main``.

Run from the repository root: ``PYTHONPATH=$PWD python tests/hostile/suite.py [-v]``. Each case is
handled cleanly when the command returns an exit status with no traceback, within
the time bound (SIGALRM, 120 s) and, for bad input, with a one-line message. Prints the counts.
"""

from __future__ import annotations

import contextlib
import io
import os
import signal
import sys
import tempfile
import traceback
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import yaml

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from fakes import FakeBackend  # noqa: E402

from legbench import backends as registry  # noqa: E402
from legbench import cli  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
EFFORT = str(ROOT / "scenarios" / "effort.yaml")
GOOD: dict[str, Any] = {"name": "t", "duration": 0.6, "events": [{"t": 0.0, "position": {"joint": [0.0, -1.0, -1.0]}}]}
_reg = registry._registry


@contextlib.contextmanager
def fake_backend() -> Iterator[None]:
    """The registry with the engine-free ``fake`` backend beside the real ones, for the cases that run one;
    the registry as it was afterwards (the pytest wrapper shares its process with other tests)."""
    registry._registry = lambda: {**_reg(), "fake": FakeBackend}  # type: ignore[assignment]
    try:
        yield
    finally:
        registry._registry = _reg  # type: ignore[assignment]


class Hang(Exception):
    pass


def _alarm(signum: int, frame: object) -> None:
    raise Hang


def bomb(levels: int) -> str:
    text = 'name: t\nduration: 1.0\nl0: &l0 ["x","x","x","x","x","x","x","x","x","x"]\n'
    for i in range(1, levels):
        text += f"l{i}: &l{i} [" + ",".join([f"*l{i - 1}"] * 10) + "]\n"
    return text


def build(d: Path) -> list[tuple[str, list[str], set[int]]]:
    """(case id, argv, acceptable exit statuses)."""

    def w(name: str, text: str) -> str:
        (d / name).write_text(text)
        return str(d / name)

    def wb(name: str, data: bytes) -> str:
        (d / name).write_bytes(data)
        return str(d / name)

    good = w("good.yaml", yaml.safe_dump(GOOD))
    sc: dict[str, str] = {
        "bomb9": bomb(9), "bomb3": bomb(3), "deep": "a: " + "[" * 50000 + "]" * 50000, "dup": "name: t\nname: u\n",
        "nul": "name: t\x00", "empty": "", "list": "- 1\n", "tag": "name: !!python/object/apply:os.system [ls]\n",
        "malformed": "name: [t\n", "indent": "name: t\n  duration: 1\n", "recursive": "a: &a [*a]\n",
        "undefined_alias": "a: *x\n", "ticks": yaml.safe_dump({**GOOD, "duration": 1e6, "control_rate": 1e6}),
        "substep": yaml.safe_dump({**GOOD, "backends": {"pinocchio": {"dt": 1e-10}}}),
        "overflow": yaml.safe_dump({**GOOD, "backends": {"pybullet": {"solver_iterations": 10**20}}}),
        "neg_kd": yaml.safe_dump({**GOOD, "gains": {"Kd": -1}}),
        "same_instant": yaml.safe_dump({**GOOD, "duration": 1.0, "events": GOOD["events"] * 2}),
        "mu": yaml.safe_dump({**GOOD, "physics": {"contact": {"mu_k": 2.0}}}),
        "reference": yaml.safe_dump({**GOOD, "comparison": {"reference": "pinochio"}}),
        "nan": "name: t\nduration: .nan\nevents: []\n", "huge_num": "name: t\nduration: 1e400\nevents: []\n",
        "bool_dur": "name: t\nduration: yes\nevents: []\n", "name_path": yaml.safe_dump({**GOOD, "name": "../x"}),
        "dt_divide": yaml.safe_dump({**GOOD, "backends": {"mujoco": {"dt": 3e-4}}}),
        "big_list": yaml.safe_dump({**GOOD, "events": [{"t": i * 1e-3, "effort": {"force": [0, 0, 1]}}
                                                       for i in range(20)]}),
        "big_ellipse": yaml.safe_dump({**GOOD, "events": [{"t": 0.0, "ellipse": {"a": 0.01, "b": 0.01, "DY": 0.0,
                                                          "DZ": 0.1, "T": 1.0, "points": 10**7}}]}),
        # valid-looking, but every run would fail: at t = 0 (diverged), or at an engine's load
        "qd_fast": yaml.safe_dump({**GOOD, "initial": {"qd": [0, 0, 5000]}}),
        "foot_deep": yaml.safe_dump({**GOOD, "initial": {"q": [0.0, -1.6, 0.0]}}),
        "rate_333": yaml.safe_dump({**GOOD, "duration": 3.0, "control_rate": 333}),
        "tol_unknown": yaml.safe_dump({**GOOD, "comparison": {"tolerances": {"foo": 1}}}),
        "tol_negative": yaml.safe_dump({**GOOD, "comparison": {"tolerances": {"rms": {"abs": -1}}}}),
    }  # fmt: skip
    if "ode" in registry.available():  # its settings are checked where it is installed
        sc["ode_erp"] = yaml.safe_dump({**GOOD, "backends": {"ode": {"erp": 5}}})
    files = {k: w(f"{k}.yaml", v) for k, v in sc.items()}
    files["latin1"] = wb("latin1.yaml", b"name: caf\xe9\n")
    if Path("/dev/zero").exists():  # no end: it was read until the process was killed
        files["dev_zero"] = "/dev/zero"
    if hasattr(os, "mkfifo"):  # opening it for reading blocked for ever
        os.mkfifo(d / "fifo.yaml")
        files["fifo"] = str(d / "fifo.yaml")
    files["dir"] = str(d)
    files["missing"] = str(d / "nope.yaml")
    files["huge_file"] = w("huge.yaml", "name: t\n" + "#" * 3_000_000)
    cases: list[tuple[str, list[str], set[int]]] = []
    for k, f in files.items():
        cases.append((f"validate/{k}", ["validate", f], {2}))
        # big_list is valid; rate_333 suits no engine's default sub-step (validate refuses it) but the fake
        # engine has no fixed step, so it runs: a run checks only the engines it loads
        cases.append((f"run/{k}", ["run", f, "--backends", "fake", "--out", str(d / "o" / k), "-q", "--no-preflight"],
                      {0} if k in ("big_list", "rate_333") else {2}))  # fmt: skip
    cases.append(("validate/good", ["validate", good], {0}))
    cases[cases.index(("validate/big_list", ["validate", files["big_list"]], {2}))] = (
        "validate/big_list",
        ["validate", files["big_list"]],
        {0},
    )  # valid: 20 force events 1 ms apart
    sets = ["duration=[0.3", "duration.x=1", "events.0.t=1", "events.5.t=1",
            "name=!!python/object/apply:os.system [ls]", "=1", "a..b=1", "duration=1e400", "duration=-1",
            "backends.nope.dt=1", "comparison.reference=pinochio",
            "physics.contact.Kp=[1,2]", "gains=5", "events={}", "duration=&a [*a]"]  # fmt: skip
    for i, s in enumerate(sets):
        cases.append((f"run/--set {s}", ["run", good, "--backends", "fake", "--out", str(d / "s" / str(i)), "-q",
                                         "--set", s], {2}))  # fmt: skip
    regular = w("regular", "x")
    out_missing_parent = str(Path(regular) / "sub")
    for cmd in (["run", good, "--backends", "fake"], ["sweep", str(ROOT / "scenarios/sweeps/gains.yaml")],
                ["bench", "--quick"], ["verify"], ["calibrate-contact"], ["reproduce"]):  # fmt: skip
        cases.append((f"{cmd[0]}/--out regular file", [*cmd, "--out", regular], {2}))
        cases.append((f"{cmd[0]}/--out under a file", [*cmd, "--out", out_missing_parent], {2}))
    for jobs in ("0", "-3"):
        cases.append((f"run/--jobs {jobs}", ["run", good, "--backends", "fake", "--jobs", jobs, "--out", str(d / "j")],
                       {2}))  # fmt: skip
        cases.append((f"sweep/--jobs {jobs}", ["sweep", str(ROOT / "scenarios/sweeps/gains.yaml"), "--jobs", jobs,
                                               "--out", str(d / "sj")], {2}))  # fmt: skip
    cases += [
        ("run/--backends ''", ["run", good, "--backends", "", "--out", str(d / "b")], {2}),
        ("run/--backends bogus", ["run", good, "--backends", "bogus", "--out", str(d / "b")], {2}),
        (
            "run/two scenarios one name",
            ["run", good, w("good2.yaml", yaml.safe_dump(GOOD)), "--backends", "fake", "--out", str(d / "tree"), "-q"],
            {2},
        ),  # fmt: skip
        (
            "sweep/--scheduler foo://bar",
            [
                "sweep",
                str(ROOT / "scenarios/sweeps/gains.yaml"),
                "--executor",
                "dask",
                "--scheduler",
                "foo://bar",
                "--out",
                str(d / "sw"),
            ],
            {2},
        ),  # fmt: skip
        (
            "sweep/dt abc",
            [
                "sweep",
                w(
                    "sw.yaml",
                    f"name: s\nscenario: {EFFORT}\nstudies:\n  - backends: [pinocchio]\n"
                    "    grid: {backends.*.dt: [abc]}\n    reference: {backend: pinocchio}\n",
                ),
                "--out",
                str(d / "sw2"),
            ],
            {2},
        ),  # fmt: skip
        ("model urdf/--params dir", ["model", "urdf", "--params", str(d), "--out", str(d / "l.urdf")], {2}),
        (
            "model urdf/--params missing",
            ["model", "urdf", "--params", str(d / "no.yaml"), "--out", str(d / "l.urdf")],
            {2},
        ),
        (
            "model urdf/--params malformed",
            ["model", "urdf", "--params", files["malformed"], "--out", str(d / "l.urdf")],
            {2},
        ),  # fmt: skip
        ("model urdf/--params latin1", ["model", "urdf", "--params", files["latin1"], "--out", str(d / "l.urdf")], {2}),
        ("model urdf/--out dir", ["model", "urdf", "--out", str(d)], {2}),
        ("model calibrate/--params bomb", ["model", "calibrate", "--params", files["bomb9"]], {2}),
        ("model fk/letters", ["model", "fk", "a", "b", "c"], {2}),
        ("model ik/nan", ["model", "ik", "nan", "nan", "nan"], {0, 1, 2}),
        ("doctor/bomb", ["doctor", files["bomb9"]], {2}),
        ("verify/--cases bogus", ["verify", "--cases", "bogus", "--out", str(d / "v")], {2}),
        (
            "calibrate-contact/--backends bogus",
            ["calibrate-contact", "--backends", "bogus", "--out", str(d / "c")],
            {2},
        ),
        ("reproduce/--frameworks bomb", ["reproduce", "--frameworks", files["bomb9"], "--out", str(d / "rp")], {2}),
        ("bench/bad scenario", ["bench", files["neg_kd"], "--out", str(d / "bn")], {2}),
        ("schema", ["schema"], {0}),
    ]
    # results readers
    run_dir = d / "run"
    cli.main(["run", good, "--backends", "fake", "--out", str(run_dir), "-q", "--no-compare", "--no-preflight"])
    corrupt = d / "corrupt"
    corrupt.mkdir()
    (corrupt / "run.json").write_bytes(b"\xff\xfe")
    trunc = d / "trunc"
    trunc.mkdir()
    (trunc / "run.json").write_text((run_dir / "run.json").read_text())
    (trunc / "fake.parquet").write_bytes((run_dir / "fake.parquet").read_bytes()[:100])
    notobj = d / "notobj"
    notobj.mkdir()
    (notobj / "run.json").write_text("[1, 2]")
    (d / "empty").mkdir()
    badmetrics = d / "badmetrics"
    badmetrics.mkdir()
    (badmetrics / "metrics.json").write_text('{"schema": "x"}')
    n = 21
    t = np.arange(n) * 1e-3
    log = pd.DataFrame({"t": t, **{f"q{i}": np.full(n, 1e308) for i in (1, 2, 3)}})
    big = w("big.csv", log.to_csv(index=False))
    nanlog = w(
        "nan.csv", pd.DataFrame({"t": t, **{f"q{i}": np.full(n, np.nan) for i in (1, 2, 3)}}).to_csv(index=False)
    )
    ms = w("ms.csv", pd.DataFrame({"t": t * 1000, **{f"q{i}": np.zeros(n) for i in (1, 2, 3)}}).to_csv(index=False))
    deg = w("deg.csv", pd.DataFrame({"t": t, **{f"q{i}": np.full(n, -57.0) for i in (1, 2, 3)}}).to_csv(index=False))
    for name, p in [("missing", d / "none"), ("file", Path(regular)), ("corrupt run.json", corrupt),
                    ("truncated parquet", trunc), ("run.json not an object", notobj), ("bad metrics", badmetrics),
                    ("empty dir", d / "empty")]:  # fmt: skip
        cases.append((f"compare/{name}", ["compare", str(p)], {2}))
        cases.append((f"check/{name}", ["check", str(p), "--baseline", str(run_dir)], {2}))
    for name, f, ok in [("1e308", big, {2}), ("nan-only", nanlog, {2}), ("ms", ms, {0}), ("degrees", deg, {0}),
                        ("missing", str(d / "x.csv"), {2}), ("latin1", files["latin1"], {2}),
                        ("dir", str(d), {2})]:  # fmt: skip
        cases.append((f"compare/--reference-log {name}", ["compare", str(run_dir), "--reference-log", f], ok))
    cases += [
        ("compare/--log-time-scale 0", ["compare", str(run_dir), "--reference-log", ms, "--log-time-scale", "0"], {2}),
        ("compare/--log-columns bad", ["compare", str(run_dir), "--reference-log", ms, "--log-columns", "x"], {2}),
        (
            "check/bad tolerances",
            ["check", str(run_dir), "--baseline", str(run_dir), "--tolerances", files["bomb9"]],
            {2},
        ),  # fmt: skip
        (
            "check/--summary missing folder",
            ["check", str(run_dir), "--baseline", str(run_dir), "--summary", str(d / "no" / "s.md")],
            {2},
        ),  # fmt: skip
    ]
    return cases


def run_case(argv: list[str], guard: bool = True) -> tuple[int | None, str, str]:
    """(exit status, stderr, stdout) of ``legbench ARGV`` in-process; with ``guard`` a hang (120 s, SIGALRM)
    is reported instead of waited on (the pytest wrapper runs without it: no wall-clock bound in tests)."""
    err, out = io.StringIO(), io.StringIO()
    if guard:
        signal.signal(signal.SIGALRM, _alarm)
        signal.alarm(120)
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
            try:
                status: int | None = cli.main(argv)
            except SystemExit as exc:  # argparse
                status = exc.code if isinstance(exc.code, int) else 2
    except Hang:
        return None, "hang", ""
    except BaseException:
        return None, "traceback", traceback.format_exc(limit=3)
    finally:
        if guard:
            signal.alarm(0)
    return status, err.getvalue(), out.getvalue()


def clean(cid: str, argv: list[str], ok: set[int], status: int | None, err: str) -> bool:
    """A case is handled cleanly: an expected exit status, no traceback, a message for a refusal, one line and
    no usage block for bad input (validate lists every problem, one line each), and a warning where the input
    is accepted."""
    lines = [ln for ln in err.splitlines() if ln.startswith(("legbench", "usage:"))]
    good = status in ok and "Traceback" not in err and (status in (0, 1) or len(lines) >= 1)
    if cid.endswith(("log ms", "log degrees")):  # accepted, with a warning giving the evidence
        good = good and "warning" in err
    if status == 2 and not argv[0] == "validate":  # argparse's errors too: one line, no usage block
        good = good and len([ln for ln in err.splitlines() if ln.startswith("legbench")]) == 1
        good = good and "usage:" not in err
    return good


def main() -> int:
    verbose = "-v" in sys.argv
    with tempfile.TemporaryDirectory() as tmp, fake_backend():
        cwd = os.getcwd()
        os.chdir(tmp)
        try:
            cases = build(Path(tmp))
            n_clean, bad = 0, []
            for cid, argv, ok in cases:
                status, err, extra = run_case(argv)
                good = clean(cid, argv, ok, status, err)
                if good:
                    n_clean += 1
                else:
                    bad.append((cid, status, (err or extra).strip().splitlines()[-3:]))
                if verbose:
                    print(f"{'ok ' if good else 'BAD'} {status!s:>4} {cid}: {err.strip().splitlines()[-1:] or ''}")
        finally:
            os.chdir(cwd)
    print(f"{len(cases)} cases, {n_clean} handled cleanly, {len(bad)} not")
    for cid, status, tail in bad:
        print(f"  NOT CLEAN {cid}: status {status}: {tail}")
    return 0 if not bad else 1


if __name__ == "__main__":
    sys.exit(main())
