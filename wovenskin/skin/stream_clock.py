"""The stream clock of a serial skin: seconds since the source started, never going back.

- binary: the device timestamp, offset so that the first frame lands on the host's
  elapsed time; at each device reset the offset is re-anchored (to the later of the host
  time and the previous ``t`` plus one sample period), so ``t`` is continuous and
  strictly increasing across resets and reconnects, and keeps the device's sample spacing.
- text: lines carry no trustworthy clock, so ``t`` advances by one nominal period per
  line; it is pulled back to the host clock whenever the two differ by more than
  :data:`TEXT_CLOCK_TOLERANCE_S` (after a pause, or when the nominal rate is wrong),
  never going backwards.
"""

from __future__ import annotations

from dataclasses import dataclass

TEXT_CLOCK_TOLERANCE_S = 0.1
_SEQ_MASK = 0xFFFFFFFF


@dataclass(frozen=True)
class Placed:
    """Where :meth:`StreamClock.place_frame` put a frame: its time (``None`` for an exact
    duplicate of the previous frame), the frames dropped before it, and ``reset_from``,
    the previous sequence number when the device reset."""

    t: float | None
    dropped: int = 0
    reset_from: int | None = None


class StreamClock:
    """Turns device sequence numbers and timestamps (or text lines) into stream times."""

    def __init__(self) -> None:
        self.last_seq: int | None = None
        self.last_device_us = 0
        self.last_t: float | None = None
        self._anchor_t = 0.0
        self._anchor_device_us = 0

    def place_frame(self, seq: int, device_us: int, elapsed: float, period_s: float) -> Placed:
        """Account for a binary frame ``seq`` at host time ``elapsed`` (drops, resets)."""
        dropped, reset_from = 0, None
        last_seq = self.last_seq
        if last_seq is None:
            self._anchor(elapsed, device_us)
        else:
            step = (seq - last_seq) & _SEQ_MASK
            if step == 0 and device_us == self.last_device_us:
                return Placed(None)
            if step == 0 or step >= 1 << 31 or device_us < self.last_device_us:
                reset_from = last_seq
                last_t = self.last_t if self.last_t is not None else elapsed
                self._anchor(max(elapsed, last_t + period_s), device_us)
            else:
                dropped = step - 1
        self.last_seq = seq
        self.last_device_us = device_us
        t = self._anchor_t + (device_us - self._anchor_device_us) * 1e-6
        if self.last_t is not None and t <= self.last_t:
            t = self.last_t + 1e-6  # equal device timestamps: keep the clock strictly increasing
        self.last_t = t
        return Placed(t, dropped, reset_from)

    def place_line(self, elapsed: float, period_s: float) -> float:
        """The stream time of a text line read at host time ``elapsed``."""
        if self.last_t is None:
            t = elapsed
        else:
            t = self.last_t + period_s
            if abs(elapsed - t) > TEXT_CLOCK_TOLERANCE_S:
                t = max(elapsed, self.last_t + 1e-6)
        self.last_t = t
        return t

    def _anchor(self, t: float, device_us: int) -> None:
        self._anchor_t = t
        self._anchor_device_us = device_us
