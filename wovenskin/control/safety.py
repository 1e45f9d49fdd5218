"""The safety layer: every command to every robot backend passes through :class:`SafetyLayer`.

It wraps a backend and is itself a :class:`~wovenskin.robots.base.Robot`. The backend's
declaration (:meth:`~wovenskin.robots.base.Robot.capabilities`, resolved by
:class:`~wovenskin.control.arm_model.ArmModel`) must give the arm's kinematics (forward
kinematics and Jacobian): an arm without them is refused with a one-line
:class:`RobotError` unless the user opts into **degraded safety** (``degraded=True``, or
``safety=degraded`` in the robot spec), which a warning in the log announces. Each twist
is checked before it is forwarded:

- a non-finite or wrongly shaped twist stops the arm (a latched stop) and raises
  ``ValueError``; it is never forwarded;
- the linear and angular parts are scaled down (direction kept) to the speed caps
  (250 mm/s: the reduced speed for manual guidance in ISO 10218-1) **as the arm will
  report them**: under the caps divided by ``1 + tracking_error`` (the backend's declared
  headroom), and, from the Jacobian, with the speeds the arm reports at the end of its
  control period (a backend holding joint velocities for a period ends it a little off
  the commanded twist, by several per cent near singularities);
- each linear component that would carry the TCP out of the workspace box within the
  prediction horizon **plus the stopping distance** (speed x stop time / 2) is reduced so
  the TCP stops at the wall (less a standoff of the backend's tracking error); outside
  the box only motion back inside is allowed;
- if a joint is (or would within the horizon plus its stopping distance be) within the
  margin of its limit and the command drives it further, the command is not forwarded
  and the arm stops. The joint motion is predicted from the Jacobian (in degraded mode
  the reported joint velocities are used, one tick late).

The stop time is the backend's declared one (``stop_time_s`` or ``stop_deceleration``),
else :attr:`SafetyLimits.assumed_stop_time_s`. Point-to-point moves are refused
(``RobotError``) when the target lies outside the box or the joint limits less the margin,
and run no faster than the caps allow. Watchdogs stop the arm when the skin stream or the
command stream is silent for longer than ``watchdog_s``; :meth:`SafetyLayer.emergency_stop`
(the stop key) latches like them until :meth:`SafetyLayer.clear_stop`. Every safety stop
is a :class:`StopEvent` with a one-line reason, also logged through :mod:`logging`; the
caller's own :meth:`SafetyLayer.stop` is a plain stop and records nothing. See
``docs/safety.md``. The limits, stop records and the cap and box rules are
:mod:`.safety_limits`'; the planning of joint moves is :mod:`.joint_moves`'.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable

import numpy as np

from wovenskin.control.arm_model import ArmModel
from wovenskin.control.joint_moves import Jacobian, Kinematics, capped_fraction, path_leaves_box
from wovenskin.control.safety_limits import (
    SafetyLimits,
    StopEvent,
    cap_speeds,
    held_back,
    keep_in_box,
)
from wovenskin.control.watchdogs import Watchdogs
from wovenskin.robots.base import (
    N_JOINTS,
    JointLimits,
    Pose,
    Robot,
    RobotCapabilities,
    RobotError,
    RobotState,
    finite_vector,
    rotation_angle,
)

log = logging.getLogger(__name__)

MOVE_SPEED_TOLERANCE = 1.02  # a running move is stopped above 102 % of the speed cap


class SafetyLayer(Robot):
    """A :class:`Robot` that checks every command before the wrapped backend sees it."""

    def __init__(
        self,
        robot: Robot,
        limits: SafetyLimits | None = None,
        clock: Callable[[], float] = time.monotonic,
        jacobian: Jacobian | None = None,
        forward_kinematics: Kinematics | None = None,
        degraded: bool | None = None,
    ) -> None:
        """Wrap ``robot``. ``jacobian`` and ``forward_kinematics`` override the declared
        kinematics; ``degraded`` (default: the backend's ``degraded_safety`` opt-in from the
        robot spec) accepts an arm that lacks what the full checks need."""
        self.robot = robot
        self.limits = limits or SafetyLimits()
        self.name = robot.name
        self._clock = clock
        self.model = ArmModel.resolve(
            robot, self.limits.assumed_stop_time_s, jacobian, forward_kinematics
        )
        opted_in = bool(robot.degraded_safety if degraded is None else degraded)
        self.degraded = opted_in and bool(self.model.missing)
        self._announce(opted_in)
        self._jacobian = self.model.jacobian
        self._fk = self.model.forward
        self._joint_limits: JointLimits | None = None
        self._stops: list[StopEvent] = []
        self._latched: StopEvent | None = None
        self._watchdogs = Watchdogs(self.limits.watchdog_s)
        self._sent = np.zeros(6)  # the twist the backend is moving with
        self._refusing: str | None = None  # the reason of a refusal still in force
        self._in_move = False  # a point-to-point move of ours may be running
        self._blocked: tuple[np.ndarray, str] | None = None  # refused direction, no Jacobian
        self._limiting: tuple[str, ...] = ()  # what held back the last twist (limiting)

    def _announce(self, opted_in: bool) -> None:
        """Refuse an arm the full checks cannot cover, or say how the checks are weakened."""
        missing = " and ".join(self.model.missing)
        if self.model.missing and not opted_in:
            hint = self.model.capabilities.how_to_complete
            raise RobotError(
                f"the safety layer needs the {self.name} arm's {missing}, which its backend "
                f"does not declare; {hint + '; or ' if hint else ''}opt into degraded safety "
                "(safety=degraded in the robot spec, see docs/safety.md)"
            )
        if self.model.missing:
            log.warning(
                "safety DEGRADED for the %s arm (the user opted in): no %s, so joint margins "
                "use the reported joint velocities (one tick late), joint moves are not "
                "checked along their path and their TCP speed is bounded with a %.1f m reach",
                self.name, missing, self.limits.arm_reach,
            )  # fmt: skip
        elif opted_in:
            log.info("safety: degraded mode requested for %s, but nothing is missing", self.name)
        if not self.model.declares_stop:
            log.info(
                "safety: %s declares no stop time; margins assume %.2f s to rest",
                self.name, self.limits.assumed_stop_time_s,
            )  # fmt: skip

    # -- state of the layer

    @property
    def stops(self) -> list[StopEvent]:
        """Every safety stop so far, oldest first."""
        return list(self._stops)

    @property
    def stopped(self) -> bool:
        """Whether a latched stop holds the arm (cleared by :meth:`clear_stop`)."""
        return self._latched is not None

    @property
    def last_twist(self) -> np.ndarray:
        """The twist last forwarded to the backend (zero after a stop)."""
        return self._sent.copy()

    @property
    def limiting(self) -> tuple[str, ...]:
        """Read-only report for views: one line per limit that holds the arm back now --
        the latched stop, or what scaled or refused the last twist sent (speed cap,
        workspace box face, joint margin); empty when the last twist ran as asked."""
        if self._latched is not None:
            return (f"{self._latched.source}: {self._latched.reason}",)
        return self._limiting

    # -- Robot interface

    def connect(self) -> None:
        self.robot.connect()

    def disconnect(self) -> None:
        self._sent = np.zeros(6)
        self.robot.disconnect()

    def state(self) -> RobotState:
        return self.robot.state()

    def capabilities(self) -> RobotCapabilities:
        """The wrapped backend's declaration."""
        return self.model.capabilities

    def joint_limits(self) -> JointLimits:
        if self._joint_limits is None:
            self._joint_limits = self.robot.joint_limits()
        return self._joint_limits

    def send_twist(self, twist: np.ndarray) -> None:
        now = self._now()
        command = self._checked_twist(twist, now)
        self._watchdogs.command(now)
        if self._latched is not None:
            if np.any(command):
                raise RobotError(f"robot is stopped ({self._latched.reason}); clear the stop first")
            return
        self._forward(command, self.limits.box_horizon_s, self.limits.joint_horizon_s, now)
        self._limiting = held_back(command, self._sent, self._refusing, self.limits)

    def move_to_joints(self, q: np.ndarray, speed_fraction: float = 0.2) -> None:
        self._require_running()
        goal = finite_vector(q, N_JOINTS, "joint target")
        fraction = _fraction(speed_fraction)
        limits = self.joint_limits()
        margin = self.limits.joint_margin
        outside = (goal < limits.lower + margin) | (goal > limits.upper - margin)
        if np.any(outside):
            joint = int(np.flatnonzero(outside)[0]) + 1
            self._refuse(
                f"joint target refused: joint {joint} at {math.degrees(goal[joint - 1]):.1f} deg "
                f"is within {math.degrees(margin):.1f} deg of its limit or beyond",
                "joint limit",
            )
        start = np.asarray(self.robot.state().q, dtype=float)
        leaves = path_leaves_box(self._fk, start, goal, self.limits)
        if leaves is not None:
            where = ", ".join(f"{v:.3f}" for v in leaves)
            self._refuse(
                f"joint target refused: the TCP would pass [{where}] m, outside the workspace box",
                "workspace",
            )
        self._sent = np.zeros(6)
        self._in_move = False
        capped = capped_fraction(self._jacobian, start, goal, fraction, limits, self.limits)
        self.robot.move_to_joints(goal, capped)
        self._in_move = True

    def move_to_pose(self, pose: Pose, speed: float = 0.05) -> None:
        self._require_running()
        if not isinstance(pose, Pose):
            raise ValueError(f"pose must be a Pose, got {type(pose).__name__}")
        ok = isinstance(speed, int | float) and not isinstance(speed, bool)
        if not (ok and math.isfinite(speed) and speed > 0.0):
            raise ValueError(f"speed must be a positive number of m/s, got {speed!r}")
        if not self.limits.in_box(pose.position):
            where = ", ".join(f"{v:.3f}" for v in pose.position)
            self._refuse(f"pose target [{where}] m is outside the workspace box", "workspace")
        self._sent = np.zeros(6)
        self._in_move = False
        cap = self.limits.max_linear_speed / self.model.headroom
        self.robot.move_to_pose(pose, min(float(speed), cap, self._turn_speed_cap(pose)))
        self._in_move = True

    def _turn_speed_cap(self, pose: Pose) -> float:
        """The linear speed (m/s) at which a move to ``pose`` that turns the tool in step
        with its travel (a line with the orientation interpolated along it) keeps under the
        angular cap: the angular cap times the way over the turn (``inf`` for no turn; at
        least 1 mm/s, and :meth:`_watch_move` stops a move that turns too fast anyway)."""
        tcp = self.robot.state().tcp
        way = float(np.linalg.norm(np.subtract(pose.position, tcp.position)))
        turn = rotation_angle(np.asarray(tcp.rotation()).T @ np.asarray(pose.rotation()))
        if turn < 1e-6:
            return math.inf
        return max(1e-3, self.limits.max_angular_speed / self.model.headroom * way / turn)

    def stop(self) -> None:
        self._sent = np.zeros(6)
        self._in_move = False
        self.robot.stop()

    def set_gripper(self, closed: bool) -> None:
        """Pass a gripper command on (``True`` closes); refused while a stop holds the arm."""
        self._require_running()
        if not isinstance(closed, bool | np.bool_):
            raise ValueError(f"gripper command must be True or False, got {closed!r}")
        self.robot.set_gripper(bool(closed))

    def step(self, dt: float) -> None:
        """Advance a simulated backend, first re-checking the running twist over ``dt``."""
        if not (math.isfinite(dt) and dt >= 0.0):
            raise ValueError(f"dt must be a finite non-negative number of seconds, got {dt}")
        if self._latched is None and np.any(self._sent):
            box = max(dt, self.limits.box_horizon_s)
            joints = max(dt, self.limits.joint_horizon_s)
            self._forward(self._sent, box, joints, self._now(), only_if_changed=True)
        elif self._latched is None and self._in_move:
            self._watch_move(max(dt, self.limits.box_horizon_s), self._now())
        self.robot.step(dt)

    # -- watchdogs and stops

    def heartbeat_skin(self, t: float | None = None) -> None:
        """The skin stream delivered a frame at ``t`` (default: now)."""
        self._watchdogs.skin(self._time(t))

    def heartbeat_command(self, t: float | None = None) -> None:
        """The control loop is alive at ``t`` (default: now), whether or not it moves."""
        self._watchdogs.command(self._time(t))

    def check(self, now: float | None = None) -> list[StopEvent]:
        """Run the watchdogs at ``now`` (default: the clock); returns the stops they made."""
        now = self._time(now)
        fired: list[StopEvent] = []
        if self._latched is not None:
            return fired  # already held: nothing more to stop
        if self._in_move:
            self._watch_move(self.limits.box_horizon_s, now)
        due = self._watchdogs.due(now)
        if due is not None:
            fired.append(self._stop_now(now, *due))
        return fired

    def emergency_stop(self, reason: str = "emergency stop") -> None:
        """Stop now and hold until :meth:`clear_stop` (the stop key)."""
        self._stop_now(self._now(), " ".join(str(reason).split()), "emergency")

    def clear_stop(self) -> None:
        """Release a latched stop; the armed watchdogs start counting again from now."""
        if self._latched is not None:
            log.info("safety stop cleared (was: %s)", self._latched.reason)
        self._watchdogs.restart(self._now())
        self._latched = None
        self._refusing = None
        self._blocked = None

    # -- internals

    def _now(self) -> float:
        return float(self._clock())

    def _time(self, t: float | None) -> float:
        value = self._now() if t is None else float(t)
        if not math.isfinite(value):
            raise ValueError(f"time must be finite, got {t!r}")
        return value

    def _require_running(self) -> None:
        if self._latched is not None:
            raise RobotError(f"robot is stopped ({self._latched.reason}); clear the stop first")

    def _record(self, now: float, reason: str, source: str) -> StopEvent:
        event = StopEvent(now, reason, source)
        self._stops.append(event)
        log.warning("robot stop (%s) at %.3f s: %s", source, now, reason)
        return event

    def _stop_now(self, now: float, reason: str, source: str) -> StopEvent:
        """A latched stop: record it, hold the arm, stop the backend."""
        event = self._record(now, reason, source)
        self._latched = event
        self._sent = np.zeros(6)
        self._in_move = False
        self.robot.stop()
        return event

    def _refuse(self, reason: str, source: str) -> None:
        """Refuse a point-to-point move: stop what runs, record and raise (not latched)."""
        self._record(self._now(), reason, source)
        self._sent = np.zeros(6)
        self._in_move = False
        self.robot.stop()
        raise RobotError(reason)

    def _checked_twist(self, twist: object, now: float) -> np.ndarray:
        try:
            return finite_vector(twist, 6, "twist")
        except ValueError as exc:
            problem = str(exc)
        self._stop_now(now, f"bad command refused: {problem}", "command")
        raise ValueError(problem)

    def _forward(
        self,
        command: np.ndarray,
        box_horizon: float,
        joint_horizon: float,
        now: float,
        only_if_changed: bool = False,
    ) -> None:
        """Limit ``command`` against the arm's state and send it (or stop the arm)."""
        if not np.any(command):
            self._refusing = None
            if np.any(self._sent) or self._in_move:  # else at rest or stopping: leave it be
                self._sent = np.zeros(6)
                self._in_move = False
                self.robot.send_twist(np.zeros(6))
            return
        state = self.robot.state()
        q = np.asarray(state.q, dtype=float)
        safe = self._within_caps(command, q)
        stopping = self.model.stop_time(safe) / 2.0  # distance = speed x this
        if np.any(safe):
            boxed = self._within_box(safe, q, state.tcp.position, box_horizon + stopping)
            if not np.array_equal(boxed, safe):  # a wall may have turned a component inward
                safe = self._within_caps(boxed, q)
        refusal = self._joint_refusal(safe, state, joint_horizon + stopping)
        if refusal is not None:
            if refusal != self._refusing:
                self._record(now, refusal, "joint limit")
            self._refusing = refusal
            self._sent = np.zeros(6)
            self.robot.stop()
            return
        self._refusing = None
        if only_if_changed and np.array_equal(safe, self._sent):
            return
        self._in_move = False
        self._sent = safe
        self.robot.send_twist(safe.copy())

    def _within_caps(self, command: np.ndarray, q: np.ndarray) -> np.ndarray:
        """``command`` scaled down (direction kept) so the speeds the arm will report stay
        under the caps: the declared headroom, then the end-of-period prediction."""
        max_linear = self.limits.max_linear_speed / self.model.headroom
        max_angular = self.limits.max_angular_speed / self.model.headroom
        safe = cap_speeds(command, max_linear, max_angular)
        if not np.any(safe):
            return safe
        ratio = self.model.measured_speed_ratio(q, safe, max_linear, max_angular)
        if ratio > 1.0:  # the reported speeds fall faster than the scale: one pass is enough
            safe = safe / ratio if math.isfinite(ratio) else np.zeros(6)
        return safe

    def _within_box(
        self, twist: np.ndarray, q: np.ndarray, position: np.ndarray, horizon: float
    ) -> np.ndarray:
        """``twist`` with its linear part limited so the TCP, as it really moves (the
        commanded velocity plus the model's drift), stays in the box over ``horizon``;
        the backend's tracking error keeps that share of the travel off the walls."""
        drift = self.model.linear_drift(q, twist)
        speed = float(np.linalg.norm(twist[:3] + drift))
        travel = speed * horizon
        # A velocity held in the turning tool's frame turns with it at |w|: over the horizon
        # the TCP leaves the straight line by up to |v| |w| h^2 / 2 (the arc's sagitta bound).
        bend = 0.5 * speed * float(np.linalg.norm(twist[3:])) * horizon**2
        standoff = self.model.capabilities.tracking_error * travel + bend
        out = twist.copy()
        out[:3] = keep_in_box(twist[:3] + drift, position, self.limits, horizon, standoff) - drift
        return out

    def _joint_refusal(self, twist: np.ndarray, state: RobotState, horizon: float) -> str | None:
        """Why ``twist`` may not run because of a joint margin, or ``None`` when it may."""
        if not np.any(twist):
            return None
        limits = self.joint_limits()
        margin = self.limits.joint_margin
        q = np.asarray(state.q, dtype=float)
        reach = margin + limits.max_speed * horizon  # where a refusal can come from
        near = (q > limits.upper - reach) | (q < limits.lower + reach)
        if self._jacobian is not None:
            dq = self.model.joint_velocities(q, twist)
            dq = np.clip(dq, -limits.max_speed, limits.max_speed)
        else:
            dq = np.asarray(state.dq, dtype=float)
            if self._blocked is not None and not np.any(near):
                self._blocked = None
            if self._blocked is not None and float(twist @ self._blocked[0]) > 0.0:
                return self._blocked[1]  # no model: anything like the refused twist stays refused
        ahead = q + dq * horizon
        toward = ((dq > 0) & (ahead > limits.upper - margin)) | (
            (dq < 0) & (ahead < limits.lower + margin)
        )
        if not np.any(toward):
            return None
        joint = int(np.flatnonzero(toward)[0])
        reason = (
            f"joint {joint + 1} would come within {math.degrees(margin):.1f} deg of its limit: "
            "command stopped"
        )
        if self._jacobian is None:
            self._blocked = (twist / float(np.linalg.norm(twist)), reason)
        return reason

    def _watch_move(self, horizon: float, now: float) -> None:
        """Stop a point-to-point move about to leave the box or a joint range, or too fast."""
        state = self.robot.state()
        if not state.moving:
            self._in_move = False
            return
        problem = None
        velocity = np.asarray(state.tcp_twist, dtype=float)
        position = np.asarray(state.tcp.position, dtype=float)
        horizon += self.model.stop_time(velocity) / 2.0  # the stopping distance too
        ahead = keep_in_box(velocity[:3], position, self.limits, horizon)
        if not np.allclose(ahead, velocity[:3], rtol=0.0, atol=1e-9):
            problem = ("the move would carry the TCP out of the workspace box", "workspace")
        elif state.tcp_speed > self.limits.max_linear_speed * MOVE_SPEED_TOLERANCE:
            problem = (f"the move ran at {1000 * state.tcp_speed:.0f} mm/s", "speed")
        elif np.linalg.norm(velocity[3:]) > self.limits.max_angular_speed * MOVE_SPEED_TOLERANCE:
            turning = math.degrees(float(np.linalg.norm(velocity[3:])))
            problem = (f"the move turned the tool at {turning:.0f} deg/s", "speed")
        else:
            limits = self.joint_limits()
            q, dq = np.asarray(state.q, dtype=float), np.asarray(state.dq, dtype=float)
            after = q + dq * horizon
            if np.any(((dq > 0) & (after > limits.upper)) | ((dq < 0) & (after < limits.lower))):
                problem = ("the move would drive a joint past its limit", "joint limit")
        if problem is not None:
            self._record(now, *problem)
            self._in_move = False
            self.robot.stop()


def _fraction(speed_fraction: object) -> float:
    ok = isinstance(speed_fraction, int | float) and not isinstance(speed_fraction, bool)
    if not (ok and math.isfinite(speed_fraction) and 0.0 < speed_fraction <= 1.0):  # type: ignore[arg-type]
        raise ValueError(f"speed_fraction must be in (0, 1], got {speed_fraction!r}")
    return float(speed_fraction)  # type: ignore[arg-type]
