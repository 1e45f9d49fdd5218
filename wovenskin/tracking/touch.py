"""The touch so far: what the fingers on the skin have done since the first landed.

:class:`TouchReader` steps frame by frame (the short moving average of the conditioned
signal, its active mask, the debounced ``touched`` flag) and keeps, for the current touch
(first contact to lift-off), the measures a gesture is read from (:class:`TouchState`):

- *position and spread*: the strength-weighted centroid of the touch region (active
  channels grown by one, above a soft floor of 15 % of the frame's peak, as
  :func:`~wovenskin.recognition.performing.touch_features`) and its rms radius, in mm;
- *coherent motion*: the centroid's displacement summed over *steady* frames only, those
  whose total strength changes by less than ``steady_rate`` per second.  A finger landing
  or lifting beside another moves the centroid by half their distance in a few frames;
  those jumps are not motion (nor are the ``count_settle_s`` after the signal shows more
  peaks than ever before in the touch: a finger landing), and leaving them out is what
  lets two fingers that land one after the other swipe cleanly.  Beside the net
  displacement ``D`` it keeps the path length ``L`` in steps of at least
  ``path_step_mm`` (straightness ``|D| / L``: a finger rubbed back and forth has a long
  path and little displacement), the largest displacement so far, and the spread's
  change summed the same way (a pinch);
- *turning*: the signed angle the heading of the path's steps of ``turn_step_mm`` has
  turned through (the path sampled in space, not time, so a slow finger's jitter does not
  turn; a step that turns by more than ``max_step_turn_deg`` is a reversal, not part of a
  circle, and counts nothing): about 2 pi a turn for a circle, near 0 for a straight
  stroke.  Positive is clockwise as the user sees the
  skin (from +x toward +y, y pointing down);
- *pressure*: the total strength now against the least it was over the last
  ``press_span_s``, counting only frames at least ``press_settle_s`` into the touch (a
  press rises, slowly or quickly; a landed finger holds steady; the landing's own ramp is
  no press);
- *fingers*: the fingertips of :mod:`~wovenskin.tracking.fingertips` per frame, the most
  that were present together for ``sustain_s``, and the mean spread of the strongest blob
  along its major axis over steady frames (two fingertips side by side make one blob
  half their distance longer than one fingertip does);
- *size*: the most channels and blobs the touch has covered (a palm, a grasp);
- *tracks*: the fingertips followed with identities (:mod:`~wovenskin.tracking.tracker`).

Everything is causal; a frame without ``touched`` ends the touch and resets the state.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field

import numpy as np

from wovenskin.errors import ConfigError
from wovenskin.tracking.fingertips import (
    FingertipSettings,
    FrameContacts,
    find_fingertips,
    neighbourhood,
)
from wovenskin.tracking.tracker import ContactTracker, Track, TrackerSettings

RELATIVE_FLOOR = 0.15
"""Share of a frame's peak below which a channel does not count toward the touch's
centroid, spread and total (here and in
:func:`~wovenskin.recognition.performing.touch_features`)."""


@dataclass(frozen=True)
class TouchSettings:
    """How the touch's measures are taken (see the module doc)."""

    steady_rate: float = 30.0  # relative strength change per second still counted as steady
    path_step_mm: float = 2.0  # the path is measured in steps of at least this
    turn_step_mm: float = 5.0  # the heading is taken over steps of at least this
    max_step_turn_deg: float = 60.0  # a step turning more counts no turn (not a circle's)
    press_span_s: float = 0.4
    press_settle_s: float = 0.1
    sustain_s: float = 0.02
    settle_s: float = 0.02  # frames after the first contact left out of the blob spread
    count_settle_s: float = 0.03  # after more peaks than ever in the touch: not steady
    rebase_fingers: int = 2  # a rise of the sustained count up to this restarts the motion
    fingertips: FingertipSettings = field(default_factory=FingertipSettings)
    tracker: TrackerSettings = field(default_factory=TrackerSettings)

    def __post_init__(self) -> None:
        for name in (
            "steady_rate",
            "path_step_mm",
            "turn_step_mm",
            "max_step_turn_deg",
            "press_span_s",
        ):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
                raise ConfigError(f"{name} must be a positive number, got {value!r}")
        for name in ("sustain_s", "settle_s", "count_settle_s", "press_settle_s"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value >= 0):
                raise ConfigError(f"{name} must be a number >= 0, got {value!r}")


