"""The execution rules of docs/gestures.md: from per-window class probabilities to commands.

Owns :class:`Arbiter` (which gesture is the active command, frame by frame) and
:class:`PerformingDetector` (whether the fingers on the skin are *being performed* --
moving or changing pressure -- or merely resting), with their settings.

Inputs, one value per conditioned frame: its time ``t`` (s), the conditioner's debounced
``touched`` flag, the ``performing`` flag of :class:`PerformingDetector`, and, on the
frames where the streaming recogniser ran the model, the class probabilities of the
window ending there (:mod:`~wovenskin.recognition.streaming`).

Rules (docs/gestures.md, "Execution rules" and the resting paragraph before them):

- With ``smoothing_s`` (``None``: off) every prediction's probabilities are first replaced
  by the mean of the touch's predictions of the last ``smoothing_s``
  (:mod:`~wovenskin.recognition.smoothing`); the rules below then read those rows.
- A prediction *recognises* class ``g`` when ``g`` is its most probable class, ``g`` is
  not ``invalid`` and its probability reaches ``min_probability``; otherwise it
  recognises nothing.  ``invalid`` and no contact never start an action.
- The *candidate* is the class recognised by every prediction since the frame
  ``candidate_since`` where it first was (any other prediction replaces or clears it).
  With ``keep_probability`` (``None``: ``min_probability``; never above it) a prediction
  that recognises nothing still *keeps* the candidate when the candidate is its most
  probable class with at least ``keep_probability``: a gesture must be recognised
  confidently to become the candidate, less confidently to stay one (hysteresis, the
  touch's history beside the 150 ms window).  A prediction of another valid gesture at
  ``min_probability`` still replaces it.
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
- Flicks (``flick_s``; ``None`` turns them off): a touch that lifts before any command
  started in it emits, on the lift's frame, ``CommandChange(t, g, "flick")`` immediately
  followed by ``CommandChange(t, None, "lift-off")`` -- a command that ends at once,
  which the control session turns into its smallest step -- when all of these hold:

  - the touch's latest *streak*, unbroken consecutive predictions whose most probable
    class is the valid gesture ``g`` with at least ``flick_probability`` (``None``:
    ``min_probability``; never below it), spans at least ``flick_s`` from its first to
    its last prediction (0.075 s: 16 predictions at every frame; the dwell needs 21);
  - its last prediction lies at most ``flick_gap_s`` (0.05 s) before the lift (the
    windows that see the finger leave may recognise nothing; a prediction of another
    gesture ends the streak);
  - the fingers were being performed within ``start_within_s`` of that prediction (as
    for a dwell: resting fingers start nothing);
  - the touch began at least ``flick_after_s`` (0.3 s) after the previous command ended:
    on a dull skin the contact flag can drop for a few frames in the middle of a gesture
    whose command just ended, and that fragment is no new gesture.

  A swipe lifted as soon as its motion ends (a flick) may give the model fewer
  confident windows than the dwell needs; its streak is what the touch showed.  The
  figures behind these defaults are in ``docs/benchmarks.md`` ("The window reader's
  smoothing and flick rules").

"Being performed" is :mod:`~wovenskin.recognition.performing`'s flag (its module doc has
the rule and its defaults); its names are re-exported here.

Everything is causal and carries its state between calls, so any split of the frames
into calls gives the same commands.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from wovenskin.errors import ConfigError
from wovenskin.gestures import INVALID
from wovenskin.recognition.performing import RELATIVE_FLOOR as RELATIVE_FLOOR
from wovenskin.recognition.performing import PerformingDetector as PerformingDetector
from wovenskin.recognition.performing import PerformingSettings as PerformingSettings
from wovenskin.recognition.performing import check_positive
from wovenskin.recognition.performing import touch_features as touch_features
from wovenskin.recognition.smoothing import ProbabilitySmoother

DWELL = "dwell"
PREEMPT = "preempt"
LIFT_OFF = "lift-off"
ERRATIC = "erratic"
FLICK = "flick"
REASONS: tuple[str, ...] = (DWELL, PREEMPT, LIFT_OFF, FLICK)
"""Why the active command changed, as :attr:`CommandChange.reason`."""

NOTHING = -1
"""Class index meaning "this prediction recognises no valid gesture"."""

FLICK_S = 0.075
"""Default shortest streak of the flick rule (see the module doc), in seconds."""

FLICK_GAP_S = 0.05
"""Default longest time from a flick's streak to the lift (see the module doc), in seconds."""

