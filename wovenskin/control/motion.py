"""Smooth velocity commands: an acceleration- and jerk-limited approach to a target twist.

:class:`TwistShaper` turns the mapping's step-like target twist (full speed while a
command is active, zero on release) into an S-curve: each tick the commanded twist moves
toward the target with its acceleration bounded by the acceleration limit and the change
of acceleration by the jerk limit. The linear and angular parts are shaped separately,
each as a vector: the change points along the remaining difference, so a start from rest
or a release keeps the direction of the commanded twist (it is scaled, never clipped per
axis). Braking is planned in discrete time so the twist lands on the target without
overshoot whenever the limits allow it.

A release is different: when a part's target becomes zero (the command ended), that part
brakes at once along its current direction, whatever its acceleration was, with a constant
deceleration of ``max(acceleration limit, speed at release / release_stop_s)``, so it is at
rest within ``release_stop_s`` (0.05 s by default) from any speed. Like a real arm's stop
ramp this is not jerk-limited: a jerk-limited release first has to undo the acceleration
of a start still in progress (a 0.2 s command kept speeding up for 0.1 s after its end and
moved for 0.37 s), and from the speed caps the start's acceleration limit would need a
whole second. Starts, and changes between two commands, stay jerk-limited S-curves.
"""

from __future__ import annotations

import math

import numpy as np

from wovenskin.control.mapping import MotionSettings

LANDED = 1e-12  # m/s or rad/s: closer than this to the target counts as on it
RELEASE_STOP_S = 0.05  # s: a released part brakes to rest within this time from any speed


class TwistShaper:
    """Jerk- and acceleration-limited tracking of a target twist (see the module docstring)."""

    def __init__(
        self, settings: MotionSettings | None = None, release_stop_s: float | None = None
    ) -> None:
        """``release_stop_s``: the release brake's longest stop (None: :data:`RELEASE_STOP_S`;
        an arm that ramps its own stops declares less, see ``RobotCapabilities``)."""
        release_stop_s = RELEASE_STOP_S if release_stop_s is None else release_stop_s
        if not (math.isfinite(release_stop_s) and release_stop_s > 0.0):
            raise ValueError(f"release_stop_s must be a positive number, got {release_stop_s!r}")
        self.settings = settings or MotionSettings()
        self.release_stop_s = float(release_stop_s)
        self.reset()

    def reset(self) -> None:
        """Forget the motion: the commanded twist and its acceleration become zero."""
        self.twist = np.zeros(6)
        self.acceleration = np.zeros(6)
        self.braking = [0.0, 0.0]  # deceleration of a running release brake: linear, angular

    @property
    def releasing(self) -> bool:
        """Whether a part is braking after its command ended."""
        return any(self.braking)

    def update(self, target: np.ndarray, dt: float) -> np.ndarray:
        """Advance ``dt`` seconds toward ``target`` and return the twist to command now."""
        goal = np.asarray(target, dtype=float)
        if goal.shape != (6,):
            raise ValueError(f"target twist must have shape (6,), got {goal.shape}")
        if not np.all(np.isfinite(goal)):
            raise ValueError("target twist has non-finite values")
        if not (math.isfinite(dt) and dt >= 0.0):
            raise ValueError(f"dt must be a finite non-negative number of seconds, got {dt}")
        if dt == 0.0:
            return self.twist.copy()
        s = self.settings
        parts = ((slice(0, 3), s.linear_accel, s.linear_jerk), (slice(3, 6), s.angular_accel,
                 s.angular_jerk))  # fmt: skip
        for index, (part, accel_limit, jerk_limit) in enumerate(parts):
            if not np.any(goal[part]) and np.any(self.twist[part]):  # released: brake now
                if self.braking[index] == 0.0:
                    speed = float(np.linalg.norm(self.twist[part]))
                    self.braking[index] = max(accel_limit, speed / self.release_stop_s)
                velocity, acceleration = brake(self.twist[part], dt, self.braking[index])
                if not np.any(velocity):
                    self.braking[index] = 0.0
                    acceleration = np.zeros(3)  # at rest: a new start begins from nothing
            else:
                if self.braking[index]:  # a new command during the brake: start from here
                    self.braking[index] = 0.0
                    self.acceleration[part] = 0.0
                velocity, acceleration = approach(
                    self.twist[part], self.acceleration[part], goal[part], dt, accel_limit,
                    jerk_limit,
                )  # fmt: skip
            self.twist[part] = velocity
            self.acceleration[part] = acceleration
        return self.twist.copy()


def brake(velocity: np.ndarray, dt: float, deceleration: float) -> tuple[np.ndarray, np.ndarray]:
    """One tick of a release brake: ``velocity`` shrinks along its direction by
    ``deceleration * dt`` (to exactly zero when less is left); returns the new velocity and
    the acceleration that took it there."""
    speed = float(np.linalg.norm(velocity))
    step = deceleration * dt
    new = np.zeros_like(velocity) if speed <= step else velocity * (1.0 - step / speed)
    return new, (new - velocity) / dt


def approach(
    velocity: np.ndarray,
    acceleration: np.ndarray,
    target: np.ndarray,
    dt: float,
    accel_limit: float,
    jerk_limit: float,
) -> tuple[np.ndarray, np.ndarray]:
    """One tick of the vector S-curve: the new velocity and the acceleration used to reach it.

    The acceleration applied over the tick changes by at most ``jerk_limit * dt`` (vector
    norm) from the previous tick's and never exceeds ``accel_limit``; it aims along the
    remaining difference at the largest value from which braking at the jerk limit still
    ends exactly on the target.
    """
    difference = target - velocity
    distance = float(np.linalg.norm(difference))
    if distance <= LANDED and float(np.linalg.norm(acceleration)) <= jerk_limit * dt:
        return target.copy(), np.zeros_like(acceleration)  # on the target: settle exactly
    desired = np.zeros_like(velocity)
    if distance > 0.0:
        magnitude = min(accel_limit, braking_acceleration(distance / dt, jerk_limit * dt))
        desired = difference / distance * magnitude
    change = desired - acceleration
    max_change = jerk_limit * dt
    size = float(np.linalg.norm(change))
    if size > max_change:
        change *= max_change / size
    new_acceleration = acceleration + change
    return velocity + new_acceleration * dt, new_acceleration


def braking_acceleration(remaining: float, step: float) -> float:
    """The acceleration ``a`` from which ``a, a - step, a - 2 step, ...`` (down to zero) sums
    to ``remaining``: the largest acceleration that still lands on the target.

    ``remaining`` is the velocity difference over ``dt`` and ``step`` is ``jerk * dt``
    (both in acceleration units); with ``m`` terms the sum is ``m a - step m (m - 1) / 2``.
    """
    if remaining <= 0.0:
        return 0.0
    terms = max(1, math.ceil((math.sqrt(1.0 + 8.0 * remaining / step) - 1.0) / 2.0 - 1e-12))
    return (remaining + step * terms * (terms - 1) / 2.0) / terms
