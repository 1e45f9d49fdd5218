"""Scoring captures one label each with a capture model, on ONNX Runtime (no torch).

Windows every ``eval_stride`` model frames cover each capture, each window is scored under
every grid symmetry the model was trained with, and the capture's label is the class with
the highest mean log-probability over all of them.  Window accuracy is reported too
(identity symmetry only).  What a checkpoint needs for this is in its ``meta.json``
(:class:`CaptureModelSpec`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from wovenskin.errors import ConfigError, DataError
from wovenskin.recognition.checkpoint_meta import CheckpointMeta
from wovenskin.recognition.onnx_runtime import ONNX_THREADS, OnnxRecognizer
from wovenskin.recording.formats import LabelledCaptures
from wovenskin.training.capture_prep import (
    capture_digest,
    capture_windows,
    grid_symmetries,
    prepare_captures,
    read_capture_file,
)
from wovenskin.training.datasets.normalisation import CaptureNormalisation
from wovenskin.training.metrics import ClassificationMetrics, classification_metrics

SCORE_CHUNK = 64
"""Captures scored per ONNX Runtime batch in :func:`score_captures`."""


@dataclass(frozen=True)
class CaptureModelSpec:
    """What scoring captures with a checkpoint needs, read from its ``meta.json``."""

    normalisation: CaptureNormalisation
    frame_step: int
    window_frames: int
    eval_stride: int
    symmetries: bool
    train_digests: frozenset[str]

    @classmethod
    def from_meta(cls, meta: CheckpointMeta, where: str) -> CaptureModelSpec:
        conditioning = meta.conditioning
        stored = conditioning.get("capture_normalisation")
        if not isinstance(stored, Mapping):
            raise ConfigError(
                f"model {where} was not trained on labelled captures "
                "(train one with `wovenskin train --captures FILE`)"
            )
        info = meta.training_data.get("captures")
        info = info if isinstance(info, Mapping) else {}
        recipe = info.get("recipe") if isinstance(info.get("recipe"), Mapping) else {}
        try:
            normalisation = CaptureNormalisation.from_dict(dict(stored))
            if normalisation.reference_scale is None:
                raise ValueError("its capture normalisation has no reference scale")
            return cls(
                normalisation=normalisation,
                frame_step=int(conditioning.get("frame_step", 1)),
                window_frames=meta.window,
                eval_stride=int(recipe.get("eval_stride", max(1, meta.window // 4))),
                symmetries=bool(recipe.get("symmetries", False)),
                train_digests=frozenset(str(d) for d in info.get("train_capture_digests", [])),
            )
        except (TypeError, ValueError) as exc:
            raise DataError(f"model {where}: bad capture settings in meta.json ({exc})") from None


def per_class_dict(metrics: ClassificationMetrics) -> dict[str, dict[str, float]]:
    """``{class: {precision, recall, f1, support}}`` of ``metrics``."""
    return {
        s.name: {"precision": s.precision, "recall": s.recall, "f1": s.f1, "support": s.support}
        for s in metrics.per_class
    }


@dataclass
class CaptureEvaluation:
    """Captures scored one label each (and their windows), with what was scored."""

    source: str
    model_dir: str
    model_name: str
    class_names: tuple[str, ...]
    captures: ClassificationMetrics  # one prediction per capture
    windows: ClassificationMetrics  # one prediction per window (identity view)
    labels: np.ndarray  # (n,) true label of every scored capture
    predictions: np.ndarray  # (n,) predicted label of every scored capture
    groups: np.ndarray  # (n,) str, participant of every scored capture
    seen_in_training: int  # scored captures identical to a training capture of the model
    seconds: float
    views: int  # grid symmetries averaged per window
    log_probs: np.ndarray | None = None  # (n, K) mean log-probability of every capture

    @property
    def capture_accuracy(self) -> float:
        return self.captures.accuracy

    @property
    def window_accuracy(self) -> float:
        return self.windows.accuracy

    def per_group(self) -> dict[str, float]:
        """Capture accuracy of every participant."""
        return {
            g: float(np.mean(self.predictions[self.groups == g] == self.labels[self.groups == g]))
            for g in sorted(set(self.groups.tolist()))
        }

    def warnings(self) -> list[str]:
        if not self.seen_in_training:
            return []
        return [
            f"{self.seen_in_training} of the {self.captures.n} captures were used to train "
            "the model: their scores are not a test result"
        ]

    def to_dict(self) -> dict[str, Any]:
        return {
            "source": self.source,
            "model_dir": self.model_dir,
            "model_name": self.model_name,
            "capture_accuracy": self.captures.accuracy,
            "window_accuracy": self.windows.accuracy,
            "macro_f1": self.captures.macro_f1,
            "window_macro_f1": self.windows.macro_f1,
            "n_captures": self.captures.n,
            "n_windows": self.windows.n,
            "class_names": list(self.class_names),
            "per_class": per_class_dict(self.captures),
            "confusion": self.captures.confusion,
            "window_confusion": self.windows.confusion,
            "per_group": self.per_group(),
            "aggregation": f"mean log-probability over all windows and {self.views} grid views",
            "seen_in_training": self.seen_in_training,
            "warnings": self.warnings(),
            "seconds": self.seconds,
        }

    def summary(self) -> str:
        return (
            f"{self.captures.n} captures, {self.windows.n} windows: capture accuracy "
            f"{100 * self.capture_accuracy:.1f} %, window accuracy "
            f"{100 * self.window_accuracy:.1f} %, macro-F1 {self.captures.macro_f1:.3f}"
        )


def check_captures_fit(
    captures: LabelledCaptures, meta: CheckpointMeta, source: str, model_dir: str
) -> None:
    """One-line ``DataError`` unless the file's classes, rate and grid are the model's."""
    if list(captures.class_names) != list(meta.class_names):
        raise DataError(
            f"{source} has classes {', '.join(captures.class_names)}; model {model_dir} was "
            f"trained on {', '.join(meta.class_names)}"
        )
    rows, cols = captures.frames.shape[2:]
    if not math.isclose(captures.sample_rate_hz, meta.sample_rate_hz, rel_tol=1e-3):
        raise DataError(
            f"{source} was sampled at {captures.sample_rate_hz:g} Hz; model {model_dir} "
            f"expects {meta.sample_rate_hz:g} Hz"
        )
    if (rows, cols) != (meta.rows, meta.cols):
        raise DataError(
            f"{source} holds {rows}x{cols} frames; model {model_dir} expects "
            f"{meta.rows}x{meta.cols}"
        )


def _log_softmax(logits: np.ndarray) -> np.ndarray:
    z = np.asarray(logits, dtype=np.float64)
    z = z - z.max(axis=1, keepdims=True)
    return z - np.log(np.exp(z).sum(axis=1, keepdims=True))


def score_captures(
    recognizer: OnnxRecognizer,
    captures: LabelledCaptures,
    indices: Sequence[int] | np.ndarray | None = None,
    *,
    source: str = "",
) -> CaptureEvaluation:
    """Score the captures at ``indices`` (all by default) with a capture model.

    Every capture is prepared as in training, cut into windows every ``eval_stride`` model
    frames (the last one ending at its last frame), and every window scored under each grid
    symmetry the model was trained with; the capture's label is the class of highest mean
    log-probability.  Window accuracy counts each window's own (identity view) prediction.
    """
    started = time.perf_counter()
    meta = recognizer.meta
    model_dir = str(recognizer.checkpoint_dir)
    check_captures_fit(captures, meta, source or "the captures", model_dir)
    spec = CaptureModelSpec.from_meta(meta, model_dir)
    ids = np.arange(len(captures.labels)) if indices is None else np.asarray(indices, np.int64)
    if ids.size == 0:
        raise DataError("no captures to score")
    capture_log_p = np.empty((ids.size, meta.n_classes))
    window_true: list[np.ndarray] = []
    window_pred: list[np.ndarray] = []
    views = 1
    for start in range(0, ids.size, SCORE_CHUNK):
        chunk = ids[start : start + SCORE_CHUNK]
        prepared = prepare_captures(captures, spec.normalisation, spec.frame_step, chunk)
        per_capture = [
            capture_windows(
                prepared[int(i)], len(prepared[int(i)]), spec.window_frames, spec.eval_stride
            )
            for i in chunk
        ]
        counts = np.array([len(w) for w in per_capture])
        batch = np.concatenate(per_capture)
        log_p = np.zeros((len(batch), meta.n_classes))
        views = 0
        for view in grid_symmetries(batch, spec.symmetries) if spec.symmetries else [batch]:
            view_log_p = _log_softmax(recognizer.predict_logits(np.ascontiguousarray(view)))
            if views == 0:
                window_pred.append(view_log_p.argmax(axis=1))
            log_p += view_log_p
            views += 1
        owner = np.repeat(np.arange(chunk.size), counts)
        sums = np.zeros((chunk.size, meta.n_classes))
        np.add.at(sums, owner, log_p)
        capture_log_p[start : start + chunk.size] = sums / (counts[:, None] * views)
        window_true.append(np.repeat(captures.labels[chunk], counts))
    capture_pred = capture_log_p.argmax(axis=1)
    labels = captures.labels[ids].astype(np.int64)
    seen = 0
    if spec.train_digests:
        seen = sum(
            capture_digest(captures.frames[i, : captures.lengths[i]]) in spec.train_digests
            for i in ids.tolist()
        )
    class_names = tuple(meta.class_names)
    return CaptureEvaluation(
        source=source,
        model_dir=model_dir,
        model_name=meta.model_name,
        class_names=class_names,
        captures=classification_metrics(labels, capture_pred, class_names),
        windows=classification_metrics(
            np.concatenate(window_true), np.concatenate(window_pred), class_names
        ),
        labels=labels,
        predictions=capture_pred,
        groups=captures.groups[ids].astype(str),
        seen_in_training=int(seen),
        seconds=time.perf_counter() - started,
        views=views,
        log_probs=capture_log_p,
    )


def evaluate_captures(
    path: str | Path, model_dir: str | Path, *, threads: int = ONNX_THREADS
) -> CaptureEvaluation:
    """Score a labelled-captures file with a capture model, on ONNX Runtime (no torch).

    One label per capture (:func:`score_captures`).  A file whose class names, sample rate
    or grid differ from the model's, or a model not trained on captures, is refused with a
    one-line ``DataError``.
    """
    captures = read_capture_file(path)
    recognizer = OnnxRecognizer(model_dir, threads=threads)
    return score_captures(recognizer, captures, source=str(path))
