"""Point-to-point moves as streams of twists, for arms that only take velocity commands.

MoveIt Servo follows twists; it has no "go to these joint angles". A :class:`JointMove`
follows the joint-space path the safety layer checked (a quintic, rest to rest, whose peak
joint speeds are the asked fraction of the limits) by sending, every cycle, the twist
``J(q) (dq_ref + gain (q_ref - q))``: with a square, non-singular Jacobian Servo's inverse
kinematics turns it back into exactly those joint velocities, and the feedback term pulls
the arm onto the path where Servo's smoothing or scaling let it lag. A :class:`CartesianMove`
drives the tool centre point along a straight line and a shortest rotation to a pose the
same way, in Cartesian space. A move that has not arrived ``patience_s`` after its plan
ended gives up with one line.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from wovenskin.robots.base import JointLimits, Kinematics, Pose

GAIN_PER_S = 4.0  # feedback gain on the path error, 1/s
JOINT_TOLERANCE_RAD = math.radians(0.2)
POSITION_TOLERANCE_M = 0.0005
ANGLE_TOLERANCE_RAD = math.radians(0.2)
QUINTIC_PEAK = 1.875  # the peak of the quintic's speed, in units of distance / duration


def _quintic(tau: float) -> tuple[float, float]:
    """Progress and its derivative (per unit time of a unit-length plan) at ``tau`` in [0, 1]."""
    tau = min(max(tau, 0.0), 1.0)
    s = tau**3 * (10.0 - 15.0 * tau + 6.0 * tau * tau)
    ds = 30.0 * tau * tau * (1.0 - tau) ** 2
    return s, ds


class MoveFailed(RuntimeError):
    """A streamed move could not arrive; the message is one line."""


@dataclass
class JointMove:
    """A rest-to-rest joint-space move from ``start`` to ``goal``, streamed as twists."""

    start: np.ndarray
    goal: np.ndarray
    duration_s: float
    started_t: float
    patience_s: float = 3.0

    @classmethod
    def plan(
        cls, start: np.ndarray, goal: np.ndarray, fraction: float, limits: JointLimits, t: float
    ) -> JointMove:
        """The move whose fastest joint peaks at ``fraction`` of its speed limit."""
        distance = np.abs(np.asarray(goal, float) - np.asarray(start, float))
        speeds = np.asarray(limits.max_speed, float) * float(fraction)
        duration = float(np.max(QUINTIC_PEAK * distance / speeds)) if np.any(distance) else 0.0
        return cls(np.array(start, float), np.array(goal, float), duration, t)

    def twist(self, q: np.ndarray, t: float, kinematics: Kinematics) -> np.ndarray | None:
        """The base-frame twist to send at ``t`` with the arm at ``q``; ``None`` once it
        has arrived. Raises :class:`MoveFailed` when it overstays its plan."""
        elapsed = t - self.started_t
        tau = elapsed / self.duration_s if self.duration_s > 0 else 1.0
        s, ds = _quintic(tau)
        delta = self.goal - self.start
        q_ref = self.start + s * delta
        dq_ref = delta * (ds / self.duration_s if self.duration_s > 0 else 0.0)
        error = q_ref - q
        if tau >= 1.0 and float(np.max(np.abs(self.goal - q))) < JOINT_TOLERANCE_RAD:
            return None
        if elapsed > self.duration_s + self.patience_s:
            worst = float(np.degrees(np.max(np.abs(self.goal - q))))
            raise MoveFailed(f"joint move stopped {worst:.1f} deg short of its target")
        return kinematics.jacobian(q) @ (dq_ref + GAIN_PER_S * error)


@dataclass
class CartesianMove:
    """A straight-line move of the tool centre point to ``goal``, streamed as twists."""

    start: Pose
    goal: Pose
    duration_s: float
    started_t: float
    patience_s: float = 3.0

    @classmethod
    def plan(
        cls, start: Pose, goal: Pose, speed: float, angular_speed: float, t: float
    ) -> CartesianMove:
        """The move whose peak linear (angular) speed is ``speed`` (``angular_speed``)."""
        distance = float(np.linalg.norm(goal.position - start.position))
        turn = _angle(start, goal)
        duration = QUINTIC_PEAK * max(distance / speed, turn / angular_speed)
        return cls(start, goal, duration, t)

    def twist(self, q: np.ndarray, t: float, kinematics: Kinematics) -> np.ndarray | None:
        """As :meth:`JointMove.twist`, in Cartesian space."""
        elapsed = t - self.started_t
        tau = elapsed / self.duration_s if self.duration_s > 0 else 1.0
        s, ds = _quintic(tau)
        rate = ds / self.duration_s if self.duration_s > 0 else 0.0
        pose = kinematics.forward(q)
        position, rotation = pose[:3, 3], Rotation.from_matrix(pose[:3, :3])
        ends = Rotation.from_quat(
            np.stack([self.start.quat[[1, 2, 3, 0]], self.goal.quat[[1, 2, 3, 0]]])
        )
        turn = (ends[1] * ends[0].inv()).as_rotvec()
        p_ref = self.start.position + s * (self.goal.position - self.start.position)
        r_ref = Slerp([0.0, 1.0], ends)([s])[0]
        goal_rotation = ends[1]
        arrived = (
            float(np.linalg.norm(self.goal.position - position)) < POSITION_TOLERANCE_M
            and (goal_rotation * rotation.inv()).magnitude() < ANGLE_TOLERANCE_RAD
        )
        if tau >= 1.0 and arrived:
            return None
        if elapsed > self.duration_s + self.patience_s:
            short = 1000.0 * float(np.linalg.norm(self.goal.position - position))
            raise MoveFailed(f"pose move stopped {short:.1f} mm short of its target")
        linear = (self.goal.position - self.start.position) * rate + GAIN_PER_S * (p_ref - position)
        angular = turn * rate + GAIN_PER_S * (r_ref * rotation.inv()).as_rotvec()
        return np.concatenate([linear, angular])


def _angle(a: Pose, b: Pose) -> float:
    """The angle (rad) of the rotation from ``a`` to ``b``."""
    dot = abs(float(np.dot(a.quat, b.quat)))
    return 2.0 * math.acos(min(1.0, dot))
