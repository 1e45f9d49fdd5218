"""How skin frames become control ticks: the part of a control session that polls the
skin, keeps the session clock and ends :meth:`~wovenskin.control.session.ControlSession.run`.

:class:`SkinLoop` polls the ``LiveSkin`` once per :meth:`SkinLoop.step`. A block of
conditioned frames goes through the recogniser once, then each frame is one tick at its
time on the skin clock, the recogniser's command changes applied as their times come. The
session clock is the skin clock while frames arrive and advances with the wall clock
while none do (``SessionSettings.wall_clock_stalls``), so the watchdogs see a stall. It
calls back into the session through six functions, nothing else: ``tick(t)``,
``change(c)``, ``predictions(t)``, ``alive(t)`` (frames without conditioned output, as
while calibrating), ``idle(now, stalled)`` and ``error(text)``.
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable
from typing import Any

import numpy as np

from wovenskin.control.session_state import SessionSettings, SessionState


class SkinLoop:
    """The skin's polls, the session clock and the end of a run (module docstring)."""

    def __init__(
        self,
        live_skin: Any,
        pipeline: Any,
        settings: SessionSettings,
        state: SessionState,
        wall: Callable[[], float],
        *,
        tick: Callable[[float], None],
        change: Callable[[Any], None],
        predictions: Callable[[float], None],
        alive: Callable[[float], None],
        idle: Callable[[float, bool], None],
        error: Callable[[str], None],
        watchdog_s: float,
    ) -> None:
        self.live_skin, self.pipeline, self.settings, self.state = (
            live_skin,
            pipeline,
            settings,
            state,
        )
        self._wall = wall
        self._tick, self._change, self._predictions = tick, change, predictions
        self._alive, self._idle, self._error = alive, idle, error
        self._watchdog_s = watchdog_s
        self.now = 0.0  # the session clock
        self.started_wall: float | None = None
        self.first_t: float | None = None
        self.quit = ""
        self.last_block_compute_s = 0.0  # recogniser + control + robot for the last block
        self.tick_block: Any = None  # the LiveBlock whose frames are being ticked
        self._quit_asked = False  # request_quit() since the last run() ended
        self._last_t: float | None = None  # stream time of the newest frame seen
        self._last_wall: float | None = None  # wall time when it arrived
        self._last_seq = -1
        self._seconds: float | None = None
        self._end_t: float | None = None  # session time at which run() ends
        self._held_over: tuple[np.ndarray, deque] | None = None  # frames past a run's end

    def request_quit(self, reason: str) -> None:
        """End :meth:`run` after the current step (or the next run, if none is running)."""
        self.quit = reason
        self._quit_asked = True

    def run(self, seconds: float | None, should_continue: Callable[[], bool] | None) -> None:
        """Step until the skin ends, a quit is asked, ``seconds`` of session time pass, or
        ``should_continue()`` returns False; ``quit`` then says why. It may be called
        again: the next run goes on from where this one ended (the frames of its last
        block that lay past its end come first)."""
        if not self._quit_asked:
            self.quit = ""  # the previous run's own end, not a request to quit
        self._seconds = seconds
        self._end_t = None
        if seconds is not None and self.first_t is not None:
            self._end_t = self.now + seconds
        if self._held_over is not None and not self.quit:
            times, pending = self._held_over
            self._held_over = None
            self._tick_frames(times, pending)
        try:
            while not self.quit:
                self.step()
                if self.quit:
                    break
                if self.state.ended:
                    self.quit = "the skin stream ended"
                elif self._end_t is not None and self.now >= self._end_t:
                    self.quit = f"{seconds:g} s elapsed"
                elif should_continue is not None and not should_continue():
                    self.quit = self.quit or "stopped by the caller"
        finally:
            self._quit_asked = False

    def step(self, timeout: float | None = None) -> int:
        """One skin poll and the ticks of the frames it brought; returns the tick count."""
        timeout = self.settings.idle_timeout_s if timeout is None else timeout
        block = self.live_skin.step(timeout=timeout)
        polled = time.perf_counter()
        skin = self.live_skin.state
        self.state.ended = bool(skin.ended)
        arrived = skin.seq != self._last_seq and skin.seq >= 0  # also while calibrating
        if arrived:
            self._last_seq = skin.seq
            self._frames_arrived(float(skin.t))
        if block is None or len(block.t) == 0:
            if arrived:  # frames but no conditioned output (calibrating): the skin is alive
                self.now = max(self.now, float(skin.t))
                self._alive(float(skin.t))
            else:
                self._wait()
            return 0
        ticks = self._on_block(block)
        self.last_block_compute_s = time.perf_counter() - polled
        return ticks

    def figures(self) -> tuple[float, float]:
        """Seconds of skin stream and of wall time the session has run."""
        stream_s = 0.0 if self.first_t is None else self.now - self.first_t
        wall_s = 0.0 if self.started_wall is None else self._wall() - self.started_wall
        return stream_s, wall_s

    def _frames_arrived(self, t: float) -> None:
        if self.first_t is None:  # the first poll may bring many frames: its first one
            frames = max(1, self.live_skin.stats().good_frames)
            self.first_t = t - (frames - 1) / self.live_skin.info.sample_rate_hz
            if self._seconds is not None:
                self._end_t = self.first_t + self._seconds
        self._last_t = t
        self._last_wall = self._wall()

    def _wait(self) -> None:
        """No conditioned frames: the session clock follows the wall clock (a stall)."""
        if self._last_t is None or self._last_wall is None:
            return
        if not self.settings.wall_clock_stalls:
            return
        self.now = max(self.now, self._last_t + (self._wall() - self._last_wall))
        self._idle(self.now, self.now - self._last_t > self._watchdog_s)

    def _on_block(self, block: Any) -> int:
        times = np.asarray(block.t, dtype=np.float64).reshape(-1)
        try:
            changes = list(self.pipeline.feed(block))
        except ValueError as exc:  # the command ends: no motion on frames we cannot trust
            self._error(f"skin frames dropped: {exc}")  # one line however many frames
            ended = self.pipeline.reset(float(times[0]))
            changes = [] if ended is None else [ended]
        self._predictions(float(times[-1]))
        self.tick_block = block
        self._tick_frames(times, deque(sorted(changes, key=lambda c: c.t)))
        return len(times)

    def _tick_frames(self, times: np.ndarray, pending: deque) -> None:
        """Tick the frames at ``times``, applying the recogniser's ``pending`` changes as
        their times come; frames past the run's end are held over for the next run."""
        for i, t in enumerate(times):
            if self._end_t is not None and t > self._end_t:
                self.quit = f"{self._seconds:g} s elapsed"
                self._held_over = (times[i:], pending)
                return
            while pending and pending[0].t <= t:
                self._change(pending.popleft())
            self.now = max(self.now, float(t))
            self._tick(float(t))
        while pending:  # changes stamped after the block's last frame (none expected)
            self._change(pending.popleft())
