"""The Python API: legbench.run_scenario -> Result (DataFrames, compare, report, Jupyter rendering)."""

from __future__ import annotations

import dataclasses
import json
import shutil
import subprocess
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest

import legbench
from legbench import api, logs, resources
from legbench.compare import compare
from legbench.exceptions import LegbenchError, ResultsError, ScenarioError
from legbench.signals import RUN_COLUMNS

pytest.importorskip("mujoco")

#: The position task cut to 0.3 s (free space, PD holding the start pose against gravity), as a mapping.
SHORT = {"duration": 0.3, "comparison.steady_window": 0.1}


@pytest.fixture(scope="module")
def result(tmp_path_factory: pytest.TempPathFactory) -> api.Result:
    out = tmp_path_factory.mktemp("api") / "position"
    return legbench.run_scenario("position", backends=["pinocchio", "mujoco"], overrides=SHORT, out=out)


def test_frames_are_the_documented_log_columns(result: api.Result) -> None:
    """One DataFrame per backend, the run-directory columns, one row per control tick (0.3 s at 1 kHz: 301), and the
    same numbers as the parquet file legbench run writes (the API reads what the CLI writes, nothing recomputed)."""
    assert result.backends == ["pinocchio", "mujoco"] and result.status() == {"pinocchio": "ok", "mujoco": "ok"}
    for name, df in result.frames.items():
        assert list(df.columns) == list(RUN_COLUMNS) and len(df) == 301
        np.testing.assert_allclose(df["t"].iloc[-1], 0.3, rtol=0, atol=1e-12)
        import pandas as pd

        on_disk = pd.read_parquet(result.path / f"{name}.parquet")
        np.testing.assert_array_equal(df[["q1", "q2", "q3", "fz"]].to_numpy(), on_disk[["q1", "q2", "q3", "fz"]])
    assert result["mujoco"].equals(result.frames["mujoco"])


def test_two_engines_agree_in_free_space(result: api.Result) -> None:
    """Free space, the same PD torques at the same ticks, matched profile: MuJoCo stays within 1e-9 rad of Pinocchio
    over 0.3 s (measured 1e-16 rad: in free space the matched profile integrates alike; 1e-9 rad leaves room for
    round-off across platforms, while a wrong joint mapping, sign or tick would give 1e-3 rad or more); the leg sags
    (q2 moves by more than 0.1 rad from 0), and no ground force (the foot is in the air)."""
    s = result.compare().summary().set_index("backend")
    assert s.loc["mujoco", "q_max_abs"] < 1e-9
    assert s.loc["mujoco", "q2_steady"] < -0.1
    assert np.isnan(s.loc["pinocchio", "q_max_abs"])  # the reference against itself: not measured
    assert (result["mujoco"][["fx", "fy", "fz"]].abs().to_numpy() == 0.0).all()


def test_compare_is_legbench_compare(result: api.Result) -> None:
    """Comparison is a view of legbench.compare.compare on the run directory: the same metrics table row for row, and
    the summary's max |q - q_ref| is the largest q entry of the pair's max_abs."""
    mine = result.compare()
    theirs = compare(result.path)
    assert mine.metrics.equals(theirs.frame())
    pair = theirs.pair("mujoco")
    assert pair is not None
    assert mine.summary().set_index("backend").loc["mujoco", "q_max_abs"] == float(np.max(pair.max_abs[:3]))
    assert result.compare() is mine  # cached


def test_repr_html_tables(result: api.Result) -> None:
    page = result._repr_html_()
    assert page.count("<table>") == 2 and "<td>mujoco</td>" in page and "pinocchio (reference)" in page
    assert "max |q - q_ref| [rad]" in result.compare()._repr_html_()


def test_report_goes_to_a_new_directory_only(result: api.Result, tmp_path: Path) -> None:
    html = result.report(tmp_path / "rep")
    assert html == tmp_path / "rep" / "report.html" and html.is_file()
    metrics = json.loads((tmp_path / "rep" / "metrics.json").read_text())
    assert metrics["reference"] == "pinocchio" and set(metrics["backends"]) == {"pinocchio", "mujoco"}
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "mine.txt").write_text("keep")
    with pytest.raises(ResultsError, match="exists and is not empty"):
        result.report(tmp_path / "full")
    assert (tmp_path / "full" / "mine.txt").read_text() == "keep"


def test_a_report_that_fails_leaves_its_new_directory_as_it_was(result: api.Result, tmp_path: Path) -> None:
    """report(out_dir, log=<no such file>) copied the run into out_dir, then failed on the log, leaving a
    half-written directory behind. Now out_dir is removed again when it did not exist, and emptied when it was
    (the directory itself kept: its mode, a link to it)."""
    with pytest.raises(ResultsError, match="no such log file"):
        result.report(tmp_path / "new", log=tmp_path / "missing.csv")
    assert not (tmp_path / "new").exists()
    (tmp_path / "empty").mkdir()
    with pytest.raises(ResultsError, match="no such log file"):
        result.report(tmp_path / "empty", log=tmp_path / "missing.csv")
    assert (tmp_path / "empty").is_dir() and not any((tmp_path / "empty").iterdir())
    assert (result.path / "run.json").is_file()  # the run itself untouched
    # an existing directory keeps its mode (it was removed and made again, 0o755), a link its target's contents
    (tmp_path / "mine").mkdir(mode=0o700)
    (tmp_path / "real").mkdir()
    (tmp_path / "link").symlink_to(tmp_path / "real")
    for out in ("mine", "link"):
        with pytest.raises(ResultsError, match="no such log file"):
            result.report(tmp_path / out, log=tmp_path / "missing.csv")
    assert (tmp_path / "mine").stat().st_mode & 0o777 == 0o700 and not any((tmp_path / "mine").iterdir())
    assert (tmp_path / "link").is_symlink() and not any((tmp_path / "real").iterdir())


