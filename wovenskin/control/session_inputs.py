"""Command inputs beside the skin (keyboard, teach pendant, scripts) and the command count.

A :class:`CommandInput` is polled by :class:`~wovenskin.control.session.ControlSession`
once per control tick, at the tick's session time, and returns :class:`InputEvent` s.
:class:`SessionInputs` (a part of the session) applies them through the same path as the
skin's gestures: a ``press`` holds an action (a gesture name, an action written as in the
mapping file such as ``"translate +x"``, or a joint jog ``"joint 3 +"``) until its
``release``, like a gesture until lift-off, with the twist shaped by the session's
``TwistShaper`` and sent through its ``SafetyLayer``; ``step`` moves by a fixed increment
(a joint move to a target computed with the arm's declared kinematics), ``go_to`` runs to
a stored pose, ``gripper`` opens or closes the gripper (``on_gripper``), ``speed`` sets
the speed override and ``mode`` is a panel setting (a pendant's frame).  The newest of the
held input and the skin's gesture is the active command.

Commands are counted as the paper defines them: every discrete input (a gesture's
activation, a key press, a panel operation, a gripper toggle) is one
:class:`CommandRecord` ``(t, source, name, kind)`` in :attr:`SessionInputs.command_log`;
a release or a key's auto-repeat is none.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from wovenskin.control.mapping import FRAMES, Action, TwistAction
from wovenskin.control.session_poses import PoseMove
from wovenskin.errors import ConfigError
from wovenskin.robots.base import N_JOINTS, RobotError, RobotState, rotation_angle

INPUT_KINDS = ("press", "release", "step", "go_to", "gripper", "speed", "mode")
INPUT_FRAMES = (*FRAMES, "joint")
GRIPPER_COMMANDS = ("toggle", "open", "close")
NEWTON_STEPS = 20  # iterations of the step-goal solver (converges in 3-4 for small steps)


@dataclass(frozen=True)
class InputEvent:
    """One input operation.

    ``name``: for ``press``/``release``/``step`` a gesture name, an action
    (``"translate +x"``, ``"rotate -z"``, ``"pose home"``) or a joint jog
    (``"joint 3 +"``, joints 1-6); for ``go_to`` a pose name; for ``gripper`` one of
    ``toggle``/``open``/``close``; for ``mode`` a free label (``"frame base"``).
    ``frame`` (``tool``/``base``/``skin``/``joint``; ``None``: the mapping's frame) is the
    frame a twist's axis is read in; ``amount`` a step's size (m or rad) or the speed
    override (a fraction, 0.01-1); ``counts``: whether it is a command (a release is not).
    """

    kind: str
    name: str = ""
    source: str = "input"
    frame: str | None = None
    amount: float | None = None
    counts: bool = True

    def __post_init__(self) -> None:
        if self.kind not in INPUT_KINDS:
            raise ConfigError(f"unknown input kind {self.kind!r}: use {', '.join(INPUT_KINDS)}")
        if self.frame is not None and self.frame not in INPUT_FRAMES:
            raise ConfigError(f"unknown frame {self.frame!r}: use {', '.join(INPUT_FRAMES)}")
        if self.amount is not None and not math.isfinite(float(self.amount)):
            raise ConfigError(f"input amount must be finite, got {self.amount!r}")


class CommandInput(Protocol):
    """An input device: the events since the last poll, at session time ``t``."""

    def poll(self, t: float) -> list[InputEvent]: ...


@dataclass(frozen=True)
class CommandRecord:
    """One counted command: session time, source (skin, keyboard, pendant), name, kind."""

    t: float
    source: str
    name: str
    kind: str


@dataclass(frozen=True)
class JointJog:
    """Turn one joint (0-based index) in the direction of ``sign`` while held."""

    joint: int
    sign: float

    def __str__(self) -> str:
        return f"joint {self.joint + 1} {'+' if self.sign > 0 else '-'}"


def parse_joint(name: str) -> JointJog | None:
    """``"joint 3 +"`` -> ``JointJog(2, +1)``; ``None`` for a name that is no joint jog."""
    words = name.split()
    if len(words) != 3 or words[0] != "joint":
        return None
    if not words[1].isdigit() or not 1 <= int(words[1]) <= N_JOINTS or words[2] not in "+-":
        raise ConfigError(f"bad joint jog {name!r}: use 'joint N +' or 'joint N -', N 1-6")
    return JointJog(int(words[1]) - 1, 1.0 if words[2] == "+" else -1.0)


@dataclass
class HeldInput:
    """An input held now: what was pressed, its action, since when (session time)."""

    event: InputEvent
    action: Action | JointJog | None
    since: float

    @property
    def label(self) -> str:
        return f"{self.event.name} ({self.event.source})"


class SessionInputs:
    """The inputs of :class:`~wovenskin.control.session.ControlSession` (module doc)."""

    _held: HeldInput | None
    _pose_move: PoseMove | None

    def _init_inputs(self, inputs: Iterable[CommandInput]) -> None:
        self.inputs: list[CommandInput] = list(inputs)
        self.command_log: list[CommandRecord] = []
        self.gripper_closed = False
        # on_gripper(closed) drives the gripper; default: the arm's own (set_gripper), if any
        self.on_gripper: Callable[[bool], None] | None = None
        # the frame the skin's gestures are read in, over the mapping's motion.frame (None:
        # the mapping's; "skin": the skin-registered mapping a study may compare)
        self.gesture_frame: str | None = None
        self._held = None

    def add_input(self, source: CommandInput) -> None:
        """Poll ``source`` every tick from now on."""
        self.inputs.append(source)

    @property
    def command_count(self) -> int:
        """Commands so far, as the paper counts them (discrete inputs)."""
        return len(self.command_log)

    @property
    def held_input(self) -> str | None:
        """The held input's label (``"translate +x (keyboard)"``), or ``None``."""
        return None if self._held is None else self._held.label

    def count_command(self, t: float, source: str, name: str, kind: str) -> None:
        """Count one command and log it (and into the recording, when one runs)."""
        self.command_log.append(CommandRecord(float(t), source, name, kind))
        if self.recorder is not None:
            payload = {"source": source, "name": name, "kind": kind}
            self.recorder.add_annotation("inputs", float(t), payload)

    def apply_input(self, event: InputEvent, t: float | None = None) -> None:
        """Apply ``event`` now (at session time ``t``, default the session clock)."""
        self._apply_input(event, self._now if t is None else float(t))

    def _poll_inputs(self, t: float) -> None:
        for source in self.inputs:
            for event in source.poll(t):
                self._apply_input(event, t)

    def _apply_input(self, event: InputEvent, t: float) -> None:
        if event.counts:
            self.count_command(t, event.source, event.name, event.kind)
        try:
            if event.kind == "press":
                self._press(event, t)
            elif event.kind == "release":
                if self._held is not None and event.name in ("", self._held.event.name):
                    self._held = None
            elif event.kind == "step":
                self._held = None
                self._step(event, t)
            elif event.kind == "go_to":
                self._held = None
                self.go_to_pose(event.name)
            elif event.kind == "gripper":
                self._gripper(event.name, t)
            elif event.kind == "speed":
                self.set_speed_scale(1.0 if event.amount is None else event.amount)
            else:
                self._message(f"{t:8.2f} s  {event.source}: {event.name}")
        except ConfigError as exc:
            self._error(f"{event.source}: {exc}")
        self.state.held = self.held_input

    def _press(self, event: InputEvent, t: float) -> None:
        if self._held is not None and self._held.event.name == event.name:
            return  # already held (a repeated press): keep its start
        action: Action | JointJog | None = parse_joint(event.name)
        if action is None:
            if event.frame == "joint":
                raise ConfigError(f"{event.name!r} is no joint jog ('joint N +')")
            action = self.mapping.resolve(event.name)
        elif self.safety.model.jacobian is None:
            raise ConfigError("joint jogging needs the arm's kinematics (a Jacobian)")
        self._held = HeldInput(event, action, t)
        self._message(f"{t:8.2f} s  {event.source}: {event.name}")

    def _active_command(self) -> tuple[str | None, Any, str | None, float | None]:
        """The active command: label, action, frame and start of the newest of the held
        input and the skin's gesture (``None`` s when there is none)."""
        gesture, since = self.state.gesture, self.state.gesture_since
        held = self._held
        if held is not None and (gesture is None or since is None or held.since >= since):
            frame = held.event.frame if held.event.frame in FRAMES else None
            return held.label, held.action, frame, held.since
        if gesture is None:
            return None, None, None, None
        return gesture, self.mapping.action_for(gesture), self.gesture_frame, since

    def _target_twist(self, action: Any, frame: str | None, robot: RobotState) -> np.ndarray:
        """Full-speed base-frame twist of a twist action or a joint jog."""
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

    # -- steps and the gripper

    def _step(self, event: InputEvent, t: float) -> None:
        robot = self.state.robot
        if self.safety.stopped:
            raise ConfigError("cannot step while stopped: clear the stop first")
        if robot is None:
            raise ConfigError("cannot step: no robot state yet")
        if event.amount is None or not event.amount > 0.0:
            raise ConfigError(f"a step needs a positive amount, got {event.amount!r}")
        q = np.asarray(robot.q, dtype=float)
        jog = parse_joint(event.name)
        if jog is not None:
            goal = q.copy()
            goal[jog.joint] += jog.sign * float(event.amount)
        else:
            action = self.mapping.resolve(event.name)
            if not isinstance(action, TwistAction):
                raise ConfigError(f"cannot step {event.name!r}: it is no translation or turn")
            goal = self._cartesian_goal(q, action, event.frame, float(event.amount))
        self._pose_move = None
        self.shaper.reset()
        self.state.twist = np.zeros(6)
        try:
            self.safety.move_to_joints(goal, self.settings.pose_speed_fraction * self.speed_scale)
        except (RobotError, ValueError) as exc:
            self._robot_failed(exc)
            self._report_new_stops()
            return
        self._pose_move = PoseMove(f"{event.name} step", hold_to_run=False, started_t=t)
        self.state.action = f"step {event.name}"
        self._read_robot()

    def _cartesian_goal(
        self, q: np.ndarray, action: TwistAction, frame: str | None, amount: float
    ) -> np.ndarray:
        """Joint angles that move the TCP by ``amount`` along (or about) the action's axis
        in ``frame``, by Newton steps on the declared kinematics."""
        forward, jacobian = self.safety.model.forward, self.safety.model.jacobian
        if forward is None or jacobian is None:
            raise ConfigError("steps in base or tool frame need the arm's kinematics")
        start = np.asarray(forward(q), dtype=float)
        axis = np.asarray(action.axis, dtype=float)
        frame = self.mapping.settings.frame if frame not in FRAMES else frame
        if frame == "skin":
            axis = start[:3, :3] @ (self.mapping.settings.skin_rotation() @ axis)
        elif frame == "tool":
            axis = start[:3, :3] @ axis
        position, rotation = start[:3, 3].copy(), start[:3, :3]
        if action.kind == "translate":
            position += axis * amount
        else:
            rotation = rotation_matrix(axis * amount) @ rotation
        goal = q.copy()
        for _ in range(NEWTON_STEPS):
            now = np.asarray(forward(goal), dtype=float)
            error = np.concatenate(
                [position - now[:3, 3], rotation_vector(rotation @ now[:3, :3].T)]
            )
            if float(np.linalg.norm(error)) < 1e-10:
                break
            goal = goal + np.linalg.lstsq(np.asarray(jacobian(goal), float), error, rcond=None)[0]
        return goal

    def gripper_was_opened(self) -> None:
        """The gripper was opened outside the inputs (a task scene's reset opens it): the
        next toggle closes it."""
        self.gripper_closed = False

    def _gripper(self, command: str, t: float) -> None:
        if command not in GRIPPER_COMMANDS:
            raise ConfigError(f"unknown gripper command {command!r}: use toggle, open or close")
        closed = not self.gripper_closed if command == "toggle" else command == "close"
        self.gripper_closed = closed
        self._message(f"{t:8.2f} s  gripper {'closes' if closed else 'opens'}")
        drive = self.on_gripper
        if drive is None and self.safety.capabilities().gripper:
            drive = self.safety.set_gripper  # through the safety layer (refused while stopped)
        if drive is None:
            return
        try:
            drive(closed)
        except (RobotError, ValueError) as exc:
            self._error(f"gripper: {exc}")


def rotation_matrix(vector: np.ndarray) -> np.ndarray:
    """The rotation by ``vector`` (axis times angle, rad): Rodrigues' formula."""
    angle = float(np.linalg.norm(vector))
    if angle < 1e-15:
        return np.eye(3)
    k = np.asarray(vector, dtype=float) / angle
    skew = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + math.sin(angle) * skew + (1.0 - math.cos(angle)) * skew @ skew


def rotation_vector(rotation: np.ndarray) -> np.ndarray:
    """Axis times angle of a rotation matrix (the inverse of :func:`rotation_matrix`)."""
    angle = rotation_angle(rotation)
    axis = np.array(
        [
            rotation[2, 1] - rotation[1, 2],
            rotation[0, 2] - rotation[2, 0],
            rotation[1, 0] - rotation[0, 1],
        ]
    )
    if angle < 1e-12:
        return axis / 2.0
    return axis * angle / (2.0 * math.sin(angle))
