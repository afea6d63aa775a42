"""Progress: an overall count with the ETA on a terminal; nothing off a terminal, in CI or when quiet."""

from __future__ import annotations

import io

import pytest

from legbench import progress


class _Tty(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_count_and_last_item_are_drawn_on_a_terminal(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("CI", raising=False)
    out = _Tty()
    with progress.bar(4, "runs", stream=out) as bar:
        assert bar.drawn
        bar.update(1, "effort/mujoco")
        bar.update(2)
        bar.write("a message")
    text = out.getvalue()
    assert "runs: 1/4 runs" in text and "effort/mujoco" in text and "runs: 3/4 runs" in text
    assert "a message\n" in text and bar.n == 3


@pytest.mark.parametrize("case", ["quiet", "ci", "pipe"])
def test_nothing_is_drawn_when_quiet_in_ci_or_off_a_terminal(monkeypatch: pytest.MonkeyPatch, case: str) -> None:
    monkeypatch.delenv("CI", raising=False)
    if case == "ci":
        monkeypatch.setenv("CI", "true")
    out = io.StringIO() if case == "pipe" else _Tty()
    with progress.bar(2, "runs", quiet=case == "quiet", stream=out) as bar:
        bar.update(2, "x")
        assert not bar.drawn and bar.n == 2
        bar.write("still said")
    assert out.getvalue() == "still said\n"  # messages still reach the user, plain
