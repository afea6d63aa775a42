"""The command line: compare with an imported log whose headers and time unit differ."""

from __future__ import annotations

import argparse
import gc
import importlib.metadata
import json
import os
import stat
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pandas as pd
import pytest
import yaml
from fakerun import scale, write_run

from legbench import backends, cli

SCENARIOS = Path(__file__).resolve().parent.parent / "scenarios"


def test_compare_imports_a_log_with_mapped_headers_in_milliseconds(tmp_path: Path) -> None:
    """Backend a's own log, renamed and in ms, imported with --log-columns and --log-time-scale 1e-3 and
    used as the reference: a deviates from it by exactly 0 in every measured signal."""
    run_dir = tmp_path / "fake"
    write_run(run_dir, {"ref": None, "a": scale(1.02)})
    df = pd.read_parquet(run_dir / "a.parquet").drop(columns=["controller"])
    df = df.rename(columns={"t": "time_ms", "q1": "hip_aa", "q2": "hip_fe", "q3": "knee"})
    df["time_ms"] *= 1000.0
    log = tmp_path / "hw.csv"
    df.to_csv(log, index=False)
    argv = ["compare", str(run_dir), "--reference-log", str(log), "--log-columns",
            "time_ms=t, hip_aa=q1, hip_fe=q2, knee=q3", "--log-time-scale", "1e-3", "--log-is-reference"]  # fmt: skip
    assert cli.main(argv) == 0
    rows = json.loads((run_dir / "metrics.json").read_text())["metrics"]
    ours = [r for r in rows if r["backend"] == "a" and r["metric"] == "sim_error_pct" and r["value"] is not None]
    assert {r["signal"] for r in ours} == {"q", "qd", "tau", "force"}
    assert all(r["value"] == pytest.approx(0.0, abs=1e-9) for r in ours)


