"""The raw-signal lift detector (wovenskin.signal.lift) and its use by the conditioner.

A lift must release the skin within a few frames of the last fingertip leaving, on dull
and sensitive skins alike, and must never end a touch that is still there: a still finger
on a noisy dull skin, a finger sliding from channel to channel, a press whose pressure
wobbles, two fingers of which one lifts.  The scenarios are rendered by the simulator's
skin physics (fabric lag, crosstalk, noise, mains, a hand's own mains pickup).
"""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis.extra import numpy as hnp
from paths import REPO

from wovenskin.errors import ConfigError
from wovenskin.recognition.checkpoint_meta import conditioning_differences
from wovenskin.signal.calibration import calibrate
from wovenskin.signal.conditioner import Conditioner, condition_recording
from wovenskin.signal.config import FLAG_ONLY_SETTINGS, ConditioningConfig
from wovenskin.signal.lift import LiftDetector, LiftSettings, raw_noise
from wovenskin.sim.contact import ContactTrack
from wovenskin.sim.physics import SkinModel
from wovenskin.sim.skin_physics import SkinPhysics

FS = 200
CONFIG = ConditioningConfig()
OFF = replace(CONFIG, lift_fraction=0.0)
META = REPO / "wovenskin" / "models" / "default" / "meta.json"


def fingertip(n, land, lift, x, y, force=1.5, to=None, wobble=0.0, ramp=5) -> ContactTrack:
    """A fingertip landing at frame ``land`` and gone from frame ``lift`` on (its force
    ramps over ``ramp`` frames), at ``(x, y)`` mm or sliding to ``to``; ``wobble``: the
    relative amplitude of a 5 Hz pressure wobble."""
    t = np.arange(n)
    force_n = np.clip(np.minimum((t - land + 1) / ramp, (lift - t) / ramp), 0, 1) * force
    force_n *= 1.0 + wobble * np.sin(2 * np.pi * 5.0 * t / FS)
    xs, ys = np.full(n, float(x)), np.full(n, float(y))
    if to is not None:
        xs, ys = np.interp(t, [land, lift], [x, to[0]]), np.interp(t, [land, lift], [y, to[1]])
    return ContactTrack(xs, ys, force_n, 5.5, 4.5)


def conditioned(physics: SkinPhysics, tracks, n: int, seed: int = 0, config=CONFIG):
    raw = SkinModel(physics, seed=seed).render(tracks, n)
    return condition_recording(raw, config)[1]


def releases(touched: np.ndarray, start: int, end: int) -> int:
    """Times ``touched`` turns off within frames ``[start, end)``."""
    part = touched[start:end]
    return int(np.sum(part[:-1] & ~part[1:]))


@pytest.mark.parametrize("factor", [0.3, 1.0, 3.0, 10.0])
def test_a_lift_releases_within_three_frames_of_the_last_fingertip_leaving(factor):
    physics = replace(SkinPhysics(), gain_pf=4.0 * factor)  # skins 0.3x to 10x as sensitive
    for seed in range(3):
        out = conditioned(physics, [fingertip(400, 150, 300, 45.0, 60.0)], 400, seed)
        assert out.touched[170:296].all()
        # frame 300 is the first without the fingertip; the fabric springs back with its
        # 20 ms time constant, the spike filter's median adds a frame
        assert int(np.argmax(~out.touched[300:])) <= 4, (factor, seed)


def test_a_lift_on_the_dullest_skin_releases_no_later_than_the_moving_average():
    physics = replace(SkinPhysics(), gain_pf=0.4)  # 0.1x: a firm press is ~12 noise sds
    for seed in range(3):
        fast = conditioned(physics, [fingertip(400, 150, 300, 45.0, 60.0)], 400, seed)
        slow = conditioned(physics, [fingertip(400, 150, 300, 45.0, 60.0)], 400, seed, OFF)
        assert np.argmax(~fast.touched[300:]) <= np.argmax(~slow.touched[300:])


