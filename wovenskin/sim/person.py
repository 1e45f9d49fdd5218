"""Simulated people: the habits that make one person's gestures differ from another's.

Owns :class:`Person` (a set of traits, drawn by :meth:`Person.sample` or, a typical one, by
:meth:`Person.sample_typical`) and :class:`Trial`,
which draws the parameters of one performance around the person's habits (trial-to-trial
variation) while keeping them inside the ranges of ``docs/gestures.md``.

Tempo and size are *quantiles*: ``pace = 0.8`` means this person's swipes, circles and
pinches run at 80 % of the way through the allowed speed ranges, so a fast person is fast at
everything yet never leaves a range.  Hand orientation is an angle in degrees, measured
clockwise as the user sees the skin, of the direction the fingers point: 0 = fingers point
up (toward row 0), 90 = to the right.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, replace

import numpy as np

from wovenskin.errors import ConfigError
from wovenskin.settings import from_dict
from wovenskin.sim import spec

FINGERS = ("thumb", "index", "middle", "ring", "little")

# A typical person's traits (:meth:`Person.sample_typical`): ``(low, high)`` bounds that
# keep out the lightest touch and press, the far edge of the skin, the tightest pair of fingers, the
# oddest hand postures and the most erratic trial-to-trial variation; every other trait
# keeps its full range.
TYPICAL_TRAITS: dict[str, tuple[float, float]] = {
    "pace": (0.15, 0.85),
    "reach": (0.15, 0.85),
    "force_n": (0.6, 1.5),
    "press_ratio": (2.2, 3.6),
    "location_u": (0.4, 0.6),
    "location_v": (0.4, 0.6),
    "location_spread": (0.03, 0.08),
    "finger_spacing_mm": (17.0, 22.0),
    "hand_angle_deg": (-45.0, 45.0),
    "hand_angle_sd_deg": (8.0, 15.0),
    "posture_variety": (0.05, 0.15),
    "consistency": (0.5, 1.0),
}


@dataclass(frozen=True)
class Pad:
    """A fingertip's contact patch: ``width_mm`` at a light touch, wider when pressed.

    Width grows as ``width + growth * (1 - exp(-F / 1 N))`` and the patch is ``aspect``
    times longer along the finger; both axes stay within ``spec.FINGERTIP_PATCH_MM``.
    """

    width_mm: float
    growth_mm: float
    aspect: float

    def axes_mm(self, force_n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Semi-major and semi-minor axes (mm) of the patch at each force."""
        low, high = spec.FINGERTIP_PATCH_MM
        width = self.width_mm + self.growth_mm * (1.0 - np.exp(-np.asarray(force_n) / 1.0))
        width = np.clip(width, low, high)
        length = np.clip(width * self.aspect, width, high)
        return length / 2.0, width / 2.0


def _reflect01(x: float) -> float:
    """Fold ``x`` back into [0, 1] (a mirror at each end keeps the distribution smooth)."""
    x = abs(x) % 2.0
    return 2.0 - x if x > 1.0 else x


