"""A skin source that plays back a labelled-stream ``.npz`` or a native ``.wsrec`` recording.

:class:`ReplaySource` implements :class:`~wovenskin.skin.source.SkinSource`.  Frames come
out in file order with ``Frame.t`` taken from the file's timestamps, paced against the
wall clock (``speed`` 1 = real time, 2 = twice as fast, 0 = as fast as the consumer
polls).  ``start_s`` starts at the first frame with ``t >= start_s`` (file time).  With
``loop`` the whole file repeats; each pass shifts ``t`` and ``seq`` by the file's span so
the stream clock keeps increasing.  A non-looping replay emits ``SourceEvent("end")`` once
after its last frame.  The file's labels are available as :attr:`ReplaySource.events`
(ground truth, in file time).  Bad files raise :class:`FormatError` when the source is
created, never later, and a grid or rate outside the supported range one
:class:`~wovenskin.skin.layout.UnsupportedSkinError` line.  A ``replay:FILE?...`` spec's
options are :class:`ReplayOptions`.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from wovenskin.errors import ConfigError
from wovenskin.recording.files import read_as_recording
from wovenskin.recording.records import LABEL_KIND_TRIAL
from wovenskin.recording.untrusted import FormatError
from wovenskin.settings import from_dict
from wovenskin.skin.frames import Frame, SourceEvent, SourceStats
from wovenskin.skin.source import DevicelessSource

FAST_BATCH = 256
"""Most frames one :meth:`ReplaySource.poll` returns at ``speed=0``."""


@dataclass(frozen=True)
class ReplayOptions:
    """What ``replay:FILE?...`` may say: ``speed`` (1 = real time, 0 = as fast as polled),
    ``loop`` (repeat the file) and ``start_s`` (file time to start at)."""

    speed: float = 1.0
    loop: bool = False
    start_s: float = 0.0


class ReplaySource(DevicelessSource):
    """Plays a recorded file as if a skin were streaming it (see the module docstring)."""

    def __init__(
        self,
        path: str | os.PathLike,
        *,
        speed: float = 1.0,
        loop: bool = False,
        start_s: float = 0.0,
    ) -> None:
        if not (np.isfinite(speed) and speed >= 0):
            raise ConfigError(f"replay speed must be >= 0 (0 = as fast as polled), got {speed}")
        if not np.isfinite(start_s):
            raise ConfigError(f"replay start_s must be a finite time in seconds, got {start_s}")
        self.path = Path(path)
        self.speed = float(speed)
        self.loop = bool(loop)
        self._load(self.path)
        self._start_index = int(np.searchsorted(self._t, start_s, side="left"))
        if self._start_index == len(self._t):
            raise ConfigError(
                f"replay start_s={start_s} is past the end of {self.path} "
                f"(last frame at t={self._t[-1]:.3f} s)"
            )
        span_dt = float(np.median(np.diff(self._t))) if len(self._t) > 1 else 0.0
        step = span_dt if span_dt > 0 else 1.0 / self._info.sample_rate_hz
        self._period_s = float(self._t[-1] - self._t[0]) + step
        self._seq_period = max(int(self._seq[-1] - self._seq[0]), 0) + 1
        self._stats = SourceStats()
        self._queue: list[Frame | SourceEvent] = []
        self._started = self._finished = self._closed = False
        self._index = self._start_index
        self._pass = 0
        self._last_seq: int | None = None
        self._wall_start = 0.0

    @classmethod
    def from_options(cls, path: str, options: dict[str, str]) -> ReplaySource:
        """Create from ``replay:PATH?speed=2&loop=1&start_s=10`` style options."""
        given = {key: value for key, value in options.items() if value.strip()}
        o = from_dict(ReplayOptions, given, "replay options")  # an empty value: the default
        return cls(path, speed=o.speed, loop=o.loop, start_s=o.start_s)

    # -- SkinSource

    @property
    def events(self) -> list[tuple[str, float, float]]:
        """The file's labelled events ``(label, start_s, end_s)`` in file time."""
        return list(self._events)

    @property
    def duration_s(self) -> float:
        """Stream time one pass over the whole file covers."""
        return self._period_s

    def start(self) -> None:
        if self._started or self._closed:
            return
        self._wall_start = time.monotonic()
        message = f"replaying {self.path}: {len(self._t)} frames, {self._period_s:.1f} s"
        if self._warnings:
            message += f" ({len(self._warnings)} warning(s): {self._warnings[0]})"
        self._open(message, self._wall_start)

    def poll(self, timeout: float = 0.05) -> list[Frame | SourceEvent]:
        now = time.monotonic()
        deadline = now + max(timeout, 0.0)
        if not self._started or self._closed:
            time.sleep(max(timeout, 0.0))
            return []
        items, self._queue = self._queue, []
        while True:
            items.extend(self._take_due(now))
            if items or self._finished or now >= deadline:
                break
            time.sleep(min(deadline - now, self._wait_for_next(now)))
            now = time.monotonic()
        if not items and self._finished:
            time.sleep(max(deadline - now, 0.0))
        return items

    # -- internals

    def _load(self, path: Path) -> None:
        recording = read_as_recording(path, "replay")
        frames, t, seq = recording.frames, recording.t, recording.seq
        self._device_t_us = recording.device_t_us  # -1 where the file has no device time
        self._events = [
            (label.label, label.start_s, label.end_s)
            for label in recording.labels
            if label.kind == LABEL_KIND_TRIAL
        ]
        self._warnings = list(recording.warnings)
        backwards = np.flatnonzero(~(np.diff(t) >= 0))
        if backwards.size:
            i = int(backwards[0]) + 1
            raise FormatError(f"{path}: frame times go backwards (or are NaN) at frame {i}")
        self._frames = np.asarray(frames, dtype=np.float32)
        self._t = np.asarray(t, dtype=np.float64)
        self._seq = np.asarray(seq, dtype=np.int64)
        rows, cols = self._frames.shape[1:]
        info = replace(recording.info, rows=rows, cols=cols, source=f"replay:{path}")
        self._info = info.check_supported()

    def _stream_time(self, index: int) -> float:
        return float(self._t[index]) + self._pass * self._period_s

    def _take_due(self, now: float) -> list[Frame | SourceEvent]:
        if not self._started or self._finished:
            return []
        t_origin = float(self._t[self._start_index])
        elapsed = (now - self._wall_start) * self.speed if self.speed > 0 else np.inf
        limit = FAST_BATCH if self.speed == 0 else None
        items: list[Frame | SourceEvent] = []
        while self._stream_time(self._index) - t_origin <= elapsed:
            items.append(self._frame(self._index, now))
            self._index += 1
            if self._index == len(self._t):
                if not self.loop:
                    self._finished = True
                    message = (
                        f"replay of {self.path} finished after {self._stats.good_frames} frames"
                    )
                    items.append(SourceEvent("end", message, now))
                    break
                self._index = 0
                self._pass += 1
            if limit is not None and len(items) >= limit:
                break
        return items

    def _wait_for_next(self, now: float) -> float:
        if self.speed == 0:
            return 0.0
        due = (self._stream_time(self._index) - float(self._t[self._start_index])) / self.speed
        return max(due - (now - self._wall_start), 0.0)

    def _frame(self, index: int, now: float) -> Frame:
        seq = int(self._seq[index]) + self._pass * self._seq_period
        if self._last_seq is not None and seq > self._last_seq + 1:
            self._stats.dropped_frames += seq - self._last_seq - 1
        elif self._last_seq is not None and seq <= self._last_seq:
            self._stats.resets += 1  # the recorded device restarted its sequence
        self._last_seq = seq
        self._stats.good_frames += 1
        device_t_us = None
        if self._device_t_us[index] >= 0:
            device_t_us = int(self._device_t_us[index]) + round(self._pass * self._period_s * 1e6)
        return Frame(
            seq=seq,
            t=self._stream_time(index),
            values=self._frames[index].copy(),
            t_host=now,
            device_t_us=device_t_us,
        )
