"""A stand-in for MoveIt Servo: takes twists, moves a kinematic arm, publishes its joints.

It is not Servo; it does what wovenskin relies on Servo and the arm's driver for, so the
``ros2:`` backend can be driven end to end in another process with no ROS install:

- ``<servo>/switch_command_type`` (``moveit_msgs/srv/ServoCommandType``): twists are
  followed only after a request for ``TWIST`` (as Servo, which starts in another mode);
- twists on the twist topic (``geometry_msgs/msg/TwistStamped``) in the chain's base frame
  or any link of the chain, dropped as stale when their stamp is older than
  ``incoming_command_timeout`` against the system clock (Servo's rule);
- a receiver thread takes each twist as it arrives; every cycle the joints move by damped
  least squares, ``dq = J^T (J J^T + l^2 I)^-1 v``, capped at the URDF's joint speeds,
  and ``sensor_msgs/msg/JointState`` goes out (a driver's ``joint_state_broadcaster``).

Every twist received is logged as one JSON line with its CDR bytes, the receiver's clocks
and the integrated joints, so a test can decode it with an independent serialiser and
check stamps and timing; ``silence_after_s`` stops the joint states that long after the
first moving twist (the arm goes on following twists) to test what the client does.
"""

from __future__ import annotations

import json
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

import numpy as np

from wovenskin.robots.ros2 import servo_service
from wovenskin.robots.urdf import UrdfChain
from wovenskin.ros2 import messages
from wovenskin.ros2.clock import join_ns, now_ns, split_ns
from wovenskin.ros2.node import COMMANDS, Ros2Node

DAMPING = 0.01  # damped least squares' lambda (m, rad)


@dataclass(frozen=True)
class StandinSettings:
    """The stand-in's topics, rates and behaviour."""

    twist_topic: str = "/servo_node/delta_twist_cmds"
    joints_topic: str = "/joint_states"
    servo: str = "/servo_node"
    rate_hz: float = 100.0  # integration and joint-state rate
    incoming_command_timeout_s: float = 0.1  # Servo's default
    require_twist_mode: bool = True
    silence_after_s: float | None = None  # stop joint states this long after motion starts


