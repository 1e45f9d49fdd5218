"""Techman arms over TMflow's Listen Node (scripts) and Ethernet Slave (state).

:mod:`.protocol` is the packet format, :mod:`.client` the :class:`TechmanRobot` backend,
:mod:`.fake_server` a loopback stand-in robot for tests.
"""

from wovenskin.robots.techman.client import TechmanRobot
from wovenskin.robots.techman.fake_server import FakeListenNode

__all__ = ["FakeListenNode", "TechmanRobot"]
