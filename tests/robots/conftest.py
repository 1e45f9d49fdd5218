"""Fixtures the robot tests share: a fake Techman controller on loopback."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from wovenskin.robots.techman import FakeListenNode


@pytest.fixture
def fake() -> Iterator[FakeListenNode]:
    """A fake TMflow Listen Node and Ethernet Slave on loopback, closed after the test."""
    with FakeListenNode() as node:
        yield node
