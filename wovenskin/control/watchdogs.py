"""The safety layer's two watchdogs: the skin stream and the command stream must speak.

Each is armed by its first heartbeat and fires once when its stream has been silent for
longer than the limit (100 ms by default, ``SafetyLimits.watchdog_s``); a new heartbeat
re-arms it. The skin watchdog is asked first: a stalled skin also silences the commands,
and the stop should name the cause.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass
class Watchdogs:
    """When the skin and the command streams last spoke, and whether each has fired."""

    limit_s: float
    last_skin: float | None = None
    last_command: float | None = None
    skin_fired: bool = False
    command_fired: bool = False

    def skin(self, t: float) -> None:
        """The skin stream delivered a frame at ``t``."""
        self.last_skin, self.skin_fired = t, False

    def command(self, t: float) -> None:
        """The control loop spoke at ``t``."""
        self.last_command, self.command_fired = t, False

    def due(self, now: float) -> tuple[str, str] | None:
        """``(reason, source)`` of the watchdog that fires at ``now``, once per silence."""
        if not self.skin_fired and _silent(self.last_skin, now, self.limit_s):
            self.skin_fired = True
            silence = now - (self.last_skin or now)
            return f"skin stream stalled: no frame for {1000 * silence:.0f} ms", "skin watchdog"
        if not self.command_fired and _silent(self.last_command, now, self.limit_s):
            self.command_fired = True
            silence = now - (self.last_command or now)
            return f"command stream silent for {1000 * silence:.0f} ms", "command watchdog"
        return None

    def restart(self, now: float) -> None:
        """A stop was cleared at ``now``: the armed watchdogs count again from it."""
        if self.last_skin is not None:
            self.last_skin = max(self.last_skin, now)
        if self.last_command is not None:
            self.last_command = max(self.last_command, now)
        self.skin_fired = self.command_fired = False


def _silent(last: float | None, now: float, limit: float) -> bool:
    return last is not None and now - last > limit
