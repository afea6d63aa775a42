"""Shared fixtures."""

from __future__ import annotations

import pytest
from fakes import FakeBackend


@pytest.fixture
def fake_backend() -> type[FakeBackend]:
    return FakeBackend
