"""Differential inverse kinematics for the simulated arm, with mink.

:class:`DifferentialIK` turns a commanded base-frame twist of the ``tcp`` site into joint
velocities for one control step. It integrates a target pose from the twist and solves
mink's QP (a :class:`mink.FrameTask` on the TCP, joint position and speed limits, solver
``daqp``). Motion is never bent off its commanded direction: when a joint's speed limit
or its braking distance to a position limit would bind, the whole twist is scaled down.
Near singularities it slows and then stops as MoveIt Servo does
(``velocityScalingFactorForSingularity``: slow down above a condition number of 17, stop
at 30): the Jacobian's condition number is compared with two thresholds, and only motion
that raises the condition number (moves further into the singularity) is slowed or
stopped; motion that lowers it runs at full speed, so the arm is never trapped. The
condition number is taken on the Jacobian with its linear rows divided by a
characteristic length (:attr:`SingularityThresholds.length`), so that it does not depend
on the unit of length: MoveIt Servo takes it on the raw Jacobian, whose linear rows are in
metres and angular rows in radians, which on the TM5-900 reads 8.3 at the initial posture
(5.7 unit-free) and stopped the wrist 14.2 degrees from its singularity (10.6 now) and the
elbow 23.5 degrees short of straight (17.7 now); docs/safety.md.
:meth:`DifferentialIK.solve_pose` is the position-level IK used for point-to-point moves.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mink
import mujoco
import numpy as np

from wovenskin.robots.base import JointLimits

SOLVER = "daqp"
PROBE_STEP = 1e-3  # rad, joint-space step used to see where a motion takes the condition
POSITION_LIMIT_GAIN = 0.95  # share of the room to a position limit one step may use
DIRECTION_TOLERANCE = 0.02  # relative twist error accepted before a step is refused


@dataclass(frozen=True)
class SingularityThresholds:
    """Condition numbers of the unit-free Jacobian (:func:`condition_number`) where motion
    toward a singularity slows, then stops (MoveIt Servo's defaults), and the length (m)
    that makes it unit-free. 0.4 m is the TM5-900's: it gives the smallest condition
    number at its initial posture (5.71, against 8.34 in metres and radians; any length
    from 0.35 to 0.5 m is within 2 % of it)."""

    slow_down: float = 17.0
    hard_stop: float = 30.0
    length: float = 0.4

    def __post_init__(self) -> None:
        if not 1.0 <= self.slow_down < self.hard_stop:
            raise ValueError("singularity thresholds need 1 <= slow_down < hard_stop")
        if not (math.isfinite(self.length) and self.length > 0.0):
            raise ValueError(
                f"singularity length must be a positive number of m, got {self.length}"
            )


def condition_number(jacobian: np.ndarray, length: float) -> float:
    """The condition number of a ``[v; w]`` Jacobian with its linear rows divided by
    ``length``: the same whatever the unit of length (a Jacobian in millimetres with
    ``length`` in millimetres gives the same number), so a threshold on it means one
    thing for every posture and arm size (the raw Jacobian mixes m/s and rad/s)."""
    scaled = np.array(jacobian, dtype=float)
    scaled[:3] /= length
    return float(np.linalg.cond(scaled))


@dataclass(frozen=True)
class IKInfo:
    """What one IK step did: the twist scale applied, the condition number, why limited."""

    scale: float = 1.0
    condition: float = 1.0
    limited_by: str | None = None  # "singularity", "joint speed J3", "joint limit J2", ...


class DifferentialIK:
    """One-step differential IK of the ``site`` frame of a MuJoCo arm model."""

    def __init__(
        self,
        model: mujoco.MjModel,
        limits: JointLimits,
        site: str = "tcp",
        thresholds: SingularityThresholds | None = None,
        brake_time: float = 0.2,
    ) -> None:
        if model.nv != len(limits.max_speed):
            raise ValueError(f"model has {model.nv} joints, limits give {len(limits.max_speed)}")
        self.model = model
        self.limits = limits
        self.site = site
        self.thresholds = thresholds or SingularityThresholds()
        self.brake_accel = np.asarray(limits.max_speed) / brake_time  # rad/s^2
        self.configuration = mink.Configuration(model)
        self.task = mink.FrameTask(site, "site", position_cost=1.0, orientation_cost=1.0)
        joint_names = [model.joint(i).name for i in range(model.njnt)]
        self.qp_limits: list[mink.Limit] = [
            mink.ConfigurationLimit(model, gain=POSITION_LIMIT_GAIN),
            mink.VelocityLimit(model, dict(zip(joint_names, limits.max_speed, strict=True))),
        ]
        self._site_id = model.site(site).id
        self._probe = mujoco.MjData(model)
        self._jacp = np.zeros((3, model.nv))
        self._jacr = np.zeros((3, model.nv))

    # -- kinematic helpers ----------------------------------------------------------

    def _jacobian(self, data: mujoco.MjData) -> np.ndarray:
        """Base-frame Jacobian of the site: ``[v; w] = J @ dq`` (needs mj_comPos done)."""
        mujoco.mj_jacSite(self.model, data, self._jacp, self._jacr, self._site_id)
        return np.vstack([self._jacp, self._jacr])

    def _condition_at(self, q: np.ndarray) -> float:
        self._probe.qpos[:] = q
        mujoco.mj_kinematics(self.model, self._probe)
        mujoco.mj_comPos(self.model, self._probe)
        return condition_number(self._jacobian(self._probe), self.thresholds.length)

    def _site_pose(self) -> mink.SE3:
        data = self.configuration.data
        rotation = mink.SO3.from_matrix(data.site_xmat[self._site_id].reshape(3, 3))
        return mink.SE3.from_rotation_and_translation(rotation, data.site_xpos[self._site_id])

    @staticmethod
    def _advance(pose: mink.SE3, twist: np.ndarray, dt: float) -> mink.SE3:
        """``pose`` moved for ``dt`` by a base-frame twist of its own origin."""
        rotation = mink.SO3.exp(twist[3:] * dt) @ pose.rotation()
        return mink.SE3.from_rotation_and_translation(rotation, pose.translation() + twist[:3] * dt)

    def _solve(self, pose: mink.SE3, twist: np.ndarray, dt: float, limited: bool) -> np.ndarray:
        self.task.set_target(self._advance(pose, twist, dt))
        return mink.solve_ik(
            self.configuration,
            [self.task],
            dt,
            SOLVER,
            limits=self.qp_limits if limited else [],
        )

    def _speed_bounds(self, q: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per-joint velocity bounds (lower, upper) and where position limits are tighter."""
        speed = np.asarray(self.limits.max_speed, dtype=float)
        room_up = np.maximum(np.asarray(self.limits.upper) - q, 0.0)
        room_down = np.maximum(q - np.asarray(self.limits.lower), 0.0)
        # Approach a position limit no faster than it can be braked for, and never past it.
        gain = POSITION_LIMIT_GAIN / max(dt, 1e-9)  # a vanishing step must not overflow
        up = np.minimum(np.sqrt(2.0 * self.brake_accel * room_up), gain * room_up)
        down = np.minimum(np.sqrt(2.0 * self.brake_accel * room_down), gain * room_down)
        upper = np.minimum(speed, up)
        lower = -np.minimum(speed, down)
        position_bound = np.vstack([up < speed, down < speed])
        return lower, upper, position_bound

    # -- the step ---------------------------------------------------------------------

    def singularity_scale(self, q: np.ndarray, twist: np.ndarray, jac: np.ndarray) -> IKInfo:
        """Servo-style slow-down: scale for ``twist`` from the unit-free condition number
        (:func:`condition_number`); only a twist that raises it is slowed or stopped."""
        condition = condition_number(jac, self.thresholds.length)
        lower, hard = self.thresholds.slow_down, self.thresholds.hard_stop
        if condition <= lower or not np.any(twist):
            return IKInfo(1.0, condition, None)
        # Where does the commanded motion take the condition number? (damped least squares)
        direction = jac.T @ np.linalg.solve(jac @ jac.T + 1e-6 * np.eye(6), twist)
        norm = float(np.linalg.norm(direction))
        if norm == 0.0 or not np.isfinite(norm):
            return IKInfo(0.0, condition, "singularity")
        approaching = self._condition_at(q + PROBE_STEP * direction / norm) > condition
        if not approaching:
            return IKInfo(1.0, condition, None)
        scale = float(np.clip((hard - condition) / (hard - lower), 0.0, 1.0))
        return IKInfo(scale, condition, "singularity")

    def step(self, q: np.ndarray, twist: np.ndarray, dt: float) -> tuple[np.ndarray, IKInfo]:
        """Joint velocities (rad/s) that move the site with ``twist`` for ``dt`` seconds.

        ``twist`` is ``[vx, vy, vz, wx, wy, wz]`` in the base frame (velocity of the site's
        origin). The returned velocities respect the joints' speed and position limits and
        produce ``info.scale * twist`` (same direction) or nothing.
        """
        q = np.asarray(q, dtype=float)
        twist = np.asarray(twist, dtype=float)
        self.configuration.update(q)
        jac = self._jacobian(self.configuration.data)
        info = self.singularity_scale(q, twist, jac)
        commanded = info.scale * twist
        if not np.any(commanded):
            return np.zeros(self.model.nv), info
        pose = self._site_pose()
        nominal = self._solve(pose, commanded, dt, limited=False)
        lower, upper, position_bound = self._speed_bounds(q, dt)
        scale, limited_by = info.scale, info.limited_by
        joint, ratio = _worst_joint(nominal, lower, upper)
        if ratio > 1.0:
            limited_by = _bound_name(nominal, joint, position_bound)
            scale *= (1.0 - 1e-6) / ratio
            commanded = scale * twist
            if not np.any(commanded):
                return np.zeros(self.model.nv), IKInfo(0.0, info.condition, limited_by)
        velocity = self._solve(pose, commanded, dt, limited=True)
        # The scaled solve is linear only to first order: rescale so the binding joint sits
        # on its bound (never above it, never faster than the unbound command).
        joint, ratio = _worst_joint(velocity, lower, upper)
        bound_limited = limited_by is not None and limited_by.startswith("joint")
        if ratio > 1.0 or (bound_limited and ratio > 0.0):
            factor = min((1.0 - 1e-6) / ratio, info.scale / scale if scale > 0 else 1.0)
            limited_by = limited_by or _bound_name(velocity, joint, position_bound)
            velocity = velocity * factor
            commanded = commanded * factor
            scale *= factor
        achieved = jac @ velocity
        error = float(np.linalg.norm(achieved - commanded))
        if error > DIRECTION_TOLERANCE * float(np.linalg.norm(commanded)) + 1e-6:
            return np.zeros(self.model.nv), IKInfo(0.0, info.condition, "direction")
        return velocity, IKInfo(scale, info.condition, limited_by)

    # -- position-level IK ------------------------------------------------------------

    def solve_pose(
        self,
        q0: np.ndarray,
        target: np.ndarray,
        iterations: int = 400,
        position_tolerance: float = 1e-5,
        orientation_tolerance: float = 1e-4,
    ) -> np.ndarray | None:
        """Joint angles within limits that put the site at ``target`` (4x4, base frame).

        Iterates mink from ``q0``; returns None when it does not converge (unreachable).
        """
        self.configuration.update(np.asarray(q0, dtype=float))
        self.task.set_target(mink.SE3.from_matrix(np.asarray(target, dtype=float)))
        dt = 0.05
        for _ in range(iterations):
            error = self.task.compute_error(self.configuration)
            if (
                np.linalg.norm(error[:3]) < position_tolerance
                and np.linalg.norm(error[3:]) < orientation_tolerance
            ):
                return self.configuration.q.copy()
            velocity = mink.solve_ik(
                self.configuration,
                [self.task],
                dt,
                SOLVER,
                damping=1e-3,
                limits=self.qp_limits[:1],
            )
            self.configuration.integrate_inplace(velocity, dt)
        return None


def _worst_joint(velocity: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> tuple[int, float]:
    """The joint whose velocity most exceeds its bound, and by what factor (inf: no room)."""
    room = np.where(velocity > 0, upper, -lower)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(room > 0, np.abs(velocity) / room, np.where(velocity != 0, np.inf, 0.0))
    joint = int(np.argmax(ratio))
    return joint, float(ratio[joint])


def _bound_name(velocity: np.ndarray, joint: int, position_bound: np.ndarray) -> str:
    side = 0 if velocity[joint] > 0 else 1
    kind = "joint limit" if position_bound[side, joint] else "joint speed"
    return f"{kind} J{joint + 1}"
