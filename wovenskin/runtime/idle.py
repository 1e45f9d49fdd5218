"""The "no skin" source (``--skin none``): contact-free frames at the skin's rate, so a
keyboard- or pendant-only session ticks on a stream clock without any skin.

:class:`IdleSkinSource` implements :class:`~wovenskin.skin.source.SkinSource`.  Every frame
holds a resting skin's reading on every channel: ``level`` pF plus a little seeded white
noise (``noise`` pF standard deviation; the conditioning takes a flat channel for a dead
one), far below any contact threshold, so no contact is ever seen; at ``rate`` Hz on a
stream clock that starts at 0 when the source starts.  ``speed`` 1 paces the frames in
real time, 2 twice as fast, 0 as fast as the consumer polls (tests).
A ``none:...`` spec's options are :class:`IdleOptions`.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from wovenskin.errors import ConfigError
from wovenskin.settings import from_dict
from wovenskin.skin.frames import Frame, SkinInfo, SourceEvent, SourceStats
from wovenskin.skin.layout import (
    DEFAULT_COLS,
    DEFAULT_ROWS,
    DEFAULT_SAMPLE_RATE_HZ,
    check_supported,
)
from wovenskin.skin.source import DevicelessSource, held_back

FAST_BATCH = 10
"""Most frames one :meth:`IdleSkinSource.poll` returns at ``speed=0``."""


@dataclass(frozen=True)
class IdleOptions:
    """What ``none:...`` may say: ``speed`` (1 real time, 0 as fast as polled), ``rate``
    (frames per second), the grid (``rows``, ``cols``), the resting ``level`` and its
    ``noise`` (pF)."""

    speed: float = 1.0
    rate: float = DEFAULT_SAMPLE_RATE_HZ
    rows: int = DEFAULT_ROWS
    cols: int = DEFAULT_COLS
    level: float = 10.0
    noise: float = 0.002


class IdleSkinSource(DevicelessSource):
    """A skin nobody touches: constant readings paced to the wall clock (module docstring)."""

    def __init__(
        self,
        speed: float = 1.0,
        rate: float = DEFAULT_SAMPLE_RATE_HZ,
        rows: int = DEFAULT_ROWS,
        cols: int = DEFAULT_COLS,
        level: float = 10.0,
        noise: float = 0.002,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        if not (math.isfinite(speed) and speed >= 0):
            raise ConfigError(f"idle skin speed must be >= 0 (0 = as fast as polled), got {speed}")
        check_supported(rows, cols, rate, "no skin (none)")
        if not (math.isfinite(level) and level > 0):
            raise ConfigError(f"idle skin level must be a positive reading in pF, got {level}")
        if not (math.isfinite(noise) and 0 < noise <= 0.01 * level):
            raise ConfigError(f"idle skin noise must be > 0 and <= 1 % of the level, got {noise}")
        self.speed = float(speed)
        self._noise = float(noise)
        self._rng = np.random.default_rng(0)
        self._period = 1.0 / float(rate)
        self._values = np.full((rows, cols), level, dtype=np.float32)
        self._clock = clock
        self._info = SkinInfo(
            rows=rows,
            cols=cols,
            sample_rate_hz=float(rate),
            firmware="wovenskin-idle",
            device_id="none",
            source="none",
        )
        self._stats = SourceStats()
        self._queue: list[Frame | SourceEvent] = []
        self._started = self._closed = False
        self._wall_start = 0.0
        self._next = 0  # sequence number of the next frame

    @classmethod
    def from_options(cls, options: dict[str, str]) -> IdleSkinSource:
        """Create from ``none:speed=0,rate=200`` style options."""
        given = {key: value for key, value in options.items() if value.strip()}
        o = from_dict(IdleOptions, given, "none (no skin) options")
        return cls(o.speed, o.rate, o.rows, o.cols, o.level, o.noise)

    # -- SkinSource

    def start(self) -> None:
        if self._started or self._closed:
            return
        self._wall_start = self._clock()
        self._open("no skin: idle frames keep the session's clock", self._wall_start)

    def poll(self, timeout: float = 0.05) -> list[Frame | SourceEvent]:
        if not self._started or self._closed:
            time.sleep(max(timeout, 0.0))
            return []
        items, self._queue = self._queue, []
        now = self._clock()
        due = self._due(now)
        if due == 0 and not items:  # wait for the next frame, at most ``timeout``
            wait = (self._next * self._period) / self.speed - (now - self._wall_start)
            time.sleep(min(max(wait, 0.0), max(timeout, 0.0)))
            now = self._clock()
            due = self._due(now)
        for _ in range(due):
            items.append(self._frame(now))
        return items

    # -- internals

    def _due(self, now: float) -> int:
        if self.speed == 0:
            return FAST_BATCH
        elapsed = (now - self._wall_start) * self.speed
        due = max(0, int(math.floor(elapsed / self._period)) + 1 - self._next)
        now, behind = held_back(due, self.speed / self._period)  # a reader far behind
        self._wall_start += behind  # holds the stream clock back (MAX_READER_LAG_S)
        return now

    def _reading(self) -> np.ndarray:
        jitter = self._rng.normal(0.0, self._noise, self._values.shape).astype(np.float32)
        return self._values + jitter

    def _frame(self, now: float) -> Frame:
        seq = self._next
        self._next += 1
        self._stats.good_frames += 1
        return Frame(seq=seq, t=seq * self._period, values=self._reading(), t_host=now)
