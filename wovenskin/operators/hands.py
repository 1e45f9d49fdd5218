"""How a simulated operator acts through each interface, with the time each act takes.

Every hand offers the same five acts, each a plan (:mod:`.script`) that spends the
operator's time and returns how many commands it sent:

- ``press(axis, sign)``: start a held move along a BASE-frame ``axis`` (``x``, ``y``,
  ``z``; ``rx``, ``ry``, ``rz`` about the TCP) until ``release()``;
- ``nudge(axis, sign, amount)``: a short move of about ``amount`` (m or rad);
- ``gripper()``: toggle the gripper.

:class:`KeyboardHand` presses the key map's keys (the keys act in the tool frame: the key
of the tool axis that best matches the base axis now; K per key press);
:class:`PendantHand` points at the jog panel's buttons in the base frame (P per button,
step mode for short moves: 10, 5 or 1 mm or deg a press, one command per mode change);
:class:`SkinHand` performs the gesture of that tool axis on an operator's skin
(:class:`~wovenskin.operators.touch_skin.TouchSkin`: the hands and skins of
:mod:`wovenskin.independent` or of :mod:`wovenskin.sim`), holds it while the arm moves and
lifts it to stop; it watches the session's command and, when the recogniser read
something else or nothing, lifts, thinks and tries again, as a person would.  A
novice's tool-frame hand may start the wrong way (``wrong_direction``): the operator sees
the arm go the wrong way and corrects.  The keyboard and pendant hands are
:class:`~wovenskin.control.session_inputs.CommandInput` s the session polls.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from wovenskin.control.mapping import TwistAction
from wovenskin.control.session_inputs import InputEvent
from wovenskin.operators.profiles import OperatorProfile
from wovenskin.operators.script import Plan, Sleep, Timeout, Until
from wovenskin.operators.touch_skin import TouchSkin
from wovenskin.teleop.keyboard import Keyboard, key_map
from wovenskin.teleop.pendant import Pendant

TRANSLATIONS = ("x", "y", "z")
ROTATIONS = ("rx", "ry", "rz")
TAP_S = 0.08  # the shortest key press
STEP_SIZES = (10, 5, 1)  # the pendant's increments, mm or deg
MAX_GESTURE_TRIES = 4
LIFT_LAG_S = 0.3  # first guess of how long a gesture's command lasts after the lift
LIFT_LAG_LEARNING = 0.3  # share of the gap to the lag just seen that a short move learns


def tool_axes(session: Any) -> np.ndarray:
    """The TCP's x, y, z axes in the base frame, as the rows of a 3x3 array."""
    return session.state.robot.tcp.rotation().T


def tool_command(session: Any, axis: str, sign: int) -> str:
    """The tool-frame action (``"translate +y"``) that best moves along base ``axis``."""
    base = np.eye(3)["xyz".index(axis[-1])]
    dots = tool_axes(session) @ base
    k = int(np.argmax(np.abs(dots)))
    kind = "rotate" if axis in ROTATIONS else "translate"
    mark = "+" if sign * dots[k] > 0 else "-"
    return f"{kind} {mark}{'xyz'[k]}"


def press_time(amount: float, speed: float, accel: float) -> float:
    """How long a held move goes ``amount``: accelerating half the way and braking the
    other (``sqrt(amount / accel)``), or ``amount / speed`` past full speed."""
    if amount < speed * speed / accel:
        return math.sqrt(amount / accel)
    return amount / speed


def short_hold_s(
    profile: Any, amount: float, full_speed: float, acting_s: float, lift_lag_s: float
) -> float:
    """How much longer a short move's gesture stays on the skin once its command acts: as
    long as the mapping's speed ``profile`` takes to cover ``amount`` at ``full_speed``,
    less the ``acting_s`` it has already run and how late a lift acts (``lift_lag_s``)."""
    return max(0.0, profile.hold_for(amount, full_speed) - acting_s - lift_lag_s)


def learn_lift_lag(lag_s: float, seen_s: float) -> float:
    """The lift lag learnt after a lift whose command ended ``seen_s`` after it."""
    return lag_s + LIFT_LAG_LEARNING * (seen_s - lag_s)