def test_a_report_into_a_folder_inside_the_run_is_refused_as_on_the_command_line(
    result: api.Result, tmp_path: Path
) -> None:
    """report(run/sub) wrote a copy of the run inside the run (taken for part of it, lost with it), where
    ``legbench compare`` refuses an --out inside a run: now refused before anything is written, naming ``out_dir``;
    so is a link that leads inside the run. report(out_dir=the run itself) still writes into the run."""
    run = tmp_path / "run"
    shutil.copytree(result.path, run)
    opened = api.open_run(run)
    before = sorted(p.name for p in run.iterdir())
    with pytest.raises(LegbenchError) as exc:
        opened.report(run / "sub")
    assert str(exc.value) == f"out_dir {run / 'sub'}: inside the run directory {run}, which holds one run; choose " \
                             "another out_dir"  # fmt: skip
    (run / "empty").mkdir()
    (tmp_path / "link").symlink_to(run / "empty")
    with pytest.raises(LegbenchError, match=r"^out_dir .*link: inside the run directory .*run, which holds one run"):
        opened.report(tmp_path / "link")
    assert sorted(p.name for p in run.iterdir()) == sorted([*before, "empty"]) and not any((run / "empty").iterdir())
    html = opened.report(run)
    assert html == run / "report.html" and html.is_file()


