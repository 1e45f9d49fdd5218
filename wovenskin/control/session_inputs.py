"""Command inputs beside the skin (keyboard, teach pendant, scripts) and the command count.

A :class:`CommandInput` is polled by :class:`~wovenskin.control.session.ControlSession`
once per control tick, at the tick's session time, and returns :class:`InputEvent` s.
:class:`Inputs` (a part of the session) holds the devices, the held input, the command
count and the gripper's state; the session applies each event through the same path as
the skin's gestures: a ``press`` holds an action (a gesture name, an action written as in the
mapping file such as ``"translate +x"``, or a joint jog ``"joint 3 +"``) until its
``release``, like a gesture until lift-off, with the twist shaped by the session's
``TwistShaper`` and sent through its ``SafetyLayer``; ``step`` moves by a fixed increment
(a joint move to a target computed with the arm's declared kinematics), ``go_to`` runs to
a stored pose, ``gripper`` opens or closes the gripper (``on_gripper``), ``speed`` sets
the speed override and ``mode`` is a panel setting (a pendant's frame).  The newest of the
held input and the skin's gesture is the active command.

Commands are counted as the paper defines them: every discrete input (a gesture's
activation, a key press, a panel operation, a gripper toggle) is one
:class:`CommandRecord` ``(t, source, name, kind)`` in :attr:`Inputs.command_log`;
a release or a key's auto-repeat is none.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any, NamedTuple, Protocol

import numpy as np

from wovenskin.control.mapping import FRAMES, Action, TwistAction
from wovenskin.errors import ConfigError
from wovenskin.robots.base import N_JOINTS, RobotError, rotation_angle

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
        """What is held and from where: the action (``"translate +x (keyboard)"``), or
        the name pressed when it has none."""
        what = self.action if self.action is not None else self.event.name
        return f"{what} ({self.event.source})"


class Inputs:
    """The inputs beside the skin (module docstring): devices, what is held, the commands
    counted and the gripper's state. It moves nothing itself: the session applies the
    events (:meth:`~wovenskin.control.session.ControlSession.apply_input`)."""

    def __init__(self, devices: Iterable[CommandInput] = ()) -> None:
        self.devices: list[CommandInput] = list(devices)
        self.command_log: list[CommandRecord] = []
        self.gripper_closed = False
        # on_gripper(closed) drives the gripper; default: the arm's own (set_gripper), if any
        self.on_gripper: Callable[[bool], None] | None = None
        # the frame the skin's gestures are read in, over the mapping's motion.frame (None:
        # the mapping's; "skin": the skin-registered mapping a study may compare)
        self.gesture_frame: str | None = None
        self.held: HeldInput | None = None

    def poll(self, t: float) -> list[InputEvent]:
        """Every device's events since the last poll, at session time ``t``."""
        return [event for device in self.devices for event in device.poll(t)]

    def count(self, t: float, source: str, name: str, kind: str) -> CommandRecord:
        """Count one command (the paper's definition) and return its record."""
        record = CommandRecord(float(t), source, name, kind)
        self.command_log.append(record)
        return record

    @property
    def held_label(self) -> str | None:
        """The held input's label (``"translate +x (keyboard)"``), or ``None``."""
        return None if self.held is None else self.held.label

    def press(self, event: InputEvent, action: Action | JointJog | None, t: float) -> bool:
        """Hold ``event``'s ``action`` from ``t``; ``False`` when it is already held (a
        repeated press keeps its start)."""
        if self.held is not None and self.held.event.name == event.name:
            return False
        self.held = HeldInput(event, action, t)
        return True

    def release(self, name: str) -> None:
        """End the held input named ``name`` (``""``: whatever is held)."""
        if self.held is not None and name in ("", self.held.event.name):
            self.held = None

    def gripper(
        self, command: str, t: float, safety: Any, say: Callable[[str], None],
        warn: Callable[[str], None],
    ) -> None:  # fmt: skip
        """``toggle``, ``open`` or ``close`` the gripper: through :attr:`on_gripper`, else
        the arm's own through the safety layer (refused while stopped), if it has one."""
        if command not in GRIPPER_COMMANDS:
            raise ConfigError(f"unknown gripper command {command!r}: use toggle, open or close")
        closed = not self.gripper_closed if command == "toggle" else command == "close"
        self.gripper_closed = closed
        say(f"{t:8.2f} s  gripper {'closes' if closed else 'opens'}")
        drive = self.on_gripper
        if drive is None and safety.capabilities().gripper:
            drive = safety.set_gripper
        if drive is None:
            return
        try:
            drive(closed)
        except (RobotError, ValueError) as exc:
            warn(f"gripper: {exc}")


