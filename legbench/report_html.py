"""The report's small document model, rendered to Markdown and to HTML.

A page is a list of blocks: headings, paragraphs, tables (cells with an
optional link, colour class and exact value on hover), collapsible details,
interactive figures (:class:`legbench.report_figures.Figure`) and navigation
links. :func:`to_markdown` and :func:`to_html` render the same blocks, so the
two files of a report always say the same. Numbers are written by one
function, :func:`num`.
"""

from __future__ import annotations

import html
import json
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from legbench.report_figures import LEGBENCH_FILE, PLOTLY_JS, Arrays, Figure

__all__ = ["Block", "Details", "Heading", "Nav", "Para", "Table", "num", "num_apart", "to_html", "to_markdown"]


def num(v: Any, digits: int = 4) -> str:
    """The one number format of the report: ``digits`` significant digits, plain decimals from 1e-3 to 1e6
    (``156``, ``1800``, ``0.0123``), ``2.41e-13`` outside; ``n/a`` for NaN or None, ``0`` for zero."""
    if v is None:
        return "n/a"
    x = float(v)
    if not math.isfinite(x):
        return "n/a"
    if x == 0.0:
        return "0"
    if 1e-3 <= abs(x) < 1e6:
        # round to significant digits, then print without an exponent and without trailing zeros
        decimals = max(0, digits - 1 - math.floor(math.log10(abs(x))))
        s = f"{round(x, decimals):.{decimals}f}"
        return s.rstrip("0").rstrip(".") if "." in s else s
    mant, exp = f"{x:.{digits - 1}e}".split("e")
    mant = mant.rstrip("0").rstrip(".") if "." in mant else mant
    return f"{mant}e{int(exp)}"


def num_apart(v: Any, bounds: Sequence[float], digits: int = 4) -> str:
    """:func:`num` of ``v`` with as many more significant digits (up to 12) as it takes not to read as one of the
    ``bounds`` it is compared with and differs from: a 100.04 % over a 100 % limit is written ``100.04``, not
    ``100``; a 0.010004 beyond a tolerance of 0.01, ``0.010004``."""
    if v is None or not math.isfinite(float(v)):
        return num(v, digits)
    x = float(v)
    near = [b for b in bounds if math.isfinite(b) and b != x]
    for d in range(digits, 13):
        s = num(x, d)
        if all(s != num(b, d) for b in near):
            return s
    return num(x, 12)


@dataclass(frozen=True)
class Heading:
    level: int
    text: str
    anchor: str = ""


@dataclass(frozen=True)
class Para:
    text: str
    warn: bool = False


@dataclass(frozen=True)
class Table:
    """A table of text cells; ``links``, ``classes`` and ``titles`` are keyed by (row, column)."""

    header: tuple[str, ...]
    rows: tuple[tuple[str, ...], ...]
    caption: str = ""
    links: Mapping[tuple[int, int], str] | None = None
    classes: Mapping[tuple[int, int], str] | None = None
    titles: Mapping[tuple[int, int], str] | None = None
    group_rows: Mapping[int, str] = field(default_factory=dict)  # row index -> a group heading row above it


@dataclass(frozen=True)
class Details:
    """A summary line; the blocks open on demand (HTML ``<details>``; Markdown writes them out)."""

    summary: str
    blocks: tuple[Block, ...]
    cls: str = ""


@dataclass(frozen=True)
class Nav:
    """A line of links: (text, href)."""

    links: tuple[tuple[str, str], ...]


Block = Heading | Para | Table | Details | Nav | Figure


def _md_cell(s: str) -> str:
    return s.replace("|", "\\|").replace("\n", " ")


def _md(blocks: Sequence[Block], out: list[str], page: str) -> None:
    for b in blocks:
        if isinstance(b, Heading):
            if b.anchor:  # the target of the page's own links (#task-effort, #tables), as in the HTML
                out.append(f'<a id="{b.anchor}"></a>\n')
            out.append(f"{'#' * b.level} {b.text}\n")
        elif isinstance(b, Para):
            out.append(f"{'**Warning:** ' if b.warn else ''}{b.text}\n")
        elif isinstance(b, Table):
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
        elif isinstance(b, Details):  # written out, under its summary in bold (the HTML's closed line)
            out.append(f"**{b.summary}**\n")
            _md(b.blocks, out, page)
        elif isinstance(b, Nav):
            out.append(
                " | ".join(f"[{t}]({h.replace('.html', '.md') if h.endswith('.html') else h})" for t, h in b.links)
                + "\n"
            )
        else:
            link = f"[{page}]({page}#{b.key})"
            out.append(f'- <a id="{b.key}"></a>Figure ({b.key}): {b.caption} Interactive in {link}.\n')


