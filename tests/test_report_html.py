"""legbench/report_html.py: which table cells read as numbers, the classes and attributes each cell gets in the
HTML, and the digits :func:`num_apart` gives a number compared with a bound.

The report's pages as a whole (figures, links, colours per comparison) are tests/test_report.py's; this file holds
the document model's own rules, on tables built here.
"""

from __future__ import annotations

import html
import math
from html.parser import HTMLParser

import pytest

from legbench.report_html import Table, _html_table, _is_number, num_apart, to_html, to_markdown

MINUS = "\u2212"  # U+2212 MINUS SIGN, as typeset numbers write a negative


@pytest.mark.parametrize(
    ("text", "number"),
    [
        ("0.5", True),
        ("-0.5", True),
        (f"{MINUS}0.5", True),  # the typographic minus reads as '-'
        ("1.396e+05", True),
        ("2.41e-13", True),
        ("3 %", True),  # the first word decides: a number with its unit
        ("100.04 % exceeds the scenario's limit 100 %", True),
        ("inf", True),  # the calibration's Ft/creep of a foot that sticks: a value (report.py writes it so)
        ("-inf", True),
        ("n/a", False),  # num's NaN: text
        ("", False),
        ("mujoco", False),
        (MINUS, False),  # a minus sign alone
        ("3%", False),  # no space before the unit: one word, not a number
        ("- 0.5", False),  # the first word is the sign alone
    ],
)
def test_is_number_reads_the_first_word(text: str, number: bool) -> None:
    """A cell is a number when its first space-separated word parses as a float once U+2212 is read as '-'."""
    assert _is_number(text) is number


class _Cells(HTMLParser):
    """The body rows of one rendered table: per row, (tag, attributes, text) of each cell."""

    def __init__(self) -> None:
        super().__init__()
        self.rows: list[list[tuple[str, dict[str, str | None], str]]] = []
        self._body = False
        self._cell: tuple[str, dict[str, str | None]] | None = None
        self._text: list[str] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        if tag == "tbody":
            self._body = True
        elif self._body and tag == "tr":
            self.rows.append([])
        elif self._body and tag in ("td", "th"):
            self._cell, self._text = (tag, dict(attrs)), []

    def handle_endtag(self, tag: str) -> None:
        if tag == "tbody":
            self._body = False
        elif self._cell is not None and tag == self._cell[0]:
            self.rows[-1].append((*self._cell, "".join(self._text)))
            self._cell = None

    def handle_data(self, data: str) -> None:
        if self._cell is not None:
            self._text.append(data)


def _cells(table: Table) -> list[list[tuple[str, dict[str, str | None], str]]]:
    parser = _Cells()
    parser.feed("\n".join(_html_table(table, html.escape)))
    return parser.rows


def test_html_table_aligns_numbers_right_and_text_left() -> None:
    """A number cell (U+2212 and '3 %' included) has no class (right-aligned by the CSS); a text cell is 'text',
    and 'text short' (kept on one line) up to 24 characters: 24 is short, 25 is not. 'n/a' is text."""
    t = Table(
        header=("case", "value", "unit", "note"),
        rows=(
            ("a", f"{MINUS}0.5", "3 %", "y" * 24),
            ("x" * 25, "n/a", "1.396e+05", "z" * 25),
        ),
    )
    rows = _cells(t)
    assert [[(tag, a.get("class"), text) for tag, a, text in r] for r in rows] == [
        [("th", "text short", "a"), ("td", None, f"{MINUS}0.5"), ("td", None, "3 %"), ("td", "text short", "y" * 24)],
        [("th", "text", "x" * 25), ("td", "text short", "n/a"), ("td", None, "1.396e+05"), ("td", "text", "z" * 25)],
    ]


def test_html_table_heads_rows_and_adds_classes_titles_links_and_groups() -> None:
    """The first cell of each row is its header (th scope=row); a class given for a cell follows the alignment
    class; a title (the exact value on hover) and a link are escaped; a group row sits above its row, spanning the
    columns; the caption names the scrolling box."""
    t = Table(
        header=("backend", "err [%]"),
        rows=(("b<1>", "100.04"), ("b2", "n/a")),
        caption="errors & limits",
        links={(0, 0): "run.html?a=1&b=2"},
        classes={(0, 1): "over", (1, 1): "na"},
        titles={(0, 1): 'exact "100.0412"'},
        group_rows={1: "effort <task>"},
    )
    out = "\n".join(_html_table(t, html.escape))
    assert '<p class="caption">errors &amp; limits</p>' in out
    assert '<div class="scroll" role="region" tabindex="0" aria-label="errors &amp; limits"><table>' in out
    assert '<th scope="row" class="text short"><a href="run.html?a=1&amp;b=2">b&lt;1&gt;</a></th>' in out
    assert '<td class="over" title="exact &quot;100.0412&quot;">100.04</td>' in out
    assert '<td class="text short na">n/a</td>' in out  # the alignment class first, then the given one
    group = '<tr class="group"><th scope="rowgroup" colspan="2">effort &lt;task&gt;</th></tr>'
    assert out.index("100.04") < out.index(group) < out.index(">b2<")
    assert [[(tag, a.get("scope")) for tag, a, _ in r] for r in _cells(t)] == [
        [("th", "row"), ("td", None)],
        [("th", "rowgroup")],
        [("th", "row"), ("td", None)],
    ]


def test_a_table_without_caption_has_no_caption_or_label() -> None:
    """No caption: no caption paragraph and no aria-label on the box; the header cells head their columns."""
    out = to_html([Table(header=("a", "b"), rows=(("x", "1"),))], title="t")
    assert 'class="caption"' not in out and "aria-label" not in out
    assert '<thead><tr><th scope="col">a</th><th scope="col">b</th></tr></thead>' in out


def test_markdown_table_escapes_pipes_and_links_its_cells() -> None:
    """The Markdown of a table: a '|' in a cell is escaped, a newline becomes a space, a linked cell is a link."""
    t = Table(header=("a|b", "c"), rows=(("x", "1|2\n3"),), links={(0, 0): "r.md"})
    assert to_markdown([t]) == "| a\\|b | c |\n|---|---|\n| [x](r.md) | 1\\|2 3 |\n"


@pytest.mark.parametrize(
    ("value", "bounds", "digits", "text"),
    [
        (100.0412345, (100.0,), 4, "100.04"),  # one digit more than num's "100", not twelve
        (99.996, (100.0,), 4, "99.996"),  # rounds up to the bound at four digits: "100" would hide it
        (-100.0412, (-100.0,), 4, "-100.04"),
        (5.0004, (5.0, 10.0), 4, "5.0004"),  # apart from the nearer of two bounds
        (5.12345, (5.0, 10.0), 4, "5.123"),  # already apart from both: num's four digits
        (100.0412345, (100.0,), 6, "100.041"),  # digits is where the search starts
        (100.0, (100.0,), 4, "100"),  # equal to its bound: nothing to set apart
        (2.0, (math.nan, math.inf), 4, "2"),  # a bound that is not finite is ignored
        (None, (1.0,), 4, "n/a"),
    ],
)
def test_num_apart_adds_the_fewest_digits_that_part_a_number_from_its_bounds(
    value: float | None, bounds: tuple[float, ...], digits: int, text: str
) -> None:
    """num_apart(v, bounds, digits) is num(v, digits) with as many more significant digits as it takes not to read
    as a bound v differs from (a 99.996 % over a 100 % limit is not written "100")."""
    assert num_apart(value, bounds, digits) == text
