"""The one validated reader of run directories (legbench.results): a hand-edited or corrupt run.json or
metrics.json is one line naming the file, the key and the problem, exit 2, and nothing is written."""

from __future__ import annotations

import hashlib
import json
import math
import os
import stat
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest
from fakerun import scale, write_run

from legbench import cli, results
from legbench.exceptions import LegbenchError, ResultsError


def _set(path: Path, key: str, value: Any) -> None:
    """Set a dotted key of a JSON file (``scenario.comparison.skip``), as a hand edit would."""
    doc = json.loads(path.read_text())
    *head, last = key.split(".")
    cur = doc
    for k in head:
        cur = cur[k]
    cur[last] = value
    path.write_text(json.dumps(doc))  # NaN and Infinity as Python's json writes (and reads) them


BAD_RUN_JSON = [
    # (key edited, value, key named in the error, the problem named): each used to be a traceback of float(),
    # iteration or numpy indexing, or a metrics.json that could not be written (NaN)
    ("scenario.duration", "abc", "scenario.duration", "must be a finite number > 0, not 'abc'"),
    ("scenario.duration", math.nan, "scenario.duration", "must be a finite number > 0, not nan"),
    ("scenario.duration", -1.0, "scenario.duration", "must be a finite number > 0"),
    ("scenario.duration", True, "scenario.duration", "must be a finite number > 0, not True"),
    ("scenario.events", 5, "scenario.events", "must be a list of events, not int 5"),
    ("scenario.events", [5], "scenario.events[0]", "must be an object, not int 5"),
    ("scenario.comparison.steady_window", -5, "scenario.comparison.steady_window", "must be a finite number > 0"),
    ("scenario.comparison.steady_window", 9.0, "scenario.comparison.steady_window", "longer than the run (2 s)"),
    ("scenario.comparison.skip", math.inf, "scenario.comparison.skip", "must be a finite number >= 0, not inf"),
    ("scenario.comparison.skip", 2.0, "scenario.comparison.skip", "is not shorter than the run (2 s)"),
    ("scenario.comparison", "x", "scenario.comparison", "must be an object, not str 'x'"),
    ("scenario.contact_mode", "sideways", "scenario.contact_mode", "must be one of ['native', 'reference']"),
    ("scenario.contact", {"Kp": "stiff"}, "scenario.contact.Kp", "must be a finite number >= 0, not 'stiff'"),
    ("scenario.contact", {"gravity": 9.81}, "scenario.contact.gravity", "unknown contact parameter"),
    ("scenario.name", 3, "scenario.name", "must be a non-empty string, not 3"),
    ("backends", "x", "backends", "must be an object, not str 'x'"),
    ("backends.a", 5, "backends.a", "must be an object, not int 5"),
    ("backends.a.status", "done", "backends.a.status", "must be one of ['ok', 'failed', 'missing', 'interrupted']"),
]


@pytest.mark.parametrize(("key", "value", "shown", "problem"), BAD_RUN_JSON,
                         ids=[f"{k}={v!r}" for k, v, _, _ in BAD_RUN_JSON])  # fmt: skip
