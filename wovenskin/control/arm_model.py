"""What the safety layer knows about one arm, resolved from the backend's declaration.

:meth:`ArmModel.resolve` reads :meth:`wovenskin.robots.base.Robot.capabilities` (never a
method found by its name) and says what is missing for the layer's full checks; the layer
refuses such an arm unless the user opted into degraded safety. The model then answers
the layer's questions:

- how long a stop takes from a twist (:meth:`ArmModel.stop_time`), so margins and the
  workspace box can include the stopping distance (speed x stop time / 2);
- which joint velocities a twist needs (:meth:`ArmModel.joint_velocities`);
- what TCP speeds the arm will *report* for a commanded twist
  (:meth:`ArmModel.measured_speed_ratio`): a backend that holds its joint velocities for
  ``control_period_s`` ends each period with TCP speeds a little off the commanded ones
  (up to several per cent near singularities), which the layer predicts from the
  Jacobian and keeps under the caps; ``tracking_error`` is the headroom left for the rest;
- how far the TCP drifts off the commanded direction over such a period
  (:meth:`ArmModel.linear_drift`), which the workspace box check corrects for.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from wovenskin.robots.base import Robot, RobotCapabilities

JointFunction = Callable[[np.ndarray], np.ndarray]


@dataclass(frozen=True)
class ArmModel:
    """The layer's model of one arm (see the module docstring)."""

    jacobian: JointFunction | None  # q -> 6x6, base frame
    forward: JointFunction | None  # q -> 4x4 base <- TCP
    capabilities: RobotCapabilities
    assumed_stop_time_s: float  # used when the backend declares no stop profile
    missing: tuple[str, ...] = ()  # what the full checks need and the arm lacks
    _cache: dict = field(default_factory=dict, repr=False, compare=False)  # last q -> J, FK

    @classmethod
    def resolve(
        cls,
        robot: Robot,
        assumed_stop_time_s: float,
        jacobian: JointFunction | None = None,
        forward: JointFunction | None = None,
    ) -> ArmModel:
        """The model of ``robot`` from its declaration; explicit ``jacobian``/``forward``
        (a caller's own model) take precedence over the declared kinematics."""
        capabilities = robot.capabilities()
        if not isinstance(capabilities, RobotCapabilities):
            kind = type(capabilities).__name__
            raise TypeError(f"{robot.name}: capabilities() gave a {kind}, not RobotCapabilities")
        declared = capabilities.kinematics
        if jacobian is None and declared is not None:
            jacobian = declared.jacobian
        if forward is None and declared is not None:
            forward = declared.forward
        missing = []
        if forward is None:
            missing.append("forward kinematics")
        if jacobian is None:
            missing.append("Jacobian")
        return cls(jacobian, forward, capabilities, assumed_stop_time_s, tuple(missing))

    # -- stopping

    @property
    def declares_stop(self) -> bool:
        c = self.capabilities
        return c.stop_time_s is not None or c.stop_deceleration is not None

    def stop_time(self, twist: np.ndarray) -> float:
        """Longest time the backend's ``stop`` takes to bring ``twist`` to rest."""
        declared = self.capabilities.stop_time(twist)
        return self.assumed_stop_time_s if declared is None else declared

    # -- speeds

    @property
    def headroom(self) -> float:
        """Commands are capped at the caps divided by this (>= 1)."""
        return 1.0 + self.capabilities.tracking_error

    def jacobian_at(self, q: np.ndarray) -> np.ndarray | None:
        """The Jacobian at ``q`` (the last one is kept: a tick asks several times)."""
        return self._cached("jacobian", self.jacobian, q)

    def forward_at(self, q: np.ndarray) -> np.ndarray | None:
        """The TCP pose at ``q`` (the last one is kept)."""
        return self._cached("forward", self.forward, q)

    def _cached(self, name: str, function: JointFunction | None, q: np.ndarray):
        if function is None:
            return None
        q = np.asarray(q, dtype=float)
        key = q.tobytes()
        hit = self._cache.get(name)
        if hit is None or hit[0] != key:
            hit = (key, np.asarray(function(q), dtype=float))
            self._cache[name] = hit
        return hit[1]

    def joint_velocities(self, q: np.ndarray, twist: np.ndarray) -> np.ndarray | None:
        """Joint velocities that give ``twist`` at ``q`` (least squares), or ``None``."""
        jac = self.jacobian_at(q)
        if jac is None:
            return None
        return np.linalg.lstsq(jac, np.asarray(twist, dtype=float), rcond=1e-6)[0]

    def measured_twist(self, q: np.ndarray, twist: np.ndarray) -> np.ndarray:
        """The TCP twist the arm reports at the end of one control period spent moving
        with the joint velocities of ``twist`` (``twist`` itself without a model or a
        declared period)."""
        period = self.capabilities.control_period_s
        dq = self.joint_velocities(q, twist)
        if dq is None or period <= 0.0:
            return np.asarray(twist, dtype=float)
        assert self.jacobian is not None
        return np.asarray(self.jacobian(np.asarray(q, dtype=float) + dq * period)) @ dq

    def linear_drift(self, q: np.ndarray, twist: np.ndarray) -> np.ndarray:
        """How much faster than ``twist``'s linear part, per axis, the TCP really moves on
        average over one control period (from the forward kinematics), m/s: rotation near
        a singularity carries the TCP sideways. Zero without a model or a period."""
        period = self.capabilities.control_period_s
        dq = self.joint_velocities(q, twist)
        if dq is None or self.forward is None or period <= 0.0:
            return np.zeros(3)
        q = np.asarray(q, dtype=float)
        after = np.asarray(self.forward(q + dq * period), dtype=float)[:3, 3]
        before = self.forward_at(q)
        assert before is not None
        return (after - before[:3, 3]) / period - np.asarray(twist, dtype=float)[:3]

    def measured_speed_ratio(
        self, q: np.ndarray, twist: np.ndarray, max_linear: float, max_angular: float
    ) -> float:
        """The largest of the reported linear and angular speeds over their caps."""
        measured = self.measured_twist(q, twist)
        linear = float(np.linalg.norm(measured[:3])) / max_linear
        angular = float(np.linalg.norm(measured[3:])) / max_angular
        ratio = max(linear, angular)
        return ratio if math.isfinite(ratio) else math.inf