def flip(command: str) -> str:
    """The same action the other way."""
    kind, axis = command.split()
    return f"{kind} {'-' if axis[0] == '+' else '+'}{axis[1]}"


class Hand:
    """What the hands share: the session, the profile, the random draws, the counters."""

    interface = ""

    def __init__(self, session: Any, profile: OperatorProfile, rng: np.random.Generator):
        self.session = session
        self.profile = profile
        self.rng = rng
        settings = session.mapping.settings
        self.speed = {"linear": settings.linear_speed, "angular": settings.angular_speed}
        self.accel = {"linear": settings.linear_accel, "angular": settings.angular_accel}
        self.wrong = 0  # moves started the wrong way
        self.tool_frame = True
        self.scale = 1.0  # the speed setting the hand's moves run at

    def kind(self, axis: str) -> str:
        return "angular" if axis in ROTATIONS else "linear"

    def _command(self, axis: str, sign: int) -> str:
        command = tool_command(self.session, axis, sign)
        if self.tool_frame and self.rng.random() < self.profile.wrong_direction:
            self.wrong += 1
            return flip(command)
        return command

    def held_for(self, axis: str, amount: float) -> float:
        """How long to hold a move of ``amount`` (at least a tap: :func:`press_time`)."""
        kind = self.kind(axis)
        return max(TAP_S, press_time(amount, self.speed[kind], self.accel[kind]))

    def release_now(self) -> None:
        """Let go of anything held (the trial ended)."""


class KeyboardHand(Hand):
    """The key map's keys, tool frame (module docstring)."""

    interface = "keyboard"

    def __init__(self, session: Any, profile: OperatorProfile, rng: np.random.Generator):
        super().__init__(session, profile, rng)
        self.keyboard = Keyboard()
        self.keys = {row.action: row.key for row in key_map(session.mapping)}
        self.held: str | None = None

    def poll(self, t: float) -> list[InputEvent]:
        return self.keyboard.poll(t)

    def press(self, axis: str, sign: int, distance: float = math.inf) -> Plan:
        key = self.keys[self._command(axis, sign)]
        yield Sleep(self.profile.key_s)
        self.keyboard.key_down(key)
        self.held = key
        return 1

    def release(self) -> Plan:
        self.release_now()
        return 0
        yield  # a plan

    def release_now(self) -> None:
        if self.held is not None:
            self.keyboard.key_up(self.held)
            self.held = None

    def nudge(self, axis: str, sign: int, amount: float) -> Plan:
        sent = yield from self.press(axis, sign)
        yield Sleep(self.held_for(axis, amount))
        yield from self.release()
        return sent

    def gripper(self) -> Plan:
        yield Sleep(self.profile.key_s)
        self.keyboard.key_down(self.keyboard.gripper_key)
        self.keyboard.key_up(self.keyboard.gripper_key)
        return 1


class PendantHand(Hand):
    """The jog panel in the base frame at 100 % speed (module docstring)."""

    interface = "pendant"

    def __init__(self, session: Any, profile: OperatorProfile, rng: np.random.Generator):
        super().__init__(session, profile, rng)
        self.pendant = Pendant(speed_percent=100, frame="base")
        self.tool_frame = False  # base-frame buttons: what you press is where it goes

    def poll(self, t: float) -> list[InputEvent]:
        return self.pendant.poll(t)

    def _mode(self, size: int | None) -> Plan:
        if self.pendant.step_size == size:
            return 0
        yield Sleep(self.profile.point_s)
        self.pendant.set_step(size)
        return 1

    def press(self, axis: str, sign: int, distance: float = math.inf) -> Plan:
        sent = yield from self._mode(None)
        yield Sleep(self.profile.point_s)
        self.pendant.press(axis, sign)
        return sent + 1

    def release(self) -> Plan:
        self.release_now()
        return 0
        yield  # a plan

    def release_now(self) -> None:
        if self.pendant.jogging is not None:
            self.pendant.release()

    def nudge(self, axis: str, sign: int, amount: float) -> Plan:
        unit = amount * (math.degrees(1) if axis in ROTATIONS else 1000.0)
        size = next((s for s in STEP_SIZES if s <= max(unit, 1.0)), 1)
        sent = yield from self._mode(size)
        yield Sleep(self.profile.point_s)
        self.pendant.step(axis, sign)
        return sent + 1

    def gripper(self) -> Plan:
        yield Sleep(self.profile.point_s)
        self.pendant.gripper()
        return 1


