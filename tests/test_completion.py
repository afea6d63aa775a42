"""Shell completion (argcomplete): the completions of subcommands and options, and the shell code."""

from __future__ import annotations

import os
import shlex
import subprocess
import sys

import pytest

from legbench import cli

argcomplete = pytest.importorskip("argcomplete")


def _complete(line: str) -> list[str]:
    """What bash would offer after ``line``: argcomplete's protocol, as bash runs it (COMP_LINE / COMP_POINT in the
    environment, the words out on file descriptor 8), in a subprocess since argcomplete rewires the streams."""
    env = os.environ | {
        "_ARGCOMPLETE": "1",
        "COMP_LINE": line,
        "COMP_POINT": str(len(line)),
        "_ARGCOMPLETE_IFS": "\013",
    }
    cmd = f"{shlex.quote(sys.executable)} -m legbench.cli 8>&1 1>/dev/null 2>/dev/null"
    out = subprocess.run(["bash", "-c", cmd], env=env, capture_output=True, text=True, check=True, timeout=300).stdout
    return sorted(w.strip() for w in out.split("\013"))  # a single match comes with its trailing space


def test_subcommands_and_options_complete() -> None:
    """A subcommand, a choice of a subcommand's option (only that subcommand's module imported), a global option."""
    assert _complete("legbench re") == ["reproduce"]
    assert _complete("legbench run --contact-mode b") == ["both"]
    assert _complete("legbench run --variant engine") == ["engine-defaults:native", "engine-defaults:reference"]
    assert _complete("legbench --mo") == ["--model"]


def test_completion_command_prints_shell_code(capsys: pytest.CaptureFixture[str]) -> None:
    assert cli.main(["completion", "bash"]) == 0
    code = capsys.readouterr().out
    assert "complete " in code and "legbench" in code and "_ARGCOMPLETE" in code
    assert cli.main(["completion", "zsh"]) == 0
    assert "#compdef legbench" in capsys.readouterr().out
    assert "_ARGCOMPLETE" not in os.environ
