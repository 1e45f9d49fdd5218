"""What a control session is set to do, shows while it runs and reports when it ends.

:class:`SessionSettings` (how the loop turns commands into motion), :class:`SessionState`
(the newest tick's inputs and outputs, for views), :class:`SessionResult` (the figures of a
finished session), :func:`unsure_line` (the recogniser's hesitation, for views) and
:func:`update_predictions`; :class:`Reporter` says its messages and errors.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from wovenskin.control.safety_limits import StopEvent
from wovenskin.robots.base import RobotState


@dataclass(frozen=True)
class SessionSettings:
    """How the loop turns commands into motion."""

    pose_speed_fraction: float = 0.2  # joint moves to stored poses, fraction of joint limits
    max_shaper_dt_s: float = 0.05  # longest step the twist shaper integrates at once
    max_robot_step_s: float = 0.5  # longest step of a simulated robot (longer ones are cut)
    error_repeat_s: float = 1.0  # the same error line is reported at most this often
    idle_timeout_s: float = 0.02  # longest wait for skin frames in one step
    # Time without frames counts on the wall clock (a live skin).  False only for a source
    # played faster than real time into a simulated arm, which moves on the stream's clock:
    # there only gaps in the stream's own timestamps stop the arm, so a pause of the host
    # (a busy machine) cannot change the outcome of a replay.
    wall_clock_stalls: bool = True


@dataclass
class SessionState:
    """What views show: the newest tick's inputs and outputs.

    The newest skin frame, its contacts and the stream's health are the ``LiveSkin``'s
    own state (``session.live_skin.state``).
    """

    t: float = 0.0
    ticks: int = 0
    gesture: str | None = None
    gesture_since: float | None = None
    held: str | None = None  # the key or panel button held now ("translate +x (keyboard)")
    action: str = "-"
    top: tuple[str, float] = ("-", 0.0)
    probabilities: np.ndarray | None = None
    class_names: tuple[str, ...] = ()
    robot: RobotState | None = None
    twist: np.ndarray = field(default_factory=lambda: np.zeros(6))
    stops: list[StopEvent] = field(default_factory=list)
    stopped: bool = False
    messages: deque = field(default_factory=lambda: deque(maxlen=8))
    last_error: str = ""
    errors: int = 0
    ended: bool = False
    unsure: str = ""  # "unsure: a 0.55 / b 0.40" while the recogniser hesitates (see below)
    unsure_t: float | None = None  # session time of the newest unsure reading


INTERRUPTED = "interrupted (Ctrl-C)"
"""How a session that Ctrl-C ended says it ended (:attr:`SessionResult.ended`); the command
line then exits 130, as a shell expects of an interrupted program."""


@dataclass
class SessionResult:
    """Figures of a finished session."""

    ticks: int
    stream_s: float
    wall_s: float
    commands: int
    stops: list[StopEvent]
    errors: int
    ended: str

    def summary(self) -> str:
        speed = self.stream_s / self.wall_s if self.wall_s > 0 else 0.0
        reasons = "; ".join(f"{s.t:.2f} s {s.reason}" for s in self.stops[-3:])
        return (
            f"{self.ticks} control ticks over {self.stream_s:.1f} s of skin stream in "
            f"{self.wall_s:.1f} s ({speed:.1f}x real time), {self.commands} command changes, "
            f"{len(self.stops)} stops{f' ({reasons})' if reasons else ''}, "
            f"{self.errors} errors; {self.ended}"
        )


UNSURE_FLOOR = 0.3  # a gesture this likely is worth showing when nothing fires
UNSURE_HOLD_S = 2.0  # how long the last unsure reading stays after the touch


def unsure_line(
    probabilities: np.ndarray, class_names: tuple[str, ...], min_probability: float
) -> str:
    """``"unsure: swipe_left 0.55 / swipe_left_2f 0.40"`` when the likeliest gesture
    reaches :data:`UNSURE_FLOOR` but would not fire (below ``min_probability`` or behind
    ``invalid``); ``""`` otherwise."""
    p = np.asarray(probabilities, dtype=float).reshape(-1)
    if p.size != len(class_names) or not np.all(np.isfinite(p)):
        return ""
    gestures = [k for k, name in enumerate(class_names) if name != "invalid"]
    ranked = sorted(gestures, key=lambda k: -p[k])[:2]
    if not ranked or p[ranked[0]] < UNSURE_FLOOR:
        return ""
    best = ranked[0]
    if int(np.argmax(p)) == best and p[best] >= min_probability:
        return ""  # it would fire
    shown = " / ".join(f"{class_names[k]} {p[k]:.2f}" for k in ranked if p[k] >= 0.05)
    return f"unsure: {shown}"


def min_probability_of(pipeline: Any) -> float:
    """The arbiter's ``min_probability`` (0 when the pipeline does not say)."""
    settings = getattr(getattr(pipeline, "settings", None), "arbiter", None)
    return float(getattr(settings, "min_probability", 0.0) or 0.0)


def update_predictions(
    state: SessionState,
    probabilities: np.ndarray,
    min_probability: float,
    touching: bool,
    t: float,
) -> None:
    """Keep the recogniser's newest ``probabilities`` for the views: the top class and,
    while fingers are on the skin (``touching``) and no command runs, its hesitation
    (:func:`unsure_line`), which stays :data:`UNSURE_HOLD_S` after the touch so a user sees
    how the gesture was read and can draw it better."""
    state.probabilities = probabilities
    names = state.class_names
    if not (probabilities.size and names):
        return
    k = int(np.argmax(probabilities))
    state.top = (names[k], float(probabilities[k]))
    if state.gesture is not None:
        state.unsure, state.unsure_t = "", None
        return
    line = unsure_line(probabilities, names, min_probability)
    if line and touching:
        state.unsure, state.unsure_t = line, t
    elif state.unsure_t is not None and t - state.unsure_t > UNSURE_HOLD_S:
        state.unsure, state.unsure_t = "", None


class Reporter:
    """The session's messages and errors: into the state (for views), to ``on_message``
    (a terminal), and errors also to ``note`` (the recording); the same error line at
    most once every ``repeat_s`` of wall time."""

    def __init__(
        self,
        state: SessionState,
        on_message: Callable[[str], None],
        wall: Callable[[], float],
        repeat_s: float,
        note: Callable[[str, float, Any], None],
        now: Callable[[], float],
    ) -> None:
        self._state, self._on_message, self._wall = state, on_message, wall
        self._repeat_s, self._note, self._now = repeat_s, note, now
        self._error_times: dict[str, float] = {}

    def say(self, text: str) -> None:
        self._state.messages.append(text)
        self._on_message(text)

    def warn(self, text: str) -> None:
        line = " ".join(str(text).split())
        self._state.errors += 1
        self._state.last_error = line
        now = self._wall()
        if now - self._error_times.get(line, -np.inf) >= self._repeat_s:
            self._error_times[line] = now
            self.say(f"error: {line}")
        self._note("errors", self._now(), {"message": line})
