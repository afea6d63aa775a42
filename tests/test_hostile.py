"""The hostile user's suite (tests/hostile/suite.py, also runnable on its own) as a test: every one of its
bad inputs over every subcommand is handled cleanly (an expected exit status, no traceback, one line for bad
input), run in-process without the suite's own hang alarm."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

_SPEC = importlib.util.spec_from_file_location("hostile_suite", Path(__file__).parent / "hostile" / "suite.py")
assert _SPEC is not None and _SPEC.loader is not None
suite = importlib.util.module_from_spec(_SPEC)
_SPEC.loader.exec_module(suite)


def test_the_hostile_suite_builds_its_cases(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The suite's bad inputs are there to be run (152 built, over 100 held), each under its own id, so that a
    case lost, or two under one id, does not pass the test below unnoticed."""
    monkeypatch.chdir(tmp_path)
    with suite.fake_backend():
        cases = suite.build(tmp_path)
    assert len(cases) > 100, len(cases)
    ids = [cid for cid, _, _ in cases]
    assert len(set(ids)) == len(ids), sorted(i for i in set(ids) if ids.count(i) > 1)


def test_every_hostile_case_is_handled_cleanly(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    """Logged warnings (a log in ms, in degrees) reach stderr on the command line; under pytest the logging
    plugin takes them, so they are added back to what the case printed."""
    monkeypatch.chdir(tmp_path)
    bad = []
    with suite.fake_backend():
        cases = suite.build(tmp_path)
        for cid, argv, ok in cases:
            caplog.clear()
            status, err, _ = suite.run_case(argv, guard=False)
            err += "".join(f"{m}\n" for m in caplog.messages)
            if not suite.clean(cid, argv, ok, status, err):
                bad.append(f"{cid}: status {status}: {err.strip().splitlines()[-3:]}")
    assert "fake" not in suite.registry.available()  # the registry as it was, for the tests after this one
    assert not bad, "\n".join(bad)
