"""Techman arms over TMflow's Listen Node (scripts) and Ethernet Slave (state).

:mod:`.protocol` is the packet format, :mod:`.ethernet_slave` the state data table
(binary and JSON modes), :mod:`.velocity` the velocity-mode timeouts, :mod:`.connection`
the two links, :mod:`.client` the :class:`TechmanRobot` backend and :mod:`.config` its
robot spec; :mod:`.fake_controller` and :mod:`.fake_server` are a stand-in controller
built from Techman's public material, for tests. docs/techman.md
explains the setup and cites the sources.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from wovenskin.robots.techman.client import TechmanRobot

if TYPE_CHECKING:
    from wovenskin.robots.techman.fake_server import FakeListenNode

__all__ = ["FakeListenNode", "TechmanRobot"]


def __getattr__(name: str) -> object:
    """``FakeListenNode`` is imported on first use, so ``python -m
    wovenskin.robots.techman.fake_server`` runs the module once, as ``__main__``."""
    if name == "FakeListenNode":
        from wovenskin.robots.techman.fake_server import FakeListenNode

        return FakeListenNode
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
