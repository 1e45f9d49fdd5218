"""Tests of window extraction and the paper's augmentation (wovenskin.training.windows).

Most tests run on a synthetic recording whose channels record where every window frame
came from, so each window can be traced back to the recording frames it was made of:

- channel [0, 0] = frame number + 1 outside events, 0 inside;
- channel [0, 1] = frame number + 1 inside events, 0 outside;
- channel [1, 0] = class index + 1 inside events, 0 outside;
- channel [1, 1] = 0.

A canvas holds quiet frames only (outside events), so in an overlay window channel [0, 0]
shows the canvas frames and channel [0, 1] the pasted segment.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from wovenskin.training.capture_prep import capture_window_ends, capture_windows
from wovenskin.training.window_settings import SOURCE_CODES, WindowSettings
from wovenskin.training.windows import (
    FrameEvents,
    align_to_contact,
    canvas_starts,
    events_to_frames,
    gather_windows,
    overlay_windows,
    quiet_frames,
    sample_windows,
)

INVALID = 3  # class index of "invalid" in the synthetic recordings (classes 0, 1, 2 valid)
W = 30
SETTINGS = WindowSettings()


def traced_recording(events: list[tuple[int, int, int]], n_frames: int = 3000):
    """Signal, touched and FrameEvents for ``(label, start, stop)`` events (see module doc)."""
    t = np.arange(n_frames)
    signal = np.zeros((n_frames, 2, 2), dtype=np.float32)
    in_event = np.zeros(n_frames, dtype=bool)
    for label, start, stop in events:
        in_event[start:stop] = True
        signal[start:stop, 1, 0] = label + 1
    signal[:, 0, 0] = np.where(in_event, 0, t + 1)
    signal[:, 0, 1] = np.where(in_event, t + 1, 0)
    touched = in_event.copy()
    labels, starts, stops = (np.array(v) for v in zip(*events, strict=True))
    return signal, touched, FrameEvents(labels, starts, stops, stops)


EVENTS = [
    (0, 400, 520),
    (1, 700, 900),
    (INVALID, 1100, 1180),
    (2, 1400, 1700),
    (0, 1900, 2000),
    (INVALID, 2200, 2210),
    (1, 2500, 2650),
]


def event_of(frame: int, events: FrameEvents) -> int:
    hits = np.flatnonzero((events.start <= frame) & (frame < events.stop))
    assert hits.size == 1, f"frame {frame} is in {hits.size} events"
    return int(hits[0])


def check_plain(window: np.ndarray) -> np.ndarray:
    """The recording frame numbers of a plain window; they must be consecutive."""
    frames = (window[:, 0, 0] + window[:, 0, 1]).astype(np.int64) - 1
    assert np.all(np.diff(frames) == 1)
    return frames


def check_overlay(window: np.ndarray, quiet: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(canvas frames, segment frames) of an overlay window, checked for consistency."""
    canvas = window[:, 0, 0].astype(np.int64) - 1
    assert np.all(np.diff(canvas) == 1) and quiet[canvas].all()
    pasted = np.flatnonzero(window[:, 0, 1] > 0)
    assert pasted.size >= 1 and np.all(np.diff(pasted) == 1), "segment must be one run"
    segment = window[pasted, 0, 1].astype(np.int64) - 1
    assert np.all(np.diff(segment) == 1)
    return canvas, segment


@pytest.fixture(scope="module")
def traced():
    signal, touched, events = traced_recording(EVENTS)
    batch = sample_windows(
        signal, touched, events, 600, 400, INVALID, SETTINGS, np.random.default_rng(3)
    )
    return signal, touched, events, batch


# ---------------------------------------------------------------------------- settings


def test_settings_round_trip_and_validation():
    s = WindowSettings(window_frames=40, invalid_mix=(1, 0, 0))
    assert WindowSettings.from_dict(s.to_dict()) == s
    with pytest.raises(ValueError, match="max_partial_frames < min_segment_frames"):
        WindowSettings(min_segment_frames=8, max_partial_frames=8)
    with pytest.raises(ValueError, match="min_segment_frames <= window_frames"):
        WindowSettings(window_frames=9)
    with pytest.raises(ValueError, match="overlay_fraction"):
        WindowSettings(overlay_fraction=1.5)
    with pytest.raises(ValueError, match="invalid_mix"):
        WindowSettings(invalid_mix=(0, 0, 0))
    with pytest.raises(ValueError, match="bad window settings: unknown setting"):
        WindowSettings.from_dict({"window": 30})


