"""Reports of a comparison: Markdown, one self-contained HTML file, PNG figures.

:func:`write_report` turns one run directory into ``metrics.json``,
``report.md``, ``report.html`` (every figure embedded as a base64 PNG, no
external assets) and ``figures/*.png``. :func:`write_index` writes the
top-level ``report.html``/``report.md`` of a results tree (one directory per
scenario) with links to each scenario's report and one table of every
simulation error %. :func:`write_all` does both for a tree.

Figures use matplotlib's object API on the Agg canvas (no pyplot, no global
state), so they can be drawn from any thread and never open a window.
"""

from __future__ import annotations

import base64
import html
import json
import logging
import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from legbench.compare import ComparisonResult, compare
from legbench.exceptions import ResultsError
from legbench.results import Run, RunResult, read_meta, read_metrics, run_dirs, write_metrics
from legbench.signals import JOINTS, LABELS, SIGNAL_OF, SIGNALS, SLICE, UNITS
from legbench.signals import label as column_label

__all__ = ["IndexFiles", "ReportFiles", "write_all", "write_index", "write_report"]

logger = logging.getLogger("legbench.report")

#: Resolution of the PNG figures [dots per inch].
DPI = 90
_FIGSIZE = (10.0, 7.0)
_NAMES = {"q": "joint angle", "qd": "joint velocity", "tau": "joint torque", "force": "ground force on the foot (W)"}
_EE = "ee"
_EE_NAME = "foot centre position (W)"


@dataclass(frozen=True)
class ReportFiles:
    """Files written by :func:`write_report`.

    Attributes:
        metrics: ``DIR/metrics.json``.
        markdown: ``DIR/report.md``.
        html: ``DIR/report.html`` (self-contained).
        figures: the PNGs in ``DIR/figures/``, in report order.
    """

    metrics: Path
    markdown: Path
    html: Path
    figures: tuple[Path, ...]


@dataclass(frozen=True)
class IndexFiles:
    """Files written by :func:`write_index`.

    Attributes:
        html: ``ROOT/report.html``.
        markdown: ``ROOT/report.md``.
        scenarios: the run directories indexed.
    """

    html: Path
    markdown: Path
    scenarios: tuple[Path, ...]


# --------------------------------------------------------------------------- #
# A tiny document model rendered to Markdown and HTML


@dataclass(frozen=True)
class _Heading:
    level: int
    text: str


@dataclass(frozen=True)
class _Para:
    text: str
    warn: bool = False


@dataclass(frozen=True)
class _Table:
    header: tuple[str, ...]
    rows: tuple[tuple[str, ...], ...]
    caption: str = ""
    links: Mapping[tuple[int, int], str] | None = None  # (row, col) -> href


@dataclass(frozen=True)
class _Image:
    path: Path
    caption: str


_Block = _Heading | _Para | _Table | _Image


def _md_cell(s: str) -> str:
    return s.replace("|", "\\|").replace("\n", " ")


def _to_markdown(blocks: Sequence[_Block], base: Path) -> str:
    out: list[str] = []
    for b in blocks:
        if isinstance(b, _Heading):
            out.append(f"{'#' * b.level} {b.text}\n")
        elif isinstance(b, _Para):
            out.append(f"{'**Warning:** ' if b.warn else ''}{b.text}\n")
        elif isinstance(b, _Table):
            if b.caption:
                out.append(f"*{b.caption}*\n")
            out.append("| " + " | ".join(_md_cell(h) for h in b.header) + " |")
            out.append("|" + "|".join("---" for _ in b.header) + "|")
            for i, r in enumerate(b.rows):
                cells = [
                    f"[{_md_cell(c)}]({b.links[(i, j)]})" if b.links and (i, j) in b.links else _md_cell(c)
                    for j, c in enumerate(r)
                ]
                out.append("| " + " | ".join(cells) + " |")
            out.append("")
        else:
            out.append(f"![{b.caption}]({b.path.relative_to(base).as_posix()})\n")
    return "\n".join(out)


_CSS = """
body { font-family: system-ui, sans-serif; margin: 2em auto; max-width: 1100px; color: #222; }
table { border-collapse: collapse; margin: 0.5em 0 1.5em; font-size: 0.85em; }
th, td { border: 1px solid #ccc; padding: 2px 6px; text-align: right; }
th { background: #f0f0f0; }
td:first-child, th:first-child, td.text { text-align: left; }
caption { caption-side: top; text-align: left; font-style: italic; padding-bottom: 3px; }
.warn { background: #fde8e8; border-left: 4px solid #c00; padding: 4px 8px; }
img { max-width: 100%; display: block; margin: 0.3em 0 0.2em; }
figcaption { font-size: 0.85em; color: #555; margin-bottom: 1.2em; }
"""


