"""Training windows from one conditioned recording: plain windows and the paper's augmentation.

Input: the conditioned ``signal`` ``(T, R, C)`` and debounced ``touched`` ``(T,)`` of one
recording (:func:`wovenskin.signal.conditioner.condition_recording`), and its labelled
events as frame spans (:class:`FrameEvents`, from :func:`events_to_frames`).  Output: a
:class:`WindowBatch` of fixed-length windows ``(N, W, R, C)`` (``W`` =
``WindowSettings.window_frames``, 30 by default, 150 ms at 200 Hz), one class label each,
and a code saying how each window was made (:data:`SOURCE_NAMES`).  Everything is counted
in frames of the recording's own rate.  All randomness comes from the
``numpy.random.Generator`` passed in, so a seed gives identical windows.

Definitions (``W`` window, ``m`` = ``min_segment_frames`` (10), ``p`` =
``max_partial_frames`` (8)):

- An event spans ``[start, stop)``: its first contact frame to one past its last lift-off;
  a gesture's ``start`` is then moved to the first frame the conditioning flags as
  touched (:func:`align_to_contact`: a light landing stays under the contact threshold
  for a while, and frames the skin did not sense should not count as gesture frames).
- Its *informative span* is ``[start, informative_stop)``: for a gesture whose motion end
  is known (simulated streams carry it), up to ``rest_context_frames`` (20, the 0.1 s
  moving average of the conditioning) after the motion ends, else the whole event.  A
  finger resting after a swipe belongs to the swipe (docs/gestures.md), so windows that *end*
  in the resting phase keep the gesture's label; but a window that shows nothing except a
  still finger is the same for every gesture (and for a push's hold), so windows must
  overlap the informative span by at least ``m`` frames.  Keeping the command through the
  rest of a long rest is the arbiter's job, not the classifier's.
- *Quiet* frames are contact-free: ``touched`` is false and the frame lies more than
  ``quiet_margin_frames`` (30) from every event (the hand hovering before a landing, the
  moving average and the fabric relaxing after a lift-off) and from the start of the
  recording (the filters filling up).  A *canvas* is ``W`` consecutive quiet frames: real
  background noise of the same skin (white noise, mains, drift, as the moving average
  shaped it), around 0.

Gesture windows (label = the event's class), balanced over the classes present (each
gets ``n // classes`` windows, the remainder going to randomly chosen classes), the event
drawn uniformly among that class's usable events:

- ``gesture_plain``: the ``W`` frames ending at a frame drawn uniformly from those ending
  inside the event and overlapping its informative span by at least ``m`` frames.  This
  is exactly what the live sliding window sees, onset, motion and rest included.
- ``gesture_overlay`` (share ``overlay_fraction``, 0.5): the paper's augmentation.  A
  segment of random length ``L`` in ``[m, min(W, event length)]`` is sliced from a random
  start inside the event (holding at least ``m`` informative frames) and *added* to a
  random canvas at a random position ``[0, W - L]``.  Adding keeps the canvas noise under
  the segment (whose own noise then reads ``sqrt(2)`` times stronger); the segment's ends
  are abrupt, which teaches the model to recognise a gesture from any part of it,
  wherever it sits in the window.

Invalid windows (label ``invalid``), from three sources mixed by ``invalid_mix``
(0.4, 0.25, 0.35); a source the recording cannot supply gives its share to the others:

- invalid touch events (palm, grasp, taps, brushing, noise bursts...): ``invalid_plain``,
  the ``W`` frames ending anywhere from the event's first frame to ``quiet_margin_frames``
  after it; or ``invalid_overlay`` (share ``invalid_overlay_fraction``, 0.5), a slice of
  any length ``[1, min(W, event length)]`` added to a canvas as above;
- ``idle``: a canvas alone (no contact: noise, drift, a relaxing fabric);
- partial contacts of valid gestures, too short to act on (the 0.1 s dwell is 20 frames
  at 200 Hz): ``partial_overlay`` (share ``invalid_overlay_fraction``), a slice of
  ``[1, p]`` frames from anywhere in a valid event added to a canvas (a blip); or
  ``partial_onset``, the ``W`` frames ending within the first ``p`` frames of a valid
  event (a gesture only just begun, indistinguishable from a tap: never act on it).

A window overlapping a gesture by ``p < k < m`` frames (9 with the defaults) is never
made: it is the deliberate margin between "too short" and "recognisable".  Windows ending
in the conditioned tail after a valid gesture's lift-off are not made either (lift-off
ends the command whatever the classifier says).  Plain windows need ``W - 1`` frames
before their last one, so an event that begins too early to allow that is skipped.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from wovenskin.training.window_settings import SOURCE_CODES, WindowSettings


@dataclass
class FrameEvents:
    """Labelled events of one recording as frame spans (see the module doc)."""

    labels: np.ndarray  # (K,) int64 class index
    start: np.ndarray  # (K,) int64 first contact frame
    stop: np.ndarray  # (K,) int64 one past the last lift-off frame
    informative_stop: np.ndarray  # (K,) int64 in [start, stop]

    def __post_init__(self) -> None:
        arrays = [np.asarray(a, dtype=np.int64) for a in (self.labels, self.start, self.stop)]
        self.labels, self.start, self.stop = arrays
        self.informative_stop = np.asarray(self.informative_stop, dtype=np.int64)
        k = self.labels.shape
        if len(k) != 1 or any(a.shape != k for a in (self.start, self.stop, self.informative_stop)):
            raise ValueError("event labels, starts, stops and informative stops must be (K,) each")
        if np.any(self.stop < self.start) or np.any(
            (self.informative_stop < self.start) | (self.informative_stop > self.stop)
        ):
            raise ValueError("events need start <= informative_stop <= stop")

    def __len__(self) -> int:
        return int(self.labels.size)


@dataclass
class WindowBatch:
    """Windows cut from one recording."""

    windows: np.ndarray  # (N, W, R, C) float32
    labels: np.ndarray  # (N,) int16 class index
    sources: np.ndarray  # (N,) int8 index into SOURCE_NAMES

    def __len__(self) -> int:
        return int(self.labels.size)


def events_to_frames(
    t: np.ndarray,
    start_s: np.ndarray,
    end_s: np.ndarray,
    labels: np.ndarray,
    motion_end_s: np.ndarray | None = None,
    rest_context_frames: int = 20,
) -> FrameEvents:
    """Events in seconds on the clock ``t`` -> :class:`FrameEvents`.

    ``start`` is the first frame at or after ``start_s``, ``stop`` one past the last frame
    at or before ``end_s``; ``labels`` are class indices.  ``motion_end_s`` (NaN where
    unknown) bounds the informative span at ``rest_context_frames`` past the motion's end.
    Events that cover no frame are kept with ``start == stop`` (they yield no window).
    """
    t = np.asarray(t, dtype=np.float64)
    start = np.searchsorted(t, np.asarray(start_s, dtype=np.float64), side="left")
    stop = np.searchsorted(t, np.asarray(end_s, dtype=np.float64), side="right")
    stop = np.maximum(stop, start)
    informative = stop.copy()
    if motion_end_s is not None:
        motion_end = np.asarray(motion_end_s, dtype=np.float64)
        known = np.isfinite(motion_end)
        after_motion = np.searchsorted(t, np.where(known, motion_end, 0.0), side="right")
        bounded = np.clip(after_motion + rest_context_frames, start, stop)
        informative = np.where(known, bounded, stop)
    return FrameEvents(np.asarray(labels, dtype=np.int64), start, stop, informative)


def align_to_contact(
    events: FrameEvents, touched: np.ndarray, invalid_label: int
) -> tuple[FrameEvents, np.ndarray]:
    """Start every gesture event at its first ``touched`` frame; also say which were seen.

    The labelled start is the physical first contact, but a light landing ramps in under
    the contact threshold (and through the 0.1 s moving average) for up to ~0.1 s: a
    window overlapping only that stretch looks like noise, whatever its label.  Counting
    a gesture's frames from the first frame the conditioning flags as touched makes "the
    first ``p`` frames" and "at least ``m`` frames" mean frames the skin actually sensed.
    Invalid events keep their labelled start (a noise burst never sets ``touched``).
    Returns the aligned events (all of them) and ``seen`` ``(K,)``: False for a gesture
    event with no touched frame at all (a missed trial), which should be dropped.
    """
    touched_at = np.flatnonzero(np.asarray(touched, dtype=bool))
    first = np.searchsorted(touched_at, events.start)
    onset = np.where(
        first < touched_at.size, touched_at[np.minimum(first, touched_at.size - 1)], events.stop
    )
    gesture = events.labels != invalid_label
    seen = ~gesture | (onset < events.stop)
    start = np.where(gesture & seen, onset, events.start)
    aligned = FrameEvents(
        events.labels.copy(),
        start,
        events.stop.copy(),
        np.clip(events.informative_stop, start, events.stop),
    )
    return aligned, seen


def quiet_frames(touched: np.ndarray, events: FrameEvents, margin: int) -> np.ndarray:
    """``(T,)`` bool: untouched, and more than ``margin`` frames from every event and the start."""
    touched = np.asarray(touched, dtype=bool)
    n = touched.size
    cover = np.zeros(n + 1, dtype=np.int64)
    lo = np.clip(events.start - margin, 0, n)
    hi = np.clip(events.stop + margin, 0, n)
    np.add.at(cover, lo, 1)
    np.add.at(cover, hi, -1)
    near_event = np.cumsum(cover[:n]) > 0
    quiet = ~touched & ~near_event
    quiet[: min(margin, n)] = False
    return quiet


def canvas_starts(quiet: np.ndarray, window_frames: int) -> np.ndarray:
    """First frames of every run of ``window_frames`` consecutive quiet frames."""
    quiet = np.asarray(quiet, dtype=bool)
    if quiet.size < window_frames:
        return np.zeros(0, dtype=np.int64)
    counts = np.concatenate(([0], np.cumsum(quiet, dtype=np.int64)))
    full = counts[window_frames:] - counts[:-window_frames] == window_frames
    return np.flatnonzero(full).astype(np.int64)


def gather_windows(signal: np.ndarray, ends: np.ndarray, window_frames: int) -> np.ndarray:
    """The ``window_frames`` frames ending at each of ``ends`` (inclusive): ``(N, W, R, C)``."""
    ends = np.asarray(ends, dtype=np.int64)
    if ends.size and (ends.min() < window_frames - 1 or ends.max() >= len(signal)):
        raise ValueError(
            f"window ends must lie in [{window_frames - 1}, {len(signal) - 1}], got "
            f"[{ends.min()}, {ends.max()}]"
        )
    index = ends[:, None] + np.arange(1 - window_frames, 1, dtype=np.int64)
    return np.asarray(signal[index], dtype=np.float32)


def overlay_windows(
    signal: np.ndarray,
    canvas: np.ndarray,
    segment_start: np.ndarray,
    segment_length: np.ndarray,
    position: np.ndarray,
    window_frames: int,
) -> np.ndarray:
    """Canvases ``signal[canvas : canvas + W]`` plus segments placed at ``position``.

    Segment ``i`` is ``signal[segment_start[i] : segment_start[i] + segment_length[i]]``,
    added to window frames ``position[i]`` onward; it must fit: ``position + length <= W``.
    """
    canvas = np.asarray(canvas, dtype=np.int64)
    segment_start = np.asarray(segment_start, dtype=np.int64)
    segment_length = np.asarray(segment_length, dtype=np.int64)
    position = np.asarray(position, dtype=np.int64)
    if canvas.size == 0:
        return np.zeros((0, window_frames, *signal.shape[1:]), dtype=np.float32)
    if np.any(position < 0) or np.any(position + segment_length > window_frames):
        raise ValueError("every overlaid segment must fit inside the window")
    if np.any(segment_start < 0) or np.any(segment_start + segment_length > len(signal)):
        raise ValueError("an overlaid segment reaches past the recording")
    frames = np.arange(window_frames, dtype=np.int64)
    out = np.asarray(signal[canvas[:, None] + frames], dtype=np.float32)
    offset = frames[None, :] - position[:, None]
    inside = (offset >= 0) & (offset < segment_length[:, None])
    source = np.where(inside, segment_start[:, None] + offset, 0)
    out += signal[source] * inside[:, :, None, None]
    return out


def sample_windows(
    signal: np.ndarray,
    touched: np.ndarray,
    events: FrameEvents,
    n_gesture: int,
    n_invalid: int,
    invalid_label: int,
    settings: WindowSettings,
    rng: np.random.Generator,
) -> WindowBatch:
    """``n_gesture`` gesture and ``n_invalid`` invalid windows of one recording (module doc).

    Windows come out gesture windows first, then invalid ones.  Raises ``ValueError`` when
    the recording cannot supply them (no usable gesture event, or no invalid source).
    """
    signal = np.asarray(signal)
    touched = np.asarray(touched, dtype=bool)
    if signal.ndim != 3 or touched.shape != signal.shape[:1]:
        raise ValueError(
            f"need signal (T, R, C) and touched (T,), got {signal.shape} and {touched.shape}"
        )
    if n_gesture < 0 or n_invalid < 0:
        raise ValueError("window counts must be >= 0")
    sampler = _Sampler(signal, touched, events, invalid_label, settings, rng)
    parts = [sampler.gesture_windows(n_gesture), sampler.invalid_windows(n_invalid)]
    batch = WindowBatch(
        windows=np.concatenate([p.windows for p in parts]),
        labels=np.concatenate([p.labels for p in parts]),
        sources=np.concatenate([p.sources for p in parts]),
    )
    if not np.all(np.isfinite(batch.windows)):
        raise ValueError("conditioned signal holds NaN or infinite values")
    return batch


class _Sampler:
    """Draws the windows of one recording; see :func:`sample_windows`."""

    def __init__(self, signal, touched, events, invalid_label, settings, rng) -> None:
        self.signal = signal
        self.events = events
        self.invalid_label = int(invalid_label)
        self.s = settings
        self.rng = rng
        self.n_frames = len(signal)
        self.canvases = canvas_starts(
            quiet_frames(touched, events, settings.quiet_margin_frames), settings.window_frames
        )
        self.shape = signal.shape[1:]

    # -- gestures ---------------------------------------------------------------------------
    def _gesture_ranges(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Usable gesture events and the range of their plain windows' last frame."""
        ev, s = self.events, self.s
        w, m = s.window_frames, s.min_segment_frames
        end_lo = np.maximum(ev.start + m - 1, w - 1)
        end_hi = np.minimum(ev.stop - 1, ev.informative_stop - 1 + w - m)
        usable = (
            (ev.labels != self.invalid_label)
            & (ev.informative_stop - ev.start >= m)
            & (end_lo <= end_hi)
        )
        return np.flatnonzero(usable), end_lo, end_hi

    def gesture_windows(self, n: int) -> WindowBatch:
        if n == 0:
            return self._empty()
        usable, end_lo, end_hi = self._gesture_ranges()
        if usable.size == 0:
            raise ValueError("the recording has no usable gesture event to cut windows from")
        ev, rng, s = self.events, self.rng, self.s
        w, m = s.window_frames, s.min_segment_frames
        classes = np.unique(ev.labels[usable])
        per_class = np.full(classes.size, n // classes.size, dtype=np.int64)
        per_class[rng.choice(classes.size, n % classes.size, replace=False)] += 1
        chosen = np.concatenate(
            [
                usable[ev.labels[usable] == c][
                    rng.integers(0, np.count_nonzero(ev.labels[usable] == c), size=k)
                ]
                for c, k in zip(classes, per_class, strict=True)
            ]
        )
        overlay = rng.random(n) < s.overlay_fraction if self.canvases.size else np.zeros(n, bool)
        ends = rng.integers(end_lo[chosen], end_hi[chosen] + 1)
        length = rng.integers(m, np.minimum(w, ev.stop[chosen] - ev.start[chosen]) + 1)
        start_hi = np.minimum(ev.stop[chosen] - length, ev.informative_stop[chosen] - m)
        seg_start = rng.integers(ev.start[chosen], start_hi + 1)
        position = rng.integers(0, w - length + 1)
        canvas = self._canvases(n)
        return self._assemble(
            ev.labels[chosen], overlay, ends, canvas, seg_start, length, position, "gesture"
        )

    # -- invalid ----------------------------------------------------------------------------
    def invalid_windows(self, n: int) -> WindowBatch:
        if n == 0:
            return self._empty()
        ev, s = self.events, self.s
        w, p = s.window_frames, s.max_partial_frames
        last = self.n_frames - 1
        is_invalid = (ev.labels == self.invalid_label) & (ev.stop > ev.start)
        inv_lo = np.maximum(ev.start, w - 1)
        inv_hi = np.minimum(ev.stop - 1 + s.quiet_margin_frames, last)
        invalid_events = np.flatnonzero(is_invalid & (inv_lo <= inv_hi))
        is_valid = (ev.labels != self.invalid_label) & (ev.stop > ev.start)
        onset_lo = np.maximum(ev.start, w - 1)
        onset_hi = np.minimum(ev.start + p - 1, ev.stop - 1)
        valid_events = np.flatnonzero(is_valid & (onset_lo <= onset_hi))
        available = np.array(
            [invalid_events.size > 0, self.canvases.size > 0, valid_events.size > 0]
        )
        weights = np.asarray(s.invalid_mix) * available
        if weights.sum() <= 0:
            raise ValueError(
                "the recording has no source of invalid windows (no invalid event, no "
                "contact-free stretch, no gesture to take partial contacts from)"
            )
        counts = self.rng.multinomial(n, weights / weights.sum())
        parts = [
            self._from_events(counts[0], invalid_events, inv_lo, inv_hi, w, "invalid"),
            self._idle(counts[1]),
            self._from_events(counts[2], valid_events, onset_lo, onset_hi, p, "partial"),
        ]
        return WindowBatch(
            windows=np.concatenate([b.windows for b in parts]),
            labels=np.concatenate([b.labels for b in parts]),
            sources=np.concatenate([b.sources for b in parts]),
        )

    def _from_events(self, n, candidates, end_lo, end_hi, max_length, kind) -> WindowBatch:
        """Invalid windows of ``kind`` ("invalid" or "partial") from ``candidates`` events."""
        if n == 0:
            return self._empty()
        ev, rng, w = self.events, self.rng, self.s.window_frames
        chosen = candidates[rng.integers(0, candidates.size, size=n)]
        share = self.s.invalid_overlay_fraction
        overlay = rng.random(n) < share if self.canvases.size else np.zeros(n, bool)
        ends = rng.integers(end_lo[chosen], end_hi[chosen] + 1)
        span = ev.stop[chosen] - ev.start[chosen]
        length = rng.integers(1, np.minimum(max_length, span) + 1)
        seg_start = rng.integers(ev.start[chosen], ev.stop[chosen] - length + 1)
        position = rng.integers(0, w - length + 1)
        canvas = self._canvases(n)
        labels = np.full(n, self.invalid_label, dtype=np.int64)
        return self._assemble(labels, overlay, ends, canvas, seg_start, length, position, kind)

    def _idle(self, n: int) -> WindowBatch:
        if n == 0:
            return self._empty()
        ends = self._canvases(n) + self.s.window_frames - 1
        return WindowBatch(
            windows=gather_windows(self.signal, ends, self.s.window_frames),
            labels=np.full(n, self.invalid_label, dtype=np.int16),
            sources=np.full(n, SOURCE_CODES["idle"], dtype=np.int8),
        )

    # -- helpers ----------------------------------------------------------------------------
    def _canvases(self, n: int) -> np.ndarray:
        if self.canvases.size == 0:
            return np.zeros(n, dtype=np.int64)
        return self.canvases[self.rng.integers(0, self.canvases.size, size=n)]

    def _assemble(self, labels, overlay, ends, canvas, seg_start, length, position, kind):
        """Windows in draw order: plain where ``overlay`` is false, overlays where true."""
        n, w = labels.size, self.s.window_frames
        windows = np.empty((n, w, *self.shape), dtype=np.float32)
        plain = ~overlay
        windows[plain] = gather_windows(self.signal, ends[plain], w)
        windows[overlay] = overlay_windows(
            self.signal, canvas[overlay], seg_start[overlay], length[overlay],
            position[overlay], w,
        )  # fmt: skip
        plain_name, overlay_name = {
            "gesture": ("gesture_plain", "gesture_overlay"),
            "invalid": ("invalid_plain", "invalid_overlay"),
            "partial": ("partial_onset", "partial_overlay"),
        }[kind]
        sources = np.where(overlay, SOURCE_CODES[overlay_name], SOURCE_CODES[plain_name])
        return WindowBatch(windows, labels.astype(np.int16), sources.astype(np.int8))

    def _empty(self) -> WindowBatch:
        return WindowBatch(
            windows=np.zeros((0, self.s.window_frames, *self.shape), dtype=np.float32),
            labels=np.zeros(0, dtype=np.int16),
            sources=np.zeros(0, dtype=np.int8),
        )
