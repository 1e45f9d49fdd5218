"""The keyboard interface: one key per action of the vocabulary, held to move, released to stop.

:data:`DEFAULT_LAYOUT` binds a key to each of the 14 gestures (its action comes from the
session's :class:`~wovenskin.control.mapping.ActionMapping`, so a key does exactly what its
gesture does) and :data:`GRIPPER_KEY` toggles the gripper; :func:`key_map` is the visible
table.  :class:`Keyboard` turns key-down/key-up events (a browser's) into the session's
:class:`~wovenskin.control.session_inputs.InputEvent` s; :class:`TerminalKeyboard` gets
characters from a terminal, which sends no key-up: a key counts as held from its first
character until its auto-repeat stops (docs/interfaces.md).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass

from wovenskin.control.mapping import ActionMapping
from wovenskin.control.session_inputs import InputEvent
from wovenskin.errors import ConfigError
from wovenskin.gestures import CLASS_NAMES, INVALID

SOURCE = "keyboard"
GRIPPER_KEY = "g"
# key -> gesture; grouped by the default mapping's actions (tool frame): translations on
# the left hand (w/s: x, d/a: y, r/f: z), rotations on the right (u/o about x, i/k about
# y, l/j about z), h and p for the home and initial poses.
DEFAULT_LAYOUT: dict[str, str] = {
    "w": "pinch_in_2f",
    "s": "push",
    "d": "swipe_right",
    "a": "swipe_left",
    "r": "swipe_up",
    "f": "swipe_down",
    "u": "circle_cw_2f",
    "o": "circle_ccw_2f",
    "i": "swipe_up_2f",
    "k": "swipe_down_2f",
    "l": "swipe_right_2f",
    "j": "swipe_left_2f",
    "p": "pinch_in_5f",
    "h": "pinch_out_5f",
}
INITIAL_REPEAT_S = 0.6  # a terminal key is held this long after its first character ...
REPEAT_S = 0.15  # ... and this long after each auto-repeated one


@dataclass(frozen=True)
class KeyBinding:
    """One row of the key map: the key, the gesture it stands for and what it does."""

    key: str
    gesture: str
    action: str


def check_layout(layout: Mapping[str, str], gripper_key: str = GRIPPER_KEY) -> dict[str, str]:
    """``layout`` with lower-case single-character keys bound to known gestures; else a
    one-line ``ConfigError``."""
    checked: dict[str, str] = {}
    for key, gesture in layout.items():
        if len(key) != 1 or key.lower() in checked or key.lower() == gripper_key:
            raise ConfigError(f"key {key!r}: keys must be single characters, each used once")
        if gesture not in CLASS_NAMES or gesture == INVALID:
            raise ConfigError(f"key {key!r}: unknown gesture {gesture!r}")
        checked[key.lower()] = gesture
    return checked


def key_map(
    mapping: ActionMapping | None = None,
    layout: Mapping[str, str] = DEFAULT_LAYOUT,
    gripper_key: str = GRIPPER_KEY,
) -> list[KeyBinding]:
    """The visible key map: a row per key, with its action under ``mapping``."""
    mapping = mapping if mapping is not None else ActionMapping.load()
    rows = []
    for key, gesture in check_layout(layout, gripper_key).items():
        action = mapping.action_for(gesture)
        rows.append(KeyBinding(key, gesture, "none" if action is None else str(action)))
    rows.append(KeyBinding(gripper_key, "gripper", "gripper open/close (toggle)"))
    return rows


class Keyboard:
    """Key-down/key-up events to input events (thread-safe; see the module docstring).

    A key-down of a bound key presses its gesture (one command); a key already down
    (auto-repeat) does nothing; its key-up releases it.  The gripper key toggles the
    gripper on key-down.  Keys are case-insensitive.
    """

    def __init__(
        self, layout: Mapping[str, str] | None = None, gripper_key: str = GRIPPER_KEY
    ) -> None:
        self.layout = check_layout(DEFAULT_LAYOUT if layout is None else layout, gripper_key)
        self.gripper_key = gripper_key
        self._down: set[str] = set()
        self._pending: list[InputEvent] = []
        self._lock = threading.Lock()

    @property
    def down(self) -> frozenset[str]:
        """The keys held now."""
        with self._lock:
            return frozenset(self._down)

    def bound(self, key: str) -> bool:
        """Whether ``key`` does something here."""
        key = key.lower()
        return key in self.layout or key == self.gripper_key

    def key_down(self, key: str) -> bool:
        """A key went down; returns whether it is bound."""
        key = key.lower()
        if not self.bound(key):
            return False
        with self._lock:
            if key in self._down:
                return True  # auto-repeat: no new command
            self._down.add(key)
            if key == self.gripper_key:
                self._pending.append(InputEvent("gripper", "toggle", SOURCE))
            else:
                self._pending.append(InputEvent("press", self.layout[key], SOURCE))
        return True

    def key_up(self, key: str) -> bool:
        """A key came up; returns whether it is bound."""
        key = key.lower()
        if not self.bound(key):
            return False
        with self._lock:
            if key not in self._down:
                return True
            self._down.discard(key)
            if key != self.gripper_key:
                self._pending.append(InputEvent("release", self.layout[key], SOURCE, counts=False))
        return True

    def release_all(self) -> None:
        """Every held key comes up (the window lost focus)."""
        for key in sorted(self.down):
            self.key_up(key)

    def poll(self, t: float) -> list[InputEvent]:
        """The events since the last poll (``CommandInput``)."""
        with self._lock:
            events, self._pending = self._pending, []
        return events


class TerminalKeyboard(Keyboard):
    """A keyboard read from a terminal's characters, which come without key-up events.

    A bound key goes down at its first character and stays down while its auto-repeat
    keeps sending it: it comes up ``initial_s`` after the first character when no repeat
    followed (a tap), or ``repeat_s`` after the last repeat.  ``initial_s`` must exceed
    the terminal's auto-repeat delay (often 0.25-0.6 s) and ``repeat_s`` its repeat
    interval (often 0.03-0.05 s); a tap therefore moves for ``initial_s``.
    """

    def __init__(
        self,
        layout: Mapping[str, str] | None = None,
        gripper_key: str = GRIPPER_KEY,
        initial_s: float = INITIAL_REPEAT_S,
        repeat_s: float = REPEAT_S,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        super().__init__(layout, gripper_key)
        if not (0.0 < repeat_s <= initial_s):
            raise ConfigError("key timeouts: need 0 < repeat_s <= initial_s")
        self.initial_s = float(initial_s)
        self.repeat_s = float(repeat_s)
        self._clock = clock
        self._seen: dict[str, tuple[float, bool]] = {}  # key -> (last character, repeated)

    def feed(self, chars: str) -> str:
        """Take characters read from the terminal; returns those that are not bound."""
        self.expire()
        now = self._clock()
        rest = []
        for char in chars:
            key = char.lower()
            if not self.bound(key):
                rest.append(char)
            elif key in self._seen:
                self._seen[key] = (now, True)
            else:
                self._seen[key] = (now, False)
                self.key_down(key)
        return "".join(rest)

    def expire(self) -> None:
        """Bring up the keys whose auto-repeat stopped."""
        now = self._clock()
        for key, (last, repeated) in list(self._seen.items()):
            if now - last > (self.repeat_s if repeated else self.initial_s):
                del self._seen[key]
                self.key_up(key)

    def release_all(self) -> None:
        self._seen.clear()
        super().release_all()

    def poll(self, t: float) -> list[InputEvent]:
        self.expire()
        return super().poll(t)