# ---------------------------------------------------------------------------- events


def test_events_to_frames_uses_the_clock_and_motion_end():
    t = np.arange(1000) / 200.0
    ev = events_to_frames(
        t,
        start_s=[1.0, 2.0, 3.0],
        end_s=[1.5, 2.5, 3.0],
        labels=[0, 1, INVALID],
        motion_end_s=[1.2, np.nan, np.nan],
        rest_context_frames=20,
    )
    assert ev.start.tolist() == [200, 400, 600]
    assert ev.stop.tolist() == [301, 501, 601]  # one past the last frame at or before the end
    # motion ends at frame 240, informative until 20 frames later; unknown -> whole event
    assert ev.informative_stop.tolist() == [261, 501, 601]


def test_align_to_contact_moves_gestures_to_the_first_touched_frame():
    events = FrameEvents([0, INVALID, 1], [100, 300, 500], [200, 400, 600], [180, 400, 600])
    touched = np.zeros(1000, dtype=bool)
    touched[112:190] = True  # the gesture is sensed 12 frames after its labelled start
    touched[310:390] = True
    aligned, seen = align_to_contact(events, touched, INVALID)
    assert aligned.start.tolist() == [112, 300, 500]  # invalid keeps its labelled start
    assert seen.tolist() == [True, True, False]  # the last gesture was never sensed
    assert aligned.informative_stop.tolist() == [180, 400, 600]


def test_frame_events_validate():
    with pytest.raises(ValueError, match="start <= informative_stop <= stop"):
        FrameEvents([0], [10], [5], [5])


def test_quiet_frames_keep_a_margin_around_events_and_the_start():
    touched = np.zeros(400, dtype=bool)
    touched[350:360] = True  # contact outside any labelled event
    events = FrameEvents([0], [100], [150], [150])
    quiet = quiet_frames(touched, events, margin=30)
    expected = np.ones(400, dtype=bool)
    expected[:30] = False
    expected[70:180] = False
    expected[350:360] = False
    assert np.array_equal(quiet, expected)
    starts = canvas_starts(quiet, 30)
    assert starts.min() == 30 and starts.max() == 400 - 30
    assert 40 in starts and 41 not in starts  # frames 40..69 are the last fit before the event
    assert canvas_starts(np.ones(10, bool), 30).size == 0


# ---------------------------------------------------------------------------- assembly


def test_gather_windows_end_at_the_given_frames():
    signal = np.arange(100, dtype=np.float32).reshape(100, 1, 1)
    out = gather_windows(signal, np.array([29, 99]), 30)
    assert out.shape == (2, 30, 1, 1)
    assert out[0, :, 0, 0].tolist() == list(range(30))
    assert out[1, -1, 0, 0] == 99
    with pytest.raises(ValueError, match="window ends"):
        gather_windows(signal, np.array([28]), 30)


def test_overlay_adds_the_segment_to_the_canvas():
    signal = np.zeros((200, 1, 2), dtype=np.float32)
    signal[:, 0, 0] = 0.5  # canvas level
    signal[100:150, 0, 1] = np.arange(50)  # the gesture
    signal[100:150, 0, 0] = 0.0
    out = overlay_windows(
        signal, np.array([10]), np.array([110]), np.array([12]), np.array([5]), 30
    )
    assert np.all(out[0, :, 0, 0] == 0.5)  # canvas kept under the segment (added, not replaced)
    expected = np.zeros(30)
    expected[5:17] = np.arange(10, 22)
    assert np.array_equal(out[0, :, 0, 1], expected)
    with pytest.raises(ValueError, match="fit inside"):
        overlay_windows(signal, np.array([10]), np.array([110]), np.array([12]), np.array([20]), 30)


# ---------------------------------------------------------------------------- sampling


def test_counts_labels_and_class_balance(traced):
    _, _, _, batch = traced
    assert batch.windows.shape == (1000, W, 2, 2) and batch.windows.dtype == np.float32
    assert batch.labels.dtype == np.int16 and batch.sources.dtype == np.int8
    assert np.count_nonzero(batch.labels == INVALID) == 400
    per_class = np.bincount(batch.labels[:600], minlength=3)
    assert per_class.tolist() == [200, 200, 200]
    gesture_sources = {SOURCE_CODES["gesture_plain"], SOURCE_CODES["gesture_overlay"]}
    assert set(batch.sources[:600].tolist()) == gesture_sources
    share = np.mean(batch.sources[:600] == SOURCE_CODES["gesture_overlay"])
    assert 0.4 < share < 0.6
    invalid_sources = set(batch.sources[600:].tolist())
    assert invalid_sources == {
        SOURCE_CODES[k]
        for k in ("invalid_plain", "invalid_overlay", "idle", "partial_overlay", "partial_onset")
    }


