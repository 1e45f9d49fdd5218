"""The per-channel baseline ``C0``: input guard, relative change and drift tracking.

:class:`BaselineTracker` starts from a :class:`~wovenskin.signal.calibration.Calibration`
and owns everything that depends on the baseline:

- the input guard (:meth:`BaselineTracker.guard`): a reading that is NaN/inf is flagged
  ``invalid``, one at or above the configured full scale or outside the plausible range
  of relative change is flagged ``saturated``, and either is replaced by the channel's
  last good reading, so one bad sample never poisons the state; dead channels read
  exactly their baseline;
- the relative change ``(C - C0) / C0``, which makes skins of different gain alike;
- drift tracking, built on one asymmetry: a baseline left too *high* only makes its
  channel read a little low until it is corrected, while one left too *low* reads as a
  contact, and a phantom contact keeps its channel frozen, so it never corrects itself.
  The baseline is constant within blocks of ``block_frames`` frames aligned to the
  absolute frame index and is updated at the end of each block from the block's median
  reading ``m`` (robust to short glitches; the median of a block of whole mains periods
  is unbiased by the mains):

  * *where the contacts are*: channels active in the block and their neighbours (the
    active set dilated by one channel, diagonals included) are frozen, and stay frozen
    for ``hold_blocks`` blocks; the skin counts as *touched* for ``skin_hold_blocks``
    blocks after its last active channel;
  * *common-mode drift* (thermal drift is largely shared by all channels), through
    :class:`CommonDrift`: the median relative deviation of the channels on contact-free
    lines (no frozen channel in their row or column, so neither contacts nor their
    cross-talk along the electrode lines count) shifts every live channel, in full when
    the skin rose, by at most ``common_drift_max_drop_rel_per_s`` when it sank, and not
    at all downward while the skin is touched.  A sink faster than thermal drift marks
    the skin *disturbed*: a grounded hand or sleeve near the skin lowers the channels
    around it (the negative fringe field of a mutual-capacitance readout), even with no
    contact detected.  When contacts leave fewer than ``common_drift_min_fraction`` of
    the channels that quiet, frozen channels follow a rise of the free channels at the
    pace of drift tracking;
  * *a hand is near* while the skin is touched or disturbed.  Readings above the
    baseline are followed at drift pace (``C0 += drift_alpha * (m - C0)``), by frozen
    channels that are not active themselves more slowly (``frozen_drift_alpha``) and
    only while they read less than their contact threshold, so channels that are touched
    again and again still follow their drift without absorbing a finger's edge.
    Readings below the baseline are followed only by free channels, only while no hand
    is near, and no further per block than ``drift_alpha`` times the recovery threshold
    (a burst or a sleeve brushing past must not drag a baseline down);
  * *fast recovery*: a channel whose block reads more than
    ``max(recover_sigma * noise, recover_min_rel)`` below baseline through most of the
    block (its upper quartile does), at a steady level, for ``recover_blocks`` blocks in
    a row while no hand is near, recovers with ``recover_alpha``.  Pressing only raises
    capacitance, so that baseline is wrong: a finger rested there during calibration, or
    a stale contact was re-baselined.  Glitches and bursts swing both ways, a moving hand
    is not steady, and a resting one is near;
  * *stale contacts*: a channel frozen without a break for ``stale_contact_blocks``
    blocks while reading less than ``stale_contact_rel`` above baseline, or for
    ``max_contact_blocks`` blocks whatever it reads, is re-baselined to its block
    median: the last guard against a "contact" that is really a baseline error.  While
    a hand is near, that never lowers a baseline: the channels around a resting hand
    are frozen as its neighbours, and on a mutual-capacitance skin its grounded fringe
    field holds them *below* their resting level for as long as it rests.  Re-baselined
    there after a long hold, they would read a phantom contact the moment the hand
    lifts (their true level, 10-30 noise sds above the lowered baseline), hold the skin
    touched for another ``stale_contact_s`` and hide the lift from the lift detector.
    A stale contact is a baseline too *low*, which re-baselining raises.

Because the baseline only changes at block ends, from the frames of that block, the
tracker's results do not depend on how frames are chunked.
"""