@dataclass
class TouchState:
    """The measures of the current touch (see the module doc); mm, seconds, radians."""

    frames: int = 0  # frames since the first contact (1 on that frame)
    age_s: float = 0.0
    y: float = 0.0  # centroid now
    x: float = 0.0
    radius: float = 0.0  # rms radius now
    strength: float = 0.0
    dy: float = 0.0  # coherent displacement since the first contact
    dx: float = 0.0
    path: float = 0.0  # coherent path length
    max_travel: float = 0.0  # largest |(dy, dx)| so far
    spread_change: float = 0.0  # coherent change of the rms radius
    radius_min: float = math.inf  # smallest / largest rms radius over steady frames
    radius_max: float = 0.0
    turning: float = 0.0  # signed, clockwise positive
    press_ratio: float = 1.0  # strength now / least over press_span_s (1 before)
    max_press_ratio: float = 1.0
    peak_strength: float = 0.0
    fingertips: int = 0  # fingertips now
    sustained_fingertips: int = 0  # most present together for sustain_s
    sustained_peaks: int = 0  # the same for distinct peaks (a blob split in two counts once)
    max_separation: float = 0.0  # largest distance between two fingertips so far
    separation: float = 0.0  # distance between the two farthest fingertips now
    major_sd: float = 0.0  # mean major-axis spread of the strongest blob, steady frames
    max_channels: int = 0
    max_blobs: int = 0
    contacts: FrameContacts | None = None
    tracks: list[Track] = field(default_factory=list)  # the fingertips' tracks now
    max_tracks: int = 0  # most tracks (merged ones too) present together

    @property
    def travel(self) -> float:
        return math.hypot(self.dy, self.dx)

    @property
    def straightness(self) -> float:
        """``|D| / L`` (1 for a straight stroke; 1 before any motion)."""
        return min(1.0, self.travel / self.path) if self.path > 0 else 1.0


