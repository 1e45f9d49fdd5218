"""A gesture command's motion in time: its speed profile, its way so far, and its nudge.

:class:`GestureMotion` follows the skin's command for the control session
(:class:`~wovenskin.control.session.ControlSession`): while a gesture's twist command is
active the target twist is scaled by the mapping's
:class:`~wovenskin.control.profile.SpeedProfile` at the time the command has been held,
and the way the shaped twist covered is added up.  When the fingers lift before the
command covered the profile's nudge (1 mm or 0.5 deg by default), the command is
finished as a nudge: the same twist, at the speed that covers the rest of the way in
about ``nudge_s`` (0.08 s; never slower than the profile's start speed nor faster than
full speed), until the way covered plus the brake's way reaches the nudge, then the
shaper's release brake.  A flick -- a
gesture the recogniser took only as the fingers lifted -- is therefore a nudge, like a
pendant's smallest step.  A nudge never outlasts ``max_nudge_s`` (the safety layer may
hold a twist back) and any new command, a stop or an error ends it.

The way is the *commanded* twist's, integrated tick by tick: it is what the profile
controls, and it is known the same on a real arm as on the simulated one.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from wovenskin.control.mapping import ActionMapping, TwistAction
from wovenskin.control.profile import SpeedProfile
from wovenskin.robots.base import Pose

MAX_NUDGE_S = 0.4  # s: a nudge the safety layer holds back ends after this long
NUDGE_S = 0.08  # s: a nudge covers its way in about this long (ramp, cruise and brake)


@dataclass
class _Command:
    """The running (or nudging) gesture command."""

    action: TwistAction
    frame: str | None
    started: float
    way: float = 0.0  # m or rad covered by the shaped twist
    nudge_from: float | None = None  # session time the fingers lifted (nudging since)
    nudge_fraction: float = 0.0  # share of full speed the nudge runs at


class GestureMotion:
    """The speed profile and nudge of the skin's twist commands (module docstring)."""

    def __init__(
        self, mapping: ActionMapping, max_nudge_s: float = MAX_NUDGE_S, nudge_s: float = NUDGE_S
    ) -> None:
        self.mapping = mapping
        self.max_nudge_s = float(max_nudge_s)
        self.nudge_s = float(nudge_s)
        self._command: _Command | None = None

    @property
    def profile(self) -> SpeedProfile:
        return self.mapping.settings.profile

    @property
    def nudging(self) -> bool:
        """Whether a lifted gesture is being finished as a nudge."""
        return self._command is not None and self._command.nudge_from is not None

    @property
    def way(self) -> float:
        """Way (m or rad) the current or last nudging command has covered."""
        return 0.0 if self._command is None else self._command.way

    def started(self, action: object, frame: str | None, t: float) -> None:
        """A gesture's command became active at ``t`` (a twist action is followed)."""
        self._command = _Command(action, frame, t) if isinstance(action, TwistAction) else None

    def ended(self, t: float, lifted: bool) -> None:
        """The gesture's command ended at ``t``; ``lifted``: by the fingers lifting (a
        command short of its nudge is then finished), else (reset, erratic) it just ends."""
        command = self._command
        if command is None:
            return
        nudge = self.profile.nudge(command.action.kind)
        if lifted and command.way < nudge:
            command.nudge_from = t
            settings = self.mapping.settings
            full = (
                settings.linear_speed
                if command.action.kind == "translate"
                else (settings.angular_speed)
            )
            wanted = 2.0 * (nudge - command.way) / (self.nudge_s * full)  # peak of a triangle
            command.nudge_fraction = min(1.0, max(self.profile.start_fraction, wanted))
        else:
            self._command = None

    def cancel(self) -> None:
        """Forget the command and any nudge (a stop, an error, another input)."""
        self._command = None

    def speed_fraction(self, t: float) -> float:
        """The profile's share of full speed for the active command at ``t``."""
        command = self._command
        if command is None:
            return 1.0
        if command.nudge_from is not None:
            return command.nudge_fraction
        return self.profile.fraction(t - command.started)

    def nudge_target(
        self, t: float, tcp: Pose, twist_now: np.ndarray, brake_s: float, accel: tuple
    ) -> np.ndarray | None:
        """The full-speed-scaled target twist of a running nudge at ``t`` (``None``: no
        nudge runs, or it just ended and the shaper should brake).  ``twist_now`` is the
        shaped twist, ``brake_s`` the shaper's release time and ``accel`` its (linear,
        angular) acceleration limits, which give the brake's way."""
        command = self._command
        if command is None or command.nudge_from is None:
            return None
        part = slice(0, 3) if command.action.kind == "translate" else slice(3, 6)
        speed = float(np.linalg.norm(twist_now[part]))
        limit = accel[0] if command.action.kind == "translate" else accel[1]
        deceleration = max(limit, speed / brake_s) if speed > 0 else limit
        braking = speed * speed / (2.0 * deceleration)
        nudge = self.profile.nudge(command.action.kind)
        if command.way + braking >= nudge or t - command.nudge_from > self.max_nudge_s:
            self._command = None
            return None
        twist = self.mapping.twist_of(command.action, tcp, command.frame)
        return twist * command.nudge_fraction

    def add_way(self, twist: np.ndarray, dt: float) -> None:
        """Count the way the shaped ``twist`` covers over ``dt`` toward the command."""
        command = self._command
        if command is None or dt <= 0.0:
            return
        part = slice(0, 3) if command.action.kind == "translate" else slice(3, 6)
        command.way += float(np.linalg.norm(np.asarray(twist)[part])) * dt