def test_compare_names_a_hand_edited_run_json_field_in_one_line_and_writes_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], key: str, value: Any, shown: str, problem: str
) -> None:
    """Each field compare, check and the report use is checked once, where run.json is read: its type, that it
    is finite and in range (skip inside the run, a positive steady window no longer than the run), and a
    backend status legbench writes. The error names run.json and the dotted key; no report is half-written."""
    run = write_run(tmp_path / "one", {"ref": None, "a": scale(1.1)}, name="one")
    rj = run / "run.json"
    _set(rj, key, value)
    before = sorted(p.name for p in run.iterdir())
    assert cli.main(["compare", str(run)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert err.startswith(f"legbench: error: {rj}: {shown}: "), err
    assert problem in err
    assert sorted(p.name for p in run.iterdir()) == before  # no metrics.json, report or assets/


def test_read_meta_keeps_the_documented_defaults_of_absent_fields(tmp_path: Path) -> None:
    """Checking is not requiring: a run.json without the optional comparison fields and events still reads,
    with skip 0, steady window 0.5 s, the default reference and no events (older run directories)."""
    run = write_run(tmp_path / "one", {"pinocchio": None}, name="one")
    rj = run / "run.json"
    doc = json.loads(rj.read_text())
    del doc["scenario"]["comparison"], doc["scenario"]["events"], doc["scenario"]["contact"]
    rj.write_text(json.dumps(doc))
    loaded = results.load_run(run)
    assert (loaded.skip, loaded.steady_window, loaded.reference, loaded.events) == (0.0, 0.5, "pinocchio", ())
    assert loaded.poc == "true"


def test_a_results_error_names_the_key_between_file_and_problem() -> None:
    """The same shape as a ScenarioError: file, dotted key, problem, on one line."""
    exc = ResultsError("r/run.json", "must be a finite number > 0, not 'abc'", "scenario.duration")
    assert str(exc) == "r/run.json: scenario.duration: must be a finite number > 0, not 'abc'"
    assert (exc.file, exc.key) == ("r/run.json", "scenario.duration")
    assert str(ResultsError("r/a.parquet", "no such file")) == "r/a.parquet: no such file"


def test_a_run_json_without_duration_is_compared_with_duration_null(tmp_path: Path) -> None:
    """scenario.duration is checked when present, not required (run.json written outside legbench, or older):
    compare measures the logs as they are, and metrics.json says duration null (it used to fail writing NaN,
    which JSON does not allow)."""
    run = write_run(tmp_path / "one", {"ref": None, "a": scale(1.1)}, name="one")
    doc = json.loads((run / "run.json").read_text())
    del doc["scenario"]["duration"]
    (run / "run.json").write_text(json.dumps(doc))
    assert cli.main(["compare", str(run)]) == 0
    head, _ = results.read_metrics(run / "metrics.json")
    assert head["duration"] is None


@pytest.mark.parametrize(
    ("path", "words"),
    [("/dev/null", "--out /dev/null: is a character device, not a directory"),
     ("/dev/null/sub", "--out /dev/null/sub: /dev/null is a character device, not a directory")],
)  # fmt: skip
def test_an_out_that_is_a_device_is_called_a_device(path: str, words: str) -> None:
    """``check_out_path('/dev/null')`` called /dev/null 'a regular file': the message says what it is."""
    with pytest.raises(LegbenchError) as exc:
        results.check_out_path(path)
    assert str(exc.value) == words and "regular file" not in str(exc.value)


def test_an_out_that_is_a_regular_file_is_still_called_one(tmp_path: Path) -> None:
    f = tmp_path / "file"
    f.write_text("keep")
    with pytest.raises(LegbenchError, match=r": is a regular file, not a directory$"):
        results.check_out_path(f)
    with pytest.raises(LegbenchError, match=rf": {f} is a regular file, not a directory$"):
        results.check_out_path(f / "sub")


@pytest.mark.skipif(not Path("/proc/self").is_dir(), reason="no /proc file system here")
def test_an_out_where_nothing_can_be_made_is_refused_whatever_the_permissions_say(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """As root, /proc's permissions read writable and the run failed only when it staged its output (exit 4, an
    I/O error, after the pre-flight): a folder is made there and removed at once, and the refusal is the one line
    of bad input (exit 2). (os.access is made to say yes, as it does for root, so the test checks the folder made
    whoever runs it.) A writable place is left as it was."""
    monkeypatch.setattr(results.os, "access", lambda *_a, **_k: True)
    with pytest.raises(LegbenchError, match=r"^--out /proc/legbench_out: /proc is not writable"):
        results.check_out_path("/proc/legbench_out")
    results.check_out_path(tmp_path / "new" / "run")
    assert list(tmp_path.iterdir()) == []


def test_run_json_names_the_model_active_when_the_run_is_written(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """run.json's ``urdf`` is the URDF of the model ``--model`` selected, which happens after legbench.results is
    imported: it named the bundled leg.urdf for every ``--model`` run (the name was taken at import), so a
    report could not tell which leg the run used."""
    import re

    from legbench import resources

    monkeypatch.setenv(resources.CACHE_ENV, str(tmp_path / "cache"))
    monkeypatch.delenv(resources.MODEL_ENV, raising=False)
    text, n = re.subn(r"(\n\s*gravity:\s*)9\.81", r"\g<1>9.0", resources.bundled_model().read_text())
    assert n == 1
    params = tmp_path / "heavy_leg.yaml"
    params.write_text(text)
    out = tmp_path / "run"
    try:
        argv = ["--model", str(params), "run", str(resources.scenario("position")), "--backends", "pinocchio",
                "--set", "duration=0.01", "--set", "comparison.steady_window=0.005", "--out", str(out), "--no-compare",
                "-q"]  # fmt: skip
        assert cli.main(argv) == 0
        want = resources.urdf_target().name
    finally:
        resources.select_model(None)
    assert want.startswith("heavy_leg-") and want.endswith(".urdf")
    assert json.loads((out / "run.json").read_text())["urdf"] == want


def test_a_refused_output_directory_names_what_the_caller_named_it_with(tmp_path: Path) -> None:
    """check_out_dir and check_out_tree end in "choose another OPTION": ``--out`` by default (the command line's),
    ``out`` as the Python API passes it."""
    from legbench import scenario

    sc = scenario.load(Path(__file__).resolve().parents[1] / "scenarios" / "position.yaml")
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("keep")
    other = write_run(tmp_path / "other", {"ref": None, "a": scale(1.01)})  # scenario 'fake'
    corrupt = tmp_path / "corrupt"
    corrupt.mkdir()
    (corrupt / "run.json").write_text("{")
    for option in ("--out", "out"):
        given = () if option == "--out" else (option,)  # --out: the default
        with pytest.raises(LegbenchError) as exc:
            results.check_out_dir(sc, mine, *given)
        assert str(exc.value) == (f"{mine}: not empty and not a legbench run directory (it holds notes.txt); choose "
                                  f"another {option}")  # fmt: skip
        with pytest.raises(LegbenchError) as exc:
            results.check_out_dir(sc, other, *given)
        assert str(exc.value).endswith(f"not 'position'; choose another {option} or remove it")
        with pytest.raises(LegbenchError) as exc:
            results.check_out_dir(sc, corrupt, *given)
        assert str(exc.value).endswith(f"(not written by legbench); choose another {option} or remove it")
        with pytest.raises(LegbenchError) as exc:
            results.check_out_tree(mine, ["a"], (), "results tree", *given)
        assert str(exc.value).endswith(f"(it holds notes.txt); choose another {option}")


def test_a_log_that_is_a_folder_is_one_results_error(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """a.parquet replaced by a folder: load_run read it as missing while the metrics' log digests tried to read
    the folder, an I/O error (exit 4) from compare, "missing" from open_run. Now one ResultsError naming the file
    (exit 2 from compare), and log_digests hashes only files."""
    run = write_run(tmp_path / "one", {"ref": None, "a": scale(1.1)}, name="one")
    (run / "a.parquet").unlink()
    (run / "a.parquet").mkdir()
    with pytest.raises(ResultsError) as exc:
        results.load_run(run)
    assert str(exc.value) == f"{run / 'a.parquet'}: is a directory, not a backend log (run.json says a ran ok)"
    assert list(results.log_digests(run)) == ["ref.parquet"]
    assert cli.main(["compare", str(run)]) == 2
    assert capsys.readouterr().err.count("\n") == 1


@pytest.mark.parametrize("name", ["../../other/a.parquet", "../a.parquet", "sub/a.parquet", "/etc/passwd", "..", "."])
def test_a_backend_file_outside_the_run_directory_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], name: str
) -> None:
    """run.json's backends.<name>.file was joined to the run directory and followed wherever it led: a hand-edited
    ``../../other/a.parquet`` was read (and measured) as the backend's log, ``/etc/passwd`` read as parquet. Now
    the validated reader refuses anything but a plain file name in the run directory, one line naming run.json
    and the key, and compare writes nothing."""
    run = write_run(tmp_path / "one", {"ref": None, "a": scale(1.1)}, name="one")
    other = tmp_path / "other"
    other.mkdir()
    (other / "a.parquet").write_bytes((run / "a.parquet").read_bytes())
    (run / "sub").mkdir()
    (run / "sub" / "a.parquet").write_bytes((run / "a.parquet").read_bytes())
    (run / "a.parquet").replace(tmp_path / "a.parquet")  # what ../a.parquet names
    rj = run / "run.json"
    _set(rj, "backends.a.file", name)
    with pytest.raises(ResultsError) as exc:
        results.read_meta(run)
    assert exc.value.key == "backends.a.file" and exc.value.file == str(rj)
    before = sorted(p.name for p in run.iterdir())
    assert cli.main(["compare", str(run)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(f"legbench: error: {rj}: backends.a.file: must be a plain file name")
    assert sorted(p.name for p in run.iterdir()) == before


def test_a_backend_file_that_is_a_plain_name_is_read(tmp_path: Path) -> None:
    """The check refuses only names that leave the directory: a log renamed and run.json edited to match reads."""
    run = write_run(tmp_path / "one", {"ref": None, "a": scale(1.1)}, name="one")
    (run / "a.parquet").rename(run / "a-renamed.parquet")
    _set(run / "run.json", "backends.a.file", "a-renamed.parquet")
    assert results.load_run(run).backends["a"].status == "ok"


# --------------------------------------------------------------------------- #
# Output paths: links, devices, files of the user's, names too long for the temporaries


def _special_files(tmp_path: Path) -> dict[str, Path]:
    """A FIFO, a link to a regular file, a link to nothing and (as root) a character device, all under tmp_path
    (never a real /dev node)."""
    target = tmp_path / "target.md"
    target.write_text("mine")
    found = {"a FIFO": tmp_path / "fifo", "a link": tmp_path / "link", "a dangling link": tmp_path / "dangling"}
    os.mkfifo(found["a FIFO"])
    found["a link"].symlink_to(target)
    found["a dangling link"].symlink_to(tmp_path / "nowhere")
    if os.geteuid() == 0:
        found["a character device"] = tmp_path / "dev"
        os.mknod(found["a character device"], stat.S_IFCHR | 0o644, os.makedev(1, 7))
    return found


def test_an_output_file_that_is_a_link_or_no_regular_file_is_refused(tmp_path: Path) -> None:
    """check_out_file passed a FIFO, a device and a symbolic link (to a file, or to nothing): the writers rename
    a new file over the name, so ``--summary DEVICE --force`` turned the device into a plain file and a link to
    /proc/self/fd/1 into one; each is refused, naming what it is, and left as it was."""
    found = _special_files(tmp_path)
    for kind, path in found.items():
        words = "a symbolic link" if "link" in kind else f"is {kind}, not a regular file"
        with pytest.raises(LegbenchError, match=rf"^--summary {path}: {words}"):
            results.check_out_file(path, "--summary")
    assert (tmp_path / "link").is_symlink() and (tmp_path / "target.md").read_text() == "mine"
    assert stat.S_ISFIFO((tmp_path / "fifo").lstat().st_mode)
    assert results.check_out_file(tmp_path / "target.md") == tmp_path / "target.md"


def test_an_output_file_inside_a_run_directory_is_refused(tmp_path: Path) -> None:
    """check_out_file let ``model urdf --out RUN/run.json --force`` replace a run's run.json: a file inside a run
    directory is refused (the rule of check_out_path), unless the caller has its own rule (``in_run_ok``)."""
    run = write_run(tmp_path / "r", {"ref": None})
    for path in (run / "run.json", run / "leg.urdf"):
        with pytest.raises(LegbenchError, match=rf"^--out {path}: inside the run directory {run}, which holds one"):
            results.check_out_file(path)
        assert results.check_out_file(path, in_run_ok=True) == path


def test_an_out_whose_temporary_names_would_not_fit_is_refused(tmp_path: Path) -> None:
    """An --out of 250 characters passed (the name fits 255), the whole run ran, then writing its temporary
    sibling ``.<name>.tmp-<pid>`` failed, exit 4: check_out_path and check_out_file refuse a name whose temporaries
    do not fit, before any work; 242 characters (the temporary at 255, a 7-digit PID) still pass, 243 do not."""
    for check in (results.check_out_path, results.check_out_file):
        for n in (250, 243):
            with pytest.raises(LegbenchError, match=rf"a name of {n} characters; .* must fit 255, so at most 242 "):
                check(tmp_path / ("a" * n))
        assert check(tmp_path / ("a" * 242)) == tmp_path / ("a" * 242)


def test_a_run_directory_holding_the_users_files_is_refused(tmp_path: Path) -> None:
    """A single-scenario ``run --out DIR --force`` of a run directory holding notes.txt and a folder of the
    user's deleted both (the run replaces the whole directory): check_out_dir refuses it, naming the entry,
    --force or not (as check_out_tree does for a tree); what legbench writes into a run directory passes."""
    from legbench import scenario

    sc = scenario.load(Path(__file__).resolve().parents[1] / "scenarios" / "position.yaml")
    run = write_run(tmp_path / "r", {"ref": None}, name=sc.name)
    for name in {*results.RUN_FILES, "ref.csv", ".x.tmp-1"} - {"run.json"}:
        (run / name).write_text("")
    results.check_out_dir(sc, run)
    (run / "myplots").mkdir()
    with pytest.raises(LegbenchError, match=rf"^{run}: not only a legbench run directory \(it holds myplots\)"):
        results.check_out_dir(sc, run)
    assert (run / "myplots").is_dir()


def test_atomic_dir_writes_through_a_link(tmp_path: Path) -> None:
    """atomic_dir of a symbolic link to a folder replaced the link by a new folder (the folder it named kept the
    old contents); now the folder the link names is replaced, and the link stays."""
    target = tmp_path / "target"
    target.mkdir()
    (target / "old.txt").write_text("old")
    link = tmp_path / "link"
    link.symlink_to(target)
    with results.atomic_dir(link) as tmp:
        (tmp / "new.txt").write_text("new")
    assert link.is_symlink() and sorted(p.name for p in target.iterdir()) == ["new.txt"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["link", "target"]


@pytest.mark.parametrize(
    ("value", "words"),
    [("corrupt", "'corrupt'"), ([1], r"\[1\]"), ("NaN", "'NaN'"), (True, "True"), (math.inf, "inf")],
)
def test_a_metrics_value_that_is_no_number_is_refused(tmp_path: Path, value: Any, words: str) -> None:
    """read_metrics turned a row's value "corrupt", [1] or "NaN" into NaN (n/a), so a corrupt baseline passed
    ``legbench check`` with every row "new": a value not a finite number or null is refused, naming the row."""
    d = write_run(tmp_path / "r", {"ref": None})
    results.write_metrics({"schema": results.METRICS_SCHEMA, "backends": {}, "metrics": []}, d / "metrics.json")
    doc = json.loads((d / "metrics.json").read_text())
    row = dict(zip(results.FRAME_COLUMNS, ("fake", "ref", "", "qd", "1", "steady_mean", 0.5), strict=True))
    doc["metrics"] = [row, {**row, "joint": "2", "value": value}]
    (d / "metrics.json").write_text(json.dumps(doc))
    with pytest.raises(ResultsError, match=rf"metrics\.json: metrics\[1\]\.value: must be a finite number or null "
                                           rf"\(n/a\), not {words} \(row fake/ref//qd/2/steady_mean\)$"):  # fmt: skip
        results.read_metrics(d / "metrics.json")


def test_a_metrics_row_given_twice_is_refused(tmp_path: Path) -> None:
    """Two rows of one metric (same key columns) were both read, and which one a check compared depended on the
    table's order: the second is refused, naming the first."""
    d = tmp_path / "metrics.json"
    row = dict(zip(results.FRAME_COLUMNS, ("fake", "ref", "", "qd", "1", "steady_mean", 0.5), strict=True))
    results.write_metrics({"schema": results.METRICS_SCHEMA, "backends": {}, "metrics": [row, row]}, d)
    with pytest.raises(ResultsError, match=r"metrics\[1\]: the same row as metrics\[0\] \(fake/ref//qd/1/"):
        results.read_metrics(d)


def test_a_full_disk_names_the_output_it_was_writing(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A full disk reads "No space left on device" with no file (the OS names none for a write): the atomic writers
    name the output they were making, so the CLI's one line says where (it read "legbench: I/O error: No space left
    on device; nothing was replaced"); the previous file and directory stay as they were."""
    import errno

    def full(*args: Any, **kwargs: Any) -> None:
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    target = tmp_path / "page.md"
    target.write_text("before")
    with pytest.MonkeyPatch.context() as m:
        m.setattr(os, "fsync", full)
        with pytest.raises(OSError) as exc:
            results.atomic_write_text(target, "after")
        assert exc.value.filename == str(target) and target.read_text() == "before"
        with pytest.raises(OSError) as exc:
            results.stage_text(target, "after", "t")
        assert exc.value.filename == str(target)
    run_dir = tmp_path / "run"
    with pytest.raises(OSError) as exc, results.atomic_dir(run_dir) as tmp:
        (tmp / "x").write_text("x")
        full()
    assert exc.value.filename == str(run_dir) and not run_dir.exists()
    # through the CLI: one line naming the output (legbench compare of a run whose page cannot be written)
    d = write_run(tmp_path / "fake", {"ref": None, "a": scale(1.01)})
    with pytest.MonkeyPatch.context() as m:
        m.setattr(os, "fsync", full)
        assert cli.main(["compare", str(d)]) == 4
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"legbench: I/O error: {d}") and "No space left on device" in err[0]


# --------------------------------------------------------------------------- #
# What a result holds, what run.json says of it, and the readers' limits


def test_a_signal_with_some_missing_samples_is_still_present() -> None:
    """``RunResult.has`` is true with at least one finite sample: an imported log whose force is NaN in 2 of its 5
    rows (a ROS bag's wrench span shorter than the joint states') still has a force, and gets its figure; NaN in
    every row (or no column) is no force. A mutation audit found no test holding it (``.all()`` passed)."""
    t = np.arange(5) * 1e-3
    fz = np.array([np.nan, 20.0, 21.0, 22.0, np.nan])
    df = pd.DataFrame({"t": t, "q1": 0.1, "q2": -1.0, "q3": -1.2, "fx": 0.0, "fy": 0.0, "fz": fz})
    df.loc[[0, 4], ["fx", "fy"]] = np.nan
    tr = results.result_from_frame(df, "log")
    assert int(np.isnan(tr.signal("force")).any(axis=1).sum()) == 2
    assert tr.has("force") and tr.has("q")
    assert not tr.has("tau")  # no tau column: NaN in all 5 rows
    df["fx"] = df["fy"] = df["fz"] = np.nan
    assert not results.result_from_frame(df, "log").has("force")


def test_run_json_rtf_is_simulated_time_over_wall_time(tmp_path: Path) -> None:
    """run.json's ``rtf`` (the real-time factor the report's backend table shows) is simulated time / wall time:
    2 s simulated in 0.5 s of wall time is 4.0 (0.25 is the inverse), read back as 4.0 by load_run. A mutation
    audit found no test holding it."""
    from legbench import scenario

    sc = scenario.parse({"name": "fake", "duration": 2.0, "events": [{"t": 0.0, "position": {"joint": [0, -1, -1]}}]})
    n = 5
    t = np.linspace(0.0, 2.0, n)
    zeros = np.zeros((n, 3))
    tr = results.RunResult("a", t, zeros, zeros, zeros, zeros, np.full(n, "position", dtype=object), wall_time=0.5)
    out = results.write_run(sc, [tr], tmp_path / "fake")
    entry = json.loads((out / "run.json").read_text())["backends"]["a"]
    assert (entry["wall_time"], entry["rtf"]) == (0.5, 4.0)
    assert results.load_run(out).backends["a"].rtf == 4.0


@pytest.mark.parametrize(("rows_cut", "last_t", "refused"), [(2, 1.998, True), (1, 1.999, True), (0, 1.9996, False)],
                         ids=["2 periods short", "1 period short", "0.4 period short"])  # fmt: skip
def test_an_ok_log_may_end_at_most_half_a_control_period_before_the_duration(
    tmp_path: Path, rows_cut: int, last_t: float, refused: bool
) -> None:
    """An ok backend's log spans 0 .. duration to half a control period (0.5 ms at 1 kHz): of a 2 s run, a log
    ending at 1.998 s (two periods short, the last two rows lost) or 1.999 s is cut short, one ending 0.4 ms early
    (1.9996 s) is whole. A mutation audit found only a log cut to 10 of 2001 rows tested (a tolerance of 5 periods
    passed)."""
    run = write_run(tmp_path / "one", {"ref": None, "a": scale(1.1)}, name="one")
    log = run / "a.parquet"
    df = pd.read_parquet(log)
    df = df.iloc[: len(df) - rows_cut].copy()
    df.loc[df.index[-1], "t"] = last_t
    df.to_parquet(log, index=False)
    if not refused:
        assert results.load_run(run).traces["a"].t[-1] == 1.9996
        return
    with pytest.raises(ResultsError) as exc:
        results.load_run(run)
    assert str(exc.value).startswith(f"{log}: column 't' spans 0 .. {last_t:g} s ({2001 - rows_cut} rows), not the "
                                     "scenario's 0 .. 2 s")  # fmt: skip
    assert str(exc.value).endswith("the log is cut short")


def test_a_steady_window_longer_than_the_run_is_refused_and_one_as_long_is_read(tmp_path: Path) -> None:
    """run.json's steady_window may be as long as the run, not longer: of a 1 s run, 1.5 s is refused naming the
    key ("1.5 s is longer than the run (1 s)"), 1.0 s is read. A mutation audit found only 9 s of a 2 s run
    tested (a limit of twice the run passed)."""
    run = write_run(tmp_path / "one", {"ref": None}, name="one", duration=1.0)
    rj = run / "run.json"
    _set(rj, "scenario.comparison.steady_window", 1.5)
    with pytest.raises(ResultsError) as exc:
        results.read_meta(run)
    assert str(exc.value) == f"{rj}: scenario.comparison.steady_window: 1.5 s is longer than the run (1 s)"
    _set(rj, "scenario.comparison.steady_window", 1.0)
    assert results.load_run(run).steady_window == 1.0


@pytest.mark.parametrize("bad", [True, "3.71", -9.81, None])
def test_run_json_gravity_is_a_number_or_refused(tmp_path: Path, bad: Any) -> None:
    """run.json's scenario.gravity [m/s^2] is read as given (3.71, the integer 4); absent (null), the leg file's
    9.81. ``true`` (Python's bool is an int: 1 m/s^2?), the string "3.71" or a negative number are refused naming
    the key (the first two were read as the leg file's 9.81, silently, the last as given: a mutation audit, then a
    review of its finding)."""
    from legbench.model import load_params

    run = write_run(tmp_path / "one", {"ref": None}, name="one", gravity=3.71)
    assert results.load_run(run).gravity == 3.71
    _set(run / "run.json", "scenario.gravity", 4)
    assert results.load_run(run).gravity == 4.0
    _set(run / "run.json", "scenario.gravity", bad)
    if bad is None:
        assert results.load_run(run).gravity == load_params().gravity == 9.81
        return
    with pytest.raises(ResultsError, match=r"run\.json: scenario\.gravity: must be a finite number >= 0"):
        results.load_run(run)


@pytest.mark.parametrize(("digits", "refused"), [(32, True), (63, True), (64, False), (65, True)])
def test_a_metrics_log_digest_is_64_hex_digits(tmp_path: Path, digits: int, refused: bool) -> None:
    """metrics.json's ``logs`` maps each log to its SHA-256, 64 hex digits (what ``legbench check`` compares to
    tell whether a log changed): a 32-digit digest (an MD5's length), 63 or 65 digits are refused, 64 read. A
    mutation audit found only a 3-letter digest tested (32 to 64 digits passed)."""
    d = tmp_path / "metrics.json"
    digest = (hashlib.sha256(b"a log").hexdigest() + "0")[:digits]
    doc = {"schema": results.METRICS_SCHEMA, "backends": {}, "logs": {"a.parquet": digest}, "metrics": []}
    results.write_metrics(doc, d)
    if not refused:
        assert results.read_metrics(d)[0]["logs"] == {"a.parquet": digest}
        return
    with pytest.raises(ResultsError) as exc:
        results.read_metrics(d)
    assert str(exc.value) == f"{d}: logs: must be an object of log file name -> SHA-256 (64 hex digits)"


def test_the_source_commit_names_the_checkout_and_its_uncommitted_changes(tmp_path: Path) -> None:
    """run.json's versions carry ``legbench_commit`` where legbench runs from a git checkout (a provenance review:
    its version said 0.1.0 over every commit): the checkout's HEAD, with " (uncommitted changes)" once a tracked
    file differs from it (an untracked one does not count); "" outside a checkout."""
    import subprocess

    assert results.source_commit(tmp_path) == ""

    def git(*args: str) -> str:
        return subprocess.run(["git", "-C", str(tmp_path), "-c", "user.name=t", "-c", "user.email=t@t", *args],
                              capture_output=True, text=True, check=True).stdout.strip()  # fmt: skip

    git("init", "-q")
    (tmp_path / "a.txt").write_text("one\n")
    git("add", "a.txt")
    git("commit", "-q", "-m", "one")
    head = git("rev-parse", "HEAD")
    assert len(head) == 40
    results.source_commit.cache_clear()
    (tmp_path / "untracked.txt").write_text("x\n")
    assert results.source_commit(tmp_path) == head
    results.source_commit.cache_clear()
    (tmp_path / "a.txt").write_text("two\n")
    assert results.source_commit(tmp_path) == f"{head} (uncommitted changes)"
    results.source_commit.cache_clear()
    recorded = results.versions()  # this checkout's, where the tests run from one
    checkout = Path(results.__file__).resolve().parent.parent
    if (checkout / ".git").exists():
        assert (
            recorded["legbench_commit"].split()[0]
            == subprocess.run(
                ["git", "-C", str(checkout), "rev-parse", "HEAD"], capture_output=True, text=True, check=True
            ).stdout.strip()
        )
    else:
        assert "legbench_commit" not in recorded
