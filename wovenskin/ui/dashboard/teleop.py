"""The page's keyboard and teach pendant: one Keyboard and one Pendant input per dashboard.

:class:`PageInputs` owns a :class:`~wovenskin.teleop.keyboard.Keyboard` and a
:class:`~wovenskin.teleop.pendant.Pendant`, added to every session the dashboard opens,
and the chosen interface (``skin``, ``keyboard`` or ``pendant``): key and panel messages
are taken only while their interface is chosen, so a study trial is driven by one
interface.  :func:`handle_input` carries out one ``{"type": "key"}`` or
``{"type": "pendant"}`` message from the server's thread (both inputs are thread-safe;
the session polls them on its own thread).  :class:`PageHold` is one page's held keys
and jog button, which the server releases when that page falls silent (hold-to-run).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from wovenskin.control.session_inputs import InputEvent
from wovenskin.errors import ConfigError
from wovenskin.teleop.keyboard import Keyboard, key_map
from wovenskin.teleop.pendant import POSES, Pendant

INTERFACES = ("skin", "skin_registered", "keyboard", "pendant")
GESTURE_FRAMES = {"skin_registered": "skin"}  # interfaces that read gestures in another frame
PENDANT_OPS = ("frame", "speed", "step", "press", "release", "go_to", "gripper")


@dataclass
class PageHold:
    """What one page holds down: keys and a jog button (released if it falls silent)."""

    keys: set[str] = field(default_factory=set)
    jog: bool = False

    @property
    def held(self) -> bool:
        return bool(self.keys) or self.jog


class PageInputs:
    """The dashboard's keyboard and pendant and the chosen interface."""

    def __init__(self, interface: str = "skin") -> None:
        self.keyboard = Keyboard()
        self.pendant = Pendant()
        self.pendant.poll(0.0)  # its override applies once the pendant is chosen (speed())
        self.interface = check_interface(interface)

    def attach(self, session: Any) -> None:
        """Poll both inputs in ``session`` (a new session after a switch) and read its
        gestures in the chosen interface's frame."""
        self.release_all()
        session.add_input(self.keyboard)
        session.add_input(self.pendant)
        session.gesture_frame = self.gesture_frame

    def choose(self, interface: str, session: Any = None) -> None:
        """Choose the interface; whatever the others held comes up.  ``skin_registered``
        is the skin with its gestures read in the skin patch's frame (``session``'s
        ``gesture_frame``), ``skin`` the mapping's own frame (the paper's tool frame)."""
        self.interface = check_interface(interface)
        self.release_all()
        if session is not None:
            session.gesture_frame = self.gesture_frame

    @property
    def gesture_frame(self) -> str | None:
        """The frame the chosen interface reads gestures in (None: the mapping's)."""
        return GESTURE_FRAMES.get(self.interface)

    def speed(self) -> float | None:
        """The speed scale the chosen interface sets: the pendant's override, else none."""
        return self.pendant.speed_percent / 100 if self.interface == "pendant" else None

    def release_all(self) -> None:
        self.keyboard.release_all()
        self.pendant.release()

    def key_map(self, session: Any) -> list[dict]:
        """The visible key map under the session's mapping."""
        mapping = getattr(session, "mapping", None)
        return [
            {"key": row.key, "gesture": row.gesture, "action": row.action}
            for row in key_map(mapping)
        ]

    def gripper(self, session: Any) -> None:
        """The page's gripper button: one toggle through the chosen interface (session
        thread: the skin's goes straight to the session)."""
        if self.interface == "keyboard":
            self.keyboard.key_down(self.keyboard.gripper_key)
            self.keyboard.key_up(self.keyboard.gripper_key)
        elif self.interface == "pendant":
            self.pendant.gripper()
        else:
            session.apply_input(InputEvent("gripper", "toggle", "skin"))

    def part(self, session: Any) -> dict:
        """The snapshot's share: interface, command count, gripper, held keys, panel."""
        out: dict[str, Any] = {
            "interface": self.interface,
            "commands": int(session.command_count),
            "gripper_closed": bool(session.gripper_closed),
            "held": session.held_input,
            "keys_down": sorted(self.keyboard.down),
        }
        if self.interface == "pendant":
            out["pendant"] = self.pendant.panel()
        return out


def check_interface(interface: object) -> str:
    if interface not in INTERFACES:
        raise ConfigError(f"unknown interface {interface!r}: use {', '.join(INTERFACES)}")
    return str(interface)


def handle_input(inputs: PageInputs, message: dict, hold: PageHold) -> None:
    """One key or pendant message of a page; ValueError (one line) for a bad one.

    ``{"type": "key", "key": "w", "down": true}`` (``{"type": "key", "release_all":
    true}`` when the page loses focus); ``{"type": "pendant", "op": ...}`` with ``frame``
    (``value`` base/tool/joint), ``speed`` (``value`` 1-100), ``step`` (``value`` 1, 5, 10
    or null), ``press`` (``axis``, ``sign`` +1/-1), ``release``, ``go_to`` (``pose``),
    ``gripper``."""
    kind = message.get("type")
    if kind == "key":
        if message.get("release_all"):
            for key in sorted(hold.keys):
                inputs.keyboard.key_up(key)
            hold.keys.clear()
            return
        key = message.get("key")
        if not isinstance(key, str) or len(key) != 1:
            raise ValueError("a key message needs a one-character key")
        down = message.get("down")
        if not isinstance(down, bool):
            raise ValueError("a key message needs down: true or false")
        key = key.lower()
        if not down:  # a key-up is taken whatever the interface: nothing stays held
            inputs.keyboard.key_up(key)
            hold.keys.discard(key)
            return
        _check_chosen(inputs, "keyboard")
        if not inputs.keyboard.key_down(key):
            raise ValueError(f"key {key!r} is not bound (see the key map)")
        if key != inputs.keyboard.gripper_key:
            hold.keys.add(key)
        else:
            inputs.keyboard.key_up(key)
        return
    op = message.get("op")
    if op not in PENDANT_OPS:
        raise ValueError(f"unknown pendant operation {str(op)[:40]!r}")
    pendant = inputs.pendant
    if op == "release":
        pendant.release()
        hold.jog = False
        return
    _check_chosen(inputs, "pendant")
    value = message.get("value")
    if op == "frame":
        pendant.set_frame(str(value))
    elif op == "speed":
        pendant.set_speed(value)  # type: ignore[arg-type]
    elif op == "step":
        pendant.set_step(None if value in (None, "off") else _int(value, "step size"))
    elif op == "press":
        axis = message.get("axis")
        axis = _int(axis, "joint") if pendant.frame == "joint" else str(axis)
        pendant.press(axis, _int(message.get("sign"), "sign"))
        hold.jog = pendant.jogging is not None
    elif op == "go_to":
        pose = message.get("pose")
        if pose not in POSES:
            raise ValueError(f"unknown pose {str(pose)[:40]!r}: use initial or home")
        pendant.go_to(str(pose))
    else:
        pendant.gripper()


def _check_chosen(inputs: PageInputs, interface: str) -> None:
    if inputs.interface != interface:
        raise ValueError(f"the {interface} is off: choose the {interface} interface first")


def _int(value: object, what: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int | float) or value != int(value):
        raise ValueError(f"{what} must be a whole number, got {str(value)[:20]}")
    return int(value)
