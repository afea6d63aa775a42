"""legbench check on real engine runs: passes against itself, fails naming the signal when one
backend's setting is perturbed."""

from __future__ import annotations

from pathlib import Path

import pytest

from legbench import backends, check, report, run, scenario

SCENARIOS = Path(__file__).resolve().parent.parent / "scenarios"
pytestmark = pytest.mark.skipif("mujoco" not in backends.available(), reason="mujoco not installed")


def _run(out: Path, overrides: dict[str, object]) -> Path:
    sc = scenario.load(SCENARIOS / "effort.yaml", {"duration": 1.0, **overrides})
    run.run(sc, ["pinocchio", "mujoco"], out, progress=False)
    report.write_report(out)
    return out


def test_check_passes_on_itself_and_fails_on_a_perturbed_engine_setting(tmp_path: Path) -> None:
    base = _run(tmp_path / "base" / "effort", {})
    same = _run(tmp_path / "same" / "effort", {})
    ok = check.check(same.parent, base.parent)
    assert ok.passed
    assert {t.status for t in ok.traces} == {"identical"}  # bit-identical reruns
    bad = _run(tmp_path / "bad" / "effort", {"backends.mujoco.dt": 2e-4})  # 4x the default sub-step
    res = check.check(bad.parent, base.parent)
    assert not res.passed
    assert all(r.backend == "mujoco" for r in res.regressions)
    assert any(r.signal in ("q", "qd", "force", "tau") for r in res.regressions)
    assert "mujoco" in res.regressions[0].message
