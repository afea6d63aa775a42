"""Reports on synthetic runs: every figure embedded, nothing external, failures and settings shown."""

from __future__ import annotations

import base64
import json
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from fakerun import offset, scale, write_run

from legbench import cli, results
from legbench import report as R
from legbench.exceptions import ResultsError

IMG = re.compile(r'<img src="data:image/png;base64,([A-Za-z0-9+/=]+)"')
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"

SCENARIOS = Path(__file__).resolve().parent.parent / "scenarios"


def test_report_html_embeds_every_figure_and_nothing_external(tmp_path: Path) -> None:
    """report.html holds one base64 PNG per file in figures/ (byte for byte), and no external URL or script."""
    d = write_run(tmp_path / "s", {"ref": None, "a": scale(1.1), "b": offset(0.01)}, skip=0.2)
    files = R.write_report(d)
    pngs = sorted((d / "figures").glob("*.png"))
    assert len(pngs) == len(files.figures) == 9  # 5 overlays (q, qd, tau, force, foot) + 4 deviations
    page = files.html.read_text()
    embedded = [base64.b64decode(m) for m in IMG.findall(page)]
    assert len(embedded) == len(pngs)
    assert all(e.startswith(PNG_MAGIC) for e in embedded)
    assert sorted(embedded) == sorted(p.read_bytes() for p in pngs)
    assert not re.search(r'(src|href)="(https?:|//)', page) and "<script" not in page and "<link" not in page
    md = files.markdown.read_text()
    assert all(f"(figures/{p.name})" in md for p in pngs)
    assert files.metrics == d / "metrics.json" and files.metrics.is_file()


def test_report_shows_failed_backends_with_reason_and_every_backend_version(tmp_path: Path) -> None:
    """A failed backend is listed with its reason as a warning; engine, version and settings come from run.json."""
    d = write_run(tmp_path / "s", {"ref": None, "a": None}, failed={"c": "diverged at t = 0.3 s"})
    files = R.write_report(d)
    page, md = files.html.read_text(), files.markdown.read_text()
    for text in (page, md):
        assert "diverged at t = 0.3 s" in text
        assert "fake-ref" in text and "fake-a" in text and "fake-c" in text
        assert '"dt": 0.0001' in text.replace("&quot;", '"')
    assert '<p class="warn">backend &#x27;c&#x27; failed: diverged at t = 0.3 s</p>' in page


def test_partial_log_of_a_failed_backend_is_plotted_not_measured(tmp_path: Path) -> None:
    """A failed backend whose parquet exists is drawn in the overlays but has no metrics."""
    d = write_run(tmp_path / "s", {"ref": None, "a": None, "c": offset(0.5)})
    meta = json.loads((d / "run.json").read_text())
    meta["backends"]["c"].update(status="failed", reason="diverged")
    (d / "run.json").write_text(json.dumps(meta))
    files = R.write_report(d)
    metrics = json.loads(files.metrics.read_text())["metrics"]
    assert {r["backend"] for r in metrics} == {"ref", "a"}
    assert len(files.figures) == 9


def test_a_signal_missing_everywhere_gets_no_figure_and_stale_pngs_go(tmp_path: Path) -> None:
    """Force NaN in every trace: no force overlay or deviation figure; an old PNG in figures/ is removed."""

    def no_force(t: np.ndarray, x: np.ndarray) -> np.ndarray:
        x[:, 9:12] = np.nan
        return x

    d = write_run(tmp_path / "s", {"ref": no_force, "a": no_force})
    (d / "figures").mkdir()
    (d / "figures" / "stale.png").write_bytes(PNG_MAGIC)
    files = R.write_report(d)
    names = {p.name for p in files.figures}
    assert "overlay_force.png" not in names and "deviation_force.png" not in names
    assert {p.name for p in (d / "figures").glob("*.png")} == names
    assert len(IMG.findall(files.html.read_text())) == len(names)


def test_report_includes_the_contact_mode_split_when_the_sibling_exists(tmp_path: Path) -> None:
    """A native run with a __reference sibling gets the split tables."""
    write_run(tmp_path / "fake", {"ref": None, "a": offset(0.04)})
    write_run(tmp_path / "fake__reference", {"ref": None, "a": offset(0.01)}, contact_mode="reference")
    md = R.write_report(tmp_path / "fake").markdown.read_text()
    assert "Contact model vs integration (with fake__reference)" in md
    assert "| a | contact | 0.03 |" in md


def test_report_with_an_imported_log_lists_it_as_a_backend(tmp_path: Path) -> None:
    """An imported CSV log appears in the backends table and the deviation tables."""
    d = write_run(tmp_path / "s", {"ref": None})
    log = tmp_path / "bench.csv"
    pd.read_parquet(d / "ref.parquet").to_csv(log, index=False)
    md = R.write_report(d, log=log).markdown.read_text()
    assert "| log:bench | ok |  | imported log |" in md
    assert "| log:bench | ref | 0 | 0 | 0 |" in md


def test_index_links_every_scenario_and_tabulates_every_sim_error(tmp_path: Path) -> None:
    """results/latest/report.html links each scenario's report; its table has one row per (scenario, backend)."""
    root = tmp_path / "latest"
    write_run(root / "one", {"ref": None, "a": scale(1.1)}, name="one")
    write_run(root / "two", {"ref": None, "a": scale(1.2), "b": None}, name="two", failed={"c": "no engine"})
    out = R.write_all(root)
    index = out[-1]
    assert isinstance(index, R.IndexFiles)
    page = index.html.read_text()
    assert 'href="one/report.html"' in page and 'href="two/report.html"' in page
    md = index.markdown.read_text()
    assert "| [one](one/report.html) | a | ref | 10 | 10 |" in md
    assert "| [two](two/report.html) | a | ref | 20 | 20 |" in md
    assert "| two | c | failed | no engine |" in md
    assert md.count("](two/report.html) |") == 2  # backends a and b


