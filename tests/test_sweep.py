"""Sweeps: the shipped time-step study shows each integrator's order; sweep files are validated."""

from __future__ import annotations

import argparse
import dataclasses
import errno
import json
import math
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest

from legbench import backends, scenario
from legbench.backends.base import Physics
from legbench.exceptions import LegbenchError, ScenarioError
from legbench.results import RunResult
from legbench.studies import sweep

ROOT = Path(__file__).resolve().parents[1]
TIMESTEP = ROOT / "scenarios" / "sweeps" / "timestep.yaml"
FREE_SPACE = ROOT / "scenarios" / "verification" / "free_space.yaml"


@pytest.fixture(scope="module")
def timestep(tmp_path_factory: pytest.TempPathFactory) -> sweep.SweepResult:
    return sweep.run_sweep(TIMESTEP, tmp_path_factory.mktemp("sweeps") / "timestep", jobs=2)


def _family(table: pd.DataFrame, study: int, backend: str) -> str:
    """The study's integrator setting, else the backend's declared integrator family (default settings)."""
    rows = table[(table["study"] == study) & (table["backend"] == backend) & (table["role"] == "run")]
    integ = rows["integrator"].iloc[0] if "integrator" in rows else None
    if integ is None or (isinstance(integ, float) and math.isnan(integ)):
        loaded = backends.load(backend, Physics(), {})
        try:
            return loaded.integrator_family()
        finally:
            loaded.close()
    return str(integ)


def test_first_order_integrators_converge_at_order_one(timestep: sweep.SweepResult) -> None:
    """Semi-implicit Euler (MuJoCo's implicit variants, ODE's step) converge at order 1 in free space, on every backend.

    Tolerance 0.1 on the slope: e(h) = C h + O(h^2) measured against a run at
    h_ref = 5 us, which biases the slope by at most h_ref / h_min = 4 % at the
    finest step, and the O(h^2) term by h_max W ~ 1 % at the coarsest.
    """
    fits = timestep.fits
    first = {"euler", "implicitfast", "implicit", "first-order"}  # first-order: e.g. ODE's, maximal coordinates
    seen = set()
    for f in fits.itertuples():
        if _family(timestep.table, f.study, f.backend) in first:
            assert f.n_points == 4, f.label
            assert abs(f.slope - 1.0) < 0.1, f"{f.label}: slope {f.slope:.3f}"
            seen.add(f.backend)
    fixed_step = {n for n in backends.available() if "dt" in backends.get(n).defaults}  # adaptive ones: no dt
    assert seen == fixed_step, "every fixed-step backend offers a first-order integrator"


def test_rk4_converges_at_order_four(timestep: sweep.SweepResult) -> None:
    """RK4 converges at order ~4 on every backend that offers it (slope within 0.3 of 4).

    The points at or below the 1e-12 rad floor are left out (a conservative floor: the round-off of the two
    runs is nearer 1e-15, scenarios/sweeps/timestep.yaml); the three above it span 5.6e-10 .. 2.2e-12 rad.
    """
    fits = timestep.fits
    offered = {n for n in backends.available() if "rk4" in backends.get(n).choices.get("integrator", ())}
    seen = set()
    for f in fits.itertuples():
        if _family(timestep.table, f.study, f.backend) == "rk4":
            assert f.n_points >= 3, f.label
            assert abs(f.slope - 4.0) < 0.3, f"{f.label}: slope {f.slope:.3f}"
            seen.add(f.backend)
    assert seen == offered


def test_timestep_sweep_writes_table_fits_and_plots(timestep: sweep.SweepResult) -> None:
    out = timestep.out_dir
    assert out is not None
    for name in ("sweep.csv", "sweep.parquet", "fits.csv", "sweep.json", "convergence.png", "speed_accuracy.png"):
        assert (out / name).stat().st_size > 0, name
    back = pd.read_parquet(out / "sweep.parquet")
    pd.testing.assert_frame_equal(back, timestep.table, check_dtype=False)
    meta = json.loads((out / "sweep.json").read_text())
    assert meta["name"] == "timestep" and len(meta["fits"]) == len(timestep.fits)
    # the base scenario as loaded, its document and hash (a provenance review: only its path was recorded); parsed
    # back it is that scenario, hash for hash
    base = scenario.parse(meta["scenario_raw"])
    assert meta["scenario_sha256"] == base.sha256 == scenario.load(timestep.sweep.scenario).sha256
    runs = timestep.table[timestep.table["role"] == "run"]
    assert (runs["status"] == "ok").all()
    assert (runs["wall_per_sim_s"] > 0).all() and np.isfinite(runs["rtf"]).all()


