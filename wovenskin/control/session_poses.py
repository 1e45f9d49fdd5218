"""The pose moves of a control session: joint moves to the stored home and initial poses.

:class:`PoseMoves` is the part of :class:`~wovenskin.control.session.ControlSession` that
starts a move (a pose gesture, or the dashboard's go-home button), keeps it going while its
command lasts (hold to run) or until the pose is reached (to completion), and stores the
arm's current pose.  It uses the session's safety layer, shaper, state and messages.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from wovenskin.control.mapping import PoseAction
from wovenskin.control.poses import PoseStore, set_pose_from_robot
from wovenskin.errors import ConfigError
from wovenskin.robots.base import Robot, RobotError


@dataclass
class PoseMove:
    """A joint move under way: to which pose, whether it is hold-to-run, when it started."""

    name: str
    hold_to_run: bool
    started_t: float


class PoseMoves:
    """Pose moves of :class:`~wovenskin.control.session.ControlSession` (see the module doc)."""

    _pose_move: PoseMove | None

    def go_to_pose(self, name: str) -> bool:
        """Start a move to the stored ``name`` pose that runs to completion (the dashboard's
        go-home button); a gesture, the stop key or a watchdog ends it.  Returns whether
        the move started: not while stopped, nor without a stored (or built-in) pose."""
        if name not in ("home", "initial"):
            raise ConfigError(f"unknown pose {name!r}: use home or initial")
        if self.safety.stopped:
            self._error(f"cannot go to the {name} pose while stopped: clear the stop first")
            return False
        self._pose_move = None
        started = self._start_pose_move(PoseAction(name, hold_to_run=False), self._now)
        self._read_robot()  # the next tick must see the move, not the state before it
        return started

    def store_pose(self, name: str) -> None:
        """Store the arm's current joints as the ``name`` pose (``PoseStore`` file)."""
        if self.poses is None:
            self.poses = PoseStore.load()
        stored = set_pose_from_robot(self.poses, name, self.safety)
        degrees = ", ".join(f"{v:.1f}" for v in np.degrees(stored.q))
        self._message(f"stored the {name} pose ({degrees} deg) in {self.poses.path}")

    def _start_pose_move(self, action: PoseAction, t: float) -> bool:
        q = self._stored_pose(action.name)
        if q is None:
            return False
        self.shaper.reset()
        self.state.twist = np.zeros(6)
        try:
            self.safety.move_to_joints(q, self.settings.pose_speed_fraction * self.speed_scale)
        except (RobotError, ValueError) as exc:
            self._robot_failed(exc)
            return False
        self._pose_move = PoseMove(action.name, action.hold_to_run, t)
        mode = "hold to run" if action.hold_to_run else "to completion"
        self.state.action = f"move to {action.name} ({mode})"
        self._message(f"{t:8.2f} s  moving to the {action.name} pose ({mode})")
        return True

    def _continue_pose_move(self, action: Any) -> bool:
        """Whether the running pose move goes on this tick; stops it when it must end."""
        move = self._pose_move
        assert move is not None
        same = isinstance(action, PoseAction) and action.name == move.name
        if same or (action is None and not move.hold_to_run):
            robot = self.state.robot
            if robot is not None and not robot.moving and self._tick_t != move.started_t:
                self.state.action = "-"
                self._message(f"{self._now:8.2f} s  reached the {move.name} pose")
                return False
            return True
        try:  # the command ended (hold to run) or another one took over
            self.safety.stop()
        except RobotError as exc:
            self._robot_failed(exc)
        self.state.action = "-"
        return False

    def _stored_pose(self, name: str) -> np.ndarray | None:
        stored = self.poses.get(name) if self.poses is not None else None
        if stored is not None:
            return np.asarray(stored.q, dtype=float)
        default = _declared_default_pose(self.robot, name)
        if default is not None:
            return default
        self._error(f"no stored {name!r} pose: store one with `wovenskin pose set {name}`")
        return None


def _declared_default_pose(robot: Robot, name: str) -> np.ndarray | None:
    """The backend's declared pose ``name`` (``RobotCapabilities.default_poses``: the
    simulated arm's home and initial poses) when none is stored."""
    pose = robot.capabilities().default_poses.get(name)
    return None if pose is None else np.asarray(pose, dtype=float)
