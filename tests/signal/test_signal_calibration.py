"""Tests for wovenskin.signal.calibration: baseline, noise, dead and disturbed channels."""

from __future__ import annotations

import json

import numpy as np
import pytest
from signal_synth import SkinSpec, Touch, skin_baseline, synth_stream

from wovenskin.signal.calibration import Calibration, calibrate
from wovenskin.signal.conditioner import condition_recording
from wovenskin.signal.config import ConditioningConfig

CONFIG = ConditioningConfig()


def test_clean_calibration_measures_baseline_and_smoothed_noise():
    spec = SkinSpec(noise_rel=0.004, mains_rel=0.004, seed=1)
    calibration = calibrate(synth_stream(0.5, spec=spec), CONFIG)
    assert calibration.ok
    assert calibration.message.startswith("calibration ok: 100 frames")
    assert calibration.n_frames == 100
    np.testing.assert_allclose(calibration.baseline, skin_baseline(spec), rtol=2e-3)
    # White noise through the median of three and the 20-frame mean (about 0.24 of its
    # per-frame size); the 50 Hz mains cancels in the window.
    expected = 0.238 * 0.004
    assert 0.8 * expected < np.median(calibration.noise) < 1.25 * expected
    assert calibration.noise.max() < 2 * expected
    plain = calibrate(synth_stream(0.5, spec=spec), ConditioningConfig(spike_filter=False))
    assert np.median(plain.noise) == pytest.approx(0.004 / np.sqrt(20), rel=0.2)
    assert not calibration.dead.any() and not calibration.touched.any()


def test_noise_matches_the_spread_of_the_conditioned_signal_later_on():
    spec = SkinSpec(noise_rel=0.003, mains_rel=0.01, seed=14)
    raw = synth_stream(10.0, spec=spec)
    calibration, out = condition_recording(raw, CONFIG)
    ratio = calibration.noise / out.signal[200:].std(axis=0)
    assert 0.85 < np.median(ratio) < 1.2
    assert np.quantile(ratio, 0.05) > 0.6  # few channels get a much too low threshold


def test_noise_is_relative_so_skin_gain_does_not_matter():
    weak = calibrate(synth_stream(0.5, spec=SkinSpec(gain=1.0, seed=2)), CONFIG)
    strong = calibrate(synth_stream(0.5, spec=SkinSpec(gain=2.5, seed=2)), CONFIG)
    np.testing.assert_allclose(strong.baseline, 2.5 * weak.baseline, rtol=1e-5)
    np.testing.assert_allclose(strong.noise, weak.noise, rtol=1e-2)


def test_suspiciously_quiet_channel_gets_a_floored_noise():
    raw = synth_stream(0.5, spec=SkinSpec(noise_rel=0.004, seed=3)).astype(np.float64)
    raw[:, 4, 4] = 20.0 + 1e-5 * np.sin(np.arange(100))  # nearly silent, but not flat
    calibration = calibrate(raw, CONFIG)
    assert not calibration.dead[4, 4]
    typical = np.median(calibration.noise)
    assert calibration.noise[4, 4] >= CONFIG.noise_floor_fraction * typical * 0.99
    silent = calibrate(np.full((100, 3, 3), 5.0) + 1e-5 * np.arange(100)[:, None, None], CONFIG)
    assert (silent.noise >= CONFIG.noise_floor_rel).all()


def test_dead_channels_are_found_and_listed():
    raw = synth_stream(0.5, spec=SkinSpec(seed=4)).astype(np.float64)
    raw[:, 0, 1] = np.nan  # disconnected
    raw[:, 2, 2] = 17.0  # flat
    raw[:, 3, 3] = -1.0  # non-positive
    raw[::3, 5, 5] = np.nan  # a third NaN: still alive
    calibration = calibrate(raw, CONFIG)
    assert set(zip(*np.nonzero(calibration.dead), strict=True)) == {(0, 1), (2, 2), (3, 3)}
    assert "3 dead channels" in calibration.message and "(0,1)" in calibration.message
    assert calibration.noise[0, 1] == 0.0 and calibration.baseline[0, 1] == 0.0
    assert calibration.baseline[2, 2] == 17.0
    assert not calibration.touched.any()
    assert calibration.ok  # dead channels alone do not call for a new calibration


