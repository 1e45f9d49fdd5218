"""Tests for wovenskin.signal.config: defaults, derived frame counts, validation, dicts."""

from __future__ import annotations

import json

import numpy as np
import pytest

from wovenskin.signal.config import ConditioningConfig


def test_defaults_match_the_published_design():
    config = ConditioningConfig()
    assert config.sample_rate_hz == 200.0
    assert config.calibration_frames == 100  # 500 ms static calibration
    assert config.window_frames == 20  # 100 ms moving average
    assert config.block_frames == 20
    assert config.hold_blocks == 5
    assert config.debounce_on_frames == 3
    assert config.debounce_off_frames == 6
    assert config.release_window_frames == 5  # the fast signal for release: 25 ms
    assert config.glitch_max_frames == 25  # longer than any firmware average (<= 0.1 s)
    assert config.skin_hold_blocks == 2 and config.disturbed_max_blocks == 100
    assert config.drift_alpha > config.frozen_drift_alpha > 0


def test_frame_counts_follow_the_settings():
    config = ConditioningConfig(sample_rate_hz=100.0, smoothing_s=0.05, calibration_s=1.0)
    assert config.window_frames == 5
    assert config.calibration_frames == 100
    assert ConditioningConfig(smoothing_s=0.001).window_frames == 1


def test_alphas_are_fractions_that_grow_with_the_block():
    config = ConditioningConfig()
    assert 0 < config.drift_alpha < config.recover_alpha < 1
    slower = ConditioningConfig(drift_tau_s=20.0)
    assert slower.drift_alpha < config.drift_alpha


def test_contact_guards_in_blocks():
    config = ConditioningConfig()
    assert config.stale_contact_blocks == 50 and config.max_contact_blocks == 600
    assert ConditioningConfig(max_contact_s=0).max_contact_blocks == 0
    assert ConditioningConfig(max_contact_s=60).max_contact_blocks == 600


def test_peak_memory_is_a_per_frame_decay():
    config = ConditioningConfig(peak_memory_s=1.0)
    assert config.peak_decay**config.sample_rate_hz == pytest.approx(np.exp(-1.0))


def test_dict_round_trip_through_json():
    config = ConditioningConfig(smoothing_s=0.05, full_scale=65535.0, connectivity=8)
    again = ConditioningConfig.from_dict(json.loads(json.dumps(config.to_dict())))
    assert again == config


def test_from_dict_fills_defaults_and_rejects_unknown_keys():
    assert ConditioningConfig.from_dict({"hold_s": 1.0}) == ConditioningConfig(hold_s=1.0)
    with pytest.raises(ValueError, match="conditioning settings: unknown setting 'smoothing_ms'"):
        ConditioningConfig.from_dict({"smoothing_ms": 100})


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"sample_rate_hz": 0}, "sample_rate_hz"),
        ({"smoothing_s": float("nan")}, "smoothing_s"),
        ({"drift_tau_s": -1}, "drift_tau_s"),
        ({"hold_s": -0.1}, "hold_s"),
        ({"contact_off_sigma": 9.0}, "contact_off_sigma"),
        ({"on_peak_fraction": 0.05}, "peak fractions"),
        ({"rearm_fraction": 0.1}, "release_fraction"),
        ({"recover_blocks": 0}, "recover_blocks"),
        ({"spike_filter": "yes"}, "spike_filter"),
        ({"seeded_blobs": 1}, "seeded_blobs"),
        ({"common_drift": None}, "common_drift"),
        ({"common_mode_quantile": 1.0}, "common_mode_quantile"),
        ({"min_release_rel": 0.05}, "min_release_rel"),
        ({"connectivity": 6}, "connectivity"),
        ({"max_drop_rel": 1.0}, "max_drop_rel"),
        ({"full_scale": float("inf")}, "full_scale"),
        ({"calibration_s": 0.1}, "calibration_s"),
        ({"min_contact_rel": "0.02"}, "min_contact_rel"),
        ({"glitch_filter": 1}, "glitch_filter"),
        ({"glitch_sigma": 0}, "glitch_sigma"),
        ({"release_smoothing_s": -0.01}, "release_smoothing_s"),
        ({"fast_on_factor": 0.5}, "fast_on_factor"),
        ({"skin_hold_s": -1}, "skin_hold_s"),
        ({"frozen_drift_tau_s": 0}, "frozen_drift_tau_s"),
        ({"common_drift_max_drop_rel_per_s": 0}, "common_drift_max_drop_rel_per_s"),
        ({"disturbed_max_s": float("inf")}, "disturbed_max_s"),
    ],
)
def test_invalid_settings_are_rejected_with_their_name(changes, message):
    with pytest.raises(ValueError, match=message):
        ConditioningConfig(**changes)
