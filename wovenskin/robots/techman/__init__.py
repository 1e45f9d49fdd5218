"""Techman arms over TMflow's Listen Node (scripts) and Ethernet Slave (state).

:mod:`.protocol` is the packet format, :mod:`.ethernet_slave` the state data table
(binary and JSON modes), :mod:`.velocity` the velocity-mode timeouts, :mod:`.client` the
:class:`TechmanRobot` backend; :mod:`.fake_controller` and :mod:`.fake_server` are a
stand-in controller built from Techman's public material, for tests. docs/techman.md
explains the setup and cites the sources.
"""

from wovenskin.robots.techman.client import TechmanRobot
from wovenskin.robots.techman.fake_server import FakeListenNode

__all__ = ["FakeListenNode", "TechmanRobot"]
