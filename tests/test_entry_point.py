"""A backend from another package, found through the ``legbench.backends`` entry point, gets full rows.

The plug-in is built here as an installed distribution would look on
``sys.path``: a ``*.dist-info`` directory (METADATA + entry_points.txt) and a
module whose class subclasses a built-in backend under a new name. Nothing in
legbench is edited or told about it; doctor, verify, calibrate-contact and
bench must treat it as any other backend, from what it declares.
"""

from __future__ import annotations

import math
import os
import subprocess
import sys
import textwrap
from collections.abc import Iterator
from pathlib import Path

import pytest

from legbench import backends
from legbench.backends import Physics
from legbench.exceptions import BackendNotFound
from legbench.studies import bench, calibrate_contact, doctor, verify

NAME = "rebadged"
EFFORT = Path(__file__).resolve().parents[1] / "scenarios" / "effort.yaml"

pytestmark = pytest.mark.skipif("pinocchio" not in backends.available(), reason="the plug-in subclasses pinocchio")


def _install(site: Path, dist: str, entry_points: str) -> None:
    """A distribution ``dist`` as pip leaves one on ``sys.path`` in ``site``: its METADATA, and its
    ``legbench.backends`` entry points (``entry_points``: lines ``name = module:Class``)."""
    info = site / f"{dist.replace('-', '_')}-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {dist}\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text(f"[legbench.backends]\n{entry_points}")