def test_a_report_beside_the_run_named_from_inside_it_is_written(
    result: api.Result, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """From inside the run directory, report("../copy") goes beside the run, not inside it: the path is taken
    after its ``..`` (it was refused as inside the run, whose name the unresolved path still held)."""
    run = tmp_path / "run"
    shutil.copytree(result.path, run)
    monkeypatch.chdir(run)
    html = api.open_run(".").report("../copy")
    assert (tmp_path / "copy" / "report.html").is_file() and html == Path("../copy/report.html")
    assert not (run / "copy").exists()


def test_mapping_profile_and_both_contact_modes(tmp_path: Path) -> None:
    """A mapping scenario, the engine-defaults profile and both contact modes: two sibling run directories, the
    profile recorded in each run.json, and the native comparison split against the reference-mode one."""
    doc = {
        "name": "hold",
        "duration": 0.05,
        "initial": {"q": [0.0, -0.8, -1.6]},
        "events": [{"t": 0.0, "position": {"joint": [0.0, -0.8, -1.6]}}],
        "comparison": {"steady_window": 0.02},
    }
    res = legbench.run_scenario(doc, backends="pinocchio,mujoco", profile="engine-defaults", contact_mode="both",
                                out=tmp_path)  # fmt: skip
    assert res.reference_mode is not None
    assert res.path.parent == res.reference_mode.path.parent == tmp_path
    assert (res.contact_mode, res.reference_mode.contact_mode) == ("native", "reference")
    meta = json.loads((res.path / "run.json").read_text())
    assert meta["scenario"]["profile"] == "engine-defaults"
    assert res.compare().result.split_run is not None


def test_bad_input_is_a_scenario_error(tmp_path: Path) -> None:
    with pytest.raises(ScenarioError, match=r"<mapping>: duration"):
        api.load_scenario({"name": "x", "duration": -1, "events": []})
    with pytest.raises(ScenarioError, match="duration"):
        legbench.run_scenario("position", backends="pinocchio", overrides={"duration": "soon"}, out=tmp_path)
    assert not any(tmp_path.iterdir())  # nothing half-written


def test_jobs_below_1_and_a_file_as_out_are_refused_before_anything_runs(tmp_path: Path) -> None:
    """``jobs=0`` raises LegbenchError as the CLI's --jobs 0 is refused (it ran anyway); ``out`` naming a regular
    file raises LegbenchError saying so (it was a raw NotADirectoryError); nothing is written."""
    with pytest.raises(LegbenchError, match="jobs 0: must be at least 1"):
        legbench.run_scenario("position", backends="pinocchio", overrides=SHORT, out=tmp_path / "r", jobs=0)
    assert not (tmp_path / "r").exists()
    f = tmp_path / "file"
    f.write_text("keep me")
    with pytest.raises(LegbenchError, match="is a regular file, not a directory"):
        legbench.run_scenario("position", backends="pinocchio", overrides=SHORT, out=f)
    assert f.read_text() == "keep me" and sorted(p.name for p in tmp_path.iterdir()) == ["file"]


def test_an_out_inside_a_run_or_a_link_to_nothing_is_refused_as_on_the_command_line(
    result: api.Result, tmp_path: Path
) -> None:
    """``out`` inside a run directory wrote a second run inside the first (taken for part of it, or lost with it),
    and ``out`` a symbolic link to nothing ran every backend before failing to move the result into place: the
    command line refused both before any work, the API now too, naming ``out``; nothing is written."""
    before = sorted(p.name for p in result.path.iterdir())
    with pytest.raises(LegbenchError) as exc:
        legbench.run_scenario("position", backends="pinocchio", overrides=SHORT, out=result.path / "sub")
    assert str(exc.value) == (f"out {result.path / 'sub'}: inside the run directory {result.path.absolute()}, "
                              "which holds one run; choose another out")  # fmt: skip
    assert sorted(p.name for p in result.path.iterdir()) == before
    link = tmp_path / "link"
    link.symlink_to(tmp_path / "gone")
    with pytest.raises(LegbenchError, match=r"^out .*link: a symbolic link to .*gone, which does not exist; choose"):
        legbench.run_scenario("position", backends="pinocchio", overrides=SHORT, out=link)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["link"] and not (tmp_path / "gone").exists()


def test_a_finished_run_in_out_is_replaced_only_with_force(tmp_path: Path) -> None:
    """As the command line: a second run_scenario into the ``out`` of a finished run raises LegbenchError naming
    force=True and leaves the run as it was; with force=True it is replaced."""
    out = tmp_path / "r"
    legbench.run_scenario("position", backends="pinocchio", overrides=SHORT, out=out)
    before = (out / "run.json").read_bytes()
    with pytest.raises(LegbenchError, match="holds a finished run; choose another out for a new one, or force=True"):
        legbench.run_scenario("position", backends="pinocchio", overrides=SHORT, out=out)
    assert (out / "run.json").read_bytes() == before
    legbench.run_scenario("position", backends="pinocchio", overrides=SHORT, out=out, force=True)
    assert (out / "run.json").read_bytes() != before  # rewritten: its wall times differ


def test_bundled_scenarios_by_name() -> None:
    assert api.load_scenario("effort").sha256 == api.load_scenario(resources.scenario("effort")).sha256
    assert api.load_scenario("verification/energy").name == "energy"


def test_import_legbench_is_light() -> None:
    """``import legbench`` imports no numpy, pandas or engine; the API names resolve on first use."""
    code = (
        "import sys, legbench; print(sorted(m for m in ('numpy', 'pandas', 'pinocchio', 'mujoco') if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"
    assert legbench.run_scenario is api.run_scenario and "run_scenario" in dir(legbench)


def test_a_resumed_run_returns_every_backend_asked_for(tmp_path: Path) -> None:
    """An interrupted run into ``out`` is resumed: only the unfinished backend runs again, and the Result still holds
    every backend asked for, in that order (it held only the one that ran: the reference's frame was missing), the
    kept one read back from the run directory with its wall time."""
    out = tmp_path / "r"
    first = legbench.run_scenario("position", backends=["pinocchio", "mujoco"], overrides=SHORT, out=out)
    meta = json.loads((out / "run.json").read_text())  # as a run stopped by Ctrl-C during mujoco leaves it
    meta["complete"] = False
    meta["backends"]["mujoco"] |= {"status": "interrupted", "reason": "interrupted"}
    (out / "run.json").write_text(json.dumps(meta))
    (out / "mujoco.parquet").unlink()
    res = legbench.run_scenario("position", backends=["pinocchio", "mujoco"], overrides=SHORT, out=out)
    assert res.backends == ["pinocchio", "mujoco"] and res.status() == {"pinocchio": "ok", "mujoco": "ok"}
    assert res["pinocchio"].equals(first["pinocchio"])
    assert res.traces["pinocchio"].wall_time == meta["backends"]["pinocchio"]["wall_time"]
    assert res.compare().summary()["backend"].tolist() == ["pinocchio", "mujoco"]


def test_out_holding_another_scenarios_run_is_refused_even_with_force(tmp_path: Path) -> None:
    """As ``legbench run``: a run directory of scenario 'position' is not replaced by a run of another scenario, with
    or without force=True (the error offered force=True, which then failed with another message); it stays as it
    was."""
    out = tmp_path / "r"
    legbench.run_scenario("position", backends="pinocchio", overrides=SHORT, out=out)
    before = (out / "run.json").read_bytes()
    other = {**api.load_scenario("position", SHORT).raw, "name": "other"}
    for force in (False, True):
        with pytest.raises(LegbenchError, match=r"holds results of scenario 'position', not 'other'"):
            legbench.run_scenario(other, backends="pinocchio", out=out, force=force)
    assert (out / "run.json").read_bytes() == before


def test_both_contact_modes_refuse_a_foreign_folder_or_a_run_as_out(tmp_path: Path) -> None:
    """With contact_mode='both' ``out`` is a results tree's root, refused as ``legbench run --contact-mode both
    --out`` refuses it, before anything runs: a folder holding the user's files (both runs were written beside them)
    and a run directory (two run directories were written inside it)."""
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("keep")
    with pytest.raises(LegbenchError, match=r"not a legbench results tree directory \(it holds notes.txt\)"):
        legbench.run_scenario("position", backends="pinocchio", overrides=SHORT, out=mine, contact_mode="both")
    assert [p.name for p in mine.iterdir()] == ["notes.txt"]
    run = tmp_path / "run"
    legbench.run_scenario("position", backends="pinocchio", overrides=SHORT, out=run)
    before = sorted(p.name for p in run.iterdir())
    with pytest.raises(LegbenchError, match="holds one run, and 2 runs make a tree of run directories"):
        legbench.run_scenario("position", backends="pinocchio", overrides=SHORT, out=run, contact_mode="both")
    assert sorted(p.name for p in run.iterdir()) == before


@pytest.mark.parametrize("overrides", [[("duration", 0.3)], {1: 0.3}, {"": 0.3}])
def test_overrides_not_a_mapping_of_keys_is_a_scenario_error(overrides: Any, tmp_path: Path) -> None:
    """``overrides`` that is not a mapping of dotted keys raises ScenarioError naming it (it was an AttributeError or
    TypeError from inside the loader)."""
    with pytest.raises(ScenarioError, match=r"<overrides>: .*expected a"):
        legbench.run_scenario("position", backends="pinocchio", overrides=overrides, out=tmp_path / "r")
    assert not (tmp_path / "r").exists()


@pytest.mark.parametrize("jobs", [1.5, "2", True])
def test_jobs_not_a_whole_number_is_refused(jobs: Any, tmp_path: Path) -> None:
    """``jobs`` must be a whole number: 1.5 ran silently in one process, "2" was a TypeError, True was taken as 1."""
    with pytest.raises(LegbenchError, match=r"jobs .*: expected a whole number of processes, at least 1"):
        legbench.run_scenario("position", backends="pinocchio", overrides=SHORT, out=tmp_path / "r", jobs=jobs)
    assert not (tmp_path / "r").exists()


_SCRIPT = """import legbench

def main():
    legbench.run_scenario("position", backends=["pinocchio", "mujoco"], overrides={short!r}, out={out!r}, jobs=2)
    print("done")

{call}
"""


def test_jobs_2_from_a_script_under_the_main_guard_gives_the_jobs_1_logs(result: api.Result, tmp_path: Path) -> None:
    """A script calling run_scenario(jobs=2) under ``if __name__ == "__main__":`` runs both backends in worker
    processes and writes the same logs, bit for bit, as the same run with jobs=1."""
    out = tmp_path / "r"
    script = tmp_path / "guarded.py"
    script.write_text(_SCRIPT.format(short=SHORT, out=str(out), call='if __name__ == "__main__":\n    main()'))
    done = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=600)
    assert done.returncode == 0 and done.stdout.strip() == "done", done.stderr
    import pandas as pd

    for name in ("pinocchio", "mujoco"):
        assert pd.read_parquet(out / f"{name}.parquet").equals(pd.read_parquet(result.path / f"{name}.parquet"))


def test_jobs_2_at_a_scripts_top_level_is_refused_before_anything_runs(tmp_path: Path) -> None:
    """Without the guard the workers import the script again and run the call again: they died, and the Result came
    back with every backend "failed: the engine crashed". Now the pool refuses to start (studies.executors: for a
    sweep or a reproduce too), with a LegbenchError naming the script's line and the guard, and nothing is written."""
    out = tmp_path / "r"
    script = tmp_path / "bare.py"
    script.write_text(_SCRIPT.format(short=SHORT, out=str(out), call="main()"))
    done = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=600)
    assert done.returncode == 1 and "done" not in done.stdout
    last = done.stderr.strip().splitlines()[-1]
    assert (
        last.startswith("legbench.exceptions.LegbenchError: ")
        and f"{script}:7: 2 worker processes started outside" in last
    )
    assert 'if __name__ == "__main__":' in last and not out.exists()


