"""The touch reader: which gesture the whole touch so far is, fused from the tracks and the network.

The paper's recogniser judges every 150 ms window alone.  :class:`TouchRecognizer` reads
the touch from its first contact to now instead, frame by frame and causally:

1. *Which gesture.*  The network's valid-class probabilities are averaged over every
   window of the touch so far (renormalised without ``invalid``): a window that sees a
   still finger says little, one that sees the motion says a lot, and the average keeps
   both.  To their logarithm the touch's geometry (:mod:`wovenskin.tracking.touch`) adds
   evidence the window cannot weigh: the direction of the coherent displacement for a
   swipe (``direction_mm``: the penalty for a direction off the displacement grows with
   the travel), the fingers' count from the blob's shape for one- against two-finger
   swipes and presses (``two_finger_sd_mm``), the sense of turning for a circle and the
   sign of the spread's change for a pinch.  The best-scoring gesture is the touch's
   reading.
2. *Whether it is happening.*  A reading counts only when the touch shows its motion:
   a swipe ``min_travel_mm`` of straight coherent travel that has hardly turned, a circle
   ``min_turn`` turns, a pinch ``min_spread_mm`` of spread change with the right fingers,
   a push the pressure risen ``press_ratio`` times over its least of the last 0.4 s
   (:class:`~wovenskin.tracking.touch.TouchSettings`' ``press_span_s``) with no travel, at
   least ``press_after_s`` into the touch (a landing ramps in faster; such a press also
   adds ``press_evidence`` to push's score).  And the network must have given the gesture
   at least ``net_peak`` (smoothed over ``net_smoothing_s``; ``press_net_peak`` for a push,
   which the window sees poorly) at some window of the touch: geometry alone never starts
   a command.  A blob wider
   than ``max_blob_sd_mm`` (a palm, a grasp, a forearm) is no one- or two-finger gesture.
3. *Keeping it.*  Once a reading counts it is kept while it stays the best-scoring
   gesture, unless a swipe's path loses its straightness (``keep_straightness``) or turns
   (``keep_turn``): a scribble or a circle that began as a stroke.

Each frame's reading is a probability row with the read gesture at 1 (``invalid`` at 1
when nothing counts), so the :mod:`~wovenskin.recognition.arbiter` applies the paper's
execution rules to it unchanged: 0.1 s of dwell, one command at a time, preemption while
the fingers are performed, lift-off ends it, flicks.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

from wovenskin.errors import ConfigError
from wovenskin.gestures import INVALID, SPECS
from wovenskin.tracking.touch import TouchReader, TouchSettings, TouchState
from wovenskin.tracking.tracker import Track

TOUCH = "touch"
WINDOW = "window"
READERS: tuple[str, ...] = (TOUCH, WINDOW)
"""The readers the live pipeline can run: the whole touch (this module) or the paper's
window by window."""

_ANGLE = {"up": -math.pi / 2, "down": math.pi / 2, "right": 0.0, "left": math.pi}
_FLOOR = 1e-4


@dataclass(frozen=True)
class ReaderSettings:
    """The touch reader's evidence and thresholds (see the module doc); mm, s, turns."""

    min_travel_mm: float = 6.0
    min_straightness: float = 0.8
    max_swipe_turn: float = 0.1  # turns (0.2 pi)
    keep_straightness: float = 0.7
    keep_turn: float = 0.15
    min_turn: float = 0.4
    min_spread_mm: float = 6.0
    five_finger_radius_mm: float = 18.0
    pinch_separation_mm: float = 30.0
    press_ratio: float = 1.3
    press_after_s: float = 0.15
    press_max_travel_mm: float = 4.0
    press_evidence: float = 4.0  # log units a press adds to push
    press_net_peak: float = 0.1  # the network's least peak for a push (it sees presses poorly)
    two_finger_sd_mm: float = 8.3
    finger_weight: float = 0.8  # evidence per mm of blob spread
    direction_mm: float = 5.0  # travel per unit of direction evidence
    max_blob_sd_mm: float = 14.5
    net_peak: float = 0.5
    net_smoothing_s: float = 0.05

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value >= 0):
                raise ConfigError(f"reader setting {f.name} must be a number >= 0, got {value!r}")
        for name in ("min_straightness", "keep_straightness", "net_peak"):
            if getattr(self, name) > 1:
                raise ConfigError(f"reader setting {name} must lie in [0, 1]")

    @classmethod
    def from_dict(cls, values: dict[str, Any] | None) -> ReaderSettings:
        """Settings from a checkpoint's ``reader`` object (unknown keys are ignored)."""
        known = {f.name for f in fields(cls)}
        return cls(**{k: v for k, v in (values or {}).items() if k in known})


