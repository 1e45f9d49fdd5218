"""The contact tracks after each recent frame the touch reader read, by stream time.

:class:`~wovenskin.recognition.pipeline.LivePipeline` reads a whole block of frames at
once, and a control session then ticks through them one by one; a view of one tick (a
ROS 2 ``tracks`` cloud beside that tick's contacts) needs the tracks after *that* frame,
not after the block's last.  :func:`read_touch` runs the touch reader
(:meth:`~wovenskin.recognition.touch_reader.TouchRecognizer.run`) and notes the
tracks after each frame in a :class:`FrameTracks`, which keeps the last
:data:`KEEP_FRAMES` of them (copies: the tracker moves its tracks in place).
"""

from __future__ import annotations

from collections import deque
from dataclasses import replace

import numpy as np

from wovenskin.recognition.touch_reader import TouchRecognizer
from wovenskin.tracking.tracker import Track

KEEP_FRAMES = 1024
"""Frames whose tracks are kept: more than a block holds (a fast replay's are 256)."""

_NONE: tuple[Track, ...] = ()


class FrameTracks:
    """The live tracks after each of the last :data:`KEEP_FRAMES` frames, by stream time."""

    def __init__(self, keep: int = KEEP_FRAMES) -> None:
        self._frames: deque[tuple[float, tuple[Track, ...]]] = deque(maxlen=keep)

    def add(self, t: float, tracks: list[Track]) -> None:
        """Note the tracks after the frame at stream time ``t`` (copied)."""
        kept = tuple(replace(track, path=[]) for track in tracks) if tracks else _NONE
        self._frames.append((float(t), kept))

    def at(self, t: float) -> list[Track] | None:
        """The tracks after the frame at stream time ``t``; ``None`` when it is not kept."""
        for when, tracks in reversed(self._frames):
            if when == t:
                return list(tracks)
            if when < t:
                break
        return None

    def clear(self) -> None:
        """Forget every frame (the pipeline was reset)."""
        self._frames.clear()


def read_touch(
    touch: TouchRecognizer,
    history: FrameTracks,
    t: np.ndarray,
    frames: np.ndarray,
    active: np.ndarray,
    touched: np.ndarray,
    probabilities: np.ndarray,
) -> np.ndarray:
    """The touch reader's ``(N, K)`` readings of ``N`` frames at times ``t``, its tracks
    after each frame noted in ``history``."""
    times = np.asarray(t, dtype=np.float64)
    return touch.run(
        frames, np.asarray(active), touched, probabilities,
        after=lambda i: history.add(float(times[i]), touch.tracks),
    )  # fmt: skip
