"""``legbench reproduce``: the framework file, and the tables against the metrics of the same run directories.

One shortened reproduce (every task cut to 0.2 s; two cheap framework analogues and
one that is not installed) runs once per module. Its table numbers must equal what
metrics.json of each run directory says (written by ``legbench compare``'s path) and
what :mod:`legbench.metrics` computes from the logs: the same code on the same data,
so the tolerance is JSON's round trip (1e-12 relative).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest
import yaml

from legbench import backends, cli, kinematics, metrics, results
from legbench.exceptions import ScenarioError
from legbench.studies import reproduce as rp

SCENARIOS = Path(__file__).resolve().parent.parent / "scenarios"
RTOL = 1e-12  # same computation on the same data; JSON keeps every digit of a float
GHOST = "ghostengine"  # a built-in whose engine is not installed anywhere


def _plan_doc(**patch: Any) -> dict[str, Any]:
    doc: dict[str, Any] = {
        "frameworks": [
            {"name": "Simscape", "backend": "pinocchio", "profile": "matched"},
            {"name": "Gazebo", "backend": "mujoco", "profile": "engine-defaults"},
            {"name": "custom sim", "backend": GHOST, "profile": "engine-defaults"},
        ],
        "others": "matched",
        "tasks": [
            {"file": str(SCENARIOS / "position.yaml"), "tables": ["sim_error"]},
            {"file": str(SCENARIOS / "ellipse.yaml"), "tables": ["sim_error"]},
            {"file": str(SCENARIOS / "effort.yaml"), "tables": ["steady", "force"]},
            {"file": str(SCENARIOS / "combined.yaml"), "tables": ["force"]},
        ],
    }
    doc.update(patch)
    return doc


@pytest.fixture
def ghost(monkeypatch: pytest.MonkeyPatch) -> None:
    """A built-in backend whose module does not exist: known to legbench, missing here."""
    monkeypatch.setitem(backends.BUILTIN, GHOST, ("legbench.backends.ghostengine_", "GhostBackend", "ghostengine"))


def _write(tmp_path: Path, doc: dict[str, Any]) -> Path:
    p = tmp_path / "frameworks.yaml"
    p.write_text(yaml.safe_dump(doc))
    return p


def test_shipped_framework_file_names_the_three_analogues() -> None:
    plan = rp.load_plan()
    assert [(f.name, f.backend, f.profile) for f in plan.frameworks] == [
        ("Gazebo", "ode", "gazebo"),
        ("Simscape", "pinocchio", "ode45"),
        ("custom sim", "lagrange", "engine-defaults"),
    ]
    assert [t.file.name for t in plan.tasks] == [
        "position.yaml", "ellipse.yaml", "effort.yaml", "combined.yaml", "combined_ros.yaml",
    ]  # fmt: skip
    assert plan.others == "matched"


@pytest.mark.parametrize(
    ("patch", "key", "words"),
    [
        ({"frameworks": [{"name": "Gazebo", "backend": "gazebo9", "profile": "matched"}]}, "frameworks[0].backend",
         "unknown backend 'gazebo9'"),
        ({"frameworks": [{"name": "Simscape", "backend": "pinocchio", "profile": "gazebo"}]}, "frameworks[0].profile",
         "pinocchio offers the profiles"),
        ({"frameworks": [{"name": "Simscape", "backend": "pinocchio"}]}, "frameworks[0]", "missing required key"),
        ({"others": "ode45"}, "others", "expected one of matched, engine-defaults"),
        ({"tasks": [{"file": "nowhere.yaml", "tables": ["steady"]}]}, "tasks[0].file", "no scenario file"),
        ({"tasks": [{"file": str(SCENARIOS / "effort.yaml"), "tables": ["table10"]}]}, "tasks[0].tables[0]",
         "expected one of steady, force, sim_error"),
        ({"framework": []}, "framework", "did you mean 'frameworks'"),
    ],
)  # fmt: skip
def test_bad_framework_file_is_one_line_naming_file_and_key(
    tmp_path: Path, ghost: None, patch: dict[str, Any], key: str, words: str
) -> None:
    path = _write(tmp_path, _plan_doc(**patch))
    with pytest.raises(ScenarioError) as err:
        rp.load_plan(path)
    msg = str(err.value)
    assert str(path) in msg and err.value.key == key and words in msg
    assert "\n" not in msg


def test_other_backends_follow_the_framework_analogues(tmp_path: Path, ghost: None) -> None:
    plan = rp.load_plan(_write(tmp_path, _plan_doc()))
    names = rp.backend_names(plan, "all")
    assert names[:3] == ["pinocchio", "mujoco", GHOST]  # a missing analogue keeps its row
    assert set(names[3:]) == set(backends.available()) - {"pinocchio", "mujoco"}
    assert rp.backend_names(plan, "none") == ["pinocchio", "mujoco", GHOST]
    assert plan.label("mujoco") == "Gazebo: mujoco (engine-defaults)" and plan.label("dart") == "dart (matched)"


@pytest.fixture(scope="module")
def repro(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, rp.Table], str]:
    """One shortened ``legbench reproduce`` through the CLI: every task cut to 0.2 s."""
    mp = pytest.MonkeyPatch()
    mp.setitem(backends.BUILTIN, GHOST, ("legbench.backends.ghostengine_", "GhostBackend", "ghostengine"))
    tmp = tmp_path_factory.mktemp("repro")
    fw = _write(tmp, _plan_doc())
    out = tmp / "out"
    try:
        args = cli.build_parser(["reproduce"]).parse_args(
            [
                "reproduce",
                "--frameworks",
                str(fw),
                "--out",
                str(out),
                "--duration",
                "0.2",
                "--backends",
                "none",
                "--quiet",
            ]  # fmt: skip
        )
        status = args.func(args)
        plan = rp.load_plan(fw)
        runs = [results.load_run(out / name) for name in ("position", "ellipse", "effort", "combined")]
        tabs = {t.key: t for t in rp.tables(plan, runs, rp.backend_names(plan, "none"))}
    finally:
        mp.undo()
    assert status == 0  # a missing backend is a row, not a failure
    return out, tabs, (out / "reproduce.md").read_text()


def _metric(run_dir: Path, backend: str, signal: str, metric: str, reference: str = "") -> np.ndarray:
    """A backend's three values of one signal and metric from the run directory's metrics.json."""
    _, df = results.read_metrics(run_dir / "metrics.json")
    sel: pd.DataFrame = df[(df.backend == backend) & (df.signal == signal) & (df.metric == metric)]
    if reference:
        sel = sel[sel.reference == reference]
    assert len(sel) == 3, (backend, signal, metric)
    return sel["value"].to_numpy()


@pytest.fixture(scope="module")
def with_metrics(repro: tuple[Path, dict[str, rp.Table], str]) -> Path:
    """The results tree; each run directory has the metrics.json its report wrote (legbench compare's path)."""
    return repro[0]


def test_reproduce_writes_the_tables_and_ordinary_run_directories(repro: tuple[Path, dict[str, rp.Table], str]) -> None:
    out, tabs, md = repro
    assert set(tabs) == {"table10", "steady_force", "steady_fn", "sim_error_position", "sim_error_ellipse"}
    for f in ("reproduce.md", "reproduce.html", "reproduce.json"):
        assert (out / f).stat().st_size > 500
    for title in ("Table 10", "Steady ground force and its analytic check, task effort (legbench's; the source names "
                  "no table of it)", "Steady normal ground force per task (legbench's", "Simulation error %, task "
                  "position", "task ellipse"):  # fmt: skip
        assert title in md
    assert "Table 11" not in md and "Table 12" not in md  # the source's table 10 alone is described
    # strict JSON: an n/a cell is null (a bare NaN token is no JSON value)
    doc = json.loads((out / "reproduce.json").read_text(), parse_constant=lambda c: pytest.fail(f"{c} in JSON"))
    assert any(v is None for t in doc["tables"].values() for r in t["rows"] for v in r)
    # what made it (a provenance review: no versions, and nothing said the tasks were cut to 0.2 s)
    assert doc["duration"] == 0.2 and doc["versions"] == results.versions() and doc["platform"]["cpus"] >= 1
    assert "lab report, table 10: Gazebo (ODE, Coulomb friction)" in md
    meta = results.read_meta(out / "effort")
    assert meta["backends"]["pinocchio"]["info"]["profile"] == "matched"
    assert meta["backends"]["mujoco"]["info"]["profile"] == "engine-defaults"
    assert meta["backends"][GHOST]["status"] == "missing"
    assert meta["scenario"]["duration"] == 0.2


def test_table10_published_rows_and_steady_qd_equal_the_metrics(with_metrics: Path, repro: Any) -> None:
    t10 = repro[1]["table10"]
    published = [r for r in t10.rows if str(r[0]).startswith("lab report")]
    assert [list(r[1:]) for r in published] == [
        [4.0e-4, 8.7e-4, 6.4e-4, ""],
        [4.0e-4, 9.0e-4, 6.4e-4, ""],
        [2.3e-5, 3.6e-3, 8.6e-3, ""],
    ]
    rows = {r[0]: r[1:] for r in t10.rows}
    for label, name in (("legbench, Simscape: pinocchio (matched)", "pinocchio"),
                        ("legbench, Gazebo: mujoco (engine-defaults)", "mujoco")):  # fmt: skip
        np.testing.assert_allclose(
            rows[label][:3], np.abs(_metric(with_metrics / "effort", name, "qd", "steady_mean")), rtol=RTOL
        )
    run_ = results.load_run(with_metrics / "effort")  # the direction column is the run's steady state's
    cos = rows["legbench, Simscape: pinocchio (matched)"][3]
    assert cos == rp.steady_of(run_, "pinocchio").slide_cosine and -1.0 <= cos < 0.0  # it slides against friction
    ghost_row = rows[f"legbench, custom sim: {GHOST} (engine-defaults)"]
    assert str(ghost_row[0]).startswith("missing:")


def test_steady_force_and_its_check_equal_the_metrics(with_metrics: Path, repro: Any) -> None:
    rows = {r[0]: r[1:] for r in repro[1]["steady_force"].rows}
    run_ = results.load_run(with_metrics / "effort")
    for label, name, at in (("Simscape: pinocchio (matched)", "pinocchio", "true"),
                            ("Gazebo: mujoco (engine-defaults)", "mujoco", "true, 0.5 y above")):  # fmt: skip
        poc, *vals = rows[label]
        assert poc == at  # MuJoCo's own contact acts halfway through the penetration
        np.testing.assert_allclose(vals[0:3], _metric(with_metrics / "effort", name, "force", "steady_mean"), rtol=RTOL)
        np.testing.assert_allclose(
            vals[3:6], _metric(with_metrics / "effort", name, "force", "analytic_poc"), rtol=RTOL
        )
        assert np.isnan(vals[6:9]).all()  # true poc: nothing to compensate
        s = metrics.steady_state(run_.traces[name], run_.steady_window, "centre")
        assert s.poc_compensation is not None and np.abs(s.poc_compensation).max() > 0.01  # J_E != J_poc here
    assert str(rows[f"custom sim: {GHOST} (engine-defaults)"][0]).startswith("missing:")


def test_a_centre_poc_row_is_checked_at_the_centre_and_shown_at_the_true_poc(with_metrics: Path, repro: Any) -> None:
    """A law taking the poc at the sphere centre E applies its force there: its check is -h(J_E); 'at true poc' is
    -h(J_poc), the same torques' force at the true poc, apart from it by the friction's moment about E (> 1e-3 N)."""
    run_ = results.load_run(with_metrics / "effort")
    st = run_.backends["pinocchio"]
    centre = results.Run(**{**run_.__dict__, "backends": {**run_.backends, "pinocchio": results.BackendStatus(
        st.name, st.status, st.reason, {**st.info, "contact": {**st.info["contact"], "poc": "centre"}})}})  # fmt: skip
    plan = rp.Plan("<memory>", (rp.Framework("Simscape", "pinocchio", "matched"),), "matched", ())
    (row,) = rp.steady_force_table(plan, centre, ["pinocchio"]).rows
    s = metrics.steady_state(run_.traces["pinocchio"], run_.steady_window, "centre")
    assert row[1] == "centre" and s.analytic_centre is not None
    np.testing.assert_allclose(row[5:8], s.analytic_centre, rtol=RTOL)
    np.testing.assert_allclose(row[8:11], s.analytic_poc, rtol=RTOL)
    assert np.abs(np.subtract(row[5:8], row[8:11])).max() > 1e-3


def test_steady_fn_equals_the_metrics_per_task(with_metrics: Path, repro: Any) -> None:
    t12 = repro[1]["steady_fn"]
    assert t12.header == ("backend", "Fn, effort", "Fn, combined")
    rows = {r[0]: r[1:] for r in t12.rows}
    for label, name in (("Simscape: pinocchio (matched)", "pinocchio"), ("Gazebo: mujoco (engine-defaults)", "mujoco")):
        for col, task in enumerate(("effort", "combined")):
            fn = _metric(with_metrics / task, name, "force", "steady_mean")[2]
            assert rows[label][col] == pytest.approx(fn, rel=RTOL, abs=1e-12)
    assert all(str(c).startswith("missing:") for c in rows[f"custom sim: {GHOST} (engine-defaults)"])


@pytest.mark.parametrize("task", ["position", "ellipse"])
def test_sim_error_between_frameworks_equals_the_metrics(with_metrics: Path, repro: Any, task: str) -> None:
    table = repro[1][f"sim_error_{task}"]
    rows = {(r[0], r[1]): r[2:] for r in table.rows}
    # pinocchio (Simscape) against mujoco (Gazebo) over the scenario reference's (pinocchio's) peak: mujoco against
    # pinocchio in metrics.json, the same number (one denominator; docs/metrics.md), so each pair is shown once.
    # It was divided by b's own peak (0.1517 against 0.1516 % in a review's run).
    from_json = _metric(with_metrics / task, "mujoco", "q", "sim_error_pct", "pinocchio")
    np.testing.assert_allclose(rows[("Simscape", "Gazebo")], from_json, rtol=RTOL)
    run_ = results.load_run(with_metrics / task)
    own = metrics.pair_metrics(run_.traces["pinocchio"], run_.traces["mujoco"], run_.skip)  # mujoco's own peak
    assert not np.allclose(own.sim_error_pct[:3], rows[("Simscape", "Gazebo")], rtol=1e-9, atol=0)
    assert rows[("Simscape", "Gazebo")][0] > 0.0  # two engines: not identical traces
    assert str(rows[("Simscape", "custom sim")][0]).startswith(f"{GHOST} missing:")
    assert list(rows) == [("Simscape", "Gazebo"), ("Simscape", "custom sim"), ("Gazebo", "custom sim")]


def test_without_the_reference_each_ordered_pair_is_over_b_s_own_peak(
    with_metrics: Path, tmp_path: Path, ghost: None
) -> None:
    """The scenario's reference did not run: no common denominator, so a against b (over b's peak) and b against a
    differ, and every ordered pair is shown (6 for three frameworks)."""
    run_ = results.load_run(with_metrics / "position")
    no_ref = results.Run(**{**run_.__dict__, "reference": "drake"})  # a backend this run does not hold
    plan = rp.load_plan(_write(tmp_path, _plan_doc()))
    table = rp.sim_error_table(plan, no_ref)
    rows = {(r[0], r[1]): r[2:] for r in table.rows}
    assert len(rows) == 6 and "did not run" in table.caption
    own = metrics.pair_metrics(run_.traces["mujoco"], run_.traces["pinocchio"], run_.skip)
    np.testing.assert_allclose(rows[("Gazebo", "Simscape")], own.sim_error_pct[:3], rtol=RTOL)
    assert not np.allclose(rows[("Gazebo", "Simscape")], rows[("Simscape", "Gazebo")], rtol=1e-9, atol=0)


def _tiny(tmp_path: Path) -> Path:
    """A framework file of one task whose one framework backend is not installed: a reproduce of it runs no
    engine (the backend's row says missing) and writes one run directory and the pages."""
    doc = {"frameworks": [{"name": "custom sim", "backend": GHOST, "profile": "engine-defaults"}],
           "tasks": [{"file": str(SCENARIOS / "effort.yaml"), "tables": ["force"]}]}  # fmt: skip
    return _write(tmp_path, doc)


def _reproduce(fw: Path, *extra: str) -> list[str]:
    return ["reproduce", "--frameworks", str(fw), "--backends", "none", "--duration", "0.01", "--no-report", "-q",
            *extra]  # fmt: skip


def test_reproduce_refuses_a_folder_that_is_not_legbench_s(
    tmp_path: Path, ghost: None, capsys: pytest.CaptureFixture[str]
) -> None:
    """``legbench reproduce --out DIR`` into a non-empty folder of someone else's files wrote its runs and pages
    among them, exit 0: refused before any work, one line, exit 2, the folder as it was (also with --force)."""
    fw = _tiny(tmp_path)
    out = tmp_path / "mine"
    out.mkdir()
    (out / "notes.txt").write_text("keep me")
    for extra in ((), ("--force",)):
        assert cli.main(_reproduce(fw, "--out", str(out), *extra)) == 2
        err = capsys.readouterr().err
        assert err == f"legbench: error: {out}: not empty and not a legbench reproduce directory (it holds " \
                      "notes.txt); choose another --out\n"  # fmt: skip
        assert sorted(p.name for p in out.iterdir()) == ["notes.txt"]
    (out / "notes.txt").unlink()
    (out / "effort").mkdir()
    (out / "effort" / "notes.txt").write_text("keep me")  # a task's directory holding someone else's files
    assert cli.main(_reproduce(fw, "--out", str(out))) == 2
    assert "not empty and not a legbench run directory" in capsys.readouterr().err
    assert sorted(p.name for p in (out / "effort").iterdir()) == ["notes.txt"]


def test_reproduce_replaces_its_finished_runs_only_with_force(
    tmp_path: Path, ghost: None, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """A rerun of ``legbench reproduce`` silently replaced its finished task runs and tables, where ``run`` and
    ``sweep`` refuse without --force: refused in one line naming --force (exit 2, everything as it was), replaced
    with --force; an interrupted reproduce of the same command is resumed without it; tables whose runs are gone
    are not replaced without it either. Without --out, the message says to pass one."""
    import json

    fw = _tiny(tmp_path)
    out = tmp_path / "rep"
    argv = _reproduce(fw, "--out", str(out))
    assert cli.main(argv) == 0
    before = {p.name: p.read_bytes() for p in [*out.iterdir(), *(out / "effort").iterdir()] if p.is_file()}
    capsys.readouterr()
    assert cli.main(argv) == 2
    err = capsys.readouterr().err
    assert err == f"legbench: error: {out / 'effort'} holds a finished run; choose another --out for a new one, " \
                  "or --force to replace it\n"  # fmt: skip
    assert {p.name: p.read_bytes() for p in [*out.iterdir(), *(out / "effort").iterdir()] if p.is_file()} == before
    assert cli.main([*argv, "--force"]) == 0
    meta = json.loads((out / "effort" / "run.json").read_text())
    meta["backends"][GHOST] |= {"status": "interrupted", "reason": "not run: interrupted before it finished"}
    (out / "effort" / "run.json").write_text(json.dumps({**meta, "complete": False}))  # as Ctrl-C leaves it
    assert cli.main(argv) == 0  # resumed
    assert results.read_meta(out / "effort")["complete"] is True
    for p in (out / "effort").iterdir():
        p.unlink()
    (out / "effort").rmdir()
    capsys.readouterr()
    assert cli.main(argv) == 2
    assert capsys.readouterr().err == f"legbench: error: {out} holds a finished reproduce (reproduce.json); " \
                                      "choose another --out for a new one, or --force to replace it\n"  # fmt: skip
    assert not (out / "effort").exists()
    monkeypatch.chdir(tmp_path)
    assert cli.main(_reproduce(fw)) == 0  # the default, results/reproduce
    assert cli.main(_reproduce(fw)) == 2
    assert "holds a finished run; pass --out DIR for a new one, or --force" in capsys.readouterr().err


def test_the_switch_table_sets_the_report_s_task_4_beside_each_backend(tmp_path: Path) -> None:
    """The report's task 4 in Gazebo (first contact about 1.29 s; tau [1.04247, 0.186749, -0.30101] N m right
    after the switch, h_d still 0) was run as combined_ros but shown nowhere: the switch table gives the published
    row, then each backend's first contact (Fn > 0.5 N) and its torque at the switch (2.013 s), which with h_d = 0
    is G(q) there (the effort law's gravity term alone; unsaturated)."""
    doc = {"frameworks": [{"name": "Simscape", "backend": "pinocchio", "profile": "matched",
                           "note": "the spec's law, legbench's ABA"}],
           "tasks": [{"file": str(SCENARIOS / "combined_ros.yaml"), "tables": ["switch"]}]}  # fmt: skip
    plan = rp.load_plan(_write(tmp_path, doc))
    tabs, runs = rp.reproduce(plan, tmp_path / "out", ["pinocchio"], reports=False)
    (table,) = tabs
    assert table.key == "switch_combined_ros"
    published, mine = table.rows
    assert published[0].startswith("lab report, task 4: Gazebo") and list(published[1:]) == [
        1.29, 1.04247, 0.186749, -0.30101]  # fmt: skip
    tr = runs[0].traces["pinocchio"]
    k = int(np.searchsorted(tr.t, 2.013 - 1e-9))
    assert tr.t[k] == pytest.approx(2.013) and mine[1] == pytest.approx(1.139, abs=1e-3)
    np.testing.assert_allclose(mine[2:], tr.tau[k], rtol=0, atol=0)
    np.testing.assert_allclose(mine[2:], kinematics.gravity(tr.q[k]), rtol=1e-9, atol=1e-9)
    page = (tmp_path / "out" / "reproduce.md").read_text()
    assert "Simscape -> pinocchio with profile matched (the spec's law, legbench's ABA)" in page
