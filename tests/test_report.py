"""Reports on synthetic runs: interactive figures from the tree's one plotly.js, nothing external, failures,
settings, colours and sentences shown; the index grouped by task; parallel rendering identical to serial."""

from __future__ import annotations

import base64
import html
import json
import math
import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest
from fakerun import add_to, base_signals, offset, scale, write_run

from legbench import cli, kinematics, resources, results
from legbench import report as R
from legbench.compare import compare
from legbench.exceptions import ResultsError
from legbench.report_figures import BINS, Arrays, envelope, run_figures
from legbench.report_html import num, num_apart, to_markdown

SCENARIOS = Path(__file__).resolve().parent.parent / "scenarios"
#: 5 overlays (q, qd, tau, force, foot) + 4 deviations + 2 focused views + the 3D leg
N_FIGURES = 12
PLOT = re.compile(r'legbench\.(plot|leg)\("([\w-]+)-plot", ')
DATA = re.compile(r"<script>legbench\.data\((\{.*?\})\);</script>")


def _arrays(page: str) -> dict[str, np.ndarray]:
    """The float32 arrays a page holds, decoded as the browser does."""
    m = DATA.search(page)
    assert m is not None
    return {k: np.frombuffer(base64.b64decode(v), dtype="<f4") for k, v in json.loads(m.group(1)).items()}


def _decode(arrays: Arrays, ref: str) -> np.ndarray:
    return np.frombuffer(base64.b64decode(arrays.items[ref.removeprefix("@")]), dtype="<f4")


def test_report_html_draws_every_figure_from_the_one_plotly_js_and_nothing_external(tmp_path: Path) -> None:
    """report.html loads plotly.js from assets/ (a copy of the plotly package's own file) and calls it once per
    figure; every figure's div exists, its arrays are on the page; no external URL; report.md links each figure."""
    d = write_run(tmp_path / "s", {"ref": None, "a": scale(1.1), "b": offset(0.01)}, skip=0.2)
    files = R.write_report(d)
    assert len(files.figures) == N_FIGURES and files.assets == d / "assets"
    page = files.html.read_text()
    assert '<script src="assets/plotly.min.js"></script><script src="assets/legbench.js"></script>' in page
    import plotly

    shipped = Path(plotly.__file__).parent / "package_data" / "plotly.min.js"
    assert (files.assets / "plotly.min.js").read_bytes() == shipped.read_bytes()
    assert [k for _, k in PLOT.findall(page)] == list(files.figures)
    assert all(f'<div id="{k}-plot" class="lb-plot' in page for k in files.figures)
    refs = set(re.findall(r'"@(a\d+)"', page))
    assert refs and refs <= set(_arrays(page))
    assert not re.search(r'(src|href)="(https?:|//)', page) and "<link" not in page
    md = files.markdown.read_text()
    assert all(f"(report.html#{k})" in md for k in files.figures)
    assert files.metrics == d / "metrics.json" and files.metrics.is_file()


def test_report_shows_failed_backends_with_reason_versions_and_settings_as_a_table(tmp_path: Path) -> None:
    """A failed backend is listed with its reason as a warning; engine and version come from run.json; the
    settings are a table with one row per setting and one column per backend (not a JSON blob)."""
    d = write_run(tmp_path / "s", {"ref": None, "a": None}, failed={"c": "diverged at t = 0.3 s"})
    files = R.write_report(d)
    page, md = files.html.read_text(), files.markdown.read_text()
    for text in (page, md):
        assert "diverged at t = 0.3 s" in text
        assert "fake-ref" in text and "fake-a" in text and "fake-c" in text
        assert '"dt"' not in text.replace("&quot;", '"')
    assert "| setting | ref | a | c |" in md and "| dt [s] | 1e-4 | 1e-4 |  |" in md
    assert "<details><summary>Settings of every backend (1 row)</summary>" in page
    assert "\n**Settings of every backend (1 row)**\n" in md  # the closed line, in bold over its table
    assert '<p class="warn">backend &#x27;c&#x27; failed: diverged at t = 0.3 s</p>' in page


def test_partial_log_of_a_failed_backend_is_plotted_not_measured(tmp_path: Path) -> None:
    """A failed backend whose parquet exists is drawn in the overlays but has no metrics."""
    d = write_run(tmp_path / "s", {"ref": None, "a": offset(0.01), "c": offset(0.5)})
    meta = json.loads((d / "run.json").read_text())
    meta["backends"]["c"].update(status="failed", reason="diverged")
    (d / "run.json").write_text(json.dumps(meta))
    files = R.write_report(d)
    metrics = json.loads(files.metrics.read_text())["metrics"]
    assert {r["backend"] for r in metrics} == {"ref", "a"}
    assert len(files.figures) == N_FIGURES
    assert '"name":"c (failed)"' in files.html.read_text()


