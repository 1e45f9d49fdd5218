"""The live front end of the pipeline: a skin source feeding calibration and conditioning.

:class:`LiveSkin` pulls frames and events from any :class:`~wovenskin.skin.SkinSource`,
runs them through :class:`~wovenskin.signal.conditioner.LiveConditioner` (calibration with
retry, then conditioning), optionally writes every raw frame to a native recording, and
keeps the latest state and running rates for views.  Views, the guided recorder and the
robot session all sit on top of it, so they share exactly one path from bytes to contacts.
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from wovenskin.signal.conditioner import ConditionedFrames, LiveConditioner
from wovenskin.signal.config import ConditioningConfig
from wovenskin.skin.frames import Frame, SkinInfo, SourceEvent, SourceStats
from wovenskin.skin.source import SkinSource


@dataclass
class LiveBlock:
    """Conditioned frames that came out of one :meth:`LiveSkin.step`, with their times."""

    t: np.ndarray
    cond: ConditionedFrames


@dataclass
class LiveState:
    """What a view shows: the newest conditioned frame and the stream's health."""

    t: float = 0.0
    seq: int = -1
    raw: np.ndarray | None = None
    signal: np.ndarray | None = None
    active: np.ndarray | None = None
    contacts: list = field(default_factory=list)
    touched: bool = False
    frame_rate_hz: float = 0.0
    calibrating: bool = True
    ended: bool = False
    stalled: bool = False
    events: deque = field(default_factory=lambda: deque(maxlen=8))


class RateMeter:
    """Events per second over a sliding wall-clock window."""

    def __init__(self, window_s: float = 1.0) -> None:
        self.window_s = window_s
        self._stamps: deque[float] = deque()

    def add(self, n: int = 1, now: float | None = None) -> None:
        now = time.monotonic() if now is None else now
        self._stamps.extend([now] * n)
        self._trim(now)

    def rate(self, now: float | None = None) -> float:
        now = time.monotonic() if now is None else now
        self._trim(now)
        return len(self._stamps) / self.window_s

    def _trim(self, now: float) -> None:
        while self._stamps and now - self._stamps[0] > self.window_s:
            self._stamps.popleft()


class LiveSkin:
    """Source -> calibration/conditioning, with an optional raw-frame recorder.

    Call :meth:`step` repeatedly (it waits at most ``timeout`` for new frames); it returns
    the conditioned frames that arrived with their stream times (or ``None`` while nothing
    arrived or the skin is still calibrating) and updates :attr:`state`.  ``on_block``, when
    set, also gets each such block: an observer beside whoever steps the skin (the
    dashboard's guided recording beside its control session).
    """

    def __init__(
        self,
        source: SkinSource,
        config: ConditioningConfig | None = None,
        on_message: Callable[[str], None] | None = None,
        recorder=None,
    ) -> None:
        self.source = source
        info = source.info
        self.config = replace(config or ConditioningConfig(), sample_rate_hz=info.sample_rate_hz)
        self._on_message = on_message or (lambda _msg: None)
        self._shape = (info.rows, info.cols)
        self.conditioner = LiveConditioner(self.config, info.rows, info.cols, on_warning=self._warn)
        self.recorder = recorder
        self.on_block: Callable[[LiveBlock], None] | None = None  # sees every block stepped
        self.state = LiveState()
        self._rate = RateMeter()
        self._calibration_written = False

    @property
    def info(self) -> SkinInfo:
        return self.source.info

    def _warn(self, message: str) -> None:
        self.state.events.append(("warning", message))
        self._on_message(message)

    def start(self) -> None:
        self.source.start()

    def close(self) -> None:
        self.source.close()

    def stats(self) -> SourceStats:
        return self.source.stats()

    def recalibrate(self) -> None:
        self.conditioner.recalibrate()
        self._calibration_written = False
        self.state.calibrating = True

    def step(self, timeout: float = 0.02) -> LiveBlock | None:
        items = self.source.poll(timeout)
        frames: list[Frame] = []
        for item in items:
            if isinstance(item, SourceEvent):
                self._handle_event(item)
            else:
                frames.append(item)
        if not frames:
            if self.recorder is not None:
                self.recorder.tick()  # keep buffered frames durable through a stall
            return None
        block = self._consume(frames)
        if block is not None and self.on_block is not None:
            self.on_block(block)
        return block

    def _handle_event(self, event: SourceEvent) -> None:
        self.state.events.append((event.kind, event.message))
        if event.kind == "stalled":
            self.state.stalled = True
        elif event.kind == "resumed":
            self.state.stalled = False
        elif event.kind == "end":
            self.state.ended = True
        elif event.kind == "info" and event.info is not None:
            info = event.info
            self._record_info(info)
            if (info.rows, info.cols) != self._shape:
                self._shape = (info.rows, info.cols)
                self._warn(
                    f"skin reports a {info.rows}x{info.cols} grid: recalibrating for the new size"
                )
                self.config = replace(self.config, sample_rate_hz=info.sample_rate_hz)
                self.conditioner = LiveConditioner(
                    self.config,
                    info.rows,
                    info.cols,
                    on_warning=self._warn,
                )
        if self.recorder is not None:
            payload = {"kind": event.kind, "message": event.message}
            self.recorder.add_annotation("source", self.state.t, payload)
        if event.kind != "info":
            self._on_message(f"skin: {event.kind} {event.message}".strip())

    def _record_info(self, info: SkinInfo) -> None:
        """The recording describes the skin its device declared, where it holds no frame yet;
        after its first frame it keeps its grid (frames of another are not recorded)."""
        if self.recorder is None or self.recorder.info == info:
            return
        try:
            self.recorder.change_info(info)
        except ValueError as exc:
            self._warn(f"the recording keeps its first skin description: {exc}")

    def _consume(self, frames: list[Frame]) -> LiveBlock | None:
        shape = self._shape
        good = [f for f in frames if f.values.shape == shape]
        if len(good) != len(frames):
            self._warn(f"dropped {len(frames) - len(good)} frame(s) whose shape is not {shape}")
        if not good:
            return None
        raw = np.stack([f.values for f in good]).astype(np.float32, copy=False)
        recorder = self.recorder
        if recorder is not None and (recorder.info.rows, recorder.info.cols) == shape:
            recorder.append_frames(
                np.array([f.seq for f in good], dtype=np.int64),
                np.array([f.t for f in good], dtype=np.float64),
                raw,
                np.array(
                    [-1 if f.device_t_us is None else f.device_t_us for f in good], dtype=np.int64
                ),
            )
        self._rate.add(len(good))
        out = self.conditioner.feed(raw)
        st = self.state
        st.t, st.seq, st.raw = good[-1].t, good[-1].seq, raw[-1]
        st.frame_rate_hz = self._rate.rate()
        st.calibrating = self.conditioner.state != "running"
        if out is None or len(out) == 0:
            return None
        if self.recorder is not None and not self._calibration_written:
            calibration = self.conditioner.calibration
            if calibration is not None:
                self.recorder.add_calibration(calibration.to_dict())
                self._calibration_written = True
        st.signal = out.signal[-1]
        st.active = out.active[-1]
        st.contacts = out.contacts[-1]
        st.touched = bool(out.touched[-1])
        # Once calibration completes mid-batch, only the trailing frames come out.
        times = np.array([f.t for f in good[len(good) - len(out) :]], dtype=np.float64)
        return LiveBlock(times, out)
