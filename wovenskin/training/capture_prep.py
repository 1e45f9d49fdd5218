"""Labelled captures made into model input: normalised, averaged frames, cut into windows.

Preprocessing (recorded in every capture checkpoint and replayed by evaluation):

1. each capture's valid frames are normalised on their own
   (:class:`~wovenskin.training.datasets.normalisation.CaptureNormalisation`: minus an
   untouched reading, divided by the capture's strong readings), so people who press with
   very different force look alike;
2. every ``frame_step`` consecutive frames are averaged into one model frame (HAART:
   54 Hz to 27 Hz).  The rhythm that separates the classes (stroke ~1 Hz, pat and rub
   2-4 Hz, scratch and tickle up to ~10 Hz) stays below the new Nyquist rate, and the
   per-frame convolutional stem, most of the cost of a model, runs half as often;
3. windows of ``window_frames`` model frames (default 2 s) are classified: fixed windows
   at a stride (:func:`capture_windows`), or fresh random ones every epoch
   (:class:`CaptureWindowArray`, training).
"""

from __future__ import annotations

import hashlib
import math
import zlib
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from wovenskin.recording.files import read_captures
from wovenskin.recording.formats import LabelledCaptures
from wovenskin.training.windows import gather_windows

if TYPE_CHECKING:  # the package of data sets imports this module
    from wovenskin.training.datasets.normalisation import CaptureNormalisation


def prepare_capture(
    frames: np.ndarray,
    normalisation: CaptureNormalisation,
    frame_step: int,
    group_spread: float | None = None,
) -> np.ndarray:
    """One capture's valid frames ``(T, R, C)`` as model frames ``(T // frame_step, R, C)``.

    Normalised (``normalisation`` must be resolved; ``group_spread`` for a per-group one),
    then every ``frame_step`` frames averaged; a capture shorter than ``frame_step``
    becomes one frame, its mean.
    """
    x = normalisation.apply(frames, group_spread)
    if frame_step == 1:
        return x
    if len(x) < frame_step:
        return x.mean(axis=0, keepdims=True)
    n = len(x) // frame_step
    return x[: n * frame_step].reshape(n, frame_step, *x.shape[1:]).mean(axis=1)


def prepare_captures(
    captures: LabelledCaptures,
    normalisation: CaptureNormalisation,
    frame_step: int,
    indices: Sequence[int] | np.ndarray | None = None,
) -> dict[int, np.ndarray]:
    """:func:`prepare_capture` of the captures at ``indices`` (all by default), by index.

    A per-group normalisation takes each group's spread from all of its captures in
    ``captures`` (not only those at ``indices``)."""
    chosen = range(len(captures.lengths)) if indices is None else indices
    spreads = normalisation.group_spreads(captures) if normalisation.per_group else {}
    groups = np.asarray(captures.groups).astype(str)
    return {
        int(i): prepare_capture(
            captures.frames[i, : captures.lengths[i]],
            normalisation,
            frame_step,
            spreads.get(str(groups[i])),
        )
        for i in chosen
    }


def grid_symmetries(windows: np.ndarray, transpose: bool) -> Iterator[np.ndarray]:
    """``windows`` ``(B, W, R, C)`` under the identity, row flip, column flip, both flips,
    and (``transpose``, square grids only) the same four transposed: 4 or 8 views."""
    for t in (False, True) if transpose and windows.shape[2] == windows.shape[3] else (False,):
        base = windows.transpose(0, 1, 3, 2) if t else windows
        for flip_rows in (False, True):
            for flip_cols in (False, True):
                view = base[:, :, ::-1] if flip_rows else base
                yield view[:, :, :, ::-1] if flip_cols else view


def window_ending(frames: np.ndarray, end: int, window_frames: int) -> np.ndarray:
    """The ``window_frames`` frames of ``frames`` ending at ``end`` (inclusive), padded with
    zeros in front when ``end`` is earlier than a full window (as ``capture_windows`` does)."""
    start = end - window_frames + 1
    if start >= 0:
        return frames[start : end + 1]
    pad = np.zeros((-start, *frames.shape[1:]), dtype=frames.dtype)
    return np.concatenate([pad, frames[: end + 1]])


