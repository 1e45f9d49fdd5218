"""The skin interface for :mod:`task_operator`: gestures drawn with the mouse on the page's
virtual skin, recognised by the shipped recogniser from the simulated skin's frames.

:class:`SkinDriver` turns the operator's base-frame moves into the gesture whose action
(the default mapping, tool frame) best matches: a one-finger swipe for a translation along
the tool's y or z, ``push`` / ``pinch_in_2f`` along its x, a two-finger swipe for a turn
about its y or z, a two-finger circle about its x.  ``press`` draws the gesture and keeps
the fingers resting on the skin (the command runs until lift-off), ``release`` lifts them,
``nudge`` lifts as soon as the command starts, at a lower speed (the page's speed slider,
as a person slows down for the last millimetres).  Like a person who is not understood,
the driver lifts and draws again when the recogniser gives nothing, or gives another
command (lifted at once: the operator measures and corrects), up to three times.
"""

from __future__ import annotations

import math
import time

import numpy as np
from task_operator import ROTATIONS, TRANSLATIONS, OperatorError, ServerView

# (action kind, tool axis index, sign) -> gesture, as in control/default_mapping.toml
GESTURE_FOR = {
    ("translate", 2, 1): "swipe_up",
    ("translate", 2, -1): "swipe_down",
    ("translate", 1, 1): "swipe_right",
    ("translate", 1, -1): "swipe_left",
    ("translate", 0, 1): "pinch_in_2f",
    ("translate", 0, -1): "push",
    ("rotate", 1, 1): "swipe_up_2f",
    ("rotate", 1, -1): "swipe_down_2f",
    ("rotate", 2, 1): "swipe_right_2f",
    ("rotate", 2, -1): "swipe_left_2f",
    ("rotate", 0, 1): "circle_cw_2f",
    ("rotate", 0, -1): "circle_ccw_2f",
}
# swipe directions on the canvas (fractions of its width and height; y grows downward)
SWIPES = {"up": ((0.5, 0.8), (0.5, 0.25)), "down": ((0.5, 0.2), (0.5, 0.75)),
          "right": ((0.2, 0.5), (0.75, 0.5)), "left": ((0.8, 0.5), (0.25, 0.5))}  # fmt: skip
NUDGE_SPEED = 0.15  # the page's speed slider while nudging


