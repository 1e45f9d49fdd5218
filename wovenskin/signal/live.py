"""Live conditioning: calibrate on the first frames of a stream, with retries, then condition.

:class:`LiveConditioner` is what a real-time pipeline feeds.  In state ``"calibrating"``
it collects ``calibration_s`` of frames and calibrates.  When something touched the skin
meanwhile it warns (``warnings`` and the ``on_warning`` callback) and collects a fresh
period, up to ``max_retries`` times; after that it accepts the calibration (baseline
recovery repairs touched channels after lift-off).  It then conditions the calibration
frames silently, to fill the moving average and block state exactly as
:func:`~wovenskin.signal.conditioner.condition_recording` would, and enters
``"running"``.  Frames that arrive in the same call after calibration completes are
conditioned at once, so the output does not depend on how frames are grouped into calls.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from wovenskin.signal.calibration import Calibration, calibrate
from wovenskin.signal.conditioner import ConditionedFrames, Conditioner, as_frames
from wovenskin.signal.config import ConditioningConfig

CALIBRATING = "calibrating"
RUNNING = "running"


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