class TouchReader:
    """Steps the touch's measures frame by frame (see the module doc)."""

    def __init__(
        self,
        rows: int,
        cols: int,
        row_pitch_mm: float,
        col_pitch_mm: float,
        sample_rate_hz: float,
        settings: TouchSettings | None = None,
    ) -> None:
        if rows < 1 or cols < 1:
            raise ConfigError(f"skin needs at least one row and column, got {rows}x{cols}")
        for name, value in (
            ("row_pitch_mm", row_pitch_mm),
            ("col_pitch_mm", col_pitch_mm),
            ("sample_rate_hz", sample_rate_hz),
        ):
            if not (math.isfinite(value) and value > 0):
                raise ConfigError(f"{name} must be a positive number, got {value!r}")
        self.shape = (int(rows), int(cols))
        self.pitches = (float(row_pitch_mm), float(col_pitch_mm))
        self.rate = float(sample_rate_hz)
        self.settings = settings or TouchSettings()
        s = self.settings
        self._press_span = max(1, int(round(s.press_span_s * self.rate)))
        self._press_settle = int(round(s.press_settle_s * self.rate))
        self._sustain = max(1, int(round(s.sustain_s * self.rate)))
        self._settle = int(round(s.settle_s * self.rate))
        self._settle_frames = int(round(s.count_settle_s * self.rate))
        self._max_turn = math.radians(s.max_step_turn_deg)
        self._steady_step = s.steady_rate / self.rate
        self._y_mm = np.arange(rows, dtype=np.float64)[:, None] * row_pitch_mm
        self._x_mm = np.arange(cols, dtype=np.float64)[None, :] * col_pitch_mm
        self.state = TouchState()
        self.tracker = ContactTracker(self.rate, self.settings.tracker)
        self.reset()

    def reset(self) -> None:
        """Forget the current touch."""
        self.state = TouchState()
        self.tracker.reset()
        self._prev: tuple[float, float, float, float] | None = None  # y, x, radius, strength
        self._strengths: deque[tuple[int, float]] = deque()  # running minimum (frame, strength)
        self._heading: tuple[float, float] | None = None
        self._runs: dict[int, int] = {}
        self._peak_run = 0  # frames in a row with two distinct peaks or more
        self._major_sum = 0.0
        self._major_n = 0
        self._most_peaks = 0
        self._anchor = (0.0, 0.0)
        self._turn_anchor = (0.0, 0.0)
        self._unsettled = 0

    def step(self, frame: np.ndarray, active: np.ndarray, touched: bool) -> TouchState | None:
        """One frame ``(R, C)`` of the tracking signal with its active mask; the touch's
        state after it, or ``None`` when nothing touches the skin."""
        if not touched:
            if self.state.frames:
                self.reset()
            return None
        st = self.state
        st.frames += 1
        st.age_s = (st.frames - 1) / self.rate
        frame = np.maximum(np.asarray(frame, dtype=np.float64), 0.0)
        region = neighbourhood(active, False, np.logical_or)
        inside = np.where(region, frame, 0.0)
        top = float(inside.max()) if inside.size else 0.0
        weights = np.maximum(inside - RELATIVE_FLOOR * top, 0.0)
        total = float(weights.sum())
        if total <= 0.0:
            self._press(0.0)
            st.contacts = None
            st.fingertips = 0
            st.tracks = self.tracker.step(None)
            self._prev = None
            return st
        y = float((weights * self._y_mm).sum() / total)
        x = float((weights * self._x_mm).sum() / total)
        second = float((weights * (self._y_mm**2 + self._x_mm**2)).sum() / total)
        radius = math.sqrt(max(second - y * y - x * x, 0.0))
        strength = float(inside[region].sum()) if region.any() else 0.0
        contacts = find_fingertips(
            frame, active, *self.pitches, self.settings.fingertips, region=region
        )
        steady = False
        if self._prev is not None:
            py, px, pr, ps = self._prev
            larger = max(strength, ps)
            steady = larger > 0 and abs(strength - ps) <= self._steady_step * larger
            if contacts.peak_count > self._most_peaks:  # a finger more than ever: landing
                self._unsettled = self._settle_frames
            elif self._unsettled > 0:
                self._unsettled -= 1
            steady = steady and self._unsettled == 0
            if steady:
                st.dy += y - py
                st.dx += x - px
                st.spread_change += radius - pr
                st.max_travel = max(st.max_travel, st.travel)
                ay, ax = self._anchor
                step = math.hypot(y - ay, x - ax)
                if step >= self.settings.path_step_mm:
                    st.path += step
                    self._anchor = (y, x)
                ty, tx = self._turn_anchor
                if math.hypot(y - ty, x - tx) >= self.settings.turn_step_mm:
                    self._turn(y - ty, x - tx)
                    self._turn_anchor = (y, x)
            else:  # a jump is no motion: the path's anchors move with it
                ay, ax = self._anchor
                self._anchor = (ay + y - py, ax + x - px)
                ty, tx = self._turn_anchor
                self._turn_anchor = (ty + y - py, tx + x - px)
        else:
            self._anchor = (y, x)
            self._turn_anchor = (y, x)
        if steady or self._prev is None:
            st.radius_min = min(st.radius_min, radius)
            st.radius_max = max(st.radius_max, radius)
        self._prev = (y, x, radius, strength)
        st.y, st.x, st.radius, st.strength = y, x, radius, strength
        st.peak_strength = max(st.peak_strength, strength)
        self._press(strength)
        st.contacts = contacts
        st.tracks = self.tracker.step(contacts)
        st.max_tracks = max(st.max_tracks, len(st.tracks))
        self._most_peaks = max(self._most_peaks, contacts.peak_count)
        before = st.sustained_fingertips
        self._fingers(contacts, steady)
        if before < st.sustained_fingertips <= self.settings.rebase_fingers and before:
            self._rebase(y, x)
        st.max_channels = max(st.max_channels, int(active.sum()))
        st.max_blobs = max(st.max_blobs, len(contacts.blobs))
        return st

    def _press(self, strength: float) -> None:
        """The pressure's rise: ``strength`` against the least over the span (module doc)."""
        st = self.state
        if st.frames <= self._press_settle:
            return
        window = self._strengths
        while window and window[-1][1] >= strength:
            window.pop()
        window.append((st.frames, strength))
        while window[0][0] <= st.frames - self._press_span:
            window.popleft()
        least = window[0][1]
        st.press_ratio = strength / least if least > 0 else 1.0
        st.max_press_ratio = max(st.max_press_ratio, st.press_ratio)

    def _rebase(self, y: float, x: float) -> None:
        """Restart the coherent motion here: a finger joined the touch, and what the
        centroid did while it landed is no motion of the fingers."""
        st = self.state
        st.dy = st.dx = st.path = st.max_travel = st.turning = 0.0
        self._anchor = self._turn_anchor = (y, x)
        self._heading = None

    def _turn(self, vy: float, vx: float) -> None:
        """Add the turn from the previous path step's heading to this step's ``(vy, vx)``."""
        if self._heading is not None:
            hy, hx = self._heading
            turn = math.atan2(hx * vy - hy * vx, hx * vx + hy * vy)
            if abs(turn) <= self._max_turn:  # a sharper turn is a reversal or jitter
                self.state.turning += turn
        self._heading = (vy, vx)

    def _fingers(self, contacts: FrameContacts, steady: bool) -> None:
        st = self.state
        n = len(contacts)
        st.fingertips = n
        for k in range(1, max(n, max(self._runs, default=0)) + 1):
            self._runs[k] = self._runs.get(k, 0) + 1 if n >= k else 0
            if self._runs[k] >= self._sustain:
                st.sustained_fingertips = max(st.sustained_fingertips, k)
        peaks = contacts.peak_count
        self._peak_run = self._peak_run + 1 if peaks >= 2 else 0
        if self._peak_run >= self._sustain:
            st.sustained_peaks = max(st.sustained_peaks, 2)
        elif peaks >= 1:
            st.sustained_peaks = max(st.sustained_peaks, 1)
        if n >= 2:
            dy = contacts.y[:, None] - contacts.y[None, :]
            dx = contacts.x[:, None] - contacts.x[None, :]
            st.separation = float(np.sqrt(dy * dy + dx * dx).max())
            st.max_separation = max(st.max_separation, st.separation)
        else:
            st.separation = 0.0
        if contacts.blobs and steady and st.frames > self._settle:
            self._major_sum += max(contacts.blobs, key=lambda b: b.strength).major_sd
            self._major_n += 1
            st.major_sd = self._major_sum / self._major_n