def _write(tmp_path: Path, text: str, name: str = "s.yaml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


GOOD = f"""
name: t
scenario: {FREE_SPACE}
set: {{duration: 0.1}}
studies:
  - backends: [pinocchio]
    grid: {{backends.*.dt: [1.0e-3, 5.0e-4]}}
    reference: {{set: {{backends.*.dt: 1.0e-4}}}}
"""


@pytest.mark.parametrize(
    ("text", "key", "problem"),
    [
        (GOOD + "foo: 1\n", "foo", "unknown key"),
        # a fit over dt in a study that also sweeps the integrator: one slope over Euler's and RK4's points (-1.22)
        (
            GOOD.replace(
                "grid: {backends.*.dt: [1.0e-3, 5.0e-4]}",
                "grid: {backends.*.dt: [1.0e-3, 5.0e-4], backends.*.integrator: [euler, rk4]}",
            )
            + "fit: {x: dt}\n",
            "studies[0].grid",
            "would mix their lines",
        ),  # fmt: skip
        (GOOD.replace("name: t", "name: a/b"), "name", "plain name"),
        (GOOD + "signals: [q, bogus]\n", "signals[1]", "unknown signal"),
        (GOOD + "metric: zz_max\n", "metric", "unknown metric"),
        (GOOD + "fit: {x: gains.Kp}\n", "fit.x", "no study sweeps"),
        (GOOD + "short_horizon: {window: -1}\n", "short_horizon.window", "must be > 0"),
        (GOOD.replace("[pinocchio]", "[nonexistent]"), "studies[0].backends[0]", "unknown backend"),
        (GOOD.replace("[1.0e-3, 5.0e-4]", "1.0e-3"), "studies[0].grid.backends.*.dt", "non-empty list"),
        (GOOD.replace("backends.*.dt: [", "backends.pin*.dt: ["), "studies[0].grid.backends.pin*.dt", "whole key"),
        (GOOD.replace("{set: {backends.*.dt: 1.0e-4}}", "{}"), "studies[0].reference", "the run itself"),
        (GOOD.replace("    reference: {set: {backends.*.dt: 1.0e-4}}\n", ""), "studies[0]", "'reference'"),
        (GOOD.replace(str(FREE_SPACE), "missing.yaml"), "scenario", "no such scenario"),
    ],
)
def test_invalid_sweep_file_names_file_and_key(tmp_path: Path, text: str, key: str, problem: str) -> None:
    path = _write(tmp_path, text)
    with pytest.raises(ScenarioError) as err:
        sweep.load_sweep(path)
    assert err.value.file == str(path)
    assert err.value.key == key
    assert problem in err.value.problem


def test_value_the_scenario_rejects_is_reported_at_its_sweep_key(tmp_path: Path) -> None:
    path = _write(tmp_path, GOOD.replace("    grid:", "    set: {backends.*.integrator: bogus}\n    grid:"))
    with pytest.raises(ScenarioError) as err:
        sweep.plan(sweep.load_sweep(path))
    assert err.value.file == str(path)
    assert err.value.key == "studies[0].set.backends.*.integrator"
    assert "pinocchio" in err.value.problem and "'bogus'" in err.value.problem and err.value.line is not None


def test_malformed_yaml_and_missing_file(tmp_path: Path) -> None:
    with pytest.raises(ScenarioError, match="malformed YAML"):
        sweep.load_sweep(_write(tmp_path, "name: [unclosed\n"))
    with pytest.raises(ScenarioError, match="no such file"):
        sweep.load_sweep(tmp_path / "nope.yaml")


def test_backend_not_installed_is_skipped_with_a_note(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(backends, "available", lambda: ["pinocchio"])
    path = _write(tmp_path, GOOD.replace("[pinocchio]", "[pinocchio, mujoco]"))
    p = sweep.plan(sweep.load_sweep(path))
    assert {r.backend for r in p.rows} == {"pinocchio"}
    assert any("mujoco is not installed" in n for n in p.notes)


def test_grid_is_a_cartesian_product_and_references_are_shared(tmp_path: Path) -> None:
    text = GOOD.replace(
        "grid: {backends.*.dt: [1.0e-3, 5.0e-4]}", "grid: {backends.*.dt: [1.0e-3, 5.0e-4], gains.Kp: [5, 10, 20]}"
    )
    p = sweep.plan(sweep.load_sweep(_write(tmp_path, text)))
    runs = [r for r in p.rows if r.role == "run"]
    assert len(runs) == 6 and len({r.run for r in runs}) == 6
    assert {tuple(sorted(r.params)) for r in runs} == {("dt", "gains.Kp")}
    # the reference keeps gains.Kp of its grid point and replaces dt: one reference per Kp
    assert len({r.ref for r in runs}) == 3


def test_run_metrics_are_zero_for_identical_runs_and_wrap_the_hip() -> None:
    t = np.arange(5) * 1e-3
    q = np.column_stack([np.linspace(0, 0.1, 5), np.linspace(3.0, 3.2, 5), np.zeros(5)])
    ref = RunResult("ref", t, q, np.ones((5, 3)), np.ones((5, 3)), np.zeros((5, 3)), np.full(5, "", dtype=object))
    wrapped = dataclasses.replace(ref, q=q + np.array([0.0, -2 * np.pi, 0.0]))
    m = sweep.run_metrics(wrapped, ref, ["q", "qd", "force"])
    assert m["q_max"] < 1e-12 and m["qd_max"] == 0.0
    assert math.isnan(m["force_pct"])  # reference peak is zero: % undefined
    shifted = dataclasses.replace(ref, q=q + np.array([0.01, 0.0, 0.0]))
    m = sweep.run_metrics(shifted, ref, ["q"])
    assert m["q1_max"] == pytest.approx(0.01) and m["q1_pct"] == pytest.approx(100 * 0.01 / 0.1)
    assert math.isnan(sweep.run_metrics(dataclasses.replace(ref, status="failed"), ref, ["q"])["q_max"])


def test_a_foreign_directory_is_refused_before_any_run(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """An --out holding a file of the user's was refused only when writing, after every run: now before any."""
    out = tmp_path / "out"
    out.mkdir()
    (out / "precious.txt").write_text("keep")

    def ran(*args: Any) -> None:
        raise AssertionError("a run started")

    monkeypatch.setattr(sweep, "execute", ran)
    with pytest.raises(LegbenchError, match="not a legbench sweep directory"):
        sweep.run_sweep(_write(tmp_path, GOOD), out, jobs=1)
    assert [p.name for p in out.iterdir()] == ["precious.txt"]


def test_cli_replaces_a_finished_sweep_in_its_out_directory_only_with_force(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A second sweep into the --out of a finished one is refused (one line naming --force) and leaves it as
    it was; with --force it replaces it."""
    parser = argparse.ArgumentParser()
    sweep.add_cli(parser.add_subparsers())
    path = _write(tmp_path, GOOD)
    out = tmp_path / "res"
    args = parser.parse_args(["sweep", str(path), "--out", str(out), "--jobs", "1"])
    assert args.func(args) == 0
    first = (out / "sweep.json").read_bytes()
    with pytest.raises(LegbenchError, match="holds a finished sweep; choose another --out .* or --force"):
        args.func(args)
    assert (out / "sweep.json").read_bytes() == first  # left as it was
    meta = json.loads(first)
    (out / "sweep.json").write_text(json.dumps({**meta, "complete": False}))  # as an interrupted one leaves it
    with pytest.raises(LegbenchError, match=r"holds an interrupted sweep \(a sweep is not resumed\); .* --force"):
        args.func(args)
    (out / "sweep.json").write_bytes(first)
    inode = (out / "sweep.json").stat().st_ino
    args = parser.parse_args(["sweep", str(path), "--out", str(out), "--jobs", "1", "--force"])
    assert args.func(args) == 0
    assert "2 runs + 1 references, 0 failed" in capsys.readouterr().out
    assert (out / "sweep.csv").exists() and (out / "sweep.png").exists()
    assert (out / "sweep.json").stat().st_ino != inode  # a new file, moved into place


@pytest.mark.parametrize("foreign", ["notes.txt", "plots", "a_run/run.json"])
def test_force_refuses_a_sweep_directory_holding_files_of_the_users(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, foreign: str
) -> None:
    """``legbench sweep --out D --force`` deleted the user's notes.txt and plots/ in D (the old directory was
    removed whole): like ``legbench run --force``, it now refuses before any run, naming the first entry that is
    not the sweep's own, and leaves D as it was. Fails without the fix: the runs start (AssertionError)."""
    out = tmp_path / "res"
    out.mkdir()
    (out / "sweep.json").write_text(json.dumps({"name": "t", "complete": True}))  # a finished sweep "t"
    (out / "sweep.csv").write_text("x\n")
    (out / foreign).parent.mkdir(parents=True, exist_ok=True)
    if foreign == "plots":
        (out / foreign).mkdir()
    else:
        (out / foreign).write_text("mine")
    before = sorted(str(p.relative_to(out)) for p in out.rglob("*"))

    def ran(*args: Any) -> None:
        raise AssertionError("a run started")

    monkeypatch.setattr(sweep, "execute", ran)
    parser = argparse.ArgumentParser()
    sweep.add_cli(parser.add_subparsers())
    args = parser.parse_args(["sweep", str(_write(tmp_path, GOOD)), "--out", str(out), "--jobs", "1", "--force"])
    name = Path(foreign).parts[0]
    with pytest.raises(LegbenchError, match=rf"^{out}: not .*legbench sweep directory \(it holds {name}\)"):
        args.func(args)
    assert sorted(str(p.relative_to(out)) for p in out.rglob("*")) == before


def _dead_pid() -> int:
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


def test_a_failed_write_leaves_no_temporary_and_stale_ones_are_cleaned(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A sweep whose write failed (a full disk) left ``.<out>.tmp-<pid>/`` beside its output, and nothing ever
    removed it (nor one of a killed sweep). Now the failed write removes its temporary and the next sweep cleans
    a stale one (results.atomic_dir). Fails without the fix: the temporaries are still there."""
    sw = sweep.load_sweep(_write(tmp_path, GOOD))
    table = pd.DataFrame({"role": ["run"], "status": ["ok"], "label": ["x"], "study": [0], "backend": ["pinocchio"]})
    result = sweep.SweepResult(sw, table, pd.DataFrame(), pd.DataFrame(), (), None)
    monkeypatch.setattr(sweep, "_plot", lambda figure: None)  # no figures: the files are what is tested
    parent = tmp_path / "sweeps"
    out = parent / "t"

    def full(*args: Any, **kwargs: Any) -> None:
        raise OSError(errno.ENOSPC, "No space left on device")

    with monkeypatch.context() as m:
        m.setattr(pd.DataFrame, "to_parquet", full)
        with pytest.raises(OSError, match="No space left"):
            sweep.write_sweep(result, out)
    assert list(parent.iterdir()) == []  # neither the output nor a temporary
    stale = parent / f".t.tmp-{_dead_pid()}"  # a sweep killed while writing
    stale.mkdir()
    (stale / "sweep.csv").write_text("half")
    assert sweep.write_sweep(result, out) == out
    assert [p.name for p in parent.iterdir()] == ["t"]
    assert json.loads((out / "sweep.json").read_text())["name"] == "t"


def test_star_keys_configure_the_run_not_another_backends_reference(tmp_path: Path) -> None:
    """``backends.*.dt`` of a MuJoCo/Bullet study is their step; the Pinocchio reference keeps its own,
    and the two studies share one reference run."""
    text = GOOD.replace("[pinocchio]", "[mujoco, pybullet]").replace(
        "reference: {set: {backends.*.dt: 1.0e-4}}", "reference: {backend: pinocchio}"
    )
    p = sweep.plan(sweep.load_sweep(_write(tmp_path, text)))
    refs = {r.ref for r in p.rows if r.role == "run"}
    assert len(refs) == 1
    ref = refs.pop()
    assert ref is not None  # a run row always names its reference task
    ref_task = p.tasks[ref]
    assert ref_task.backend == "pinocchio" and not any(k.startswith("backends.") for k in ref_task.overrides)
    runs = [p.tasks[r.run] for r in p.rows if r.role == "run"]
    assert {tuple(t.overrides) for t in runs} == {("duration", f"backends.{t.backend}.dt") for t in runs}


def test_rows_carry_their_study_label(timestep: sweep.SweepResult) -> None:
    runs = timestep.table[timestep.table["role"] == "run"]
    assert "pinocchio euler" in set(runs["label"]) and not runs["label"].str.contains("reference").any()
    refs = timestep.table[timestep.table["role"] == "reference"]
    assert refs["label"].str.contains("reference").all()


def test_a_sweep_without_out_does_not_replace_a_finished_one(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """As ``legbench run``: without --out, a finished sweep in the default directory is replaced only with
    --force (the refusal is one line, exit 2, before anything runs; the old sweep.json is untouched)."""
    from legbench import cli

    monkeypatch.chdir(tmp_path)
    done = tmp_path / "results" / "sweeps" / sweep.load_sweep(TIMESTEP).name
    done.mkdir(parents=True)
    (done / "sweep.json").write_text('{"name": "kept"}')
    assert cli.main(["sweep", str(TIMESTEP), "-q"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "holds a finished sweep" in err and "--force" in err
    assert (done / "sweep.json").read_text() == '{"name": "kept"}'


def test_a_broken_scenario_is_named_not_blamed_on_a_study(tmp_path: Path) -> None:
    """The sweep's scenario is read on its own first: its malformed YAML is reported with its own file and line,
    under the sweep's ``scenario`` key (it was reported as a problem of studies[0].set)."""
    (tmp_path / "broken.yaml").write_text("name: t\nduration: [1\n")
    text = TIMESTEP.read_text().replace("scenario: ../verification/free_space.yaml", "scenario: broken.yaml")
    (tmp_path / "sw.yaml").write_text(text)
    with pytest.raises(ScenarioError) as exc:
        sweep.load_sweep(tmp_path / "sw.yaml")
    assert exc.value.key == "scenario"
    assert f"{tmp_path / 'broken.yaml'}:3: malformed YAML" in str(exc.value)


@pytest.mark.parametrize(
    ("old", "new", "key", "words"),
    [
        ("reference: {set: {backends.*.dt: 5.0e-6}}", "reference: {set: {backends.*.dt: -1}}",
         "studies[0].reference.set", "must be > 0"),
        ("fit: {x: dt, floor: 1.0e-12}", "fit: {x: dt, floor: 1.0e-12}\nshort_horizon: {window: 0.0105}",
         "short_horizon.window", "not a whole number of control periods"),
        ("fit: {x: dt, floor: 1.0e-12}", "fit: {x: dt, floor: 1.0e-12}\nshort_horizon: {window: 100}",
         "short_horizon.window", "longer than the runs"),
    ],
)  # fmt: skip
def test_what_the_sweep_would_refuse_is_refused_when_it_is_read(
    tmp_path: Path, old: str, new: str, key: str, words: str
) -> None:
    """A reference's overrides and the short-horizon window are checked when the sweep file is read (so by
    ``legbench validate``), naming the key: they passed validation and failed mid-sweep (the window's message
    named neither file nor key), or a window longer than the run ran silently."""
    text = TIMESTEP.read_text()
    assert old in text
    f = tmp_path / "sw.yaml"
    f.write_text(text.replace(old, new, 1).replace("../verification/", str(ROOT / "scenarios/verification") + "/"))
    with pytest.raises(ScenarioError) as exc:
        sweep.load_sweep(f)
    assert exc.value.key == key and words in str(exc.value), str(exc.value)


def test_an_engine_that_crashes_its_worker_fails_its_rows_and_the_sweep_goes_on(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """--jobs 2, a study on a plug-in engine that kills its worker (SIGSEGV) against a Pinocchio reference, beside
    a Pinocchio study: the crashing engine's rows are failed naming the signal, every other row is ok."""
    from fakes import install_crashing_engine

    monkeypatch.syspath_prepend(str(tmp_path / "site"))
    crashy = install_crashing_engine(tmp_path / "site")
    text = GOOD + (f"  - backends: [{crashy}]\n    grid: {{backends.*.dt: [1.0e-3, 5.0e-4]}}\n"
                   "    reference: {backend: pinocchio, set: {backends.pinocchio.dt: 1.0e-4}}\n")  # fmt: skip
    res = sweep.run_sweep(_write(tmp_path, text), None, "local", jobs=2)
    t = res.table
    bad = t[t["backend"] == crashy]
    assert len(bad) == 2 and (bad["status"] == "failed").all()
    assert bad["reason"].str.contains("the engine crashed: its worker process died \\(killed by SIGSEGV\\)").all()
    assert (t[t["backend"] != crashy]["status"] == "ok").all() and len(t) > len(bad)


def test_a_sweep_starts_no_more_workers_than_its_runs(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """``legbench sweep --jobs 8`` on a sweep of three runs (a reference and two steps) started eight worker
    processes, each importing every engine: it starts three, counted as the pool spawns them."""
    from concurrent.futures import ProcessPoolExecutor

    spawned: list[int] = []
    real_spawn = ProcessPoolExecutor._spawn_process  # type: ignore[attr-defined]

    def spawn(self: Any) -> None:
        spawned.append(1)
        real_spawn(self)

    monkeypatch.setattr(ProcessPoolExecutor, "_spawn_process", spawn)
    res = sweep.run_sweep(_write(tmp_path, GOOD), None, "local", jobs=8)
    assert len(res.table) == 3 and (res.table["status"] == "ok").all()
    assert len(spawned) == 3


def test_a_grid_value_s_error_names_the_study_and_a_folder_as_scenario_is_called_one(tmp_path: Path) -> None:
    """A grid value a scenario refuses named it "(from --set gains)", an option the user never gave: it names the
    study's key; ``scenario: .`` (a folder) was "no such scenario file"."""
    text = (ROOT / "scenarios" / "sweeps" / "gains.yaml").read_text()
    text = text.replace("../verification/", str(ROOT / "scenarios/verification") + "/")
    f = tmp_path / "g.yaml"
    f.write_text(text.replace("{Kp: 5, Kd: 0.5}", "{Kp: abc, Kd: 0.5}", 1))
    with pytest.raises(ScenarioError) as exc:
        sweep.load_sweep(f)
    assert exc.value.key == "studies[0].grid.gains" and str(exc.value).endswith(
        "with mujoco: gains.Kp: expected a number or a list of 3 numbers, got 'abc' (from the study's gains)"
    )
    f.write_text(text.replace(f"scenario: {ROOT / 'scenarios/verification'}/free_space.yaml", "scenario: ."))
    with pytest.raises(ScenarioError) as exc:
        sweep.load_sweep(f)
    assert exc.value.key == "scenario" and str(exc.value).endswith(f"is a directory, not a scenario file: {tmp_path}")


@pytest.mark.skipif("mujoco" not in backends.available(), reason="mujoco backend not installed")
def test_fixed_values_valid_only_together_pass_and_a_pair_that_fails_is_named(tmp_path: Path) -> None:
    """MuJoCo's pyramidal cone runs only with the contact's own friction reference: a study's ``set`` giving both
    was refused at its ``cone`` key, checked alone against the default deadbeat friction. The fixed values are
    checked together; where together they fail, the one that fails alone is named, else the ``set``."""
    study = ("name: pyr\nscenario: {s}\nstudies:\n  - label: x\n    backends: [mujoco]\n    set: {{{set}}}\n"
             "    grid: {{backends.*.solver: [newton, cg]}}\n    reference: {{backend: pinocchio}}\n")  # fmt: skip
    scenario_file = ROOT / "scenarios" / "effort.yaml"
    ok = _write(tmp_path, study.format(s=scenario_file, set="backends.*.cone: pyramidal, "
                                                           "backends.*.friction_solref: contact"))  # fmt: skip
    assert len(sweep.plan(sweep.load_sweep(ok)).tasks) == 3  # newton, cg and one Pinocchio reference
    bad = _write(tmp_path, study.format(s=scenario_file, set="backends.*.cone: pyramidal"))
    with pytest.raises(ScenarioError) as exc:
        sweep.load_sweep(bad)
    assert exc.value.key == "studies[0].set.backends.*.cone"
    assert "cone 'pyramidal' ignores friction_solref 'deadbeat'" in exc.value.problem
    # a valid pair beside a bad value: the bad value is named, not the cone (which fails alone, for another reason)
    other = _write(tmp_path, study.format(s=scenario_file, set="backends.*.cone: pyramidal, "
                                                              "backends.*.friction_solref: contact, "
                                                              "backends.*.iterations: -5"))  # fmt: skip
    with pytest.raises(ScenarioError) as exc:
        sweep.load_sweep(other)
    assert exc.value.key == "studies[0].set.backends.*.iterations", exc.value


@pytest.mark.parametrize(
    ("grid", "set_", "words"),
    [
        ("{physics.contact.Kp: [1.0e+4, 2.0e+4], physics.contact: [{Kp: 3.0e+4}]}", "{}",
         "studies[0].grid.physics.contact.Kp: sets what physics.contact in another grid key sets too"),
        ("{backends.*.dt: [1.0e-4, 5.0e-5]}", "{backends.pinocchio.dt: 2.0e-4}",
         "studies[0].grid.backends.*.dt: sets what backends.pinocchio.dt in this study's set sets too (with "
         "pinocchio: backends.pinocchio.dt)"),
        ("{backends.*.dt: [1.0e-4, 5.0e-5]}", "{backends.*.dt: 2.0e-4}",
         "studies[0].grid.backends.*.dt: also given in this study's set; give it in one place"),
    ],
)  # fmt: skip
def test_two_keys_that_set_the_same_value_are_refused(tmp_path: Path, grid: str, set_: str, words: str) -> None:
    """A grid key and another that sets (part of) the same value (physics.contact.Kp beside physics.contact;
    backends.*.dt beside backends.pinocchio.dt) ran with one of them while the table recorded the other's values
    (both of Kp 1e4 and 2e4 ran at 3e4); refused, as the same key twice is, naming the first."""
    f = _write(tmp_path, f"name: s\nscenario: {ROOT / 'scenarios' / 'effort.yaml'}\nstudies:\n"
                         f"  - backends: [pinocchio]\n    set: {set_}\n    grid: {grid}\n"
                         "    reference: {backend: pinocchio, set: {backends.*.dt: 1.0e-5}}\n")  # fmt: skip
    with pytest.raises(ScenarioError) as exc:
        sweep.load_sweep(f)
    assert f"{exc.value.key}: {exc.value.problem}".startswith(words), exc.value


@pytest.mark.skipif("mujoco" not in backends.available(), reason="mujoco backend not installed")
@pytest.mark.parametrize(
    ("value", "problem"),
    [
        ("physics.contact.Kp: -1", "physics.contact.Kp: must be >= 0, got -1 (from the sweep's physics.contact.Kp)"),
        ("duration: 0.0005", "duration: 0.0005 s is not a whole number of control periods"),
        ("physics.contact.kpp: 3", "physics.contact.kpp: unknown key"),
    ],
)
def test_a_bad_value_in_the_sweeps_own_set_is_named_at_its_key(tmp_path: Path, value: str, problem: str) -> None:
    """A bad value in the sweep's top-level ``set`` was blamed on ``studies[0].set`` (a key the study did not have)
    at the study's line; it is named at its own key and line, ``set.<key>``, with the backend it failed with."""
    study = "  - backends: [mujoco]\n    grid: {gains.Kp: [10, 20]}\n    reference: {backend: pinocchio}\n"
    scenario = ROOT / "scenarios" / "effort.yaml"
    f = _write(tmp_path, f"name: s\nscenario: {scenario}\nset: {{{value}}}\nstudies:\n{study}")
    with pytest.raises(ScenarioError) as exc:
        sweep.load_sweep(f)
    assert exc.value.key == f"set.{value.split(':')[0]}" and exc.value.line == 3, exc.value
    assert exc.value.problem.startswith(f"with mujoco: {problem}"), exc.value


@pytest.mark.parametrize(
    ("reference", "at"),
    [
        ("{backend: pinocchio}", "at dt=0.001"),  # the fuzzing review's case: "2 runs + 0 references", errors 0
        ("{set: {backends.mujoco.dt: 1.0e-4}}", "at dt=0.001"),  # another backend's setting: none of pinocchio's
        ("{backend: pinocchio, set: {backends.*.dt: 5.0e-4}}", "at dt=0.0005"),  # the run's own value at one point
        ("{set: {duration: 0.1}}", "at dt=0.001"),  # the sweep's own set already gives it
    ],
    ids=["same-backend", "other-backends-setting", "same-value-at-a-point", "same-as-the-common-set"],
)
def test_a_reference_that_is_the_run_itself_is_refused_at_load(tmp_path: Path, reference: str, at: str) -> None:
    """docs/studies.md: "A reference that would be the run itself is an error". Only `reference: {}` was refused;
    `backends: [pinocchio]` with `reference: {backend: pinocchio}` (same settings) was accepted, planned as 2 runs +
    0 references, every error 0.0, exit 0. Any reference on the run's backend that leaves a grid point's settings as
    the run has them is refused when the file is read, naming studies[0].reference, the backend and the point."""
    path = _write(tmp_path, GOOD.replace("{set: {backends.*.dt: 1.0e-4}}", reference))
    with pytest.raises(ScenarioError) as err:
        sweep.load_sweep(path)
    assert err.value.file == str(path) and err.value.key == "studies[0].reference" and err.value.line is not None
    assert err.value.problem.startswith(f"with pinocchio {at}, the reference is the run itself"), err.value.problem
    assert "\n" not in str(err.value)
    # another backend, or a setting that differs, is a reference of its own
    other = _write(tmp_path, GOOD.replace("{set: {backends.*.dt: 1.0e-4}}", "{backend: mujoco}"), "o.yaml")
    assert len(sweep.plan(sweep.load_sweep(other)).tasks) == 3


@pytest.mark.parametrize(
    ("grid", "value"),
    [
        ("{backends.*.integrator: [euler, rk4]}", "'euler'"),
        ("{gains: [{Kp: 5, Kd: 0.5}, {Kp: 10, Kd: 1}]}", "{'Kp': 5, 'Kd': 0.5}"),
    ],
    ids=["integrator", "gains-mapping"],
)
def test_a_fit_over_a_column_that_is_not_numeric_is_refused_at_load(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], grid: str, value: str
) -> None:
    """`fit: {x: integrator}` (a text column) was accepted: the sweep ran, matplotlib's UserWarning ("No artists
    with labels found to put in legend") reached stderr from sweep.py and the slope was NaN (0 points), exit 0.
    fit.x must be a numeric swept key: refused when the file is read, naming fit.x and the study's grid key, exit 2
    from the command line before any run."""
    from legbench import cli

    x = "integrator" if "integrator" in grid else "gains"
    path = _write(tmp_path, GOOD.replace("{backends.*.dt: [1.0e-3, 5.0e-4]}", grid) + f"fit: {{x: {x}}}\n")
    with pytest.raises(ScenarioError) as err:
        sweep.load_sweep(path)
    assert err.value.file == str(path) and err.value.key == "fit.x"
    key = "backends.*.integrator" if x == "integrator" else "gains"
    assert err.value.problem.startswith(f"{x!r} is not a numeric column: studies[0].grid.{key} sweeps {value}")
    out = tmp_path / "out"
    assert cli.main(["sweep", str(path), "--out", str(out)]) == 2
    captured = capsys.readouterr()
    assert captured.err.count("\n") == 1 and "fit.x" in captured.err and "Warning" not in captured.err
    assert not out.exists()


def _fit_table(x: list[float], y: list[float], status: list[str] | None = None) -> pd.DataFrame:
    n = len(x)
    return pd.DataFrame({"role": ["run"] * n, "study": [0] * n, "label": ["s"] * n, "backend": ["b"] * n,
                         "status": status or ["ok"] * n, "dt": x, "q_max": y})  # fmt: skip


def test_the_slope_fit_leaves_out_what_it_cannot_fit_and_says_so() -> None:
    """A first-order error e = 3 dt: slope 1 over the usable points; a point at the floor (exactly), one at x = 0
    (a Kd grid holding 0: log 0 crashed the sweep after every run had finished) and a failed run are left out,
    and the note counts them; a column held at one value (an adaptive solver's study) or given twice gets no
    slope and says why."""
    fit = sweep.Fit("dt", floor=1e-12)
    x = [1e-3, 5e-4, 2.5e-4, 0.0, 1e-4, 2e-3]
    y = [3e-3, 1.5e-3, 7.5e-4, 0.0, 1e-12, 6e-3]
    table = _fit_table(x, y, ["ok"] * 5 + ["failed"])
    (row,) = sweep.fit_slopes(table, "q_max", fit).to_dict("records")
    assert row["slope"] == pytest.approx(1.0, abs=1e-12) and row["n_points"] == 3, row
    assert row["note"] == "3 point(s) left out (failed, dt not > 0, or at or below the floor 1e-12)"
    (one,) = sweep.fit_slopes(_fit_table([1e-4, 1e-4], [1e-6, 2e-6]), "q_max", fit).to_dict("records")
    assert math.isnan(one["slope"]) and one["note"] == "dt takes one value in this study: no slope against it"
    (few,) = sweep.fit_slopes(_fit_table([1e-3, 1e-4], [1e-6, 1e-13]), "q_max", fit).to_dict("records")
    assert math.isnan(few["slope"]) and few["note"].startswith("fewer than two usable points"), few


def test_the_short_horizon_columns_leave_out_the_windows_before_the_skip() -> None:
    """docs/studies.md: the sweep's skip is left out of every comparison; the sh_ columns took every window from
    t = 0 (a transient at the start set them). They take the windows starting at or after the skip; a window
    starting at it is kept."""
    from legbench.studies import horizon

    peaks = {s: np.array([[9.0, 9.0, 9.0], [1.0, 2.0, 3.0], [0.5, 0.5, 0.5]]) for s in horizon.SIGNALS}
    h = horizon.HorizonResult(0.1, np.array([0.0, 0.1, 0.2]), peaks, peaks)
    every = sweep._horizon_columns(h)
    kept = sweep._horizon_columns(h, skip=0.1)
    s = horizon.SIGNALS[0]
    assert every[f"sh_{s}_max"] == 9.0 and kept[f"sh_{s}_max"] == 3.0
    assert math.isnan(sweep._horizon_columns(None, 0.1)[f"sh_{s}_max"])  # a reference row: no windows


@pytest.mark.parametrize("name", ["mujoco", "ode"])
def test_a_sweeps_short_horizon_carries_each_runs_reset_floor(name: str) -> None:
    """A sweep's short-horizon row has the reset floor beside its local error (legbench.studies.horizon): the
    run's own log replayed on its backend in the same windows. MuJoCo's state is its joint coordinates: floor
    exactly 0, not reset-limited. ODE's is not (maximal coordinates): in 10 ms windows over 0.2 s of free space
    its q floor is 7.3e-6 rad (held within 2e-6..3e-5) against a local error of 7.4e-6 rad against Pinocchio,
    0.99x, so its q and qd are marked reset-limited (the floor is 0.1x the local error or more)."""
    from legbench.studies import horizon, tasks

    if name not in backends.available() or "pinocchio" not in backends.available():
        pytest.skip(f"{name} or pinocchio not installed")
    fs = Path(__file__).resolve().parents[1] / "scenarios" / "verification" / "free_space.yaml"
    ref = tasks.run_task(tasks.RunTask(0, str(fs), {"duration": 0.2}, "pinocchio")).run
    res = tasks.run_task(tasks.RunTask(1, str(fs), {"duration": 0.2}, name, replay_window=0.01, reference=ref))
    assert res.horizon is not None and res.floor is not None and len(res.floor.t0) == len(res.horizon.t0) == 20
    cols = sweep._horizon_columns(res.horizon, 0.0, res.floor)
    if name == "mujoco":
        assert all(cols[f"sh_floor_{s}_max"] == 0.0 for s in horizon.SIGNALS)
        assert not any(cols[f"sh_{s}_reset_limited"] for s in horizon.SIGNALS)
    else:
        assert 2e-6 < cols["sh_floor_q_max"] < 3e-5
        assert cols["sh_q_reset_limited"] and cols["sh_qd_reset_limited"]
        assert cols["sh_floor_q_max"] >= horizon.FLOOR_FRACTION * cols["sh_q_max"]
