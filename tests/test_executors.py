"""Executors: a sweep gives the same table, bit for bit, on the local pool and on Dask, at any job count."""

from __future__ import annotations

import math
from pathlib import Path

import pandas as pd
import pytest

from legbench import backends
from legbench.exceptions import LegbenchError
from legbench.studies import executors, sweep, tasks

FREE_SPACE = Path(__file__).resolve().parents[1] / "scenarios" / "verification" / "free_space.yaml"
TIMING = ["wall_time", "rtf", "wall_per_sim_s"]  # measured, so they differ between runs


@pytest.fixture(scope="module")
def small_sweep(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Two backends x two steps against a Pinocchio reference, with short-horizon replays (exercises both phases)."""
    names = [n for n in ("pinocchio", "mujoco") if n in backends.available()]
    path = tmp_path_factory.mktemp("sweep") / "small.yaml"
    path.write_text(f"""
name: small
scenario: {FREE_SPACE}
set: {{duration: 0.1}}
signals: [q, qd, force, ee]
short_horizon: {{window: 0.02}}
studies:
  - backends: {names}
    set: {{backends.*.integrator: euler}}
    grid: {{backends.*.dt: [1.0e-3, 5.0e-4]}}
    reference: {{backend: pinocchio, set: {{backends.pinocchio.dt: 1.0e-4}}}}
""")
    return path


def _physics(result: sweep.SweepResult) -> pd.DataFrame:
    return result.table.drop(columns=TIMING)


@pytest.fixture(scope="module")
def serial(small_sweep: Path) -> sweep.SweepResult:
    return sweep.run_sweep(small_sweep, None, "local", jobs=1)


def test_local_pool_matches_serial_bit_for_bit(small_sweep: Path, serial: sweep.SweepResult) -> None:
    pooled = sweep.run_sweep(small_sweep, None, "local", jobs=2)
    pd.testing.assert_frame_equal(_physics(pooled), _physics(serial), check_exact=True)
    pd.testing.assert_frame_equal(pooled.windows, serial.windows, check_exact=True)
    assert len(serial.windows) and (serial.table["status"] == "ok").all()


def test_dask_local_cluster_matches_local_pool(small_sweep: Path, serial: sweep.SweepResult) -> None:
    pytest.importorskip("distributed")
    with executors.DaskExecutor(jobs=2, processes=False) as ex:
        result = sweep.run_sweep(small_sweep, None, ex)
        assert ex.describe()["executor"] == "dask"
    pd.testing.assert_frame_equal(_physics(result), _physics(serial), check_exact=True)
    pd.testing.assert_frame_equal(result.windows, serial.windows, check_exact=True)


def test_dask_scheduler_address_matches_local_pool(small_sweep: Path, serial: sweep.SweepResult) -> None:
    """The path a real cluster takes: connect to a scheduler by address (here one started in-process)."""
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=1, threads_per_worker=2, processes=False, dashboard_address=None) as c:
        result = sweep.run_sweep(small_sweep, None, "dask", scheduler=c.scheduler_address)
    pd.testing.assert_frame_equal(_physics(result), _physics(serial), check_exact=True)


def test_local_pool_returns_results_in_task_order() -> None:
    with executors.LocalExecutor(2) as ex:
        assert ex.map(math.sqrt, [16.0, 1.0, 9.0, 4.0]) == [4.0, 1.0, 3.0, 2.0]
    assert executors.LocalExecutor(1).map(math.sqrt, []) == []


def test_run_task_reports_a_missing_backend_instead_of_raising() -> None:
    res = tasks.run_task(tasks.RunTask(7, str(FREE_SPACE), {"duration": 0.1}, "nonexistent"))
    assert res.index == 7 and res.run.status == "missing" and "nonexistent" in (res.run.reason or "")


def test_executor_errors_are_clear() -> None:
    with pytest.raises(LegbenchError, match="unknown executor 'ray'; choose one of local, dask"):
        executors.make_executor("ray")
    with pytest.raises(LegbenchError, match="--scheduler needs --executor dask"):
        executors.make_executor("local", scheduler="tcp://x:8786")
    with pytest.raises(LegbenchError, match="jobs must be >= 1"):
        executors.LocalExecutor(-1)