def test_channels_at_full_scale_are_dead():
    raw = synth_stream(0.5, spec=SkinSpec(seed=5)).astype(np.float64)
    raw[:, 1, 1] = 1000.0
    calibration = calibrate(raw, ConditioningConfig(full_scale=1000.0))
    assert calibration.dead[1, 1] and calibration.dead.sum() == 1


def test_all_dead_is_not_ok():
    calibration = calibrate(np.zeros((100, 4, 4)), CONFIG)
    assert calibration.dead.all() and not calibration.ok
    assert "no working channel" in calibration.message


def test_touch_during_calibration_is_detected_and_located():
    spec = SkinSpec(seed=6, crosstalk=0.02)
    raw = synth_stream(0.5, [Touch(0.2, 2.0, 3.0, 4.0, amplitude=0.3)], spec)
    calibration = calibrate(raw, CONFIG)
    assert not calibration.ok
    assert calibration.touched[3, 4] and calibration.touched.sum() >= 5
    assert "touch detected on" in calibration.message
    assert "near row 3, col 4 during calibration" in calibration.message
    # Touched channels take their latest level (the finger is still there: recovery will
    # repair it after lift-off) and the typical noise.
    pressed = skin_baseline(spec)[3, 4] * 1.3
    np.testing.assert_allclose(calibration.baseline[3, 4], pressed, rtol=0.01)
    quiet_noise = np.median(calibration.noise[~calibration.touched])
    assert calibration.noise[3, 4] == pytest.approx(quiet_noise)


def test_touch_lifting_during_calibration_leaves_the_untouched_level():
    spec = SkinSpec(seed=12)
    raw = synth_stream(0.5, [Touch(-1.0, 0.2, 6.0, 2.0, amplitude=0.3)], spec)
    calibration = calibrate(raw, CONFIG)
    assert calibration.touched[6, 2]
    np.testing.assert_allclose(calibration.baseline[6, 2], skin_baseline(spec)[6, 2], rtol=3e-3)


def test_one_frame_glitches_do_not_disturb_calibration():
    raw = synth_stream(0.5, spec=SkinSpec(seed=13)).astype(np.float64)
    raw[30, 2, 2] *= 1.5
    raw[60, 7, 1] *= 0.5
    calibration = calibrate(raw, CONFIG)
    assert calibration.ok and calibration.noise[2, 2] < 2 * np.median(calibration.noise)


def test_a_glitch_pulse_from_a_firmware_average_is_no_touch_and_no_bias():
    # A converter glitch averaged by a 13-frame firmware window: a -2 % box that ends
    # just before the calibration does (it once left a phantom +1.5 % for 30 s).
    spec = SkinSpec(seed=15, noise_rel=0.0005, mains_rel=0.0)
    raw = synth_stream(0.5, spec=spec).astype(np.float64)
    raw[80:93, 4, 6] *= 0.98
    calibration = calibrate(raw, CONFIG)
    assert calibration.ok
    np.testing.assert_allclose(calibration.baseline[4, 6], skin_baseline(spec)[4, 6], rtol=3e-4)
    assert calibration.noise[4, 6] < 2 * np.median(calibration.noise)


def test_step_noise_measures_frame_to_frame_changes_even_when_quantised():
    spec = SkinSpec(seed=16, noise_rel=0.001, mains_rel=0.0)
    raw = synth_stream(0.5, spec=spec).astype(np.float64)
    calibration = calibrate(raw, CONFIG)
    np.testing.assert_allclose(np.median(calibration.step_noise), 0.001 * np.sqrt(2), rtol=0.15)
    coarse = np.round(raw / 0.01) * 0.01  # steps mostly 0, sometimes one LSB
    assert (calibrate(coarse, CONFIG).step_noise > 0).all()


