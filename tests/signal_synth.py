"""Small synthetic skin streams for the signal-conditioning tests (not the real simulator).

A stream is ``baseline * gain * (1 + drift + touches + cross-talk) + noise + mains``:

- baseline ~20 pF per channel with +-20 % spread, times a per-skin gain;
- touches: gaussian fingertip blobs (relative change ``amplitude`` at the centre) that
  ramp in and out and may move linearly;
- cross-talk: every row and column line rises by ``crosstalk`` times the largest touch
  value on it;
- drift: linear thermal drift of ``drift_rel_per_min`` per minute, per-channel factor
  0.5..1.5;
- white noise of ``noise_rel`` and 50 Hz mains of ``mains_rel`` (relative to baseline;
  a period of 4 frames at 200 Hz).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Touch:
    """A fingertip pressing from ``start_s`` to ``end_s`` (ramps included)."""

    start_s: float
    end_s: float
    row: float
    col: float
    to_row: float | None = None  # where it ends up (linear motion); None: it stays
    to_col: float | None = None
    amplitude: float = 0.3
    sigma: float = 0.6  # blob radius, channels
    ramp_s: float = 0.03


@dataclass(frozen=True)
class SkinSpec:
    rows: int = 10
    cols: int = 10
    sample_rate_hz: float = 200.0
    baseline_pf: float = 20.0
    spread: float = 0.2
    gain: float = 1.0
    noise_rel: float = 0.002
    mains_rel: float = 0.002
    mains_hz: float = 50.0
    drift_rel_per_min: float = 0.0
    crosstalk: float = 0.0
    seed: int = 0


def skin_baseline(spec: SkinSpec) -> np.ndarray:
    rng = np.random.default_rng(spec.seed)
    spread = rng.uniform(-spec.spread, spec.spread, (spec.rows, spec.cols))
    return spec.baseline_pf * spec.gain * (1.0 + spread)


def touch_image(
    touches: Sequence[Touch], n_frames: int, spec: SkinSpec, start_frame: int = 0
) -> np.ndarray:
    """Relative change caused by the touches alone, ``(n_frames, rows, cols)``."""
    t = (start_frame + np.arange(n_frames)) / spec.sample_rate_hz
    rr = np.arange(spec.rows).reshape(1, -1, 1)
    cc = np.arange(spec.cols).reshape(1, 1, -1)
    image = np.zeros((n_frames, spec.rows, spec.cols))
    for touch in touches:
        duration = touch.end_s - touch.start_s
        ramp = max(touch.ramp_s, 1e-9)
        in_and_out = np.minimum(t - touch.start_s, touch.end_s - t) / ramp
        envelope = np.clip(in_and_out, 0.0, 1.0).reshape(-1, 1, 1)
        progress = np.clip((t - touch.start_s) / duration, 0.0, 1.0).reshape(-1, 1, 1)
        end_row = touch.row if touch.to_row is None else touch.to_row
        end_col = touch.col if touch.to_col is None else touch.to_col
        row = touch.row + progress * (end_row - touch.row)
        col = touch.col + progress * (end_col - touch.col)
        blob = np.exp(-((rr - row) ** 2 + (cc - col) ** 2) / (2 * touch.sigma**2))
        image += touch.amplitude * envelope * blob
    return image


def synth_stream(
    duration_s: float, touches: Sequence[Touch] = (), spec: SkinSpec | None = None
) -> np.ndarray:
    """Raw frames ``(N, rows, cols)`` float32 in pF."""
    spec = spec or SkinSpec()
    n = int(round(duration_s * spec.sample_rate_hz))
    rng = np.random.default_rng(spec.seed + 1)
    baseline = skin_baseline(spec)
    t = (np.arange(n) / spec.sample_rate_hz).reshape(-1, 1, 1)
    pressure = touch_image(touches, n, spec)
    crosstalk = spec.crosstalk * (
        pressure.max(axis=2, keepdims=True) + pressure.max(axis=1, keepdims=True)
    )
    drift_factor = rng.uniform(0.5, 1.5, (spec.rows, spec.cols))
    drift = spec.drift_rel_per_min * drift_factor * t / 60.0
    phase = rng.uniform(0, 2 * np.pi, (spec.rows, 1))
    mains = spec.mains_rel * np.sin(2 * np.pi * spec.mains_hz * t + phase)
    noise = spec.noise_rel * rng.standard_normal((n, spec.rows, spec.cols))
    raw = baseline * (1.0 + drift + pressure + crosstalk + mains + noise)
    return raw.astype(np.float32)
