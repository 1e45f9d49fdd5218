"""Synthetic skin frames with Gaussian fingertips where a test places them."""

from __future__ import annotations

import numpy as np

ROWS, COLS, RP, CP, RATE = 10, 10, 14.0, 10.0, 200.0


def frame_of(tips: list[tuple[float, float]], sd_mm: float = 5.0, amp: float = 0.05) -> np.ndarray:
    """A frame of Gaussian fingertips at ``(y, x)`` mm from the centre of channel [0, 0]."""
    y = np.arange(ROWS)[:, None] * RP
    x = np.arange(COLS)[None, :] * CP
    out = np.zeros((ROWS, COLS))
    for ty, tx in tips:
        out += amp * np.exp(-((y - ty) ** 2 + (x - tx) ** 2) / (2 * sd_mm**2))
    return out


def active_of(frame: np.ndarray) -> np.ndarray:
    return frame > 0.1 * frame.max() if frame.max() > 0 else frame > 1