def test_finger_resting_still_through_calibration_is_invisible():
    raw = synth_stream(0.5, [Touch(-1.0, 2.0, 5.0, 5.0, amplitude=0.3)], SkinSpec(seed=7))
    calibration = calibrate(raw, CONFIG)
    assert calibration.ok  # nothing to see; recovery after lift-off handles it
    assert calibration.baseline[5, 5] > 1.25 * skin_baseline(SkinSpec(seed=7))[5, 5]


def test_slow_drift_during_calibration_is_not_a_touch():
    spec = SkinSpec(seed=8, drift_rel_per_min=0.5)  # far faster than thermal drift
    assert calibrate(synth_stream(0.5, spec=spec), CONFIG).ok


def test_palm_covering_most_of_the_skin_is_detected():
    spec = SkinSpec(seed=9)
    palm = [Touch(0.2, 2.0, r, c, amplitude=0.2, sigma=1.0) for r in (2, 5, 8) for c in (2, 5, 8)]
    calibration = calibrate(synth_stream(0.5, palm, spec), CONFIG)
    assert calibration.touched.mean() > 0.75


def test_all_frames_given_are_used():
    calibration = calibrate(synth_stream(1.0, spec=SkinSpec(seed=10)), CONFIG)
    assert calibration.n_frames == 200


@pytest.mark.parametrize(
    ("raw", "message"),
    [
        (np.ones((100, 10)), "shaped \\(N, rows, cols\\)"),
        (np.ones((100, 0, 3)), "shaped \\(N, rows, cols\\)"),
        (np.ones((99, 10, 10)), "at least 100 frames \\(0.5 s at 200 Hz\\), got 99"),
        (np.full((100, 2, 2), np.nan), "all NaN"),
        (np.full((100, 2, 2), "x"), "numeric"),
        (np.ones((100, 2, 2), dtype=complex), "numeric"),
    ],
)
def test_bad_input_raises_a_clear_error(raw, message):
    with pytest.raises(ValueError, match=message):
        calibrate(raw, CONFIG)


def test_dict_round_trip_through_json():
    raw = synth_stream(0.5, spec=SkinSpec(rows=3, cols=5, seed=11)).astype(np.float64)
    raw[:, 0, 0] = np.nan
    calibration = calibrate(raw, CONFIG)
    again = Calibration.from_dict(json.loads(json.dumps(calibration.to_dict())))
    for name in ("baseline", "noise", "dead", "touched", "step_noise"):
        assert np.array_equal(getattr(again, name), getattr(calibration, name))
        assert getattr(again, name).dtype == getattr(calibration, name).dtype
    assert (again.n_frames, again.message) == (calibration.n_frames, calibration.message)
    # Records written before step_noise existed still load (no glitch filter then).
    old = {k: v for k, v in calibration.to_dict().items() if k != "step_noise"}
    assert Calibration.from_dict(old).step_noise is None


def test_from_dict_rejects_malformed_records():
    good = calibrate(synth_stream(0.5, spec=SkinSpec(rows=2, cols=2)), CONFIG).to_dict()
    with pytest.raises(ValueError, match="lacks key 'noise'"):
        Calibration.from_dict({k: v for k, v in good.items() if k != "noise"})
    with pytest.raises(ValueError, match="dead has shape"):
        Calibration.from_dict({**good, "dead": [True, False]})
    with pytest.raises(ValueError, match="malformed"):
        Calibration.from_dict({**good, "baseline": [["a", "b"], ["c", "d"]]})
    with pytest.raises(ValueError, match="finite"):
        Calibration.from_dict({**good, "noise": [[float("nan"), 0.0], [0.0, 0.0]]})
    with pytest.raises(ValueError, match="step_noise has shape"):
        Calibration.from_dict({**good, "step_noise": [1.0]})
