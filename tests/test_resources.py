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
