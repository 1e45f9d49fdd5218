"""Speed profiles: how fast a gesture's command moves the arm while the gesture is held.

The paper maps each gesture to "a predefined velocity profile". Two ship, chosen in the
mapping file's ``[motion.profile]`` table:

- ``graded`` (the default): a command starts slowly and keeps speeding up while the
  fingers stay on the skin, so the same gesture gives a fine and a coarse move.  For the
  first ``fine_s`` seconds of the command it runs at ``start_fraction`` of the mapping's
  full speed; over the next ``ramp_s`` seconds its speed rises along a smoothstep
  (``3u^2 - 2u^3``, no kink at either end) to full speed, and stays there.  Every command
  moves at least ``nudge_mm`` (a translation) or ``nudge_deg`` (a turn), like a teach
  pendant's smallest step: a gesture lifted before it got that far (a flick) is finished
  as a *nudge* at the start speed, then braked.  The speed grows with hold time, not with
  the finger's travel (a swipe's travel is over before its command starts: the
  recogniser needs most of the motion) nor with pressure (skins differ 10x in response
  and people 5x in force), so a person controls it by one thing they can feel: how long
  they keep their fingers on the skin.
- ``constant``: the paper's literal profile, full speed from the first instant until the
  fingers lift, no nudge.

The profile shapes the *target* speed; :class:`~wovenskin.control.motion.TwistShaper`
still limits acceleration and jerk, and the safety layer still caps every twist.
Keyboard keys and the teach pendant keep their own conventions (a key held moves at full
speed, a pendant steps by its increments); the profile belongs to the skin's gestures.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

from wovenskin.control.mapping_defaults import PROFILE
from wovenskin.errors import ConfigError

PROFILE_KINDS = ("graded", "constant")


@dataclass(frozen=True)
class SpeedProfile:
    """The target speed of a held gesture, as a fraction of full speed (module docstring).

    Times in s; ``nudge_deg`` in degrees, as in the mapping file.  The defaults are the
    packaged mapping file's ``[motion.profile]`` (:mod:`~wovenskin.control.mapping_defaults`).
    """

    kind: Literal["graded", "constant"] = PROFILE["kind"]
    start_fraction: float = PROFILE["start_fraction"]
    fine_s: float = PROFILE["fine_s"]
    ramp_s: float = PROFILE["ramp_s"]
    nudge_mm: float = PROFILE["nudge_mm"]
    nudge_deg: float = PROFILE["nudge_deg"]

    def __post_init__(self) -> None:
        if self.kind not in PROFILE_KINDS:
            raise ConfigError(f"profile kind must be 'graded' or 'constant', got {self.kind!r}")
        for name in ("start_fraction", "fine_s", "ramp_s", "nudge_mm", "nudge_deg"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise ConfigError(f"profile {name} must be a number, got {value!r}")
            if not (math.isfinite(value) and value >= 0.0):
                raise ConfigError(f"profile {name} must be a finite number >= 0, got {value!r}")
        if not 0.0 < self.start_fraction <= 1.0:
            raise ConfigError(
                f"profile start_fraction must lie in (0, 1], got {self.start_fraction!r}"
            )

    @property
    def graded(self) -> bool:
        return self.kind == "graded"

    def fraction(self, held_s: float) -> float:
        """Share of full speed ``held_s`` seconds after the command started."""
        if not self.graded:
            return 1.0
        if held_s <= self.fine_s:
            return self.start_fraction
        if self.ramp_s <= 0.0 or held_s >= self.fine_s + self.ramp_s:
            return 1.0
        u = (held_s - self.fine_s) / self.ramp_s
        return self.start_fraction + (1.0 - self.start_fraction) * u * u * (3.0 - 2.0 * u)

    def nudge(self, kind: str) -> float:
        """The least way a command moves: m for ``"translate"``, rad for ``"rotate"``
        (0 for the constant profile)."""
        if not self.graded:
            return 0.0
        if kind == "translate":
            return self.nudge_mm / 1000.0
        return math.radians(self.nudge_deg)

    def distance(self, held_s: float, full_speed: float) -> float:
        """Way covered by the target speed over the first ``held_s`` seconds (m or rad),
        the shaper's ramps left out: the integral of :meth:`fraction` times ``full_speed``."""
        held_s = max(0.0, float(held_s))
        if not self.graded:
            return full_speed * held_s
        f0, fine, ramp = self.start_fraction, self.fine_s, self.ramp_s
        way = f0 * min(held_s, fine)
        if held_s > fine and ramp > 0.0:
            u = min(1.0, (held_s - fine) / ramp)
            # integral of f0 + (1 - f0) (3u^2 - 2u^3) over [0, u], times ramp
            way += ramp * (f0 * u + (1.0 - f0) * (u**3 - u**4 / 2.0))
        way += max(0.0, held_s - fine - ramp)
        return full_speed * way

    def hold_for(self, way: float, full_speed: float) -> float:
        """How long to hold a command for its target speed to cover ``way`` (m or rad):
        the inverse of :meth:`distance` (bisection; it is monotonic)."""
        if way <= 0.0 or full_speed <= 0.0:
            return 0.0
        low, high = 0.0, self.fine_s + self.ramp_s + way / full_speed + 1.0
        for _ in range(60):
            mid = 0.5 * (low + high)
            if self.distance(mid, full_speed) < way:
                low = mid
            else:
                high = mid
        return high

    def to_dict(self) -> dict:
        return {
            "kind": self.kind,
            "start_fraction": self.start_fraction,
            "fine_s": self.fine_s,
            "ramp_s": self.ramp_s,
            "nudge_mm": self.nudge_mm,
            "nudge_deg": self.nudge_deg,
        }


PROFILE_KEYS = tuple(SpeedProfile.__dataclass_fields__)


def profile_from_table(table: object, where: str) -> SpeedProfile:
    """A :class:`SpeedProfile` from a mapping file's ``[motion.profile]`` table; a
    one-line ``ConfigError`` naming ``where`` and the key on anything wrong."""
    if not isinstance(table, dict):
        raise ConfigError(f"{where} must be a table")
    unknown = sorted(set(table) - set(PROFILE_KEYS))
    if unknown:
        expected = ", ".join(PROFILE_KEYS)
        raise ConfigError(f"{where}.{unknown[0]}: unknown key (expected one of {expected})")
    try:
        return SpeedProfile(**table)
    except ConfigError as exc:
        raise ConfigError(f"{where}: {exc}") from None