def test_an_unknown_backend_names_the_argument_the_caller_used() -> None:
    """The API's error named the command line's option ("--backends mujocoo: ..."): it names ``backends``, one
    line, with the backends available here; it is the registry's UnknownBackend either way."""
    from legbench.exceptions import UnknownBackend

    with pytest.raises(UnknownBackend) as exc:
        legbench.run_scenario("effort", backends=["pinocchio", "mujocoo"])
    assert str(exc.value).startswith("backends mujocoo: unknown backend; available here: ")
    assert "--backends" not in str(exc.value) and "\n" not in str(exc.value)


# --------------------------------------------------------------------------- #
# open_run: a run directory already on disk as a Result


def test_open_run_gives_back_the_result_run_scenario_returned(result: api.Result) -> None:
    """open_run on run_scenario's ``out``: the same backends in the same order and statuses, every log column
    exactly, the settings and wall times run.json records, the scenario validated again from run.json (equal to the
    one that ran but for its file name, which run.json shows relative), the contact mode and the metrics; reading
    writes nothing."""
    before = sorted(p.name for p in result.path.iterdir())
    opened = legbench.open_run(str(result.path))
    assert opened.path == result.path and opened.backends == result.backends == ["pinocchio", "mujoco"]
    assert opened.status() == result.status()
    for name in result.backends:
        pd.testing.assert_frame_equal(opened[name], result[name], check_exact=True)
        assert opened.traces[name].info == result.traces[name].info
        assert opened.traces[name].wall_time == result.traces[name].wall_time
    assert dataclasses.replace(opened.scenario, file=result.scenario.file) == result.scenario
    assert (opened.scenario.name, opened.scenario.duration) == ("position", 0.3)
    assert opened.scenario.sha256 == result.scenario.sha256
    assert opened.contact_mode == result.contact_mode == "native" and opened.reference_mode is None
    pd.testing.assert_frame_equal(opened.compare().metrics, result.compare().metrics, check_exact=True)
    assert sorted(p.name for p in result.path.iterdir()) == before


