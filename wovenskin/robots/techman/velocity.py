"""Velocity mode on a Techman arm: the two controller timeouts and what a refusal means.

``ContinueVLine(timeout_zero_vel, timeout_stop)`` puts the controller in Cartesian
velocity mode; both arguments are milliseconds (Techman's driver names them so). While
the mode lasts, each ``SetContinueVLine(vx, vy, vz, wx, wy, wz)`` (mm/s, deg/s, base
frame) sets the velocity. If no ``SetContinueVLine`` arrives for ``timeout_zero_vel`` ms
the controller brings the arm to rest; after ``timeout_stop`` ms it leaves velocity mode,
and every later ``SetContinueVLine`` is refused until ``ContinueVLine`` is sent again.
``StopContinueVmode()`` leaves the mode on request.

The timeouts are the controller's own watchdog, so :class:`VelocityTimeouts` chooses them
for safety first (docs/techman.md, "Timeouts"):

* ``zero_velocity_ms`` = 300: longer than the client's own command timeout (0.2 s, after
  which it sends a zero velocity itself) and three keep-alive periods, so it never fires
  while the client is alive; short enough that a crashed client or a cut cable leaves
  the arm moving for at most 0.3 s plus its deceleration (<= 75 mm at 250 mm/s).
* ``stop_ms`` = 2000: the arm is already at rest by then; leaving the mode later than
  that would hold a dead session's mode for no gain, sooner would end the mode on an
  ordinary stall of a busy host (garbage collection, a loaded CPU).
* ``keepalive_s`` = 0.1: while the mode is on and nothing moves, the client re-sends a
  zero velocity this often, so the mode survives idle periods between gestures.
"""

from __future__ import annotations

from dataclasses import dataclass

from wovenskin.robots.techman.protocol import call


@dataclass(frozen=True)
class VelocityTimeouts:
    """The ``ContinueVLine`` timeouts (ms) and the client's keep-alive period (s)."""

    zero_velocity_ms: int = 300
    stop_ms: int = 2000
    keepalive_s: float = 0.1

    def __post_init__(self) -> None:
        zero, stop, keep = self.zero_velocity_ms, self.stop_ms, self.keepalive_s
        if not (isinstance(zero, int) and isinstance(stop, int)):
            raise ValueError("velocity-mode timeouts are whole milliseconds")
        if not 50 <= zero < stop <= 60_000:
            raise ValueError(
                f"velocity-mode timeouts {zero} ms / {stop} ms must satisfy "
                "50 <= zero-velocity < stop <= 60000"
            )
        if not 0.0 < keep * 1000.0 <= zero / 2:
            raise ValueError(
                f"keep-alive period {keep} s must be positive and at most half the "
                f"zero-velocity timeout ({zero} ms)"
            )

    @property
    def zero_velocity_s(self) -> float:
        """``zero_velocity_ms`` in seconds."""
        return self.zero_velocity_ms / 1000.0

    @property
    def stop_s(self) -> float:
        """``stop_ms`` in seconds."""
        return self.stop_ms / 1000.0

    @property
    def reenter_after_s(self) -> float:
        """After this long without a velocity sent, the client no longer trusts the mode:
        half ``stop_ms``, so it re-enters before relying on a mode that may have ended."""
        return self.stop_s / 2.0

    def enter_script(self) -> str:
        """The ``ContinueVLine`` line that enters velocity mode with these timeouts."""
        return call("ContinueVLine", self.zero_velocity_ms, self.stop_ms)


def enter_refused(lines: tuple[int, ...], entered_before: bool) -> str:
    """One line explaining a refused ``ContinueVLine`` (``lines``: the reply's error lines)."""
    where = f"script line {','.join(map(str, lines)) or '?'}"
    if entered_before:
        return (
            f"the robot refused ContinueVLine ({where}) after accepting it earlier this "
            "session: the arm is in a state that forbids motion (a stop, error or mode change "
            "on the controller); clear it on the robot, then move again"
        )
    return (
        f"the robot refused ContinueVLine ({where}): velocity mode is a licensed TMflow "
        "function, so the controller most likely lacks Techman's velocity-mode licence "
        "(dongle) or runs a TMflow without it; see docs/techman.md"
    )


def stream_refused(script_name: str, lines: tuple[int, ...], stop_ms: int) -> str:
    """One line explaining a refused streamed script (``SetContinueVLine``)."""
    where = f"script line {','.join(map(str, lines)) or '?'}"
    return (
        f"the robot refused {script_name} ({where}): it is no longer in velocity mode "
        f"(no command reached it for its {stop_ms} ms stop timeout, or a stop or fault ended "
        "the mode); the arm is stopped and the next command re-enters velocity mode"
    )