def test_the_model_input_is_the_same_with_and_without_the_lift_detector():
    physics = SkinPhysics()
    tracks = [fingertip(500, 150, 300, 45.0, 60.0, to=(20.0, 30.0))]
    on = conditioned(physics, tracks, 500, 3)
    off = conditioned(physics, tracks, 500, 3, OFF)
    assert np.array_equal(on.signal, off.signal) and np.array_equal(on.active, off.active)
    assert np.array_equal(on.baseline, off.baseline)
    assert not np.array_equal(on.touched, off.touched)  # only the flag: it ends sooner
    assert (on.touched <= off.touched).all()


def test_a_still_finger_on_a_noisy_dull_skin_is_never_released():
    noisy = replace(
        SkinPhysics(), gain_pf=0.4, noise_pf=0.03, mains_pf=0.04, body_mains_pf=0.1
    )  # the dullest response with the noisiest readout and hand pickup of the ranges
    for seed in range(3):
        for force in (0.5, 1.5):  # 3 s (longer weak contacts are re-baselined: stale_contact_s)
            tracks = [fingertip(900, 150, 750, 45.0, 60.0, force)]
            on, off = (conditioned(noisy, tracks, 900, seed, c) for c in (CONFIG, OFF))
            first = 150 + int(np.argmax(on.touched[150:]))
            assert first < 250
            # a finger this weak may flicker through the moving average's thresholds now
            # and then; the lift detector adds no release of its own
            assert releases(on.touched, first, 745) == releases(off.touched, first, 745)
            if force > 1.0:
                assert on.touched[first:745].mean() > 0.97, seed


def test_a_finger_sliding_across_channels_is_never_released():
    for physics in (SkinPhysics(), replace(SkinPhysics(), field_spread_mm=0.0, noise_pf=0.02)):
        for seed in range(3):  # 100 mm in 0.5 s: a channel every 25 ms
            track = fingertip(500, 100, 200, 10.0, 10.0, 1.0, to=(90.0, 130.0))
            out = conditioned(physics, [track], 500, seed)
            first = 100 + int(np.argmax(out.touched[100:]))
            assert releases(out.touched, first, 197) == 0, seed
            assert not out.touched[230:].any()


def test_a_press_whose_pressure_wobbles_is_never_released():
    for seed in range(3):
        track = fingertip(800, 100, 700, 45.0, 60.0, 1.0, wobble=0.5)  # 0.5-1.5 N at 5 Hz
        out = conditioned(SkinPhysics(), [track], 800, seed)
        assert releases(out.touched, 120, 695) == 0 and out.touched[120:695].all()


def test_two_fingers_of_which_one_lifts_still_touch():
    for seed in range(3):
        first = fingertip(700, 100, 350, 30.0, 60.0, 1.5)
        second = fingertip(700, 100, 600, 70.0, 60.0, 0.5)  # lighter, and stays longer
        out = conditioned(SkinPhysics(), [first, second], 700, seed)
        assert out.touched[120:596].all(), seed
        # the lighter finger left alone is judged against the pair's peak: the moving
        # average may release it first
        assert not out.touched[630:].any()


def test_touched_is_the_same_for_any_chunking():
    physics = replace(SkinPhysics(), gain_pf=2.0)
    tracks = [
        fingertip(900, 150, 300, 45.0, 60.0, to=(60.0, 90.0)),
        fingertip(900, 420, 470, 20.0, 20.0),  # a quick tap
        fingertip(900, 560, 800, 80.0, 100.0, wobble=0.3),
    ]
    raw = SkinModel(physics, seed=5).render(tracks, 900)
    calibration = calibrate(raw[:100], CONFIG)
    whole = Conditioner(calibration, CONFIG).process(raw)
    stepper = Conditioner(calibration, CONFIG)
    rng = np.random.default_rng(1)
    parts, pos = [], 0
    while pos < raw.shape[0]:
        size = int(rng.choice([1, 1, 3, 7, 40]))
        parts.append(stepper.process(raw[pos : pos + size]))
        pos += size
    assert np.array_equal(whole.touched, np.concatenate([p.touched for p in parts]))
    assert releases(whole.touched, 0, 900) == 3


