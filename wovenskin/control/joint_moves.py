"""Joint moves under the safety caps: where the TCP path leaves the box, how much to slow one."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from wovenskin.control.safety_limits import SafetyLimits
from wovenskin.robots.base import JointLimits

CAP_SAFETY_FACTOR = 0.9  # joint moves plan for 90 % of the caps (the path is sampled)
PATH_SAMPLES = 21  # points checked along a joint move

Jacobian = Callable[[np.ndarray], np.ndarray]
Kinematics = Callable[[np.ndarray], np.ndarray]  # q -> 4x4 base <- tcp


def path_leaves_box(
    fk: Kinematics | None, start: np.ndarray, goal: np.ndarray, limits: SafetyLimits
) -> np.ndarray | None:
    """The first TCP position outside the box along the straight joint path, if any
    (``None`` too without forward kinematics ``fk``)."""
    if fk is None:
        return None
    for s in np.linspace(0.0, 1.0, PATH_SAMPLES):
        position = np.asarray(fk(start + s * (goal - start)), dtype=float)[:3, 3]
        if s > 0.0 and not limits.in_box(position):
            return position
    return None


def capped_fraction(
    jacobian: Jacobian | None,
    start: np.ndarray,
    goal: np.ndarray,
    fraction: float,
    joint_limits: JointLimits,
    limits: SafetyLimits,
) -> float:
    """Slow a joint move so its TCP speeds stay under the caps.

    The backend is assumed to move the joints in step along the straight joint path, the
    busiest joint at ``fraction`` of its speed limit. With a Jacobian the TCP speeds are
    sampled along the path; without one they are bounded by ``arm_reach`` times the sum
    of the joint speeds (and the sum itself for the angular speed).
    """
    delta = goal - np.asarray(start, dtype=float)
    moving = np.abs(delta) > 1e-12
    if not np.any(moving):
        return fraction
    path_rate = fraction * float(np.min(joint_limits.max_speed[moving] / np.abs(delta[moving])))
    if jacobian is None:
        angular = float(np.sum(np.abs(delta))) * path_rate
        linear = limits.arm_reach * angular
    else:
        linear = angular = 0.0
        for s in np.linspace(0.0, 1.0, PATH_SAMPLES):
            jac = np.asarray(jacobian(start + s * delta), dtype=float)
            linear = max(linear, float(np.linalg.norm(jac[:3] @ delta)) * path_rate)
            angular = max(angular, float(np.linalg.norm(jac[3:] @ delta)) * path_rate)
    ratio = max(linear / limits.max_linear_speed, angular / limits.max_angular_speed)
    if ratio <= CAP_SAFETY_FACTOR:
        return fraction
    return fraction * CAP_SAFETY_FACTOR / ratio
