"""Tests for wovenskin.signal.baseline: input guard, relative change and drift tracking."""

from __future__ import annotations

import numpy as np
import pytest

from wovenskin.signal.baseline import BaselineTracker, CommonDrift, dilate_one_channel
from wovenskin.signal.calibration import Calibration
from wovenskin.signal.config import ConditioningConfig

SHAPE = (6, 6)
BLOCK = 20  # frames per block with the default config
NOISE = 1e-3


def _calibration(baseline: float = 10.0, dead=None) -> Calibration:
    base = np.full(SHAPE, baseline)
    dead = np.zeros(SHAPE, bool) if dead is None else dead
    return Calibration(base, np.full(SHAPE, NOISE), dead, np.zeros(SHAPE, bool), 100, "test")


def _run_block(tracker: BaselineTracker, level, active=None) -> None:
    """Feed one block of constant readings ``level`` with the given active channels."""
    frames = np.broadcast_to(np.asarray(level, dtype=np.float64), (BLOCK, *SHAPE)).copy()
    active = np.zeros(SHAPE, bool) if active is None else active
    clean, _, _ = tracker.guard(frames)
    tracker.accumulate(clean, np.broadcast_to(active, (BLOCK, *SHAPE)))


def _one(row: int, col: int) -> np.ndarray:
    mask = np.zeros(SHAPE, bool)
    mask[row, col] = True
    return mask


def test_dilation_grows_by_one_channel_including_diagonals():
    mask = np.zeros((5, 5), bool)
    mask[2, 2] = True
    mask[0, 4] = True
    expected = np.zeros((5, 5), bool)
    expected[1:4, 1:4] = True
    expected[0:2, 3:5] = True
    assert np.array_equal(dilate_one_channel(mask), expected)


def test_untouched_channels_follow_their_drift_with_the_configured_time_constant():
    config = ConditioningConfig(common_drift=False)
    tracker = BaselineTracker(_calibration(10.0), config)
    _run_block(tracker, 10.1)  # 1 % above the calibrated baseline
    np.testing.assert_allclose(tracker.baseline, 10.0 + 0.1 * config.drift_alpha)
    for _ in range(9):  # 10 blocks of 0.1 s = one 1 s time constant
        _run_block(tracker, 10.1)
    np.testing.assert_allclose(tracker.baseline, 10.0 + 0.1 * (1 - np.exp(-1)), rtol=1e-9)


def test_common_mode_drift_moves_every_channel_at_once_even_under_a_contact():
    tracker = BaselineTracker(_calibration(10.0), ConditioningConfig())
    level = np.full(SHAPE, 10.05)
    level[2, 2] = 11.0  # pressed
    _run_block(tracker, level, _one(2, 2))
    # Rows 1-3 and columns 1-3 touch the frozen patch; the other lines measure the drift.
    np.testing.assert_allclose(tracker.baseline[2, 2], 10.05)
    np.testing.assert_allclose(tracker.baseline[0, 0], 10.05)


def test_cross_talk_lines_do_not_count_as_common_drift():
    tracker = BaselineTracker(_calibration(10.0), ConditioningConfig())
    level = np.full(SHAPE, 10.0)
    level[2, :] = 10.03  # the pressed channel's row and column rise by cross-talk
    level[:, 2] = 10.03
    level[2, 2] = 11.0
    _run_block(tracker, level, _one(2, 2))
    assert tracker.baseline[2, 2] == 10.0  # frozen, and no common drift measured
    assert tracker.baseline[0, 0] == 10.0


def test_without_quiet_lines_frozen_channels_follow_the_tracking_ones_gently():
    config = ConditioningConfig()
    tracker = BaselineTracker(_calibration(10.0), config)
    active = np.zeros(SHAPE, bool)
    active[4, :] = True  # a palm across the bottom: no column is free of it
    level = np.full(SHAPE, 10.1)
    level[4, :] = 11.0
    _run_block(tracker, level, active)
    expected = 10.0 * (1 + config.drift_alpha * 0.01)
    np.testing.assert_allclose(tracker.baseline[4, 0], expected)  # frozen, follows
    np.testing.assert_allclose(tracker.baseline[0, 0], 10.0 + 0.1 * config.drift_alpha)


