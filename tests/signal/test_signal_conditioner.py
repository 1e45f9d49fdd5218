"""Tests for wovenskin.signal.conditioner: the pipeline and LiveConditioner on synthetic skins."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from signal_synth import SkinSpec, Touch, synth_stream

from wovenskin.signal.calibration import calibrate
from wovenskin.signal.conditioner import (
    ConditionedFrames,
    Conditioner,
    LiveConditioner,
    condition_recording,
)
from wovenskin.signal.config import ConditioningConfig

CONFIG = ConditioningConfig()
FS = 200


def _frame(t_s: float) -> int:
    return int(round(t_s * FS))


def _assert_identical(a: ConditionedFrames, b: ConditionedFrames) -> None:
    for name in ("signal", "active", "touched", "n_contacts", "saturated", "invalid", "index"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    assert np.array_equal(a.baseline, b.baseline)
    assert np.array_equal(a.dead, b.dead)
    assert a.contacts == b.contacts


def test_output_is_the_smoothed_relative_change_whatever_the_skin_gain():
    touches = [Touch(1.0, 2.0, 4.0, 4.0, amplitude=0.25)]
    weak = condition_recording(synth_stream(2.5, touches, SkinSpec(gain=1.0)), CONFIG)[1]
    strong = condition_recording(synth_stream(2.5, touches, SkinSpec(gain=2.2)), CONFIG)[1]
    assert weak.signal.dtype == np.float32 and weak.signal.shape == (500, 10, 10)
    np.testing.assert_allclose(weak.signal, strong.signal, atol=2e-6)
    assert np.array_equal(weak.active, strong.active)
    # A static press reads its relative change at the centre once the window has filled.
    assert weak.signal[_frame(1.5), 4, 4] == pytest.approx(0.25, abs=0.01)


@pytest.mark.parametrize("smoothing_s", [0.05, 0.1])
def test_moving_average_length_is_settable(smoothing_s):
    dither = 1e-3 * np.sin(np.arange(200) * 0.7).reshape(-1, 1, 1)  # not flat, not dead
    raw = 20.0 + np.zeros((200, 3, 3)) + dither
    raw[150:, 1, 1] += 2.0  # a 10 % step
    for spike_filter, delay in ((False, 0), (True, 1)):  # the median of 3 costs one frame
        # A one-channel step that holds is what a glitch pulse looks like: no glitch filter.
        config = ConditioningConfig(
            smoothing_s=smoothing_s, spike_filter=spike_filter, glitch_filter=False
        )
        trace = condition_recording(raw, config)[1].signal[:, 1, 1]
        window = config.window_frames
        start = 150 + delay
        assert abs(trace[start - 1]) < 1e-4
        ramp = 0.1 * np.arange(1, window + 1) / window
        np.testing.assert_allclose(trace[start : start + window], ramp, atol=1e-4)
        np.testing.assert_allclose(trace[start + window :], 0.1, atol=1e-4)


def test_one_frame_glitches_are_removed():
    raw = synth_stream(2.0, [], SkinSpec(seed=21)).astype(np.float64)
    raw[300, 4, 4] *= 1.4  # +40 % for one frame
    raw[320, 2, 7] *= 0.7
    _, out = condition_recording(raw, CONFIG)
    assert not out.active.any() and np.abs(out.signal[290:340]).max() < 0.003


def test_twenty_second_press_stays_detected_and_releases_cleanly():
    spec = SkinSpec(crosstalk=0.03, drift_rel_per_min=0.01, seed=11)
    press = Touch(2.0, 22.0, 4.4, 6.3, amplitude=0.3)
    raw = synth_stream(25.0, [press], spec)
    calibration, out = condition_recording(raw, CONFIG)
    assert calibration.ok
    during = slice(_frame(2.05), _frame(22.0))
    pressed = slice(_frame(2.05), _frame(22.0 - press.ramp_s))  # the lift's ramp may release
    assert out.touched[pressed].all() and (out.n_contacts[during] == 1).all()
    assert out.active[during, 4, 6].all()
    centroid = np.array([(c[0].row, c[0].col) for c in out.contacts[during]])
    np.testing.assert_allclose(centroid.mean(axis=0), [4.4, 6.3], atol=0.2)
    # Not absorbed: the press still reads its full strength at the end.
    assert out.signal[_frame(21.9), 4, 6] > 0.95 * out.signal[_frame(3.0), 4, 6]
    # Cross-talk raised the pressed row and column, yet they never became contacts.
    assert not out.active[during, 4, :3].any() and not out.active[during, :2, 6].any()
    # Released: back to ~0 quickly and no phantom contact anywhere afterwards.
    after = slice(_frame(22.25), None)
    assert np.abs(out.signal[after][:, 4, 6]).max() < 0.003
    assert np.abs(out.signal[after][:, 3:6, 5:8]).max() < 0.005
    assert not out.active[after].any() and not out.touched[after].any()
    # The baseline is right afterwards, cross-talk rows and columns included.
    np.testing.assert_allclose(out.baseline, raw[-100:].mean(axis=0), rtol=0.002)


def test_slow_thermal_drift_without_touch_produces_no_contacts():
    spec = SkinSpec(drift_rel_per_min=0.04, mains_rel=0.005, seed=12)
    raw = synth_stream(60.0, [], spec)
    calibration, out = condition_recording(raw, CONFIG)
    assert calibration.ok
    assert not out.active.any() and not out.touched.any() and out.n_contacts.sum() == 0
    # Tracked without lag: the signal averages to ~0 on every channel.
    assert np.abs(out.signal[_frame(50.0) :].mean(axis=0)).max() < 5e-4
    np.testing.assert_allclose(out.baseline, raw[-200:].mean(axis=0), rtol=0.001)


def test_fast_common_drift_during_a_long_press_leaves_no_offset():
    # 2 % in 10 s, the same on every channel: faster than any per-channel tracking.
    spec = SkinSpec(seed=22)
    raw = synth_stream(14.0, [Touch(2.0, 12.0, 5.0, 5.0, amplitude=0.2)], spec).astype(float)
    raw *= 1.0 + 0.002 * np.arange(len(raw)).reshape(-1, 1, 1) / FS
    _, out = condition_recording(raw, CONFIG)
    assert out.touched[_frame(2.1) : _frame(12.0)].all()
    assert not out.touched[_frame(12.3) :].any()
    assert np.abs(out.signal[_frame(12.5) :]).max() < 0.003


def test_interference_burst_does_not_leave_a_contact_behind():
    spec = SkinSpec(seed=23)
    raw = synth_stream(10.0, [], spec).astype(np.float64)
    t = np.arange(_frame(0.3)) / FS
    burst = 0.05 * np.sin(2 * np.pi * 4.0 * t)  # 0.3 s of 4 Hz on rows 2-4, +-5 %
    raw[_frame(2.0) : _frame(2.3), 2:5, :] *= 1.0 + burst.reshape(-1, 1, 1)
    _, out = condition_recording(raw, CONFIG)
    assert out.touched[_frame(2.0) : _frame(2.4)].any()  # the burst itself is seen
    assert not out.active[_frame(3.0) :].any()


def test_finger_resting_through_calibration_recovers_after_lift_off():
    spec = SkinSpec(crosstalk=0.02, seed=13)
    touches = [
        Touch(-1.0, 2.0, 5.0, 5.0, amplitude=0.3),  # resting still from before the start
        Touch(4.0, 5.0, 5.0, 5.0, amplitude=0.3),  # a real touch on the same spot later
    ]
    calibration, out = condition_recording(synth_stream(6.0, touches, spec), CONFIG)
    assert calibration.ok  # it could not be seen
    assert not out.active[: _frame(4.0)].any()  # no phantom, during or after the lift-off
    assert out.signal[_frame(2.1), 5, 5] < -0.05  # lift-off reads below the baseline ...
    settled = slice(_frame(2.8), _frame(4.0))
    assert np.abs(out.signal[settled, 5, 5]).max() < 0.003  # ... and recovers within 0.8 s
    assert out.signal[settled].max() < 0.003  # no positive offset anywhere
    assert out.signal[settled].min() > -0.006  # at most a small negative rest, fading
    later = slice(_frame(4.1), _frame(5.0 - touches[1].ramp_s))  # before the lift's ramp
    assert out.touched[later].all()
    assert out.signal[_frame(4.5), 5, 5] == pytest.approx(0.3, abs=0.02)


def test_touch_landing_during_calibration_is_reported_and_recovered_from():
    spec = SkinSpec(seed=14)
    touches = [Touch(0.3, 2.0, 2.0, 7.0, amplitude=0.3), Touch(3.5, 4.0, 2.0, 7.0, amplitude=0.3)]
    calibration, out = condition_recording(synth_stream(4.5, touches, spec), CONFIG)
    assert not calibration.ok and "near row 2, col 7" in calibration.message
    # The finger was taken into the baseline; after lift-off the baseline recovers, with
    # no phantom contact, and the next touch on the same spot reads in full.
    assert not out.active[_frame(2.2) : _frame(3.5)].any()
    assert out.signal[_frame(2.8) : _frame(3.5), 2, 7].min() > -0.006
    assert out.signal[_frame(2.8) : _frame(3.5)].max() < 0.003
    assert out.touched[_frame(3.6) : _frame(4.0 - touches[1].ramp_s)].all()
    assert out.signal[_frame(3.9), 2, 7] == pytest.approx(0.3, abs=0.02)


def test_lift_off_releases_within_a_few_frames_not_the_whole_window():
    spec = SkinSpec(seed=24)
    press = Touch(1.0, 2.0, 5.0, 5.0, amplitude=0.05, ramp_s=0.01)
    _, out = condition_recording(synth_stream(3.0, [press], spec), CONFIG)
    assert out.touched[_frame(1.05) : _frame(1.99)].all()
    released = _frame(1.99) + int(np.argmin(out.touched[_frame(1.99) :]))
    # Drop (2 frames) + median (1) + fast average falling to 20 % (4) + debounce (6):
    # about 13 frames; the 20-frame average alone would take over 20.
    assert released - _frame(1.99) <= 14
    assert not out.touched[released:].any()


def test_glitch_pulses_on_a_running_skin_make_no_contact():
    raw = synth_stream(3.0, [], SkinSpec(seed=25, noise_rel=0.001)).astype(np.float64)
    for start, width, row, col, size in (
        (200, 13, 2, 2, 1.1),
        (300, 2, 7, 7, 1.3),
        (400, 20, 5, 1, 0.9),
    ):
        raw[start : start + width, row, col] *= size
    calibration, out = condition_recording(raw, CONFIG)
    assert calibration.ok and not out.active.any() and not out.touched.any()
    assert np.abs(out.signal).max() < 0.003


def test_nan_inf_and_spikes_do_not_poison_the_state():
    spec = SkinSpec(seed=15)
    clean = synth_stream(3.0, [Touch(2.0, 2.8, 6.0, 6.0)], spec).astype(np.float64)
    raw = clean.copy()
    raw[300:340, 2, 3] = np.nan
    raw[350] = np.inf
    raw[360:363, 7, 7] = 1e9
    raw[370, 1, 1] = -5.0
    _, out = condition_recording(raw, CONFIG)
    _, reference = condition_recording(clean, CONFIG)
    assert out.invalid.sum() == 40 + 100 and out.invalid[300:340, 2, 3].all()
    assert out.saturated.sum() == 4 and out.saturated[360:363, 7, 7].all()
    assert np.isfinite(out.signal).all()
    assert not out.active[: _frame(2.0)].any()
    assert np.abs(out.signal[:400] - reference.signal[:400]).max() < 0.005
    # Once the held values have left the window, the output is the clean stream's again.
    np.testing.assert_allclose(
        out.signal[_frame(2.0) :], reference.signal[_frame(2.0) :], atol=1e-3
    )
    assert np.array_equal(out.touched[_frame(2.0) :], reference.touched[_frame(2.0) :])


def test_full_scale_readings_are_flagged_but_the_press_is_still_a_contact():
    spec = SkinSpec(seed=16)
    raw = synth_stream(2.0, [Touch(1.0, 1.8, 5.0, 5.0, amplitude=0.8)], spec)
    full_scale = float(np.quantile(raw[:, 5, 5], 0.9))
    raw = np.minimum(raw, full_scale)
    _, out = condition_recording(raw, ConditioningConfig(full_scale=full_scale))
    assert out.saturated[:, 5, 5].sum() >= 15
    pressed = out.saturated[:, 5, 5]
    assert out.active[pressed, 5, 5].all() and out.touched[pressed].all()


def test_dead_channels_never_produce_contacts():
    spec = SkinSpec(seed=17)
    raw = synth_stream(2.0, [Touch(1.0, 1.8, 3.0, 3.0, amplitude=0.3)], spec).astype(np.float64)
    raw[:, 3, 3] = 18.0  # flat: dead
    raw[: _frame(1.0), 8, 8] = np.nan  # disconnected during calibration ...
    raw[_frame(1.0) :, 8, 8] = 500.0  # ... then reading garbage
    calibration, out = condition_recording(raw, CONFIG)
    assert calibration.dead[3, 3] and calibration.dead[8, 8]
    assert not out.active[:, 3, 3].any() and not out.active[:, 8, 8].any()
    assert (out.signal[:, 3, 3] == 0).all() and (out.signal[:, 8, 8] == 0).all()
    assert out.touched[_frame(1.1) : _frame(1.7)].all()  # its neighbours still see the finger
    assert np.array_equal(out.dead, calibration.dead)


def test_two_fingers_are_two_contacts_on_a_6x8_skin():
    spec = SkinSpec(rows=6, cols=8, seed=18)
    touches = [Touch(1.0, 2.0, 1.0, 1.5, amplitude=0.3), Touch(1.0, 2.0, 4.0, 6.0, amplitude=0.3)]
    raw = synth_stream(2.5, touches, spec)
    calibration, out = condition_recording(raw, CONFIG)
    assert calibration.baseline.shape == (6, 8) and out.signal.shape == (500, 6, 8)
    during = slice(_frame(1.1), _frame(1.95))
    assert (out.n_contacts[during] == 2).all()
    first, second = out.contacts[_frame(1.5)]
    assert (first.row, first.col) == pytest.approx((1.0, 1.5), abs=0.15)
    assert (second.row, second.col) == pytest.approx((4.0, 6.0), abs=0.15)
    assert first.size >= 2 and first.peak > 0.15
    assert not out.touched[_frame(2.2) :].any()


@pytest.mark.parametrize(("rows", "cols"), [(1, 1), (1, 4), (3, 3)])
def test_tiny_skins_work_too(rows, cols):
    spec = SkinSpec(rows=rows, cols=cols, seed=25)
    touch = Touch(1.0, 2.0, (rows - 1) / 2, (cols - 1) / 2, amplitude=0.3)
    _, out = condition_recording(synth_stream(3.0, [touch], spec), CONFIG)
    assert out.touched[
        _frame(1.1) : _frame(2.0 - touch.ramp_s)
    ].all()  # the lift's ramp may release
    assert not out.touched[_frame(2.2) :].any() and not out.touched[: _frame(1.0)].any()


def test_moving_finger_centroid_follows_the_swipe():
    spec = SkinSpec(seed=19)
    swipe = Touch(1.0, 1.5, 8.0, 5.0, to_row=1.0, to_col=5.0, amplitude=0.3, sigma=0.7)
    _, out = condition_recording(synth_stream(2.0, [swipe], spec), CONFIG)
    rows = [c[0].row for c in out.contacts[_frame(1.15) : _frame(1.45)] if len(c) == 1]
    assert len(rows) > 40
    assert np.all(np.diff(rows) < 0.05)  # moves up, allowing for noise
    assert rows[0] - rows[-1] > 3.0


def test_a_step_in_one_channel_is_re_baselined_once_it_proves_stale():
    spec = SkinSpec(seed=24)
    raw = synth_stream(9.0, [], spec).astype(np.float64)
    raw[_frame(1.0) :, 3, 3] *= 1.006  # the reading settles 0.6 % higher for good
    _, out = condition_recording(raw, CONFIG)
    assert out.active[_frame(1.2) : _frame(5.0), 3, 3].all()  # looks like a light touch
    assert not out.active[_frame(7.0) :].any()  # ... until it proves stale
    assert abs(out.signal[-1, 3, 3]) < 0.002


RECORDING = synth_stream(
    4.0,
    [Touch(0.8, 1.6, 3.0, 3.0), Touch(1.2, 2.4, 6.0, 7.0, to_row=2.0), Touch(2.9, 3.3, 8.0, 1.0)],
    SkinSpec(crosstalk=0.03, drift_rel_per_min=0.05, seed=20),
).astype(np.float64)
RECORDING[500:520, 4, 4] = np.nan
RECORDING[600:603, 7, 2] = 1e9  # implausible: held and flagged saturated
RECORDING[:, 9, 0] = 15.0  # flat: dead
RECORDING[420, 1, 8] *= 1.5  # a one-frame glitch
RECORDING[700:713, 2, 5] *= 1.06  # glitches smeared into pulses by a firmware average
RECORDING[86:89, 0, 4] *= 0.95  # (one during calibration)
CALIBRATION = calibrate(RECORDING[:100], CONFIG)
WHOLE = Conditioner(CALIBRATION, CONFIG).process(RECORDING)


def test_frame_by_frame_is_bit_identical_to_all_at_once():
    conditioner = Conditioner(CALIBRATION, CONFIG)
    parts = [conditioner.process(frame) for frame in RECORDING]  # (R, C) frames
    assert all(len(p) == 1 for p in parts)
    _assert_identical(ConditionedFrames.concat(parts), WHOLE)
    assert WHOLE.n_contacts.max() == 2 and WHOLE.invalid.sum() == 20
    assert WHOLE.saturated.sum() == 3 and WHOLE.dead[9, 0]
    assert CALIBRATION.ok and not WHOLE.active[690:740, 1:4, 4:7].any()


@settings(max_examples=20, deadline=None, derandomize=True)
@given(sizes=st.lists(st.integers(1, 97), min_size=1, max_size=10))
def test_any_chunking_is_bit_identical(sizes):
    conditioner = Conditioner(CALIBRATION, CONFIG)
    parts, pos, k = [], 0, 0
    while pos < len(RECORDING):
        stop = min(len(RECORDING), pos + sizes[k % len(sizes)])
        parts.append(conditioner.process(RECORDING[pos:stop]))
        pos, k = stop, k + 1
    _assert_identical(ConditionedFrames.concat(parts), WHOLE)
    assert conditioner.frames_processed == len(RECORDING)


def test_process_validates_its_input():
    conditioner = Conditioner(CALIBRATION, CONFIG)
    with pytest.raises(ValueError, match=r"expected raw frames shaped \(N, 10, 10\)"):
        conditioner.process(np.zeros((5, 10, 9)))
    with pytest.raises(ValueError, match="expected raw frames"):
        conditioner.process(np.zeros(10))
    with pytest.raises(ValueError, match="real numbers"):
        conditioner.process(np.full((10, 10), "a"))
    empty = conditioner.process(np.zeros((0, 10, 10)))
    assert len(empty) == 0 and empty.baseline.shape == (10, 10)
    integers = conditioner.process(RECORDING[:3].astype(np.int32))
    assert len(integers) == 3 and integers.index.tolist() == [0, 1, 2]


def test_thresholds_come_from_the_calibrated_noise():
    conditioner = Conditioner(CALIBRATION, CONFIG)
    live = ~CALIBRATION.dead
    assert (conditioner.on_threshold[live] >= CONFIG.min_contact_rel).all()
    assert (conditioner.off_threshold[live] < conditioner.on_threshold[live]).all()
    assert np.isinf(conditioner.on_threshold[CALIBRATION.dead]).all()
    np.testing.assert_array_equal(conditioner.baseline, CALIBRATION.baseline)


def test_concat_needs_parts():
    with pytest.raises(ValueError, match="empty list"):
        ConditionedFrames.concat([])


def test_condition_recording_needs_a_full_calibration_period():
    with pytest.raises(ValueError, match="at least 100 frames"):
        condition_recording(np.ones((60, 4, 4)), CONFIG)
    with pytest.raises(ValueError, match=r"\(N, rows, cols\)"):
        condition_recording(np.ones((600, 16)), CONFIG)


# -- LiveConditioner ------------------------------------------------------------

LIVE_RAW = synth_stream(
    3.0, [Touch(1.0, 2.0, 5.0, 2.0, to_col=7.0)], SkinSpec(crosstalk=0.02, seed=30)
).astype(np.float64)


def _feed(live: LiveConditioner, raw: np.ndarray, size: int) -> ConditionedFrames | None:
    outputs = [live.feed(raw[i : i + size]) for i in range(0, len(raw), size)]
    produced = [o for o in outputs if o is not None]
    return ConditionedFrames.concat(produced) if produced else None


@pytest.mark.parametrize("size", [1, 7, 100, 300])
def test_live_output_equals_the_recording_output_after_calibration(size):
    live = LiveConditioner(CONFIG, 10, 10)
    out = _feed(live, LIVE_RAW, size)
    _, recording = condition_recording(LIVE_RAW, CONFIG)
    assert live.state == "running" and live.calibration is not None and live.warnings == []
    assert out is not None and len(out) == len(LIVE_RAW) - 100
    assert out.index[0] == 100
    for name in ("signal", "active", "touched", "n_contacts"):
        assert np.array_equal(getattr(out, name), getattr(recording, name)[100:]), name
    assert out.contacts == recording.contacts[100:]
    assert np.array_equal(out.baseline, recording.baseline)
    assert out.touched.any()


def test_nothing_is_returned_while_calibrating():
    live = LiveConditioner(CONFIG, 10, 10)
    assert live.feed(LIVE_RAW[:99]) is None
    assert live.state == "calibrating" and live.calibration is None
    assert live.feed(LIVE_RAW[99]) is None  # completes calibration, no frame left to condition
    assert live.state == "running"
    assert len(live.feed(LIVE_RAW[100])) == 1


def test_touch_during_calibration_warns_and_retries():
    touched = synth_stream(0.5, [Touch(0.2, 0.5, 3.0, 4.0)], SkinSpec(seed=31))
    messages: list[str] = []
    live = LiveConditioner(CONFIG, 10, 10, on_warning=messages.append)
    assert live.feed(touched) is None
    assert live.state == "calibrating" and live.attempts == 1
    assert messages == live.warnings and len(messages) == 1
    assert "touch detected" in messages[0] and "near row 3, col 4" in messages[0]
    assert "retrying (1/3)" in messages[0]
    out = live.feed(LIVE_RAW)  # a clean period follows, then conditioning
    assert live.state == "running" and live.calibration.ok and len(live.warnings) == 1
    assert out is not None and len(out) == len(LIVE_RAW) - 100


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
    raw = LIVE_RAW.copy()
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
