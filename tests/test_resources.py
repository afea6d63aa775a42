"""Package data and the active leg model: --model PATH, LEGBENCH_MODEL, the URDF cache."""

from __future__ import annotations

import re
from collections.abc import Iterator
from pathlib import Path

import pytest

from legbench import cli, model, resources


@pytest.fixture
def other_model(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[Path]:
    """The bundled parameter file with gravity 9.0 instead of 9.81 m/s^2; the cache in tmp; selection undone after."""
    monkeypatch.setenv(resources.CACHE_ENV, str(tmp_path / "cache"))
    monkeypatch.delenv(resources.MODEL_ENV, raising=False)
    text = resources.bundled_model().read_text()
    new, n = re.subn(r"(\n\s*gravity:\s*)9\.81", r"\g<1>9.0", text)
    assert n == 1
    path = tmp_path / "heavy_leg.yaml"
    path.write_text(new)
    yield path
    resources.select_model(None)


def _g(out: str) -> list[float]:
    m = re.search(r"G\(q\*\)\s*=\s*\[([^\]]*)\]", out)
    assert m, out
    return [float(x) for x in m.group(1).split(",")]


def test_bundled_data_is_found() -> None:
    assert resources.bundled_model().is_file() and resources.bundled_urdf().is_file()
    assert (resources.scenarios_dir() / "verification" / "energy.yaml").is_file()
    assert resources.scenario("sweeps/gains") == resources.scenarios_dir() / "sweeps" / "gains.yaml"


def test_model_option_selects_another_parameter_file(other_model: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """G(q*) scales with gravity: with the 9.0 m/s^2 file every component is 9.0 / 9.81 of the bundled one (to the
    printed 4 decimals: 5e-5 N m)."""
    assert cli.main(["model", "check"]) == 0
    g_bundled = _g(capsys.readouterr().out)
    # exit 1: `model check` fails a leg whose G(q*) is not the report's, as this one's is not
    assert cli.main(["--model", str(other_model), "model", "check"]) == 1
    g_other = _g(capsys.readouterr().out)
    for a, b in zip(g_bundled, g_other, strict=True):
        assert b == pytest.approx(a * 9.0 / 9.81, abs=5e-5)
    assert resources.model_file() == other_model.resolve()


def test_environment_variable_and_urdf_in_the_cache(other_model: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """LEGBENCH_MODEL selects the file; its URDF is generated into the cache (named by the file's hash), not next to
    the bundled model, and equals what model.urdf_text makes of it; the bundled model keeps its shipped URDF."""
    monkeypatch.setenv(resources.MODEL_ENV, str(other_model))
    urdf = resources.urdf_file()
    assert urdf.parent == Path(resources.cache_dir()) / "urdf" and urdf.name.startswith("heavy_leg-")
    assert urdf.read_text() == model.urdf_text(model.load_params(other_model))
    assert model.load_params().gravity == 9.0
    monkeypatch.delenv(resources.MODEL_ENV)
    assert resources.urdf_file() == resources.bundled_urdf()
    assert model.load_params().gravity == 9.81


def test_a_urdf_cached_by_another_generator_version_is_not_reused(
    other_model: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The cached URDF's name hashes the generator's URDF_FORMAT with the parameter file: a URDF an earlier
    legbench wrote for the same file (its numbers to 12 digits) sits under another name and is not read; the
    one used is what model.urdf_text writes now (numbers exact: pi/2 as 1.5707963267948966)."""
    monkeypatch.setenv(resources.MODEL_ENV, str(other_model))
    now = resources.urdf_target()
    monkeypatch.setattr(resources, "URDF_FORMAT", b"legbench-urdf-1\n")
    earlier = resources.urdf_target()
    assert earlier != now and earlier.parent == now.parent
    earlier.parent.mkdir(parents=True, exist_ok=True)
    earlier.write_text("<robot name='stale'/>")
    monkeypatch.undo()
    monkeypatch.setenv(resources.CACHE_ENV, str(earlier.parent.parent))
    monkeypatch.setenv(resources.MODEL_ENV, str(other_model))
    urdf = resources.urdf_file()
    assert urdf == now and "1.5707963267948966" in urdf.read_text()


def test_bad_model_file_is_one_line_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text("geometry: {H: 1}\n")
    assert cli.main(["--model", str(bad), "model", "check"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"legbench: error: {bad}: missing or malformed entry") and "\n" not in err
    assert cli.main(["--model", str(tmp_path / "none.yaml"), "model", "check"]) == 2
    assert "no such parameter file" in capsys.readouterr().err
    assert resources.MODEL_ENV not in __import__("os").environ


def test_outputs_name_files_without_this_machines_paths(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """resources.shown: a file under the working directory by its relative path, a bundled file as
    legbench/data/... from anywhere else (the bundled effort task: scenarios/effort.yaml from the checkout),
    anything else as given; run.json's scenario file goes through it."""
    from legbench import scenario

    effort = resources.scenario("effort")
    monkeypatch.chdir(tmp_path)
    assert resources.shown(effort) == "legbench/data/scenarios/effort.yaml"
    (tmp_path / "mine").mkdir()
    mine = tmp_path / "mine" / "task.yaml"
    mine.write_text(effort.read_text())
    assert resources.shown(mine) == "mine/task.yaml"
    assert resources.shown("/elsewhere/x.yaml") == "/elsewhere/x.yaml"
    assert scenario.load(mine).to_dict()["file"] == "mine/task.yaml"
    assert scenario.load(effort).to_dict()["file"] == "legbench/data/scenarios/effort.yaml"
    monkeypatch.chdir(resources.source_tree() or tmp_path)
    if resources.source_tree() is not None:  # a checkout: the bundled scenarios are links to scenarios/
        assert resources.shown(effort) == "scenarios/effort.yaml"


def test_the_cached_urdf_name_hashes_the_whole_parameter_file_as_before(tmp_path: Path) -> None:
    """A regular parameter file's URDF is named by sha256(URDF_FORMAT + the file's bytes), as it always was (the
    cache's names depend on it); a missing file's is '<stem>-missing.urdf'."""
    import hashlib

    leg = tmp_path / "my_leg.yaml"
    leg.write_bytes(resources.bundled_model().read_bytes())
    digest = hashlib.sha256(resources.URDF_FORMAT + leg.read_bytes()).hexdigest()[:16]
    assert resources.urdf_target(leg).name == f"my_leg-{digest}.urdf"
    assert resources.urdf_target(tmp_path / "gone.yaml").name == "gone-missing.urdf"


def test_urdf_target_refuses_what_is_not_a_regular_file_unread(tmp_path: Path) -> None:
    """urdf_target read the whole parameter file to hash it, whatever it was: a device (/dev/zero: no end) was
    read until the process was killed. Anything but a regular file is a one-line ModelError naming it and what it
    is, before a byte is read (/dev/null, which ends, shows it without the hang)."""
    from legbench.exceptions import ModelError

    cases = [(tmp_path, "is a directory, not a leg parameter file")]  # the YAML reader's words (one reader)
    if Path("/dev/null").exists():
        cases.append((Path("/dev/null"), "is a character device, not a regular file (a leg parameter file is read "
                                         "only from one)"))  # fmt: skip
    for path, says in cases:
        with pytest.raises(ModelError) as exc:
            resources.urdf_target(path)
        assert str(exc.value) == f"{path}: {says}"


def test_urdf_target_reads_no_more_than_the_file_size_limit(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A parameter file larger than the YAML reader's limit (``file_bytes``, which LEGBENCH_LIMITS sets) is refused
    in one line before it is hashed, as reading it would be; one at the limit is hashed as before."""
    from legbench.exceptions import ModelError

    leg = tmp_path / "leg_copy.yaml"
    leg.write_bytes(resources.bundled_model().read_bytes())
    size = leg.stat().st_size
    monkeypatch.setenv("LEGBENCH_LIMITS", f"file_bytes={size - 1}")
    with pytest.raises(ModelError, match=rf"^{re.escape(str(leg))}: {size} bytes is more than {size - 1} \(limit"):
        resources.urdf_target(leg)
    monkeypatch.setenv("LEGBENCH_LIMITS", f"file_bytes={size}")
    assert resources.urdf_target(leg).name.startswith("leg_copy-") and "missing" not in resources.urdf_target(leg).name


@pytest.mark.skipif(not hasattr(__import__("os"), "mkfifo"), reason="no FIFOs here")
def test_the_library_refuses_a_model_variable_naming_a_fifo_on_import(tmp_path: Path) -> None:
    """``import legbench.results`` (the Python API's path, not the CLI's, which checks LEGBENCH_MODEL first) hashed
    the active model's file for its URDF name: a FIFO there blocked the import for ever (no writer comes). The
    import now reads no model, and naming the URDF (what a run's run.json records) is a ModelError at once, in a
    fresh process (the timeout only bounds a regression)."""
    import os
    import subprocess
    import sys

    fifo = tmp_path / "leg.yaml"
    os.mkfifo(fifo)
    env = {**os.environ, resources.MODEL_ENV: str(fifo), resources.CACHE_ENV: str(tmp_path / "cache")}
    code = "import legbench.results; print('imported', flush=True); legbench.resources.urdf_target()"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120)
    assert done.returncode == 1 and done.stdout == "imported\n"
    last = done.stderr.strip().splitlines()[-1]
    assert last == f"legbench.exceptions.ModelError: {fifo}: is a FIFO, not a regular file (a leg parameter file " \
                   "is read only from one)"  # fmt: skip
    assert not (tmp_path / "cache").exists()