def capture_digest(frames: np.ndarray) -> str:
    """A short content hash of one capture's valid frames (to spot reused captures)."""
    data = np.ascontiguousarray(frames)
    return hashlib.sha1(str(data.shape).encode() + data.tobytes()).hexdigest()[:12]


def capture_window_ends(length: int, window_frames: int, stride: int) -> np.ndarray:
    """Last frames of the windows cut from a capture of ``length`` valid frames.

    Windows end every ``stride`` frames from the first full window on, and one always ends
    at the capture's last frame, so with ``stride <= window_frames`` every frame is
    covered.  A capture shorter than the window gives one window ending at its last frame
    (see :func:`capture_windows`).
    """
    if length < 1 or window_frames < 1 or stride < 1:
        raise ValueError(
            f"need length, window_frames and stride >= 1, got {length}, {window_frames}, {stride}"
        )
    if length <= window_frames:
        return np.array([length - 1], dtype=np.int64)
    ends = np.arange(window_frames - 1, length, stride, dtype=np.int64)
    if ends[-1] != length - 1:
        ends = np.append(ends, length - 1)
    return ends


def capture_windows(frames: np.ndarray, length: int, window_frames: int, stride: int) -> np.ndarray:
    """Windows ``(N, W, R, C)`` float32 of one capture's first ``length`` frames.

    Window ends follow :func:`capture_window_ends`.  A capture shorter than the window is
    padded with zeros in front (the value of "no touch" once normalised), like a live
    window that began before the capture.
    """
    frames = np.asarray(frames)
    if frames.ndim != 3 or not 1 <= length <= len(frames):
        raise ValueError(
            f"need capture frames (T, R, C) and 1 <= length <= T, got {frames.shape} and "
            f"length {length}"
        )
    ends = capture_window_ends(length, window_frames, stride)
    pad = max(0, window_frames - length)
    valid = np.asarray(frames[:length], dtype=np.float32)
    if pad:
        valid = np.concatenate([np.zeros((pad, *frames.shape[1:]), np.float32), valid])
    return gather_windows(valid, ends + pad, window_frames)


