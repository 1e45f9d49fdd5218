"""Universal Robots arms through ``ur_rtde`` (install ``wovenskin[ur]``): :class:`URRobot`.

:mod:`.models` holds the e-series arms' kinematics, :mod:`.robot` the backend and
:mod:`.config` its robot spec (``ur:HOST?model=ur5e``).
"""

from wovenskin.robots.ur.robot import URRobot

__all__ = ["URRobot"]