def test_active_channels_and_their_neighbours_freeze_and_hold_after_release():
    config = ConditioningConfig(common_drift=False)
    tracker = BaselineTracker(_calibration(10.0), config)
    _run_block(tracker, 10.1, _one(2, 2))
    frozen = dilate_one_channel(_one(2, 2))
    assert (tracker.baseline[frozen] == 10.0).all()
    assert (tracker.baseline[~frozen] > 10.0).all()
    for _ in range(config.hold_blocks):  # released, but held
        _run_block(tracker, 10.1)
    assert (tracker.baseline[frozen] == 10.0).all()
    _run_block(tracker, 10.1)  # hold over: tracking again
    assert (tracker.baseline[frozen] > 10.0).all()


def test_reading_below_baseline_recovers_fast_once_no_hand_is_near_even_when_frozen():
    config = ConditioningConfig()
    tracker = BaselineTracker(_calibration(10.0), config)
    level = np.full(SHAPE, 10.0)
    level[1, 1] = 8.0  # a finger rested there during calibration and has lifted
    level[3, 3] = 8.0  # the same next to a channel touched a moment ago
    for _ in range(config.recover_blocks + 2):  # a contact on the skin: nothing moves down
        _run_block(tracker, level, _one(3, 4))
    assert tracker.baseline[1, 1] == 10.0 and tracker.baseline[3, 3] == 10.0
    for _ in range(config.skin_hold_blocks):  # lifted, but the hand may still be near
        _run_block(tracker, level)
    assert tracker.baseline[1, 1] == 10.0
    _run_block(tracker, level)  # the hand is gone: both recover, frozen or not
    expected = 10.0 - 2.0 * config.recover_alpha
    assert tracker.baseline[1, 1] == pytest.approx(expected)
    assert tracker.baseline[3, 3] == pytest.approx(expected)
    for _ in range(4):
        _run_block(tracker, level)
    # Fast recovery stops within its threshold; slow tracking does the rest.
    assert 8.0 < tracker.baseline[1, 1] < 8.0 * (1 + config.recover_sigma * NOISE)


def test_an_unsteady_low_reading_does_not_recover_fast():
    config = ConditioningConfig(common_drift=False)
    tracker = BaselineTracker(_calibration(10.0), config)
    for i in range(2 * config.recover_blocks):  # a sleeve moving over the skin
        level = np.full(SHAPE, 10.0)
        level[2, 2] = 9.7 - 0.1 * (i % 3)  # -3 % .. -5 %, never steady
        _run_block(tracker, level)
    assert tracker.baseline[2, 2] > 9.9  # slow tracking only; fast recovery would be ~9.6


def test_a_burst_swinging_both_ways_does_not_trigger_recovery():
    tracker = BaselineTracker(_calibration(10.0), ConditioningConfig(common_drift=False))
    swing = 10.0 + 0.5 * np.sign(np.sin(np.arange(BLOCK) * 2 * np.pi / 8))  # +-5 %
    for _ in range(8):
        frames = np.broadcast_to(swing.reshape(-1, 1, 1), (BLOCK, *SHAPE)).copy()
        frames -= 0.1  # and a little below the baseline on average
        clean, _, _ = tracker.guard(frames)
        tracker.accumulate(clean, np.zeros(clean.shape, bool))
    assert (tracker.baseline > 9.95).all()


def test_small_negative_deviation_is_left_to_slow_tracking():
    config = ConditioningConfig(common_drift=False)
    tracker = BaselineTracker(_calibration(10.0), config)
    active = np.ones(SHAPE, bool)  # everything frozen
    for _ in range(config.recover_blocks + 1):
        _run_block(tracker, 10.0 * (1 - 0.5 * config.recover_sigma * NOISE), active)
    assert (tracker.baseline == 10.0).all()


def _assert_rebaselined_after(config: ConditioningConfig, reading: float, blocks: int) -> None:
    """A contact held at (4, 4) reading ``reading`` (the rest at the 10.0 baseline) keeps the
    baseline for ``blocks - 1`` blocks and becomes it in block ``blocks``."""
    tracker = BaselineTracker(_calibration(10.0), config)
    level = np.full(SHAPE, 10.0)
    level[4, 4] = reading
    for _ in range(blocks - 1):
        _run_block(tracker, level, _one(4, 4))
    assert tracker.baseline[4, 4] == 10.0
    _run_block(tracker, level, _one(4, 4))
    assert tracker.baseline[4, 4] == reading


def test_a_weak_endless_contact_is_rebaselined_as_stale():
    config = ConditioningConfig(stale_contact_s=1.0, common_drift=False)
    # +0.5 %: a baseline error that keeps itself active
    _assert_rebaselined_after(config, 10.05, config.stale_contact_blocks)


