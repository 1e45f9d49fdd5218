"""What a simulated operator's skins share: frames rendered when polled, a touch held till lifted.

:class:`TouchSkin` is a :class:`~wovenskin.skin.source.SkinSource` that renders ``block``
frames (50 ms) a poll, in the session's own thread: a simulated operator acting at session
time sees its touch in the very next frames, and a run is the same for the same seeds.
:meth:`TouchSkin.touch` begins a performance (landing, the pause after landing, the
motion, the fingers resting) and keeps the fingers resting where it was before its
lift-off until :meth:`TouchSkin.lift`, which plays the performance's own lift-off: a held
gesture, as an operator holds a swipe while the arm moves.  A lift while the hand still
moves finishes the motion and lifts without the rest after it (a flick).

Its subclasses say whose hand and skin it is: :class:`~.skin_hand.OperatorSkin`
(:mod:`wovenskin.sim`, the simulator the shipped model was trained on) and
:class:`~.independent_skin.IndependentSkin` (:mod:`wovenskin.independent`, written apart
from it).  A subclass performs with :meth:`_perform` (an object with ``phases`` and
``n_frames``) and renders with :meth:`_render_idle`, :meth:`_render_played` and
:meth:`_render_held`.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from wovenskin.errors import ConfigError
from wovenskin.skin.frames import Frame, SkinInfo, SourceEvent, SourceStats
from wovenskin.skin.source import DevicelessSource

BLOCK_FRAMES = 10
"""Frames rendered per poll (50 ms at 200 Hz)."""


class TouchSkin(DevicelessSource):
    """A skin rendered on the session's clock under one simulated hand (module docstring)."""

    opened = "simulated skin under a simulated operator's hand"
    """The "connected" event's message."""

    def _ready(self, info: SkinInfo, block: int, sample_rate_hz: float) -> None:
        """Set the source's state: its ``info``, ``block`` frames a poll, no hand on it."""
        self._info = info
        self._fs = float(sample_rate_hz)
        self.block = max(1, int(block))
        self._stats = SourceStats()
        self._closed = self._started = False
        self._queue: list[Frame | SourceEvent] = []
        self._next = 0  # sequence number of the next frame
        self._performance: Any = None
        self._done = 0  # frames of the performance rendered
        self._hold_from = 0  # its first lift-off frame: the hold repeats the frame before
        self._motion_end = 0  # the frame its motion ends (a flick lifts from there)
        self._lifting = False
        self.touches = 0  # gestures begun

    # -- what a subclass provides

    def _perform(self, gesture: str) -> Any:
        """One performance of ``gesture`` by this skin's person."""
        raise NotImplementedError

    def _render_idle(self, n: int) -> np.ndarray:
        """``n`` frames without a touch."""
        raise NotImplementedError

    def _render_played(self, start: int, n: int) -> np.ndarray:
        """Frames ``start`` to ``start + n`` of the performance."""
        raise NotImplementedError

    def _render_held(self, frame: int, n: int) -> np.ndarray:
        """``n`` frames of the performance's fingers resting as at ``frame``."""
        raise NotImplementedError

    # -- what the operator does

    def touch(self, gesture: str) -> Any:
        """Begin ``gesture`` (a class name) now; the fingers stay down until :meth:`lift`."""
        if self._performance is not None:
            raise ConfigError("the hand is on the skin: lift it first")
        performance = self._perform(gesture)
        phases = performance.phases
        self._performance, self._done, self._lifting = performance, 0, False
        self._hold_from = int(round(phases.lift_start_s * self._fs))
        motion_end = phases.lift_start_s if phases.motion_end_s is None else phases.motion_end_s
        self._motion_end = min(int(round(motion_end * self._fs)), self._hold_from)
        self.touches += 1
        return performance

    def lift(self) -> None:
        """Lift the hand: a held hand's lift-off plays from the next frame; a hand still
        moving finishes its motion and lifts without the rest after it (a flick)."""
        if self._performance is not None:
            self._lifting = True

    @property
    def touching(self) -> bool:
        """Whether a hand is on the skin or lifting off."""
        return self._performance is not None

    @property
    def holding(self) -> bool:
        """Whether the gesture's motion is over and the fingers rest, held."""
        return self._performance is not None and not self._lifting and self._done >= self._hold_from

    @property
    def stream_t(self) -> float:
        """Stream time of the next frame (s)."""
        return self._next / self._fs

    # -- SkinSource

    def start(self) -> None:
        if self._started or self._closed:
            return
        self._open(self.opened, time.monotonic())

    def poll(self, timeout: float = 0.05) -> list[Frame | SourceEvent]:
        if not self._started or self._closed:
            return []
        items, self._queue = self._queue, []
        values = self._render(self.block)
        now = time.monotonic()
        for frame in values:
            items.append(Frame(seq=self._next, t=self._next / self._fs, values=frame, t_host=now))
            self._next += 1
            self._stats.good_frames += 1
        return items

    # -- rendering

    def _render(self, n: int) -> np.ndarray:
        out = []
        while n > 0:
            piece = self._piece(n)
            out.append(piece)
            n -= len(piece)
        return np.concatenate(out) if len(out) > 1 else out[0]

    def _piece(self, n: int) -> np.ndarray:
        performance = self._performance
        if performance is None:
            return self._render_idle(n)
        if not self._lifting and self._done >= self._hold_from:
            return self._render_held(self._hold_from - 1, n)
        if self._lifting and self._motion_end <= self._done < self._hold_from:
            self._done = self._hold_from  # the fingers stand where the motion ended: lift
        if self._done < self._motion_end:
            end = self._motion_end
        else:
            end = self._hold_from if not self._lifting else performance.n_frames
        k = max(1, min(n, end - self._done))
        frames = self._render_played(self._done, k)
        self._done += k
        if self._done >= performance.n_frames:
            self._performance = None
        return frames
