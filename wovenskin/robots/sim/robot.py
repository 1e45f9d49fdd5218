"""SimRobot: the simulated TM5-900, a kinematic MuJoCo arm behind the Robot interface.

The arm moves only when :meth:`SimRobot.step` advances its clock (simulated seconds; the
caller decides how fast that runs). Velocity commands go through
:class:`~wovenskin.robots.sim.ik.DifferentialIK` at ``ik_rate_hz`` substeps; point-to-point
moves follow quintic joint-space profiles within the joints' speed limits. Like the real
arm, it stops by itself when no velocity command arrives for :data:`STALE_COMMAND_S`,
decelerates to rest within :data:`STOP_TIME_S` on ``stop``, and a refused command stops
the arm and raises :class:`RobotError` without starting any motion. One ``step`` advances
at most :data:`MAX_STEP_S` (a longer one is cut, with a log line: the number of substeps
stays bounded whatever the caller's clock does). The joint positions live in
``data.qpos`` (kept up to date with ``mj_kinematics``) for viewers. Given an
:class:`~wovenskin.robots.sim.physics.ArmPhysics` (a task scene), every substep also runs
that scene's physics with the arm's joints following, and :meth:`SimRobot.set_gripper`
drives its gripper; without one (the default) nothing of that runs.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field

import mink
import mujoco
import numpy as np

from wovenskin.robots.base import (
    N_JOINTS,
    GripperState,
    JointLimits,
    Pose,
    Robot,
    RobotCapabilities,
    RobotError,
    RobotState,
    finite_vector,
)
from wovenskin.robots.sim import tm5_900
from wovenskin.robots.sim.ik import DifferentialIK, IKInfo
from wovenskin.robots.sim.physics import ArmPhysics
from wovenskin.robots.sim.tm5_900 import MODEL_FILE as MODEL_FILE  # re-exported
from wovenskin.robots.sim.tm5_900 import load_model

log = logging.getLogger(__name__)

STALE_COMMAND_S = 0.2  # a twist older than this (simulated seconds) stops the arm
# stop() brings the arm to rest within this time: a STOP or a watchdog stop must get the TCP
# below 1 mm/s within 0.1 s, and it reaches the arm up to one 5 ms control tick late.
STOP_TIME_S = 0.08
MAX_STEP_S = 1.0  # longest simulated time one step() advances (longer steps are cut)
MOVING_SPEED = 1e-6  # rad/s; joint speeds below this count as standing still
TRACKING_ERROR = 0.01  # reported TCP speeds vs the commanded ones, beyond the IK step's
PLAN_SAMPLES = 41


@dataclass
class JointMove:
    """A quintic joint-space path from ``start`` (moving at ``v0``) to rest at ``goal``."""

    start: np.ndarray
    goal: np.ndarray
    v0: np.ndarray
    duration: float
    elapsed: float = 0.0
    coeffs: np.ndarray = field(init=False)  # (3, 6): s^3, s^4, s^5 terms

    def __post_init__(self) -> None:
        span = self.goal - self.start
        initial = self.v0 * self.duration  # velocity in normalised time s = t / T
        # p(s) = V s + a3 s^3 + a4 s^4 + a5 s^5 with p(1) = D, p'(1) = 0, p''(1) = 0
        system = np.array([[1.0, 1.0, 1.0], [3.0, 4.0, 5.0], [6.0, 12.0, 20.0]])
        rhs = np.vstack([span - initial, -initial, np.zeros_like(span)])
        self.coeffs = np.linalg.solve(system, rhs)

    def sample(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Joint angles and velocities ``t`` seconds after the start."""
        if self.duration <= 0.0 or t >= self.duration:
            return self.goal.copy(), np.zeros_like(self.goal)
        s = max(t, 0.0) / self.duration
        a3, a4, a5 = self.coeffs
        initial = self.v0 * self.duration
        position = self.start + initial * s + a3 * s**3 + a4 * s**4 + a5 * s**5
        velocity = (initial + 3 * a3 * s**2 + 4 * a4 * s**3 + 5 * a5 * s**4) / self.duration
        return position, velocity

    def peak_joint_speeds(self) -> np.ndarray:
        times = np.linspace(0.0, self.duration, PLAN_SAMPLES)
        return np.max([np.abs(self.sample(t)[1]) for t in times[:-1]], axis=0)


