"""The independent generator (issue 23): custom gestures from their stroke scripts, several
streams of the same person and skin, and a skin of fixed or scaled gain -- with the default
streams unchanged."""

from __future__ import annotations

from collections import Counter

import numpy as np
import pytest
from paths import REPO

from wovenskin.control.mapping import ActionMapping
from wovenskin.custom_gestures import CustomGesture
from wovenskin.errors import ConfigError
from wovenskin.independent.skins import GAIN_RANGE, TYPICAL_GAIN, WEAK_GAIN
from wovenskin.independent.streams import (
    Request,
    gesture_stream,
    mixed_stream,
    person_of,
    render_stream,
    skin_of,
)
from wovenskin.recognition.event_scoring import motion_starts

EXAMPLE = REPO / "examples" / "custom_gestures.toml"
CUSTOM = ActionMapping.load(EXAMPLE).custom


def touches_seen(stream, event: int = 0) -> int:
    """How many separate touches one event shows on the skin: runs of frames where the
    total change of all channels exceeds a third of its peak (a strong skin, so that its
    noise and drift stay far below)."""
    start, end = stream.event_start_s[event], stream.event_end_s[event]
    fs = stream.sample_rate_hz
    frames = stream.frames.astype(float)
    idle = frames[: int(fs)].mean(axis=0)
    change = (frames / idle - 1.0).sum(axis=(1, 2))
    window = change[int(start * fs) - 5 : int(end * fs) + 5]
    above = window > window.max() / 3
    return int(np.sum(np.diff(above.astype(int)) == 1) + above[0])


def test_a_custom_gesture_is_rendered_from_its_strokes() -> None:
    for seed in range(3):
        stream = gesture_stream("double_tap", seed, custom=CUSTOM, gain=0.3)
        assert list(stream.event_labels) == ["double_tap"]
        event = stream.metadata["events"][0]
        assert event["kind"] == "custom" and event["params"]["strokes"] == 2
        assert 0.15 < stream.event_end_s[0] - stream.event_start_s[0] < 1.0
        assert touches_seen(stream) == 2  # two taps, the skin released between them
        assert stream.metadata["custom_gestures"]["double_tap"] == CUSTOM["double_tap"].to_dict()
        stroke = gesture_stream("l_stroke", seed, custom=list(CUSTOM.values()), gain=0.3)
        assert list(stroke.event_labels) == ["l_stroke"]
        assert np.isfinite(motion_starts(stroke)).all()  # latency counts from its motion
        assert touches_seen(stroke) == 1


def test_a_custom_gesture_needs_its_definition_and_strokes() -> None:
    with pytest.raises(ConfigError, match="unknown gesture 'double_tap'"):
        gesture_stream("double_tap", 0)
    with pytest.raises(ConfigError, match="no variant"):
        Request.parse("double_tap:flick", CUSTOM)
    wave = CustomGesture("wave", 1, "wave at the skin")
    with pytest.raises(ConfigError, match="'wave' has no strokes"):
        gesture_stream("wave", 0, custom=[wave])


def test_mixed_streams_take_custom_gestures_as_often_as_asked() -> None:
    stream = mixed_stream(90.0, 2, custom=CUSTOM, invalid_fraction=0.0)
    counts = Counter(stream.event_labels.tolist())
    built_in = [n for n in counts if n not in CUSTOM]
    assert counts["double_tap"] >= 2 and counts["l_stroke"] >= 2
    assert abs(counts["double_tap"] - np.mean([counts[n] for n in built_in])) <= 2
    twice = mixed_stream(90.0, 2, custom=CUSTOM, custom_rounds=3.0, invalid_fraction=0.0)
    many = Counter(twice.event_labels.tolist())
    assert many["double_tap"] + many["l_stroke"] > counts["double_tap"] + counts["l_stroke"]
    none = mixed_stream(30.0, 2, custom=CUSTOM, custom_rounds=0.0)
    assert not set(none.event_labels) & set(CUSTOM)
    with pytest.raises(ConfigError, match="custom_rounds"):
        mixed_stream(10.0, 2, custom=CUSTOM, custom_rounds=-1.0)


def test_streams_of_the_same_person_and_skin_differ_only_in_their_trials() -> None:
    a = mixed_stream(20.0, 5, person_seed=11, skin_seed=12)
    b = mixed_stream(20.0, 6, person_seed=11, skin_seed=12)
    assert a.metadata["person"] == b.metadata["person"] == person_of(11).to_dict()
    assert a.metadata["skin"] == b.metadata["skin"] == skin_of(12).to_dict()
    assert a.metadata["skin"] == mixed_stream(5.0, 12).metadata["skin"]
    assert list(a.event_labels) != list(b.event_labels) or not np.array_equal(a.frames, b.frames)
    idle_a, idle_b = a.frames[:100].astype(float), b.frames[:100].astype(float)
    assert not np.array_equal(idle_a, idle_b)  # each stream its own sensor noise
    np.testing.assert_allclose(idle_a.mean(axis=0), idle_b.mean(axis=0), rtol=0.01)  # one skin


def test_the_defaults_leave_a_stream_as_it_was() -> None:
    plain = render_stream(["swipe_up"], 7)
    same = render_stream(["swipe_up"], 7, person_seed=7, skin_seed=7, custom=None)
    np.testing.assert_array_equal(plain.frames, same.frames)
    assert plain.metadata["person"] == same.metadata["person"]
    assert "custom_gestures" not in plain.metadata and "gain" not in plain.metadata
    with_custom = mixed_stream(20.0, 3, custom=CUSTOM, custom_rounds=0.0)
    assert list(with_custom.event_labels) == list(mixed_stream(20.0, 3).event_labels)


def test_a_weak_skin_changes_a_fifth_of_a_typical_one() -> None:
    typical_gain, weak_gain = TYPICAL_GAIN, WEAK_GAIN
    assert typical_gain == pytest.approx(np.sqrt(GAIN_RANGE[0] * GAIN_RANGE[1]))
    assert weak_gain == pytest.approx(typical_gain / 5)

    def peak_change(stream) -> float:
        frames = stream.frames.astype(float)
        idle = frames[:100].mean(axis=0)
        return float(np.abs(frames / idle - 1.0).max())

    typical = gesture_stream("push", 4, gain=TYPICAL_GAIN)
    weak = gesture_stream("push", 4, gain=WEAK_GAIN)
    assert weak.metadata["skin"]["gain"] == pytest.approx(WEAK_GAIN)
    assert weak.metadata["gain"] == pytest.approx(WEAK_GAIN)
    ratio = peak_change(weak) / peak_change(typical)
    assert 0.15 < ratio < 0.25  # the same touch, a fifth of the change (plus noise)
    scaled = gesture_stream("push", 4, gain_scale=0.2)
    assert scaled.metadata["skin"]["gain"] == pytest.approx(0.2 * skin_of(4).gain)
    with pytest.raises(ConfigError, match="gain"):
        gesture_stream("push", 4, gain=-1.0)
