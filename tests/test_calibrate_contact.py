"""Contact calibration: measured stiffness, damping and creep against the spec and each engine's known mapping."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest

from legbench import backends
from legbench.studies import calibrate_contact


@pytest.fixture(scope="module")
def table(tmp_path_factory: pytest.TempPathFactory) -> pd.DataFrame:
    return calibrate_contact.calibrate(tmp_path_factory.mktemp("cal"), backends.available())


def test_normal_stiffness_and_damping_match_the_spec(table: pd.DataFrame) -> None:
    """k and c within 0.1 % of Kp = 1e4 N/m and Kd = 100 N s/m on every compliant backend.

    Each backend claims an exact mapping (Pinocchio: the law itself; MuJoCo: direct
    solref with the impedance pinned; Bullet: contactStiffness/Damping with zero slop;
    Drake: SAP's stiffness and relaxation time Kd / Kp); the estimates use the 1 kHz log
    (k from two rests, c from the transient's pressing-in samples), whose own error is
    below 1e-4 for Pinocchio. A backend whose contact is rigid (declares no Kp, e.g.
    DART's LCP) must be at least 1e3 times stiffer than Kp (measured ~8e10 N/m).
    """
    for r in table.itertuples():
        if not r.compliant:
            assert r.k_eff > 1e3 * r.Kp, r.backend
            continue
        assert r.k_eff == pytest.approx(r.Kp, rel=1e-3), r.backend
        assert r.c_eff == pytest.approx(r.Kd, rel=1e-3), r.backend
        assert r.Ft < r.mu_s * r.Fn, "the tangential load stays below the friction limit"


def test_creep_under_a_tangential_load_below_the_limit(table: pd.DataFrame) -> None:
    """The stick-slip law creeps at v_th Ft / (mu_s Fn) (0.1 %: steady creep, 1 kHz log); the Coulomb
    cones hold the foot: Bullet's, and MuJoCo's in the matched profile (noslip with deadbeat friction
    rows; its regularised cone of the engine defaults crept at about Ft / Kd), both < 1e-5 m/s, 1/10
    of the law's creep at v_th = 1e-3 m/s."""
    rows = table.set_index("backend")
    p = rows.loc["pinocchio"]
    assert p.creep == pytest.approx(p.creep_law, rel=1e-3)
    for engine in ("mujoco", "pybullet"):
        if engine in rows.index:
            assert rows.loc[engine].creep < 0.1 * p.creep_law, engine


def test_files_written(table: pd.DataFrame, tmp_path: Path) -> None:
    calibrate_contact.write_calibration(table, tmp_path)
    md = (tmp_path / "calibration.md").read_text()
    assert "k eff [N/m]" in md and all(n in md for n in table["backend"])
    assert (tmp_path / "calibration.json").stat().st_size > 0