class CaptureWindowArray:
    """A read-only ``(N, W, R, C)`` float32 window array over prepared captures.

    It is what :func:`~wovenskin.training.train.train_model` reads batches from.
    Indices ``[0, n_random)`` are random windows: slot ``i`` belongs to capture
    ``random_captures[i]``, and every read draws a fresh position in that capture and
    (``symmetries``) a random flip/transposition, from ``SeedSequence(seed, crc32 of
    the indices read)``.  The training loop reads each epoch's batches in an order fixed by
    ``(seed, epoch)``, so the windows are new every epoch yet deterministic for the run,
    and a resumed run reads the same ones.  Indices ``[n_random, N)`` are the ``fixed``
    windows ``(capture, last frame)``, read as they are (validation).  A capture shorter
    than the window is padded with zeros in front (``capture_windows``' convention).
    """

    def __init__(
        self,
        prepared: Mapping[int, np.ndarray],
        window_frames: int,
        random_captures: Sequence[int] | np.ndarray,
        fixed: Sequence[tuple[int, int]],
        seed: int = 0,
        symmetries: bool = True,
        *,
        gain: float = 1.0,
        noise: float = 0.0,
        time_stretch: float = 1.0,
        shift: int = 0,
        taxel_gain: float = 0.0,
        mix: float = 0.0,
        partners: Mapping[int, Sequence[int] | np.ndarray] | None = None,
    ) -> None:
        if not prepared:
            raise ValueError("no captures to cut windows from")
        self.prepared = prepared
        self.window_frames = int(window_frames)
        self.random_captures = np.asarray(random_captures, dtype=np.int64)
        self.fixed = [(int(c), int(e)) for c, e in fixed]
        self.seed = int(seed)
        self.symmetries = symmetries
        self.gain = float(gain)
        self.noise = float(noise)
        self.time_stretch = float(time_stretch)
        self.shift = int(shift)
        self.taxel_gain = float(taxel_gain)
        self.mix = float(mix)
        self.partners = {int(k): np.asarray(v, dtype=np.int64) for k, v in (partners or {}).items()}
        grid = next(iter(prepared.values())).shape[1:]
        self.shape = (self.random_captures.size + len(self.fixed), self.window_frames, *grid)
        self.dtype = np.dtype(np.float32)
        self.ndim = 4

    def __len__(self) -> int:
        return self.shape[0]

    def __getitem__(self, index: Any) -> np.ndarray:
        idx = np.asarray(index, dtype=np.int64)
        scalar = idx.ndim == 0
        idx = np.atleast_1d(idx)
        if idx.size and (idx.min() < -len(self) or idx.max() >= len(self)):
            raise IndexError(f"window index out of range [0, {len(self)})")
        idx = np.where(idx < 0, idx + len(self), idx)
        rng = np.random.default_rng([self.seed, zlib.crc32(idx.tobytes())])
        out = np.empty((idx.size, *self.shape[1:]), dtype=np.float32)
        n_random = self.random_captures.size
        for k, i in enumerate(idx.tolist()):
            if i < n_random:
                capture = int(self.random_captures[i])
                out[k] = self._random_window(self.prepared[capture], rng)
                partners = self.partners.get(capture, ())
                if self.mix > 0 and len(partners) and rng.random() < self.mix:
                    other = self.prepared[int(rng.choice(partners))]
                    share = np.float32(rng.uniform(0.0, 0.5))
                    out[k] = (1 - share) * out[k] + share * self._random_window(other, rng)
            else:
                capture, end = self.fixed[i - n_random]
                out[k] = window_ending(self.prepared[capture], end, self.window_frames)
        return out[0] if scalar else out

    def _random_window(self, x: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        w = self.window_frames
        span = w
        if self.time_stretch > 1:  # play a span of w * rate frames back in w frames
            rate = math.exp(rng.uniform(-1, 1) * math.log(self.time_stretch))
            span = max(2, round(w * rate))
        end = len(x) - 1 if len(x) <= span else int(rng.integers(span - 1, len(x)))
        window = window_ending(x, end, span)
        if span != w:
            window = resample_frames(window, w)
        if self.symmetries:
            if rng.random() < 0.5:
                window = window[:, ::-1]
            if rng.random() < 0.5:
                window = window[:, :, ::-1]
            if window.shape[1] == window.shape[2] and rng.random() < 0.5:
                window = window.transpose(0, 2, 1)
        if self.shift:
            window = shifted(window, *rng.integers(-self.shift, self.shift + 1, size=2))
        if self.taxel_gain > 0:
            window = window * np.exp(
                self.taxel_gain * rng.standard_normal(window.shape[1:], dtype=np.float32)
            )
        if self.gain > 1:
            window = window * np.float32(math.exp(rng.uniform(-1, 1) * math.log(self.gain)))
        if self.noise > 0:
            window = window + np.float32(self.noise) * rng.standard_normal(
                window.shape, dtype=np.float32
            )
        return window


def shifted(frames: np.ndarray, rows: int, cols: int) -> np.ndarray:
    """``frames`` ``(T, R, C)`` moved by ``rows`` and ``cols`` taxels, zeros shifted in."""
    out = np.zeros_like(frames)
    r, c = frames.shape[1:]
    out[:, max(rows, 0) : r + min(rows, 0), max(cols, 0) : c + min(cols, 0)] = frames[
        :, max(-rows, 0) : r + min(-rows, 0), max(-cols, 0) : c + min(-cols, 0)
    ]
    return out


def resample_frames(frames: np.ndarray, n: int) -> np.ndarray:
    """``frames`` ``(T, R, C)`` linearly interpolated to ``n`` frames spanning the same time
    (first and last frames kept)."""
    t = np.linspace(0.0, len(frames) - 1, n)
    lo = np.minimum(np.floor(t).astype(np.int64), len(frames) - 1)
    hi = np.minimum(lo + 1, len(frames) - 1)
    frac = (t - lo).astype(np.float32)[:, None, None]
    return frames[lo] * (1 - frac) + frames[hi] * frac


def read_capture_file(path: str | Path) -> LabelledCaptures:
    """Read a labelled-captures file; every problem is a one-line error."""
    if not Path(path).is_file():
        raise FileNotFoundError(f"{path}: no such captures file")
    return read_captures(path, "training or scoring on captures")