def test_open_run_keeps_a_failed_backend_failed_with_its_reason(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A backend that failed mid-run (MuJoCo raising at its 20th step, in this process: jobs=1) is opened as failed,
    with its reason, settings and no log (its partial log is not a result); the comparison is the original's, and
    report() with no directory writes into the run directory, as ``legbench compare DIR`` does."""
    from legbench.backends.mujoco_ import MujocoBackend

    real = MujocoBackend.step
    steps = [0]

    def failing(self: MujocoBackend, tau: np.ndarray) -> None:
        steps[0] += 1
        if steps[0] == 20:
            raise RuntimeError("the solver gave up")
        real(self, tau)

    monkeypatch.setattr(MujocoBackend, "step", failing)
    out = tmp_path / "r"
    res = legbench.run_scenario("position", backends=["pinocchio", "mujoco"], overrides=SHORT, out=out)
    assert res.traces["mujoco"].status == "failed"
    opened = legbench.open_run(out)
    assert opened.status() == res.status() and opened.status()["mujoco"].startswith("failed: RuntimeError at t = ")
    tr = opened.traces["mujoco"]
    assert (tr.status, tr.reason) == ("failed", res.traces["mujoco"].reason) and "the solver gave up" in str(tr.reason)
    assert len(tr.t) == 0 and tr.info == res.traces["mujoco"].info and list(opened.frames) == ["pinocchio"]
    with pytest.raises(KeyError, match="backend 'mujoco' failed: RuntimeError"):
        opened["mujoco"]
    pd.testing.assert_frame_equal(opened["pinocchio"], res["pinocchio"], check_exact=True)
    pd.testing.assert_frame_equal(opened.compare().metrics, res.compare().metrics, check_exact=True)
    assert opened.report() == out / "report.html" and (out / "report.html").is_file()
    assert json.loads((out / "metrics.json").read_text())["backends"]["mujoco"]["status"] == "failed"


def test_open_run_of_a_native_run_opens_its_reference_mode_sibling(result: api.Result, tmp_path: Path) -> None:
    """contact_mode="both" writes <name>/ and <name>__reference/: opening the native one opens the other as
    reference_mode, and its comparison is split as the original's; the reference-mode run opened alone has none. A
    sibling that is not the same scenario in reference mode is not taken for one."""
    res = legbench.run_scenario("position", backends=["pinocchio", "mujoco"], overrides=SHORT, contact_mode="both",
                                out=tmp_path / "both")  # fmt: skip
    assert res.reference_mode is not None
    opened = legbench.open_run(res.path)
    ref = opened.reference_mode
    assert ref is not None and ref.path == res.reference_mode.path and ref.reference_mode is None
    assert (opened.contact_mode, ref.contact_mode) == ("native", "reference")
    for mine, theirs in ((opened, res), (ref, res.reference_mode)):
        for name in theirs.backends:
            pd.testing.assert_frame_equal(mine[name], theirs[name], check_exact=True)
    cmp = opened.compare()
    assert cmp.result.split_run is not None and cmp.result.split_run.path == ref.path
    pd.testing.assert_frame_equal(cmp.metrics, res.compare().metrics, check_exact=True)
    alone = legbench.open_run(res.reference_mode.path)
    assert alone.contact_mode == "reference" and alone.reference_mode is None
    # two native runs side by side, one named as the other's sibling: no reference_mode
    shutil.copytree(result.path, tmp_path / "x")
    shutil.copytree(result.path, tmp_path / "x__reference")
    assert legbench.open_run(tmp_path / "x").reference_mode is None


def test_open_run_of_what_is_not_a_run_directory_says_what_it_is(result: api.Result, tmp_path: Path) -> None:
    """A missing path, a file, run.json itself, a folder without run.json and a results tree's root: ResultsError,
    one line starting with the path, saying what it is and what open_run wants."""
    (tmp_path / "notes.txt").write_text("mine")
    (tmp_path / "empty").mkdir()
    tree = result.path.parent  # the fixture's folder, holding the run directory "position"
    cases = {
        tmp_path / "nope": "no such run directory",
        tmp_path / "notes.txt": "is a regular file, not a run directory (a folder holding run.json)",
        result.path / "run.json": f"is a regular file, not a run directory (open its folder, {result.path})",
        tmp_path / "empty": "no run.json here: not a legbench run directory",
        tree: f"is a results tree of 1 run(s), not a run directory: open one of them, e.g. {result.path}",
    }
    for path, what in cases.items():
        with pytest.raises(ResultsError) as exc:
            legbench.open_run(path)
        assert str(exc.value) == f"{path}: {what}"


def test_open_run_refuses_a_scenario_it_cannot_validate_again(result: api.Result, tmp_path: Path) -> None:
    """run.json's scenario.raw is validated again: missing, invalid here, or not the scenario that ran (its hash
    differs from scenario.sha256) is a ResultsError naming run.json and the key, not a Result of another scenario."""
    out = tmp_path / "r"
    shutil.copytree(result.path, out)
    meta = json.loads((out / "run.json").read_text())
    edits: list[tuple[Any, str]] = [
        (None, "missing key 'scenario.raw'"),
        ({**meta["scenario"]["raw"], "duration": -1}, "scenario.raw: does not validate here (duration: must be > 0"),
        ({**meta["scenario"]["raw"], "duration": 0.2}, "scenario.raw: hashes to "),
    ]
    for raw, problem in edits:
        doc = json.loads(json.dumps(meta))
        if raw is None:
            del doc["scenario"]["raw"]
        else:
            doc["scenario"]["raw"] = raw
        (out / "run.json").write_text(json.dumps(doc))
        with pytest.raises(ResultsError) as exc:
            legbench.open_run(out)
        assert str(exc.value).startswith(f"{out / 'run.json'}: {problem}"), str(exc.value)


def test_open_run_is_exported_lazily() -> None:
    assert legbench.open_run is api.open_run and "open_run" in legbench.__all__ and "open_run" in dir(legbench)


# --------------------------------------------------------------------------- #
# Errors an API caller receives from other modules name the API's arguments (out, overrides, log_time_scale,
# column_map, ros), not the command line's options: each module takes the wording from its caller. The command
# line's own wording of the same errors, unchanged, is asserted in test_cli.py and test_logs.py.


@pytest.mark.parametrize("as_mapping", [False, True], ids=["by name", "as a mapping"])
@pytest.mark.parametrize(
    ("overrides", "ends"),
    [
        ({"events[0].t": 0.1}, "overrides: events[0].t: a list item is written with a dot: events.0.t"),
        ({"events.7.t": 0.1}, "overrides: events.7.t: 'events' is a list of 1: '7' is not an index of it"),
        ({"duration.x": 0.1}, "overrides: duration.x: 'duration' is 3.0, not a mapping"),
        ({"duration": "soon"}, ": duration: expected a number, got 'soon' (from overrides duration)"),
    ],
)
def test_an_override_error_names_overrides_not_set(overrides: dict[str, Any], ends: str, as_mapping: bool) -> None:
    """yamlfile.set_key (its file "--set" on the command line) and YamlContext.error ("(from --set KEY)"), reached by
    load_scenario of a bundled scenario's name (through scenario.load) or of a mapping."""
    source: str | Mapping[str, Any] = api.load_scenario("position").raw if as_mapping else "position"
    with pytest.raises(ScenarioError) as exc:
        api.load_scenario(source, overrides)
    assert "--set" not in str(exc.value) and str(exc.value).endswith(ends), str(exc.value)


def test_a_bad_profile_is_not_blamed_on_overrides(tmp_path: Path) -> None:
    """run_scenario(profile=...) sets the scenario's profile, but not through ``overrides``: its error names the
    profile alone."""
    with pytest.raises(ScenarioError) as exc:
        legbench.run_scenario("position", backends="pinocchio", profile="bogus", out=tmp_path / "r")
    assert str(exc.value).startswith(f"{api.load_scenario('position').file}: profile: expected one of matched, "
                                     "engine-defaults")  # the scenario's file, not "<mapping>"  # fmt: skip
    assert "overrides" not in str(exc.value) and "--set" not in str(exc.value)


@pytest.mark.parametrize("holds", ["a foreign file", "a corrupt run.json", "another scenario's run", "a foreign tree"])
def test_a_refused_out_names_out_not_the_option(holds: str, result: api.Result, tmp_path: Path) -> None:
    """results.check_out_dir (through run.check_outs) and results.check_out_tree (through run.check_tree, with
    contact_mode="both"): "choose another --out" on the command line."""
    out, mode = tmp_path / "r", None
    scenario: str | dict[str, Any] = "position"
    overrides: dict[str, Any] | None = SHORT
    out.mkdir()
    if holds in ("a foreign file", "a foreign tree"):
        (out / "notes.txt").write_text("mine")
        mode = "both" if holds == "a foreign tree" else None
    elif holds == "a corrupt run.json":
        (out / "run.json").write_text("{")
    else:
        out, overrides = result.path, None
        scenario = {**api.load_scenario("position", SHORT).raw, "name": "other"}
    with pytest.raises(LegbenchError) as exc:
        legbench.run_scenario(scenario, backends="pinocchio", overrides=overrides, out=out, contact_mode=mode)
    assert "--out" not in str(exc.value) and "choose another out" in str(exc.value)


