"""The one validated reader of run directories (legbench.results): a hand-edited or corrupt run.json or
metrics.json is one line naming the file, the key and the problem, exit 2, and nothing is written."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

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
        assert str(exc.value) == f"{mine}: not empty and not a legbench run directory; choose another {option}"
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