def to_markdown(blocks: Sequence[Block], page: str = "report.html") -> str:
    """The blocks as Markdown (figures as links into the HTML ``page``, which holds them)."""
    out: list[str] = []
    _md(blocks, out, page)
    return "\n".join(out)


CSS = """
body { font-family: system-ui, sans-serif; margin: 1.5em auto; max-width: 1400px; padding: 0 1em; color: #222; }
h1 { font-size: 1.5em; } h2 { font-size: 1.2em; margin-top: 1.6em; border-bottom: 1px solid #ddd; }
h3 { font-size: 1.05em; margin-top: 1.2em; }
table { border-collapse: collapse; font-size: 0.82em; }
.scroll { overflow: auto; max-height: 85vh; margin: 0 0 1.2em; }
th, td { border: 1px solid #d0d0d0; padding: 2px 5px; text-align: right; white-space: nowrap; }
thead th { background: #f0f0f0; position: sticky; top: 0; z-index: 1; }
tbody th { background: #fff; position: sticky; left: 0; font-weight: normal; }
thead th:first-child { left: 0; z-index: 2; }
.text { text-align: left; white-space: normal; } .short { white-space: nowrap; }
td:first-child, th:first-child { text-align: left; white-space: nowrap; }
tr.group th { background: #f7f7f7; font-weight: 600; text-align: left; }
p.caption { text-align: left; font-style: italic; margin: 0.4em 0 3px; color: #444; }
.warn { background: #fde8e8; border-left: 4px solid #c00; padding: 4px 8px; }
.nav { font-size: 0.9em; margin: 0.3em 0 1em; } .nav a { margin-right: 1.2em; }
figure { margin: 0.8em 0 1.6em; } figcaption { font-size: 0.85em; color: #555; }
.lb-plot { width: 100%; min-height: 300px; }
.leg-controls { font-size: 0.9em; margin: 0.3em 0; } .leg-controls input { width: 60%; vertical-align: middle; }
details { margin: 0.3em 0 1em; } summary { cursor: pointer; font-weight: 600; }
details.fail > summary { color: #a00; }
:is(td, th).agree { background: #d9f2d9; } :is(td, th).close { background: #eef7d6; }
:is(td, th).differ { background: #fde9c8; } :is(td, th).far { background: #f9cccc; }
:is(td, th).within { background: #d9f2d9; } :is(td, th).over { background: #f4a7a7; font-weight: 600; }
:is(td, th).pass { background: #d9f2d9; } :is(td, th).fail { background: #f4a7a7; font-weight: 600; }
:is(td, th).na { background: #eeeeee; color: #555; }
.legend span { display: inline-block; padding: 1px 6px; margin-right: 6px; border: 1px solid #ccc; font-size: 0.85em; }
.sentence { margin: 0.2em 0 0.6em; }
"""


def _html_table(b: Table, e: Any) -> list[str]:
    """The table in a box that scrolls it (sideways where it is wide, down where it is long, its header row and
    first column staying in view), its caption above the box at the page's width, naming the box for a screen
    reader; the header cells head their columns, each row's first cell heads its row."""
    out = [f'<p class="caption">{e(b.caption)}</p>'] if b.caption else []
    label = f' aria-label="{e(b.caption)}"' if b.caption else ""
    out.append(f'<div class="scroll" role="region" tabindex="0"{label}><table>')
    out.append("<thead><tr>" + "".join(f'<th scope="col">{e(h)}</th>' for h in b.header) + "</tr></thead><tbody>")
    for i, r in enumerate(b.rows):
        if i in b.group_rows:
            group = e(b.group_rows[i])
            out.append(f'<tr class="group"><th scope="rowgroup" colspan="{len(b.header)}">{group}</th></tr>')
        cells = []
        for j, c in enumerate(r):
            txt = e(c)
            if b.links and (i, j) in b.links:
                txt = f'<a href="{e(b.links[(i, j)])}">{txt}</a>'
            cls = [] if _is_number(c) else (["text", "short"] if len(c) <= 24 else ["text"])
            if b.classes and (i, j) in b.classes:
                cls.append(b.classes[(i, j)])
            attr = f' class="{" ".join(cls)}"' if cls else ""
            if b.titles and (i, j) in b.titles:
                attr += f' title="{e(b.titles[(i, j)])}"'
            # the first column names the row (a backend, a case): its header, kept in view scrolling sideways
            cells.append(f'<th scope="row"{attr}>{txt}</th>' if j == 0 else f"<td{attr}>{txt}</td>")
        out.append("<tr>" + "".join(cells) + "</tr>")
    out.append("</tbody></table></div>")
    return out