class SkinDriver:
    """Gestures on the page's virtual skin (module docstring)."""

    interface = "skin"

    def __init__(self, page, runner, log=print) -> None:
        self.page = page
        self.view = ServerView(runner)
        self.log = log
        self.gesture: str | None = None
        self.attempts: list[tuple[str, list[str]]] = []  # (wanted, commands seen) per touch
        self.lifts: list[tuple[float, float | None, str | None]] = []  # wall, session t, cmd

    # -- the Driver protocol

    def prepare(self) -> None:
        self.page.select_option("#interface", "skin")
        self.view.wait(lambda s: s["teleop"]["interface"] == "skin", 15, "the skin interface")
        self._speed(1.0)

    def press(self, axis: str, sign: int) -> int:
        self._perform(self._gesture(axis, sign))
        return 1  # at least the gesture's activation (a misread one before it counts too)

    def release(self) -> None:
        self._lift()

    def nudge(self, axis: str, sign: int, amount: float) -> int:
        self._speed(NUDGE_SPEED)
        try:
            self._perform(self._gesture(axis, sign))
        finally:
            self._lift()
            self._speed(1.0)
        return 1

    def gripper(self) -> int:
        self.page.click("#gripper")
        return 1

    # -- gestures

    def _gesture(self, axis: str, sign: int) -> str:
        """The gesture whose tool-frame action best matches ``sign`` x base ``axis``."""
        if axis in TRANSLATIONS:
            kind, wanted = "translate", np.eye(3)[TRANSLATIONS.index(axis)] * sign
        else:
            kind, wanted = "rotate", np.eye(3)[ROTATIONS.index(axis)] * sign
        along = self.view.tool_axes() @ wanted  # each tool axis against the wanted direction
        i = int(np.argmax(np.abs(along)))
        return GESTURE_FOR[(kind, i, 1 if along[i] > 0 else -1)]

    def _perform(self, gesture: str) -> None:
        """Draw ``gesture`` and rest on the skin once the recogniser gives it; up to three
        touches.  OperatorError if it never does."""
        for _ in range(3):
            seen: list[str] = []
            self.attempts.append((gesture, seen))
            self._draw(gesture)
            deadline = time.monotonic() + 3.0
            while time.monotonic() < deadline:
                command = self.view.state().get("recognition", {}).get("command")
                if command and (not seen or seen[-1] != command):
                    seen.append(command)
                if command == gesture:
                    self.gesture = gesture
                    return
                if command and command != gesture:
                    break  # understood as something else: lift at once, draw again
                if gesture.startswith("circle"):
                    self._circle_step(gesture)
                else:
                    time.sleep(0.03)
            self._lift()
            self.view.wait(lambda s: not s["recognition"]["command"], 15, "no command")
        raise OperatorError(f"{gesture} not recognised in three touches: {self.attempts[-3:]}")

    def _box(self) -> dict:
        return self.page.locator("#skin").bounding_box()

    def _at(self, fx: float, fy: float) -> tuple[float, float]:
        box = self._box()
        return box["x"] + box["width"] * fx, box["y"] + box["height"] * fy

    def _fingers(self, n: int) -> None:
        if self.page.eval_on_selector("#fingers", "e => e.value") != str(n):
            self.page.select_option("#fingers", str(n))

    def _draw(self, gesture: str) -> None:
        mouse = self.page.mouse
        if gesture.startswith("swipe"):
            direction = gesture.split("_")[1]
            self._fingers(2 if gesture.endswith("_2f") else 1)
            (x0, y0), (x1, y1) = SWIPES[direction]
            mouse.move(*self._at(x0, y0))
            mouse.down()
            for k in range(1, 16):  # ~40 mm in ~0.2 s, then the fingers rest
                f = k / 15
                mouse.move(*self._at(x0 + (x1 - x0) * f, y0 + (y1 - y0) * f))
                time.sleep(0.012)
        elif gesture == "push":
            self._fingers(1)
            mouse.move(*self._at(0.5, 0.5))
            mouse.down()
            time.sleep(0.3)  # people pause after landing, then press firmly
            mouse.wheel(0, -100)
        elif gesture == "pinch_in_2f":
            self._fingers(2)
            mouse.move(*self._at(0.5, 0.5))
            for _ in range(14):  # hovering: spread the hand to ~60 mm
                mouse.wheel(0, -100)
            mouse.down()
            time.sleep(0.15)
            for _ in range(16):  # pressing: bring the fingertips together
                mouse.wheel(0, 100)
                time.sleep(0.015)
        elif gesture.startswith("circle"):
            self._fingers(2)
            self._angle, self._last = 0.0, time.monotonic()
            mouse.move(*self._circle_point(0.0))
            mouse.down()
        else:
            raise OperatorError(f"the skin driver cannot draw {gesture}")

    def _circle_point(self, angle: float) -> tuple[float, float]:
        r = 0.18  # 18 mm of the 100 mm skin
        return self._at(0.5 + r * math.cos(angle), 0.5 + r * math.sin(angle))

    def _circle_step(self, gesture: str) -> None:
        """One move of a circle (0.6 s a turn, at most 40 deg a move: never aliased); y
        grows downward on the canvas, so a growing angle turns clockwise."""
        now = time.monotonic()
        step = min(2 * math.pi * (now - self._last) / 0.6, math.radians(40))
        self._last = now
        self._angle += step if gesture == "circle_cw_2f" else -step
        self.page.mouse.move(*self._circle_point(self._angle))

    def _lift(self) -> None:
        state = self.view.state()
        self.page.mouse.up()
        command = state.get("recognition", {}).get("command")
        self.lifts.append((time.monotonic(), state.get("t"), command))  # for failure reports
        self.gesture = None

    def _speed(self, value: float) -> None:
        """Set the page's speed slider (as a person drags it) and wait for the session."""
        if abs(float(self.view.state().get("speed_scale", -1)) - value) < 1e-6:
            return
        slider = self.page.locator("#speed")
        slider.fill(str(value))  # fires input and change, as a released drag does
        self.view.wait(lambda s: abs(float(s["speed_scale"]) - value) < 1e-6, 15, "the speed")
