"""Verification cases: every backend meets each closed-form answer within the tolerance verify.py states.

The tolerances are derived in legbench/verify.py (module docstring), one per
case, from the physics or numerics that may legitimately separate the
simulation from the closed form; the tests restate them here beside the
assertion.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import json
import math
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest
from fakes import FakeBackend, install_crashing_engine

from legbench import backends, kinematics, model
from legbench import scenario as scenario_mod
from legbench.backends.base import Physics, explained_note
from legbench.backends.pinocchio_ import PinocchioBackend
from legbench.exceptions import LegbenchError
from legbench.results import RunResult
from legbench.studies import verify
from legbench.studies.sliding_case import applies_law

#: A run the verification simulated: its scenario, backend, physics and the run.
SimulatedRun = tuple[Any, str, Physics, RunResult]


@pytest.fixture(scope="module")
def verify_runs() -> list[SimulatedRun]:
    """Every run the ``results`` fixture's verify simulated (energy, rest and small-oscillation scenarios), in
    order: for the tests that recompute a row's tolerance from its run."""
    return []


@pytest.fixture(scope="module")
def results(tmp_path_factory: pytest.TempPathFactory, verify_runs: list[SimulatedRun]) -> tuple[pd.DataFrame, Path]:
    out = tmp_path_factory.mktemp("verification")
    with _recording(verify_runs):  # verify runs in this process (jobs = 1)
        return verify.verify(out), out


@contextlib.contextmanager
def _recording(runs: list[SimulatedRun]) -> Iterator[None]:
    """verify's runs appended to ``runs`` as it simulates them, in order (its ``_simulate`` wrapped meanwhile)."""
    simulate = verify._simulate

    def keep(scenario: Any, name: str, physics: Physics, settings: Mapping[str, Any], profile: str) -> RunResult:
        tr = simulate(scenario, name, physics, settings, profile)
        runs.append((scenario, name, physics, tr))
        return tr

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(verify, "_simulate", keep)
        yield


@pytest.fixture(scope="module")
def engine_defaults_rest() -> tuple[pd.DataFrame, list[SimulatedRun]]:
    """The rest cases (rest_penetration, static_balance) of every available backend in the engine-defaults profile,
    and the runs they simulated (one per backend, in order)."""
    runs: list[SimulatedRun] = []
    with _recording(runs):
        df = verify.verify(None, None, ["rest_penetration", "static_balance"], profile="engine-defaults")
    return df, runs


def _failures(df: pd.DataFrame) -> str:
    bad = df[~df["pass"].astype(bool)]
    return "\n".join(
        f"{r.case} {r.backend} {r.variant} {r.quantity}: measured {r.measured:.6g}, expected {r.expected:.6g}, "
        f"error {r.error:.3g} > tolerance {r.tolerance:.3g} ({r.note})"
        for r in bad.itertuples()
    )


#: Verified quantities a backend is known to miss, each investigated and reported, not hidden: the test
#: asserts they still fail (so a fix is noticed) and that everything else passes.
#: Drake (SAP, matched): the sliding foot leaves the ground at 0.372 s (slip 0.245 m/s, where mu_s Kd v is
#: about Fn: SAP's convex approximation). Scored only where the central difference's three samples are in contact,
#: the window's mean slip acceleration is 4.116 m/s^2 against the closed form's 3.710 (5 of 51 samples out of
#: contact): the lift-off falls between the sub-steps of the period ending 0.372 s, which a 1 kHz log cannot show;
#: up to 0.370 s it agrees to 0.13 % (docs/backends/drake.md). No closed form of that is built: a plain miss
#: (UNEXPLAINED), no "known: " note.
#: ODE (dWorldStep): the Dantzig LCP bounds each friction row by mu times the normal impulse solved before any
#: friction row, not the final one: the drag axis holds 0.7068 Fn (the slip accelerates 11 % less than the
#: pyramid's closed form); with ODE's quick stepper it meets the closed form (test_the_pyramid_closed_form_below).
#: DART's Dantzig solver misses the same way (0.83 Fn, the foot does not slide: its engine-defaults); its matched
#: profile's NSGS solver slides at 0.700 Fn on a cone and passes. Both Dantzig misses are explained by the pyramid's
#: closed form at the bound re-solved without friction (Backend.frictionless_normal).
KNOWN_DISCREPANCIES = {
    ("sliding", "drake", "slip acceleration along the slip (mean)"),
    ("sliding", "ode", "slip acceleration along the drag (mean; pyramid)"),
}
#: The known misses no backend explains (no closed form held to the row's measured value).
UNEXPLAINED = {("sliding", "drake", "slip acceleration along the slip (mean)")}


@pytest.mark.parametrize("case", verify.CASES)
def test_case_passes_on_every_backend(results: tuple[pd.DataFrame, Path], case: str) -> None:
    """energy: first-order integrators follow the predicted drift h int e2 dt within max|pred| (h W + (Ts W)^2)
    (the O(h^2) remainder and the trapezoid sum), RK4 its predicted drift h^4 int e5 + h^5 (...) at the declared step
    and at the check's own 0.5 ms, adaptive within
    (max_step W)^5 W T max T + round-off; rest_penetration: mean y = mean Fn/Kp within
    0.1 % plus the damping force's mean over Kp; static_balance: every tick within its own tolerance, the dynamic
    terms left and the held torque's step, plus
    for an engine's own contact 1e-5 |F| at the point it declares (the application point's lever y |F_t| where
    it declares none), for a law backend
    round-off and its solver's tolerance; small_oscillation: each closed-loop pole within 0.5 % of the
    sampled, integrator-aware linear model."""
    df, _ = results
    rows = df[df["case"] == case]
    assert set(rows["backend"]) == set(backends.available())
    expected = {k for k in KNOWN_DISCREPANCIES if k[0] == case and k[1] in backends.available()}
    assert expected <= set(zip(rows["case"], rows["backend"], rows["quantity"], strict=True)), "a known row is gone"
    known = rows.apply(lambda r: (r["case"], r["backend"], r["quantity"]) in KNOWN_DISCREPANCIES, axis=1)
    assert not rows[known]["pass"].any(), "a known discrepancy now passes: remove it from KNOWN_DISCREPANCIES"
    # the backend explains exactly its known misses beside the row (Backend.known_deviation), and nothing else
    plain = rows.apply(lambda r: (r["case"], r["backend"], r["quantity"]) in UNEXPLAINED, axis=1)
    assert rows[known & ~plain]["note"].str.startswith("known: ").all()
    assert not rows[~known | plain]["note"].str.contains("known: ", regex=False).any()
    rows = rows[~known]
    assert rows["pass"].all(), _failures(rows)
    assert np.isfinite(rows["measured"]).all()


def test_every_error_is_in_the_rows_unit_and_decides_the_pass(results: tuple[pd.DataFrame, Path]) -> None:
    """A row passes exactly when its error is within its tolerance, both in the row's unit. The sliding rows'
    error is |measured - expected| (for a bound, its excess max(measured - expected, 0)) to round-off (1e-12
    relative), where they gave |measured / expected - 1| beside a unit of m/s^2; the energy rows' error is the
    largest gap between the energy curve and its prediction over the run, not only at the end."""
    df, _ = results
    rows = df[df["status"] != "not-applicable"]
    assert (rows["pass"] == (rows["error"] <= rows["tolerance"])).all()
    sliding = rows[rows["case"] == "sliding"]
    gap = sliding["measured"] - sliding["expected"]
    want = gap.where(sliding["quantity"].str.contains("bound"), gap.abs()).clip(lower=0.0)
    assert len(sliding) == 3 * len(set(sliding["backend"]))
    np.testing.assert_allclose(sliding["error"], want, rtol=1e-12, atol=1e-300)


def test_tolerances_are_the_stated_ones_not_the_codes_choice(
    results: tuple[pd.DataFrame, Path], engine_defaults_rest: tuple[pd.DataFrame, list[SimulatedRun]]
) -> None:
    """The pass/fail tolerances come from the code under test, so they are bounded here from the physics:
    rest penetration within 10 um of a 5.25 mm sink (0.1 % of it plus the damping of a foot at rest: measured
    5.3 um; a rigid contact's 0.1 % of its own sink, DART 6.1e-13 m), static balance within 1 N of a 52 N push
    (measured <= 0.54 N for a backend that does not declare where its contact acts: the dynamic terms left and the
    application point's lever), within 1e-3 N for an engine that declares its point (every built-in, matched:
    5.3e-4 N, 1e-5 |F| and the dynamic terms; 0.053 N at the former 0.1 % |F|), within 0.1 N for a backend
    applying the law itself (no lever:
    Pinocchio 2e-4 N, the held torque's step; Lagrange 0.062 N, its atol 1e-6 times the friction's slope), each
    adaptive energy row within 1e-10 J (8.2e-13 J: (max_step W)^5 W T max T and round-off), each
    closed-loop pole within 0.5 % plus one step's first-order error h |s| (at most 2.5 %, measured <= 2.2 %);
    and the rates the docstring above states. A tolerance widened in verify.py fails this test.

    The rest rows of the engine-defaults profile too, to the same bounds: rest penetration measured <= 6.0 um
    (MuJoCo's 5.9 mm; ODE 5.29 um, where Kd max|ydot|/Kp made it 84.7 um on a jittering quick step), static
    balance <= 0.088 N (MuJoCo 0.076 N, Lagrange 0.059 N; ODE's ticks furthest beyond their own tolerances
    0.084, 0.088, 0.060 N, where the window's largest tolerance made the rows 9.0, 2.3 and 2.1 N)."""
    assert (verify.SOLVER_RTOL, verify.POLE_RTOL, verify.BALANCE_SOLVER_RTOL) == (1e-3, 5e-3, 1e-5)
    assert (verify.AT_REST_RTOL, verify.RIGID_REST_BOUND) == (1e-3, 1e-6)
    df, _ = results
    rest = df[(df["case"] == "rest_penetration") & (df["status"] != "not-applicable")]
    assert len(rest) and (rest["tolerance"] <= 1e-5).all(), rest[["backend", "tolerance"]]
    balance = df[(df["case"] == "static_balance") & (df["status"] != "not-applicable")]
    assert len(balance) and (balance["tolerance"] <= 1.0).all(), balance[["backend", "quantity", "tolerance"]]
    law = balance[balance["note"].str.startswith("law backend")]
    assert set(law["backend"]) == {"pinocchio", "lagrange"} & set(backends.available())
    assert (law["tolerance"] <= 0.1).all(), law[["backend", "quantity", "tolerance"]]
    # every built-in engine declares where its contact acts (info's contact.lift), so none needs the lever term:
    # 1e-5 of |F| and the dynamic terms, 5.3e-4 N (it was 0.54 N with the lever, which let MuJoCo's 0.10 N pass,
    # and 0.053 N at 0.1 % of |F|)
    declared = balance[balance["note"].str.startswith("engine contact at its declared point")]
    assert set(declared["backend"]) == set(backends.available()) - {"pinocchio", "lagrange"}
    assert (declared["tolerance"] <= 1e-3).all(), declared[["backend", "quantity", "tolerance"]]
    ed, _ = engine_defaults_rest
    assert set(ed["backend"]) == set(backends.available()) and (ed["status"] != "not-applicable").all()
    rest = ed[ed["case"] == "rest_penetration"]
    assert len(rest) == len(backends.available()) and (rest["tolerance"] <= 1e-5).all(), rest[["backend", "tolerance"]]
    balance = ed[ed["case"] == "static_balance"]
    assert len(balance) == 3 * len(backends.available()), balance[["backend", "quantity"]]
    assert (balance["tolerance"] <= 0.1).all(), balance[["backend", "quantity", "tolerance"]]
    adaptive = df[(df["case"] == "energy") & df["note"].str.startswith("adaptive")]
    assert len(adaptive) and (adaptive["tolerance"] <= 1e-10).all(), adaptive[["backend", "variant", "tolerance"]]
    small = df[(df["case"] == "small_oscillation") & (df["status"] != "not-applicable")]
    zeta = small["quantity"].str.endswith("damping ratio")
    poles = small[~zeta]
    rel = poles["tolerance"] / poles["expected"].abs()
    assert len(poles) and (rel >= 5e-3 - 1e-12).all() and (rel <= 0.025).all(), rel.describe()
    # a damping ratio's: the pole's own, turned into zeta's change (at most rel sqrt(1 - zeta^2), to first order)
    ratios, s = small[zeta], np.sqrt(1.0 - small[zeta]["expected"] ** 2)
    assert len(ratios) and (ratios["tolerance"] >= 5e-3 * s * (1 - 1e-3)).all(), ratios[["backend", "tolerance"]]
    assert (ratios["tolerance"] <= 0.025 * s * (1 + 1e-3)).all(), ratios[["backend", "tolerance"]]


