"""Shared fixtures."""

from __future__ import annotations

import signal
from collections.abc import Iterator

import pytest
from fakes import FakeBackend


@pytest.fixture(autouse=True, scope="session")
def _sigint_as_in_a_terminal() -> Iterator[None]:
    """Ctrl-C as a user's terminal delivers it: the default handler (KeyboardInterrupt).

    A test run started in the background by a non-interactive shell (``make test &``, nohup, some CI runners)
    inherits SIGINT ignored, and an ignored signal stays ignored in every process it starts; Python (and so
    legbench) keeps it ignored, as it must for a background job. The interrupt tests send SIGINT to legbench
    processes and need a terminal's setting, whoever started the suite.
    """
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, previous)


@pytest.fixture
def fake_backend() -> type[FakeBackend]:
    return FakeBackend
