"""Arms driven through ROS 2 and MoveIt Servo, with no ROS install (``wovenskin[ros2]``).

:mod:`.robot` is the backend (twists out, joint states in, kinematics from a URDF),
:mod:`.moves` turns point-to-point moves into streamed twists, :mod:`.servo_service` calls
MoveIt Servo's ``~/switch_command_type``, :mod:`.config` reads the ``ros2:`` robot spec and
:mod:`.standin` is a stand-in for MoveIt Servo that tests and ``wovenskin bench ros2``
drive in another process.
"""
