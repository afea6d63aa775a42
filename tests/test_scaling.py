"""``legbench bench --parallel N``: the study's structure and the arithmetic of its figures, never a timing.

One small study (a 0.2 s task on pinocchio, two workers, one repeat, probes of 0.2 s CPU) runs once;
the tests check what it recorded and derived. Whether ``--jobs 2`` is fast is the benchmark's
business (docs/performance.md), not the suite's.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from legbench import backends, resources, scenario
from legbench.exceptions import LegbenchError
from legbench.studies import scaling

POSITION = resources.scenarios_dir() / "position.yaml"
pytestmark = pytest.mark.skipif("pinocchio" not in backends.available(), reason="needs pin")


@pytest.fixture(scope="module")
def study() -> scaling.ScalingResult:
    sc = scenario.shorten(scenario.load(POSITION), 0.2)
    return scaling.run_scaling([sc], ["pinocchio"], jobs=2, repeats=1, probe_cpu=0.2)


def test_every_sample_recorded(study: scaling.ScalingResult) -> None:
    """One repeat: one serial and one parallel batch wall time, one probe alone, two probes together."""
    assert study.jobs == 2
    assert study.runs == ["position/pinocchio"] and study.probe == "position/pinocchio"
    assert len(study.wall_serial) == len(study.wall_parallel) == 1
    assert len(study.probe_cpu_alone) == len(study.probe_wall_alone) == 1
    assert [len(t) for t in study.probe_cpu_together] == [2]
    values = [*study.wall_serial, *study.wall_parallel, *study.probe_cpu_alone, *study.probe_cpu_together[0]]
    assert all(math.isfinite(v) and v > 0 for v in values)
    # a process's CPU time never exceeds its wall time (one thread), up to the clocks' resolution
    for cpu, wall in zip(study.probe_cpu_together[0], study.probe_wall_together[0], strict=True):
        assert cpu <= wall + 1e-3


def test_figures_are_the_stated_ratios(study: scaling.ScalingResult) -> None:
    """speed-up = wall(1) / wall(N); ceiling = N cpu(alone) / mean cpu(together); efficiency = their ratio."""
    s = study.speedup().median
    c = study.ceiling_cpu().median
    assert s == pytest.approx(study.wall_serial[0] / study.wall_parallel[0], rel=1e-12)
    together = study.probe_cpu_together[0]
    assert c == pytest.approx(2 * study.probe_cpu_alone[0] / (sum(together) / 2), rel=1e-12)
    assert study.efficiency().median == pytest.approx(s / c, rel=1e-12)
    assert study.ceiling_wall().median == pytest.approx(
        2 * study.probe_wall_alone[0] / max(study.probe_wall_together[0]), rel=1e-12
    )


def test_written_tables(study: scaling.ScalingResult, tmp_path: Path) -> None:
    js, md = scaling.write_scaling(study, tmp_path, {"command": "legbench bench --parallel 2", "machine": {}})
    doc = json.loads(js.read_text())
    assert doc["figures"]["speedup"]["values"] == pytest.approx(study.speedup().values)
    text = md.read_text()
    for row in ("**speed-up**", "**ceiling**", "**efficiency**", "jobs 1 [s]", "jobs 2 [s]"):
        assert row in text


def test_bad_worker_count_refused() -> None:
    sc = scenario.load(POSITION)
    with pytest.raises(LegbenchError, match="--parallel must be at least 2"):
        scaling.run_scaling([sc], ["pinocchio"], jobs=1)