def test_bad_log_column_mapping_is_a_one_line_error(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    run_dir = tmp_path / "fake"
    write_run(run_dir, {"ref": None, "a": scale(1.02)})
    assert cli.main(["compare", str(run_dir), "--reference-log", "x.csv", "--log-columns", "time_ms"]) == 2
    assert "--log-columns 'time_ms': expected HEADER=COLUMN" in capsys.readouterr().err


def test_compare_of_a_run_missing_a_log_says_so_and_exits_3(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A run directory whose run.json says a backend ran ok but whose log is gone: the report leaves that backend
    out (as a failed one), and the command says so on stderr and exits 3, as a run with a failed backend does (it
    said nothing and exited 0; the gap showed only inside report.md). In a tree, each such log is named."""
    tree = tmp_path / "tree"
    write_run(tree / "one", {"ref": None, "a": scale(1.02)}, name="one")
    write_run(tree / "two", {"ref": None, "a": scale(1.01)}, name="two")
    assert cli.main(["compare", str(tree)]) == 0
    (tree / "two" / "a.parquet").unlink()
    capsys.readouterr()
    assert cli.main(["compare", str(tree / "two")]) == 3
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"legbench: a missing: run.json says ok but a.parquet is not in {tree / 'two'}"]
    assert cli.main(["compare", str(tree)]) == 3
    assert "a.parquet is not in" in capsys.readouterr().err
    assert "backend 'a' missing" in (tree / "two" / "report.md").read_text()


def test_compare_of_a_run_with_a_failed_backend_says_so_and_exits_3(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A run whose backend failed (diverged): ``legbench run`` exited 3 naming it, ``legbench compare`` of the same
    directory exited 0 in silence. It exits 3 too, with the one line naming the run/backend; in a tree each."""
    tree = tmp_path / "tree"
    write_run(tree / "one", {"ref": None, "a": scale(1.02)}, name="one", failed={"b": "diverged at t = 0.1 s"})
    write_run(tree / "two", {"ref": None, "a": scale(1.01)}, name="two")
    capsys.readouterr()
    assert cli.main(["compare", str(tree / "two")]) == 0
    assert capsys.readouterr().err == ""
    assert cli.main(["compare", str(tree / "one")]) == 3
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["legbench: 1 run(s) did not finish ok (one/b); the others' results are compared"]
    assert cli.main(["compare", str(tree)]) == 3
    assert "(one/b)" in capsys.readouterr().err


def test_run_records_the_declared_abilities(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``legbench run`` end to end on one backend: exit 0, one log of 51 ticks (0.05 s at 1 kHz), and run.json
    holding the backend's declared integrator family and sub-step count (control period / dt) beside its settings."""
    scenario = Path(__file__).resolve().parents[1] / "scenarios" / "position.yaml"
    argv = ["run", str(scenario), "--backends", "pinocchio", "--set", "duration=0.05", "--set",
            "comparison.steady_window=0.01", "--out", str(tmp_path / "r"), "-q", "--no-compare",
            "--no-preflight"]  # fmt: skip
    assert cli.main(argv) == 0
    assert "pinocchio  ok" in capsys.readouterr().out
    info = json.loads((tmp_path / "r" / "run.json").read_text())["backends"]["pinocchio"]["info"]
    dt = info["dt"]  # the pinocchio sub-step the scenario sets [s]
    assert info["integrator_family"] == "euler" and info["sub_steps"] == round(1e-3 / dt) > 1
    assert len(pd.read_parquet(tmp_path / "r" / "pinocchio.parquet")) == 51


def _subcommands(parser: argparse.ArgumentParser) -> list[list[str]]:
    """Every subcommand path of ``parser`` (e.g. ["model", "fk"])."""
    paths: list[list[str]] = []
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, child in action.choices.items():
                paths.append([name])
                paths.extend([name, *rest] for rest in _subcommands(child))
    return paths


def test_every_subcommand_has_working_help(capsys: pytest.CaptureFixture[str]) -> None:
    """`legbench X --help` prints usage and exits 0 for every subcommand and sub-subcommand."""
    paths = _subcommands(cli.build_parser())
    assert {"run", "compare", "check", "doctor", "bench"} <= {p[0] for p in paths} and ["model", "fk"] in paths
    for path in paths:
        with pytest.raises(SystemExit) as exc:
            cli.main([*path, "--help"])
        assert exc.value.code == 0, path
        assert "usage: legbench" in capsys.readouterr().out


def test_version(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        cli.main(["--version"])
    assert exc.value.code == 0
    assert capsys.readouterr().out.startswith("legbench ")


def test_variants_run_exactly_the_listed_profile_and_contact_pairs(tmp_path: Path) -> None:
    """``--variant`` runs each scenario in exactly the listed (profile, contact mode) pairs, in one command (one
    pool): three directories per scenario, not the four of ``--profile both --contact-mode both``; each run.json
    records its own pair, and the matched native run is byte-identical to the same run made without --variant."""
    scenario = Path(__file__).resolve().parents[1] / "scenarios" / "position.yaml"
    common = ["--backends", "pinocchio", "--set", "duration=0.05", "--set", "comparison.steady_window=0.01",
              "-q", "--no-compare", "--no-preflight"]  # fmt: skip
    variants = ["--variant", "matched:native", "--variant", "matched:reference", "--variant", "engine-defaults:native"]
    argv = ["run", str(scenario), *common, "--jobs", "2", "--out", str(tmp_path / "tree"), *variants]
    assert cli.main(argv) == 0
    tree = tmp_path / "tree"
    assert sorted(p.name for p in tree.iterdir() if p.is_dir()) == [
        "position", "position__engine-defaults", "position__reference"]  # fmt: skip
    for name, profile, mode in (("position", "matched", "native"), ("position__reference", "matched", "reference"),
                                ("position__engine-defaults", "engine-defaults", "native")):  # fmt: skip
        meta = json.loads((tree / name / "run.json").read_text())
        assert (meta["scenario"]["profile"], meta["scenario"]["contact_mode"]) == (profile, mode), name
    assert cli.main(["run", str(scenario), *common, "--out", str(tmp_path / "one")]) == 0
    one = (tmp_path / "one" / "pinocchio.parquet").read_bytes()
    assert one == (tree / "position" / "pinocchio.parquet").read_bytes()


def test_the_pool_starts_before_the_preflight_and_stops_when_it_fails(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """With --jobs 2 the workers start while the pre-flight runs; a pre-flight that refuses the run (exit 2, its
    one line) leaves no worker running and nothing written."""
    from legbench import run
    from legbench.studies import doctor

    pools: list[Any] = []

    def start(jobs: int, tasks: int | None = None, backend_names: Any = None) -> Any:
        pool = real_start(jobs, tasks, backend_names)
        pools.append(pool)
        return pool

    def refuse(*_: Any) -> None:
        assert pools and pools[0] is not None  # started before the pre-flight
        raise doctor.ParityError("mujoco", "link2.mass", 0.5, 0.322, "kg")

    real_start = run.start_pool
    monkeypatch.setattr(run, "start_pool", start)
    monkeypatch.setattr(doctor, "preflight", refuse)
    scenario = Path(__file__).resolve().parents[1] / "scenarios" / "position.yaml"
    argv = ["run", str(scenario), "--backends", "pinocchio,mujoco", "--jobs", "2", "--out", str(tmp_path / "r"), "-q"]
    assert cli.main(argv) == 2
    assert "mujoco holds link2.mass = 0.5 kg" in capsys.readouterr().err
    procs = list((getattr(pools[0]._pool, "_processes", None) or {}).values()) if pools[0]._pool else []
    assert pools[0]._pool is None and not any(p.is_alive() for p in procs)
    assert not (tmp_path / "r").exists()


def test_a_single_run_starts_no_pool(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """One scenario on one backend runs in this process even with --jobs 2: no worker pool is started."""
    from legbench import run

    started: list[int] = []
    monkeypatch.setattr(run, "start_pool", lambda jobs: started.append(jobs))
    scenario = Path(__file__).resolve().parents[1] / "scenarios" / "position.yaml"
    argv = ["run", str(scenario), "--backends", "pinocchio", "--jobs", "2", "--set", "duration=0.05", "--set",
            "comparison.steady_window=0.01", "--out", str(tmp_path / "r"), "-q", "--no-compare"]  # fmt: skip
    assert cli.main(argv) == 0
    assert started == [] and (tmp_path / "r" / "pinocchio.parquet").is_file()


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--variant", "matched:bogus"], "argument --variant: 'matched:bogus': expected PROFILE:MODE"),
        (["--variant", "fast:native"], "argument --variant: 'fast:native': expected PROFILE:MODE"),
        (["--variant", "matched"], "argument --variant: 'matched': expected PROFILE:MODE"),
        (["--variant", "matched:native", "--contact-mode", "both"], "--variant: give the profile and contact mode"),
        (["--variant", "matched:native", "--variant", "matched:native"], "--variant matched:native: given twice"),
        # a value given by --set and by the option that sets it: one would win in silence (it ran native, matched)
        (["--set", "physics.contact_mode=reference", "--contact-mode", "native"],
         "--set: physics.contact_mode: also given by --contact-mode native; give it in one place"),
        (["--set", "profile=engine-defaults", "--profile", "matched"],
         "--set: profile: also given by --profile matched; give it in one place"),
        (["--set", "physics={contact_mode: reference}", "--variant", "matched:native"],
         "--set: physics: also given by --variant; give it in one place"),
        # a mapping above the key that does not hold it sets something else: not refused for it (the run's error)
        (["--set", "physics={gravity: -1}", "--contact-mode", "native"], "physics.gravity: must be >= 0"),
    ],
)  # fmt: skip
def test_a_bad_variant_is_a_one_line_error_before_anything_runs(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], extra: list[str], message: str
) -> None:
    """A malformed ``--variant``, or one beside --profile/--contact-mode, or a ``--set`` of what an option sets:
    exit status 2, the problem on one line of stderr, nothing written."""
    scenario = Path(__file__).resolve().parents[1] / "scenarios" / "position.yaml"
    argv = ["run", str(scenario), "--backends", "pinocchio", "--out", str(tmp_path / "r"), "-q", *extra]
    try:
        rc = cli.main(argv)
    except SystemExit as exc:  # argparse's own usage error
        rc = int(exc.code or 0)
    assert rc == 2
    err = capsys.readouterr().err
    assert message in err and len([line for line in err.splitlines() if message in line]) == 1
    assert not (tmp_path / "r").exists()


def test_top_level_help_lists_every_subcommand_with_its_own_help_without_importing_them() -> None:
    """`legbench --help` lists the subcommands from cli.SUMMARY, which must equal each registrar's own help
    (the full parser's), and imports none of their modules (0.05 s instead of 0.8 s)."""
    full = next(a for a in cli.build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    helps = {c.dest: c.help for c in full._choices_actions}
    assert helps == cli.SUMMARY and list(cli.SUMMARY) == list(cli.COMMANDS)
    code = (
        "import sys, contextlib, io\n"
        "from legbench import cli\n"
        "with contextlib.redirect_stdout(io.StringIO()) as out, contextlib.suppress(SystemExit):\n"
        "    cli.main(['--help'])\n"
        "mods = {m.split(':')[0] for m in cli.COMMANDS.values()} - {'legbench.cli'}\n"
        "print(sorted(m for m in mods if m in sys.modules), all(n in out.getvalue() for n in cli.COMMANDS))\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "[] True", done.stdout + done.stderr


def test_an_interrupted_study_says_nothing_was_written(monkeypatch: pytest.MonkeyPatch, tmp_path: Path,
                                                       capsys: pytest.CaptureFixture[str]) -> None:  # fmt: skip
    """Ctrl-C during `legbench verify` (which writes only when every case is done): exit 130, one stderr line
    saying nothing was written, and no output directory; a run keeps what finished, and says so."""
    from legbench.studies import verify

    def interrupted(*args: object, **kwargs: object) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr(verify, "verify", interrupted)
    assert cli.main(["verify", "--out", str(tmp_path / "v"), "--backends", "pinocchio"]) == 130
    err = capsys.readouterr().err
    assert err == "legbench: interrupted; nothing was written (it writes when all is done)\n"
    assert not (tmp_path / "v").exists()
    assert "what finished is kept" in cli._INTERRUPTED["run"] and "what finished is kept" in cli._INTERRUPTED["sweep"]


def test_an_interrupt_python_could_not_raise_still_stops_the_command(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Ctrl-C that lands in a callback Python cannot raise from (during an import: importlib's module-lock
    weakref callback; here an object's __del__, reported the same way through sys.unraisablehook) still ends the
    command with exit 130 and the interrupt's one line, not "Exception ignored" and a run carried to its end
    (measured with Drake's import: 1 of 30 Ctrl-Cs sent 0.24-0.36 s after the start ran to exit status 0)."""
    from legbench.studies import verify

    class RaisesWhenDropped:
        def __del__(self) -> None:
            raise KeyboardInterrupt

    finished = []

    def swallowed(*args: object, **kwargs: object) -> None:
        RaisesWhenDropped()  # dropped at once: CPython can only report the interrupt as unraisable
        deadline = time.monotonic() + 60.0  # an upper bound, never a wait: the interrupt ends the loop
        while time.monotonic() < deadline:  # the study's work goes on
            pass
        finished.append(True)

    monkeypatch.setattr(verify, "verify", swallowed)
    hook = sys.unraisablehook
    assert cli.main(["verify", "--out", str(tmp_path / "v"), "--backends", "pinocchio"]) == 130
    assert not finished
    assert capsys.readouterr().err == "legbench: interrupted; nothing was written (it writes when all is done)\n"
    assert sys.unraisablehook is hook  # restored


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["run", "x.yaml", "--jobs", "x"], "legbench run: error: argument --jobs: invalid int value: 'x'"),
        (["model", "fk", "a", "0", "0"], "legbench model fk: error: argument Q: 'a' is not a number"),
        (["verify", "--cases", ""], "--cases '': names no case"),
        (["verify", "--backends", " , "], "--backends ' , ': names no backend"),
        (["doctor", "x.yaml", "--backends", ""], "--backends '': names no backend"),
        (["sweep", "x.yaml", "--executor", "dask", "--scheduler", "bogus"], "--scheduler bogus: expected an address"),
        (["sweep", "x.yaml", "--executor", "dask", "--scheduler", "tcp://host"], "--scheduler tcp://host: expected"),
        (["run", "x.yaml", "--out", ""], "--out '': an empty path"),  # it skipped the overwrite guard
        (["model", "fk", "nan", "0", "0"], "argument Q: 'nan' is not a finite number"),  # printed x = nan
        (["model", "ik", "0.1", "inf", "0"], "argument P: 'inf' is not a finite number"),
        (["bench", "x.yaml", "--duration", "inf"], "argument --duration: 'inf' is not a finite number"),
        (["compare", "d", "--log-time-scale", "-1"], "argument --log-time-scale: '-1' must be > 0"),
        (["compare", "d", "--log-columns", "a=q1"], "--log-columns: need --reference-log"),  # was ignored
        (
            ["compare", "d", "--reference-log", "h.csv", "--ros-force-sign", "-1"],
            "--ros-force-sign: need --reference-log naming a ROS bag",
        ),  # ignored for a CSV
        (
            ["compare", "d", "--reference-log", "h.csv", "--log-columns", "a=q1,a=q2"],
            "--log-columns 'a=q1,a=q2': header 'a' is mapped twice (q1 and q2); map each header once",
        ),  # q2 won
        (["check", "d", "--baseline", "b", "--summary", "s.md", "--junit", "s.md"], "name the same file"),
    ],
)
def test_bad_options_are_one_line_errors(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], argv: list[str], message: str
) -> None:
    """argparse's own errors (a usage block, then the error) and empty lists (which never mean 'all') are one
    line on stderr, exit status 2, before anything runs."""
    try:
        rc = cli.main([*argv, "--out", str(tmp_path / "o")] if argv[0] in ("verify", "sweep") else argv)
    except SystemExit as exc:  # argparse exits from parse_args
        rc = int(exc.code or 0)
    assert rc == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and message in err, err
    assert not (tmp_path / "o").exists()


def test_python_dash_m_runs_the_command() -> None:
    """``python -m legbench`` is the ``legbench`` command."""
    out = subprocess.run([sys.executable, "-m", "legbench", "--version"], capture_output=True, text=True, check=True)
    assert out.stdout.startswith("legbench ")


def test_the_command_freezes_the_heap_before_the_interpreter_exits(monkeypatch: pytest.MonkeyPatch) -> None:
    """The console script and ``python -m legbench`` run :func:`cli.entry`: main's exit status, then the
    heap frozen, so the interpreter's final garbage collections skip what the command leaves (0.5 s of the
    exit after a sweep). main alone, as tests and scripts call it in their own processes, freezes nothing."""
    scripts = [e.value for e in importlib.metadata.entry_points(group="console_scripts") if e.name == "legbench"]
    assert scripts == ["legbench.cli:entry"]
    effort = str(Path(__file__).resolve().parents[1] / "scenarios" / "effort.yaml")
    before = gc.get_freeze_count()
    assert cli.main(["validate", effort]) == 0
    assert gc.get_freeze_count() == before
    monkeypatch.setattr(sys, "argv", ["legbench", "validate", effort])
    try:
        assert cli.entry() == 0
        assert gc.get_freeze_count() > before
    finally:
        gc.unfreeze()
    probe = ("import gc, runpy, sys\n"
             f"sys.argv = ['legbench', 'validate', {effort!r}]\n"
             "try:\n    runpy.run_module('legbench', run_name='__main__')\n"
             "except SystemExit as e:\n    print(e.code, gc.get_freeze_count() > 0)\n")  # fmt: skip
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True)
    assert out.stdout.split()[-2:] == ["0", "True"], out.stdout


def test_several_scenarios_are_not_written_into_a_single_runs_directory(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Two scenarios make a tree of run directories; --out naming one run's directory would nest the tree in it
    and rewrite that run's pages: refused in one line, exit 2, the run untouched."""
    run_dir = write_run(tmp_path / "one", {"ref": None, "a": scale(1.01)})
    before = {p.name: p.read_bytes() for p in run_dir.iterdir()}
    scenarios = Path(__file__).resolve().parents[1] / "scenarios"
    argv = ["run", str(scenarios / "position.yaml"), str(scenarios / "ellipse.yaml"), "--backends", "pinocchio",
            "--out", str(run_dir), "-q"]  # fmt: skip
    assert cli.main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "holds one run" in err
    assert {p.name: p.read_bytes() for p in run_dir.iterdir()} == before


def test_validate_knows_the_reproduce_framework_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """`legbench validate scenarios/*.yaml` checks the bundled framework file as one (it was read as a scenario
    and refused); a bad framework file is one line naming the key, exit 2."""
    frameworks = Path(__file__).resolve().parents[1] / "scenarios" / "reproduce.yaml"
    assert cli.main(["validate", str(frameworks)]) == 0
    assert "ok (frameworks: 3, tasks: 5)" in capsys.readouterr().out
    bad = tmp_path / "fw.yaml"
    bad.write_text(frameworks.read_text() + "\nbogus: 1\n")
    assert cli.main(["validate", str(bad)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "bogus" in err and str(bad) in err


@pytest.mark.parametrize(
    "text",
    ["sim_error_pc:\n  abs: 1\n", "rmse: {abs: 1}\n", "rms: {abs: 1}\nscenarios:\n  effort:\n    rms: {rel: -1}\n",
     "scenarios:\n  my.task:\n    max_sim_error_pct: 5\n"],
)  # fmt: skip
def test_validate_takes_a_tolerance_file_as_check_does(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], text: str
) -> None:
    """A tolerance file whose every key was misspelt (``sim_error_pc``) was taken for a scenario by validate: "unknown
    key; valid keys: name, description, duration..." and "missing required key 'name'", two lines; and a tolerance
    file's errors from validate had no line. Now validate says what ``legbench check --tolerances`` says, one line
    with the line number; under a scenario named with a dot (``my.task``), the entry's own line (3), where the
    key re-split at every dot named line 1."""
    from legbench import check
    from legbench.exceptions import ScenarioError

    tol = tmp_path / "tol.yaml"
    tol.write_text(text)
    with pytest.raises(ScenarioError) as exc:
        check.load_tolerances(tol)
    assert exc.value.line is not None
    if "my.task" in text:
        assert exc.value.line == 3
    assert cli.main(["validate", str(tol)]) == 2
    assert capsys.readouterr().err == f"legbench: error: {exc.value}\n"


def test_validate_takes_a_leg_parameter_file_as_one(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """`legbench validate models/leg.yaml` printed one "unknown key" line per section of the leg file and "missing
    required key 'name'", exit 2. Now it is checked as the leg parameter file it is (as --model reads it) and the
    line says which option takes it; a bad one is the model's one line."""
    leg = Path(__file__).resolve().parents[1] / "models" / "leg.yaml"
    assert cli.main(["validate", str(leg)]) == 0
    assert capsys.readouterr().out == f"{leg}: ok (a leg parameter file: give it to legbench --model {leg}, or " \
                                      "LEGBENCH_MODEL)\n"  # fmt: skip
    bad = tmp_path / "leg.yaml"
    bad.write_text(leg.read_text().replace("R_foot", "R_fot"))
    assert cli.main(["validate", str(bad)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"{bad}: geometry.R_fot" in err and "missing required key" not in err


def test_compare_of_a_regular_file_says_it_is_a_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """`legbench compare FILE` says FILE is a file, not a results directory (it said "no such results
    directory"), in one line, exit 2."""
    f = tmp_path / "afile"
    f.write_text("x")
    assert cli.main(["compare", str(f)]) == 2
    err = capsys.readouterr().err
    assert err == f"legbench: error: {f}: is a file, not a results directory (give a run directory or a tree)\n"


def _option(parser: argparse.ArgumentParser, path: list[str], dest: str) -> argparse.Action:
    """The action of option ``dest`` of the subcommand at ``path`` (e.g. ["model", "calibrate"])."""
    for name in path:
        sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
        parser = sub.choices[name]
    return next(a for a in parser._actions if a.dest == dest)


def test_help_states_the_defaults_and_what_options_do() -> None:
    """Every option named here says its default in its help (they said none), `model calibrate --params` has a
    help text (it had none), `model urdf --out` no longer claims models/leg.urdf for every --params, and `check`
    says an existing --summary/--junit file needs --force."""
    parser = cli.build_parser()
    for path, dest, default in ((["compare"], "lag", "default off"), (["compare"], "log_time_scale", "default 1"),
                                (["completion"], "shell", "default bash"),
                                (["model", "calibrate"], "params", "default: the active model"),
                                (["model", "urdf"], "params", "default: the active model")):  # fmt: skip
        assert default in (_option(parser, path, dest).help or ""), (path, dest)
    assert "never the bundled model's" in (_option(parser, ["model", "urdf"], "out").help or "")
    for dest in ("summary", "junit"):
        assert "replaced only with --force" in (_option(parser, ["check"], dest).help or ""), dest


def test_a_run_whose_engine_refuses_the_control_rate_names_the_scenario_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """control_rate 333 Hz (3 s: 999 ticks) with Pinocchio's default 50 us sub-step, which does not divide
    1/333 s: the run refuses it in one line that names the scenario file and control_rate (the key the file set;
    it blamed backends.pinocchio.dt, which the file never set, where legbench validate named control_rate) with the
    engine's key, exit 2, nothing written; with a sub-step that divides the period it runs."""
    sc = tmp_path / "r333.yaml"
    sc.write_text("name: r333\nduration: 3.0\ncontrol_rate: 333\nevents:\n  - {t: 0, position: {joint: [0, 0, 0]}}\n")
    out = tmp_path / "o"
    assert cli.main(["run", str(sc), "--backends", "pinocchio", "--out", str(out), "-q", "--no-compare"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert (
        len(err) == 1
        and f"{sc}:3: control_rate: 333 Hz does not suit the default (or profile) sub-step of "
        "pinocchio: backends.pinocchio.dt: 5e-05 s does not divide the control period"
        in err[0]
    )
    assert not out.exists()
    argv = ["run", str(sc), "--backends", "pinocchio", "--out", str(out), "-q", "--no-compare",
            "--set", f"backends.pinocchio.dt={1 / 333 / 60!r}"]  # fmt: skip
    assert cli.main(argv) == 0


def _framework_file(tmp_path: Path, frameworks: str, tasks: str) -> Path:
    scenarios = Path(__file__).resolve().parents[1] / "scenarios"
    for name in ("position", "effort"):
        (tmp_path / f"{name}.yaml").write_text((scenarios / f"{name}.yaml").read_text())
    (tmp_path / "bad.yaml").write_text("name: bad\nduration: -1\nevents: [{t: 0, position: {joint: [0, 0, 0]}}]\n")
    fw = tmp_path / "fw.yaml"
    fw.write_text(f"frameworks:\n{frameworks}tasks:\n{tasks}")
    return fw


_FW = "  - {name: Simscape, backend: pinocchio, profile: ode45}\n"


@pytest.mark.parametrize(
    ("frameworks", "tasks", "key", "words"),
    [
        # validate said ok; reproduce then refused the task's scenario, naming neither the framework file nor its key
        (_FW, "  - {file: bad.yaml, tables: [force]}\n", "tasks[0].file", "bad.yaml:2: duration: must be > 0"),
        (_FW, "  - {file: fw.yaml, tables: [force]}\n", "tasks[0].file", "is a framework file"),
        # two tasks of one scenario ran into one directory, the second over the first
        (_FW, "  - {file: effort.yaml, tables: [force]}\n  - {file: effort.yaml, tables: [steady]}\n",
         "tasks[1].file", "'effort' is task 0's too"),
        # two frameworks of one name: the tables' rows and columns could not be told apart
        (_FW + "  - {name: Simscape, backend: mujoco, profile: matched}\n",
         "  - {file: effort.yaml, tables: [force]}\n", "frameworks[1].name", "names another framework already"),
        (_FW, "  - {file: effort.yaml, tables: [force, force]}\n", "tasks[0].tables[1]", "given twice"),
        (_FW, "  - {file: 12, tables: [force]}\n", "tasks[0].file", "expected the path of a scenario file"),
        # a scenario given as the framework file: 'comparison: unknown key; valid keys: frameworks, ...'
        ("", "", "", "is a scenario (it has 'events'), not a framework file: run it with legbench run"),
    ],
)  # fmt: skip
def test_validate_refuses_a_framework_file_that_reproduce_cannot_run(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], frameworks: str, tasks: str, key: str, words: str
) -> None:
    """`legbench validate` and `legbench reproduce` refuse in one line, naming the framework file and the key,
    exit 2, nothing written."""
    fw = _framework_file(tmp_path, frameworks, tasks)
    if not frameworks:
        fw = tmp_path / "effort.yaml"
    out = tmp_path / "out"
    for argv in (["validate", str(fw)], ["reproduce", "--frameworks", str(fw), "--out", str(out), "--backends",
                                        "none", "--duration", "0.01", "-q"]):  # fmt: skip
        if argv[0] == "validate" and not frameworks:
            continue  # validate takes a scenario for one
        assert cli.main(argv) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and f"{fw}:" in err and (f": {key}: " in err or not key) and words in err, err
    assert not out.exists()


@pytest.mark.parametrize(("key", "value"), [("description", "[]"), ("description", "0"), ("label", "[]")])
def test_sweep_text_keys_that_are_no_text_are_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], key: str, value: str
) -> None:
    """A sweep's ``description: []`` or a study's ``label: 0`` was read as empty text (``or ""``)."""
    effort = Path(__file__).resolve().parents[1] / "scenarios" / "effort.yaml"
    sw = tmp_path / "sw.yaml"
    top = f"description: {value}\n" if key == "description" else ""
    label = f"label: {value}, " if key == "label" else ""
    sw.write_text(f"name: s\n{top}scenario: {effort}\nstudies:\n  - {{{label}backends: [pinocchio], "
                  "reference: {backend: pinocchio}}\n")  # fmt: skip
    assert cli.main(["validate", str(sw)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"{key}: expected text" in err


@pytest.mark.parametrize(("path", "words"), [("/dev/null", "is not a regular file"), (".", "is a directory")])
def test_a_model_that_is_no_file_says_what_it_is(capsys: pytest.CaptureFixture[str], path: str, words: str) -> None:
    """``--model /dev/null`` said 'no such parameter file' of a path that exists."""
    if not Path(path).exists():
        pytest.skip(f"no {path} here")
    assert cli.main(["--model", path, "model", "check"]) == 2
    assert capsys.readouterr().err == f"legbench: error: --model {path}: {words}\n"


def test_a_model_variable_naming_no_regular_file_is_refused_before_it_is_read(tmp_path: Path) -> None:
    """``LEGBENCH_MODEL`` naming a FIFO (or /dev/zero) was read on import, to hash it for the URDF's name: the
    command blocked for ever (/dev/zero: read until the kernel killed the process). One line naming the variable,
    exit 2, at once (a fresh process: the import is what read it)."""
    import os

    fifo = tmp_path / "leg.yaml"
    os.mkfifo(fifo)
    env = {**os.environ, "LEGBENCH_MODEL": str(fifo)}
    done = subprocess.run([sys.executable, "-m", "legbench", "model", "check"], capture_output=True, text=True,
                          env=env, timeout=120)  # fmt: skip
    assert done.returncode == 2, done.stderr[-500:]
    assert done.stderr == f"legbench: error: LEGBENCH_MODEL={fifo}: is not a regular file\n"


def test_model_urdf_refuses_a_params_path_that_is_no_file_before_hashing_it(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """``model urdf --params /dev/zero`` (no --out) hashed the whole file to name the URDF before reading it as
    YAML, and /dev/zero has no end (a FIFO blocks): the file is refused unread where its URDF is named
    (model.param_bytes, the YAML reader's checks), one line, exit 2."""
    fifo = tmp_path / "p.yaml"
    import os

    os.mkfifo(fifo)
    assert cli.main(["model", "urdf", "--params", str(fifo)]) == 2
    assert capsys.readouterr().err == f"legbench: error: {fifo}: is a FIFO, not a regular file (a leg parameter " \
                                      "file is read only from one)\n"  # fmt: skip


LEG_YAML = Path(__file__).resolve().parents[1] / "models" / "leg.yaml"


def test_model_urdf_never_writes_over_its_parameter_file_nor_a_file_it_did_not_generate(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``model urdf --out FILE`` replaced any FILE, its own parameter file included (the leg's YAML became XML):
    the parameter file is refused even with --force, another existing file without a legbench stamp unless
    --force, one line, exit 2, the file untouched; a URDF generated before is regenerated in place."""
    params = tmp_path / "mine.yaml"
    params.write_bytes(LEG_YAML.read_bytes())
    mine = tmp_path / "notes.urdf"
    mine.write_text("precious")
    for extra in ([], ["--force"]):
        assert cli.main(["model", "urdf", "--params", str(params), "--out", str(params), *extra]) == 2
        assert capsys.readouterr().err == (f"legbench: error: --out {params}: is the parameter file the URDF is "
                                           "generated from; choose another file\n")  # fmt: skip
    assert params.read_bytes() == LEG_YAML.read_bytes()
    assert cli.main(["model", "urdf", "--params", str(params), "--out", str(mine)]) == 2
    assert capsys.readouterr().err == (f"legbench: error: --out {mine}: exists and is not a URDF legbench generated; "
                                       "choose another file, or pass --force to replace it\n")  # fmt: skip
    assert mine.read_text() == "precious"
    out = tmp_path / "leg.urdf"
    assert cli.main(["model", "urdf", "--params", str(params), "--out", str(out)]) == 0
    first = out.read_bytes()
    assert cli.main(["model", "urdf", "--params", str(params), "--out", str(out)]) == 0  # its own: regenerated
    assert out.read_bytes() == first
    assert cli.main(["model", "urdf", "--params", str(params), "--out", str(mine), "--force"]) == 0
    assert mine.read_bytes() == first


def test_a_study_out_that_is_a_run_directory_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``legbench reproduce --out RUN`` (RUN an existing run directory) wrote its task runs and pages into that
    run's directory, exit 0: refused before any work, one line, exit 2, the run untouched."""
    run_dir = write_run(tmp_path / "one", {"ref": None, "a": scale(1.01)})
    before = sorted(p.name for p in run_dir.iterdir())
    argv = ["reproduce", "--out", str(run_dir), "--backends", "none", "--duration", "0.01", "--no-report", "-q"]
    assert cli.main(argv) == 2
    err = capsys.readouterr().err
    assert err == f"legbench: error: --out {run_dir}: a run directory, which holds one run; choose another --out\n"
    assert sorted(p.name for p in run_dir.iterdir()) == before


@pytest.mark.parametrize(
    ("extra", "study", "key", "words"),
    [
        # every error metric undefined (NaN), the sweep exited 0
        ("skip: 5.0\n", "backends: [pinocchio]", "skip", "5 s skips the whole of the runs (3 s)"),
        # each run a second table row and a second point of the fit
        ("", "backends: [pinocchio, mujoco, pinocchio]", "studies[0].backends[2]", "pinocchio given twice"),
    ],
)
def test_a_sweep_that_would_measure_nothing_or_twice_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], extra: str, study: str, key: str, words: str
) -> None:
    effort = Path(__file__).resolve().parents[1] / "scenarios" / "effort.yaml"
    sw = tmp_path / "sw.yaml"
    sw.write_text(f"name: s\nscenario: {effort}\n{extra}studies:\n  - {{{study}, grid: {{backends.*.dt: [1.0e-4]}}, "
                  "reference: {set: {backends.*.dt: 5.0e-5}}}\n")  # fmt: skip
    for argv in (["validate", str(sw)], ["sweep", str(sw), "--out", str(tmp_path / "o"), "--jobs", "1", "-q"]):
        assert cli.main(argv) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and f"{sw}:" in err and f": {key}: {words}" in err, err
    assert not (tmp_path / "o").exists()


def test_an_unknown_backend_names_the_backends_option(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """``legbench run SCENARIO --backends bogus`` said "backend 'bogus' is not available", naming no option: one
    line naming ``--backends`` and the name, with the backends available here (and, for one legbench knows
    whose engine is missing, what to install), exit 2."""
    from legbench import backends

    effort = Path(__file__).resolve().parents[1] / "scenarios" / "effort.yaml"
    here = ", ".join(sorted(backends.available()))
    assert cli.main(["run", str(effort), "--backends", "bogus"]) == 2
    assert capsys.readouterr().err == f"legbench: error: --backends bogus: unknown backend; available here: {here}\n"
    monkeypatch.setitem(backends.BUILTIN, "ghostengine", ("legbench.backends.ghostengine_", "G", "ghostengine"))
    assert cli.main(["run", str(effort), "--backends", "pinocchio,ghostengine"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("legbench: error: --backends ghostengine: not installed here (pip install ghostengine")
    assert err.endswith(f"; available here: {here}\n") and err.count("\n") == 1


def test_compare_jobs_beyond_the_pages_start_no_more_workers_than_pages(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``legbench compare TREE --jobs 8`` for a tree of two runs made a pool of 8 workers: it is as large as the
    pages, at most, and no more workers than that are started."""
    from concurrent.futures import ProcessPoolExecutor

    from legbench import report

    for name in ("a", "b"):
        write_run(tmp_path / "tree" / name, {"ref": None, "x": scale(1.01)}, name=name, duration=0.2, steady_window=0.1)
    made: list[Any] = []
    spawned: list[int] = []
    real_make, real_spawn = report.make_executor, ProcessPoolExecutor._spawn_process  # type: ignore[attr-defined]

    def make(*args: Any, **kwargs: Any) -> Any:
        made.append(real_make(*args, **kwargs))
        return made[-1]

    def spawn(self: Any) -> None:
        spawned.append(1)
        real_spawn(self)

    monkeypatch.setattr(report, "make_executor", make)
    monkeypatch.setattr(ProcessPoolExecutor, "_spawn_process", spawn)
    assert cli.main(["compare", str(tmp_path / "tree"), "--jobs", "8"]) == 0
    assert [ex.jobs for ex in made] == [2] and 1 <= len(spawned) <= 2
    assert (tmp_path / "tree" / "a" / "report.html").is_file() and (tmp_path / "tree" / "report.html").is_file()


def test_backends_lists_what_runs_here_plug_ins_included_and_how_to_install_the_rest(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """A newcomer had no command to list the backends (`legbench backends` was an invalid choice): it lists every
    available one with its origin and profiles, a plug-in by its class, and a missing engine with its install
    command, one line each, exit 0."""
    from fakes import FakeBackend

    from legbench import backends

    reg, missing = backends._registry, dict(backends._MISSING)

    def registry() -> dict[str, type[backends.Backend]]:
        found = {k: v for k, v in reg().items() if k != "dart"} | {"fake": FakeBackend}
        backends._MISSING["dart"] = "pip install dartpy (No module named 'dartpy')"
        return found

    monkeypatch.setattr(backends, "_registry", registry)
    monkeypatch.setattr(backends, "_MISSING", missing)
    assert cli.main(["backends"]) == 0
    lines = {line.split()[0]: line for line in capsys.readouterr().out.splitlines()}
    # a record of an engine no longer known (a built-in or plug-in another test planted and removed) is not listed
    plugins = {ep.name for ep in importlib.metadata.entry_points(group="legbench.backends")}
    assert set(lines) == {*reg(), "fake", *(set(missing) & plugins)}
    assert "built-in; profiles: matched, engine-defaults, ode45; integrators: euler, rk4, rk45, dop853 (matched: " \
           "euler)" in lines["pinocchio"]  # fmt: skip
    assert "plug-in fakes:FakeBackend; profiles: matched, engine-defaults" in lines["fake"]
    assert lines["dart"].endswith("not available: pip install dartpy (No module named 'dartpy')")


# --------------------------------------------------------------------------- #
# Errors whose wording the Python API replaces by its arguments' (test_api.py): on the command line they name the
# options, byte for byte as before.

POSITION = Path(__file__).resolve().parents[1] / "scenarios" / "position.yaml"


@pytest.mark.parametrize("holds", ["a foreign file", "a corrupt run.json", "another scenario's run", "a foreign tree"])
def test_a_refused_out_names_the_option(holds: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """results.check_out_dir (through run.check_outs) and results.check_out_tree (through run.check_tree, with
    --contact-mode both), before anything runs: "choose another --out" (the API's: "choose another out")."""
    out = tmp_path / "r"
    out.mkdir()
    mode = ["--contact-mode", "both"] if holds == "a foreign tree" else []
    if holds in ("a foreign file", "a foreign tree"):
        (out / "notes.txt").write_text("mine")
    elif holds == "a corrupt run.json":
        (out / "run.json").write_text("{")
    else:
        write_run(out, {"ref": None, "a": scale(1.01)})  # scenario 'fake'
    argv = ["run", str(POSITION), "--backends", "pinocchio", "--out", str(out), *mode, "-q", "--no-compare"]
    assert cli.main(argv) == 2
    why = {
        "a foreign file": "not empty and not a legbench run directory (it holds notes.txt); choose another --out",
        "a corrupt run.json": "its run.json is unreadable or corrupt (not written by legbench); choose another --out "
        "or remove it",
        "another scenario's run": "holds results of scenario 'fake', not 'position'; choose another --out or remove it",
        "a foreign tree": "not empty and not a legbench results tree directory (it holds notes.txt); choose another "
        "--out",
    }[holds]
    assert capsys.readouterr().err == f"legbench: error: {out}: {why}\n"


@pytest.mark.parametrize(
    ("setting", "message"),
    [
        ("events[0].t=0.1", "--set: events[0].t: a list item is written with a dot: events.0.t"),
        ("events.7.t=0.1", "--set: events.7.t: 'events' is a list of 1: '7' is not an index of it"),
        ("duration.x=0.1", "--set: duration.x: 'duration' is 3.0, not a mapping"),
        ("duration=soon", f"{POSITION}: duration: expected a number, got 'soon' (from --set duration)"),
    ],
)
def test_an_override_error_names_the_set_option(
    setting: str, message: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """yamlfile.set_key and YamlContext.error through scenario.load: "--set" (the API's: "overrides")."""
    argv = ["run", str(POSITION), "--backends", "pinocchio", "--set", setting, "--out", str(tmp_path / "r"), "-q"]
    assert cli.main(argv) == 2
    assert capsys.readouterr().err == f"legbench: error: {message}\n"


def test_log_errors_name_the_options_of_compare(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], caplog: pytest.LogCaptureFixture
) -> None:
    """legbench.logs through ``legbench compare --reference-log``: two header columns of one legbench column and none
    for q1 name --log-columns (and the API's column_map), a log in ms is a warning naming --log-time-scale 1e-3
    (the API's: column_map, column_map={...}, log_time_scale=1e-3)."""
    run_dir = write_run(tmp_path / "fake", {"ref": None, "a": scale(1.02)})
    df = pd.read_parquet(run_dir / "a.parquet").drop(columns=["controller"])
    dup, none, ms = tmp_path / "dup.csv", tmp_path / "none.csv", tmp_path / "ms.csv"
    df.assign(**{"q1 [rad]": df["q1"]}).to_csv(dup, index=False)
    df.rename(columns={"q1": "hip"}).to_csv(none, index=False)
    df.assign(t=df["t"] * 1000.0).to_csv(ms, index=False)
    assert cli.main(["compare", str(run_dir), "--reference-log", str(dup)]) == 2
    assert capsys.readouterr().err == f"legbench: error: {dup}: several header columns map to ['q1']; choose one " \
                                      "with --log-columns (column_map in the Python API)\n"  # fmt: skip
    assert cli.main(["compare", str(run_dir), "--reference-log", str(none)]) == 2
    header = ["t", "hip", *df.columns[2:]]
    assert capsys.readouterr().err == f"legbench: error: {none}: no column matches ['q1'] in the header {header}; " \
                                      "map them with --log-columns 'theirs=t, ...' (column_map in the Python " \
                                      "API)\n"  # fmt: skip
    with caplog.at_level("WARNING", logger="legbench.logs"):
        assert cli.main(["compare", str(run_dir), "--reference-log", str(ms)]) == 0
    assert caplog.messages == [f"legbench: warning: {ms}: median time step 1 s: is the time in ms? (--log-time-scale "
                               "1e-3)"]  # fmt: skip


def test_validate_takes_set_as_run_does(capsys: pytest.CaptureFixture[str]) -> None:
    """`legbench validate` had no --set (README: --set "changes a key before validation"), so what a run with --set
    would refuse could not be checked without running: now each scenario file is validated with the overrides
    set, every problem one line naming the file, the key and the override; a sweep file refuses --set (exit 2)."""
    root = Path(__file__).resolve().parent.parent
    effort, sweep = str(root / "scenarios" / "effort.yaml"), str(root / "scenarios" / "sweeps" / "timestep.yaml")
    assert cli.main(["validate", effort, "--set", "duration=0.5", "--set", "comparison.steady_window=0.1"]) == 0
    assert capsys.readouterr().out.strip().endswith("effort.yaml: ok (effort: 1 event, 0.5 s)")
    assert cli.main(["validate", effort, "--set", "duration=-1", "--set", "backends.eulr.dt=1e-5"]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 2
    assert err[0].endswith("effort.yaml: duration: must be > 0, got -1 (from --set duration)")
    assert err[1].endswith("effort.yaml: backends.eulr: unknown backend; known: pinocchio, mujoco, pybullet, drake, "
                           "dart, lagrange, ode (from --set backends.eulr.dt)")  # fmt: skip
    assert cli.main(["validate", sweep, "--set", "duration=1"]) == 2
    assert capsys.readouterr().err.strip().endswith("timestep.yaml: --set applies to scenario files; this is a sweep "
                                                    "file")  # fmt: skip


def test_an_unknown_backend_names_the_plug_ins_registered_here(monkeypatch: pytest.MonkeyPatch) -> None:
    """The known names in an unknown-backend error were the built-ins only: a plug-in's author, misspelling it,
    was not shown their own backend's name."""
    from fakes import FakeBackend

    from legbench import backends, scenario
    from legbench.exceptions import ScenarioError

    reg = backends._registry
    monkeypatch.setattr(backends, "_registry", lambda: {**reg(), "euler": FakeBackend})
    root = Path(__file__).resolve().parent.parent
    with pytest.raises(ScenarioError, match=r"backends\.eulr: unknown backend; known: pinocchio, .*, ode, euler "):
        scenario.load(root / "scenarios" / "effort.yaml", {"backends.eulr.dt": 1e-5})
    with pytest.raises(ScenarioError, match=r"comparison\.reference: unknown backend 'eulr'; known: .*, ode, euler"):
        scenario.load(root / "scenarios" / "effort.yaml", {"comparison.reference": "eulr"})


def test_python_m_legbench_runs_in_a_pool(tmp_path: Path) -> None:
    """`python -m legbench run ... --jobs 2` was refused by the pool's __main__-guard check: __main__.py called
    the command at its top level, which each worker would run again on import. It is now under the guard."""
    root = Path(__file__).resolve().parent.parent
    out = tmp_path / "run"
    cmd = [sys.executable, "-m", "legbench", "run", str(root / "scenarios" / "position.yaml"), "--backends",
           "pinocchio,mujoco", "--jobs", "2", "--out", str(out), "-q", "--no-compare", "--no-preflight",
           "--set", "duration=0.05", "--set", "comparison.steady_window=0.02"]  # fmt: skip
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=300, check=False)
    assert proc.returncode == 0, proc.stderr
    assert {p.stem for p in out.glob("*.parquet")} == {"pinocchio", "mujoco"}


def test_compare_of_an_empty_path_is_refused(capsys: pytest.CaptureFixture[str]) -> None:
    """``legbench compare ''`` compared the working directory (Path("") is "."): one line, exit 2."""
    assert cli.main(["compare", ""]) == 2
    assert capsys.readouterr().err == "legbench: error: '': an empty path; give a run directory or a results tree\n"


def test_an_engine_whose_import_breaks_fails_alone(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """An engine whose import raises something other than ImportError (a bad build, a shared library that fails
    to load: a RuntimeError, an OSError) took every command down, those not using it too (a traceback, or an
    "I/O error"). It is now unavailable with the reason, and the others run."""
    from legbench import backends

    (tmp_path / "brokenengine_mod.py").write_text("raise RuntimeError('engine broken')\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setitem(backends.BUILTIN, "brokenengine", ("brokenengine_mod", "B", "'brokenengine'"))
    assert "brokenengine" not in backends.available()
    assert cli.main(["backends"]) == 0
    out = capsys.readouterr().out
    assert "its engine failed to import: RuntimeError: engine broken" in out, out
    effort = Path(__file__).resolve().parents[1] / "scenarios" / "effort.yaml"
    short = ["--set", "duration=0.05", "--set", "comparison.steady_window=0.02"]
    args = ["run", str(effort), *short, "--no-compare", "-q", "--out", str(tmp_path / "r")]
    assert cli.main([*args, "--backends", "pinocchio"]) == 0
    assert cli.main([*args, "--backends", "all", "--force"]) == 0
    capsys.readouterr()
    assert cli.main([*args, "--backends", "pinocchio,brokenengine", "--force"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("legbench: error: --backends brokenengine: not installed here (its engine failed to import: "
                          "RuntimeError: engine broken)") and err.count("\n") == 1  # fmt: skip


def test_a_reader_that_went_away_ends_the_command_quietly() -> None:
    """``legbench doctor ... | head -1``: the write to the closed pipe was an "I/O error: Broken pipe; nothing was
    replaced", exit 4. A command whose stdout's reader is gone ends quietly with the shell's SIGPIPE status 141 (the
    pipe's read end is closed before the command starts, so its first write fails)."""
    read, write = os.pipe()
    os.close(read)
    try:
        proc = subprocess.run([sys.executable, "-m", "legbench", "schema"], stdout=write, stderr=subprocess.PIPE,
                              text=True, timeout=120)  # fmt: skip
    finally:
        os.close(write)
    assert proc.returncode == 141 and proc.stderr == "", proc.stderr


@pytest.mark.skipif("drake" not in backends.available(), reason="drake backend not installed")
@pytest.mark.parametrize(
    ("mode_args", "given"),
    [
        (["--contact-mode", "reference", "--no-preflight"], "--contact-mode reference"),
        (["--contact-mode", "both"], "--contact-mode both"),
        (["--variant", "matched:reference", "--no-preflight"], "--variant matched:reference"),
    ],
)
def test_a_contact_mode_the_settings_cannot_run_is_refused_with_or_without_the_preflight(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], mode_args: list[str], given: str
) -> None:
    """Drake's continuous plant in reference contact: ``run --no-preflight --contact-mode reference`` ran Pinocchio
    and failed Drake at load (exit 3, a run directory written), where the same mode in the file is refused. Now
    the mode given on the command line is checked as the file's would be, before any work: one line naming the
    file, the setting and the option as given, exit 2, nothing written. The API's ``contact_mode`` likewise."""
    import legbench
    from legbench.exceptions import ScenarioError

    doc = yaml.safe_load((SCENARIOS / "position.yaml").read_text())
    doc |= {"duration": 0.2, "comparison": {"reference": "pinocchio", "steady_window": 0.1},
            "backends": {"drake": {"solver": "continuous"}}}  # fmt: skip
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump(doc))
    out = tmp_path / "out"
    assert cli.main(["run", str(path), "--backends", "drake,pinocchio", *mode_args, "--out", str(out), "-q"]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"legbench: error: {path}: backends.drake.solver: 'continuous' cannot run reference contact")
    assert err.endswith(f"(with {given})\n") and err.count("\n") == 1
    assert not out.exists()
    with pytest.raises(ScenarioError, match=r"\(with contact_mode='reference'\)$"):
        legbench.run_scenario(path, backends=["drake", "pinocchio"], contact_mode="reference", out=out)
    assert not out.exists()
    assert cli.main(["run", str(path), "--backends", "drake,pinocchio", "--no-preflight", "--out", str(out), "-q"]) == 0


# --------------------------------------------------------------------------- #
# Output files and directories: devices, links, files of the user's, names too long


def test_summary_junit_and_urdf_out_never_replace_a_device_a_fifo_or_a_link(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``check --summary DEVICE --force`` exited 0 and the device became a regular file (the same for a link to
    /proc/self/fd/1 with --junit, and ``model urdf --out DEVICE --force``); a dangling link as --summary was
    replaced without --force: refused before any work, one line, exit 2, each left as it was. Only nodes made
    here (a FIFO, links, as root a device under tmp_path), never a real /dev node."""
    new = write_run(tmp_path / "new", {"ref": None})
    base = write_run(tmp_path / "base", {"ref": None})
    targets = {"fifo": tmp_path / "fifo", "link": tmp_path / "link", "dangling": tmp_path / "dangling"}
    os.mkfifo(targets["fifo"])
    targets["link"].symlink_to(tmp_path / "fifo")
    targets["dangling"].symlink_to(tmp_path / "nowhere")
    if os.geteuid() == 0:
        targets["dev"] = tmp_path / "dev"
        os.mknod(targets["dev"], stat.S_IFCHR | 0o644, os.makedev(1, 7))
    for path in targets.values():
        for argv in (["check", str(new), "--baseline", str(base), "--summary", str(path), "--force"],
                     ["check", str(new), "--baseline", str(base), "--junit", str(path)],
                     ["model", "urdf", "--out", str(path), "--force"]):  # fmt: skip
            assert cli.main(argv) == 2, argv
            err = capsys.readouterr().err
            assert err.count("\n") == 1 and f" {path}: " in err, err
            assert "a symbolic link" in err if path.is_symlink() else "not a regular file" in err, err
    assert not (new / "check.md").exists()
    assert stat.S_ISFIFO(targets["fifo"].lstat().st_mode)
    assert targets["link"].is_symlink() and targets["dangling"].is_symlink()
    assert "dev" not in targets or stat.S_ISCHR(targets["dev"].lstat().st_mode)


def test_model_urdf_out_inside_a_run_directory_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``model urdf --out RUN/run.json --force`` replaced the run's run.json with the URDF (compare then called it
    invalid JSON): an --out inside a run directory is refused, as --summary and --junit are, one line, exit 2."""
    run = write_run(tmp_path / "r", {"ref": None})
    before = (run / "run.json").read_bytes()
    for out in (run / "run.json", run / "leg.urdf"):
        assert cli.main(["model", "urdf", "--out", str(out), "--force"]) == 2
        assert capsys.readouterr().err == (f"legbench: error: --out {out}: inside the run directory {run}, which "
                                           "holds one run; choose another file\n")  # fmt: skip
    assert (run / "run.json").read_bytes() == before and not (run / "leg.urdf").exists()


def test_a_single_run_with_force_never_deletes_the_users_files(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``run good.yaml --out keep --force`` into a run directory holding notes.txt and myplots/ exited 0 and both
    were gone (a run replaces its whole directory), while a tree's run and verify refuse such a folder: refused
    before anything runs, with --force too, one line naming the entry, exit 2, everything kept."""
    out = write_run(tmp_path / "keep", {"pinocchio": None}, name="position")
    (out / "notes.txt").write_text("mine")
    (out / "myplots").mkdir()
    before = sorted(p.name for p in out.iterdir())
    assert cli.main(["run", str(POSITION), "--backends", "pinocchio", "--out", str(out), "--force", "-q"]) == 2
    assert capsys.readouterr().err == (f"legbench: error: {out}: not only a legbench run directory (it holds "
                                       "myplots), and a run replaces the whole directory; move it away, or choose "
                                       "another --out\n")  # fmt: skip
    assert sorted(p.name for p in out.iterdir()) == before and (out / "notes.txt").read_text() == "mine"


def test_a_single_run_into_a_linked_out_writes_through_the_link(tmp_path: Path) -> None:
    """``run --out LINK`` (a link to a folder) replaced the link by a new folder and left the folder empty; with
    --force on a link to an old run, that run stayed stale: the run goes into the folder the link names, as a
    tree's run, verify and bench do, and the link stays."""
    target = tmp_path / "target"
    target.mkdir()
    link = tmp_path / "link"
    link.symlink_to(target)
    argv = ["run", str(POSITION), "--backends", "pinocchio", "--set", "duration=0.05", "--set",
            "comparison.steady_window=0.01", "--out", str(link), "-q", "--no-compare", "--no-preflight"]  # fmt: skip
    assert cli.main(argv) == 0
    assert link.is_symlink() and (target / "run.json").is_file() and (target / "pinocchio.parquet").is_file()
    first = (target / "run.json").read_text()
    assert cli.main([*argv, "--force"]) == 0
    assert link.is_symlink() and (target / "run.json").read_text() != first  # replaced (its wall time differs)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["link", "target"]


def test_a_run_out_whose_temporary_would_not_fit_is_refused_before_any_work(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """``run --out`` a name of 250 characters ran everything, then exited 4 ("File name too long") writing its
    temporary sibling: exit 2 before any work, one line."""
    monkeypatch.chdir(tmp_path)
    long = "a" * 250
    assert cli.main(["run", str(POSITION), "--backends", "pinocchio", "--out", long, "-q"]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"legbench: error: --out {long}: a name of 250 characters;") and err.count("\n") == 1
    assert list(tmp_path.iterdir()) == []


def test_a_run_of_named_backends_imports_no_other_engine(tmp_path: Path) -> None:
    """`legbench run --backends pinocchio` (pre-flight included) imports Pinocchio's engine and no other: it imported
    every installed one for the pre-flight (pydrake's import alone takes about a second, and swallows a Ctrl-C)."""
    others = ("mujoco", "pybullet", "pydrake", "dartpy", "odepy", "sympy")
    code = (
        "import sys\nfrom legbench import cli\n"
        f"rc = cli.main(['run', {str(SCENARIOS / 'position.yaml')!r}, '--backends', 'pinocchio', '--set', "
        f"'duration=0.6', '--out', {str(tmp_path / 'r')!r}, '-q', '--no-compare'])\n"
        f"print(rc, [m for m in {others!r} if m in sys.modules])"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300, check=True)
    assert out.stdout.strip().splitlines()[-1] == "0 []", out.stdout + out.stderr


def test_a_bundled_scenarios_bare_name_says_where_the_file_is(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """`legbench run position` said "position: no such file" though the Python API takes the bundled name: the
    line names the bundled file by a path that can be given from here; another missing name stays as it was."""
    from legbench import resources

    monkeypatch.chdir(tmp_path)
    assert cli.main(["run", "position", "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip()
    assert err == (f"legbench: error: position: no such file; the bundled scenario of that name is "
                   f"{resources.scenario('position')}: give its path")  # fmt: skip
    assert cli.main(["run", "nothere", "--out", str(tmp_path / "out")]) == 2
    assert capsys.readouterr().err.strip() == "legbench: error: nothere: no such file"
    assert not (tmp_path / "out").exists()


def test_log_t0_shifts_a_csv_log_onto_the_run_and_needs_a_log(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`--log-t0`: a log that starts 2 s before the run (its t = 2 at the run's 0) is compared where it belongs
    (exit 0; its deviation from the run it copies 0); without --reference-log it is refused, exit 2."""
    import numpy as np
    from fakerun import base_signals, frame, write_run

    d = write_run(tmp_path / "s", {"ref": None})
    t = np.arange(0, 2.0 + 1e-9, 1e-3)
    df = frame(t, base_signals(t))
    df["t"] = t + 2.0
    df.to_csv(tmp_path / "late.csv", index=False)
    assert cli.main(["compare", str(d), "--reference-log", str(tmp_path / "late.csv"), "--log-t0", "2"]) == 0
    doc = json.loads((d / "metrics.json").read_text())
    sim = [m["value"] for m in doc["metrics"] if m["backend"] == "log:late" and m["metric"] == "max_abs"]
    assert sim and max(sim) < 1e-9, sim
    capsys.readouterr()
    assert cli.main(["compare", str(d), "--log-t0", "2"]) == 2
    assert "--log-t0: need --reference-log" in capsys.readouterr().err


def test_every_subcommands_help_page_says_what_it_does() -> None:
    """`legbench doctor --help` (and most others) showed usage and options with no line saying what the command
    does: each page now opens with its one-line summary (the one `legbench --help` lists), where it has no
    description of its own."""
    parser = cli.build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    for name, page in sub.choices.items():
        assert page.description, name
        if name in cli.SUMMARY and not name.startswith(("bench", "reproduce", "completion")):
            assert page.description.lower().startswith(cli.SUMMARY[name][:20].lower()), (name, page.description)


@pytest.mark.parametrize("argv", [["model", "fk", "1e308", "0", "0"], ["model", "ik", "0", "1e300", "0"],
                                  ["model", "gravity", "0", "0", "1e13"]])  # fmt: skip
def test_a_model_command_refuses_a_number_no_pose_has(argv: list[str], capsys: pytest.CaptureFixture[str]) -> None:
    """`model fk 1e308 0 0` printed a meaningless pose with exit 0 (ik: 'distance inf m'): a number beyond the
    files' limit (1e12) is refused on the command line too, one line, exit 2."""
    with pytest.raises(SystemExit) as exc:
        cli.main(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip()
    assert "is beyond +-1e+12, more than any physical value here (limit float_abs)" in err and "\n" not in err


def test_a_negative_number_in_exponent_notation_is_a_value(capsys: pytest.CaptureFixture[str]) -> None:
    """`model fk 0.1 -1e-3 0.2` was refused: argparse (3.11) reads -1e-3 as an unknown option, where it reads -0.001
    as a number. Both give the same pose to the printed 6 digits; an option's value in that notation is judged as a
    value (--jobs -1e13: not an int), not as a missing argument."""
    out = []
    for q2 in ("-1e-3", "-0.001", "-1E-3", "-.1e-2"):
        assert cli.main(["model", "fk", "0.1", q2, "0.2"]) == 0
        out.append(capsys.readouterr().out)
    assert len(set(out)) == 1 and out[0].startswith("foot centre E in W [m]: x = "), out
    with pytest.raises(SystemExit) as exc:
        cli.main(["run", "x.yaml", "--jobs", "-1e13"])
    assert exc.value.code == 2
    assert "argument --jobs: invalid int value: '-1e13'" in capsys.readouterr().err


def test_a_run_in_a_contact_mode_the_file_does_not_give_records_it_in_its_scenario(tmp_path: Path) -> None:
    """`--contact-mode both`: the reference run's recorded scenario (run.json's raw, and its hash) says reference, as
    a profile given on the command line is recorded; re-run from that document alone it runs in reference mode
    again, bit for bit (a provenance review: re-running it ran natively, and the two runs shared one hash)."""
    import hashlib

    argv = ["run", str(SCENARIOS / "effort.yaml"), "--backends", "pinocchio,mujoco", "--contact-mode", "both",
            "--set", "duration=0.05", "--set", "comparison.steady_window=0.02", "-q", "--no-compare",
            "--no-preflight"]  # fmt: skip
    assert cli.main([*argv, "--out", str(tmp_path / "a")]) == 0
    native, ref = (json.loads((tmp_path / "a" / d / "run.json").read_text())["scenario"]
                   for d in ("effort", "effort__reference"))  # fmt: skip
    assert ref["raw"]["physics"]["contact_mode"] == "reference" and ref["contact_mode"] == "reference"
    assert "contact_mode" not in native["raw"].get("physics", {}) and native["sha256"] != ref["sha256"]
    again = tmp_path / "again.yaml"
    again.write_text(yaml.safe_dump(ref["raw"]))
    rerun_argv = ["run", str(again), "--backends", "pinocchio,mujoco", "-q", "--no-compare", "--no-preflight"]
    assert cli.main([*rerun_argv, "--out", str(tmp_path / "b")]) == 0
    rerun = json.loads((tmp_path / "b" / "run.json").read_text())["scenario"]
    assert rerun["contact_mode"] == "reference" and rerun["sha256"] == ref["sha256"]
    for b in ("pinocchio", "mujoco"):
        digests = {hashlib.sha256((d / f"{b}.parquet").read_bytes()).hexdigest()
                   for d in (tmp_path / "a" / "effort__reference", tmp_path / "b")}  # fmt: skip
        assert len(digests) == 1, b