@pytest.fixture(scope="module")
def plugin(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    """Install the plug-in distribution on sys.path for this module's tests."""
    root = tmp_path_factory.mktemp("site")
    (root / "legbench_rebadged.py").write_text(
        textwrap.dedent(f'''\
        from legbench.backends.pinocchio_ import PinocchioBackend


        class RebadgedBackend(PinocchioBackend):
            """The Pinocchio backend under another name, as a third-party package would ship it."""

            name = "{NAME}"
            install = "pip install legbench-rebadged"


        class NeedsEngineBackend(PinocchioBackend):
            """A plug-in whose engine package is not installed: it imports it only when loading."""

            name = "needs-engine"
            install = "pip install imaginary-engine"

            def load(self, urdf, physics, settings):
                import imaginary_engine  # noqa: F401
        ''')
    )
    _install(root, "legbench-rebadged", f"{NAME} = legbench_rebadged:RebadgedBackend\n"
                                        "needs-engine = legbench_rebadged:NeedsEngineBackend\n")  # fmt: skip
    mp = pytest.MonkeyPatch()
    mp.syspath_prepend(str(root))
    yield NAME
    mp.undo()


def test_the_registry_finds_the_plugin_through_the_entry_point(plugin: str) -> None:
    assert plugin in backends.available()
    assert backends.get(plugin).__module__ == "legbench_rebadged"


def test_a_plugin_whose_engine_is_missing_says_what_to_install(plugin: str) -> None:
    """The registry's hint is the class's own ``install`` command."""
    with pytest.raises(BackendNotFound, match="pip install imaginary-engine"):
        backends.load("needs-engine", Physics(), {})


def test_doctor_reads_back_every_parity_row_of_the_plugin(plugin: str) -> None:
    """Every parity row (mass properties, joint and torque limits, gravity) read back and within 1e-6 of the spec."""
    t = doctor.table(EFFORT, [plugin])
    parity = t[t["status"] != "info"]
    assert len(parity) > 0 and (parity["status"] == "ok").all(), parity[parity["status"] != "ok"]
    assert parity[plugin].notna().all()
    rows = set(t["row"])
    assert {"engine.timestep", "engine.limit_enforcement"} <= rows


def test_verify_gives_the_plugin_every_case_and_it_passes(plugin: str) -> None:
    """Its declared integrator family and sub-steps give the same closed-form checks as the class it subclasses."""
    df = verify.verify(None, [plugin])
    assert set(df["case"]) == set(verify.CASES)
    assert (df["status"] == "pass").all(), df[df["status"] != "pass"][["case", "variant", "quantity", "note"]]
    offered = backends.get(plugin).choices.get("integrator", (None,))
    assert len(df[df["case"] == "energy"]) == len(offered)


def test_calibrate_contact_measures_the_plugin(plugin: str, tmp_path: Path) -> None:
    """k and c within 0.1 % of Kp and Kd (the same claim as for the built-in it subclasses)."""
    df = calibrate_contact.calibrate(tmp_path, [plugin])
    row = df.set_index("backend").loc[plugin]
    assert row.k_eff == pytest.approx(row.Kp, rel=1e-3)
    assert row.c_eff == pytest.approx(row.Kd, rel=1e-3)


def test_bench_times_the_plugin_with_its_kernel_floors(plugin: str) -> None:
    sc = bench.load_tasks([bench.TASKS[0]], duration=0.05)
    (res,) = bench.run_bench(sc, [plugin], repeats=1, warmup=0, memory=False)
    assert res.status == "ok" and res.replay_identical
    floors = [t for t in res.timings.values() if t.kind == "floor"]
    assert floors and all(math.isfinite(v) and v > 0 for t in floors for v in t.cpu_samples)
    assert res.floor in res.timings


def test_the_install_command_of_a_missing_built_in_engine_carries_pyproject_s_pin() -> None:
    """``legbench backends`` and a refused --backends name the pip requirement of a missing engine: each is the
    one pyproject.toml declares (its dependencies or extras), pin included (`pip install drake` gave no pin)."""
    import tomllib

    from legbench import backends

    doc = tomllib.loads((Path(__file__).resolve().parents[1] / "pyproject.toml").read_text())
    reqs = {*doc["project"]["dependencies"], *(r for extra in doc["project"]["optional-dependencies"].values()
                                              for r in extra)}  # fmt: skip
    for name, (_, _, package) in backends.BUILTIN.items():
        if package.startswith("apt-get "):
            assert package.endswith("pip install ode-python") and any(r.startswith("ode-python") for r in reqs)
            continue
        assert package.startswith("'") and package.endswith("'") and package.strip("'") in reqs, (name, package)


def test_a_run_records_the_version_of_every_installed_engine() -> None:
    """run.json's ``versions`` (and the bench's Machine line) hold each built-in engine's distribution with its
    installed version: the distribution named by its requirement (pin, dartpy, ode-python), as importlib.metadata
    gives it. The requirements took pyproject's pins on 27 Nov and the versions lost every engine ("'pin>=3.0'" is
    no distribution) until 28 Nov."""
    from importlib import metadata

    from legbench import backends, results

    assert backends.engine_packages() == ["pin", "mujoco", "pybullet", "drake", "dartpy", "sympy", "ode-python"]
    recorded = results.versions()
    for name in backends.available():
        if name in backends.BUILTIN:
            dist = backends.engine_packages()[list(backends.BUILTIN).index(name)]
            assert recorded[dist] == metadata.version(dist), name


def test_all_says_once_which_known_engines_are_not_installed(
    monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    """``--backends all`` left out the engines not installed here without a word (the README says "reported and
    skipped"): one note names each with its install command, once per process; 'all' beside names is refused."""
    from legbench import backends
    from legbench.exceptions import LegbenchError

    monkeypatch.setitem(backends.BUILTIN, "ghostengine", ("legbench.backends.ghostengine_", "G", "'ghostengine>=1'"))
    monkeypatch.setattr(backends, "_SAID_MISSING", set())
    with caplog.at_level("WARNING", logger="legbench.backends"):
        names = backends.resolve("all")
        assert backends.resolve("all") == names and "ghostengine" not in names
    (note,) = [r.getMessage() for r in caplog.records]
    assert note.startswith("legbench: note: --backends all: the backends that can run here; not available, so not run: "
                           "ghostengine (pip install 'ghostengine>=1' (No module named")  # fmt: skip
    with pytest.raises(LegbenchError, match=r"^--backends all,mujoco: 'all' stands alone"):
        backends.resolve("all,mujoco")


def test_a_missing_engine_s_multi_line_import_error_is_one_line(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """An engine whose ImportError spans lines (numpy's "C-extensions failed" text does): its reason, as
    ``legbench backends`` and the --backends all note give it, is one line."""
    from legbench import backends

    (tmp_path / "multiline_engine_.py").write_text("raise ImportError('C-extensions failed.\\n\\nIMPORTANT: read')\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setitem(backends.BUILTIN, "multiline", ("multiline_engine_", "M", "'multiline>=1'"))
    why = backends.unavailable()["multiline"]
    assert "\n" not in why and why.startswith("pip install 'multiline>=1' (C-extensions failed.")


def test_a_missing_engine_no_longer_registered_is_not_listed(monkeypatch: pytest.MonkeyPatch) -> None:
    """The registry records why an engine is missing; an engine no longer known (a built-in entry removed, a
    plug-in uninstalled) kept its record, and ``--backends all`` noted it: only known engines are listed."""
    from legbench import backends

    with monkeypatch.context() as mp:
        mp.setitem(backends.BUILTIN, "ghostengine", ("legbench.backends.ghostengine_", "G", "'ghostengine>=1'"))
        assert "ghostengine" in backends.unavailable()
    assert "ghostengine" in backends._MISSING and "ghostengine" not in backends.unavailable()


_INTERRUPTED_IMPORT = {
    # Ctrl-C reaching the import itself
    "direct": "raise KeyboardInterrupt\n",
    # as a pybind11 engine (MuJoCo) gives it back: ImportError("initialization failed") from the interrupt
    "wrapped": (
        "try:\n"
        "    raise KeyboardInterrupt\n"
        "except KeyboardInterrupt as exc:\n"
        "    raise ImportError('initialization failed') from exc\n"
    ),
}


@pytest.mark.parametrize("kind", ["built-in", "plug-in"])
@pytest.mark.parametrize("how", sorted(_INTERRUPTED_IMPORT))
def test_an_interrupt_while_an_engine_imports_is_an_interrupt(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, kind: str, how: str
) -> None:
    """Ctrl-C while MuJoCo was imported came back as ``--backends mujoco: not installed here ... (initialization
    failed)``, exit 2: an interrupt wrapped in an engine's ImportError is an interrupt (exit 130 from the cli), and
    the engine is not recorded as missing. Fails without the fix for the ``wrapped`` cases (BackendNotFound /
    UnknownBackend); the ``direct`` ones keep that a bare interrupt propagates."""
    module = f"legbench_sig_{how}_{kind.replace('-', '')}"
    name = f"sig-{how}-{kind}"
    (tmp_path / f"{module}.py").write_text(_INTERRUPTED_IMPORT[how])
    if kind == "built-in":
        monkeypatch.setitem(backends.BUILTIN, name, (module, "SigBackend", "'sig>=1'"))
    else:
        _install(tmp_path, module, f"{name} = {module}:SigBackend\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    with pytest.raises(KeyboardInterrupt):
        backends.get(name)
    with pytest.raises(KeyboardInterrupt):
        backends.resolve(f"pinocchio,{name}")
    assert name not in backends._MISSING


_NAMED_ONLY = """
import os
import sys
from legbench import backends

names = backends.resolve(sys.argv[1])
assert names == sys.argv[1].split(","), names
others = [m for n, (m, _, _) in backends.BUILTIN.items() if n not in names and m in sys.modules]
loud = "LEGBENCH_LOUD_IMPORTED" in os.environ  # set by its import, which then fails
print(f"imported: {others} loud: {loud}")
"""


def test_resolving_named_backends_imports_no_other_engine(tmp_path: Path) -> None:
    """``--backends pinocchio,<plug-in>`` imported every installed engine (Drake's ~1 s import, which swallows a
    Ctrl-C): a plug-in's name was looked up in the whole registry. Now each named backend is imported alone, and
    neither another built-in nor another plug-in (``loud``, whose import fails loudly) is. Fails without the fix:
    every other built-in's module is imported, and legbench_loud too."""
    (tmp_path / "legbench_quiet.py").write_text(
        "from legbench.backends.pinocchio_ import PinocchioBackend\n\n\nclass QuietBackend(PinocchioBackend):\n"
        "    name = 'quiet'\n"
    )
    (tmp_path / "legbench_loud.py").write_text(
        "import os\n\nos.environ['LEGBENCH_LOUD_IMPORTED'] = '1'\n"
        "raise RuntimeError('a plug-in nobody named was imported')\n"
    )
    _install(tmp_path, "legbench-quiet", "quiet = legbench_quiet:QuietBackend\nloud = legbench_loud:LoudBackend\n")
    root = Path(__file__).resolve().parents[1]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(tmp_path), str(root)])}
    out = subprocess.run([sys.executable, "-c", _NAMED_ONLY, "pinocchio,quiet"], env=env, capture_output=True,
                         text=True, timeout=120, check=False)  # fmt: skip
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "imported: [] loud: False"


def test_a_plugin_whose_engine_is_missing_fails_alone_in_a_run(
    plugin: str, tmp_path: Path, capsys: pytest.CaptureFixture[str], caplog: pytest.LogCaptureFixture
) -> None:
    """A review's plug-in importing its engine in load(), the engine not installed: `legbench run --backends all`
    (so `make compare`) stopped at the pre-flight, exit 2, nothing run, with "'needs-engine' is not available.
    Available backends: [..., 'needs-engine', ...]". The pre-flight now warns in one line, the others run and
    the plug-in's run is 'missing' with what to install; the message names the others, not itself."""
    from legbench import cli, results

    out = tmp_path / "run"
    short = ["--set", "duration=0.05", "--set", "comparison.steady_window=0.02"]
    code = cli.main(["run", str(EFFORT), "--backends", f"needs-engine,{plugin}", *short, "--out", str(out), "--quiet"])
    err = capsys.readouterr().err
    assert (out / "run.json").is_file(), (code, err)
    meta = results.read_meta(out)
    assert meta["backends"][plugin]["status"] == "ok"
    assert meta["backends"]["needs-engine"]["status"] == "missing", meta["backends"]["needs-engine"]
    reason = meta["backends"]["needs-engine"]["reason"]
    assert "pip install imaginary-engine" in reason and "its engine did not import when loading" in reason
    assert "needs-engine" not in reason.split("available here:")[1]
    assert "warning: backend 'needs-engine' is not available" in caplog.text and code == 3, (code, err)
    assert "did not finish ok (run/needs-engine)" in err


def test_an_entry_point_that_names_no_runnable_backend_is_unavailable_with_why(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """An entry point naming pathlib.Path crashed `legbench backends` with "AttributeError: type object 'Path' has
    no attribute 'profiles'", and a Backend subclass lacking abstract methods was listed as runnable (its run
    failed at load), and one without the engine-defaults profile ran alone and stopped `--backends all` runs of
    that profile: all are unavailable now, each with why, and `--backends` naming one is one line, exit 2."""
    from legbench import cli

    (tmp_path / "legbench_halfdone.py").write_text(
        "from legbench.backends.base import Backend\nfrom legbench.backends.pinocchio_ import PinocchioBackend\n\n\n"
        "class HalfBackend(Backend):\n    name = 'halfdone'\n\n\n"
        "class OnlyMatched(PinocchioBackend):\n    name = 'onlymatched'\n    profiles = {'matched': {}}\n\n\n"
        "class NoProfiles(PinocchioBackend):\n    name = 'noprofiles'\n    profiles = None\n"
    )
    _install(tmp_path, "legbench-halfdone", "notclass = pathlib:Path\nhalfdone = legbench_halfdone:HalfBackend\n"
                                            "onlymatched = legbench_halfdone:OnlyMatched\n"
                                            "noprofiles = legbench_halfdone:NoProfiles\n")  # fmt: skip
    monkeypatch.syspath_prepend(str(tmp_path))
    missing = backends.unavailable()
    assert missing["notclass"] == "entry point pathlib:Path names <class 'pathlib.Path'>, not a subclass of " \
                                  "legbench's Backend"  # fmt: skip
    half = "entry point legbench_halfdone:HalfBackend: HalfBackend does not implement ground_force, info, "
    assert missing["halfdone"].startswith(half + "integrator_family, limits, load, ")
    # a review: one lacking engine-defaults was listed and ran, then stopped every make compare (exit 2)
    assert missing["onlymatched"] == ("entry point legbench_halfdone:OnlyMatched: OnlyMatched.profiles has no "
                                      "'engine-defaults' (every backend offers matched and engine-defaults; it may "
                                      "add its own)")  # fmt: skip
    assert missing["noprofiles"] == ("entry point legbench_halfdone:NoProfiles: NoProfiles.profiles is NoneType, "
                                     "not a mapping of profile name to settings")  # fmt: skip
    assert not {"notclass", "halfdone", "onlymatched", "noprofiles"} & set(backends.available())
    assert cli.main(["backends"]) == 0
    assert cli.main(["run", str(EFFORT), "--backends", "notclass", "--out", str(tmp_path / "out")]) == 2
    assert not (tmp_path / "out").exists()


def test_the_schema_holds_the_plugins_settings(plugin: str) -> None:
    """`legbench schema` listed the built-ins alone under additionalProperties false, so an editor marked a
    scenario's `backends: {<plug-in>: ...}` invalid, though run and validate take it: the plug-in's settings are
    in it, as its class declares them."""
    from legbench import scenario

    props = scenario.json_schema()["properties"]["backends"]["properties"]
    mine = props[plugin]
    assert mine["additionalProperties"] is False and set(backends.get(plugin).defaults) <= set(mine["properties"])
    assert mine["properties"]["profile"]["enum"] == list(backends.get(plugin).profiles)
