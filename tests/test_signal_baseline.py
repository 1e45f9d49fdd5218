"""Tests for wovenskin.signal.baseline: input guard, relative change and drift tracking."""

from __future__ import annotations

import numpy as np
import pytest

from wovenskin.signal.baseline import BaselineTracker, dilate_one_channel
from wovenskin.signal.calibration import Calibration
from wovenskin.signal.config import ConditioningConfig

SHAPE = (6, 6)
BLOCK = 20  # frames per block with the default config


def _calibration(baseline: float | np.ndarray = 10.0, dead=None) -> Calibration:
    base = np.broadcast_to(np.asarray(baseline, dtype=np.float64), SHAPE).copy()
    dead = np.zeros(SHAPE, bool) if dead is None else dead
    return Calibration(base, np.full(SHAPE, 1e-3), dead, np.zeros(SHAPE, bool), 100, "test")


def _run_block(tracker: BaselineTracker, level: np.ndarray, active=None) -> None:
    """Feed one block of constant readings with the given active channels."""
    frames = np.broadcast_to(level, (BLOCK, *SHAPE)).astype(np.float64)
    active = np.zeros(SHAPE, bool) if active is None else active
    clean, _, _, _ = tracker.relative(frames)
    tracker.accumulate(clean, np.broadcast_to(active, (BLOCK, *SHAPE)))


def test_dilation_grows_by_one_channel_including_diagonals():
    mask = np.zeros((5, 5), bool)
    mask[2, 2] = True
    mask[0, 4] = True
    grown = dilate_one_channel(mask)
    expected = np.zeros((5, 5), bool)
    expected[1:4, 1:4] = True
    expected[0:2, 3:5] = True
    assert np.array_equal(grown, expected)


def test_untouched_channels_follow_slow_drift_with_the_configured_time_constant():
    config = ConditioningConfig()
    tracker = BaselineTracker(_calibration(10.0), config)
    level = np.full(SHAPE, 10.1)  # 1 % above the calibrated baseline
    _run_block(tracker, level)
    np.testing.assert_allclose(tracker.baseline, 10.0 + 0.1 * config.drift_alpha)
    for _ in range(19):  # 20 blocks of 0.1 s = one 2 s time constant
        _run_block(tracker, level)
    np.testing.assert_allclose(tracker.baseline, 10.0 + 0.1 * (1 - np.exp(-1)), rtol=1e-9)


def test_active_channels_and_their_neighbours_freeze_and_hold_after_release():
    config = ConditioningConfig(common_drift_min_fraction=0.0)
    tracker = BaselineTracker(_calibration(10.0), config)
    level = np.full(SHAPE, 10.1)
    active = np.zeros(SHAPE, bool)
    active[2, 2] = True
    _run_block(tracker, level, active)
    frozen = dilate_one_channel(active)
    assert (tracker.baseline[frozen] == 10.0).all()
    assert (tracker.baseline[~frozen] > 10.0).all()
    for _ in range(config.hold_blocks):  # released, but held
        _run_block(tracker, level)
    assert (tracker.baseline[frozen] == 10.0).all()
    _run_block(tracker, level)  # hold over: tracking again
    assert (tracker.baseline[frozen] > 10.0).all()


def test_frozen_channels_follow_the_common_drift_of_the_others():
    config = ConditioningConfig()
    tracker = BaselineTracker(_calibration(10.0), config)
    active = np.zeros(SHAPE, bool)
    active[2, 2] = True
    for _ in range(30):
        _run_block(tracker, np.full(SHAPE, 10.2), active)
    tracking = tracker.baseline[0, 5]
    assert tracking > 10.1
    assert tracker.baseline[2, 2] == pytest.approx(tracking, rel=1e-3)


def test_reading_well_below_baseline_recovers_fast_even_when_frozen():
    config = ConditioningConfig()
    tracker = BaselineTracker(_calibration(10.0), config)
    level = np.full(SHAPE, 10.0)
    level[1, 1] = 8.0  # a finger rested there during calibration and has lifted
    level[3, 3] = 8.0
    active = np.zeros(SHAPE, bool)
    active[3, 4] = True  # (3, 3) is frozen as a neighbour, recovery wins anyway
    _run_block(tracker, level, active)
    expected = 10.0 - 2.0 * config.recover_alpha
    assert tracker.baseline[1, 1] == pytest.approx(expected)
    assert tracker.baseline[3, 3] == pytest.approx(expected)
    for _ in range(4):
        _run_block(tracker, level, active)
    # Fast recovery stops within its threshold (6 sigma = 0.6 %); slow tracking does the rest.
    assert 8.0 < tracker.baseline[1, 1] < 8.0 * (1 + 6 * 1e-3)


