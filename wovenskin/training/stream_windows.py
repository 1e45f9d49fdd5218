"""Training windows cut from a continuous stream and labelled by what each window shows.

The live recogniser slides a ``W``-frame window over the conditioned stream one frame at a
time, so it sees every phase of every touch: the hand hovering, the landing, the pause
before the motion, the characteristic motion, the fingers resting afterwards and the
lift-off.  This module (the ``stream`` recipe of :class:`~.window_settings.WindowSettings`) draws
training windows from exactly those positions and labels each one by its content:

- the gesture's class when the window holds at least ``min_motion_frames`` frames of the
  gesture's *characteristic span*: the motion (a swipe, circle or pinch) or the pressure
  rise (a push), shifted by ``motion_lag_frames`` for the delay of the conditioning's
  moving average (half its length);
- ``invalid`` (a *still* window) when the window holds none of it and starts at least
  ``motion_lag_frames`` after it ended, or ends before it began: the landing and the pause
  before the motion, and the fingers resting after it.  Such a window looks the same for
  every gesture (a resting finger is not a push), so no window may claim one; keeping the
  active command through a rest is the arbiter's job (``invalid`` never ends a command);
- windows in between (``0 < overlap < min_motion_frames`` at the motion's start, or the
  moving average's tail at its end) are ambiguous and never drawn.

Only windows whose last frame lies inside the event (first contact to last lift-off) are
drawn: after lift-off the arbiter ends the command whatever the model says.  Events
without a known characteristic span (recordings of real people carry only first contact
and lift-off) count everything after their first ``max_partial_frames`` touched frames
as characteristic, as the ``overlay`` recipe does.

Invalid windows mix three sources by :attr:`~.windows.WindowSettings.invalid_mix`
(events, idle, still): plain windows ending anywhere in an invalid touch or up to
``quiet_margin_frames`` after it (palms, grasps, taps, scribbles, noise bursts), contact-
free stretches, and the still windows above.  Gesture windows are balanced over the
classes present, uniformly over each class's labelled positions.
"""

from __future__ import annotations

import numpy as np

from wovenskin.training.window_settings import SOURCE_CODES, WindowSettings
from wovenskin.training.windows import (
    FrameEvents,
    WindowBatch,
    canvas_starts,
    gather_windows,
    quiet_frames,
)


def characteristic_spans(
    events: FrameEvents,
    motion_start: np.ndarray | None,
    motion_stop: np.ndarray | None,
    settings: WindowSettings,
) -> tuple[np.ndarray, np.ndarray]:
    """``(K,)`` first and one-past-last frame of each event's characteristic span.

    ``motion_start``/``motion_stop`` are frames of the stream (``-1`` where unknown); the
    span is shifted by ``motion_lag_frames`` and clipped to the event.  Unknown spans
    start ``max_partial_frames`` after the event's start and run to its informative stop.
    """
    lag = settings.motion_lag_frames
    start = events.start + settings.max_partial_frames
    stop = events.informative_stop.copy()
    if motion_start is not None and motion_stop is not None:
        ms = np.asarray(motion_start, dtype=np.int64)
        me = np.asarray(motion_stop, dtype=np.int64)
        known = (ms >= 0) & (me > ms)
        start = np.where(known, ms + lag, start)
        stop = np.where(known, me + lag, stop)
    start = np.clip(start, events.start, events.stop)
    stop = np.clip(stop, start, events.stop)
    return start, stop


