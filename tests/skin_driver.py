"""The skin interface for :mod:`page_drivers`: gestures drawn with the mouse on the page's
virtual skin, recognised by the shipped recogniser from the simulated skin's frames.

:class:`SkinDriver` turns the operator's base-frame moves into the gesture whose action
(the session's mapping, tool frame) best matches: a one-finger swipe for a translation along
the tool's y or z, ``push`` / ``pinch_in_2f`` along its x, a two-finger swipe for a turn
about its y or z, a two-finger circle about its x.  ``press`` draws the gesture and keeps
the fingers resting on the skin (the command runs until lift-off), ``release`` lifts them,
``nudge`` keeps it on the skin as long as the mapping's speed profile takes for the way
asked, as the simulated study's skin hand does.  Like a person
who is not understood, the driver lifts and draws again when the recogniser gives
nothing, or gives another command (lifted at once: the operator measures and corrects),
up to three times.
"""

from __future__ import annotations

import math
import time

from hardware_mouse import HardwareMouse
from page_drivers import OperatorError, ServerView, choose

from wovenskin.control.mapping import TwistAction
from wovenskin.operators.hands import (
    LIFT_LAG_S,
    ROTATIONS,
    learn_lift_lag,
    short_hold_s,
    tool_command,
)

# swipe directions on the canvas (fractions of its width and height; y grows downward)
SWIPES = {"up": ((0.5, 0.8), (0.5, 0.25)), "down": ((0.5, 0.2), (0.5, 0.75)),
          "right": ((0.2, 0.5), (0.75, 0.5)), "left": ((0.8, 0.5), (0.25, 0.5))}  # fmt: skip
SWIPE_S = 0.4  # 140-190 mm/s on average (docs/gestures.md: 70-250 mm/s)
LIFT_WAIT_S = 5.0  # session seconds a lifted gesture's command may take to end


