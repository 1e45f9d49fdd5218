"""Lift detection on the raw relative signal: a lifted hand releases the skin at once.

The moving average that smooths the conditioned signal needs most of its window (and the
detector's debounce) before a lifted finger stops counting: 50-100 ms in which the arm
would go on moving.  A lift shows in the raw relative change ``(C - C0) / C0`` a frame or
two after it happens (the fabric springs back with its own 10-30 ms time constant), so
:class:`LiftDetector` watches that, frame by frame, beside the moving average:

- the *touch region*: the channels whose recent raw peak (a decaying envelope, as the
  contact detector keeps one on the smoothed signal) stood above ``sigma`` times the
  channel's raw noise -- the channels a fingertip presses or pressed lately, without the
  noise of the untouched ones;
- its *sum* ``S``, the raw relative change summed over the region, and ``P``, the recent
  peak of ``S`` (the same decaying envelope): a finger sliding from one channel to the
  next keeps ``S`` (what one channel loses the next gains);
- the *lowest dip*: the least ``S / P`` of the touch so far, counting only frames at least
  ``delay`` frames old (while the hand was surely on the skin: a lift's own fall never
  counts) and only while ``P`` stands ``arm_sigma`` noise sds above zero.  A finger
  crossing a channel border, a wobbling press, a hand's own mains pickup (which
  calibration never saw) all show here as dips the touch came back from.

The skin counts as *released* (``lifted``) on the first frame in which

1. the touch has been judged for at least ``delay`` frames (2 x ``delay`` since ``P``
   first stood above the noise);
2. the lowest dip times ``P`` still stands ``arm_sigma`` noise sds above zero (the noise
   of ``S``: the square root of the region's summed raw noise variances), so a light
   finger on a noisy skin, whose sum wanders through the noise, is never released this
   way (the moving average still releases it, as before);
3. ``S`` has fallen below ``fraction`` of the lowest dip times ``P``;
4. no channel next to an active one still *holds*: reads above both ``fraction`` of its
   own recent peak and ``sigma`` noise sds.  A second finger still pressing when the
   first lifts, or the next channel of a sliding finger, holds the touch.

It stays released until no channel is active any more (the moving average has released
them all: then the usual debounce takes over), or until ``S`` comes back, above half way
between the release level and ``P`` or at the release level for ``back_frames`` frames in
a row (a finger landing again at once).

Everything is stepped frame by frame with state carried between calls, so any chunking
gives identical results.  The detector only reads the signal: the moving average, the
``signal`` output, ``active`` and the baseline tracking are untouched; the conditioner
only uses ``lifted`` to clear its debounced ``touched`` flag early
(:meth:`~wovenskin.signal.contacts.ContactDetector.update_touched`).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np


def _grown(active: np.ndarray) -> np.ndarray:
    """``(n, R, C)`` masks grown by their 8 neighbours within each frame (never across
    frames): a binary dilation without scipy's per-call overhead on skin-sized frames."""
    n, rows, cols = active.shape
    padded = np.zeros((n, rows + 2, cols + 2), dtype=bool)
    padded[:, 1:-1, 1:-1] = active
    out = active.copy()
    for dr in (0, 1, 2):
        for dc in (0, 1, 2):
            if dr != 1 or dc != 1:
                out |= padded[:, dr : dr + rows, dc : dc + cols]
    return out


