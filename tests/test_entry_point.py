"""A backend from another package, found through the ``legbench.backends`` entry point, gets full rows.

The plug-in is built here as an installed distribution would look on
``sys.path``: a ``*.dist-info`` directory (METADATA + entry_points.txt) and a
module whose class subclasses a built-in backend under a new name. Nothing in
legbench is edited or told about it; doctor, verify, calibrate-contact and
bench must treat it as any other backend, from what it declares.
"""

from __future__ import annotations

import math
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
    dist = root / "legbench_rebadged-0.1.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: legbench-rebadged\nVersion: 0.1\n")
    (dist / "entry_points.txt").write_text(f"[legbench.backends]\n{NAME} = legbench_rebadged:RebadgedBackend\n"
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
