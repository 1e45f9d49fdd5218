"""ROS 2 time stamps: ``builtin_interfaces/msg/Time`` from and to the system clock.

MoveIt Servo drops a twist whose stamp is older than its ``incoming_command_timeout``
(measured against its node's clock, the system clock unless ``use_sim_time``), so every
command is stamped with :func:`time.time_ns` when it is sent, never with the skin's stream
clock. Stamps are ``(sec, nanosec)`` with ``0 <= nanosec < 1e9``, ``sec`` a signed 32-bit
count (ROS 2's range: until 2038).
"""

from __future__ import annotations

import time

NANOSECONDS = 1_000_000_000
INT32_MAX = 2**31 - 1


def split_ns(ns: int) -> tuple[int, int]:
    """``(sec, nanosec)`` of a time in integer nanoseconds since the epoch; ``ValueError``
    when ``sec`` would not fit ROS 2's signed 32-bit field."""
    sec, nanosec = divmod(int(ns), NANOSECONDS)
    if not -INT32_MAX - 1 <= sec <= INT32_MAX:
        raise ValueError(f"time {ns} ns is outside the range of a ROS 2 stamp")
    return sec, nanosec


def join_ns(sec: int, nanosec: int) -> int:
    """Integer nanoseconds since the epoch of a ``(sec, nanosec)`` stamp."""
    return int(sec) * NANOSECONDS + int(nanosec)


def now_ns() -> int:
    """The system clock (what a ROS 2 node's clock reads without ``use_sim_time``), ns."""
    return time.time_ns()
