"""The per-channel baseline ``C0``: input guard, relative change and drift tracking.

:class:`BaselineTracker` starts from a :class:`~wovenskin.signal.calibration.Calibration`
and owns everything that depends on the baseline:

- the input guard (:meth:`BaselineTracker.guard`): a reading that is NaN/inf is flagged
  ``invalid``, one at or above the configured full scale or outside the plausible range
  of relative change is flagged ``saturated``, and either is replaced by the channel's
  last good reading, so one bad sample never poisons the state; dead channels read
  exactly their baseline;
- the relative change ``(C - C0) / C0``, which makes skins of different gain alike;
- drift tracking.  The baseline is constant within blocks of ``block_frames`` frames
  aligned to the absolute frame index and is updated at the end of each block from the
  block's median reading ``m`` (robust to short glitches, and the median of a block of
  whole mains periods is unbiased by the mains):

  * channels whose block reads more than ``max(recover_sigma * noise, recover_min_rel)``
    below baseline through most of the block (its upper quartile does) for
    ``recover_blocks`` blocks in a row recover fast, ``C0 += recover_alpha * (m - C0)``
    (pressing only raises capacitance, so the baseline is wrong: a finger rested on it
    during calibration, or it followed electrode cross-talk during a long press
    elsewhere).  Glitches and interference bursts swing both ways and do not qualify;
  * otherwise channels that were active in the block, or are next to one (the active set
    dilated by one channel, diagonals included), are frozen, and stay frozen for
    ``hold_blocks`` blocks after that;
  * live channels that are not frozen follow slowly, ``C0 += drift_alpha * (m - C0)``;
  * common-mode drift (thermal drift is largely shared by all channels): the median
    relative deviation of the channels on contact-free lines (no frozen channel in their
    row or column, so neither contacts nor their cross-talk along the electrode lines
    count) shifts every live channel in full, block by block.  When contacts leave
    fewer than ``common_drift_min_fraction`` of the channels that quiet, the frozen
    channels instead follow the median deviation of the tracking channels at the pace
    of drift tracking;
  * a channel frozen without a break for ``stale_contact_blocks`` blocks while reading
    less than ``stale_contact_rel`` above baseline, or for ``max_contact_blocks``
    blocks whatever it reads, is re-baselined to its block median: a guard against a
    "contact" that is really a baseline error (left by an interference burst, a step in
    the reading), which would otherwise keep itself frozen.

Because the baseline only changes at block ends, from the frames of that block, the
tracker's results do not depend on how frames are chunked.
"""

from __future__ import annotations

import numpy as np

from wovenskin.signal.calibration import Calibration
from wovenskin.signal.config import ConditioningConfig
from wovenskin.signal.filters import hold_last_good

_NEVER = np.int64(-(2**40))


def dilate_one_channel(mask: np.ndarray) -> np.ndarray:
    """``mask`` ``(R, C)`` grown by one channel in all eight directions."""
    rows = mask.copy()
    rows[1:] |= mask[:-1]
    rows[:-1] |= mask[1:]
    out = rows.copy()
    out[:, 1:] |= rows[:, :-1]
    out[:, :-1] |= rows[:, 1:]
    return out


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
        self._baseline = np.where(usable, baseline, 1.0)
        self._inverse = 1.0 / self._baseline
        self._recover_threshold = np.where(
            self.live, np.maximum(config.recover_sigma * noise, config.recover_min_rel), np.inf
        )
        self._block_frames = config.block_frames
        self._hold_blocks = np.int64(config.hold_blocks)
        self._drift_alpha = config.drift_alpha
        self._recover_alpha = config.recover_alpha
        self._max_rise = config.max_rise_rel
        self._max_drop = -config.max_drop_rel
        self._full_scale = config.full_scale
        self._last_good = self._baseline.copy()
        self._block = np.zeros((self._block_frames, *self.shape), dtype=np.float64)
        self._recover_blocks = config.recover_blocks
        self._low_blocks = np.zeros(self.shape, dtype=np.int64)  # consecutive low blocks
        self._block_active = np.zeros(self.shape, dtype=bool)
        self._in_block = 0
        self._block_index = np.int64(0)
        self._last_frozen_block = np.full(self.shape, _NEVER, dtype=np.int64)
        self._last_free_block = np.full(self.shape, -1, dtype=np.int64)
        self._max_contact_blocks = np.int64(config.max_contact_blocks)
        self._stale_blocks = (
            np.int64(config.stale_contact_blocks) if config.stale_contact_s > 0 else np.int64(2**40)
        )
        self._stale_rel = config.stale_contact_rel
        self._common_min_channels = (
            max(1, int(np.ceil(config.common_drift_min_fraction * self.live.sum())))
            if config.common_drift
            else None
        )

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
        rel = (x - self._baseline) * self._inverse  # NaN/inf stay NaN/inf, no warning
        good = (rel <= self._max_rise) & (rel >= self._max_drop)  # False for NaN
        if self._full_scale is not None:
            good &= x < self._full_scale
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
        baseline = self._baseline
        deviation = (level - baseline) * self._inverse
        frozen_now = dilate_one_channel(self._block_active)
        self._last_frozen_block[frozen_now] = self._block_index
        frozen = self._block_index - self._last_frozen_block <= self._hold_blocks
        low = (upper - baseline) * self._inverse < -self._recover_threshold
        self._low_blocks = np.where(low, self._low_blocks + 1, 0)
        recover = self._low_blocks >= self._recover_blocks

        track = self.live & ~frozen & ~recover
        shift_all, shift_frozen = self._common_drift(deviation, frozen, track)
        shifted = baseline + baseline * shift_all if shift_all != 0.0 else baseline
        tracked = shifted + self._drift_alpha * (level - shifted)
        held = shifted + shifted * shift_frozen if shift_frozen != 0.0 else shifted
        recovered = baseline + self._recover_alpha * (level - baseline)
        new = np.where(recover, recovered, np.where(track, tracked, held))

        self._last_free_block[~frozen] = self._block_index
        frozen_for = self._block_index - self._last_free_block
        stuck = (frozen_for >= self._stale_blocks) & (deviation < self._stale_rel)
        if self._max_contact_blocks > 0:
            stuck |= frozen_for >= self._max_contact_blocks
        if stuck.any():
            new = np.where(stuck, level, new)
            self._last_free_block[stuck] = self._block_index
        self._baseline = np.where(self.live, new, baseline)
        self._inverse = 1.0 / self._baseline
        self._block_active.fill(False)
        self._in_block = 0
        self._block_index += 1

    def _common_drift(
        self, deviation: np.ndarray, frozen: np.ndarray, track: np.ndarray
    ) -> tuple[float, float]:
        """Common-mode baseline shifts ``(for every live channel, for frozen ones only)``.

        Preferably the median relative deviation of the live channels on contact-free
        lines (no frozen channel in their row or column, so neither contacts nor their
        cross-talk reach them), applied in full to every channel.  When contacts leave too
        few of those, the frozen channels follow the median deviation of the tracking
        channels at the pace of drift tracking: cross-talk can bias that estimate, so it
        is used gently and only where nothing else moves the baseline.
        """
        if self._common_min_channels is None:
            return 0.0, 0.0
        quiet = self.live & ~frozen.any(axis=1, keepdims=True) & ~frozen.any(axis=0)
        if int(quiet.sum()) >= self._common_min_channels:
            return float(np.median(deviation[quiet])), 0.0
        if int(track.sum()) >= self._common_min_channels:
            return 0.0, self._drift_alpha * float(np.median(deviation[track]))
        return 0.0, 0.0