class SkinDriver:
    """Gestures on the page's virtual skin (module docstring)."""

    interface = "skin"
    exact_nudges = False

    def __init__(self, page, runner, log=print) -> None:
        self.page = page
        self.view = ServerView(runner)
        self.log = log
        self.gesture: str | None = None
        self.attempts: list[tuple[str, list[str]]] = []  # (wanted, commands seen) per touch
        self.lifts: list[tuple[float, float | None, str | None]] = []  # wall, session t, cmd
        self.mouse = HardwareMouse(page)  # swipes and circles: sampled on its own clock
        self.box: dict | None = None
        self.timings: list[tuple[str, float, float]] = []  # gesture, s to land, s to command
        self.fingers: int | None = None  # the page's hand, as this driver last chose it
        self.session = runner.session
        mapping = self.session.mapping
        self.gestures = {  # the mapping's tool-frame action -> its gesture
            str(action): name for name, action in mapping.actions.items()
            if isinstance(action, TwistAction)
        }  # fmt: skip
        settings = mapping.settings
        self.profile = settings.profile  # the graded speed of a held gesture
        self.lift_lag = LIFT_LAG_S  # learnt: how long a command lasts after the lift (s)
        self.speed = {"linear": settings.linear_speed, "angular": settings.angular_speed}

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
        """The simulated study's short move on the skin: once the gesture acts, held for as
        long as the mapping's speed profile takes to cover ``amount``, less how late a lift
        acts (learnt lift by lift), then lifted (:func:`~wovenskin.operators.hands.short_hold_s`,
        :func:`~wovenskin.operators.hands.learn_lift_lag`)."""
        session = self.session
        speed = self.speed["angular" if axis in ROTATIONS else "linear"]
        try:
            self._perform(self._gesture(axis, sign))
            acting = session.now - (session.state.gesture_since or session.now)
            self._rest(short_hold_s(self.profile, amount, speed, acting, self.lift_lag))
        finally:
            lifted_at = session.now
            self._lift()
        while session.state.gesture is not None and session.now - lifted_at < LIFT_WAIT_S:
            time.sleep(0.005)
        if session.state.gesture is None:
            self.lift_lag = learn_lift_lag(self.lift_lag, session.now - lifted_at)
        return 1

    def _rest(self, seconds: float) -> None:
        """Keep the fingers on the skin for ``seconds`` of session time (a swipe still
        being drawn goes on to its end)."""
        until = self.session.now + seconds
        while self.session.now < until:
            if self.mouse.pressed:
                self.mouse.step()
            time.sleep(0.005)

    def gripper(self) -> int:
        self.page.click("#gripper")
        return 1

    def misread(self) -> list[tuple[str, list[str]]]:
        """The touches whose commands were not just the gesture drawn: (wanted, seen)."""
        return [(wanted, seen) for wanted, seen in self.attempts if seen != [wanted]]

    # -- gestures

    def _gesture(self, axis: str, sign: int) -> str:
        """The gesture whose tool-frame action best matches ``sign`` x base ``axis``."""
        return self.gestures[tool_command(self.session, axis, sign)]

    def _perform(self, gesture: str) -> None:
        """Draw ``gesture`` and rest on the skin once the recogniser gives it; up to three
        touches.  OperatorError if it never does."""
        for _ in range(3):
            seen: list[str] = []
            self.attempts.append((gesture, seen))
            started = time.monotonic()
            self._draw(gesture)
            drawn = time.monotonic() - started
            deadline = time.monotonic() + 3.0
            while time.monotonic() < deadline:
                command = self.view.state().get("recognition", {}).get("command")
                if command and (not seen or seen[-1] != command):
                    seen.append(command)
                if command == gesture:
                    self.gesture = gesture
                    self.timings.append((gesture, drawn, time.monotonic() - started))
                    return
                if command and command != gesture:
                    break  # understood as something else: lift at once, draw again
                if self.mouse.pressed:
                    self.mouse.step()
                time.sleep(0.01)
            self._lift()
            self.view.wait(lambda s: not s["recognition"]["command"], 15, "no command")
        raise OperatorError(f"{gesture} not recognised in three touches: {self.attempts[-3:]}")

    def _box(self) -> dict:
        """The skin canvas's box (read once: every read is a round trip to a busy page)."""
        if self.box is None:
            self.box = self.page.locator("#skin").bounding_box()
        return self.box

    def _at(self, fx: float, fy: float) -> tuple[float, float]:
        box = self._box()
        return box["x"] + box["width"] * fx, box["y"] + box["height"] * fy

    def _fingers(self, n: int) -> None:
        """Choose the mouse hand's fingers (:func:`task_operator.choose`)."""
        if self.fingers != n:
            choose(self.page, "#fingers", str(n))
            self.fingers = n

    def _draw(self, gesture: str) -> None:
        mouse = self.page.mouse
        if gesture.startswith("swipe"):  # 55-77 mm in 0.4 s, bell-shaped, then a rest
            direction = gesture.split("_")[1]
            self._fingers(2 if gesture.endswith("_2f") else 1)
            (x0, y0), (x1, y1) = (self._at(*end) for end in SWIPES[direction])

            def swipe(s: float) -> tuple[float, float]:
                u = min(s / SWIPE_S, 1.0)
                f = u * u * (3 - 2 * u)  # smoothstep: the speed peaks mid-way
                return x0 + (x1 - x0) * f, y0 + (y1 - y0) * f

            self.mouse.down(swipe)
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
        elif gesture.startswith("circle"):  # 0.6 s a turn (y grows downward: cw)
            self._fingers(2)
            rate = (1.0 if gesture == "circle_cw_2f" else -1.0) * 2 * math.pi / 0.6
            cx, cy = self._at(0.5, 0.5)
            r = 0.18 * self._box()["width"]  # 18 mm of the 100 mm skin
            self.mouse.down(lambda s: (cx + r * math.cos(rate * s), cy + r * math.sin(rate * s)))
        else:
            raise OperatorError(f"the skin driver cannot draw {gesture}")

    def _lift(self) -> None:
        state = self.view.state()
        if self.mouse.pressed:
            self.mouse.up()
        else:
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