def _to_html(blocks: Sequence[_Block], title: str) -> str:
    e = html.escape
    out = [
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8">',
        f"<title>{e(title)}</title><style>{_CSS}</style></head><body>",
    ]
    for b in blocks:
        if isinstance(b, _Heading):
            out.append(f"<h{b.level}>{e(b.text)}</h{b.level}>")
        elif isinstance(b, _Para):
            out.append(f'<p class="warn">{e(b.text)}</p>' if b.warn else f"<p>{e(b.text)}</p>")
        elif isinstance(b, _Table):
            out.append("<table>")
            if b.caption:
                out.append(f"<caption>{e(b.caption)}</caption>")
            out.append("<tr>" + "".join(f"<th>{e(h)}</th>" for h in b.header) + "</tr>")
            for i, r in enumerate(b.rows):
                cells = []
                for j, c in enumerate(r):
                    txt = e(c)
                    if b.links and (i, j) in b.links:
                        txt = f'<a href="{e(b.links[(i, j)])}">{txt}</a>'
                    cls = ' class="text"' if not _is_number(c) else ""
                    cells.append(f"<td{cls}>{txt}</td>")
                out.append("<tr>" + "".join(cells) + "</tr>")
            out.append("</table>")
        else:
            data = base64.b64encode(b.path.read_bytes()).decode("ascii")
            out.append(
                f'<figure><img src="data:image/png;base64,{data}" alt="{e(b.caption)}">'
                f"<figcaption>{e(b.caption)}</figcaption></figure>"
            )
    out.append("</body></html>")
    return "\n".join(out) + "\n"


def _is_number(s: str) -> bool:
    try:
        float(s.split(" ")[0].replace("\u2212", "-"))
    except ValueError:
        return False
    return True


def _fmt(v: float, digits: int = 4) -> str:
    if v is None or not math.isfinite(v):
        return "n/a"
    return f"{v:.{digits}g}"


# --------------------------------------------------------------------------- #
# Figures


def _colors(names: Iterable[str], reference: str) -> dict[str, str]:
    palette = ["tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown", "tab:pink", "tab:olive"]
    out = {reference: "black"}
    for n in names:
        if n not in out:
            out[n] = palette[(len(out) - 1) % len(palette)]
    return out


def _dashes(names: Iterable[str], reference: str) -> dict[str, Any]:
    """A line style per backend, so curves that coincide (engines often agree to 1e-12) stay visible."""
    styles: list[Any] = ["-", (0, (5, 3)), (0, (1, 2)), (0, (6, 2, 1, 2))]
    out: dict[str, Any] = {reference: "-"}
    for n in names:
        if n not in out:
            out[n] = styles[(len(out) - 1) % len(styles)]
    return out


def _events(fig: Figure, axes: Sequence[Any], run: Run) -> None:
    for ax in axes:
        for ev in run.events:
            ax.axvline(ev.t, color="0.55", linestyle="--", linewidth=0.8, zorder=0)
    top = axes[0]
    for ev in run.events:
        top.annotate(
            ev.controller,
            xy=(ev.t, 1.0),
            xycoords=("data", "axes fraction"),
            xytext=(2, -2),
            textcoords="offset points",
            fontsize=7,
            color="0.35",
            va="top",
        )


