"""Universal Robots arms through ``ur_rtde`` (install ``wovenskin[ur]``): :class:`URRobot`."""

from wovenskin.robots.ur.robot import URRobot

__all__ = ["URRobot"]
