"""Ros2Robot: an arm under MoveIt Servo, driven over ROS 2 with no ROS install.

Twists go out as ``geometry_msgs/msg/TwistStamped`` on Servo's twist topic (default
``/servo_node/delta_twist_cmds``), one per control tick while the arm is commanded to move
and one zero twist when it stops, stamped with the system clock and expressed in ``frame``:
any link of the chain, whose axes at the current joint angles the base-frame twist is
turned into (default: the mapping's frame, the tip for a tool-frame mapping, else the base).
Joint angles come in as ``sensor_msgs/msg/JointState`` (default ``/joint_states``), matched
by name to the chain's joints; the tool centre point's pose, its Jacobian and the joint
limits come from the arm's URDF (default: the TM5-900's, with Techman's ROS joint names).

A watch thread (every :data:`WATCH_PERIOD_S`) reads the joint states as they arrive and

- sends a zero twist, and reports a fault on every later call, when none has arrived for
  ``joint_timeout_s``: the arm stops and the user is told why;
- sends a zero twist when a moving twist has not been renewed for ``command_timeout_s``
  (a stalled control loop; Servo's own ``incoming_command_timeout`` is the second line);
- streams the twists of a point-to-point move (:mod:`.moves`).

Zero twists also go out on :meth:`stop` and :meth:`disconnect`. On connect the backend waits
for the first joint state and, unless ``servo`` is empty, asks Servo to take twists through
its ``~/switch_command_type`` service (:mod:`.servo_service`).

What the safety layer gets (:meth:`Ros2Robot.capabilities`): the URDF's kinematics, so its
workspace box, speed caps and joint-margin look-ahead all run here. Collision checking and
singularity handling are Servo's (``check_collisions``, its singularity thresholds): this
backend knows no obstacles.
"""

from __future__ import annotations

import contextlib
import threading
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from wovenskin.errors import MissingExtraError
from wovenskin.robots.base import (
    JointLimits,
    Pose,
    Robot,
    RobotCapabilities,
    RobotError,
    RobotState,
    check_pose_move,
    command_twist,
    joint_move_target,
)
from wovenskin.robots.ros2 import servo_service
from wovenskin.robots.ros2.joint_states import JointStateReader
from wovenskin.robots.ros2.moves import CartesianMove, JointMove, MoveFailed
from wovenskin.robots.ros2.settings import Ros2Settings
from wovenskin.robots.sim import tm5_900
from wovenskin.robots.urdf import UrdfChain
from wovenskin.ros2 import messages
from wovenskin.ros2.clock import now_ns, split_ns
from wovenskin.ros2.node import COMMANDS, SENSOR_DATA, Ros2Error, Ros2Node

WATCH_PERIOD_S = 0.01
MAX_POSE_SPEED = 0.25  # m/s, the fastest move_to_pose streamed
POSE_ANGULAR_SPEED = 0.5  # rad/s, the fastest turn of a streamed pose move
TRACKING_ERROR = 0.05  # assumed allowance for Servo's smoothing (not measured on a real arm)
RELEASE_STOP_S = 0.001  # Servo smooths a step to zero itself: send it on the lift-off's tick
LEFT_TO_SERVO = (
    "collision checking (MoveIt Servo's check_collisions, against its planning scene)",
    "singularity handling (MoveIt Servo's lower/hard_stop_singularity_threshold)",
)


