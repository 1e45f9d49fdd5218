"""Tests of wovenskin.training.stream_windows: windows labelled by what they show."""

import numpy as np
import pytest

from wovenskin.training.stream_windows import (
    characteristic_spans,
    sample_stream_windows,
    window_labels,
)
from wovenskin.training.window_settings import SOURCE_CODES, WindowSettings
from wovenskin.training.windows import FrameEvents

INVALID = 9
SETTINGS = WindowSettings(window_frames=30, min_motion_frames=6, motion_lag_frames=6)


def _events():
    # A swipe (class 0) touching frames 100..299 moving 140..200, an invalid touch 400..460.
    return FrameEvents(
        labels=np.array([0, INVALID]),
        start=np.array([100, 400]),
        stop=np.array([300, 460]),
        informative_stop=np.array([300, 460]),
    )


def test_spans_follow_the_motion_shifted_by_the_lag():
    start, stop = characteristic_spans(
        _events(), np.array([140, -1]), np.array([200, -1]), SETTINGS
    )
    assert start[0] == 146 and stop[0] == 206
    # Unknown motion: from max_partial_frames after the first contact to the informative stop.
    assert start[1] == 400 + SETTINGS.max_partial_frames and stop[1] == 460


def test_labels_gesture_only_while_the_motion_is_in_view():
    ev = _events()
    start, stop = characteristic_spans(ev, np.array([140, -1]), np.array([200, -1]), SETTINGS)
    ends, labels, owner, still = window_labels(ev, start, stop, INVALID, SETTINGS, 1000)
    assert (owner == 0).all()  # invalid events are not labelled here
    by_end = dict(zip(ends.tolist(), labels.tolist(), strict=True))
    k = SETTINGS.min_motion_frames
    # Landing and pause before the motion: still (invalid).
    assert by_end[120] == INVALID and by_end[145] == INVALID
    # Fewer than k motion frames in view: ambiguous, never drawn.
    assert 146 + k - 2 not in by_end
    # k frames of motion in view: the gesture.
    assert by_end[146 + k - 1] == 0
    assert by_end[229] == 0 and 230 not in by_end  # the last window with k motion frames
    # The window has left the motion (and the moving average's tail): resting, invalid.
    first_still_end = 206 + SETTINGS.motion_lag_frames + 29
    assert by_end[first_still_end] == INVALID
    assert first_still_end - 1 not in by_end
    assert by_end[299] == INVALID
    assert 300 not in by_end  # after lift-off: never drawn
    assert still[labels == INVALID].all() and not still[labels == 0].any()


def test_sample_stream_windows_balances_and_mixes_sources():
    rng = np.random.default_rng(0)
    n = 1000
    signal = rng.normal(0, 1e-4, (n, 4, 5)).astype(np.float32)
    touched = np.zeros(n, dtype=bool)
    touched[100:300] = True
    touched[400:460] = True
    ev = _events()
    start, stop = characteristic_spans(ev, np.array([140, -1]), np.array([200, -1]), SETTINGS)
    batch = sample_stream_windows(signal, touched, ev, start, stop, 50, 40, INVALID, SETTINGS, rng)
    assert batch.windows.shape == (90, 30, 4, 5)
    assert (batch.labels[:50] == 0).all() and (batch.labels[50:] == INVALID).all()
    sources = set(batch.sources[50:].tolist())
    assert sources <= {SOURCE_CODES["invalid_plain"], SOURCE_CODES["idle"], SOURCE_CODES["still"]}
    assert len(sources) >= 2
    # A window is the signal itself, not a mix: its frames are consecutive stream frames.
    end = None
    for i in range(n - 30):
        if np.array_equal(batch.windows[0][0], signal[i]):
            end = i + 29
            break
    assert end is not None and np.array_equal(batch.windows[0], signal[end - 29 : end + 1])


def test_refuses_a_recording_without_gestures():
    ev = FrameEvents(np.array([INVALID]), np.array([10]), np.array([50]), np.array([50]))
    start, stop = characteristic_spans(ev, None, None, SETTINGS)
    with pytest.raises(ValueError, match="no usable gesture"):
        sample_stream_windows(
            np.zeros((100, 2, 2), np.float32), np.zeros(100, bool), ev, start, stop, 5, 0,
            INVALID, SETTINGS, np.random.default_rng(0),
        )  # fmt: skip


def test_settings_recipes_and_legacy_dicts():
    assert WindowSettings().recipe == "stream"
    assert WindowSettings.from_dict({"window_frames": 30}).recipe == "overlay"
    assert WindowSettings.from_dict({}).recipe == "stream"
    with pytest.raises(ValueError, match="recipe"):
        WindowSettings(recipe="magic")
    with pytest.raises(ValueError, match="min_motion_frames"):
        WindowSettings(min_motion_frames=0)