def _finger_evidence(state: TouchState, s: ReaderSettings) -> float:
    """Evidence for two fingers over one (log units): the blob's length (clipped to +-3),
    plus 1 when two distinct peaks stayed together.  A blob split in two by its shape
    adds nothing more: its length already spoke, and a broad fingertip would count twice."""
    shape = s.finger_weight * (state.major_sd - s.two_finger_sd_mm)
    return float(np.clip(shape, -3.0, 3.0)) + (1.0 if state.sustained_peaks >= 2 else 0.0)


class TouchRecognizer:
    """Fuses the touch's geometry with the network's windows, frame by frame (module doc).

    ``class_names`` are the network's; gestures the vocabulary does not declare (a user's
    own) are read from the network alone.
    """

    def __init__(
        self,
        class_names: tuple[str, ...],
        rows: int,
        cols: int,
        row_pitch_mm: float,
        col_pitch_mm: float,
        sample_rate_hz: float,
        settings: ReaderSettings | None = None,
        touch: TouchSettings | None = None,
    ) -> None:
        self.class_names = tuple(class_names)
        if INVALID not in self.class_names:
            raise ConfigError(f"the touch reader needs an {INVALID!r} class")
        self.settings = settings or ReaderSettings()
        self.invalid = self.class_names.index(INVALID)
        self.valid = np.array([i for i, c in enumerate(self.class_names) if c != INVALID])
        self.specs = [SPECS.get(self.class_names[i]) for i in self.valid]
        self.touch = TouchReader(rows, cols, row_pitch_mm, col_pitch_mm, sample_rate_hz, touch)
        motions = np.array([None if spec is None else spec.motion for spec in self.specs])
        fingers = np.array([0 if spec is None else spec.fingers for spec in self.specs])
        self._kinds = {
            "swipe": motions == "swipe",
            "swipe1": (motions == "swipe") & (fingers == 1),
            "swipe2": (motions == "swipe") & (fingers == 2),
            "circle": motions == "circle",
            "press": motions == "press",
            "pinch": motions == "pinch",
        }
        self._angles = np.array(
            [_ANGLE.get(spec.direction, 0.0) if spec else 0.0 for spec in self.specs]
        )
        self._signs = np.array(
            [(-1.0 if spec.direction in ("ccw", "in") else 1.0) if spec else 0.0
             for spec in self.specs]
        )  # fmt: skip
        self._smooth = max(1, int(round(self.settings.net_smoothing_s * sample_rate_hz)))
        self.reset()

    def reset(self) -> None:
        """Forget the current touch."""
        self.touch.reset()
        self._sum = np.zeros(len(self.valid))
        self._count = 0
        self._recent: deque[np.ndarray] = deque()
        self._recent_sum = np.zeros(len(self.valid))
        self._peak = np.zeros(len(self.valid))
        self._invalid_sum = 0.0
        self._held: int | None = None
        self.reading: str | None = None
        self.state: TouchState | None = None

    def _score(self, st: TouchState) -> np.ndarray:
        """Each valid class's score (module doc, step 1): the log of the network's windows
        averaged over the touch (renormalised without ``invalid``) plus the geometry."""
        mean = self._sum / self._count
        return np.log(mean / max(float(mean.sum()), _FLOOR) + _FLOOR) + self._geometry(st)

    def _geometry(self, st: TouchState) -> np.ndarray:
        """Each valid class's log evidence from the touch's geometry (see the module doc)."""
        s, k = self.settings, self._kinds
        travel = st.travel
        kappa = min(travel / s.direction_mm, 6.0) if travel >= 3.0 else 0.0
        two = _finger_evidence(st, s)
        out = np.zeros(len(self.valid))
        if kappa:
            angle = math.atan2(st.dy, st.dx)
            out[k["swipe"]] += kappa * (np.cos(angle - self._angles[k["swipe"]]) - 1.0)
        out[k["swipe2"]] += min(0.0, two)
        out[k["swipe1"]] += min(0.0, -two)
        turns = st.turning / (2 * math.pi)
        if abs(turns) > 0.15:
            out[k["circle"]] += 4.0 * np.clip(self._signs[k["circle"]] * turns, -1.5, 1.5)
        press = -(max(0.0, travel - 5.0) / 3.0 + max(0.0, two))
        out[k["press"]] += press + (s.press_evidence if self._presses(st) else 0.0)
        out[k["pinch"]] += np.clip(self._signs[k["pinch"]] * st.spread_change / 4.0, -4.0, 4.0)
        return out

    def _presses(self, st: TouchState) -> bool:
        """The pressure rises with no travel, well after the landing."""
        s = self.settings
        return (
            st.press_ratio >= s.press_ratio
            and st.max_travel <= s.press_max_travel_mm
            and st.age_s >= s.press_after_s
        )

    def _shows(self, j: int, st: TouchState) -> bool:
        """The touch shows gesture ``j``'s motion (see the module doc)."""
        spec, s = self.specs[j], self.settings
        if spec is None:
            return True
        wide = st.major_sd > s.max_blob_sd_mm
        if spec.motion == "swipe":
            return (
                st.travel >= s.min_travel_mm
                and st.straightness >= s.min_straightness
                and abs(st.turning) < s.max_swipe_turn * 2 * math.pi
                and not wide
            )
        if spec.motion == "circle":
            fingers_fit = spec.fingers < 2 or _finger_evidence(st, s) > 0.0
            return abs(st.turning) >= s.min_turn * 2 * math.pi and fingers_fit and not wide
        if spec.motion == "press":
            return self._presses(st) and not wide
        if spec.fingers >= 5:
            return abs(st.spread_change) >= s.min_spread_mm and st.radius_max >= (
                s.five_finger_radius_mm
            )
        return (
            -st.spread_change >= s.min_spread_mm
            and st.sustained_fingertips >= 2
            and st.max_separation >= s.pinch_separation_mm
        )

    def _kept(self, j: int, st: TouchState) -> bool:
        spec, s = self.specs[j], self.settings
        if spec is None:
            return True
        if spec.motion == "swipe" and (
            st.straightness < s.keep_straightness or abs(st.turning) > s.keep_turn * 2 * math.pi
        ):
            return False
        return not (st.major_sd > s.max_blob_sd_mm and spec.fingers < 5)

    def step(
        self, frame: np.ndarray, active: np.ndarray, touched: bool, probabilities: np.ndarray
    ) -> np.ndarray:
        """One frame of the tracking signal, its active mask and ``touched`` flag, and the
        network's latest probabilities ``(K,)``; returns this frame's reading ``(K,)``."""
        row = np.zeros(len(self.class_names), dtype=np.float32)
        row[self.invalid] = 1.0
        st = self.touch.step(frame, active, touched)
        if st is None:
            if self._count:
                self.reset()
            return row
        self.state = st
        full = np.asarray(probabilities, dtype=np.float64)
        p = full[self.valid]
        self._invalid_sum += float(full[self.invalid])
        self._sum += p
        self._count += 1
        self._recent.append(p)
        self._recent_sum += p
        if len(self._recent) > self._smooth:
            self._recent_sum -= self._recent.popleft()
        self._peak = np.maximum(self._peak, self._recent_sum / len(self._recent))
        score = self._score(st)
        j = int(np.argmax(score))
        spec = self.specs[j]
        least = (
            self.settings.press_net_peak
            if spec is not None and spec.motion == "press"
            else self.settings.net_peak
        )
        if (j == self._held and self._kept(j, st)) or (
            self._shows(j, st) and self._peak[j] >= least
        ):
            self._held = j
            row[self.invalid] = 0.0
            row[self.valid[j]] = 1.0
            self.reading = self.class_names[self.valid[j]]
        else:
            self._held = None
            self.reading = None
        return row

    def evidence(self) -> np.ndarray | None:
        """``(K,)`` what the reader holds of the touch so far, as probabilities (``None``
        between touches): the valid classes' scores (the network's windows averaged over
        the touch, plus the geometry) softmaxed, scaled by one less ``invalid``'s share,
        which is 0 while a reading counts, else the touch's mean ``invalid`` probability.
        This is what the dashboard's bars show, not the latest window alone."""
        if not self._count or self.state is None:
            return None
        score = self._score(self.state)
        soft = np.exp(score - score.max())
        soft /= soft.sum()
        invalid = 0.0 if self.reading is not None else self._invalid_sum / self._count
        row = np.zeros(len(self.class_names), dtype=np.float32)
        row[self.valid] = (1.0 - invalid) * soft
        row[self.invalid] = invalid
        return row

    @property
    def tracks(self) -> list[Track]:
        """The live contact tracks of the current touch (empty between touches)."""
        return list(self.touch.tracker.tracks)

    def run(
        self,
        frames: np.ndarray,
        active: np.ndarray,
        touched: np.ndarray,
        probabilities: np.ndarray,
        after: Callable[[int], None] | None = None,
    ) -> np.ndarray:
        """Many frames: ``(N, R, C)`` tracking frames and masks, ``(N,)`` flags and ``(N, K)``
        network rows; returns ``(N, K)`` readings. ``after(i)`` runs after frame ``i``."""
        n = frames.shape[0]
        out = np.empty((n, len(self.class_names)), dtype=np.float32)
        flags = np.asarray(touched, dtype=bool).reshape(-1)
        for i in range(n):
            out[i] = self.step(frames[i], active[i], bool(flags[i]), probabilities[i])
            if after is not None:
                after(i)
        return out