def test_the_shipped_models_conditioning_loads_and_feeds_it_unchanged():
    stored = json.loads(META.read_text())["conditioning"]
    config = ConditioningConfig.from_dict(stored)
    assert config.lift_fraction == CONFIG.lift_fraction  # settings it predates: defaults
    assert conditioning_differences(stored, config.to_dict()) == []
    # a lift setting never makes a model's input differ; any other setting does
    assert conditioning_differences(stored, replace(config, lift_fraction=0.2).to_dict()) == []
    assert conditioning_differences(stored, replace(config, smoothing_s=0.05).to_dict())
    assert set(config.to_dict()) >= FLAG_ONLY_SETTINGS


@pytest.mark.parametrize(
    "bad",
    [
        {"lift_fraction": 1.0},
        {"lift_fraction": -0.1},
        {"lift_arm_sigma": 0.0},
        {"lift_sigma": float("nan")},
    ],
)
def test_bad_lift_settings_are_one_line_errors(bad):
    with pytest.raises(ConfigError, match="lift"):
        ConditioningConfig.from_dict(bad)


def test_lift_settings_are_checked():
    with pytest.raises(ValueError, match="delay"):
        LiftSettings(delay=0)
    with pytest.raises(ValueError, match="peak_decay"):
        LiftSettings(peak_decay=1.0)
    assert not LiftSettings(fraction=0.0).enabled


def test_the_detector_needs_a_touch_long_and_strong_enough_to_release():
    noise = np.full((4, 4), 1e-3)
    detector = LiftDetector(noise, np.ones((4, 4), bool), LiftSettings(delay=5))
    active = np.zeros((30, 4, 4), bool)
    active[:, 1, 1] = True
    relative = np.zeros((30, 4, 4))
    relative[:, 1, 1] = 0.1  # 100 noise sds
    relative[6:, 1, 1] = 0.0  # lifted after 6 frames: judged only after 2 x 5 frames
    lifted = detector.update(relative, active)
    assert not lifted[:9].any() and lifted[9:].all()
    detector.reset()
    relative[:20, 1, 1] = 0.1
    relative[20:, 1, 1] = 0.0  # lifted after 20 frames
    lifted = detector.update(relative, active)
    assert not lifted[:20].any() and lifted[20:].all()
    detector.reset()
    weak = np.where(relative > 0, 0.004, 0.0)  # 4 noise sds: left to the moving average
    assert not detector.update(weak, active).any()
    nobody = detector.update(relative, np.zeros_like(active))  # no active channel
    assert not nobody.any()


def test_raw_noise_comes_from_the_calibration():
    noise = np.full((2, 2), 1e-4)
    np.testing.assert_allclose(raw_noise(noise, None, 16), 4e-4)
    step = np.full((2, 2), 1e-3)
    np.testing.assert_allclose(raw_noise(noise, step, 16), 1e-3 / np.sqrt(2))
    with pytest.raises(ValueError, match="grids"):
        LiftDetector(np.zeros((2, 2)), np.ones((3, 3), bool), LiftSettings())


@given(hnp.arrays(bool, hnp.array_shapes(min_dims=3, max_dims=3, min_side=1, max_side=12)))
@settings(max_examples=200, deadline=None)
def test_the_grown_mask_is_scipys_8_neighbour_dilation_within_each_frame(mask) -> None:
    from scipy import ndimage

    from wovenskin.signal.lift import _grown

    expected = ndimage.binary_dilation(mask, structure=np.ones((1, 3, 3), dtype=bool))
    np.testing.assert_array_equal(_grown(mask), expected)
