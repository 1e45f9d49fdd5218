"""Chunking-exact streaming filters: moving average, spike and glitch filters, hold.

All carry state between calls and give bit-identical output whether frames arrive one
at a time, all at once or in any chunks: the moving average keeps a running sum that is
updated by the same sequence of float64 additions however the frames are split
(``np.cumsum`` along time is a plain sequential accumulation); the spike filter (a causal
median of three frames) and the hold are pure selection; the glitch-pulse filter steps
through the frames that need it one by one, with the same arithmetic either way.  Frames
are ``(n, R, C)`` float64 arrays.
"""

from __future__ import annotations

import numpy as np


class CausalMovingAverage:
    """Mean of the last ``window`` frames, per channel; frames before the start count as 0.

    State: a ring buffer of the last ``window`` inputs and their running sum.  For every
    frame ``t`` the sum is updated as ``S_t = S_{t-1} + (x_t - x_{t-window})`` and the
    output is ``S_t / window``.  Rounding error in ``S`` is a random walk of ~1e-16 per
    frame on inputs of order 1: negligible for hours of data.
    """

    def __init__(self, window: int, shape: tuple[int, int]) -> None:
        if window < 1:
            raise ValueError(f"moving-average window must be at least 1 frame, got {window}")
        self.window = int(window)
        self.shape = tuple(shape)
        self.reset()

    def reset(self) -> None:
        self._ring = np.zeros((self.window, *self.shape), dtype=np.float64)
        self._sum = np.zeros(self.shape, dtype=np.float64)
        self._t = 0  # frames seen; the ring slot of frame t is t % window

    def apply(self, x: np.ndarray) -> np.ndarray:
        """Smooth ``x`` ``(n, R, C)`` float64 and advance the state by ``n`` frames."""
        n = x.shape[0]
        if n == 1:  # the live case: the same arithmetic on one frame
            slot = self._t % self.window
            total = x - self._ring[slot]
            total[0] += self._sum
            self._sum = total[0].copy()
            self._ring[slot] = x[0]
            self._t += 1
            total /= self.window
            return total
        if n == 0:
            return np.empty_like(x)
        w = self.window
        k = min(n, w)
        oldest = self._ring_slots(self._t, k)
        old = self._ring[oldest]
        if n > w:
            old = np.concatenate((old, x[: n - w]))
        steps = x - old
        steps[0] += self._sum
        if n > 1:
            np.cumsum(steps, axis=0, out=steps)
        self._sum = steps[-1].copy()
        self._ring[self._ring_slots(self._t + n - k, k)] = x[n - k :]
        self._t += n
        steps /= w
        return steps

    def _ring_slots(self, start: int, count: int) -> slice | np.ndarray:
        """Ring positions of ``count`` consecutive frames from absolute frame ``start``."""
        first = start % self.window
        if first + count <= self.window:
            return slice(first, first + count)
        return (first + np.arange(count)) % self.window


