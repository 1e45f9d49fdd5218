"""A control session's pose moves: joint moves to the stored home and initial poses.

:class:`PoseMover` starts a move (a pose gesture, the dashboard's go-home button, an
input's step), says each tick whether it goes on (while its command lasts when it is
hold-to-run, until the pose is reached when it runs to completion) and stores the arm's
current pose. It moves the arm only through the session's safety layer; a refusal is
raised for the session to handle as any robot error.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from wovenskin.control.mapping import PoseAction
from wovenskin.control.poses import PoseStore, set_pose_from_robot
from wovenskin.control.safety import SafetyLayer


@dataclass
class PoseMove:
    """A joint move under way: to which pose, whether it is hold-to-run, when it started."""

    name: str
    hold_to_run: bool
    started_t: float


class PoseMover:
    """Pose moves through ``safety`` to the poses of ``poses`` (or the arm's declared ones)."""

    def __init__(
        self,
        safety: SafetyLayer,
        poses: PoseStore | None,
        say: Callable[[str], None],
        warn: Callable[[str], None],
    ) -> None:
        self.safety = safety
        self.poses = poses
        self._say, self._warn = say, warn
        self.move: PoseMove | None = None

    def stored(self, name: str) -> np.ndarray | None:
        """The joints of the ``name`` pose: stored, else the backend's declared default
        (``RobotCapabilities.default_poses``), else ``None`` with one line saying how to
        store one."""
        stored = self.poses.get(name) if self.poses is not None else None
        if stored is not None:
            return np.asarray(stored.q, dtype=float)
        default = self.safety.capabilities().default_poses.get(name)
        if default is not None:
            return np.asarray(default, dtype=float)
        self._warn(f"no stored {name!r} pose: store one with `wovenskin pose set {name}`")
        return None

    def start_joints(self, q: np.ndarray, move: PoseMove, speed_fraction: float) -> None:
        """Start a joint move to ``q`` (a pose, an input's step) recorded as ``move``."""
        self.move = None
        self.safety.move_to_joints(q, speed_fraction)
        self.move = move

    def goes_on(self, action: Any, robot_moving: bool, started_tick: bool, now: float) -> bool:
        """Whether the running move goes on this tick (``action``: the active command's;
        ``started_tick``: this is the tick it started on). Ends it, stopping the arm, when
        its command ended (hold to run) or another one took over; raises ``RobotError``
        when that stop fails."""
        move = self.move
        assert move is not None
        same = isinstance(action, PoseAction) and action.name == move.name
        if same or (action is None and not move.hold_to_run):
            if not robot_moving and not started_tick:
                self._say(f"{now:8.2f} s  reached the {move.name} pose")
                self.move = None
                return False
            return True
        self.move = None
        self.safety.stop()
        return False

    def store(self, name: str) -> None:
        """Store the arm's current joints as the ``name`` pose (``PoseStore`` file)."""
        if self.poses is None:
            self.poses = PoseStore.load()
        stored = set_pose_from_robot(self.poses, name, self.safety)
        degrees = ", ".join(f"{v:.1f}" for v in np.degrees(stored.q))
        self._say(f"stored the {name} pose ({degrees} deg) in {self.poses.path}")
