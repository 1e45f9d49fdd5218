"""What the ``ros2:`` backend needs to know besides the arm's URDF: topics, frame, domain,
the Servo node and the timeouts. Plain data, importable without ``cyclonedds``."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Ros2Settings:
    """Where the arm is on ROS 2 and how long to wait for it (see :mod:`.config`)."""

    twist_topic: str = "/servo_node/delta_twist_cmds"
    joints_topic: str = "/joint_states"
    frame: str | None = None  # the twists' frame_id; None: the mapping's (tip or base link)
    domain: int | None = None  # None: ROS_DOMAIN_ID, else 0
    servo: str = "/servo_node"  # whose ~/switch_command_type to call; "": do not
    joint_timeout_s: float = 0.1
    command_timeout_s: float = 0.1
    connect_timeout_s: float = 5.0