from __future__ import annotations

import numpy as np

from wovenskin.signal.calibration import Calibration
from wovenskin.signal.config import ConditioningConfig
from wovenskin.signal.filters import hold_last_good

_NEVER = np.int64(-(2**40))

HOLD_WANDER_SIGMA = 10.0
"""A weak stale-contact candidate that is active and whose block levels over the last half
of ``stale_contact_s`` wander by more than this many sds of a block median's noise is a
finger holding still (force wobble, tremor), not a baseline error: the stale rule spares
it, and ``max_contact_s`` stays the guard.  A baseline step is flat but for noise and
mains (about 5 such sds on the test skins); a finger held on 0.1x to 1x skins wandered by
13-35."""


def _median(values: np.ndarray) -> float:
    """Median of a 1-D array (``np.median`` without its overhead)."""
    n = values.size
    half = n // 2
    if n % 2:
        return float(np.partition(values, half)[half])
    low, high = np.partition(values, (half - 1, half))[half - 1 : half + 1]
    return float(0.5 * (low + high))


def dilate_one_channel(mask: np.ndarray) -> np.ndarray:
    """``mask`` ``(R, C)`` grown by one channel in all eight directions."""
    rows = mask.copy()
    rows[1:] |= mask[:-1]
    rows[:-1] |= mask[1:]
    out = rows.copy()
    out[:, 1:] |= rows[:, :-1]
    out[:, :-1] |= rows[:, 1:]
    return out


_REFERENCE_ALPHA = 0.3
"""Per-block weight with which the undisturbed reference level follows the skin's level
(smooths the block-to-block noise of the median; a sink over a few blocks still shows)."""


class CommonDrift:
    """The skin's common-mode level and whether a hand near the skin is pulling it down.

    Each block, :meth:`update` gets the median relative deviation ``m`` of the channels on
    contact-free lines (or ``None`` when contacts leave too few of them) and returns the
    shift to apply to every baseline: ``m`` in full when the skin rose, at most
    ``max_drop`` per block when it sank (thermal drift is slower than that).  The level
    the skin had before a sudden sink is kept as the *reference*: while the skin reads
    more than ``disturbed_drop`` below it, the skin is *disturbed*: a grounded hand or
    sleeve near a mutual-capacitance skin lowers every channel around it (its negative
    fringe field), so nothing it pulls down is a baseline error.  The disturbance ends
    when the skin is back at the reference, or after ``max_disturbed_blocks`` (a lasting
    change is then accepted as the new level).
    """

    def __init__(self, max_drop: float, disturbed_drop: float, max_disturbed_blocks: int):
        self.max_drop = float(max_drop)
        self.disturbed_drop = float(disturbed_drop)
        self.max_disturbed_blocks = int(max_disturbed_blocks)
        self.level = 0.0  # sum of the shifts applied so far (relative)
        self.reference = 0.0  # the skin's level before the current disturbance
        self.disturbed_blocks = 0

    @property
    def disturbed(self) -> bool:
        return self.disturbed_blocks > 0

    def update(self, median_deviation: float | None, touched: bool) -> float:
        """Shift for every baseline after a block whose quiet channels read ``m``.

        While the skin is ``touched`` the baselines do not sink at all (a fringe field
        can bias even the quiet channels, and a baseline left too high only costs a
        little sensitivity until the contact ends).
        """
        if median_deviation is None:  # nothing to measure: a disturbance goes on
            if self.disturbed:
                self.disturbed_blocks = min(self.disturbed_blocks + 1, self.max_disturbed_blocks)
            return 0.0
        now = self.level + median_deviation
        if self.reference - now > self.disturbed_drop:
            self.disturbed_blocks += 1
            if self.disturbed_blocks > self.max_disturbed_blocks:
                self.disturbed_blocks = 0
                self.reference = now
        else:
            self.disturbed_blocks = 0
            self.reference += _REFERENCE_ALPHA * (now - self.reference)
        shift = max(median_deviation, 0.0 if touched else -self.max_drop)
        self.level += shift
        return shift