FLICK_PROBABILITY = 0.9
"""Default probability every prediction of a flick's streak reaches (see the module doc)."""

FLICK_AFTER_S = 0.3
"""Default shortest time from a command's end to the touch of a flick (see the module doc)."""


@dataclass(frozen=True)
class CommandChange:
    """From time ``t`` (stream clock, s) the active command is ``gesture`` (None: none)."""

    t: float
    gesture: str | None
    reason: str

    def to_dict(self) -> dict:
        return {"t": self.t, "gesture": self.gesture, "reason": self.reason}


@dataclass(frozen=True)
class ArbiterSettings:
    """Execution-rule settings (see the module doc)."""

    dwell_s: float = 0.1
    min_probability: float = 0.0
    keep_probability: float | None = None
    max_switches: int | None = 1
    start_within_s: float | None = 0.2
    flick_s: float | None = FLICK_S
    flick_gap_s: float = FLICK_GAP_S
    flick_probability: float | None = FLICK_PROBABILITY
    flick_after_s: float = FLICK_AFTER_S
    smoothing_s: float | None = None

    def __post_init__(self) -> None:
        check_positive("dwell_s", self.dwell_s)
        f = self.flick_s
        if f is not None and not (isinstance(f, int | float) and math.isfinite(f) and f >= 0):
            raise ConfigError(f"flick_s must be None or a number >= 0, got {f!r}")
        k = self.keep_probability
        if k is not None and not (isinstance(k, int | float) and 0.0 <= k <= 1.0):
            raise ConfigError(f"keep_probability must be None or lie in [0, 1], got {k!r}")
        q = self.flick_probability
        if q is not None and not (isinstance(q, int | float) and 0.0 <= q <= 1.0):
            raise ConfigError(f"flick_probability must be None or lie in [0, 1], got {q!r}")
        for name in ("flick_gap_s", "flick_after_s"):
            g = getattr(self, name)
            if not (isinstance(g, int | float) and math.isfinite(g) and g >= 0):
                raise ConfigError(f"{name} must be a number >= 0, got {g!r}")
        m = self.smoothing_s
        if m is not None and not (isinstance(m, int | float) and math.isfinite(m) and m > 0):
            raise ConfigError(f"smoothing_s must be None or a number > 0, got {m!r}")
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

    def flick_frames(self, sample_rate_hz: float) -> int | None:
        """The flick rule's shortest streak in frames (None: no flicks)."""
        return None if self.flick_s is None else int(round(self.flick_s * sample_rate_hz))

    def smoothing_frames(self, sample_rate_hz: float) -> int | None:
        """The smoothing time in frames (at least 1; None: no smoothing)."""
        s = self.smoothing_s
        return None if s is None else max(1, int(round(s * sample_rate_hz)))


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
        check_positive("sample_rate_hz", sample_rate_hz)
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
        self._flick_frames = self.settings.flick_frames(sample_rate_hz)
        smoothing = self.settings.smoothing_frames(sample_rate_hz)
        self._smoother = None if smoothing is None else ProbabilitySmoother(smoothing)
        keep = self.settings.keep_probability
        self._keep_probability = (
            self.settings.min_probability
            if keep is None
            else min(keep, self.settings.min_probability)
        )
        self._flick_probability = (
            self.settings.min_probability
            if self.settings.flick_probability is None
            else max(self.settings.flick_probability, self.settings.min_probability)
        )
        self._flick_gap = int(round(self.settings.flick_gap_s * sample_rate_hz))
        self._touching = False
        self._touch_start = 0  # first frame of the current touch
        self._ended_at: int | None = None  # frame of the latest command's end
        self._after_frames = int(round(self.settings.flick_after_s * sample_rate_hz))
        self._streak = NOTHING  # the flick rule's streak: its class, first and last frame
        self._streak_since = 0
        self._streak_last = 0
        self._streak_open = False  # the latest prediction recognised the streak's class
        self._streak_fresh = False  # fingers performed near the streak's last prediction
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
    ) -> list[CommandChange]:
        """One frame; ``probabilities`` ``(K,)`` when the model ran on it. Returns its changes
        (none, one, or a flick and its lift-off)."""
        row = None if probabilities is None else np.asarray(probabilities, dtype=np.float64)
        if row is not None and row.reshape(1, -1).shape[1] != len(self.class_names):
            raise ValueError(
                f"expected {len(self.class_names)} class probabilities, got {row.size}"
            )
        if self._smoother is not None:
            row = self._smoother.step(bool(touched), None if row is None else row.reshape(-1))
        if row is None:
            return self._step(float(t), bool(touched), bool(performing), None)
        row = row.reshape(1, -1)
        names = self.class_names
        recognised = int(recognised_classes(row, names, self.settings.min_probability)[0])
        strong = int(recognised_classes(row, names, self._flick_probability)[0])
        kept = int(recognised_classes(row, names, self._keep_probability)[0])
        return self._step(float(t), bool(touched), bool(performing), recognised, strong, kept)

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
        if self._smoother is not None:
            probabilities = self._smoother.run(touched, predicted, probabilities)
        recognised = np.full(n, NOTHING, dtype=np.int64)
        strong = np.full(n, NOTHING, dtype=np.int64)
        kept = np.full(n, NOTHING, dtype=np.int64)
        if predicted.any():
            rows = probabilities[predicted]
            names = self.class_names
            recognised[predicted] = recognised_classes(rows, names, self.settings.min_probability)
            strong[predicted] = recognised_classes(rows, names, self._flick_probability)
            kept[predicted] = recognised_classes(rows, names, self._keep_probability)
        changes = []
        for ti, on, perf, pred, rec, sure, keep in zip(
            t.tolist(),
            touched.tolist(),
            performing.tolist(),
            predicted.tolist(),
            recognised.tolist(),
            strong.tolist(),
            kept.tolist(),
            strict=True,
        ):
            if pred:
                changes.extend(self._step(ti, on, perf, rec, sure, keep))
            else:
                changes.extend(self._step(ti, on, perf, None))
        return changes

    def _step(
        self,
        t: float,
        touched: bool,
        performing: bool,
        recognised: int | None,
        strong: int = NOTHING,
        kept: int = NOTHING,
    ) -> list[CommandChange]:
        self._frame += 1
        i = self._frame
        if not touched:
            flick = self._flick(i) if self._touching else NOTHING
            self._touching = False
            self._candidate = NOTHING
            self._performing_since = None
            self._switches = 0
            self._suppressed = False
            self._last_performing = None
            self._streak = NOTHING
            self._streak_open = False
            if flick != NOTHING:
                self._ended_at = i
                gesture = self.class_names[flick]
                return [CommandChange(t, gesture, FLICK), CommandChange(t, None, LIFT_OFF)]
            if self._active != NOTHING:
                self._active = NOTHING
                self._ended_at = i
                return [CommandChange(t, None, LIFT_OFF)]
            return []
        if not self._touching:
            self._touch_start = i
        self._touching = True
        if not performing:
            self._performing_since = None
        else:
            self._last_performing = i
            if self._performing_since is None:
                self._performing_since = i
        if recognised is None or self._suppressed:
            return []
        self._track_streak(i, strong)
        change = self._decide(t, i, recognised, kept)
        return [] if change is None else [change]

    def _fresh(self, i: int) -> bool:
        """Fingers were being performed within ``start_within_s`` of frame ``i``."""
        if self._start_frames is None:
            return True
        return self._last_performing is not None and i - self._last_performing <= self._start_frames

    def _track_streak(self, i: int, recognised: int) -> None:
        """The flick rule's streak: unbroken predictions of one gesture (see the module doc)."""
        if recognised == NOTHING:
            self._streak_open = False
            return
        if not (self._streak_open and recognised == self._streak):
            self._streak = recognised
            self._streak_since = i
        self._streak_open = True
        self._streak_last = i
        self._streak_fresh = self._fresh(i)

    def _flick(self, i: int) -> int:
        """The gesture a lift at frame ``i`` flicks (:data:`NOTHING`: none)."""
        if self._flick_frames is None or self._active != NOTHING or self._suppressed:
            return NOTHING
        if self._streak == NOTHING or not self._streak_fresh:
            return NOTHING
        if self._ended_at is not None and self._touch_start - self._ended_at < self._after_frames:
            return NOTHING
        if self._streak_last - self._streak_since < self._flick_frames:
            return NOTHING
        if i - self._streak_last > self._flick_gap:
            return NOTHING
        return self._streak

    def _decide(self, t: float, i: int, recognised: int, kept: int) -> CommandChange | None:
        if recognised != self._candidate and not (
            recognised == NOTHING and kept == self._candidate
        ):
            self._candidate = recognised
            self._candidate_since = i
        if self._candidate == NOTHING or self._candidate == self._active:
            return None
        if self._active == NOTHING:
            if not self._fresh(i):
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
