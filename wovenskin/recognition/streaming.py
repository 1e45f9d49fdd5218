"""Sliding-window recognition over a live conditioned stream.

:class:`StreamingRecognizer` keeps the last ``W`` conditioned frames (``signal``
``(R, C)`` frames indexed ``[row, col]``, from :mod:`wovenskin.signal`) and runs a
recogniser on the window ending at every ``every``-th frame.  It takes single frames or
blocks of frames (``LiveSkin`` delivers 20 ms blocks: :meth:`push_block`); windows due
inside one call are classified in one batch, and the results do not depend on how the
frames are split into calls.

- The recogniser is anything with ``class_names`` and ``predict_proba(windows)``
  (``(B, W, R, C)`` in, ``(B, K)`` out), normally an
  :class:`~wovenskin.recognition.onnx_runtime.OnnxRecognizer` on one thread.  Its
  window length is ``recognizer.meta.window`` (or the ``window`` argument).  At
  construction the stream (grid, window, rate, conditioning settings) is checked against
  it with its ``check_input`` when it has one, which refuses a mismatch with a one-line
  ``ValueError``.  The class list must contain ``invalid``.
- Prediction frames: counting the frames this object has seen from 0, frame ``n``
  is a prediction frame when a full window ends there (``n >= W - 1``) and
  ``(n - (W - 1)) % every == 0``.
- A window in which no channel is active and the skin is never ``touched`` is
  contact-free: it is not classified, its probabilities are ``invalid`` with
  certainty, so an idle skin costs no inference.
- Every output frame carries the latest probabilities (held between prediction frames;
  ``invalid`` before the first one), so views can show them at any time.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from wovenskin.gestures import INVALID

MAX_BATCH = 256
"""Windows per ``predict_proba`` call (bounds memory when a whole recording comes at once)."""


class Recognizer(Protocol):
    """What the streaming recogniser needs from a model."""

    @property
    def class_names(self) -> tuple[str, ...]: ...

    def predict_proba(self, windows: np.ndarray) -> np.ndarray: ...


@dataclass
class StreamPredictions:
    """What :meth:`StreamingRecognizer.push` returns for ``N`` consecutive frames."""

    predicted: np.ndarray  # (N,) bool: a prediction was made on the window ending here
    inferred: np.ndarray  # (N,) bool: ... and the model ran (the window had contact)
    probabilities: np.ndarray  # (N, K) float32 latest probabilities at each frame

    def __len__(self) -> int:
        return int(self.predicted.shape[0])


def model_window(recognizer: Any, window: int | None = None) -> int:
    """The recogniser's window length: ``recognizer.meta.window``, else ``window``."""
    meta = getattr(recognizer, "meta", None)
    from_meta = getattr(meta, "window", None)
    if from_meta is not None:
        if window is not None and int(window) != int(from_meta):
            raise ValueError(f"model expects windows of {from_meta} frames, got {window}")
        return int(from_meta)
    if window is None:
        raise ValueError("the recogniser does not say its window length: pass window=")
    return int(window)