class BaselineTracker:
    """Baseline state of one skin, advanced frame by frame or in chunks (see module doc)."""

    def __init__(self, calibration: Calibration, config: ConditioningConfig) -> None:
        baseline = np.asarray(calibration.baseline, dtype=np.float64)
        noise = np.asarray(calibration.noise, dtype=np.float64)
        usable = np.isfinite(baseline) & (baseline > 0)
        self.config = config
        self.shape: tuple[int, int] = (int(baseline.shape[0]), int(baseline.shape[1]))
        self.dead: np.ndarray = np.asarray(calibration.dead, dtype=bool) | ~usable
        self.live: np.ndarray = ~self.dead
        self._any_dead = bool(self.dead.any())
        self._reported_dead_baseline = np.where(np.isfinite(baseline), baseline, 0.0)
        # Input guard: readings outside [lowest, highest] are implausible.
        self._max_rise = config.max_rise_rel
        self._max_drop = config.max_drop_rel
        self._full_scale = config.full_scale
        self._set_baseline(np.where(usable, baseline, 1.0))
        self._last_good = self._baseline.copy()
        # The block being collected.
        self._block_frames = config.block_frames
        self._block = np.zeros((self._block_frames, *self.shape), dtype=np.float64)
        self._block_active = np.zeros(self.shape, dtype=bool)
        self._in_block = 0
        self._block_index = np.int64(0)
        # Where contacts are.
        self._hold_blocks = np.int64(config.hold_blocks)
        self._skin_hold_blocks = np.int64(config.skin_hold_blocks)
        self._last_frozen_block = np.full(self.shape, _NEVER, dtype=np.int64)
        self._last_free_block = np.full(self.shape, -1, dtype=np.int64)
        self._last_touch_block = _NEVER
        # Drift tracking.
        self._drift_alpha = config.drift_alpha
        self._frozen_alpha = config.frozen_drift_alpha
        self._on_threshold = np.maximum(config.contact_on_sigma * noise, config.min_contact_rel)
        # Fast recovery.
        self._recover_threshold = np.where(
            self.live, np.maximum(config.recover_sigma * noise, config.recover_min_rel), np.inf
        )
        self._recover_alpha = config.recover_alpha
        self._recover_blocks = config.recover_blocks
        self._low_blocks = np.zeros(self.shape, dtype=np.int64)  # consecutive low blocks
        self._recent_levels = np.zeros((config.recover_blocks, *self.shape))
        # Stale contacts.
        self._max_contact_blocks = np.int64(config.max_contact_blocks)
        self._stale_blocks = (
            np.int64(config.stale_contact_blocks) if config.stale_contact_s > 0 else np.int64(2**40)
        )
        self._stale_rel = config.stale_contact_rel
        # A finger holding still wanders; a baseline error does not (HOLD_WANDER_SIGMA).
        self._wander_blocks = int(min(max(2, self._stale_blocks // 2), 200))
        self._recent_deviation = np.zeros((self._wander_blocks, *self.shape))
        self._recent_peak = np.zeros(self._wander_blocks)  # the strongest active channel's
        self._median_noise = np.where(
            self.live, noise * 1.2533 / np.sqrt(self._block_frames), np.inf
        )  # sd of a block's median under white noise
        # Common-mode drift.
        self._common_min_channels = (
            max(1, int(np.ceil(config.common_drift_min_fraction * self.live.sum())))
            if config.common_drift
            else None
        )
        typical_noise = float(np.median(noise[self.live])) if self.live.any() else 0.0
        max_drop = config.common_drift_max_drop_rel_per_s * config.baseline_block_s
        self._common = CommonDrift(
            max_drop,
            max(config.disturbed_sigma * typical_noise, 2.0 * max_drop),
            config.disturbed_max_blocks,
        )

    def _set_baseline(self, baseline: np.ndarray) -> None:
        self._baseline = baseline
        self._inverse = 1.0 / baseline
        self._highest = baseline * (1.0 + self._max_rise)
        self._lowest = baseline * (1.0 - self._max_drop)
        if self._full_scale is not None:  # x < full scale, exactly
            below_full = np.nextafter(self._full_scale, -np.inf)
            self._highest = np.minimum(self._highest, below_full)

    @property
    def baseline(self) -> np.ndarray:
        """Current baseline ``(R, C)`` (a copy); dead channels show their calibration value."""
        if self._any_dead:
            return np.where(self.dead, self._reported_dead_baseline, self._baseline)
        return self._baseline.copy()

    @property
    def frames_to_block_end(self) -> int:
        """Frames still to come before the baseline is next updated."""
        return self._block_frames - self._in_block

    @property
    def resting_level(self) -> np.ndarray:
        """What each channel reads at rest now: the baseline, 1.0 where it is unknown."""
        return self._baseline.copy()

    def guard(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
        """Replace bad readings of ``x`` ``(n, R, C)`` float64 (all within one block).

        Returns ``(clean, invalid, saturated)``: the readings with bad samples replaced by
        the channel's last good one (dead channels read their baseline), and the two flag
        arrays (``None`` when no sample was bad, the usual case).
        """
        if self._any_dead:
            x = np.where(self.dead, self._baseline, x)
        good = (x <= self._highest) & (x >= self._lowest)  # False for NaN
        invalid = saturated = None
        if not good.all():
            bad = ~good
            finite = np.isfinite(x)
            invalid = bad & ~finite
            saturated = bad & finite
            x = hold_last_good(x, bad, self._last_good)
        self._last_good = x[-1].copy()
        return x, invalid, saturated

    def relative(self, x: np.ndarray) -> np.ndarray:
        """Relative change ``(x - C0) / C0`` of readings within the current block."""
        return (x - self._baseline) * self._inverse

    def accumulate(self, clean: np.ndarray, active: np.ndarray) -> None:
        """Add frames (within the current block) and their active channels to the block.

        Updates the baseline when the block is complete.
        """
        n = clean.shape[0]
        if n > self.frames_to_block_end:
            raise ValueError(
                f"{n} frames do not fit in the {self.frames_to_block_end} left in this block"
            )
        self._block[self._in_block : self._in_block + n] = clean
        self._block_active |= active[0] if n == 1 else active.any(axis=0)
        self._in_block += n
        if self._in_block == self._block_frames:
            self._end_block()

    def _end_block(self) -> None:
        ordered = np.sort(self._block, axis=0)
        middle = self._block_frames // 2
        if self._block_frames % 2:
            level = ordered[middle]
        else:
            level = 0.5 * (ordered[middle - 1] + ordered[middle])
        upper = ordered[(3 * (self._block_frames - 1)) // 4]  # upper quartile
        baseline, inverse, index = self._baseline, self._inverse, self._block_index
        deviation = (level - baseline) * inverse
        upper_deviation = (upper - baseline) * inverse
        active = self._block_active

        # Where the contacts are: active channels and their neighbours freeze, and stay
        # frozen for hold_blocks; the skin counts as touched for skin_hold_blocks.
        if active.any():
            self._last_touch_block = index
            self._last_frozen_block[dilate_one_channel(active)] = index
        frozen = index - self._last_frozen_block <= self._hold_blocks
        touched = index - self._last_touch_block <= self._skin_hold_blocks

        shift_all, shift_frozen = self._common_drift(deviation, frozen, touched)
        hand_near = touched or self._common.disturbed
        shifted = baseline + baseline * shift_all if shift_all != 0.0 else baseline
        if shift_frozen != 0.0:
            shifted = np.where(frozen, shifted + shifted * shift_frozen, shifted)

        # Asymmetric drift tracking (see the module doc).
        offset = level - shifted
        up_alpha = np.where(frozen, self._frozen_alpha, self._drift_alpha)
        up_alpha[active] = 0.0
        rising = (offset > 0) & ((offset < self._on_threshold * shifted) | ~frozen)
        new = shifted + np.where(rising, up_alpha, 0.0) * offset
        if not hand_near:
            down = self._drift_alpha * np.maximum(offset, -self._recover_threshold * shifted)
            new = np.where((offset < 0) & ~frozen, shifted + down, new)

        recover = self._fast_recovery(level, upper_deviation, hand_near)
        if recover is not None:
            new = np.where(recover, baseline + self._recover_alpha * (level - baseline), new)

        self._last_free_block[~frozen] = index
        frozen_for = index - self._last_free_block
        self._recent_deviation[index % self._wander_blocks] = deviation
        self._recent_peak[index % self._wander_blocks] = (
            float(deviation[active].max()) if active.any() else np.inf
        )
        stuck = (frozen_for >= self._stale_blocks) & (deviation < self._stale_rel)
        if stuck.any():
            stuck &= ~self._holding(stuck & active)
        if self._max_contact_blocks > 0:
            stuck |= frozen_for >= self._max_contact_blocks
        if stuck.any():
            # While a hand is near, never lower a baseline (module doc): keep it then.
            new = np.where(stuck, np.maximum(level, new) if hand_near else level, new)
            self._last_free_block[stuck] = index
        self._set_baseline(np.where(self.live, new, baseline))
        self._block_active.fill(False)
        self._in_block = 0
        self._block_index += 1

    def _holding(self, candidates: np.ndarray) -> np.ndarray:
        """Of the active stale ``candidates``, those a finger holds: over the last half of
        ``stale_contact_s`` each was the contact's core in every block (at least half the
        strongest active channel's level: a fringe of crosstalk, or what is left when the
        finger beside it lifted, is not), stayed weak (a firm press lifting is no weak
        hold) and wandered by more than :data:`HOLD_WANDER_SIGMA` block-noise sds."""
        held = np.zeros(self.shape, dtype=bool)
        if candidates.any():
            recent = self._recent_deviation[:, candidates]
            core = (recent >= 0.5 * self._recent_peak[:, None]).all(axis=0)
            weak = recent.max(axis=0) < 3 * self._stale_rel
            wanders = recent.std(axis=0) > HOLD_WANDER_SIGMA * self._median_noise[candidates]
            held[candidates] = core & weak & wanders
        return held

    def _fast_recovery(
        self, level: np.ndarray, upper_deviation: np.ndarray, hand_near: bool
    ) -> np.ndarray | None:
        """Channels whose baseline is clearly too high and recover fast (``None``: none).

        A channel qualifies after ``recover_blocks`` blocks in a row read below
        ``-recover_threshold`` through most of the block (glitches and bursts swing both
        ways) at a steady level (a hand or sleeve moving near the skin pulls channels
        down unsteadily), and only while no hand is near: a grounded hand's fringe field
        can pull channels further down than its own contact pushes any up (a palm, a
        forearm), so nothing read then is known to be a baseline error.
        """
        low = upper_deviation < -self._recover_threshold
        self._low_blocks = np.where(low, self._low_blocks + 1, 0)
        self._recent_levels[self._block_index % self._recover_blocks] = level
        if hand_near:
            return None
        recover = self._low_blocks >= self._recover_blocks
        if not recover.any():
            return None
        spread = self._recent_levels.max(axis=0) - self._recent_levels.min(axis=0)
        recover &= spread * self._inverse <= self._recover_threshold
        return recover if recover.any() else None

    def _common_drift(
        self, deviation: np.ndarray, frozen: np.ndarray, touched: bool
    ) -> tuple[float, float]:
        """Common-mode baseline shifts ``(for every live channel, for frozen ones only)``.

        Preferably from the median relative deviation of the live channels on
        contact-free lines (no frozen channel in their row or column, so neither contacts
        nor their cross-talk reach them), through :class:`CommonDrift`.  When contacts
        leave too few of those, the frozen channels follow the median deviation of the
        free channels at the pace of drift tracking (upward; downward no faster than
        thermal drift): cross-talk and fringe fields can bias that estimate, so it is
        used gently and only where nothing else moves the baseline.
        """
        if self._common_min_channels is None:
            return 0.0, 0.0
        quiet = self.live & ~frozen.any(axis=1, keepdims=True) & ~frozen.any(axis=0)
        if int(quiet.sum()) >= self._common_min_channels:
            return self._common.update(_median(deviation[quiet]), touched), 0.0
        self._common.update(None, touched)
        free = self.live & ~frozen
        if int(free.sum()) >= self._common_min_channels:
            follow = self._drift_alpha * _median(deviation[free])
            return 0.0, max(follow, 0.0)
        return 0.0, 0.0