def test_a_bad_log_time_scale_names_the_argument(result: api.Result, tmp_path: Path) -> None:
    """logs.load_log: "--log-time-scale 0.0: ..." on the command line, reached by Result.compare(log=...,
    log_time_scale=0)."""
    log = tmp_path / "log.csv"
    result["mujoco"].drop(columns=["controller"]).to_csv(log, index=False)
    with pytest.raises(LegbenchError) as exc:
        result.compare(log=log, log_time_scale=0.0)
    assert str(exc.value) == "log_time_scale 0.0: must be a finite number > 0 (1e-3 for ms)"


def test_log_errors_name_the_arguments_of_compare(
    result: api.Result, tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """The messages of legbench.logs through Result.compare and Result.report: two header columns of one legbench
    column, and none for q1, name ``column_map`` (not "--log-columns ... (column_map in the Python API)"); a log
    in ms is a warning naming ``log_time_scale=1e-3`` (not "--log-time-scale 1e-3"). Outside the API, logs' own
    default wording is the command line's again."""
    from legbench import logs

    df = result["mujoco"].drop(columns=["controller"])
    dup, none, ms = tmp_path / "dup.csv", tmp_path / "none.csv", tmp_path / "ms.csv"
    df.assign(**{"q1 [rad]": df["q1"]}).to_csv(dup, index=False)
    df.rename(columns={"q1": "hip"}).to_csv(none, index=False)
    df.assign(t=df["t"] * 1000.0).to_csv(ms, index=False)
    for call in (lambda log: result.compare(log=log), lambda log: result.report(tmp_path / log.stem, log=log)):
        with pytest.raises(ResultsError) as exc:
            call(dup)
        assert str(exc.value) == f"{dup}: several header columns map to ['q1']; choose one with column_map"
        with pytest.raises(ResultsError) as exc:
            call(none)
        assert str(exc.value).endswith("; map them with column_map={'theirs': 't', ...}"), str(exc.value)
    with caplog.at_level("WARNING", logger="legbench.logs"):
        result.compare(log=ms)
    assert f"{ms}: median time step 1 s: is the time in ms? (log_time_scale=1e-3)" in caplog.text
    with pytest.raises(ResultsError, match=r"choose one with --log-columns \(column_map in the Python API\)$"):
        logs.load_log(dup)


# --------------------------------------------------------------------------- #
# Arguments of the wrong type or value: one LegbenchError naming the argument and what it takes, before anything is
# read, written or run (they were TypeErrors from pathlib, AttributeErrors, KeyErrors, or taken for their truth).


def _tree(path: Path) -> dict[str, bytes]:
    """Every file under ``path``, by relative name, with its bytes."""
    return {str(p.relative_to(path)): p.read_bytes() for p in sorted(path.rglob("*")) if p.is_file()}


@pytest.mark.parametrize(
    ("flag", "value", "message"),
    [
        ("force", "no", "force 'no': expected True or False, not str"),
        ("force", 1, "force 1: expected True or False, not int"),
        ("force", None, "force None: expected True or False, not NoneType"),
        ("progress", "yes", "progress 'yes': expected True or False, not str"),
    ],
)
def test_a_flag_not_a_bool_is_refused_and_a_finished_run_left_byte_for_byte(
    flag: str, value: Any, message: str, result: api.Result
) -> None:
    """force="no" replaced the finished run in ``out`` ("no" is truthy): a flag must be True or False, else one
    LegbenchError naming it, and the run is left as it was, every file byte for byte."""
    before = _tree(result.path)
    with pytest.raises(LegbenchError) as exc:
        legbench.run_scenario("position", backends=["pinocchio", "mujoco"], overrides=SHORT, out=result.path,
                              **{flag: value})  # fmt: skip
    assert str(exc.value) == message
    assert _tree(result.path) == before


def test_numpy_bools_are_flags(result: api.Result) -> None:
    """np.False_ is False: the finished run is refused without force, not replaced."""
    before = _tree(result.path)
    with pytest.raises(LegbenchError, match="holds a finished run; choose another out for a new one, or force=True"):
        legbench.run_scenario("position", backends=["pinocchio", "mujoco"], overrides=SHORT, out=result.path,
                              force=np.False_, progress=np.False_)  # fmt: skip
    assert _tree(result.path) == before


_SCENARIO_TYPES = "expected a bundled scenario's name, a scenario file (str or os.PathLike)"


@pytest.mark.parametrize(
    ("scenario", "shown"),
    [
        (123, "123 ... int"),
        (None, "None ... NoneType"),
        (["a"], "['a'] ... list"),
        (b"position", "b'position' ... bytes"),
    ],  # fmt: skip
)
def test_a_scenario_of_another_type_is_refused(scenario: Any, shown: str, tmp_path: Path) -> None:
    """run_scenario(123 | None | ["a"] | b"position") and load_scenario(...) raised pathlib's TypeError."""
    value, kind = shown.split(" ... ")
    with pytest.raises(LegbenchError) as exc:
        legbench.run_scenario(scenario, backends="pinocchio", overrides=SHORT, out=tmp_path / "r")
    assert str(exc.value) == (f"scenario {value}: {_SCENARIO_TYPES}, a mapping in the scenario format or a Scenario, "
                              f"not {kind}")  # fmt: skip
    with pytest.raises(LegbenchError) as exc:
        legbench.load_scenario(scenario)
    assert str(exc.value) == f"source {value}: {_SCENARIO_TYPES} or a mapping in the scenario format, not {kind}"
    assert not (tmp_path / "r").exists()


def test_load_scenario_refuses_overrides_not_a_mapping() -> None:
    """load_scenario("position", [1]) was an AttributeError from the loader, as run_scenario's overrides once were."""
    with pytest.raises(ScenarioError) as exc:
        legbench.load_scenario("position", [1])  # type: ignore[arg-type]
    assert str(exc.value) == "<overrides>: expected a mapping of dotted keys to values, got list"


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"out": 5}, "out 5: expected a directory (str or os.PathLike) or None, not int"),
        (
            {"out": ""},
            "out '': expected a directory (str or os.PathLike) or None, not an empty name or one holding "
            "a NUL character",
        ),  # fmt: skip
        (
            {"backends": 5},
            "backends 5: expected backend names: a list of strings, a comma-separated string or 'all', not int",
        ),  # fmt: skip
        (
            {"backends": [1, 2]},
            "backends [1, 2]: expected backend names: a list of strings, a comma-separated string "
            "or 'all', not a list holding 1 (int)",
        ),  # fmt: skip
        ({"profile": 5}, "profile 5: expected 'matched' or 'engine-defaults', not int"),
        ({"contact_mode": ["both"]}, "contact_mode ['both']: expected 'native', 'reference' or 'both'"),
    ],
)
def test_run_scenario_arguments_of_the_wrong_type_are_refused(kwargs: dict[str, Any], message: str) -> None:
    """out=5 was pathlib's TypeError, ``out=""`` the working directory; backends=5 "'int' object is not iterable",
    backends=[1, 2] an AttributeError."""
    args: dict[str, Any] = {"backends": "pinocchio", "overrides": SHORT} | kwargs
    with pytest.raises(LegbenchError) as exc:
        legbench.run_scenario("position", **args)
    assert str(exc.value) == message