def window_labels(
    events: FrameEvents,
    span_start: np.ndarray,
    span_stop: np.ndarray,
    invalid_label: int,
    settings: WindowSettings,
    n_frames: int,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Every labelled window end inside the valid events.

    Returns ``(ends, labels, event, still)``: the last frame of each window, its label
    (the event's class, or ``invalid_label`` for a still window), the event it belongs to
    and whether it is a still window.  Ambiguous windows are left out.
    """
    w, k, lag = settings.window_frames, settings.min_motion_frames, settings.motion_lag_frames
    ends, labels, owner, still = [], [], [], []
    for e in np.flatnonzero(events.labels != invalid_label):
        lo = max(int(events.start[e]), w - 1)
        hi = min(int(events.stop[e]), n_frames)
        if hi <= lo:
            continue
        end = np.arange(lo, hi, dtype=np.int64)
        first = end - w + 1
        cs, ce = int(span_start[e]), int(span_stop[e])
        overlap = np.clip(np.minimum(end + 1, ce) - np.maximum(first, cs), 0, None)
        shows = overlap >= k
        quiet = (overlap == 0) & ((end < cs) | (first >= ce + lag))
        keep = shows | quiet
        ends.append(end[keep])
        labels.append(np.where(shows[keep], events.labels[e], invalid_label))
        owner.append(np.full(int(keep.sum()), e, dtype=np.int64))
        still.append(quiet[keep])
    if not ends:
        empty = np.zeros(0, dtype=np.int64)
        return empty, empty, empty, np.zeros(0, dtype=bool)
    return (
        np.concatenate(ends),
        np.concatenate(labels).astype(np.int64),
        np.concatenate(owner),
        np.concatenate(still),
    )


def sample_stream_windows(
    signal: np.ndarray,
    touched: np.ndarray,
    events: FrameEvents,
    span_start: np.ndarray,
    span_stop: np.ndarray,
    n_gesture: int,
    n_invalid: int,
    invalid_label: int,
    settings: WindowSettings,
    rng: np.random.Generator,
    allowed: np.ndarray | None = None,
) -> WindowBatch:
    """``n_gesture`` gesture and ``n_invalid`` invalid plain windows (see the module doc).

    ``allowed`` ``(T,)`` bool, if given, says which frames may end a drawn window (e.g. only
    windows inside the trials ``wovenskin adapt`` trains on, none over its held-out ones).
    """
    w = settings.window_frames
    n_frames = len(signal)
    ends, labels, _, still = window_labels(
        events, span_start, span_stop, invalid_label, settings, n_frames
    )
    if allowed is not None:
        allowed = np.asarray(allowed, dtype=bool)
        if allowed.shape != (n_frames,):
            raise ValueError(f"allowed must be ({n_frames},) bool, got shape {allowed.shape}")
        keep = allowed[ends]
        ends, labels, still = ends[keep], labels[keep], still[keep]
    gesture = ~still
    parts_ends, parts_labels, parts_sources = [], [], []
    if n_gesture:
        classes = np.unique(labels[gesture])
        if classes.size == 0:
            raise ValueError("the recording has no usable gesture event to cut windows from")
        per_class = np.full(classes.size, n_gesture // classes.size, dtype=np.int64)
        per_class[rng.choice(classes.size, n_gesture % classes.size, replace=False)] += 1
        for c, count in zip(classes, per_class, strict=True):
            pool = np.flatnonzero(gesture & (labels == c))
            pick = pool[rng.integers(0, pool.size, size=count)]
            parts_ends.append(ends[pick])
            parts_labels.append(labels[pick])
            parts_sources.append(np.full(count, SOURCE_CODES["gesture_plain"]))
    if n_invalid:
        inv_ends, inv_sources = _invalid_ends(
            touched, events, ends[still], invalid_label, settings, rng, n_invalid, n_frames,
            allowed,
        )  # fmt: skip
        parts_ends.append(inv_ends)
        parts_labels.append(np.full(inv_ends.size, invalid_label))
        parts_sources.append(inv_sources)
    all_ends = np.concatenate(parts_ends) if parts_ends else np.zeros(0, dtype=np.int64)
    windows = gather_windows(signal, all_ends, w)
    if not np.all(np.isfinite(windows)):
        raise ValueError("conditioned signal holds NaN or infinite values")
    return WindowBatch(
        windows=windows,
        labels=np.concatenate(parts_labels).astype(np.int16),
        sources=np.concatenate(parts_sources).astype(np.int8),
    )


def _invalid_ends(
    touched: np.ndarray,
    events: FrameEvents,
    still_ends: np.ndarray,
    invalid_label: int,
    settings: WindowSettings,
    rng: np.random.Generator,
    n: int,
    n_frames: int,
    allowed: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Last frames of ``n`` invalid windows and their source codes (ends in ``allowed``)."""
    w = settings.window_frames
    spans = []
    for e in np.flatnonzero((events.labels == invalid_label) & (events.stop > events.start)):
        lo = max(int(events.start[e]), w - 1)
        hi = min(int(events.stop[e]) + settings.quiet_margin_frames, n_frames)
        if hi > lo:
            spans.append(np.arange(lo, hi, dtype=np.int64))
    event_ends = np.concatenate(spans) if spans else np.zeros(0, dtype=np.int64)
    canvases = canvas_starts(quiet_frames(touched, events, settings.quiet_margin_frames), w)
    idle_ends = canvases + w - 1
    pools = (event_ends, idle_ends, still_ends)
    if allowed is not None:
        pools = tuple(p[allowed[p]] for p in pools)
    weights = np.asarray(settings.invalid_mix) * np.array([p.size > 0 for p in pools])
    if weights.sum() <= 0:
        raise ValueError(
            "the recording has no source of invalid windows (no invalid event, no "
            "contact-free stretch, no still fingers)"
        )
    counts = rng.multinomial(n, weights / weights.sum())
    codes = (SOURCE_CODES["invalid_plain"], SOURCE_CODES["idle"], SOURCE_CODES["still"])
    out_ends, out_codes = [], []
    for pool, count, code in zip(pools, counts, codes, strict=True):
        if count:
            out_ends.append(pool[rng.integers(0, pool.size, size=count)])
            out_codes.append(np.full(count, code))
    return np.concatenate(out_ends), np.concatenate(out_codes)