def test_gesture_plain_windows_end_inside_their_event(traced):
    _, _, events, batch = traced
    m = SETTINGS.min_segment_frames
    for i in np.flatnonzero(batch.sources == SOURCE_CODES["gesture_plain"]):
        frames = check_plain(batch.windows[i])
        k = event_of(frames[-1], events)
        assert events.labels[k] == batch.labels[i]
        overlap = np.count_nonzero(frames >= events.start[k])
        assert overlap >= m


def test_gesture_overlays_paste_a_segment_of_the_event_on_quiet_noise(traced):
    _, touched, events, batch = traced
    quiet = quiet_frames(touched, events, SETTINGS.quiet_margin_frames)
    lengths = []
    for i in np.flatnonzero(batch.sources == SOURCE_CODES["gesture_overlay"]):
        _, segment = check_overlay(batch.windows[i], quiet)
        k = event_of(segment[0], events)
        assert events.stop[k] > segment[-1] and events.labels[k] == batch.labels[i]
        assert SETTINGS.min_segment_frames <= segment.size <= W
        lengths.append(segment.size)
    assert min(lengths) == SETTINGS.min_segment_frames and max(lengths) == W


def test_invalid_windows_follow_their_source_rules(traced):
    _, touched, events, batch = traced
    quiet = quiet_frames(touched, events, SETTINGS.quiet_margin_frames)
    p, margin = SETTINGS.max_partial_frames, SETTINGS.quiet_margin_frames
    for i in np.flatnonzero(batch.labels == INVALID):
        source, window = batch.sources[i], batch.windows[i]
        if source == SOURCE_CODES["idle"]:
            assert quiet[check_plain(window)].all()
        elif source == SOURCE_CODES["partial_onset"]:
            last = check_plain(window)[-1]
            k = event_of(last, events)
            assert events.labels[k] != INVALID and last - events.start[k] < p
        elif source == SOURCE_CODES["partial_overlay"]:
            _, segment = check_overlay(window, quiet)
            assert 1 <= segment.size <= p
            assert events.labels[event_of(segment[0], events)] != INVALID
        elif source == SOURCE_CODES["invalid_overlay"]:
            _, segment = check_overlay(window, quiet)
            assert events.labels[event_of(segment[0], events)] == INVALID
        else:
            assert source == SOURCE_CODES["invalid_plain"]
            last = check_plain(window)[-1]
            near = (events.labels == INVALID) & (events.start <= last)
            assert np.any(near & (last < events.stop + margin))


def test_informative_span_bounds_resting_windows():
    signal, touched, events = traced_recording([(0, 400, 800), (INVALID, 1200, 1260)])
    events.informative_stop[0] = 500  # the motion ends at 480; the rest is a still finger
    batch = sample_windows(
        signal, touched, events, 300, 0, INVALID, SETTINGS, np.random.default_rng(0)
    )
    m = SETTINGS.min_segment_frames
    for window, source in zip(batch.windows, batch.sources, strict=True):
        if source == SOURCE_CODES["gesture_plain"]:
            frames = check_plain(window)
            assert np.count_nonzero((frames >= 400) & (frames < 500)) >= m
        else:
            segment = window[window[:, 0, 1] > 0, 0, 1] - 1
            assert np.count_nonzero(segment < 500) >= m


def test_same_seed_same_windows_other_seed_others():
    signal, touched, events = traced_recording(EVENTS)

    def draw(seed: int):
        return sample_windows(
            signal, touched, events, 50, 20, INVALID, SETTINGS, np.random.default_rng(seed)
        )

    a, b, c = draw(7), draw(7), draw(8)
    assert np.array_equal(a.windows, b.windows) and np.array_equal(a.sources, b.sources)
    assert not np.array_equal(a.windows, c.windows)


def test_without_quiet_frames_there_are_no_overlays_and_no_idle_windows():
    signal, touched, events = traced_recording(EVENTS)
    touched[:] = True  # never contact-free: no canvas anywhere
    batch = sample_windows(
        signal, touched, events, 100, 100, INVALID, SETTINGS, np.random.default_rng(1)
    )
    used = set(batch.sources.tolist())
    assert used <= {SOURCE_CODES[k] for k in ("gesture_plain", "invalid_plain", "partial_onset")}
    assert np.count_nonzero(batch.labels == INVALID) == 100


