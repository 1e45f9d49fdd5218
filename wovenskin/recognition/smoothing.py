"""Causal smoothing of the class probabilities within a touch, before the execution rules.

:class:`ProbabilitySmoother` replaces each fresh prediction's row of class probabilities by
the mean of the rows predicted in the same touch at most ``frames - 1`` frames before it
(the prediction itself included): with the recogniser run at every frame and
``frames = round(smoothing_s * rate)``, the mean of the last ``frames`` windows (8 at
200 Hz for 0.04 s).  A frame without contact (the conditioner's ``touched`` flag false)
forgets every row, so a new touch starts from its own first window; frames without a
prediction keep their row as it is (the arbiter ignores them).

Why: a window's probabilities flicker around the arbiter's ``min_probability`` while a
gesture is under way; the dwell needs every prediction of 0.1 s to reach it, so one dip
restarts it.  The mean of a few windows dips less, and a spurious single window of
another class (the kind that makes a false activation) is diluted; it costs about half
the smoothing time in latency.  Figures in ``docs/gestures.md`` ("Execution rules").

A non-finite probability makes the means that include it non-finite, and the arbiter
recognises nothing in those predictions.  State is carried between calls, so any split
of the frames into calls gives the same rows.
"""

from __future__ import annotations

from collections import deque

import numpy as np

from wovenskin.errors import ConfigError


class ProbabilitySmoother:
    """Running mean of the current touch's last predictions (see the module doc)."""

    def __init__(self, frames: int) -> None:
        if not (isinstance(frames, int) and not isinstance(frames, bool) and frames >= 1):
            raise ConfigError(f"smoothing frames must be an integer >= 1, got {frames!r}")
        self.frames = frames
        self._frame = -1
        self._rows: deque[tuple[int, np.ndarray]] = deque()

    def step(self, touched: bool, row: np.ndarray | None) -> np.ndarray | None:
        """One frame: the smoothed ``row`` (a new array), or None when none was predicted."""
        self._frame += 1
        if not touched:
            self._rows.clear()
            return None if row is None else np.asarray(row, dtype=np.float64).copy()
        if row is None:
            return None
        self._rows.append((self._frame, np.asarray(row, dtype=np.float64).copy()))
        while self._frame - self._rows[0][0] >= self.frames:
            self._rows.popleft()
        return np.mean([r for _, r in self._rows], axis=0)

    def run(
        self, touched: np.ndarray, predicted: np.ndarray, probabilities: np.ndarray
    ) -> np.ndarray:
        """Many frames: ``(N, K)`` rows, those marked ``predicted`` smoothed (a new array)."""
        out = np.array(probabilities, dtype=np.float64, copy=True)
        for i, (on, pred) in enumerate(zip(touched.tolist(), predicted.tolist(), strict=True)):
            smoothed = self.step(on, out[i] if pred else None)
            if smoothed is not None:
                out[i] = smoothed
        return out