@pytest.mark.parametrize("path", [5, None, b"/tmp"])
def test_open_run_of_a_path_of_another_type_is_refused(path: Any) -> None:
    """open_run(5 | None | b"...") was pathlib's TypeError."""
    with pytest.raises(LegbenchError) as exc:
        legbench.open_run(path)
    assert str(exc.value) == f"path {path!r}: expected a run directory (str or os.PathLike), not {type(path).__name__}"


_LAG_SIGNALS = "expected a non-empty list of signal names from q, qd, tau, force, e.g. ['q']"
_NEED_LOG = "need log (they describe that log)"


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"lag": "x"}, "lag 'x': expected one of 'off', 'report', 'remove'"),
        ({"max_lag": float("nan")}, "max_lag nan: must be a finite number > 0 [s] (the largest lag searched)"),
        ({"max_lag": "x"}, "max_lag 'x': must be a finite number > 0 [s] (the largest lag searched)"),
        ({"max_lag": -1}, "max_lag -1: must be a finite number > 0 [s] (the largest lag searched)"),
        ({"max_lag": 0}, "max_lag 0: must be a finite number > 0 [s] (the largest lag searched)"),
        ({"lag_signals": ("zz",)}, f"lag_signals ('zz',): {_LAG_SIGNALS}"),
        ({"lag_signals": "qd"}, f"lag_signals 'qd': {_LAG_SIGNALS}"),
        (
            {"column_map": ["a"]},
            "column_map ['a']: expected a mapping of the log's header names to legbench columns, "
            "e.g. {'joint1_pos': 'q1'}, not list",
        ),  # fmt: skip
        (
            {"log": "x.csv", "column_map": {"a": " "}},
            "column_map {'a': ' '}: expected HEADER: COLUMN, two non-empty strings, e.g. {'joint1_pos': 'q1'}",
        ),  # fmt: skip
        ({"log": 5}, "log 5: expected a log file or ROS bag (str or os.PathLike), not int"),
        ({"log_time_scale": "x"}, "log_time_scale 'x': must be a finite number > 0 (1e-3 for ms)"),
        ({"log_is_reference": True}, f"log_is_reference: {_NEED_LOG}"),
        ({"column_map": {"a": "q1"}, "log_time_scale": 1e-3}, f"column_map, log_time_scale: {_NEED_LOG}"),
        ({"log_is_reference": "yes"}, "log_is_reference 'yes': expected True or False, not str"),
        ({"all_pairs": "no"}, "all_pairs 'no': expected True or False, not str"),
        ({"ros": "x"}, "ros 'x': expected legbench.logs.RosOptions(...), not str"),
        (
            {"log": "x.csv", "ros": logs.RosOptions()},
            "ros: need log naming a ROS bag (a .bag file, a ROS 2 bag directory or its .db3 / .mcap file)",
        ),  # fmt: skip
        ({"log": "x.bag", "ros": logs.RosOptions(force_sign=2.0)}, "ros.force_sign 2.0: expected 1.0 or -1.0"),
        ({"log_name": 5}, "log_name 5: expected a non-empty name (str), not int"),
        ({"split_dir": 5}, "split_dir 5: expected a run directory (str or os.PathLike), 'auto' or None, not int"),
        (
            {"bogus": 1},
            "bogus: not an argument of {method} (it takes log, log_name, column_map, log_time_scale, log_t0, "
            "log_is_reference, ros, all_pairs, lag, max_lag, lag_signals, split_dir)",
        ),  # fmt: skip
    ],
)
def test_compare_and_report_refuse_a_bad_argument_by_name(
    kwargs: dict[str, Any], message: str, result: api.Result, tmp_path: Path
) -> None:
    """Result.compare raised ValueError (lag="x", max_lag=nan), TypeError (max_lag="x", log=5, log_time_scale="x"),
    KeyError (lag_signals=("zz",)), or took max_lag=-1, ros="x" and log_is_reference=True without a log (which
    ``legbench compare`` refuses: its options that describe the log need the log, its ROS options a ROS bag, as
    here). Result.report, taking the same arguments, refuses them the same, before its out_dir is made."""
    for method in ("compare", "report"):
        with pytest.raises(LegbenchError) as exc:
            if method == "compare":
                result.compare(**kwargs)
            else:
                result.report(tmp_path / "rep", **kwargs)
        assert str(exc.value) == message.replace("{method}", method)
    assert not (tmp_path / "rep").exists()


