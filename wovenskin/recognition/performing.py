"""Whether the fingers on the skin are *being performed* -- moving or changing pressure --
or merely resting: :class:`PerformingDetector` and its :class:`PerformingSettings`, one
input of the execution rules (:mod:`~wovenskin.recognition.arbiter`, which re-exports them).

"Being performed" (:class:`PerformingDetector`): over the *touch region* -- the active
channels and their 8 neighbours -- each frame gets the total signal ``S`` (of the
signal above 15 % of the frame's peak: a soft floor, so channels flickering at their
contact threshold do not jump the measures), its centroid (mm) and its spread (rms
distance of the signal from the centroid, mm).  Frame ``i`` is compared with frame
``i - L`` (``L = round(span_s * rate)``, 0.1 s): the fingers are being performed when
the touch region is not empty in either and

- the centroid moved faster than ``min_speed_mm_s`` (a swipe, a circle), or
- the spread changed faster than ``min_spread_rate_mm_s`` (a pinch: the centroid of two
  converging fingers hardly moves), or
- ``|S_i - S_{i-L}| / max(S_i, S_{i-L})`` reaches ``min_pressure_change`` (a push, a
  landing or a lift: a contact appearing or vanishing is a change of 1).

The defaults (30 mm/s, 20 mm/s, 0.2) come from simulated streams of 20 people and skins:
resting phases (from 0.25 s after the motion ended, past the 0.1 s moving average) never
showed more than 3 consecutive performing frames (the preemption dwell needs 21), while
swipes, circles and pinches are performing for most of their motion; a slow push press
is performing for at least 7 consecutive frames after its landing.  The signal is the
conditioner's 0.1 s moving average, so the flag lags the fingers by up to about 0.1 s.

Everything is causal and carries its state between calls, so any split of the frames
into calls gives the same flags.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from wovenskin.errors import ConfigError
from wovenskin.skin.layout import DEFAULT_COL_PITCH_MM, DEFAULT_ROW_PITCH_MM
from wovenskin.tracking.touch import RELATIVE_FLOOR


def check_positive(name: str, value: float) -> None:
    """One :class:`ConfigError` line unless ``value`` is a positive finite number."""
    if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
        raise ConfigError(f"{name} must be a positive finite number, got {value!r}")


@dataclass(frozen=True)
class PerformingSettings:
    """When fingers count as being performed rather than resting (see the module doc)."""

    span_s: float = 0.1
    min_speed_mm_s: float = 30.0
    min_spread_rate_mm_s: float = 20.0
    min_pressure_change: float = 0.2
    row_pitch_mm: float = DEFAULT_ROW_PITCH_MM
    col_pitch_mm: float = DEFAULT_COL_PITCH_MM

    def __post_init__(self) -> None:
        for name in (
            "span_s",
            "min_speed_mm_s",
            "min_spread_rate_mm_s",
            "row_pitch_mm",
            "col_pitch_mm",
        ):
            check_positive(name, getattr(self, name))
        change = self.min_pressure_change
        if not (isinstance(change, int | float) and 0.0 < change <= 1.0):
            raise ConfigError(f"min_pressure_change must lie in (0, 1], got {change!r}")

    def span_frames(self, sample_rate_hz: float) -> int:
        """Frames between the two compared frames (at least 1)."""
        return max(1, int(round(self.span_s * sample_rate_hz)))


_REGION_STRUCTURE = np.zeros((3, 3, 3), dtype=bool)
_REGION_STRUCTURE[1] = True  # 8 neighbours within a frame, never across frames


def touch_features(
    signal: np.ndarray,
    active: np.ndarray,
    row_pitch_mm: float = DEFAULT_ROW_PITCH_MM,
    col_pitch_mm: float = DEFAULT_COL_PITCH_MM,
) -> np.ndarray:
    """``(N, 4)`` float64 per frame: total signal, centroid row and col (mm), spread (mm).

    Each channel weighs by how far its signal rises above :data:`RELATIVE_FLOOR` times
    the frame's peak, within the touch region (active channels and their 8 neighbours).
    The soft floor makes the measures continuous in the signal: on a dull, noisy skin
    the fingertips of a resting hand flicker across the contact threshold, and counting
    a channel fully or not at all made their centroid jump by tens of mm/s.  A frame
    without active channels has total 0 and centroid/spread 0.  Each frame's values
    depend on that frame alone.
    """
    n, rows, cols = signal.shape
    region = ndimage.binary_dilation(active, structure=_REGION_STRUCTURE)
    inside = np.where(region, np.maximum(signal, 0.0), 0.0).astype(np.float64)
    peak = inside.reshape(n, -1).max(axis=1)[:, None, None]
    weights = np.maximum(inside - RELATIVE_FLOOR * peak, 0.0)
    weights = weights.reshape(n, rows * cols)
    row_mm = np.repeat(np.arange(rows, dtype=np.float64) * row_pitch_mm, cols)
    col_mm = np.tile(np.arange(cols, dtype=np.float64) * col_pitch_mm, rows)
    total = weights.sum(axis=1)
    safe = np.where(total > 0, total, 1.0)
    r = (weights * row_mm).sum(axis=1) / safe
    c = (weights * col_mm).sum(axis=1) / safe
    second = (weights * (row_mm * row_mm + col_mm * col_mm)).sum(axis=1) / safe
    spread = np.sqrt(np.maximum(second - r * r - c * c, 0.0))
    return np.stack([total, r, c, spread], axis=1)


class PerformingDetector:
    """Frame-by-frame "fingers are being performed" flag (see the module doc)."""

    def __init__(self, sample_rate_hz: float, settings: PerformingSettings | None = None) -> None:
        check_positive("sample_rate_hz", sample_rate_hz)
        self.settings = settings or PerformingSettings()
        self.sample_rate_hz = float(sample_rate_hz)
        self.span = self.settings.span_frames(sample_rate_hz)
        self._history = np.zeros((self.span, 4), dtype=np.float64)  # frames before the next

    def reset(self) -> None:
        """Forget the past frames (as if the skin had been untouched)."""
        self._history[:] = 0.0

    def update(self, signal: np.ndarray, active: np.ndarray) -> np.ndarray:
        """``(N,)`` bool flags for conditioned ``signal`` and ``active`` ``(N, R, C)``."""
        s = self.settings
        features = touch_features(signal, active, s.row_pitch_mm, s.col_pitch_mm)
        joined = np.concatenate([self._history, features])
        now, before = joined[self.span :], joined[: -self.span]
        self._history = joined[-self.span :].copy()
        elapsed = self.span / self.sample_rate_hz
        both = (now[:, 0] > 0) & (before[:, 0] > 0)
        either = (now[:, 0] > 0) | (before[:, 0] > 0)
        speed = np.hypot(now[:, 1] - before[:, 1], now[:, 2] - before[:, 2]) / elapsed
        spread_rate = np.abs(now[:, 3] - before[:, 3]) / elapsed
        larger = np.maximum(np.maximum(now[:, 0], before[:, 0]), np.finfo(np.float64).tiny)
        pressure_change = np.abs(now[:, 0] - before[:, 0]) / larger
        moving = both & ((speed >= s.min_speed_mm_s) | (spread_rate >= s.min_spread_rate_mm_s))
        return moving | (either & (pressure_change >= s.min_pressure_change))