def test_a_weak_contact_that_wanders_like_a_held_finger_is_not_stale():
    """A light finger held on a weak skin reads as little as a baseline error, but its force
    wobbles: its block levels wander by far more than their noise, and the stale rule
    spares it (only ``max_contact_s`` re-baselines it)."""
    config = ConditioningConfig(stale_contact_s=1.0, max_contact_s=3.0, common_drift=False)
    tracker = BaselineTracker(_calibration(10.0), config)
    level = np.full(SHAPE, 10.0)
    for k in range(config.max_contact_blocks - 1):  # past stale_contact_s, short of the max
        level[4, 4] = 10.0 * (1.005 + 0.004 * (-1) ** k)  # +0.1 % and +0.9 % in turn
        _run_block(tracker, level, _one(4, 4))
    assert tracker.baseline[4, 4] == 10.0
    _run_block(tracker, level, _one(4, 4))
    assert tracker.baseline[4, 4] == level[4, 4]  # max_contact_s: the last guard


def test_a_firm_long_press_is_kept_until_max_contact():
    config = ConditioningConfig(stale_contact_s=0.5, max_contact_s=2.0, common_drift=False)
    # +20 %: far above stale_contact_rel
    _assert_rebaselined_after(config, 12.0, config.max_contact_blocks)


def test_block_level_is_the_median_so_short_glitches_do_not_move_the_baseline():
    tracker = BaselineTracker(_calibration(10.0), ConditioningConfig(common_drift=False))
    frames = np.full((BLOCK, *SHAPE), 10.0)
    frames[5:9, 0, 0] = 6.0  # a 4-frame dropout
    clean, _, _ = tracker.guard(frames)
    tracker.accumulate(clean, np.zeros(clean.shape, bool))
    assert tracker.baseline[0, 0] == 10.0


def test_guard_holds_bad_readings_and_flags_them():
    tracker = BaselineTracker(_calibration(10.0), ConditioningConfig(full_scale=30.0))
    x = np.full((4, *SHAPE), 11.0)
    x[1, 0, 0] = np.nan
    x[2, 0, 0] = -np.inf
    x[1, 1, 1] = 30.0  # full scale
    x[2, 2, 2] = 1e6  # implausible rise
    x[3, 3, 3] = 1.0  # implausible drop
    clean, invalid, saturated = tracker.guard(x)
    assert invalid is not None and saturated is not None
    assert set(zip(*np.nonzero(invalid), strict=True)) == {(1, 0, 0), (2, 0, 0)}
    assert set(zip(*np.nonzero(saturated), strict=True)) == {(1, 1, 1), (2, 2, 2), (3, 3, 3)}
    assert (clean == 11.0).all()  # last good value held
    np.testing.assert_allclose(tracker.relative(clean), 0.1)
    # The first bad reading of a stream falls back on the baseline.
    fresh = BaselineTracker(_calibration(10.0), ConditioningConfig())
    clean, _, _ = fresh.guard(np.full((1, *SHAPE), np.nan))
    assert (clean == 10.0).all() and (fresh.relative(clean) == 0.0).all()


def test_clean_readings_report_no_flags():
    tracker = BaselineTracker(_calibration(10.0), ConditioningConfig())
    clean, invalid, saturated = tracker.guard(np.full((3, *SHAPE), 12.0))
    assert invalid is None and saturated is None
    np.testing.assert_allclose(tracker.relative(clean), 0.2)


def test_dead_channels_read_their_baseline_and_never_move():
    dead = np.zeros(SHAPE, bool)
    dead[0, 0] = True
    calibration = _calibration(10.0, dead)
    calibration.baseline[0, 0] = 0.0  # unknown level
    tracker = BaselineTracker(calibration, ConditioningConfig())
    assert tracker.resting_level[0, 0] == 1.0
    x = np.full((BLOCK, *SHAPE), 12.0)
    x[:, 0, 0] = np.nan
    clean, invalid, _ = tracker.guard(x)
    assert invalid is None  # dead channels are not re-flagged every frame
    assert (tracker.relative(clean)[:, 0, 0] == 0.0).all()
    tracker.accumulate(clean, np.zeros(x.shape, bool))
    assert tracker.baseline[0, 0] == 0.0
    assert tracker.baseline[1, 1] > 10.0