def test_the_api_checks_every_argument_of_compare() -> None:
    """Result.compare passes on the keyword arguments of legbench.compare.compare: each has its check."""
    import inspect

    kw_only = [p.name for p in inspect.signature(compare).parameters.values() if p.kind is p.KEYWORD_ONLY]
    assert list(api._COMPARE_ARGS) == kw_only


@pytest.mark.parametrize("kind", ["a regular file", "a link to nothing"])
def test_a_report_into_a_file_or_a_link_to_nothing_is_refused(kind: str, result: api.Result, tmp_path: Path) -> None:
    """report(<a file>) was NotADirectoryError, report(<a link to nothing>) FileExistsError: as --out of the command
    line, a LegbenchError naming out_dir; the file and the link stay as they were."""
    out = tmp_path / "out"
    if kind == "a regular file":
        out.write_text("keep")
        expected = f"out_dir {out}: is a regular file, not a directory"
    else:
        out.symlink_to(tmp_path / "gone")
        expected = (
            f"out_dir {out}: a symbolic link to {tmp_path / 'gone'}, which does not exist; choose another out_dir"
        )
    with pytest.raises(LegbenchError) as exc:
        result.report(out)
    assert str(exc.value) == expected
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]
    assert out.read_text() == "keep" if kind == "a regular file" else out.is_symlink() and not out.exists()
    with pytest.raises(LegbenchError) as exc:
        result.report(5)  # type: ignore[arg-type]
    assert str(exc.value) == "out_dir 5: expected a directory (str or os.PathLike) or None, not int"


def test_an_unknown_backend_key_lists_the_backends_it_has(result: api.Result) -> None:
    """res["nosuch"] was a bare KeyError('nosuch'): still a KeyError (a mapping's), saying which backends there are."""
    for key, shown in (("nosuch", "'nosuch'"), (5, "5")):
        with pytest.raises(KeyError) as exc:
            result[key]  # type: ignore[index]
        assert exc.value.args[0] == f"no backend {shown} in this run; its backends: pinocchio, mujoco"


def test_log_t0_is_checked_and_needs_a_log(result: api.Result, tmp_path: Path) -> None:
    """Result.compare(log_t0=...) takes what `--log-t0` takes: a finite number [s], with a log."""
    with pytest.raises(LegbenchError) as exc:
        result.compare(log_t0=2.0)
    assert str(exc.value) == "log_t0: need log (they describe that log)"
    with pytest.raises(LegbenchError) as exc:
        result.compare(log=tmp_path / "x.csv", log_t0=float("inf"))
    assert str(exc.value) == "log_t0 inf: must be a finite number [s] (the log's time at the run's t = 0)"


def test_a_folder_named_as_a_bundled_scenario_does_not_shadow_it(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """run_scenario("effort") failed with "effort: is a directory, not a file" where the working directory held
    a folder named effort (a run's own output): a folder is no scenario file, so the bundled name is taken."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "effort").mkdir()
    sc = api.load_scenario("effort")
    assert sc.name == "effort" and sc.duration == 3.0


def test_a_mapping_may_hold_tuples_and_numpy_values_as_a_python_user_writes_them() -> None:
    """A scenario mapping or override holding a tuple or a numpy array where the format has a list (a joint
    target, gains) was refused as "expected a list of 3 numbers, got (0, -1, -1)"; numpy scalars are numbers. They
    load as the same scenario as the plain lists (same hash), and the caller's mapping is left as it was."""
    plain = {"name": "x", "duration": 0.05, "events": [{"t": 0, "position": {"joint": [0.0, -1.0, -1.0]}}]}
    target = np.array([0.0, -1.0, -1.0])
    numpyish = {"name": "x", "duration": np.array(0.05),  # a 0-d array: the number
                "events": ({"t": np.int64(0), "position": {"joint": target}},)}  # fmt: skip
    a = legbench.load_scenario(plain, overrides={"gains.Kp": [12, 12.0, 12]})
    b = legbench.load_scenario(numpyish, overrides={"gains.Kp": (12, np.float32(12.0), np.int64(12))})
    assert b.events[0].joint == a.events[0].joint == (0.0, -1.0, -1.0)
    assert b.gains.Kp == a.gains.Kp == (12.0, 12.0, 12.0)
    assert b.sha256 == a.sha256
    assert isinstance(numpyish["events"], tuple) and numpyish["events"][0]["position"]["joint"] is target
    with pytest.raises(ScenarioError, match=r"events\[0\]\.position\.joint: expected .*a list of 3 numbers"):
        legbench.load_scenario({**plain, "events": [{"t": 0, "position": {"joint": np.array([0.0, -1.0])}}]})


def test_a_profile_or_contact_mode_given_twice_is_refused_as_on_the_command_line(tmp_path: Path) -> None:
    """``overrides={"profile": ...}`` beside ``profile=`` (or the contact mode beside ``contact_mode=``): one of
    the two won in silence; refused as the command line refuses ``--set profile=... --profile ...``, naming the
    override and the argument, before anything is written."""
    cases: list[tuple[dict[str, Any], dict[str, Any], str]] = [
        ({"profile": "engine-defaults"}, {"profile": "matched"}, "overrides: profile: also given by "
                                                                   "profile='matched'; give it in one place"),
        ({"physics.contact_mode": "reference"}, {"contact_mode": "native"}, "overrides: physics.contact_mode: "
                                                                            "also given by contact_mode='native'"),
    ]  # fmt: skip
    for overrides, kwargs, words in cases:
        with pytest.raises(ScenarioError) as exc:
            legbench.run_scenario("position", backends=["pinocchio"], overrides={**overrides, "duration": 0.05},
                                  out=tmp_path / "r", **kwargs)  # fmt: skip
        assert str(exc.value).startswith(words), exc.value
        assert not (tmp_path / "r").exists()