def test_energy_covers_every_integrator_of_every_backend(results: tuple[pd.DataFrame, Path]) -> None:
    df, _ = results
    energy = df[df["case"] == "energy"]
    for name in backends.available():
        offered = backends.get(name).choices.get("integrator", (None,))
        assert len(energy[energy["backend"] == name]) == len(offered), name


def test_semi_implicit_euler_drifts_as_predicted_not_as_zero(results: tuple[pd.DataFrame, Path]) -> None:
    """The first-order drift is real (>> round-off) and the prediction catches its sign and size."""
    df, _ = results
    euler = df[(df["case"] == "energy") & df["variant"].str.contains("euler")]
    assert len(euler)
    assert (euler["measured"].abs() > 1e-5).all()
    assert (np.sign(euler["measured"]) == np.sign(euler["expected"])).all()


def test_small_oscillation_accounts_for_sampling(results: tuple[pd.DataFrame, Path]) -> None:
    """The 1 kHz PD moves the fast real pole from -231/s (continuous model) to -331/s: a 43 % effect the
    sampled model predicts and the simulations show."""
    df, _ = results
    fast = df[(df["case"] == "small_oscillation") & (df["quantity"] == "mode 4 decay rate")]
    assert len(fast) and (fast["expected"] > 300).all() and (fast["measured"] > 300).all()
    assert fast["note"].str.contains("continuous-time model \\(no sampling\\) -231", regex=True).all()


def test_files_written(results: tuple[pd.DataFrame, Path]) -> None:
    df, out = results
    meta = json.loads((out / "verification.json").read_text())
    assert meta["total"] == len(df) and meta["passed"] == int(df["pass"].sum())
    md = (out / "verification.md").read_text()
    n_pass, n_na = int(df["pass"].sum()), int((df["status"] == "not-applicable").sum())
    n_fail = int((df["status"] == "fail").sum())
    assert n_pass + n_fail + n_na == len(df)
    assert md.startswith(f"# Verification: {n_pass} of {len(df)} checks pass")
    assert (f", {n_na} not applicable" in md.splitlines()[0]) == (n_na > 0)
    assert (f", {n_fail} fail" in md.splitlines()[0]) == (n_fail > 0)
    assert "| case | backend |" in md


def test_matrix_pencil_recovers_known_poles() -> None:
    z_true = np.array([0.99 * np.exp(0.05j), 0.99 * np.exp(-0.05j), 0.95, 0.7])
    k = np.arange(300)
    Y = np.vstack([(np.array([1.0, 0.5, -2.0, 1.0]) * z_true[None, :] ** k[:, None]).sum(axis=1).real,
                   (np.array([0.3, 0.3, 1.0, -1.0]) * z_true[None, :] ** k[:, None]).sum(axis=1).real])  # fmt: skip
    z = verify.matrix_pencil(Y, 4)
    assert np.sort_complex(z) == pytest.approx(np.sort_complex(z_true), abs=1e-9)


def test_discrete_loop_converges_to_the_exact_flow() -> None:
    """Sub-stepped semi-implicit Euler approaches the exact ZOH flow at first order, RK4 at fourth: the largest
    entry's error halves from 10 to 20 Euler sub-steps (ratio measured 1.99999986, held to 2 within 1e-3) and falls
    16 times from 1 to 2 RK4 steps (1.9e-10 to 1.2e-11, ratio 16.0048, held to 16 within 5e-3: both errors far
    above round-off, so the ratio is the order's, not noise)."""
    M = np.array([[0.04, 0.01, 0.0], [0.01, 0.05, 0.005], [0.0, 0.005, 0.008]])
    Kg = np.diag([0.5, 0.3, -0.1])
    Kp, Kd = 10 * np.eye(3), np.eye(3)
    exact = verify.discrete_loop(M, Kg, Kp, Kd, 1e-3, "exact")
    e = [np.abs(verify.discrete_loop(M, Kg, Kp, Kd, 1e-3, "euler", n) - exact).max() for n in (10, 20)]
    r = [np.abs(verify.discrete_loop(M, Kg, Kp, Kd, 1e-3, "rk4", n) - exact).max() for n in (1, 2)]
    assert e[0] / e[1] == pytest.approx(2.0, rel=1e-3)
    assert r[0] / r[1] == pytest.approx(16.0, rel=5e-3)


def test_unknown_case_is_an_error() -> None:
    with pytest.raises(LegbenchError, match="unknown verification case 'bogus'"):
        verify.verify(None, ["pinocchio"], ["bogus"])


