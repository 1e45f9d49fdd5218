"""From the active command to the robot, top to bottom: the part of a control session that
moves the arm.

Each tick :meth:`Drive.control` takes the active command (a skin gesture or a held input,
:func:`~wovenskin.control.session_inputs.active_command`) and

1. holds still while the safety layer holds a stop;
2. lets a running pose move go on, or ends it (:class:`~wovenskin.control.session_poses.PoseMover`);
3. starts the pose move of a pose action, once per command;
4. else drives a twist: the action's twist at the mapping's full speeds
   (:meth:`~wovenskin.control.mapping.ActionMapping.twist_of`, or a joint jog's), times the
   speed override and, for a gesture, the speed profile
   (:class:`~wovenskin.control.gesture_motion.GestureMotion`); after a flick's lift, its
   nudge; shaped by :class:`~wovenskin.control.motion.TwistShaper` and sent through the
   session's :class:`~wovenskin.control.safety.SafetyLayer`, which passes it to the robot.

A robot error stops the arm and is reported as one line; nothing is retried.
"""

from __future__ import annotations

import logging
from typing import Any

import numpy as np

from wovenskin.control.gesture_motion import GestureMotion
from wovenskin.control.mapping import ActionMapping, PoseAction, TwistAction
from wovenskin.control.motion import TwistShaper
from wovenskin.control.safety import SafetyLayer
from wovenskin.control.session_inputs import ActiveCommand, JointJog
from wovenskin.control.session_poses import PoseMove, PoseMover
from wovenskin.control.session_state import Reporter, SessionSettings, SessionState
from wovenskin.robots.base import Robot, RobotError, RobotState

log = logging.getLogger(__name__)