def test_small_negative_deviation_does_not_trigger_recovery():
    config = ConditioningConfig(common_drift_min_fraction=0.0)
    tracker = BaselineTracker(_calibration(10.0), config)
    active = np.ones(SHAPE, bool)  # all frozen
    _run_block(tracker, np.full(SHAPE, 10.0 * (1 - 0.5 * config.recover_min_rel)), active)
    assert (tracker.baseline == 10.0).all()


def test_a_contact_stuck_longer_than_max_contact_is_rebaselined():
    config = ConditioningConfig(max_contact_s=1.0)
    tracker = BaselineTracker(_calibration(10.0), config)
    active = np.zeros(SHAPE, bool)
    active[4, 4] = True
    level = np.full(SHAPE, 10.0)
    level[4, 4] = 11.0
    for _ in range(config.max_contact_blocks - 1):
        _run_block(tracker, level, active)
    assert tracker.baseline[4, 4] == 10.0
    _run_block(tracker, level, active)
    assert tracker.baseline[4, 4] == 11.0


def test_guard_holds_bad_readings_and_flags_them():
    config = ConditioningConfig(full_scale=30.0)
    tracker = BaselineTracker(_calibration(10.0), config)
    x = np.full((4, *SHAPE), 11.0)
    x[1, 0, 0] = np.nan
    x[2, 0, 0] = -np.inf
    x[1, 1, 1] = 30.0  # full scale
    x[2, 2, 2] = 1e6  # implausible rise
    x[3, 3, 3] = 1.0  # implausible drop
    clean, rel, invalid, saturated = tracker.relative(x)
    assert invalid is not None and saturated is not None
    assert set(zip(*np.nonzero(invalid), strict=True)) == {(1, 0, 0), (2, 0, 0)}
    assert set(zip(*np.nonzero(saturated), strict=True)) == {(1, 1, 1), (2, 2, 2), (3, 3, 3)}
    assert clean[1, 0, 0] == clean[2, 0, 0] == 11.0  # last good value held
    assert clean[1, 1, 1] == 11.0 and clean[3, 3, 3] == 11.0
    np.testing.assert_allclose(rel, 0.1)
    # The first bad reading of a stream falls back on the baseline.
    fresh = BaselineTracker(_calibration(10.0), config)
    clean, rel, _, _ = fresh.relative(np.full((1, *SHAPE), np.nan))
    assert (clean == 10.0).all() and (rel == 0.0).all()


def test_clean_readings_report_no_flags():
    tracker = BaselineTracker(_calibration(10.0), ConditioningConfig())
    clean, rel, invalid, saturated = tracker.relative(np.full((3, *SHAPE), 12.0))
    assert invalid is None and saturated is None
    np.testing.assert_allclose(rel, 0.2)


def test_dead_channels_read_their_baseline_and_never_move():
    dead = np.zeros(SHAPE, bool)
    dead[0, 0] = True
    calibration = _calibration(10.0, dead)
    calibration.baseline[0, 0] = 0.0  # unknown level
    tracker = BaselineTracker(calibration, ConditioningConfig())
    x = np.full((BLOCK, *SHAPE), 12.0)
    x[:, 0, 0] = np.nan
    clean, rel, invalid, _ = tracker.relative(x)
    assert invalid is None  # dead channels are not re-flagged every frame
    assert (rel[:, 0, 0] == 0.0).all()
    tracker.accumulate(clean, np.zeros(x.shape, bool))
    assert tracker.baseline[0, 0] == 0.0
    assert tracker.baseline[1, 1] > 10.0


def test_frames_must_fit_in_the_current_block():
    tracker = BaselineTracker(_calibration(), ConditioningConfig())
    assert tracker.frames_to_block_end == BLOCK
    clean, _, _, _ = tracker.relative(np.full((5, *SHAPE), 10.0))
    tracker.accumulate(clean, np.zeros(clean.shape, bool))
    assert tracker.frames_to_block_end == BLOCK - 5
    with pytest.raises(ValueError, match="do not fit"):
        tracker.accumulate(np.full((BLOCK, *SHAPE), 10.0), np.zeros((BLOCK, *SHAPE), bool))