class StandinServo:
    """The stand-in's node and arm; :meth:`run` serves until a deadline or interrupt."""

    def __init__(
        self,
        chain: UrdfChain,
        q0: np.ndarray,
        settings: StandinSettings | None = None,
        *,
        domain: int | None = None,
        log: IO[str] | None = None,
    ) -> None:
        self.chain = chain
        self.settings = settings or StandinSettings()
        self.q = np.array(q0, dtype=float)
        self.dq = np.zeros_like(self.q)
        self._log = log
        self.node = Ros2Node(domain)
        self._twists = self.node.subscription(
            self.settings.twist_topic, messages.TwistStamped, COMMANDS
        )
        self._joints = self.node.publisher(
            self.settings.joints_topic, messages.JointState, COMMANDS
        )
        self._requests, self._replies = self.node.service_endpoints(
            f"{self.settings.servo.rstrip('/')}/{servo_service.SERVICE}",
            messages.ServoCommandTypeRequest,
            messages.ServoCommandTypeResponse,
            server=True,
        )
        self.twist_mode = not self.settings.require_twist_mode
        self._command: tuple[np.ndarray, int, str] | None = None  # twist, stamp ns, frame
        self._moving_since: float | None = None
        self.silenced_at_ns: int | None = None
        self.received = 0
        self._lock = threading.Lock()  # the receiver thread and the cycle share the command
        self._closing = threading.Event()

    def _write(self, record: dict[str, Any]) -> None:
        if self._log is not None:
            with self._lock:
                self._log.write(json.dumps(record) + "\n")

    def _receive(self) -> None:
        """The receiver thread: each twist is taken (and timed) the moment it arrives."""
        while not self._closing.is_set():
            if self._twists.wait(0.05):
                for data, _source_ns in self._twists.take_serialized():
                    self._received(data)

    def run(self, seconds: float | None = None) -> None:
        """Serve every ``1 / rate_hz`` s until ``seconds`` pass (None: until interrupted)."""
        period = 1.0 / self.settings.rate_hz
        start = time.monotonic()
        self._write({"event": "start", "wall_ns": now_ns(), "mono_ns": time.monotonic_ns()})
        next_t = start
        receiver = threading.Thread(target=self._receive, name="standin-twists", daemon=True)
        receiver.start()
        try:
            while not self._closing.is_set() and (
                seconds is None or time.monotonic() - start < seconds
            ):
                next_t += period
                self.cycle(period)
                time.sleep(max(0.0, next_t - time.monotonic()))
        finally:
            self._closing.set()
            receiver.join(timeout=1.0)
            self._write({"event": "end", "wall_ns": now_ns(), "q": self.q.tolist()})
            if self._log is not None:
                self._log.flush()

    def cycle(self, dt: float) -> None:
        """One cycle: answer the service, take twists, move the arm, publish its joints."""
        servo_service.serve_requests(self._requests, self._replies, self._switch)
        twist = self._fresh_twist()
        self._integrate(twist, dt)
        if twist is not None and np.any(twist) and self._moving_since is None:
            self._moving_since = time.monotonic()
        if self._silence_due():
            self.silenced_at_ns = now_ns()
            self._write({"event": "joint_states_stopped", "wall_ns": self.silenced_at_ns})
        if self.silenced_at_ns is None:
            self._publish_joints()

    def _silence_due(self) -> bool:
        silence = self.settings.silence_after_s
        if silence is None or self._moving_since is None or self.silenced_at_ns is not None:
            return False
        return time.monotonic() - self._moving_since >= silence

    def _switch(self, command_type: int) -> bool:
        self._write({"event": "switch_command_type", "wall_ns": now_ns(), "type": command_type})
        self.twist_mode = command_type == messages.ServoCommandTypeRequest.TWIST
        return True

    def _received(self, data: bytes) -> None:
        wall, mono = now_ns(), time.monotonic_ns()
        self.received += 1
        message = messages.TwistStamped.deserialize(data)
        linear, angular = message.twist.linear, message.twist.angular
        twist = np.array([linear.x, linear.y, linear.z, angular.x, angular.y, angular.z])
        stamp = join_ns(message.header.stamp.sec, message.header.stamp.nanosec)
        with self._lock:
            self._command = (twist, stamp, message.header.frame_id)
        self._write(
            {
                "event": "twist",
                "wall_ns": wall,
                "mono_ns": mono,
                "stamp_ns": stamp,
                "frame_id": message.header.frame_id,
                "twist": twist.tolist(),
                "cdr": data.hex(),
                "twist_mode": self.twist_mode,
                "q": self.q.tolist(),
            }
        )

    def _fresh_twist(self) -> np.ndarray | None:
        """The latest twist in the base frame, if Servo would follow it now."""
        with self._lock:
            command = self._command
        if command is None or not self.twist_mode:
            return None
        twist, stamp, frame = command
        if (now_ns() - stamp) * 1e-9 > self.settings.incoming_command_timeout_s:
            return None
        if frame == self.chain.base_link:
            return twist
        if frame not in self.chain.links:
            return None  # Servo would not find the frame either
        rotation = self.chain.link_pose(self.q, frame)[:3, :3]
        return np.concatenate([rotation @ twist[:3], rotation @ twist[3:]])

    def _integrate(self, twist: np.ndarray | None, dt: float) -> None:
        if twist is None or not np.any(twist):
            self.dq = np.zeros_like(self.q)
            return
        jacobian = self.chain.jacobian(self.q)
        damped = jacobian @ jacobian.T + DAMPING**2 * np.eye(6)
        dq = jacobian.T @ np.linalg.solve(damped, twist)
        limits = self.chain.limits
        scale = float(np.max(np.abs(dq) / limits.max_speed))
        if scale > 1.0:
            dq = dq / scale
        self.q = np.clip(self.q + dq * dt, limits.lower, limits.upper)
        self.dq = dq

    def _publish_joints(self) -> None:
        sec, nanosec = split_ns(now_ns())
        self._joints.publish(
            messages.JointState(
                header=messages.Header(messages.Time(sec, nanosec), ""),
                name=list(self.chain.joint_names),
                position=[float(v) for v in self.q],
                velocity=[float(v) for v in self.dq],
                effort=[],
            )
        )

    def stop(self) -> None:
        """End :meth:`run` (from another thread) after its current cycle."""
        self._closing.set()

    def close(self) -> None:
        self.node.close()


def read_log(path: str | Path) -> list[dict[str, Any]]:
    """The records of a stand-in's log, in order."""
    lines = Path(path).read_text(encoding="utf-8").splitlines()
    return [json.loads(line) for line in lines if line.strip()]
