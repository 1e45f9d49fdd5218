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
"""

from __future__ import annotations

import abc
from dataclasses import dataclass, field

import numpy as np

N_JOINTS = 6


class RobotError(RuntimeError):
    """A robot backend could not carry out a command; the message is one line."""


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
class RobotState:
    """What a backend reports about its arm at one instant."""

    t: float  # seconds, the backend's clock (monotonic)
    q: np.ndarray  # (6,) joint angles, rad
    dq: np.ndarray  # (6,) joint velocities, rad/s
    tcp: Pose  # tool centre point in the base frame
    tcp_twist: np.ndarray = field(default_factory=lambda: np.zeros(6))  # base frame, measured
    moving: bool = False
    fault: str | None = None  # one line when the arm is in a fault or protective stop

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


class Robot(abc.ABC):
    """One 6-DOF arm. Backends implement every abstract method.

    ``send_twist`` is velocity mode: the arm moves with the given base-frame twist until
    the next call, ``stop`` or the backend's own command timeout (a backend must stop by
    itself if no command arrives for longer than its timeout, where the hardware allows).
    ``move_to_joints``/``move_to_pose`` start a point-to-point motion and return at once;
    ``state().moving`` tells when it is over, ``stop`` cancels it.
    """

    name: str = "robot"

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

    def step(self, dt: float) -> None:  # noqa: B027 - optional hook, no-op for real arms
        """Advance a simulated arm by ``dt`` seconds; real arms move on their own."""

    def __enter__(self) -> Robot:
        self.connect()
        return self

    def __exit__(self, *exc: object) -> None:
        self.disconnect()