def test_index_reads_metrics_without_reports(tmp_path: Path) -> None:
    """write_index works from run.json alone (metrics computed in memory), without links to absent reports."""
    root = tmp_path / "latest"
    write_run(root / "one", {"ref": None, "a": scale(1.1)}, name="one")
    md = R.write_index(root).markdown.read_text()
    assert "| one | a | ref | 10 |" in md


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


def test_index_shows_verification_and_calibration_tables_when_present(tmp_path: Path) -> None:
    """The study outputs under the results root become tables of the index, one row per record."""
    root = tmp_path / "results"
    write_run(root / "fake", {"ref": None, "a": scale(1.02)})
    (root / "verification").mkdir()
    checks = [{"case": "energy", "backend": "a", "variant": "euler", "quantity": "dE", "unit": "J", "measured": 1e-4,
               "expected": 1e-4, "error": 1e-9, "tolerance": 1e-6, "pass": True}]  # fmt: skip
    (root / "verification" / "verification.json").write_text(json.dumps({"checks": checks}))
    (root / "calibration").mkdir()
    rows = [{"backend": "a", "Kp": 1e4, "k_eff": 9999.0, "Kd": 100.0, "c_eff": 99.0, "mu_s": 0.7, "Fn": 40.0,
             "Ft": 13.0, "creep": 0.1, "creep_law": 0.005, "c_tangential": 130.0}]  # fmt: skip
    (root / "calibration" / "calibration.json").write_text(json.dumps({"rows": rows}))
    R.write_all(root)
    md = (root / "report.md").read_text()
    assert "## Verification against closed-form answers" in md and "| energy | a | euler |" in md
    assert "## Contact calibration" in md and "| a | 1e+04 | 9999 |" in md
    assert "Contact calibration" in (root / "report.html").read_text()


def test_index_shows_the_benchmark_beside_the_results_root(tmp_path: Path) -> None:
    """results/bench/bench.json (written by legbench bench) becomes the index's Performance table."""
    root = tmp_path / "results" / "latest"
    write_run(root / "fake", {"ref": None, "a": scale(1.02)})
    (tmp_path / "results" / "bench").mkdir()
    stat = {"median": 50.0}
    rec = {"task": "effort", "backend": "a", "status": "ok", "full_us_per_tick": stat,
           "engine_us_per_tick": {"median": 46.0}, "harness_us_per_tick": 4.0, "overhead_ratio": {"median": 1.087},
           "rtf_full": 20.0, "mem_peak_bytes": 1020, "series_bytes": 1000, "replay_identical": True}  # fmt: skip
    doc = {"created": "now", "machine": {"cpus": 2}, "results": [rec]}
    (tmp_path / "results" / "bench" / "bench.json").write_text(json.dumps(doc))
    R.write_all(root)
    md = (root / "report.md").read_text()
    assert "## Performance" in md and "| effort | a | 50 | 46 | 4 | 1.087 | 20 | 1.02 | yes |" in md


def test_index_sets_the_two_profiles_side_by_side(tmp_path: Path) -> None:
    """A task run in both profiles gets one index row per backend with both profiles' numbers, each equal to
    the steady Fn of that profile's own metrics (to the 4 significant digits printed)."""
    argv = ["run", str(SCENARIOS / "effort.yaml"), "--backends", "pinocchio,mujoco", "--profile", "both",
            "--out", str(tmp_path), "-q", "--no-preflight", "--set", "duration=0.6"]  # fmt: skip
    assert cli.main(argv) == 0
    md = (tmp_path / "report.md").read_text()
    assert "Profiles side by side" in md
    row = next(line for line in md.splitlines() if line.startswith("| effort | mujoco |"))
    cells = [c.strip() for c in row.strip("|").split("|")]
    for prof, col in (("matched", 4), ("engine-defaults", 5)):
        d = tmp_path / ("effort" if prof == "matched" else "effort__engine-defaults")
        _, df = results.read_metrics(d / "metrics.json")
        fz = df[(df.backend == "mujoco") & (df.metric == "steady_mean") & (df.signal == "force") & (df.joint == "z")]
        assert float(cells[col]) == pytest.approx(float(fz["value"].iloc[0]), rel=5e-4)


def test_write_page_renders_headings_paragraphs_and_tables(tmp_path: Path) -> None:
    """R.write_page: the public page writer the studies use (Markdown and self-contained HTML)."""
    items: list[R.PageItem] = ["# Title", "A paragraph.", ("caption", ("a", "b"), [["x|y", "1.5"]]), "## Sub"]
    md, page = R.write_page(tmp_path, "p", "T", items)
    text = md.read_text()
    assert text == R.page_markdown(items)
    assert "# Title\n" in text and "## Sub\n" in text and "*caption*" in text and "| x\\|y | 1.5 |" in text
    html_text = page.read_text()
    assert "<h1>Title</h1>" in html_text and "<caption>caption</caption>" in html_text
    assert "<td>1.5</td>" in html_text and '<td class="text">x|y</td>' in html_text
