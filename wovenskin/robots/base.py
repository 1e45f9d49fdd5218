"""The robot interface every backend implements, and the types it speaks.

A backend (one folder each: ``sim``, ``techman``, ``ur``) drives one 6-DOF arm. It knows
nothing of gestures or safety: the control layer decides what to send and
:class:`wovenskin.control.safety.SafetyLayer` checks every command before it reaches a
backend. Units are SI throughout: metres, radians, seconds; twists are
``[vx, vy, vz, wx, wy, wz]`` in the robot **base** frame (the control layer converts
tool-frame twists); quaternions are ``[w, x, y, z]``.

A backend's methods raise :class:`RobotError` with a one-line message when the arm
cannot do what was asked (disconnected, fault, unreachable pose); they never leave the arm
moving after an error.

Beyond the abstract methods, a backend declares what else it offers in
:meth:`Robot.capabilities` (a :class:`RobotCapabilities`): its kinematic model, the scene
to draw, named default poses, how it stops and how closely it follows a twist. Nothing is
found by probing for method names: the safety layer refuses an arm whose declaration lacks
what its checks need unless the user opts into degraded safety
(:attr:`Robot.degraded_safety`, set by the robot spec's ``safety=degraded``).
"""

from __future__ import annotations

import abc
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from wovenskin.errors import DeviceError

N_JOINTS = 6


class RobotError(DeviceError, RuntimeError):
    """A robot backend could not carry out a command; the message is one line.

    A :class:`~wovenskin.errors.DeviceError` (the command line prints it as one line); it
    stays a ``RuntimeError``, as it was before the error root existed.
    """