def median_of_three(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Element-wise median of three arrays (pure selection: exact)."""
    return np.maximum(np.minimum(a, b), np.minimum(np.maximum(a, b), c))


class SpikeFilter:
    """Causal median of the last three frames, per channel: removes one-frame glitches.

    A one-frame spike on one channel (a common readout glitch) would otherwise pass
    through the moving average as a bump of ``spike / window`` lasting a whole window.
    The median delays edges by one frame and leaves slower changes untouched.  The two
    frames before the start are ``initial`` (e.g. the calibrated baseline).
    """

    def __init__(self, initial: np.ndarray) -> None:
        self._initial = np.asarray(initial, dtype=np.float64).copy()
        self.reset()

    def reset(self) -> None:
        self._older = self._initial.copy()  # frame t-2
        self._newer = self._initial.copy()  # frame t-1

    def apply(self, x: np.ndarray) -> np.ndarray:
        """Filter ``x`` ``(n, R, C)`` and advance the state by ``n`` frames."""
        n = x.shape[0]
        if n == 1:
            out = median_of_three(self._older, self._newer, x[0])[None]
            self._older, self._newer = self._newer, x[0].copy()
            return out
        if n == 0:
            return np.empty_like(x)
        joined = np.concatenate((self._older[None], self._newer[None], x))
        self._older, self._newer = joined[-2].copy(), joined[-1].copy()
        return median_of_three(joined[:n], joined[1 : n + 1], joined[2:])


def hold_last_good(x: np.ndarray, bad: np.ndarray, last_good: np.ndarray) -> np.ndarray:
    """Replace each bad sample of ``x`` ``(n, R, C)`` with the channel's last good one.

    ``last_good`` ``(R, C)`` is the value to use before the first good sample of the chunk.
    Returns a new array; ``x`` is not modified.
    """
    n = x.shape[0]
    frame = np.arange(n).reshape(n, 1, 1)
    source = np.where(bad, -1, frame)
    np.maximum.accumulate(source, axis=0, out=source)
    picked = np.take_along_axis(x, np.maximum(source, 0), axis=0)
    return np.where(source >= 0, picked, last_good)


_NEIGHBOUR_FRACTION = 0.25
"""A glitch's neighbours change by less than this share of its jump (relative units)."""


class StepGlitchFilter:
    """Removes glitches smeared by a firmware moving average: one-channel steps that hold.

    A one-frame glitch of a channel's converter becomes, after a firmware average of
    ``W`` frames, a rectangular pulse: the channel steps by ``h`` in one frame, stays
    there for ``W`` frames and steps back.  The causal median of three cannot remove it
    when ``W >= 2``, and after the moving average it looks like a short touch.  Nothing
    mechanical does that: a finger lands and lifts over several frames (contact ramps,
    the fabric's lag, the firmware average itself), and an electrical burst swings both
    ways on whole lines.  So a channel whose raw reading

    - jumps by more than its ``threshold`` (raw units) from frame ``t-2`` to ``t-1``,
    - while none of its eight neighbours moves by a quarter as much, relative to its
      level (glitches are single channel; hands and bursts are not),
    - and then stays flat (moves by less than ``flat_fraction`` of the jump at ``t``),

    is taken to carry a glitch pulse: from frame ``t`` on the jump is subtracted, until
    the reading steps back by about as much (the pulse is over) or ``max_frames`` have
    passed (it was a lasting step after all, which then passes through).  Frame ``t-1``
    is left as it is: place this filter before :class:`SpikeFilter`, whose median of three
    then removes that single frame, so the filter adds no latency.

    Most frames cost a few array operations (is any jump big, from a flat reading?);
    the rest runs only on frames with a candidate or a pulse in progress.  State carries
    over between calls and the result does not depend on how frames are chunked.
    """

    def __init__(
        self,
        threshold: np.ndarray,
        level: np.ndarray,
        max_frames: int,
        flat_fraction: float = 0.3,
    ) -> None:
        threshold = np.asarray(threshold, dtype=np.float64)
        level = np.asarray(level, dtype=np.float64)
        if threshold.ndim != 2:
            raise ValueError(
                f"glitch thresholds must be a (rows, cols) grid, got {threshold.shape}"
            )
        if level.shape != threshold.shape or not (level > 0).all():
            raise ValueError("glitch filter levels must be positive, one per channel")
        if max_frames < 1:
            raise ValueError(f"max_frames must be at least 1, got {max_frames}")
        if not 0 < flat_fraction < 1:
            raise ValueError(f"flat_fraction must lie in (0, 1), got {flat_fraction}")
        self.threshold = threshold
        self._inverse_level = 1.0 / level
        self._padded = np.zeros((threshold.shape[0] + 2, threshold.shape[1] + 2))
        self.max_frames = int(max_frames)
        self.flat_fraction = float(flat_fraction)
        self.shape = (int(threshold.shape[0]), int(threshold.shape[1]))
        self._previous: np.ndarray | None = None  # raw frame t-1
        self._last_jump = np.zeros(self.shape)  # raw change from t-2 to t-1
        self._pending: np.ndarray | None = None  # jumps into t-1 that may start a pulse
        self._offset = np.zeros(self.shape)  # pulse height being removed (0: none)
        self._age = np.zeros(self.shape, dtype=np.int64)
        self._in_pulse = False

    @property
    def pulses(self) -> int:
        """Channels whose glitch pulse is being removed now."""
        return int(np.count_nonzero(self._offset)) if self._in_pulse else 0

    def apply(self, x: np.ndarray) -> np.ndarray:
        """Filter raw frames ``x`` ``(n, R, C)`` float64; returns a new array or ``x``."""
        n = x.shape[0]
        if n == 0:
            return x
        previous = x[0] if self._previous is None else self._previous
        if n == 1:
            jumps = x[0] - previous
            before = self._last_jump
        else:
            jumps = np.diff(x, axis=0, prepend=previous[None])
            before = np.concatenate((self._last_jump[None], jumps[:-1]))
        last_jump = jumps if n == 1 else jumps[-1]
        size = np.abs(jumps)
        big = size > self.threshold
        # Quiet unless some jump is big and starts from a flat reading (mains on a hand
        # makes big jumps every frame, but never from a flat reading).
        quiet = not big.any() or not (big & (np.abs(before) < self.flat_fraction * size)).any()
        if quiet and self._pending is None and not self._in_pulse:
            self._previous = x[-1].copy()
            self._last_jump = last_jump
            return x
        out = x.copy()
        for i in range(n):
            out[i] = self._step(x[i], previous)
            previous = x[i]
        self._previous = x[-1].copy()
        return out

    def _step(self, frame: np.ndarray, previous: np.ndarray) -> np.ndarray:
        jump = frame - previous
        over = None
        if self._in_pulse:
            pulse = self._offset != 0.0
            self._age[pulse] += 1
            over = pulse & (
                (np.abs(jump + self._offset) < self.flat_fraction * np.abs(self._offset))
                | (self._age > self.max_frames)
            )
            self._offset[over] = 0.0
            self._age[over] = 0
        if self._pending is not None:
            start = (self._pending != 0.0) & (
                np.abs(jump) < self.flat_fraction * np.abs(self._pending)
            )
            start &= self._offset == 0.0
            self._offset[start] = self._pending[start]
            self._age[start] = 1
        self._in_pulse = bool(self._offset.any())
        self._pending = self._candidates(jump, self._last_jump)
        self._last_jump = jump
        if self._pending is not None and over is not None and over.any():
            self._pending[over] = 0.0  # a pulse's trailing edge starts nothing
        return frame - self._offset if self._in_pulse else frame

    def _candidates(self, jump: np.ndarray, before: np.ndarray) -> np.ndarray | None:
        """Jumps above threshold from a flat reading (``before`` is the previous change) on
        channels whose neighbours stayed still, else ``None``.  The flat start keeps the
        trailing edge of a one-frame spike out."""
        size = np.abs(jump)
        big = (size > self.threshold) & (np.abs(before) < self.flat_fraction * size)
        if not big.any():
            return None
        relative = size * self._inverse_level
        padded = self._padded
        padded[1:-1, 1:-1] = relative
        rows, cols = self.shape
        around = np.zeros(self.shape)  # the largest relative jump among the 8 neighbours
        for dr in range(3):
            for dc in range(3):
                if dr != 1 or dc != 1:
                    np.maximum(around, padded[dr : dr + rows, dc : dc + cols], out=around)
        isolated = big & (around < _NEIGHBOUR_FRACTION * relative)
        return np.where(isolated, jump, 0.0) if isolated.any() else None
