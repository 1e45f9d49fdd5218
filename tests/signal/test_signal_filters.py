"""Tests for wovenskin.signal.filters: moving average, spike and glitch filters, hold."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from wovenskin.signal.filters import (
    CausalMovingAverage,
    SpikeFilter,
    StepGlitchFilter,
    hold_last_good,
    median_of_three,
)


def _naive_trailing_mean(x: np.ndarray, window: int) -> np.ndarray:
    padded = np.concatenate([np.zeros((window - 1, *x.shape[1:])), x])
    return np.stack([padded[i : i + window].mean(axis=0) for i in range(len(x))])


def _chunks(n: int, sizes: list[int]) -> list[tuple[int, int]]:
    out, pos, k = [], 0, 0
    while pos < n:
        size = sizes[k % len(sizes)]
        out.append((pos, min(n, pos + size)))
        pos, k = pos + size, k + 1
    return out


@pytest.mark.parametrize("window", [1, 4, 20])
def test_matches_a_naive_trailing_mean(window):
    x = np.random.default_rng(window).normal(size=(137, 3, 4))
    smoothed = CausalMovingAverage(window, (3, 4)).apply(x)
    np.testing.assert_allclose(smoothed, _naive_trailing_mean(x, window), atol=1e-12)


def test_step_response_ramps_over_the_window():
    x = np.zeros((30, 1, 1))
    x[10:] = 1.0
    smoothed = CausalMovingAverage(5, (1, 1)).apply(x)[:, 0, 0]
    np.testing.assert_allclose(smoothed[9:16], [0, 0.2, 0.4, 0.6, 0.8, 1.0, 1.0])


@settings(max_examples=30, deadline=None, derandomize=True)
@given(
    window=st.integers(1, 25),
    sizes=st.lists(st.integers(1, 60), min_size=1, max_size=8),
)
def test_any_chunking_is_bit_identical(window, sizes):
    x = np.random.default_rng(0).normal(size=(300, 2, 3))
    whole = CausalMovingAverage(window, (2, 3)).apply(x)
    streaming = CausalMovingAverage(window, (2, 3))
    parts = [streaming.apply(x[a:b]) for a, b in _chunks(len(x), sizes)]
    assert np.array_equal(np.concatenate(parts), whole)


def test_reset_forgets_the_history_and_empty_input_is_fine():
    average = CausalMovingAverage(3, (1, 1))
    first = average.apply(np.ones((5, 1, 1)))
    assert average.apply(np.zeros((0, 1, 1))).shape == (0, 1, 1)
    average.reset()
    assert np.array_equal(average.apply(np.ones((5, 1, 1))), first)


def test_window_must_be_positive():
    with pytest.raises(ValueError, match="at least 1 frame"):
        CausalMovingAverage(0, (2, 2))


def test_hold_last_good_fills_forward_from_the_carried_value():
    x = np.array([[1.0, 10.0], [np.nan, 20.0], [3.0, np.inf], [np.nan, np.nan]]).reshape(4, 1, 2)
    bad = ~np.isfinite(x)
    bad[0, 0, 1] = True  # first sample of channel 1 is bad too: use the carried value
    filled = hold_last_good(x, bad, np.array([[-1.0, -2.0]]))
    assert filled[:, 0, 0].tolist() == [1.0, 1.0, 3.0, 3.0]
    assert filled[:, 0, 1].tolist() == [-2.0, 20.0, 20.0, 20.0]
    assert np.isnan(x[1, 0, 0])  # input untouched


def test_median_of_three_is_the_middle_value():
    a, b, c = np.array([1.0, 5.0, 3.0]), np.array([2.0, 4.0, 9.0]), np.array([3.0, 6.0, 1.0])
    assert median_of_three(a, b, c).tolist() == [2.0, 5.0, 3.0]


def test_spike_filter_removes_one_frame_spikes_and_delays_steps_by_one_frame():
    x = np.zeros((12, 1, 2))
    x[4, 0, 0] = 9.0  # one-frame spike
    x[6:, 0, 1] = 1.0  # step
    out = SpikeFilter(np.zeros((1, 2))).apply(x)
    assert (out[:, 0, 0] == 0.0).all()
    assert out[:, 0, 1].tolist() == [0.0] * 7 + [1.0] * 5


def test_spike_filter_starts_from_the_given_level_and_chunks_exactly():
    rng = np.random.default_rng(7)
    x = 10.0 + rng.normal(size=(50, 2, 2))
    whole = SpikeFilter(np.full((2, 2), 10.0)).apply(x)
    assert np.array_equal(whole[0], np.full((2, 2), 10.0))  # median(10, 10, x0)
    streaming = SpikeFilter(np.full((2, 2), 10.0))
    parts = [streaming.apply(x[a:b]) for a, b in _chunks(50, [1, 3, 7, 2])]
    assert np.array_equal(np.concatenate(parts), whole)
    streaming.reset()
    assert np.array_equal(streaming.apply(x), whole)


# -- glitch pulses ------------------------------------------------------------------------
GLITCH_SHAPE = (5, 5)
LEVEL = 20.0


def _quiet_skin(n: int, seed: int = 0) -> np.ndarray:
    """Raw frames at 20 pF with 0.01 % white noise."""
    rng = np.random.default_rng(seed)
    return LEVEL * (1.0 + 1e-4 * rng.standard_normal((n, *GLITCH_SHAPE)))


def _glitch_filter(max_frames: int = 25) -> StepGlitchFilter:
    threshold = np.full(GLITCH_SHAPE, LEVEL * 0.002)
    return StepGlitchFilter(threshold, np.full(GLITCH_SHAPE, LEVEL), max_frames)


def _both_filters(x: np.ndarray, glitches: StepGlitchFilter) -> np.ndarray:
    """The conditioner's order: glitch pulses first, then the median of three."""
    return SpikeFilter(np.full(GLITCH_SHAPE, LEVEL)).apply(glitches.apply(x))