@dataclass(frozen=True)
class Person:
    """Traits of one simulated person (see the module docstring for units and angles)."""

    person_id: str = "sim-default"
    handedness: str = "right"
    pace: float = 0.5  # 0..1 position within the speed / rate ranges (1 = fastest)
    reach: float = 0.5  # 0..1 position within the travel / radius / spread ranges
    force_n: float = 0.8  # typical fingertip force while sliding (0.25-2 N)
    press_ratio: float = 2.5  # push: held force / landing force (1.8-4)
    location_u: float = 0.5  # preferred gesture centre, share of skin width (0.3-0.7)
    location_v: float = 0.5  # preferred gesture centre, share of skin height (0.3-0.7)
    location_spread: float = 0.08  # trial sd of the gesture centre, share of skin size
    hand_angle_deg: float = 0.0  # habitual finger direction, clockwise from "up"
    hand_angle_sd_deg: float = 15.0  # trial-to-trial sd of the hand orientation
    posture_variety: float = 0.15  # chance per trial of an unusual hand orientation
    finger_spacing_mm: float = 18.0  # index-middle fingertip spacing (15-22 mm)
    pad_mm: float = 8.8  # fingertip patch width at a light touch (8-9.5 mm)
    pad_growth_mm: float = 3.0  # extra patch width at a firm press (2-4 mm)
    pad_aspect: float = 1.1  # patch length along the finger / width (1-1.2)
    settle_s: float = 0.08  # pause between landing and the start of the motion (0-0.2 s)
    rest_probability: float = 0.6  # how often the fingers rest after the motion
    rest_mean_s: float = 0.5  # typical resting time when they do
    tremor_mm: float = 0.1  # physiological tremor sd (8-12 Hz)
    tremor_hz: float = 10.0
    sway_mm: float = 0.25  # slow postural sway sd of a touching finger
    landing_ramp_s: float = 0.025  # typical contact ramp-in (10-50 ms)
    lift_ramp_s: float = 0.025  # typical contact ramp-out (10-50 ms)
    finger_async_s: float = 0.02  # sd of landing / lift-off asynchrony between fingers
    aim_sd_deg: float = 3.0  # sd of a swipe's off-axis angle
    bow: float = 0.02  # typical sideways bow of a swipe, share of its travel
    force_wobble: float = 0.08  # relative force fluctuation while sliding
    skew: float = 0.0  # asymmetry of the speed profile (<0: early peak)
    consistency: float = 1.0  # scales trial-to-trial variation (0.5 steady - 1.5 erratic)
    flick_probability: float = 0.15  # chance a swipe lifts off while still moving

    def __post_init__(self) -> None:
        if self.handedness not in ("right", "left"):
            raise ConfigError(f"handedness must be 'right' or 'left', got {self.handedness!r}")
        for name in ("pace", "reach", "location_u", "location_v", "posture_variety"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise ConfigError(f"person {name} must lie in [0, 1], got {getattr(self, name)}")
        if self.force_n <= 0 or self.press_ratio < 1.0:
            raise ConfigError("person force must be positive and press ratio >= 1")

    @classmethod
    def sample(cls, rng: np.random.Generator) -> Person:
        """A random person; every trait drawn independently within its plausible range."""

        def u(low: float, high: float) -> float:
            return float(rng.uniform(low, high))

        def logu(low: float, high: float) -> float:
            return float(np.exp(rng.uniform(np.log(low), np.log(high))))

        return cls(
            person_id=f"sim-{rng.integers(16**6):06x}",
            handedness="left" if rng.random() < 0.12 else "right",
            pace=u(0.0, 1.0),
            reach=u(0.0, 1.0),
            force_n=logu(0.25, 2.0),
            press_ratio=u(1.8, 4.0),
            location_u=u(0.3, 0.7),
            location_v=u(0.3, 0.7),
            location_spread=u(0.03, 0.15),
            hand_angle_deg=u(-100.0, 100.0),
            hand_angle_sd_deg=u(8.0, 25.0),
            posture_variety=u(0.05, 0.35),
            finger_spacing_mm=u(15.0, 22.0),
            pad_mm=u(8.0, 9.5),
            pad_growth_mm=u(2.0, 4.0),
            pad_aspect=u(1.0, 1.2),
            settle_s=0.0 if rng.random() < 0.15 else logu(0.02, 0.2),
            rest_probability=u(0.2, 0.9),
            rest_mean_s=u(0.2, 1.0),
            tremor_mm=logu(0.03, 0.25),
            tremor_hz=u(8.0, 12.0),
            sway_mm=u(0.1, 0.4),
            landing_ramp_s=u(0.012, 0.045),
            lift_ramp_s=u(0.012, 0.045),
            finger_async_s=u(0.0, 0.05),
            aim_sd_deg=u(1.5, 5.0),
            bow=u(0.0, 0.05),
            force_wobble=u(0.03, 0.15),
            skew=u(-0.15, 0.15),
            consistency=u(0.5, 1.5),
            flick_probability=u(0.0, 0.4),
        )

    @classmethod
    def sample_typical(cls, rng: np.random.Generator) -> Person:
        """A random person of typical habits: :meth:`sample` with the traits of
        :data:`TYPICAL_TRAITS` kept within their bounds.

        The full range trains and tests recognisers; the person behind a demonstration's
        gesture buttons (the dashboard's, ``wovenskin run``'s) is this one."""
        person = cls.sample(rng)
        kept = {
            name: float(np.clip(getattr(person, name), low, high))
            for name, (low, high) in TYPICAL_TRAITS.items()
        }
        return replace(person, **kept)

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict) -> Person:
        """The person :meth:`to_dict` wrote; one :class:`ConfigError` line naming a bad key."""
        return from_dict(cls, d, "person traits")


