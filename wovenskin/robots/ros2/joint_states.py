"""Reading an arm's joint angles from ``sensor_msgs/msg/JointState`` messages.

Drivers publish every joint they know (a gripper's too) in an order of their own; the
reader picks the chain's joints by name. A message that lacks one of them, or whose arrays
disagree in length or hold non-finite values, is dropped and counted, and the last such
problem is kept as one line for the error the user sees. Velocities are taken from the
message when it has them for every joint, else differenced from the previous message's
angles over the stamps' interval.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from wovenskin.robots.base import RobotError
from wovenskin.ros2.clock import join_ns


@dataclass(frozen=True)
class JointReading:
    """The chain's joints in one message: angles (rad), velocities (rad/s), when it came."""

    q: np.ndarray
    dq: np.ndarray
    received_t: float  # the reader's clock
    stamp_ns: int  # the message's header stamp


class JointStateReader:
    """The newest usable joint state of ``joint_names`` on a subscription."""

    def __init__(
        self, subscription: Any, joint_names: Sequence[str], clock: Callable[[], float]
    ) -> None:
        self._subscription = subscription
        self.joint_names = tuple(joint_names)
        self._clock = clock
        self._latest: JointReading | None = None
        self.received = 0
        self.dropped = 0
        self.problem: str | None = None

    def poll(self) -> JointReading | None:
        """Take what has arrived; the newest usable reading (``None`` before the first)."""
        now = self._clock()
        for message in self._subscription.take():
            self.received += 1
            try:
                self._latest = self._reading(message, now)
            except ValueError as exc:
                self.dropped += 1
                self.problem = str(exc)
        return self._latest

    def latest(self) -> JointReading:
        """The newest usable reading; :class:`RobotError` before the first."""
        if self._latest is None:
            raise RobotError(f"no usable joint state yet ({self.problem or 'none arrived'})")
        return self._latest

    def age(self, now: float) -> float:
        """Seconds since the newest usable reading arrived (infinite before the first)."""
        return math.inf if self._latest is None else now - self._latest.received_t

    def _reading(self, message: Any, now: float) -> JointReading:
        names = list(message.name)
        positions = list(message.position)
        velocities = list(message.velocity)
        if len(positions) != len(names):
            raise ValueError(f"joint state has {len(names)} names but {len(positions)} positions")
        index = {name: i for i, name in enumerate(names)}
        missing = [name for name in self.joint_names if name not in index]
        if missing:
            have = ", ".join(names[:8]) or "none"
            raise ValueError(f"joint state lacks {', '.join(missing)} (it has {have})")
        order = [index[name] for name in self.joint_names]
        q = np.array([positions[i] for i in order], dtype=float)
        if not np.all(np.isfinite(q)):
            raise ValueError("joint state has non-finite angles")
        stamp = join_ns(message.header.stamp.sec, message.header.stamp.nanosec)
        if len(velocities) == len(names):
            dq = np.array([velocities[i] for i in order], dtype=float)
            if not np.all(np.isfinite(dq)):
                raise ValueError("joint state has non-finite velocities")
        else:
            dq = self._differenced(q, stamp)
        return JointReading(q, dq, now, stamp)

    def _differenced(self, q: np.ndarray, stamp_ns: int) -> np.ndarray:
        previous = self._latest
        if previous is None or stamp_ns <= previous.stamp_ns:
            return np.zeros_like(q) if previous is None else previous.dq
        return (q - previous.q) / ((stamp_ns - previous.stamp_ns) * 1e-9)
