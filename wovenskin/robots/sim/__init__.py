"""The simulated TM5-900 (the default robot): MuJoCo model, DH kinematics, mink IK.

:mod:`.tm5_900` holds the arm's DH table, limits and postures, ``tm5_900.xml`` the MuJoCo
model built from them, :mod:`.ik` the differential IK, :mod:`.robot` the
:class:`SimRobot` backend and :mod:`.config` its robot spec (``sim``).
"""

from wovenskin.robots.sim.ik import DifferentialIK, IKInfo, SingularityThresholds
from wovenskin.robots.sim.robot import SimRobot

__all__ = ["DifferentialIK", "IKInfo", "SimRobot", "SingularityThresholds"]
