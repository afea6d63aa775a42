"""Package data and the active leg model: --model PATH, LEGBENCH_MODEL, the URDF cache."""

from __future__ import annotations

import hashlib
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


def test_a_cached_urdf_cut_short_is_generated_again(other_model: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A cached URDF cut short (a full disk, a hand edit: half of its bytes, or the last one missing) no longer ends
    in </robot> and is generated again, whole (what model.urdf_text writes); before, every engine failed on it."""
    monkeypatch.setenv(resources.MODEL_ENV, str(other_model))
    urdf = resources.urdf_file()
    whole = urdf.read_bytes()
    assert whole.endswith(resources.URDF_END)
    for cut in (whole[: len(whole) // 2], whole[:-1], b""):
        urdf.write_bytes(cut)
        assert resources.urdf_file() == urdf and urdf.read_bytes() == whole
    assert whole.decode() == model.urdf_text(model.load_params(other_model))


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
    assert err == (f"legbench: error: {bad}: joints: missing (a leg parameter file has geometry, joints, materials, "
                   "links, calibration, collision, contact)")  # fmt: skip
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


# --------------------------------------------------------------------------- #
# The bundled leg.urdf's stamp: it is used only while it is the bundled leg.yaml's


@pytest.fixture
def tree(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[Path]:
    """A copy of the checkout's models/ (leg.yaml and the committed leg.urdf) in ``tmp_path/tree``, standing for the
    bundled model and the source tree (resources.models_dir, resources.source_tree), so the real files are never
    written; the cache in ``tmp_path/cache``; no other model selected; earlier warnings forgotten."""
    tree = tmp_path / "tree"
    models = tree / "models"
    models.mkdir(parents=True)
    for name in ("leg.yaml", "leg.urdf"):
        (models / name).write_bytes((resources.models_dir() / name).read_bytes())
    monkeypatch.setattr(resources, "models_dir", lambda: models)
    monkeypatch.setattr(resources, "source_tree", lambda: tree)
    monkeypatch.setattr(resources, "_warned", set(), raising=False)
    monkeypatch.setenv(resources.CACHE_ENV, str(tmp_path / "cache"))
    monkeypatch.delenv(resources.MODEL_ENV, raising=False)
    resources.select_model(None)
    yield tree
    resources.select_model(None)


def _digest(data: bytes) -> str:
    """The digest a cached URDF's name and a URDF's stamp carry: sha256(URDF_FORMAT + the file's bytes)[:16]."""
    return hashlib.sha256(resources.URDF_FORMAT + data).hexdigest()[:16]


def _masses(urdf_text: str) -> dict[str, float]:
    """Each link's <mass value> in a URDF's text."""
    found = re.findall(r'<link name="(\w+)">\s*<inertial>.*?<mass value="([^"]+)"/>', urdf_text, re.DOTALL)
    return {name: float(value) for name, value in found}


def _stale_warnings(caplog: pytest.LogCaptureFixture) -> list[str]:
    return [r.getMessage() for r in caplog.records if r.name == "legbench.resources" and r.levelname == "WARNING"]


def test_an_edited_bundled_leg_yaml_is_simulated_from_its_own_urdf(
    tree: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """models/leg.yaml edited (link 2's mass scale 1.48493010 -> 2.0) and models/leg.urdf not regenerated:
    urdf_file() returned the stale leg.urdf (engines simulated the old leg) and urdf_target() (run.json's "urdf")
    named it leg.urdf, as for the unedited leg. Now both are urdf/leg-<digest of the edited file>.urdf in the
    cache, generated from the edited file: link 2's mass is the committed one times 2.0 / 1.48493010, links 1
    and 3 unchanged. One warning line (however often it is asked) says leg.urdf is out of date and how to
    regenerate it; `legbench model urdf` without --out then rewrites models/leg.urdf (not the cache), which is
    used again, with the same text as the cached one."""
    leg, committed = tree / "models" / "leg.yaml", tree / "models" / "leg.urdf"
    edited, n = re.subn(r"link2: 1\.48493010\b", "link2: 2.0", leg.read_text())
    assert n == 1
    leg.write_text(edited)
    cached = resources.cache_dir() / "urdf" / f"leg-{_digest(edited.encode())}.urdf"

    assert resources.urdf_file() == cached
    assert resources.urdf_target() == cached and cached.name != "leg.urdf"
    old, new = _masses(committed.read_text()), _masses(cached.read_text())
    assert new["link2"] == pytest.approx(old["link2"] * 2.0 / 1.48493010, rel=1e-12)
    assert (new["link1"], new["link3"], new["foot"]) == (old["link1"], old["link3"], old["foot"])
    assert resources.urdf_file() == cached  # asked again: the same file, no second warning
    (warning,) = _stale_warnings(caplog)
    assert warning.startswith("legbench: warning: models/leg.urdf is out of date with models/leg.yaml")
    assert cached.name in warning and "`legbench model urdf` (make urdf) regenerates it" in warning
    assert "\n" not in warning

    assert cli.main(["model", "urdf"]) == 0
    assert resources.urdf_file() == committed and resources.urdf_target() == committed
    assert committed.read_text() == cached.read_text()
    assert _masses(committed.read_text())["link2"] == new["link2"]


def test_the_committed_leg_urdf_carries_the_stamp_of_leg_yaml_and_is_used_as_is(
    tree: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """The committed models/leg.urdf's header comment carries the stamp of the committed models/leg.yaml (the
    digest a cached URDF's name uses) and names the file models/leg.yaml; with neither edited, urdf_file() is that
    leg.urdf, urdf_target() models/leg.urdf (run.json: "leg.urdf"), nothing is generated, nothing is warned."""
    leg, committed = tree / "models" / "leg.yaml", tree / "models" / "leg.urdf"
    digest = _digest(leg.read_bytes())
    header = committed.read_text().splitlines()[1]
    assert header.startswith("<!-- ") and header.endswith(" -->")
    assert f"stamp sha256:{digest}," in header and " from models/leg.yaml. " in header
    assert resources.urdf_stamp(committed) == resources.param_digest(leg) == digest
    assert resources.urdf_file() == committed
    assert resources.urdf_target() == committed and resources.urdf_target().name == "leg.urdf"
    assert not resources.cache_dir().exists()
    assert _stale_warnings(caplog) == []


def test_a_leg_urdf_without_the_stamp_or_of_another_format_counts_as_out_of_date(
    tree: Path, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    """A models/leg.urdf from a legbench before the stamp (header '... from models/leg.yaml. Do not edit.', the
    numbers the same) cannot say what it was generated from, so it counts as out of date: urdf_file() is the
    cache's urdf/leg-<digest>.urdf, which is what model.urdf_text makes of leg.yaml, and one warning says so. A
    stamp made under another URDF_FORMAT (another generator) is out of date too."""
    leg, committed = tree / "models" / "leg.yaml", tree / "models" / "leg.urdf"
    stamped = committed.read_text()
    lines = stamped.splitlines(keepends=True)
    lines[1] = "<!-- Generated by `legbench model urdf` from models/leg.yaml. Do not edit. -->\n"
    committed.write_text("".join(lines))

    urdf = resources.urdf_file()
    assert urdf != committed and urdf == resources.cache_dir() / "urdf" / f"leg-{_digest(leg.read_bytes())}.urdf"
    assert urdf.read_text() == model.urdf_text(model.read_params(leg)) == stamped
    assert resources.urdf_stamp(committed) is None
    assert len(_stale_warnings(caplog)) == 1

    committed.write_text(stamped)
    assert resources.urdf_file() == committed
    monkeypatch.setattr(resources, "URDF_FORMAT", b"legbench-urdf-3\n")
    later = resources.urdf_file()
    assert later != committed and later.parent == urdf.parent and later.name == f"leg-{_digest(leg.read_bytes())}.urdf"
    assert "of legbench-urdf-3 and the file's bytes" in later.read_text()


def test_a_generated_urdf_names_its_parameter_file_without_a_machine_path(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The header comment said 'from models/leg.yaml' for every parameter file. It names the file as outputs do
    (resources.shown: relative to the working directory inside it), by its file name alone outside it (never
    this machine's path), with its own stamp; a '--' in the name (not allowed in an XML comment) is split, so
    the URDF still parses."""
    import xml.etree.ElementTree as ET

    monkeypatch.setenv(resources.CACHE_ENV, str(tmp_path / "cache"))
    monkeypatch.delenv(resources.MODEL_ENV, raising=False)
    source = resources.bundled_model().read_bytes()
    (tmp_path / "work" / "mine").mkdir(parents=True)
    inside, outside = tmp_path / "work" / "mine" / "heavy.yaml", tmp_path / "my--leg.yaml"
    for path in (inside, outside):
        path.write_bytes(source)
    monkeypatch.chdir(tmp_path / "work")
    digest = _digest(source)
    for path, name in ((inside, "mine/heavy.yaml"), (outside, "my- -leg.yaml")):
        text = resources.urdf_file(path).read_text()
        header = text.splitlines()[1]
        assert header.endswith(f" from {name}. Do not edit. -->") and f"stamp sha256:{digest}," in header
        assert str(tmp_path) not in text and "models/leg.yaml" not in text
        ET.fromstring(text.split("\n", 1)[1])  # well-formed XML after the declaration


# --------------------------------------------------------------------------- #
# Paths from environment variables: one line naming the variable and its value


def _no_such_user() -> str:
    """A ``~user`` no password entry has (pathlib cannot expand it)."""
    import pwd

    name = "legbench_no_such_user"
    with pytest.raises(KeyError):
        pwd.getpwnam(name)
    return f"~{name}"


def test_a_model_variable_whose_tilde_cannot_be_expanded_is_one_line(monkeypatch: pytest.MonkeyPatch) -> None:
    """LEGBENCH_MODEL=~nouser/x.yaml raised pathlib's 'RuntimeError: Could not determine home directory.' from
    model_file (a traceback); now a ModelError naming the variable, its value and why. A loop of links
    (RuntimeError on Python 3.11) likewise; select_model names the path it was given."""
    from legbench.exceptions import ModelError

    user = _no_such_user()
    monkeypatch.delenv(resources.MODEL_ENV, raising=False)
    resources.select_model(None)
    monkeypatch.setenv(resources.MODEL_ENV, f"{user}/x.yaml")
    with pytest.raises(ModelError) as exc:
        resources.model_file()
    assert str(exc.value) == f"LEGBENCH_MODEL={user}/x.yaml: cannot expand {user}: no such user"
    with pytest.raises(ModelError) as exc:
        resources.env_path(resources.MODEL_ENV)
    assert str(exc.value) == f"LEGBENCH_MODEL={user}/x.yaml: cannot expand {user}: no such user"
    with pytest.raises(ModelError) as exc:
        resources.select_model(f"{user}/y.yaml")
    assert str(exc.value) == f"{user}/y.yaml: cannot expand {user}: no such user"
    assert resources.MODEL_ENV in __import__("os").environ  # select_model changed nothing
    monkeypatch.delenv(resources.MODEL_ENV)
    assert resources.env_path(resources.MODEL_ENV) is None and resources.model_file() == resources.bundled_model()


def test_a_model_variable_naming_a_loop_of_links_is_one_line(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from legbench.exceptions import ModelError

    (tmp_path / "a").symlink_to(tmp_path / "b")
    (tmp_path / "b").symlink_to(tmp_path / "a")
    loop = tmp_path / "a" / "leg.yaml"
    resources.select_model(None)
    monkeypatch.setenv(resources.MODEL_ENV, str(loop))
    with pytest.raises(ModelError) as exc:
        resources.model_file()
    assert str(exc.value) == f"LEGBENCH_MODEL={loop}: a loop of symbolic links"


def test_the_cli_refuses_a_model_variable_whose_tilde_cannot_be_expanded(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """`LEGBENCH_MODEL=~nouser/x.yaml legbench validate ...` exited 1 with a traceback (cli._check_model_env's own
    expanduser); it is one line, exit 2."""
    user = _no_such_user()
    resources.select_model(None)
    monkeypatch.setenv(resources.MODEL_ENV, f"{user}/x.yaml")
    try:
        status = cli.main(["validate", str(resources.scenario("position"))])
    except RuntimeError:
        status = 1
    assert status == 2
    says = f"LEGBENCH_MODEL={user}/x.yaml: cannot expand {user}: no such user"
    assert capsys.readouterr().err == f"legbench: error: {says}\n"


def test_a_cache_variable_naming_a_file_is_one_line_naming_it(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """LEGBENCH_CACHE_DIR naming a regular file (or a path under one) failed as NotADirectoryError inside each
    engine's load; ~nouser as a RuntimeError. Now cache_dir(), and urdf_file() of a model whose URDF goes to the
    cache, raise one ModelError naming the variable, its value and the problem, before the model is read, and
    nothing is written."""
    from legbench.exceptions import ModelError

    leg = tmp_path / "leg2.yaml"
    leg.write_bytes(resources.bundled_model().read_bytes())
    file = tmp_path / "cachefile"
    file.write_text("")
    user = _no_such_user()
    cases = [
        (str(file), f"LEGBENCH_CACHE_DIR={file}: not a directory"),
        (f"{file}/sub", f"LEGBENCH_CACHE_DIR={file}/sub: cannot be created: {file} is not a directory"),
        (f"{user}/c", f"LEGBENCH_CACHE_DIR={user}/c: cannot expand {user}: no such user"),
    ]
    for value, says in cases:
        monkeypatch.setenv(resources.CACHE_ENV, value)
        for call in (resources.cache_dir, lambda: resources.urdf_file(leg), lambda: resources.cache_subdir("urdf")):
            with pytest.raises(ModelError) as exc:
                call()
            assert str(exc.value) == says
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cachefile", "leg2.yaml"] and file.read_text() == ""


def test_the_xdg_and_home_defaults_of_the_cache_are_one_line_too(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Without LEGBENCH_CACHE_DIR: XDG_CACHE_HOME naming a file, or ~nouser, and no home directory at all (HOME
    unset and no password entry: pathlib's RuntimeError) are one line naming where the cache came from."""
    import os

    from legbench.exceptions import ModelError

    monkeypatch.delenv(resources.CACHE_ENV, raising=False)
    file = tmp_path / "xdgfile"
    file.write_text("")
    user = _no_such_user()
    for value, says in [
        (
            str(file),
            f"cache directory {file}/legbench (from XDG_CACHE_HOME={file}): cannot be created: {file} is "
            "not a directory",
        ),  # fmt: skip
        (user, f"XDG_CACHE_HOME={user}: cannot expand {user}: no such user"),
    ]:
        monkeypatch.setenv("XDG_CACHE_HOME", value)
        with pytest.raises(ModelError) as exc:
            resources.cache_dir()
        assert str(exc.value) == says
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert resources.cache_dir() == tmp_path / "xdg" / "legbench" and not (tmp_path / "xdg").exists()
    monkeypatch.delenv("XDG_CACHE_HOME")
    monkeypatch.setattr(os.path, "expanduser", lambda p: p)  # as with HOME unset and no password entry
    with pytest.raises(ModelError) as exc:
        resources.cache_dir()
    assert str(exc.value) == ("cache directory ~/.cache/legbench (LEGBENCH_CACHE_DIR chooses another): cannot "
                              "expand ~: no home directory (HOME is not set)")  # fmt: skip


def test_a_cache_that_cannot_be_created_or_written_is_one_line_and_leaves_nothing(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A cache directory that passes the look (its parent a directory) but cannot be made (/proc/legbench: the
    kernel refuses), whose urdf/ is a file, or in which no file can be made (a read-only file system) is one line
    naming the variable, where the directory is made; a write that fails part-way leaves no temporary."""
    import errno
    import os
    import tempfile

    from legbench.exceptions import ModelError

    leg = tmp_path / "leg2.yaml"
    leg.write_bytes(resources.bundled_model().read_bytes())
    if Path("/proc/self").is_dir():
        monkeypatch.setenv(resources.CACHE_ENV, "/proc/legbench")
        assert resources.cache_dir() == Path("/proc/legbench")  # nothing is made by looking
        with pytest.raises(ModelError) as exc:
            resources.urdf_file(leg)
        assert str(exc.value) == "LEGBENCH_CACHE_DIR=/proc/legbench: cannot be created: No such file or directory"
    cache = tmp_path / "cache"
    cache.mkdir()
    (cache / "urdf").write_text("")
    monkeypatch.setenv(resources.CACHE_ENV, str(cache))
    with pytest.raises(ModelError) as exc:
        resources.urdf_file(leg)
    assert str(exc.value) == f"LEGBENCH_CACHE_DIR={cache}: {cache}/urdf: not a directory"
    (cache / "urdf").unlink()

    def read_only(*args: object, **kwargs: object) -> tuple[int, str]:
        raise OSError(errno.EROFS, os.strerror(errno.EROFS))

    with monkeypatch.context() as m:
        m.setattr(tempfile, "mkstemp", read_only)
        with pytest.raises(ModelError) as exc:
            resources.urdf_file(leg)
    assert str(exc.value) == f"LEGBENCH_CACHE_DIR={cache}: cannot write in it: Read-only file system"

    def full(src: object, dst: object) -> None:
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    with monkeypatch.context() as m:
        m.setattr(os, "replace", full)
        with pytest.raises(OSError, match="No space left on device"):
            resources.urdf_file(leg)
    assert list((cache / "urdf").iterdir()) == []
    assert resources.urdf_file(leg).parent == cache / "urdf"


def test_run_refuses_a_bad_cache_directory_before_any_engine(
    other_model: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """`LEGBENCH_CACHE_DIR=<a file> legbench --model leg2.yaml run ...` blamed one engine ('parity check: pinocchio
    failed to load: NotADirectoryError'), with --no-preflight failed every backend and wrote a run.json of
    failures. The cache is every backend's: one line, exit 2, no output directory (the CLI resolves the URDF
    before any engine loads)."""
    file = tmp_path / "cachefile"
    file.write_text("")
    for value, says in [(str(file), "not a directory"),
                        ("/proc/legbench", "cannot be created: No such file or directory")]:  # fmt: skip
        if value.startswith("/proc") and not Path("/proc/self").is_dir():
            continue
        monkeypatch.setenv(resources.CACHE_ENV, value)
        for extra in ([], ["--no-preflight"]):
            out = tmp_path / "r"
            argv = ["--model", str(other_model), "run", str(resources.scenario("position")), "--backends",
                    "pinocchio", "--set", "duration=0.6", "--out", str(out), "--no-compare", *extra]  # fmt: skip
            assert cli.main(argv) == 2
            assert capsys.readouterr().err == f"legbench: error: LEGBENCH_CACHE_DIR={value}: {says}\n"
            assert not out.exists()


def test_the_urdf_s_name_needs_no_cache_directory(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """What run.json records and a report compares is the URDF's file name: installed (no source tree), the
    bundled leg's target lies in the cache, and a cache that could not be used stopped a run of the bundled leg
    after it had run (exit 2, nothing written), and every comparison. The name is found without it."""
    from legbench.exceptions import ModelError

    file = tmp_path / "cachefile"
    file.write_text("")
    monkeypatch.setenv(resources.CACHE_ENV, str(file))
    monkeypatch.setattr(resources, "source_tree", lambda: None)
    with pytest.raises(ModelError, match="not a directory"):
        resources.urdf_target()
    assert resources.urdf_name() == "leg.urdf"