_FINGER_FORCE = {"thumb": 1.15, "index": 1.0, "middle": 0.95, "ring": 0.8, "little": 0.7}
_FINGER_PAD = {"thumb": 0.8, "index": 0.0, "middle": 0.2, "ring": -0.2, "little": -0.6}


class Trial:
    """Draws one performance's parameters around a person's habits.

    ``quick_start`` removes the pause between landing and motion (used for gestures that
    are cut short right after they begin).
    """

    def __init__(self, person: Person, rng: np.random.Generator, quick_start: bool = False):
        self.person = person
        self.rng = rng
        self.quick_start = quick_start
        self.force_scale = float(np.exp(rng.normal(0.0, 0.12 * person.consistency)))
        self._hand_angle = self._draw_hand_angle()

    # -- ranges ---------------------------------------------------------------------------
    def quantile(self, habit: float, sd: float = 0.12) -> float:
        """A trial quantile in [0, 1] around ``habit``."""
        return _reflect01(habit + self.rng.normal(0.0, sd * self.person.consistency))

    @staticmethod
    def at_quantile(q: float, value_range: tuple[float, float], log: bool = False) -> float:
        low, high = value_range
        if log:
            return float(low * (high / low) ** q)
        return float(low + (high - low) * q)

    def paced(self, value_range: tuple[float, float], log: bool = True) -> float:
        """A value in ``value_range`` following the person's pace (fast -> high)."""
        return self.at_quantile(self.quantile(self.person.pace), value_range, log)

    def paced_duration(self, value_range: tuple[float, float]) -> float:
        """A duration in ``value_range`` following the person's pace (fast -> short)."""
        return self.at_quantile(1.0 - self.quantile(self.person.pace), value_range, log=True)

    def sized(self, value_range: tuple[float, float]) -> float:
        """A value in ``value_range`` following the person's reach (large -> high)."""
        return self.at_quantile(self.quantile(self.person.reach), value_range)

    def uniform(self, low: float, high: float) -> float:
        return float(self.rng.uniform(low, high))

    # -- hand -----------------------------------------------------------------------------
    def _draw_hand_angle(self) -> float:
        p, rng = self.person, self.rng
        if rng.random() < p.posture_variety:
            return float(rng.uniform(-180.0, 180.0))
        return float(p.hand_angle_deg + rng.normal(0.0, p.hand_angle_sd_deg))

    @property
    def hand_angle_deg(self) -> float:
        """This trial's finger direction (clockwise from up, degrees)."""
        return self._hand_angle

    def finger_direction(self) -> np.ndarray:
        """Unit vector (x right, y down) in which the fingers point."""
        a = math.radians(self._hand_angle)
        return np.array([math.sin(a), -math.cos(a)])

    def mirror(self) -> float:
        """+1 for a right hand, -1 for a left hand (mirrors hand layouts)."""
        return 1.0 if self.person.handedness == "right" else -1.0

    def spacing(self, value_range: tuple[float, float], squeeze_mm: float = 0.0) -> float:
        """Fingertip spacing around the person's habit less ``squeeze_mm``, in ``value_range``."""
        low, high = value_range
        habit = self.person.finger_spacing_mm - squeeze_mm
        value = habit + self.rng.normal(0.0, 1.5 * self.person.consistency)
        return float(np.clip(value, low, high))

    def pad(self, finger: str = "index") -> Pad:
        p = self.person
        width = p.pad_mm + _FINGER_PAD.get(finger, 0.0) + self.rng.normal(0.0, 0.2)
        return Pad(float(np.clip(width, 8.0, 10.5)), p.pad_growth_mm, p.pad_aspect)

    def finger_force(self, finger: str = "index") -> float:
        """Typical force of ``finger`` in this trial (N)."""
        base = self.person.force_n * self.force_scale * _FINGER_FORCE.get(finger, 1.0)
        return float(np.clip(base * np.exp(self.rng.normal(0.0, 0.08)), 0.12, 6.0))

    # -- location ---------------------------------------------------------------------------
    def location(self, width_mm: float, height_mm: float) -> np.ndarray:
        """Where this trial's gesture is centred before it is fitted onto the skin."""
        p, rng = self.person, self.rng
        u = p.location_u + rng.normal(0.0, p.location_spread)
        v = p.location_v + rng.normal(0.0, p.location_spread)
        return np.array([u * width_mm, v * height_mm])

    # -- timing -----------------------------------------------------------------------------
    def settle_s(self) -> float:
        if self.quick_start:
            return 0.0
        return float(np.clip(self.person.settle_s * np.exp(self.rng.normal(0.0, 0.35)), 0.0, 0.4))

    def rest_s(self) -> float:
        """Resting time after the motion: often 0, else up to ``spec.REST_S[1]``."""
        p, rng = self.person, self.rng
        if rng.random() >= p.rest_probability:
            return float(rng.uniform(0.0, 0.05))
        return float(np.clip(rng.gamma(2.0, p.rest_mean_s / 2.0), *spec.REST_S))

    def ramp_s(self, habit_s: float) -> float:
        low, high = spec.CONTACT_RAMP_S
        return float(np.clip(habit_s * np.exp(self.rng.normal(0.0, 0.25)), low, high))

    def landing_ramp_s(self) -> float:
        return self.ramp_s(self.person.landing_ramp_s)

    def lift_ramp_s(self) -> float:
        return self.ramp_s(self.person.lift_ramp_s)

    def finger_delays_s(self, count: int) -> np.ndarray:
        """Landing (or lift-off) delays of ``count`` fingers; the first one is 0."""
        delays = np.abs(self.rng.normal(0.0, self.person.finger_async_s + 1e-6, count))
        return np.minimum(delays - delays.min(), 0.12)

    # -- swipe shape ------------------------------------------------------------------------
    def aim_deg(self) -> float:
        """Off-axis angle of a swipe's chord (degrees, within the allowed maximum)."""
        limit = spec.SWIPE_MAX_OFF_AXIS_DEG - 2.0  # tremor and finger wander add a little
        return float(np.clip(self.rng.normal(0.0, self.person.aim_sd_deg), -limit, limit))

    def bow(self, direction_sign: float = 1.0) -> float:
        """Signed sideways bow as a share of the travel; handedness biases its sign."""
        p, rng = self.person, self.rng
        magnitude = abs(rng.normal(p.bow, 0.012 * p.consistency))
        sign = direction_sign * self.mirror() if rng.random() < 0.7 else -1.0
        return float(np.clip(sign * magnitude, -0.9 * spec.SWIPE_MAX_BOW, 0.9 * spec.SWIPE_MAX_BOW))

    def skew(self) -> float:
        return float(np.clip(self.person.skew + self.rng.normal(0.0, 0.05), -0.25, 0.25))

    def flick(self) -> bool:
        return bool(self.rng.random() < self.person.flick_probability)