@pytest.mark.parametrize("width", [2, 3, 13, 20])
def test_a_firmware_smeared_glitch_pulse_is_removed_without_latency(width):
    x = _quiet_skin(100)
    x[40 : 40 + width, 2, 3] += 1.0  # +5 % for `width` frames: a glitch after a W-average
    out = _both_filters(x, _glitch_filter())
    assert np.abs(out[:, 2, 3] / LEVEL - 1).max() < 2e-3  # gone, edge frames included
    clean = _both_filters(_quiet_skin(100), _glitch_filter())
    others = np.ones(GLITCH_SHAPE, bool)
    others[2, 3] = False
    assert np.array_equal(out[:, others], clean[:, others])


def test_a_one_frame_spike_is_left_to_the_median_and_starts_nothing():
    x = _quiet_skin(60)
    x[30, 1, 1] += 2.0
    x[45, 3, 3] -= 2.0
    glitches = _glitch_filter()
    filtered = glitches.apply(x)
    assert glitches.pulses == 0
    np.testing.assert_array_equal(filtered, x)  # nothing to do for this filter


def test_a_finger_landing_or_a_burst_on_a_line_passes_untouched():
    x = _quiet_skin(80)
    ramp = np.clip((np.arange(80) - 30) / 4.0, 0.0, 1.0)  # lands over 4 frames
    x[:, 2, 2] += 2.0 * ramp
    x[:, 2, 1] += 0.6 * ramp
    x[50:56, 4, :] += 0.8  # a burst steps a whole row at once
    glitches = _glitch_filter()
    np.testing.assert_array_equal(glitches.apply(x), x)


def test_a_lasting_one_channel_step_passes_after_max_frames():
    x = _quiet_skin(80)
    x[20:, 0, 0] += 1.0
    out = _glitch_filter(max_frames=10).apply(x)[:, 0, 0] - LEVEL
    assert np.abs(out[21:31]).max() < 0.01  # taken for a glitch for 10 frames
    np.testing.assert_allclose(out[32:], 1.0, atol=0.01)  # then it is a step after all


@settings(max_examples=25, deadline=None, derandomize=True)
@given(sizes=st.lists(st.integers(1, 30), min_size=1, max_size=6))
def test_glitch_filter_gives_the_same_result_for_any_chunking(sizes):
    x = _quiet_skin(240, seed=3)
    for start, width, row, col in ((20, 13, 1, 1), (60, 2, 3, 4), (61, 5, 0, 0), (200, 30, 2, 2)):
        x[start : start + width, row, col] += 1.5
    whole = _glitch_filter().apply(x)
    streaming = _glitch_filter()
    parts = [streaming.apply(x[a:b]) for a, b in _chunks(len(x), sizes)]
    assert np.array_equal(np.concatenate(parts), whole)


def test_glitch_filter_rejects_bad_settings():
    level = np.full((2, 2), 10.0)
    with pytest.raises(ValueError, match="grid"):
        StepGlitchFilter(np.ones(4), level, 10)
    with pytest.raises(ValueError, match="positive"):
        StepGlitchFilter(np.ones((2, 2)), np.zeros((2, 2)), 10)
    with pytest.raises(ValueError, match="max_frames"):
        StepGlitchFilter(np.ones((2, 2)), level, 0)
    with pytest.raises(ValueError, match="flat_fraction"):
        StepGlitchFilter(np.ones((2, 2)), level, 10, flat_fraction=1.5)
