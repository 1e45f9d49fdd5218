"""The real-time recognition pipeline: conditioned frames -> recogniser -> arbiter -> commands.

:class:`LivePipeline` is the one path from conditioned frames to commands.  It chains
:class:`~wovenskin.recognition.streaming.StreamingRecognizer` (sliding window, model
every ``every`` frames, idle windows skipped),
:class:`~wovenskin.recognition.arbiter.PerformingDetector` and
:class:`~wovenskin.recognition.arbiter.Arbiter`, consumes ``LiveSkin`` blocks
(:meth:`LivePipeline.feed`) or any conditioned frames (:meth:`LivePipeline.process`) and
keeps the latest probabilities and the active command for views and the robot layer.
A malformed input raises a one-line ``ValueError`` (a :class:`~wovenskin.errors.DataError`
where the pipeline checks it) and leaves the pipeline's state as it was, so a live loop
can report it and carry on.

:func:`run_pipeline` runs the whole pipeline on a labelled stream (a
:class:`~wovenskin.recording.formats.LabelledStream`, or a labelled-stream ``.npz`` or
native ``.wsrec`` path): calibration on the contact-free start and conditioning by
:class:`~wovenskin.signal.conditioner.LiveConditioner` with the settings recorded in the
model's checkpoint (so the stream goes through exactly what the training data went
through), then :class:`LivePipeline`.  By default the whole stream goes through as one
block -- conditioning vectorised, the model batched over all windows with contact -- and
``block_frames=k`` feeds it ``k`` raw frames at a time as a live skin would.  Every stage
gives the same output for any split of its input, so both give the same command log
(only the floating-point rounding of a batched versus a single-window model call may
differ, which can matter only at an exact tie between two classes).

Times are the stream's own clock: the conditioner's output for a call is always the
trailing frames of the raw frames fed so far (calibration frames produce no output, as
live), so each conditioned frame takes the time of its raw frame.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from wovenskin.errors import ConfigError, DataError
from wovenskin.recognition.arbiter import (
    Arbiter,
    ArbiterSettings,
    CommandChange,
    PerformingDetector,
    PerformingSettings,
)
from wovenskin.recognition.checkpoint_meta import ModelInputError
from wovenskin.recognition.frame_tracks import FrameTracks, read_touch
from wovenskin.recognition.onnx_runtime import ONNX_THREADS, OnnxRecognizer
from wovenskin.recognition.shipped import resolve_model_dir
from wovenskin.recognition.stream_file import load_stream
from wovenskin.recognition.streaming import Recognizer, StreamingRecognizer, model_window
from wovenskin.recognition.touch_reader import (
    READERS,
    TOUCH,
    WINDOW,
    ReaderSettings,
    TouchRecognizer,
)
from wovenskin.recording.formats import LabelledStream
from wovenskin.signal.conditioner import LiveConditioner
from wovenskin.signal.config import ConditioningConfig
from wovenskin.signal.live_skin import LiveBlock
from wovenskin.tracking.tracker import Track

RESET = "reset"
"""Reason of the change that ends an active command when the pipeline is reset."""


@dataclass(frozen=True)
class PipelineSettings:
    """How often the model runs, the execution rules, the "being performed" thresholds and
    the reader (``"window"``: the paper's, window by window; ``"touch"``: the whole touch
    so far, :mod:`~wovenskin.recognition.touch_reader`, with ``reader_settings``, ``None``:
    its defaults).

    ``performing`` ``None`` takes the default thresholds with the skin's own channel
    pitches (from the stream or the model's checkpoint when known).
    """

    every: int = 1
    arbiter: ArbiterSettings = field(default_factory=ArbiterSettings)
    performing: PerformingSettings | None = None
    reader: str = WINDOW
    reader_settings: ReaderSettings | None = None

    def __post_init__(self) -> None:
        if not (isinstance(self.every, int) and self.every >= 1):
            raise ConfigError(f"every must be an integer >= 1, got {self.every!r}")
        if self.reader not in READERS:
            raise ConfigError(f"reader must be one of {', '.join(READERS)}, got {self.reader!r}")


def load_recognizer(
    model: str | os.PathLike | None = None, threads: int | None = None
) -> OnnxRecognizer:
    """The ONNX recogniser of checkpoint directory ``model`` (None: the shipped default)
    on ``threads`` ONNX Runtime threads (None: :data:`ONNX_THREADS`, an unset option)."""
    threads = ONNX_THREADS if threads is None else threads
    return OnnxRecognizer(resolve_model_dir(model), threads=threads)


def model_reader(recognizer: Any, reader: str | None = None) -> str:
    """The reader to run a recogniser with: ``reader`` when given (an explicit option), else
    the checkpoint's recommendation (``meta.json``'s ``reader.kind``), else ``"window"``."""
    if reader is not None:
        if reader not in READERS:
            raise ConfigError(f"reader must be one of {', '.join(READERS)}, got {reader!r}")
        return reader
    meta = getattr(recognizer, "meta", None)
    kind = (getattr(meta, "reader", None) or {}).get("kind")
    return kind if kind in READERS else WINDOW


def arbiter_settings_for_model(
    recognizer: Any, reader: str | None = None, **overrides: Any
) -> ArbiterSettings:
    """The execution rules for a recogniser, each setting resolved the one way: an override
    that is not ``None`` (an explicit option), else the checkpoint's recommended settings
    for its reader (``meta.json``: ``arbiter`` for the window reader, ``reader.arbiter``
    for the touch reader; measured for that model, e.g. ``min_probability``), else the
    :class:`ArbiterSettings` default.  A recommendation the arbiter does not know is
    ignored."""
    meta = getattr(recognizer, "meta", None)
    if model_reader(recognizer, reader) == TOUCH:
        stored = dict((getattr(meta, "reader", None) or {}).get("arbiter") or {})
    else:
        stored = dict(getattr(meta, "arbiter", None) or {})
    known = set(ArbiterSettings.__dataclass_fields__)
    values = {k: v for k, v in stored.items() if k in known}
    values.update({k: v for k, v in overrides.items() if v is not None})
    return ArbiterSettings(**values)


def pipeline_settings_for_model(
    recognizer: Any, every: int | None = None, reader: str | None = None, **arbiter_overrides: Any
) -> PipelineSettings:
    """The pipeline settings every command and the dashboard run a model with: the model on
    every ``every``-th window (``None``: the :class:`PipelineSettings` default), read by
    :func:`model_reader` under the execution rules of :func:`arbiter_settings_for_model`
    (explicit overrides, else the model's recommendation, else the defaults), ``every``
    included (the touch reader's ``reader.every`` in ``meta.json``)."""
    kind = model_reader(recognizer, reader)
    arbiter = arbiter_settings_for_model(recognizer, kind, **arbiter_overrides)
    meta = getattr(recognizer, "meta", None)
    reader_settings = (
        ReaderSettings.from_dict(getattr(meta, "reader", None) or {}) if kind == TOUCH else None
    )
    if every is None and kind == TOUCH:  # the touch reader's recommendation, if any
        every = (getattr(meta, "reader", None) or {}).get("every")
    extra = {} if every is None else {"every": every}
    return PipelineSettings(arbiter=arbiter, reader=kind, reader_settings=reader_settings, **extra)


def conditioning_for_model(recognizer: Any) -> ConditioningConfig | None:
    """The conditioning settings a recogniser's checkpoint was trained with.

    ``None`` when the recogniser's meta records no conditioning (a test double); a
    :class:`~wovenskin.errors.DataError` when the checkpoint was not trained on conditioned
    streams (e.g. labelled captures) or records unusable settings.
    """
    meta = getattr(recognizer, "meta", None)
    if meta is None or not hasattr(meta, "conditioning"):
        return None
    stored = dict(meta.conditioning or {})
    if not stored or "capture_normalisation" in stored:
        raise DataError(
            "the model was not trained on conditioned skin streams (its checkpoint records "
            "no conditioning settings), so it cannot run on a stream"
        )
    try:
        return ConditioningConfig.from_dict(stored)
    except (TypeError, ValueError) as exc:
        raise DataError(f"the model's conditioning settings are unusable: {exc}") from None


def _pitches(recognizer: Any, metadata: dict | None = None) -> tuple[float, float] | None:
    """Channel pitches (row, col) in mm from stream metadata, else from the model's meta."""
    for source in (
        (metadata or {}).get("layout"),
        (metadata or {}).get("info"),
    ):
        if isinstance(source, dict):
            try:
                row, col = float(source["row_pitch_mm"]), float(source["col_pitch_mm"])
            except (KeyError, TypeError, ValueError):
                continue
            if row > 0 and col > 0:
                return row, col
    meta = getattr(recognizer, "meta", None)
    row, col = getattr(meta, "row_pitch_mm", None), getattr(meta, "col_pitch_mm", None)
    if row and col:
        return float(row), float(col)
    return None


class LivePipeline:
    """Conditioned frames in, command changes out (see the module doc).

    ``conditioning`` is the configuration the frames were conditioned with; it is
    checked against the model's (as are the grid, window and rate) with a one-line
    ``ValueError`` on a mismatch.  ``pitches_mm`` (row, col) scales the "being
    performed" measures when ``settings.performing`` is None.
    """

    def __init__(
        self,
        recognizer: Recognizer,
        rows: int,
        cols: int,
        sample_rate_hz: float,
        conditioning: ConditioningConfig | None = None,
        settings: PipelineSettings | None = None,
        pitches_mm: tuple[float, float] | None = None,
    ) -> None:
        self.settings = settings or PipelineSettings()
        self.streaming = StreamingRecognizer(
            recognizer,
            rows,
            cols,
            sample_rate_hz,
            conditioning,
            every=self.settings.every,
        )
        performing = self.settings.performing
        if performing is None:
            pitches = pitches_mm or _pitches(recognizer)
            performing = PerformingSettings()
            if pitches is not None:
                performing = replace(performing, row_pitch_mm=pitches[0], col_pitch_mm=pitches[1])
        self.performing = PerformingDetector(sample_rate_hz, performing)
        self.touch: TouchRecognizer | None = None
        self.frame_tracks = FrameTracks()  # the tracks after each recent frame
        if self.settings.reader == TOUCH:
            self.touch = TouchRecognizer(
                self.streaming.class_names,
                rows,
                cols,
                performing.row_pitch_mm,
                performing.col_pitch_mm,
                sample_rate_hz,
                self.settings.reader_settings,
            )
        self.arbiter = Arbiter(self.streaming.class_names, sample_rate_hz, self.settings.arbiter)
        self.class_names = self.streaming.class_names
        self.changes: list[CommandChange] = []
        self.last_t: float | None = None
        self.touched = False
        self._next_index: int | None = None  # conditioner index expected next (feed)
        self.recorded: list[tuple[np.ndarray, ...]] | None = None
        """Set to a list to collect the arbiter's inputs of every :meth:`process` call
        (times, touched, performing, predicted, probabilities): other execution rules can
        then be replayed on them without running the model again (``wovenskin adapt``)."""

    @classmethod
    def for_live_skin(
        cls, live_skin: Any, recognizer: Recognizer, settings: PipelineSettings | None = None
    ) -> LivePipeline:
        """A pipeline for a live skin (:class:`~wovenskin.signal.live_skin.LiveSkin`), made
        with ``config=conditioning_for_model(recognizer)``: the model refuses others."""
        info = live_skin.info
        return cls(
            recognizer,
            info.rows,
            info.cols,
            info.sample_rate_hz,
            live_skin.config,
            settings,
            (info.row_pitch_mm, info.col_pitch_mm),
        )

    @property
    def active(self) -> str | None:
        """The active command (None: none)."""
        return self.arbiter.active

    @property
    def latest_probabilities(self) -> np.ndarray:
        """``(K,)`` probabilities of the latest window, columns in :attr:`class_names` order."""
        return self.streaming.latest_probabilities

    @property
    def evidence(self) -> np.ndarray:
        """``(K,)`` what views show: the touch reader's evidence for the touch so far while
        one lasts (:meth:`TouchRecognizer.evidence`), else the latest window's."""
        row = None if self.touch is None else self.touch.evidence()
        return self.streaming.latest_probabilities if row is None else row

    def tracks(self) -> list[Track]:
        """The live contact tracks after the latest frame fed (mm from the centre of
        channel ``[0, 0]``); empty with the window reader, which tracks nothing."""
        return [] if self.touch is None else self.touch.tracks

    def tracks_at(self, t: float) -> list[Track] | None:
        """The live tracks after the frame at stream time ``t`` of the last frames fed
        (:mod:`~wovenskin.recognition.frame_tracks`); ``None`` when it is not among them."""
        return [] if self.touch is None else self.frame_tracks.at(t)

    def latest_top(self) -> tuple[str, float]:
        """The most probable class of the latest window and its probability."""
        p = self.streaming.latest_probabilities
        k = int(np.argmax(p))
        return self.class_names[k], float(p[k])

    def feed(self, block: LiveBlock) -> list[CommandChange]:
        """One block from :meth:`~wovenskin.signal.live_skin.LiveSkin.step`; returns its changes.

        A block of another grid than the model's (a device that declared a new one) is one
        :class:`~wovenskin.recognition.checkpoint_meta.ModelInputError` line.  A block whose
        conditioner frame index does not follow the previous block's (the
        skin was recalibrated: a new conditioner started) first resets the pipeline, so
        no window mixes frames from two calibrations; the reset's change comes first.
        """
        cond = block.cond
        shape = tuple(np.shape(cond.signal)[-2:])
        if shape != self.streaming.shape:  # the device declared another grid since
            rows, cols = self.streaming.shape
            raise ModelInputError(
                f"the skin now streams {shape[0]}x{shape[1]} frames, the model expects "
                f"{rows}x{cols}: use a model trained for this skin (docs/skins.md)"
            )
        index = np.asarray(cond.index)
        changes: list[CommandChange] = []
        if len(index) and self._next_index is not None and int(index[0]) != self._next_index:
            ended = self.reset(float(np.asarray(block.t).reshape(-1)[0]))
            if ended is not None:
                changes.append(ended)
        changes += self.process(
            block.t, cond.signal, cond.active, cond.touched, getattr(cond, "fast", None)
        )
        if len(index):
            self._next_index = int(index[-1]) + 1
        return changes

    def process(
        self,
        t: np.ndarray,
        signal: np.ndarray,
        active: np.ndarray,
        touched: np.ndarray,
        fast: np.ndarray | None = None,
    ) -> list[CommandChange]:
        """Consecutive conditioned frames with their stream times; returns the changes.
        ``fast``, the short moving average of the same frames, is what the touch reader
        tracks the fingers on (``signal`` when not given)."""
        t = np.asarray(t, dtype=np.float64).reshape(-1)
        signal = np.asarray(signal)
        if signal.ndim == 2:
            signal, active = signal[np.newaxis], np.asarray(active)[np.newaxis]
        if t.shape[0] != signal.shape[0]:
            raise DataError(f"{t.shape[0]} frame times for {signal.shape[0]} frames")
        if not np.isfinite(t).all():
            raise DataError("frame times must be finite")
        predictions = self.streaming.push(signal, active, touched)
        performing = self.performing.update(signal.astype(np.float32, copy=False), active)
        touched = np.asarray(touched, dtype=bool).reshape(-1)
        predicted, rows = predictions.predicted, predictions.probabilities
        if self.touch is not None:
            tracked = signal if fast is None else np.asarray(fast)
            if tracked.ndim == 2:
                tracked = tracked[np.newaxis]
            if tracked.shape != signal.shape:
                raise DataError(f"fast frames shaped {tracked.shape}, frames {signal.shape}")
            rows = read_touch(self.touch, self.frame_tracks, t, tracked, active, touched, rows)
            predicted = np.ones(len(t), dtype=bool)
        if self.recorded is not None:  # the arbiter's inputs, to replay other rules on
            self.recorded.append((t, touched, performing, predicted, rows))
        changes = self.arbiter.run(t, touched, performing, predicted, rows)
        if t.size:
            self.last_t = float(t[-1])
            self.touched = bool(touched[-1])
        self.changes.extend(changes)
        return changes

    def reset(self, t: float | None = None) -> CommandChange | None:
        """Forget all frames (e.g. on recalibration); ends the active command if any."""
        ended = None
        if self.arbiter.active is not None:
            when = t if t is not None else (self.last_t if self.last_t is not None else 0.0)
            ended = CommandChange(float(when), None, RESET)
            self.changes.append(ended)
        self.streaming.reset()
        self.performing.reset()
        if self.touch is not None:
            self.touch.reset()
        self.frame_tracks.clear()
        self.arbiter = Arbiter(self.class_names, self.arbiter.sample_rate_hz, self.arbiter.settings)
        self.touched = False
        self._next_index = None
        return ended


@dataclass
class PipelineResult:
    """Commands of one run of :func:`run_pipeline` and what it cost."""

    commands: list[CommandChange]
    n_frames: int
    duration_s: float
    elapsed_s: float
    windows_predicted: int
    windows_inferred: int
    calibration: str
    warnings: list[str]

    @property
    def realtime_factor(self) -> float:
        """Stream seconds processed per second of wall-clock time."""
        return self.duration_s / self.elapsed_s if self.elapsed_s > 0 else float("inf")

    def to_dict(self) -> dict:
        return {
            "commands": [c.to_dict() for c in self.commands],
            "n_frames": self.n_frames,
            "duration_s": self.duration_s,
            "elapsed_s": self.elapsed_s,
            "realtime_factor": self.realtime_factor,
            "windows_predicted": self.windows_predicted,
            "windows_inferred": self.windows_inferred,
            "calibration": self.calibration,
            "warnings": list(self.warnings),
        }


def run_pipeline(
    stream: LabelledStream | str | os.PathLike,
    recognizer: Recognizer,
    settings: PipelineSettings | None = None,
    *,
    conditioning: ConditioningConfig | None = None,
    block_frames: int | None = None,
    on_warning: Callable[[str], None] | None = None,
    record: list | None = None,
) -> PipelineResult:
    """Calibrate, condition, recognise and arbitrate a whole labelled stream.

    ``conditioning`` defaults to the model's training settings (a recogniser without
    checkpoint meta gets the default settings at the stream's rate).  ``block_frames``
    ``None`` processes the stream as one block (fastest); an integer feeds the raw
    frames in blocks of that many, exactly as a live skin does.  Calibration warnings go
    to ``on_warning`` and into the result.  ``record``, a list, receives the arbiter's
    inputs (:attr:`LivePipeline.recorded`).
    """
    stream = load_stream(stream)
    if block_frames is not None and not (isinstance(block_frames, int) and block_frames >= 1):
        raise ConfigError(f"block_frames must be an integer >= 1, got {block_frames!r}")
    frames = np.asarray(stream.frames)
    if frames.ndim != 3:
        raise DataError(f"stream frames must be shaped (T, rows, cols), got {frames.shape}")
    n_frames, rows, cols = frames.shape
    rate = float(stream.sample_rate_hz)
    if conditioning is None:
        conditioning = conditioning_for_model(recognizer)
    if conditioning is None:
        conditioning = ConditioningConfig(sample_rate_hz=rate)
    model_window(recognizer)  # a recogniser that cannot say its window fails here
    pipeline = LivePipeline(
        recognizer, rows, cols, rate, conditioning, settings, _pitches(recognizer, stream.metadata)
    )
    if n_frames < conditioning.calibration_frames:
        raise DataError(
            f"the stream has {n_frames} frames, fewer than the {conditioning.calibration_frames} "
            f"the calibration needs ({conditioning.calibration_s:g} s)"
        )
    times = np.asarray(stream.t, dtype=np.float64)
    if times.shape != (n_frames,):
        raise DataError(f"the stream has {n_frames} frames but {times.shape[0]} times")
    warnings: list[str] = []

    def warn(message: str) -> None:
        warnings.append(message)
        if on_warning is not None:
            on_warning(message)

    pipeline.recorded = record
    conditioner = LiveConditioner(conditioning, rows, cols, on_warning=warn)
    started = time.perf_counter()
    step = n_frames if block_frames is None else block_frames
    for start in range(0, n_frames, step):
        stop = min(start + step, n_frames)
        out = conditioner.feed(frames[start:stop])
        if out is not None and len(out):  # the trailing frames of all fed so far
            pipeline.process(
                times[stop - len(out) : stop], out.signal, out.active, out.touched, out.fast
            )
    elapsed = time.perf_counter() - started
    calibration = conditioner.calibration
    return PipelineResult(
        commands=list(pipeline.changes),
        n_frames=int(n_frames),
        duration_s=n_frames / rate,
        elapsed_s=elapsed,
        windows_predicted=pipeline.streaming.windows_predicted,
        windows_inferred=pipeline.streaming.windows_inferred,
        calibration=calibration.message if calibration is not None else "not calibrated",
        warnings=warnings,
    )
