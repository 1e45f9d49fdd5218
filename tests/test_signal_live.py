"""Tests for wovenskin.signal.live: calibration with warning and retry, then conditioning."""

from __future__ import annotations

import numpy as np
import pytest
from signal_synth import SkinSpec, Touch, synth_stream

from wovenskin.signal.conditioner import ConditionedFrames, condition_recording
from wovenskin.signal.config import ConditioningConfig
from wovenskin.signal.live import LiveConditioner

CONFIG = ConditioningConfig()
RAW = synth_stream(
    3.0, [Touch(1.0, 2.0, 5.0, 2.0, to_col=7.0)], SkinSpec(crosstalk=0.02, seed=30)
).astype(np.float64)


def _feed(live: LiveConditioner, raw: np.ndarray, size: int) -> ConditionedFrames | None:
    outputs = [live.feed(raw[i : i + size]) for i in range(0, len(raw), size)]
    produced = [o for o in outputs if o is not None]
    return ConditionedFrames.concat(produced) if produced else None


@pytest.mark.parametrize("size", [1, 7, 100, 300])
def test_live_output_equals_the_recording_output_after_calibration(size):
    live = LiveConditioner(CONFIG, 10, 10)
    out = _feed(live, RAW, size)
    _, recording = condition_recording(RAW, CONFIG)
    assert live.state == "running" and live.calibration is not None and live.warnings == []
    assert out is not None and len(out) == len(RAW) - 100
    assert out.index[0] == 100
    for name in ("signal", "active", "touched", "n_contacts"):
        assert np.array_equal(getattr(out, name), getattr(recording, name)[100:]), name
    assert out.contacts == recording.contacts[100:]
    assert np.array_equal(out.baseline, recording.baseline)
    assert out.touched.any()


def test_nothing_is_returned_while_calibrating():
    live = LiveConditioner(CONFIG, 10, 10)
    assert live.feed(RAW[:99]) is None
    assert live.state == "calibrating" and live.calibration is None
    assert live.feed(RAW[99]) is None  # completes calibration, no frame left to condition
    assert live.state == "running"
    assert len(live.feed(RAW[100])) == 1


def test_touch_during_calibration_warns_and_retries():
    touched = synth_stream(0.5, [Touch(0.2, 0.5, 3.0, 4.0)], SkinSpec(seed=31))
    messages: list[str] = []
    live = LiveConditioner(CONFIG, 10, 10, on_warning=messages.append)
    assert live.feed(touched) is None
    assert live.state == "calibrating" and live.attempts == 1
    assert messages == live.warnings and len(messages) == 1
    assert "touch detected" in messages[0] and "near row 3, col 4" in messages[0]
    assert "retrying (1/3)" in messages[0]
    out = live.feed(RAW)  # a clean period follows, then conditioning
    assert live.state == "running" and live.calibration.ok and len(live.warnings) == 1
    assert out is not None and len(out) == len(RAW) - 100


def test_after_max_retries_the_calibration_is_accepted():
    spec = SkinSpec(seed=32)
    live = LiveConditioner(CONFIG, 10, 10, max_retries=2)
    for attempt in range(3):
        raw = synth_stream(0.5, [Touch(0.1 + 0.05 * attempt, 0.45, 6.0, 6.0)], spec)
        assert live.feed(raw) is None
    assert live.state == "running" and not live.calibration.ok
    assert len(live.warnings) == 3 and "accepting it after 2 retries" in live.warnings[-1]


def test_all_nan_calibration_warns_and_keeps_calibrating():
    live = LiveConditioner(CONFIG, 4, 4)
    assert live.feed(np.full((250, 4, 4), np.nan)) is None
    assert live.state == "calibrating"
    assert len(live.warnings) == 2 and "calibration failed" in live.warnings[0]


def test_dead_channels_are_reported_once():
    raw = RAW.copy()
    raw[:, 0, 0] = 5.0
    live = LiveConditioner(CONFIG, 10, 10)
    live.feed(raw)
    assert live.state == "running" and len(live.warnings) == 1
    assert "1 dead channel" in live.warnings[0]


def test_recalibrate_starts_over():
    clean = synth_stream(2.0, [], SkinSpec(seed=33))
    live = LiveConditioner(CONFIG, 10, 10)
    live.feed(clean[:150])
    assert live.state == "running"
    live.recalibrate()
    assert live.state == "calibrating" and live.calibration is None
    assert live.feed(clean[150:200]) is None
    out = live.feed(clean[200:300])
    assert live.state == "running" and out is not None and len(out) == 50
    assert out.index[0] == 100  # the new conditioner counts from its calibration period


def test_bad_shapes_and_settings_are_rejected():
    live = LiveConditioner(CONFIG, 6, 8)
    with pytest.raises(ValueError, match=r"\(N, 6, 8\)"):
        live.feed(np.zeros((10, 8, 6)))
    with pytest.raises(ValueError, match="max_retries"):
        LiveConditioner(CONFIG, 6, 8, max_retries=-1)
    with pytest.raises(ValueError, match="at least one row"):
        LiveConditioner(CONFIG, 0, 8)
