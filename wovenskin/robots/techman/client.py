"""TechmanRobot: a Techman arm driven through TMflow's Listen Node and read via Ethernet Slave.

Two TCP connections: scripts go to the Listen Node (port 5890) as ``TMSCT`` packets; state
comes from the Ethernet Slave (port 5891), which pushes its data table in binary mode
(Techman's default for its drivers) or JSON mode, both read here (:mod:`.ethernet_slave`).
The table must hold ``Joint_Angle``, ``Coord_Robot_Tool``, ``TCP_Speed``, ``Robot_Error``
and ``Error_Code``; ``TCP_Speed3D``, ``Joint_Speed``, ``ESTOP`` and ``Project_Run`` are
used when present. A frame that fails its checks (corrupt bytes, wrong types, NaN) is
dropped and counted; the state then goes stale and reports a one-line fault. The links
themselves (sockets, reader threads, script answers) are :mod:`.connection`'s.

Velocity mode (:mod:`.velocity`): the first twist sends ``ContinueVLine(300,2000)`` (the
controller's zero-velocity and stop timeouts, ms) and waits for its answer; each twist
then sends ``SetContinueVLine(vx, vy, vz, wx, wy, wz)`` in mm/s and deg/s (base frame)
without waiting, so a tick costs no round trip; a refused or unanswered script surfaces as
one :class:`RobotError` on the next call. A watch thread sends a zero velocity when no
twist arrives for ``command_timeout_s``, and while the commanded velocity is zero it
re-sends it every ``keepalive_s`` so the mode outlives the idle time between gestures.
``stop`` sends ``StopContinueVmode()`` and ``StopAndClearBuffer()``. Point-to-point moves
are ``PTP("JPP", ...)`` and ``Line("CAP", ...)`` followed by ``QueueTag(n)``; the watch
thread polls the tag (``TMSTA 01``) to know when the move is over.

The controller's ``0,NAME`` message (the flow entered the Listen Node) is recorded, not
taken for an error. docs/techman.md describes the setup and every error message.
"""

from __future__ import annotations

import contextlib
import logging
import threading
import time
from collections.abc import Callable

import numpy as np

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
from wovenskin.robots.sim import tm5_900
from wovenskin.robots.techman.connection import TechmanConnection, one_line
from wovenskin.robots.techman.protocol import (
    ETHERNET_SLAVE_PORT,
    LISTEN_NODE_PORT,
    PacketError,
    call,
    pose_from_wire,
    pose_to_wire,
    status_packet,
)
from wovenskin.robots.techman.velocity import VelocityTimeouts, enter_refused

log = logging.getLogger(__name__)

_MOVING_SPEED_MM_S = 1.0  # measured TCP speed above which the arm counts as moving
_MOVING_SPEED_DEG_S = 0.5  # measured TCP angular speed above which it counts as moving
_TAG_POLL_S = 0.05
_WATCH_PERIOD_S = 0.01
_ZERO_TWIST = (0.0,) * 6