def test_a_run_whose_foot_never_touches_gets_no_force_figures_and_says_why(tmp_path: Path) -> None:
    """The position and ellipse tasks: every backend's ground force 0 at every sample drew two figures of flat
    lines at 0; the page says why it has none. One backend's 0.1 N somewhere brings both back."""

    def airborne(t: np.ndarray, x: np.ndarray) -> np.ndarray:
        x[:, 9:12] = 0.0
        return x

    def touches(t: np.ndarray, x: np.ndarray) -> np.ndarray:
        x[:, 9:12] = 0.0
        x[len(t) // 2, 11] = 0.1
        return x

    d = write_run(tmp_path / "air", {"ref": airborne, "a": airborne})
    files = R.write_report(d)
    assert "overlay-force" not in files.figures and "deviation-force" not in files.figures
    assert "overlay-q" in files.figures and "deviation-q" in files.figures
    assert "No figures of the ground force: every backend's is 0 at every sample" in files.markdown.read_text()
    d = write_run(tmp_path / "touch", {"ref": airborne, "a": touches})
    files = R.write_report(d)
    assert "overlay-force" in files.figures and "deviation-force" in files.figures
    assert "No figures of the ground force" not in files.markdown.read_text()


def test_a_signal_missing_everywhere_gets_no_figure_and_stale_pngs_go(tmp_path: Path) -> None:
    """Force NaN in every trace: no force overlay or deviation figure; an old PNG in figures/ is removed."""

    def no_force(t: np.ndarray, x: np.ndarray) -> np.ndarray:
        x[:, 9:12] = np.nan
        return x

    d = write_run(tmp_path / "s", {"ref": no_force, "a": no_force})
    (d / "figures").mkdir()
    (d / "figures" / "stale.png").write_bytes(b"\x89PNG\r\n\x1a\n")
    files = R.write_report(d)
    assert "overlay-force" not in files.figures and "deviation-force" not in files.figures
    assert "overlay-q" in files.figures and "deviation-q" in files.figures
    assert not (d / "figures").exists()


def test_envelope_keeps_a_one_sample_spike_and_the_order_of_extremes() -> None:
    """A 1-sample transient of height 5 in 100 000 samples survives decimation to 2 x 700 points exactly
    (float64 values copied, not averaged), at the time of its bin (within one bin width of the truth)."""
    n, k = 100_000, 61_234
    t = np.arange(n) * 1e-3
    y = np.sin(t)
    y[k] = 5.0
    tt, yy = envelope(t, y, bins=700)
    assert len(tt) == len(yy) <= 1400
    assert yy.max() == 5.0 and yy.min() == y.min()
    width = t[-1] / 700 * 1.01
    assert abs(tt[int(np.argmax(yy))] - t[k]) <= width
    assert np.all(np.diff(tt) >= 0)  # times stay ordered for the line
    short_t, short_y = envelope(t[:1000], y[:1000], bins=700)
    assert short_t is not None and np.array_equal(short_y, y[:1000])  # short series as they are
    y2 = np.column_stack([y, -y])
    y2[5:200, 1] = np.nan  # a gap: ignored inside the bin, not spread
    _, yy2 = envelope(t, y2, bins=700)
    assert yy2[:, 1].min() == -5.0 and np.isfinite(yy2[:, 1]).all()


def test_envelope_draws_each_extreme_at_its_own_sample_time() -> None:
    """100 000 samples into 700 bins of 143: a 1-sample spike of 5 in the middle of its bin is in the envelope as its
    exact (t, value) pair (not at the bin's first or last time), and so is every point: each (t, y) is a sample of the
    series, float64 equal. In a 2-D series each column has its own times (a spike of -7 at another sample in column
    1), ordered within every column."""
    n, k, k1 = 100_000, 61_234, 12_345
    t = np.arange(n) * 1e-3
    y = np.sin(t)
    y[k] = 5.0
    tt, yy = envelope(t, y, bins=700)
    i = int(np.argmax(yy))
    assert (tt[i], yy[i]) == (t[k], 5.0)
    np.testing.assert_array_equal(yy, y[np.searchsorted(t, tt)])  # every point is a sample
    y2 = np.column_stack([y, np.cos(t)])
    y2[k1, 1] = -7.0
    tt2, yy2 = envelope(t, y2, bins=700)
    assert tt2.shape == yy2.shape == (len(tt), 2)
    j = int(np.argmin(yy2[:, 1]))
    assert (tt2[j, 1], yy2[j, 1]) == (t[k1], -7.0)
    for c in range(2):
        np.testing.assert_array_equal(yy2[:, c], y2[np.searchsorted(t, tt2[:, c]), c])
    assert np.all(np.diff(tt2, axis=0) >= 0)
    short_t, _ = envelope(t[:100], y2[:100], bins=700)
    np.testing.assert_array_equal(short_t, np.column_stack([t[:100], t[:100]]))  # short: as it is, per column


def test_deviation_figure_holds_the_largest_deviation_and_the_leg_view_is_the_kinematics(tmp_path: Path) -> None:
    """The deviation figure's data reach each pair's max |x - x_ref| (to float32 rounding, rel 1e-6); the 3D
    view's points are kinematics.chain of the logged q at the slider's times (to float32, 1e-6 m)."""
    spike = add_to("q2", lambda t: 1e-3 * (np.abs(t - 1.2345) < 5e-4))  # one sample, 1 mrad
    d = write_run(tmp_path / "s", {"ref": None, "a": spike}, duration=20.0)
    res = compare(d)
    arrays = Arrays()
    figs = {f.key: f for f in run_figures(res, arrays)}
    dev = figs["deviation-q"].spec["data"]
    q2 = next(tr for tr in dev if tr["yaxis"] == "y2")
    assert np.max(np.abs(_decode(arrays, q2["y"]))) == pytest.approx(res.pairs[0].max_abs[1], rel=1e-6)
    assert len(_decode(arrays, q2["y"])) <= 2 * BINS  # 20 001 samples decimated
    leg = figs["leg"].spec
    times = np.array(leg["times"])
    a = res.traces["a"]
    pts = _decode(arrays, leg["backends"][1]["points"]).reshape(len(times), 5, 3)
    want = kinematics.chain(a.q[np.clip(np.searchsorted(a.t, times), 0, len(a.t) - 1)])
    np.testing.assert_allclose(pts, want, atol=1e-6)
    focus = figs["focus-transients"].spec["data"]
    assert max(float(np.max(np.abs(_decode(arrays, tr["y"])))) for tr in focus if tr["yaxis"] == "y") == (
        pytest.approx(1e-3, rel=1e-6)
    )


def test_report_includes_the_contact_mode_split_when_the_sibling_exists(tmp_path: Path) -> None:
    """A native run with a __reference sibling gets the split tables."""
    write_run(tmp_path / "fake", {"ref": None, "a": offset(0.04)})
    write_run(tmp_path / "fake__reference", {"ref": None, "a": offset(0.01)}, contact_mode="reference")
    md = R.write_report(tmp_path / "fake").markdown.read_text()
    assert "Contact model vs integration (with fake__reference)" in md
    assert "| a | contact | 0.03 |" in md


def test_residual_table_says_what_it_computes_and_the_doc_it_cites_defines_every_row(tmp_path: Path) -> None:
    """The relative-penetration column holds median |y Kp / Fn_spring - 1| (Fn_spring = Fn - Kd max(ydot, 0)) and
    its header says Fn_spring, not Fn; the caption cites docs/metrics.md, which defines every residual_* row compare
    writes (one table row each) and the steady window as the closed interval [t_end - steady_window, t_end]."""
    d = write_run(tmp_path / "s", {"ref": None})
    md = R.write_report(d).markdown.read_text()
    assert r" | median \|y Kp/Fn_spring - 1\| | " in md and "y Kp/Fn -" not in md
    assert "docs/metrics.md, section Contact-law residuals" in md
    doc = (Path(__file__).resolve().parents[1] / "docs" / "metrics.md").read_text()
    written = {m for m in compare(d).frame()["metric"] if m.startswith("residual_")}
    assert len(written) == 12
    section = doc[doc.index("### Contact-law residuals") :]
    assert all(f"| `{m}` |" in section for m in written)
    assert "[t_end - steady_window, t_end]" in doc and "501 ticks" in doc


def test_report_with_an_imported_log_lists_it_as_a_backend(tmp_path: Path) -> None:
    """An imported CSV log appears in the backends table and the deviation tables."""
    d = write_run(tmp_path / "s", {"ref": None})
    log = tmp_path / "bench.csv"
    pd.read_parquet(d / "ref.parquet").to_csv(log, index=False)
    md = R.write_report(d, log=log).markdown.read_text()
    assert "| log:bench | ok |  | imported log |" in md
    assert "| log:bench | ref | 0 | 0 | 0 |" in md


@pytest.mark.parametrize(
    ("value", "digits", "text"),
    [
        (156.0, 3, "156"),
        (1800.0, 3, "1800"),
        (2.41e-13, 3, "2.41e-13"),
        (0.0123, 3, "0.0123"),
        (1e4, 4, "10000"),
        (1.0874, 4, "1.087"),
        (-0.5, 4, "-0.5"),
        (1e6, 4, "1e6"),
        (0.0, 4, "0"),
        (math.nan, 4, "n/a"),
        (None, 4, "n/a"),
        (9.9996, 4, "10"),
        (0.001, 3, "0.001"),
        (-3.5e-4, 3, "-3.5e-4"),
    ],
)
def test_one_number_format(value: float, digits: int, text: str) -> None:
    """Plain decimals from 1e-3 to 1e6, a short exponent outside, never '+03' or trailing zeros."""
    assert num(value, digits) == text


def test_colours_follow_the_scenario_ceiling_else_the_bands() -> None:
    """A ceiling of the scenario (by label, then signal, then default) decides over/within; without one the
    value falls in BANDS: round-off below 1e-8 % (engines computing the same thing differ by at most 7e-10 %), so
    a first-order integrator's 1e-4 % at another step is "close", not round-off."""
    tol = {"max_sim_error_pct": {"q2": 5.0, "q": 15.0}}
    assert R.sim_class(6.0, "q", "2", tol)[0] == "over" and R.sim_class(6.0, "q", "1", tol)[0] == "within"
    assert R.sim_class(16.0, "q", "1", tol)[0] == "over"
    classes = [R.sim_class(v, "tau", "1", tol)[0] for v in (1e-13, 7e-10, 1e-4, 0.5, 5.0, 50.0)]
    assert classes == ["agree", "agree", "close", "close", "differ", "far"]
    assert R.sim_class(math.nan, "q", "1", {})[0] == ""


def test_a_number_held_to_a_bound_is_written_apart_from_it() -> None:
    """A 100.04 % over a 100 % limit read '100' in a red cell, an error of 0.010004 beyond a tolerance of 0.01
    read '0.01': a number compared with a bound gets the digits (up to 12) that set it apart from the bound; one
    equal to its bound, or far from it, keeps the four."""
    assert num_apart(100.04, (100.0,)) == "100.04" and num(100.04) == "100"
    assert num_apart(0.010004, (0.01,)) == "0.010004"
    assert num_apart(0.01, (0.01,)) == "0.01" and num_apart(5.12345, (1.0, 10.0)) == "5.123"
    assert num_apart(1.0 + 1e-15, (1.0,)) == "1"  # beyond 12 digits: the 12-digit form, as near as it can say
    # the fewest digits that part it from the bound, not all 12 (a review: a search that never added a digit
    # passed the examples above, whose 12-digit forms are the same text)
    assert num_apart(100.0412345, (100.0,)) == "100.04" and num_apart(0.0100041234, (0.01,)) == "0.010004"
    assert num_apart(math.nan, (1.0,)) == "n/a" and num_apart(2.0, (math.inf,)) == "2"
    tol = {"max_sim_error_pct": 100.0}
    cls, why, bounds = R.sim_class(100.04, "q", "1", tol)
    assert (cls, bounds) == ("over", (100.0,)) and why.startswith("100.04 % exceeds the scenario's limit 100 %")
    assert R.sim_class(0.99996, "q", "1", {})[1].startswith("0.99996 %: < 1 %")  # the band's edge, 6 digits
    # a limit that needs the digits too (a review: "100.03 % within the scenario's limit 100 %")
    assert R.sim_class(100.03, "q", "1", {"max_sim_error_pct": 100.04})[1] == (
        "100.03 % within the scenario's limit 100.04 %"
    )
    assert R._residual_text(1.01003, "friction_ratio") == "1.01003"  # beyond 1 + 0.01
    assert R._residual_marks(1.01003, "friction_ratio")[0] == "fail"
    assert R._error_cell({"error": 0.010004, "tolerance": 0.01}) == "0.010004"
    assert R._error_cell({"error": 0.0123, "tolerance": 0.01}) == "0.0123"
    assert R._error_cell({"error": "", "tolerance": 0.01}) == ""


def test_the_sentence_names_the_largest_deviation_and_says_why(tmp_path: Path) -> None:
    """Largest simulation error: backend, component, size, time and the reference's peak it is a percentage of
    (tau2 = 2 cos(0.7 w t) peaks at 2 N m at t = 0); in reference contact mode the reason is integration;
    identical backends agree to round-off."""
    d = write_run(tmp_path / "s", {"ref": None, "a": scale(1.05), "b": add_to("tau2", lambda t: 0.5 * (t > 1.5))})
    res = compare(d)
    text = R.sentence(res.to_json(), res.frame())
    assert text.startswith("Largest difference: b's tau2 (joint torque) deviates from ref by up to 0.5 N m")
    best = max(res.pair("b").sim_error_pct)  # type: ignore[union-attr]
    assert f"{num(best, 3)} % of the reference's peak (2 N m)" in text
    assert "; of the other backends, the largest is a's " in text and ", 5 % (" in text
    r = write_run(tmp_path / "r", {"ref": None, "a": scale(1.05)}, contact_mode="reference")
    res_r = compare(r)
    assert "same contact law" in R.sentence(res_r.to_json(), res_r.frame())
    same = compare(write_run(tmp_path / "z", {"ref": None, "a": None}))
    assert R.sentence(same.to_json(), same.frame()).startswith("Every backend agrees with ref to round-off")


def test_index_groups_by_task_links_both_ways_and_tabulates_every_sim_error(tmp_path: Path) -> None:
    """results/latest/report.html: a section per task, its runs grouped by profile and contact mode, one row per
    (run, backend), run names linking to their reports and the reports linking back; failed backends listed."""
    root = tmp_path / "latest"
    write_run(root / "one", {"ref": None, "a": scale(1.1)}, name="one")
    write_run(root / "one__reference", {"ref": None, "a": scale(1.01)}, name="one", contact_mode="reference")
    write_run(root / "two", {"ref": None, "a": scale(1.2), "b": None}, name="two", failed={"c": "no engine"})
    out = R.write_all(root)
    index = out[-1]
    assert isinstance(index, R.IndexFiles)
    page = index.html.read_text()
    assert 'href="one/report.html"' in page and 'href="two/report.html"' in page
    assert '<tr class="group"><th scope="rowgroup" colspan="17">matched profile, reference contact</th></tr>' in page
    md = index.markdown.read_text()
    assert "## one\n" in md and "## two\n" in md
    assert "| [one](one/report.html) | matched | native | a | ref | 10 (small peak) | 10 |" in md
    assert "| [one__reference](one__reference/report.html) | matched | reference | a | ref | 1 (small peak) | 1 |" in md
    assert "| [two](two/report.html) | matched | native | a | ref | 20 (small peak) | 20 |" in md
    assert "| two | c | failed | no engine |" in md
    assert md.count("](two/report.html) |") == 2  # backends a and b
    assert md.index("| [one](one/report.html)") < md.index("| [one__reference]")  # native before reference
    assert "one (matched profile, native contact): Largest difference: a's" in md
    for d in ("one", "one__reference", "two"):
        run_page = (root / d / "report.html").read_text()
        assert '<a href="../report.html">' in run_page
        assert '<script src="../assets/plotly.min.js"></script>' in run_page
    assert [p.relative_to(root).as_posix() for p in root.rglob("plotly.min.js")] == ["assets/plotly.min.js"]


def test_a_run_shares_assets_only_with_the_results_tree_it_is_in(tmp_path: Path) -> None:
    """A run directory beside other runs in a plain folder (or beside another tool's assets/, as in /tmp) keeps
    its own assets/; one inside a results tree (the tree's index and assets/ in its parent) shares the tree's."""
    folder = tmp_path / "runs"
    write_run(folder / "first", {"ref": None, "a": scale(1.01)})
    (folder / "assets").mkdir()
    (folder / "assets" / "plotly.min.js").write_text("someone else's")
    alone = R.write_report(write_run(folder / "second", {"ref": None, "a": scale(1.01)}))
    assert alone.assets == folder / "second" / "assets"
    assert '<script src="assets/plotly.min.js"></script>' in alone.html.read_text()
    assert (folder / "assets" / "plotly.min.js").read_text() == "someone else's"
    tree = tmp_path / "tree"
    write_run(tree / "one", {"ref": None, "a": scale(1.01)})
    R.write_all(tree)
    shared = R.write_report(write_run(tree / "two", {"ref": None, "a": scale(1.02)}))
    assert shared.assets == tree / "assets"
    assert '<script src="../assets/plotly.min.js"></script>' in shared.html.read_text()


def test_index_colours_each_sim_error_against_the_scenario_ceiling(tmp_path: Path) -> None:
    """A scenario's max_sim_error_pct ceiling colours each cell over/within, with the reason on hover."""
    root = tmp_path / "latest"
    write_run(root / "one", {"ref": None, "a": scale(1.2)}, name="one", tolerances={"max_sim_error_pct": {"q": 15}})
    write_run(root / "two", {"ref": None, "a": scale(1.1)}, name="two", tolerances={"max_sim_error_pct": {"q": 15}})
    page = R.write_index(root).html.read_text()
    assert '<td class="over" title="20 % exceeds the scenario&#x27;s limit 15 %; largest deviation ' in page
    assert '<td class="within" title="10 % within the scenario&#x27;s limit 15 %; largest deviation ' in page
    assert '<td class="far" title="20 %: &gt;= 10 %: differs a lot; largest deviation ' in page  # qd: the bands


def test_index_reads_metrics_without_reports(tmp_path: Path) -> None:
    """write_index works from run.json alone (metrics computed in memory), without links to absent reports."""
    root = tmp_path / "latest"
    write_run(root / "one", {"ref": None, "a": scale(1.1)}, name="one")
    md = R.write_index(root).markdown.read_text()
    assert "| one | matched | native | a | ref | 10 (small peak) | 10 |" in md


def test_write_all_in_parallel_writes_the_same_pages_and_reports_progress(tmp_path: Path) -> None:
    """jobs = 2 (a process pool, one page per task) writes byte-identical files to jobs = 1, and the progress
    callback is called once per page written: every run report in order, then the index."""
    pages: dict[int, list[Path]] = {}
    text: dict[int, dict[str, bytes]] = {}
    for jobs in (1, 2):
        root = tmp_path / f"j{jobs}" / "latest"
        for name, k in (("one", 1.1), ("two", 1.2), ("three", 1.3)):
            write_run(root / name, {"ref": None, "a": scale(k)}, name=name)
        pages[jobs] = []
        R.write_all(root, jobs=jobs, progress=pages[jobs].append)
        text[jobs] = {p.relative_to(root).as_posix(): p.read_bytes() for p in sorted(root.rglob("report.*"))}
        text[jobs] |= {p.relative_to(root).as_posix(): p.read_bytes() for p in sorted(root.rglob("metrics.json"))}
        assert [p.relative_to(root).as_posix() for p in pages[jobs]] == [
            "one/report.html",
            "three/report.html",
            "two/report.html",
            "report.html",
        ]
    assert text[1] == text[2] and len(text[1]) == 11


def test_a_log_cannot_be_attached_to_a_whole_tree(tmp_path: Path) -> None:
    """write_all with a log on a tree of scenarios is a ResultsError: a log belongs to one scenario."""
    write_run(tmp_path / "latest" / "one", {"ref": None}, name="one")
    with pytest.raises(ResultsError, match="belongs to one scenario"):
        R.write_all(tmp_path / "latest", log=tmp_path / "x.csv")


def test_index_of_a_missing_or_empty_directory_raises(tmp_path: Path) -> None:
    """A results directory that is missing or holds no run directory is a ResultsError naming it."""
    with pytest.raises(ResultsError, match="no such results directory"):
        R.write_index(tmp_path / "nope")
    with pytest.raises(ResultsError, match="no run directories"):
        R.write_index(tmp_path)


def _check(case: str, ok: bool) -> dict[str, Any]:
    return {
        "case": case,
        "backend": "a",
        "variant": "euler",
        "quantity": "dE",
        "unit": "J",
        "measured": 1e-4,
        "expected": 1e-4,
        "error": 1e-9,
        "tolerance": 1e-6,
        "pass": ok,
    }


def test_index_collapses_verification_and_calibration_to_counts_with_the_tables_on_demand(tmp_path: Path) -> None:
    """The study outputs become a count each (failing checks shown open), the full tables inside <details>;
    report.md keeps every row."""
    root = tmp_path / "results"
    write_run(root / "fake", {"ref": None, "a": scale(1.02)})
    (root / "verification").mkdir()
    checks = [_check("energy", True), _check("rest", True), _check("balance", False)]
    (root / "verification" / "verification.json").write_text(json.dumps({"checks": checks}))
    (root / "calibration").mkdir()
    rows = [
        {
            "backend": "a",
            "Kp": 1e4,
            "k_eff": 9999.0,
            "Kd": 100.0,
            "c_eff": 99.0,
            "mu_s": 0.7,
            "Fn": 40.0,
            "Ft": 13.0,
            "creep": 0.1,
            "creep_law": 0.005,
            "c_tangential": 130.0,
        }
    ]
    (root / "calibration" / "calibration.json").write_text(json.dumps({"rows": rows}))
    R.write_all(root)
    md = (root / "report.md").read_text()
    assert "## Verification against closed-form answers, matched profile: 2 of 3 checks pass" in md
    assert "| energy | a | euler |" in md and "| balance | a | euler |" in md
    assert "## Contact calibration, matched profile: 1 backend measured" in md and "| a | 10000 | 9999 |" in md
    page = (root / "report.html").read_text()
    # each study linked by its files, not its folder (a static host lists no folder; the folder link read as one)
    assert 'href="verification/verification.md"' in page and 'href="calibration/calibration.json"' in page
    assert 'href="verification/"' not in page and 'href="calibration/"' not in page
    # a caption above its table's scroll box, at the page's width (inside the box it was clipped with the table)
    assert '<p class="caption">Failing checks</p>\n<div class="scroll" role="region" tabindex="0" aria-label=' \
           '"Failing checks"><table>' in page and "<caption>" not in page  # fmt: skip
    failing = page.index('<p class="caption">Failing checks</p>')
    details = page.index('<details class="fail"><summary>all 3 checks</summary>')
    assert failing < details and page.count(">energy</th>", 0, details) == 0  # passing rows only on demand
    assert page[failing:details].count('<th scope="row" class="text short">balance</th>') == 1
    assert len(re.findall(r'<td class="text short fail"(?: title="[^"]*")?>NO</td>', page)) == 2
    # the engine-defaults calibration (calibrate-contact --profile engine-defaults) under its own heading, after
    (root / "calibration__engine-defaults").mkdir()
    stiff = [{**rows[0], "k_eff": 1.4e5}]
    (root / "calibration__engine-defaults" / "calibration.json").write_text(json.dumps({"profile": "engine-defaults",
                                                                                       "rows": stiff}))  # fmt: skip
    R.write_all(root)
    md = (root / "report.md").read_text()
    matched = md.index("## Contact calibration, matched profile: 1 backend measured")
    assert md.index("## Contact calibration, engine-defaults profile: 1 backend measured") > matched
    assert "| a | 10000 | 140000 |" in md
    assert len(re.findall(r'<td class="text short pass"(?: title="[^"]*")?>yes</td>', page)) == 2


def test_index_counts_not_applicable_checks_apart_from_failures_and_shows_their_notes(tmp_path: Path) -> None:
    """A check with status not-applicable (no closed form for that engine) is neither a pass nor a failure:
    the count says so, it is absent from "Failing checks", its cell reads n/a, and both the failing and the
    not-applicable rows carry their note (why) in the open tables."""
    root = tmp_path / "results"
    write_run(root / "fake", {"ref": None, "a": scale(1.02)})
    (root / "verification").mkdir()
    checks = [
        {**_check("energy", True), "status": "pass", "note": ""},
        {**_check("sliding", False), "status": "fail", "note": "known: the solver lifts the foot"},
        {**_check("pyramid", False), "status": "not-applicable", "note": "native friction is a pyramid"},
    ]
    (root / "verification" / "verification.json").write_text(json.dumps({"checks": checks}))
    R.write_all(root)
    md = (root / "report.md").read_text()
    heading = (
        "## Verification against closed-form answers, matched profile: 1 of 3 checks pass, 1 fail, 1 not applicable"
    )
    assert heading in md
    failing, na = md.index("*Failing checks*"), md.index("*Not applicable:")
    assert "| sliding | a | euler |" in md[failing:na] and "known: the solver lifts the foot" in md[failing:na]
    assert "pyramid" not in md[failing:na]
    assert "| pyramid | a | euler | dE | J | 1e-4 | 1e-4 | 1e-9 | 1e-6 | n/a | native friction is a pyramid |" in md
    page = (root / "report.html").read_text()
    # the failing table and the full one
    assert len(re.findall(r'<td class="text short fail"(?: title="[^"]*")?>NO</td>', page)) == 2
    assert len(re.findall(r'<td class="text short na"(?: title="[^"]*")?>n/a</td>', page)) == 2
    assert page.count(">n/a</td>") == 2


def test_index_names_a_malformed_study_file(tmp_path: Path) -> None:
    """A verification.json whose rows are not a list of objects is one ResultsError naming the file and key."""
    root = tmp_path / "results"
    write_run(root / "fake", {"ref": None, "a": scale(1.02)})
    (root / "verification").mkdir()
    (root / "verification" / "verification.json").write_text(json.dumps({"checks": {"energy": 1}}))
    with pytest.raises(ResultsError, match=r"verification\.json: 'checks' must be a list of objects"):
        R.write_index(root)
    assert not (root / "report.html").exists()


def test_index_shows_the_benchmark_beside_the_results_root(tmp_path: Path) -> None:
    """results/bench/bench.json (written by legbench bench) becomes the index's Performance table."""
    root = tmp_path / "results" / "latest"
    write_run(root / "fake", {"ref": None, "a": scale(1.02)})
    (tmp_path / "results" / "bench").mkdir()
    stat = {"median": 50.0}
    rec = {
        "task": "effort",
        "backend": "a",
        "status": "ok",
        "full_us_per_tick": stat,
        "engine_us_per_tick": {"median": 46.0},
        "harness_us_per_tick": 4.0,
        "overhead_ratio": {"median": 1.087},
        "rtf_full": 20.0,
        "mem_peak_bytes": 1020,
        "series_bytes": 1000,
        "replay_identical": True,
    }
    doc = {"created": "now", "machine": {"cpus": 2}, "results": [rec]}
    (tmp_path / "results" / "bench" / "bench.json").write_text(json.dumps(doc))
    R.write_all(root)
    md = (root / "report.md").read_text()
    assert "## Performance" in md and "| effort | a | 50 | 46 | 4 | 1.087 | 20 | 1.02 | yes |" in md


def test_index_sets_the_two_profiles_side_by_side(tmp_path: Path) -> None:
    """A task run in both profiles gets one index row per backend with both profiles' numbers, each equal to
    the steady Fn of that profile's own metrics (to the 4 significant digits printed); a run whose joints still
    move in the steady window (metrics.json's steady_qd_max at or over STATIC_QD: MuJoCo's engine-defaults foot
    creeping) says so beside its Fn, as its own page gives no analytic check there (a report review: the index
    showed 59.03 N as a steady force)."""
    argv = [
        "run",
        str(SCENARIOS / "effort.yaml"),
        "--backends",
        "pinocchio,mujoco",
        "--profile",
        "both",
        "--out",
        str(tmp_path),
        "-q",
        "--no-preflight",
        "--set",
        "duration=0.6",
    ]
    assert cli.main(argv) == 0
    md = (tmp_path / "report.md").read_text()
    assert "Profiles side by side" in md
    row = next(line for line in md.splitlines() if line.startswith("| effort | mujoco |"))
    cells = [c.strip() for c in row.strip("|").split("|")]
    for prof, col in (("matched", 4), ("engine-defaults", 5)):
        d = tmp_path / ("effort" if prof == "matched" else "effort__engine-defaults")
        _, df = results.read_metrics(d / "metrics.json")
        fz = df[(df.backend == "mujoco") & (df.metric == "steady_mean") & (df.signal == "force") & (df.joint == "z")]
        assert float(cells[col].split(" (")[0]) == pytest.approx(float(fz["value"].iloc[0]), rel=5e-4)
        speed = results.read_metrics(d / "metrics.json")[0]["backends"]["mujoco"]["steady_qd_max"]
        assert ("(moving: max " in cells[col]) == (speed >= R.STATIC_QD), (prof, speed)  # the last column
        assert (speed >= R.STATIC_QD) == (prof == "engine-defaults"), speed  # matched sticks, defaults creep
    assert "| [effort__engine-defaults](effort__engine-defaults/report.html) | engine-defaults | native |" in md
    # a user's own run of the same task beside them (a README review: it took the effort rows, its Fn for
    # pinocchio's and n/a for mujoco's) is listed in the task's table and left out of the tables across runs
    argv_mine = [*argv[:3], "pinocchio", "--out", str(tmp_path / "myrun"), "-q", "--no-preflight", "--set",
                 "duration=0.6", "--set", "backends.pinocchio.dt=2.5e-5"]  # fmt: skip
    assert cli.main(argv_mine) == 0 and cli.main(["compare", str(tmp_path)]) == 0
    again = (tmp_path / "report.md").read_text()
    assert next(line for line in again.splitlines() if line.startswith("| effort | mujoco |")) == row
    assert "Left out of the tables across runs below: myrun," in again and "varies by task" not in again
    assert "| [myrun](myrun/report.html) | matched | native |" in again


def test_write_page_renders_headings_paragraphs_and_tables(tmp_path: Path) -> None:
    """R.write_page: the public page writer the studies use (Markdown and self-contained HTML, no script)."""
    items: list[R.PageItem] = ["# Title", "A paragraph.", ("caption", ("a", "b"), [["x|y", "1.5"]]), "## Sub"]
    md, page = R.write_page(tmp_path, "p", "T", items)
    text = md.read_text()
    assert text == R.page_markdown(items)
    assert "# Title\n" in text and "## Sub\n" in text and "*caption*" in text and "| x\\|y | 1.5 |" in text
    html_text = page.read_text()
    assert "<h1>Title</h1>" in html_text and '<p class="caption">caption</p>' in html_text
    assert "<td>1.5</td>" in html_text and '<th scope="row" class="text short">x|y</th>' in html_text
    assert "<script" not in html_text


def test_compare_command_renders_a_tree_with_jobs_and_prints_each_page(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`legbench compare TREE --jobs 2` exits 0 and prints each page as it is written, the index last."""
    root = tmp_path / "latest"
    for name in ("one", "two"):
        write_run(root / name, {"ref": None, "a": scale(1.1)}, name=name)
    assert cli.main(["compare", str(root), "--jobs", "2"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines == [f"wrote {root / 'one' / 'report.html'}", f"wrote {root / 'two' / 'report.html'}",
                     f"wrote {root / 'report.html'}"]  # fmt: skip


def test_compare_with_jobs_names_a_worker_s_corrupt_parquet_in_the_same_one_line_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A ResultsError raised in a report worker reaches the parent whole (legbench's errors pickle): --jobs 2
    gives the one line and exit 2 of --jobs 1, not a broken process pool and a traceback."""
    root = tmp_path / "latest"
    for name in ("one", "two"):
        write_run(root / name, {"ref": None, "a": scale(1.1)}, name=name, duration=0.5)
    log = root / "two" / "a.parquet"
    log.write_bytes(log.read_bytes()[: log.stat().st_size // 2])  # cut short, as by a full disk
    errors = []
    for jobs in ("1", "2"):
        assert cli.main(["compare", str(root), "--jobs", jobs]) == 2
        errors.append(capsys.readouterr().err)
    assert errors[0] == errors[1]
    assert errors[0].count("\n") == 1 and "Traceback" not in errors[0]
    assert errors[0].startswith(f"legbench: error: {log}: not a readable parquet file")


def _snapshot(root: Path) -> dict[str, tuple[bytes, int]]:
    """Every file under ``root`` (hidden ones too) with its bytes and mtime [ns]."""
    return {str(p.relative_to(root)): (p.read_bytes(), p.stat().st_mtime_ns) for p in root.rglob("*") if p.is_file()}


def test_compare_on_a_directory_without_run_json_writes_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A directory holding metrics.json and logs but no run.json is taken for a run directory and refused
    (exit 2); the assets (plotly.min.js, legbench.js) used to be written into it before the refusal."""
    d = write_run(tmp_path / "one", {"ref": None, "a": scale(1.1)}, name="one")
    R.write_report(d)
    for p in (d / "run.json", d / "report.md", d / "report.html"):
        p.unlink()
    for p in (d / "assets").iterdir():
        p.unlink()
    (d / "assets").rmdir()
    before = _snapshot(d)
    assert cli.main(["compare", str(d)]) == 2
    assert capsys.readouterr().err == f"legbench: error: {d}: no run.json here: not a legbench run directory\n"
    assert _snapshot(d) == before and not (d / "assets").exists()


@pytest.mark.parametrize("jobs", ["1", "2"])
def test_compare_on_a_tree_with_one_corrupt_run_leaves_every_report_as_it_was(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], jobs: str
) -> None:
    """Read everything first, write after: with 'two' corrupt, 'one' (rendered first) used to get its
    metrics.json and reports rewritten before the error. Now every file of the tree keeps its bytes and
    mtime, no page is announced, and no staged file is left, with one worker or two."""
    root = tmp_path / "latest"
    for name in ("one", "two", "three"):
        write_run(root / name, {"ref": None, "a": scale(1.1)}, name=name, duration=0.5)
    assert cli.main(["compare", str(root)]) == 0
    capsys.readouterr()
    (root / "one" / "a.parquet").touch()  # newer than its metrics: a rerun would rewrite one's report
    log = root / "two" / "a.parquet"
    log.write_bytes(log.read_bytes()[:-100])
    before = _snapshot(root)
    assert cli.main(["compare", str(root), "--jobs", jobs]) == 2
    out, err = capsys.readouterr()
    assert out == "" and err.startswith(f"legbench: error: {log}: not a readable parquet file")
    assert _snapshot(root) == before


def test_an_unreadable_index_input_leaves_the_run_reports_as_they_were(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The index is built (its study files read) before any page is put in place: a malformed
    verification.json is the one-line error and the run reports are not rewritten either."""
    root = tmp_path / "latest"
    write_run(root / "one", {"ref": None, "a": scale(1.1)}, name="one", duration=0.5)
    (root / "verification").mkdir()
    (root / "verification" / "verification.json").write_text('{"checks": 5}')
    before = _snapshot(root)
    assert cli.main(["compare", str(root)]) == 2
    assert "verification.json: 'checks' must be a list of objects" in capsys.readouterr().err
    assert _snapshot(root) == before


def test_a_failure_while_rendering_removes_the_pages_already_rendered(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Pages rendered before a later one fails are staged beside their final names, never put in place,
    and removed: the directory holds what it held before, nothing more."""
    root = tmp_path / "latest"
    for name in ("one", "two"):
        write_run(root / name, {"ref": None, "a": scale(1.1)}, name=name, duration=0.5)
    before = _snapshot(root)
    real = R.run_figures

    def fail_on_two(res: Any, arrays: Arrays) -> Any:
        if res.run.name == "two":
            raise ResultsError(str(res.run.path), "cannot draw")
        return real(res, arrays)

    monkeypatch.setattr(R, "run_figures", fail_on_two)
    with pytest.raises(ResultsError, match="cannot draw"):
        R.write_all(root)
    assert _snapshot(root) == before


def test_index_shows_each_backends_step_and_integrator_per_profile(tmp_path: Path) -> None:
    """From each native run's run.json: the step with its sub-steps per control period (or 'adaptive') and the
    integrator, with the solver where the backend names one, one column pair per profile."""
    root = tmp_path / "tree"
    d = write_run(root / "one", {"ref": None, "a": scale(1.01)}, name="one")
    meta = json.loads((d / "run.json").read_text())
    meta["backends"]["ref"]["info"] |= {"dt": 5e-5, "sub_steps": 20, "integrator": "euler"}
    meta["backends"]["a"]["info"] |= {"dt": 1e-4, "sub_steps": 10, "integrator": "euler", "solver": "sap"}
    (d / "run.json").write_text(json.dumps(meta))
    e = write_run(root / "two", {"ref": None, "a": scale(1.02)}, name="two")
    meta = json.loads((e / "run.json").read_text())
    meta["backends"]["ref"]["info"] |= {"dt": 5e-5, "sub_steps": 20, "integrator": "euler"}
    meta["backends"]["a"]["info"] |= {"dt": None, "sub_steps": 1, "integrator": "rk45"}
    (e / "run.json").write_text(json.dumps(meta))
    md = R.write_index(root).markdown.read_text()
    assert "| backend | step per control tick (matched) | integrator (matched) |" in md
    assert "| ref | 50 us x 20 | euler |" in md
    assert "| a | varies by task | varies by task |" in md  # 100 us x 10 (euler, sap) in one, rk45 in two


def test_two_runs_of_one_scenario_neither_under_its_own_name_are_both_left_out_of_the_tables_across_runs(
    tmp_path: Path,
) -> None:
    """Two runs of the scenario 'fake' (matched, native) as 'a' and 'b', neither named 'fake': no run stands for
    the scenario there, so the step table has no row from them and the index names both, saying why; each keeps
    its row in the task's table."""
    root = tmp_path / "tree"
    for label, k in (("a", 1.01), ("b", 1.02)):
        write_run(root / label, {"ref": None, "a": scale(k)})
    md = R.write_index(root).markdown.read_text()
    assert "Left out of the tables across runs below: a, b, each one of several runs of a scenario" in md
    assert "How each backend integrates" not in md
    assert "| a | matched | native | a | ref |" in md and "| b | matched | native | a | ref |" in md


# --------------------------------------------------------------------------- #
# What the sentences and tables claim, against the numbers they come from


def _metrics(rows: dict[tuple[str, str, str], tuple[float, float, float]],
             peaks: dict[tuple[str, str], float]) -> pd.DataFrame:  # fmt: skip
    """A metrics table against reference ``ref``: (backend, signal, joint) -> (sim_error_pct, max_abs,
    t_max_abs); ``peaks``: (signal, joint) -> ref_peak, written for every backend."""
    out = []
    for (b, s, j), (pct, dev, t) in rows.items():
        out += [(b, "ref", s, j, "sim_error_pct", pct), (b, "ref", s, j, "max_abs", dev)]
        out += [(b, "ref", s, j, "t_max_abs", t)]
    for b in {k[0] for k in rows}:
        out += [(b, "ref", s, j, "ref_peak", p) for (s, j), p in peaks.items()]
    cols = ["backend", "reference", "signal", "joint", "metric", "value"]
    return pd.DataFrame([dict(zip(cols, r, strict=True)) for r in out])


#: The effort task's reference peaks (results/latest/effort, 28 Nov): q1 0.004 rad beside q3's 1.26 rad, qd1
#: 0.0891 rad/s beside qd3's 2.24 rad/s; the other components are a third of their signal's largest or more.
EFFORT_PEAKS = {
    ("q", "1"): 0.00397, ("q", "2"): 1.2037, ("q", "3"): 1.2599,
    ("qd", "1"): 0.0891, ("qd", "2"): 0.9289, ("qd", "3"): 2.2449,
    ("force", "x"): 16.787, ("force", "y"): 24.804, ("force", "z"): 59.257,
}  # fmt: skip


def _next(text: str) -> tuple[str, float]:
    """(``backend's component``, its %) of "of the other backends, the largest is X, Y %"."""
    m = re.search(r"of the other backends, the largest is ([^,]+), ([^ ]+) %", text)
    assert m is not None, text
    return m.group(1), float(m.group(2))


def test_the_headline_leaves_out_components_whose_reference_barely_moves_and_says_so() -> None:
    """The effort task's numbers: ODE's qd1 is 102 % of a 0.0891 rad/s peak (0.0911 rad/s at t = 0.004 s), DART's
    qd3 100.04 % of a 2.24 rad/s peak (2.2458 rad/s at t = 0.007 s). A component whose reference peak is under 10 %
    of its signal's largest is left out of the headline (DART's qd3 leads), the bound on the others is over the
    same components (ODE's 63.8 % fx, named with its 4 digits) and the left-out component's 102 % is still stated
    with its size and time."""
    rows = {
        ("ode", "qd", "1"): (102.213, 0.091062, 0.004),
        ("ode", "force", "x"): (63.815, 10.713, 0.006),
        ("ode", "q", "1"): (37.772, 0.0015, 3.0),
        ("dart", "qd", "3"): (100.0403, 2.24583, 0.007),
        ("dart", "qd", "1"): (99.998, 0.08909, 0.004),
        ("dart", "force", "x"): (64.382, 10.808, 0.006),
        ("mujoco", "force", "x"): (63.765, 10.704, 0.006),
    }
    text = R.sentence({"reference": "ref"}, _metrics(rows, EFFORT_PEAKS))
    assert text.startswith(
        "Largest difference: dart's qd3 (joint velocity) deviates from ref by up to 2.25 rad/s at t = 0.007 s, "
        "100 % of the reference's peak (2.24 rad/s)"
    ), text
    assert _next(text) == ("ode's fx", float(num(63.815)))  # as the run table prints it
    assert "ode's qd1 reaches 102.2 % (0.0911 rad/s at t = 0.004 s)" in text  # the tables' 4 digits
    assert "q1 (0.00397 rad)" in text and "qd1 (0.0891 rad/s)" in text


def test_the_sentence_names_the_largest_of_the_other_backends_as_the_table_prints_it() -> None:
    """results/latest, effort__engine-defaults: "every other backend stays at or below 105.3 %" beside a table
    showing MuJoCo's qd2 as 105.2 (the bound rounded up): it read as a number missing from the table. The sentence now
    names the holder, its component, its percentage in the run table's 4 digits, its size and time: "of the other
    backends, the largest is mujoco's qd2, 105.2 %"."""
    rows = {
        ("dart", "force", "z"): (117.8, 69.8, 0.002),
        ("mujoco", "qd", "2"): (105.24, 0.9776, 0.009),
        ("drake", "qd", "1"): (140.0, 0.125, 0.006),  # a small-peak component: not the next largest
        ("ode", "force", "x"): (51.9, 8.71, 0.006),
    }
    text = R.sentence({"reference": "ref"}, _metrics(rows, EFFORT_PEAKS))
    assert text.startswith("Largest difference: dart's fz"), text
    assert "; of the other backends, the largest is mujoco's qd2, 105.2 % (0.978 rad/s at t = 0.009 s)." in text
    assert _next(text) == ("mujoco's qd2", float(num(105.24)))


def test_backends_that_deviate_as_much_as_the_largest_are_named_with_it() -> None:
    """position__engine-defaults: ODE's tau1 3.964814 %, DART's, Drake's, MuJoCo's and PyBullet's 3.964759 %
    (1.4e-5 apart relative, all at the 1 ms step): the sentence names the four as deviating as much (within 0.1 %)
    instead of naming one of them as the next largest; that is then lagrange's 0.2087 %."""
    rows = {(b, "tau", "1"): (3.964759, 0.046735, 0.001) for b in ("pybullet", "dart", "drake", "mujoco")}
    rows |= {("ode", "tau", "1"): (3.964814, 0.046736, 0.001), ("lagrange", "tau", "1"): (0.2087, 0.00246, 0.001)}
    text = R.sentence({"reference": "ref"}, _metrics(rows, {("tau", "1"): 1.1788}))
    assert text.startswith("Largest difference: ode's tau1 (joint torque)"), text
    assert "dart, drake, mujoco and pybullet deviate as much (within 0.1 % of it)" in text
    assert _next(text) == ("lagrange's tau1", 0.2087)


def test_times_are_quoted_to_the_millisecond_of_the_log(tmp_path: Path) -> None:
    """A 1 kHz log's largest deviation at t = 11.009 s is quoted as 11.009 s (not 11.01 s) in the sentence and in
    the largest-deviation table; a component that never deviates reads 0 there, without a time."""
    spike = add_to("q2", lambda t: 1e-3 * (np.abs(t - 11.009) < 5e-4))
    d = write_run(tmp_path / "s", {"ref": None, "a": spike}, duration=12.0)
    res = compare(d)
    assert "at t = 11.009 s" in R.sentence(res.to_json(), res.frame())
    md = R.write_report(d, res).markdown.read_text()
    table = md[md.index("*Largest deviation |x - x_ref|") :]
    row = next(line for line in table.splitlines() if line.startswith("| a | ref |"))
    assert row.startswith(f"| a | ref | 0 | {num(res.pairs[0].max_abs[1], 3)} @ 11.009 s | 0 |"), row


def test_colour_key_names_each_colour_once() -> None:
    """Each column of the colour key is one colour with its own header (the limit's two were both 'scenario
    limit'); the grey of a held component (and n/a) has its column too: it was not in the key."""
    key = R.colour_key(limits=True)
    assert len(set(key.header)) == len(key.header) == len(key.rows[0]) == 7
    assert key.classes is not None and key.classes[(0, 6)] == "na" and "held" in key.rows[0][6]
    assert R.sim_class(5.0, "q", "1", {"max_sim_error_pct": 5.0})[0] == "within"  # <= limit is within


def test_every_anchor_a_markdown_page_links_to_exists_in_it(tmp_path: Path) -> None:
    """The index's task links (#task-one) and a run page's (#tables, #figures, #leg) land on an anchor in the
    Markdown too, not only in the HTML."""
    root = tmp_path / "latest"
    write_run(root / "one", {"ref": None, "a": scale(1.1)}, name="one")
    R.write_all(root)
    for md in (root / "report.md", root / "one" / "report.md"):
        text = md.read_text()
        anchors = set(re.findall(r"\]\(#([\w-]+)\)", text))
        assert anchors, md
        missing = {a for a in anchors if f'<a id="{a}"></a>' not in text}
        assert not missing, (md, missing)


def test_a_run_page_names_its_profile_and_contact_mode(tmp_path: Path) -> None:
    """The engine-defaults run of a task has the same scenario label as the matched one; its page title, heading
    and figure titles say which profile and contact mode it is."""
    d = write_run(tmp_path / "one__engine-defaults", {"ref": None, "a": scale(1.1)}, name="one")
    meta = json.loads((d / "run.json").read_text())
    meta["scenario"]["profile"] = "engine-defaults"
    (d / "run.json").write_text(json.dumps(meta))
    files = R.write_report(d)
    md, page = files.markdown.read_text(), files.html.read_text()
    assert "# legbench comparison: one (engine-defaults profile, native contact)\n" in md
    assert "<title>legbench: one (engine-defaults profile, native contact)</title>" in page
    assert '"text":"one (engine-defaults profile, native contact): joint angle, every backend"' in page


def test_calibration_table_shows_a_stuck_foot_as_inf_with_units_and_notes(tmp_path: Path) -> None:
    """calibration.json's c_tangential = inf (the foot sticks: MuJoCo, ODE) reads 'inf', not 'n/a' (which the
    table also uses for an unmeasured NaN); every dimensional column names its unit; a row's note (DART: rigid
    contact, no Kp or Kd to match) is shown."""
    root = tmp_path / "results"
    write_run(root / "fake", {"ref": None, "a": scale(1.02)})
    (root / "calibration").mkdir()
    row = {"backend": "a", "Kp": 1e4, "k_eff": 1e4, "Kd": 100.0, "c_eff": math.nan, "mu_s": 0.7, "Fn": 40.0, "Ft": 13.0,
           "creep": 0.0, "jitter": 2e-6, "creep_law": 4.7e-4, "c_tangential": math.inf,
           "note": "rigid contact"}  # fmt: skip
    (root / "calibration" / "calibration.json").write_text(json.dumps({"rows": [row]}))
    R.write_all(root)
    md = (root / "report.md").read_text()
    header = next(line for line in md.splitlines() if line.startswith("| backend | Kp"))
    assert "| c_tangential [N s/m] |" in header and "| k_eff [N/m] |" in header and "| creep [mm/s] |" in header
    assert "| jitter [mm/s] |" in header
    line = next(line for line in md.splitlines() if line.startswith("| a | 10000 |"))
    assert line.endswith("| n/a | 0.7 | 40 | 13 | 0 | 0.002 | 0.47 | inf |  |  | rigid contact |"), line  # mm/s


def test_calibration_rows_not_explained_are_counted_and_marked(tmp_path: Path) -> None:
    """A calibration row off the spec with no explanation (status 'not explained') is counted in its heading and
    its status cell marked as a failure; 'as specified' is marked as a pass; 'explained' neither."""
    root = tmp_path / "results"
    write_run(root / "fake", {"ref": None, "a": scale(1.02)})
    (root / "calibration").mkdir()
    base = {"Kp": 1e4, "k_eff": 1e4, "Kd": 100.0, "c_eff": 100.0, "mu_s": 0.7, "Fn": 40.0, "Ft": 13.0,
            "creep": 4.7e-4, "jitter": 0.0, "creep_law": 4.7e-4, "c_tangential": 2.8e4, "note": ""}  # fmt: skip
    rows = [
        {**base, "backend": "a", "status": "as specified", "against_spec": ""},
        {**base, "backend": "b", "status": "explained", "against_spec": "creep 2x the law's"},
        {**base, "backend": "c", "status": "not explained", "against_spec": "c eff 0.7x Kd: not explained"},
    ]
    (root / "calibration" / "calibration.json").write_text(json.dumps({"rows": rows}))
    R.write_all(root)
    md = (root / "report.md").read_text()
    assert "## Contact calibration, matched profile: 3 backends measured, 1 not explained or failed (c)" in md, md
    assert "| not explained | c eff 0.7x Kd: not explained |" in md
    page = (root / "report.html").read_text()
    assert '<td class="text short fail">not explained</td>' in page
    assert '<td class="text short pass">as specified</td>' in page and '<td class="text short">explained</td>' in page


def test_the_profile_paragraph_names_the_backends_that_keep_their_step(tmp_path: Path) -> None:
    """'engine-defaults' runs the engines at one step per 1 ms period, but not every backend: the reference
    (50 us x 20 in both profiles here) is named as keeping its step and integrator."""
    root = tmp_path / "tree"
    for label, prof, dt, n in (("one", "matched", 5e-5, 20), ("one__engine-defaults", "engine-defaults", 1e-3, 1)):
        d = write_run(root / label, {"ref": None, "a": scale(1.01)}, name="one")
        meta = json.loads((d / "run.json").read_text())
        meta["scenario"]["profile"] = prof
        meta["backends"]["ref"]["info"] |= {"dt": 5e-5, "sub_steps": 20, "integrator": "euler"}
        meta["backends"]["a"]["info"] |= {"dt": dt, "sub_steps": n, "integrator": "euler"}
        (d / "run.json").write_text(json.dumps(meta))
    md = R.write_index(root).markdown.read_text()
    para = next(line for line in md.splitlines() if line.startswith("Native contact. 'matched'"))
    assert "ref keeps the same step and integrator in both profiles" in para, para
    assert "point of contact at the sphere centre" not in para


def test_the_profile_paragraph_says_when_a_backend_moves_its_point_of_contact(tmp_path: Path) -> None:
    """The symbolic model keeps its step and integrator in engine-defaults but takes the lab's centre poc, which
    moves its effort numbers (q error 0.058 -> 1.79 %, Fn 52.53 -> 53.54 N): the paragraph says so."""
    root = tmp_path / "tree"
    for label, prof, poc in (("one", "matched", "true"), ("one__engine-defaults", "engine-defaults", "centre")):
        d = write_run(root / label, {"ref": None, "a": scale(1.01)}, name="one")
        meta = json.loads((d / "run.json").read_text())
        meta["scenario"]["profile"] = prof
        meta["backends"]["ref"]["info"] |= {"dt": 5e-5, "sub_steps": 20, "integrator": "euler",
                                            "contact": {"poc": poc}}  # fmt: skip
        meta["backends"]["a"]["info"] |= {"dt": 5e-5 if prof == "matched" else 1e-3, "integrator": "euler",
                                          "sub_steps": 20 if prof == "matched" else 1}  # fmt: skip
        (d / "run.json").write_text(json.dumps(meta))
    R.write_all(root)  # metrics.json first: the paragraph reads each backend's contact_poc there
    md = (root / "report.md").read_text()
    para = next(line for line in md.splitlines() if line.startswith("Native contact. 'matched'"))
    assert "; ref takes the point of contact at the sphere centre in engine-defaults" in para, para


def test_a_backend_keeps_its_colour_in_every_figure(tmp_path: Path) -> None:
    """An imported log without a force (NaN: a bag without a wrench topic) has no force deviation; the
    backends after it keep their colour there (b was drawn in a's colour in deviation-force)."""

    def no_force(t: np.ndarray, x: np.ndarray) -> np.ndarray:
        x[:, 9:12] = np.nan
        return 1.01 * x

    res = compare(write_run(tmp_path / "s", {"ref": None, "a": no_force, "b": scale(1.02)}))
    figs = {f.key: f for f in run_figures(res, Arrays())}

    def colour(key: str, name: str) -> str:
        return next(tr["line"]["color"] for tr in figs[key].spec["data"] if tr["name"] == name)

    assert colour("deviation-force", "b") == colour("deviation-q", "b") == colour("overlay-q", "b")
    legs = {b["name"]: b["color"] for b in figs["leg"].spec["backends"]}
    assert legs["b"] == colour("overlay-q", "b")


def test_a_rigid_contact_is_not_scored_against_the_spring_it_does_not_have(tmp_path: Path) -> None:
    """A backend whose run.json says its engine contact has no stiffness (DART's LCP: contact.Kp null) reads
    'n/a (rigid)' in the penetration columns, not a 5.13 mm miss of Fn/Kp (the effort page's DART row); the
    same backend with the law applied (reference mode: contact.enabled false) is scored."""
    d = write_run(tmp_path / "s", {"ref": None, "a": scale(1.01)})
    meta = json.loads((d / "run.json").read_text())
    meta["backends"]["a"]["info"]["contact"] = {"enabled": True, "Kp": None, "Kd": None}
    (d / "run.json").write_text(json.dumps(meta))
    md = R.write_report(d).markdown.read_text()
    table = md[md.index("## Contact-law residuals") :]
    row = next(line for line in table.splitlines() if line.startswith("| a |"))
    assert row.split(" | ")[2:4] == ["n/a (rigid)", "n/a (rigid)"], row
    meta["backends"]["a"]["info"]["contact"]["enabled"] = False
    (d / "run.json").write_text(json.dumps(meta))
    md = R.write_report(d).markdown.read_text()
    row = next(line for line in md[md.index("## Contact-law residuals") :].splitlines() if line.startswith("| a |"))
    assert "rigid" not in row


def _set_urdf(d: Path, urdf: str) -> None:
    """Name the leg model of a fake run as run.json does: its URDF's file name."""
    meta = json.loads((d / "run.json").read_text())
    meta["urdf"] = urdf
    (d / "run.json").write_text(json.dumps(meta))


def test_the_leg_view_is_drawn_only_for_a_run_made_with_the_active_model(tmp_path: Path) -> None:
    """The 3D view draws the legs through the active model's kinematics: it is on the page when run.json's urdf is
    the active model's URDF name, and left out, with one sentence saying why and how to get it, when the run used
    another model (a `--model other.yaml` run reported without --model); the pages then say that the analytic
    check and the contact-law residuals used the active model, and the nav's #leg lands on the sentence."""
    d = write_run(tmp_path / "s", {"ref": None, "a": scale(1.01)})
    _set_urdf(d, resources.urdf_target().name)
    files = R.write_report(d)
    assert "leg" in files.figures and "left out" not in files.markdown.read_text()
    _set_urdf(d, "other_leg-0123456789abcdef.urdf")
    files = R.write_report(d)
    assert "leg" not in files.figures and len(files.figures) == N_FIGURES - 1
    assert "leg" not in {f.key for f in run_figures(compare(d), Arrays())}
    md, page = files.markdown.read_text(), files.html.read_text()
    leg = [line for line in md.splitlines() if line.startswith("The 3D leg view is left out")]
    assert len(leg) == 1 and leg[0].count(". ") == 0, leg  # one sentence
    assert f"(run.json: other_leg-0123456789abcdef.urdf) than the active one ({resources.urdf_target().name})" in leg[0]
    command = f"`legbench --model FILE compare {resources.shown(d)}` with FILE the run's parameter file (other_leg.yaml"
    assert command in leg[0]
    assert '<a id="leg"></a>' in md and '<h3 id="leg">3D leg view</h3>' in page and "legbench.leg(" not in page
    used = "The analytic force check and the contact-law residuals on this page (and in metrics.json) used the active"
    assert md.count(used) == 2  # above the steady-state table and the residual table
    assert md.index(used) < md.index("## Contact-law residuals") < md.rindex(used)


def test_a_bundled_model_run_reported_with_another_active_model_says_which_file_to_pass(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The other way round: a run of the bundled leg (run.json urdf leg.urdf) reported while another parameter file
    is active (LEGBENCH_MODEL, --model) has no leg view, and the page names the bundled file as FILE."""
    other = tmp_path / "long_thigh.yaml"
    other.write_text(resources.bundled_model().read_text().replace("L_23: 0.2531", "L_23: 0.26", 1))
    assert other.read_text() != resources.bundled_model().read_text()
    monkeypatch.setenv(resources.CACHE_ENV, str(tmp_path / "cache"))
    monkeypatch.setattr(resources, "_selected", other.resolve())  # what select_model sets, without the env var
    assert resources.urdf_target().name.startswith("long_thigh-")
    d = write_run(tmp_path / "s", {"ref": None, "a": scale(1.01)})
    _set_urdf(d, "leg.urdf")
    files = R.write_report(d)
    md = files.markdown.read_text()
    assert "leg" not in files.figures
    assert f"(run.json: leg.urdf) than the active one ({resources.urdf_target().name})" in md
    assert "with FILE the bundled leg, legbench/data/models/leg.yaml" in md
    assert f"used the active leg model ({resources.urdf_target().name}: " in md


def _still(qd_peak: float) -> Any:
    """Base signals of a leg held still in the steady window, its hip speed oscillating with peak ``qd_peak``."""

    def base(t: np.ndarray) -> np.ndarray:
        x = base_signals(t)
        x[:, 0:3] = (0.05, -1.0, -1.2)
        x[:, 3:6] = 0.0
        x[:, 4] = qd_peak * np.sin(2 * np.pi * 3.0 * t + 0.4)
        return x

    return base


def test_the_analytic_force_check_is_na_where_the_leg_moves_in_the_steady_window(tmp_path: Path) -> None:
    """The check is statics: a backend whose max |qd| over the steady window reaches STATIC_QD (the ellipse's 0.40
    rad/s: -0.1 N printed for a force of 0) gets one n/a row with the reason instead of the check's numbers; a leg
    held still (below it, as the static tasks' 1e-3 rad/s) keeps them."""
    moving = write_run(tmp_path / "moving", {"ref": None, "a": scale(1.01)})
    res = compare(moving)
    files = R.write_report(moving, res)
    md, page = files.markdown.read_text(), files.html.read_text()
    for s in res.steady:
        tr = res.traces[s.backend]
        speed = float(np.abs(tr.qd[tr.t >= s.t0]).max())
        assert speed > 1.0
        row = next(line for line in md.splitlines() if line.startswith(f"| {s.backend} | analytic check"))
        assert row == (
            f"| {s.backend} | analytic check: n/a (the leg moves in the steady window: max \\|qd\\| {num(speed, 3)} "
            f"rad/s, static means below {num(R.STATIC_QD)} rad/s) |  |  |  | n/a | n/a | n/a |"
        )
        assert num(s.analytic_poc[2]) not in row
    assert "measured - analytic" not in md
    assert page.count(' na" title="the leg moves in the steady window: max |qd| ') == 3 * len(res.steady)
    for peak, shown in ((0.5 * R.STATIC_QD, True), (2.0 * R.STATIC_QD, False)):
        d = write_run(tmp_path / f"still-{peak}", {"ref": None, "a": scale(1.01)}, base=_still(peak))
        res = compare(d)
        md = R.write_report(d, res).markdown.read_text()
        rows = [line for line in md.splitlines() if "| analytic check" in line]
        assert len(rows) == 2, rows
        if shown:
            assert all(
                r.startswith(f"| {s.backend} | analytic check, J_poc |") for r, s in zip(rows, res.steady, strict=True)
            )
            assert f"| ref | analytic check, J_poc |  |  |  | {num(res.steady[0].analytic_poc[0])} |" in md
            assert md.count("| measured - analytic (J_poc) |") == 2
        else:
            assert all("analytic check: n/a (the leg moves" in r for r in rows)


def test_a_static_leg_whose_logged_force_departs_from_its_statics_is_marked(tmp_path: Path) -> None:
    """A leg at rest whose logged force is not what holds it (Pinocchio's RK4 above its friction step bound logged
    a force 43 % off its statics, smooth at 1 kHz: nothing in the page said so) gets its residual row's force
    cells marked fail, with the share of |F| in their titles (12 N off a 42.5 N force: 28.2 %); a force that
    satisfies the statics is not marked, nor one 0.5 % off (below STATIC_RESIDUAL, 1 %)."""
    from test_compare import static_base

    h = np.array([3.0, -2.0, -40.0])  # the force the foot exerts on the ground [N]: |F| 40.16 N
    d = write_run(tmp_path / "s", {"ref": None, "near": add_to("fz", lambda t: 0.2 + 0 * t),
                                   "off": add_to("fy", lambda t: 12.0 + 0 * t)}, base=static_base(h))  # fmt: skip
    res = compare(d)
    files = R.write_report(d, res)
    page = files.html.read_text()
    marked = re.findall(r'class="fail" title="the logged force departs from the leg&#x27;s statics by ([0-9.]+) % of '
                        r"\|F\|", page)  # fmt: skip
    assert marked == [num(100 * 12.0 / float(np.linalg.norm(-h + [0.0, 12.0, 0.0])), 3)] * 3, marked  # 28.2 %
    assert page.count("statics by") == 3  # only "off"'s three force cells: not "ref", not "near" (0.5 %)


def test_a_force_acting_above_the_lowest_point_shows_the_spec_s_check_and_the_lever(tmp_path: Path) -> None:
    """A backend that declares its force acting halfway through the penetration (contact.lift 0.5, as MuJoCo) is
    checked at that point, and the spec's check at the lowest point and the lever between the two follow it as
    their own rows (the lever sum: the check at its point is the spec's plus the compensation, to 1e-12 N)."""
    from legbench.model import load_params

    q = kinematics.ik_nearest(np.array([0.1667, 0.0, load_params().geometry.R_foot - 0.005]), np.array([0, -1, -1.2]))
    F = np.array([4.0, -3.0, 50.0])  # ground force on the foot [N], acting y/2 above the lowest point
    tau = kinematics.gravity(q) - kinematics.jacobian_at(q, "true", 0.5).T @ F

    def pressing(t: np.ndarray) -> np.ndarray:
        return np.tile(np.concatenate([q, np.zeros(3), tau, F]), (len(t), 1))

    d = write_run(tmp_path / "lift", {"ref": None}, base=pressing)
    meta = json.loads((d / "run.json").read_text())
    meta["backends"]["ref"]["info"]["contact"] = {"poc": "true", "lift": 0.5}
    (d / "run.json").write_text(json.dumps(meta))
    res = compare(d)
    (s,) = res.steady
    assert s.lift == 0.5 and s.analytic_lowest is not None and s.lift_compensation is not None
    np.testing.assert_allclose(s.analytic_lowest + s.lift_compensation, s.analytic_poc, rtol=0, atol=1e-12)
    md = R.write_report(d, res).markdown.read_text()
    steady = md[md.index("## Steady state") :].split("\n## ")[0]
    rows = [line for line in steady.splitlines() if line.startswith("| ref | ")]
    labels = [r.split(" | ")[1] for r in rows]
    assert labels == [
        "measured (mean over 1.500..2.000 s)",
        "analytic check, J at 0.5 y above the poc",
        "measured - analytic (J at 0.5 y above the poc)",
        "analytic check, J_poc (the spec's: the sphere's lowest point)",
        "lever compensation (J at 0.5 y above the poc - J_poc)",
    ]
    assert f"| {num(s.analytic_lowest[0])} | {num(s.analytic_lowest[1])} | {num(s.analytic_lowest[2])} |" in rows[3]


def test_the_split_says_mostly_only_for_a_clear_ratio(tmp_path: Path) -> None:
    """The contact-mode split's two peaks are taken at their own times: the sentence calls one part 'mostly' the
    cause only when it is at least MOSTLY = 3 times the other (native 5 % off, reference mode 0.01 %: contact
    about 5 %, mostly the contact model); with contact 3 % and integration 2 % it names both."""
    for sub, ref_scale, says in (("clear", 1.0001, "Why: mostly the contact model ("),
                                 ("close", 1.02, "Why: both the contact model and the integration (")):  # fmt: skip
        root = tmp_path / sub
        write_run(root / "s", {"ref": None, "a": scale(1.05)}, name="s")
        write_run(root / "s__reference", {"ref": None, "a": scale(ref_scale)}, name="s", contact_mode="reference")
        res = compare(root / "s")
        assert says in R.sentence(res.to_json(), res.frame()), R.sentence(res.to_json(), res.frame())


def test_the_headline_of_a_run_with_only_the_reference_left_says_so() -> None:
    """Every other backend's log gone or failed, the reference's there: the headline said the reference had no
    data; it now says no other backend has any. A reference without data is still named as such."""
    empty = pd.DataFrame(columns=["backend", "reference", "signal", "joint", "metric", "value"])
    ok = {"reference": "ref", "backends": {"ref": {"status": "ok"}, "a": {"status": "missing"}}}
    assert R.sentence(ok, empty) == "No deviation measured: no backend but the reference 'ref' has data."
    gone = {"reference": "ref", "backends": {"ref": {"status": "missing"}, "a": {"status": "ok"}}}
    assert R.sentence(gone, empty) == "No deviation measured: the reference backend 'ref' has no data."


@pytest.mark.parametrize("page", ["report.md", "report.html"])
def test_the_index_never_replaces_a_page_legbench_did_not_write(page: str, tmp_path: Path) -> None:
    """``legbench compare TREE`` with the user's own report.md (or .html) at TREE's root replaced it by the index:
    refused before anything is written, one ResultsError naming the file, the page as it was and no run's report
    written; legbench's own index there is rewritten (written twice here)."""
    root = tmp_path / "tree"
    write_run(root / "one", {"ref": None, "a": scale(1.01)})
    (root / page).write_text("# my notes\n")
    for write in (R.write_all, R.write_index):
        with pytest.raises(ResultsError) as exc:
            write(root)
        assert str(exc.value) == (f"{root / page}: not an index legbench wrote, and this results tree's index goes "
                                  "there; move it away first")  # fmt: skip
    assert (root / page).read_text() == "# my notes\n" and not (root / "one" / "report.html").exists()
    (root / page).unlink()
    R.write_all(root)
    R.write_all(root)
    assert R.write_index(root).markdown.read_text().startswith("# legbench: comparison summary\n")


def test_a_published_row_shows_its_caveat(tmp_path: Path) -> None:
    """The lab report's Gazebo row of table 10 is, by the report's own account, misreported: the caveat was only a
    comment in the scenario file, and the page showed the row beside legbench's ODE without a word. A published
    row's ``note`` is printed with it; a row without one is unchanged."""
    d = write_run(tmp_path / "fake", {"ref": None, "a": scale(1.01)}, base=_still(0.5 * R.STATIC_QD))
    meta = json.loads((d / "run.json").read_text())
    meta["scenario"].setdefault("comparison", {})["published"] = [
        {"source": "lab, table 10: A", "qd_abs": [1e-4, 2e-4, 3e-4]},
        {"source": "lab, table 10: B", "qd_abs": [2.3e-5, 3.6e-3, 8.6e-3], "note": "the lab says B misreported these"},
    ]
    (d / "run.json").write_text(json.dumps(meta))
    md = R.write_report(d).markdown.read_text()
    assert "| lab, table 10: A | published (\\|qd\\| magnitudes) |" in md
    assert "| lab, table 10: B | published (\\|qd\\| magnitudes); caveat: the lab says B misreported these |" in md


def test_a_component_both_runs_hold_constant_is_not_coloured_as_agreement(tmp_path: Path) -> None:
    """The effort task's tau1 and tau3 sit at their limits in every backend at every sample: 0 % simulation error,
    which the pages coloured "the same to round-off", as if the engines agreed. metrics.json marks such a pair
    component ``held`` (1) and both pages grey it with the reason; a component that only agrees is still green."""

    def clamp(t: np.ndarray, data: np.ndarray) -> np.ndarray:
        out = data.copy()
        out[:, 6] = -7.051408  # tau1 held at its limit
        return out

    d = write_run(tmp_path / "fake", {"ref": clamp, "a": clamp, "b": lambda t, x: clamp(t, x) * 1.0})
    res = compare(d)
    for p in res.pairs:
        assert p.held.tolist() == [i == 6 for i in range(12)]
    files = R.write_report(d, res)
    rows = res.frame()
    held = rows[rows["metric"] == "held"]
    assert set(zip(held["backend"], held["joint"], held["value"], strict=True)) == {("a", "1", 1.0), ("b", "1", 1.0)}
    cell = f'<td class="na" title="{html.escape(R.HELD)}">'
    assert files.html.read_text().count(cell) == 2  # tau1 of a and b
    index = R.write_index(tmp_path)
    assert index.html.read_text().count(cell) == 2
    # the steady section says why the ground force is not the commanded one
    assert "tau1 sits at its torque limit throughout in every backend compared (held)" in files.markdown.read_text()
    # the Markdown has no colour: the cell says it (a bare 0 read as perfect agreement)
    assert files.markdown.read_text().count(" 0 (held) |") == 2 and index.markdown.read_text().count("0 (held)") == 2


def test_a_higher_order_backend_s_free_space_deviation_is_put_on_the_first_order_reference(tmp_path: Path) -> None:
    """Position task: the symbolic model (rk45) "deviates most" from Pinocchio's 50 us semi-implicit Euler by
    0.21 %, while that reference is itself 0.20 % off a converged run and the rk45 run 0.01 %: the headline blamed
    the most accurate backend. Where the foot never touches the ground and the backend that deviates most integrates
    at a higher order than a first-order reference, the sentence says the deviation is mostly the reference's; a
    first-order backend against it gets no such note."""

    def airborne(t: np.ndarray) -> np.ndarray:
        data = base_signals(t)
        data[:, 9:] = 0.0  # no ground force: the foot in the air
        return data

    d = write_run(tmp_path / "fake", {"ref": None, "a": scale(1.01)}, base=airborne)
    meta = json.loads((d / "run.json").read_text())
    meta["scenario"]["contact"] = {"Kp": 1e4, "Kd": 100.0, "mu_s": 0.7, "mu_k": 0.6, "v_th": 1e-3, "poc": "true"}
    for family in ("adaptive", "euler"):
        meta["backends"]["ref"]["info"] = {**meta["backends"]["ref"].get("info", {}), "integrator_family": "euler"}
        meta["backends"]["a"]["info"] = {**meta["backends"]["a"].get("info", {}), "integrator_family": family}
        (d / "run.json").write_text(json.dumps(meta))
        res = compare(d)
        doc = res.to_json()
        assert doc["backends"]["a"]["integrator_family"] == family
        text = R.sentence(doc, res.frame())
        assert text.startswith("Largest difference: a's")
        assert "The foot never touches the ground" in text
        note = "a integrates at a higher order (adaptive) than the first-order reference ref (euler integration): in"
        assert (note in text) == (family == "adaptive"), text


def test_a_higher_order_backend_s_reference_mode_deviation_is_put_on_the_first_order_reference(
    tmp_path: Path,
) -> None:
    """Effort task in reference contact mode: the symbolic model (rk45) deviates from Pinocchio's 50 us Euler by
    1.83 % in fy, while against a converged run (Pinocchio rk45 at rtol 1e-10) the reference misses fy by 0.46 N
    and the symbolic model by 0.026 N: every backend applies the same law there, so the note of the free-space
    case applies (it was given in free space only); in native contact, with each engine's own contact model, it
    does not."""
    for mode, said in (("reference", True), ("native", False)):
        d = write_run(tmp_path / mode, {"ref": None, "a": scale(1.01)}, contact_mode=mode)
        meta = json.loads((d / "run.json").read_text())
        meta["backends"]["ref"]["info"] = {**meta["backends"]["ref"].get("info", {}), "integrator_family": "euler"}
        meta["backends"]["a"]["info"] = {**meta["backends"]["a"].get("info", {}), "integrator_family": "adaptive"}
        (d / "run.json").write_text(json.dumps(meta))
        res = compare(d)
        text = R.sentence(res.to_json(), res.frame())
        note = ("a integrates at a higher order (adaptive) than the first-order reference ref (euler integration): "
                "in reference contact mode, with the same dynamics")  # fmt: skip
        assert (note in text) == said, text


def test_engines_sharing_a_coarser_step_put_their_free_space_deviation_on_the_step(tmp_path: Path) -> None:
    """Position task, engine-defaults: dart, drake, mujoco, ode and pybullet all deviate by 3.965 % in tau1, each
    at its own 1 ms step against the reference's 50 us sub-steps, and the headline named ode for it (a report
    review). Where the backends that deviate most share one fixed step at least twice the reference's, all first
    order, the sentence says the deviation is mostly that step's; metrics.json records each fixed step (control
    period / sub-steps), none for an adaptive solve; a step under twice the reference's, or two steps, get no note."""

    def airborne(t: np.ndarray) -> np.ndarray:
        data = base_signals(t)
        data[:, 9:] = 0.0  # no ground force: the foot in the air
        return data

    cases = (
        ((20, 1, 1), True),
        ((20, 20, 20), False),
        ((20, 1, 2), False),
        ((20, 10, 10), True),
        ((20, 15, 15), False),
    )
    for k, ((n_ref, n_a, n_b), said) in enumerate(cases):
        d = write_run(tmp_path / f"fake{k}", {"ref": None, "a": scale(1.01), "b": scale(1.01)}, base=airborne)
        meta = json.loads((d / "run.json").read_text())
        meta["scenario"]["contact"] = {"Kp": 1e4, "Kd": 100.0, "mu_s": 0.7, "mu_k": 0.6, "v_th": 1e-3, "poc": "true"}
        for name, n_sub, family in (("ref", n_ref, "euler"), ("a", n_a, "euler"), ("b", n_b, "first-order")):
            info = meta["backends"][name].get("info", {})
            meta["backends"][name]["info"] = {**info, "integrator_family": family, "sub_steps": n_sub}
        (d / "run.json").write_text(json.dumps(meta))
        res = compare(d)
        doc = res.to_json()
        assert doc["backends"]["a"]["step"] == pytest.approx(res.run.control_dt / n_a)
        text = R.sentence(doc, res.frame())
        assert "deviate as much" in text, text  # a and b tied
        note = (f"a and b all step at {R.num(res.run.control_dt / n_a, 3)} s against the reference's "
                f"{R.num(res.run.control_dt / 20, 3)} s (first-order integration each): in free space")  # fmt: skip
        assert (note in text) == said, (k, text)
        assert ("coarser step's error" in text) == said, (k, text)
    meta["backends"]["a"]["info"]["integrator_family"] = "adaptive"
    (d / "run.json").write_text(json.dumps(meta))
    assert "step" not in compare(d).to_json()["backends"]["a"]


def test_a_rigid_backend_s_contact_deviation_says_its_contact_has_no_spring(tmp_path: Path) -> None:
    """Effort task: DART's rigid contact leads the headline with qd3 at 100 % (it does not sink, the reference's
    foot sinks into its spring), which read as a failure of DART (a report review). Where the backend that deviates
    most declares its native contact rigid (run.json contact.Kp null), the sentence says so; a compliant one, or
    the same backend in reference contact (the law applied, compliant), gets no such note."""
    for mode, kp, said in (("native", None, True), ("native", 1e4, False), ("reference", None, False)):
        d = write_run(tmp_path / f"{mode}{kp}", {"ref": None, "a": scale(1.5)}, contact_mode=mode)
        meta = json.loads((d / "run.json").read_text())
        meta["backends"]["a"]["info"] = {**meta["backends"]["a"].get("info", {}), "contact": {"Kp": kp, "poc": "true"}}
        (d / "run.json").write_text(json.dumps(meta))
        res = compare(d)
        doc = res.to_json()
        assert doc["backends"]["a"].get("contact_rigid", False) == said
        text = R.sentence(doc, res.frame())
        assert text.startswith("Largest difference: a's"), text
        assert ("a's own contact is rigid (no stiffness: run.json's contact.Kp null)" in text) == said, text


def test_the_index_says_from_when_a_task_s_errors_are_measured(tmp_path: Path) -> None:
    """The ellipse's percentages are over t >= 1 s (its approach left out): its run page said so, the index did
    not. The index table's caption names the scenario's skip where it is not 0, and nothing where it is."""
    write_run(tmp_path / "late", {"ref": None, "a": scale(1.01)}, name="late", skip=0.5)
    write_run(tmp_path / "whole", {"ref": None, "a": scale(1.01)}, name="whole")
    md = R.write_index(tmp_path).markdown.read_text()
    assert "late: simulation error % (backend x signal component; from t = 0.5 s (the scenario's skip))" in md
    assert "whole: simulation error % (backend x signal component)" in md


def test_a_report_whose_assets_cannot_be_written_leaves_nothing_staged(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A full disk while the assets are written (after the pages were rendered into staged files) left
    .metrics.json.out.tmp-PID, .report.md.out.tmp-PID and .report.html.out.tmp-PID in the run directory and the
    tree's root for good: now nothing staged is left, the error goes on up, and the reports already in place stay
    as they were, byte for byte (a run's page and a tree's)."""
    import errno

    tree = tmp_path / "tree"
    d = write_run(tree / "fake", {"ref": None, "a": scale(1.01)})
    R.write_all(tree)
    before = {p: p.read_bytes() for p in sorted(tree.rglob("*")) if p.is_file()}

    def full(directory: Path) -> Path:
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(R, "write_assets", full)
    for write in (lambda: R.write_report(d), lambda: R.write_all(tree)):
        with pytest.raises(OSError, match="No space left"):
            write()
        assert {p: p.read_bytes() for p in sorted(tree.rglob("*")) if p.is_file()} == before


def _profile_entry(profile: str, sims: dict[tuple[str, str], float]) -> Any:
    """An index entry of the effort task in one profile: backend 'a' against 'ref', the effort task's q peaks."""
    peaks = {"1": 0.00397, "2": 1.2037, "3": 1.2599}
    rows = [("a", "ref", "q", j, "sim_error_pct", v) for (_, j), v in sims.items()]
    rows += [("a", "ref", "q", j, "ref_peak", p) for j, p in peaks.items()]
    rows += [("a", "", "force", "z", "steady_mean", 52.5), ("ref", "", "force", "z", "steady_mean", 52.53)]
    df = pd.DataFrame(rows, columns=["backend", "reference", "signal", "joint", "metric", "value"])
    return R._Entry(dir=Path(profile), label=f"effort-{profile}", name="effort", profile=profile, mode="native",
                    meta={"reference": "ref"}, tolerances={}, df=df, has_page=False, infos={})  # fmt: skip


def test_the_profiles_table_leaves_out_the_joints_the_headline_leaves_out_and_names_the_joint() -> None:
    """results/latest: the effort task's q1 (reference peak 0.004 rad, a third of a percent of the knee's 1.26 rad)
    made the profiles' 'max q error %' MuJoCo's 30.7 (matched) and 3759 (engine-defaults), Drake's 32.4 -> 15.2
    (engine-defaults looked better), while the sentences leave q1 out for that reason. The table takes the same
    rule, names the joint its largest is in, and its caption names what it left out."""
    matched = _profile_entry("matched", {("q", "1"): 30.71, ("q", "2"): 0.2437, ("q", "3"): 0.1684})
    defaults = _profile_entry("engine-defaults", {("q", "1"): 3759.4, ("q", "2"): 15.71, ("q", "3"): 13.02})
    md = to_markdown(R._profile_blocks([matched, defaults]))
    assert "| effort | a | 0.244 (q2) | 15.7 (q2) | 52.5 | 52.5 |" in md, md
    assert "30.7" not in md and "3759" not in md
    assert "left out: effort's q1" in md


def _touching_down_at(t0: float) -> Any:
    """Base signals with no ground force before ``t0`` [s]: the foot touches down there."""

    def base(t: np.ndarray) -> np.ndarray:
        data = base_signals(t)
        data[t < t0, 9:] = 0.0
        return data

    return base


def test_a_largest_deviation_in_the_first_ms_of_contact_is_named_as_its_transient(tmp_path: Path) -> None:
    """results/latest, effort: the red fx 63.8 % is a deviation at t = 0.006 s, 5 ms after the foot's first contact
    (the reference's own fx peak, 16.8 N, is there; its steady friction is 5.6 N): nothing said so. metrics.json
    records each backend's first contact (Fn > 0.5 N) and the controller switches; the sentence and each cell's
    hover give the largest deviation's time, and name the touch-down transient where it is within 10 ms of the
    first contact, the onset transient within 10 ms of a switch with the foot in contact (the combined task's push
    at 2 s), and neither elsewhere."""
    spikes = {"a": (0.506, 30.0), "b": (1.004, 20.0), "c": (0.8, 10.0)}

    def spike(c: float, h: float) -> Callable[[np.ndarray], np.ndarray]:
        return lambda t: h * (np.abs(t - c) < 5e-4)

    d = write_run(
        tmp_path / "fake",
        {"ref": None, **{n: add_to("fz", spike(c, h)) for n, (c, h) in spikes.items()}},
        base=_touching_down_at(0.5),
    )
    res = compare(d)
    doc = res.to_json()
    assert doc["backends"]["ref"]["first_contact"] == pytest.approx(0.5, abs=1e-9)
    assert doc["events"] == [{"t": 0.0, "controller": "position"}, {"t": 1.0, "controller": "effort"}]
    text = R.sentence(doc, res.frame())
    assert "a's fz (ground force on the foot (W)) deviates from ref by up to 30 N at t = 0.506 s (touch-down " \
           "transient: 6 ms after the foot's first contact at t = 0.5 s)" in text, text  # fmt: skip
    R.write_report(d, res)
    index = R.write_index(tmp_path).html.read_text()
    cell = r"(?:<td[^>]*>.*?</td>)"  # the fz cell: 11 after backend and vs
    titles = {b: re.search(rf"<td[^>]*>{b}</td><td[^>]*>ref</td>{cell}{{11}}<td[^>]*title=\"([^\"]*)\"", index)
              for b in spikes}  # fmt: skip
    found = {b: html.unescape(m.group(1)) if m else "" for b, m in titles.items()}
    assert found["a"].endswith("largest deviation 30 N at t = 0.506 s (touch-down transient: 6 ms after the foot's "
                               "first contact at t = 0.5 s)"), found  # fmt: skip
    assert found["b"].endswith("largest deviation 20 N at t = 1.004 s (onset transient: 4 ms after the switch to "
                               "effort control at t = 1 s, the foot in contact)"), found  # fmt: skip
    assert found["c"].endswith("largest deviation 10 N at t = 0.8 s"), found


def test_a_component_whose_reference_barely_moves_is_coloured_by_its_deviation_against_the_signals_largest(
    tmp_path: Path,
) -> None:
    """results/latest, effort: q1's 30.7-37.8 % (a deviation of 1-1.5 mrad over a 4 mrad reference peak) was red in
    both tables while the headline leaves it out (SMALL_PEAK). Such a cell reads '30 (small peak)' (the Markdown has
    no colour) and is coloured by the deviation as a % of its signal's largest peak, the hover saying what the
    percentage amounts to: 30 % of a 0.1 rad peak is 0.03 rad, 2.14 % of q3's 1.4 rad (differs); a deviation of
    0.16 rad there, 160 % of its own peak, is 11.4 % of the largest (differs a lot): a real walk of a joint that
    barely moves in the reference (MuJoCo engine-defaults' q1, 0.149 rad) stays red. A component with a full-size
    peak keeps its band, and the colour key's caption explains the mark."""
    root = tmp_path / "tree"
    d = write_run(root / "one", {"ref": None, "a": scale(1.3), "b": scale(2.6)}, name="one")  # q1 0.1, q3 1.4 rad
    R.write_all(root)
    index, page = (root / "report.html").read_text(), (d / "report.html").read_text()
    small = re.compile(r'<td class="differ" title="(small reference peak: 0.1 rad, under 10 % of the largest in its '
                       r'signal \(1.4 rad\): 30 % of it is 0.03 rad;[^"]*2.14 % of the largest: &lt; 10 %: '
                       r'differs[^"]*)">30 \(small peak\)</td>')  # fmt: skip
    walk = re.compile(r'<td class="far" title="small reference peak: 0.1 rad[^"]*: 160 % of it is 0.16 rad;[^"]*'
                      r'11.4 % of the largest: &gt;= 10 %: differs a lot[^"]*">160 \(small peak\)</td>')  # fmt: skip
    for text in (index, page):
        m = small.search(text)
        assert m is not None and "largest deviation 0.03 rad at t = " in m.group(1), text[-3000:]
        assert walk.search(text), text[-3000:]
        assert re.search(r'<td class="far" title="30 %: &gt;= 10 %: differs a lot[^"]*">30</td>', text)  # q2
    assert "| a | ref | 30 (small peak) | 30 |" in (d / "report.md").read_text()
    assert "| 30 (small peak) | 30 |" in (root / "report.md").read_text()
    assert "(small peak)" in R.colour_key().caption and "as a % of the signal's largest peak" in R.colour_key().caption


def _declare(d: Path, infos: dict[str, dict[str, Any]]) -> None:
    """Merge ``infos`` into the run.json info of each named backend of run directory ``d``."""
    meta = json.loads((d / "run.json").read_text())
    for name, info in infos.items():
        meta["backends"][name]["info"] |= info
    (d / "run.json").write_text(json.dumps(meta))


def test_reference_mode_pages_say_the_implicit_friction_step_is_legbench_s_own(tmp_path: Path) -> None:
    """results/latest, effort__reference: MuJoCo, PyBullet, Drake and DART agree to the same 3.78355e-5 %, because in
    reference mode the law's implicit friction step is legbench's code with M^-1 from the reference model
    (contact.ReferenceContact.implicit_generalized; reference_friction: implicit in each run.json). The reference-mode
    page, its index paragraph and the native page's split caption say so, naming the backends that declare it; a
    run where none declares it says nothing of it."""
    root = tmp_path / "tree"
    write_run(root / "one", {"ref": None, "a": offset(0.04), "b": offset(0.02)}, name="one")
    ref = write_run(root / "one__reference", {"ref": None, "a": offset(0.01), "b": offset(0.01)}, name="one",
                    contact_mode="reference")  # fmt: skip
    _declare(ref, {"a": {"reference_friction": "implicit"}, "b": {"reference_friction": "explicit"}})
    R.write_all(root)
    said = (
        "In reference contact mode the contact law, its implicit friction step included, is legbench's own code "
        "(legbench/contact.py), and a (reference_friction: implicit) takes that step's M^-1 and explicit "
        "acceleration from legbench's own model of the leg (the same URDF), not from the engine: agreement in this "
        "mode, even to the same digits, is not independent evidence of the engines' dynamics in contact."
    )
    assert said in (ref / "report.md").read_text()
    assert (root / "report.md").read_text().count(said) == 1  # the reference run's paragraph only
    split = (root / "one" / "report.md").read_text()
    assert f"sample by sample. {said}*" in split and split.count(said) == 1
    _declare(ref, {"a": {"reference_friction": "explicit"}})
    R.write_all(root)
    assert "is legbench's own code" not in (ref / "report.md").read_text() + (root / "report.md").read_text()


def test_the_verification_says_which_profile_it_checks_and_each_row_s_tolerance_basis(tmp_path: Path) -> None:
    """results/latest: "112 of 117 checks pass" did not say that legbench verify loads every backend in the matched
    profile (verify.py: registry.load's profile; the engine-defaults settings are never verified), and a passing
    row's tolerance (6.404e-7 J) came with no word of where it comes from. The heading names the profile
    (verification.json's ``profile``; legbench verify's own where an older file has none), a paragraph says what
    runs, and every row's tolerance and pass cells carry its case's tolerance basis and its own note on hover."""
    root = tmp_path / "results"
    write_run(root / "fake", {"ref": None, "a": scale(1.02)})
    (root / "verification").mkdir()
    checks = [{**_check("energy", True), "note": "euler x20: predicted E(t) - E(0)"}, _check("static_balance", True)]
    basis = {"energy": "how energy's is derived", "static_balance": "how the balance's is derived"}
    doc = {"checks": checks, "tolerance_basis": basis, "scope": "what verify says it runs"}
    (root / "verification" / "verification.json").write_text(json.dumps(doc))
    md = R.write_index(root).markdown.read_text()
    assert "## Verification against closed-form answers, matched profile: 2 of 2 checks pass\n" in md
    assert (
        "legbench verify --profile matched runs every check with each backend's matched settings (what verify says "
        "it runs)" in md
    )
    assert "The engine-defaults profile's settings are not verified in this tree." in md
    # the bases readable without a hover (the Markdown has none): one table under the paragraph
    assert "| energy | how energy's is derived |\n| static_balance | how the balance's is derived |" in md
    page = html.unescape((root / "report.html").read_text())
    energy = 'title="tolerance: how energy\'s is derived; this row: euler x20: predicted E(t) - E(0)">'
    assert page.count(energy) == 2  # tolerance and pass cells of the passing row
    assert page.count('title="tolerance: how the balance\'s is derived">') == 2
    # the engine-defaults verification, in its own folder (legbench verify --profile engine-defaults), is shown
    # after the matched one, under its own heading, and neither then says the other profile is not verified
    (root / "verification__engine-defaults").mkdir()
    failing = [_check("energy", True), _check("rest_penetration", False)]
    (root / "verification__engine-defaults" / "verification.json").write_text(json.dumps({
        "profile": "engine-defaults", "checks": failing}))  # fmt: skip
    md = R.write_index(root).markdown.read_text()
    matched = md.index("## Verification against closed-form answers, matched profile: 2 of 2 checks pass\n")
    defaults = md.index("## Verification against closed-form answers, engine-defaults profile: 1 of 2 checks pass, "
                        "1 fail\n")  # fmt: skip
    assert matched < defaults and "not verified in this tree" not in md
    assert (
        "a check that passes matched and fails here is mostly what the defaults and that usual way cost"
        in (md[defaults:])
    )


def test_a_failing_rows_shared_explanation_is_said_once_in_the_failing_table() -> None:
    """The engine-defaults verification's failing table repeated ODE's 900-character explanation on each of its six
    pole rows (and DART's on three): a row whose note begins with the same explanation as the row above, same
    backend and case, reads "as above" and keeps its own numbers; another backend's or case's row, or a shared
    prefix of a few words, is left whole."""
    known = "known: " + "the quick step leaves the hinges off their axes; " * 4
    records = [
        {"backend": "ode", "case": "small_oscillation", "note": known + "pole -1/s"},
        {"backend": "ode", "case": "small_oscillation", "note": known + "pole -2/s"},
        {"backend": "ode", "case": "small_oscillation", "note": known + "pole -2/s"},
        {"backend": "dart", "case": "small_oscillation", "note": known + "pole -3/s"},
        {"backend": "dart", "case": "small_oscillation", "note": "known: short; pole -4/s"},
    ]
    notes = R._shortened_notes(records, range(len(records)))
    assert notes == [known + "pole -1/s", "as above; pole -2/s", "as above", known + "pole -3/s",
                     "known: short; pole -4/s"]  # fmt: skip


def test_the_index_says_what_the_reference_is_and_rtf_creep_and_integrator_read_alike_everywhere(
    tmp_path: Path,
) -> None:
    """Newcomer gaps in results/latest: the index never said what 'vs pinocchio' is; 'RTF' was not defined; creep
    was m/s in the index's calibration table and mm/s on the run pages; PyBullet's integrator was blank in a run
    page's settings table (its info declares only integrator_family: Bullet has no integrator setting) and 'euler'
    in the index's step table. The index names the reference and its settings and says it is not ground truth, RTF
    is defined where it appears, creep is mm/s, and the integrator reads the same in both tables."""
    root = tmp_path / "tree"
    d = write_run(root / "one", {"ref": None, "a": scale(1.01)}, name="one")
    _declare(d, {"ref": {"dt": 5e-5, "sub_steps": 20, "integrator": "euler", "integrator_family": "euler"},
                 "a": {"dt": 5e-5, "sub_steps": 20, "integrator_family": "euler"}})  # fmt: skip
    R.write_all(root)
    index, page = (root / "report.md").read_text(), (d / "report.md").read_text()
    assert ("The reference ('vs' column) is the backend each scenario names as its comparison.reference, run with its "
            "own settings: ref (euler at 50 us x 20 per 1 ms control tick in the matched profile). It is not ground "
            "truth: 'simulation error' is a difference from it") in index  # fmt: skip
    said = "semi-implicit euler (declared family; no integrator setting)"  # as verification names it
    assert f"| a | 50 us x 20 | {said} |" in index
    assert f"| integrator | euler | {said} |" in page
    assert "| RTF (simulated s per wall s) |" in page and "RTF, the real-time factor: the run's simulated time" in page


def test_the_index_says_what_computes_the_references_dynamics_where_the_backend_declares_it(tmp_path: Path) -> None:
    """A reviewer read 'vs pinocchio' in the index as Pinocchio's code, where the reference runs legbench's compiled
    ABA on Pinocchio's model (the run pages' dynamics column said so, the index did not): the index's reference
    sentence carries the reference's declared ``dynamics``, and says nothing more for an engine's own stepper."""
    root = tmp_path / "tree"
    d = write_run(root / "one", {"ref": None, "a": scale(1.01)}, name="one")
    _declare(d, {"ref": {"dt": 5e-5, "sub_steps": 20, "integrator": "euler", "dynamics": "a compiled ABA"},
                 "a": {"dt": 5e-5, "sub_steps": 20, "integrator": "euler"}})  # fmt: skip
    R.write_all(root)
    index = (root / "report.md").read_text()
    assert "own settings: ref (euler at 50 us x 20 per 1 ms control tick in the matched profile; dynamics: a " \
           "compiled ABA). It is not ground truth" in index  # fmt: skip
    plain = tmp_path / "plain"
    d = write_run(plain / "one", {"ref": None, "a": scale(1.01)}, name="one")
    _declare(d, {"ref": {"dt": 5e-5, "sub_steps": 20, "integrator": "euler"},
                 "a": {"dt": 5e-5, "sub_steps": 20, "integrator": "euler"}})  # fmt: skip
    R.write_all(plain)
    assert "per 1 ms control tick in the matched profile). It is not" in (plain / "report.md").read_text()


def test_the_limit_colours_are_keyed_only_where_a_scenario_sets_a_limit(tmp_path: Path) -> None:
    """results/latest's key listed 'within/exceeds the scenario limit' though no scenario sets max_sim_error_pct, so
    those colours never appear: the key and the paragraph above it name them only where some scenario sets one."""
    root = tmp_path / "tree"
    write_run(root / "one", {"ref": None, "a": scale(1.1)}, name="one")
    md = R.write_index(root).markdown.read_text()
    assert "scenario limit" not in md and "| < 1e-8 % | < 1 % | < 10 % | >= 10 % | grey |" in md
    assert "no scenario here sets its own limit" in md
    write_run(root / "two", {"ref": None, "a": scale(1.1)}, name="two", tolerances={"max_sim_error_pct": {"q": 15}})
    md = R.write_index(root).markdown.read_text()
    assert "| < 1e-8 % | < 1 % | < 10 % | >= 10 % | <= scenario limit | > scenario limit | grey |" in md


def test_a_task_that_never_touches_the_ground_gets_no_contact_mode_split(tmp_path: Path) -> None:
    """results/latest, position and ellipse: "Why: mostly the integration and dynamics (contact-mode split: contact
    0 %, ...)" for tasks whose foot never touches the ground, where the contact part is 0 by construction. The
    sentence says the foot never touches the ground instead, and the page leaves the split tables out; a task in
    contact keeps both."""

    def airborne(t: np.ndarray) -> np.ndarray:
        data = base_signals(t)
        data[:, 9:] = 0.0
        return data

    for base, touches in ((airborne, False), (base_signals, True)):
        root = tmp_path / ("air" if not touches else "ground")
        write_run(root / "fake", {"ref": None, "a": offset(0.04)}, base=base)
        write_run(root / "fake__reference", {"ref": None, "a": offset(0.01)}, contact_mode="reference", base=base)
        res = compare(root / "fake")
        text = R.sentence(res.to_json(), res.frame())
        assert ("contact-mode split" in text) == touches, text
        assert ("The foot never touches the ground" in text) == (not touches), text
        md = R.write_report(root / "fake", res).markdown.read_text()
        assert ("Contact model vs integration" in md) == touches


def test_a_run_without_a_contact_law_keeps_its_contact_mode_split(tmp_path: Path) -> None:
    """The split tables were left out wherever the page found no residual with a contact sample, which includes a
    run whose run.json names no contact law (no residuals at all): the sentence still gave "contact-mode split:
    contact 9.55 %, ..." and the page had no split to read it in. A foot not known to be in the air keeps the split
    (the sentence's rule, residual_n_contact recorded and 0)."""
    root = tmp_path / "nolaw"
    write_run(root / "fake", {"ref": None, "a": offset(0.04)})
    write_run(root / "fake__reference", {"ref": None, "a": offset(0.01)}, contact_mode="reference")
    for label in ("fake", "fake__reference"):
        meta = json.loads((root / label / "run.json").read_text())
        del meta["scenario"]["contact"]
        (root / label / "run.json").write_text(json.dumps(meta))
    res = compare(root / "fake")
    assert not res.residuals and "contact-mode split" in R.sentence(res.to_json(), res.frame())
    assert "Contact model vs integration" in R.write_report(root / "fake", res).markdown.read_text()


def test_a_free_space_engine_defaults_page_says_the_profile_changes_the_step(tmp_path: Path) -> None:
    """results/latest, position__engine-defaults: MuJoCo, PyBullet, Drake and DART all deviate by 3.96 % in tau1,
    and nothing said why: in free space the engine-defaults profile changes their step (1 ms once per tick against
    the reference's 50 us x 20; run.json), not their semi-implicit Euler. The page says so from run.json, naming the
    matched run's step, and names a backend that changes its integrator too; the matched page says nothing of it."""

    def airborne(t: np.ndarray) -> np.ndarray:
        data = base_signals(t)
        data[:, 9:] = 0.0
        return data

    root = tmp_path / "tree"
    fine = {"dt": 5e-5, "sub_steps": 20, "integrator_family": "euler"}
    for label, profile, a, c in (("one", "matched", fine, {**fine, "integrator": "dWorldStep"}),
                                 ("one__engine-defaults", "engine-defaults", {**fine, "dt": 1e-3, "sub_steps": 1},
                                  {"dt": 1e-3, "sub_steps": 1, "integrator_family": "euler",
                                   "integrator": "dWorldQuickStep"})):  # fmt: skip
        d = write_run(root / label, {"ref": None, "a": scale(1.01), "c": scale(1.02)}, name="one", base=airborne)
        meta = json.loads((d / "run.json").read_text())
        meta["scenario"]["profile"] = profile
        (d / "run.json").write_text(json.dumps(meta))
        _declare(d, {"ref": {**fine, "integrator": "euler"}, "a": a, "c": c})
    R.write_all(root)
    md = (root / "one__engine-defaults" / "report.md").read_text()
    assert ("The foot never touches the ground here, so the contact settings act on nothing and the "
            "engine-defaults profile's change that acts here is chiefly the step (settings such as joint limits that "
            "the motion never reaches act on nothing either): a runs the reference's integrator family (euler) at 1 ms "
            "per control tick, against ref's 50 us x 20 (its own step in the matched profile: 50 us x 20), as run.json "
            "records; c changes its integrator too (dWorldStep in the matched profile, dWorldQuickStep here, at "
            "1 ms).") in md, md[:3000]  # fmt: skip
    assert "what the" not in (root / "one" / "report.md").read_text()


def test_contact_residuals_show_what_the_law_expects_and_colour_what_departs_from_it(tmp_path: Path) -> None:
    """results/latest: the residuals table had no expected value and no colour, so ODE's engine-defaults friction at
    171.8 deg to the slip and Drake's 0.76 friction ratio while sliding read like any other number. The table's first
    row gives the expected value and tolerance per column, a cell beyond it is red and one within green (hover: the
    value against it); a friction pyramid (DART's, ODE's contact, as run.json describes it) is held to its own
    bounds, 1 to sqrt(2) in ratio and 45 deg in angle (ODE matched: 1.053 and 23.7 deg pass)."""
    assert R._residual_marks(171.8, "angle_max", "pyramid")[0] == "fail"
    assert R._residual_marks(0.7565, "friction_ratio", "cone")[0] == "fail"
    assert R._residual_marks(1.053, "friction_ratio", "pyramid")[0] == "pass"
    assert R._residual_marks(23.67, "angle_max", "pyramid")[0] == "pass"
    assert R._residual_marks(23.67, "angle_max", "cone")[0] == "fail"
    assert R._residual_marks(0.7403, "penetration_max_mm", "cone")[0] == "fail"  # Drake matched: 0.74 mm
    assert R._residual_marks(0.01375, "penetration_max_mm", "pyramid")[0] == "pass"  # ODE matched
    assert R._residual_marks(math.nan, "angle_max", "cone") == ("", "")
    # a diamond (|F_t1| + |F_t2| <= mu Fn) slides at 1/sqrt(2) to 1 of mu Fn: 0.869 passes, 1.2 (a pyramid's) fails
    assert R._residual_marks(0.869, "friction_ratio", "diamond")[0] == "pass"
    assert R._residual_marks(1.2, "friction_ratio", "diamond")[0] == "fail"
    assert R._residual_marks(1.2, "friction_ratio", "pyramid")[0] == "pass"
    ode_said = {"contact": {"friction": "pyramid (dContactApprox1: bound mu x normal force per tangent)"}}
    assert R.friction_shape(ode_said) == "pyramid"
    assert R.friction_shape({"friction_cone": "diamond", "contact": {"friction": "pyramid"}}) == "diamond"
    assert R.friction_shape({"contact": {"cone": "mjCONE_ELLIPTIC"}}) == "cone"
    d = write_run(tmp_path / "one", {"ref": None, "a": scale(1.01)})
    _declare(d, {"a": {"contact": {"friction": "pyramid (bound mu x normal force per tangent direction)"}}})
    md = R.write_report(d).markdown.read_text()
    assert ("| expected (tolerance) |  | 0 ± 0.05 mm | 0 ± 0.01 |  | 1 ± 0.01 (pyramid: 1 to 1.414 ± 0.01) "
            "| 0 ± 10 (pyramid: <= 45 + 10) |  | the law's creep |  |") in md  # fmt: skip
    assert "\n| a (pyramid) | " in md and "\n| ref | " in md
    page = (d / "report.html").read_text()
    assert re.search(r'<td class="(pass|fail)" title="[^"]*(within the tolerance|departs from)', page)


def test_in_reference_mode_every_backend_is_scored_against_the_law_s_kinetic_friction(tmp_path: Path) -> None:
    """results/latest, effort__reference: MuJoCo, PyBullet, Drake, DART and ODE read a friction ratio of 0.857
    (= mu_k / mu_s) while sliding, because the ratio took the coefficient each engine's own contact slides with
    (mu_s) though in reference mode each applies the law, which slides at mu_k. In reference mode every backend's
    ratio is now against mu_k, as the law's; in native mode a Coulomb engine's is still against mu_s."""
    ratios = {}
    for mode in ("native", "reference"):
        d = write_run(tmp_path / mode, {"ref": None, "a": None}, contact_mode=mode)
        _declare(d, {"a": {"sliding_coefficient": "mu_s"}, "ref": {"sliding_coefficient": "mu_k"}})
        res = compare(d)
        ratios[mode] = res.residuals["a"].friction_ratio / res.residuals["ref"].friction_ratio
    assert ratios["native"] == pytest.approx(0.6 / 0.7, rel=1e-12)
    assert ratios["reference"] == pytest.approx(1.0, rel=1e-12)


def test_the_residuals_expected_row_names_only_the_shapes_on_the_page_and_their_bounds_with_the_tolerance(
    tmp_path: Path,
) -> None:
    """results/latest, every run page: the expected row read '1 +- 0.01 (pyramid: 1 to 1.41; diamond: 0.707 to 1)'
    and '0 +- 10 (pyramid: <= 45; diamond: <= 45)' on pages where no backend is a diamond (all of them) or a
    pyramid (every reference-mode page), and a pyramid's angle passed up to 55 deg (its 45 plus the tolerance)
    while the row and the hover ('within the tolerance 10 of a friction pyramid's own bound: <= 45 deg') said 45.
    The row lists only the shapes of the page's rows, each bound with the tolerance it is widened by, and the hover
    says the same."""
    d = write_run(tmp_path / "cone", {"ref": None, "a": scale(1.01)})
    md = R.write_report(d).markdown.read_text()
    expected = "| expected (tolerance) |  | 0 ± 0.05 mm | 0 ± 0.01 |  | 1 ± 0.01 | 0 ± 10 |  | the law's creep |  |"
    assert expected in md
    assert "diamond" not in md.split("| expected (tolerance) |")[1].split("\n")[0]
    assert R._residual_marks(50.0, "angle_max", "pyramid") == (
        "pass",
        "50: within a friction pyramid's own bound, <= 45 deg, + the tolerance 10",
    )
    assert R._residual_marks(0.7525, "friction_ratio", "pyramid") == (
        "fail",
        "0.7525: beyond a friction pyramid's own bounds, 1 to 1.414, ± the tolerance 0.01",
    )


def test_the_failing_checks_carry_the_tolerance_basis_the_paragraph_promises(tmp_path: Path) -> None:
    """results/latest: the verification paragraph says 'Hover a row's tolerance or pass cell for how its tolerance
    is derived', but the 'Failing checks' table, the one a reader opens first, had no hover at all (only the table
    of all checks, collapsed, had). Its tolerance and pass cells now carry the case's basis (the row's note is in
    its own column there)."""
    root = tmp_path / "results"
    write_run(root / "fake", {"ref": None, "a": scale(1.02)})
    (root / "verification").mkdir()
    checks = [{**_check("sliding", False), "note": "known: why it misses"}, _check("energy", True)]
    doc = {"checks": checks, "tolerance_basis": {"sliding": "how sliding's is derived"}}
    (root / "verification" / "verification.json").write_text(json.dumps(doc))
    R.write_index(root)
    page = html.unescape((root / "report.html").read_text())
    failing = page.split('<p class="caption">Failing checks</p>')[1].split("</table>")[0]
    assert failing.count('title="tolerance: how sliding\'s is derived">') == 2


def test_a_task_that_starts_on_the_ground_has_its_push_onset_not_a_touch_down() -> None:
    """results/latest, effort: the push starts at t = 0 with the foot at the surface (Fn 0 at t = 0, 21.3 N at the
    next tick), and its largest force deviation at 0.006 s was called a "touch-down transient: 5 ms after the
    foot's first contact", where the combined task's push, the same physics, is an onset. A first contact within
    one control tick of a switch is that switch's onset; a touch-down later in an event stays a touch-down, and a
    metrics.json without control_dt (an older legbench) says what it said."""
    meta = {"reference": "ref", "control_dt": 1e-3, "events": [{"t": 0.0, "controller": "effort"}],
            "backends": {"ref": {"first_contact": 0.001}, "a": {"first_contact": 0.001}}}  # fmt: skip
    assert R.transient(meta, "a", 0.006) == ("onset transient: 6 ms after the switch to effort control at t = 0 s, "
                                             "the foot in contact from its next tick")  # fmt: skip
    late = {**meta, "backends": {"ref": {"first_contact": 0.139}, "a": {"first_contact": 0.139}}}
    assert R.transient(late, "a", 0.144) == "touch-down transient: 5 ms after the foot's first contact at t = 0.139 s"
    older = {k: v for k, v in meta.items() if k != "control_dt"}
    assert R.transient(older, "a", 0.006) == "touch-down transient: 5 ms after the foot's first contact at t = 0.001 s"


def test_every_run_page_of_a_scenario_is_titled_by_the_scenario_and_its_figures_keep_each_traces_time(
    tmp_path: Path,
) -> None:
    """A review found the reference-contact page titled "fake__reference (matched profile, reference contact)"
    beside the engine-defaults page's "fake (engine-defaults profile, native contact)": both name the scenario
    now. The figures' shared hover shows each trace's value with its own sample time (the display envelopes sample
    each trace at its own times), and six non-reference backends get six line styles."""
    d = write_run(tmp_path / "fake__reference", {"ref": None, "a": scale(1.02)}, contact_mode="reference")
    R.write_report(d)
    page = (d / "report.html").read_text()
    assert "<h1>legbench comparison: fake (matched profile, reference contact)</h1>" in page
    assert "fake__reference (" not in page
    assert '"hovertemplate":"%{y:.6g} at t = %{x:.4f} s"' in page
    from legbench import report_figures

    assert len(set(report_figures._DASHES)) >= 6


def test_a_run_page_links_the_same_scenarios_other_runs_in_its_tree(tmp_path: Path) -> None:
    """A reader on one run's page had to go back to the index to reach the same scenario's other contact mode or
    profile: the page's navigation links each of them, named by profile and mode (another scenario's runs and a
    run directory of another scenario's name sharing the prefix are not linked)."""
    root = tmp_path / "tree"
    write_run(root / "fake", {"ref": None, "a": scale(1.02)})
    write_run(root / "fake__reference", {"ref": None, "a": scale(1.01)}, contact_mode="reference")
    write_run(root / "other", {"ref": None, "a": scale(1.03)}, name="other")
    R.write_all(root)
    page = (root / "fake" / "report.html").read_text()
    assert '<a href="../fake__reference/report.html">matched, reference</a>' in page
    assert "../other/report.html" not in page and "../fake/report.html" not in page
    assert '<a href="../fake/report.html">matched, native</a>' in (root / "fake__reference" / "report.html").read_text()
    assert "[matched, reference](../fake__reference/report.md)" in (root / "fake" / "report.md").read_text()
    assert "matched, " not in (root / "other" / "report.html").read_text().split("<h1>")[0]


def test_an_infinite_number_reads_n_a() -> None:
    """num writes +-inf as it writes NaN, "n/a" (with any number of digits), and num_apart too: an infinite value
    in a table does not stop the report (a check for NaN alone would split "inf" at its "e" and raise ValueError).
    A mutation audit found that only NaN was tested."""
    for x in (math.inf, -math.inf):
        assert num(x) == "n/a" and num(x, 3) == "n/a"
        assert num_apart(x, (1.0,)) == "n/a"


def test_a_number_equal_to_its_bound_keeps_its_four_digits() -> None:
    """num_apart adds digits only to set a number apart from a bound it differs from; a number equal to its bound
    (1/3 against 1/3, 2/3 against 2/3 and 100.04) is written with the four digits, "0.3333" and "0.6667", not the 12
    digits of a search that could never tell it from itself. A mutation audit found that the existing case, 0.01
    against 0.01, reads "0.01" at any number of digits."""
    assert num_apart(1 / 3, (1 / 3,)) == "0.3333"
    assert num_apart(2 / 3, (100.04, 2 / 3)) == "0.6667"


def test_the_scenario_table_shows_the_scenario_as_run_with_its_overrides(tmp_path: Path) -> None:
    """A run with `--set gains.Kp=20` and the push's force set to -50 N: the run page's Scenario table gives the
    gains, the initial state and each event's force as run (a provenance review: it showed the file's -100 N and
    no gains), and names the hash as the scenario's as run, not the file's."""
    out = tmp_path / "r"
    argv = ["run", str(SCENARIOS / "effort.yaml"), "--backends", "pinocchio", "--out", str(out), "-q",
            "--no-preflight", "--set", "duration=0.05", "--set", "comparison.steady_window=0.02", "--set",
            "gains.Kp=20", "--set", "events.0.effort.force=[0, 0, -50]"]  # fmt: skip
    assert cli.main(argv) == 0
    rows = dict(line.strip("|").split("|")[:2] for line in (out / "report.md").read_text().splitlines()
                if line.startswith("| ") and line.count("|") == 3)  # fmt: skip
    rows = {k.strip(): v.strip() for k, v in rows.items()}
    assert rows["gains Kp [N m/rad]"] == "20, 20, 20" and rows["gains Kd [N m s/rad]"] == "1, 1, 1"
    assert rows["events"] == "effort @ 0 s: force [0, 0, -50]"
    assert rows["initial q [rad]"] == "-0.0025, -1.19, -1.26"
    sha = json.loads((out / "run.json").read_text())["scenario"]["sha256"]
    assert rows["scenario as run, sha256"].startswith(f"{sha[:12]} (run.json's scenario.raw")


def test_the_page_says_which_coulomb_engines_slide_with_another_coefficient_than_the_reference() -> None:
    """A Coulomb engine has one coefficient (its friction_coefficient setting) and slides with it, the law with
    mu_k: in a native run on the ground that is the onset's friction difference, and the page names the engines
    that slide with another coefficient than the reference, not one that slides with the same, nor one without the
    setting (it has no choice to make)."""
    infos = {"ref": {"sliding_coefficient": "mu_k"},
             "a": {"sliding_coefficient": "mu_s", "friction_coefficient": "mu_s"},
             "b": {"sliding_coefficient": "mu_k", "friction_coefficient": "mu_k"},
             "c": {"sliding_coefficient": "mu_s"},
             "d": {"sliding_coefficient": "mu_s", "friction_coefficient": "mu_s"}}  # fmt: skip
    note = R.coefficient_note(infos, "ref")
    assert note.startswith("a and d slide with mu_s (friction_coefficient: one Coulomb coefficient), where ref "
                           "slides with mu_k: wherever both feet slide (an onset, a push) their friction differs by "
                           "|mu_s - mu_k| Fn, which can be most of a contact task's onset force "
                           "difference"), note  # fmt: skip
    assert R.coefficient_note({**infos, "a": infos["b"], "d": infos["b"]}, "ref") == ""
    assert R.coefficient_note(infos, "missing") == ""


def test_a_native_page_on_the_ground_carries_the_coefficient_note(tmp_path: Path) -> None:
    """The note is on a native run's page where a foot touches the ground, and not on its reference-mode twin
    (there every backend applies the law)."""
    root = tmp_path / "tree"
    for label, mode in (("fake", "native"), ("fake__reference", "reference")):
        d = write_run(root / label, {"ref": None, "a": scale(1.01)}, contact_mode=mode)
        meta = json.loads((d / "run.json").read_text())
        meta["backends"]["ref"]["info"]["sliding_coefficient"] = "mu_k"
        meta["backends"]["a"]["info"] |= {"sliding_coefficient": "mu_s", "friction_coefficient": "mu_s"}
        (d / "run.json").write_text(json.dumps(meta))
    res = compare(root / "fake")
    assert R._touches(res.frame())
    assert "a slides with mu_s (friction_coefficient" in R.write_report(root / "fake", res).markdown.read_text()
    # and in the index, beside the run's sentence (a reader of the index alone missed it)
    assert "fake (matched profile, native contact): " in (index := R.write_index(root).markdown.read_text())
    assert "a slides with mu_s (friction_coefficient" in index, index
    ref_md = R.write_report(root / "fake__reference", compare(root / "fake__reference")).markdown.read_text()
    assert "friction_coefficient: one Coulomb coefficient" not in ref_md


def test_the_index_says_which_legbench_commits_made_the_tree(tmp_path: Path) -> None:
    """A reviewer read results/latest built 41 commits behind its checkout, with nothing on the page to say so: the
    index names the commit that made every run and study, and where they differ, each commit with what it made, as a
    warning (a tree mixing commits compares the results of different code)."""
    root = tmp_path / "tree"
    for label in ("one", "two"):
        write_run(root / label, {"ref": None, "a": scale(1.01)}, name=label)

    def stamp(label: str, commit: str | None) -> None:
        meta = json.loads((root / label / "run.json").read_text())
        meta["versions"] = {k: v for k, v in meta.get("versions", {}).items() if k != "legbench_commit"}
        if commit is not None:
            meta["versions"]["legbench_commit"] = commit
        (root / label / "run.json").write_text(json.dumps(meta))

    stamp("one", "a" * 40)
    stamp("two", "a" * 40)
    md = R.write_index(root).markdown.read_text()
    assert f"Made by legbench commit {'a' * 12}: every run and study this index lists." in md, md
    stamp("two", "b" * 40 + " (uncommitted changes)")
    (root / "verification").mkdir()
    (root / "verification" / "verification.json").write_text(json.dumps({"checks": [], "versions": {}}))
    md = R.write_index(root).markdown.read_text()
    assert (f"Made by 3 legbench versions, so its tables compare the results of different code: commit {'a' * 12}: "
            f"one; commit {'b' * 12} (uncommitted changes): two; of no recorded commit: verification. `make compare` "
            "remakes the tree at one.") in md, md  # fmt: skip
