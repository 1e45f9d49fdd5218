"""The ``sim`` robot spec: the common options only; it builds a :class:`SimRobot`."""

from __future__ import annotations

from wovenskin.robots.sim.robot import SimRobot
from wovenskin.robots.spec import Backend, RobotOptions, RobotSpec


def build_sim(spec: RobotSpec) -> SimRobot:
    """The simulated TM5-900 at its initial pose."""
    return SimRobot()


SIM = Backend("sim", build_sim, RobotOptions, address=False)