def _new_figure(title: str) -> tuple[Figure, Sequence[Any]]:
    fig = Figure(figsize=_FIGSIZE, dpi=DPI, layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(3, 1, sharex=True)
    fig.suptitle(title, fontsize=11)
    return fig, axes


def _legend(fig: Figure, ax: Any) -> None:
    """One legend below the axes, outside the data."""
    handles, labels = ax.get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside lower center", ncol=min(5, len(labels)), fontsize=8, frameon=False)


def _save(fig: Figure, path: Path) -> Path:
    fig.savefig(path, format="png", dpi=DPI)
    return path


def _xlim(run: Run, traces: Mapping[str, RunResult]) -> tuple[float, float]:
    ends = [tr.t[-1] for tr in traces.values()]
    hi = run.duration if math.isfinite(run.duration) else max(ends, default=1.0)
    return 0.0, float(max(hi, max(ends, default=hi)))


def _overlay(result: ComparisonResult, signal: str, path: Path) -> Path | None:
    run = result.run
    traces = dict(result.traces)
    shown = {**traces, **{f"{k} (failed)": v for k, v in run.partial.items()}}
    if signal != _EE and not any(tr.has(signal) for tr in shown.values()):
        return None
    colors = _colors(list(traces) + list(run.partial), result.reference)
    dashes = _dashes(list(traces) + list(run.partial), result.reference)
    name = _EE_NAME if signal == _EE else _NAMES[signal]
    fig, axes = _new_figure(f"{run.label}: {name}, all backends")
    comps = ("x", "y", "z") if signal == _EE else JOINTS[signal]
    unit = UNITS[signal]
    for label, tr in shown.items():
        base = label.removesuffix(" (failed)")
        y = tr.ee if signal == _EE else tr.signal(signal)
        is_ref = base == result.reference
        style: dict[str, Any] = {
            "color": colors[base],
            "linewidth": 2.4 if is_ref else 1.2,
            "alpha": 0.45 if is_ref else 0.95,
            "linestyle": ":" if label.endswith("(failed)") else dashes[base],
            "label": f"{label} (reference)" if is_ref else label,
        }
        for j, ax in enumerate(axes):
            ax.plot(tr.t, y[:, j], **style)
    for j, ax in enumerate(axes):
        sym = f"ee_{comps[j]}" if signal == _EE else column_label(signal, comps[j])
        ax.set_ylabel(f"{sym} [{unit}]")
        ax.grid(True, linewidth=0.3)
    axes[-1].set_xlabel("t [s]")
    axes[-1].set_xlim(*_xlim(run, shown))
    _events(fig, axes, run)
    _legend(fig, axes[0])
    return _save(fig, path)


def _deviation(result: ComparisonResult, signal: str, path: Path) -> Path | None:
    run = result.run
    pairs = [p for p in result.pairs if p.reference == result.reference]
    cols = np.arange(12)[SLICE[signal]]
    pairs = [p for p in pairs if np.isfinite(p.deviation[:, cols]).any()]
    if not pairs:
        return None
    colors = _colors([p.backend for p in pairs], result.reference)
    dashes = _dashes([p.backend for p in pairs], result.reference)
    fig, axes = _new_figure(f"{run.label}: {_NAMES[signal]}, deviation from {result.reference}")
    unit = UNITS[signal]
    for p in pairs:
        for j, ax in enumerate(axes):
            c = cols[j]
            lag = f", lag {p.lag_removed * 1e3:.3g} ms removed" if p.lag_removed else ""
            ax.plot(
                p.t,
                p.deviation[:, c],
                color=colors[p.backend],
                linestyle=dashes[p.backend],
                linewidth=1.1,
                label=f"{p.backend}{lag}",
            )
            if math.isfinite(p.t_max_abs[c]):
                k = int(np.searchsorted(p.t, p.t_max_abs[c]))
                ax.plot(p.t[k], p.deviation[k, c], "o", color=colors[p.backend], markersize=4)
    for j, ax in enumerate(axes):
        ax.axhline(0.0, color="black", linewidth=0.6)
        if run.skip > 0:
            ax.axvspan(0.0, run.skip, color="0.92", zorder=-1, label="skipped" if j == 0 else None)
        ax.set_ylabel(f"\u0394{column_label(signal, JOINTS[signal][j])} [{unit}]")
        ax.grid(True, linewidth=0.3)
    axes[-1].set_xlabel("t [s]")
    axes[-1].set_xlim(*_xlim(run, result.traces))
    _events(fig, axes, run)
    _legend(fig, axes[0])
    return _save(fig, path)


def _figures(result: ComparisonResult, fig_dir: Path) -> list[tuple[Path, str]]:
    fig_dir.mkdir(parents=True, exist_ok=True)
    for old in fig_dir.glob("*.png"):
        old.unlink()
    out: list[tuple[Path, str]] = []
    for s in (*SIGNALS, _EE):
        p = _overlay(result, s, fig_dir / f"overlay_{s}.png")
        if p is not None:
            name = _EE_NAME if s == _EE else _NAMES[s]
            out.append((p, f"Overlay of {name} per component, every backend; dashed lines are controller switches."))
    for s in SIGNALS:
        p = _deviation(result, s, fig_dir / f"deviation_{s}.png")
        if p is not None:
            out.append((p, f"Deviation of {_NAMES[s]} from {result.reference}; dots mark the largest deviation."))
    return out


# --------------------------------------------------------------------------- #
# Tables


def _col_header(i: int) -> str:
    return f"{LABELS[i]} [{UNITS[SIGNAL_OF[i]]}]"


def _pair_table(result: ComparisonResult, metric: str, caption: str, unit: bool) -> _Table:
    header = ("backend", "vs", *(_col_header(i) if unit else LABELS[i] for i in range(12)))
    rows = tuple(
        (p.backend, p.reference, *(_fmt(v) for v in getattr(p, metric))) for p in result.pairs
    )  # fmt: skip
    return _Table(header, rows, caption)


def _maxdev_table(result: ComparisonResult) -> _Table:
    header = ("backend", "vs", *(_col_header(i) for i in range(12)))
    rows = tuple(
        (
            p.backend,
            p.reference,
            *(f"{_fmt(m, 3)} @ {_fmt(t, 4)} s" for m, t in zip(p.max_abs, p.t_max_abs, strict=True)),
        )
        for p in result.pairs
    )
    return _Table(header, rows, "Largest deviation |x - x_ref| and the time it happens")


def _steady_table(result: ComparisonResult) -> _Table:
    header = ("backend", "row", "qd1 [rad/s]", "qd2 [rad/s]", "qd3 [rad/s]", "Fx [N]", "Fy [N]", "Fn [N]")
    rows: list[tuple[str, ...]] = []
    blank = ("", "", "")
    for s in result.steady:
        win = f"measured (mean over {s.t0:.3f}..{s.t1:.3f} s)"
        rows.append((s.backend, win, *(_fmt(v) for v in s.qd), *(_fmt(v) for v in s.force)))
        rows.append((s.backend, "analytic check, J_poc", *blank, *(_fmt(v) for v in s.analytic_poc)))
        rows.append((s.backend, "measured - analytic (J_poc)", *blank, *(_fmt(v) for v in s.residual)))
        if s.analytic_centre is not None and s.poc_compensation is not None:
            rows.append(
                (s.backend, "analytic check, J_E (poc at centre)", *blank, *(_fmt(v) for v in s.analytic_centre))
            )
            rows.append((s.backend, "poc compensation (J_poc - J_E)", *blank, *(_fmt(v) for v in s.poc_compensation)))
    published = ((result.run.meta.get("scenario") or {}).get("comparison") or {}).get("published") or []
    for row in published:  # the lab report's numbers for this task, as the scenario file gives them
        qd = [_fmt(v) for v in row["qd_abs"]] if "qd_abs" in row else list(blank)
        force = [_fmt(v) for v in row["force"]] if "force" in row else list(blank)
        rows.append((str(row["source"]), "published (|qd| magnitudes)" if "qd_abs" in row else "published",
                     *qd, *force))  # fmt: skip
    return _Table(
        header,
        tuple(rows),
        "Steady state over the final window; analytic check F = -(J^T)^-1 (tau - G(q)) at the mean q and tau "
        "(ground force on the foot; valid when the leg is static)",
    )


def _split_table(result: ComparisonResult, kind: str) -> _Table:
    header = ("backend", "part", *(_col_header(i) if kind == "rms" else LABELS[i] for i in range(12)))
    rows = []
    for m in result.split:
        for part in ("native", "contact", "integration", "drift"):
            rows.append((m.backend, part, *(_fmt(v) for v in getattr(m, f"{part}_{kind}"))))
    what = "RMS" if kind == "rms" else "max |part| / max |x_ref| x 100 [%]"
    return _Table(
        header,
        tuple(rows),
        f"Contact-mode split ({what}): native = contact (a_native - a_reference-mode) + integration "
        "(a_reference-mode - ref_reference-mode) + drift (ref_reference-mode - ref_native), sample by sample",
    )


def _info_text(info: Mapping[str, Any]) -> str:
    rest = {k: v for k, v in info.items() if k not in ("engine", "version")}
    if set(rest) == {"settings"} and isinstance(rest["settings"], Mapping):
        rest = dict(rest["settings"])
    return json.dumps(rest, sort_keys=True, default=str, separators=(", ", ": ")) if rest else ""


def _backend_table(result: ComparisonResult) -> _Table:
    header = ("backend", "status", "reason", "engine", "version", "wall time [s]", "RTF", "settings")
    rows = []
    for b in result.run.backends.values():
        rows.append(
            (
                b.name,
                b.status,
                b.reason or "",
                str(b.info.get("engine", "")),
                str(b.info.get("version", "")),
                _fmt(b.wall_time, 3),
                _fmt(b.rtf, 3),
                _info_text(b.info),
            )
        )
    for name, tr in result.traces.items():
        if name not in result.run.backends:
            rows.append((name, "ok", "", "imported log", "", "", "", tr.source))
    return _Table(header, tuple(rows), "Backends: status, engine, version and settings (from run.json)")


def _residual_table(result: ComparisonResult) -> _Table:
    rows = []
    for name, r in result.residuals.items():
        rows.append((name, str(r.n_contact), _fmt(r.penetration_max * 1e3), _fmt(r.penetration_rel),
                     str(r.n_sliding), _fmt(r.friction_ratio), _fmt(r.angle_max), str(r.n_creep),
                     _fmt(r.creep_speed * 1e3), _fmt(r.creep_law * 1e3)))  # fmt: skip
    return _Table(
        (
            "backend",
            "contact samples",
            "max |y - Fn_spring/Kp| [mm]",
            "median |y Kp/Fn - 1|",
            "sliding samples",
            "|F_t| / (mu_k Fn) sliding",
            "max angle F_t vs -v [deg]",
            "sub-limit samples",
            "creep [mm/s]",
            "law's creep [mm/s]",
        ),  # fmt: skip
        tuple(rows),
        "Each backend against the contact law it was meant to follow (docs/metrics.md): penetration against "
        "the spring, friction magnitude while sliding (1 for the law), friction direction against the slip, "
        "and creep under a sub-limit load beside the law's v_th |F_t| / (mu_s Fn); n/a where no sample qualifies",
    )


def _blocks(result: ComparisonResult, figures: Sequence[tuple[Path, str]]) -> list[_Block]:
    run = result.run
    sc = run.meta.get("scenario", {})
    b: list[_Block] = [_Heading(1, f"legbench comparison: {run.label}")]
    if sc.get("description"):
        b.append(_Para(str(sc["description"])))
    contact = sc.get("contact") or {}
    b.append(
        _Table(
            ("item", "value"),
            (
                ("scenario file", f"{sc.get('file', '')} (sha256 {str(sc.get('sha256', ''))[:12]})"),
                ("duration [s]", _fmt(run.duration)),
                ("control rate [Hz]", _fmt(float(sc.get("control_rate", math.nan)))),
                ("contact mode", run.contact_mode),
                ("contact", ", ".join(f"{k} = {v}" for k, v in contact.items())),
                ("reference", result.reference),
                ("skip [s]", _fmt(run.skip)),
                ("steady window [s]", _fmt(run.steady_window)),
                ("events", ", ".join(f"{e.controller} @ {e.t:g} s" for e in run.events)),
                ("legbench version", str(run.meta.get("legbench_version", ""))),
                ("platform", json.dumps(run.meta.get("platform", {}), sort_keys=True, default=str)),
            ),
        )
    )
    for n in result.notes:
        b.append(_Para(n, warn=True))
    b.append(_Heading(2, "Backends"))
    b.append(_backend_table(result))
    for bk in result.run.backends.values():
        for w in bk.info.get("warnings") or ():
            b.append(_Para(f"{bk.name}: {w}", warn=True))
    if result.pairs:
        b.append(_Heading(2, "Deviation from the reference"))
        skip = f" for t >= {run.skip:g} s" if run.skip > 0 else ""
        b.append(
            _pair_table(result, "sim_error_pct", f"Simulation error % = max|x - x_ref| / max|x_ref| x 100{skip}", False)
        )
        b.append(_pair_table(result, "rms", f"RMS deviation{skip}", True))
        b.append(_maxdev_table(result))
        lags = [p for p in result.pairs if p.lag is not None]
        if lags:
            b.append(
                _Table(
                    ("backend", "vs", "lag [ms]", "samples", "correlation", "removed [ms]"),
                    tuple(
                        (
                            p.backend,
                            p.reference,
                            _fmt(p.lag.seconds * 1e3),
                            _fmt(p.lag.samples),
                            _fmt(p.lag.correlation),
                            _fmt(p.lag_removed * 1e3),
                        )
                        for p in lags
                        if p.lag is not None
                    ),  # fmt: skip
                    "Constant time lag by cross-correlation (> 0: the backend is late)",
                )
            )
    b.append(_Heading(2, "Steady state and analytic force check"))
    b.append(_steady_table(result))
    if any(r.n_contact for r in result.residuals.values()):
        b.append(_Heading(2, "Contact-law residuals"))
        b.append(_residual_table(result))
    if result.split:
        b.append(
            _Heading(2, f"Contact model vs integration (with {result.split_run.label if result.split_run else ''})")
        )
        b.append(_split_table(result, "rms"))
        b.append(_split_table(result, "pct"))
    b.append(_Heading(2, "Figures"))
    b.extend(_Image(p, cap) for p, cap in figures)
    return b


def write_report(run_dir: str | Path, result: ComparisonResult | None = None, **compare_kwargs: Any) -> ReportFiles:
    """Write metrics.json, report.md, report.html and figures/*.png into a run directory.

    Args:
        run_dir: the run directory.
        result: a comparison already computed for it (else :func:`legbench.compare.compare`
            is called with ``compare_kwargs``).
        **compare_kwargs: passed to :func:`legbench.compare.compare` (log, lag, all_pairs, ...).

    Returns:
        The files written.

    Raises:
        ResultsError: the run directory is missing or malformed.
    """
    path = Path(run_dir)
    res = result if result is not None else compare(path, **compare_kwargs)
    metrics = write_metrics(res.to_json(), path / "metrics.json")
    figures = _figures(res, path / "figures")
    blocks = _blocks(res, figures)
    md = path / "report.md"
    md.write_text(_to_markdown(blocks, path))
    page = path / "report.html"
    page.write_text(_to_html(blocks, f"legbench: {res.run.label}"))
    logger.info("wrote %s, %s and %d figures", md, page, len(figures))
    return ReportFiles(metrics, md, page, tuple(p for p, _ in figures))


#: One piece of a page for :func:`write_page`: a heading (``"## text"``), a paragraph (any
#: other text) or a table ``(caption, header, rows)`` of text cells.
PageItem = str | tuple[str, Sequence[str], Sequence[Sequence[str]]]


def _page_blocks(items: Sequence[PageItem]) -> list[_Block]:
    blocks: list[_Block] = []
    for item in items:
        if isinstance(item, str):
            level = len(item) - len(item.lstrip("#"))
            blocks.append(_Heading(level, item[level:].strip()) if level else _Para(item))
        else:
            caption, header, rows = item
            blocks.append(_Table(tuple(header), tuple(tuple(r) for r in rows), caption))
    return blocks


def page_markdown(items: Sequence[PageItem]) -> str:
    """The Markdown of a page of headings, paragraphs and tables (see :data:`PageItem`)."""
    return _to_markdown(_page_blocks(items), Path("."))


def write_page(out_dir: str | Path, stem: str, title: str, items: Sequence[PageItem]) -> tuple[Path, Path]:
    """Write ``out_dir/stem.md`` and ``out_dir/stem.html`` (self-contained) from headings, paragraphs and
    tables (see :data:`PageItem`), in the same style as the run reports; returns both paths."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    blocks = _page_blocks(items)
    md, page = out / f"{stem}.md", out / f"{stem}.html"
    md.write_text(_to_markdown(blocks, out))
    page.write_text(_to_html(blocks, title))
    return md, page


# --------------------------------------------------------------------------- #
# Index of a results tree


def write_index(root: str | Path) -> IndexFiles:
    """Write ROOT/report.html and ROOT/report.md for a tree of run directories.

    Each scenario directory (a subdirectory with run.json) is linked to its
    report.html; one table holds every simulation error % (scenario x backend x
    signal component), read from each directory's metrics.json (computed in
    memory if absent). Backends that failed are listed with their reason.

    Raises:
        ResultsError: ROOT is missing or holds no run directory.
    """
    root = Path(root)
    dirs = list(run_dirs(root).values())
    header = ("scenario", "backend", "vs", *LABELS)
    rows: list[tuple[str, ...]] = []
    links: dict[tuple[int, int], str] = {}
    problems: list[tuple[str, ...]] = []
    measured: list[tuple[str, str, str, pd.DataFrame]] = []  # (scenario name, profile, contact mode, metrics)
    for d in dirs:
        mfile = d / "metrics.json"
        if mfile.is_file():
            meta, df = read_metrics(mfile)
        else:
            res = compare(d)
            meta, df = res.to_json(), res.frame()
        sc_meta = read_meta(d)["scenario"]
        measured.append((str(sc_meta["name"]), str(sc_meta.get("profile", "matched")),
                         str(meta.get("contact_mode", "native")), df))  # fmt: skip
        label = str(meta.get("scenario", d.name))
        for bname, b in (meta.get("backends") or {}).items():
            if b.get("status") != "ok":
                problems.append((label, bname, str(b.get("status")), str(b.get("reason") or "")))
        sim = df[df["metric"] == "sim_error_pct"]
        first = len(rows)
        for (backend, ref), g in sim.groupby(["backend", "reference"], sort=False):
            vals = {column_label(s, j): v for s, j, v in zip(g["signal"], g["joint"], g["value"], strict=True)}
            rows.append((label, str(backend), str(ref), *(_fmt(vals.get(c, math.nan), 3) for c in LABELS)))
        if len(rows) == first:
            rows.append((label, "-", str(meta.get("reference", "")), *("n/a" for _ in LABELS)))
        if (d / "report.html").is_file():
            for i in range(first, len(rows)):
                links[(i, 0)] = f"{d.name}/report.html"
    blocks: list[_Block] = [
        _Heading(1, "legbench: comparison summary"),
        _Para(
            "Simulation error % = max_t |x_a - x_ref| / max_t |x_ref| x 100 per signal component, each backend "
            "against its scenario's reference backend (n/a: the reference signal is zero, or missing). "
            "Scenario names link to their reports."
        ),
        _Table(header, tuple(rows), "Simulation error % (scenario x backend x signal)", links),
    ]
    if problems:
        blocks.append(_Heading(2, "Backends that did not run"))
        blocks.append(_Table(("scenario", "backend", "status", "reason"), tuple(problems)))
    blocks += _profile_blocks(measured)
    blocks += _study_blocks(root)
    md = root / "report.md"
    md.write_text(_to_markdown(blocks, root))
    page = root / "report.html"
    page.write_text(_to_html(blocks, "legbench: comparison summary"))
    return IndexFiles(page, md, tuple(dirs))


def _profile_blocks(measured: Sequence[tuple[str, str, str, pd.DataFrame]]) -> list[_Block]:
    """What configuration costs: each scenario's native-contact runs in the ``matched`` and
    ``engine-defaults`` profiles side by side (largest joint-angle error %, steady ground force)."""
    by_key = {(name, prof): df for name, prof, mode, df in measured if mode == "native"}
    names = [n for n in dict.fromkeys(name for name, _, _, _ in measured) if (n, "engine-defaults") in by_key
             and (n, "matched") in by_key]  # fmt: skip
    if not names:
        return []
    rows: list[tuple[str, ...]] = []
    for name in names:
        cells: dict[str, dict[str, tuple[float, float]]] = {}
        for prof in ("matched", "engine-defaults"):
            df = by_key[(name, prof)]
            for backend, g in df.groupby("backend", sort=False):
                q = g[(g["metric"] == "sim_error_pct") & (g["signal"] == "q")]["value"]
                fz = g[(g["metric"] == "steady_mean") & (g["signal"] == "force") & (g["joint"] == "z")]["value"]
                cells.setdefault(str(backend), {})[prof] = (
                    float(q.max()) if len(q) else math.nan,
                    float(fz.iloc[0]) if len(fz) else math.nan,
                )
        for backend, by_prof in cells.items():
            m = by_prof.get("matched", (math.nan, math.nan))
            e = by_prof.get("engine-defaults", (math.nan, math.nan))
            rows.append((name, backend, _fmt(m[0], 3), _fmt(e[0], 3), _fmt(m[1], 4), _fmt(e[1], 4)))
    return [
        _Heading(2, "Profiles side by side: what configuration costs"),
        _Para(
            "Native contact. 'matched': each engine configured to the spec's physics as faithfully as it allows; "
            "'engine-defaults': the engine's documented defaults with only Kp, Kd and mu set "
            "(docs/contact_mapping.md). "
            "A difference between the two columns is the settings', not the engine's."
        ),
        _Table(
            (
                "scenario",
                "backend",
                "max q error % (matched)",
                "max q error % (engine-defaults)",
                "steady Fn [N] (matched)",
                "steady Fn [N] (engine-defaults)",
            ),  # fmt: skip
            tuple(rows),
            "Largest joint-angle simulation error % against the scenario's reference backend in the same profile, "
            "and the steady normal ground force (mean over the steady window)",
        ),
    ]


#: Study outputs the index shows when present under the results root:
#: (file, heading, record list key, columns, caption).
STUDIES: tuple[tuple[str, str, str, tuple[str, ...], str], ...] = (
    (
        "verification/verification.json",
        "Verification against closed-form answers",
        "checks",
        ("case", "backend", "variant", "quantity", "unit", "measured", "expected", "error", "tolerance", "pass"),
        "legbench verify: each case, backend and integrator against its closed-form answer (legbench/verify.py)",
    ),
    (
        "calibration/calibration.json",
        "Contact calibration",
        "rows",
        ("backend", "Kp", "k_eff", "Kd", "c_eff", "mu_s", "Fn", "Ft", "creep", "creep_law", "c_tangential"),
        "legbench calibrate-contact: effective normal stiffness k_eff [N/m] and damping c_eff [N s/m] from a static "
        "push, creep [m/s] under a tangential load Ft [N] below mu_s Fn, beside the spec (Kp, Kd, mu_s) and the "
        "law's own creep",
    ),
)


def _cell(v: Any) -> str:
    if isinstance(v, bool):
        return "yes" if v else "NO"
    if isinstance(v, int | float):
        return _fmt(float(v), 4)
    return str(v)


def _study_blocks(root: Path) -> list[_Block]:
    """Tables of the verification and calibration studies found under ``root``."""
    blocks: list[_Block] = []
    for rel, heading, key, cols, caption in STUDIES:
        path = root / rel
        if not path.is_file():
            continue
        try:
            records = json.loads(path.read_text())[key]
        except (ValueError, KeyError, TypeError) as exc:
            raise ResultsError(str(path), f"malformed study output: {exc}") from None
        rows = tuple(tuple(_cell(r.get(c, "")) for c in cols) for r in records)
        blocks += [_Heading(2, heading), _Table(cols, rows, caption)]
    return blocks + _bench_blocks(root)


def _bench_blocks(root: Path) -> list[_Block]:
    """The latest `legbench bench` figures (results/bench/bench.json beside the results root), if any."""
    path = next((p for p in (root / "bench" / "bench.json", root.parent / "bench" / "bench.json") if p.is_file()), None)
    if path is None:
        return []
    try:
        doc = json.loads(path.read_text())
        rows = []
        for r in doc["results"]:
            if r.get("status") != "ok":
                rows.append((r["task"], r["backend"], r.get("status", "?"), "", "", "", "", "", ""))
                continue
            mem = r["mem_peak_bytes"] / r["series_bytes"] if r.get("mem_peak_bytes") and r.get("series_bytes") else None
            rows.append((
                r["task"], r["backend"], _cell(r["full_us_per_tick"]["median"]),
                _cell(r["engine_us_per_tick"]["median"]), _cell(r["harness_us_per_tick"]),
                _cell(r["overhead_ratio"]["median"]), _cell(r["rtf_full"]),
                _cell(mem) if mem is not None else "-", "yes" if r.get("replay_identical") else "NO",
            ))  # fmt: skip
    except (ValueError, KeyError, TypeError) as exc:
        raise ResultsError(str(path), f"malformed benchmark output: {exc}") from None
    cols = ("task", "backend", "full [us/tick]", "engine only [us/tick]", "harness [us/tick]", "overhead ratio",
            "RTF", "memory / series", "replay identical")  # fmt: skip
    caption = (f"legbench bench ({doc.get('created', '')}, {doc.get('machine', {}).get('cpus', '?')} CPUs): medians; "
               "overhead ratio = full run / engine-only replay of the same torques")  # fmt: skip
    return [_Heading(2, "Performance"), _Table(cols, tuple(rows), caption)]


def write_all(root: str | Path, **compare_kwargs: Any) -> list[ReportFiles | IndexFiles]:
    """Report a run directory, or every run directory under ``root`` and then the index.

    Args:
        root: a run directory (has run.json) or a tree of them (results/latest).
        **compare_kwargs: passed to :func:`legbench.compare.compare`.

    Returns:
        Every :class:`ReportFiles` written, then the :class:`IndexFiles` for a tree.
    """
    root = Path(root)
    if (root / "run.json").is_file():
        return [write_report(root, **compare_kwargs)]
    if not root.is_dir():
        raise ResultsError(str(root), "no such results directory")
    if compare_kwargs.get("log") is not None:
        raise ResultsError(str(root), "an imported log belongs to one scenario: pass that scenario's run directory")
    out: list[ReportFiles | IndexFiles] = [write_report(d, **compare_kwargs) for d in run_dirs(root).values()]
    out.append(write_index(root))
    return out