class TechmanRobot(TechmanConnection, Robot):
    """A Techman arm (TM5-900 by default) over the Listen Node and Ethernet Slave."""

    name = "techman"

    def __init__(
        self,
        host: str,
        port: int = LISTEN_NODE_PORT,
        state_port: int = ETHERNET_SLAVE_PORT,
        *,
        timeout_s: float = 1.0,
        command_timeout_s: float = 0.2,
        accel_time_ms: int = 200,
        max_speed_mm_s: float = 250.0,
        stale_state_s: float = 0.5,
        velocity_timeouts: VelocityTimeouts | None = None,
        limits: JointLimits | None = None,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        timeouts = velocity_timeouts or VelocityTimeouts()
        if not 0.0 < command_timeout_s < timeouts.zero_velocity_s:
            raise ValueError(
                f"command timeout {command_timeout_s} s must be positive and shorter than the "
                f"controller's zero-velocity timeout ({timeouts.zero_velocity_ms} ms)"
            )
        super().__init__(
            host,
            port,
            state_port,
            timeout_s=timeout_s,
            stale_state_s=stale_state_s,
            velocity_timeouts=timeouts,
            clock=clock,
        )
        self.command_timeout_s = command_timeout_s
        self.accel_time_ms = int(accel_time_ms)
        self.max_speed_mm_s = float(max_speed_mm_s)
        self._limits = limits if limits is not None else tm5_900.JOINT_LIMITS
        # counters a caller or test may read
        self.watchdog_stops = 0  # zero velocities sent because twists stopped arriving
        self.keepalives = 0  # zero velocities re-sent to keep an idle velocity mode alive
        self.velocity_mode_entries = 0  # ContinueVLine accepted
        self._velocity_lock = threading.RLock()  # one writer of velocity commands at a time

    def _extra_threads(self) -> tuple[Callable[[], None], ...]:
        return (self._watch,)

    def disconnect(self) -> None:
        if not self._connected:
            return
        if self._lost is None:
            with contextlib.suppress(RobotError):
                self.stop()
        self._shutdown()

    @property
    def in_velocity_mode(self) -> bool:
        """Whether the client believes the controller is in velocity mode."""
        return self._velocity_mode

    def _require_link(self) -> None:
        if not self._connected:
            raise RobotError("Techman robot is not connected")
        if self._lost is not None:
            raise RobotError(f"Techman robot: {self._lost}")

    def _raise_pending_failure(self) -> None:
        """Raise for a streamed script the robot refused or never answered."""
        with self._cond:
            now = self._clock()
            late = [name for sent, name in self._in_flight.values() if now - sent > self.timeout_s]
            if late:
                self._failures.append(
                    f"the robot did not answer {late[0]} within {self.timeout_s:g} s"
                )
                self._in_flight.clear()
            if not self._failures:
                return
            failure = self._failures[0]
            self._failures.clear()
        with contextlib.suppress(RobotError):
            self.stop()
        with self._cond:
            self._failures.clear()  # answers that arrived while stopping belong to this one
        raise RobotError(failure)

    def _check_fault(self) -> None:
        fault = self._fault()
        if fault is not None:
            with self._cond:
                self._failures.clear()  # refusals during a fault are explained by it
            raise RobotError(f"Techman robot: {fault}")

    # -- velocity mode ----------------------------------------------------------------

    def _enter_velocity_mode(self) -> None:
        """Send ``ContinueVLine`` and wait for it; a refusal raises one explained line."""
        if self._pending_tag is not None:
            self._script(call("StopAndClearBuffer"))
            self._pending_tag = None
        if self._mode_doubtful:  # leave a mode that may linger before entering afresh
            self._script(call("StopContinueVmode"), check=False)
            self._mode_doubtful = False
        reply = self._script(self.velocity_timeouts.enter_script(), check=False)
        assert reply is not None
        if not reply.ok:
            self.velocity_refusals += 1
            message = enter_refused(reply.error_lines, self._entered_before)
            log.info("Techman: %s", message)
            raise RobotError(message)
        self._velocity_mode = True
        self._entered_before = True
        self.velocity_mode_entries += 1
        self._last_velocity_sent_t = self._clock()
        if self.velocity_mode_entries > 1:
            log.info("Techman: velocity mode entered again (%d times)", self.velocity_mode_entries)

    def _send_velocity(self, values: tuple[float, ...] | list[float], now: float) -> None:
        self._last_velocity_sent_t = now
        self._script(call("SetContinueVLine", *values), wait=False)

    def _mode_went_stale(self, now: float) -> bool:
        """If no velocity went out for half the controller's stop timeout, stop trusting
        the mode (the controller may have left it): the next twist re-enters it."""
        idle = now - self._last_velocity_sent_t
        if not self._velocity_mode or idle < self.velocity_timeouts.reenter_after_s:
            return False
        self._velocity_mode_ended()
        self._mode_doubtful = True
        log.warning(
            "Techman: no velocity command went out for %.2f s (the controller leaves velocity "
            "mode after %d ms); the next command re-enters velocity mode",
            idle,
            self.velocity_timeouts.stop_ms,
        )
        return True

    def _leave_velocity_mode(self) -> None:
        with self._velocity_lock:
            if self._velocity_mode:
                self._velocity_mode_ended()
                self._script(call("StopContinueVmode"))
            elif self._mode_doubtful:
                self._mode_doubtful = False
                self._script(call("StopContinueVmode"), check=False)

    # -- watch thread: command timeout, keep-alive and move tags ----------------------

    def _watch(self) -> None:
        keepalive_s = self.velocity_timeouts.keepalive_s
        while not self._closing.wait(_WATCH_PERIOD_S):
            if self._lost is not None:
                continue
            try:
                with self._velocity_lock:
                    now = self._clock()
                    if self._mode_went_stale(now):
                        pass
                    elif self._velocity_mode and self._twist_nonzero:
                        if now - self._last_twist_t > self.command_timeout_s:
                            self._twist_nonzero = False
                            self.watchdog_stops += 1
                            self._send_velocity(_ZERO_TWIST, now)
                    elif self._velocity_mode and now - self._last_velocity_sent_t >= keepalive_s:
                        self.keepalives += 1
                        self._send_velocity(_ZERO_TWIST, now)
                now = self._clock()
                if self._pending_tag is not None and now - self._tag_polled_t > _TAG_POLL_S:
                    self._tag_polled_t = now
                    self._send(status_packet("01", str(self._pending_tag)))
            except RobotError:
                continue

    # -- the Robot interface ----------------------------------------------------------

    def joint_limits(self) -> JointLimits:
        return self._limits

    def capabilities(self) -> RobotCapabilities:
        """The TM5-900 model and drawing. No stop profile is declared (the safety layer
        then assumes its conservative stop time) and no default poses (a real arm goes
        only to poses the user stored); 1 % tracking allowance, assumed, not measured."""
        return RobotCapabilities(
            kinematics=tm5_900.kinematics(), scene=tm5_900.scene(), tracking_error=0.01
        )

    def state(self) -> RobotState:
        if not self._connected:
            raise RobotError("Techman robot is not connected")
        with self._cond:
            current = self._state
            t = self._state_t
        if current is None:
            raise RobotError(f"Techman robot: {self._fault()}")
        try:
            tcp = pose_from_wire(current.tool_wire)
        except PacketError as exc:
            raise RobotError(f"Techman state frame is unusable: {one_line(exc)}") from None
        speed = current.tcp_speed
        twist = np.concatenate([speed[:3] / 1000.0, np.deg2rad(speed[3:])])
        joint_speed = current.joint_speed_deg_s
        dq = np.zeros(6) if joint_speed is None else np.deg2rad(joint_speed)
        commanding = self._velocity_mode and self._twist_nonzero
        moving = (
            commanding
            or self._pending_tag is not None
            or t <= self._tag_done_t
            or current.linear_speed_mm_s > _MOVING_SPEED_MM_S
            or float(np.linalg.norm(speed[3:])) > _MOVING_SPEED_DEG_S
        )
        return RobotState(
            t=t,
            q=np.deg2rad(current.joint_deg),
            dq=dq,
            tcp=tcp,
            tcp_twist=twist,
            moving=moving,
            fault=self._fault(),
        )

    def send_twist(self, twist: np.ndarray) -> None:
        command = command_twist(twist)
        linear_mm_s = command[:3] * 1000.0
        if float(np.linalg.norm(linear_mm_s)) > self.max_speed_mm_s * (1 + 1e-6):
            raise RobotError(
                f"twist speed {np.linalg.norm(command[:3]):.3f} m/s exceeds "
                f"{self.max_speed_mm_s / 1000.0:.3f} m/s"
            )
        self._require_link()
        self._check_fault()
        self._raise_pending_failure()
        with self._velocity_lock:
            now = self._clock()
            self._mode_went_stale(now)
            if not self._velocity_mode:
                self._enter_velocity_mode()
            values = [*linear_mm_s, *np.rad2deg(command[3:])]
            self._last_twist_t = now
            self._twist_nonzero = bool(np.any(command != 0.0))
            self._send_velocity(values, self._clock())

    def _start_move(self, line: str) -> None:
        self._require_link()
        self._check_fault()
        self._raise_pending_failure()
        self._leave_velocity_mode()
        self._tag = self._tag % 15 + 1
        self._script(f"{line}\r\n{call('QueueTag', self._tag)}")
        self._pending_tag = self._tag
        self._tag_polled_t = self._clock()

    def move_to_joints(self, q: np.ndarray, speed_fraction: float = 0.2) -> None:
        target = joint_move_target(q, speed_fraction, self._limits)
        percent = max(1, int(round(speed_fraction * 100)))
        degrees = np.rad2deg(target)
        self._start_move(call("PTP", "JPP", *degrees, percent, self.accel_time_ms, 0, False))

    def move_to_pose(self, pose: Pose, speed: float = 0.05) -> None:
        check_pose_move(pose, speed, self.max_speed_mm_s / 1000.0)
        speed_mm_s = speed * 1000.0
        wire = pose_to_wire(pose)
        speed_arg = max(1, int(round(speed_mm_s)))
        self._start_move(call("Line", "CAP", *wire, speed_arg, self.accel_time_ms, 0, False))

    def stop(self) -> None:
        if not self._connected or self._lost is not None:
            return
        errors: list[str] = []
        for action in (self._leave_velocity_mode, lambda: self._script(call("StopAndClearBuffer"))):
            try:
                action()
            except RobotError as exc:
                errors.append(str(exc))
        self._pending_tag = None
        if errors:
            raise RobotError(errors[0])