def _json(doc: Any) -> str:
    """JSON safe inside a <script> element."""
    return json.dumps(doc, separators=(",", ":"), allow_nan=False).replace("</", "<\\/")


def _html(blocks: Sequence[Block], out: list[str]) -> None:
    e = html.escape
    for b in blocks:
        if isinstance(b, Heading):
            anchor = f' id="{e(b.anchor)}"' if b.anchor else ""
            out.append(f"<h{b.level}{anchor}>{e(b.text)}</h{b.level}>")
        elif isinstance(b, Para):
            out.append(f'<p class="warn">{e(b.text)}</p>' if b.warn else f"<p>{e(b.text)}</p>")
        elif isinstance(b, Table):
            out.extend(_html_table(b, e))
        elif isinstance(b, Details):
            cls = f' class="{e(b.cls)}"' if b.cls else ""
            out.append(f"<details{cls}><summary>{e(b.summary)}</summary>")
            _html(b.blocks, out)
            out.append("</details>")
        elif isinstance(b, Nav):
            out.append('<p class="nav">' + "".join(f'<a href="{e(h)}">{e(t)}</a>' for t, h in b.links) + "</p>")
        elif b.kind == "leg":
            k = e(b.key)
            out.append(
                f'<figure id="{k}"><div id="{k}-plot" class="lb-plot lb-leg"></div>'
                f'<div class="leg-controls"><button id="{k}-plot-play" type="button">play</button> '
                f'<input id="{k}-plot-slider" type="range" min="0" max="0" step="1" value="0" '
                f'aria-label="time"> <span id="{k}-plot-time"></span></div>'
                f'<script>legbench.leg("{k}-plot", {_json(b.spec)});</script>'
                f"<figcaption>{e(b.caption)}</figcaption></figure>"
            )
        else:
            k = e(b.key)
            out.append(
                f'<figure id="{k}"><div id="{k}-plot" class="lb-plot"></div>'
                f'<script>legbench.plot("{k}-plot", {_json(b.spec)});</script>'
                f"<figcaption>{e(b.caption)}</figcaption></figure>"
            )


def _has_figure(blocks: Sequence[Block]) -> bool:
    return any(isinstance(b, Figure) or (isinstance(b, Details) and _has_figure(b.blocks)) for b in blocks)


def to_html(blocks: Sequence[Block], title: str, assets: str = "", arrays: Arrays | None = None) -> str:
    """The blocks as one HTML page.

    Args:
        blocks: the page.
        title: the page title.
        assets: relative URL of the directory holding plotly.min.js and legbench.js (needed with figures).
        arrays: the page's array store (the figures' data), written once before the figures.
    """
    e = html.escape
    out = [
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8">',
        '<meta name="viewport" content="width=device-width, initial-scale=1">',
        f"<title>{e(title)}</title><style>{CSS}</style>",
    ]
    if _has_figure(blocks):
        base = assets.rstrip("/") + "/" if assets else ""
        out.append(f'<script src="{e(base + PLOTLY_JS)}"></script><script src="{e(base + LEGBENCH_FILE)}"></script>')
    out.append("</head><body>")
    if arrays is not None and arrays.items:
        out.append(f"<script>legbench.data({_json(arrays.items)});</script>")
    _html(blocks, out)
    out.append("</body></html>")
    return "\n".join(out) + "\n"


def _is_number(s: str) -> bool:
    try:
        float(s.split(" ")[0].replace("\u2212", "-"))
    except ValueError:
        return False
    return True


def relpath(target: Path, start: Path) -> str:
    """``target`` relative to the directory ``start``, with forward slashes (for hrefs)."""
    return Path(os.path.relpath(target, start)).as_posix()
