"""The teach pendant interface: a jog panel's state machine, as the dashboard's panel drives it.

Modelled on the jog screens of industrial teach pendants (docs/interfaces.md cites them):
a frame selector (``base``, ``tool``, ``joint``); axis +/- buttons that jog while held
(hold-to-run) and stop on release; a speed override in percent; a step mode in which each
press moves one fixed increment (1, 5 or 10 mm; 1, 5 or 10 deg) instead; go-to-pose
buttons for the stored poses; a gripper button.  :class:`Pendant` is pure Python: the
dashboard calls its methods and the session polls it (a
:class:`~wovenskin.control.session_inputs.CommandInput`).  Every panel operation is one
command (a release is none).
"""

from __future__ import annotations

import math
import threading
from typing import Any

from wovenskin.control.session_inputs import InputEvent
from wovenskin.errors import ConfigError

SOURCE = "pendant"
FRAMES = ("base", "tool", "joint")
AXES = ("x", "y", "z", "rx", "ry", "rz")
JOINTS = (1, 2, 3, 4, 5, 6)
STEP_SIZES = (1, 5, 10)  # mm for translations, deg for rotations and joints
POSES = ("initial", "home")
SPEED_RANGE = (1, 100)  # percent


def jog_name(frame: str, axis: str | int, sign: int) -> str:
    """The session's action name of a jog button: ``translate +x``, ``rotate -z``,
    ``joint 3 +``; a one-line ``ConfigError`` for a button the frame does not have."""
    if sign not in (1, -1):
        raise ConfigError(f"jog sign must be +1 or -1, got {sign!r}")
    mark = "+" if sign > 0 else "-"
    if frame == "joint":
        joint = int(str(axis).removeprefix("j")) if str(axis).removeprefix("j").isdigit() else 0
        if joint not in JOINTS:
            raise ConfigError(f"joint frame: axis must be a joint 1-6, got {axis!r}")
        return f"joint {joint} {mark}"
    if axis not in AXES:
        raise ConfigError(f"{frame} frame: axis must be one of {', '.join(AXES)}, got {axis!r}")
    kind = "rotate" if str(axis).startswith("r") else "translate"
    return f"{kind} {mark}{str(axis)[-1]}"


class Pendant:
    """A jog panel (see the module docstring); thread-safe."""

    def __init__(self, speed_percent: int = 50, frame: str = "base") -> None:
        self._lock = threading.Lock()
        self._pending: list[InputEvent] = []
        self.frame = _checked_frame(frame)
        self.speed_percent = _checked_speed(speed_percent)
        self.step_size: int | None = None  # None: continuous jog; else the increment
        self.jogging: str | None = None  # the action name of the held button
        amount = self.speed_percent / 100  # the session starts at the panel's override
        self._queue(InputEvent("speed", "speed", SOURCE, amount=amount, counts=False))

    # -- panel operations (each is one command)

    def set_frame(self, frame: str) -> None:
        """Select the jog frame: base, tool or joint (stops a running jog)."""
        frame = _checked_frame(frame)
        self.release()
        self.frame = frame
        self._queue(InputEvent("mode", f"frame {frame}", SOURCE))

    def set_speed(self, percent: int) -> None:
        """Set the speed override, 1-100 % of the mapping's speeds."""
        self.speed_percent = _checked_speed(percent)
        self._queue(InputEvent("speed", f"speed {self.speed_percent} %", SOURCE,
                               amount=self.speed_percent / 100))  # fmt: skip

    def set_step(self, size: int | None) -> None:
        """Step mode with increments of ``size`` (1, 5 or 10 mm / deg), or ``None``:
        continuous jogging."""
        if size is not None and size not in STEP_SIZES:
            raise ConfigError(f"step size must be one of {STEP_SIZES} or None, got {size!r}")
        self.release()
        self.step_size = size
        label = "continuous" if size is None else f"{size}"
        self._queue(InputEvent("mode", f"step {label}", SOURCE))

    def press(self, axis: str | int, sign: int) -> None:
        """An axis button goes down: jog while held, or one step in step mode."""
        if self.step_size is not None:
            self.step(axis, sign)
            return
        name = jog_name(self.frame, axis, sign)
        frame = self.frame
        with self._lock:
            self.jogging = name
        self._queue(InputEvent("press", name, SOURCE, frame=frame))

    def release(self) -> None:
        """The held button comes up: the jog stops (not a command)."""
        with self._lock:
            name, self.jogging = self.jogging, None
        if name is not None:
            self._queue(InputEvent("release", name, SOURCE, counts=False))

    def step(self, axis: str | int, sign: int, size: int | None = None) -> None:
        """Move one increment (``size``, default the step mode's, else 1) along the axis."""
        size = size if size is not None else (self.step_size or STEP_SIZES[0])
        if size not in STEP_SIZES:
            raise ConfigError(f"step size must be one of {STEP_SIZES}, got {size!r}")
        name = jog_name(self.frame, axis, sign)
        amount = size / 1000 if name.startswith("translate") else math.radians(size)
        self._queue(InputEvent("step", name, SOURCE, frame=self.frame, amount=amount))

    def go_to(self, pose: str, hold: bool = False) -> None:
        """Move to a stored pose (initial, home): to completion, or while held when
        ``hold`` (the move stops at :meth:`release`)."""
        if pose not in POSES:
            raise ConfigError(f"unknown pose {pose!r}: use initial or home")
        if hold:
            with self._lock:
                self.jogging = f"pose {pose}"
            self._queue(InputEvent("press", f"pose {pose}", SOURCE))
        else:
            self._queue(InputEvent("go_to", pose, SOURCE))

    def gripper(self) -> None:
        """Open or close the gripper (a toggle)."""
        self._queue(InputEvent("gripper", "toggle", SOURCE))

    # -- what the session and the dashboard read

    def poll(self, t: float) -> list[InputEvent]:
        """The events since the last poll (``CommandInput``)."""
        with self._lock:
            events, self._pending = self._pending, []
        return events

    def panel(self) -> dict[str, Any]:
        """The panel's state and choices, JSON-ready, for the dashboard to draw."""
        return {
            "frame": self.frame,
            "frames": list(FRAMES),
            "axes": list(JOINTS) if self.frame == "joint" else list(AXES),
            "speed_percent": self.speed_percent,
            "speed_range": list(SPEED_RANGE),
            "step_size": self.step_size,
            "step_sizes": list(STEP_SIZES),
            "step_unit": "deg" if self.frame == "joint" else "mm / deg",
            "jogging": self.jogging,
            "poses": list(POSES),
        }

    def _queue(self, event: InputEvent) -> None:
        with self._lock:
            self._pending.append(event)


def _checked_frame(frame: str) -> str:
    if frame not in FRAMES:
        raise ConfigError(f"unknown jog frame {frame!r}: use base, tool or joint")
    return frame


def _checked_speed(percent: Any) -> int:
    ok = isinstance(percent, int | float) and not isinstance(percent, bool)
    if not (ok and math.isfinite(percent) and SPEED_RANGE[0] <= percent <= SPEED_RANGE[1]):
        raise ConfigError(f"speed override must be 1-100 %, got {percent!r}")
    return int(round(percent))