class ActiveCommand(NamedTuple):
    """The command acting now: its label, action, the frame its axis is read in (None:
    the mapping's) and when it began; all ``None`` when none acts."""

    label: str | None = None
    action: Any = None
    frame: str | None = None
    since: float | None = None


def active_command(
    inputs: Inputs, gesture: str | None, since: float | None, mapping: Any
) -> ActiveCommand:
    """The newer of the held input and the skin's ``gesture`` (begun at ``since``)."""
    held = inputs.held
    if held is not None and (gesture is None or since is None or held.since >= since):
        frame = held.event.frame if held.event.frame in FRAMES else None
        return ActiveCommand(held.label, held.action, frame, held.since)
    if gesture is None:
        return ActiveCommand()
    return ActiveCommand(gesture, mapping.action_for(gesture), inputs.gesture_frame, since)


def resolve_input(event: InputEvent, mapping: Any, has_jacobian: bool) -> Action | JointJog | None:
    """The action a pressed ``event`` holds: a joint jog (which needs the arm's Jacobian),
    else a gesture name or an action written as in the mapping file."""
    jog = parse_joint(event.name)
    if jog is None:
        if event.frame == "joint":
            raise ConfigError(f"{event.name!r} is no joint jog ('joint N +')")
        return mapping.resolve(event.name)
    if not has_jacobian:
        raise ConfigError("joint jogging needs the arm's kinematics (a Jacobian)")
    return jog


def step_goal(q: np.ndarray, event: InputEvent, mapping: Any, model: Any) -> np.ndarray:
    """The joint angles a ``step`` event moves to from ``q``: a joint jog's turn, or the
    TCP moved by ``event.amount`` along (or about) an action's axis in its frame."""
    if event.amount is None or not event.amount > 0.0:
        raise ConfigError(f"a step needs a positive amount, got {event.amount!r}")
    jog = parse_joint(event.name)
    if jog is not None:
        goal = np.array(q, dtype=float)
        goal[jog.joint] += jog.sign * float(event.amount)
        return goal
    action = mapping.resolve(event.name)
    if not isinstance(action, TwistAction):
        raise ConfigError(f"cannot step {event.name!r}: it is no translation or turn")
    return cartesian_goal(q, action, event.frame, float(event.amount), mapping, model)


def cartesian_goal(
    q: np.ndarray, action: TwistAction, frame: str | None, amount: float, mapping: Any, model: Any
) -> np.ndarray:
    """Joint angles that move the TCP by ``amount`` along (or about) the action's axis in
    ``frame``, by Newton steps on the arm's declared kinematics (``model``)."""
    forward, jacobian = model.forward, model.jacobian
    if forward is None or jacobian is None:
        raise ConfigError("steps in base or tool frame need the arm's kinematics")
    start = np.asarray(forward(q), dtype=float)
    axis = np.asarray(action.axis, dtype=float)
    frame = mapping.settings.frame if frame not in FRAMES else frame
    if frame == "skin":
        axis = start[:3, :3] @ (mapping.settings.skin_rotation() @ axis)
    elif frame == "tool":
        axis = start[:3, :3] @ axis
    position, rotation = start[:3, 3].copy(), start[:3, :3]
    if action.kind == "translate":
        position += axis * amount
    else:
        rotation = rotation_matrix(axis * amount) @ rotation
    goal = np.array(q, dtype=float)
    for _ in range(NEWTON_STEPS):
        now = np.asarray(forward(goal), dtype=float)
        error = np.concatenate([position - now[:3, 3], rotation_vector(rotation @ now[:3, :3].T)])
        if float(np.linalg.norm(error)) < 1e-10:
            break
        goal = goal + np.linalg.lstsq(np.asarray(jacobian(goal), float), error, rcond=None)[0]
    return goal


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