def finite_vector(values: object, size: int, what: str) -> np.ndarray:
    """``values`` as a float vector of ``size`` finite numbers; else a one-line ``ValueError``
    naming ``what`` (every backend and the safety layer check commands with this)."""
    try:
        vector = np.array(values, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{what} is not numeric") from None
    if vector.shape != (size,):
        raise ValueError(f"{what} must have shape ({size},), got {vector.shape}")
    if not np.all(np.isfinite(vector)):
        raise ValueError(f"{what} has non-finite values")
    return vector


@dataclass(frozen=True)
class Pose:
    """A pose of the tool centre point in the base frame."""

    position: np.ndarray  # (3,) metres
    quat: np.ndarray  # (4,) [w, x, y, z], unit norm

    def __post_init__(self) -> None:
        position = np.asarray(self.position, dtype=float).reshape(3)
        quat = np.asarray(self.quat, dtype=float).reshape(4)
        if not (np.all(np.isfinite(position)) and np.all(np.isfinite(quat))):
            raise ValueError("pose has non-finite values")
        norm = float(np.linalg.norm(quat))
        if norm < 1e-9:
            raise ValueError("pose quaternion has zero norm")
        object.__setattr__(self, "position", position)
        object.__setattr__(self, "quat", quat / norm)

    @classmethod
    def from_transform(cls, transform: np.ndarray) -> Pose:
        """The pose of a 4x4 homogeneous transform (base <- TCP)."""
        from scipy.spatial.transform import Rotation  # not at import: the CLI loads this module

        matrix = np.asarray(transform, dtype=float)
        x, y, z, w = Rotation.from_matrix(matrix[:3, :3]).as_quat()
        return cls(matrix[:3, 3], np.array([w, x, y, z]))

    def rotation(self) -> np.ndarray:
        """The 3x3 rotation matrix of :attr:`quat` (base <- tool)."""
        w, x, y, z = self.quat
        return np.array(
            [
                [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
            ]
        )


@dataclass(frozen=True)
class GripperState:
    """A parallel gripper: the last command (``closed``) and the measured opening."""

    closed: bool  # the last command: True closes the fingers, False opens them
    width: float  # m, between the fingers' inner faces (stops on a held object)


@dataclass(frozen=True)
class RobotState:
    """What a backend reports about its arm at one instant."""

    t: float  # seconds, the backend's clock (monotonic)
    q: np.ndarray  # (6,) joint angles, rad
    dq: np.ndarray  # (6,) joint velocities, rad/s
    tcp: Pose  # tool centre point in the base frame
    tcp_twist: np.ndarray = field(default_factory=lambda: np.zeros(6))  # base frame, measured
    moving: bool = False
    fault: str | None = None  # one line when the arm is in a fault or protective stop
    gripper: GripperState | None = None  # None: the arm has no gripper

    @property
    def tcp_speed(self) -> float:
        """Linear speed of the tool centre point, m/s."""
        return float(np.linalg.norm(self.tcp_twist[:3]))


@dataclass(frozen=True)
class JointLimits:
    """Position and speed limits of the six joints."""

    lower: np.ndarray  # (6,) rad
    upper: np.ndarray  # (6,) rad
    max_speed: np.ndarray  # (6,) rad/s


def rotation_angle(rotation: np.ndarray) -> float:
    """The angle (rad, 0..pi) of a 3x3 rotation matrix: how far it turns about its axis."""
    cos = (float(np.trace(rotation)) - 1.0) / 2.0
    return math.acos(max(-1.0, min(1.0, cos)))


def command_twist(twist: object) -> np.ndarray:
    """A twist command as six finite numbers; else a one-line :class:`RobotError`."""
    try:
        return finite_vector(twist, 6, "twist")
    except ValueError as exc:
        raise RobotError(str(exc)) from None


def joint_move_target(q: object, speed_fraction: float, limits: JointLimits) -> np.ndarray:
    """A joint move's target within ``limits`` at a speed fraction in (0, 1]; else a
    one-line :class:`RobotError`."""
    target = np.asarray(q, dtype=float)
    if target.shape != (N_JOINTS,) or not np.all(np.isfinite(target)):
        raise RobotError("joint target must be six finite angles")
    if not (np.isfinite(speed_fraction) and 0.0 < speed_fraction <= 1.0):
        raise RobotError(f"speed fraction {speed_fraction} is not in (0, 1]")
    if np.any(target < limits.lower) or np.any(target > limits.upper):
        raise RobotError("joint target is outside the joint limits")
    return target


def check_pose_move(pose: object, speed: float, max_speed: float) -> None:
    """A pose move's target must be a :class:`Pose` and its speed in (0, ``max_speed``] m/s;
    else a one-line :class:`RobotError`."""
    if not isinstance(pose, Pose):
        raise RobotError("move_to_pose needs a Pose")
    if not (np.isfinite(speed) and 0.0 < speed <= max_speed):
        raise RobotError(f"pose move speed {speed} m/s is not in (0, {max_speed:g}]")


JointFunction = Callable[[np.ndarray], np.ndarray]


@dataclass(frozen=True)
class Kinematics:
    """A kinematic model of the arm's tool centre point, base frame, at joint angles ``q``."""

    forward: JointFunction  # q -> 4x4 pose, base <- TCP
    jacobian: JointFunction  # q -> 6x6 geometric Jacobian: [v; w] = J @ dq


@dataclass(frozen=True)
class SceneModel:
    """How to draw the arm: a MuJoCo model of it and where its skin patch sits.

    ``load`` builds the ``mujoco.MjModel`` (called when a view needs it, so declaring a
    scene costs nothing); ``skin_site`` names the patch's site, whose frame has the skin's
    ``up`` and ``right`` axes; ``caveat`` is one line the view shows when the drawing is
    only a stand-in for the real arm.
    """

    load: Callable[[], Any]
    skin_site: str
    up_axis: np.ndarray
    right_axis: np.ndarray
    caveat: str = ""


@dataclass(frozen=True)
class RobotCapabilities:
    """What a backend offers besides the abstract :class:`Robot` methods.

    - ``kinematics``: its TCP's forward kinematics and Jacobian; the safety layer needs
      both for its full checks (joint margins predicted from the commanded twist, joint
      moves checked along their path and slowed to the TCP caps).
    - ``scene``: the model the dashboard draws.
    - ``default_poses``: joint angles (rad) for named poses (``home``, ``initial``) used
      when the user stored none.
    - ``stop_time_s`` / ``stop_deceleration``: how :meth:`Robot.stop` brings the arm to
      rest: within a fixed time from any speed, and/or at a constant TCP deceleration
      ``(linear m/s^2, angular rad/s^2)``; speed falls at least linearly, so the distance
      covered is at most speed x stop time / 2. Undeclared, the safety layer assumes
      :attr:`~wovenskin.control.safety.SafetyLimits.assumed_stop_time_s`.
    - ``control_period_s``: how long the backend holds its joint velocities between
      updates (a simulation's IK step, a controller's servo period; 0: continuously
      updated). The arm moves on meanwhile, so the TCP speeds it reports at the end of a
      period differ from the commanded ones; the safety layer predicts that from the
      kinematics and keeps the reported speeds under its caps.
    - ``tracking_error``: how closely a twist is followed beyond that, as measured: the
      reported TCP linear (angular) speed exceeds the commanded one by at most this
      fraction. The safety layer leaves that much headroom under its caps and keeps that
      share of the TCP's travel away from the workspace walls.
    - ``release_stop_s``: how long the control layer's brake may take to bring a released
      twist to rest on this arm (None: its own default, 0.05 s). An arm whose controller
      ramps a velocity step by itself (MoveIt Servo's smoothing filter) declares a short
      time, so the zero twist of a lift-off goes out on the next tick instead of being
      ramped twice.
    - ``how_to_complete``: one line telling the user how to supply what is missing.
    - ``left_to_controller``: the checks wovenskin does not make on this arm because its
      own controller makes them (MoveIt Servo's collision checking, say), one line each;
      the session says them when it starts.
    - ``gripper``: whether :meth:`Robot.set_gripper` drives a gripper on this arm.

    Joint limits are not here: every backend must give them (:meth:`Robot.joint_limits`).
    """

    kinematics: Kinematics | None = None
    scene: SceneModel | None = None
    default_poses: Mapping[str, np.ndarray] = field(default_factory=dict)
    stop_time_s: float | None = None
    stop_deceleration: tuple[float, float] | None = None
    control_period_s: float = 0.0
    tracking_error: float = 0.0
    release_stop_s: float | None = None
    how_to_complete: str = ""
    left_to_controller: tuple[str, ...] = ()
    gripper: bool = False

    def __post_init__(self) -> None:
        if self.stop_time_s is not None and not (
            math.isfinite(self.stop_time_s) and self.stop_time_s >= 0.0
        ):
            raise ValueError(f"stop_time_s must be >= 0, got {self.stop_time_s!r}")
        if self.stop_deceleration is not None:
            linear, angular = self.stop_deceleration
            if not (linear > 0.0 and angular > 0.0):
                raise ValueError(
                    f"stop_deceleration must be positive, got {self.stop_deceleration}"
                )
        if not (math.isfinite(self.control_period_s) and self.control_period_s >= 0.0):
            raise ValueError(f"control_period_s must be >= 0, got {self.control_period_s!r}")
        if self.release_stop_s is not None and not (
            math.isfinite(self.release_stop_s) and self.release_stop_s > 0.0
        ):
            raise ValueError(f"release_stop_s must be > 0, got {self.release_stop_s!r}")
        if not (math.isfinite(self.tracking_error) and 0.0 <= self.tracking_error < 1.0):
            raise ValueError(f"tracking_error must be in [0, 1), got {self.tracking_error!r}")
        poses = {}
        for name, q in self.default_poses.items():
            poses[name] = finite_vector(q, N_JOINTS, f"default pose {name!r}")
        object.__setattr__(self, "default_poses", poses)

    def stop_time(self, twist: np.ndarray) -> float | None:
        """Longest time :meth:`Robot.stop` takes to bring ``twist`` to rest, or ``None``
        when the backend declares neither a stop time nor a deceleration."""
        if self.stop_time_s is None and self.stop_deceleration is None:
            return None
        t = self.stop_time_s or 0.0
        if self.stop_deceleration is not None:
            v = np.asarray(twist, dtype=float)
            linear, angular = self.stop_deceleration
            t = max(
                t, float(np.linalg.norm(v[:3])) / linear, float(np.linalg.norm(v[3:])) / angular
            )
        return t


class Robot(abc.ABC):
    """One 6-DOF arm. Backends implement every abstract method.

    ``send_twist`` is velocity mode: the arm moves with the given base-frame twist until
    the next call, ``stop`` or the backend's own command timeout (a backend must stop by
    itself if no command arrives for longer than its timeout, where the hardware allows).
    ``move_to_joints``/``move_to_pose`` start a point-to-point motion and return at once;
    ``state().moving`` tells when it is over, ``stop`` cancels it.
    """

    name: str = "robot"
    degraded_safety: bool = False  # the user's opt-in to degraded safety (robot spec)

    def capabilities(self) -> RobotCapabilities:
        """What this backend offers beyond the abstract methods; a backend that declares
        nothing is refused by the safety layer unless :attr:`degraded_safety` is set."""
        return RobotCapabilities()

    @abc.abstractmethod
    def connect(self) -> None:
        """Open the connection; raises :class:`RobotError` when the arm is not there."""

    @abc.abstractmethod
    def disconnect(self) -> None:
        """Stop the arm and close the connection; safe to call twice."""

    @abc.abstractmethod
    def state(self) -> RobotState:
        """The latest state of the arm."""

    @abc.abstractmethod
    def joint_limits(self) -> JointLimits:
        """The arm's joint position and speed limits."""

    @abc.abstractmethod
    def send_twist(self, twist: np.ndarray) -> None:
        """Move with the base-frame twist ``[vx, vy, vz, wx, wy, wz]`` (m/s, rad/s)."""

    @abc.abstractmethod
    def move_to_joints(self, q: np.ndarray, speed_fraction: float = 0.2) -> None:
        """Start a joint-space move to ``q`` at a fraction of the joints' speed limits."""

    @abc.abstractmethod
    def move_to_pose(self, pose: Pose, speed: float = 0.05) -> None:
        """Start a move of the tool centre point to ``pose`` (linear speed m/s)."""

    @abc.abstractmethod
    def stop(self) -> None:
        """Stop now (within the arm's deceleration limits)."""

    def set_gripper(self, closed: bool) -> None:
        """Close (``True``) or open (``False``) the gripper; returns at once, and
        ``state().gripper`` reports the opening. Raises :class:`RobotError` on an arm
        without one (the default)."""
        raise RobotError(f"this arm ({self.name}) has no gripper")

    def step(self, dt: float) -> None:  # noqa: B027 - optional hook, no-op for real arms
        """Advance a simulated arm by ``dt`` seconds; real arms move on their own."""

    def use_mapping_frame(self, frame: str) -> None:  # noqa: B027 - optional hook
        """The action mapping thinks in ``frame`` (``tool``, ``base`` or ``skin``). Twists
        still arrive in the base frame; a backend that passes them on in a frame of its
        choosing (a ROS 2 ``frame_id``) may express them in the mapping's."""

    def __enter__(self) -> Robot:
        self.connect()
        return self

    def __exit__(self, *exc: object) -> None:
        self.disconnect()