def plan_joint_move(
    start: np.ndarray, v0: np.ndarray, goal: np.ndarray, max_speed: np.ndarray
) -> JointMove:
    """The shortest quintic move whose joint speeds stay within ``max_speed``."""
    span = np.abs(goal - start)
    duration = float(np.max(1.875 * span / max_speed))  # 1.875: quintic peak / mean speed
    if not np.any(v0) and duration == 0.0:
        return JointMove(start, goal, v0, 0.0)
    duration = max(duration, 0.05)
    allowed = np.maximum(max_speed, np.abs(v0)) * (1.0 + 1e-9)
    move = JointMove(start, goal, v0, duration)
    for _ in range(60):
        if np.all(move.peak_joint_speeds() <= allowed):
            break
        move = JointMove(start, goal, v0, move.duration * 1.15)
    return move


@dataclass
class Stopping:
    """A deceleration to rest over :data:`STOP_TIME_S`: of a twist, or of joint speeds."""

    twist: np.ndarray | None
    dq: np.ndarray
    elapsed: float = 0.0


class SimRobot(Robot):
    """The simulated TM5-900; see the module docstring."""

    name = "sim"

    def __init__(
        self,
        q0: np.ndarray | None = None,
        ik_rate_hz: float = 250.0,
        physics: ArmPhysics | None = None,
    ) -> None:
        if not (math.isfinite(ik_rate_hz) and ik_rate_hz > 0.0):
            raise ValueError(f"ik_rate_hz must be a positive number, got {ik_rate_hz}")
        start = tm5_900.INITIAL_Q.copy() if q0 is None else np.asarray(q0, dtype=float)
        if start.shape != (N_JOINTS,) or not np.all(np.isfinite(start)):
            raise ValueError(f"q0 must be {N_JOINTS} finite joint angles")
        if not _within_limits(start, tm5_900.JOINT_LIMITS):
            raise ValueError("q0 is outside the TM5-900's joint limits")
        self.ik_rate_hz = float(ik_rate_hz)
        self.model = load_model()
        self.data = mujoco.MjData(self.model)
        self.ik = DifferentialIK(self.model, tm5_900.JOINT_LIMITS)
        self.ik_info = IKInfo()
        self.last_stop_reason: str | None = None
        self._site = self.model.site("tcp").id
        self._q = start
        self._dq = np.zeros(N_JOINTS)
        self._t = 0.0
        self._connected = False
        self._fault: str | None = None
        self._twist = np.zeros(6)
        self._twist_t = 0.0
        self._executed_twist = np.zeros(6)
        self._move: JointMove | None = None
        self._stopping: Stopping | None = None
        self._tcp_twist = np.zeros(6)
        self._velocity_mode = False
        self.physics = physics
        if physics is not None:
            physics.place_arm(start)
        self._sync()

    # -- connection ----------------------------------------------------------------

    @property
    def connected(self) -> bool:
        return self._connected

    @property
    def t(self) -> float:
        """Simulated time, seconds since construction."""
        return self._t

    def connect(self) -> None:
        self._connected = True
        self._fault = None

    def disconnect(self) -> None:
        self._halt()
        self._connected = False

    def _require_connected(self) -> None:
        if not self._connected:
            raise RobotError("simulated robot is not connected")
        if self._fault is not None:
            raise RobotError(f"simulated robot is in a fault: {self._fault}")

    # -- reading -------------------------------------------------------------------

    def joint_limits(self) -> JointLimits:
        return tm5_900.JOINT_LIMITS

    def capabilities(self) -> RobotCapabilities:
        """The TM5-900 model and drawing, its home and initial poses, how it stops (a ramp
        over :data:`STOP_TIME_S`) and how it follows a twist: joint velocities held for
        one IK step, then :data:`TRACKING_ERROR` at most off the commanded speeds."""
        return RobotCapabilities(
            kinematics=tm5_900.kinematics(),
            scene=tm5_900.scene(),
            default_poses={"home": tm5_900.HOME_Q, "initial": tm5_900.INITIAL_Q},
            stop_time_s=STOP_TIME_S,
            control_period_s=1.0 / self.ik_rate_hz,
            tracking_error=TRACKING_ERROR,
            gripper=self.physics is not None and self.physics.has_gripper,
        )

    def tcp_pose(self) -> Pose:
        """The TCP pose from the MuJoCo model (base frame)."""
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, self.data.site_xmat[self._site])
        return Pose(self.data.site_xpos[self._site].copy(), quat)

    def state(self) -> RobotState:
        if not self._connected:
            raise RobotError("simulated robot is not connected")
        moving = (
            self._move is not None
            or self._stopping is not None
            or bool(np.any(np.abs(self._dq) > MOVING_SPEED))
        )
        return RobotState(
            t=self._t,
            q=self._q.copy(),
            dq=self._dq.copy(),
            tcp=self.tcp_pose(),
            tcp_twist=self._tcp_twist.copy(),
            moving=moving,
            fault=self._fault,
            gripper=self._gripper_state(),
        )

    def _gripper_state(self) -> GripperState | None:
        return None if self.physics is None else self.physics.gripper_state()

    # -- commands ------------------------------------------------------------------

    def _refuse(self, message: str) -> RobotError:
        """Stop whatever is running and build the error for a refused command."""
        self.stop()
        return RobotError(message)

    def send_twist(self, twist: np.ndarray) -> None:
        self._require_connected()
        try:
            command = finite_vector(twist, 6, "twist")
        except ValueError as exc:
            raise self._refuse(str(exc)) from None
        self._move = None
        self._stopping = None
        self._velocity_mode = True
        self._twist = command
        self._twist_t = self._t

    def move_to_joints(self, q: np.ndarray, speed_fraction: float = 0.2) -> None:
        self._require_connected()
        goal = self._joint_goal(q)
        fraction = self._fraction(speed_fraction)
        limits = tm5_900.JOINT_LIMITS
        self._start_move(plan_joint_move(self._q, self._dq, goal, fraction * limits.max_speed))

    def move_to_pose(self, pose: Pose, speed: float = 0.05) -> None:
        self._require_connected()
        if not isinstance(pose, Pose):
            raise self._refuse(f"pose must be a Pose, got {type(pose).__name__}")
        if not (isinstance(speed, int | float) and math.isfinite(speed) and speed > 0.0):
            raise self._refuse(f"speed must be a positive number of m/s, got {speed!r}")
        target = np.eye(4)
        target[:3, :3] = pose.rotation()
        target[:3, 3] = pose.position
        goal = None
        for seed in (self._q, tm5_900.INITIAL_Q):
            goal = self.ik.solve_pose(seed, target)
            if goal is not None:
                break
        if goal is None:
            raise self._refuse(f"pose at {np.round(pose.position, 3).tolist()} m is unreachable")
        move = plan_joint_move(self._q, self._dq, goal, tm5_900.JOINT_LIMITS.max_speed)
        for _ in range(10):
            peak = _peak_tcp_speed(move)
            if peak <= speed * (1.0 + 1e-3) or move.duration == 0.0:
                break
            move = JointMove(move.start, move.goal, move.v0, move.duration * peak / speed * 1.001)
        self._start_move(move)

    def set_gripper(self, closed: bool) -> None:
        """Close or open the task scene's gripper (the arm keeps doing what it does)."""
        self._require_connected()
        if self.physics is None or not self.physics.has_gripper:
            raise RobotError("this arm has no gripper (load a task scene with one)")
        if not isinstance(closed, bool | np.bool_):
            raise RobotError(f"gripper command must be True or False, got {closed!r}")
        self.physics.set_gripper(bool(closed))

    def stop(self) -> None:
        if self._stopping is not None:
            return
        if self._velocity_mode:
            self._stopping = Stopping(twist=self._executed_twist.copy(), dq=self._dq.copy())
        elif self._move is not None or np.any(self._dq):
            self._stopping = Stopping(twist=None, dq=self._dq.copy())
        self._move = None
        self._velocity_mode = False
        self._twist = np.zeros(6)

    def _joint_goal(self, q: np.ndarray) -> np.ndarray:
        try:
            goal = finite_vector(q, N_JOINTS, "joint target")
        except ValueError as exc:
            raise self._refuse(str(exc)) from None
        if not _within_limits(goal, tm5_900.JOINT_LIMITS):
            raise self._refuse("joint target is outside the joint limits")
        return goal

    def _fraction(self, speed_fraction: float) -> float:
        ok = isinstance(speed_fraction, int | float) and math.isfinite(speed_fraction)
        if not (ok and 0.0 < speed_fraction <= 1.0):
            raise self._refuse(f"speed_fraction must be in (0, 1], got {speed_fraction!r}")
        return float(speed_fraction)

    def _start_move(self, move: JointMove) -> None:
        self._stopping = None
        self._velocity_mode = False
        self._twist = np.zeros(6)
        self._move = move

    # -- simulation ----------------------------------------------------------------

    def step(self, dt: float) -> None:
        """Advance the simulation by ``dt`` seconds (at most :data:`MAX_STEP_S`) in substeps
        of at most 1/ik_rate_hz."""
        if not (math.isfinite(dt) and dt >= 0.0):
            raise ValueError(f"dt must be a finite non-negative number of seconds, got {dt}")
        if dt > MAX_STEP_S:
            log.warning("simulated arm: a step of %.3g s capped to %g s", dt, MAX_STEP_S)
            dt = MAX_STEP_S
        substeps = max(1, math.ceil(dt * self.ik_rate_hz - 1e-9))
        for _ in range(substeps):
            self._substep(dt / substeps)

    def _substep(self, h: float) -> None:
        self._t += h
        if h == 0.0:
            return
        start = self._q
        self._move_arm(h)
        if self.physics is not None:
            self.physics.advance(start, self._q, h)

    def _move_arm(self, h: float) -> None:
        """One substep of the kinematic arm: a twist, a joint move, a stop, or rest."""
        if self._velocity_mode and self._t - self._twist_t > STALE_COMMAND_S + 1e-9:
            self.last_stop_reason = f"no velocity command for {STALE_COMMAND_S} s"
            self.stop()
        if self._velocity_mode:
            self._follow_twist(self._twist, h)
            self._executed_twist = self.ik_info.scale * self._twist
        elif self._move is not None:
            self._move.elapsed += h
            q, self._dq = self._move.sample(self._move.elapsed)
            self._q = np.clip(q, tm5_900.JOINT_LIMITS.lower, tm5_900.JOINT_LIMITS.upper)
            if self._move.elapsed >= self._move.duration:
                self._move = None
        elif self._stopping is not None:
            self._decelerate(self._stopping, h)
        else:
            self._dq = np.zeros(N_JOINTS)
        self._sync()

    def _follow_twist(self, twist: np.ndarray, h: float) -> None:
        try:
            velocity, self.ik_info = self.ik.step(self._q, twist, h)
        except mink.NoSolutionFound:
            self._fault = "the IK found no solution; connect again to clear"
            self._halt()
            return
        limits = tm5_900.JOINT_LIMITS
        self._q = np.clip(self._q + velocity * h, limits.lower, limits.upper)
        self._dq = velocity

    def _decelerate(self, stopping: Stopping, h: float) -> None:
        stopping.elapsed += h
        remaining = max(0.0, 1.0 - stopping.elapsed / STOP_TIME_S)
        if stopping.twist is not None:
            self._follow_twist(stopping.twist * remaining, h)
        else:
            limits = tm5_900.JOINT_LIMITS
            self._dq = stopping.dq * remaining
            self._q = np.clip(self._q + self._dq * h, limits.lower, limits.upper)
        if remaining == 0.0:
            self._stopping = None
            self._dq = np.zeros(N_JOINTS)

    def _halt(self) -> None:
        """Drop every command at once (disconnect: the simulation stops with it)."""
        self._move = None
        self._stopping = None
        self._velocity_mode = False
        self._twist = np.zeros(6)
        self._dq = np.zeros(N_JOINTS)
        self._sync()

    def _sync(self) -> None:
        self.data.qpos[:] = self._q
        mujoco.mj_kinematics(self.model, self.data)
        mujoco.mj_comPos(self.model, self.data)
        jacp, jacr = np.zeros((3, N_JOINTS)), np.zeros((3, N_JOINTS))
        mujoco.mj_jacSite(self.model, self.data, jacp, jacr, self._site)
        self._tcp_twist = np.concatenate([jacp @ self._dq, jacr @ self._dq])


def _within_limits(q: np.ndarray, limits: JointLimits) -> bool:
    tolerance = 1e-9
    return bool(np.all(q >= limits.lower - tolerance) and np.all(q <= limits.upper + tolerance))


def _peak_tcp_speed(move: JointMove) -> float:
    """Largest TCP linear speed along a joint move (sampled)."""
    peak = 0.0
    for t in np.linspace(0.0, move.duration, PLAN_SAMPLES):
        q, dq = move.sample(float(t))
        peak = max(peak, float(np.linalg.norm(tm5_900.jacobian(q)[:3] @ dq)))
    return peak