class SkinHand(Hand):
    """Gestures on an operator's skin (a :class:`TouchSkin`), a gripper button beside it."""

    interface = "skin"

    def __init__(
        self, session: Any, profile: OperatorProfile, rng: np.random.Generator, skin: TouchSkin
    ):
        super().__init__(session, profile, rng)
        self.skin = skin
        self.gestures: dict[str, str] = {}
        for name, action in session.mapping.actions.items():
            if isinstance(action, TwistAction):
                self.gestures[str(action)] = name
        self._pending: list[InputEvent] = []
        self.speed_profile = session.mapping.settings.profile
        self.lift_lag = LIFT_LAG_S  # learnt: how long a command lasts after the lift (s)
        self.on_skin = False  # the hand is at the skin (not at the gripper button)
        self.misread: list[tuple[str, str | None]] = []  # (performed, recognised)

    def poll(self, t: float) -> list[InputEvent]:
        events, self._pending = self._pending, []
        return events

    def _lifted(self) -> Plan:
        if self.skin.touching:
            self.skin.lift()
            yield Until(lambda: not self.skin.touching, 5.0, "the hand off the skin")

    def press(self, axis: str, sign: int, distance: float = math.inf) -> Plan:
        """Perform the gesture and hold it once the arm takes it; a misread gesture is
        lifted and performed again (each try a command when it activated something).
        The speed profile does what a speed control would: a held gesture starts fine and
        speeds up, so the hand never stops to set a speed."""
        return (yield from self._perform(axis, sign))

    def _perform(self, axis: str, sign: int) -> Plan:
        gesture = self.gestures[self._command(axis, sign)]
        for _ in range(MAX_GESTURE_TRIES):
            yield from self._lifted()
            if not self.on_skin:
                yield Sleep(self.profile.home_s)
                self.on_skin = True
            performance = self.skin.touch(gesture)
            limit = performance.phases.lift_start_s + 0.4
            state = self.session.state
            try:
                yield Until(
                    lambda: self.session.state.gesture is not None, limit, f"{gesture} recognised"
                )
            except Timeout:  # nothing was recognised: try again
                self.misread.append((gesture, None))
                yield Sleep(self.profile.reaction_s)
                yield from self._lifted()
                yield Sleep(self.profile.thinking(1) * 0.5)
                continue
            state = self.session.state
            if state.gesture == gesture:
                return 1
            self.misread.append((gesture, state.gesture))  # the arm does something else
            yield Sleep(self.profile.reaction_s)
            yield from self._lifted()
            yield Sleep(self.profile.thinking(1) * 0.5)
        return 0

    def release(self) -> Plan:
        self.skin.lift()
        return 0
        yield  # a plan

    def release_now(self) -> None:
        self.skin.lift()

    def nudge(self, axis: str, sign: int, amount: float) -> Plan:
        """A short move: the gesture held for as long as the mapping's speed profile takes
        to cover ``amount`` less how late a lift acts, then lifted; a flick (lifted as soon
        as the arm takes it) when that is no time at all, which the profile turns into at
        least its nudge.  The hand learns how late its lifts act, move by move."""
        kind = self.kind(axis)
        taken = yield from self._perform(axis, sign)
        if taken:
            since = self.session.state.gesture_since or self.session.now
            acting = self.session.now - since
            yield Sleep(
                short_hold_s(self.speed_profile, amount, self.speed[kind], acting, self.lift_lag)
            )
        lifted_at = self.session.now
        self.skin.lift()
        if taken:
            try:
                yield Until(lambda: self.session.state.gesture is None, 5.0, "the command ended")
            except Timeout:
                return taken
            self.lift_lag = learn_lift_lag(self.lift_lag, self.session.now - lifted_at)
        return taken

    def gripper(self) -> Plan:
        yield from self._lifted()
        yield Sleep(self.profile.home_s + self.profile.key_s)
        self.on_skin = False
        self._pending.append(InputEvent("gripper", "toggle", "skin"))
        return 1