def test_frames_must_fit_in_the_current_block():
    tracker = BaselineTracker(_calibration(), ConditioningConfig())
    assert tracker.frames_to_block_end == BLOCK
    clean, _, _ = tracker.guard(np.full((5, *SHAPE), 10.0))
    tracker.accumulate(clean, np.zeros(clean.shape, bool))
    assert tracker.frames_to_block_end == BLOCK - 5
    with pytest.raises(ValueError, match="do not fit"):
        tracker.accumulate(np.full((BLOCK, *SHAPE), 10.0), np.zeros((BLOCK, *SHAPE), bool))


def test_frozen_channels_follow_a_small_rise_slowly_but_never_a_contact_edge():
    config = ConditioningConfig(common_drift=False)
    tracker = BaselineTracker(_calibration(10.0), config)
    level = np.full(SHAPE, 10.0)
    level[2, 3] = 10.03  # +0.3 %: drift, below the contact threshold
    level[3, 2] = 10.2  # +2 %: the edge of the finger on (2, 2)
    level[2, 2] = 12.0
    for _ in range(10):
        _run_block(tracker, level, _one(2, 2))
    assert tracker.baseline[2, 2] == 10.0  # active: never follows
    assert tracker.baseline[3, 2] == 10.0  # a contact's edge: never absorbed
    expected = 10.0 + 0.03 * (1 - (1 - config.frozen_drift_alpha) ** 10)
    assert tracker.baseline[2, 3] == pytest.approx(expected)  # slowly, at the frozen pace
    assert config.frozen_drift_alpha < config.drift_alpha


def test_nothing_sinks_while_a_contact_is_on_the_skin():
    config = ConditioningConfig()
    tracker = BaselineTracker(_calibration(10.0), config)
    level = np.full(SHAPE, 9.99)  # -0.1 % everywhere: a hand's fringe field, or drift
    level[0, 0] = 11.0
    for _ in range(20):
        _run_block(tracker, level, _one(0, 0))
    assert (tracker.baseline == 10.0).all()
    for _ in range(30):  # contact-free: now the skin follows, no faster than drift goes
        _run_block(tracker, np.full(SHAPE, 9.99))
    np.testing.assert_allclose(tracker.baseline, 9.99, rtol=2e-4)


def test_a_hand_sinking_the_whole_skin_leaves_no_baseline_error_behind():
    # A grounded forearm near a mutual-capacitance skin pulls every channel down, some
    # more than others, without any contact being detected.  Nothing may follow it down
    # (or the channels read as contacts once it leaves), although the common level
    # keeps sinking at the drift pace.
    config = ConditioningConfig()
    tracker = BaselineTracker(_calibration(10.0), config)
    fringe = np.linspace(-0.002, -0.012, SHAPE[0] * SHAPE[1]).reshape(SHAPE)
    for _ in range(30):  # 3 s, steady
        _run_block(tracker, 10.0 * (1 + fringe))
    assert tracker.baseline.min() > 10.0 * (1 - 30 * config.common_drift_max_drop_rel_per_s * 0.1)
    for _ in range(3):  # the hand leaves: no channel reads above its baseline
        _run_block(tracker, np.full(SHAPE, 10.0))
    assert (tracker.baseline >= 10.0 - 1e-9).all()
    np.testing.assert_allclose(tracker.baseline, 10.0, rtol=5e-4)


def test_common_drift_follows_rises_at_once_and_sinks_at_drift_pace():
    drift = CommonDrift(max_drop=0.001, disturbed_drop=0.002, max_disturbed_blocks=5)
    assert drift.update(0.004, touched=False) == 0.004
    assert drift.update(-0.0005, touched=False) == -0.0005
    assert drift.update(-0.0015, touched=False) == -0.001  # faster than drift: limited
    assert not drift.disturbed  # 1.5 blocks of drift behind: not yet a hand
    assert drift.update(-0.005, touched=False) == -0.001
    assert drift.disturbed  # sank far faster than drift goes
    assert drift.update(-0.004, touched=True) == 0.0  # touched: nothing sinks
    assert drift.disturbed
    drift.update(0.0, touched=False)  # back where it was: over
    assert not drift.disturbed


def test_a_lasting_sink_is_accepted_after_the_longest_disturbance():
    drift = CommonDrift(max_drop=0.0001, disturbed_drop=0.001, max_disturbed_blocks=3)
    drift.update(0.0, touched=False)
    for _ in range(3):
        drift.update(-0.01 - drift.level, touched=False)
        assert drift.disturbed
    drift.update(-0.01 - drift.level, touched=False)
    assert not drift.disturbed  # the new level is the reference now
    drift.update(-0.01 - drift.level, touched=False)
    assert not drift.disturbed
