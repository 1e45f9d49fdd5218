"""Every setting of signal conditioning, in one frozen dataclass with units in the names.

:class:`ConditioningConfig` is shared by calibration, baseline tracking, the moving
average and contact detection.  Times are seconds (``_s``) and are turned into frame
counts here, once, so that every module rounds them the same way.  Relative quantities
(``_rel``) are fractions of a channel's baseline (0.02 = 2 %); ``_sigma`` quantities are
multiples of a channel's calibrated noise, i.e. the standard deviation of its conditioned
(relative, smoothed) signal while nothing touches the skin.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

from wovenskin.errors import ConfigError
from wovenskin.settings import from_dict

FLAG_ONLY_SETTINGS = frozenset({"lift_fraction", "lift_arm_sigma", "lift_sigma"})
"""Settings that change only the ``touched`` flag, never the ``signal`` (nor ``active``, nor
the baseline): a recogniser's input does not depend on them, so a checkpoint need not have
been trained with them (one stored before they existed has none)."""


@dataclass(frozen=True)
class ConditioningConfig:
    """Settings of calibration, drift tracking, smoothing and contact detection.

    Sampling and smoothing:

    - ``sample_rate_hz``: nominal frame rate of the skin.
    - ``calibration_s``: length of the contact-free calibration period (baseline + noise).
    - ``smoothing_s``: length of the causal moving average applied to the relative change
      (0.1 s = 20 frames at 200 Hz; it also cancels 50 Hz and 60 Hz mains exactly).  Its
      output is the ``signal``.
    - ``release_smoothing_s``: length of a second, short moving average (the *fast*
      signal, used by detection only): a channel also releases once its fast signal falls
      below ``release_fraction`` of its recent peak, so a lifted finger stops counting
      within a few frames instead of the whole smoothing window; it also turns a channel
      on early when it exceeds ``fast_on_factor`` times the on threshold (the fast signal
      is noisier and does not cancel mains, hence the factor; 0 disables that).  A length
      not shorter than ``smoothing_s`` disables the fast signal.
    - ``spike_filter``: take the median of the last three readings, which removes
      one-frame single-channel glitches for one frame of latency.
    - ``glitch_filter`` / ``glitch_sigma`` / ``glitch_max_s``: remove glitches that a
      firmware moving average has smeared into a rectangular pulse (a single channel
      steps by more than ``max(glitch_sigma * step noise, min_contact_rel)`` in one frame,
      with its neighbours still, then holds flat), for up to ``glitch_max_s``; see
      :class:`~wovenskin.signal.filters.StepGlitchFilter`.  No added latency.

    Contact detection (per channel, with hysteresis; a channel turns on above
    ``max(contact_on_sigma * noise, min_contact_rel, on_peak_fraction * frame peak)`` and
    off below ``max(contact_off_sigma * noise, min_release_rel, off_peak_fraction * frame
    peak)``, where the frame peak is the largest signal of the frame):

    - ``contact_on_sigma`` / ``contact_off_sigma``: thresholds in units of channel noise.
    - ``min_contact_rel`` / ``min_release_rel``: floors on those thresholds, as relative
      change, so a very quiet channel cannot trigger on what is not noise yet is no touch
      either (a hovering hand's fringe field, the fabric relaxing, a small baseline
      error).  0.2 % is well below a light fingertip (~1 % on a typical skin, 0.4 % on
      the weakest simulated one).
    - ``on_peak_fraction`` / ``off_peak_fraction``: thresholds relative to the frame's
      strongest channel, so the electrode cross-talk of a firm press (a few percent of it
      on its whole row and column) does not light up those lines; 0 disables them.
    - ``rearm_fraction`` / ``release_fraction``: thresholds relative to the channel's own
      recent peak, which decays with time constant ``peak_memory_s``: a channel releases
      once it falls to ``release_fraction`` of what the finger gave it, and cannot fire
      again on what a firm press leaves behind (the fabric's creep, at most ~12 % of the
      press relaxing within a second) until the memory has faded; 0 disables them.  Kept
      low enough that the next gesture on the same spot, a second later and lighter, is
      still seen.
    - ``debounce_on_s``: how long some channel must stay active before the skin counts as
      touched; ``debounce_off_s``: how long all must stay inactive before it counts as
      released.
    - ``connectivity``: 4 (edge neighbours) or 8 (edges and corners) for contact blobs.
    - ``common_mode_quantile``: detection works on the signal minus, frame by frame, this
      quantile of all live channels' signals when positive, so an offset shared by the
      whole skin (thermal drift faster than the baseline follows) never looks like
      contact, while contacts covering up to ``1 - quantile`` of the skin are unaffected;
      0 disables it.  The ``signal`` output is not changed.
    - ``seeded_blobs``: a channel that passes the hysteresis is active only when its blob
      holds a channel above the on threshold in that frame (before ``rearm_fraction``), so
      a lone channel lingering just above its off threshold cannot keep itself frozen.

    Lift detection on the raw relative change, before the moving average
    (:mod:`~wovenskin.signal.lift`): the skin counts as released, without waiting for the
    moving average and the debounce, on the first frame in which the raw change summed
    over the recently pressed channels falls below ``lift_fraction`` of the lowest it
    came (relative to its recent peak, memory ``peak_memory_s``) while the hand was surely
    on the skin, and no channel next to an active one still reads above ``lift_fraction``
    of its own recent peak.  These settings change only ``touched``
    (:data:`FLAG_ONLY_SETTINGS`):

    - ``lift_fraction``: that fraction; 0 turns the lift detector off.
    - ``lift_arm_sigma``: that lowest level must stand at least this many noise sds of the
      summed raw noise of those channels above zero (a light finger on a noisy skin is
      released by the moving average alone).
    - ``lift_sigma``: a channel counts as recently pressed, or as still holding, only
      above this many sds of its raw (one frame, unsmoothed) noise.

    Baseline (drift) tracking, updated once per block of frames aligned to the absolute
    frame index (see :mod:`wovenskin.signal.baseline` for the rules):

    - ``baseline_block_s``: block length (0.1 s cancels 50 Hz and 60 Hz mains).
    - ``drift_tau_s``: time constant with which the baseline follows untouched channels.
    - ``frozen_drift_tau_s``: time constant with which frozen channels that are not
      active themselves follow a reading above their baseline (below their contact
      threshold): channels in the middle of the skin are touched again and again and
      would otherwise never follow their drift.
    - ``hold_s``: how long a channel stays frozen after it (or a neighbour) was last active.
    - ``skin_hold_s``: how long the skin counts as touched (a hand near) after its last
      active channel; no baseline moves down while a hand is near.
    - ``recover_sigma`` / ``recover_min_rel``: ``recover_blocks`` blocks in a row that
      read more than ``max(recover_sigma * noise, recover_min_rel)`` below baseline
      through most of the block (its upper quartile does), at a level steady within that
      threshold, while no hand is near, trigger fast recovery (pressing only raises
      capacitance, so such a baseline is wrong; glitches and interference bursts swing
      both ways, a hand's fringe field only lasts while the hand is near).
    - ``recover_tau_s``: time constant of that fast recovery.
    - ``common_drift``: every channel, frozen or not, follows the common-mode drift of
      the skin (thermal drift is largely shared by all channels), block by block; it is
      measured on the channels whose row and column hold no contact, and skipped when
      fewer than ``common_drift_min_fraction`` of the live channels are that quiet.
    - ``common_drift_max_drop_rel_per_s``: the fastest the common level may sink (a
      rise is followed at once); thermal drift is far slower (~1 % per minute at most).
    - ``disturbed_sigma`` / ``disturbed_max_s``: when the quiet channels sink more than
      ``max(disturbed_sigma * median noise, 2 blocks of the largest drop)`` below where
      they were, faster than drift goes, the skin is *disturbed* (a hand or sleeve near
      it: its fringe field pulls channels down even before any contact is seen) until
      it is back, or for at most ``disturbed_max_s``.
    - ``stale_contact_s`` / ``stale_contact_rel``: a channel frozen without a break for
      longer than ``stale_contact_s`` while reading less than ``stale_contact_rel`` above
      its baseline is re-baselined (a weak, endless "contact" is a baseline error, e.g.
      left by an interference burst; fingers rest for seconds, not longer); 0 disables.
    - ``max_contact_s``: a channel frozen for longer than this is re-baselined whatever
      it reads (a guard against a contact stuck by a baseline step); 0 disables it.
      Neither rule lowers a baseline while a hand is near: a resting hand's fringe field
      holds its neighbours below their resting level (see :mod:`~wovenskin.signal.baseline`).

    Calibration:

    - ``noise_floor_rel``: absolute floor on a channel's noise (relative units).
    - ``noise_floor_fraction``: floor on a channel's noise as a fraction of the median noise
      of the undisturbed channels, so a suspiciously quiet channel keeps a sane threshold.
    - ``calib_disturb_ratio``: a channel is disturbed during calibration when the range of
      its smoothed relative signal exceeds this many times the lower-quartile range of all
      channels, and also exceeds ``calib_disturb_min_rel``.
    - ``calib_disturb_abs_rel``: a range above this is a disturbance whatever the others do
      (a palm covering most of the skin).
    - ``dead_flat_rel``: a channel whose peak-to-peak range over calibration is below this
      fraction of its level is flat, i.e. dead.
    - ``dead_nan_fraction``: a channel with more than this fraction of NaN/inf calibration
      samples is dead.

    Input plausibility (a reading failing these is flagged ``saturated`` and the channel's
    last good value is held in its place):

    - ``full_scale``: raw value at which the converter saturates (``None``: no full scale).
    - ``max_rise_rel`` / ``max_drop_rel``: largest plausible rise / drop of a reading
      relative to its baseline.
    """

    sample_rate_hz: float = 200.0
    calibration_s: float = 0.5
    smoothing_s: float = 0.1
    release_smoothing_s: float = 0.025
    fast_on_factor: float = 2.0
    spike_filter: bool = True
    glitch_filter: bool = True
    glitch_sigma: float = 8.0
    glitch_max_s: float = 0.125
    contact_on_sigma: float = 8.0
    contact_off_sigma: float = 4.0
    min_contact_rel: float = 0.002
    min_release_rel: float = 0.001
    on_peak_fraction: float = 0.2
    off_peak_fraction: float = 0.1
    rearm_fraction: float = 0.25
    release_fraction: float = 0.2
    peak_memory_s: float = 1.0
    debounce_on_s: float = 0.015
    debounce_off_s: float = 0.03
    lift_fraction: float = 0.4
    lift_arm_sigma: float = 6.0
    lift_sigma: float = 3.0
    connectivity: int = 4
    seeded_blobs: bool = True
    common_mode_quantile: float = 0.25
    baseline_block_s: float = 0.1
    drift_tau_s: float = 1.0
    frozen_drift_tau_s: float = 3.0
    hold_s: float = 0.5
    skin_hold_s: float = 0.2
    recover_sigma: float = 6.0
    recover_min_rel: float = 0.001
    recover_tau_s: float = 0.05
    recover_blocks: int = 4
    common_drift: bool = True
    common_drift_min_fraction: float = 0.1
    common_drift_max_drop_rel_per_s: float = 0.001
    disturbed_sigma: float = 2.0
    disturbed_max_s: float = 10.0
    stale_contact_s: float = 5.0
    stale_contact_rel: float = 0.01
    max_contact_s: float = 60.0
    noise_floor_rel: float = 2e-5
    noise_floor_fraction: float = 0.5
    calib_disturb_ratio: float = 5.0
    calib_disturb_min_rel: float = 0.002
    calib_disturb_abs_rel: float = 0.02
    dead_flat_rel: float = 1e-7
    dead_nan_fraction: float = 0.5
    full_scale: float | None = None
    max_rise_rel: float = 4.0
    max_drop_rel: float = 0.6

    def __post_init__(self) -> None:
        positive = (
            "sample_rate_hz",
            "calibration_s",
            "smoothing_s",
            "contact_on_sigma",
            "contact_off_sigma",
            "min_contact_rel",
            "min_release_rel",
            "baseline_block_s",
            "drift_tau_s",
            "recover_sigma",
            "recover_min_rel",
            "recover_tau_s",
            "noise_floor_rel",
            "calib_disturb_ratio",
            "calib_disturb_min_rel",
            "calib_disturb_abs_rel",
            "dead_flat_rel",
            "max_rise_rel",
            "max_drop_rel",
            "peak_memory_s",
            "release_smoothing_s",
            "glitch_sigma",
            "glitch_max_s",
            "frozen_drift_tau_s",
            "common_drift_max_drop_rel_per_s",
            "disturbed_max_s",
            "lift_arm_sigma",
            "lift_sigma",
        )
        for name in positive:
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
                raise ConfigError(f"{name} must be a positive finite number, got {value!r}")
        non_negative = (
            "debounce_on_s",
            "debounce_off_s",
            "hold_s",
            "noise_floor_fraction",
            "common_drift_min_fraction",
            "max_contact_s",
            "stale_contact_s",
            "stale_contact_rel",
            "on_peak_fraction",
            "off_peak_fraction",
            "rearm_fraction",
            "release_fraction",
            "common_mode_quantile",
            "fast_on_factor",
            "skin_hold_s",
            "disturbed_sigma",
        )
        for name in non_negative:
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value >= 0):
                raise ConfigError(f"{name} must be a non-negative finite number, got {value!r}")
        if not (isinstance(self.recover_blocks, int) and self.recover_blocks >= 1):
            raise ConfigError(
                f"recover_blocks must be an integer >= 1, got {self.recover_blocks!r}"
            )
        if self.common_mode_quantile >= 1:
            raise ConfigError("common_mode_quantile must be below 1")
        if 0 < self.fast_on_factor < 1:
            raise ConfigError(
                f"fast_on_factor must be 0 (off) or >= 1, got {self.fast_on_factor!r}"
            )
        if not isinstance(self.seeded_blobs, bool):
            raise ConfigError(f"seeded_blobs must be true or false, got {self.seeded_blobs!r}")
        for name in ("spike_filter", "glitch_filter"):
            if not isinstance(getattr(self, name), bool):
                raise ConfigError(f"{name} must be true or false, got {getattr(self, name)!r}")
        if not 0 <= self.off_peak_fraction <= self.on_peak_fraction < 1:
            raise ConfigError(
                "peak fractions need 0 <= off_peak_fraction <= on_peak_fraction < 1, got "
                f"{self.off_peak_fraction!r} and {self.on_peak_fraction!r}"
            )
        if not isinstance(self.common_drift, bool):
            raise ConfigError(f"common_drift must be true or false, got {self.common_drift!r}")
        if self.common_drift_min_fraction > 1:
            raise ConfigError("common_drift_min_fraction must be at most 1")
        if not 0 <= self.lift_fraction < 1:
            raise ConfigError(f"lift_fraction must be in [0, 1), got {self.lift_fraction!r}")
        if not 0 <= self.release_fraction <= self.rearm_fraction < 1:
            raise ConfigError(
                "need 0 <= release_fraction <= rearm_fraction < 1, got "
                f"{self.release_fraction!r} and {self.rearm_fraction!r}"
            )
        if self.contact_off_sigma >= self.contact_on_sigma:
            raise ConfigError("contact_off_sigma must be below contact_on_sigma (hysteresis)")
        if self.min_release_rel >= self.min_contact_rel:
            raise ConfigError("min_release_rel must be below min_contact_rel (hysteresis)")
        if self.connectivity not in (4, 8):
            raise ConfigError(f"connectivity must be 4 or 8, got {self.connectivity!r}")
        if self.max_drop_rel >= 1:
            raise ConfigError("max_drop_rel must be below 1 (a reading cannot drop below zero)")
        if self.full_scale is not None and not (
            isinstance(self.full_scale, int | float) and math.isfinite(self.full_scale)
        ):
            raise ConfigError(
                f"full_scale must be a finite number or None, got {self.full_scale!r}"
            )
        if self.calibration_frames < self.window_frames + 10:
            raise ConfigError(
                f"calibration_s={self.calibration_s:g} is too short: it needs at least "
                f"{self.window_frames + 10} frames (smoothing window + 10) at "
                f"{self.sample_rate_hz:g} Hz"
            )

    def _frames(self, seconds: float) -> int:
        return int(round(seconds * self.sample_rate_hz))

    @property
    def window_frames(self) -> int:
        """Frames in the causal moving average (at least 1)."""
        return max(1, self._frames(self.smoothing_s))

    @property
    def release_window_frames(self) -> int:
        """Frames in the short moving average that lets a lifted finger release fast."""
        return max(1, self._frames(self.release_smoothing_s))

    @property
    def calibration_frames(self) -> int:
        """Frames in one calibration period."""
        return max(1, self._frames(self.calibration_s))

    @property
    def glitch_max_frames(self) -> int:
        """Longest glitch pulse (frames) the glitch filter removes."""
        return max(1, self._frames(self.glitch_max_s))

    @property
    def block_frames(self) -> int:
        """Frames per baseline-update block (at least 1)."""
        return max(1, self._frames(self.baseline_block_s))

    @property
    def hold_blocks(self) -> int:
        """Blocks a channel stays frozen after its last contact (rounded up)."""
        return int(math.ceil(self._frames(self.hold_s) / self.block_frames))

    @property
    def disturbed_max_blocks(self) -> int:
        """Blocks after which a lasting sink of the whole skin is accepted as drift."""
        return max(1, int(math.ceil(self._frames(self.disturbed_max_s) / self.block_frames)))

    @property
    def skin_hold_blocks(self) -> int:
        """Blocks the skin counts as touched after its last active channel (rounded up)."""
        return int(math.ceil(self._frames(self.skin_hold_s) / self.block_frames))

    @property
    def frozen_drift_alpha(self) -> float:
        """Per-block weight with which frozen, inactive channels follow a rising level."""
        return -math.expm1(-self.block_frames / self.sample_rate_hz / self.frozen_drift_tau_s)

    @property
    def max_contact_blocks(self) -> int:
        """Blocks of continuous activity after which a channel is re-baselined (0: never)."""
        if self.max_contact_s == 0:
            return 0
        return max(1, int(math.ceil(self._frames(self.max_contact_s) / self.block_frames)))

    @property
    def stale_contact_blocks(self) -> int:
        """Blocks of continuous weak activity after which a channel is re-baselined."""
        return max(1, int(math.ceil(self._frames(self.stale_contact_s) / self.block_frames)))

    @property
    def debounce_on_frames(self) -> int:
        """Consecutive active frames needed before the skin counts as touched (>= 1)."""
        return max(1, self._frames(self.debounce_on_s))

    @property
    def debounce_off_frames(self) -> int:
        """Consecutive inactive frames needed before the skin counts as released (>= 1)."""
        return max(1, self._frames(self.debounce_off_s))

    @property
    def peak_decay(self) -> float:
        """Per-frame factor of the decaying recent-peak envelope of each channel."""
        return math.exp(-1.0 / (self.peak_memory_s * self.sample_rate_hz))

    @property
    def drift_alpha(self) -> float:
        """Per-block weight of a new block mean in drift tracking."""
        return -math.expm1(-self.block_frames / self.sample_rate_hz / self.drift_tau_s)

    @property
    def recover_alpha(self) -> float:
        """Per-block weight of a new block mean in fast recovery."""
        return -math.expm1(-self.block_frames / self.sample_rate_hz / self.recover_tau_s)

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict) -> ConditioningConfig:
        """Build from a dict; missing keys take defaults, unknown keys are a ConfigError."""
        return from_dict(cls, d, "conditioning settings")