class Drive:
    """Moves the arm for the active command (see the module docstring)."""

    def __init__(
        self,
        mapping: ActionMapping,
        safety: SafetyLayer,
        poses: PoseMover,
        state: SessionState,
        settings: SessionSettings,
        report: Reporter,
    ) -> None:
        self.mapping, self.safety, self.poses = mapping, safety, poses
        self.state, self.settings, self.report = state, settings, report
        self.shaper = TwistShaper(mapping.settings, safety.capabilities().release_stop_s)
        self.gesture_motion = GestureMotion(mapping)
        self.speed_scale = 1.0  # a pendant's override, 0.01-1 of the mapping's speeds
        self._pose_tried: float | None = None  # the start of the last pose command tried
        self.simulated = type(safety.robot).step is not Robot.step  # moves on session time
        self._robot_t: float | None = None  # session time a simulated robot has reached

    def control(self, command: ActiveCommand, t: float, dt: float, tick_t: float | None) -> None:
        """One tick of the active ``command`` at session time ``t``."""
        label, action, frame, since = command
        if self.safety.stopped:
            self.halt()
            self.state.action = "stopped"
            return
        if self.poses.move is not None and not self._pose_goes_on(action, tick_t, t):
            self.state.action = "-"
        if self.poses.move is not None:
            self.safety.heartbeat_command(t)
            return
        if isinstance(action, PoseAction):
            if self._pose_tried != since:  # once per command
                self._pose_tried = since
                if self.start_pose(action, t):
                    self.safety.heartbeat_command(t)
                    return
            action = None  # reached, or the move could not start: hold still
        skin = label is not None and label == self.state.gesture
        if label is not None and not skin:
            self.gesture_motion.cancel()  # another input took over
        moves = isinstance(action, TwistAction | JointJog)
        self._twist(label if moves else None, action, frame, t, dt, skin)

    def _twist(
        self, label: str | None, action: Any, frame: str | None, t: float, dt: float, skin: bool
    ) -> None:
        robot = self.state.robot
        target = np.zeros(6)
        doing = f"twist {label}" if label is not None else "-"
        if label is not None and robot is not None:
            target = self.target_twist(action, frame, robot) * self.speed_scale
            if skin:  # the gestures' speed profile (control/profile.py)
                target = target * self.gesture_motion.speed_fraction(t)
        elif robot is not None and self.gesture_motion.nudging:
            s = self.mapping.settings
            nudge = self.gesture_motion.nudge_target(
                t, robot.tcp, self.shaper.twist, self.shaper.release_stop_s,
                (s.linear_accel, s.angular_accel),
            )  # fmt: skip
            if nudge is not None:
                target = nudge * self.speed_scale
                doing = "nudge"
        step = min(dt, self.settings.max_shaper_dt_s)
        twist = self.shaper.update(target, step)
        self.gesture_motion.add_way(twist, step)
        self.state.action = doing
        try:
            self.safety.send_twist(twist)
        except (RobotError, ValueError) as exc:
            self.robot_failed(exc)
            return
        self.state.twist = np.asarray(twist, dtype=float)
        self.safety.heartbeat_command(t)

    def target_twist(self, action: Any, frame: str | None, robot: RobotState) -> np.ndarray:
        """Full-speed base-frame twist of a twist action (the mapping's) or a joint jog
        (the joint at the mapping's angular speed, its TCP at most at the linear one)."""
        if not isinstance(action, JointJog):
            return np.asarray(self.mapping.twist_of(action, robot.tcp, frame), dtype=float)
        jacobian = self.safety.model.jacobian_at(np.asarray(robot.q, dtype=float))
        if jacobian is None:
            return np.zeros(6)
        settings = self.mapping.settings
        twist = np.asarray(jacobian, dtype=float)[:, action.joint] * action.sign
        twist = twist * settings.angular_speed
        linear = float(np.linalg.norm(twist[:3]))
        if linear > settings.linear_speed:  # a far TCP: keep it at the linear speed
            twist *= settings.linear_speed / linear
        return twist

    # -- pose moves and steps

    def start_pose(self, action: PoseAction, t: float) -> bool:
        """Start the pose move of ``action`` at the settings' speed; ``False`` when there
        is no pose to go to or the safety layer refused (reported)."""
        q = self.poses.stored(action.name)
        if q is None:
            return False
        self._ready_for_move()
        move = PoseMove(action.name, action.hold_to_run, t)
        try:
            self.poses.start_joints(q, move, self.settings.pose_speed_fraction * self.speed_scale)
        except (RobotError, ValueError) as exc:
            self.robot_failed(exc)
            return False
        mode = "hold to run" if action.hold_to_run else "to completion"
        self.state.action = f"move to {action.name} ({mode})"
        self.report.say(f"{t:8.2f} s  moving to the {action.name} pose ({mode})")
        return True

    def start_step(self, goal: np.ndarray, name: str, t: float) -> bool:
        """Start a step (a joint move to ``goal``); ``False`` when refused (reported)."""
        self._ready_for_move()
        move = PoseMove(f"{name} step", hold_to_run=False, started_t=t)
        fraction = self.settings.pose_speed_fraction * self.speed_scale
        try:
            self.poses.start_joints(goal, move, fraction)
        except (RobotError, ValueError) as exc:
            self.robot_failed(exc)
            return False
        self.state.action = f"step {name}"
        return True

    def _ready_for_move(self) -> None:
        self.poses.move = None
        self.shaper.reset()
        self.state.twist = np.zeros(6)

    def _pose_goes_on(self, action: Any, tick_t: float | None, now: float) -> bool:
        robot = self.state.robot
        moving = robot is None or robot.moving
        started_now = tick_t == self.poses.move.started_t  # type: ignore[union-attr]
        try:
            return self.poses.goes_on(action, moving, started_now, now)
        except RobotError as exc:
            self.robot_failed(exc)
            return False

    def advance_robot(self, t: float) -> None:
        """Step a simulated robot from the time it has reached to ``t`` (never backwards,
        at most ``max_robot_step_s`` at once: a longer gap is cut and reported); real
        arms move on their own."""
        if not self.simulated:
            return
        if self._robot_t is None:
            self._robot_t = t
            return
        dt = t - self._robot_t
        if not dt > 0.0:
            return
        self._robot_t = t
        cap = self.settings.max_robot_step_s
        if dt > cap:
            text = f"skin time jumped by {dt:.3g} s: the simulated arm is stepped {cap:g} s"
            log.warning("%s", text)
            self.report.say(f"{t:8.2f} s  {text} (capped)")
            dt = cap
        try:
            self.safety.step(dt)  # steps the robot, and watches the layer's own moves
        except RobotError as exc:
            self.robot_failed(exc)

    # -- stops

    def halt(self) -> None:
        """Forget every motion (a stop, the stop key): no pose move, no twist, no nudge."""
        self.poses.move = None
        self.shaper.reset()
        self.gesture_motion.cancel()
        self.state.twist = np.zeros(6)

    def robot_failed(self, exc: Exception) -> None:
        """Report a robot error as one line and stop the arm."""
        self.report.warn(f"robot: {exc}")
        self.poses.move = None
        self.shaper.reset()
        self.state.twist = np.zeros(6)
        try:
            self.safety.stop()
        except RobotError as again:
            self.report.warn(f"robot: stop failed: {again}")
