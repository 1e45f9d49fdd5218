"""The conditioning pipeline: raw frames in, relative smoothed signal and contacts out.

:class:`Conditioner` chains, for every frame,

1. the input guard: NaN/inf and implausible readings hold the channel's last good value
   and are flagged (:mod:`~wovenskin.signal.baseline`),
2. the glitch filters (:mod:`~wovenskin.signal.filters`): glitch pulses smeared by a
   firmware average are removed, then one-frame spikes by a causal median of three,
3. the relative change ``(C - C0) / C0``,
4. the causal moving average (``signal``) and a short one (the fast signal, for
   detection only),
5. contact detection: common-mode removal, hysteresis (with fast release) and blob
   seeding (:mod:`~wovenskin.signal.contacts`),
6. lift detection on the relative change of step 3 (:mod:`~wovenskin.signal.lift`): a
   lifted hand releases the skin a frame or two after it leaves, before the moving
   average has seen it,
7. drift tracking of ``C0`` once per block of frames, from the filtered readings and
   the active channels,

then debounces "touched" (cleared at once where step 6 saw a lift) and extracts contact
blobs for the whole chunk.  Frames are cut only at baseline-block boundaries, and every
step carries its state, so feeding a stream one frame at a time, all at once or in any
chunks gives bit-identical results.

:func:`condition_recording` calibrates on the first ``calibration_s`` of a recording and
conditions all of it, calibration frames included.

:class:`LiveConditioner` is what a real-time pipeline feeds.  In state ``"calibrating"``
it collects ``calibration_s`` of frames and calibrates.  When something touched the skin
meanwhile it warns (``warnings`` and the ``on_warning`` callback) and collects a fresh
period, up to ``max_retries`` times; after that it accepts the calibration (baseline
recovery repairs touched channels after lift-off).  It then conditions the calibration
frames silently, to fill the filters and the block state exactly as
:func:`condition_recording` would, and enters ``"running"``.  Frames that arrive in the
same call after calibration completes are conditioned at once, so the output does not
depend on how frames are grouped into calls.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from wovenskin.errors import DataError
from wovenskin.signal.baseline import BaselineTracker
from wovenskin.signal.calibration import Calibration, calibrate, glitch_threshold
from wovenskin.signal.config import ConditioningConfig
from wovenskin.signal.contacts import Contact, ContactDetector
from wovenskin.signal.filters import CausalMovingAverage, SpikeFilter, StepGlitchFilter
from wovenskin.signal.lift import LiftDetector, LiftSettings, raw_noise

CALIBRATING = "calibrating"  # LiveConditioner.state values
RUNNING = "running"


@dataclass
class ConditionedFrames:
    """Conditioned output for ``N`` consecutive frames."""

    signal: np.ndarray  # (N, R, C) float32 smoothed (C - C0) / C0
    active: np.ndarray  # (N, R, C) bool channels in contact (after hysteresis)
    touched: np.ndarray  # (N,) bool debounced "something touches the skin"
    n_contacts: np.ndarray  # (N,) int64 contact blobs per frame
    contacts: list[list[Contact]]  # N lists of blobs
    saturated: np.ndarray  # (N, R, C) bool at full scale or implausible (held value used)
    dead: np.ndarray  # (R, C) bool dead since calibration (never active)
    baseline: np.ndarray  # (R, C) float64 baseline after the last frame
    invalid: np.ndarray  # (N, R, C) bool reading was NaN/inf (last good value held)
    index: np.ndarray  # (N,) int64 frame index since the conditioner started
    fast: np.ndarray | None = None  # (N, R, C) float32 short moving average (contact tracking)

    @property
    def tracking_signal(self) -> np.ndarray:
        """The signal contact tracking reads: the short moving average when there is one
        (it lags a moving finger by a quarter of the long one), else ``signal``."""
        return self.signal if self.fast is None else self.fast

    def __len__(self) -> int:
        return int(self.signal.shape[0])

    @classmethod
    def empty(cls, dead: np.ndarray, baseline: np.ndarray, start_index: int = 0):
        """No frames, for a skin with these ``dead`` channels and ``baseline``."""
        rows, cols = dead.shape
        return cls(
            signal=np.zeros((0, rows, cols), dtype=np.float32),
            active=np.zeros((0, rows, cols), dtype=bool),
            touched=np.zeros(0, dtype=bool),
            n_contacts=np.zeros(0, dtype=np.int64),
            contacts=[],
            saturated=np.zeros((0, rows, cols), dtype=bool),
            dead=dead.copy(),
            baseline=baseline.copy(),
            invalid=np.zeros((0, rows, cols), dtype=bool),
            index=np.arange(start_index, start_index, dtype=np.int64),
            fast=np.zeros((0, rows, cols), dtype=np.float32),
        )

    @staticmethod
    def concat(parts: list[ConditionedFrames]) -> ConditionedFrames:
        """Join consecutive parts; ``dead`` and ``baseline`` come from the last one."""
        if not parts:
            raise ValueError("cannot concatenate an empty list of ConditionedFrames")
        contacts: list[list[Contact]] = []
        for part in parts:
            contacts.extend(part.contacts)
        last = parts[-1]
        return ConditionedFrames(
            signal=np.concatenate([p.signal for p in parts]),
            active=np.concatenate([p.active for p in parts]),
            touched=np.concatenate([p.touched for p in parts]),
            n_contacts=np.concatenate([p.n_contacts for p in parts]),
            contacts=contacts,
            saturated=np.concatenate([p.saturated for p in parts]),
            dead=last.dead.copy(),
            baseline=last.baseline.copy(),
            invalid=np.concatenate([p.invalid for p in parts]),
            index=np.concatenate([p.index for p in parts]),
            fast=(
                None
                if any(p.fast is None for p in parts)
                else np.concatenate([p.fast for p in parts])
            ),
        )


def as_frames(raw: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """``raw`` ``(N, R, C)`` or ``(R, C)`` as a new float64 ``(N, R, C)`` array.

    Raises ``ValueError`` with the expected shape for anything else.
    """
    arr = np.asarray(raw)
    if arr.ndim == 2:
        arr = arr.reshape(1, *arr.shape)
    rows, cols = shape
    if arr.ndim != 3 or arr.shape[1] != rows or arr.shape[2] != cols:
        raise ValueError(
            f"expected raw frames shaped (N, {rows}, {cols}) or ({rows}, {cols}), got "
            f"{np.shape(raw)}"
        )
    if arr.dtype.kind not in "fiu":
        raise ValueError(f"raw frames must be real numbers, got dtype {arr.dtype}")
    return arr.astype(np.float64)


class Conditioner:
    """Conditions a stream of raw frames with a fixed calibration (see module doc)."""

    def __init__(self, calibration: Calibration, config: ConditioningConfig) -> None:
        self.calibration = calibration
        self.config = config
        self._tracker = BaselineTracker(calibration, config)
        self.shape = self._tracker.shape
        self.dead = self._tracker.dead
        self._spikes = SpikeFilter(self._tracker.resting_level) if config.spike_filter else None
        self._glitches = None
        if config.glitch_filter and calibration.step_noise is not None:
            threshold = glitch_threshold(
                calibration.step_noise, self._tracker.resting_level, ~self.dead, config
            )
            self._glitches = StepGlitchFilter(
                threshold, self._tracker.resting_level, config.glitch_max_frames
            )
        self._smoother = CausalMovingAverage(config.window_frames, self.shape)
        self._fast = (
            CausalMovingAverage(config.release_window_frames, self.shape)
            if config.release_window_frames < config.window_frames
            else None
        )
        self._detector = ContactDetector.from_calibration(calibration.noise, self.dead, config)
        lift = LiftSettings.from_config(config)
        self._lift = (
            LiftDetector(
                raw_noise(calibration.noise, calibration.step_noise, config.window_frames),
                ~self.dead,
                lift,
            )
            if lift.enabled
            else None
        )
        self._next_index = 0

    @property
    def baseline(self) -> np.ndarray:
        """Current baseline ``(R, C)`` (a copy)."""
        return self._tracker.baseline

    @property
    def frames_processed(self) -> int:
        return self._next_index

    @property
    def on_threshold(self) -> np.ndarray:
        """Per-channel signal level at which a channel turns active (+inf when dead)."""
        return self._detector.on_threshold.copy()

    @property
    def off_threshold(self) -> np.ndarray:
        """Per-channel signal level below which an active channel turns off."""
        return self._detector.off_threshold.copy()

    def process(self, raw: np.ndarray) -> ConditionedFrames:
        """Condition ``raw`` ``(N, R, C)`` or one frame ``(R, C)``; state carries over."""
        x = as_frames(raw, self.shape)
        n = x.shape[0]
        start = self._next_index
        if n == 0:
            return ConditionedFrames.empty(self.dead, self.baseline, start)
        if n <= self._tracker.frames_to_block_end:  # one block: the live, per-frame case
            signal, active, lifted, invalid, saturated, fast = self._condition_segment(x)
            labels = self._detector.last_labels
        else:
            segments = []
            pos = 0
            while pos < n:
                stop = pos + min(self._tracker.frames_to_block_end, n - pos)
                segments.append((*self._condition_segment(x[pos:stop]), self._detector.last_labels))
                pos = stop
            lengths = [len(s[0]) for s in segments]
            labels = _join_labels([s[6] for s in segments], lengths)
            fast = np.concatenate([s[5] for s in segments])
            signal = np.concatenate([s[0] for s in segments])
            active = np.concatenate([s[1] for s in segments])
            lifted = np.concatenate([s[2] for s in segments])
            invalid = _join_flags([s[3] for s in segments], lengths, self.shape)
            saturated = _join_flags([s[4] for s in segments], lengths, self.shape)
        self._next_index += n
        if invalid is None:
            invalid = np.zeros(x.shape, dtype=bool)
        if saturated is None:
            saturated = np.zeros(x.shape, dtype=bool)
        touched = self._detector.update_touched(active, lifted)
        if active.any():
            contacts = self._detector.contacts(signal, active, labels)
            n_contacts = np.array([len(c) for c in contacts], dtype=np.int64)
        else:
            contacts = [[] for _ in range(n)]
            n_contacts = np.zeros(n, dtype=np.int64)
        return ConditionedFrames(
            signal=signal.astype(np.float32),
            active=active,
            touched=touched,
            n_contacts=n_contacts,
            contacts=contacts,
            saturated=saturated,
            dead=self.dead.copy(),
            baseline=self._tracker.baseline,
            invalid=invalid,
            index=np.arange(start, start + n, dtype=np.int64),
            fast=fast.astype(np.float32),
        )

    def _condition_segment(
        self, x: np.ndarray
    ) -> tuple[
        np.ndarray, np.ndarray, np.ndarray, np.ndarray | None, np.ndarray | None, np.ndarray
    ]:
        """Steps 1-7 on frames ``x`` within one baseline block: ``(signal, active, lifted,
        invalid, saturated, fast)`` with the flags ``None`` when no reading was bad (``fast``
        is ``signal`` itself when there is no short moving average)."""
        clean, invalid, saturated = self._tracker.guard(x)
        if self._glitches is not None:
            clean = self._glitches.apply(clean)
        if self._spikes is not None:
            clean = self._spikes.apply(clean)
        relative = self._tracker.relative(clean)
        smoothed = self._smoother.apply(relative)
        fast = self._fast.apply(relative) if self._fast is not None else None
        active = self._detector.update_active(smoothed, fast)
        if self._lift is not None:
            lifted = self._lift.update(relative, active)
        else:
            lifted = np.zeros(x.shape[0], dtype=bool)
        self._tracker.accumulate(clean, active)
        return smoothed, active, lifted, invalid, saturated, smoothed if fast is None else fast


def _join_labels(labels: list[np.ndarray | None], lengths: list[int]) -> np.ndarray | None:
    """Blob labels of consecutive segments as one array with distinct ids, if all have them.

    A segment without active channels may have no labels (``None``): it contributes
    zeros.  Returns ``None`` when no segment has labels (contacts are then labelled anew).
    """
    if len(labels) == 1 or all(lab is None for lab in labels):
        return labels[0]
    shape = next(lab.shape[1:] for lab in labels if lab is not None)
    parts, offset = [], 0
    for lab, length in zip(labels, lengths, strict=True):
        if lab is None:
            parts.append(np.zeros((length, *shape), dtype=np.int64))
            continue
        lab = lab.astype(np.int64)
        parts.append(np.where(lab > 0, lab + offset, 0))
        offset += int(lab.max())
    return np.concatenate(parts)


def _join_flags(flags: list[np.ndarray | None], lengths: list[int], shape) -> np.ndarray | None:
    """Concatenate per-segment flag arrays, where ``None`` stands for all-False."""
    if all(f is None for f in flags):
        return None
    return np.concatenate(
        [
            f if f is not None else np.zeros((length, *shape), dtype=bool)
            for f, length in zip(flags, lengths, strict=True)
        ]
    )


def condition_recording(
    raw: np.ndarray, config: ConditioningConfig
) -> tuple[Calibration, ConditionedFrames]:
    """Calibrate on the first ``calibration_s`` of ``raw`` ``(N, R, C)`` and condition it all.

    Raises ``ValueError`` when the recording is malformed or shorter than the calibration.
    """
    raw = np.asarray(raw)
    if raw.ndim != 3:
        raise DataError(f"a recording must be shaped (N, rows, cols), got {raw.shape}")
    calibration = calibrate(raw[: config.calibration_frames], config)
    conditioner = Conditioner(calibration, config)
    return calibration, conditioner.process(raw)


class LiveConditioner:
    """Calibration phase with warning and retry, then frame-by-frame conditioning."""

    def __init__(
        self,
        config: ConditioningConfig,
        rows: int,
        cols: int,
        max_retries: int = 3,
        on_warning: Callable[[str], None] | None = None,
    ) -> None:
        if rows < 1 or cols < 1:
            raise ValueError(f"skin needs at least one row and column, got {rows}x{cols}")
        if max_retries < 0:
            raise ValueError(f"max_retries must be >= 0, got {max_retries}")
        self.config = config
        self.shape = (int(rows), int(cols))
        self.max_retries = int(max_retries)
        self.on_warning = on_warning
        self.warnings: list[str] = []
        self.state: str = CALIBRATING
        self.calibration: Calibration | None = None
        self.conditioner: Conditioner | None = None
        self.attempts = 0  # calibration periods collected since the last (re)calibration
        self._pending: list[np.ndarray] = []
        self._pending_frames = 0

    def recalibrate(self) -> None:
        """Drop the current calibration and calibrate again on the next frames."""
        self.state = CALIBRATING
        self.calibration = None
        self.conditioner = None
        self.attempts = 0
        self._pending = []
        self._pending_frames = 0

    def feed(self, raw: np.ndarray) -> ConditionedFrames | None:
        """Feed ``(N, R, C)`` or one ``(R, C)`` frame; ``None`` when nothing was conditioned.

        Raises ``ValueError`` for frames of the wrong shape or dtype.
        """
        x = as_frames(raw, self.shape)
        if self.state == RUNNING:
            assert self.conditioner is not None
            return self.conditioner.process(x)
        need = self.config.calibration_frames
        while self.state == CALIBRATING:
            take = min(need - self._pending_frames, x.shape[0])
            if take > 0:
                self._pending.append(x[:take])
                self._pending_frames += take
                x = x[take:]
            if self._pending_frames < need:
                return None
            self._finish_period(np.concatenate(self._pending))
        assert self.conditioner is not None
        return self.conditioner.process(x) if x.shape[0] else None

    def _finish_period(self, frames: np.ndarray) -> None:
        self._pending = []
        self._pending_frames = 0
        self.attempts += 1
        try:
            calibration = calibrate(frames, self.config)
        except ValueError as exc:
            self._warn(f"calibration failed: {exc}; retrying")
            return
        if calibration.touched.any() and self.attempts <= self.max_retries:
            self._warn(
                f"{calibration.message}; keep the skin untouched, retrying "
                f"({self.attempts}/{self.max_retries})"
            )
            return
        if calibration.touched.any():
            self._warn(
                f"{calibration.message}; accepting it after {self.max_retries} retries, "
                "touched channels will re-baseline after lift-off"
            )
        elif calibration.dead.any():
            self._warn(calibration.message)
        self.calibration = calibration
        self.conditioner = Conditioner(calibration, self.config)
        self.conditioner.process(frames)  # prime the filters exactly like a recording
        self.state = RUNNING

    def _warn(self, message: str) -> None:
        self.warnings.append(message)
        if self.on_warning is not None:
            self.on_warning(message)