@dataclass(frozen=True)
class LiftSettings:
    """The rules of :class:`LiftDetector` (module doc); ``fraction`` 0 turns it off.

    ``peak_decay`` is the per-frame factor of the decaying peaks; ``delay`` and
    ``back_frames`` are frame counts.
    """

    fraction: float = 0.4
    arm_sigma: float = 6.0
    sigma: float = 3.0
    peak_decay: float = 0.995
    delay: int = 10
    back_frames: int = 6

    def __post_init__(self) -> None:
        if not 0 <= self.fraction < 1:
            raise ValueError(f"lift fraction must be in [0, 1), got {self.fraction!r}")
        for name in ("arm_sigma", "sigma"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"lift {name} must be a positive finite number, got {value!r}")
        if not 0 <= self.peak_decay < 1:
            raise ValueError(f"peak_decay must be in [0, 1), got {self.peak_decay!r}")
        for name in ("delay", "back_frames"):
            if getattr(self, name) < 1:
                raise ValueError(f"{name} must be at least 1 frame, got {getattr(self, name)!r}")

    @property
    def enabled(self) -> bool:
        return self.fraction > 0

    @classmethod
    def from_config(cls, config) -> LiftSettings:
        """Settings of a :class:`~wovenskin.signal.config.ConditioningConfig`."""
        return cls(
            fraction=config.lift_fraction,
            arm_sigma=config.lift_arm_sigma,
            sigma=config.lift_sigma,
            peak_decay=config.peak_decay,
            delay=max(1, config.window_frames // 2),
            back_frames=config.debounce_off_frames,
        )


def raw_noise(noise: np.ndarray, step_noise: np.ndarray | None, window_frames: int) -> np.ndarray:
    """Per-channel noise sd of one raw relative frame, from a calibration.

    The smoothed signal's ``noise`` scaled back by the square root of the moving average's
    window (what white noise would need to average down to it; the spike filter's median
    makes neighbouring frames alike, so this errs high), and never below ``step_noise /
    sqrt(2)`` (frame-to-frame changes have twice the variance of white noise; mains
    pickup, which the moving average cancels, shows there).
    """
    raw = np.asarray(noise, dtype=np.float64) * math.sqrt(max(1, int(window_frames)))
    if step_noise is None:  # a calibration stored before it had one
        return raw
    return np.maximum(np.asarray(step_noise, dtype=np.float64) / math.sqrt(2.0), raw)


class LiftDetector:
    """Raw-signal lift detection with state carried between calls (module doc).

    ``noise`` is each channel's raw noise sd ``(R, C)`` in relative units (see
    :func:`raw_noise`); ``live`` marks the channels to watch (dead ones never count).
    """

    def __init__(self, noise: np.ndarray, live: np.ndarray, settings: LiftSettings) -> None:
        noise = np.asarray(noise, dtype=np.float64)
        live = np.asarray(live, dtype=bool)
        if noise.ndim != 2 or live.shape != noise.shape:
            raise ValueError(
                f"noise and live must be two equal (rows, cols) grids, got {noise.shape} "
                f"and {live.shape}"
            )
        live = live & np.isfinite(noise) & (noise > 0)
        self.settings = settings
        self.shape: tuple[int, int] = (int(noise.shape[0]), int(noise.shape[1]))
        self._live = live
        self._variance = np.where(live, noise * noise, 0.0)
        self._level = np.where(live, settings.sigma * noise, np.inf)
        self.reset()

    def reset(self) -> None:
        """Forget all state: no recent peaks, not released."""
        self._envelope = np.zeros(self.shape, dtype=np.float64)
        self._peak = 0.0
        self._released = False
        self._release_level = 0.0
        self._back = 0  # frames in a row back at the release level since the release
        self._lowest = math.inf  # least sum / peak of this touch, up to ``delay`` frames ago
        self._seen = 0  # frames that went into it
        self._recent: deque[float | None] = deque(maxlen=self.settings.delay)  # the rest

    def update(self, relative: np.ndarray, active: np.ndarray) -> np.ndarray:
        """``lifted`` ``(n,)`` for raw relative frames ``(n, R, C)`` and their active
        channels ``(n, R, C)`` (from the contact detector)."""
        n = relative.shape[0]
        lifted = np.zeros(n, dtype=bool)
        if n == 0 or not self.settings.enabled:
            return lifted
        if relative.shape != active.shape or relative.shape[1:] != self.shape:
            raise ValueError(
                f"relative {relative.shape} and active {active.shape} must both be "
                f"(n, {self.shape[0]}, {self.shape[1]})"
            )
        rules = self.settings
        rel = np.where(self._live, relative, 0.0)
        envelope = np.empty(rel.shape)
        before = self._envelope
        for i in range(n):
            before = envelope[i] = np.maximum(rel[i], before * rules.peak_decay)
        self._envelope = before.copy()
        near = _grown(active) & self._live
        region = envelope > self._level
        total = np.where(region, rel, 0.0).reshape(n, -1).sum(axis=1)
        spread = np.sqrt(np.where(region, self._variance, 0.0).reshape(n, -1).sum(axis=1))
        holding = near & (rel > np.maximum(rules.fraction * envelope, self._level))
        holds = holding.reshape(n, -1).any(axis=1).tolist()
        occupied = near.reshape(n, -1).any(axis=1).tolist()
        sums, spreads = total.tolist(), spread.tolist()
        peak, released, level = self._peak, self._released, self._release_level
        lowest, seen, back, recent = self._lowest, self._seen, self._back, self._recent
        for i in range(n):
            if not occupied[i]:
                peak, released, lowest, seen, back = 0.0, False, math.inf, 0, 0
                recent.clear()
                continue
            s = sums[i]
            peak = max(s, peak * rules.peak_decay)
            armed = peak > 0 and peak >= rules.arm_sigma * spreads[i]
            if len(recent) == recent.maxlen and recent[0] is not None:
                lowest = min(lowest, recent[0])
                seen += 1
            recent.append(s / peak if armed else None)
            if released:
                back = back + 1 if s >= level else 0
                released = s <= 0.5 * (level + peak) and back < rules.back_frames
            elif (
                not holds[i]
                and seen >= rules.delay
                and spreads[i] > 0
                and lowest * peak >= rules.arm_sigma * spreads[i]
            ):
                level = rules.fraction * min(lowest, 1.0) * peak
                released = s < level
                back = 0
            lifted[i] = released
        self._peak, self._released, self._release_level = peak, released, level
        self._lowest, self._seen, self._back = lowest, seen, back
        return lifted