class StreamingRecognizer:
    """A sliding window over conditioned frames, classified every ``every`` frames."""

    def __init__(
        self,
        recognizer: Recognizer,
        rows: int,
        cols: int,
        sample_rate_hz: float,
        conditioning: Any = None,
        every: int = 1,
        window: int | None = None,
    ) -> None:
        if not (isinstance(every, int | np.integer) and every >= 1):
            raise ValueError(f"every must be an integer >= 1, got {every!r}")
        if rows < 1 or cols < 1:
            raise ValueError(f"skin needs at least one row and column, got {rows}x{cols}")
        if not (math.isfinite(sample_rate_hz) and sample_rate_hz > 0):
            raise ValueError(f"sample rate must be positive, got {sample_rate_hz}")
        self.window = model_window(recognizer, window)
        if self.window < 1:
            raise ValueError(f"window must be at least 1 frame, got {self.window}")
        check = getattr(recognizer, "check_input", None)
        if callable(check):
            check(int(rows), int(cols), self.window, float(sample_rate_hz), conditioning)
        self.recognizer = recognizer
        self.class_names: tuple[str, ...] = tuple(str(c) for c in recognizer.class_names)
        if INVALID not in self.class_names:
            raise ValueError(
                f"the model has no {INVALID!r} class, so it cannot run on a live stream "
                f"(classes: {', '.join(self.class_names)})"
            )
        self.shape = (int(rows), int(cols))
        self.sample_rate_hz = float(sample_rate_hz)
        self.every = int(every)
        self.invalid_probabilities = np.zeros(len(self.class_names), dtype=np.float32)
        self.invalid_probabilities[self.class_names.index(INVALID)] = 1.0
        self.reset()

    def reset(self) -> None:
        """Forget every frame (after a recalibration, for example)."""
        history = self.window - 1
        self._signal = np.zeros((history, *self.shape), dtype=np.float32)
        self._contact = np.zeros(history, dtype=bool)
        self._seen = 0
        self._latest = self.invalid_probabilities.copy()
        self.windows_predicted = 0
        self.windows_inferred = 0

    @property
    def frames_seen(self) -> int:
        return self._seen

    @property
    def latest_probabilities(self) -> np.ndarray:
        """``(K,)`` probabilities of the latest prediction (``invalid`` before the first)."""
        return self._latest.copy()

    def push_block(self, cond: Any) -> StreamPredictions:
        """A block of :class:`~wovenskin.signal.conditioner.ConditionedFrames` (or any object
        with ``signal``, ``active`` and ``touched``), e.g. ``LiveBlock.cond``."""
        return self.push(cond.signal, cond.active, cond.touched)

    def push(
        self, signal: np.ndarray, active: np.ndarray, touched: np.ndarray | bool
    ) -> StreamPredictions:
        """Frames ``signal`` ``(N, R, C)`` (or one ``(R, C)``), their ``active`` channels and
        ``touched`` flags ``(N,)``; returns the predictions for these ``N`` frames."""
        signal, active, touched = self._validated(signal, active, touched)
        n = signal.shape[0]
        contact = active.reshape(n, -1).any(axis=1) | touched
        w, history = self.window, self.window - 1
        all_signal = np.concatenate([self._signal, signal]) if history else signal
        all_contact = np.concatenate([self._contact, contact]) if history else contact
        positions = np.arange(self._seen, self._seen + n)
        due = (positions >= history) & ((positions - history) % self.every == 0)
        ends = np.flatnonzero(due) + history  # index into all_* of each due window's end
        # Contact anywhere in the window ending at each due frame (prefix sums of flags).
        counts = np.concatenate([[0], np.cumsum(all_contact, dtype=np.int64)])
        starts = ends - (w - 1)
        had_contact = counts[ends + 1] - counts[starts] > 0
        probabilities = np.empty((len(ends), len(self.class_names)), dtype=np.float32)
        probabilities[:] = self.invalid_probabilities
        to_infer = np.flatnonzero(had_contact)
        if to_infer.size:
            views = np.lib.stride_tricks.sliding_window_view(all_signal, w, axis=0)
            for k in range(0, to_infer.size, MAX_BATCH):
                chosen = to_infer[k : k + MAX_BATCH]
                batch = np.moveaxis(views[starts[chosen]], -1, 1)  # (B, W, R, C)
                probabilities[chosen] = self._predict(np.ascontiguousarray(batch))
        out = np.empty((n, len(self.class_names)), dtype=np.float32)
        rows_due = np.flatnonzero(due)
        # Hold each prediction until the next one (the one before this call at first).
        last = np.full(n, -1, dtype=np.int64)
        last[rows_due] = np.arange(rows_due.size)
        last = np.maximum.accumulate(last)
        out[last < 0] = self._latest
        out[last >= 0] = probabilities[last[last >= 0]]
        if rows_due.size:
            self._latest = probabilities[-1].copy()
        inferred = np.zeros(n, dtype=bool)
        inferred[rows_due[to_infer]] = True
        if history:
            self._signal = all_signal[-history:].copy()
            self._contact = all_contact[-history:].copy()
        self._seen += n
        self.windows_predicted += int(rows_due.size)
        self.windows_inferred += int(to_infer.size)
        return StreamPredictions(predicted=due, inferred=inferred, probabilities=out)

    def _predict(self, batch: np.ndarray) -> np.ndarray:
        result = np.asarray(self.recognizer.predict_proba(batch), dtype=np.float32)
        expected = (batch.shape[0], len(self.class_names))
        if result.shape != expected:
            raise ValueError(
                f"the recogniser returned probabilities shaped {result.shape}, expected {expected}"
            )
        if not np.isfinite(result).all():
            raise ValueError("the recogniser returned NaN or inf probabilities")
        return result

    def _validated(
        self, signal: np.ndarray, active: np.ndarray, touched: np.ndarray | bool
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        rows, cols = self.shape
        signal = np.asarray(signal)
        active = np.asarray(active)
        if signal.ndim == 2:
            signal = signal[np.newaxis]
        if active.ndim == 2:
            active = active[np.newaxis]
        if signal.ndim != 3 or signal.shape[1:] != (rows, cols):
            raise ValueError(
                f"expected conditioned frames shaped (N, {rows}, {cols}) or ({rows}, {cols}), "
                f"got {np.shape(signal)}"
            )
        n = signal.shape[0]
        if active.shape != signal.shape:
            raise ValueError(f"active flags shaped {active.shape} do not match {signal.shape}")
        if signal.dtype.kind not in "fiu":
            raise ValueError(f"conditioned frames must be real numbers, got dtype {signal.dtype}")
        signal = signal.astype(np.float32, copy=False)
        if not np.isfinite(signal).all():
            raise ValueError("conditioned frames contain NaN or inf values")
        touched = np.asarray(touched, dtype=bool).reshape(-1)
        if touched.shape != (n,):
            raise ValueError(f"expected {n} touched flags, got {touched.shape[0]}")
        return signal, active.astype(bool, copy=False), touched