def test_cli_runs_a_case(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    parser = argparse.ArgumentParser()
    verify.add_cli(parser.add_subparsers())
    args = parser.parse_args(["verify", "--out", str(tmp_path), "--backends", "pinocchio", "--cases",
                              "rest_penetration"])  # fmt: skip
    assert args.func(args) == 0
    assert "1 of 1 checks pass" in capsys.readouterr().out
    assert math.isfinite(json.loads((tmp_path / "verification.json").read_text())["checks"][0]["measured"])


def test_unknown_profile_is_an_error() -> None:
    with pytest.raises(LegbenchError, match="unknown profile 'defaults'; choose from matched, engine-defaults"):
        verify.verify(None, ["pinocchio"], ["energy"], profile="defaults")


@pytest.mark.skipif("mujoco" not in backends.available(), reason="mujoco backend not installed")
def test_engine_defaults_verification_runs_each_engine_as_its_defaults_have_it(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """``legbench verify --profile engine-defaults`` loads every backend in that profile and runs its own integrator
    and step only (matched runs each integrator offered: four energy rows for MuJoCo). MuJoCo's defaults step
    semi-implicit Euler once per 1 ms period: its free swing drifts 6.19e-3 J, 20 x the 3.06e-4 J of the matched
    50 us step (a first-order drift), and the drift is still the one predicted for that step (the row passes, error
    4.2e-5 J within 1.9e-4 J). The CLI writes into results/verification__engine-defaults by default, and
    verification.json records the profile and its scope."""
    monkeypatch.chdir(tmp_path)
    parser = argparse.ArgumentParser()
    verify.add_cli(parser.add_subparsers())
    args = parser.parse_args(["verify", "--profile", "engine-defaults", "--backends", "mujoco", "--cases", "energy"])
    assert args.func(args) == 0
    assert "1 of 1 checks pass (engine-defaults profile); wrote results/verification__engine-defaults" in (
        capsys.readouterr().out
    )
    doc = json.loads((tmp_path / "results" / "verification__engine-defaults" / "verification.json").read_text())
    assert doc["profile"] == "engine-defaults" and doc["scope"] == verify.scope("engine-defaults")
    (row,) = doc["checks"]
    assert row["variant"] == "integrator=euler dt=0.001" and row["pass"]
    assert row["measured"] == pytest.approx(6.19e-3, rel=0.01) and row["error"] < 0.3 * row["tolerance"]
    matched = verify.verify(None, ["mujoco"], ["energy"])
    assert len(matched) == 4 and matched["variant"].str.endswith("dt=5e-05").all()
    euler = matched[matched["variant"] == "integrator=euler dt=5e-05"].iloc[0]
    assert row["measured"] / euler["measured"] == pytest.approx(20.0, rel=0.02)  # first order in h: 1 ms / 50 us


@pytest.mark.skipif(not {"pybullet", "ode"} <= set(backends.available()), reason="pybullet or ode not installed")
def test_an_engine_defaults_miss_carries_its_backends_explanation_and_still_fails() -> None:
    """The engine-defaults verification's misses are the defaults', each measured and, where a closed form holds
    it, explained by its backend (``Backend.known_deviation``, asked by every case, not only the sliding drag):
    PyBullet's default contact slop (1e-5 m) rests the foot one slop deeper than Fn/Kp (+9.83 um, tolerance
    5.2 um); ODE's quick step at its default 20 iterations leaves the hinges off their axes by as much as the
    100 urad oscillation, and no pole is right, with no closed form of the fitted poles, so no explanation
    (spurious modes of 130-150 Hz with ODE's own advancing row order; near 500 Hz with one order per
    step). The rows still fail; the matched rows of the same cases pass with no such note."""
    (rest,) = [c for c in verify.check_rest(["pybullet"], profile="engine-defaults") if c.case == "rest_penetration"]
    assert not rest.passed and rest.note.startswith("known: with a contact stiffness set, Bullet springs"), rest
    assert rest.measured - rest.expected == pytest.approx(1e-5, abs=3e-7)  # one slop deeper
    poles = verify.check_small_oscillation(["ode"], profile="engine-defaults")
    assert poles and all(not c.passed and "known: " not in c.note for c in poles)  # no closed form of the poles
    assert max(c.measured for c in poles if c.quantity.endswith("frequency")) > 100.0  # [Hz]: the leg's are < 2 Hz
    matched = verify.check_rest(["pybullet"]) + verify.check_small_oscillation(["ode"], integrators=None)
    assert all(c.passed and not c.note.startswith("known") for c in matched)
    # an explanation holds the row to its own closed form: a miss it does not account for is not explained, and a
    # run that failed is not the engine's known miss
    pb = backends.get("pybullet")
    sc = scenario_mod.load(verify.REST_SCENARIO)
    info = verify._simulate(sc, "pybullet", scenario_mod.physics_of(sc), {}, "engine-defaults").info
    args = ("rest_penetration", rest.quantity, info)
    assert pb.known_deviation(*args, rest.measured, rest.expected, rest.tolerance) is not None
    assert pb.known_deviation(*args, rest.expected + 3e-5, rest.expected, rest.tolerance) is None  # 3 slops deeper
    failed = explained_note(pb, *args, False, math.nan, math.nan, math.nan, "simulation diverged")
    assert failed == "simulation diverged"


@pytest.mark.skipif("mujoco" not in backends.available(), reason="mujoco backend not installed")
def test_mujocos_engine_defaults_rest_is_its_own_steady_state() -> None:
    """MuJoCo's usual solref (-Kp, -Kd) is not Kp N/m: with the default impedance the foot rests at 0.42 mm under
    59 N, not Fn/Kp = 5.9 mm, and the row fails against the spec. Its note is MuJoCo's own steady state from the
    run's info (solimp, A, the pyramidal cone's share 2 / (mu^2 (1 + mu^2))): y = 0.4203 mm, 1.405e5 N/m, met to
    3e-4 of y; held to it, so the note is an explanation and not a label."""
    (rest,) = [c for c in verify.check_rest(["mujoco"], profile="engine-defaults") if c.case == "rest_penetration"]
    assert not rest.passed and rest.measured == pytest.approx(4.2e-4, rel=0.01), rest
    assert rest.note.startswith("known: the usual solref (-Kp, -Kd) is not Kp N/m"), rest.note
    assert "1.405e+05 N/m, y = 0.0004203 m" in rest.note, rest.note


def test_a_family_without_prediction_gets_not_applicable_rows(monkeypatch: pytest.MonkeyPatch,
                                                              tmp_path: Path) -> None:  # fmt: skip
    """The fake backend declares integrator family ``other``: its energy and pole rows say why there is no
    closed-form answer, with status not-applicable (neither pass nor fail)."""
    registry = backends._registry
    monkeypatch.setattr(backends, "_registry", lambda: {**registry(), "fake": FakeBackend})
    df = verify.verify(tmp_path, ["fake"], ["energy", "small_oscillation"])
    assert list(df["case"]) == ["energy", "small_oscillation"]
    assert (df["status"] == "not-applicable").all() and not df["pass"].any()
    assert df["note"].str.contains("integrator family 'other': no closed-form prediction").all()
    assert "unknown integrator family" not in " ".join(df["note"])
    md = (tmp_path / "verification.md").read_text()
    assert md.startswith("# Verification: 0 of 2 checks pass, 2 not applicable\n") and "| n/a |" in md


def test_verify_runs_the_sliding_case_with_three_closed_form_rows_per_backend() -> None:
    """`legbench verify` includes the drag above the friction limit: |F_t|/Fn = mu, friction against the slip,
    slip acceleration of the closed form, each within the case's stated tolerance (all pass on these backends)."""
    from legbench.studies import verify as V

    df = V.verify(backends=["pinocchio", "mujoco"], cases=["sliding"])
    assert sorted(df["backend"].value_counts().to_dict().items()) == [("mujoco", 3), ("pinocchio", 3)]
    assert (df["status"] == "pass").all(), df[["backend", "quantity", "measured", "expected", "note"]]
    # Pinocchio applies the law itself: its friction ratio and angle are the law read back, and say so
    # (|F_t|/Fn = mu_k to round-off); MuJoCo's are its engine's, and its acceleration row is a test either way
    read_back = df["note"].str.startswith("the law read back")
    assert set(df[read_back]["backend"]) == {"pinocchio"} and read_back.sum() == 2
    assert not df[read_back]["quantity"].str.startswith("slip acceleration").any()
    ratio = df[read_back & df["quantity"].str.startswith("friction")]
    assert float(ratio["error"].iloc[0]) < 1e-9


def _pyramid_state() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Five states of the foot 1 mm into the ground near q*, random speeds and torques, Fn = 15 N."""
    rng = np.random.default_rng(7)
    p = model.load_params()
    q0 = kinematics.ik_nearest(np.array([0.1667, 0.0, p.geometry.R_foot - 0.001]), np.array(p.q_star))
    q = q0 + 0.01 * rng.standard_normal((5, 3))
    return q, 0.3 * rng.standard_normal((5, 3)), 3.0 * rng.standard_normal((5, 3)), np.full(5, 15.0)


def test_the_pyramids_closed_form_holds_where_it_can_and_slides_at_the_bound() -> None:
    """sliding_case.pyramid_friction: with a bound no force reaches, both axes hold (the poc's horizontal
    acceleration 0 to 1e-9 m/s^2); with mu = 0 the force is 0 and the acceleration the unforced one; with mu
    between the two holding forces' ratios the axis that needs more slides at exactly mu Fn and the other still
    holds (its acceleration 0 to 1e-9) or slides at the bound too."""
    from legbench.studies.sliding_case import predicted_acceleration, pyramid_friction

    q, qd, tau, fn = _pyramid_state()
    held, acc = pyramid_friction(q, qd, tau, fn, 1e9)
    np.testing.assert_allclose(acc, 0.0, atol=1e-9)
    free, acc0 = pyramid_friction(q, qd, tau, fn, 0.0)
    assert not free.any()
    np.testing.assert_allclose(acc0, predicted_acceleration(q, qd, tau, np.column_stack([free, fn])), rtol=1e-12)
    ratio = np.abs(held) / fn[:, None]
    mixed = 0
    for s in range(len(q)):
        mu = float(ratio[s].mean())  # between the two axes' holding forces
        ft, a = pyramid_friction(q[s : s + 1], qd[s : s + 1], tau[s : s + 1], fn[s : s + 1], mu)
        i = int(np.argmax(ratio[s]))
        assert abs(ft[0, i]) == pytest.approx(mu * fn[s], rel=1e-12) and np.sign(ft[0, i]) == np.sign(held[s, i])
        assert abs(a[0, i]) > 1e-3  # it slides
        if abs(ft[0, 1 - i]) < mu * fn[s]:  # the other axis holds: no acceleration along it
            assert abs(a[0, 1 - i]) < 1e-9
            mixed += 1
        else:  # or slides at its bound too
            assert abs(ft[0, 1 - i]) == pytest.approx(mu * fn[s], rel=1e-12)
    assert mixed >= 1


@pytest.mark.parametrize(
    ("name", "exact", "dantzig"),
    [("dart", {"lcp_solver": "pgs"}, {"lcp_solver": "dantzig"}), ("ode", {"stepper": "quick"}, {"stepper": "world"})],
)
def test_the_pyramid_closed_form_is_met_where_the_bound_is_the_current_normal_force(
    name: str, exact: dict[str, str], dantzig: dict[str, str]
) -> None:
    """A friction pyramid whose solver bounds each friction row by mu times the current normal force (DART's
    PGS, ODE's quick step) meets the pyramid's closed form within the case's tolerances (measured: slip
    acceleration within 0.1 % and 0.06 %, friction along the drag 0.700 Fn); the Dantzig LCP that bounds by the
    normal impulse solved before the friction rows does not (DART holds 0.83 Fn and does not slide; ODE slides at
    0.7068 Fn, 11 % less acceleration), each explained by the pyramid's closed form at that bound, predicted by
    re-solving each sample without friction (Backend.frictionless_normal)."""
    if name not in backends.available():
        pytest.skip(f"{name} not installed")
    from legbench.studies import sliding_case as S

    tr, physics = S.drag(name, settings=exact)
    rows = S.score(tr, physics)
    assert len(rows) == 3 and all(r["passed"] for r in rows), rows
    assert rows[0]["measured"] == pytest.approx(0.7, rel=1e-3) and rows[2]["error"] < 0.005 * rows[2]["expected"]
    tr, physics = S.drag(name, settings=dantzig)
    along, _, slip = S.score(tr, physics)
    assert along["measured"] == pytest.approx(0.833 if name == "dart" else 0.7068, abs=0.005)
    assert not slip["passed"] and slip["note"].startswith("known: "), slip["note"]
    assert slip["error"] > (0.9 if name == "dart" else 0.08) * slip["expected"]


def test_the_table_does_not_depend_on_the_number_of_workers(tmp_path: Path) -> None:
    """verify(jobs=2) (a pool, one case group and backend per task, the slowest started first) gives the
    same rows as jobs=1, in the same order, to the last bit."""
    names, cases = ["pinocchio", "mujoco"], ["energy", "small_oscillation", "rest_penetration"]
    one = verify.verify(None, names, cases, jobs=1)
    two = verify.verify(None, names, cases, jobs=2)
    assert len(one) > 10 and set(one["case"]) == set(cases)
    pd.testing.assert_frame_equal(one, two)


def test_an_engine_that_crashes_its_worker_fails_its_cases_and_the_others_are_verified(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """verify --jobs 2 with a plug-in engine that kills its worker (SIGSEGV) beside Pinocchio: every case of
    the crashing engine is a failed row naming the signal, Pinocchio's rows are those of a verify without it
    (it ended with BrokenProcessPool, a traceback, before)."""
    monkeypatch.syspath_prepend(str(tmp_path))
    crashy = install_crashing_engine(tmp_path)
    df = verify.verify(None, ["pinocchio", crashy], ["energy", "rest_penetration"], jobs=2)
    bad = df[df["backend"] == crashy]
    assert set(bad["case"]) == {"energy", "rest_penetration"} and (bad["status"] == "fail").all()
    assert bad["note"].str.contains("the engine crashed: its worker process died \\(killed by SIGSEGV\\)").all()
    alone = verify.verify(None, ["pinocchio"], ["energy", "rest_penetration"], jobs=1)
    pd.testing.assert_frame_equal(df[df["backend"] == "pinocchio"].reset_index(drop=True), alone)


def test_the_adaptive_energy_tolerance_fails_a_first_order_step(monkeypatch: pytest.MonkeyPatch) -> None:
    """The adaptive rows' tolerance, (max_step W)^5 W T max T + round-off (8.2e-13 J at max_step 1e-4 s), tells
    a fifth-order step from a first-order one: Pinocchio's semi-implicit Euler at 50 us, declared adaptive with
    max_step = its step, drifts 4.9e-4 J and fails (its tolerance is below 1e-10 J). The former tolerance,
    n_periods (rtol |x| + atol) |grad E| = 5.2e-4 J, passed it."""
    info = PinocchioBackend.info
    monkeypatch.setattr(PinocchioBackend, "integrator_family", lambda self: "adaptive")
    monkeypatch.setattr(PinocchioBackend, "info", lambda self: {**info(self), "max_step": self.h})
    (row,) = verify.check_energy(["pinocchio"], integrators=["euler"])
    assert row.measured > 1e-4  # Euler's drift, 4.9e-4 J
    assert row.status == "fail" and row.tolerance < 1e-9, (row.measured, row.tolerance)
    assert row.note.startswith("adaptive") and "h = 5e-05 s" in row.note


def test_the_adaptive_energy_rows_pass_for_the_real_solvers() -> None:
    """Pinocchio's rk45 and dop853 (1.4e-14, 1.0e-14 J) and the Lagrange backend's (8e-15, 1.7e-14 J: its model
    from the parameter file, E on the URDF, which carries the same numbers exactly) stay within the same
    tolerance, 8.2e-13 J."""
    rows = verify.check_energy(["pinocchio", "lagrange"], integrators=["rk45", "dop853"])
    assert len(rows) == 4 and all(r.note.startswith("adaptive") for r in rows)
    for r in rows:
        assert r.passed and r.measured <= r.tolerance <= 1e-10, (r.backend, r.variant, r.measured, r.tolerance)


def _read_with_a_lever_error(tr: RunResult) -> RunResult:
    """The run with its ground force read as if the law's force acted y below the sphere's lowest point (at
    R_foot + y below E, a lever error of y): the force that balances the same torques through that point."""
    R = model.load_params().geometry.R_foot
    f, q = tr.f.copy(), tr.q
    y = R - kinematics.fk(q)[:, 2]
    J, Jv, Jw = kinematics.jacobian_poc(q), kinematics.jacobian(q), kinematics.angular_jacobian(q)
    for k in np.flatnonzero(y > 0):
        d = R + y[k]
        J_app = Jv[k] - np.array([[0.0, d, 0.0], [-d, 0.0, 0.0], [0.0, 0.0, 0.0]]) @ Jw[k]
        f[k] = np.linalg.solve(J_app.T, J[k].T @ f[k])
    return dataclasses.replace(tr, f=f)


def test_static_balance_of_a_law_backend_catches_a_lever_error(monkeypatch: pytest.MonkeyPatch) -> None:
    """A backend applying the law itself puts the force at the known point of contact, so its static balance has
    no lever term: Pinocchio's tolerance is 2e-4 N (the held torque's step) against its 5e-5 N. The same run with
    the force read at R_foot + y below E (a lever error of y = 5.25 mm) is off by (0.018, 0.078, 0.20) N and
    fails every component; the former tolerance, 0.54 N (the lever term for a point anywhere in the
    penetration band), passed it."""
    with monkeypatch.context() as m:
        simulate = verify._simulate
        m.setattr(verify, "_simulate", lambda *a: _read_with_a_lever_error(simulate(*a)))
        bad = [c for c in verify.check_rest(["pinocchio"]) if c.case == "static_balance"]
    assert len(bad) == 3
    for c in bad:
        assert c.error > 0.01 and c.status == "fail", (c.quantity, c.error, c.tolerance)

    real = verify.check_rest(["pinocchio"])
    balance = [c for c in real if c.case == "static_balance"]
    assert len(balance) == 3 and all(c.passed for c in balance), balance
    assert all(c.tolerance < 1e-3 and c.note.startswith("law backend") for c in balance)
    (rest,) = [c for c in real if c.case == "rest_penetration"]
    assert rest.passed and "checks the force read-out's consistency, not the engine" in rest.note


def test_adaptive_energy_rows_name_their_max_step_not_a_sub_step(results: tuple[pd.DataFrame, Path]) -> None:
    """An adaptive solver's steps are its error control's, bounded by max_step: its energy rows' variant names
    that bound (integrator=rk45 max_step=0.0001 for Pinocchio and Lagrange, and dop853), not a sub-step dt (the
    declared one sub-step per period would read dt=0.001, a step it never takes)."""
    df, _ = results
    adaptive = df[(df["case"] == "energy") & df["note"].str.startswith("adaptive")]
    named = set(zip(adaptive["backend"], adaptive["variant"], strict=True))
    for name in ("pinocchio", "lagrange"):
        for integ in ("rk45", "dop853"):
            assert (name, f"integrator={integ} max_step=0.0001") in named, named
    assert not adaptive["variant"].str.contains("dt=").any(), adaptive["variant"]


def test_a_law_backends_static_balance_is_taken_at_the_poc_its_settings_set(tmp_path: Path) -> None:
    """The Lagrange backend with its setting poc: centre (the report's custom simulation) applies the law's force
    at the sphere's centre while the scenario's poc is the true one: its static balance, F = -(J_poc^T)^-1
    (tau - G) with J at the centre, passes within 0.1 N and the note names poc centre. Measured: errors
    (0.0025, 0.013, 4e-5) N against a tolerance of 0.059 N (its solver term); J at the scenario's true poc
    instead misses by (0.071, 0.36, 0.89) N (the lever R_foot to the centre)."""
    text = verify.REST_SCENARIO.read_text() + "backends: {lagrange: {poc: centre}}\n"
    scenario_file = tmp_path / "effort_rest_centre.yaml"
    scenario_file.write_text(text)
    balance = [c for c in verify.check_rest(["lagrange"], scenario_file) if c.case == "static_balance"]
    assert len(balance) == 3
    for c in balance:
        assert c.passed and c.tolerance <= 0.1, (c.quantity, c.error, c.tolerance)
        assert c.note.startswith("law backend (the law's force at its known point of contact, poc centre)"), c.note


def test_applies_law_is_no_engine_contact_or_reference_mode() -> None:
    """The law is legbench's when the run is in reference contact mode (whatever the engine), or the backend has
    no contact of its own (engine_contact False); a run that did not record engine_contact is taken as an
    engine's own contact (native mode)."""
    assert applies_law({"engine_contact": True}, Physics(contact_mode="reference"))
    assert applies_law({}, Physics(contact_mode="reference"))
    assert not applies_law({}, Physics())
    assert not applies_law({"engine_contact": True}, Physics())
    assert applies_law({"engine_contact": False}, Physics())


def _adaptive_energy_tolerance(physics: Physics, tr: RunResult) -> tuple[float, int]:
    """The adaptive energy row's tolerance [J] as verify.py's docstring states it, from the run: (h W)^5 W T_end
    max T + 4 sqrt(n) eps max|T, V| with h = min(max_step, Ts), n = (len(t) - 1) ceil(Ts / h) (the fewest steps
    the solver can take); and n."""
    Ts = physics.control_dt
    TV = np.array([model.Dynamics(physics.gravity).energy(q, qd) for q, qd in zip(tr.q, tr.qd, strict=True)])
    h = min(float(tr.info.get("max_step", Ts)), Ts)
    n_min = (len(tr.t) - 1) * math.ceil(Ts / h - 1e-9)
    W = float(np.abs(tr.qd).max())
    trunc = (h * W) ** 5 * W * float(tr.t[-1]) * float(TV[:, 0].max())
    return trunc + 4.0 * math.sqrt(n_min) * verify.EPS * float(np.abs(TV).max()), n_min


def _first_order_energy_order(physics: Physics, tr: RunResult, half: RunResult, quarter: RunResult) -> float:
    """A first-order family's energy row as verify.py's docstring states it, from its runs at h, h/2 and h/4: the
    order log2(R_h / R_h/2) of the Richardson remainder R_h = max|D_h - 2 D_h/2| (D = E(t) - E(0) on the same
    ticks)."""
    dyn = model.Dynamics(physics.gravity)
    D = [np.array([sum(dyn.energy(q, qd)) for q, qd in zip(r.q, r.qd, strict=True)]) for r in (tr, half, quarter)]
    D = [d - d[0] for d in D]
    return math.log2(float(np.abs(D[0] - 2.0 * D[1]).max()) / float(np.abs(D[1] - 2.0 * D[2]).max()))


def _static_balance_terms(scenario: Any, physics: Physics, tr: RunResult) -> dict[str, np.ndarray]:
    """The static balance tolerance's terms per tick of the steady window [N], as verify.py's docstring states
    them, from the run: ``dyn`` (n, 3) |(J_poc^T)^-1 (M qdd + C qd)| (qdd the central difference); ``step``
    ||(J_poc^T)^-1||_2 ||tau_k - tau_{k-1}||_2; for an engine's contact ``solver`` 1e-5 |F| and, where the backend
    declares no point of application (its info's ``contact.lift``), ``lever`` ||(J_poc^T)^-1||_2 y |F_t|; for a law
    backend (reference mode or no engine contact) ``roundoff`` 8 eps (|F| +
    ||(J_poc^T)^-1||_2 (|tau| + |G|)) and, adaptive, ``solver`` ||J_poc||_2 ((max(mu_s, 2 |mu_s - mu_k|) Fn /
    v_th + Kd (1 + mu_s)) e_qd + Kp (1 + mu_s) e_q), e_q = sqrt(6) (atol + rtol max|q|), e_qd the same of |qd|;
    J where the backend declares its force acts (the law's poc; an engine's lift above the lowest point). Also
    ``expected`` (n, 3) -(J_poc^T)^-1 (tau - G) and ``inertial`` (n,) ||(J_poc^T)^-1 (M qdd + C qd)||_2 [N]."""
    c = scenario.contact
    law = physics.contact_mode == "reference" or not tr.info["engine_contact"]
    poc = tr.info["contact"].get("poc", c.poc)
    lift = float(tr.info["contact"].get("lift", 0.0))
    declared = "lift" in tr.info["contact"]
    idx = np.flatnonzero(tr.t >= tr.t[-1] - scenario.comparison.steady_window - 1e-9)
    assert idx[0] > 0
    q, qd, tau, f = tr.q[idx], tr.qd[idx], tr.tau[idx], tr.f[idx]
    qdd = np.gradient(tr.qd, tr.t, axis=0)[idx]
    J = kinematics.jacobian_at(q, poc, lift)
    y = model.load_params().geometry.R_foot - kinematics.fk(q)[:, 2]
    leg = model.Dynamics(scenario.gravity)
    adaptive = law and tr.info["integrator_family"] == "adaptive"
    rtol, atol = float(tr.info.get("rtol", 0.0)), float(tr.info.get("atol", 0.0))
    n = len(idx)
    out = {"dyn": np.zeros((n, 3)), "step": np.zeros(n), "lever": np.zeros(n), "solver": np.zeros(n),
           "roundoff": np.zeros(n), "expected": np.zeros((n, 3)), "inertial": np.zeros(n)}  # fmt: skip
    for k in range(n):
        G = leg.gravity(q[k])
        JTinv = np.linalg.inv(J[k].T)
        norm = np.linalg.norm(JTinv, 2)
        inertial = JTinv @ (leg.inverse_dynamics(q[k], qd[k], qdd[k]) - G)
        out["dyn"][k], out["inertial"][k] = np.abs(inertial), np.linalg.norm(inertial)
        out["expected"][k] = -JTinv @ (tau[k] - G)
        out["step"][k] = norm * np.linalg.norm(tau[k] - tr.tau[idx[k] - 1])
        if not law:
            if not declared:
                out["lever"][k] = norm * max(y[k], 0.0) * math.hypot(f[k, 0], f[k, 1])
            out["solver"][k] = 1e-5 * np.linalg.norm(f[k])
            continue
        out["roundoff"][k] = (
            8 * verify.EPS * (np.linalg.norm(f[k]) + norm * (np.linalg.norm(tau[k]) + np.linalg.norm(G)))
        )
        if adaptive:
            e_q = math.sqrt(6) * (atol + rtol * float(np.abs(q[k]).max()))
            e_qd = math.sqrt(6) * (atol + rtol * float(np.abs(qd[k]).max()))
            slope_v = max(c.mu_s, 2.0 * abs(c.mu_s - c.mu_k)) / c.v_th
            out["solver"][k] = np.linalg.norm(J[k], 2) * (
                (slope_v * max(f[k, 2], 0.0) + c.Kd * (1.0 + c.mu_s)) * e_qd + c.Kp * (1.0 + c.mu_s) * e_q
            )
    return out


def _assert_rest_rows_recomputed(df: pd.DataFrame, name: str, scenario: Any, physics: Physics, tr: RunResult) -> bool:
    """The run's rest_penetration and static_balance rows in ``df`` are the docstring of verify.py's, recomputed
    from the run: mean y against mean Fn/Kp within 1e-3 Fn/Kp + Kd v/Kp, v = |mean ydot| for an engine's damper
    (both ways), mean(max(ydot, 0)) for the spec's law (a law backend); a rigid contact (info contact.Kp None)
    against its backend's ``rest_sink`` at mean Fn within 1e-3 of it (DART's closed form itself is recomputed in
    test_backend_dart.py), met to 1e-5 of it (measured 2.5e-6 at 50 us, 3e-8 at 1 ms); each static balance
    component at the tick whose error is furthest beyond its own tolerance (the sum of
    :func:`_static_balance_terms`), passing iff every tick is within its own and the inertial force is within 0.1 %
    of |F| at every tick (else 'not at rest'). All to rel 1e-6. Returns whether the run's backend applies the law."""
    c = scenario.contact
    law = applies_law(tr.info, physics)
    idx = np.flatnonzero(tr.t >= tr.t[-1] - scenario.comparison.steady_window - 1e-9)
    q, qd, f = tr.q[idx], tr.qd[idx], tr.f[idx]
    J = kinematics.jacobian_at(q, tr.info["contact"].get("poc", c.poc), float(tr.info["contact"].get("lift", 0.0)))
    ydot = -np.einsum("nj,nj->n", J[:, 2, :], qd)
    v = float(np.maximum(ydot, 0.0).mean()) if law else abs(float(ydot.mean()))
    fn = float(f[:, 2].mean())
    ((_, pen),) = df[(df["case"] == "rest_penetration") & (df["backend"] == name)].iterrows()
    if tr.info["contact"].get("Kp", c.Kp) is None:  # rigid: the engine's own sink, no spring
        sink = getattr(backends.get(name), "rest_sink")(tr.info, fn)  # noqa: B009 (not in the base class)
        assert pen["expected"] == pytest.approx(sink, rel=1e-12) and sink > 0.0, (name, pen["expected"], sink)
        assert pen["tolerance"] == pytest.approx(1e-3 * sink, rel=1e-12), (name, pen["tolerance"])
        assert pen["error"] <= 1e-5 * sink and pen["pass"], (name, pen["error"], sink)
    else:
        tol = 1e-3 * fn / c.Kp + c.Kd * v / c.Kp
        assert pen["tolerance"] == pytest.approx(tol, rel=1e-6), (name, pen["tolerance"])
    terms = _static_balance_terms(scenario, physics, tr)
    rows = df[(df["case"] == "static_balance") & (df["backend"] == name)]
    assert [q.split()[0] for q in rows["quantity"]] == ["Fx", "Fy", "Fz"], name
    at_rest = bool((terms["inertial"] <= 1e-3 * np.linalg.norm(f, axis=1)).all())
    for j, (_, row) in enumerate(rows.iterrows()):
        total = terms["dyn"][:, j] + terms["step"] + terms["lever"] + terms["solver"] + terms["roundoff"]
        err = np.abs(f[:, j] - terms["expected"][:, j])
        k = int(np.argmax(err / total))
        quantity, note = row["quantity"], row["note"]
        assert row["tolerance"] == pytest.approx(total[k], rel=1e-6), (name, quantity, row["tolerance"], total[k])
        assert row["measured"] == pytest.approx(f[k, j], rel=1e-12), (name, quantity)
        assert row["error"] == pytest.approx(err[k], rel=1e-6, abs=1e-12), (name, quantity)
        assert row["expected"] == pytest.approx(terms["expected"][k, j], rel=1e-9, abs=1e-12), (name, quantity)
        assert row["pass"] == (bool((err <= total).all()) and at_rest), (name, quantity, row["pass"])
        assert note.startswith("not at rest: ") == (not at_rest), note
        assert f"torque step up to {terms['step'].max():.2e} N" in note, note
        assert f"dynamic term there {terms['dyn'][k, j]:.2e} N (up to {terms['dyn'][:, j].max():.2e} N)" in note
        if law:
            assert f"solver tolerance up to {terms['solver'].max():.2e} N" in note, note
    return law


def test_stated_tolerance_terms_recomputed_from_each_run(
    results: tuple[pd.DataFrame, Path], verify_runs: list[SimulatedRun]
) -> None:
    """Each adaptive energy row's and each static balance row's tolerance is the sum the docstring of verify.py
    states, recomputed here from the row's run to rel 1e-6 (measured: equal to round-off).

    energy, adaptive (Pinocchio and Lagrange, rk45 and dop853): 8.2e-13 J = (h W)^5 W T_end max T (4.4e-13 J,
    h = max_step 1e-4 s, W = 18.9 rad/s) + 4 sqrt(n) eps max|T, V| (3.8e-13 J), n = (len(t) - 1) ceil(Ts / h) =
    10000 steps, as the note says. energy, RK4 (Pinocchio and MuJoCo): the row's run (the declared step's, 20 per
    period, or the check's own, 2 per period: the one its note names) gives its measured E(t_end) - E(0), within a
    tolerance below 1e-12 J (5.4e-13 J). static_balance, at the tick furthest beyond its own tolerance, the sum of the
    terms of :func:`_static_balance_terms` there (:func:`_assert_rest_rows_recomputed`): Pinocchio 1.98e-4 N (the
    torque step, 2-norms; round-off 3.4e-13 N), Lagrange 0.0622 N (its solver term 0.0620 N at atol 1e-6, rtol
    1e-8; the torque step 2.0e-4 N), the engines 5.3e-4 N (1e-5 |F|, no lever at their declared points); rest
    penetration 1e-3 Fn/Kp + the mean damping, 5.2-5.3 um (a rigid contact: its backend's closed form of the sink
    within 1e-3 of it). The notes' stated maxima agree at their 3 digits."""
    df, _ = results
    assert verify_runs
    energy_runs = [r for r in verify_runs if r[0].name == "energy"]
    rest_runs = [r for r in verify_runs if r[0].name == "effort_rest"]
    adaptive_seen, law_seen, first_order_seen, rk4_seen = set(), set(), set(), set()
    for name in backends.available():
        runs = iter([r for r in energy_runs if r[1] == name])
        rows = df[(df["case"] == "energy") & (df["backend"] == name)]
        for row in rows.itertuples():
            _, _, physics, tr = next(runs)
            assert tr.status == "ok" and row.variant.startswith(f"integrator={tr.info.get('integrator', '')}")
            if tr.info["integrator_family"] == "first-order":  # and its runs at h/2 and h/4 (Richardson)
                half, quarter = next(runs)[3], next(runs)[3]
                assert [r.info["sub_steps"] for r in (half, quarter)] == [
                    2 * tr.info["sub_steps"],
                    4 * tr.info["sub_steps"],
                ]
                order = _first_order_energy_order(physics, tr, half, quarter)
                assert row.measured == pytest.approx(order, rel=1e-9), (name, row.measured, order)
                assert (row.expected, row.tolerance) == (2.0, 0.5), (name, row.expected, row.tolerance)
                first_order_seen.add(name)
            if tr.info["integrator_family"] == "rk4":  # and its run at the check's own step, Ts / 2
                check = next(runs)[3]
                assert (tr.info["sub_steps"], check.info["sub_steps"]) == (20, 2), (name, row.variant)
                shown = check if "the row shows the check's step's run" in row.note else tr
                dyn = model.Dynamics(physics.gravity)
                E = [sum(dyn.energy(q, qd)) for q, qd in ((shown.q[0], shown.qd[0]), (shown.q[-1], shown.qd[-1]))]
                assert row.measured == pytest.approx(E[1] - E[0], rel=1e-9, abs=1e-18), (name, row.measured)
                assert row.tolerance < 1e-12, (name, row.tolerance)  # round-off 5.4e-13 J + max|pred| (h W + (Ts W)^2)
                rk4_seen.add(name)
            if tr.info["integrator_family"] != "adaptive":
                continue
            tol, n_min = _adaptive_energy_tolerance(physics, tr)
            assert row.tolerance == pytest.approx(tol, rel=1e-6), (name, row.variant, row.tolerance, tol)
            assert row.note.endswith(f"({n_min} steps)"), (row.note, n_min)
            adaptive_seen.add((name, tr.info["integrator"]))
        ((scenario, _, physics, tr),) = [r for r in rest_runs if r[1] == name]
        assert tr.status == "ok", name
        assert next(runs, None) is None, name  # no run of the backend's energy rows left over
        if _assert_rest_rows_recomputed(df, name, scenario, physics, tr):
            law_seen.add(name)
    assert {
        ("pinocchio", "rk45"),
        ("pinocchio", "dop853"),
        ("lagrange", "rk45"),
        ("lagrange", "dop853"),
    } <= adaptive_seen
    assert law_seen == {"pinocchio", "lagrange"}
    assert first_order_seen == {"ode"} & set(backends.available())
    assert rk4_seen == {"pinocchio", "mujoco"} & set(backends.available())


def test_the_torque_step_term_is_the_2_norm_of_the_step_over_the_joints(monkeypatch: pytest.MonkeyPatch) -> None:
    """In the effort_rest run the abad and the knee sit at their torque limits (7.051, 10.073 N m), so the held
    torque steps in the hip alone (up to 2.3e-5 N m) and every norm of the step is the same. With +-1e-5 N m
    alternating every tick added on all three joints over the last 0.6 s (steps of 2e-5 N m), Pinocchio's static balance
    tolerance is ||(J_poc^T)^-1||_2 ||tau_k - tau_{k-1}||_2 (the 2-norm over the joints) plus the rest, as
    recomputed from the run at each row's tick (the one furthest beyond its own tolerance) to rel 1e-6 (measured
    2.46e-4, 4.46e-4, 2.47e-4 N; the largest component instead of the 2-norm would give 1.73e-4, 3.72e-4, 1.74e-4
    N there)."""
    runs: list[SimulatedRun] = []
    simulate = verify._simulate

    def stepped(scenario: Any, name: str, physics: Physics, settings: Mapping[str, Any], profile: str) -> RunResult:
        tr = simulate(scenario, name, physics, settings, profile)
        tau = tr.tau.copy()
        tau[-600:] += 1e-5 * (-1.0) ** np.arange(600)[:, None]
        tr = dataclasses.replace(tr, tau=tau)
        runs.append((scenario, name, physics, tr))
        return tr

    monkeypatch.setattr(verify, "_simulate", stepped)
    rows = [c for c in verify.check_rest(["pinocchio"]) if c.case == "static_balance"]
    ((scenario, _, physics, tr),) = runs
    terms = _static_balance_terms(scenario, physics, tr)
    idx = np.flatnonzero(tr.t >= tr.t[-1] - scenario.comparison.steady_window - 1e-9)
    step = tr.tau[idx] - tr.tau[idx - 1]
    assert (np.abs(step[:, [0, 2]]) > 1.9e-5).all() and (step[:, 1] != 0.0).all()  # every joint steps
    largest = terms["step"] / np.linalg.norm(step, axis=1) * np.abs(step).max(axis=1)
    assert len(rows) == 3
    for j, row in enumerate(rows):
        rest = terms["dyn"][:, j] + terms["roundoff"]
        total = rest + terms["step"]
        k = int(np.argmax(np.abs(tr.f[idx, j] - terms["expected"][:, j]) / total))  # the row's tick
        assert row.tolerance == pytest.approx(total[k], rel=1e-6), (row.quantity, row.tolerance)
        assert row.tolerance > 1.1 * (rest + largest)[k], (row.quantity, row.tolerance)


def _with_knee_rate_spike(tr: RunResult, spike: float, fz_error: float = 0.0) -> RunResult:
    """The run with the knee's logged rate raised by ``spike`` [rad/s] at the tick 300 before the end (so the
    central difference reads qdd = +-spike / (2 ms) at the ticks beside it: a dynamic term there) and the logged Fz
    raised by ``fz_error`` [N] at the tick 100 before the end (t = 2.901 s), 0.2 s later."""
    qd, f = tr.qd.copy(), tr.f.copy()
    qd[-300, 2] += spike
    f[-100, 2] += fz_error
    return dataclasses.replace(tr, qd=qd, f=f)


def test_a_tick_over_its_own_tolerance_fails_beside_a_large_dynamic_term(monkeypatch: pytest.MonkeyPatch) -> None:
    """Each tick is held to its own tolerance. Pinocchio's run with Fz off by 0.01 N at one tick (its tolerance
    there 1.98e-4 N: 50 times over) and a knee rate spike of 3e-3 rad/s 0.2 s earlier (a dynamic term of 0.033 N at
    the ticks beside it, the inertial force 0.037 N, 0.07 % of |F|: still at rest): the Fz row fails at the tick
    of the error (error 50 times its tolerance), its numbers that tick's. The window's largest tolerance against
    the worst error, as before, was 0.033 N and passed it. Fx and Fy, with no error, pass."""
    simulate = verify._simulate
    monkeypatch.setattr(verify, "_simulate", lambda *a: _with_knee_rate_spike(simulate(*a), 3e-3, 0.01))
    fx, fy, fz = (c for c in verify.check_rest(["pinocchio"]) if c.case == "static_balance")
    assert fx.passed and fy.passed and not fx.note.startswith("not at rest"), (fx, fy)
    assert not fz.passed and fz.error == pytest.approx(0.01, abs=1e-4), fz
    assert fz.tolerance < 2.1e-4 and fz.error / fz.tolerance > 40, fz  # [N]: the tick's own, not the spike's
    assert fz.measured - fz.expected == pytest.approx(0.01, abs=1e-4) and "worst tick t = 2.901 s" in fz.note, fz
    assert "(up to 3.3" in fz.note and "e-02 N)" in fz.note, fz.note  # the spike's dynamic term, still said
    assert "1 of 501 ticks over theirs" in fz.note, fz.note


def test_a_leg_not_at_rest_fails_its_static_balance_within_every_ticks_tolerance(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The static balance is the closed form of a leg at rest: with Pinocchio's knee rate spiked by 1e-2 rad/s at
    one tick (no force error), the ticks beside it read an inertial force of 0.16 N, 0.30 % of |F| (the rest:
    below 1e-8 |F|), above the 0.1 % an engine's contact solver may miss by. Every tick is within its own
    tolerance (which takes the dynamic term in), and the rows fail, saying the leg is not at rest."""
    simulate = verify._simulate
    monkeypatch.setattr(verify, "_simulate", lambda *a: _with_knee_rate_spike(simulate(*a), 1e-2))
    rows = [c for c in verify.check_rest(["pinocchio"]) if c.case == "static_balance"]
    assert len(rows) == 3 and verify.AT_REST_RTOL == 1e-3
    for c in rows:
        assert c.status == "fail" and c.error <= c.tolerance, c
        assert c.note.startswith("not at rest: the inertial force |(J_poc^T)^-1 (M qdd + C qd)| is 0.298 % of |F|")
        assert "over 0.1 % at 2 of 501 ticks" in c.note, c.note


def _jittering_engine(tr: RunResult, v: float, fn_shift: float) -> RunResult:
    """Pinocchio's run as an engine's own contact would log it (info: engine_contact, the point declared at the
    sphere's lowest point), its penetration rate jittering by +-``v`` [m/s] from tick to tick (the joint rates
    moved along J_z, one tick up, the next down: mean ~0) and its normal force moved by ``fn_shift`` [N]."""
    Jz = kinematics.jacobian_at(tr.q, "true", 0.0)[:, 2, :]
    sign = (-1.0) ** np.arange(len(tr.t))
    qd = tr.qd - (sign * v / np.einsum("nj,nj->n", Jz, Jz))[:, None] * Jz  # ydot = -J_z qd moves by sign v
    f = tr.f.copy()
    f[:, 2] += fn_shift
    info = {**tr.info, "engine_contact": True, "contact": {**tr.info["contact"], "poc": "true", "lift": 0.0}}
    return dataclasses.replace(tr, qd=qd, f=f, info=info)


def test_a_jitter_does_not_widen_the_rest_penetration(monkeypatch: pytest.MonkeyPatch) -> None:
    """The row compares mean y with mean Fn/Kp, which differ by the damping force's mean over Kp, so that is what
    it allows: an engine's damper acts both ways, Kd |mean ydot| / Kp. Pinocchio's run logged as an engine's,
    jittering +-2 mm/s (mean 8.2 um/s) with Fn 0.1 N high (mean Fn/Kp 10 um above the mean y, twice the 0.1 %
    of y): it fails, error 10.0 um against 5.35 um (5.26 um the solver's share, 0.08 um the mean damping). Kd
    max|ydot| / Kp, as before, allowed 25 um and passed it. Without the 0.1 N it passes (error 0.04 um)."""
    simulate = verify._simulate
    with monkeypatch.context() as m:
        m.setattr(verify, "_simulate", lambda *a: _jittering_engine(simulate(*a), 2e-3, 0.1))
        (bad,) = [c for c in verify.check_rest(["pinocchio"]) if c.case == "rest_penetration"]
        m.setattr(verify, "_simulate", lambda *a: _jittering_engine(simulate(*a), 2e-3, 0.0))
        (good,) = [c for c in verify.check_rest(["pinocchio"]) if c.case == "rest_penetration"]
    assert not bad.passed and bad.error == pytest.approx(1e-5, rel=0.01), bad
    assert 5.2e-6 < bad.tolerance < 5.4e-6, bad  # [m]: 1e-3 y + Kd |mean ydot| / Kp
    assert "damping allowance Kd |mean(ydot)|/Kp" in bad.note and "max|ydot| = 2.00e-03 m/s" in bad.note, bad.note
    assert good.passed and good.error < 1e-7 and good.tolerance == pytest.approx(bad.tolerance, abs=2e-8), good


@pytest.mark.skipif("ode" not in backends.available(), reason="ode backend not installed")
def test_odes_jittering_engine_defaults_rest_misses_and_says_so(
    engine_defaults_rest: tuple[pd.DataFrame, list[SimulatedRun]],
) -> None:
    """ODE's engine-defaults quick step (20 iterations, 1 ms) jitters at rest: max|ydot| 7.9 mm/s, the inertial
    force up to 9.0 N (17 % of |F|). Its rest penetration, mean y 5.2155 mm against mean Fn/Kp 5.2217 mm (error
    6.23 um), fails against 5.29 um (0.1 % of y and Kd |mean ydot| / Kp = 0.06 um; Kd max|ydot| / Kp made it
    84.7 um). Its static balance rows fail at ticks 54.6, 58.9 and 19.1 times over their own tolerances (69, 140 and
    33 of 501 ticks over theirs; 12.0, 7.7, 2.2 times and 61, 112, 14 ticks at the former solver share 1e-3 |F|, now
    1e-5; the window's largest tolerance made the rows 9.0, 2.3, 2.1 N and passed them), and say the leg is not at
    rest. No explanation is attached: ODE's known_deviation has none for these."""
    df, _ = engine_defaults_rest
    ode = df[df["backend"] == "ode"].set_index("quantity")
    pen = ode.loc["penetration R_foot - z_E"]
    assert not pen["pass"] and pen["measured"] == pytest.approx(5.2155e-3, abs=1e-7), pen
    assert pen["error"] == pytest.approx(6.23e-6, rel=0.02) and 5.2e-6 < pen["tolerance"] < 5.4e-6, pen
    balance = ode[ode["case"] == "static_balance"]
    ratios = (balance["error"] / balance["tolerance"]).tolist()
    assert ratios == pytest.approx([54.6, 58.9, 19.1], rel=0.02), ratios
    assert not balance["pass"].any() and balance["note"].str.startswith("not at rest: ").all(), balance["note"]
    for n, note in zip((69, 140, 33), balance["note"], strict=True):
        assert f"{n} of 501 ticks over theirs" in note, note
    assert not ode["note"].str.contains("known: ", regex=False).any()
    # every other backend's static balance holds at every tick, at rest
    others = df[(df["case"] == "static_balance") & (df["backend"] != "ode")]
    assert others["pass"].all() and others["note"].str.contains(" 0 of 501 ticks over theirs").all(), _failures(others)


def test_engine_defaults_rest_rows_recomputed_from_each_run(
    engine_defaults_rest: tuple[pd.DataFrame, list[SimulatedRun]],
) -> None:
    """The engine-defaults rest rows are the docstring's too (:func:`_assert_rest_rows_recomputed`, rel 1e-6):
    rest penetration 1e-3 Fn/Kp + the damping's mean (5.2-6.0 um; DART's rigid rest 1e-3 of its own sink, 2.4e-10
    m), each static balance component at the tick furthest beyond its own tolerance (5.3e-4 N for PyBullet, Drake
    and DART, 0.014-0.018 N for MuJoCo, whose dynamic terms are larger, 0.059 N for Lagrange; ODE 0.004-0.009 N,
    not at rest), failing where a tick is over or the leg not at rest."""
    df, runs = engine_defaults_rest
    assert sorted(r[1] for r in runs) == sorted(backends.available())
    law = {
        name for scenario, name, physics, tr in runs if _assert_rest_rows_recomputed(df, name, scenario, physics, tr)
    }
    assert law == {"pinocchio", "lagrange"} & set(backends.available())


class _LoadRaises(FakeBackend):
    """A plug-in whose load raises an error of its own (not one of legbench's)."""

    name = "loadraises"

    def load(self, urdf: Path, physics: Physics, settings: Mapping[str, Any]) -> None:
        raise AttributeError("'str' object has no attribute 'get'")


def test_a_backend_that_raises_fails_its_own_rows_and_the_others_are_verified(monkeypatch: pytest.MonkeyPatch) -> None:
    """A plug-in raising in load (or in its run, or an info() verification cannot read) ended verify with a
    traceback, every other backend's rows lost. Now each of its cases is one failed row naming the error, and
    Pinocchio's rows are those of a verify without it."""
    reg = backends._registry
    monkeypatch.setattr(backends, "_registry", lambda: {**reg(), "loadraises": _LoadRaises})
    cases = ["energy", "rest_penetration", "static_balance"]
    df = verify.verify(None, ["pinocchio", "loadraises"], cases, jobs=1)
    bad = df[df["backend"] == "loadraises"]
    assert sorted(bad["case"]) == sorted(cases) and (bad["status"] == "fail").all()
    assert bad["note"].str.contains("AttributeError: 'str' object has no attribute 'get'", regex=False).all()
    alone = verify.verify(None, ["pinocchio"], cases, jobs=1)
    pd.testing.assert_frame_equal(df[df["backend"] == "pinocchio"].reset_index(drop=True), alone)


def test_a_backend_whose_info_breaks_keeps_its_reason_in_verify(monkeypatch: pytest.MonkeyPatch) -> None:
    """A run whose info() breaks the keys legbench reads fails with that reason; verify then read the empty info
    for its variant and reported KeyError: 'integrator_family' instead. The declared abilities are kept and the
    rows name the real reason."""
    original = PinocchioBackend.info

    def info(self: PinocchioBackend) -> dict[str, Any]:
        return {**original(self), "contact": {"poc": "center"}}

    monkeypatch.setattr(PinocchioBackend, "info", info)
    rows = verify._group_checks(("energy", "pinocchio", "matched"))
    assert rows and all(not r.passed for r in rows)
    assert all("contact.poc: expected 'true' or 'centre', got 'center'" in r.note for r in rows), [r.note for r in rows]


@pytest.mark.skipif("mujoco" not in backends.available(), reason="mujoco backend not installed")
def test_an_engine_is_held_to_its_declared_contact_point(monkeypatch: pytest.MonkeyPatch) -> None:
    """MuJoCo's force acts y/2 above the sphere's lowest point, as its info declares (contact.lift 0.5): its static
    balance is checked there without a lever band, 0.054 N (measured 2e-14 N). Checked at the true poc, as before,
    it was 0.10 N off, inside the band of 0.54 N that let any point between the lowest point and the ground pass.
    A backend that declares no point (a plug-in) still gets that band, and the note says so."""

    def undeclared(tr: RunResult) -> RunResult:
        contact = {k: v for k, v in tr.info["contact"].items() if k != "lift"}
        return dataclasses.replace(tr, info={**tr.info, "contact": contact})

    rows = [c for c in verify.check_rest(["mujoco"]) if c.case == "static_balance"]
    assert len(rows) == 3 and all(r.passed for r in rows)
    assert all(r.note.startswith("engine contact at its declared point (0.5 of the penetration") for r in rows)
    assert max(r.tolerance for r in rows) < 0.06 and max(abs(r.measured - r.expected) for r in rows) < 1e-9
    with monkeypatch.context() as m:
        simulate = verify._simulate
        m.setattr(verify, "_simulate", lambda *a: undeclared(simulate(*a)))
        banded = [c for c in verify.check_rest(["mujoco"]) if c.case == "static_balance"]
    assert all("lever term up to" in r.note for r in banded)
    assert max(r.tolerance for r in banded) > 0.4  # [N]: the band, |(J^T)^-1| y |F_t| ~ 0.49 N
    assert max(abs(r.measured - r.expected) for r in banded) > 0.05  # the true poc: MuJoCo's lever is off by y/2


def test_the_small_oscillation_poles_do_not_depend_on_a_tiny_static_offset(monkeypatch: pytest.MonkeyPatch) -> None:
    """The pencil fitted the response about the model's q_eq with exactly the modes it predicts: an engine at rest
    3e-9 rad from q_eq (a 1e-6 relative parameter difference, which the pre-flight allows, moves it 1e-7 rad)
    put a constant into the fit that it could not absorb, and a correct engine's poles missed by 0.53 % (tolerance
    0.5 %). The response's differences have the same poles and no constant: Pinocchio's rows pass, and their poles
    move by less than 1e-6 relative with a 1e-7 rad offset."""

    def offset(tr: RunResult) -> RunResult:
        return dataclasses.replace(tr, q=tr.q + 1e-7)

    plain = verify.check_small_oscillation(["pinocchio"])
    with monkeypatch.context() as m:
        simulate = verify._simulate
        m.setattr(verify, "_simulate", lambda *a: offset(simulate(*a)))
        moved = verify.check_small_oscillation(["pinocchio"])
    assert plain and all(r.passed for r in plain) and all(r.passed for r in moved)
    for a, b in zip(plain, moved, strict=True):
        assert b.measured == pytest.approx(a.measured, rel=1e-6)


@pytest.mark.skipif("ode" not in backends.available(), reason="ode backend not installed")
def test_a_pyramid_engine_without_friction_across_the_drag_fails() -> None:
    """ODE's drag: the pyramid's closed form holds the foot across the drag (W x) with F_x = 0.014 Fn, and ODE
    reads 0.0147 Fn (within 1 % of mu). An engine with no friction along W x at all (F_x = 0) passed every row:
    the old row only bounded |F_x| <= mu Fn, and the W y acceleration moved by 1.6 %, inside 2 %. The row now
    compares F_x with the closed form's and fails it."""
    from legbench.studies import sliding_case

    tr, physics = sliding_case.drag("ode")
    rows = {r["quantity"]: r for r in sliding_case.score(tr, physics)}
    across = rows["friction across the drag F_x / Fn (mean; pyramid)"]
    assert across["passed"] and across["expected"] > 0.01
    f = tr.f.copy()
    f[:, 0] = 0.0
    wrong = {r["quantity"]: r for r in sliding_case.score(dataclasses.replace(tr, f=f), physics)}
    assert not wrong["friction across the drag F_x / Fn (mean; pyramid)"]["passed"]


def test_an_rk4_energy_row_fails_a_step_ten_times_the_declared_one(monkeypatch: pytest.MonkeyPatch) -> None:
    """Pinocchio's RK4 at a real step of 0.5 ms, ten times the 50 us it would declare, drifts 4.9e-11 J. The row
    predicts RK4's drift, h^4 int e5 dt + h^5 (int e6 dt - (e5(t) - e5(0)) / 2), at the declared step and at the
    check's own 0.5 ms: the declared step's run misses its prediction (5e-15 J) by 4.9e-11 J against a tolerance of
    5.4e-13 J, and the check's run, predicted at the 50 us it declares, by the same. At the declared step the honest
    row's error is 2.3e-14 J (round-off) against 5.4e-13 J, and at 0.5 ms 1.3e-14 J against 6.5e-13 J (its drift
    4.92e-11 J predicted to 2.7e-4)."""
    (honest,) = verify.check_energy(["pinocchio"], integrators=["rk4"])
    assert honest.passed and honest.quantity == "E(t_end) - E(0)", honest
    assert honest.error < 5e-14 and honest.tolerance < 6e-13, honest  # the declared step's run: round-off
    assert "check's h = 0.0005 s: max|E - E0| = 4.92e-11 J, predicted 4.92e-11 J" in honest.note, honest.note
    with monkeypatch.context() as m:
        m.setattr(
            verify, "_variants", lambda name, base, integrators, profile: [{**base, "integrator": "rk4", "dt": 5e-4}]
        )
        m.setattr(verify, "_sub_step", lambda info, control_dt: 5e-5)  # what it would declare
        (lying,) = verify.check_energy(["pinocchio"], integrators=["rk4"])
    assert not lying.passed and lying.error > 50 * lying.tolerance, lying


def test_an_rk4_energy_row_fails_a_real_step_twice_the_declared_one(monkeypatch: pytest.MonkeyPatch) -> None:
    """A backend whose RK4 takes steps twice as long as it declares (half the sub-steps its info says), at any
    step asked: at the declared 50 us its drift, 7.7e-14 J against the 5e-15 J predicted, is within the round-off
    bound 5.4e-13 J (RK4's truncation there is below round-off: the former row, (h W)^4 W T max T + round-off =
    1.5e-11 J, passed such a step up to about 7 times the declared one, 3.1e-12 J at 5 times). At the check's own
    step, 0.5 ms (declared; 1 ms real), it drifts 7.8e-10 J against the 4.9e-11 J predicted: error 7.3e-10 J, over
    1000 times the tolerance 6.5e-13 J, and the row, which shows the run furthest beyond its tolerance, fails."""
    simulate = verify._simulate

    def lying(scenario: Any, name: str, physics: Physics, settings: Mapping[str, Any], profile: str) -> RunResult:
        dt = float(settings.get("dt", PinocchioBackend.defaults["dt"]))
        tr = simulate(scenario, name, physics, {**settings, "dt": 2.0 * dt}, profile)
        return dataclasses.replace(tr, info={**tr.info, "dt": dt, "sub_steps": 2 * int(tr.info["sub_steps"])})

    monkeypatch.setattr(verify, "_simulate", lying)
    (row,) = verify.check_energy(["pinocchio"], integrators=["rk4"])
    assert row.variant == "integrator=rk4 dt=5e-05", row
    assert "declared h = 5e-05 s: max|E - E0| = 7.7" in row.note, row.note  # the declared step alone: within
    assert "the row shows the check's step's run" in row.note, row.note
    assert row.measured == pytest.approx(-6.5e-11, rel=0.05) and row.expected == pytest.approx(-2.97e-12, rel=0.01)
    assert not row.passed and row.error > 1000 * row.tolerance, row


@pytest.mark.skipif("ode" not in backends.available(), reason="ode backend not installed")
def test_a_first_order_energy_row_is_the_steps_own_drift_not_a_defect(monkeypatch: pytest.MonkeyPatch) -> None:
    """A first-order family with no closed form (ODE's step in maximal coordinates) was bounded by twice semi-implicit
    Euler's drift, 2.46e-3 J against its own 2.38e-4 J at 50 us: a per-step velocity damping of 2e-8, an error that
    does not vanish with h, drifted 6.3e-4 J and passed. The row is now Richardson's: the same run at h/2 and h/4
    (ODE: 2.384e-4, 1.192e-4, 5.961e-5 J), and the remainder R_h = max|D_h - 2 D_h/2| is the step's own O(h^2):
    1.646e-6 J at h, 4.105e-7 J at h/2, order 2.003 (expected 2 within 0.5). With the damping the drift grows as h
    shrinks and the remainder doubles per halving (order -1.0: fails). At ODE's engine-defaults quick step at 1 ms
    with one row order per step the remainder is 17 % of the drift, order 2.057: a fixed 5 % share of the drift,
    the earlier rule, failed that correct step (the same 15 % with ODE's exact solver at 1 ms). With ODE's own
    advancing row order (engine-defaults since 28 Nov) each step solves its rows in a new random order: the drift
    still halves with h (12.04, 5.937, 2.929 mJ) but its time series is not smooth in h, so the remainder falls as
    h^1.1 and the row fails: the check's premise, a deterministic step, does not hold there."""
    (own,) = verify.check_energy(["ode"])
    assert own.passed and own.quantity == "order of R_h = max|D_h - 2 D_h/2| in h", own
    assert own.measured == pytest.approx(2.0, abs=0.05) and own.error == max(2.0 - own.measured, 0.0), own
    assert "max|E - E0| 0.0002384, 0.0001192, 5.961e-05 J" in own.note, own.note
    assert (verify.REMAINDER_ORDER, verify.REMAINDER_ORDER_TOL) == (2.0, 0.5)
    (shuffled,) = verify.check_energy(["ode"], profile="engine-defaults")
    assert not shuffled.passed and shuffled.measured == pytest.approx(1.11, abs=0.1), shuffled
    assert "max|E - E0| 0.01204, 0.005937, 0.002929 J" in shuffled.note, shuffled.note  # the drift: first order
    variants = verify._variants
    with monkeypatch.context() as m:
        m.setattr(verify, "_variants", lambda name, base, i, p: [{**s, "row_order": "repeated"}
                                                                  for s in variants(name, base, i, p)])  # fmt: skip
        (defaults,) = verify.check_energy(["ode"], profile="engine-defaults")
    assert defaults.passed and defaults.measured == pytest.approx(2.06, abs=0.05), defaults
    assert defaults.error == 0.0  # one-sided: a remainder falling faster than h^2 is no defect
    assert "(17.3 % of the drift at h)" in defaults.note, defaults.note
    monkeypatch.setattr(
        verify, "_variants", lambda name, base, i, p: [{**s, "damping": 2e-8} for s in variants(name, base, i, p)]
    )
    (leaky,) = verify.check_energy(["ode"])
    assert not leaky.passed and leaky.measured == pytest.approx(-1.0, abs=0.1), leaky  # R doubles per halving


def test_the_closed_forms_take_the_scenarios_gravity(tmp_path: Path) -> None:
    """The static balance's expected force took G(q) at the leg file's 9.81 m/s^2 while the tolerance's dynamic
    terms took the scenario's gravity, so at g = 4.905 the whole error of G went into the tolerance and passed:
    0.93 N within 0.93 N (a review's run). Now G is the scenario's: Pinocchio's force meets F = -(J_poc^T)^-1
    (tau - G(q)) to 1e-3 N within a tolerance under 1e-3 N (at 9.81: 5e-5 N within 2e-4 N), and the small
    oscillation's equilibrium and gravity stiffness are the scenario's too (dG/dq halves with g)."""
    rest = tmp_path / "rest_g.yaml"
    rest.write_text(
        verify.REST_SCENARIO.read_text().replace(
            "physics: {contact_mode: native}", "physics: {contact_mode: native, gravity: 4.905}"
        )
    )
    rows = [r for r in verify.check_rest(["pinocchio"], rest) if r.case == "static_balance"]
    assert len(rows) == 3 and all(r.passed for r in rows), rows
    assert max(r.tolerance for r in rows) < 1e-3 and max(r.error for r in rows) < 1e-3, rows
    q = np.array([-0.0025, -1.1899, -1.2599])
    half, full = model.Dynamics(4.905), model.Dynamics(9.81)
    np.testing.assert_allclose(half.gravity(q), 0.5 * full.gravity(q), rtol=1e-12)
    np.testing.assert_allclose(verify.gravity_stiffness(q, leg=half), 0.5 * verify.gravity_stiffness(q, leg=full),
                               rtol=1e-6, atol=1e-9)  # fmt: skip


def test_a_damping_ratio_is_held_to_its_poles_tolerance_and_no_more() -> None:
    """zeta = -cos(arg s): a pole moved by up to rel |s| turns by up to asin(rel) seen from the origin, so zeta
    moves by up to rel sqrt(1 - zeta^2). The row allowed 2 rel (0.01, 3.6 times the bound at zeta 0.83); the
    bound now is the largest change over the disc, checked against a dense sampling of its edge."""
    for zeta, rel in ((0.638, 5e-3), (0.829, 5e-3), (0.1, 0.02)):
        s = complex(-zeta, math.sqrt(1.0 - zeta**2)) * 10.0
        edge = s + rel * abs(s) * np.exp(1j * np.linspace(0.0, 2 * np.pi, 20001))
        worst = float(np.max(np.abs(-edge.real / np.abs(edge) - zeta)))
        tol = verify.damping_tolerance(s, rel)
        assert tol == pytest.approx(worst, rel=1e-6) and tol <= rel * math.sqrt(1 - zeta**2) * 1.01


@pytest.mark.skipif("dart" not in backends.available(), reason="dart backend not installed")
def test_a_rigid_rest_is_held_to_the_engines_own_sink(monkeypatch: pytest.MonkeyPatch) -> None:
    """DART's contact is rigid (info contact.Kp None): its rest row expected y = 0 within 0.1 % of Fn / Kp plus that
    spring's damping, 5.1 um, for a spring DART does not have, 8300 times its sink. Now the row expects the sink
    DART's own regularisation gives, cfm A_nn Fn h^2 / ERP (its class's rest_sink at the window's mean Fn = 51.31 N:
    6.1173e-10 m at 50 us), within 0.1 % of it (6.1e-13 m): measured 6.1173e-10 m, met to 1.5e-15 m (2.5e-6 of it,
    the round-off of the foot's height). A closed form off by 0.5 % fails; a rigid backend that declares none is
    held to y = 0 within RIGID_REST_BOUND, 1 um, which DART's 0.61 nm meets."""
    from legbench.backends.dart_ import DartBackend

    (pen, *_) = verify.check_rest(["dart"])
    assert pen.case == "rest_penetration" and pen.passed, pen
    assert pen.expected == pytest.approx(6.1173e-10, rel=1e-4) and pen.tolerance == pytest.approx(1e-3 * pen.expected)
    assert pen.error < 1e-5 * pen.expected, pen
    assert "sink = cfm A_nn Fn h^2 / ERP" in pen.note, pen.note
    sink = DartBackend.rest_sink
    with monkeypatch.context() as m:
        m.setattr(DartBackend, "rest_sink", classmethod(lambda cls, info, fn: 1.005 * (sink(info, fn) or 0.0)))
        (off, *_) = verify.check_rest(["dart"])
    assert not off.passed and off.error == pytest.approx(5e-3 * pen.expected, rel=1e-3), off
    monkeypatch.setattr(DartBackend, "rest_sink", classmethod(lambda cls, info, fn: None))
    (none, *_) = verify.check_rest(["dart"])
    assert none.passed and (none.expected, none.tolerance) == (0.0, 1e-6), none
    assert none.measured == pytest.approx(pen.measured, rel=1e-12) and "no closed form of its sink" in none.note


@pytest.mark.skipif("pybullet" not in backends.available(), reason="pybullet backend not installed")
def test_an_engines_static_balance_catches_a_force_off_by_two_ten_thousandths(monkeypatch: pytest.MonkeyPatch) -> None:
    """The engines' solver share of the static balance is 1e-5 |F| (5.3e-4 N at |F| = 53 N; measured at most
    1.2e-6 |F|, Drake's 6.1e-5 N; PyBullet's 1.1e-7 N). A ground force read 0.01 N high in z (1.9e-4 |F|, a solver
    200 times worse than Drake's) fails PyBullet's Fz row (its tolerance 5.35e-4 N); at the former 0.1 % |F|
    (0.0535 N) it passed."""
    simulate = verify._simulate

    def offset(scenario: Any, name: str, physics: Physics, settings: Mapping[str, Any], profile: str) -> RunResult:
        tr = simulate(scenario, name, physics, settings, profile)
        return dataclasses.replace(tr, f=tr.f + np.array([0.0, 0.0, 0.01]))

    honest = {c.quantity.split()[0]: c for c in verify.check_rest(["pybullet"]) if c.case == "static_balance"}
    assert all(c.passed and c.error < 1e-6 for c in honest.values()), honest
    assert honest["Fz"].tolerance == pytest.approx(5.35e-4, rel=0.01), honest["Fz"]
    monkeypatch.setattr(verify, "_simulate", offset)
    rows = {c.quantity.split()[0]: c for c in verify.check_rest(["pybullet"]) if c.case == "static_balance"}
    assert not rows["Fz"].passed and rows["Fz"].error == pytest.approx(0.01, rel=1e-3), rows["Fz"]
    assert rows["Fz"].error > 10 * rows["Fz"].tolerance and rows["Fz"].error < 0.2 * 0.0535, rows["Fz"]