def test_recordings_that_cannot_supply_windows_say_so():
    signal, touched, events = traced_recording([(INVALID, 400, 500)])
    rng = np.random.default_rng(0)
    with pytest.raises(ValueError, match="no usable gesture event"):
        sample_windows(signal, touched, events, 10, 0, INVALID, SETTINGS, rng)
    only_invalid = sample_windows(signal, touched, events, 0, 10, INVALID, SETTINGS, rng)
    assert np.all(only_invalid.labels == INVALID)
    touched[:] = True
    with pytest.raises(ValueError, match="no source of invalid windows"):
        no_invalid = FrameEvents([], [], [], [])
        sample_windows(signal, touched, no_invalid, 0, 5, INVALID, SETTINGS, rng)
    with pytest.raises(ValueError, match="need signal"):
        sample_windows(signal, touched[:-1], events, 1, 0, INVALID, SETTINGS, rng)
    bad = signal.copy()
    bad[:] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        sample_windows(bad, touched, events, 0, 3, INVALID, SETTINGS, rng)


@settings(max_examples=25, deadline=None)
@given(
    starts=st.lists(st.integers(40, 2800), min_size=1, max_size=6, unique=True),
    lengths=st.lists(st.integers(1, 200), min_size=6, max_size=6),
    labels=st.lists(st.integers(0, INVALID), min_size=6, max_size=6),
    seed=st.integers(0, 2**16),
)
def test_any_event_layout_gives_traceable_windows(starts, lengths, labels, seed):
    events, end = [], 0
    for start, length, label in zip(sorted(starts), lengths, labels, strict=False):
        start = max(start, end + 1)
        events.append((label, start, min(start + length, 2990)))
        end = events[-1][2]
    events = [e for e in events if e[2] > e[1]]
    if not events:
        return
    signal, touched, frame_events = traced_recording(events)
    rng = np.random.default_rng(seed)
    try:
        batch = sample_windows(signal, touched, frame_events, 40, 20, INVALID, SETTINGS, rng)
    except ValueError as exc:
        assert "no usable gesture event" in str(exc)
        return
    quiet = quiet_frames(touched, frame_events, SETTINGS.quiet_margin_frames)
    assert len(batch) == 60 and np.count_nonzero(batch.labels == INVALID) == 20
    for window, source, label in zip(batch.windows, batch.sources, batch.labels, strict=True):
        if source == SOURCE_CODES["gesture_overlay"]:
            _, segment = check_overlay(window, quiet)
            assert frame_events.labels[event_of(segment[0], frame_events)] == label != INVALID
        elif source == SOURCE_CODES["partial_overlay"]:
            _, segment = check_overlay(window, quiet)
            assert frame_events.labels[event_of(segment[0], frame_events)] != INVALID == label
        elif source == SOURCE_CODES["invalid_overlay"]:
            _, segment = check_overlay(window, quiet)
            assert frame_events.labels[event_of(segment[0], frame_events)] == INVALID == label
        else:
            last = check_plain(window)[-1]
            if source == SOURCE_CODES["gesture_plain"]:
                assert frame_events.labels[event_of(last, frame_events)] == label


# ---------------------------------------------------------------------------- captures


@settings(max_examples=60, deadline=None)
@given(length=st.integers(1, 400), window=st.integers(1, 60), stride=st.integers(1, 50))
def test_capture_windows_cover_every_frame_up_to_the_stride(length, window, stride):
    ends = capture_window_ends(length, window, stride)
    assert ends[-1] == length - 1 and np.all(np.diff(ends) > 0)
    covered = np.zeros(length, dtype=bool)
    for e in ends:
        covered[max(0, e - window + 1) : e + 1] = True
    assert covered.all() or stride > window
    if length > window:
        assert ends[0] == window - 1 and np.all(np.diff(ends)[:-1] == stride)


def test_capture_windows_pad_short_captures_in_front():
    frames = np.arange(1, 13, dtype=np.float32).reshape(12, 1, 1)
    out = capture_windows(frames, 5, 8, 4)
    assert out.shape == (1, 8, 1, 1)
    assert out[0, :, 0, 0].tolist() == [0, 0, 0, 1, 2, 3, 4, 5]
    full = capture_windows(frames, 12, 8, 2)
    assert [w[-1, 0, 0] for w in full] == [8, 10, 12]
    with pytest.raises(ValueError, match="length"):
        capture_windows(frames, 13, 8, 2)
