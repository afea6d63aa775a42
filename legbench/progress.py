"""Progress of long commands: an overall count with the ETA, on stderr, only where a person watches.

One small API for every stage that does many pieces of work (runs of ``legbench
run --jobs N``, sweep runs, report pages)::

    with progress.bar(total=len(tasks), desc="runs", quiet=args.quiet) as bar:
        for result in pool.imap(...):
            bar.update(1, f"{scenario}/{backend}")

The bar is drawn by tqdm, on stderr, only when stderr is a terminal, the
environment variable ``CI`` is not set and the caller did not ask for quiet
(:func:`enabled`); otherwise :func:`bar` gives a :class:`Progress` that counts
and draws nothing. :meth:`Progress.write` prints a line above the bar (or plain
to stderr when there is no bar), so messages and the bar do not mix.
"""

from __future__ import annotations

import os
import shutil
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any, TextIO

__all__ = ["BAR_FORMAT", "Progress", "bar", "enabled"]

#: What the bar shows: ``runs: 3/56 runs |####    | 00:41<02:10, effort/mujoco`` (count, elapsed<ETA, last done).
BAR_FORMAT = "{desc}: {n}/{total} {unit}s |{bar}| {elapsed}<{remaining}{postfix}"


def enabled(quiet: bool = False, stream: TextIO | None = None) -> bool:
    """A bar is drawn: not ``quiet``, ``CI`` unset (or empty), and the stream (stderr) is a terminal."""
    stream = sys.stderr if stream is None else stream
    if quiet or os.environ.get("CI"):
        return False
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError):  # a closed or replaced stream
        return False


class Progress:
    """A count of finished pieces of work out of ``total``, drawn (tqdm) or silent.

    Attributes:
        total: pieces of work expected.
        n: pieces finished so far.
    """

    def __init__(self, total: int, desc: str = "", unit: str = "run", draw: bool = False,
                 stream: TextIO | None = None) -> None:  # fmt: skip
        self.total = int(total)
        self.n = 0
        self._stream = sys.stderr if stream is None else stream
        self._tqdm: Any = None
        if draw:
            from tqdm import tqdm  # imported only when a bar is drawn

            # every update drawn (a few hundred at most): the count is what a watcher (or a test) waits for
            # the size given, not asked of the terminal: a pseudo-terminal of size 0 x 0 would hide the bar
            size = shutil.get_terminal_size((100, 24))
            self._tqdm = tqdm(total=self.total, desc=desc, unit=unit, file=self._stream,
                              ncols=min(size.columns, 120), nrows=max(size.lines, 2),
                              leave=False, mininterval=0.0, miniters=1,
                              bar_format=BAR_FORMAT)  # fmt: skip

    @property
    def drawn(self) -> bool:
        """A bar is on the terminal."""
        return self._tqdm is not None

    def update(self, n: int = 1, last: str | None = None) -> None:
        """``n`` more pieces finished; ``last`` (e.g. ``effort/mujoco``) is shown beside the bar."""
        self.n += n
        if self._tqdm is not None:
            if last is not None:
                self._tqdm.set_postfix_str(last, refresh=False)
            self._tqdm.update(n)

    def write(self, message: str) -> None:
        """A line for the user on stderr, above the bar if one is drawn."""
        if self._tqdm is not None:
            self._tqdm.write(message, file=self._stream)
        else:
            print(message, file=self._stream, flush=True)

    def close(self) -> None:
        """Remove the bar from the terminal."""
        if self._tqdm is not None:
            self._tqdm.close()
            self._tqdm = None


@contextmanager
def bar(total: int, desc: str = "", unit: str = "run", quiet: bool = False,
        stream: TextIO | None = None) -> Iterator[Progress]:  # fmt: skip
    """A :class:`Progress` for ``total`` pieces of work, drawn when :func:`enabled`; closed on exit.

    Args:
        total: pieces of work expected.
        desc: what is counted, shown before the count (``runs``, ``sweep timestep``).
        unit: name of one piece (``run``, ``page``); the bar shows ``n/total units``.
        quiet: never draw (``--quiet``).
        stream: where to draw (default stderr).
    """
    p = Progress(total, desc, unit, enabled(quiet, stream), stream)
    try:
        yield p
    finally:
        p.close()