class Ros2Robot(Robot):
    """An arm under MoveIt Servo over ROS 2 (DDS through Cyclone DDS)."""

    name = "ros2"

    def __init__(
        self,
        chain: UrdfChain,
        settings: Ros2Settings | None = None,
        *,
        is_default_arm: bool = False,
        node_factory: Callable[[int | None], Any] = Ros2Node,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        """``chain``: the arm's kinematics (base link to Servo's end-effector frame);
        ``is_default_arm``: the chain is the packaged TM5-900 (the 3D view draws it)."""
        self.chain = chain
        self.settings = settings or Ros2Settings()
        self.frame = self.settings.frame or chain.base_link
        chain.link_pose(np.zeros(len(chain.joint_names)), self.frame)  # an unknown frame: now
        self._is_default_arm = is_default_arm
        self._node_factory = node_factory
        self._clock = clock
        self._lock = threading.RLock()
        self._node: Any = None
        self._twists: Any = None
        self._joints: JointStateReader | None = None
        self._thread: threading.Thread | None = None
        self._closing = threading.Event()
        self._sent = np.zeros(6)  # the last twist published, base frame
        self._sent_t = 0.0
        self._commanded_t = 0.0  # when send_twist last ran
        self._move: JointMove | CartesianMove | None = None
        self._move_error: str | None = None
        self._fault: str | None = None
        self.published = 0  # twists sent, zero twists included

    def use_mapping_frame(self, frame: str) -> None:
        """Without ``frame=`` in the spec, twists go out in the mapping's frame: the tip's
        axes for a tool- or skin-frame mapping (Servo's end-effector frame), else the base's."""
        if self.settings.frame is None:
            self.frame = self.chain.base_link if frame == "base" else self.chain.tip_link

    # -- connection -------------------------------------------------------------------

    def connect(self) -> None:
        if self._node is not None:
            return
        try:
            node = self._node_factory(self.settings.domain)
        except (Ros2Error, MissingExtraError) as exc:
            raise RobotError(str(exc)) from None
        try:
            self._twists = node.publisher(
                self.settings.twist_topic, messages.TwistStamped, COMMANDS
            )
            subscription = node.subscription(
                self.settings.joints_topic, messages.JointState, SENSOR_DATA
            )
            self._joints = JointStateReader(subscription, self.chain.joint_names, self._clock)
            self._node = node
            self._wait_for_joint_states()
            if self.settings.servo:
                servo_service.switch_to_twist(
                    node, self.settings.servo, self.settings.connect_timeout_s
                )
        except (Ros2Error, RobotError, servo_service.ServiceError) as exc:
            self._release()
            raise RobotError(" ".join(str(exc).split())) from None
        except Exception:
            self._release()
            raise
        self._closing.clear()
        self._commanded_t = self._clock()
        self._thread = threading.Thread(target=self._watch, name="ros2-watch", daemon=True)
        self._thread.start()

    def _wait_for_joint_states(self) -> None:
        assert self._joints is not None
        deadline = self._clock() + self.settings.connect_timeout_s
        while self._clock() < deadline:
            if self._joints.poll() is not None:
                return
            time.sleep(WATCH_PERIOD_S)
        problem = self._joints.problem or "none arrived"
        raise RobotError(
            f"no usable joint states on {self.settings.joints_topic} in ROS 2 domain "
            f"{self._node.domain_id} within {self.settings.connect_timeout_s:g} s ({problem}); "
            "is the arm's driver running, on this domain and network (CYCLONEDDS_URI)?"
        )

    def disconnect(self) -> None:
        if self._node is None:
            return
        self._closing.set()
        if self._thread is not None:
            self._thread.join(timeout=1.0)
            self._thread = None
        with contextlib.suppress(Exception):
            self._publish(np.zeros(6))
        time.sleep(0.05)  # let the reliable writer deliver the zero twist before leaving
        self._release()

    def _release(self) -> None:
        node, self._node = self._node, None
        self._twists = self._joints = None
        if node is not None:
            with contextlib.suppress(Exception):
                node.close()

    # -- the watch thread -------------------------------------------------------------

    def _watch(self) -> None:
        while not self._closing.wait(WATCH_PERIOD_S):
            with self._lock:
                try:
                    self._watch_once(self._clock())
                except Exception as exc:  # the thread must not die silently with the arm moving
                    self._fault = f"ROS 2 link failed: {' '.join(str(exc).split())}"
                    with contextlib.suppress(Exception):
                        self._publish(np.zeros(6))

    def _watch_once(self, now: float) -> None:
        assert self._joints is not None
        self._joints.poll()
        age = self._joints.age(now)
        if age > self.settings.joint_timeout_s:
            if self._fault is None:
                self._fault = (
                    f"no joint states on {self.settings.joints_topic} for {1000 * age:.0f} ms; "
                    "the arm was stopped"
                )
                self._move = None
                self._publish(np.zeros(6))
            return
        if self._fault is not None and self._fault.startswith("no joint states"):
            self._fault = None  # they flow again: a new command may move the arm
        if self._move is not None:
            self._step_move(now)
        elif np.any(self._sent) and now - self._commanded_t > self.settings.command_timeout_s:
            self._publish(np.zeros(6))  # the control loop stalled: stop until it speaks

    def _step_move(self, now: float) -> None:
        assert self._move is not None and self._joints is not None
        q = self._joints.latest().q
        try:
            twist = self._move.twist(q, now, self.chain.kinematics())
        except MoveFailed as exc:
            self._move, self._move_error = None, str(exc)
            self._publish(np.zeros(6))
            return
        if twist is None:
            self._move = None
            self._publish(np.zeros(6))
        else:
            self._publish(twist)

    # -- publishing -------------------------------------------------------------------

    def _publish(self, twist: np.ndarray) -> None:
        """Send ``twist`` (base frame) in the twist frame, stamped now."""
        if self._twists is None:
            return
        expressed = np.asarray(twist, dtype=float)
        if self.frame != self.chain.base_link and np.any(expressed):
            assert self._joints is not None
            rotation = self.chain.link_pose(self._joints.latest().q, self.frame)[:3, :3]
            expressed = np.concatenate([rotation.T @ expressed[:3], rotation.T @ expressed[3:]])
        sec, nanosec = split_ns(now_ns())
        self._twists.publish(
            messages.TwistStamped(
                header=messages.Header(messages.Time(sec, nanosec), self.frame),
                twist=messages.Twist(
                    messages.Vector3(*map(float, expressed[:3])),
                    messages.Vector3(*map(float, expressed[3:])),
                ),
            )
        )
        self._sent = np.array(twist, dtype=float)
        self._sent_t = self._clock()
        self.published += 1

    # -- the Robot interface ----------------------------------------------------------

    def capabilities(self) -> RobotCapabilities:
        """The URDF's kinematics (the safety layer's full checks run), the TM5-900's
        drawing when the URDF is the packaged one, an assumed tracking allowance for
        Servo's smoothing, and a release brake of one tick: Servo's smoothing filter
        ramps the zero twist of a lift-off, so it goes out at once. Collisions and
        singularities are declared left to Servo (the session says so). No stop profile is
        declared: Servo's deceleration is its own setting, so the safety layer assumes its
        conservative stop time."""
        return RobotCapabilities(
            kinematics=self.chain.kinematics(),
            scene=tm5_900.scene() if self._is_default_arm else None,
            control_period_s=WATCH_PERIOD_S,
            tracking_error=TRACKING_ERROR,
            release_stop_s=RELEASE_STOP_S,
            left_to_controller=LEFT_TO_SERVO,
            how_to_complete="give the arm's URDF in the robot spec (ros2:?urdf=PATH&tip=LINK)",
        )

    def joint_limits(self) -> JointLimits:
        return self.chain.limits

    def _require(self) -> JointStateReader:
        if self._node is None or self._joints is None:
            raise RobotError("ROS 2 arm is not connected")
        return self._joints

    def state(self) -> RobotState:
        with self._lock:
            joints = self._require()
            joints.poll()
            latest = joints.latest()
            fault, self._move_error = self._fault or self._move_error, None
            moving = self._move is not None or bool(np.any(self._sent))
        tcp = Pose.from_transform(self.chain.forward(latest.q))
        return RobotState(
            t=self._clock(),
            q=latest.q,
            dq=latest.dq,
            tcp=tcp,
            tcp_twist=self.chain.jacobian(latest.q) @ latest.dq,
            moving=moving or float(np.max(np.abs(latest.dq))) > 1e-3,
            fault=fault,
        )

    def send_twist(self, twist: np.ndarray) -> None:
        command = command_twist(twist)
        with self._lock:
            self._require()
            self._commanded_t = self._clock()
            if self._fault is not None:
                self._publish(np.zeros(6))
                raise RobotError(self._fault)
            self._move = None
            self._publish(command)

    def move_to_joints(self, q: np.ndarray, speed_fraction: float = 0.2) -> None:
        target = joint_move_target(q, speed_fraction, self.chain.limits)
        with self._lock:
            joints = self._require()
            if self._fault is not None:
                raise RobotError(self._fault)
            start = joints.latest().q
            self._move = JointMove.plan(
                start, target, speed_fraction, self.chain.limits, self._clock()
            )

    def move_to_pose(self, pose: Pose, speed: float = 0.05) -> None:
        check_pose_move(pose, speed, MAX_POSE_SPEED)
        with self._lock:
            joints = self._require()
            if self._fault is not None:
                raise RobotError(self._fault)
            start = Pose.from_transform(self.chain.forward(joints.latest().q))
            self._move = CartesianMove.plan(start, pose, speed, POSE_ANGULAR_SPEED, self._clock())

    def stop(self) -> None:
        with self._lock:
            if self._node is None:
                return
            self._move = None
            self._publish(np.zeros(6))
