"""The execution rules of docs/gestures.md: from per-window class probabilities to commands.

Owns :class:`Arbiter` (which gesture is the active command, frame by frame) and
:class:`PerformingDetector` (whether the fingers on the skin are *being performed* --
moving or changing pressure -- or merely resting), with their settings.

Inputs, one value per conditioned frame: its time ``t`` (s), the conditioner's debounced
``touched`` flag, the ``performing`` flag of :class:`PerformingDetector`, and, on the
frames where the streaming recogniser ran the model, the class probabilities of the
window ending there (:mod:`~wovenskin.recognition.streaming`).

Rules (docs/gestures.md, "Execution rules" and the resting paragraph before them):

- A prediction *recognises* class ``g`` when ``g`` is its most probable class, ``g`` is
  not ``invalid`` and its probability reaches ``min_probability``; otherwise it
  recognises nothing.  ``invalid`` and no contact never start an action.
- The *candidate* is the class recognised by every prediction since the frame
  ``candidate_since`` where it first was (any other prediction replaces or clears it).
  Its dwell is satisfied at a prediction frame ``i`` when ``i - candidate_since >=
  dwell_frames`` (``dwell_frames = round(dwell_s * rate)``, 20 at 200 Hz): the gesture
  has been recognised at the start and at the end of a whole dwell time, and at every
  prediction in between.  Decisions are taken on prediction frames only.
- Nothing active: a candidate whose dwell is satisfied becomes the command (reason
  ``"dwell"``), provided the fingers were being performed at some frame in the last
  ``start_within_s`` (0.2 s; ``None``: no such condition).  Fingers that have rested
  still for longer -- a hand left on the skin, the rest after a gesture whose command
  was missed -- start nothing, whatever the windows say; the grace covers the moving
  average's lag behind the end of a fast motion.
- A command active: a *different* candidate preempts it (reason ``"preempt"``) only when
  its dwell is satisfied counting only frames in which the fingers were being performed
  without a break, i.e. ``i - max(candidate_since, performing_since) >= dwell_frames``
  where ``performing_since`` is the first frame of the current unbroken run of
  ``performing`` frames.  Fingers resting still with steady pressure therefore never
  switch the command, whatever the windows say: a finger resting after a swipe or a
  pinch keeps that command and never becomes a ``push``.  ``invalid`` predictions and
  predictions of the active gesture never end a command.
- Lift-off (``touched`` false) ends the active command at once, on that very frame
  (reason ``"lift-off"``), and forgets the candidate: a new touch starts fresh.  While
  nothing touches the skin no prediction counts.
- Context no window has: a touch whose command would switch more than ``max_switches``
  times (default 1) is not a gesture but a hand wandering over the skin (a scribble, a
  hand sliding about): instead of the next switch the command ends (reason
  ``"erratic"``) and nothing acts until every finger has lifted.  People do correct a
  wrongly recognised first command by going on with the gesture (one switch), but do not
  chain three different commands in one touch.  ``None`` allows any number.

"Being performed" (:class:`PerformingDetector`): over the *touch region* -- the active
channels and their 8 neighbours -- each frame gets the total signal ``S`` (of the
signal above 15 % of the frame's peak: a soft floor, so channels flickering at their
contact threshold do not jump the measures), its centroid (mm) and its spread (rms
distance of the signal from the centroid, mm).  Frame ``i`` is compared with frame
``i - L`` (``L = round(span_s * rate)``, 0.1 s): the fingers are being performed when
the touch region is not empty in either and

- the centroid moved faster than ``min_speed_mm_s`` (a swipe, a circle), or
- the spread changed faster than ``min_spread_rate_mm_s`` (a pinch: the centroid of two
  converging fingers hardly moves), or
- ``|S_i - S_{i-L}| / max(S_i, S_{i-L})`` reaches ``min_pressure_change`` (a push, a
  landing or a lift: a contact appearing or vanishing is a change of 1).

The defaults (30 mm/s, 20 mm/s, 0.2) come from simulated streams of 20 people and skins:
resting phases (from 0.25 s after the motion ended, past the 0.1 s moving average) never
showed more than 3 consecutive performing frames (the preemption dwell needs 21), while
swipes, circles and pinches are performing for most of their motion; a slow push press
is performing for at least 7 consecutive frames after its landing.  The signal is the
conditioner's 0.1 s moving average, so the flag lags the fingers by up to about 0.1 s.

Everything is causal and carries its state between calls, so any split of the frames
into calls gives the same commands.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from wovenskin.errors import ConfigError
from wovenskin.gestures import INVALID
from wovenskin.skin.layout import DEFAULT_COL_PITCH_MM, DEFAULT_ROW_PITCH_MM

DWELL = "dwell"
PREEMPT = "preempt"
LIFT_OFF = "lift-off"
ERRATIC = "erratic"
REASONS: tuple[str, ...] = (DWELL, PREEMPT, LIFT_OFF)
"""Why the active command changed, as :attr:`CommandChange.reason`."""

NOTHING = -1
"""Class index meaning "this prediction recognises no valid gesture"."""


@dataclass(frozen=True)
class CommandChange:
    """From time ``t`` (stream clock, s) the active command is ``gesture`` (None: none)."""

    t: float
    gesture: str | None
    reason: str

    def to_dict(self) -> dict:
        return {"t": self.t, "gesture": self.gesture, "reason": self.reason}


def _check_positive(name: str, value: float) -> None:
    if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
        raise ConfigError(f"{name} must be a positive finite number, got {value!r}")


@dataclass(frozen=True)
class ArbiterSettings:
    """Execution-rule settings (see the module doc)."""

    dwell_s: float = 0.1
    min_probability: float = 0.0
    max_switches: int | None = 1
    start_within_s: float | None = 0.2

    def __post_init__(self) -> None:
        _check_positive("dwell_s", self.dwell_s)
        w = self.start_within_s
        if w is not None and not (isinstance(w, int | float) and math.isfinite(w) and w >= 0):
            raise ConfigError(f"start_within_s must be None or a number >= 0, got {w!r}")
        m = self.max_switches
        if m is not None and not (isinstance(m, int) and not isinstance(m, bool) and m >= 0):
            raise ConfigError(f"max_switches must be None or an integer >= 0, got {m!r}")
        p = self.min_probability
        if not (isinstance(p, int | float) and 0.0 <= p <= 1.0):
            raise ConfigError(f"min_probability must lie in [0, 1], got {p!r}")

    def dwell_frames(self, sample_rate_hz: float) -> int:
        """The dwell time in frames (at least 1)."""
        return max(1, int(round(self.dwell_s * sample_rate_hz)))


@dataclass(frozen=True)
class PerformingSettings:
    """When fingers count as being performed rather than resting (see the module doc)."""

    span_s: float = 0.1
    min_speed_mm_s: float = 30.0
    min_spread_rate_mm_s: float = 20.0
    min_pressure_change: float = 0.2
    row_pitch_mm: float = DEFAULT_ROW_PITCH_MM
    col_pitch_mm: float = DEFAULT_COL_PITCH_MM

    def __post_init__(self) -> None:
        for name in (
            "span_s",
            "min_speed_mm_s",
            "min_spread_rate_mm_s",
            "row_pitch_mm",
            "col_pitch_mm",
        ):
            _check_positive(name, getattr(self, name))
        change = self.min_pressure_change
        if not (isinstance(change, int | float) and 0.0 < change <= 1.0):
            raise ConfigError(f"min_pressure_change must lie in (0, 1], got {change!r}")

    def span_frames(self, sample_rate_hz: float) -> int:
        """Frames between the two compared frames (at least 1)."""
        return max(1, int(round(self.span_s * sample_rate_hz)))


_REGION_STRUCTURE = np.zeros((3, 3, 3), dtype=bool)
_REGION_STRUCTURE[1] = True  # 8 neighbours within a frame, never across frames


RELATIVE_FLOOR = 0.15
"""Share of a frame's peak below which a channel does not count toward the touch's
centroid, spread and total (see :func:`touch_features`)."""


def touch_features(
    signal: np.ndarray,
    active: np.ndarray,
    row_pitch_mm: float = DEFAULT_ROW_PITCH_MM,
    col_pitch_mm: float = DEFAULT_COL_PITCH_MM,
) -> np.ndarray:
    """``(N, 4)`` float64 per frame: total signal, centroid row and col (mm), spread (mm).

    Each channel weighs by how far its signal rises above :data:`RELATIVE_FLOOR` times
    the frame's peak, within the touch region (active channels and their 8 neighbours).
    The soft floor makes the measures continuous in the signal: on a dull, noisy skin
    the fingertips of a resting hand flicker across the contact threshold, and counting
    a channel fully or not at all made their centroid jump by tens of mm/s.  A frame
    without active channels has total 0 and centroid/spread 0.  Each frame's values
    depend on that frame alone.
    """
    n, rows, cols = signal.shape
    region = ndimage.binary_dilation(active, structure=_REGION_STRUCTURE)
    inside = np.where(region, np.maximum(signal, 0.0), 0.0).astype(np.float64)
    peak = inside.reshape(n, -1).max(axis=1)[:, None, None]
    weights = np.maximum(inside - RELATIVE_FLOOR * peak, 0.0)
    weights = weights.reshape(n, rows * cols)
    row_mm = np.repeat(np.arange(rows, dtype=np.float64) * row_pitch_mm, cols)
    col_mm = np.tile(np.arange(cols, dtype=np.float64) * col_pitch_mm, rows)
    total = weights.sum(axis=1)
    safe = np.where(total > 0, total, 1.0)
    r = (weights * row_mm).sum(axis=1) / safe
    c = (weights * col_mm).sum(axis=1) / safe
    second = (weights * (row_mm * row_mm + col_mm * col_mm)).sum(axis=1) / safe
    spread = np.sqrt(np.maximum(second - r * r - c * c, 0.0))
    return np.stack([total, r, c, spread], axis=1)


class PerformingDetector:
    """Frame-by-frame "fingers are being performed" flag (see the module doc)."""

    def __init__(self, sample_rate_hz: float, settings: PerformingSettings | None = None) -> None:
        _check_positive("sample_rate_hz", sample_rate_hz)
        self.settings = settings or PerformingSettings()
        self.sample_rate_hz = float(sample_rate_hz)
        self.span = self.settings.span_frames(sample_rate_hz)
        self._history = np.zeros((self.span, 4), dtype=np.float64)  # frames before the next

    def reset(self) -> None:
        """Forget the past frames (as if the skin had been untouched)."""
        self._history[:] = 0.0

    def update(self, signal: np.ndarray, active: np.ndarray) -> np.ndarray:
        """``(N,)`` bool flags for conditioned ``signal`` and ``active`` ``(N, R, C)``."""
        s = self.settings
        features = touch_features(signal, active, s.row_pitch_mm, s.col_pitch_mm)
        joined = np.concatenate([self._history, features])
        now, before = joined[self.span :], joined[: -self.span]
        self._history = joined[-self.span :].copy()
        elapsed = self.span / self.sample_rate_hz
        both = (now[:, 0] > 0) & (before[:, 0] > 0)
        either = (now[:, 0] > 0) | (before[:, 0] > 0)
        speed = np.hypot(now[:, 1] - before[:, 1], now[:, 2] - before[:, 2]) / elapsed
        spread_rate = np.abs(now[:, 3] - before[:, 3]) / elapsed
        larger = np.maximum(np.maximum(now[:, 0], before[:, 0]), np.finfo(np.float64).tiny)
        pressure_change = np.abs(now[:, 0] - before[:, 0]) / larger
        moving = both & ((speed >= s.min_speed_mm_s) | (spread_rate >= s.min_spread_rate_mm_s))
        return moving | (either & (pressure_change >= s.min_pressure_change))


def recognised_classes(
    probabilities: np.ndarray, class_names: tuple[str, ...], min_probability: float
) -> np.ndarray:
    """``(B,)`` index of the class each probability row recognises, :data:`NOTHING` if none."""
    probabilities = np.asarray(probabilities)
    best = np.argmax(probabilities, axis=1)
    top = probabilities[np.arange(len(best)), best]
    valid = np.array([name != INVALID for name in class_names], dtype=bool)
    ok = valid[best] & (top >= min_probability) & np.isfinite(top)
    return np.where(ok, best, NOTHING).astype(np.int64)


class Arbiter:
    """Applies the execution rules frame by frame (see the module doc)."""

    def __init__(
        self,
        class_names: tuple[str, ...] | list[str],
        sample_rate_hz: float,
        settings: ArbiterSettings | None = None,
    ) -> None:
        _check_positive("sample_rate_hz", sample_rate_hz)
        self.class_names = tuple(str(c) for c in class_names)
        if not self.class_names:
            raise ConfigError("the arbiter needs at least one class name")
        self.settings = settings or ArbiterSettings()
        self.sample_rate_hz = float(sample_rate_hz)
        self.dwell_frames = self.settings.dwell_frames(sample_rate_hz)
        self._frame = -1
        self._active = NOTHING
        self._candidate = NOTHING
        self._candidate_since = 0
        self._performing_since: int | None = None
        self._switches = 0
        self._suppressed = False
        self._last_performing: int | None = None
        self._start_frames = (
            None
            if self.settings.start_within_s is None
            else int(round(self.settings.start_within_s * self.sample_rate_hz))
        )

    @property
    def suppressed(self) -> bool:
        """True while the current touch has been judged erratic (until lift-off)."""
        return self._suppressed

    @property
    def active(self) -> str | None:
        """The active command, or None."""
        return None if self._active == NOTHING else self.class_names[self._active]

    @property
    def candidate(self) -> str | None:
        """The gesture recognised by every prediction since it first was, or None."""
        return None if self._candidate == NOTHING else self.class_names[self._candidate]

    @property
    def frames_seen(self) -> int:
        return self._frame + 1

    def step(
        self,
        t: float,
        touched: bool,
        performing: bool,
        probabilities: np.ndarray | None = None,
    ) -> CommandChange | None:
        """One frame; ``probabilities`` ``(K,)`` when the model ran on it. Returns a change."""
        recognised = None
        if probabilities is not None:
            row = np.asarray(probabilities, dtype=np.float64).reshape(1, -1)
            if row.shape[1] != len(self.class_names):
                raise ValueError(
                    f"expected {len(self.class_names)} class probabilities, got {row.shape[1]}"
                )
            recognised = int(
                recognised_classes(row, self.class_names, self.settings.min_probability)[0]
            )
        return self._step(float(t), bool(touched), bool(performing), recognised)

    def run(
        self,
        t: np.ndarray,
        touched: np.ndarray,
        performing: np.ndarray,
        predicted: np.ndarray,
        probabilities: np.ndarray,
    ) -> list[CommandChange]:
        """Many frames: ``(N,)`` times and flags, ``predicted`` ``(N,)`` bool marks the frames
        whose row of ``probabilities`` ``(N, K)`` is a fresh prediction."""
        t = np.asarray(t, dtype=np.float64)
        n = t.shape[0]
        touched = np.asarray(touched, dtype=bool)
        performing = np.asarray(performing, dtype=bool)
        predicted = np.asarray(predicted, dtype=bool)
        probabilities = np.asarray(probabilities)
        if touched.shape != (n,) or performing.shape != (n,) or predicted.shape != (n,):
            raise ValueError(
                f"t, touched, performing and predicted must all be shaped ({n},), got "
                f"{touched.shape}, {performing.shape}, {predicted.shape}"
            )
        if probabilities.shape != (n, len(self.class_names)):
            raise ValueError(
                f"probabilities must be shaped ({n}, {len(self.class_names)}), "
                f"got {probabilities.shape}"
            )
        recognised = np.full(n, NOTHING, dtype=np.int64)
        if predicted.any():
            recognised[predicted] = recognised_classes(
                probabilities[predicted], self.class_names, self.settings.min_probability
            )
        changes = []
        times = t.tolist()
        for ti, on, perf, pred, rec in zip(
            times,
            touched.tolist(),
            performing.tolist(),
            predicted.tolist(),
            recognised.tolist(),
            strict=True,
        ):
            change = self._step(ti, on, perf, rec if pred else None)
            if change is not None:
                changes.append(change)
        return changes

    def _step(
        self, t: float, touched: bool, performing: bool, recognised: int | None
    ) -> CommandChange | None:
        self._frame += 1
        i = self._frame
        if not touched:
            self._candidate = NOTHING
            self._performing_since = None
            self._switches = 0
            self._suppressed = False
            self._last_performing = None
            if self._active != NOTHING:
                self._active = NOTHING
                return CommandChange(t, None, LIFT_OFF)
            return None
        if not performing:
            self._performing_since = None
        else:
            self._last_performing = i
            if self._performing_since is None:
                self._performing_since = i
        if recognised is None or self._suppressed:
            return None
        if recognised != self._candidate:
            self._candidate = recognised
            self._candidate_since = i
        if self._candidate == NOTHING or self._candidate == self._active:
            return None
        if self._active == NOTHING:
            if self._start_frames is not None and (
                self._last_performing is None or i - self._last_performing > self._start_frames
            ):
                return None
            if i - self._candidate_since >= self.dwell_frames:
                self._active = self._candidate
                return CommandChange(t, self.class_names[self._active], DWELL)
            return None
        if self._performing_since is None:
            return None
        if i - max(self._candidate_since, self._performing_since) >= self.dwell_frames:
            limit = self.settings.max_switches
            if limit is not None and self._switches >= limit:
                self._active = NOTHING
                self._candidate = NOTHING
                self._suppressed = True
                return CommandChange(t, None, ERRATIC)
            self._switches += 1
            self._active = self._candidate
            return CommandChange(t, self.class_names[self._active], PREEMPT)
        return None
