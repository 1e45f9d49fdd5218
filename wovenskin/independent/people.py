"""The people of the independent generator: how one person moves, presses and holds a hand.

A :class:`Person` is drawn once per stream with deliberately wide ranges: how fast they
move (a factor on every stroke speed), how hard they press, the size of their fingertip
patch, the angle of their hand on the skin, how far apart they hold their fingers within
the gesture table's ranges, how quickly their fingers land and lift, and how much their
hand trembles while it holds still.  Every trial then draws its own values around the
person's (:meth:`Person.jitter`).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np


def log_uniform(rng: np.random.Generator, low: float, high: float) -> float:
    """A value between ``low`` and ``high`` (both > 0), uniform in its logarithm."""
    return float(np.exp(rng.uniform(np.log(low), np.log(high))))


@dataclass(frozen=True)
class Person:
    """One person's habits (ranges: :meth:`draw`)."""

    speed_factor: float  # multiplies every stroke speed (0.6-1.6)
    force_n: float  # typical fingertip force of a deliberate touch (0.4-2.5 N)
    fingertip_mm: float  # contact-patch length at that force (6-16 mm)
    fingertip_aspect: float  # patch length / width (1.0-1.7)
    hand_angle_deg: float  # how the hand is turned on the skin (-40..40 deg)
    spacing: float  # where in the table's finger-spacing ranges they sit (0-1)
    ramp_s: float  # typical landing / lift ramp of one fingertip (8-60 ms)
    tremor_mm: float  # sd of the slow wander of a finger holding still (0.1-0.8 mm)
    pause_s: float  # typical pause between landing and moving (0-0.25 s)

    @classmethod
    def draw(cls, rng: np.random.Generator) -> Person:
        return cls(
            speed_factor=log_uniform(rng, 0.6, 1.6),
            force_n=log_uniform(rng, 0.4, 2.5),
            fingertip_mm=float(rng.uniform(6.0, 16.0)),
            fingertip_aspect=float(rng.uniform(1.0, 1.7)),
            hand_angle_deg=float(rng.uniform(-40.0, 40.0)),
            spacing=float(rng.uniform(0.0, 1.0)),
            ramp_s=log_uniform(rng, 0.008, 0.06),
            tremor_mm=log_uniform(rng, 0.1, 0.8),
            pause_s=float(rng.uniform(0.0, 0.25)),
        )

    def jitter(self, rng: np.random.Generator, value: float, relative: float) -> float:
        """``value`` varied by a lognormal factor of relative sd ``relative`` (one trial)."""
        return float(value * np.exp(rng.normal(0.0, relative)))

    def in_range(self, rng: np.random.Generator, low: float, high: float) -> float:
        """A value in ``[low, high]`` near this person's place in such ranges (``spacing``)."""
        u = float(np.clip(self.spacing + rng.normal(0.0, 0.2), 0.0, 1.0))
        return low + u * (high - low)

    def to_dict(self) -> dict[str, float]:
        return asdict(self)
